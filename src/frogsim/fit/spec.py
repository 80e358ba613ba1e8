"""A fit spec (FIT.toml): base scenario, experiments (traces), parameters to fit, noise, options.

::

    scenario = "rig.toml"              # base scenario: a path (relative to this file) or shipped name
    starts = 4                         # least-squares starts: the given start + the best screened points
    global_points = 20                 # the global stage: Latin-hypercube points screened (default 10 a parameter)
    seed = 1                           # seed of the Latin hypercube
    noise = "0.02 bar"                 # standard deviation of every pressure signal's noise

    [[experiments]]
    name = "6 bar"                     # optional; default: the trace's file name
    trace = "trace-6bar.csv"           # relative to this file
    ignore_columns = ["hip_left angle [deg]"]
    commands = "commands.csv"          # optional: replay a board's valve commands (frogsim.fit.replay)
    command_delay = ["0.22 ms", "0.12 ms"]   # with commands: a sample to its valve write on the board
                                       # (sample 0's, the later samples'; one time: both)
    overrides = { "source.initial_pressure_gauge" = "6 bar" }   # written with units

    [parameters]
    "valves.charge.sonic_conductance" = { min = "0.1 L/(s*bar)", max = "1 L/(s*bar)", start = "0.4 L/(s*bar)" }
    "muscle_types.hip.dead_volume" = { min = "1 cm^3", max = "30 cm^3" }   # start: the base value

    [signals."hip_left pressure"]      # optional, per signal
    noise = "0.03 bar"
    weight = 1.0

    [signals."source temperature"]     # a temperature is fitted only with a noise of its own
    noise = "1 K"                      # a difference: K or mK (delta_degC), never degC

    [[force_tables]]                   # optional: fit the muscle force law (docs/fitting.md)
    table = "dmsp20.csv"               # pressure [bar gauge], contraction [%], force [N]
    muscle = "hip"                     # the muscle type whose braid the table was measured on
    noise = "50 N"                     # each row's noise: max(noise, relative_noise x |force|)
    relative_noise = 0.1

``experiments`` and ``force_tables`` may each be left out, not both. Force-law constants are fitted
as ``muscle_force.<name>`` (force_scale, strain_scale, stiffness, stretch_stiffness,
stretch_quadratic).

Everything is read and checked here, traces included, before anything runs or is written: every
refusal is a one-line :class:`frogsim.ScenarioError` naming the file and the field.
"""
from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path

from frogsim.errors import MISSING, UNKNOWN, ScenarioError
import numpy as np

from frogsim.fit.force import PREFIX, ForceModel, ForceTable, base_law, law_meta, read_force_table
from frogsim.fit.traces import Trace, model_signals, read_trace, signal_kind
from frogsim.scenario.core import Scenario
from frogsim.scenario.fields import check_bounds, shown, unknown_key_error
from frogsim.scenario.load import load_scenario, read_toml
from frogsim.scenario.units import to_si

TOP_KEYS = ("scenario", "experiments", "force_tables", "parameters", "signals", "noise", "starts", "seed", "confidence",
            "interval", "profile", "max_evaluations", "diff_step", "threads", "global_points")
EXPERIMENT_KEYS = ("name", "trace", "overrides", "ignore_columns", "commands", "command_delay")
FORCE_TABLE_KEYS = ("name", "table", "muscle", "noise", "relative_noise")
PARAMETER_KEYS = ("min", "max", "start")
SIGNAL_KEYS = ("noise", "weight")
#: used when no noise is given: the intervals then rest on the residual variance alone
DEFAULT_NOISE_PA = 1.0e3
#: the same for a force table [N]
DEFAULT_NOISE_N = 10.0


@dataclass(frozen=True)
class Parameter:
    """A parameter to fit: dotted path, bounds and start in SI, field metadata (kind, display unit)."""
    path: str
    lower: float
    upper: float
    start: float
    meta: dict

    def shown(self, x: float) -> str:
        """An SI value in the field's display unit, e.g. "0.4 L/(s*bar)"."""
        return str(shown(x, self.meta))


