"""Valve types, one module each, and their registry (docs/architecture.md, "Adding a valve type").

No list of valve types is kept by hand: every module of this package is imported here (pkgutil, in
the order of their file names) and a module that declares ``VALVE = ValveType(...)``
(:mod:`frogsim.circuit.valves.spec`) is a valve type; ``spec`` is the helper. What the rest of
frogsim reads comes from here: the loader's settings classes (registered with
:mod:`frogsim.scenario.valves`), the parameter block of a muscle's row (:func:`write_block`), and
the compiled dispatch on a muscle's valve code ``mp[i, M_VALVE]``: :func:`valve_flows` (the
right-hand side and a law's model of the valves) and :func:`valve_openings` (the controllers'
view: a command to the valve vector's entries).

Checked at import by the shared registry (:mod:`frogsim._registry`), each failure an ImportError
naming the modules: two types with one name or one ``CODE``, a code that is not a finite float > 0,
a declaration without its parts, a settings class without its ``VALVE`` declaration. A valve code no type declares
stops a run with an error, never a silent default. A valve type lives in this package: the compiled
code's cache is keyed on the files of :mod:`frogsim.circuit` (:mod:`frogsim._jit`).
"""
from __future__ import annotations

from frogsim._registry import Registry, dispatch
from frogsim.circuit.layout import M_VALVE, M_VP, VALVE_PARAMS
from frogsim.circuit.valves.spec import ValveType
from frogsim.scenario import valves as settings_registry
from frogsim.scenario.valves import ValveSettings


REGISTRY = Registry("valve types", "VALVE", ValveType, ValveSettings, "TYPE", "type",
                    loader=lambda cls, vt: settings_registry.register(cls), parts=("block", "flows", "openings"))
#: type name -> its declaration, in the order of the modules' file names
TYPES: dict[str, ValveType] = REGISTRY.by_name
#: valve code -> its type
BY_CODE: dict[float, ValveType] = REGISTRY.by_code


#: the declaration of the valve type of ``settings`` (a [valves] settings object or class)
of = REGISTRY.of


def write_block(row, settings) -> None:
    """Write the valve type's code and parameter block into a muscle row ``row`` (of mp)."""
    REGISTRY.write_block(row, settings, M_VALVE, M_VP, VALVE_PARAMS, "frogsim.circuit.layout.VALVE_PARAMS")


_ORDER = REGISTRY.discover_all(__name__, __path__)
#: ``valve_flows(code, mp, i, u_c, u_d, p_up, T_up, p_i, T_i, p_e, T_e, rho_ref, T_ref)``: the mass
#: flows of muscle i's valve (the registry's dispatch on mp[i, M_VALVE]; a code no type declares raises)
valve_flows = dispatch([(vt.code, vt.flows) for vt in _ORDER], "mp, i, u_c, u_d, p_up, T_up, p_i, T_i, p_e, T_e, rho_ref, T_ref",
                       unknown="valve_flows: a muscle row's valve code is no valve type's (frogsim.circuit.valves)")
#: ``valve_openings(code, mp, i, command, memory, dt) -> (u_c, u_d, memory)``: the controllers' view of
#: muscle i's valve, a command to the valve vector's two entries
valve_openings = dispatch([(vt.code, vt.openings) for vt in _ORDER], "mp, i, command, memory, dt",
                          unknown="valve_openings: a muscle row's valve code is no valve type's "
                                  "(frogsim.circuit.valves)")
