"""Actuator types, one module each, and their registry (docs/architecture.md, "Adding an actuator
type").

No list of actuator types is kept by hand: every module of this package is imported here
(pkgutil, in the order of their file names) and a module that declares
``ACTUATOR = ActuatorType(...)`` (:mod:`frogsim.circuit.actuators.spec`) is an actuator type;
``spec`` is a helper. What the rest of frogsim reads comes from here: the loader's settings
classes (registered with :mod:`frogsim.scenario.actuators`, so ``[muscle_types.NAME] actuator``
finds them), the parameter block of a muscle's row (:func:`write_block`), the force-law block the
coupled engine hands the kernel (:func:`force_block`), and the compiled dispatch on a muscle's
actuator code ``mp[i, M_ACT]``: :func:`actuator_volume`, :func:`actuator_slope`,
:func:`actuator_wall_area` and :func:`actuator_force` (the right-hand side, the coupled kernel),
with :func:`volume` and :func:`force` the same for Python callers.

Checked at import by the shared registry (:mod:`frogsim._registry`), each failure an ImportError
naming the modules: two types with one name or one ``CODE``, a code that is not a finite float
> 0, a declaration without its parts, a settings class without its ``ACTUATOR`` declaration. An
actuator code no type declares stops a run with an error, never a silent default. An actuator
type lives in this package: the compiled code's cache is keyed on the files of
:mod:`frogsim.circuit` (:mod:`frogsim._jit`).
"""
from __future__ import annotations

import numpy as np

from frogsim._jit import for_python, jit, jit_inner
from frogsim._registry import Registry, dispatch, membership
from frogsim.circuit.actuators.spec import FORCE_PARAMS, ActuatorType
from frogsim.circuit.layout import ACTUATOR_PARAMS, M_ACT, M_AP, M_DEAD, M_SIZE
from frogsim.scenario import actuators as settings_registry
from frogsim.scenario.actuators import ActuatorSettings

PARTS = ("block", "volume", "slope", "wall_area", "force", "force_block")

REGISTRY = Registry("actuator types", "ACTUATOR", ActuatorType, ActuatorSettings, "TYPE", "type",
                    loader=lambda cls, at: settings_registry.register(cls), parts=PARTS)
#: type name -> its declaration, in the order of the modules' file names
TYPES: dict[str, ActuatorType] = REGISTRY.by_name
#: actuator code -> its type
BY_CODE: dict[float, ActuatorType] = REGISTRY.by_code


#: the declaration of the actuator type of ``settings`` (a muscle type's settings or class)
of = REGISTRY.of


def write_block(row, settings) -> None:
    """Write the actuator type's code and parameter block into a muscle row ``row`` (of mp)."""
    REGISTRY.write_block(row, settings, M_ACT, M_AP, ACTUATOR_PARAMS, "frogsim.circuit.layout.ACTUATOR_PARAMS")


def force_block(types, law) -> tuple:
    """The force-law block (FORCE_PARAMS floats) of the muscles of settings ``types`` under the
    force law ``law`` (``[muscle_force]``): their one actuator type's ``force_block``. ValueError
    when the muscles are of several types (the engines hold one force law)."""
    names = sorted({t.TYPE for t in types})
    if len(names) != 1:
        raise ValueError(f"muscle_types: the muscles are of actuator types {', '.join(map(repr, names))}; the "
                         "coupled engine holds one force law ([muscle_force]) and takes muscles of one type")
    block = tuple(float(v) for v in TYPES[names[0]].force_block(law))
    if len(block) > FORCE_PARAMS:
        raise ValueError(f"actuator type {names[0]!r} writes a force-law block of {len(block)}; the engines hold "
                         f"{FORCE_PARAMS}")
    return block + (0.0,) * (FORCE_PARAMS - len(block))


