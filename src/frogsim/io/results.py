"""Writing results: atomic files (never half-written), CSV in display units, JSON summaries, plots."""
from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np


def _clean(obj):
    """JSON-safe copy: numpy scalars to Python, NaN/inf to None."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        x = float(obj)
        return x if math.isfinite(x) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def atomic_write(path: str | os.PathLike, write) -> None:
    """Call write(tmp_path) then move the file into place, so readers never see half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_json(path, data: dict) -> None:
    def w(tmp):
        with open(tmp, "w") as fh:
            json.dump(_clean(data), fh, indent=2)
            fh.write("\n")
    atomic_write(path, w)


def write_csv(path, df) -> None:
    atomic_write(path, lambda tmp: df.to_csv(tmp, index=False, float_format="%.8g"))


def write_figure(path, draw) -> None:
    """draw(tmp_path) must save a PNG at tmp_path."""
    def w(tmp):
        png = tmp + ".png"
        try:
            draw(png)
            os.replace(png, tmp)
        finally:
            if os.path.exists(png):
                os.unlink(png)
    atomic_write(path, w)


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
