"""Actuator type "mckibben": the paper's braided pneumatic muscle (FESTO DMSP-20).

Volume: Eq. (5) of the paper, the braided cylinder of n turns of an inextensible thread of length
b0, V = (b0^2 - L^2) L / (4 pi n^2) (:func:`frogsim.physics.muscle.muscle_volume`), its slope
dV/dL (:func:`frogsim.physics.muscle.muscle_volume_slope`) and the cylinder's mantle as the wall
the air exchanges heat with (:func:`frogsim.physics.heat.muscle_wall_area`). Force: the
Chou-Hannaford law less the DMSP-20's fitted bladder force, or the ideal law alone
(``[muscle_force] model``; :func:`frogsim.physics.muscle_force.muscle_force`).

Settings: :class:`frogsim.scenario.schema.MuscleType` (rest length, inner diameter, braid angle,
and the crank mounting every actuator type has; it stays in the scenario layer, where every
scenario's type hints name it).
"""
from __future__ import annotations

from frogsim._jit import jit_inner
from frogsim.circuit.actuators.spec import ActuatorType
from frogsim.circuit.layout import M_AP, M_L0
from frogsim.physics.heat import muscle_wall_area
from frogsim.physics.muscle import braid_parameters, muscle_volume, muscle_volume_slope
from frogsim.physics.muscle_force import MODEL_DMSP20, MODEL_IDEAL, muscle_force
from frogsim.scenario.schema import MuscleType

CODE = 1.0

# the parameter block (offsets from M_AP)
P_B0 = 0        # braid thread length b0 [m]
P_N = 1         # braid turns n [-]

# the force-law block (offsets from ``at``)
F_MODEL = 0     # MODEL_DMSP20 or MODEL_IDEAL
F_BLADDER = 1   # the bladder constants A, eps_c, k, a, b (5)


def block(mt: MuscleType) -> tuple:
    """The braid's b0 and n from the rest length, inner diameter and braid angle."""
    b0, n = braid_parameters(mt.nominal_length, mt.inner_diameter, mt.braid_angle)
    return (b0, n)


def force_block(law) -> tuple:
    """The force law's code and its five bladder constants (``[muscle_force]``)."""
    return (MODEL_DMSP20 if law.model == "dmsp20" else MODEL_IDEAL, law.force_scale, law.strain_scale,
            law.stiffness, law.stretch_stiffness, law.stretch_quadratic)


@jit_inner
def volume(mp, i, L):
    """Eq. (5) at length L [m^3]."""
    return muscle_volume(L, mp[i, M_AP + P_B0], mp[i, M_AP + P_N])


@jit_inner
def slope(mp, i, L):
    """dV/dL of Eq. (5) at length L [m^2]."""
    return muscle_volume_slope(L, mp[i, M_AP + P_B0], mp[i, M_AP + P_N])


@jit_inner
def wall_area(mp, i, L):
    """The braid cylinder's mantle at length L [m^2]."""
    return muscle_wall_area(L, mp[i, M_AP + P_B0], mp[i, M_AP + P_N])


@jit_inner
def force(mp, i, p_gauge, L, law, at):
    """The muscle's tension [N] at gauge pressure p_gauge [Pa] and length L [m]: max(0, F_CH - F_el)."""
    return muscle_force(int(law[at + F_MODEL]), p_gauge, L, mp[i, M_L0], mp[i, M_AP + P_B0], mp[i, M_AP + P_N],
                        law[at + F_BLADDER], law[at + F_BLADDER + 1], law[at + F_BLADDER + 2],
                        law[at + F_BLADDER + 3], law[at + F_BLADDER + 4])


ACTUATOR = ActuatorType(settings=MuscleType, code=CODE, block=block, volume=volume, slope=slope,
                        wall_area=wall_area, force=force, force_block=force_block)
