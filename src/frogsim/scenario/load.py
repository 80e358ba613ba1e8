"""Load a scenario: a TOML file (or dict) laid over a named parameter set, validated into SI.

A scenario file may hold the run's own settings (name, parameters, duration, output_interval,
controller, solver, programs, muscles) and any section of the parameter set (air, source, exhaust,
pump, valves, supply, muscle_types) to override it, key by key.
"""
from __future__ import annotations

import copy
import dataclasses
import os
import re
import tomllib
from pathlib import Path

from frogsim.scenario.fields import build, check_bounds, parse_field, unknown_key_error, unwrap
from frogsim.scenario.files import check_raw, read_text
from frogsim.scenario.core import Scenario
from frogsim.scenario.rules import check
from frogsim.scenario.schema import (
    Air, Chamber, Controller, Muscle, MuscleType, Program, Pump, Solver, Supply, Valves, Setpoint,
    with_table,
)
from frogsim.scenario.firmware import Firmware
from frogsim.scenario.kinds import ControllerSettings
from frogsim.scenario.actuators import from_raw as actuator_settings
from frogsim.scenario.valves import from_raw as valve_settings, type_of as valve_type_of
from frogsim.errors import MISSING, ScenarioError, Shown

PARAMS_DIR = Path(__file__).resolve().parent.parent / "params"
SCENARIOS_DIR = Path(__file__).resolve().parent.parent / "scenarios"
PARAM_SECTIONS = ("air", "source", "exhaust", "pump", "valves", "supply", "muscle_types",
                  # the robot as a moving body (frogsim.robot.params)
                  "muscle_force", "body", "legs", "joints", "palms", "water", "hydro")
RUN_KEYS = ("name", "description", "parameters", "duration", "output_interval", "controller",
            "solver", "programs", "muscles", "controllers",
            # robot scenarios (frogsim.robot.scenario): options and gait instead of muscles
            "robot", "gait",
            # the board the valve controllers run on (frogsim.scenario.firmware)
            "firmware",
            # what `frogsim tune` searches (frogsim.optimize.tune; the runs themselves ignore it)
            "tune")


def read_toml(path: str | os.PathLike, what: str) -> dict:
    """Read a TOML file, turning file and syntax errors into ScenarioError.

    Only a regular file of UTF-8 text is read (not a directory, device or FIFO, see
    :func:`frogsim.scenario.files.read_text`); tables and arrays may nest at most
    :data:`frogsim.scenario.files.MAX_DEPTH` levels deep.
    """
    text = read_text(path, what)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(what, str(path), f"not valid TOML ({exc})") from None
    except RecursionError:
        raise ScenarioError(what, str(path), "not readable: tables or arrays nested too deeply") from None
    except ValueError as exc:      # e.g. an integer of more than 4300 digits
        raise ScenarioError(what, str(path), f"not valid TOML ({exc})") from None
    check_raw(data, what, str(path))
    return data


def parameter_set_names() -> list[str]:
    """Names of the parameter sets shipped with frogsim."""
    return sorted(p.stem for p in PARAMS_DIR.glob("*.toml"))


def load_parameter_set(name_or_path: str, base_dir: str = ".") -> dict:
    """The raw dict of a parameter set, by shipped name or by path (relative to base_dir).

    A set whose ``[meta]`` says ``extends = "NAME"`` is the shipped set NAME with its own values
    laid over it, key by key (:func:`deep_merge`)."""
    if name_or_path in parameter_set_names():
        path = PARAMS_DIR / f"{name_or_path}.toml"
    else:
        path = Path(base_dir) / name_or_path
        if not os.path.lexists(path):
            raise ScenarioError("parameters", name_or_path,
                                f"must be a shipped parameter set ({', '.join(parameter_set_names())}) "
                                "or a path to a parameter file")
    raw = read_toml(path, "parameters")
    meta = raw.pop("meta", None)
    for key in raw:
        if key not in PARAM_SECTIONS:
            raise unknown_key_error(f"parameters file {path.name}", key, PARAM_SECTIONS)
    base = meta.get("extends") if isinstance(meta, dict) else None
    if base is not None:
        # a set written as changes to a shipped set: [meta] extends = "fan2017", then its own values
        if base not in parameter_set_names() or base == Path(path).stem:
            raise ScenarioError(f"parameters file {path.name}: meta.extends", base,
                                f"must name another shipped parameter set ({', '.join(parameter_set_names())})")
        raw = deep_merge(load_parameter_set(base), raw)
    return raw


