"""Measured traces: units in the header into SI, resampling, and every class of bad data refused in
one line naming the file and the column."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import frogsim
from frogsim.errors import ScenarioError
from frogsim.fit.traces import information_factor, model_grid, read_trace

from fit_helpers import P_ATM, write_rig


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rig")
    return frogsim.load_scenario(write_rig(folder))


def _csv(path, cols: dict):
    pd.DataFrame(cols).to_csv(path, index=False)
    return path


def _times(n=501, dt=1e-3):
    return np.arange(n) * dt


def test_units_in_the_header_become_si(tmp_path, rig):
    t = _times()
    path = _csv(tmp_path / "a.csv", {"time [ms]": t * 1e3, "hip pressure [bar gauge]": np.full(t.size, 2.0),
                                      "source pressure [kPa abs]": np.full(t.size, 700.0),
                                      "exhaust pressure [psi abs]": np.full(t.size, 14.5)})
    tr = read_trace(path, rig)
    np.testing.assert_allclose(tr.time, t, rtol=1e-12)
    np.testing.assert_allclose(tr.signals["hip pressure"], 2e5 + P_ATM)       # gauge + atmosphere
    np.testing.assert_allclose(tr.signals["source pressure"], 7e5)
    np.testing.assert_allclose(tr.signals["exhaust pressure"], 14.5 * 6894.757293168, rtol=1e-9)


def test_linear_resampling_onto_the_model_grid(tmp_path, rig):
    t = np.linspace(0.0, 0.5, 51)                 # 10 ms steps, coarser than the 1 ms grid
    path = _csv(tmp_path / "b.csv", {"time [s]": t, "hip pressure [bar abs]": 1.0 + 4.0 * t})
    tr = read_trace(path, rig)
    grid = model_grid(rig)
    out = tr.resample(grid)["hip pressure"]
    np.testing.assert_allclose(out, (1.0 + 4.0 * grid) * 1e5, rtol=1e-12)   # a line stays a line
    assert information_factor(tr, rig) == pytest.approx(0.1)                # 1 ms / 10 ms


def test_ignored_columns_are_left_out(tmp_path, rig):
    t = _times()
    path = _csv(tmp_path / "c.csv", {"time [s]": t, "hip pressure [bar gauge]": t, "hip angle [deg]": t})
    tr = read_trace(path, rig, ignore_columns=["hip angle [deg]"])
    assert list(tr.signals) == ["hip pressure"] and tr.ignored == ("hip angle [deg]",)


@pytest.mark.parametrize("cols, expect", [
    ({"time [s]": [0.0, 0.2, 0.1, 0.5], "hip pressure [bar gauge]": [1, 2, 3, 4]},
     ["bad.csv", "'time [s]'", "not strictly increasing", "row 3"]),
    ({"time [s]": [0.0, 0.1, 0.2, 0.5], "hip pressure [bar gauge]": [1, 2, float("nan"), 4]},
     ["bad.csv", "'hip pressure [bar gauge]'", "NaN", "row 3"]),
    ({"time [s]": [0, 0.1, 0.2, 0.5], "hip pressure": [1, 2, 3, 4]},
     ["bad.csv", "'hip pressure'", "no unit"]),
    ({"time [s]": [0, 0.1, 0.2, 0.3], "hip pressure [bar gauge]": [1, 2, 3, 4]},
     ["bad.csv", "'time [s]'", "ends at 0.3 s", "0.5 s"]),
    ({"time [s]": [0, 0.1, 0.2, 0.5], "hip pressure [bar]": [1, 2, 3, 4]},
     ["bad.csv", "'hip pressure [bar]'", "gauge or abs"]),
    ({"time [s]": [0, 0.1, 0.2, 0.5], "hip pressure [cm gauge]": [1, 2, 3, 4]},
     ["bad.csv", "'hip pressure [cm gauge]'", "not a pressure unit"]),
    ({"time [s]": [0, 0.1, 0.2, 0.5], "hip pressure [bar gauge]": [1, 2, 3, 4],
      "knee pressure [bar gauge]": [1, 2, 3, 4], "hip angle [deg]": [0, 1, 2, 3]},
     ["bad.csv", "'knee pressure [bar gauge]'", "'hip angle [deg]'", "model does not have", "ignore_columns"]),
])
def test_bad_data_is_refused_in_one_line(tmp_path, rig, cols, expect):
    path = _csv(tmp_path / "bad.csv", cols)
    with pytest.raises(ScenarioError) as exc:
        read_trace(path, rig)
    msg = str(exc.value)
    assert "\n" not in msg
    for part in expect:
        assert part in msg, msg


def test_a_gap_is_refused(tmp_path, rig):
    t = np.concatenate([np.arange(0, 0.2, 1e-3), np.arange(0.21, 0.51, 1e-3)])   # 10 ms hole
    path = _csv(tmp_path / "gap.csv", {"time [s]": t, "hip pressure [bar gauge]": t})
    with pytest.raises(ScenarioError, match=r"gap.csv: column 'time \[s\]'.*a gap of 0.011 s after 0.199 s"):
        read_trace(path, rig)


def test_parquet_needs_pyarrow(tmp_path, rig):
    t = _times()
    df = pd.DataFrame({"time [s]": t, "hip pressure [bar gauge]": t})
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        import os
        if os.environ.get("CI"):          # the [test] extras install pyarrow: CI reads Parquet
            pytest.fail("pyarrow missing: python3 -m pip install -e '.[test]'")
        path = tmp_path / "a.parquet"
        path.write_bytes(b"PAR1")
        with pytest.raises(ScenarioError, match="a.parquet.*needs pyarrow"):
            read_trace(path, rig)
        return
    df.to_parquet(tmp_path / "a.parquet")
    from_parquet = read_trace(tmp_path / "a.parquet", rig)
    from_csv = read_trace(_csv(tmp_path / "a.csv", {"time [s]": t, "hip pressure [bar gauge]": t}), rig)
    assert "hip pressure" in from_parquet.signals
    for name in from_csv.signals:                 # the same numbers whichever file format
        assert np.array_equal(np.asarray(from_parquet.signals[name]), np.asarray(from_csv.signals[name])), name


# --- temperature signals ---------------------------------------------------------------------------

def test_temperatures_become_kelvin_and_degc_is_an_offset(tmp_path, rig):
    # 20 degC is 293.15 K (the kelvin's definition: T/K = t/degC + 273.15), not 20 K; 68 degF is
    # the same temperature (t/degF = 1.8 t/degC + 32)
    t = _times()
    path = _csv(tmp_path / "t.csv", {"time [s]": t, "hip pressure [bar gauge]": np.full(t.size, 2.0),
                                      "source temperature [degC]": np.full(t.size, 20.0),
                                      "hip temperature [K]": np.full(t.size, 300.0),
                                      "exhaust temperature [degF]": np.full(t.size, 68.0)})
    tr = read_trace(path, rig)
    np.testing.assert_allclose(tr.signals["source temperature"], 293.15, rtol=1e-14)
    np.testing.assert_allclose(tr.signals["hip temperature"], 300.0, rtol=1e-14)
    np.testing.assert_allclose(tr.signals["exhaust temperature"], 293.15, rtol=1e-12)
    np.testing.assert_allclose(tr.signals["hip pressure"], 2e5 + P_ATM)     # pressures as before


@pytest.mark.parametrize("unit, expect", [
    ("K abs", "takes no gauge or abs"),
    ("degC gauge", "takes no gauge or abs"),
    ("delta_degC", "temperature difference"),
    ("bar", "not a temperature unit"),
    ("kelvinn", "not a temperature unit"),
])
def test_bad_temperature_units_are_refused_in_one_line(tmp_path, rig, unit, expect):
    path = _csv(tmp_path / "badT.csv", {"time [s]": [0, 0.1, 0.2, 0.5], "hip pressure [bar gauge]": [1, 2, 3, 4],
                                        f"source temperature [{unit}]": [290, 291, 292, 293]})
    with pytest.raises(ScenarioError) as exc:
        read_trace(path, rig)
    msg = str(exc.value)
    assert "\n" not in msg and "badT.csv" in msg and f"'source temperature [{unit}]'" in msg and expect in msg, msg


@pytest.mark.parametrize("unit, value, kelvin", [
    ("K", -5.0, "-5 K"), ("K", 0.0, "0 K"), ("degC", -300.0, "-26.85 K"), ("K", 1e6, "1e+06 K"),
    ("degF", -190.0, "149.817 K"), ("degC", 727.0, "1000.15 K"),     # just outside 150 K and 1000 K
])
def test_temperatures_outside_the_gas_range_are_refused(tmp_path, rig, unit, value, kelvin):
    # the issue's -5 K, 0 K, -300 degC (= -26.85 K) and 1e6 K, and two values just outside 150..1000 K
    col = f"source temperature [{unit}]"
    path = _csv(tmp_path / "hotT.csv", {"time [s]": [0, 0.1, 0.2, 0.5], "hip pressure [bar gauge]": [1, 2, 3, 4],
                                        col: [293.0 if unit == "K" else 20.0, value, value, value]})
    with pytest.raises(ScenarioError) as exc:
        read_trace(path, rig)
    msg = str(exc.value)
    assert "\n" not in msg and "hotT.csv" in msg and repr(col) in msg, msg
    assert f"{kelvin} in data row 2 (3 in all)" in msg and "allowed: 150 K to 1000 K" in msg, msg


def test_temperatures_on_the_bounds_are_read(tmp_path, rig):
    path = _csv(tmp_path / "edgeT.csv", {"time [s]": [0, 0.1, 0.2, 0.5], "hip pressure [bar gauge]": [1, 2, 3, 4],
                                         "source temperature [degC]": [-123.15, 726.85, 20.0, 20.0]})
    np.testing.assert_allclose(read_trace(path, rig).signals["source temperature"][:2], [150.0, 1000.0])


def test_simulated_temperature_is_the_results(rig):
    from frogsim.fit.traces import model_signals, signal_kind, simulated
    res = frogsim.simulate(rig)
    assert "source temperature" in model_signals(rig) and "hip temperature" in model_signals(rig)
    assert signal_kind("hip temperature") == "temperature" and signal_kind("hip pressure") == "pressure"
    # T = p V/(m R) of the source, from the state itself (ideal gas), not through Result.temperature
    V = rig.source.volume
    T = res.source_pressure * V / (res.y[:, 0] * rig.air.gas_constant)
    np.testing.assert_allclose(simulated(res, "source temperature"), T, rtol=1e-12)
