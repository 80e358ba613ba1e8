"""Run results: the summary of a run and its pressure plot (files written by :mod:`frogsim._files`)."""
from __future__ import annotations


import numpy as np


def run_summary(result) -> dict:
    """Headline figures of one run, in display units with the unit in each key."""
    patm = result.atmospheric_pressure
    rho = result.reference_density
    ps = result.source_pressure
    m_total = result.total_air_mass
    muscles = {}
    for name in result.names:
        entry = {"final_pressure_bar_gauge": float((result.muscle_pressure(name)[-1] - patm) / 1e5),
                 "charged_L_std": float(result.charged_mass(name)[-1] / rho * 1e3)}
        if len(result.charge_open_times(name)):
            entry["rise_time_90_s"] = result.rise_time(name)
            entry["aeration_volume_L"] = result.aeration_volume(name) * 1e3
        muscles[name] = entry
    return {
        "scenario": result.model.scenario.name,
        "duration_s": float(result.t[-1]),
        "source": {"initial_pressure_bar_gauge": float((ps[0] - patm) / 1e5),
                   "final_pressure_bar_gauge": float((ps[-1] - patm) / 1e5),
                   "pressure_drop_bar": float((ps[0] - ps.min()) / 1e5)},
        "exhaust": {"final_pressure_bar_gauge": float((result.exhaust_pressure[-1] - patm) / 1e5)},
        "pump_moved_L_std": float(result.pumped_mass[-1] / rho * 1e3),
        "muscles": muscles,
        "air_mass_relative_drift": float(np.ptp(m_total) / m_total[0]),
        "solver": result.stats,
    }


def plot_run(result, path: str) -> None:
    """Pressures of source, exhaust and every muscle, and the valve states, against time."""
    from frogsim._plotting import figure, save
    patm = result.atmospheric_pressure
    n = result.n
    fig, ax = figure(2, 1, height=6.0, sharex=True, gridspec_kw={"height_ratios": [3, 1.2]})
    a, b = ax[0, 0], ax[1, 0]
    a.plot(result.t, (result.source_pressure - patm) / 1e5, "k", lw=2, label="source")
    a.plot(result.t, (result.exhaust_pressure - patm) / 1e5, "k--", lw=1, label="exhaust")
    for name in result.names:
        a.plot(result.t, (result.muscle_pressure(name) - patm) / 1e5, label=name)
    a.set_ylabel("pressure [bar gauge]")
    a.set_title(f"Scenario {result.model.scenario.name!r}")
    a.legend(fontsize=8, ncol=2, loc="best")
    for i, name in enumerate(result.names):
        b.step(result.t, result.u[:, 2 * i] * 0.8 + i, where="post", color=f"C{i % 10}")
        b.step(result.t, -result.u[:, 2 * i + 1] * 0.4 + i, where="post", color=f"C{i % 10}", ls=":")
    b.set_yticks(range(n), result.names, fontsize=7)
    b.set_xlabel("time [s]")
    b.set_title("valves: step up = charge open, dotted down = discharge open", fontsize=9)
    save(fig, path, "frogsim; pressures gauge")
