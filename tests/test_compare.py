"""frogsim compare: one signal of several runs (simulate folders, or scenarios run on the spot) in
one CSV equal to the runs' own time series, and one figure; bad inputs exit 2 with nothing written."""
import json

import numpy as np
import pandas as pd

from frogsim.cli import main
from frogsim.io.compare import signal_of

BASE = """
name = "cmp"
duration = "0.5 s"
[programs.stroke]
pressurise = "0.3 s"
release = "0.2 s"
[muscles.hip_left]
type = "hip"
program = "stroke"
motion = {{ kind = "constant" }}
[source]
initial_pressure_gauge = "{p}"
"""


def scenarios(tmp_path):
    for name, p in (("high", "6 bar"), ("low", "3 bar")):
        (tmp_path / f"{name}.toml").write_text(BASE.format(p=p))
    return tmp_path / "high.toml", tmp_path / "low.toml"


def test_signal_names():
    # the older spellings (timeseries.csv of frogsim 0.1, compare CSVs' "bar (gauge)") read as the one written now
    assert signal_of("hip_left_pressure_bar_gauge") == ("hip_left pressure", "bar gauge")
    assert signal_of("source_pressure_bar_gauge") == ("source pressure", "bar gauge")
    assert signal_of("knee_right_discharge_flow_L_per_min_std") == ("knee_right discharge flow", "L/min std")
    assert signal_of("hip_charge_valve") == ("hip charge valve", "1 = open")
    assert signal_of("pump_on") == ("pump on", "1 = on")
    assert signal_of("time_s") == ("time", "s")
    assert signal_of("fast [bar gauge]") == ("fast", "bar gauge")
    assert signal_of("hip_left pressure [bar gauge]") == ("hip_left pressure", "bar gauge")


def test_compare_csv_equals_the_runs_own_time_series(tmp_path, capsys):
    high, low = scenarios(tmp_path)
    for s in (high, low):
        assert main(["simulate", str(s), "--out", str(tmp_path / f"run-{s.stem}")]) == 0
    out = tmp_path / "cmp"
    # two simulate folders, and a scenario file run on the spot
    assert main(["compare", str(tmp_path / "run-high"), str(tmp_path / "run-low"), str(low),
                 "--signal", "hip_left pressure", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["hip_left-pressure.csv", "hip_left-pressure.png", "manifest.json"]
    table = pd.read_csv(out / "hip_left-pressure.csv")
    assert list(table.columns) == ["time [s]", "run-high [bar gauge]", "run-low [bar gauge]", "low [bar gauge]"]
    own_high = pd.read_csv(tmp_path / "run-high" / "timeseries.csv")
    own_low = pd.read_csv(tmp_path / "run-low" / "timeseries.csv")
    assert np.array_equal(table["time [s]"].to_numpy(), own_high["time [s]"].to_numpy())
    assert np.array_equal(table["run-high [bar gauge]"].to_numpy(), own_high["hip_left pressure [bar gauge]"].to_numpy())
    assert np.array_equal(table["run-low [bar gauge]"].to_numpy(), own_low["hip_left pressure [bar gauge]"].to_numpy())
    # the scenario run here gives what frogsim simulate wrote for it
    assert np.array_equal(table["low [bar gauge]"].to_numpy(), own_low["hip_left pressure [bar gauge]"].to_numpy())
    assert table["run-high [bar gauge]"].max() > table["run-low [bar gauge]"].max() + 1      # 6 vs 3 bar source
    assert (out / "hip_left-pressure.png").read_bytes()[:4] == b"\x89PNG"
    m = json.loads((out / "manifest.json").read_text())
    assert m["command"] == "compare" and {f["name"] for f in m["files"]} == {"hip_left-pressure.csv",
                                                                             "hip_left-pressure.png"}
    roles = [f["role"] for f in m["scenario"]["inputs"]]
    assert "run-high: run timeseries.csv" in roles and "low: scenario" in roles
    # the same compare again is refused without --overwrite
    before = (out / "hip_left-pressure.csv").read_bytes()
    capsys.readouterr()
    assert main(["compare", str(tmp_path / "run-high"), "--signal", "source pressure", "--out", str(out)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (out / "hip_left-pressure.csv").read_bytes() == before
    assert main(["compare", str(tmp_path / "run-high"), "--signal", "source_pressure_bar_gauge", "--out", str(out),
                 "--overwrite"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["manifest.json", "source-pressure.csv", "source-pressure.png"]


def test_different_time_grids_share_one_time_column(tmp_path):
    high, low = scenarios(tmp_path)
    low.write_text(low.read_text().replace('duration = "0.5 s"', 'duration = "0.6 s"').replace(
        'release = "0.2 s"', 'release = "0.3 s"'))
    assert main(["compare", str(high), str(low), "--signal", "source pressure", "--out", str(tmp_path / "c")]) == 0
    t = pd.read_csv(tmp_path / "c" / "source-pressure.csv")
    assert len(t) == 601 and t["time [s]"].iloc[-1] == 0.6
    assert t["high [bar gauge]"].isna().sum() == 100 and t["low [bar gauge]"].notna().all()


def test_bad_inputs_exit_2_one_line_nothing_written(tmp_path, capsys):
    high, low = scenarios(tmp_path)
    out = tmp_path / "cmp"
    cases = [
        ([str(high), "--signal", "hip_left presure"], ["hip_left presure", "hip_left pressure", "source pressure"]),
        ([str(high), str(tmp_path / "nope"), "--signal", "source pressure"], ["nope", "no such folder"]),
        ([str(tmp_path), "--signal", "source pressure"], ["timeseries.csv"]),
    ]
    bad = tmp_path / "bad.toml"
    bad.write_text(BASE.format(p="-4 bar"))
    cases.append(([str(high), str(bad), "--signal", "source pressure"], ["source.initial_pressure_gauge"]))
    for argv, words in cases:
        capsys.readouterr()
        assert main(["compare", *argv, "--out", str(out)]) == 2, argv
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "Traceback" not in err, err
        for w in words:
            assert w in err, (w, err)
        assert not out.exists()
