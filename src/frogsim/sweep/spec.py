"""Sweep specifications: which base scenario, which parameters over which values, what to record.

A sweep spec is a TOML file (or a dict of the same shape)::

    name = "source-saturation"

    [base]
    scenario = "paper-cycle"            # a shipped scenario, or a path relative to this file
    [base.overrides]                    # optional: dotted path = value, laid over the base
    duration = "1 s"
    "muscles.hip_left.motion" = { kind = "volume_constant", fraction = 0.5 }

    [sweep]
    method = "grid"                     # "grid", "list", "random" or "lhs"
    [sweep.parameters]
    "source.initial_pressure_gauge" = { start = "3 bar", stop = "6 bar", num = 4 }
    "supply.branch_limit" = { values = ["15 L/min", "45 L/min", "180 L/min"] }
    "muscles.hip_left.motion.fraction" = [0.0, 0.5, 1.0]

    [record]
    metrics = ["rise_time", "final_pressure", "aeration_volume"]   # frogsim.sweep.metrics.METRICS
    muscle = "hip_left"
    timeseries = { states = ["muscle_pressure"], interval = "10 ms" }   # optional

    [run]
    chunk_size = 500                    # optional: points per chunk (the unit of resume)

Parameters are addressed by dotted paths (:meth:`frogsim.scenario.core.Scenario.variable_paths`). A parameter is a
list of values (as a scenario file would write them), ``{ values = [...], unit = "bar" }``,
``{ start, stop, num }`` (evenly spaced; ``scale = "log"`` for geometric spacing), or, for the
``random`` and ``lhs`` methods, a range ``{ min, max }`` sampled ``sweep.samples`` times with
``sweep.seed``. ``grid`` takes every combination; ``list`` zips equal-length lists point by point.

Everything is checked here, before any run: unknown paths and keys (with "did you mean"), values
that are not numbers of the right kind, empty ranges, unknown metrics or muscles. Each error is a
one-line :class:`frogsim.ScenarioError` naming the spec field, the value and what is allowed.
:meth:`SweepSpec.validate_points` then validates every point's scenario.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import itertools
import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from frogsim._budget import Need, check as check_size
from frogsim.scenario.fields import parse_field, unknown_key_error, unwrap
from frogsim.errors import MISSING, UNKNOWN, ScenarioError, Shown
from frogsim.scenario.core import Scenario
from frogsim.scenario.load import merged_raw, read_toml, scenario_from_raw, with_overrides
from frogsim.scenario.units import SI_UNITS, display_factor, temperature_scale_offset

METHODS = ("grid", "list", "random", "lhs")
MAX_POINTS = 2_000_000
#: [bytes] memory a sweep holds per point beyond its numbers: the point's tuple of written values,
#: its entry in the spec hash's JSON, and the store's and dataset's flags (an estimate, on the low side)
POINT_OVERHEAD = 150
POINT_BYTES_PER_VALUE = 40       # [bytes] per parameter of a point (SI value, written value, hash text)
_SPEC_KEYS = ("name", "description", "base", "sweep", "record", "run")
_PARAM_KEYS = ("values", "start", "stop", "num", "min", "max", "unit", "scale")
_RANGE_KEYS = ("values", "start", "stop", "num", "min", "max")


# --- what a dotted path is --------------------------------------------------------------------------
@dataclass(frozen=True)
class FieldInfo:
    """How a scenario setting is read: a quantity kind, an integer, a flag or a choice (taken from
    the field's metadata in the schema, :meth:`frogsim.scenario.core.Scenario.variable_paths`)."""
    kind: str                      # a key of frogsim.scenario.units.SI_UNITS, "integer", "flag" or "choice"
    choices: tuple = ()
    meta: dict = dataclasses.field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def of(cls, meta: dict) -> "FieldInfo":
        if meta.get("boolean"):
            return cls("flag", (), meta)
        if "choices" in meta:
            return cls("choice", tuple(meta["choices"]), meta)
        if meta.get("integer"):
            return cls("integer", (), meta)
        return cls(meta["kind"], (), meta)

    @property
    def numeric(self) -> bool:
        return self.kind not in ("flag", "choice")

    @property
    def si_unit(self) -> str:
        if self.kind in SI_UNITS:
            return SI_UNITS[self.kind][0].replace("**", "^")
        return "1" if self.kind == "integer" else ""


def field_info(path: str, base: Scenario) -> FieldInfo:
    """How the setting at a dotted path is read, or ScenarioError if no setting lives there."""
    where = f"sweep.parameters.{path}"
    keys = path.split(".") if isinstance(path, str) else []
    if not all(keys) or not keys:
        raise ScenarioError(where, UNKNOWN, "expected a dotted path such as source.initial_pressure_gauge")
    paths = base.variable_paths()
    if path in paths:
        return FieldInfo.of(paths[path])
    node, here = base, ""
    for key in keys:            # find the first key that names nothing, and say what is there
        if dataclasses.is_dataclass(node):
            names = [f.name for f in dataclasses.fields(node) if f.name not in ("raw", "base_dir")]
            if key not in names:
                err = unknown_key_error(here, key, names)
                raise ScenarioError(where, UNKNOWN, f"no scenario setting at this path: {err.allowed}")
            node = getattr(node, key)
        elif isinstance(node, dict):
            if key not in node:
                raise ScenarioError(where, UNKNOWN, f"the base scenario has no {here}.{key} "
                                                    f"(it has: {', '.join(node) or 'none'})")
            node = node[key]
        else:
            raise ScenarioError(where, UNKNOWN, f"{here} is a value, not a table")
        here = f"{here}.{key}" if here else key
    inside = sorted(p for p in paths if p.startswith(path + "."))
    if inside:
        raise ScenarioError(where, UNKNOWN, f"{path!r} is a table; sweep one of its settings, e.g. {inside[0]}")
    raise ScenarioError(where, UNKNOWN, "not a setting a sweep can vary here (a name, a file, or a setting "
                                        "this scenario does not use)")


# --- values -----------------------------------------------------------------------------------------
def _split_unit(text: str) -> tuple[float, str] | None:
    """("3.5 bar") -> (3.5, "bar"); None if text does not start with a number."""
    m = re.fullmatch(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*", text)
    if not m:
        return None
    return float(m.group(1)), m.group(2)


def _fmt(x: float, digits: int = 12) -> str:
    """A number as it would be written by hand: ``digits`` significant digits, no trailing noise."""
    s = f"{x:.{digits}g}"
    return "0" if s == "-0" else s


@dataclass(frozen=True)
class Parameter:
    """One swept setting: its dotted path, how it is read, and its values (grid and list) or range.

    ``written`` are the values as they go into the scenario (text with units, numbers, choices);
    ``si`` the same values in SI (``info.si_unit``; NaN for choices and flags).
    ``display_unit``/``display_factor``: the unit the values were written in and its size in SI,
    when all share one (plots use it).
    """
    path: str
    info: FieldInfo
    written: tuple
    si: tuple
    display_unit: str = ""
    display_factor: float = 1.0
    range: dict | None = None        # random/lhs: {"min": SI, "max": SI, "unit": str, "scale": str}


def _to_si(value, info: FieldInfo, where: str) -> float:
    """SI float of one value as written (NaN for a choice or flag), or ScenarioError naming the
    spec field. The scenario loader's own parser (:func:`frogsim.scenario.fields.parse_field`);
    bounds are left to the variant (``scenario.replace``), which names the point."""
    meta = {k: v for k, v in info.meta.items() if k not in ("gt", "ge", "lt", "le")}
    x = parse_field(value, meta, where)
    return math.nan if info.kind in ("flag", "choice") else float(x)


def _with_unit(x, unit: str | None, info: FieldInfo, where: str):
    """A number given with a separate unit = "bar" -> the text "3 bar"."""
    if unit is None:
        return x
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise ScenarioError(where, x, f"expected a number (the unit {unit!r} is given separately)")
    return f"{_fmt(float(x))} {unit}" if unit else float(x)


def _unit_of(value) -> str | None:
    if isinstance(value, str):
        split = _split_unit(value)
        return split[1] if split else None
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return ""
    return None


def _offset_unit(unit: str, info: FieldInfo) -> bool:
    """A temperature unit with an offset (degC, degF): its values are not multiples of one size,
    so ranges and plot axes over it are made in K."""
    return info.kind == "temperature" and bool(unit) and temperature_scale_offset(unit)[1] != 0.0


def _range_value(text, unit, info: FieldInfo, where: str) -> tuple[float, str]:
    """A range end as (number in its written unit, that unit); checks it is the right kind. A
    temperature in degC or degF is given in K (a range of offset units is made in K)."""
    value = _with_unit(text, unit, info, where)
    si = _to_si(value, info, where)
    if isinstance(value, (int, float)):
        return float(value), ""
    split = _split_unit(value)
    if split is not None and _offset_unit(split[1], info):
        return si, "K"
    split = _split_unit(value)
    if split is None:
        raise ScenarioError(where, text, "expected a number followed by its unit, such as \"3 bar\"")
    return split


def _generated(mags, unit: str, info: FieldInfo, where: str, digits: int = 12) -> tuple[tuple, tuple]:
    """Values generated in a written unit -> (labels with ``digits`` significant digits, SI).

    The values run are the labels' numbers (rounded to ``digits``) times the unit's size, so a
    label means exactly the value run; no label is parsed back.
    """
    if info.kind == "integer":
        if any(abs(m - round(m)) > 1e-9 for m in mags):
            raise ScenarioError(where, [_fmt(m) for m in mags], "must be whole numbers for this setting")
        written = tuple(int(round(m)) for m in mags)
        return written, tuple(float(w) for w in written)
    rounded = [float(_fmt(m, digits)) for m in mags]
    factor = display_factor(unit, info.kind) if unit else 1.0
    si = tuple(r * factor for r in rounded)
    for w, x in zip(rounded, si):
        _check_si(x, info, where, w)
    written = tuple(f"{_fmt(r, digits)} {unit}" for r in rounded) if unit else tuple(rounded)
    return written, si


def _check_si(x: float, info: FieldInfo, where: str, shown) -> None:
    if not math.isfinite(x):
        raise ScenarioError(where, shown, "must be a finite number")


def _typed(info: FieldInfo, written, si: float):
    """The value a variant takes: SI float, whole number, choice or flag."""
    if not info.numeric:
        return written
    return int(si) if info.kind == "integer" else si


def _display(written: tuple, si: tuple, info: FieldInfo) -> tuple[str, float]:
    if not info.numeric or info.kind == "integer":
        return "", 1.0
    units = {_unit_of(w) for w in written}
    if len(units) == 1:
        unit = units.pop()
        if unit and not _offset_unit(unit, info):
            return unit, display_factor(unit, info.kind)
    return info.si_unit, 1.0


def _parameter(path: str, raw, method: str, base: Scenario) -> Parameter:
    where = f"sweep.parameters.{path}"
    info = field_info(path, base)
    if isinstance(raw, list):
        raw = {"values": raw}
    if not isinstance(raw, dict):
        raise ScenarioError(where, raw, "expected a list of values, { values = [...] }, "
                                        "{ start, stop, num } or { min, max }")
    for key in raw:
        if key not in _PARAM_KEYS:
            raise unknown_key_error(where, key, _PARAM_KEYS)
    unit = raw.get("unit")
    if unit is not None:
        if not isinstance(unit, str):
            raise ScenarioError(f"{where}.unit", unit, "expected a unit as text, such as \"bar\"")
        if not info.numeric or info.kind == "integer":
            raise ScenarioError(f"{where}.unit", unit, f"this setting takes no unit ({info.kind})")
        try:
            display_factor(unit, info.kind)
        except Exception:
            raise ScenarioError(f"{where}.unit", unit, f"expected a unit of {SI_UNITS[info.kind][1]}") from None
    scale = raw.get("scale", "linear")
    if scale not in ("linear", "log"):
        raise ScenarioError(f"{where}.scale", scale, "must be 'linear' or 'log'")
    given = [k for k in _RANGE_KEYS if k in raw]
    sampled = method in ("random", "lhs")
    if sampled:
        if set(given) != {"min", "max"}:
            raise ScenarioError(where, {k: raw[k] for k in given} or raw,
                                f"method {method!r} takes a range {{ min = ..., max = ... }}")
        if not info.numeric:
            raise ScenarioError(where, UNKNOWN, f"a {info.kind} setting cannot be sampled over a range; "
                                                "use method = \"grid\" or \"list\" with values")
        lo, lo_unit = _range_value(raw["min"], unit, info, f"{where}.min")
        hi_text = _with_unit(raw["max"], unit, info, f"{where}.max")
        hi_si = _to_si(hi_text, info, f"{where}.max")
        factor = display_factor(lo_unit, info.kind) if lo_unit else 1.0
        hi = hi_si / factor
        if not hi > lo:
            raise ScenarioError(f"{where}.max", raw["max"], f"must be above min ({raw['min']!r}): the range is empty")
        if scale == "log" and lo <= 0:
            raise ScenarioError(f"{where}.min", raw["min"], "must be > 0 for scale = \"log\"")
        if info.kind == "integer" and (lo != int(lo) or hi != int(hi)):
            raise ScenarioError(where, raw, "min and max must be whole numbers for this setting")
        return Parameter(path, info, (), (), lo_unit or ("" if info.kind == "integer" else info.si_unit), factor,
                         {"min": lo, "max": hi, "unit": lo_unit, "scale": scale})
    if "values" in raw:
        if set(given) != {"values"}:
            extra = sorted(set(given) - {"values"})[0]
            raise ScenarioError(f"{where}.{extra}", raw[extra], "give either values or start/stop/num, not both")
        values = raw["values"]
        if not isinstance(values, list) or not values:
            raise ScenarioError(f"{where}.values", values, "expected a non-empty list of values")
        written = []
        for j, v in enumerate(values):
            v = unwrap(v)
            if isinstance(v, (dict, list)):
                raise ScenarioError(f"{where}.values[{j}]", v, "expected a single value, not a table or list")
            written.append(_with_unit(v, unit, info, f"{where}.values[{j}]"))
        si = tuple(_to_si(w, info, f"{where}.values[{j}]") for j, w in enumerate(written))
        if len({json.dumps(w) for w in written}) < len(written) and method == "grid":
            raise ScenarioError(f"{where}.values", values, "values repeat; a grid takes each value once")
        written = tuple(written)
    elif set(given) == {"start", "stop", "num"}:
        if not info.numeric:
            raise ScenarioError(where, UNKNOWN, f"a {info.kind} setting takes a list of values, not a range")
        num = raw["num"]
        if isinstance(num, bool) or not isinstance(num, int) or num < 1:
            raise ScenarioError(f"{where}.num", num, "expected a whole number >= 1")
        a, a_unit = _range_value(raw["start"], unit, info, f"{where}.start")
        b_text = _with_unit(raw["stop"], unit, info, f"{where}.stop")
        factor = display_factor(a_unit, info.kind) if a_unit else 1.0
        b = _to_si(b_text, info, f"{where}.stop") / factor
        if num > 1 and a == b:
            raise ScenarioError(f"{where}.stop", raw["stop"], "equals start: the range is empty (or use num = 1)")
        if scale == "log":
            if a <= 0 or b <= 0:
                raise ScenarioError(f"{where}.start", raw["start"], "start and stop must be > 0 for scale = \"log\"")
            mags = np.geomspace(a, b, num)
        else:
            mags = np.linspace(a, b, num)
        written, si = _generated(mags, a_unit, info, where, digits=6)     # readable: "28.7091 L/min"
        if len(set(written)) < len(written):
            written, si = _generated(mags, a_unit, info, where)
        if len(set(written)) < len(written):
            raise ScenarioError(where, raw, "the range gives repeated values once written with 12 digits")
    else:
        raise ScenarioError(where, raw, "expected values = [...], or start, stop and num")
    unit_d, factor = _display(written, si, info)
    return Parameter(path, info, written, si, unit_d, factor)


def _flatten_parameters(node: dict, prefix: str = "") -> dict:
    """{"source": {"volume": [...]}} or {"source.volume": [...]} -> {"source.volume": [...]}."""
    out = {}
    for key, val in node.items():
        path = f"{prefix}.{key}" if prefix else key
        if isinstance(val, dict) and not (set(val) & set(_PARAM_KEYS)) and val:
            out.update(_flatten_parameters(val, path))
        else:
            out[path] = val
    return out


def _apply_overrides(raw: dict, overrides: dict, prefix: str = "") -> dict:
    """Base overrides: a key with a dot is a path whose value replaces what is there; a plain
    key holding a table descends into it (so unquoted dotted TOML keys merge key by key)."""
    for key, val in overrides.items():
        path = f"{prefix}.{key}" if prefix else key
        if "." not in key and isinstance(val, dict) and val and "value" not in val and \
                isinstance(_get(raw, path), dict):
            raw = _apply_overrides(raw, val, path)
        else:
            raw = with_overrides(raw, {path: val})
    return raw


def _get(raw: dict, path: str):
    node = raw
    for key in path.split("."):
        if not isinstance(node, dict) or key not in node:
            return None
        node = node[key]
    return node


# --- the files a scenario reads (part of a sweep's identity, and of a run's manifest) ----------------
def input_files(scenario: Scenario, source=None) -> list[tuple[str, Path]]:
    """(role, path) of every file a loaded scenario was read from or reads when it runs: the
    scenario file (``source``: a path or a shipped name; none for a dict), its parameter set,
    each muscle's joint-angle table and each controller's setpoint table (with the SHA-256 of
    the content the loader read, as a third item)."""
    from frogsim.scenario.load import PARAMS_DIR, SCENARIOS_DIR, parameter_set_names
    out = []
    if isinstance(source, (str, os.PathLike)):
        path = Path(source)
        if not path.exists() and (SCENARIOS_DIR / f"{source}.toml").exists():
            path = SCENARIOS_DIR / f"{source}.toml"
        out.append(("scenario", path))
    params = scenario.raw.get("parameters", "fan2017") if isinstance(scenario.raw, dict) else "fan2017"
    if isinstance(params, str):
        path = PARAMS_DIR / f"{params}.toml" if params in parameter_set_names() else Path(scenario.base_dir) / params
        out.append(("parameters", path))
    for name, m in getattr(scenario, "muscles", {}).items():
        if getattr(m.motion, "kind", None) == "joint_angles" and m.motion.file:
            out.append((f"muscles.{name}.motion.file", Path(scenario.base_dir) / m.motion.file))
    for name, c in getattr(scenario, "controllers", {}).items():
        for f in dataclasses.fields(c):
            sp = getattr(c, f.name)
            if getattr(sp, "digest", ""):       # a table setpoint: read, and hashed, by the loader
                out.append((f"controllers.{name}.{f.name}.file", Path(scenario.base_dir) / sp.file, sp.digest))
    return out


def file_sha256(path) -> str | None:
    """SHA-256 (hex) of a file's bytes; None if it cannot be read."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return None
    return h.hexdigest()


def describe_inputs(files) -> list[dict]:
    """[{"role", "path", "sha256"}] of (role, path) pairs (paths made absolute; a third item is
    the content's SHA-256 when it is known, else the file is hashed here)."""
    return [{"role": f[0], "path": str(Path(f[1]).resolve()), "sha256": f[2] if len(f) > 2 else file_sha256(f[1])}
            for f in files]


def inputs_sha256(inputs) -> str:
    """One SHA-256 over the roles and contents of described inputs (not where they lie)."""
    blob = json.dumps([[f["role"], f["sha256"]] for f in inputs]).encode()
    return hashlib.sha256(blob).hexdigest()


def changed_inputs(before, now) -> list[str]:
    """Descriptions ("parameters file /x/fan2017.toml") of inputs whose content differs (or that
    appeared or went away) between two lists of described inputs."""
    old = {f["role"]: f for f in before or ()}
    new = {f["role"]: f for f in now or ()}
    out = []
    for role in list(old) + [r for r in new if r not in old]:
        a, b = old.get(role), new.get(role)
        if a is None or b is None or a.get("sha256") != b.get("sha256"):
            path = (b or a).get("path", "?")
            out.append(f"{role} file {path}")
    return out


# --- the spec ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TimeSeries:
    """Time series to store per point: state names (see :data:`frogsim.sweep.metrics.STATES`), every
    ``step`` output samples of the base scenario (``interval`` [s])."""
    states: tuple
    interval: float
    step: int
    times: tuple


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep: the base scenario (merged raw dict), the parameters, the points, what to
    record. Build it with :func:`load_spec`."""
    name: str
    description: str
    method: str
    base: str                        # the base as given (shipped name or path)
    base_raw: dict                   # merged raw scenario, overrides applied (as in the files)
    base_dir: str
    scenario: Scenario               # the base scenario, typed; every point is a variant of it
    parameters: tuple                # Parameter, in the spec's order
    written: tuple                   # per point: tuple of values as written (one per parameter)
    si: np.ndarray                   # (points, parameters) SI values (NaN for choices)
    metrics: tuple
    muscle: str
    timeseries: TimeSeries | None
    chunk_size: int
    samples: int | None = None
    seed: int | None = None
    text: str = ""                   # the spec file as written ("" for a dict)
    raw: dict = dataclasses.field(default_factory=dict, repr=False)
    inputs: tuple = ()               # every file the base scenario reads: {role, path, sha256}

    @property
    def paths(self) -> list[str]:
        return [p.path for p in self.parameters]

    @property
    def shape(self) -> tuple:
        """Grid: one length per parameter; otherwise (points,)."""
        if self.method == "grid":
            return tuple(len(p.written) for p in self.parameters)
        return (len(self.written),)

    @property
    def dims(self) -> tuple:
        return tuple(self.paths) if self.method == "grid" else ("point",)

    @property
    def n_points(self) -> int:
        return len(self.written)

    def point(self, k: int) -> dict:
        """Point k (flat index, C order for a grid) as a variant: dotted path -> SI value (or the
        choice / flag / whole number), ready for ``scenario.replace``."""
        row = self.si[k]
        return {p.path: _typed(p.info, w, float(x)) for p, w, x in zip(self.parameters, self.written[k], row)}

    @property
    def notes(self) -> list[str]:
        """Things a designer should know before reading this sweep's numbers (one line each)."""
        out = []
        valve_paths = [p for p in self.paths if p.startswith("valves.charge.")]
        if valve_paths and "supply.mode" not in self.paths and self.scenario.supply.mode == "paper":
            from frogsim.circuit.model import branch_limit_standard
            limit = branch_limit_standard(self.scenario.supply) * 60e3
            out.append(f"supply.mode = 'paper' caps every branch at {limit:.3g} L/min (Eq. 9): "
                       f"{', '.join(valve_paths)} matter only where the valve passes less than that; "
                       "sweep supply.mode or set supply.mode = 'none' or 'physical' to see the valve alone")
        return out

    def need(self, out=None) -> Need:
        """What running this sweep would take (memory; with ``out``, disk): see :func:`point_need`."""
        n_ts = len(self.timeseries.states) * len(self.timeseries.times) if self.timeseries else 0
        return point_need(self.n_points, len(self.parameters), len(self.metrics) + n_ts, out)

    def variant(self, k: int) -> Scenario:
        """The scenario of point k (validated)."""
        return self.scenario.replace(self.point(k))

    def points(self, indices=None) -> list[dict]:
        idx = range(self.n_points) if indices is None else indices
        return [self.point(int(k)) for k in idx]

    def chunks(self) -> list[np.ndarray]:
        """The fixed chunk plan (flat point indices); it depends on the spec only, so a resumed or
        distributed run groups points exactly as an uninterrupted local one."""
        n = self.n_points
        return [np.arange(a, min(a + self.chunk_size, n)) for a in range(0, n, self.chunk_size)]

    @functools.cached_property
    def hash(self) -> str:
        """SHA-256 of what determines the results: base scenario, the content of every file it
        reads (:attr:`inputs`: scenario file, parameter set, joint-angle tables; content only, not
        where they lie), points, metrics, muscle, time series, chunk plan (not the name,
        description or comments of the spec)."""
        key = {"base": self.base_raw, "method": self.method,
               "inputs": [[f["role"], f["sha256"]] for f in self.inputs],
               "paths": self.paths, "points": [list(w) for w in self.written],
               "si": [[repr(float(x)) for x in row] for row in self.si],
               "metrics": list(self.metrics), "muscle": self.muscle,
               "timeseries": None if self.timeseries is None else
               [list(self.timeseries.states), self.timeseries.step], "chunk_size": self.chunk_size}
        blob = json.dumps(key, sort_keys=True, default=str).encode()
        return hashlib.sha256(blob).hexdigest()

    def base_toml(self) -> str:
        """The merged base scenario (parameter set + scenario + overrides) as TOML text."""
        return dumps_toml({k: v for k, v in self.base_raw.items()})

    def validate_points(self) -> int:
        """Validate every point's scenario (raises ScenarioError naming the point, before anything
        runs); returns the number of scenarios checked. Each point is made as the run makes it,
        ``scenario.replace(point)``: the same field bounds and cross-field rules as the loader."""
        for k in range(self.n_points):
            try:
                self.variant(k)
            except ScenarioError as exc:
                shown = _show(dict(zip(self.paths, self.written[k])))
                raise ScenarioError(exc.field, exc.value, f"{exc.allowed} (in sweep point {k}: {shown})") from None
        return self.n_points


def _show(overrides: dict) -> str:
    return ", ".join(f"{k} = {v!r}" for k, v in overrides.items()) or "the base scenario"


def _sample(method: str, n: int, seed: int, params: list[Parameter]) -> np.ndarray:
    """(n, d) numbers in [0, 1): Latin hypercube (one sample per stratum in every dimension) or
    independent uniform."""
    d = len(params)
    if method == "lhs":
        from scipy.stats import qmc
        return qmc.LatinHypercube(d=d, rng=seed).random(n)
    return np.random.default_rng(seed).random((n, d))


def _sampled_values(p: Parameter, u: np.ndarray, where: str) -> tuple[tuple, tuple]:
    r = p.range
    lo, hi = r["min"], r["max"]
    if p.info.kind == "integer":
        mags = np.minimum(np.floor(lo + u * (hi - lo + 1.0)), hi)
    elif r["scale"] == "log":
        mags = np.exp(np.log(lo) + u * (np.log(hi) - np.log(lo)))
    else:
        mags = lo + u * (hi - lo)
    written, si = _generated(mags, r["unit"], p.info, where)
    return written, si


def _check_keys(node, allowed, where):
    if not isinstance(node, dict):
        raise ScenarioError(where, node, "expected a table")
    for key in node:
        if key not in allowed:
            raise unknown_key_error(where, key, allowed)


def load_spec(source, base_dir: str | os.PathLike | None = None) -> SweepSpec:
    """Read and validate a sweep spec from a TOML path or a dict (see the module docstring).

    A dict's relative base scenario path is resolved against ``base_dir`` (default: the current
    folder). Raises ScenarioError (field, value, what is allowed) on anything wrong. Does not
    validate the points' scenarios: :meth:`SweepSpec.validate_points` does (run_sweep calls it).
    """
    from frogsim.sweep.metrics import METRICS
    text = ""
    if isinstance(source, SweepSpec):
        return source
    if isinstance(source, (str, os.PathLike)):
        path = Path(source)
        if path.is_dir():
            raise ScenarioError("spec", str(source), "is a folder, expected a sweep spec TOML file")
        raw = read_toml(path, "spec")
        text = path.read_text()
        spec_dir = path.resolve().parent
    elif isinstance(source, dict):
        raw = json.loads(json.dumps(source))
        spec_dir = Path(base_dir or ".").resolve()
    else:
        raise ScenarioError("spec", source, "expected a path to a sweep spec TOML file or a dict")
    _check_keys(raw, _SPEC_KEYS, "")
    name = raw.get("name", Path(source).stem if isinstance(source, (str, os.PathLike)) else "sweep")
    description = raw.get("description", "")
    for key, val in (("name", name), ("description", description)):
        if not isinstance(val, str):
            raise ScenarioError(key, val, "expected text")

    # base scenario
    base = raw.get("base", MISSING)
    if base is MISSING:
        raise ScenarioError("base", MISSING, "required: a shipped scenario name (paper-cycle) or a path, "
                                             "or a table { scenario = ..., overrides = { ... } }")
    if isinstance(base, str):
        base = {"scenario": base}
    _check_keys(base, ("scenario", "overrides"), "base")
    if not isinstance(base.get("scenario"), str):
        raise ScenarioError("base.scenario", base.get("scenario", MISSING),
                            "required: a shipped scenario name (paper-cycle) or a path to a scenario file")
    base_name = base["scenario"]
    from frogsim.scenario.load import SCENARIOS_DIR
    candidate = spec_dir / base_name
    if candidate.is_file():
        where = candidate
    elif (SCENARIOS_DIR / f"{base_name}.toml").exists() and "/" not in base_name and not base_name.endswith(".toml"):
        where = SCENARIOS_DIR / f"{base_name}.toml"
    else:
        shipped = ", ".join(sorted(p.stem for p in SCENARIOS_DIR.glob("*.toml")))
        raise ScenarioError("base.scenario", base_name, f"must be a scenario file (relative to the spec: "
                                                        f"{spec_dir}) or a shipped scenario ({shipped})")
    base_raw, scen_dir = merged_raw(where)
    overrides = base.get("overrides", {})
    if not isinstance(overrides, dict):
        raise ScenarioError("base.overrides", overrides, "expected a table of dotted path = value")
    try:
        base_raw = _apply_overrides(base_raw, overrides)
        scenario = scenario_from_raw(base_raw, scen_dir)
    except ScenarioError as exc:
        raise ScenarioError(exc.field, exc.value, f"{exc.allowed} (in the base scenario)") from None
    base_raw = json.loads(json.dumps(base_raw))
    inputs = tuple(describe_inputs(input_files(scenario, where)))

    # parameters and points
    sweep = raw.get("sweep", MISSING)
    if sweep is MISSING:
        raise ScenarioError("sweep", MISSING, "required: [sweep] with method and parameters")
    _check_keys(sweep, ("method", "parameters", "samples", "seed"), "sweep")
    method = sweep.get("method", "grid")
    if method not in METHODS:
        raise ScenarioError("sweep.method", method, f"must be one of {', '.join(map(repr, METHODS))}")
    params_raw = sweep.get("parameters", MISSING)
    if not isinstance(params_raw, dict) or not params_raw:
        raise ScenarioError("sweep.parameters", params_raw,
                            "expected a table of at least one dotted path = values or range")
    flat = _flatten_parameters(params_raw)
    paths = list(flat)
    for a, b in itertools.permutations(paths, 2):
        if b.startswith(a + "."):
            raise ScenarioError(f"sweep.parameters.{b}", UNKNOWN, f"lies inside another swept setting ({a})")
    _check_point_count(flat, method, sweep, raw.get("record", {}))     # before any value is made
    params = [_parameter(p, v, method, scenario) for p, v in flat.items()]
    samples = seed = None
    if method in ("random", "lhs"):
        samples = sweep.get("samples", MISSING)
        if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
            raise ScenarioError("sweep.samples", samples, f"method {method!r} needs a whole number of samples >= 1")
        seed = sweep.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ScenarioError("sweep.seed", seed, "expected a whole number >= 0")
        u = _sample(method, samples, seed, params)
        filled = []
        for j, p in enumerate(params):
            w, s = _sampled_values(p, u[:, j], f"sweep.parameters.{p.path}")
            filled.append(dataclasses.replace(p, written=w, si=s))
        params = filled
        written = list(zip(*(p.written for p in params)))
    else:
        for key in ("samples", "seed"):
            if key in sweep:
                raise ScenarioError(f"sweep.{key}", sweep[key], f"only for method 'random' or 'lhs', not {method!r}")
        if method == "list":
            lengths = {p.path: len(p.written) for p in params}
            if len(set(lengths.values())) > 1:
                first = params[0]
                odd = next(p for p in params if len(p.written) != len(first.written))
                raise ScenarioError(f"sweep.parameters.{odd.path}", f"{len(odd.written)} value(s)",
                                    f"method 'list' zips parameters point by point: must have as many "
                                    f"values as {first.path} ({len(first.written)})")
            written = list(zip(*(p.written for p in params)))
        else:
            written = list(itertools.product(*(p.written for p in params)))
    if method == "grid":
        si = np.array(list(itertools.product(*(p.si for p in params))), float).reshape(len(written), len(params))
    else:
        si = np.array([p.si for p in params], float).T.reshape(len(written), len(params))

    # what to record
    record = raw.get("record", {})
    _check_keys(record, ("metrics", "muscle", "timeseries"), "record")
    metrics = record.get("metrics", list(METRICS))
    if isinstance(metrics, str):
        metrics = [metrics]
    if not isinstance(metrics, list) or not metrics:
        raise ScenarioError("record.metrics", metrics, f"expected a list of metric names ({', '.join(METRICS)})")
    for m in metrics:
        if m not in METRICS:
            raise ScenarioError("record.metrics", m, f"must be one of {', '.join(METRICS)}")
    if len(set(metrics)) < len(metrics):
        raise ScenarioError("record.metrics", metrics, "names a metric twice")
    muscles = list(scenario.muscles)
    muscle = record.get("muscle", muscles[0])
    if muscle not in muscles:
        raise ScenarioError("record.muscle", muscle, f"must name a muscle of the base scenario ({', '.join(muscles)})")
    timeseries = _timeseries(record.get("timeseries"), scenario, params, metrics)

    run = raw.get("run", {})
    _check_keys(run, ("chunk_size",), "run")
    n = len(written)
    chunk_size = run.get("chunk_size", min(2000, max(64, math.ceil(n / 10))))
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
        raise ScenarioError("run.chunk_size", chunk_size, "expected a whole number >= 1")
    return SweepSpec(name=name, description=description, method=method, base=base_name, base_raw=base_raw,
                     base_dir=scen_dir, scenario=scenario, parameters=tuple(params), written=tuple(written), si=si,
                     metrics=tuple(metrics), muscle=muscle, timeseries=timeseries,
                     chunk_size=chunk_size, samples=samples, seed=seed, text=text, raw=raw, inputs=inputs)


def point_need(n: int, n_params: int, n_values: int, out=None) -> Need:
    """What a sweep of ``n`` points would take: memory for its point table and results
    (``n_values`` numbers per point: metrics and time-series samples, held twice: the store and
    the dataset) and, with ``out``, disk for the results file and its journal (each value
    written twice)."""
    per_point = POINT_OVERHEAD + POINT_BYTES_PER_VALUE * n_params + 16 * n_values
    disk = n * (8 * n_params + 8 * n_values + 2) * 2 if out is not None else 0.0
    return Need(f"a sweep of {n:,} points", n, "points", MAX_POINTS, memory=float(n) * per_point,
                disk=disk, disk_path=out)


def _check_point_count(flat: dict, method: str, sweep: dict, record) -> None:
    """The number of points the spec asks for, from the lengths and ``num`` of its parameters
    (grid: their product) or ``samples``, refused by :func:`frogsim._budget.check` with the memory
    it would need before any parameter's values are made."""
    counts = {}
    for path, raw in flat.items():
        if isinstance(raw, dict) and "num" in raw:
            num = raw["num"]
            if isinstance(num, bool) or not isinstance(num, int) or num < 1:
                raise ScenarioError(f"sweep.parameters.{path}.num", num, "expected a whole number >= 1")
            counts[f"sweep.parameters.{path}.num"] = num
        elif isinstance(raw, (list, dict)):
            values = raw if isinstance(raw, list) else raw.get("values", [])
            counts[f"sweep.parameters.{path}"] = len(values) if isinstance(values, list) else 1
    samples = sweep.get("samples")
    if method in ("random", "lhs") and isinstance(samples, int) and not isinstance(samples, bool):
        field, n = "sweep.samples", samples
    elif method == "grid":
        n = math.prod(counts.values())
        field = next(iter(counts)) if len(counts) == 1 else "sweep.parameters"
    else:
        field, n = max(counts.items(), key=lambda kv: kv[1], default=("sweep.parameters", 0))
    metrics = record.get("metrics") if isinstance(record, dict) else None
    from frogsim.sweep.metrics import METRICS
    n_metrics = len(metrics) if isinstance(metrics, list) else 1 if isinstance(metrics, str) else len(METRICS)
    shown = flat[field[17:-4]]["num"] if field.endswith(".num") else n if field == "sweep.samples" \
        else Shown(f"{n} points")
    check_size(field, shown, point_need(n, len(flat), n_metrics))


def _timeseries(ts, scenario, params, metrics) -> TimeSeries | None:
    from frogsim.sweep.metrics import STATES
    if ts is None:
        return None
    where = "record.timeseries"
    _check_keys(ts, ("states", "interval"), where)
    states = ts.get("states", MISSING)
    if isinstance(states, str):
        states = [states]
    if not isinstance(states, list) or not states:
        raise ScenarioError(f"{where}.states", states, f"expected a list of state names ({', '.join(STATES)})")
    for s in states:
        if s not in STATES:
            raise ScenarioError(f"{where}.states", s, f"must be one of {', '.join(STATES)}")
        if s in metrics:
            raise ScenarioError(f"{where}.states", s, "is also recorded as a metric")
    for p in params:
        if p.path in ("duration", "output_interval"):
            raise ScenarioError(f"{where}", UNKNOWN, f"time series need one time grid: not available "
                                                     f"when {p.path} is swept")
    oi = scenario.output_interval
    interval = oi if "interval" not in ts else parse_field(ts["interval"], dict(kind="time", gt=0.0, display="ms"),
                                                            f"{where}.interval")
    step = round(interval / oi)
    if step < 1 or abs(step * oi - interval) > 1e-9 * interval:
        raise ScenarioError(f"{where}.interval", ts.get("interval"),
                            f"must be a whole multiple of the base scenario's output_interval ({oi * 1e3:g} ms)")
    from frogsim.scenario.motion import output_times
    t = output_times(scenario.duration, oi)[::step]
    return TimeSeries(tuple(states), interval, step, tuple(float(x) for x in t))


# --- TOML text (the base scenario is stored in the results file) ------------------------------------
_BARE = re.compile(r"[A-Za-z0-9_-]+")


def _toml_key(k: str) -> str:
    return k if _BARE.fullmatch(k) else json.dumps(k, ensure_ascii=False)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def dumps_toml(data: dict) -> str:
    """TOML text of a dict of tables, text, numbers, booleans and lists ({value = ...} tables
    inline). ``tomllib.loads(dumps_toml(d)) == d``."""
    lines: list[str] = []

    def table(prefix: str, node: dict):
        leaves = [(k, v) for k, v in node.items() if not (isinstance(v, dict) and "value" not in v)]
        subs = [(k, v) for k, v in node.items() if isinstance(v, dict) and "value" not in v]
        if prefix and (leaves or not subs):
            lines.append(f"\n[{prefix}]")
        for k, v in leaves:
            lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
        for k, v in subs:
            table(f"{prefix}.{_toml_key(k)}" if prefix else _toml_key(k), v)

    table("", data)
    return "\n".join(lines).lstrip("\n") + "\n"
