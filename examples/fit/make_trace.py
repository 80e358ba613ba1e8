"""Make the example's "measured" traces with frogsim itself, from known parameters that differ
from the fan2017 set, so that the fit's answer can be checked against the truth.

Run:  python examples/fit/make_trace.py      (writes trace-6bar.csv and trace-4bar.csv here)

The rig (rig.toml) is run at 6 bar and at 4 bar source pressure with the TRUE values below. Each
pressure is then "measured" as a real sensor chain would: Gaussian sensor noise of 0.02 bar
(seeded), then a 10-bit ADC over 0..10 bar gauge (steps of 10/1023 bar = 9.8 mbar), written in
bar gauge. The traces also hold a column the model has no signal for (a thermocouple near the
valve), which FIT.toml leaves out with ignore_columns.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

import frogsim

HERE = Path(__file__).resolve().parent
#: the truth the fit should find (SI): fan2017 has 0.4 L/(s bar), 0.38, 5 cm^3, 2 ms
TRUE = {"valves.charge.sonic_conductance": 0.3e-3 / 1e5,    # 0.3 L/(s*bar)
        "valves.charge.critical_ratio": 0.30,
        "muscle_types.hip.dead_volume": 12e-6,               # 12 cm^3
        "valves.charge.dead_time": 5e-3}                     # 5 ms
NOISE_BAR = 0.02
ADC_BITS, ADC_FULL_SCALE_BAR = 10, 10.0
RUNS = {"trace-6bar.csv": 6e5, "trace-4bar.csv": 4e5}        # source pressure, Pa gauge


def adc(p_bar: np.ndarray) -> np.ndarray:
    """A 10-bit converter over 0..10 bar gauge: the nearest of 1024 levels, clipped to the range."""
    levels = 2 ** ADC_BITS - 1
    code = np.clip(np.round(p_bar / ADC_FULL_SCALE_BAR * levels), 0, levels)
    return code * ADC_FULL_SCALE_BAR / levels


def measure(result, patm: float, rng) -> pd.DataFrame:
    cols = {"time [s]": result.t}
    for name, p in (("hip_left pressure [bar gauge]", result.muscle_pressure("hip_left")),
                    ("source pressure [bar gauge]", result.source_pressure)):
        cols[name] = adc((p - patm) / 1e5 + rng.normal(0.0, NOISE_BAR, p.size))
    cols["valve temperature [degC]"] = 20.0 + rng.normal(0.0, 0.3, result.t.size)
    return pd.DataFrame(cols)


def main() -> None:
    rig = frogsim.load_scenario(HERE / "rig.toml")
    patm = rig.air.atmospheric_pressure_abs
    for seed, (name, p0) in enumerate(RUNS.items()):
        result = frogsim.simulate(rig.replace({**TRUE, "source.initial_pressure_gauge": p0}))
        measure(result, patm, np.random.default_rng(seed)).to_csv(HERE / name, index=False, float_format="%.6g")
        print(f"wrote {HERE / name}")


if __name__ == "__main__":
    main()