def pressure_twin(key) -> str | None:
    """The other spelling of a pressure setting: "x_gauge" <-> "x_abs" (None for other keys)."""
    if isinstance(key, str):
        if key.endswith("_gauge"):
            return key[:-len("_gauge")] + "_abs"
        if key.endswith("_abs"):
            return key[:-len("_abs")] + "_gauge"
    return None


def deep_merge(base: dict, over: dict) -> dict:
    """A copy of base with over laid on top, table by table.

    A pressure given in over as ``x_abs`` replaces base's ``x_gauge`` and the other way round
    (a scenario may write either spelling over its parameter set's).
    """
    out = copy.deepcopy(base)
    for key, val in over.items():
        twin = pressure_twin(key)
        if twin is not None and twin in out and twin not in over:
            del out[twin]
        if isinstance(val, dict) and isinstance(out.get(key), dict) and "value" not in val:
            out[key] = deep_merge(out[key], val)
        else:
            out[key] = copy.deepcopy(val)
    return out


#: the dataclasses whose ``*_gauge`` settings may be written ``*_abs`` in a file, by section
_GAUGE_SECTIONS = {"source": Chamber, "exhaust": Chamber, "pump": Pump}


def gauge_from_abs(table, cls, path: str, p_atm: float):
    """The table with every ``x_abs`` of a ``x_gauge`` field of cls turned into ``x_gauge``.

    The absolute pressure is converted with the scenario's atmospheric pressure p_atm [Pa] and
    checked against the gauge field's bounds; writing both spellings is refused. Anything that is
    not a table is returned as it is (the builder then refuses it).
    """
    if not isinstance(table, dict):
        return table
    gauge_fields = {f.name: f.metadata for f in dataclasses.fields(cls) if f.name.endswith("_gauge")}
    out = None
    for key in list(table):
        if not isinstance(key, str) or not key.endswith("_abs"):
            continue
        twin = pressure_twin(key)
        if twin not in gauge_fields:
            continue
        where = f"{path}.{key}"
        if twin in table:
            raise ScenarioError(where, table[key], f"give either {twin} or {key}, not both")
        meta = gauge_fields[twin]
        raw = table[key]
        x_abs = parse_field(raw, dict(kind="pressure", gt=0.0, display="bar"), where)
        gauge = x_abs - p_atm
        lo, hi = meta.get("ge"), meta.get("le")
        if (lo is not None and gauge < lo) or (hi is not None and gauge > hi):
            raise ScenarioError(where, unwrap(raw), f"must lie between {(lo + p_atm) / 1e5:g} and "
                                                    f"{(hi + p_atm) / 1e5:g} bar abs ({lo / 1e5:g} to "
                                                    f"{hi / 1e5:g} bar gauge at an atmosphere of "
                                                    f"{p_atm / 1e3:g} kPa)")
        check_bounds(gauge, meta, where, Shown(f"{x_abs / 1e5:g} bar abs"))
        if out is None:
            out = dict(table)
        del out[key]
        out[twin] = f"{gauge!r} Pa"
    return table if out is None else out


def scenario_names() -> list[str]:
    """Names of the scenarios shipped with frogsim."""
    return sorted(p.stem for p in SCENARIOS_DIR.glob("*.toml"))


