"""Run results: the summary of a run and its pressure plot (files written by :mod:`frogsim._files`)."""
from __future__ import annotations

import logging

import numpy as np

from frogsim.engine.measures import NO_PHASE


log = logging.getLogger("frogsim")

DOMINANT_FRACTION = 0.5     # a limit "dominates" a charge when it binds for more than half of it


def limit_notes(result) -> list[str]:
    """One-line notes on limits that dominate the run's charges (empty when none does).

    Today: the Eq. (9) per-branch limit of ``supply.mode = "paper"``, when it caps a muscle's
    charge flow for more than half of its rise (valve opening to the 90 % rise level, or to the
    close if that is not reached). While it binds, the flow equals the limit whatever the valve,
    so changing the valve's C or b changes nothing there.
    """
    from frogsim.circuit import layout as L
    if int(result.model.g[L.G_SUPPLY_MODE]) != L.SUPPLY_PAPER:
        return []
    capped = [(name, result.branch_limited_fraction(name, until="rise")) for name in result.names
              if len(result.charge_open_times(name))]
    capped = [(n, f) for n, f in capped if f > DOMINANT_FRACTION]
    if not capped:
        return []
    limit = result.model.g[L.G_BRANCH_LIMIT] / result.reference_density * 6e4
    groups = {}
    for n, f in capped:
        groups.setdefault(round(100 * f), []).append(n)
    who = "; ".join(f"{', '.join(names)} for {pct} %" for pct, names in
                    sorted(groups.items(), reverse=True))
    return [f"the Eq. (9) branch limit ({limit:.1f} L/min) capped the charge flow of {who} of the "
            f"rise to 90 %; valve changes cannot matter while it does"]


def run_summary(result, notes: bool = True) -> dict:
    """Headline figures of one run, in display units with the unit in each key (docs/metrics.md).

    A run with closed-loop controllers adds "control": each controller's tracking error (RMS and
    max after its settling time), valve switchings and air used (docs/control.md).

    A rise time that is not reached is None (JSON null) with ``rise_time_90_reason`` saying why.
    Limits that dominate the charging are listed under "notes" and, with ``notes``, logged on the
    "frogsim" logger as warnings (one line each on stderr unless logging is configured otherwise).
    """
    patm = result.atmospheric_pressure
    rho = result.reference_density
    ps = result.source_pressure
    m_total = result.total_air_mass
    muscles = {}
    for name in result.names:
        entry = {"final_pressure_bar_gauge": float((result.muscle_pressure(name)[-1] - patm) / 1e5),
                 "charged_L_std": float(result.charged_mass(name)[-1] / rho * 1e3)}
        if len(result.charge_open_times(name)):
            rise = result.rise(name)
            entry["rise_time_90_s"] = float(rise.seconds[0]) if rise.reason(0) is None else None
            entry["rise_time_90_reason"] = rise.reason(0)
            has_phase = rise.status[0] != NO_PHASE
            entry["rise_target_pressure_bar_gauge"] = float((rise.p_target[0] - patm) / 1e5) if has_phase else None
            entry["pressure_at_close_bar_gauge"] = float((result.pressure_at_close(name) - patm) / 1e5)
            entry["aeration_volume_L"] = result.aeration_volume(name) * 1e3
            entry["branch_limited_fraction_of_rise"] = result.branch_limited_fraction(name, until="rise")
            entry["branch_limited_fraction_of_phase"] = result.branch_limited_fraction(name)
        muscles[name] = entry
    found = limit_notes(result)
    if notes:
        for note in found:
            log.warning("note: %s", note)
    return {
        "scenario": result.model.scenario.name,
        "duration_s": float(result.t[-1]),
        "source": {"initial_pressure_bar_gauge": float((ps[0] - patm) / 1e5),
                   "final_pressure_bar_gauge": float((ps[-1] - patm) / 1e5),
                   "pressure_drop_bar": float((ps[0] - ps.min()) / 1e5)},
        "exhaust": {"final_pressure_bar_gauge": float((result.exhaust_pressure[-1] - patm) / 1e5)},
        "pump_moved_L_std": float(result.pumped_mass[-1] / rho * 1e3),
        "muscles": muscles,
        "notes": found,
        "air_mass_relative_drift": float(np.ptp(m_total) / m_total[0]),
        "solver": result.stats,
        **({"control": result.control_metrics()} if result.switchings else {}),
    }


