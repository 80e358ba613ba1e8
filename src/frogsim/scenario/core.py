"""The Scenario: everything about one run, typed and in SI, and its variants.

A variant is made by :meth:`Scenario.replace` with dotted paths and SI values::

    hot = scenario.replace({"source.initial_pressure_gauge": 5e5,          # Pa (gauge)
                            "valves.charge.sonic_conductance": 8e-9})    # m^3/(s Pa)

Each value is checked against its field's metadata (kind, bounds, choices: the same as the loader
applies to a file) and the result against the cross-field rules (:mod:`frogsim.scenario.rules`),
with the same one-line errors. No unit text is written or parsed. The paths that can vary are
read from the dataclass fields themselves (:meth:`Scenario.variable_paths`), so a field added to
the schema is sweepable and fittable at once.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from frogsim.errors import ScenarioError
from frogsim.scenario import rules
from frogsim.scenario.fields import check_value, quantity, unknown_key_error
from frogsim.scenario.schema import (MOTION_KINDS, Air, Chamber, Controller, Motion, Muscle, MuscleType,
                                     Program, Pump, Solver, Supply, Valves)

_LEAF_KEYS = ("kind", "integer", "boolean", "choices", "choices_from")


@dataclass(frozen=True)
class Scenario:
    """Everything about one run: parameters of the robot's circuit plus the run's own settings.

    ``raw`` is the merged file dict the scenario was loaded from (empty for a variant);
    ``base_dir`` the folder relative paths in it (CSV tables) are read from.
    """
    name: str
    parameters: str
    duration: float = quantity("time", gt=0.0, le=1e6, display="s")
    output_interval: float = quantity("time", gt=0.0, display="ms")
    controller: Controller = None
    solver: Solver = None
    air: Air = None
    source: Chamber = None
    exhaust: Chamber = None
    pump: Pump = None
    valves: Valves = None
    supply: Supply = None
    muscle_types: dict[str, MuscleType] = field(default_factory=dict)
    muscles: dict[str, Muscle] = field(default_factory=dict)
    programs: dict[str, Program] = field(default_factory=dict)
    base_dir: str = "."
    raw: dict = field(default_factory=dict, repr=False, compare=False)

    def replace(self, changes: dict) -> "Scenario":
        """A variant with the settings at the dotted paths set to SI values (see module docstring).

        Raises ScenarioError naming the path, the value and what is allowed.
        """
        new = self
        for path, value in changes.items():
            if not isinstance(path, str) or not path or not all(path.split(".")):
                raise ScenarioError(str(path), value, "expected a dotted path such as source.volume")
            new = _set(new, path.split("."), value, "", self)
        if any(p.startswith("programs.") for p in changes):
            new = _relink_programs(new)
        new = dataclasses.replace(new, raw={})
        rules.check(new)
        return new

    def variable_paths(self) -> dict[str, dict]:
        """Every setting a variant may change: dotted path -> field metadata (kind, bounds,
        display unit, choices). Read from the schema; settings that this scenario does not use
        (a cycle setting of a program written as steps, a motion setting its kind ignores) are
        left out."""
        out: dict[str, dict] = {}
        _walk(self, "", self, out)
        return out

    def program_of(self, muscle: str) -> Program:
        return self.muscles[muscle].program


def _leaf_meta(meta, root: Scenario) -> dict | None:
    if not meta or not any(k in meta for k in _LEAF_KEYS):
        return None
    if "choices_from" in meta:
        return {**meta, "choices": tuple(getattr(root, meta["choices_from"]))}
    return dict(meta)


def _unused(obj, name: str) -> str:
    """Why a leaf field of obj has no effect here ("" if it has one)."""
    if isinstance(obj, Program) and name != "steps" and not obj.is_cycle:
        return "this program is written as steps, not as a cycle"
    if isinstance(obj, Motion) and name != "kind":
        required, optional = MOTION_KINDS[obj.kind]
        if name not in required and name not in optional:
            return f"not used by motion kind {obj.kind!r} (it uses: {', '.join(required + optional) or 'nothing'})"
    return ""


def _walk(obj, prefix: str, root: Scenario, out: dict) -> None:
    for f in dataclasses.fields(obj):
        if not f.init or f.name in ("raw", "base_dir"):
            continue
        path = prefix + f.name
        meta = _leaf_meta(f.metadata, root)
        val = getattr(obj, f.name)
        if meta is not None:
            if not _unused(obj, f.name):
                out[path] = meta
        elif dataclasses.is_dataclass(val):
            if not (isinstance(obj, Muscle) and f.name == "program" and obj.program_ref):
                _walk(val, path + ".", root, out)
        elif isinstance(val, dict):
            for k, v in val.items():
                if dataclasses.is_dataclass(v):
                    _walk(v, f"{path}.{k}.", root, out)


def _set(obj, keys: list, value, prefix: str, root: Scenario):
    """obj with the setting at keys (relative to obj, whose own path is prefix) set to value."""
    name = keys[0]
    fields = {f.name: f for f in dataclasses.fields(obj) if f.init and f.name not in ("raw", "base_dir")}
    here = prefix + name
    if name not in fields:
        raise unknown_key_error(prefix.rstrip("."), name, fields)
    f = fields[name]
    meta = _leaf_meta(f.metadata, root)
    if len(keys) == 1:
        if meta is None:
            current = getattr(obj, name)
            if dataclasses.is_dataclass(current) and isinstance(value, type(current)):
                _check_object(value, here, root)       # a whole table, typed (e.g. a Motion)
                extra = {"program_ref": ""} if isinstance(obj, Muscle) and name == "program" else {}
                return dataclasses.replace(obj, **{name: value}, **extra)
            raise ScenarioError(here, value, "is a table or a fixed setting: give a value of one of its "
                                             f"settings, or a whole {type(current).__name__} object")
        why = _unused(obj, name)
        if why:
            raise ScenarioError(here, value, why)
        if value is None and meta.get("default", ...) is None:
            return dataclasses.replace(obj, **{name: None})
        return dataclasses.replace(obj, **{name: check_value(value, meta, here)})
    child = getattr(obj, name)
    if isinstance(obj, Muscle) and name == "program" and obj.program_ref:
        raise ScenarioError(here + "." + ".".join(keys[1:]), value,
                            f"this muscle uses programs.{obj.program_ref}: change that program instead")
    if dataclasses.is_dataclass(child):
        return dataclasses.replace(obj, **{name: _set(child, keys[1:], value, here + ".", root)})
    if isinstance(child, dict):
        key = keys[1]
        if key not in child:
            raise ScenarioError(f"{here}.{key}", value,
                                f"no such entry (this scenario has: {', '.join(child) or 'none'})")
        if len(keys) == 2:
            raise ScenarioError(f"{here}.{key}", value, "is a table; set one of its settings")
        new_child = dict(child)
        new_child[key] = _set(child[key], keys[2:], value, f"{here}.{key}.", root)
        return dataclasses.replace(obj, **{name: new_child})
    raise ScenarioError(here, value, f"is a value, not a table ({'.'.join(keys[1:])} cannot lie inside it)")


def _check_object(obj, path: str, root: Scenario) -> None:
    """Check every setting of a typed table given whole (bounds, choices), as the loader would."""
    for f in dataclasses.fields(obj):
        val = getattr(obj, f.name)
        meta = _leaf_meta(f.metadata, root)
        if meta is not None:
            if val is not None or meta.get("default", ...) is not None:
                check_value(val, meta, f"{path}.{f.name}")
        elif dataclasses.is_dataclass(val):
            _check_object(val, f"{path}.{f.name}", root)


def _relink_programs(sc: Scenario) -> Scenario:
    """Muscles that use a named program get that program's present version."""
    muscles = {n: (dataclasses.replace(m, program=sc.programs[m.program_ref])
                   if m.program_ref and m.program is not sc.programs[m.program_ref] else m)
               for n, m in sc.muscles.items()}
    return dataclasses.replace(sc, muscles=muscles)