@dataclass(frozen=True)
class Experiment:
    """One measured run: its scenario (the base with the experiment's overrides) and its trace."""
    name: str
    scenario: Scenario
    trace: Trace
    overrides: dict            # dotted path -> SI value
    commands: str | None = None  # the valve commands replayed (frogsim.fit.replay), or None: the closed loop
    command_delay: tuple = (0.0, 0.0)  # [s] from a sample to its valve writes on the board: sample 0's, the others'


@dataclass(frozen=True)
class ForceExperiment:
    """One force-contraction table, its model and each row's noise [N]."""
    name: str
    table: ForceTable
    model: ForceModel
    sigma: np.ndarray
    noise: float               # N
    relative_noise: float
    noise_given: bool


@dataclass(frozen=True)
class FitSpec:
    path: str
    base: Scenario
    experiments: tuple
    parameters: tuple
    noise: dict                # signal -> noise standard deviation [SI]
    weights: dict              # signal -> weight (dimensionless)
    noise_given: bool
    starts: int = 4
    seed: int = 0
    confidence: float = 0.95
    interval: str = "t"
    max_evaluations: int = 200
    diff_step: float = 1e-3
    threads: int | None = None
    global_points: int | None = None   # the global stage's Latin-hypercube points (None: 10 per parameter)
    force_tables: tuple = ()
    profile: tuple = ()        # parameter paths whose profile interval is computed as well
    notes: tuple = ()          # said with the fit's warnings: temperature columns left out


def _where(fname: str, key: str) -> str:
    return f"{fname}: {key}"


def _int(raw, key: str, fname: str, lo: int, hi: int) -> int:
    if isinstance(raw, bool) or not isinstance(raw, int) or not lo <= raw <= hi:
        raise ScenarioError(_where(fname, key), raw, f"expected a whole number from {lo} to {hi}")
    return raw


def _quantity(raw, meta: dict, where: str) -> float:
    """A value written with units, checked against the kind and bounds of a scenario field."""
    kind = meta.get("kind")
    if kind is None:
        raise ScenarioError(where, raw, "is not a continuous quantity (a choice, a flag or a whole "
                                        "number): it cannot be fitted")
    x = to_si(raw, kind, where)
    if not math.isfinite(x):
        raise ScenarioError(where, raw, "must be a finite number")
    return x


def _path_meta(path: str, variables: dict, where: str) -> dict:
    if path not in variables:
        import difflib
        close = difflib.get_close_matches(path, list(variables), n=2)
        hint = f"; did you mean {' or '.join(map(repr, close))}?" if close else ""
        raise ScenarioError(where, UNKNOWN, f"no such setting in the base scenario{hint}")
    return variables[path]


def _overrides(raw, base: Scenario, where: str) -> dict:
    if not isinstance(raw, dict):
        raise ScenarioError(where, raw, "expected a table of dotted path = value with units")
    variables = base.variable_paths()
    out = {}
    for path, value in raw.items():
        meta = _path_meta(path, variables, f"{where}.{path}")
        if "kind" in meta:
            out[path] = to_si(value, meta["kind"], f"{where}.{path}")
        else:
            out[path] = value
    return out