def shipped_scenarios() -> list[tuple[str, str, str]]:
    """(name, command that runs it, one line about it) of every shipped scenario: the command is
    ``swim`` for a robot scenario (it has a [gait]), else ``simulate``; the line is the file's
    ``description``, or else the first sentence of its opening comment."""
    out = []
    for name in scenario_names():
        path = SCENARIOS_DIR / f"{name}.toml"
        text = read_text(path, "scenario")
        raw = tomllib.loads(text)
        about = raw.get("description")
        if not isinstance(about, str) or not about.strip():
            lead = []
            for line in text.splitlines():
                if not line.startswith("#"):
                    break
                lead.append(line.lstrip("#").strip())
            about = re.split(r"(?<=\.)\s+(?=[A-Z])", " ".join(lead), maxsplit=1)[0]
        out.append((name, "swim" if "gait" in raw else "simulate", " ".join(about.split())))
    return out


def scenario_path(source) -> Path:
    """The file of a scenario given as a path or a shipped name; ScenarioError listing the shipped
    scenarios when it is neither."""
    path = Path(source)
    if os.path.lexists(path):
        return path
    if str(source) in scenario_names():
        return SCENARIOS_DIR / f"{source}.toml"
    raise ScenarioError("scenario", str(source), f"no such file, nor a shipped scenario (one of "
                                                 f"{', '.join(scenario_names())}; `frogsim scenarios` "
                                                 "lists them)")


def merged_raw(source) -> tuple[dict, str]:
    """The scenario's raw dict with its parameter set merged in, and its base directory."""
    if isinstance(source, (str, os.PathLike)):
        path = scenario_path(source)
        raw = read_toml(path, "scenario")
        base_dir = str(path.resolve().parent)
    elif isinstance(source, dict):
        check_raw(source, "scenario", Shown("(a dict)"))
        raw = copy.deepcopy(source)
        base_dir = raw.pop("base_dir", ".")
        if not isinstance(base_dir, (str, os.PathLike)):
            raise ScenarioError("base_dir", base_dir, "expected a folder path")
    else:
        raise ScenarioError("scenario", source, "expected a path to a TOML file or a dict")
    for key in raw:
        if key not in RUN_KEYS + PARAM_SECTIONS:
            raise unknown_key_error("", key, RUN_KEYS + PARAM_SECTIONS)
    for key in PARAM_SECTIONS:
        if key in raw and not isinstance(raw[key], dict):
            raise ScenarioError(key, raw[key], "expected a table of settings")
    params_name = raw.get("parameters", "fan2017")
    if not isinstance(params_name, str) or not params_name:
        raise ScenarioError("parameters", params_name, "expected a parameter set name or path")
    params = load_parameter_set(params_name, base_dir)
    if "valves" in raw and "valves" in params and valve_type_of(raw["valves"]) != valve_type_of(params["valves"]):
        # another valve type: its settings are its own, none of the parameter set's valves' apply
        params = {k: v for k, v in params.items() if k != "valves"}
    merged = deep_merge(params, raw)
    merged["parameters"] = params_name
    return merged, base_dir


def with_firmware(source) -> dict:
    """The scenario's merged raw dict (:func:`merged_raw`, its ``base_dir`` kept) with a
    ``[firmware]`` section: the file's own, or every default (as if ``[firmware]`` were written).
    :func:`load_scenario` and :func:`frogsim.load_robot_scenario` take it; this is how a shipped
    scenario without the section (``hip-angle-in-air``) runs and exports as the board runs it."""
    raw, base_dir = merged_raw(source)
    raw.setdefault("firmware", {})
    raw["base_dir"] = base_dir
    return raw


def load_scenario(source) -> Scenario:
    """Load and validate a scenario from a TOML path, a shipped scenario name, or a dict.

    Raises ScenarioError (one line: field, value, what is allowed) on any bad input.
    """
    raw, base_dir = merged_raw(source)
    return scenario_from_raw(raw, base_dir)


