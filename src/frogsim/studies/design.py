"""Design studies beyond the paper: the questions its conclusion raises, answered with numbers.

* ``design-tubes``: main tube inner diameter x number of main tubes -> hip muscle 90 % rise time,
  in the paper's Eq. (9) mode and in the physical tube mode, and the diameter from which the valve,
  not the tube, limits the rise (the paper advises "extending the main pipe diameter and number of
  main pipes" without saying how far that helps).
* ``design-endurance``: source volume x pump displacement -> strokes until the source can no longer
  fill a stroke, and the stroke rate the pump can sustain, for the robot's twelve muscles.
* ``design-valve``: valve sonic conductance C x critical ratio b -> rise time.

Each runs its points through the batched engine (:mod:`frogsim.engine.batch`).
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from frogsim.circuit import layout as L
from frogsim.engine.batch import build_models, run_models
from frogsim.engine.measures import format_rise
from frogsim.scenario.load import load_scenario
from frogsim.scenario.tables import header
from frogsim.physics.flow import pump_mass_flow
from frogsim.studies.paper import HIP, NOTE
from frogsim._plotting import figure, legend_in, save
from frogsim.studies.registry import StudyData, register
from frogsim.sweep.metrics import evaluate

VALVE_LIMITED_MARGIN = 0.05      # "the valve limits": rise time within 5 % of the valve-only value
TUBE_DIAMETERS_MM = tuple(np.round(np.arange(2.0, 10.01, 0.5), 2))
TUBE_COUNTS = (1, 2, 3)
BAR = 1e5                        # Pa
MM = 1e-3                        # m
LITRE = 1e-3                     # m^3
L_PER_MIN = 1e-3 / 60.0          # m^3/s
L_PER_S_BAR = 1e-3 / 1e5         # m^3/(s Pa): sonic conductance
REQUIRED_SWING_BAR = 4.0         # chosen: a full stroke needs 4 bar between source and exhaust (a
                                 # muscle cycles between the two): two thirds of the 6 bar force swing
                                 # (Chou-Hannaford force ~ pressure)
SOURCE_VOLUMES_L = (2, 4, 8, 16)
PUMP_FLOWS_L_PER_MIN = (5, 10, 20, 40, 80, 160)
# the studies' CSV columns, in the one header convention (frogsim.scenario.tables); "mode" is a label
RISE = header("hip rise time 90 %", "s")            # NaN: not reached while the valve was open
REACHED = header("hip rise reached", "%")
VALVE_ONLY_RISE = header("valve-only hip rise time 90 %", "s")
TUBE_COUNT = header("main tube count", "-")
DIAMETER = header("main tube inner diameter", "mm")
SOURCE_VOLUME = header("source volume", "L")
PUMP = header("pump displacement", "L/min")
STROKES = header("strokes before short", "-")
CENSORED = header("never ran short", "1 = yes")     # strokes before short is then a lower bound
STEADY_SOURCE = header("steady source pressure", "bar gauge")
STEADY_EXHAUST = header("steady exhaust pressure", "bar gauge")
RATE = header("sustainable stroke rate", "1/min")
SOURCE_AFTER = header("source pressure after run", "bar gauge")
CONDUCTANCE = header("sonic conductance", "L/(s bar)")
RATIO = header("critical ratio", "-")
VALVE_C = tuple(np.round(np.arange(0.1, 1.01, 0.1), 2))     # L/(s bar); MHJ9 is 0.4
VALVE_B = tuple(np.round(np.arange(0.15, 0.61, 0.05), 2))   # MHJ9 is 0.38


def _rise_table(base: str, points: list[dict]) -> pd.DataFrame:
    """Hip 90 % rise time [s] of each point (NaN: not reached while the valve was open, see
    docs/metrics.md) and the share of that rise it reached [%]."""
    models = build_models(load_scenario(base), points)
    v = evaluate(run_models(models), ["rise_time", "rise_reached"], HIP)
    return pd.DataFrame({RISE: v["rise_time"], REACHED: 100 * v["rise_reached"]})


def _rise_times(base: str, points: list[dict]) -> np.ndarray:
    return _rise_table(base, points)[RISE].to_numpy()


def _bore(x: float) -> str:
    """A crossing diameter for text; NaN: the valve never takes over in the range studied."""
    return f"{x:.1f} mm" if np.isfinite(x) else f"no bore up to {TUBE_DIAMETERS_MM[-1]:g} mm"


def _crossing(x, y, level):
    """First x where the decreasing curve y(x) falls to level (linear interpolation), or NaN.

    NaN entries of y (rise not reached) never count as below the level; if the point before the
    first one below the level is NaN, that first x is returned."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    below = np.nonzero(y <= level)[0]
    if not below.size:
        return float("nan")
    k = below[0]
    if k == 0 or not np.isfinite(y[k - 1]):     # first point, or the one before has no rise time
        return float(x[k])
    return float(x[k - 1] + (level - y[k - 1]) / (y[k] - y[k - 1]) * (x[k] - x[k - 1]))