def load_fit_spec(source, *, starts: int | None = None, threads: int | None = None) -> FitSpec:
    """Read and check a fit spec (a FIT.toml path or a dict; a dict's relative paths are read from
    its ``base_dir`` key, default "."). Reads every trace. ``starts``/``threads`` override the file's."""
    if isinstance(source, (str, os.PathLike)):
        path = Path(source)
        raw = read_toml(path, "fit spec")
        base_dir = path.resolve().parent
        fname = path.name
    elif isinstance(source, dict):
        raw = dict(source)
        base_dir = Path(raw.pop("base_dir", "."))
        path, fname = Path(base_dir) / "(fit spec)", "fit spec"
    else:
        raise ScenarioError("fit spec", source, "expected a path to a TOML file or a dict")
    for key in raw:
        if key not in TOP_KEYS:
            err = unknown_key_error("", key, TOP_KEYS)
            raise ScenarioError(_where(fname, err.field), UNKNOWN, err.allowed)
    if "scenario" not in raw:
        raise ScenarioError(_where(fname, "scenario"), MISSING, "name the base scenario (a TOML path or shipped name)")
    scen = raw["scenario"]
    if not isinstance(scen, str):
        raise ScenarioError(_where(fname, "scenario"), scen, "expected a TOML path or a shipped scenario name")
    scen_path = base_dir / scen
    base = load_scenario(str(scen_path) if scen_path.exists() else scen)
    variables = {**base.variable_paths(), **law_meta()}

    # parameters
    params_raw = raw.get("parameters")
    if not isinstance(params_raw, dict) or not params_raw:
        raise ScenarioError(_where(fname, "parameters"), params_raw if params_raw is not None else MISSING,
                            'expected a table of "dotted.path" = { min = ..., max = ..., start = ... }')
    parameters = []
    for p, spec in params_raw.items():
        where = _where(fname, f"parameters.{p}")
        meta = _path_meta(p, variables, where)
        if not isinstance(spec, dict):
            raise ScenarioError(where, spec, "expected { min = ..., max = ..., start = ... } with units")
        for key in spec:
            if key not in PARAMETER_KEYS:
                err = unknown_key_error(f"parameters.{p}", key, PARAMETER_KEYS)
                raise ScenarioError(_where(fname, err.field), UNKNOWN, err.allowed)
        for key in ("min", "max"):
            if key not in spec:
                raise ScenarioError(f"{where}.{key}", MISSING, "required: the fit's bound, with its unit")
        lo = _quantity(spec["min"], meta, f"{where}.min")
        hi = _quantity(spec["max"], meta, f"{where}.max")
        if not lo < hi:
            raise ScenarioError(f"{where}.max", spec["max"], f"must be above min ({spec['min']})")
        if "start" in spec:
            x0 = _quantity(spec["start"], meta, f"{where}.start")
        elif p.startswith(PREFIX):
            x0 = float(getattr(base_law(base), p[len(PREFIX):]))
        else:
            x0 = _current(base, p)
            if x0 is None:            # an optional setting the base leaves unset (wall_area, ...)
                raise ScenarioError(f"{where}.start", MISSING, "required: the base scenario does not set "
                                                               "this setting, so the fit needs a start value")
        if not lo <= x0 <= hi:
            raise ScenarioError(f"{where}.start", spec.get("start", shown(x0, meta)),
                                f"must lie within min and max ({spec['min']} .. {spec['max']})")
        for key, x in (("min", lo), ("max", hi)):          # the field's own bounds and rules
            try:
                if p.startswith(PREFIX):
                    check_bounds(x, meta, p, spec[key])
                else:
                    base.replace({p: x})
            except ScenarioError as exc:
                raise ScenarioError(f"{where}.{key}", spec[key], f"not allowed for this setting ({exc})") from None
        parameters.append(Parameter(p, lo, hi, x0, meta))

    # experiments
    exps_raw = raw.get("experiments", [] if "force_tables" in raw else None)
    if not isinstance(exps_raw, list) or (not exps_raw and "force_tables" not in raw):
        raise ScenarioError(_where(fname, "experiments"), exps_raw if exps_raw is not None else MISSING,
                            "expected one or more [[experiments]] with a trace (or [[force_tables]])")
    experiments, names, notes = [], set(), []
    for k, e in enumerate(exps_raw):
        where = _where(fname, f"experiments[{k}]")
        if not isinstance(e, dict):
            raise ScenarioError(where, e, "expected a table with trace = ...")
        for key in e:
            if key not in EXPERIMENT_KEYS:
                err = unknown_key_error(f"experiments[{k}]", key, EXPERIMENT_KEYS)
                raise ScenarioError(_where(fname, err.field), UNKNOWN, err.allowed)
        if not isinstance(e.get("trace"), str):
            raise ScenarioError(f"{where}.trace", e.get("trace", MISSING), "expected the path of a trace file")
        exp_base, commands = base, None
        if "commands" in e:
            if not isinstance(e["commands"], str):
                raise ScenarioError(f"{where}.commands", e["commands"], "expected the path of a commands file "
                                                                        "(commands.csv of frogsim sil or frogsim log)")
            commands = str(base_dir / e["commands"])
            if not Path(commands).is_file():
                raise ScenarioError(f"{where}.commands", e["commands"], "no such file")
        delay = (0.0, 0.0)
        if "command_delay" in e:
            if commands is None:
                raise ScenarioError(f"{where}.command_delay", e["command_delay"], "needs commands = ...: the delay is "
                                                                                  "that of the replayed commands")
            delay = _command_delay(e["command_delay"], base, f"{where}.command_delay")
        if commands is not None:
            from frogsim.fit.replay import replayed
            exp_base = replayed(base, commands, delay)
        over = _overrides(e.get("overrides", {}), exp_base, f"{where}.overrides")
        clash = sorted(set(over) & {q.path for q in parameters})
        if clash:
            raise ScenarioError(f"{where}.overrides.{clash[0]}", UNKNOWN, "is also fitted: set it in one place")
        try:
            scenario = exp_base.replace(over) if over else exp_base
        except ScenarioError as exc:
            raise ScenarioError(f"{where}.overrides", UNKNOWN, str(exc)) from None
        ignore = e.get("ignore_columns", [])
        if not isinstance(ignore, list) or not all(isinstance(c, str) for c in ignore):
            raise ScenarioError(f"{where}.ignore_columns", ignore, "expected a list of column headers")
        trace = _without_unnoised_temperatures(read_trace(base_dir / e["trace"], scenario, ignore),
                                               raw.get("signals"), notes)
        name = e.get("name", trace.name)
        if not isinstance(name, str) or name in names:
            raise ScenarioError(f"{where}.name", name, "expected a name used by no other experiment")
        names.add(name)
        experiments.append(Experiment(name, scenario, trace, over, commands, delay))

    force_tables = _force_tables(raw, base, base_dir, fname, names)

    # noise and weights, per signal
    signals = sorted({s for e in experiments for s in e.trace.signals})
    default_noise = None
    if "noise" in raw:
        default_noise = to_si(raw["noise"], "pressure", _where(fname, "noise"))
    sig_raw = raw.get("signals", {})
    if not isinstance(sig_raw, dict):
        raise ScenarioError(_where(fname, "signals"), sig_raw, 'expected tables [signals."<signal>"]')
    known = set(model_signals(base))
    noise, weights = {}, {}
    for s, spec in sig_raw.items():
        if s not in known:
            err = unknown_key_error("signals", s, known)
            raise ScenarioError(_where(fname, err.field), UNKNOWN, err.allowed)
        if not isinstance(spec, dict):
            raise ScenarioError(_where(fname, f"signals.{s}"), spec, "expected { noise = ..., weight = ... }")
        for key in spec:
            if key not in SIGNAL_KEYS:
                err = unknown_key_error(f"signals.{s}", key, SIGNAL_KEYS)
                raise ScenarioError(_where(fname, err.field), UNKNOWN, err.allowed)
        if "noise" in spec:
            noise[s] = _noise(spec["noise"], signal_kind(s), _where(fname, f"signals.{s}.noise"))
            if not noise[s] > 0:
                raise ScenarioError(_where(fname, f"signals.{s}.noise"), spec["noise"], "must be > 0")
        if "weight" in spec:
            w = spec["weight"]
            if isinstance(w, bool) or not isinstance(w, (int, float)) or not (math.isfinite(w) and w > 0):
                raise ScenarioError(_where(fname, f"signals.{s}.weight"), w, "expected a positive number")
            weights[s] = float(w)
    if default_noise is not None and not default_noise > 0:
        raise ScenarioError(_where(fname, "noise"), raw["noise"], "must be > 0")
    given = (all(s in noise for s in signals) or default_noise is not None or not signals) and \
        all(f.noise_given for f in force_tables)
    for s in signals:
        noise.setdefault(s, default_noise if default_noise is not None else DEFAULT_NOISE_PA)
        weights.setdefault(s, 1.0)

    # options
    starts_n = _int(raw.get("starts", 4), "starts", fname, 1, 1000) if starts is None else \
        _int(starts, "--starts", fname, 1, 1000)
    seed = _int(raw.get("seed", 0), "seed", fname, 0, 2 ** 32 - 1)
    conf = raw.get("confidence", 0.95)
    if isinstance(conf, bool) or not isinstance(conf, (int, float)) or not 0 < conf < 1:
        raise ScenarioError(_where(fname, "confidence"), conf, "expected a number between 0 and 1, e.g. 0.95")
    interval = raw.get("interval", "t")
    if interval not in ("t", "normal"):
        raise ScenarioError(_where(fname, "interval"), interval, "must be 't' (Student t quantile) or 'normal'")
    prof = raw.get("profile", [])
    fitted = [q.path for q in parameters]
    if not isinstance(prof, list) or not all(isinstance(x, str) for x in prof):
        raise ScenarioError(_where(fname, "profile"), prof, "expected a list of fitted parameter paths")
    for x in prof:
        if x not in fitted:
            raise ScenarioError(_where(fname, "profile"), x, f"is not a fitted parameter (fitted: {', '.join(fitted)})")
    max_eval = _int(raw.get("max_evaluations", 200), "max_evaluations", fname, 1, 100000)
    step = raw.get("diff_step", 1e-3)
    if isinstance(step, bool) or not isinstance(step, (int, float)) or not 1e-8 <= step <= 0.1:
        raise ScenarioError(_where(fname, "diff_step"), step,
                            "expected the finite-difference step as a fraction of each parameter's "
                            "range, from 1e-8 to 0.1")
    gp = raw.get("global_points")
    if gp is not None:
        gp = _int(gp, "global_points", fname, 0, 100000)
    thr = raw.get("threads") if threads is None else threads
    if thr is not None:
        thr = _int(thr, "threads", fname, 1, 1024)
    return FitSpec(path=str(path), base=base, experiments=tuple(experiments), parameters=tuple(parameters),
                   noise=noise, weights=weights, noise_given=given, starts=starts_n, seed=seed,
                   confidence=float(conf), interval=interval, max_evaluations=max_eval,
                   diff_step=float(step), threads=thr, global_points=gp, force_tables=tuple(force_tables), profile=tuple(prof),
                   notes=tuple(notes))