def scenario_from_raw(raw: dict, base_dir: str = ".", *, duration: float | None = None,
                      muscles: dict | None = None, joints: dict | None = None) -> Scenario:
    """Validate an already merged raw dict (see :func:`merged_raw`) into a Scenario.

    Every value is parsed from its text once, here; then the cross-field rules run
    (:func:`frogsim.scenario.rules.check`, the same as for every variant). ``duration`` [s] and
    ``muscles`` (name -> :class:`Muscle`) given typed take the place of the file's (the robot
    makes its muscles and programs from its gait). ``joints``: the robot's joints in order, each
    with its (extensor, flexor) muscles (flexor None without one); joint-angle controllers get
    their two muscles from it.
    """
    name = raw.get("name", "scenario")
    if not isinstance(name, str):
        raise ScenarioError("name", name, "expected text")
    if "gait" in raw and not raw.get("muscles") and muscles is None:
        raise ScenarioError("gait", "(a table)", "this is a robot scenario (a gait, no muscles): "
                                                 "run it with `frogsim swim` or frogsim.swim()")
    fields = {f.name: f.metadata for f in dataclasses.fields(Scenario)}
    if duration is None:
        if "duration" not in raw:
            raise ScenarioError("duration", MISSING, "required setting is missing")
        duration = parse_field(raw["duration"], fields["duration"], "duration")
    interval = parse_field(raw.get("output_interval", "1 ms"), fields["output_interval"], "output_interval")
    sections = {}
    for key, cls in (("air", Air), ("source", Chamber), ("exhaust", Chamber), ("pump", Pump),
                     ("valves", Valves), ("supply", Supply)):
        if key not in raw:
            raise ScenarioError(key, MISSING, "required section is missing (parameter set incomplete?)")
        table = raw[key]
        if key in _GAUGE_SECTIONS:      # air is built first: its atmosphere converts *_abs values
            table = gauge_from_abs(table, cls, key, sections["air"].atmospheric_pressure_abs)
        sections[key] = valve_settings(table, key) if key == "valves" else build(cls, table, key)
    controller = build(Controller, raw.get("controller", {}), "controller")
    solver = build(Solver, raw.get("solver", {}), "solver")
    types_raw = raw.get("muscle_types", {})
    if not isinstance(types_raw, dict) or not types_raw:
        raise ScenarioError("muscle_types", types_raw, "expected at least one muscle type")
    # each muscle type's settings class is its actuator type's (frogsim.scenario.actuators)
    muscle_types = {tname: actuator_settings(traw, f"muscle_types.{tname}") for tname, traw in types_raw.items()}
    programs_raw = raw.get("programs", {})
    if not isinstance(programs_raw, dict):
        raise ScenarioError("programs", programs_raw, "expected a table of named programs")
    programs = {p: Program.from_raw(v, f"programs.{p}") for p, v in programs_raw.items()}
    if muscles is None:
        muscles_raw = raw.get("muscles", {})
        if not isinstance(muscles_raw, dict) or not muscles_raw:
            raise ScenarioError("muscles", muscles_raw, "expected at least one muscle, e.g. [muscles.hip]")
        p_atm = sections["air"].atmospheric_pressure_abs
        muscles = {mname: Muscle.from_raw(gauge_from_abs(mraw, Muscle, f"muscles.{mname}", p_atm),
                                          f"muscles.{mname}", programs)
                   for mname, mraw in muscles_raw.items()}
    controllers_raw = raw.get("controllers", {})
    if not isinstance(controllers_raw, dict):
        raise ScenarioError("controllers", controllers_raw, "expected a table of named controllers")
    controllers = {c: _read_tables(ControllerSettings.from_raw(v, f"controllers.{c}"), base_dir, f"controllers.{c}")
                   for c, v in controllers_raw.items()}
    firmware = Firmware.from_raw(raw["firmware"], "firmware") if "firmware" in raw else None
    joints = dict(joints or {})
    for c, ctl in controllers.items():
        if ctl.NAMED == "joint" and ctl.joint in joints:
            ext, flex = joints[ctl.joint]
            controllers[c] = dataclasses.replace(ctl, muscle=ext, antagonist=flex or "")
    scenario = Scenario(name=name, parameters=raw["parameters"], duration=duration,
                        output_interval=interval, controller=controller, solver=solver,
                        muscle_types=muscle_types, muscles=muscles, programs=programs,
                        controllers=controllers, joints=joints, firmware=firmware,
                        base_dir=base_dir, raw=raw, **sections)
    check(scenario)
    return scenario


