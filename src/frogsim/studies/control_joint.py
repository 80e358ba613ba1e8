"""Closed-loop joint-angle control of the left hip's antagonistic pair, in air, at two stiffnesses.

``control-joint``: the robot fixed on its base in air (shipped scenario ``hip-angle-in-air``: the
legs move in the horizontal plane, so gravity does not load the joints), the left hip's driving
and recovery muscles under the compiled joint-angle cascade (docs/control.md: PID on the angle
gives the pressure difference dp, the pair's targets are p0 +- dp/2, each muscle follows its
target by bang-bang), tracking (a) a step from 10 to 30 deg and (b) a 1 Hz sine of 8 deg about
20 deg, each at two co-contraction levels p0 (1.5 and 3.5 bar gauge: a softer and a stiffer
joint). Reports per run the angle tracking error (RMS and max after the settling time), for the
step its 10-90 % rise time and overshoot, the valve switchings per second, the air used and the
samples at which the pressure targets were clipped to [atmosphere, source].
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from frogsim._plotting import figure, legend_in, save
from frogsim.circuit import layout as CL
from frogsim.engine.swim import swim
from frogsim.robot.scenario import load_robot_scenario
from frogsim.scenario.load import merged_raw
from frogsim.scenario.tables import header
from frogsim.studies.registry import StudyData, register

BAR = 1e5
# the study's CSV columns, in the one header convention (frogsim.scenario.tables); "experiment" is a label
TIME = header("time", "s")
CO_CONTRACTION = header("co-contraction", "bar gauge")
SETPOINT = header("setpoint", "deg")
ANGLE = header("angle", "deg")
EXTENSOR_PRESSURE = header("extensor pressure", "bar gauge")
FLEXOR_PRESSURE = header("flexor pressure", "bar gauge")
LEVELS_BAR = (1.5, 3.5)
STEP_AT = 1.0
EXPERIMENTS = {
    "step": {"setpoint": {"kind": "steps", "steps": [{"at": "0 s", "value": "10 deg"},
                                                      {"at": f"{STEP_AT:g} s", "value": "30 deg"}]},
             "period": "2.5 s", "settle": "1.5 s", "from_deg": 10.0, "to_deg": 30.0},
    "sine": {"setpoint": {"kind": "sine", "mean": "20 deg", "amplitude": "8 deg", "frequency": "1 Hz",
                          "start": "1 s"},
             "period": "3 s", "settle": "1.25 s"},
}


def scenario(experiment: str, level_bar: float, muscle_force: dict | None = None, name: str = "control-joint"):
    """The shipped hip-angle-in-air scenario with one experiment's setpoint and one p0, and
    ``muscle_force``'s settings over the parameter set's ``[muscle_force]`` (e.g. its hysteresis)."""
    raw, base = merged_raw("hip-angle-in-air")
    e = EXPERIMENTS[experiment]
    ctl = dict(raw["controllers"]["hip"], setpoint=e["setpoint"], settle=e["settle"],
               co_contraction=f"{level_bar:g} bar")
    return load_robot_scenario({**raw, "name": f"{name}-{experiment}-{level_bar:g}bar",
                                "gait": {**raw["gait"], "period": e["period"]},
                                "muscle_force": {**raw["muscle_force"], **(muscle_force or {})},
                                "controllers": {"hip": ctl}, "base_dir": base})


def step_response(t, th_deg, t0: float, a: float, b: float) -> dict:
    """10-90 % rise time [s] (None: not reached) and overshoot [deg] beyond b of a step a -> b at
    t0 (on the output grid)."""
    after = t >= t0
    tt, x = t[after], th_deg[after]
    frac = (x - a) / (b - a)
    out = {}
    for key, level in (("t10", 0.1), ("t90", 0.9)):
        k = np.nonzero(frac >= level)[0]
        out[key] = float(tt[k[0]]) if k.size else None
    out["rise_time_s"] = out["t90"] - out["t10"] if out["t10"] is not None and out["t90"] is not None else None
    out["overshoot_deg"] = float(max(0.0, (x.max() - b) if b > a else (b - x.min())))
    return out


@register("control-joint", "Left hip angle tracking in air with its antagonistic pair: 10-30 deg step and "
                           "1 Hz sine at two co-contraction levels (error, switchings/s, air)",
          group="control")
def control_joint() -> StudyData:
    frames, runs = [], {}
    for level in LEVELS_BAR:
        key = f"{level:g}_bar"
        runs[key] = {}
        for exp, e in EXPERIMENTS.items():
            r = swim(scenario(exp, level))
            patm = r.atmospheric_pressure
            m = r.control_metrics()["hip"]
            j = r.joint_names.index("hip_left")
            th = np.degrees(r.joint_angles[:, j])
            entry = {k: m[k] for k in ("tracking_error_rms_deg", "tracking_error_max_deg", "switchings_per_s",
                                       "air_used_L_std", "samples_pressure_target_clipped", "settle_s")}
            entry["switchings"] = m["switchings"]
            if exp == "step":
                entry.update(step_response(r.t, th, STEP_AT, e["from_deg"], e["to_deg"]))
                entry["final_error_deg"] = float(e["to_deg"] - th[-1])
            runs[key][exp] = entry
            i_ext, i_flex = (r.muscle_names.index(n) for n in ("hip_left", "hip_left_recovery"))
            frames.append(pd.DataFrame({
                CO_CONTRACTION: level, "experiment": exp, TIME: r.t,
                SETPOINT: np.degrees(r.setpoint("hip")), ANGLE: th,
                EXTENSOR_PRESSURE: (r.pressures[:, i_ext] - patm) / BAR,
                FLEXOR_PRESSURE: (r.pressures[:, i_flex] - patm) / BAR,
                header("extensor charge valve", "1 = open"): r.valves[:, CL.charge_valve(i_ext)],
                header("extensor discharge valve", "1 = open"): r.valves[:, CL.vent_valve(i_ext)],
                header("flexor charge valve", "1 = open"): r.valves[:, CL.charge_valve(i_flex)],
                header("flexor discharge valve", "1 = open"): r.valves[:, CL.vent_valve(i_flex)]}))
    lo, hi = (f"{v:g}_bar" for v in LEVELS_BAR)

    def cmp(exp, k):
        return runs[lo][exp][k], runs[hi][exp][k]

    s_lo, s_hi = cmp("sine", "tracking_error_rms_deg")
    w_lo, w_hi = cmp("sine", "switchings_per_s")
    a_lo, a_hi = cmp("sine", "air_used_L_std")
    better = "stiffer" if s_hi < s_lo else "softer"

    def fmt_rise(x):
        return f"{x * 1e3:.0f} ms" if x is not None else "not reached"

    def line(level_key, exp):
        x = runs[level_key][exp]
        txt = (f"{level_key.replace('_', ' ')}: {x['tracking_error_rms_deg']:.2f} deg RMS "
               f"({x['tracking_error_max_deg']:.2f} max), {x['switchings_per_s']:.1f} switchings/s, "
               f"{x['air_used_L_std']:.2f} L std, targets clipped at {x['samples_pressure_target_clipped']} samples")
        if exp == "step":
            txt += (f", rise {fmt_rise(x['rise_time_s'])}, overshoot {x['overshoot_deg']:.1f} deg, "
                    f"final error {x['final_error_deg']:.2f} deg")
        return txt
    conclusion = (
        f"Step 10 -> 30 deg at {STEP_AT:g} s (errors after {runs[lo]['step']['settle_s']:g} s): "
        + "; ".join(line(k, "step") for k in (lo, hi)) + ". "
        f"Sine 20 +- 8 deg at 1 Hz (after {runs[lo]['sine']['settle_s']:g} s): "
        + "; ".join(line(k, "sine") for k in (lo, hi)) + ". "
        f"On the sine the {better} joint (p0 = {LEVELS_BAR[1] if better == 'stiffer' else LEVELS_BAR[0]:g} bar) "
        f"tracks with the smaller RMS error ({min(s_lo, s_hi):.2f} against {max(s_lo, s_hi):.2f} deg), at "
        f"{w_hi if better == 'stiffer' else w_lo:.1f} against {w_lo if better == 'stiffer' else w_hi:.1f} "
        f"switchings/s; the stiffer joint uses {a_hi / a_lo:.2f} times the air of the softer one "
        f"({a_hi:.2f} against {a_lo:.2f} L std) on the sine, "
        f"{runs[hi]['step']['air_used_L_std'] / runs[lo]['step']['air_used_L_std']:.2f} times on the step. "
        f"With the same gains, raising p0 {'did not reduce' if s_hi >= s_lo else 'reduced'} the tracking error "
        f"here; a pressure target p0 +- dp/2 left [atmosphere, source] (clipped) at "
        f"{runs[lo]['sine']['samples_pressure_target_clipped']} of the sine's controller samples at "
        f"p0 = {LEVELS_BAR[0]:g} bar, at {runs[hi]['sine']['samples_pressure_target_clipped']} at "
        f"{LEVELS_BAR[1]:g} bar.")
    summary = {"control_joint": {"scenario": "hip-angle-in-air", "joint": "hip_left",
                                 "co_contraction_levels_bar_gauge": list(LEVELS_BAR), "runs": runs,
                                 "conclusion": conclusion}}
    return StudyData(pd.concat(frames, ignore_index=True), summary)


@control_joint.draws
def _draw(data: StudyData, path: str) -> None:
    t = data.table
    colors = {LEVELS_BAR[0]: "tab:blue", LEVELS_BAR[1]: "tab:red"}
    # a third, narrow column holds the pressure panels' legend (the same entries for both): the
    # pressures fill their panels, so a legend inside would cover a curve
    fig, ax = figure(2, 3, width=17.0, height=8.0, gridspec_kw={"height_ratios": [3, 2], "width_ratios": [1, 1, 0.2]})
    ax[0, 2].axis("off")
    runs = data.summary["control_joint"]["runs"]
    for col, exp in enumerate(EXPERIMENTS):
        a, b = ax[0, col], ax[1, col]
        sub = t[t["experiment"] == exp]
        first = sub[sub[CO_CONTRACTION] == LEVELS_BAR[0]]
        a.plot(first[TIME], first[SETPOINT], "k--", lw=1.5, label="setpoint")
        for level in LEVELS_BAR:
            s = sub[sub[CO_CONTRACTION] == level]
            m = runs[f"{level:g}_bar"][exp]
            a.plot(s[TIME], s[ANGLE], color=colors[level], lw=1.2,
                   label=f"p0 = {level:g} bar: {m['tracking_error_rms_deg']:.2f} deg RMS, "
                         f"{m['switchings_per_s']:.0f} sw/s, {m['air_used_L_std']:.2f} L")
            b.plot(s[TIME], s[EXTENSOR_PRESSURE], color=colors[level], lw=1,
                   label=f"extensor, p0 = {level:g} bar")
            b.plot(s[TIME], s[FLEXOR_PRESSURE], color=colors[level], lw=1, ls=":",
                   label=f"flexor, p0 = {level:g} bar")
        a.set_title(f"{exp}: left hip angle against the setpoint")
        a.set_ylabel("hip angle [deg]")
        a.legend(fontsize=8, loc="lower right")
        b.set_xlabel("time [s]")
        b.set_ylabel("pressure [bar gauge]")
        b.set_title("the pair's pressures (solid: extensor hip_left, dotted: flexor hip_left_recovery)",
                    fontsize=9)
    legend_in(ax[1, 2], ax[1, 0], fontsize=8)
    save(fig, path, "frogsim control-joint; angles from the flexed stop, pressures gauge")