# --- main tubes --------------------------------------------------------------------------------------
@register("design-tubes", "Main tube diameter x number of tubes -> hip rise time; where the valve takes over",
          group="design")
def design_tubes() -> StudyData:
    valve_only = float(_rise_times("paper-cycle", [{"supply.mode": "none"}])[0])
    rows, points = [], []
    for mode in ("paper", "physical"):
        for count in TUBE_COUNTS:
            for d in TUBE_DIAMETERS_MM:
                points.append({"supply.mode": mode, "supply.main_tube_count": int(count),
                               "supply.main_tube_inner_diameter": d * MM})
                rows.append({"mode": mode, TUBE_COUNT: count, DIAMETER: d})
    table = pd.concat([pd.DataFrame(rows), _rise_table("paper-cycle", points)], axis=1)
    table[VALVE_ONLY_RISE] = valve_only
    level = valve_only * (1 + VALVE_LIMITED_MARGIN)
    crossings = {}
    for mode in ("paper", "physical"):
        crossings[mode] = {}
        for count in TUBE_COUNTS:
            sub = table[(table["mode"] == mode) & (table[TUBE_COUNT] == count)]
            crossings[mode][str(count)] = _crossing(sub[DIAMETER], sub[RISE], level)
    paper_4mm = table[(table["mode"] == "paper") & (table[TUBE_COUNT] == 1)
                      & (table[DIAMETER] == 4.0)][RISE].iloc[0]
    phys_4mm = table[(table["mode"] == "physical") & (table[TUBE_COUNT] == 1)
                     & (table[DIAMETER] == 4.0)][RISE].iloc[0]
    missing = table[~np.isfinite(table[RISE])]
    if len(missing):
        worst = missing.sort_values(REACHED).iloc[0]
        unreached = (
            f" {len(missing)} of the {len(table)} layouts do not reach 90 % of the rise within the 1 s "
            f"pressurise (rise time \"not reached\", crosses in the figure); the worst ({worst['mode']} "
            f"mode, {worst[TUBE_COUNT]} tube(s) of {worst[DIAMETER]:g} mm) reaches "
            f"{worst[REACHED]:.0f} % of it.")
    else:
        unreached = ""
    conclusion = (
        f"Six muscles charged at once from 6 bar. The valves alone (MHJ9, C = 0.4 L/(s bar)) give a "
        f"hip rise time of {format_rise(valve_only)}. With the paper's Eq. (9) limit, one 4 mm main tube "
        f"gives {format_rise(paper_4mm)} and the valve takes over (rise within 5 % of the valve-only "
        f"value) from {_bore(crossings['paper']['1'])} with one tube, {_bore(crossings['paper']['2'])} "
        f"with two, {_bore(crossings['paper']['3'])} with three. A physical tube, whose choked flow "
        f"grows with the upstream density, gives {format_rise(phys_4mm)} with one 4 mm tube and lets the "
        f"valve take over from {_bore(crossings['physical']['1'])} ({_bore(crossings['physical']['2'])} "
        f"with two tubes): Eq. (9) understates a 6 bar tube's capacity several times, so the paper's "
        f"advice to widen the main pipe matters far less than Eq. (9) suggests.{unreached}")
    return StudyData(table, {"design_tubes": {
        "valve_only_rise_time_90_s": valve_only,
        "valve_limited_from_inner_diameter_mm": crossings,
        "criterion": f"rise time within {VALVE_LIMITED_MARGIN:.0%} of the valve-only rise time",
        "conclusion": conclusion}}, {"level": level})


