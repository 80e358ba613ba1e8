"""Gains search: the settings of a scenario's controllers that track best for the least valve
work and air, found by running the whole scenario once per trial (``frogsim tune``,
docs/control.md "Tuning the gains").

What is searched: each controller kind declares its tunable gains with a default range
(:class:`frogsim.control.kinds.spec.Gain`, in the kind's module); every closed-loop controller
of the scenario whose kind declares gains has them searched, in the gain's unit (log scale where
declared). A ``[tune]`` section of the scenario (or of the file given with ``--spec``) changes
that::

    [tune]
    tie = [["hip_left", "hip_right"]]          # one value for both (the first is searched)
    pareto = ["tracking", "air"]               # the objectives of --pareto (2 or 3 terms)
    [tune.at_most]                             # constraints, relative to the starting gains
    air = 1.0                                  # no more air than the scenario's own gains
    [tune.weights]                             # the weighted sum's weights (>= 0)
    tracking = 1.0
    air = 0.5
    [tune.gains.hip_left]
    proportional_gain = ["10 bar/rad", "100 bar/rad"]         # a narrower range (log as declared)
    integral_gain = {low = "1 bar/(rad*s)", high = "50 bar/(rad*s)", log = true}
    band = "0.1 bar"                                          # fixed, not searched

A gain is a quantity setting of the controller's kind: a declared one takes its declared range
unless narrowed, another quantity setting (e.g. ``angle_rate``) may be searched with a range
written out. A tied controller takes its leader's values: its own entries are refused.

The objective. Each term is relative to the scenario's starting gains (the run as written, the
baseline), so 1 means "as today" whatever the units:

* ``tracking``: the mean over the tracking controllers of each one's tracking RMS after its
  settle time (``control_metrics()``, docs/metrics.md: degrees for a joint angle, bar for a
  pressure), divided by the baseline's mean RMS over the controllers of the same kind (so a
  pressure loop in bar and an angle loop in degrees weigh alike);
* ``switchings``: the valve switchings per second of all controllers, over the baseline's;
* ``air``: the air their charge valves let in per second of run [L std/s], over the baseline's.

The weighted sum ``sum(w_i term_i)`` is minimised (weights: tracking 1, switchings 0, air 0 by
default; the baseline scores the sum of the weights); ``--pareto`` minimises the terms named in
``pareto`` together (Optuna multi-objective) and writes their front. ``[tune.at_most]`` bounds
terms (e.g. ``air = 1``: no more air than the starting gains): the sampler is told which trials
broke a bound (Optuna's constraints) and the best trial is chosen among those that did not.

Each trial loads the scenario with its gains (as text in the gain's unit, 6 significant digits:
the values ``best.toml`` writes are the values the trial ran) and runs it compiled: ``swim`` for
a robot scenario, with the integer twins where it has ``[firmware]``; ``simulate`` for a
pneumatic one. A robot run reports the running objective at each of its 20 progress points and
Optuna's median pruner stops a trial already worse than the median of the finished ones there
(:mod:`frogsim.optimize.study`). The pneumatic engine has no report between its pauses, so a
pneumatic trial runs whole (such runs take a fraction of a second); a Pareto search prunes
nothing (Optuna prunes no multi-objective study). A trial that fails (unstable, non-physical, a
setting the loader refuses) scores :data:`FAILED_TERM` on every term and is counted as failed.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

from frogsim.errors import ScenarioError, SimulationError

STUDY_NAME = "tune"
TERMS = ("tracking", "switchings", "air")
TERM_TEXT = {"tracking": "tracking RMS over the baseline's, per kind",
             "switchings": "valve switchings per second over the baseline's",
             "air": "air charged per second over the baseline's"}
WEIGHTS = {"tracking": 1.0, "switchings": 0.0, "air": 0.0}
PARETO = ("tracking", "air")
FAILED_TERM = 100.0       # a failed trial's score on every term: 100 times the starting gains'
REPORTS = 20              # a robot run's progress points (frogsim.engine.coupled.run_coupled)
DIGITS = 6                # significant digits of a trial's gains (as run and as written)
TUNE_KEYS = ("gains", "tie", "weights", "pareto", "at_most")


# --- what is searched -------------------------------------------------------------------------
@dataclass(frozen=True)
class Searched:
    """One searched gain: setting ``name`` of the controllers ``controllers`` (the first is the
    leader, the rest tied to it), range ``low``..``high`` in ``unit``, log scale when ``log``."""
    controllers: tuple
    name: str
    unit: str
    low: float
    high: float
    log: bool

    @property
    def key(self) -> str:
        """The Optuna parameter's name (the leader's setting)."""
        return f"{self.controllers[0]}.{self.name}"

    def paths(self) -> list:
        return [f"controllers.{c}.{self.name}" for c in self.controllers]

    def text(self, value: float) -> str:
        return f"{value:.{DIGITS}g} {self.unit}"


def _unit_factor(unit: str, kind: str, where: str) -> float:
    from frogsim.scenario.units import to_si
    return to_si(f"1 {unit}", kind, where)


def _setting(settings: type, name: str, where: str):
    """The dataclass field of the quantity setting ``name`` of ``settings``; ScenarioError naming
    the kind's gains and settings otherwise."""
    from frogsim.control import kinds
    f = settings.settings().get(name)
    if f is None or not f.metadata.get("kind"):
        gains = [g.name for g in kinds.of(settings).gains]
        raise ScenarioError(where, "(a gain)" if f is None else "(not a quantity)",
                            f"is not a gain of kind {settings.KIND!r}: its declared gains are "
                            f"{', '.join(gains) or 'none'}; any quantity setting of it may be searched "
                            f"({', '.join(n for n, x in settings.settings().items() if x.metadata.get('kind'))})")
    return f


