"""Muscle force: the ideal Chou-Hannaford law and a corrected law for the FESTO DMSP-20.

Force and volume come from the same braid geometry (:mod:`frogsim.physics.muscle`, paper Eq. (5)).
By virtual work, an ideal muscle whose volume is V(L) = (b0^2 - L^2) L / (4 pi n^2) pulls with

    F_ideal = -p_g dV/dL = p_g (3 L^2 - b0^2) / (4 pi n^2)                                   (CH)

(Chou and Hannaford 1996, the paper's reference [26]; p_g is the gauge pressure). At rest length
L0 = b0 cos(theta0) this is the familiar F = (pi D0^2 p_g / 4)(3 cos^2 theta0 - 1)/sin^2 theta0;
it vanishes at L = b0/sqrt(3) (braid angle 54.7 deg), 36 % contraction for the DMSP-20's 25.3 deg.

A real DMSP-20 pulls less: its rubber bladder and braid resist the bulging that contraction needs,
and resist stretching beyond the rest length. The corrected law subtracts an elastic force that
depends on the contraction eps = 1 - L/L0 only (so it is conservative, and the energy balance
p dV = F dL + dE_el holds with the same V(L) the pneumatic model uses):

    F = max(0, F_ideal - F_el(eps))
    F_el(eps) =  A (1 - exp(-eps/eps_c)) + k eps                    eps >= 0 (bladder resists bulging)
    F_el(eps) = -(a |eps| + b eps^2)                                eps <  0 (stretched: extra tension)

max(0, .) is the slack muscle: a tension-only actuator carries no compression. The five constants
are fitted to the force-contraction curves of FESTO's sizing data for the DMSP-20 at 1, 3 and 5 bar
(:mod:`frogsim.components.dmsp20`) and checked against the 2, 4 and 6 bar curves in the tests.
With them the muscle pulls 1499 N at 6 bar and 0 % contraction and about 110 N at 25 %.

Hysteresis (off unless the parameter set's ``[muscle_force] hysteresis = "maxwell-slip"``):
:func:`hysteretic_tension` subtracts the force of Maxwell-slip elements on the contraction
(:mod:`frogsim.physics.hysteresis`), T = max(0, F - F_h), so the muscle pulls less while it shortens
and more while it is stretched. With it off the engines call :func:`muscle_force` alone.
"""
from __future__ import annotations

import math

from frogsim._jit import jit
from frogsim.physics.hysteresis import muscle_hysteresis_force

MODEL_IDEAL = 0      # Chou-Hannaford alone (slack below zero)
MODEL_DMSP20 = 1     # Chou-Hannaford minus the fitted bladder force


@jit
def chou_hannaford_force(p_gauge: float, L: float, b0: float, n: float) -> float:
    """Eq. (CH): ideal McKibben force F = p_g (3 L^2 - b0^2) / (4 pi n^2) = -p_g dV/dL  [N].

    Args: p_gauge: pressure above the surroundings [Pa]; L: muscle length [m]; b0: braid thread
    length [m]; n: braid turns [-] (:func:`frogsim.physics.muscle.braid_parameters`).
    Negative beyond L < b0/sqrt(3), where an ideal muscle would push; see :func:`muscle_force`.

    Worked number: DMSP-20 (D0 = 20 mm, theta0 = 25.3 deg) at 6 bar and rest length: 1499 N.
    """
    return p_gauge * (3.0 * L * L - b0 * b0) / (4.0 * math.pi * n * n)


@jit
def bladder_force(contraction: float, force_scale: float, strain_scale: float, stiffness: float,
                  stretch_stiffness: float, stretch_quadratic: float) -> float:
    """Elastic force of bladder and braid F_el(eps) of the corrected law (module docstring)  [N].

    Positive for eps > 0 (it opposes the pressure force), negative for a stretched muscle (extra
    tension). Continuous at eps = 0, where it is zero.

    Args: contraction eps = 1 - L/L0 [-]; force_scale A [N]; strain_scale eps_c [-];
    stiffness k [N per unit contraction]; stretch_stiffness a [N per unit strain];
    stretch_quadratic b [N per unit strain squared].
    """
    if contraction >= 0.0:
        return force_scale * (1.0 - math.exp(-contraction / strain_scale)) + stiffness * contraction
    s = -contraction
    return -(stretch_stiffness * s + stretch_quadratic * s * s)


@jit
def muscle_force(model: int, p_gauge: float, L: float, L0: float, b0: float, n: float,
                 force_scale: float, strain_scale: float, stiffness: float,
                 stretch_stiffness: float, stretch_quadratic: float) -> float:
    """Tension of a muscle of length L at gauge pressure p_g  [N], never negative (slack).

    model = MODEL_IDEAL: max(0, F_ideal); model = MODEL_DMSP20: max(0, F_ideal - F_el(1 - L/L0)).
    Assumptions: quasi-static (no braid friction or hysteresis), the braid stays cylindrical
    (paper Fig. 7), the surroundings of the muscle (inside the sealed hull) are at atmospheric
    pressure. Units: p_gauge [Pa]; L, L0, b0 [m]; n [-]; the bladder constants as in
    :func:`bladder_force`.
    """
    f = chou_hannaford_force(p_gauge, L, b0, n)
    if model == MODEL_DMSP20:
        f -= bladder_force(1.0 - L / L0, force_scale, strain_scale, stiffness, stretch_stiffness,
                           stretch_quadratic)
    return f if f > 0.0 else 0.0


@jit
def hysteretic_tension(static_tension: float, p_gauge: float, contraction: float, anchors,
                       stiffness, slip) -> float:
    """Tension with hysteresis: max(0, F - F_h) [N], F the static tension (:func:`muscle_force`),
    F_h :func:`frogsim.physics.hysteresis.muscle_hysteresis_force` (its anchors slide, in place).

    Never negative; a muscle the static law leaves slack can pull while it is stretched (F_h < 0:
    its braid's friction resists the stretch). Args as muscle_hysteresis_force's, p_gauge [Pa],
    contraction 1 - L/L0 [-].
    """
    f = static_tension - muscle_hysteresis_force(p_gauge, contraction, anchors, stiffness, slip)
    return f if f > 0.0 else 0.0