@design_tubes.draws
def _draw_tubes(data: StudyData, path: str) -> None:
    d = data.table
    # each panel's legend in a row of its own below it: the dotted crossover lines run the panels'
    # full height, so no corner inside them is free
    fig, ax = figure(2, 2, width=11.5, height=5.8, sharey="row", gridspec_kw={"height_ratios": [4, 1]})
    vo = data.summary["design_tubes"]["valve_only_rise_time_90_s"]
    top = np.nanmax(d[RISE]) * 1.08
    for a, mode, title in ((ax[0, 0], "paper", "paper mode: Eq. (9) per-branch limit"),
                           (ax[0, 1], "physical", "physical mode: shared choked tube")):
        for count in TUBE_COUNTS:
            sub = d[(d["mode"] == mode) & (d[TUBE_COUNT] == count)]
            x = data.summary["design_tubes"]["valve_limited_from_inner_diameter_mm"][mode][str(count)]
            where = f"valve limits from {x:.1f} mm" if np.isfinite(x) else "tube limits throughout"
            a.plot(sub[DIAMETER], sub[RISE], "o-", ms=3, color=f"C{count - 1}",
                   label=f"{count} main tube(s); {where}")
            if np.isfinite(x):
                a.axvline(x, color=f"C{count - 1}", ls=":", lw=1)
            miss = sub[~np.isfinite(sub[RISE])]
            a.plot(miss[DIAMETER], np.full(len(miss), top * (1 + 0.04 * (count - 1))), "x",
                   color=f"C{count - 1}", ms=8, mew=2)
        if not np.isfinite(d[d["mode"] == mode][RISE]).all():
            a.plot([], [], "x", color="0.3", ms=8, mew=2, label="not reached in the 1 s pressurise")
        a.axhline(vo, color="k", ls="--", lw=1, label=f"valves only: {format_rise(vo)}")
        a.set_xlabel("main tube inner diameter [mm]")
        a.set_title(title)
        legend_in(ax[1, 0] if mode == "paper" else ax[1, 1], a, fontsize=8, loc="upper center")
    ax[0, 0].set_ylabel("hip muscle 90 % rise time [s]")
    fig.suptitle("Where does the valve, not the tube, limit the pressurising? (six muscles at once, 6 bar)")
    save(fig, path, NOTE + f"; dotted lines: diameter from which the rise time is within "
                           f"{VALVE_LIMITED_MARGIN:.0%} of the valves-only value")


# --- source volume and pump -------------------------------------------------------------------------
def _steady_pressures(model, swing: float) -> tuple[float, float]:
    """(source, exhaust) pressures [Pa abs] when the source is exactly ``swing`` above the exhaust.

    The closed circuit's air is conserved; with source and exhaust back at ambient temperature and
    the muscles at their initial state, p_s V_s + p_e V_e = (m_s0 + m_e0) R T and p_s - p_e = swing.
    """
    g = model.g
    R, T = g[L.G_R], g[L.G_TAMB]
    Vs, Ve = g[L.G_VS], g[L.G_VE]
    total = model.y0[L.Y_MS] + model.y0[L.Y_ME]
    ps = (total * R * T + swing * Ve) / (Vs + Ve)
    return ps, ps - swing


