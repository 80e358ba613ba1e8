"""Wall heat transfer against the paper's adiabatic model: what it changes for a valve controller.

``heat``: each of three runs twice, with the paper's adiabatic parameter set ``fan2017`` and with
``fan2017-heat`` (the same robot, Newton heat transfer through the walls of the muscles (20
W/(m^2 K)), the source tanks and the exhaust space (10 W/(m^2 K)), the walls at 293.15 K;
:mod:`frogsim.physics.heat`):

- ``paper-cycle``: the shipped scenario (six muscles, 1 s pressurise / 1 s release from 6 bar):
  the air a stroke takes from the source (all six charge valves, litres at the ISO reference
  state) and the hip's air temperature;
- ``hold-6bar``: one hip at rest length charged for 0.3 s straight from the 6 bar source (no
  supply limit), then both valves closed for 1.7 s: how far the held pressure sags;
- ``bang-bang-3bar``: the same hip under the bang-bang controller of ``control-pressure``
  (0.1 bar band, 1 kHz) holding a 3 bar step for 4 s: valve switchings per second and air used.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from frogsim._plotting import figure, save
from frogsim.circuit import layout as L
from frogsim.engine.pneumatic import simulate
from frogsim.scenario.load import load_scenario, read_toml, scenario_path
from frogsim.scenario.tables import header
from frogsim.studies.control import CONTROLLERS, EXPERIMENTS
from frogsim.studies.registry import StudyData, register

BAR = 1e5
MODELS = {"adiabatic": "fan2017", "heat": "fan2017-heat"}
TIME = header("time", "s")
PRESSURE = header("hip pressure", "bar gauge")
TEMPERATURE = header("hip temperature", "K")
CHARGE_VALVE = header("charge valve", "1 = open")
DISCHARGE_VALVE = header("discharge valve", "1 = open")
HOLD_CLOSE_S = 0.3            # the hold run's charge ends (command); its valves close 2 ms later
HOLD_END_S = 2.0
BANG_BANG_S = 4.0


def scenarios(parameters: str) -> dict:
    """The three runs of the study over a parameter set, by experiment name."""
    raw = read_toml(scenario_path("paper-cycle"), "scenario")
    raw["parameters"] = parameters
    hip = {"type": "hip", "motion": {"kind": "constant"}}
    hold = {"name": "heat-hold-6bar", "parameters": parameters, "duration": f"{HOLD_END_S!r} s",
            "output_interval": "1 ms", "supply": {"mode": "none"},
            "programs": {"charge-hold": {"steps": [{"at": "0 s", "state": "charge"},
                                                   {"at": f"{HOLD_CLOSE_S!r} s", "state": "hold"}]}},
            "muscles": {"hip": {**hip, "program": "charge-hold"}}}
    step = EXPERIMENTS["step"]
    bang = {"name": "heat-bang-bang-3bar", "parameters": parameters, "duration": f"{BANG_BANG_S!r} s",
            "output_interval": "1 ms", "muscles": {"hip": {**hip, "initial_pressure_gauge": step["initial"]}},
            "controllers": {"hip": {**CONTROLLERS["bang-bang"], "muscle": "hip", "setpoint": step["setpoint"],
                                    "settle": step["settle"]}}}
    return {"paper-cycle": load_scenario(raw), "hold-6bar": load_scenario(hold),
            "bang-bang-3bar": load_scenario(bang)}


def _frame(experiment: str, model: str, r, muscle: str) -> pd.DataFrame:
    patm = r.atmospheric_pressure
    i = r.index(muscle)
    return pd.DataFrame({"experiment": experiment, "mode": model, TIME: r.t,
                         PRESSURE: (r.muscle_pressure(muscle) - patm) / BAR, TEMPERATURE: r.temperature(muscle),
                         CHARGE_VALVE: r.u[:, L.charge_valve(i)], DISCHARGE_VALVE: r.u[:, L.vent_valve(i)]})


@register("heat", "Wall heat transfer against the adiabatic paper model: paper cycle, 6 bar hold, bang-bang "
                  "3 bar hold (pressure sag, air per stroke, switchings/s, air)", group="control", cost=2.0)
def heat_study() -> StudyData:
    frames, runs = [], {}
    for model, params in MODELS.items():
        sc = scenarios(params)
        paper = simulate(sc["paper-cycle"])
        air = sum(paper.charged_mass(m)[-1] - paper.charged_mass(m)[0] for m in paper.names)
        T_hip = paper.temperature("hip_left")
        k1 = int(np.searchsorted(paper.t, 1.0))
        hold = simulate(sc["hold-6bar"])
        p_hold = (hold.muscle_pressure("hip") - hold.atmospheric_pressure) / BAR
        closed = hold.t > HOLD_CLOSE_S + sc["hold-6bar"].valves.charge.dead_time
        p_close = float(p_hold[closed][0])
        bang = simulate(sc["bang-bang-3bar"])
        m = bang.control_metrics()["hip"]
        opened = np.flatnonzero(np.diff(bang.u[:, 0]) > 0.5) + 1          # charge valve opening samples
        last = int(np.count_nonzero(bang.t[opened] > BANG_BANG_S - 1.0))
        runs[model] = {
            "parameters": params,
            "paper_cycle_air_per_stroke_L_std": float(air / paper.reference_density * 1e3),
            "paper_cycle_hip_peak_temperature_K": float(T_hip.max()),
            "paper_cycle_hip_temperature_at_1s_K": float(T_hip[k1]),
            "paper_cycle_hip_lowest_temperature_K": float(T_hip.min()),
            "hold_pressure_at_close_bar_gauge": p_close,
            "hold_temperature_at_close_K": float(hold.temperature("hip")[closed][0]),
            "hold_pressure_at_end_bar_gauge": float(p_hold[-1]),
            "hold_pressure_sag_bar": p_close - float(p_hold[-1]),
            "hold_pressure_sag_percent_of_gauge": 100.0 * (p_close - float(p_hold[-1])) / p_close,
            "bang_bang_switchings_per_s": m["switchings_per_s"],
            "bang_bang_charge_valve_openings": int(opened.size),
            "bang_bang_charge_openings_last_second": last,
            "bang_bang_air_used_L_std": m["air_used_L_std"],
            "bang_bang_tracking_error_rms_bar": m["tracking_error_rms_bar"],
        }
        frames += [_frame("paper-cycle", model, paper, "hip_left"), _frame("hold-6bar", model, hold, "hip"),
                   _frame("bang-bang-3bar", model, bang, "hip")]
    a, h = runs["adiabatic"], runs["heat"]
    more_air = 100.0 * (h["paper_cycle_air_per_stroke_L_std"] / a["paper_cycle_air_per_stroke_L_std"] - 1.0)
    conclusion = (
        f"With the walls exchanging heat (fan2017-heat) instead of the paper's adiabatic volumes (fan2017): "
        f"a hip charged to {a['hold_pressure_at_close_bar_gauge']:.2f} bar and held closed keeps its pressure "
        f"when adiabatic but sags by {h['hold_pressure_sag_bar']:.2f} bar "
        f"({h['hold_pressure_sag_percent_of_gauge']:.0f} % of its gauge pressure) in "
        f"{HOLD_END_S - HOLD_CLOSE_S:.1f} s as its air cools from {h['hold_temperature_at_close_K']:.0f} K "
        f"towards the wall's 293 K; the paper cycle's stroke takes {h['paper_cycle_air_per_stroke_L_std']:.2f} L std "
        f"of air instead of {a['paper_cycle_air_per_stroke_L_std']:.2f} ({more_air:+.1f} %), the held hip "
        f"reaching {h['paper_cycle_hip_temperature_at_1s_K']:.0f} K at the end of its charge instead of "
        f"{a['paper_cycle_hip_temperature_at_1s_K']:.0f} K; and the bang-bang controller holding 3 bar switches "
        f"{h['bang_bang_switchings_per_s']:.1f} times per second ({h['bang_bang_charge_valve_openings']} charge "
        f"openings in {BANG_BANG_S:g} s) instead of {a['bang_bang_switchings_per_s']:.1f} "
        f"({a['bang_bang_charge_valve_openings']}: it charges once and holds), using "
        f"{h['bang_bang_air_used_L_std']:.3f} L std of air instead of {a['bang_bang_air_used_L_std']:.3f}; "
        f"the recharges thin out as the held air nears the wall temperature (charge openings in the last "
        f"second: {h['bang_bang_charge_openings_last_second']}). "
        "A controller tuned on the adiabatic model under-counts its valve wear and its air.")
    summary = {"heat": {"runs": runs, "air_per_stroke_increase_percent": more_air, "conclusion": conclusion}}
    return StudyData(pd.concat(frames, ignore_index=True), summary)


@heat_study.draws
def _draw(data: StudyData, path: str) -> None:
    t = data.table
    runs = data.summary["heat"]["runs"]
    colors = {"adiabatic": "tab:blue", "heat": "tab:red"}
    fig, ax = figure(2, 3, width=18.0, height=8.0, gridspec_kw={"height_ratios": [3, 1.4]})
    titles = {"paper-cycle": "paper cycle: hip_left", "hold-6bar": "hip charged 0.3 s, then held closed",
              "bang-bang-3bar": "bang-bang holding 3 bar (0.1 bar band)"}
    for col, exp in enumerate(titles):
        a, b = ax[0, col], ax[1, col]
        for model, c in colors.items():
            s = t[(t["experiment"] == exp) & (t["mode"] == model)]
            r = runs[model]
            label = {"paper-cycle": f"{model}: {r['paper_cycle_air_per_stroke_L_std']:.2f} L std per stroke",
                     "hold-6bar": f"{model}: sag {r['hold_pressure_sag_bar']:.2f} bar",
                     "bang-bang-3bar": f"{model}: {r['bang_bang_switchings_per_s']:.1f} switchings/s, "
                                       f"{r['bang_bang_air_used_L_std']:.3f} L std"}[exp]
            a.plot(s[TIME], s[PRESSURE], color=c, lw=1.2, label=label)
            b.plot(s[TIME], s[TEMPERATURE], color=c, lw=1.2, label=model)
        a.set_title(titles[exp])
        a.set_ylabel("pressure [bar gauge]")
        a.legend(fontsize=8, loc="lower right" if exp != "paper-cycle" else "center right")
        b.axhline(293.15, color="k", lw=0.6, ls=":")
        b.set_ylabel("air temperature [K]")
        b.set_xlabel("time [s]")
        # no legend: the temperatures fill their panels; their colours are the pressures' above
    save(fig, path, "frogsim heat; pressures gauge; temperatures coloured as the pressures above; "
                    "walls at 293.15 K (dotted)")
