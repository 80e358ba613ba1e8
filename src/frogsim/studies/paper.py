"""The paper's studies (Sec. 4.2-4.3, Figs. 13-17), the aeration volumes, and the tube modes.

All start from the shipped scenario ``paper-cycle`` (six driving muscles, 6 bar source, 1 s
pressurise / 1 s release) and change one thing at a time by dotted path.
"""
from __future__ import annotations

import functools

import numpy as np
import pandas as pd

from frogsim.circuit import layout as L
from frogsim.circuit.model import branch_limit_standard
from frogsim.engine.measures import format_rise
from frogsim.engine.pneumatic import simulate
from frogsim.scenario.load import load_scenario
from frogsim.scenario.schema import Motion, Program
from frogsim.scenario.tables import header
from frogsim._plotting import figure, save, shade_valve_phases
from frogsim.studies.registry import StudyData, register

BASE = "paper-cycle"
HIP = "hip_left"
BAR = 1e5
SOURCE_PRESSURES_BAR = (3, 4, 5, 6)                       # paper Fig. 15
VOLUME_CONSTANTS_PERCENT = (0, 25, 50, 75, 100)            # paper Fig. 16: 0 %..100 %
BRANCH_LIMITS_L_PER_MIN = (15, 30, 45, 60, 90, 120, 180)   # paper Fig. 17: several saturations
L_PER_MIN = 1e-3 / 60.0
NOTE = "frogsim, parameter set fan2017; pressures gauge"
PAPER_AERATION_L = {"hip": 0.455, "knee": 0.401, "ankle": 0.401}   # paper Sec. 4.2
# the studies' CSV columns, in the one header convention (frogsim.scenario.tables)
TIME = header("time", "s")
HIP_PRESSURE = header("hip pressure", "bar gauge")
HIP_VOLUME = header("hip volume", "cm^3")
HIP_CHARGE_FLOW = header("hip charge flow", "L/min std")
EXHAUST_PRESSURE = header("exhaust pressure", "bar gauge")
SOURCE_PRESSURE = header("source pressure", "bar gauge")
SOURCE_TEMPERATURE = header("source temperature", "K")
SIMULATED_L, PAPER_L, DIFFERENCE = (header("simulated aeration volume", "L std"),
                                    header("paper aeration volume", "L std"), header("difference", "%"))


def _fig15_column(ps, label: str) -> str:
    return header(f"hip pressure {ps} bar source {label}", "bar gauge")


def _fig16_column(frac, label: str) -> str:
    return header(f"hip pressure {frac} % volume constant {label}", "bar gauge")


def _fig17_column(q) -> str:
    return header(f"hip pressure {q} L/min branch limit", "bar gauge")


def _tube_column(signal: str, mode: str, label: str) -> str:
    """A tube-modes column: signal "charge flow" [L/min std] or "pressure" [bar gauge]."""
    unit = "L/min std" if signal == "charge flow" else "bar gauge"
    return header(f"hip {signal} {mode} mode {label.replace('_', ' ')} open", unit)


@functools.lru_cache(maxsize=1)
def _base():
    """The base scenario, read once (scenarios are immutable; variants are made from it)."""
    return load_scenario(BASE)


def run(changes: dict | None = None):
    """Simulate a variant of the base scenario (dotted path -> SI value or typed table)."""
    return simulate(_base().replace(changes or {}))


def gauge_bar(result, p):
    return (p - result.atmospheric_pressure) / BAR


def rise_entry(result, muscle=HIP, key="rise_time_90_s") -> dict:
    """{key: rise time [s] or None when not reached, key_reason: None or why not} (docs/metrics.md)."""
    rise = result.rise(muscle)
    reason = rise.reason(0)
    return {key: None if reason else float(rise.seconds[0]),
            key.removesuffix("_s") + "_reason": reason}


def final_pressure_bar(result, muscle=HIP) -> float:
    """Muscle pressure when the charge valve closes [bar gauge]."""
    return float(gauge_bar(result, result.pressure_at_close(muscle)))