def muscle_colors(n: int) -> list:
    """n distinct colours: the 10 of tab10 up to ten muscles, then the 20 of tab20, then a
    continuous map (never a repeated colour)."""
    import matplotlib
    if n <= 10:
        return [matplotlib.colormaps["tab10"](i) for i in range(n)]
    if n <= 20:
        return [matplotlib.colormaps["tab20"](i) for i in range(n)]
    cmap = matplotlib.colormaps["turbo"]
    return [cmap(i / (n - 1)) for i in range(n)]


SAME_PA = 100.0          # [Pa]: curves closer than this everywhere are drawn as one (1 mbar)


def same_curves(t, curves, tol: float = SAME_PA) -> list:
    """Group (name, values) curves that lie within ``tol`` of each other at every sample, so that a
    figure draws each visible line once and its legend names every curve on it; returns
    [(names, values of the first)] in the order given."""
    groups = []
    for name, v in curves:
        for names, ref in groups:
            if np.max(np.abs(np.asarray(v) - ref)) <= tol:
                names.append(name)
                break
        else:
            groups.append(([name], np.asarray(v)))
    return groups


def plot_run(result, path: str) -> None:
    """Pressures of source, exhaust and every muscle (a closed-loop controller's setpoint dashed in
    its muscle's colour), and the valve states, against time."""
    from frogsim._plotting import figure, save
    patm = result.atmospheric_pressure
    n = result.n
    colors = muscle_colors(n)
    fig, ax = figure(2, 1, width=10.0, height=5.0 + 0.25 * n, sharex=True,
                     gridspec_kw={"height_ratios": [3, 0.6 + 0.2 * n]})
    a, b = ax[0, 0], ax[1, 0]
    a.plot(result.t, (result.source_pressure - patm) / 1e5, "k", lw=2, label="source")
    a.plot(result.t, (result.exhaust_pressure - patm) / 1e5, "k--", lw=1, label="exhaust")
    for names, p in same_curves(result.t, [(n, result.muscle_pressure(n)) for n in result.names]):
        c = colors[result.names.index(names[0])]
        label = names[0] if len(names) == 1 else \
            ",\n".join(", ".join(names[k:k + 2]) for k in range(0, len(names), 2)) + f"\n(one curve, within {SAME_PA:g} Pa)"
        a.plot(result.t, (p - patm) / 1e5, color=c, label=label)
    # each closed-loop controller's setpoint, dashed in its muscle's colour (PWM without one: none)
    from frogsim.engine.run_result import label_and_setpoint
    from frogsim.circuit import layout as L
    for name in result._law_rows():
        ctl = result.model.scenario.controllers[name]
        kind, sp = label_and_setpoint(ctl, result.python_law, result.t, lambda name=name: result.setpoint(name))
        if sp is not None and np.isfinite(sp).any():
            a.plot(result.t, (sp - patm) / 1e5, color=colors[result.names.index(ctl.muscle)], ls="--", lw=1.2,
                   label=f"{ctl.muscle} setpoint ({name}, {kind})")
    a.set_ylabel("pressure [bar gauge]")
    a.set_title(f"Scenario {result.model.scenario.name!r}")
    a.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))     # outside: hides no curve
    for i, (name, c) in enumerate(zip(result.names, colors)):
        b.step(result.t, result.u[:, L.charge_valve(i)] * 0.8 + i, where="post", color=c)
        b.step(result.t, -result.u[:, L.vent_valve(i)] * 0.4 + i, where="post", color=c, ls=":")
    b.set_yticks(range(n), result.names, fontsize=7)
    b.set_xlabel("time [s]")
    b.set_title("valves: step up = charge open, dotted down = discharge open", fontsize=9)
    save(fig, path, "frogsim; pressures gauge")