def _read_tables(ctl, base_dir: str, path: str):
    """The controller with every table setpoint's file read, once, here (:func:`with_table`)."""
    tables = {f.name: with_table(getattr(ctl, f.name), base_dir, f"{path}.{f.name}")
              for f in dataclasses.fields(ctl) if isinstance(getattr(ctl, f.name), Setpoint)}
    return dataclasses.replace(ctl, **tables) if tables else ctl


def with_patch(source, patch_path) -> dict:
    """The scenario ``source`` (a path or shipped name) as a raw dict with ``base_dir``, the
    controllers' settings of the TOML file ``patch_path`` laid over its own, key by key: what
    ``frogsim simulate`` and ``frogsim swim`` run with ``--patch`` (``frogsim tune`` writes such a
    file, ``best.toml``). A patch holds one table, ``[controllers.NAME]``, for controllers the
    scenario has (a patch cannot add one: it would run a controller the scenario never had);
    ScenarioError (naming the key) otherwise. The settings are then checked by the loader as the
    scenario's own."""
    path = scenario_path(source)
    raw = read_toml(path, "scenario")
    patch = read_toml(patch_path, "--patch")
    where = f"--patch {Path(patch_path).name}"
    for key in patch:
        if key != "controllers":
            raise ScenarioError(f"{where}: {key}", "(a table)" if isinstance(patch[key], dict) else patch[key],
                                "a patch sets controllers' settings only: [controllers.NAME] tables")
    ctls = patch.get("controllers", {})
    own = raw.get("controllers", {})
    if not isinstance(ctls, dict) or not isinstance(own, dict):
        raise ScenarioError(f"{where}: controllers", ctls, "expected [controllers.NAME] tables")
    for name, table in ctls.items():
        if name not in own or not isinstance(own[name], dict):
            raise ScenarioError(f"{where}: controllers.{name}", "(a table)",
                                f"must name a controller of the scenario ({', '.join(own) or 'it has none'})")
        if not isinstance(table, dict):
            raise ScenarioError(f"{where}: controllers.{name}", table, "expected a table of settings")
        if "kind" in table and table["kind"] != own[name].get("kind"):
            raise ScenarioError(f"{where}: controllers.{name}.kind", table["kind"],
                                f"a patch keeps the controller's kind ({own[name].get('kind')!r})")
    raw = deep_merge(raw, {"controllers": ctls})
    params = raw.get("parameters")
    base = str(path.resolve().parent)
    if isinstance(params, str) and not os.path.isabs(params) and (Path(base) / params).exists():
        raw["parameters"] = str((Path(base) / params).resolve())
    raw["base_dir"] = base
    return raw


def with_overrides(raw: dict, overrides: dict, share: bool = False) -> dict:
    """A copy of a raw scenario dict with values set by dotted path, e.g. "source.volume".

    A table missing on the path (an optional one the scenario left out, such as ``solver``) is
    created; a misspelt one is then refused by the loader, which names it. With ``share=True`` only
    the tables on each path are copied and the rest is shared with ``raw`` (about 2 ms less per
    call, which matters to sweeps of thousands of points); the caller must then not change the
    result in place.
    """
    out = dict(raw) if share else copy.deepcopy(raw)
    for path, value in overrides.items():
        node = out
        keys = path.split(".")
        for key in keys[:-1]:
            nxt = node.get(key, {})
            if not isinstance(nxt, dict) or ("value" in nxt and set(nxt) <= {"value", "source", "note"}):
                raise ScenarioError(path, value, f"{key!r} is a value, not a table")
            if share or key not in node:
                nxt = dict(nxt)
                node[key] = nxt
            node = nxt
        twin = pressure_twin(keys[-1])
        if twin is not None and twin in node:     # node is a copy here (shared mode too)
            del node[twin]                         # "x_gauge" set: the file's "x_abs" gives way
        node[keys[-1]] = copy.deepcopy(value)
    return out
