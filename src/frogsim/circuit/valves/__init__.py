"""Valve types, one module each, and their registry (docs/architecture.md, "Adding a valve type").

No list of valve types is kept by hand: every module of this package is imported here (pkgutil, in
the order of their file names) and a module that declares ``VALVE = ValveType(...)``
(:mod:`frogsim.circuit.valves.spec`) is a valve type; ``spec`` is the helper. What the rest of
frogsim reads comes from here: the loader's settings classes (registered with
:mod:`frogsim.scenario.valves`), the parameter block of a muscle's row (:func:`write_block`), and
the compiled dispatch on a muscle's valve code ``mp[i, M_VALVE]``: :func:`valve_flows` (the
right-hand side and a law's model of the valves) and :func:`valve_openings` (the controllers'
view: a command to the valve vector's entries).

Checked at import, each failure an ImportError naming the modules: two types with one name or one
``CODE``, a code that is not a finite float > 0, a block longer than the layout's
``VALVE_PARAMS``, a settings class without its ``VALVE`` declaration. A valve code no type declares
stops a run with an error, never a silent default. A valve type lives in this package: the compiled
code's cache is keyed on the files of :mod:`frogsim.circuit` (:mod:`frogsim._jit`).
"""
from __future__ import annotations

import dataclasses
import importlib
import math
import pkgutil

from frogsim._jit import jit_inner
from frogsim.circuit.layout import M_VALVE, M_VP, VALVE_PARAMS
from frogsim.circuit.valves.spec import ValveType
from frogsim.scenario import valves as settings_registry
from frogsim.scenario.valves import ValveSettings

#: type name -> its declaration, in the order of the modules' file names
TYPES: dict[str, ValveType] = {}
#: valve code -> its type
BY_CODE: dict[float, ValveType] = {}


def _refuse(text: str):
    raise ImportError(f"valve types: {text}")


def _check(vt, module: str) -> None:
    if not isinstance(vt, ValveType):
        _refuse(f"{module}.VALVE is a {type(vt).__name__}, not a ValveType (frogsim.circuit.valves.spec)")
    s = vt.settings
    if not (isinstance(s, type) and issubclass(s, ValveSettings) and dataclasses.is_dataclass(s)):
        _refuse(f"{module}: settings {s!r} is not a dataclass derived from ValveSettings")
    if not isinstance(s.TYPE, str) or not s.TYPE:
        _refuse(f"{module}: settings class {s.__name__} has no TYPE (the valve type's name in files)")
    if not isinstance(vt.code, float) or not math.isfinite(vt.code) or vt.code <= 0.0:
        _refuse(f"{module}: valve type {s.TYPE!r} has code {vt.code!r}: a code is a finite float > 0")
    for what in ("block", "flows", "openings"):
        if getattr(vt, what) is None:
            _refuse(f"{module}: valve type {s.TYPE!r} has no {what}")


def _register(vt: ValveType, module: str) -> ValveType:
    _check(vt, module)
    other = TYPES.get(vt.name)
    if other is not None:
        _refuse(f"type name {vt.name!r} of {module} is already taken by {other.module}: each valve type "
                "needs its own name")
    if vt.code in BY_CODE:
        _refuse(f"CODE {vt.code!r} of {module} (type {vt.name!r}) is already taken by {BY_CODE[vt.code].module} "
                f"(type {BY_CODE[vt.code].name!r}): each valve type needs its own CODE")
    vt = vt.registered(module)
    settings_registry.register(vt.settings)
    TYPES[vt.name] = vt
    BY_CODE[vt.code] = vt
    return vt


def _orphan_settings(module) -> list:
    return [obj for obj in vars(module).values()
            if isinstance(obj, type) and issubclass(obj, ValveSettings) and obj.__module__ == module.__name__
            and obj.TYPE]


def _discover() -> None:
    for info in pkgutil.iter_modules(__path__):
        name = f"{__name__}.{info.name}"
        module = importlib.import_module(name)
        declared = getattr(module, "VALVE", None)
        if declared is None:
            orphans = _orphan_settings(module)
            if orphans:
                _refuse(f"{name} defines the settings of valve type {orphans[0].TYPE!r} ({orphans[0].__name__}) "
                        "but declares no VALVE = ValveType(...) (frogsim.circuit.valves.spec)")
            continue
        _register(declared, name)