# --- Figures 13 and 14: the cycle ------------------------------------------------------------------
@register("fig13", "Hip muscle pressure over the 1 s pressurise / 1 s release cycle (paper Fig. 13)")
def fig13() -> StudyData:
    r = run()
    table = pd.DataFrame({
        TIME: r.t,
        HIP_PRESSURE: gauge_bar(r, r.muscle_pressure(HIP)),
        HIP_VOLUME: r.volumes[:, r.index(HIP)] * 1e6,
        HIP_CHARGE_FLOW: r.charge_flow(HIP) / r.reference_density / L_PER_MIN,
        header("hip charge valve", "1 = open"): r.u[:, L.charge_valve(r.index(HIP))],
        header("hip discharge valve", "1 = open"): r.u[:, L.vent_valve(r.index(HIP))],
        EXHAUST_PRESSURE: gauge_bar(r, r.exhaust_pressure),
    })
    return StudyData(table, {"hip_cycle": {
        **rise_entry(r),
        "final_muscle_pressure_bar_gauge": final_pressure_bar(r),
        "end_pressure_after_release_bar_gauge": float(table[HIP_PRESSURE].iloc[-1]),
        "exhaust_pressure_end_bar_gauge": float(table[EXHAUST_PRESSURE].iloc[-1]),
    }}, {"window": r.pressurise_window(HIP)})


@fig13.draws
def _draw13(data: StudyData, path: str) -> None:
    d = data.table
    fig, ax = figure(2, 1, height=5.6, sharex=True)
    a, b = ax[0, 0], ax[1, 0]
    shade_valve_phases(a, *data.extras["window"])
    a.plot(d[TIME], d[HIP_PRESSURE], lw=2, label="hip muscle")
    a.plot(d[TIME], d[EXHAUST_PRESSURE], lw=1, ls="--", label="exhaust chamber")
    a.set_ylabel("pressure [bar gauge]")
    a.set_title("Hip muscle pressure, 1 s pressurise / 1 s release from 6 bar (cf. paper Fig. 13)")
    a.legend(loc="upper right")
    b.plot(d[TIME], d[HIP_CHARGE_FLOW], color="tab:green", label="charge flow")
    b.set_ylabel("charge flow [L/min standard]")
    b2 = b.twinx()
    b2.plot(d[TIME], d[HIP_VOLUME], color="tab:purple", lw=1, label="muscle volume")
    b2.set_ylabel("volume [cm$^3$]", color="tab:purple")
    b.set_xlabel("time [s]")
    lines, labels = b.get_legend_handles_labels()
    more, more_labels = b2.get_legend_handles_labels()
    b.legend(lines + more, labels + [f"{lb} (right axis)" for lb in more_labels], loc="center right",
             fontsize=9)          # every curve of both axes; beside the flat stretch after 1.5 s
    save(fig, path, NOTE)


@register("fig14", "Source chamber pressure over the cycle (paper Fig. 14)")
def fig14() -> StudyData:
    r = run()
    ps = gauge_bar(r, r.source_pressure)
    table = pd.DataFrame({TIME: r.t, SOURCE_PRESSURE: ps, SOURCE_TEMPERATURE: r.temperature("source")})
    return StudyData(table, {"source_chamber": {
        "pressure_drop_bar": float(ps[0] - ps.min()),
        "initial_pressure_bar_gauge": float(ps[0]),
        "final_pressure_bar_gauge": float(ps[-1]),
        "temperature_drop_K": float(table[SOURCE_TEMPERATURE].iloc[0] - table[SOURCE_TEMPERATURE].min()),
    }}, {"window": r.pressurise_window(HIP)})


