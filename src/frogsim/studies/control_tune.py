"""Gains tuned where the robot swims, against the scenario's own, in water and in air.

``control-tune``: the shipped ``swim-board`` (the swimming robot free in water, pump on, each of
its six leg joints under a joint-angle controller following the gait's 0.5 Hz sine, the board's
integer laws: the scenario has ``[firmware]``), cut to :data:`CYCLES` gait cycles, has its gains
searched by ``frogsim tune`` (:mod:`frogsim.optimize.tune`) for the Pareto front of tracking and
air (:data:`TRIALS` trials, seeded, batches of :data:`WORKERS`): left and right tied, the integral
gains fixed at 0 as the scenario has them (its loops are PD: the board does not measure the
source pressure), and the two bounds the board sets (docs/control.md, "The tuned firmware in
SIL"): bands of one count of its 8-bit conversion (0.05 bar) or more, Kd up to 1 bar s/rad. The
tuned gains are the front's member that tracks best at no more air than the
starting gains (the front's lowest tracking overall where none does). Then the starting and tuned
gains run side by side in water (the search's own case) and in air with the base fixed (the same
robot, gains, setpoints and palms), and the study reports each joint's tracking RMS, the
switchings and the air of each, and whether the gains tuned in water carry over to air.
"""
from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from frogsim._plotting import figure, legend_in, save
from frogsim.scenario.tables import header
from frogsim.studies.registry import StudyData, register

SCENARIO = "swim-board"
CYCLES = 2                 # gait cycles of 2 s: 4 s a run
TRIALS = 80                # the search's trials (a Pareto search prunes nothing: each runs whole)
WORKERS = 2                # trials asked together (the search depends on it: fixed)
SEED = 0
JOINTS = ("hip", "knee", "ankle")
SIDES = ("left", "right")
GAINS = ("start", "tuned")
ENVIRONMENTS = {"water": {"environment": "water", "base": "free"}, "air": {"environment": "air", "base": "fixed"}}
TIME = header("time", "s")
TUNE = {"tie": [[f"{j}_{s}" for s in SIDES] for j in JOINTS],
        "pareto": ["tracking", "air"],
        "gains": {f"{j}_left": {"integral_gain": "0 bar/(rad*s)", "band": ["0.05 bar", "1 bar"],
                                "derivative_gain": ["0 bar*s/rad", "1 bar*s/rad"]} for j in JOINTS}}


def column(controller: str, what: str) -> str:
    """A time-series column: ``hip_left setpoint [deg]``, ``hip_left angle, tuned gains [deg]``."""
    return header(f"{controller} {what}" if what == "setpoint" else f"{controller} angle, {what} gains", "deg")


def case_raw() -> dict:
    """swim-board as written, cut to CYCLES cycles, with the study's [tune] section."""
    from frogsim.optimize.gait import own_raw
    raw, base = own_raw(SCENARIO)
    raw["gait"] = {**raw["gait"], "cycles": CYCLES}
    raw["tune"] = TUNE
    raw["base_dir"] = base
    return raw


def chosen(front: list, base_air: float = 1.0):
    """The tuned trial of a Pareto front [(trial, tracking, air)]: the lowest tracking among the
    members at no more air than the start (``base_air``), else the lowest tracking."""
    within = [f for f in front if f[2] <= base_air]
    return min(within or front, key=lambda f: (f[1], f[0]))


def run_with(raw: dict, texts: dict, environment: str):
    """The case with the gains ``texts`` (variable path -> text) in ``environment``."""
    import frogsim
    from frogsim.scenario.load import with_overrides
    r = with_overrides({k: v for k, v in raw.items() if k != "tune"}, texts) if texts else \
        {k: v for k, v in raw.items() if k != "tune"}
    r = {**r, "robot": {**r.get("robot", {}), **ENVIRONMENTS[environment]}}
    return frogsim.swim(frogsim.load_robot_scenario(r))