def of(settings) -> ValveType:
    """The declaration of the valve type of ``settings`` (a [valves] settings object or class)."""
    return TYPES[settings.TYPE]


def write_block(row, settings) -> None:
    """Write the valve type's code and parameter block into a muscle row ``row`` (of mp)."""
    vt = of(settings)
    block = tuple(float(v) for v in vt.block(settings))
    if len(block) > VALVE_PARAMS:
        raise ValueError(f"valve type {vt.name!r} ({vt.module}) writes {len(block)} parameters; the muscle row "
                         f"holds {VALVE_PARAMS} (frogsim.circuit.layout.VALVE_PARAMS)")
    row[M_VALVE] = vt.code
    row[M_VP:M_VP + VALVE_PARAMS] = 0.0
    row[M_VP:M_VP + len(block)] = block


# --- the compiled dispatch on a muscle's valve code ---------------------------------------------------
def _flow_chain(entries):
    """``valve_flows(code, mp, i, u_c, u_d, p_up, T_up, p_i, T_i, p_e, T_e, rho_ref, T_ref)``: the
    ``flows`` of the type whose code is ``code``, one inlined branch per type (as the controller
    kinds' dispatch in :mod:`frogsim.control.sampled`); the last raises for a code no type declares."""
    def last(code, flows):
        @jit_inner
        def branch(vc, mp, i, u_c, u_d, p_up, T_up, p_i, T_i, p_e, T_e, rho_ref, T_ref):
            if vc != code:
                raise ValueError("valve_flows: a muscle row's valve code is no valve type's "
                                 "(frogsim.circuit.valves)")
            return flows(mp, i, u_c, u_d, p_up, T_up, p_i, T_i, p_e, T_e, rho_ref, T_ref)
        return branch

    def link(code, flows, rest):
        @jit_inner
        def branch(vc, mp, i, u_c, u_d, p_up, T_up, p_i, T_i, p_e, T_e, rho_ref, T_ref):
            if vc == code:
                return flows(mp, i, u_c, u_d, p_up, T_up, p_i, T_i, p_e, T_e, rho_ref, T_ref)
            return rest(vc, mp, i, u_c, u_d, p_up, T_up, p_i, T_i, p_e, T_e, rho_ref, T_ref)
        return branch

    out = last(entries[-1].code, entries[-1].flows)
    for vt in reversed(entries[:-1]):
        out = link(vt.code, vt.flows, out)
    return out


def _openings_chain(entries):
    """``valve_openings(code, mp, i, command, memory, dt) -> (u_c, u_d, memory)``: the ``openings``
    of the type whose code is ``code`` (the last raises for a code no type declares)."""
    def last(code, openings):
        @jit_inner
        def branch(vc, mp, i, command, memory, dt):
            if vc != code:
                raise ValueError("valve_openings: a muscle row's valve code is no valve type's "
                                 "(frogsim.circuit.valves)")
            return openings(mp, i, command, memory, dt)
        return branch

    def link(code, openings, rest):
        @jit_inner
        def branch(vc, mp, i, command, memory, dt):
            if vc == code:
                return openings(mp, i, command, memory, dt)
            return rest(vc, mp, i, command, memory, dt)
        return branch

    out = last(entries[-1].code, entries[-1].openings)
    for vt in reversed(entries[:-1]):
        out = link(vt.code, vt.openings, out)
    return out


_discover()
if not BY_CODE:
    _refuse("no module of frogsim.circuit.valves declares a valve type")
_ORDER = [BY_CODE[c] for c in sorted(BY_CODE)]
#: the mass flows of muscle i's valve (the registry's dispatch on mp[i, M_VALVE])
valve_flows = _flow_chain(_ORDER)
#: the controllers' view of muscle i's valve: a command to the valve vector's two entries
valve_openings = _openings_chain(_ORDER)
