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
import functools
from dataclasses import dataclass, field

from frogsim.errors import UNKNOWN, ScenarioError
from frogsim.scenario import rules
from frogsim.scenario.fields import check_value, quantity, unknown_key_error
from frogsim.scenario.firmware import Firmware
from frogsim.scenario.kinds import ControllerSettings
from frogsim.scenario.schema import (MOTION_KINDS, Air, Chamber, Controller, Motion, Muscle, MuscleType,
                                     Program, Pump, Solver, Supply, Valves)

_LEAF_KEYS = ("kind", "integer", "boolean", "choices", "choices_from")


@dataclass(frozen=True)
class Scenario:
    """Everything about one run: parameters of the robot's circuit plus the run's own settings.

    ``raw`` is the merged file dict the scenario was loaded from (for a variant, only the
    sections no typed field holds: UNTYPED_RAW);
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
    controllers: dict[str, ControllerSettings] = field(default_factory=dict)
    joints: dict = field(default_factory=dict)      # robot: joint -> (extensor, flexor or None)
    firmware: Firmware | None = None                # [firmware]: the board (frogsim.scenario.firmware)
    base_dir: str = "."
    raw: dict = field(default_factory=dict, repr=False, compare=False)

    def replace(self, changes: dict) -> "Scenario":
        """A variant with the settings at the dotted paths set to SI values (see module docstring).

        Raises ScenarioError naming the path, the value and what is allowed.
        """
        tree = _parse(changes)
        new = _with(self, **_top_changes(self, tree))
        if "programs" in tree:
            new = _with(new, muscles=_relinked(new.programs, new.muscles))
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


@functools.lru_cache(maxsize=None)
def _field_map(cls) -> dict:
    return {f.name: f for f in dataclasses.fields(cls) if f.init and f.name not in ("raw", "base_dir")}


def _with(obj, **changes):
    """dataclasses.replace for frozen dataclasses, without the generic machinery's cost: a copy
    with the fields set, then the class's own __post_init__ (a Program derives its steps)."""
    new = object.__new__(type(obj))
    new.__dict__.update(obj.__dict__)
    new.__dict__.update(changes)
    post = getattr(new, "__post_init__", None)
    if post is not None:
        post()
    return new


_LEAVES: dict = {}      # id of a field's metadata (fixed for the class's life) -> its dict, or None


def _leaf_meta(meta, root: Scenario) -> dict | None:
    """The metadata of a setting a variant can change (a copy; choices of a ``choices_from``
    field read from the scenario), or None for a table or a fixed setting. Read-only for callers."""
    key = id(meta)
    if key not in _LEAVES:
        _LEAVES[key] = dict(meta) if meta and any(k in meta for k in _LEAF_KEYS) else None
    leaf = _LEAVES[key]
    if leaf is not None and "choices_from" in leaf:
        return {**leaf, "choices": tuple(getattr(root, leaf["choices_from"]))}
    return leaf


def _unused(obj, name: str) -> str:
    """Why a leaf field of obj has no effect here ("" if it has one)."""
    if isinstance(obj, Program) and name != "steps" and not obj.is_cycle:
        return "this program is written as steps, not as a cycle"
    if hasattr(obj, "unused"):      # setpoints say which settings their kind reads
        return obj.unused(name)
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
                out[path] = dict(meta)          # the caller's own copy
        elif dataclasses.is_dataclass(val):
            if not (isinstance(obj, Muscle) and f.name == "program" and obj.program_ref):
                _walk(val, path + ".", root, out)
        elif isinstance(val, dict):
            for k, v in val.items():
                if dataclasses.is_dataclass(v):
                    _walk(v, f"{path}.{k}.", root, out)


class _Tree(dict):
    """Changes below one table: key -> value, or a _Tree for a table further down."""



def _parse(changes: dict) -> _Tree:
    """The tree of changes (one _Tree per table) of dotted paths -> values; ScenarioError on a
    malformed path or on a path that lies inside another one."""
    tree = _Tree()
    for path, value in changes.items():
        if not isinstance(path, str) or not path or not all(path.split(".")):
            raise ScenarioError(str(path), value, "expected a dotted path such as source.volume")
        node = tree
        keys = path.split(".")
        for j, key in enumerate(keys[:-1]):
            node = node.setdefault(key, _Tree())
            if not isinstance(node, _Tree):
                raise ScenarioError(path, value, f"lies inside {'.'.join(keys[:j + 1])}, which is also set")
        if isinstance(node.get(keys[-1]), _Tree):
            raise ScenarioError(path, value, "is a table whose settings are also set")
        node[keys[-1]] = value
    return tree