def _air_per_stroke_at(base, source_gauge_bar: float) -> float:
    """Air [kg] one stroke of all muscles takes with the source held at the given pressure above an
    atmospheric exhaust (a 1000 L source, pump off, one 2 s cycle)."""
    from frogsim.engine.pneumatic import simulate
    one = {f"programs.{p.split('.')[1]}.cycles": 1 for p in base.variable_paths()
           if p.startswith("programs.") and p.endswith(".cycles")}
    sc = base.replace({"source.volume": 1000 * LITRE, "pump.enabled": False,
                       "source.initial_pressure_gauge": source_gauge_bar * BAR, "duration": 2.0, **one})
    r = simulate(sc)
    return float(sum(r.charged_mass(n)[-1] for n in r.names))


def _at(table: pd.DataFrame, source_L: float, pump_L_per_min: float) -> int:
    row = table[(table[SOURCE_VOLUME] == source_L) & (table[PUMP] == pump_L_per_min)]
    return int(row[STROKES].iloc[0])


def _pump_for_rate(sub: pd.DataFrame, rate: float) -> float:
    """Pump displacement [L/min] at which the sustainable rate reaches ``rate`` (log interpolation)."""
    q = np.log(sub[PUMP].to_numpy(float))
    r = np.log(sub[RATE].to_numpy(float))
    if rate > np.exp(r).max():
        return float("nan")
    return float(np.exp(np.interp(np.log(rate), r, q)))


@register("design-endurance", "Source volume x pump flow -> strokes before the source runs short, "
          "sustainable stroke rate (12 muscles)", group="design")
def design_endurance() -> StudyData:
    base = load_scenario("robot-12")
    points, rows = [], []
    for vs in SOURCE_VOLUMES_L:
        for q in PUMP_FLOWS_L_PER_MIN:
            points.append({"source.volume": vs * LITRE, "pump.displacement": q * L_PER_MIN})
            rows.append({SOURCE_VOLUME: vs, PUMP: q})
    models = build_models(base, points)
    results = run_models(models)
    swing = REQUIRED_SWING_BAR * 1e5
    period = 2.0
    air_req = _air_per_stroke_at(base, REQUIRED_SWING_BAR)
    rho_ref = results[0].reference_density
    for row, r, m in zip(rows, results, models):
        patm = r.atmospheric_pressure
        starts = np.arange(0.0, r.t[-1] - 1e-9, period)
        swing_at_start = np.interp(starts, r.t, r.source_pressure - r.exhaust_pressure)
        short = np.nonzero(swing_at_start < swing)[0]
        row[STROKES] = int(short[0]) if short.size else len(starts)
        row[CENSORED] = int(not short.size)
        g = m.g
        ps, pe = _steady_pressures(m, swing)
        row[STEADY_SOURCE] = (ps - patm) / 1e5
        row[STEADY_EXHAUST] = (pe - patm) / 1e5
        pump = pump_mass_flow(pe, g[L.G_TAMB], ps, g[L.G_PUMP_DISP], g[L.G_PUMP_RMAX], g[L.G_R])
        row[RATE] = 60.0 * pump / air_req
        row[SOURCE_AFTER] = float((r.source_pressure[-1] - patm) / 1e5)
    table = pd.DataFrame(rows)
    base = table[(table[SOURCE_VOLUME] == 4) & (table[PUMP] == 10)].iloc[0]
    paper_rate = 60.0 / period
    need = {vs: _pump_for_rate(table[table[SOURCE_VOLUME] == vs], paper_rate) for vs in SOURCE_VOLUMES_L}
    n_strokes = int(round(results[0].t[-1] / period))
    conclusion = (
        f"Twelve muscles, a stroke every {period:g} s (the paper's 1 s pressurise / 1 s release), a "
        f"stroke needing {REQUIRED_SWING_BAR:g} bar or more between source and exhaust; one such stroke "
        f"takes {air_req / rho_ref * 1e3:.2f} L of air (standard). The paper's robot (4 L source, "
        f"10 L/min pump) manages {int(base[STROKES])} full strokes before the source runs "
        f"short, and its pump sustains {base[RATE]:.1f} strokes per minute against "
        f"the {paper_rate:g} the paper's timing asks. To sustain that timing the pump needs about "
        f"{need[4]:.0f} L/min displacement with the 4 L source ({need[2]:.0f} L/min with 2 L, "
        f"{need[16]:.0f} L/min with 16 L; more air in the closed circuit raises the exhaust pressure "
        f"the pump draws from, so each pump stroke moves more mass). A larger source alone adds few "
        f"strokes: with a 10 L/min pump, 16 L gives {_at(table, 16, 10)} full strokes against "
        f"{_at(table, 4, 10)} with 4 L, because the muscles vent into the 6 L exhaust and the swing, "
        f"not the source pressure, runs out first; the exhaust volume and the pump are the levers. "
        f"Endurance is counted over {n_strokes} simulated strokes (more is reported as {n_strokes}).")
    return StudyData(table, {"design_endurance": {
        "required_swing_bar": REQUIRED_SWING_BAR,
        "stroke_period_s": period,
        "air_per_stroke_at_required_swing_L_std": air_req / rho_ref * 1e3,
        "paper_robot": {"strokes_before_short": int(base[STROKES]),
                        "sustainable_strokes_per_min": float(base[RATE])},
        "pump_for_paper_timing_L_per_min": {f"source_{vs}_L": need[vs] for vs in SOURCE_VOLUMES_L},
        "conclusion": conclusion}})