@fig14.draws
def _draw14(data: StudyData, path: str) -> None:
    d = data.table
    fig, ax = figure(2, 1, height=6.0, sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    a, b = ax[0, 0], ax[1, 0]
    for axis in (a, b):
        shade_valve_phases(axis, *data.extras["window"])
    a.plot(d[TIME], d[SOURCE_PRESSURE], lw=2, label="source chamber (4 L)")
    a.set_ylabel("pressure [bar gauge]")
    drop = data.summary["source_chamber"]["pressure_drop_bar"]
    a.set_title(f"Source chamber pressure: six muscles charged at once, drop {drop:.2f} bar (cf. Fig. 14)")
    a.legend(loc="upper right")
    cool = data.summary["source_chamber"]["temperature_drop_K"]
    b.plot(d[TIME], d[SOURCE_TEMPERATURE], color="tab:red", lw=1.5)
    b.set_ylabel("temperature [K]")
    b.set_xlabel("time [s]")
    b.set_title(f"Source chamber temperature: adiabatic expansion cools it by {cool:.1f} K", fontsize=10)
    save(fig, path, NOTE)


# --- Figure 15: source pressure ----------------------------------------------------------------------
@register("fig15", "Hip muscle pressure for source pressures 3-6 bar, with and without saturation (Fig. 15)")
def fig15() -> StudyData:
    cols = {}
    summary = {"saturated": [], "unsaturated": []}
    for label, mode in (("saturated", "paper"), ("unsaturated", "none")):
        for ps in SOURCE_PRESSURES_BAR:
            r = run({"source.initial_pressure_gauge": ps * BAR, "supply.mode": mode})
            cols.setdefault(TIME, r.t)
            cols[_fig15_column(ps, label)] = gauge_bar(r, r.muscle_pressure(HIP))
            summary[label].append({"source_pressure_bar_gauge": ps, **rise_entry(r),
                                   "final_muscle_pressure_bar_gauge": final_pressure_bar(r)})
    return StudyData(pd.DataFrame(cols), {"source_pressure_sweep": summary})


def _draw_saturation_panels(d, curves, suptitle: str, path: str) -> None:
    """Hip pressure curves in two panels, (a) with and (b) without the Eq. (9) saturation.

    ``curves(label)`` yields (column of d, legend text) for label "saturated" or "unsaturated".
    """
    fig, ax = figure(1, 2, width=11, sharey=True)
    for a, label, title in ((ax[0, 0], "saturated", "(a) with saturation (Eq. 9 branch limit)"),
                            (ax[0, 1], "unsaturated", "(b) without saturation")):
        for column, text in curves(label):
            a.plot(d[TIME], d[column], label=text)
        a.set_xlim(0, 1.05)
        a.set_title(title)
        a.set_xlabel("time [s]")
        a.legend(loc="lower right", fontsize=8)
    ax[0, 0].set_ylabel("hip muscle pressure [bar gauge]")
    fig.suptitle(suptitle)
    save(fig, path, NOTE)


@fig15.draws
def _draw15(data: StudyData, path: str) -> None:
    def curves(label):
        for e in data.summary["source_pressure_sweep"][label]:
            ps = e["source_pressure_bar_gauge"]
            yield (_fig15_column(ps, label),
                   f"source {ps} bar: 90 % rise {format_rise(e['rise_time_90_s'], 2)}")
    _draw_saturation_panels(data.table, curves,
                            "Hip muscle pressurising under various source pressures (cf. paper Fig. 15)", path)


# --- Figure 16: muscle volume ------------------------------------------------------------------------
@register("fig16", "Hip muscle pressure for muscle volume constants 0-100 % (paper Fig. 16)")
def fig16() -> StudyData:
    cols = {}
    entries = []
    for frac in VOLUME_CONSTANTS_PERCENT:
        entry = {"volume_constant_percent": frac}
        for label, mode in (("saturated", "paper"), ("unsaturated", "none")):
            over = {"supply.mode": mode}
            for m in _base().muscles:
                over[f"muscles.{m}.motion"] = Motion("volume_constant", fraction=frac / 100.0)
            r = run(over)
            cols.setdefault(TIME, r.t)
            cols[_fig16_column(frac, label)] = gauge_bar(r, r.muscle_pressure(HIP))
            key = "rise_time_90_s" if label == "saturated" else "unsaturated_rise_time_90_s"
            entry.update(rise_entry(r, HIP, key))
            if label == "saturated":
                entry["muscle_volume_cm3"] = float(r.volumes[0, r.index(HIP)] * 1e6)
        entries.append(entry)
    return StudyData(pd.DataFrame(cols), {"muscle_volume_sweep": entries})


@fig16.draws
def _draw16(data: StudyData, path: str) -> None:
    def curves(label):
        key = "rise_time_90_s" if label == "saturated" else "unsaturated_rise_time_90_s"
        for e in data.summary["muscle_volume_sweep"]:
            f = e["volume_constant_percent"]
            yield (_fig16_column(f, label),
                   f"{f} % ({e['muscle_volume_cm3']:.0f} cm$^3$): rise {format_rise(e[key])}")
    _draw_saturation_panels(data.table, curves,
                            "Hip muscle pressurising at fixed muscle volumes, 6 bar source (cf. paper Fig. 16)",
                            path)


# --- Figure 17: saturation level ---------------------------------------------------------------------
@register("fig17", "Hip muscle pressure for several branch saturation limits (paper Fig. 17)")
def fig17() -> StudyData:
    cols = {}
    entries = []
    for q in BRANCH_LIMITS_L_PER_MIN:
        r = run({"supply.branch_limit": q * L_PER_MIN})
        cols.setdefault(TIME, r.t)
        cols[_fig17_column(q)] = gauge_bar(r, r.muscle_pressure(HIP))
        entries.append({"branch_limit_L_per_min": q, **rise_entry(r),
                        "final_muscle_pressure_bar_gauge": final_pressure_bar(r),
                        "rise_target_pressure_bar_gauge": float(gauge_bar(r, r.rise(HIP).p_target[0]))})
    return StudyData(pd.DataFrame(cols), {"saturation_sweep": entries})


@fig17.draws
def _draw17(data: StudyData, path: str) -> None:
    d = data.table
    fig, ax = figure(1, 2, width=11.5, height=4.8, gridspec_kw={"width_ratios": [1.6, 1]})
    a, b = ax[0, 0], ax[0, 1]
    entries = data.summary["saturation_sweep"]
    for e in entries:
        q = e["branch_limit_L_per_min"]
        a.plot(d[TIME], d[_fig17_column(q)],
               label=f"{q} L/min: {format_rise(e['rise_time_90_s'], 2)}")
    a.set_xlim(0, 1.05)
    a.set_xlabel("time [s]")
    a.set_ylabel("hip muscle pressure [bar gauge]")
    a.set_title("Pressure response under various saturations (cf. Fig. 17)")
    # outside the axes, to the right: no curve is hidden
    a.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, title="branch limit: 90 % rise",
             title_fontsize=8)
    q = np.array([e["branch_limit_L_per_min"] for e in entries], float)
    rt = np.array([np.nan if e["rise_time_90_s"] is None else e["rise_time_90_s"] for e in entries])
    b.plot(q, rt, "o-", label="90 % rise time")
    miss = ~np.isfinite(rt)
    if miss.any():
        top = np.nanmax(rt) if np.isfinite(rt).any() else 1.0
        b.plot(q[miss], np.full(miss.sum(), 1.08 * top), "x", color="tab:red", ms=9, mew=2,
               label="not reached while the valve was open")
        b.legend(loc="upper right", fontsize=8)
    b.set_xlabel("branch saturation limit [L/min standard]")
    b.set_ylabel("90 % rise time [s]")
    b.set_title("Rise time falls as the limit rises")
    save(fig, path, NOTE + "; rise to 90 % of the way to the source pressure at the valve's close")


