"""Load a scenario: a TOML file (or dict) laid over a named parameter set, validated into SI.

A scenario file may hold the run's own settings (name, parameters, duration, output_interval,
controller, solver, programs, muscles) and any section of the parameter set (air, source, exhaust,
pump, valves, supply, muscle_types) to override it, key by key.
"""
from __future__ import annotations

import copy
import os
import tomllib
from pathlib import Path

from frogsim.components.builder import build, parse_field, unknown_key_error
from frogsim.components.schema import (
    Air, Chamber, Controller, Muscle, MuscleType, Program, Pump, Scenario, Solver, Supply, Valves,
)
from frogsim.errors import MISSING, ScenarioError

PARAMS_DIR = Path(__file__).resolve().parent.parent / "params"
SCENARIOS_DIR = Path(__file__).resolve().parent.parent / "scenarios"
PARAM_SECTIONS = ("air", "source", "exhaust", "pump", "valves", "supply", "muscle_types",
                  # the robot as a moving body (frogsim.robot.params)
                  "muscle_force", "body", "legs", "joints", "palms", "water", "hydro")
RUN_KEYS = ("name", "description", "parameters", "duration", "output_interval", "controller",
            "solver", "programs", "muscles",
            # robot scenarios (frogsim.robot.scenario): options and gait instead of muscles
            "robot", "gait")


def read_toml(path: str | os.PathLike, what: str) -> dict:
    """Read a TOML file, turning file and syntax errors into ScenarioError."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ScenarioError(what, str(path), "file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(what, str(path), f"not valid TOML ({exc})") from None


def parameter_set_names() -> list[str]:
    """Names of the parameter sets shipped with frogsim."""
    return sorted(p.stem for p in PARAMS_DIR.glob("*.toml"))


def load_parameter_set(name_or_path: str, base_dir: str = ".") -> dict:
    """The raw dict of a parameter set, by shipped name or by path (relative to base_dir)."""
    if name_or_path in parameter_set_names():
        path = PARAMS_DIR / f"{name_or_path}.toml"
    else:
        path = Path(base_dir) / name_or_path
        if not path.exists():
            raise ScenarioError("parameters", name_or_path,
                                f"must be a shipped parameter set ({', '.join(parameter_set_names())}) "
                                "or a path to a parameter file")
    raw = read_toml(path, "parameters")
    raw.pop("meta", None)
    for key in raw:
        if key not in PARAM_SECTIONS:
            raise unknown_key_error(f"parameters file {path.name}", key, PARAM_SECTIONS)
    return raw


def deep_merge(base: dict, over: dict) -> dict:
    """A copy of base with over laid on top, table by table."""
    out = copy.deepcopy(base)
    for key, val in over.items():
        if isinstance(val, dict) and isinstance(out.get(key), dict) and "value" not in val:
            out[key] = deep_merge(out[key], val)
        else:
            out[key] = copy.deepcopy(val)
    return out


def merged_raw(source) -> tuple[dict, str]:
    """The scenario's raw dict with its parameter set merged in, and its base directory."""
    if isinstance(source, (str, os.PathLike)):
        path = Path(source)
        if not path.exists() and (SCENARIOS_DIR / f"{source}.toml").exists():
            path = SCENARIOS_DIR / f"{source}.toml"
        raw = read_toml(path, "scenario")
        base_dir = str(path.resolve().parent)
    elif isinstance(source, dict):
        raw = copy.deepcopy(source)
        base_dir = raw.pop("base_dir", ".")
    else:
        raise ScenarioError("scenario", source, "expected a path to a TOML file or a dict")
    for key in raw:
        if key not in RUN_KEYS + PARAM_SECTIONS:
            raise unknown_key_error("", key, RUN_KEYS + PARAM_SECTIONS)
    params_name = raw.get("parameters", "fan2017")
    if not isinstance(params_name, str):
        raise ScenarioError("parameters", params_name, "expected a parameter set name or path")
    merged = deep_merge(load_parameter_set(params_name, base_dir), raw)
    merged["parameters"] = params_name
    return merged, base_dir


def load_scenario(source) -> Scenario:
    """Load and validate a scenario from a TOML path, a shipped scenario name, or a dict.

    Raises ScenarioError (one line: field, value, what is allowed) on any bad input.
    """
    raw, base_dir = merged_raw(source)
    return scenario_from_raw(raw, base_dir)