@design_endurance.draws
def _draw_endurance(data: StudyData, path: str) -> None:
    d = data.table
    fig, ax = figure(1, 2, width=11.5)
    a, b = ax[0, 0], ax[0, 1]
    for k, vs in enumerate(SOURCE_VOLUMES_L):
        sub = d[d[SOURCE_VOLUME] == vs]
        a.plot(sub[PUMP], sub[STROKES], "o-", label=f"source {vs} L")
        cens = sub[sub[CENSORED] == 1]
        a.plot(cens[PUMP], cens[STROKES], "^", color=f"C{k}", ms=9)
    a.set_xscale("log")
    a.set_xlabel("pump displacement [L/min]")
    a.set_ylabel("full strokes before the source runs short")
    a.set_title("Endurance (triangles: never ran short in the simulated strokes)")
    a.legend(fontsize=8)
    for vs in SOURCE_VOLUMES_L:
        sub = d[d[SOURCE_VOLUME] == vs]
        b.plot(sub[PUMP], sub[RATE], "o-", label=f"source {vs} L")
    b.axhline(30, color="k", ls="--", lw=1, label="paper's timing: 30 strokes/min")
    b.set_xscale("log")
    b.set_yscale("log")
    b.set_xlabel("pump displacement [L/min]")
    b.set_ylabel("strokes per minute")
    b.set_title(f"Stroke rate the pump sustains at a {REQUIRED_SWING_BAR:g} bar swing (12 muscles)")
    b.legend(fontsize=8)
    save(fig, path, NOTE + f"; a full stroke needs >= {REQUIRED_SWING_BAR:g} bar between source and exhaust")


