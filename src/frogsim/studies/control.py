"""Closed-loop pressure control of one hip muscle: PWM, bang-bang and sliding mode compared.

``control-pressure``: the hip muscle (DMSP-20, 180 mm, held at its rest length so its volume is
constant) fed from the paper's 6 bar source through its MHJ9 valves (2 ms dead time, 1 kHz
controller), tracking (a) a 3 bar step and (b) a 0.5 Hz sine between 2 and 4 bar, under each of
the three compiled laws of :mod:`frogsim.control.sampled` (docs/control.md). Reports per run the
tracking error (RMS and max after the settling time), the valve switchings per second and the air
used, and says whether sliding mode tracks the sine with fewer switchings than bang-bang at no
worse RMS error.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.ticker import LogLocator, NullFormatter, StrMethodFormatter

from frogsim._plotting import away_from, figure, legend_in, save
from frogsim.engine.pneumatic import simulate
from frogsim.scenario.load import load_scenario
from frogsim.scenario.tables import header
from frogsim.studies.registry import StudyData, register

BAR = 1e5
# the study's CSV columns, in the one header convention (frogsim.scenario.tables); "experiment" and
# "controller" are labels
TIME = header("time", "s")
SETPOINT = header("setpoint", "bar gauge")
PRESSURE = header("pressure", "bar gauge")
CHARGE_VALVE = header("charge valve", "1 = open")
DISCHARGE_VALVE = header("discharge valve", "1 = open")
CONTROLLERS = {
    "pwm": {"kind": "pwm", "frequency": "50 Hz", "proportional_band": "0.5 bar"},
    "bang-bang": {"kind": "bang-bang", "band": "0.1 bar"},
    "sliding-mode": {"kind": "sliding-mode", "horizon": "2 ms", "penalty": "0.05 bar"},
}
BANDS_BAR = (0.05, 0.08, 0.1, 0.12, 0.15, 0.2, 0.3)
PENALTIES_BAR = (0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.1, 0.15)
EXPERIMENTS = {
    "step": {"setpoint": {"kind": "steps", "steps": [{"at": "0 s", "value": "0 bar"},
                                                      {"at": "0.1 s", "value": "3 bar"}]},
             "duration": "1.5 s", "settle": "0.5 s", "initial": "0 bar"},
    "sine": {"setpoint": {"kind": "sine", "mean": "3 bar", "amplitude": "1 bar", "frequency": "0.5 Hz"},
             "duration": "4 s", "settle": "0.25 s", "initial": "3 bar"},
}


def scenario(experiment: str, controller: str):
    """The scenario of one run: the hip at rest length under one controller."""
    e, c = EXPERIMENTS[experiment], CONTROLLERS[controller]
    return load_scenario({
        "name": f"control-{experiment}-{controller}", "duration": e["duration"], "output_interval": "1 ms",
        "muscles": {"hip": {"type": "hip", "motion": {"kind": "constant"}, "initial_pressure_gauge": e["initial"]}},
        "controllers": {"hip": {**c, "muscle": "hip", "setpoint": e["setpoint"], "settle": e["settle"]}}})


@register("control-pressure", "Hip pressure control: 3 bar step and 0.5 Hz 2-4 bar sine under PWM, bang-bang "
                              "and sliding mode (tracking error, switchings/s, air)", group="control")
def control_pressure() -> StudyData:
    frames, metrics = [], {}
    for exp in EXPERIMENTS:
        metrics[exp] = {}
        for ctl in CONTROLLERS:
            r = simulate(scenario(exp, ctl))
            patm = r.atmospheric_pressure
            m = r.control_metrics()["hip"]
            metrics[exp][ctl] = {k: m[k] for k in ("tracking_error_rms_bar", "tracking_error_max_bar",
                                                   "switchings_per_s", "switchings", "air_used_L_std", "settle_s")}
            frames.append(pd.DataFrame({
                "experiment": exp, "controller": ctl, TIME: r.t,
                SETPOINT: (r.setpoint("hip") - patm) / BAR,
                PRESSURE: (r.muscle_pressure("hip") - patm) / BAR,
                CHARGE_VALVE: r.u[:, 0], DISCHARGE_VALVE: r.u[:, 1]}))
    # the trade-off on the sine: bang-bang's band and sliding mode's penalty swept
    trade = {"bang-bang": [], "sliding-mode": []}
    for ctl, key, values in (("bang-bang", "band", BANDS_BAR), ("sliding-mode", "penalty", PENALTIES_BAR)):
        base = scenario("sine", ctl)
        for v in values:
            m = simulate(base.replace({f"controllers.hip.{key}": v * BAR})).control_metrics()["hip"]
            trade[ctl].append({f"{key}_bar": v, "tracking_error_rms_bar": m["tracking_error_rms_bar"],
                               "switchings_per_s": m["switchings_per_s"], "air_used_L_std": m["air_used_L_std"]})
    beaten = [b for b in trade["bang-bang"]
              if any(s["tracking_error_rms_bar"] <= b["tracking_error_rms_bar"]
                     and s["switchings_per_s"] < b["switchings_per_s"] for s in trade["sliding-mode"])]
    sine = metrics["sine"]
    sm, bb = sine["sliding-mode"], sine["bang-bang"]
    fewer = sm["switchings_per_s"] < bb["switchings_per_s"]
    no_worse = sm["tracking_error_rms_bar"] <= bb["tracking_error_rms_bar"]
    verdict = ("yes" if fewer and no_worse else "no")
    why = []
    if not fewer:
        why.append("it switches more often")
    if not no_worse:
        why.append("its RMS error is larger")

    def line(exp, ctl):
        x = metrics[exp][ctl]
        return (f"{ctl} {x['tracking_error_rms_bar'] * 1e3:.1f} mbar RMS ({x['tracking_error_max_bar'] * 1e3:.0f} max), "
                f"{x['switchings_per_s']:.1f} switchings/s, {x['air_used_L_std']:.2f} L std")
    conclusion = (
        f"Sine 2-4 bar at 0.5 Hz (after {sine['bang-bang']['settle_s']:g} s): "
        + "; ".join(line("sine", c) for c in CONTROLLERS) + ". "
        f"Does sliding mode track the sine with fewer switchings per second than bang-bang at no worse "
        f"RMS error? {verdict}: {sm['switchings_per_s']:.1f} against {bb['switchings_per_s']:.1f} switchings/s, "
        f"{sm['tracking_error_rms_bar'] * 1e3:.1f} against {bb['tracking_error_rms_bar'] * 1e3:.1f} mbar RMS"
        + (f" ({' and '.join(why)})" if why else "") + ". "
        f"3 bar step (after {metrics['step']['bang-bang']['settle_s']:g} s): "
        + "; ".join(line("step", c) for c in CONTROLLERS) + ". "
        f"Swept on the sine (bang-bang band {BANDS_BAR[0]:g}-{BANDS_BAR[-1]:g} bar, sliding-mode penalty "
        f"{PENALTIES_BAR[0]:g}-{PENALTIES_BAR[-1]:g} bar): {len(beaten)} of the {len(trade['bang-bang'])} "
        f"bang-bang settings are beaten by a sliding-mode setting (no larger RMS error and fewer "
        f"switchings/s)" + (f" (bands {', '.join(format(b['band_bar'], 'g') for b in beaten)} bar)" if beaten else "")
        + "; in this sweep neither law dominates the other: they trade error against switching along "
        "crossing curves (figure, right).")
    summary = {"control_pressure": {"runs": metrics, "sliding_mode_fewer_switchings_no_worse_rms": verdict == "yes",
                                    "sine_tradeoff": trade, "bang_bang_settings_beaten_by_sliding_mode": len(beaten),
                                    "conclusion": conclusion}}
    return StudyData(pd.concat(frames, ignore_index=True), summary, {"trade": trade})


@control_pressure.draws
def _draw(data: StudyData, path: str) -> None:
    t = data.table
    colors = {"pwm": "tab:green", "bang-bang": "tab:blue", "sliding-mode": "tab:red"}
    fig, ax = figure(2, 3, width=18.0, height=7.5, gridspec_kw={"height_ratios": [3, 1.6],
                                                                "width_ratios": [1, 1.4, 0.9]})
    runs = data.summary["control_pressure"]["runs"]
    for col, exp in enumerate(EXPERIMENTS):
        a, b = ax[0, col], ax[1, col]
        sub = t[t["experiment"] == exp]
        first = sub[sub["controller"] == "bang-bang"]
        a.plot(first[TIME], first[SETPOINT], "k--", lw=1.5, label="setpoint")
        for k, ctl in enumerate(CONTROLLERS):
            s = sub[sub["controller"] == ctl]
            m = runs[exp][ctl]
            a.plot(s[TIME], s[PRESSURE], color=colors[ctl], lw=1,
                   label=f"{ctl}: {m['tracking_error_rms_bar'] * 1e3:.0f} mbar RMS, {m['switchings_per_s']:.0f} sw/s")
            b.step(s[TIME], s[CHARGE_VALVE] * 0.8 + k, where="post", color=colors[ctl], lw=0.6)
            b.step(s[TIME], -s[DISCHARGE_VALVE] * 0.4 + k, where="post", color=colors[ctl], lw=0.6, ls=":")
        a.set_title(f"{exp}: hip pressure against the setpoint")
        a.set_ylabel("pressure [bar gauge]")
        # below the axes: the sine fills its panel, a legend inside would cover a trough
        a.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=2, frameon=False)
        b.set_yticks(range(len(CONTROLLERS)), list(CONTROLLERS), fontsize=8)
        b.set_xlabel("time [s]")
        b.set_title("valves: up = charge open, dotted down = vent open", fontsize=9)
    c = ax[0, 2]
    # log axes: the settings span a decade and more of both, and the middle ones crowd on linear axes
    curves = {}
    for ctl, key in (("bang-bang", "band_bar"), ("sliding-mode", "penalty_bar")):
        pts = data.extras["trade"][ctl]
        xy = np.array([[p["switchings_per_s"], p["tracking_error_rms_bar"] * 1e3] for p in pts])
        c.plot(xy[:, 0], xy[:, 1], "o-", color=colors[ctl], label=f"{ctl} ({key.split('_')[0]} swept, bar)")
        curves[ctl] = (xy, [f"{p[key]:g}" for p in pts])
    c.set_xscale("log")
    c.set_yscale("log")
    c.margins(x=0.15, y=0.1)
    for ctl, (xy, texts) in curves.items():
        other = np.vstack([v[0] for k, v in curves.items() if k != ctl])
        for (x, y), text, (dx, dy) in zip(xy, texts, away_from(c, xy, other)):
            c.annotate(text, (x, y), xytext=(7 * dx, 7 * dy), textcoords="offset points", fontsize=7,
                       color=colors[ctl], ha="left" if dx > 0.3 else "right" if dx < -0.3 else "center",
                       va="bottom" if dy > 0.3 else "top" if dy < -0.3 else "center")
    for axis in (c.xaxis, c.yaxis):
        axis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        axis.set_major_formatter(StrMethodFormatter("{x:g}"))
        axis.set_minor_formatter(NullFormatter())
    c.set_xlabel("valve switchings per second (log scale)")
    c.set_ylabel("RMS tracking error [mbar] (log scale)")
    c.set_title("sine: error against switching (labels: bar)", fontsize=10)
    legend_in(ax[1, 2], c, fontsize=8)
    save(fig, path, "frogsim control-pressure; pressures gauge")
