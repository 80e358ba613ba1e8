"""The joint-angle controller against the muscles' force hysteresis: the left hip in air, with and
without the Maxwell-slip elements (:mod:`frogsim.physics.hysteresis`).

``hysteresis``: the ``control-joint`` experiments (:mod:`frogsim.studies.control_joint`: the left
hip's antagonistic pair under the compiled joint-angle cascade, body fixed in air; a step from 10
to 30 deg and a 1 Hz sine of 8 deg about 20 deg) at the scenario's co-contraction (3 bar), each
with the force law as the paper has it (no memory) and with hysteresis at the parameter set's
assumed slip force (10 N/bar, half the loop's height per gauge pressure) and at 2.5 times it. Per
run: the angle's tracking error (RMS and max after the settling time), for the step the final
error and overshoot, the valve switchings per second and the air used; for the sine the width of
the loop the joint traces against its setpoint: over the last full period, the angle on the
setpoint's falling pass minus the angle on its rising pass where the setpoint crosses its mean
(its lag and any dead band both open the loop), and the loop's area in the (setpoint, angle) plane.
The slip forces are assumed, not measured (``params/fan2017.toml`` says so): the study shows what a
loop of that size does to the controller, not what the robot's muscles do.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from frogsim._plotting import figure, save
from frogsim.engine.swim import swim
from frogsim.scenario.tables import header
from frogsim.studies.control_joint import ANGLE, EXPERIMENTS, SETPOINT, STEP_AT, TIME, scenario, step_response
from frogsim.studies.registry import StudyData, register

BAR = 1e5
CO_CONTRACTION_BAR = 3.0
#: slip force per gauge pressure of each run [N/bar]: 0 = the law without memory (hysteresis off)
SLIP_N_PER_BAR = (0.0, 10.0, 25.0)
#: the table's run label: the slip force at the co-contraction pressure, c x p0 (half the loop's height)
SLIP = header(f"slip force at {CO_CONTRACTION_BAR:g} bar", "N")
EXTENSOR_TENSION = header("extensor tension", "N")


def _law(slip: float) -> dict:
    if slip == 0.0:
        return {}
    return {"hysteresis": "maxwell-slip", "slip_per_pressure": f"{slip:g} N/bar"}


def setpoint_loop(t, sp, th, period: float) -> dict:
    """Width [deg] and area [deg^2] of the loop the angle th traces against the setpoint sp over the
    last full period (samples on the output grid): the angle where the setpoint falls through its
    mean minus where it rises through it (interpolated between samples), and the area enclosed."""
    last = t >= t[-1] - period - 1e-12
    ref, ang = sp[last], th[last]
    mean = 0.5 * (ref.max() + ref.min())
    a, b = ref[:-1] - mean, ref[1:] - mean
    w = a / np.where(a != b, a - b, 1.0)                       # where the segment crosses the mean
    at = ang[:-1] + w * (ang[1:] - ang[:-1])
    up = at[(a < 0.0) & (b >= 0.0)]
    down = at[(a > 0.0) & (b <= 0.0)]
    width = float(down[-1] - up[-1]) if up.size and down.size else float("nan")
    area = float(abs(0.5 * np.sum(ref * np.roll(ang, -1) - np.roll(ref, -1) * ang)))   # shoelace, closed
    return {"loop_width_deg": width, "loop_area_deg2": area}


@register("hysteresis", "Left hip angle tracking in air with and without the muscles' force hysteresis "
                        "(Maxwell-slip): step and 1 Hz sine, error, loop width at the joint, switchings, air",
          group="control", cost=2.0)
def hysteresis() -> StudyData:
    frames, runs = [], {}
    for slip in SLIP_N_PER_BAR:
        key = "off" if slip == 0.0 else f"{slip:g}_N_per_bar"
        runs[key] = {}
        for exp, e in EXPERIMENTS.items():
            r = swim(scenario(exp, CO_CONTRACTION_BAR, _law(slip), name="hysteresis"))
            m = r.control_metrics()["hip"]
            j = r.joint_names.index("hip_left")
            th = np.degrees(r.joint_angles[:, j])
            sp = np.degrees(r.setpoint("hip"))
            entry = {k: m[k] for k in ("tracking_error_rms_deg", "tracking_error_max_deg", "switchings_per_s",
                                       "air_used_L_std", "settle_s")}
            if exp == "step":
                entry.update(step_response(r.t, th, STEP_AT, e["from_deg"], e["to_deg"]))
                entry["final_error_deg"] = float(e["to_deg"] - th[-1])
            else:
                entry.update(setpoint_loop(r.t, sp, th, 1.0))
            runs[key][exp] = entry
            i_ext = r.muscle_names.index("hip_left")
            frames.append(pd.DataFrame({SLIP: slip * CO_CONTRACTION_BAR, "experiment": exp, TIME: r.t, SETPOINT: sp, ANGLE: th,
                                        EXTENSOR_TENSION: r.tensions[:, i_ext]}))
    off, on = runs["off"], runs[f"{SLIP_N_PER_BAR[1]:g}_N_per_bar"]
    strong = runs[f"{SLIP_N_PER_BAR[2]:g}_N_per_bar"]

    def line(k, x, exp):
        txt = (f"{k.replace('_N_per_bar', ' N/bar')}: {x[exp]['tracking_error_rms_deg']:.2f} deg RMS "
               f"({x[exp]['tracking_error_max_deg']:.2f} max), {x[exp]['switchings_per_s']:.1f} switchings/s, "
               f"{x[exp]['air_used_L_std']:.2f} L std")
        if exp == "step":
            txt += f", final error {x[exp]['final_error_deg']:.2f} deg, overshoot {x[exp]['overshoot_deg']:.1f} deg"
        else:
            txt += f", loop width {x[exp]['loop_width_deg']:.2f} deg"
        return txt

    d_rms = on["sine"]["tracking_error_rms_deg"] - off["sine"]["tracking_error_rms_deg"]
    d_width = on["sine"]["loop_width_deg"] - off["sine"]["loop_width_deg"]
    conclusion = (
        f"Co-contraction {CO_CONTRACTION_BAR:g} bar. Step 10 -> 30 deg: "
        + "; ".join(line(k, x, "step") for k, x in runs.items()) + ". "
        "Sine 20 +- 8 deg at 1 Hz (loop over the last period): "
        + "; ".join(line(k, x, "sine") for k, x in runs.items()) + ". "
        f"The assumed hysteresis ({SLIP_N_PER_BAR[1]:g} N/bar, a loop 2 x {SLIP_N_PER_BAR[1]:g} x "
        f"{CO_CONTRACTION_BAR:g} = {2 * SLIP_N_PER_BAR[1] * CO_CONTRACTION_BAR:g} N high in each muscle) "
        f"{'raises' if d_rms > 0 else 'lowers'} the sine's RMS error by {abs(d_rms):.2f} deg and "
        f"{'widens' if d_width > 0 else 'narrows'} the loop the joint traces against its setpoint by "
        f"{abs(d_width):.2f} deg; at {SLIP_N_PER_BAR[2]:g} N/bar the RMS error is "
        f"{strong['sine']['tracking_error_rms_deg']:.2f} deg and the loop {strong['sine']['loop_width_deg']:.2f} deg "
        f"wide. The slip forces are assumed (no published DMSP-20 force loop with numbers was found), so "
        f"these numbers say how sensitive the tuned controller is to a loop of that size, not how the "
        f"robot behaves.")
    summary = {"hysteresis": {"scenario": "hip-angle-in-air", "joint": "hip_left",
                              "co_contraction_bar_gauge": CO_CONTRACTION_BAR,
                              "slip_per_pressure_N_per_bar": list(SLIP_N_PER_BAR), "runs": runs,
                              "conclusion": conclusion}}
    return StudyData(pd.concat(frames, ignore_index=True), summary)


@hysteresis.draws
def _draw(data: StudyData, path: str) -> None:
    t = data.table
    runs = data.summary["hysteresis"]["runs"]
    colors = dict(zip(SLIP_N_PER_BAR, ("black", "tab:orange", "tab:red")))
    fig, ax = figure(2, 2, width=15.0, height=9.0)
    for col, exp in enumerate(EXPERIMENTS):
        a = ax[0, col]
        sub = t[t["experiment"] == exp]
        first = sub[sub[SLIP] == SLIP_N_PER_BAR[0] * CO_CONTRACTION_BAR]
        a.plot(first[TIME], first[SETPOINT], "k:", lw=1.2, label="setpoint")
        for slip in SLIP_N_PER_BAR:
            s = sub[sub[SLIP] == slip * CO_CONTRACTION_BAR]
            key = "off" if slip == 0.0 else f"{slip:g}_N_per_bar"
            m = runs[key][exp]
            extra = (f", final error {m['final_error_deg']:.2f} deg" if exp == "step"
                     else f", loop {m['loop_width_deg']:.2f} deg wide")
            label = "no hysteresis" if slip == 0.0 else f"hysteresis {slip:g} N/bar"
            a.plot(s[TIME], s[ANGLE], color=colors[slip], lw=1.1,
                   label=f"{label}: {m['tracking_error_rms_deg']:.2f} deg RMS{extra}")
        a.set_title(f"{exp}: left hip angle (co-contraction {CO_CONTRACTION_BAR:g} bar)")
        a.set_xlabel("time [s]")
        a.set_ylabel("hip angle [deg]")
        a.legend(fontsize=8, loc="lower right")
    # the sine's last period: angle against setpoint (the loop seen at the joint)
    a = ax[1, 0]
    sub = t[t["experiment"] == "sine"]
    for slip in SLIP_N_PER_BAR:
        s = sub[(sub[SLIP] == slip * CO_CONTRACTION_BAR) & (sub[TIME] >= sub[TIME].max() - 1.0 - 1e-9)]
        a.plot(s[SETPOINT], s[ANGLE], color=colors[slip], lw=1.1,
               label="no hysteresis" if slip == 0.0 else f"hysteresis {slip:g} N/bar")
    lim = [sub[SETPOINT].min() - 1, sub[SETPOINT].max() + 1]
    a.plot(lim, lim, "k:", lw=0.8, label="angle = setpoint")
    a.set_xlabel("setpoint [deg]")
    a.set_ylabel("hip angle [deg]")
    a.set_title("sine, last period: the loop the joint traces against its setpoint")
    a.legend(fontsize=8)
    # the extensor's tension over the sine's last period against the angle
    a = ax[1, 1]
    for slip in SLIP_N_PER_BAR:
        s = sub[(sub[SLIP] == slip * CO_CONTRACTION_BAR) & (sub[TIME] >= sub[TIME].max() - 1.0 - 1e-9)]
        a.plot(s[ANGLE], s[EXTENSOR_TENSION], color=colors[slip], lw=1.1,
               label="no hysteresis" if slip == 0.0 else f"hysteresis {slip:g} N/bar")
    a.set_xlabel("hip angle [deg]")
    a.set_ylabel("extensor (hip_left) tension [N]")
    a.set_title("sine, last period: the extensor's tension against the angle\n(a loop without hysteresis too: the controller moves the pressures)", fontsize=10)
    a.legend(fontsize=8)
    save(fig, path, "frogsim control hysteresis; slip forces assumed (params/fan2017.toml), angles from the flexed stop")