def _top_changes(sc: Scenario, tree: _Tree) -> dict:
    """{top-level setting: its new value} for a tree of changes of sc (its ``raw`` cleared but for
    the sections no typed field holds, UNTYPED_RAW): each top-level entry is made from its own branch
    of the tree alone (:func:`_top_change`)."""
    changes = {}
    for name, value in tree.items():
        changes.update(_top_change(sc, name, value))
    changes["raw"] = variant_raw(sc)
    return changes


#: merged sections a pneumatic scenario keeps only in ``raw`` (no typed field), carried to its
#: variants: the force law its tensions and force-table fits use
#: (:func:`frogsim.robot.params.parameter_set_law`)
UNTYPED_RAW = ("muscle_force",)


def variant_raw(sc: Scenario) -> dict:
    """The ``raw`` of a variant of sc: its UNTYPED_RAW sections (the rest of raw describes the file
    sc was loaded from, which a variant no longer is)."""
    return {k: sc.raw[k] for k in UNTYPED_RAW if k in sc.raw}


def _top_change(sc: Scenario, name: str, value) -> dict:
    """{name: new value} of one top-level setting of sc, from its branch of the tree of changes."""
    fields = _field_map(type(sc))
    if name not in fields:
        raise unknown_key_error("", name, fields)
    if isinstance(value, _Tree):
        return {name: _apply_inside(sc, name, value, name, sc)}
    return _leaf_change(sc, fields[name], value, name, sc)


def _apply(obj, tree: _Tree, prefix: str, root: Scenario):
    """obj (whose own path is prefix) with every change of the tree made; one copy per table."""
    changes = {}
    fields = _field_map(type(obj))
    for name, value in tree.items():
        here = prefix + name
        if name not in fields:
            raise unknown_key_error(prefix.rstrip("."), name, fields)
        if isinstance(value, _Tree):
            changes[name] = _apply_inside(obj, name, value, here, root)
        else:
            changes.update(_leaf_change(obj, fields[name], value, here, root))
    return _with(obj, **changes)


def _apply_inside(obj, name: str, tree: _Tree, here: str, root: Scenario):
    child = getattr(obj, name)
    if isinstance(obj, Muscle) and name == "program" and obj.program_ref:
        raise ScenarioError(f"{here}.{next(iter(tree))}", UNKNOWN,
                            f"this muscle uses programs.{obj.program_ref}: change that program instead")
    if dataclasses.is_dataclass(child):
        return _apply(child, tree, here + ".", root)
    if isinstance(child, dict):
        new_child = dict(child)
        for key, sub in tree.items():
            if key not in child:
                raise ScenarioError(f"{here}.{key}", UNKNOWN,
                                    f"no such entry (this scenario has: {', '.join(child) or 'none'})")
            if not isinstance(sub, _Tree):
                raise ScenarioError(f"{here}.{key}", sub, "is a table; set one of its settings")
            new_child[key] = _apply(child[key], sub, f"{here}.{key}.", root)
        return new_child
    raise ScenarioError(f"{here}.{next(iter(tree))}", UNKNOWN, f"{here} is a value, not a table")


def _leaf_change(obj, f, value, here: str, root: Scenario) -> dict:
    """{field name: checked value} (and what goes with it) for one setting of obj."""
    name = f.name
    meta = _leaf_meta(f.metadata, root)
    if meta is None:
        current = getattr(obj, name)
        if dataclasses.is_dataclass(current) and isinstance(value, type(current)):
            _check_object(value, here, root)       # a whole table, typed (e.g. a Motion)
            extra = {"program_ref": ""} if isinstance(obj, Muscle) and name == "program" else {}
            return {name: value, **extra}
        raise ScenarioError(here, value, "is a table or a fixed setting: give a value of one of its "
                                         f"settings, or a whole {type(current).__name__} object")
    why = _unused(obj, name)
    if why:
        raise ScenarioError(here, value, why)
    if value is None and meta.get("default", ...) is None:
        return {name: None}
    return {name: check_value(value, meta, here)}


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


def _relinked(programs: dict, muscles: dict) -> dict:
    """The muscles, those that use a named program given that program's present version."""
    return {n: (dataclasses.replace(m, program=programs[m.program_ref])
                if m.program_ref and m.program is not programs[m.program_ref] else m)
            for n, m in muscles.items()}