def _si(text, kind: str, where: str) -> float:
    from frogsim.scenario.fields import unwrap
    from frogsim.scenario.units import to_si
    return to_si(unwrap(text), kind, where)


def _entry(settings: type, name: str, value, where: str, declared) -> tuple:
    """("fixed", text) or ("range", low, high, log, unit) of one [tune.gains] entry."""
    f = _setting(settings, name, where)
    kind = f.metadata["kind"]
    unit = declared.unit if declared is not None else (f.metadata.get("display") or "")
    if isinstance(value, str):
        _si(value, kind, where)                      # a fixed value: checked here, written as given
        return ("fixed", value)
    log = declared.log if declared is not None else False
    if isinstance(value, list):
        if len(value) != 2:
            raise ScenarioError(where, value, "a range is [low, high] (two values with units), a table "
                                              "{low, high, log} or one value (fixed)")
        lo, hi = value
    elif isinstance(value, dict):
        extra = set(value) - {"low", "high", "log"}
        if extra or not {"low", "high"} <= set(value):
            raise ScenarioError(where, value, "a range table has low, high (values with units) and "
                                              "optionally log (true or false)")
        lo, hi = value["low"], value["high"]
        log = value.get("log", log)
        if not isinstance(log, bool):
            raise ScenarioError(f"{where}.log", log, "expected true or false")
    else:
        raise ScenarioError(where, value, "expected a value with its unit (fixed), [low, high] or "
                                          "{low, high, log}")
    if not unit:
        raise ScenarioError(where, value, "this setting has no display unit to search it in")
    factor = _unit_factor(unit, kind, where)
    low, high = _si(lo, kind, f"{where}.low") / factor, _si(hi, kind, f"{where}.high") / factor
    _check_range(where, low, high, log, unit)
    return ("range", low, high, log, unit)


def _check_range(where: str, low: float, high: float, log: bool, unit: str) -> None:
    if not (math.isfinite(low) and math.isfinite(high)) or low >= high:
        raise ScenarioError(where, f"{low:g}..{high:g} {unit}", "a range needs low < high, both finite")
    if log and low <= 0.0:
        raise ScenarioError(where, f"{low:g}..{high:g} {unit}", "a log-scale range must start above 0 "
                                                                "(write log = false to search it linearly)")


@dataclass
class Tune:
    """A prepared gains search: validated inputs, nothing run or written yet."""
    source: object
    raw: dict                  # the scenario as written, without [tune]
    base_dir: str
    robot: bool
    name: str
    scenario: object           # the loaded baseline (a RobotScenario or a Scenario)
    searched: list
    fixed: dict                # variable path -> text
    ties: list
    weights: dict
    pareto_terms: tuple
    at_most: dict
    trials: int
    pareto: bool = False
    seed: int = 0
    workers: int = 1
    timeout: float | None = None
    written: tuple = ()        # the keys of the searched gains whose range [tune.gains] wrote

    @property
    def pneumatic(self):
        return self.scenario.pneumatic if self.robot else self.scenario

    @property
    def duration(self) -> float:
        return self.pneumatic.duration

    @property
    def directions(self):
        return ["minimize"] * len(self.pareto_terms) if self.pareto else "minimize"

    def objective_text(self) -> str:
        if self.pareto:
            return "Pareto front of " + ", ".join(self.pareto_terms)
        return "minimise " + " + ".join(t if w == 1 else f"{w:g} x {t}" for t, w in self.weights.items() if w > 0)

    def key(self) -> dict:
        """What a stored study must match to be continued."""
        return {"scenario": self.name, "objective": "pareto" if self.pareto else "weighted",
                "weights": self.weights, "at_most": self.at_most, "pareto": list(self.pareto_terms) if self.pareto else [],
                "seed": self.seed, "fixed": self.fixed, "ties": self.ties,
                "space": {s.key: [s.low, s.high, s.log, s.unit, list(s.controllers)] for s in self.searched}}

    def distributions(self) -> dict:
        from optuna.distributions import FloatDistribution
        return {s.key: FloatDistribution(s.low, s.high, log=s.log) for s in self.searched}

    def texts(self, params: dict) -> dict:
        """Variable path -> text of a trial's gains (every tied controller) and the fixed ones."""
        out = dict(self.fixed)
        for s in self.searched:
            for p in s.paths():
                out[p] = s.text(params[s.key])
        return out

    def start_texts(self) -> dict:
        """Variable path -> the scenario's own value of every searched or fixed gain, in the
        gain's unit."""
        out = {}
        ctls = self.pneumatic.controllers
        for s in self.searched:
            for c in s.controllers:
                f = ctls[c].settings()[s.name]
                value = getattr(ctls[c], s.name)
                out[f"controllers.{c}.{s.name}"] = (None if value is None else
                                                    s.text(value / _unit_factor(s.unit, f.metadata["kind"], s.key)))
        for p in self.fixed:
            _, c, n = p.split(".")
            f = ctls[c].settings()[n]
            value = getattr(ctls[c], n)
            unit = f.metadata.get("display") or ""
            out[p] = None if value is None else f"{value / _unit_factor(unit, f.metadata['kind'], p):.{DIGITS}g} {unit}"
        return out