# --- valve characteristics --------------------------------------------------------------------------
@register("design-valve", "Valve sonic conductance C x critical ratio b -> hip rise time", group="design")
def design_valve() -> StudyData:
    points, rows = [], []
    for c in VALVE_C:
        for b in VALVE_B:
            points.append({"supply.mode": "none",
                           "valves.charge.sonic_conductance": c * L_PER_S_BAR,
                           "valves.charge.critical_ratio": float(b),
                           "valves.discharge.sonic_conductance": c * L_PER_S_BAR,
                           "valves.discharge.critical_ratio": float(b)})
            rows.append({CONDUCTANCE: c, RATIO: b})
    table = pd.concat([pd.DataFrame(rows), _rise_table("paper-cycle", points)], axis=1)
    at_b = table[np.isclose(table[RATIO], 0.4)]
    fit = at_b[np.isfinite(at_b[RISE])]
    slope = np.polyfit(np.log(fit[CONDUCTANCE]), np.log(fit[RISE]), 1)[0]
    at_c = table[np.isclose(table[CONDUCTANCE], 0.4)]
    spread = (at_c[RISE].max() - at_c[RISE].min()) / at_c[RISE].mean()
    if not np.isfinite(at_c[RISE]).all():
        spread = float("nan")         # some b do not reach the level: no spread to quote
    t_lo = at_b[RISE].iloc[0]
    t_hi = at_b[RISE].iloc[-1]
    n_miss = int((~np.isfinite(table[RISE])).sum())
    conclusion = (
        f"Valve-limited charging (no tube limit), six muscles from 6 bar. At b = 0.4 the hip rise time "
        f"falls from {format_rise(t_lo)} at C = {VALVE_C[0]:g} to {format_rise(t_hi)} at C = {VALVE_C[-1]:g} "
        f"L/(s bar), a fitted rise time ~ C^{slope:.2f}: steeper than the 1/C of a choked fill into a "
        f"fixed volume, because a slow valve is still filling while the muscle contracts (0.1 to "
        f"0.4 s after the command) and its volume grows. At C = 0.4 L/(s bar) the critical ratio b "
        f"from {VALVE_B[0]:g} to {VALVE_B[-1]:g} changes the rise time by "
        f"{f'{spread:.0%}' if np.isfinite(spread) else 'an amount not measurable (some rises not reached)'}"
        f": choose valves by C first."
        + (f" {n_miss} of the {len(table)} valves do not reach 90 % of the rise within the 1 s "
           f"pressurise (\"not reached\", crosses in the figure)." if n_miss else ""))
    return StudyData(table, {"design_valve": {"rise_time_exponent_in_C": float(slope),
                                              "rise_time_spread_over_b_at_C_0p4": float(spread),
                                              "conclusion": conclusion}})


@design_valve.draws
def _draw_valve(data: StudyData, path: str) -> None:
    """The rise time over (C, b) on a log colour scale and a log C axis: it falls as a power of C
    (summary.json's exponent), so on linear scales most of the map would be one dark colour and the
    slow valves' contours would crowd at the left; on log scales the contours of a 1-2-5 series are
    evenly spaced."""
    from matplotlib.colors import LogNorm
    from matplotlib.ticker import LogLocator, NullLocator, StrMethodFormatter
    d = data.table
    grid = d.pivot(index=RATIO, columns=CONDUCTANCE, values=RISE)
    fig, ax = figure(width=7.5, height=5)
    a = ax[0, 0]
    values = grid.values[np.isfinite(grid.values)]
    lo, hi = float(values.min()), float(values.max())
    norm = LogNorm(lo, hi)
    cs = a.contourf(grid.columns, grid.index, grid.values, levels=np.geomspace(lo, hi, 15), norm=norm,
                    cmap="viridis")
    series = [m * 10.0 ** e for e in range(-3, 2) for m in (1, 2, 5)]
    lines = a.contour(grid.columns, grid.index, grid.values, levels=[v for v in series if lo < v < hi],
                      colors="w", linewidths=0.8)
    a.clabel(lines, fmt="%.3g s", fontsize=8, inline_spacing=4)
    miss = d[~np.isfinite(d[RISE])]
    if len(miss):
        a.plot(miss[CONDUCTANCE], miss[RATIO], "wx", ms=7, mew=2,
               label="90 % rise not reached in the 1 s pressurise")
    a.plot([0.4], [0.38], "r*", ms=12, label="MHJ9 (paper): C = 0.4, b = 0.38")
    bar = fig.colorbar(cs, ax=a, label="hip muscle 90 % rise time [s] (log scale)")
    bar.set_ticks([v for v in series if lo <= v <= hi], labels=[f"{v:g}" for v in series if lo <= v <= hi])
    a.set_xscale("log")
    a.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 3.0, 5.0)))
    a.xaxis.set_major_formatter(StrMethodFormatter("{x:g}"))
    a.xaxis.set_minor_locator(NullLocator())
    a.set_xlabel("sonic conductance C [L/(s bar)] (log scale)")
    a.set_ylabel("critical pressure ratio b [-]")
    a.set_title("Valve characteristics vs response (valve-limited, 6 bar)")
    a.legend(loc="upper right", fontsize=8)
    save(fig, path, NOTE)