# --- Aeration volumes -------------------------------------------------------------------------------
@register("aeration", "Aeration volumes of hip, knee and ankle muscles at standard state (paper Sec. 4.2)")
def aeration() -> StudyData:
    r = run()
    rows = []
    for joint in ("hip", "knee", "ankle"):
        sim = r.aeration_volume(f"{joint}_left") * 1e3
        paper = PAPER_AERATION_L[joint]
        rows.append({"joint": joint, SIMULATED_L: sim, PAPER_L: paper, DIFFERENCE: 100.0 * (sim - paper) / paper})
    table = pd.DataFrame(rows)
    return StudyData(table, {"aeration_volume_L": {row["joint"]: row[SIMULATED_L] for row in rows}})


@aeration.draws
def _draw_aeration(data: StudyData, path: str) -> None:
    d = data.table
    fig, ax = figure(width=6.5)
    a = ax[0, 0]
    x = np.arange(len(d))
    a.bar(x - 0.18, d[SIMULATED_L], 0.36, label="frogsim")
    a.bar(x + 0.18, d[PAPER_L], 0.36, label="paper Sec. 4.2")
    for xi, (s, diff) in enumerate(zip(d[SIMULATED_L], d[DIFFERENCE])):
        a.text(xi - 0.18, s + 0.005, f"{s:.3f} L\n({diff:+.1f} %)", ha="center", fontsize=8)
    a.set_xticks(x, d["joint"])
    a.set_ylabel("aeration volume [L at standard state]")
    a.set_ylim(0, 0.6)
    a.set_title("Air charged per pressurise phase (ISO 8778 standard litres)")
    a.legend(loc="upper center", ncol=2)     # in the empty band above the bars and their labels
    save(fig, path, NOTE)


