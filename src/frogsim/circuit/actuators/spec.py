"""The declaration every actuator type's module ends with: ``ACTUATOR = ActuatorType(...)``."""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

#: entries of an actuator type's force-law block (the engines' ``law[at:at + FORCE_PARAMS]``)
FORCE_PARAMS = 6


@dataclass(frozen=True)
class ActuatorType:
    """What the rest of frogsim reads of an actuator type (docs/architecture.md, "Adding an
    actuator type").

    * ``settings``: its settings class (a frozen dataclass derived from
      :class:`frogsim.scenario.actuators.ActuatorSettings`, ``TYPE`` its name in
      ``[muscle_types.NAME] actuator``);
    * ``code``: its value in the muscle rows' actuator column ``mp[i, M_ACT]`` (a float > 0, unique);
    * ``block(settings) -> tuple``: its parameter block, at most ``ACTUATOR_PARAMS`` floats, written
      at ``mp[i, M_AP:]`` (SI);
    * ``volume(mp, i, L) -> V``: the air volume [m^3] inside actuator i at length L [m] (without
      the dead volume of fittings and tube, which the engines add);
    * ``slope(mp, i, L) -> dV/dL`` [m^2] (the right-hand side's dV/dt = dV/dL dL/dt);
    * ``wall_area(mp, i, L) -> A`` [m^2]: the wall the air exchanges heat with;
    * ``force(mp, i, p_gauge, L, law, at) -> F`` [N]: the tension at gauge pressure p_gauge [Pa]
      and length L (never negative for a tension-only actuator), ``law[at:at + FORCE_PARAMS]`` its
      force-law block (written by ``force_block``);
    * ``force_block(law) -> tuple``: that block (at most FORCE_PARAMS floats) from the parameter
      set's ``[muscle_force]`` settings (:class:`frogsim.robot.params.MuscleForceLaw`).

    The four compiled functions are Numba, allocation-free, inlined into their callers
    (:func:`frogsim._jit.jit_inner`: the compiled code is the same as a direct call of the law's
    physics functions, bit for bit); :func:`frogsim.circuit.actuators.for_python` compiles them
    for Python callers.
    """
    settings: type
    code: float
    block: Callable
    volume: Callable
    slope: Callable
    wall_area: Callable
    force: Callable
    force_block: Callable
    module: str = ""

    @property
    def name(self) -> str:
        return self.settings.TYPE

    def registered(self, module: str) -> "ActuatorType":
        return replace(self, module=module)