def _check_trials(flag: str, n, low: int = 1) -> None:
    if isinstance(n, bool) or not isinstance(n, int) or n < low:
        raise ScenarioError(flag, n, f"must be a whole number >= {low}")


def _spec_table(spec) -> dict | None:
    if spec is None:
        return None
    from frogsim.scenario.load import read_toml
    data = read_toml(spec, "--spec")
    extra = set(data) - {"tune"}
    if extra or "tune" not in data:
        raise ScenarioError("--spec", str(spec), "expected a TOML file with one [tune] section"
                            + (f" (it has {', '.join(sorted(extra))})" if extra else ""))
    return data["tune"]


def prepare(source, trials: int, *, workers: int = 1, seed: int = 0, timeout: float | None = None,
            pareto: bool = False, spec=None) -> Tune:
    """Validate everything (ScenarioError, nothing run): the counts, the scenario and its
    controllers, the [tune] section (the scenario's, or ``spec``'s)."""
    from frogsim.control import kinds
    from frogsim.optimize.gait import own_raw
    from frogsim.scenario.load import merged_raw
    _check_trials("--trials", trials)
    _check_trials("--workers", workers)
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise ScenarioError("--seed", seed, "must be a whole number")
    if timeout is not None and not (math.isfinite(timeout) and timeout > 0):
        raise ScenarioError("--timeout", timeout, "must be a number of seconds, finite and > 0")
    raw, base = own_raw(source)
    table = raw.pop("tune", None)
    from_spec = _spec_table(spec)
    where = "tune"
    if from_spec is not None:
        table, where = from_spec, f"--spec {Path(spec).name}: tune"
    table = {} if table is None else table
    if not isinstance(table, dict):
        raise ScenarioError(where, table, "expected a table ([tune])")
    robot = "gait" in merged_raw({**raw, "base_dir": base})[0]
    scenario = _load(raw, base, robot, {})
    sc = scenario.pneumatic if robot else scenario
    tunable = {c: ctl for c, ctl in sc.controllers.items() if ctl.closed_loop and kinds.of(ctl).gains}
    if not tunable:
        have = ", ".join(f"{c} ({ctl.kind})" for c, ctl in sc.controllers.items())
        raise ScenarioError("controllers", have or "(none)",
                            "tune needs a scenario with closed-loop controllers whose kind declares gains ("
                            + ", ".join(k.name for k in kinds.KINDS.values() if k.gains) + ")")
    for key in table:
        if key not in TUNE_KEYS:
            raise ScenarioError(f"{where}.{key}", "(a setting)", f"unknown; [tune] has {', '.join(TUNE_KEYS)}")
    ties = _ties(table.get("tie", []), tunable, f"{where}.tie")
    leader_of = {c: g[0] for g in ties for c in g}
    gains_raw = table.get("gains", {})
    if not isinstance(gains_raw, dict):
        raise ScenarioError(f"{where}.gains", gains_raw, "expected [tune.gains.CONTROLLER] tables")
    entries = {}
    for c, t in gains_raw.items():
        if c not in tunable:
            raise ScenarioError(f"{where}.gains.{c}", "(a table)",
                                f"must name a tunable controller of the scenario ({', '.join(tunable)})")
        if leader_of.get(c, c) != c:
            raise ScenarioError(f"{where}.gains.{c}", "(a table)",
                                f"{c} is tied to {leader_of[c]}: set its gains on {leader_of[c]}")
        if not isinstance(t, dict):
            raise ScenarioError(f"{where}.gains.{c}", t, "expected a table of gains")
        settings = type(tunable[c])
        declared = {g.name: g for g in kinds.of(settings).gains}
        for n, v in t.items():
            entries[(c, n)] = _entry(settings, n, v, f"{where}.gains.{c}.{n}", declared.get(n))
    searched, fixed = [], {}
    for c, ctl in tunable.items():
        if leader_of.get(c, c) != c:
            continue
        group = next((tuple(g) for g in ties if g[0] == c), (c,))
        declared = kinds.of(ctl).gains
        names = [g.name for g in declared] + [n for (cc, n) in entries if cc == c and n not in
                                              {g.name for g in declared}]
        for n in names:
            g = next((x for x in declared if x.name == n), None)
            e = entries.get((c, n))
            if e is not None and e[0] == "fixed":
                for m in group:
                    fixed[f"controllers.{m}.{n}"] = e[1]
                continue
            if e is None:
                _check_range(f"{type(ctl).KIND}.gains.{n}", g.low, g.high, g.log, g.unit)
                searched.append(Searched(group, n, g.unit, float(g.low), float(g.high), g.log))
            else:
                searched.append(Searched(group, n, e[4], e[1], e[2], e[3]))
    weights = _weights(table.get("weights", {}), f"{where}.weights")
    pareto_terms = _pareto_terms(table.get("pareto", list(PARETO)), f"{where}.pareto")
    at_most = _at_most(table.get("at_most", {}), f"{where}.at_most")
    tracks = any(ctl.setpoint is not None for ctl in tunable.values())
    used = pareto_terms if pareto else tuple(t for t, w in weights.items() if w > 0)
    if "tracking" in used and not tracks:
        raise ScenarioError(f"{where}.weights.tracking" if not pareto else f"{where}.pareto", "tracking",
                            "no controller of the scenario has a setpoint to track: weigh switchings or air")
    tune = Tune(source, raw, base, robot, sc.name, scenario, searched, fixed, [list(g) for g in ties], weights,
                pareto_terms, at_most, trials, pareto, seed, workers, timeout)
    tune.written = tuple(f"{c}.{n}" for (c, n), e in entries.items() if e[0] == "range")
    _check_ends(tune, where)
    return tune