def _command_delay(raw, base: Scenario, where: str) -> tuple:
    """(sample 0's, the later samples') delay [s] from a sample to its valve write: one time for
    both, or a list of two; each from 0 to below the controller period."""
    items = raw if isinstance(raw, list) else [raw, raw]
    if len(items) != 2:
        raise ScenarioError(where, raw, 'expected a time ("0.12 ms") or two (["0.22 ms", "0.12 ms"]: sample 0\'s, '
                                        "the later samples')")
    period = 1.0 / base.controller.rate
    out = []
    for x in items:
        d = to_si(x, "time", where)
        if not (math.isfinite(d) and 0.0 <= d < period):
            raise ScenarioError(where, x, f"must lie from 0 to below the controller period ({period * 1e3:g} ms): a "
                                          "write comes within its sample's period")
        out.append(d)
    return tuple(out)


def _without_unnoised_temperatures(trace: Trace, signals_raw, notes: list) -> Trace:
    """The trace without its temperature signals that have no noise of their own in the spec's
    [signals] (the top-level noise is a pressure, never applied to a temperature): those columns are
    left out, as the other frogsim outputs the fit does not use (so a simulate folder's
    timeseries.csv stays a trace as it is), and a note says so. A trace left with no signal is
    refused."""
    given = signals_raw if isinstance(signals_raw, dict) else {}
    drop = [s for s in trace.signals if signal_kind(s) == "temperature"
            and not (isinstance(given.get(s), dict) and "noise" in given[s])]
    if not drop:
        return trace
    keep = {s: v for s, v in trace.signals.items() if s not in drop}
    cols = [trace.columns[s] for s in drop]
    if not keep:
        raise ScenarioError(f"trace {trace.name!r}", UNKNOWN,
                            f"no signal to fit: its temperature column(s) {', '.join(map(repr, cols))} need a noise "
                            f'of their own, e.g. [signals."{drop[0]}"] noise = "1 K" (the top-level noise is a pressure)')
    notes.append(f"{trace.name}: temperature column(s) {', '.join(map(repr, cols))} left out: a temperature is fitted "
                 f'only with a noise of its own, e.g. [signals."{drop[0]}"] noise = "1 K"')
    return dataclasses.replace(trace, signals=keep, columns={s: c for s, c in trace.columns.items() if s in keep},
                               ignored=trace.ignored + tuple(cols))