# --- Tube modes -------------------------------------------------------------------------------------
def _one_branch_overrides() -> dict:
    """Only the left hip muscle is charged: the other five programs hold their valves closed."""
    over = {}
    for m in _base().muscles:
        if m != HIP:
            over[f"muscles.{m}.program"] = Program(steps=((0.0, "hold"),))
    return over


@register("tube-modes", "Eq. (9) per-branch limit vs a physical shared main tube, 1 and 6 open branches")
def tube_modes() -> StudyData:
    cols = {}
    summary = {}
    for mode in ("paper", "physical"):
        summary[mode] = {}
        for label, over in (("one_branch", _one_branch_overrides()), ("six_branches", {})):
            r = run({"supply.mode": mode, **over})
            q = r.charge_flow(HIP) / r.reference_density / L_PER_MIN
            cols.setdefault(TIME, r.t)
            cols[_tube_column("charge flow", mode, label)] = q
            cols[_tube_column("pressure", mode, label)] = gauge_bar(r, r.muscle_pressure(HIP))
            summary[mode][f"{label}_L_per_min"] = float(q.max())
            summary[mode].update(rise_entry(r, HIP, f"{label}_rise_time_90_s"))
    sc = load_scenario(BASE)
    limit = branch_limit_standard(sc.supply) / L_PER_MIN
    return StudyData(pd.DataFrame(cols), {"tube_modes": summary, "branch_saturation_L_per_min": limit})


@tube_modes.draws
def _draw_tubes(data: StudyData, path: str) -> None:
    d = data.table
    fig, ax = figure(1, 2, width=11)
    a, b = ax[0, 0], ax[0, 1]
    styles = {"paper": "-", "physical": "--"}
    for mode in ("paper", "physical"):
        for label, color in (("one_branch", "tab:blue"), ("six_branches", "tab:red")):
            name = f"{mode}, {label.replace('_', ' ')} open"
            a.plot(d[TIME], d[_tube_column("charge flow", mode, label)], styles[mode], color=color, label=name)
            b.plot(d[TIME], d[_tube_column("pressure", mode, label)], styles[mode], color=color, label=name)
    a.set_xlim(0, 0.8)
    b.set_xlim(0, 1.05)
    a.set_xlabel("time [s]")
    b.set_xlabel("time [s]")
    a.set_ylabel("hip charge flow [L/min standard]")
    b.set_ylabel("hip muscle pressure [bar gauge]")
    a.set_title(f"Eq. (9) limit {data.summary['branch_saturation_L_per_min']:.1f} L/min per branch vs shared tube")
    b.set_title("Pressure response")
    a.legend(fontsize=8)
    save(fig, path, NOTE)