def _ties(value, tunable: dict, where: str) -> list:
    if not isinstance(value, list) or not all(isinstance(g, list) for g in value):
        raise ScenarioError(where, value, "expected a list of lists of controller names, e.g. "
                                          "[[\"hip_left\", \"hip_right\"]]")
    seen, out = set(), []
    for g in value:
        if len(g) < 2 or len(set(g)) != len(g):
            raise ScenarioError(where, g, "a tie names two or more different controllers")
        for c in g:
            if c not in tunable:
                raise ScenarioError(where, c, f"must name a tunable controller of the scenario ({', '.join(tunable)})")
            if c in seen:
                raise ScenarioError(where, c, "is in two ties")
            seen.add(c)
        kinds_ = {tunable[c].kind for c in g}
        if len(kinds_) > 1:
            raise ScenarioError(where, g, f"tied controllers must be of one kind (these are {', '.join(sorted(kinds_))})")
        out.append(tuple(g))
    return out


def _weights(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise ScenarioError(where, value, "expected a table: tracking, switchings, air (numbers >= 0)")
    out = dict(WEIGHTS)
    for k, v in value.items():
        if k not in TERMS:
            raise ScenarioError(f"{where}.{k}", v, f"unknown term; the terms are {', '.join(TERMS)}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise ScenarioError(f"{where}.{k}", v, "must be a finite number >= 0")
        out[k] = float(v)
    if not any(w > 0 for w in out.values()):
        raise ScenarioError(where, value, "at least one weight must be > 0")
    return out


def _at_most(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise ScenarioError(where, value, "expected a table: tracking, switchings, air (numbers > 0, relative "
                                          "to the starting gains)")
    for k, v in value.items():
        if k not in TERMS:
            raise ScenarioError(f"{where}.{k}", v, f"unknown term; the terms are {', '.join(TERMS)}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise ScenarioError(f"{where}.{k}", v, "must be a finite number > 0 (1 = the starting gains')")
    return {k: float(v) for k, v in value.items()}


def _pareto_terms(value, where: str) -> tuple:
    if (not isinstance(value, list) or not 2 <= len(value) <= 3 or len(set(value)) != len(value)
            or any(v not in TERMS for v in value)):
        raise ScenarioError(where, value, f"expected two or three different terms of {', '.join(TERMS)}")
    return tuple(value)


def _check_ends(tune: Tune, where: str) -> None:
    """Load the scenario with every searched gain at its low end, then at its high end: a range
    the settings' own bounds or rules refuse is refused here, naming the [tune] entry."""
    for end in ("low", "high"):
        params = {s.key: getattr(s, end) for s in tune.searched}
        try:
            _load(tune.raw, tune.base_dir, tune.robot, tune.texts(params))
        except ScenarioError as exc:
            hit = next((s for s in tune.searched if exc.field in s.paths()), None)
            if hit is None:
                if exc.field in tune.fixed:
                    raise ScenarioError(f"{where}.gains.{exc.field.split('.', 1)[1]}", tune.fixed[exc.field],
                                        exc.allowed) from None
                raise
            hint = ("" if hit.key in tune.written else f" (the kind's default range: write a narrower one in "
                                                       f"[tune.gains.{hit.controllers[0]}])")
            raise ScenarioError(f"{where}.gains.{hit.key}", f"{hit.low:g}..{hit.high:g} {hit.unit}",
                                f"its {end} end is refused by the scenario{hint}: {exc}") from None


def _load(raw: dict, base: str, robot: bool, texts: dict):
    from frogsim.scenario.load import load_scenario, with_overrides
    r = with_overrides(raw, texts, share=True) if texts else raw
    if robot:
        from frogsim.robot.scenario import load_robot_scenario
        return load_robot_scenario({**r, "base_dir": base})
    return load_scenario({**r, "base_dir": base})


# --- one run and its score --------------------------------------------------------------------
class _Pruned(Exception):
    def __init__(self, step: int):
        self.step = step


@dataclass
class Outcome:
    metrics: dict = field(default_factory=dict)
    terms: dict = field(default_factory=dict)
    failure: str = ""
    pruned_at: int | None = None
    wall_s: float = 0.0


def run(tune: Tune, texts: dict, report=None):
    """Run the scenario with the settings ``texts`` (variable path -> text); the result.
    ``report(partial_result, step)`` (robot runs) is called at each of the run's progress
    points with the result so far."""
    sc = _load(tune.raw, tune.base_dir, tune.robot, texts)
    if not tune.robot:
        from frogsim.engine.pneumatic import simulate
        return simulate(sc, progress=False)
    import numpy as np

    from frogsim.engine import coupled as C
    from frogsim.engine.swim import SwimResult
    cm = C.build_coupled(sc)

    def progress(fraction):
        rec = cm.arrays["rec"]
        n = int(np.argmax(np.isnan(rec[:, C.R_TIME]))) if np.isnan(rec[:, C.R_TIME]).any() else rec.shape[0]
        if n > 1:
            report(SwimResult(rec=rec[:n], model=cm), int(round(fraction * REPORTS)))
    out = C.run_coupled(cm, progress=progress if report is not None else None)
    return SwimResult(rec=out["rec"], model=cm, stats=out["stats"], wall_s=out["wall_s"],
                      compile_s=out.get("compile_s", 0.0))


def _tracking_key(kind_name: str) -> str | None:
    from frogsim.control import kinds
    return next((m for m in kinds.KINDS[kind_name].metrics if m.startswith("tracking_error_rms")), None)


def references(metrics: dict, duration: float) -> dict:
    """The baseline's scales of the terms: its mean tracking RMS per kind (in the kind's unit),
    its switchings per second and its air per second [L std/s] (1 where the baseline's is 0: the
    term is then in those units)."""
    per_kind = {}
    for m in metrics.values():
        key = _tracking_key(m["kind"])
        if key and m.get(key) is not None:
            per_kind.setdefault(m["kind"], []).append(m[key])
    track = {k: (sum(v) / len(v) if sum(v) > 0 else 1.0) for k, v in per_kind.items()}
    sw = sum(m["switchings_per_s"] or 0.0 for m in metrics.values())
    air = sum(m["air_used_L_std"] for m in metrics.values()) / duration
    return {"tracking": track, "switchings_per_s": sw if sw > 0 else 1.0, "air_L_std_per_s": air if air > 0 else 1.0}


def terms_of(metrics: dict, span: float, ref: dict) -> dict:
    """The three terms (module docstring) of a run's controller metrics over ``span`` [s] of run."""
    rel = []
    for m in metrics.values():
        key = _tracking_key(m["kind"])
        if key and m.get(key) is not None and m["kind"] in ref["tracking"]:
            rel.append(m[key] / ref["tracking"][m["kind"]])
    sw = sum(m["switchings_per_s"] or 0.0 for m in metrics.values())
    air = sum(m["air_used_L_std"] for m in metrics.values()) / span if span > 0 else math.nan
    return {"tracking": sum(rel) / len(rel) if rel else math.nan,
            "switchings": sw / ref["switchings_per_s"], "air": air / ref["air_L_std_per_s"]}


def excess(terms: dict, at_most: dict) -> list:
    """Each bound's excess (term - bound; <= 0 where it holds)."""
    return [terms[t] - b for t, b in at_most.items()]


def feasible(trial, tune: "Tune") -> bool:
    terms = trial.user_attrs.get("terms")
    return (terms is not None and "failure" not in trial.user_attrs
            and all(x <= 0 for x in excess(terms, tune.at_most)))


def weighted(terms: dict, weights: dict) -> float:
    return sum(w * terms[t] for t, w in weights.items() if w > 0)


def score(tune: Tune, terms: dict):
    if tune.pareto:
        return [terms[t] for t in tune.pareto_terms]
    return weighted(terms, tune.weights)


def _span(result) -> float:
    t = result.t
    return float(t[-1] - t[0]) if t.size > 1 else 0.0


def evaluate(tune: Tune, texts: dict, ref: dict, trial=None) -> Outcome:
    """Run one trial and score it; a failure is an outcome, not an exception. With ``trial`` (a
    single-objective study's), the running objective is reported and the trial pruned when its
    pruner says so."""
    t0 = time.perf_counter()

    def report(partial, step):
        m = partial.control_metrics()
        terms = terms_of(m, _span(partial), ref)
        value = weighted(terms, tune.weights)
        if math.isfinite(value):
            trial.report(value, step)
            if trial.should_prune():
                raise _Pruned(step)
    try:
        res = run(tune, texts, report if (trial is not None and tune.robot and not tune.pareto) else None)
        metrics = res.control_metrics()
        terms = terms_of(metrics, _span(res), ref)
    except _Pruned as p:
        return Outcome(pruned_at=p.step, wall_s=time.perf_counter() - t0)
    except (SimulationError, ScenarioError) as exc:
        return Outcome(failure=str(exc), terms=dict.fromkeys(TERMS, FAILED_TERM), wall_s=time.perf_counter() - t0)
    used = tune.pareto_terms if tune.pareto else [t for t, w in tune.weights.items() if w > 0]
    if not all(math.isfinite(terms[t]) for t in used):
        bad = [t for t in used if not math.isfinite(terms[t])]
        return Outcome(metrics, dict.fromkeys(TERMS, FAILED_TERM), f"no finite {', '.join(bad)}",
                       wall_s=time.perf_counter() - t0)
    return Outcome(metrics, terms, wall_s=time.perf_counter() - t0)


def _compact(metrics: dict) -> dict:
    """Per controller: its tracking RMS (in its unit), switchings/s, air used [L std]."""
    out = {}
    for c, m in metrics.items():
        key = _tracking_key(m["kind"])
        out[c] = {"kind": m["kind"], "tracking_rms": m.get(key) if key else None,
                  "tracking_unit": (key or "").rsplit("_", 1)[-1] or None,
                  "switchings_per_s": m["switchings_per_s"], "air_used_L_std": m["air_used_L_std"]}
    return out


# --- the search -------------------------------------------------------------------------------
def check_resumable(tune: Tune, url: str) -> int:
    """Finished trials (complete or pruned) of a study ``tune`` already stored at ``url`` (0 if
    none); ScenarioError if it was made for another scenario, objective, space or seed."""
    from frogsim.optimize import study as S
    st = S.existing(url, STUDY_NAME)
    if st is None:
        return 0
    S.check_key(st, tune.key(), "gains study", "--storage",
                "use --overwrite (the default SQLite file in --out) or another --storage / --out")
    return S.count(st, ("COMPLETE", "PRUNED"))


def run_search(tune: Tune, url: str, fresh_file: Path | None = None, progress: bool = False, say=None) -> dict:
    """Run (or continue) the search to ``tune.trials`` finished trials in all; the results:
    study, baseline, best trial, trials run now, wall time."""
    from optuna.trial import TrialState

    from frogsim.optimize import study as S
    pruner = None if (tune.pareto or not tune.robot) else S.median_pruner()
    st = S.open_study(url, STUDY_NAME, tune.directions, tune.seed, pruner=pruner, fresh_file=fresh_file)
    S.check_key(st, tune.key(), "gains study", "--storage", "use --overwrite or another --storage / --out")
    st.set_user_attr("key", tune.key())
    S.close_unfinished(st)
    t0 = time.perf_counter()
    if say is not None:
        say(f"  the scenario's own gains first (the baseline), {tune.duration:g} s ...")
    try:
        base_res = run(tune, {})
    except SimulationError as exc:
        raise SimulationError(f"the scenario's own gains: {exc}") from None
    base_metrics = base_res.control_metrics()
    ref = references(base_metrics, tune.duration)
    base_terms = terms_of(base_metrics, _span(base_res), ref)
    baseline = Outcome(base_metrics, base_terms)
    dists = tune.distributions()

    def ask(study):
        tr = study.ask(dists)
        return tr, tune.texts(tr.params)

    def evaluate_trial(tr, texts):
        return evaluate(tune, texts, ref, tr)

    def tell(tr, out: Outcome):
        tr.set_user_attr("wall_s", out.wall_s)
        if out.pruned_at is not None:
            tr.set_user_attr("pruned_at_s", out.pruned_at / REPORTS * tune.duration)
            st.tell(tr, state=TrialState.PRUNED)
            return
        tr.set_user_attr("terms", out.terms)
        tr.set_user_attr("metrics", _compact(out.metrics))
        if out.failure:
            tr.set_user_attr("failure", out.failure)
        for (term, _), x in zip(tune.at_most.items(), excess(out.terms, tune.at_most)):
            tr.set_constraint(f"{term} over its bound", x)       # the sampler models infeasible trials apart
        st.tell(tr, score(tune, out.terms))

    def finished():
        return S.count(st, ("COMPLETE", "PRUNED"))

    bar = S.Progress(tune.trials, finished(), f"tune {tune.name}", shown=progress)
    base_score = score(tune, base_terms)

    def after():
        bar.update(finished(), _best_text(st, tune, base_score))
    stop = None
    if tune.timeout is not None:
        def stop():
            return time.perf_counter() - t0 > tune.timeout
    try:
        ran = S.run_batches(st, tune.trials, tune.workers, ask, evaluate_trial, tell, done=finished,
                            after_batch=after, stop=stop)
    finally:
        bar.close()
    return {"study": st, "baseline": baseline, "reference": ref, "ran": ran,
            "wall_s": time.perf_counter() - t0, "timed_out": bool(stop and stop() and finished() < tune.trials)}


def _best_text(st, tune: Tune, base_score) -> str:
    if tune.pareto:
        return f"front of {len(front(st, tune))} trials"
    b = best_trial(st, tune)
    return "" if b is None else f"best {b.value:.4g} (start {base_score:.4g})"


def _dominates(a, b) -> bool:
    return all(x <= y for x, y in zip(a, b)) and any(x < y for x, y in zip(a, b))


def front(st, tune: Tune) -> list:
    """The non-dominated trials of a Pareto search among the complete ones that did not fail and
    keep the bounds of ``[tune.at_most]``."""
    ok = [t for t in st.get_trials(deepcopy=False) if t.state.name == "COMPLETE" and feasible(t, tune)]
    pts = {t.number: [t.user_attrs["terms"][k] for k in tune.pareto_terms] for t in ok}
    return [t for t in ok if not any(_dominates(pts[o.number], pts[t.number]) for o in ok if o is not t)]


def best_trial(st, tune: Tune):
    """The best trial among the feasible ones (:func:`feasible`): the lowest objective; for a
    Pareto search the member of the front with the lowest weighted sum (``[tune.weights]``);
    None if no trial is feasible."""
    if tune.pareto:
        f = front(st, tune)
        return min(f, key=lambda t: (weighted(t.user_attrs["terms"], tune.weights), t.number)) if f else None
    ok = [t for t in st.get_trials(deepcopy=False) if t.state.name == "COMPLETE" and feasible(t, tune)]
    return min(ok, key=lambda t: (t.value, t.number)) if ok else None


# --- outputs ----------------------------------------------------------------------------------
def trials_table(st, tune: Tune):
    """One row per trial: trial, state, its score (each Pareto term, or the objective and the best
    so far) [-], its gains [their units], each controller's tracking RMS, switchings/s and air
    used, the totals, failure; headers in the one convention (:mod:`frogsim.scenario.tables`)."""
    import pandas as pd

    from frogsim.scenario.tables import header
    rows, best = [], math.inf
    names = list(tune.pneumatic.controllers)
    for t in sorted(st.trials, key=lambda t: t.number):
        row = {"trial": t.number, "state": t.state.name}
        terms = t.user_attrs.get("terms", {})
        if tune.pareto:
            for k in tune.pareto_terms:
                row[header(k, "-")] = terms.get(k, math.nan)
        else:
            done = t.state.name == "COMPLETE"
            v = t.value if t.value is not None and done else math.nan
            if math.isfinite(v) and feasible(t, tune):
                best = min(best, v)
            row[header("objective", "-")] = v
            row[header("best so far", "-")] = best if math.isfinite(best) else math.nan
            row[header("running objective when pruned", "-")] = (t.value if t.state.name == "PRUNED"
                                                                 and t.value is not None else math.nan)
        if tune.at_most:
            row[header("within at_most", "1 = yes")] = (float(feasible(t, tune)) if t.state.name == "COMPLETE"
                                                         else math.nan)
        for s in tune.searched:
            row[header(s.key, s.unit)] = t.params.get(s.key, math.nan)
        m = t.user_attrs.get("metrics", {})
        for c in names:
            e = m.get(c)
            if e is None and c not in _compact_units(tune):
                continue
            unit = _compact_units(tune).get(c)
            if unit:
                row[header(f"{c} tracking RMS", unit)] = _num(e and e["tracking_rms"])
            row[header(f"{c} switchings", "1/s")] = _num(e and e["switchings_per_s"])
            row[header(f"{c} air used", "L std")] = _num(e and e["air_used_L_std"])
        row[header("switchings", "1/s")] = _num(sum(e["switchings_per_s"] or 0.0 for e in m.values()) if m else None)
        row[header("air used", "L std")] = _num(sum(e["air_used_L_std"] for e in m.values()) if m else None)
        row[header("pruned at", "s")] = t.user_attrs.get("pruned_at_s", math.nan)
        row["failure"] = t.user_attrs.get("failure", "")
        rows.append(row)
    return pd.DataFrame(rows)


def _num(x) -> float:
    return float(x) if x is not None else math.nan


def _compact_units(tune: Tune) -> dict:
    """controller -> the unit of its tracking RMS ("deg", "bar"), or "" if it tracks nothing."""
    out = {}
    for c, ctl in tune.pneumatic.controllers.items():
        if not ctl.closed_loop:
            continue
        key = _tracking_key(ctl.kind) if ctl.setpoint is not None else None
        out[c] = {"deg": "deg", "bar": "bar"}.get((key or "").rsplit("_", 1)[-1], "")
    return out


def best_patch_text(tune: Tune, trial, scenario_arg: str) -> str:
    """best.toml: the best trial's gains (and the fixed ones) as [controllers.NAME] tables, which
    ``frogsim simulate`` / ``frogsim swim`` lay over the scenario with ``--patch``."""
    from frogsim.sweep.spec import dumps_toml
    texts = tune.texts(trial.params)
    ctls: dict = {}
    for path, text in sorted(texts.items()):
        _, c, n = path.split(".")
        ctls.setdefault(c, {})[n] = text
    command = "swim" if tune.robot else "simulate"
    head = (f"# frogsim tune: the gains of trial {trial.number} for scenario {tune.name!r} ({tune.objective_text()}).\n"
            f"# Run them with: frogsim {command} {scenario_arg} --patch best.toml --out DIR\n")
    return head + dumps_toml({"controllers": ctls}).lstrip("\n")


def summary_of(res: dict, tune: Tune, files: dict, storage_shown: str) -> dict:
    st = res["study"]
    states = [t.state.name for t in st.trials]
    failed = sum(1 for t in st.trials if "failure" in t.user_attrs or t.state.name == "FAIL")
    best = best_trial(st, tune)
    base = res["baseline"]
    out = {
        "scenario": tune.name,
        "engine": "swim" if tune.robot else "simulate",
        "objective": tune.objective_text(),
        "objective_terms": {t: TERM_TEXT[t] for t in TERMS},
        "weights": tune.weights,
        "at_most": tune.at_most,
        "pareto": tune.pareto,
        "reference": res["reference"],
        "trials": len(st.trials),
        "trials_complete": states.count("COMPLETE") - sum(1 for t in st.trials if t.state.name == "COMPLETE"
                                                          and "failure" in t.user_attrs),
        "trials_pruned": states.count("PRUNED"),
        "trials_failed": failed,
        "trials_run_now": res["ran"],
        "timed_out": res["timed_out"],
        "sampler": f"Optuna TPE (seed {tune.seed}, batches of {tune.workers}, multivariate, constant liar)",
        "pruner": ("none (a Pareto search)" if tune.pareto else "none (the pneumatic engine reports nothing "
                   "mid-run)" if not tune.robot else "Optuna median pruner on the running objective at 20 points "
                                                    "of the run"),
        "storage": storage_shown,
        "searched": {s.key: {"controllers": list(s.controllers), "low": s.low, "high": s.high, "unit": s.unit,
                             "log": s.log} for s in tune.searched},
        "fixed": tune.fixed,
        "ties": tune.ties,
        "start_gains": tune.start_texts(),
        "start": {"score": score(tune, base.terms), "terms": base.terms, "controllers": _compact(base.metrics)},
        "files": files,
        "wall_time_s": res["wall_s"],
    }
    if best is None:
        out["best"] = None
        return out
    out["best_trial"] = best.number
    out["best_gains"] = tune.texts(best.params)
    out["best"] = {"score": score(tune, best.user_attrs["terms"]), "terms": best.user_attrs["terms"],
                   "controllers": best.user_attrs["metrics"]}
    if tune.pareto:
        out["front"] = [{"trial": t.number, "terms": t.user_attrs["terms"]} for t in
                        sorted(front(st, tune), key=lambda t: t.number)]
    return out


def plot_history(table, tune: Tune, base_score: float, path) -> None:
    """The objective of each trial (pruned ones where they stopped, failed ones marked), the best
    so far and the starting gains' score."""
    import numpy as np
    from matplotlib.ticker import MaxNLocator

    from frogsim._files import write_figure
    col, so_far = "objective [-]", "best so far [-]"

    def draw(p):
        import matplotlib.pyplot as plt

        from frogsim._plotting import legend_in
        fig, (ax, lax) = plt.subplots(1, 2, figsize=(8.5, 4), gridspec_kw={"width_ratios": [1, 0.3]})
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        v = table[col].to_numpy(float)
        ok = np.isfinite(v) & (table["failure"] == "").to_numpy() & (table["state"] == "COMPLETE").to_numpy()
        ax.plot(table["trial"][ok], v[ok], "o", ms=3.5, color="0.45", label="trial")
        pruned = (table["state"] == "PRUNED").to_numpy()
        if pruned.any():
            ax.plot(table["trial"][pruned], table["running objective when pruned [-]"][pruned], "x", ms=4,
                    color="C1", label="pruned (its running objective)")
        if "within at_most [1 = yes]" in table:
            over = (table["within at_most [1 = yes]"] == 0).to_numpy() & ok
            if over.any():
                ax.plot(table["trial"][over], v[over], "o", ms=5, mfc="none", color="C3",
                        label="over a bound of [tune.at_most]")
        bad = (table["failure"] != "").to_numpy()
        if bad.any():
            ax.plot(table["trial"][bad], np.full(bad.sum(), base_score), "v", ms=4, color="C3",
                    label="failed (drawn at the start's score)")
        ax.step(table["trial"], table[so_far], where="post", color="C0", label="best so far")
        ax.axhline(base_score, color="C3", ls="--", label="starting gains")
        finite = v[ok]
        if finite.size and finite.max() / max(finite.min(), 1e-12) > 20:
            ax.set_yscale("log")
        ax.set_xlabel("trial")
        ax.set_ylabel(f"objective [-] ({tune.objective_text()})")
        ax.set_title(f"gains search: {tune.name}, {tune.duration:g} s per trial", fontsize=10)
        legend_in(lax, ax, fontsize=8.5)
        fig.tight_layout()
        fig.savefig(p, dpi=120)
        plt.close(fig)
    write_figure(path, draw)


def plot_pareto(st, tune: Tune, base_terms: dict, path) -> None:
    """Every complete trial in the plane of the first two Pareto terms (the third, if any, as
    colour), the front joined, the starting gains at (1, 1)."""
    import numpy as np

    from frogsim._files import write_figure
    a, b = tune.pareto_terms[:2]
    c3 = tune.pareto_terms[2] if len(tune.pareto_terms) > 2 else None
    done = [t for t in st.trials if t.state.name == "COMPLETE" and "failure" not in t.user_attrs]
    fr = sorted(front(st, tune), key=lambda t: t.user_attrs["terms"][a])

    def draw(p):
        import matplotlib.pyplot as plt

        from frogsim._plotting import legend_in
        fig, (ax, lax) = plt.subplots(1, 2, figsize=(8.5, 4.6), gridspec_kw={"width_ratios": [1, 0.32]})
        x = np.array([t.user_attrs["terms"][a] for t in done])
        y = np.array([t.user_attrs["terms"][b] for t in done])
        if c3:
            z = np.array([t.user_attrs["terms"][c3] for t in done])
            sc = ax.scatter(x, y, c=z, s=14, cmap="viridis", label="trial")
            fig.colorbar(sc, ax=ax, label=f"{c3} [-]")
        else:
            ax.plot(x, y, "o", ms=3.5, color="0.6", label="trial")
        fx, fy = [t.user_attrs["terms"][a] for t in fr], [t.user_attrs["terms"][b] for t in fr]
        if c3:      # a front in three terms is not a line in the plane of two: its members ringed
            ax.plot(fx, fy, "o", ms=9, mfc="none", mec="C3", mew=1.2, label=f"Pareto front (of {a}, {b}, {c3})")
        else:
            ax.plot(fx, fy, "o-", color="C0", ms=5, label="Pareto front")
        ax.plot([base_terms[a]], [base_terms[b]], "*", ms=12, color="C3", label="starting gains")
        ax.set_xlabel(f"{a} [-] ({TERM_TEXT[a]})", fontsize=9)
        ax.set_ylabel(f"{b} [-] ({TERM_TEXT[b]})", fontsize=9)
        ax.set_title(f"gains search: {tune.name}, Pareto front of {', '.join(tune.pareto_terms)}", fontsize=10)
        legend_in(lax, ax, fontsize=8.5)
        fig.tight_layout()
        fig.savefig(p, dpi=120)
        plt.close(fig)
    write_figure(path, draw)