def search(raw: dict) -> dict:
    """The Pareto search: every complete trial's (trial, tracking, air), the front, the baseline's
    terms and the gains of the chosen trial."""
    from frogsim.optimize import study as S
    from frogsim.optimize import tune as T
    tune = T.prepare(raw, TRIALS, workers=WORKERS, seed=SEED, pareto=True)
    with tempfile.TemporaryDirectory(prefix="control-tune-") as tmp:
        res = T.run_search(tune, S.sqlite_url(Path(tmp) / "study.db"))
        st = res["study"]
        done = [t for t in st.get_trials(deepcopy=False) if t.state.name == "COMPLETE"]
        trials = [(t.number, t.user_attrs["terms"]["tracking"], t.user_attrs["terms"]["air"],
                   "failure" in t.user_attrs) for t in sorted(done, key=lambda t: t.number)]
        front = [(t.number, t.user_attrs["terms"]["tracking"], t.user_attrs["terms"]["air"])
                 for t in sorted(T.front(st, tune), key=lambda t: t.user_attrs["terms"]["tracking"])]
        pick = chosen(front)
        params = next(t.params for t in done if t.number == pick[0])
        texts = tune.texts(params)
        start = tune.start_texts()
    return {"trials": trials, "front": front, "chosen": pick, "texts": texts, "start_texts": start,
            "failed": sum(t[3] for t in trials), "reference": res["reference"]}


def metrics_of(result) -> dict:
    m = result.control_metrics()
    out = {}
    for j in JOINTS:
        for s in SIDES:
            e = m[f"{j}_{s}"]
            out[f"{j}_{s}"] = {"tracking_error_rms_deg": e["tracking_error_rms_deg"],
                               "switchings_per_s": e["switchings_per_s"], "air_used_L_std": e["air_used_L_std"]}
    return out


def joint_mean(m: dict, joint: str) -> float:
    return float(np.mean([m[f"{joint}_{s}"]["tracking_error_rms_deg"] for s in SIDES]))


def totals(m: dict) -> dict:
    return {"tracking_error_rms_deg_mean": float(np.mean([v["tracking_error_rms_deg"] for v in m.values()])),
            "switchings_per_s": float(sum(v["switchings_per_s"] for v in m.values())),
            "air_used_L_std": float(sum(v["air_used_L_std"] for v in m.values()))}


@register("control-tune", "Gains of the swimming robot's six joint-angle controllers tuned in water (Pareto front "
                          "of tracking and air): starting and tuned gains in water and in air", group="control",
          cost=6.0)