def scenario_from_raw(raw: dict, base_dir: str = ".") -> Scenario:
    """Validate an already merged raw dict (see :func:`merged_raw`) into a Scenario."""
    name = raw.get("name", "scenario")
    if not isinstance(name, str):
        raise ScenarioError("name", name, "expected text")
    if "gait" in raw and not raw.get("muscles"):
        raise ScenarioError("gait", "(a table)", "this is a robot scenario (a gait, no muscles): "
                                                 "run it with `frogsim swim` or frogsim.swim()")
    if "duration" not in raw:
        raise ScenarioError("duration", MISSING, "required setting is missing")
    duration = parse_field(raw["duration"], dict(kind="time", gt=0.0, le=1e6, display="s"), "duration")
    interval = parse_field(raw.get("output_interval", "1 ms"),
                           dict(kind="time", gt=0.0, display="ms"), "output_interval")
    if interval > duration:
        raise ScenarioError("output_interval", raw.get("output_interval"),
                            f"must not exceed the duration ({duration:g} s)")
    if duration / interval > 5_000_000:
        raise ScenarioError("output_interval", raw.get("output_interval"),
                            "too fine for the duration (more than 5 million output rows)")
    sections = {}
    for key, cls in (("air", Air), ("source", Chamber), ("exhaust", Chamber), ("pump", Pump),
                     ("valves", Valves), ("supply", Supply)):
        if key not in raw:
            raise ScenarioError(key, MISSING, "required section is missing (parameter set incomplete?)")
        sections[key] = build(cls, raw[key], key)
    controller = build(Controller, raw.get("controller", {}), "controller")
    solver = build(Solver, raw.get("solver", {}), "solver")
    pump = sections["pump"]
    if pump.on_below_gauge >= pump.off_above_gauge:
        raise ScenarioError("pump.on_below_gauge", raw["pump"].get("on_below_gauge"),
                            "must be below pump.off_above_gauge")
    for vname in ("charge", "discharge"):
        v = getattr(sections["valves"], vname)
        if v.laminar_ratio <= v.critical_ratio:
            raise ScenarioError(f"valves.{vname}.laminar_ratio", v.laminar_ratio,
                                f"must exceed critical_ratio ({v.critical_ratio:g})")
    types_raw = raw.get("muscle_types", {})
    if not isinstance(types_raw, dict) or not types_raw:
        raise ScenarioError("muscle_types", types_raw, "expected at least one muscle type")
    muscle_types = {}
    for tname, traw in types_raw.items():
        mt = build(MuscleType, traw, f"muscle_types.{tname}")
        mt.check(f"muscle_types.{tname}")
        muscle_types[tname] = mt
    programs_raw = raw.get("programs", {})
    if not isinstance(programs_raw, dict):
        raise ScenarioError("programs", programs_raw, "expected a table of named programs")
    programs = {p: Program.from_raw(v, f"programs.{p}") for p, v in programs_raw.items()}
    muscles_raw = raw.get("muscles", {})
    if not isinstance(muscles_raw, dict) or not muscles_raw:
        raise ScenarioError("muscles", muscles_raw, "expected at least one muscle, e.g. [muscles.hip]")
    muscles = {}
    for mname, mraw in muscles_raw.items():
        path = f"muscles.{mname}"
        m = Muscle.from_raw(mraw, path, programs)
        if m.type not in muscle_types:
            raise ScenarioError(f"{path}.type", m.type,
                                f"must name a muscle type ({', '.join(sorted(muscle_types))})")
        mt = muscle_types[m.type]
        if m.motion.contraction is not None and m.motion.contraction > mt.max_contraction:
            raise ScenarioError(f"{path}.motion.contraction", mraw["motion"]["contraction"],
                                f"must be <= the muscle's max_contraction ({mt.max_contraction:.0%})")
        for c in m.motion.contraction_percent:
            if c / 100.0 > mt.max_contraction:
                raise ScenarioError(f"{path}.motion.contraction_percent", c,
                                    f"must be <= the muscle's max_contraction ({mt.max_contraction:.0%})")
        muscles[mname] = m
    # program steps after the end of the run are allowed: they simply never happen
    scenario = Scenario(name=name, parameters=raw["parameters"], duration=duration,
                        output_interval=interval, controller=controller, solver=solver,
                        muscle_types=muscle_types, muscles=muscles, programs=programs,
                        base_dir=base_dir, raw=raw, **sections)
    # motions that read files or depend on programs are checked by building them now
    from frogsim.circuit.model import build_motions
    build_motions(scenario)
    return scenario


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
        node[keys[-1]] = copy.deepcopy(value)
    return out
