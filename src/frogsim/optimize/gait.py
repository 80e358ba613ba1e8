"""Gait search: the phase timing of the valves and the palms that swims fastest, or farthest per
litre of air, found by running the coupled engine once per trial.

The search space (fractions of the scenario's own period P, times rounded to 1 ms; every point a
valid gait, see :func:`gait_of`):

    drive_on    [0, 0.2] P      the driving muscles' charge command
    drive_len   [0.2, 0.75] P   ... held so long, then vent (ends by 0.95 P)
    palm_delay  [0, 0.1] P      the palms open so long after the charge command
    palm_lag    [-0.35, 0.1] P  ... and fold so long after the vent command (at least 0.05 P
                                after opening, by 0.95 P)
    rec_gap     [0, 0.2] P      (antagonistic recovery muscles only) charge after the drive vents
    rec_len     [0.1, 0.6] P    ... held so long, then vent (or to the period's end)

Both legs and all three joints share the timing; the period and the number of cycles stay the
scenario's (or ``cycles``). Objectives, both maximised, from the run's
:meth:`frogsim.engine.swim.SwimResult.summary`:

    speed               mean forward speed over the run [m/s]
    distance-per-litre  forward distance per standard litre of air charged [m/L]

Each trial runs the evaluated cycles from the scenario's initial state (a full source), so the
objective is an average over those cycles, not a steady gait's value. :func:`steadiness` judges
it from the baseline run: the source pressure still changes over the last evaluated cycle by
more than :data:`STEADY_CHANGE` (2 %) of its value, the strokes of the search are a transient
(on the shipped ``swim`` scenario: 13.9 % in cycle 1, 1.3 % in cycle 10; the muscle's force, and
the stroke, scale with the pressure). Then the search warns and its outputs say so; every output
records the cycles evaluated (``summary.json``: ``cycles_evaluated``, ``steady``; the title of
``trials.png``; ``best-gait.toml``'s gait runs those cycles and its description says so).

The sampler is Optuna's TPE, seeded; trials are asked in batches of ``workers``, run on a thread
pool (the engine's compiled kernel and MuJoCo's step release the GIL), and told in order, so a
search is the same for the same seed and worker count (the plumbing ``frogsim tune`` shares:
:mod:`frogsim.optimize.study`). The study lives in an SQLite file: running the search again
continues it to the requested total of trials. The scenario's own gait is run
as the baseline and the best gait is compared with it.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from frogsim.errors import ScenarioError, SimulationError

OBJECTIVES = {"speed": ("mean forward speed", "m/s"),
              "distance-per-litre": ("forward distance per standard litre of air", "m/L")}
STUDY_NAME = "gait"
BOUNDS = {"drive_on": (0.0, 0.2), "drive_len": (0.2, 0.75), "palm_delay": (0.0, 0.1),
          "palm_lag": (-0.35, 0.1)}
RECOVERY_BOUNDS = {"rec_gap": (0.0, 0.2), "rec_len": (0.1, 0.6)}
LAST = 0.95          # every command of the period by 0.95 P
STEADY_CHANGE = 0.02  # a gait is steady once the source pressure changes by less than this per cycle


def check_objective(objective: str) -> str:
    if objective not in OBJECTIVES:
        raise ScenarioError("--objective", objective, f"must be one of {', '.join(OBJECTIVES)}")
    return objective


def search_bounds(rs) -> dict:
    """The searched fractions of the period and their bounds for a robot scenario."""
    return {**BOUNDS, **(RECOVERY_BOUNDS if rs.options.recovery == "muscle" else {})}


def _ms(t: float) -> float:
    return round(t * 1000.0) / 1000.0


def gait_of(params: dict, period: float, cycles: int) -> dict:
    """The ``[gait]`` table of a point of the search space (fractions of the period)."""
    from frogsim.control.gait import gait_raw
    P = period
    on = _ms(params["drive_on"] * P)
    off = _ms(min(params["drive_on"] + params["drive_len"], LAST) * P)
    f_open = params["drive_on"] + params["palm_delay"]
    f_fold = min(max(params["drive_on"] + params["drive_len"] + params["palm_lag"], f_open + 0.05), LAST)
    p_open, p_fold = _ms(f_open * P), _ms(f_fold * P)
    drive = ((on, "charge"), (off, "vent"))
    if "rec_gap" in params:
        r_on = _ms(min(params["drive_on"] + params["drive_len"] + params["rec_gap"], LAST) * P)
        r_on = max(r_on, _ms(off + 0.001))
        r_off = _ms((params["drive_on"] + params["drive_len"] + params["rec_gap"]
                     + params["rec_len"]) * P)
        recover = [(0.0, "vent"), (r_on, "charge")]
        if r_off < LAST * P and r_off > r_on:
            recover.append((r_off, "vent"))
        if r_on >= P:
            recover = [(0.0, "vent")]
    else:
        recover = ((0.0, "vent"), (off, "charge"))
    return gait_raw(P, cycles, drive, tuple(recover), ((p_open, "open"), (p_fold, "fold")))


def own_raw(source) -> tuple[dict, str]:
    """The scenario as written (its parameter set not merged in) and its folder."""
    import copy
    import os

    from frogsim.scenario.load import read_toml, scenario_path
    if isinstance(source, dict):
        raw = copy.deepcopy(source)
        return raw, str(raw.pop("base_dir", "."))
    path = scenario_path(source)
    raw = read_toml(path, "scenario")
    base = str(path.resolve().parent)
    params = raw.get("parameters")
    if isinstance(params, str) and (Path(base) / params).exists() and not os.path.isabs(params):
        raw["parameters"] = str((Path(base) / params).resolve())   # still found from elsewhere
    return raw, base


def objective_value(summary: dict, objective: str) -> float:
    if objective == "speed":
        return float(summary["mean_speed_m_per_s"])
    air = summary["air_used_L_std"]
    return float(summary["distance_m"] / air) if air > 0 else -math.inf


def steadiness(summary: dict) -> dict:
    """How far a run's last cycle is from a steady gait: the source pressure's change over it
    (gauge, relative to its value at the cycle's start), and whether that is below
    :data:`STEADY_CHANGE`."""
    p = summary["source_pressure_each_cycle_start_bar_gauge"]
    change = (p[-1] - p[-2]) / abs(p[-2]) if p[-2] != 0 else math.inf
    n = len(p) - 1
    out = {"cycles_evaluated": n, "source_pressure_each_cycle_start_bar_gauge": p,
           "source_change_last_cycle_percent": 100.0 * change,
           "steady": abs(change) < STEADY_CHANGE,
           "criterion": f"the source pressure changes by less than {100 * STEADY_CHANGE:g} % over the last "
                        "evaluated cycle"}
    if not out["steady"]:
        out["warning"] = (f"the source pressure still changes by {100 * change:+.1f} % over the last of the {n} "
                          f"cycle(s) evaluated ({p[-2]:.2f} -> {p[-1]:.2f} bar gauge; steady below "
                          f"{100 * STEADY_CHANGE:g} %): the search optimises the first {n} stroke(s) from the "
                          "initial source, not a steady gait; evaluate more cycles (--cycles)")
    return out


@dataclass
class Evaluation:
    value: float
    summary: dict = field(default_factory=dict)
    failure: str = ""
    wall_s: float = 0.0


def evaluate(raw: dict, base_dir: str, gait: dict, objective: str) -> Evaluation:
    """Run the scenario with ``gait`` (a ``[gait]`` table) and score it."""
    from frogsim.engine.swim import swim
    from frogsim.robot.scenario import load_robot_scenario
    t0 = time.perf_counter()
    rs = load_robot_scenario({**raw, "gait": gait, "base_dir": base_dir})
    try:
        s = swim(rs).summary()
    except SimulationError as exc:
        return Evaluation(-math.inf, {}, str(exc), time.perf_counter() - t0)
    return Evaluation(objective_value(s, objective), s, "", time.perf_counter() - t0)


def best_scenario_text(res: dict, search: "Search") -> str:
    """best-gait.toml: the scenario with the best gait, for the cycles evaluated (so that
    ``frogsim swim`` on it reproduces the best trial's figure); its description says what was
    optimised (objective, cycles evaluated, whether that was a steady gait)."""
    best, base = res["best"].value, res["baseline"].value
    unit = OBJECTIVES[search.objective][1]
    steady = res["steadiness"]
    note = (f"Gait found by frogsim optimize-gait ({search.objective}: {best:.6g} {unit} against {base:.6g} "
            f"{unit} for the scenario's own gait, evaluated over the first {search.cycles} cycle(s)"
            + ("" if steady["steady"] else f"; not a steady gait: the source pressure still changed by "
                                           f"{steady['source_change_last_cycle_percent']:+.1f} % over the last "
                                           "evaluated cycle") + ")")
    return scenario_text(search.raw, res["best_gait"],
                         f"{search.rs.name}-best-{search.objective}", note)


def scenario_text(raw: dict, gait: dict, name: str, note: str) -> str:
    """The TOML text of the scenario with ``gait`` in place of its own."""
    from frogsim.sweep.spec import dumps_toml
    out = {k: v for k, v in raw.items() if k != "gait"}
    out["name"] = name
    out["description"] = note
    out["gait"] = gait
    return dumps_toml(out)


# --- the search -------------------------------------------------------------------------------
@dataclass
class Search:
    """A prepared gait search: validated inputs, nothing run or written yet."""
    source: object
    raw: dict
    base_dir: str
    rs: object
    objective: str
    trials: int
    cycles: int
    seed: int = 0
    workers: int = 1

    @property
    def period(self) -> float:
        return self.rs.gait.period

    def key(self) -> dict:
        """What a stored study must match to be continued."""
        return {"objective": self.objective, "cycles": self.cycles, "scenario": self.rs.name,
                "period_s": self.period, "seed": self.seed,
                "space": {k: list(v) for k, v in search_bounds(self.rs).items()}}


def prepare(source, objective: str, trials: int, cycles: int | None = None, seed: int = 0,
            workers: int = 1) -> Search:
    """Validate everything (ScenarioError, nothing run): objective, trials, the scenario and its
    gait (a robot scenario with a [gait] table)."""
    from frogsim.robot.scenario import load_robot_scenario
    check_objective(objective)
    if isinstance(trials, bool) or not isinstance(trials, int) or trials < 1:
        raise ScenarioError("--trials", trials, "must be a whole number >= 1")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ScenarioError("--workers", workers, "must be a whole number >= 1")
    raw, base = own_raw(source)
    if "gait" not in raw and not isinstance(source, dict):
        from frogsim.scenario.load import merged_raw
        if "gait" not in merged_raw(source)[0]:
            raise ScenarioError("gait", "(missing)", "gait search needs a robot scenario with a "
                                                     "[gait] table (see frogsim.control.gait)")
    rs = load_robot_scenario({**raw, "base_dir": base}, cycles=cycles)
    return Search(source, raw, base, rs, objective, trials, rs.gait.cycles, seed, workers)


def _study(search: Search, storage_path: Path, fresh: bool):
    from frogsim.optimize import study as S
    return S.open_study(S.sqlite_url(storage_path), STUDY_NAME, "maximize", search.seed,
                        fresh_file=storage_path if fresh else None)


def check_resumable(search: Search, storage_path: Path) -> int:
    """Completed trials of a study already in ``storage_path`` (0 if none); ScenarioError if it
    was made for another objective, scenario, cycle count, seed or search space."""
    if not storage_path.exists():
        return 0
    from frogsim.optimize import study as S
    try:
        study = S.existing(S.sqlite_url(storage_path), STUDY_NAME)
    except Exception:
        study = None
    if study is None:
        raise ScenarioError("--out", str(storage_path.parent),
                            f"holds {storage_path.name}, which is not a gait study; use "
                            "--overwrite to start afresh")
    try:
        S.check_key(study, search.key(), "gait study", "--out", "use --overwrite to start afresh, or another --out")
    except ScenarioError as exc:
        raise ScenarioError("--out", str(storage_path.parent), exc.allowed) from None
    return S.count(study)


def run_search(search: Search, storage_path: Path, fresh: bool = False, progress=None) -> dict:
    """Run (or continue) the search to ``search.trials`` trials in all; returns the results:
    the trials table, the baseline, the best trial and its gait."""
    from optuna.distributions import FloatDistribution
    from optuna.trial import TrialState

    from frogsim.control.gait import gait_table_of
    from frogsim.optimize import study as S
    study = _study(search, storage_path, fresh)
    study.set_user_attr("key", search.key())
    S.close_unfinished(study)        # trials an interrupted run left open are failed, then asked again
    dists = {k: FloatDistribution(*b) for k, b in search_bounds(search.rs).items()}
    t0 = time.perf_counter()
    base_gait = gait_table_of(search.rs.gait)
    if progress is not None:
        from frogsim._words import count
        progress(f"  the scenario's own gait first (the baseline), {count(search.cycles, 'cycle')} ...")
    baseline = evaluate(search.raw, search.base_dir, base_gait, search.objective)
    if baseline.failure:
        raise SimulationError(f"the scenario's own gait: {baseline.failure}")
    steady = steadiness(baseline.summary)
    if "warning" in steady and progress is not None:
        progress(f"warning: {steady['warning']}")

    def ask(st):
        tr = st.ask(dists)
        g = gait_of(tr.params, search.period, search.cycles)
        tr.set_user_attr("gait", g)
        return tr, g

    def tell(tr, ev):
        if ev.failure or not math.isfinite(ev.value):
            tr.set_user_attr("failure", ev.failure or "no air used")
            study.tell(tr, state=TrialState.FAIL)
            return
        for k in ("mean_speed_m_per_s", "distance_m", "air_used_L_std", "air_used_per_cycle_L_std"):
            tr.set_user_attr(k, ev.summary[k])
        study.tell(tr, ev.value)

    def report():
        if progress is not None:
            n = S.count(study)
            best = study.best_value if n else float("nan")
            progress(f"  {n}/{search.trials} trials, best {best:.4g} "
                     f"{OBJECTIVES[search.objective][1]} (baseline {baseline.value:.4g})")

    ran = S.run_batches(study, search.trials, search.workers, ask,
                        lambda tr, g: evaluate(search.raw, search.base_dir, g, search.objective), tell,
                        after_batch=report)
    wall = time.perf_counter() - t0
    best = study.best_trial
    return {"study": study, "baseline": baseline, "baseline_gait": base_gait, "best": best,
            "best_gait": best.user_attrs["gait"], "ran": ran, "wall_s": wall, "steadiness": steady}


def trials_table(study, search: Search):
    """One row per trial: number, state, objective, best so far, the searched fractions [period]
    and the resulting times [s], speed, distance, air, failure; headers in the one convention
    (:mod:`frogsim.scenario.tables`), "trial", "state" and "failure" being labels."""
    import pandas as pd

    from frogsim.scenario.tables import header
    unit = OBJECTIVES[search.objective][1]
    rows, best = [], -math.inf
    for t in sorted(study.trials, key=lambda t: t.number):
        v = t.value if t.value is not None else math.nan
        if t.value is not None:
            best = max(best, t.value)
        row = {"trial": t.number, "state": t.state.name,
               header(f"objective {search.objective}", unit): v,
               header("best so far", unit): best if math.isfinite(best) else math.nan}
        row.update({header(k, "period"): t.params.get(k, math.nan) for k in search_bounds(search.rs)})
        g = t.user_attrs.get("gait")
        if g:
            row[header("drive charge at", "s")] = _seconds(g["drive"][0]["at"])
            row[header("drive vent at", "s")] = _seconds(g["drive"][1]["at"])
            row[header("palms open at", "s")] = _seconds(g["palms"][0]["at"])
            row[header("palms fold at", "s")] = _seconds(g["palms"][1]["at"])
        for k, col in (("mean_speed_m_per_s", header("mean speed", "m/s")), ("distance_m", header("distance", "m")),
                       ("air_used_L_std", header("air used", "L std"))):
            row[col] = t.user_attrs.get(k, math.nan)
        row["failure"] = t.user_attrs.get("failure", "")
        rows.append(row)
    return pd.DataFrame(rows)


def _seconds(text: str) -> float:
    return float(text.split()[0])


def plot_trials(table, search: Search, baseline: float, path, steady: dict | None = None) -> None:
    """Objective per trial (whole trial numbers on the axis), the best so far, the baseline; the
    steadiness warning written on the figure when the evaluated cycles are a transient."""
    from matplotlib.ticker import MaxNLocator

    from frogsim._files import write_figure
    name, unit = OBJECTIVES[search.objective]
    col = next(c for c in table.columns if c.startswith("objective "))
    so_far = next(c for c in table.columns if c.startswith("best so far "))

    def draw(p):
        import matplotlib.pyplot as plt
        from frogsim._plotting import legend_in
        # the legend in an axes of its own at the right: the trials fill the panel (loc "lower
        # right" hid a trial)
        fig, (ax, lax) = plt.subplots(1, 2, figsize=(8.5, 4.4 if steady and "warning" in steady else 4),
                                      gridspec_kw={"width_ratios": [1, 0.28]})
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ok = np.isfinite(table[col].to_numpy(float))
        ax.plot(table["trial"][ok], table[col][ok], "o", ms=4, color="0.5", label="trial")
        ax.step(table["trial"], table[so_far], where="post", color="C0", label="best so far")
        ax.axhline(baseline, color="C3", ls="--", label="scenario's own gait")
        ax.set_xlabel("trial")
        ax.set_ylabel(f"{name} [{unit}]")
        ax.set_title(f"gait search: {search.rs.name}, objective over the first {search.cycles} cycle(s) "
                     f"of {search.period:g} s", fontsize=10)
        legend_in(lax, ax, fontsize=9)
        if steady and "warning" in steady:
            fig.text(0.01, 0.01, f"not a steady gait: source pressure {steady['source_change_last_cycle_percent']:+.1f} % "
                                 f"over the last evaluated cycle (steady below {100 * STEADY_CHANGE:g} %); "
                                 "evaluate more cycles", fontsize=7.5, color="C3", ha="left", va="bottom")
            fig.tight_layout(rect=(0, 0.05, 1, 1))
        else:
            fig.tight_layout()
        fig.savefig(p, dpi=120)
        plt.close(fig)
    write_figure(path, draw)


def summary_of(res: dict, search: Search, files: dict) -> dict:
    base, best = res["baseline"].value, res["best"].value
    name, unit = OBJECTIVES[search.objective]
    b_attrs = res["best"].user_attrs
    bs = res["baseline"].summary
    return {
        "scenario": search.rs.name,
        "objective": search.objective,
        "objective_meaning": f"{name} [{unit}], maximised",
        "cycles": search.cycles,
        "cycles_evaluated": search.cycles,
        "objective_over": f"the first {search.cycles} cycle(s) of {search.period:g} s from the scenario's "
                          "initial state",
        "steady": res["steadiness"]["steady"],
        "steadiness": res["steadiness"],
        "period_s": search.period,
        "trials": len([t for t in res["study"].trials if t.value is not None]),
        "trials_failed": len([t for t in res["study"].trials if t.state.name == "FAIL"]),
        "trials_run_now": res["ran"],
        "sampler": f"Optuna TPE (seed {search.seed}, batches of {search.workers})",
        "objective_unit": unit,
        "baseline_value": base,
        "best_value": best,
        "margin": best - base,
        "margin_percent": 100.0 * (best - base) / abs(base) if base else None,
        "beats_baseline": best > base,
        "best_trial": res["best"].number,
        "best_gait": res["best_gait"],
        "baseline_gait": res["baseline_gait"],
        "best_run": {k: b_attrs.get(k) for k in ("mean_speed_m_per_s", "distance_m", "air_used_L_std",
                                                 "air_used_per_cycle_L_std")},
        "baseline_run": {k: bs.get(k) for k in ("mean_speed_m_per_s", "distance_m", "air_used_L_std",
                                                "air_used_per_cycle_L_std")},
        "search_space_fractions_of_period": {k: list(v) for k, v in search_bounds(search.rs).items()},
        "files": files,
        "wall_time_s": res["wall_s"],
    }