def control_tune() -> StudyData:
    raw = case_raw()
    found = search(raw)
    frames, runs = [], {}
    for env in ENVIRONMENTS:
        runs[env] = {}
        res = {}
        for g in GAINS:
            r = run_with(raw, found["texts"] if g == "tuned" else {}, env)
            res[g] = r
            m = metrics_of(r)
            runs[env][g] = {"controllers": m, **totals(m),
                            "joints_deg": {j: joint_mean(m, j) for j in JOINTS}}
        a, b = res["start"], res["tuned"]
        if a.t.shape != b.t.shape or not np.array_equal(a.t, b.t):
            raise RuntimeError("the starting and tuned runs have different output grids")
        cols = {"experiment": env, TIME: a.t}
        for j in JOINTS:
            for s in SIDES:
                c = f"{j}_{s}"
                k = a.joint_names.index(c)
                cols[column(c, "setpoint")] = np.degrees(a.setpoint(c))
                cols[column(c, "start")] = np.degrees(a.joint_angles[:, k])
                cols[column(c, "tuned")] = np.degrees(b.joint_angles[:, k])
        frames.append(pd.DataFrame(cols))
    w, air = runs["water"], runs["air"]
    pick, front = found["chosen"], found["front"]
    within = pick[2] <= 1.0

    def change(env, key):
        x, y = runs[env]["start"][key], runs[env]["tuned"][key]
        return y / x if x else math.nan

    def joints_text(env):
        return ", ".join(f"{j} {runs[env]['start']['joints_deg'][j]:.2f} -> {runs[env]['tuned']['joints_deg'][j]:.2f}"
                         for j in JOINTS)
    better_w = [j for j in JOINTS if w["tuned"]["joints_deg"][j] < w["start"]["joints_deg"][j]]
    better_a = [j for j in JOINTS if air["tuned"]["joints_deg"][j] < air["start"]["joints_deg"][j]]
    carry = air["tuned"]["tracking_error_rms_deg_mean"] < air["start"]["tracking_error_rms_deg_mean"]

    def which(better):
        worse = [j for j in JOINTS if j not in better]
        if not worse:
            return "every joint better"
        if not better:
            return "no joint better"
        return f"{', '.join(better)} better, {', '.join(worse)} worse"
    if pick[1] < 1.0:
        gain = (f"the front's best tracking at no more air than the start tracks {100 * (1 - pick[1]):.0f} % better "
                f"with {100 * (1 - pick[2]):.0f} % less air" if within else
                f"the front's best tracking is {100 * (1 - pick[1]):.0f} % better but uses {pick[2]:.2f} times the air")
    else:
        gain = (f"no trial of the front tracks better than the starting gains at no more air: the one that tracks best "
                f"there is {100 * (pick[1] - 1):.0f} % worse with {100 * (1 - pick[2]):.0f} % less air" if within else
                "no trial of the front tracks better than the starting gains")
    conclusion = (
        f"{SCENARIO}, {CYCLES} gait cycles ({CYCLES * 2} s), the board's integer laws: {TRIALS} trials of a "
        f"Pareto search of tracking and air (seed {SEED}, {found['failed']} failed) found a front of {len(front)} "
        f"trials, from tracking {front[0][1]:.2f} at air {front[0][2]:.2f} to tracking {front[-1][1]:.2f} at air "
        f"{front[-1][2]:.2f} (each relative to the starting gains); {gain} (trial {pick[0]}, the tuned gains). "
        f"In water the mean tracking RMS goes {w['start']['tracking_error_rms_deg_mean']:.2f} -> "
        f"{w['tuned']['tracking_error_rms_deg_mean']:.2f} deg ({joints_text('water')} deg, left and right averaged; "
        f"{which(better_w)}), the air x{change('water', 'air_used_L_std'):.2f}, the switchings "
        f"x{change('water', 'switchings_per_s'):.2f}. In air on the fixed base the same two sets of gains give "
        f"{air['start']['tracking_error_rms_deg_mean']:.2f} -> {air['tuned']['tracking_error_rms_deg_mean']:.2f} deg "
        f"({joints_text('air')} deg; {which(better_a)}), the air x{change('air', 'air_used_L_std'):.2f}: the gains "
        f"tuned in water {'carry over to air on the mean' if carry else 'do not carry over to air'}; the starting "
        f"gains track {'worse' if air['start']['tracking_error_rms_deg_mean'] > w['start']['tracking_error_rms_deg_mean'] else 'better'} "
        f"in air ({air['start']['tracking_error_rms_deg_mean']:.2f} deg) than in water "
        f"({w['start']['tracking_error_rms_deg_mean']:.2f} deg).")
    summary = {"control_tune": {
        "scenario": SCENARIO, "cycles": CYCLES, "duration_s": CYCLES * 2.0, "trials": TRIALS, "workers": WORKERS,
        "seed": SEED, "tune": TUNE, "objectives": ["tracking", "air"],
        "terms": "relative to the starting gains' run in water (1 = as the scenario's own gains)",
        "trials_failed": found["failed"],
        "pareto": {"trials": [{"trial": t[0], "tracking": t[1], "air": t[2]} for t in found["trials"]],
                   "front": [{"trial": f[0], "tracking": f[1], "air": f[2]} for f in front]},
        "tuned_trial": pick[0], "tuned_within_start_air": within,
        "start_gains": found["start_texts"], "tuned_gains": found["texts"],
        "runs": runs, "tuned_better_in_water": better_w, "tuned_better_in_air": better_a,
        "carries_over_to_air": carry, "conclusion": conclusion}}
    return StudyData(pd.concat(frames, ignore_index=True), summary)


