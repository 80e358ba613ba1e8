"""Shared helpers for the fit tests: a cheap rig scenario and traces made from known parameters."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

P_ATM = 101325.0           # standard atmosphere (independent of frogsim's files)
BAR = 1e5
L_PER_S_BAR = 1e-3 / 1e5   # 1 L/(s*bar) in m^3/(s*Pa)

#: one hip muscle, 0.5 s (charge 0.25 s, vent 0.25 s), its valve fed straight from the source
RIG = """name = "hip-05"
parameters = "fan2017"
duration = "0.5 s"
output_interval = "1 ms"

[controller]
rate = "1 kHz"

[supply]
mode = "none"

[programs.stroke]
pressurise = "0.25 s"
release = "0.25 s"

[muscles.hip]
type = "hip"
program = "stroke"
motion = { kind = "MOTION" }
"""
STROKE = 'stroke", delay = "0.05 s", rise = "0.15 s", fall = "0.15 s'
VOLUME_CONSTANT = 'volume_constant", fraction = "0.5'


def write_rig(folder: Path, motion: str = STROKE) -> Path:
    path = Path(folder) / "rig.toml"
    path.write_text(RIG.replace("MOTION", motion))
    return path


def simulate_truth(rig: Path, truth: dict, overrides: dict | None = None):
    import frogsim
    sc = frogsim.load_scenario(rig)
    return frogsim.simulate(sc.replace({**(overrides or {}), **truth}))


def adc(p_bar: np.ndarray, bits: int = 10, full_scale_bar: float = 10.0) -> np.ndarray:
    """A converter of ``bits`` over 0..full scale (bar gauge): the nearest level, clipped to the range."""
    levels = 2 ** bits - 1
    return np.clip(np.round(p_bar / full_scale_bar * levels), 0, levels) * full_scale_bar / levels


def write_trace(path: Path, result, noise_bar: float = 0.0, seed: int = 0, source: bool = False,
                adc_bits: int | None = None) -> Path:
    """The hip pressure (and optionally the source pressure) in bar gauge, with Gaussian noise, and
    with ``adc_bits`` then quantised by a converter over 0..10 bar gauge (as examples/fit does)."""
    rng = np.random.default_rng(seed)
    cols = {"time [s]": result.t}
    cols["hip pressure [bar gauge]"] = (result.muscle_pressure("hip") - P_ATM) / BAR + \
        rng.normal(0.0, noise_bar, result.t.size) * (noise_bar > 0)
    if adc_bits:
        cols["hip pressure [bar gauge]"] = adc(cols["hip pressure [bar gauge]"], adc_bits)
    if source:
        cols["source pressure [kPa abs]"] = result.source_pressure / 1e3 + \
            rng.normal(0.0, noise_bar * 100, result.t.size) * (noise_bar > 0)
    pd.DataFrame(cols).to_csv(path, index=False, float_format="%.10g")
    return path


def spec(folder: Path, traces: list, parameters: dict, **extra) -> dict:
    """A fit spec dict over rig.toml in folder; traces: [trace file name or (name, overrides)]."""
    exps = []
    for tr in traces:
        name, over = (tr, None) if isinstance(tr, str) else tr
        exps.append({"trace": name, **({"overrides": over} if over else {})})
    return {"base_dir": str(folder), "scenario": "rig.toml", "experiments": exps, "parameters": parameters,
            **extra}