def _noise(raw, kind: str, where: str) -> float:
    """A signal's noise (standard deviation) in SI: a pressure [Pa], or a temperature difference
    [K] for a temperature signal (degC is a temperature, 273.15 K from zero: refused here)."""
    if kind != "temperature":
        return to_si(raw, "pressure", where)
    return to_si(raw, "temperature_difference", where)


def _current(scenario: Scenario, path: str) -> float | None:
    """The base scenario's value of a setting [SI]; None for an optional setting it leaves unset."""
    node = scenario
    for key in path.split("."):
        node = node[key] if isinstance(node, dict) else getattr(node, key)
    return None if node is None else float(node)


def _force_tables(raw: dict, base: Scenario, base_dir: Path, fname: str, names: set) -> list:
    """The spec's [[force_tables]], read and checked (see :mod:`frogsim.fit.force`)."""
    tables_raw = raw.get("force_tables", [])
    if not isinstance(tables_raw, list) or ("force_tables" in raw and not tables_raw):
        raise ScenarioError(_where(fname, "force_tables"), tables_raw,
                            "expected one or more [[force_tables]] with table = ...")
    if not tables_raw:
        return []
    law = base_law(base)
    out = []
    for k, e in enumerate(tables_raw):
        where = _where(fname, f"force_tables[{k}]")
        if not isinstance(e, dict):
            raise ScenarioError(where, e, "expected a table with table = ...")
        for key in e:
            if key not in FORCE_TABLE_KEYS:
                err = unknown_key_error(f"force_tables[{k}]", key, FORCE_TABLE_KEYS)
                raise ScenarioError(_where(fname, err.field), UNKNOWN, err.allowed)
        if not isinstance(e.get("table"), str):
            raise ScenarioError(f"{where}.table", e.get("table", MISSING), "expected the path of a force table")
        types = sorted(base.muscle_types)
        used = sorted({m.type for m in base.muscles.values()})
        muscle = e.get("muscle", used[0] if len(used) == 1 else None)
        if muscle not in types:
            raise ScenarioError(f"{where}.muscle", muscle if "muscle" in e else MISSING,
                                f"expected the muscle type the table was measured on: one of {', '.join(types)}")
        noise = to_si(e["noise"], "force", f"{where}.noise") if "noise" in e else None
        if noise is not None and not (math.isfinite(noise) and noise > 0):
            raise ScenarioError(f"{where}.noise", e["noise"], "must be > 0")
        rel = e.get("relative_noise", 0.0)
        if isinstance(rel, bool) or not isinstance(rel, (int, float)) or not (math.isfinite(rel) and 0 <= rel < 10):
            raise ScenarioError(f"{where}.relative_noise", rel, "expected a fraction of the force, e.g. 0.1")
        table = read_force_table(base_dir / e["table"], base)
        name = e.get("name", table.name)
        if not isinstance(name, str) or name in names:
            raise ScenarioError(f"{where}.name", name, "expected a name used by no other experiment or table")
        names.add(name)
        given = noise is not None or rel > 0
        floor = noise if noise is not None else (0.0 if rel > 0 else DEFAULT_NOISE_N)
        sigma = np.maximum(floor, rel * np.abs(table.force))
        if not np.all(sigma > 0):
            raise ScenarioError(f"{where}.noise", MISSING, "a row with zero force has no noise: give noise = \"... N\" "
                                                           "as well as relative_noise")
        out.append(ForceExperiment(name, table, ForceModel(table, base, muscle, law), sigma,
                                   float(floor), float(rel), given))
    return out