def settings_volume(settings, L: float) -> float:
    """The volume [m^3] at length L [m] of an actuator of settings ``settings`` (a muscle type),
    by its type's compiled ``volume`` on a row written for it (before a model's rows exist)."""
    row = np.zeros((1, M_SIZE))
    write_block(row[0], settings)
    return for_python(of(settings).volume)(row, 0, float(L))


def volume(mp, i: int, L: float) -> float:
    """Muscle i's actuator volume [m^3] at length L [m] (without its dead volume), for Python callers."""
    return for_python(REGISTRY.by(mp[i, M_ACT]).volume)(mp, i, float(L))


def force(mp, i: int, p_gauge: float, L: float, law, at: int = 0) -> float:
    """Muscle i's tension [N] at gauge pressure p_gauge [Pa] and length L [m], force-law block
    ``law[at:]`` (:func:`force_block`), for Python callers."""
    return for_python(REGISTRY.by(mp[i, M_ACT]).force)(mp, i, float(p_gauge), float(L), law, at)


_ORDER = REGISTRY.discover_all(__name__, __path__)
_UNKNOWN = "a muscle row's actuator code is no actuator type's (frogsim.circuit.actuators)"


def _volume_and_slope(volume, slope):
    """A type's volume and dV/dL in one inlined body (the right-hand side needs both at one length:
    one branch per muscle, and the compiler shares what the two compute alike)."""
    @jit_inner
    def both(mp, i, L):
        return volume(mp, i, L), slope(mp, i, L)
    return both


_BOTH = [(a.code, _volume_and_slope(a.volume, a.slope)) for a in _ORDER]
#: ``actuator_volume(code, mp, i, L) -> (V, dV/dL)``: muscle i's actuator volume [m^3] and its slope
#: [m^2] at length L (the dispatch on mp[i, M_ACT]; a code no type declares raises)
actuator_volume = dispatch(_BOTH, "mp, i, L", unknown="actuator_volume: " + _UNKNOWN)
#: ``known_actuator(code) -> bool``: the code is a registered type's
known_actuator = membership([a.code for a in _ORDER], "known_actuator")
#: :func:`actuator_volume` for the muscles whose codes :func:`check_codes` has passed (the right-hand
#: side's loops; the driver's start checks every run's rows): the last branch takes any code, so with
#: one type a loop over the muscles is the type's own code, as the compiler vectorizes it
checked_volume = dispatch(_BOTH, "mp, i, L")


@jit
def check_codes(mp):
    """Raise ValueError when a muscle row's actuator code is no registered type's: the compiled
    refusal of every run, made once at the driver's start (:func:`frogsim.engine.integrator.start`),
    after which the right-hand side dispatches without one (:data:`checked_volume`)."""
    for i in range(mp.shape[0]):
        if not known_actuator(mp[i, M_ACT]):
            raise ValueError("the driver's start: a muscle row's actuator code is no actuator type's "
                             "(frogsim.circuit.actuators)")
#: ``actuator_wall_area(code, mp, i, L)``: the wall's area [m^2] (after the volumes: the codes checked)
actuator_wall_area = dispatch([(a.code, a.wall_area) for a in _ORDER], "mp, i, L")
#: ``actuator_force(code, mp, i, p_gauge, L, law, at)``: the tension [N]
actuator_force = dispatch([(a.code, a.force) for a in _ORDER], "mp, i, p_gauge, L, law, at",
                          unknown="actuator_force: " + _UNKNOWN)


@jit
def knot_volumes(mp, i, mot_L, nk, out):
    """Muscle i's total volume [m^3] (actuator volume plus dead volume) at each of its first nk
    knot lengths mot_L[i, :nk], into out[:nk]: one compiled call per muscle for the engines' check
    that every prescribed volume is positive (an unknown code raises)."""
    for k in range(nk):
        V, _ = actuator_volume(mp[i, M_ACT], mp, i, mot_L[i, k])
        out[k] = V + mp[i, M_DEAD]