@control_tune.draws
def _draw(data: StudyData, path: str) -> None:
    s = data.summary["control_tune"]
    t = data.table
    fig, ax = figure(3, 4, width=18.0, height=11.0, gridspec_kw={"width_ratios": [1, 1, 1, 0.42]})
    colors = {"start": "tab:blue", "tuned": "tab:red"}
    for row, env in enumerate(ENVIRONMENTS):
        sub = t[t["experiment"] == env]
        runs = s["runs"][env]
        for col, j in enumerate(JOINTS):
            a = ax[row, col]
            c = f"{j}_left"
            a.plot(sub[TIME], sub[column(c, "setpoint")], "k--", lw=1.4, label="setpoint")
            for g in GAINS:
                a.plot(sub[TIME], sub[column(c, g)], color=colors[g], lw=1.1, label=f"{g} gains")
            ms = [runs[g]["controllers"][c]["tracking_error_rms_deg"] for g in GAINS]
            a.set_title(f"{env}{' (base fixed)' if env == 'air' else ' (free)'}: {c}, RMS start {ms[0]:.2f}, "
                        f"tuned {ms[1]:.2f} deg", fontsize=9.5)
            a.set_ylabel("angle [deg]")
            a.set_xlabel("time [s]")
        text = [f"{env}: mean RMS start {runs['start']['tracking_error_rms_deg_mean']:.2f} deg, tuned "
                f"{runs['tuned']['tracking_error_rms_deg_mean']:.2f} deg"]
        for g in GAINS:
            text.append(f"  {g}: {runs[g]['air_used_L_std']:.1f} L std, {runs[g]['switchings_per_s']:.0f} sw/s")
        leg = legend_in(ax[row, 3], ax[row, 0], fontsize=8.5)
        leg.set_title("\n".join(text), prop={"size": 8})
        leg._legend_box.align = "left"
    p = ax[2, 0]
    tr = s["pareto"]["trials"]
    fr = s["pareto"]["front"]
    p.plot([x["tracking"] for x in tr], [x["air"] for x in tr], "o", ms=3.5, color="0.6", label="trial")
    p.plot([x["tracking"] for x in fr], [x["air"] for x in fr], "o-", ms=5, color="C0", label="Pareto front")
    p.plot([1.0], [1.0], "*", ms=13, color="tab:blue", label="starting gains")
    pick = next(x for x in fr if x["trial"] == s["tuned_trial"])
    p.plot([pick["tracking"]], [pick["air"]], "*", ms=13, color="tab:red", label=f"tuned (trial {pick['trial']})")
    p.set_xlabel("tracking [-] (mean RMS over the start's)")
    p.set_ylabel("air [-] (over the start's)")
    p.set_title(f"Pareto front, {len(tr)} trials in water", fontsize=10)
    finite = [x["tracking"] for x in tr if x["tracking"] < 50]
    if finite:
        p.set_xlim(0.9 * min(finite + [1.0]), 1.05 * max(finite + [1.0]))
    b = ax[2, 1]
    x = np.arange(len(JOINTS))
    for k, (env, g) in enumerate([(e, g) for e in ENVIRONMENTS for g in GAINS]):
        vals = [s["runs"][env][g]["joints_deg"][j] for j in JOINTS]
        b.bar(x + (k - 1.5) * 0.2, vals, 0.2, color=colors[g], alpha=1.0 if env == "water" else 0.45,
              hatch=None if env == "water" else "//", label=f"{env}, {g} gains")
    b.set_xticks(x, JOINTS)
    b.set_ylabel("tracking RMS [deg] (left and right averaged)")
    b.set_title("tracking RMS per joint", fontsize=10)
    g = ax[2, 2]
    g.axis("off")
    rows = ["gains (left = right)      start -> tuned"]
    for j in JOINTS:
        rows.append(f"{j}:")
        for n, short in (("proportional_gain", "Kp"), ("derivative_gain", "Kd"), ("co_contraction", "p0"),
                         ("band", "band")):
            key = f"controllers.{j}_left.{n}"
            rows.append(f"  {short:<5}{s['start_gains'][key]:>18} -> {s['tuned_gains'][key]}")
    g.text(0.0, 1.0, "\n".join(rows), va="top", ha="left", family="monospace", fontsize=7.5, transform=g.transAxes)
    legend_in(ax[2, 3], p, b, fontsize=8.5)
    save(fig, path, f"frogsim control-tune: {s['scenario']}, {s['cycles']} gait cycles, board's integer laws; "
                    "angles from the flexed stop, left side drawn")
