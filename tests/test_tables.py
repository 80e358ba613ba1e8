"""One CSV convention and one reader: frogsim's outputs are valid fit traces and compare inputs, and a
table that is not what its header says is refused (exit 2, one line, nothing written) by every
command that reads one."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import frogsim
from frogsim.cli import main
from frogsim.errors import ScenarioError
from frogsim.scenario.tables import read_table, split_header

from fit_helpers import P_ATM, write_rig

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A simulate folder of the fit tests' 0.5 s rig (one hip muscle)."""
    folder = tmp_path_factory.mktemp("run")
    rig = write_rig(folder)
    assert main(["simulate", str(rig), "--out", str(folder / "run"), "--quiet"]) == 0
    return folder


def test_headers_are_name_and_unit(run):
    head = (run / "run" / "timeseries.csv").read_text().splitlines()[0].split(",")
    assert head[0] == "time [s]"
    for col in head:
        name, unit = split_header(col)
        assert col == f"{name} [{unit}]" and unit, col      # every column carries its unit
    assert "hip pressure [bar gauge]" in head and "source pressure [bar gauge]" in head


def test_old_spellings_read_as_the_new(tmp_path):
    (tmp_path / "old.csv").write_text("time_s,hip_pressure_bar_gauge\n0,1\n0.1,2\n")
    t = read_table(tmp_path / "old.csv")
    assert [split_header(c) for c in t.columns] == [("time", "s"), ("hip pressure", "bar gauge")]


def test_fit_takes_a_simulate_folders_timeseries_unchanged(run, tmp_path):
    """The trace is the model's own output: the fit finds the value that made it."""
    import tomllib
    fan = tomllib.loads((ROOT / "src" / "frogsim" / "params" / "fan2017.toml").read_text())
    assert fan["valves"]["charge"]["sonic_conductance"]["value"] == "0.4 L/(s*bar)"
    want = 0.4e-3 / 1e5                                          # 0.4 L/(s bar) in m^3/(s Pa)
    spec = tmp_path / "fit.toml"
    spec.write_text(f'''scenario = "{run / 'rig.toml'}"
starts = 1
[[experiments]]
trace = "{run / 'run' / 'timeseries.csv'}"
[parameters]
"valves.charge.sonic_conductance" = {{ min = "0.1 L/(s*bar)", max = "2 L/(s*bar)", start = "0.3 L/(s*bar)" }}
''')
    out = tmp_path / "fit"
    assert main(["fit", str(spec), "--out", str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    got = s["parameters"]["valves.charge.sonic_conductance"]["value_si"]
    assert got == pytest.approx(want, rel=1e-3), (got, want)


def test_fit_refuses_a_trace_far_longer_than_the_scenario(run, tmp_path):
    from frogsim.fit.traces import read_trace
    sc = frogsim.load_scenario(run / "rig.toml")
    t = np.arange(0, 501) * 1.0                                  # ms written as s: 0..500 s
    pd.DataFrame({"time [s]": t, "hip pressure [bar gauge]": np.ones_like(t)}).to_csv(tmp_path / "long.csv",
                                                                                     index=False)
    with pytest.raises(ScenarioError, match=r"long.csv.*ends at 500 s.*0.5 s"):
        read_trace(tmp_path / "long.csv", sc)


HEAD = "time [s],hip pressure [bar gauge],valve temperature [degC]"


@pytest.mark.parametrize("make, words", [
    (lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00binary"), ["binary"]),
    (lambda p: p.mkdir(), ["directory"]),
    (lambda p: None, ["not found"]),
    (lambda p: p.write_text(f"{HEAD}\n0,1,20\n0.1,2,7,1\n"), ["line 3", "4 fields", "3"]),
    (lambda p: p.write_text(f"{HEAD}\n0,1,20\n0.1\n"), ["line 3", "1 field"]),
    (lambda p: p.write_text(f"{HEAD}\n0,1,20\n0.25,abc,20\n0.5,2,20\n"), ["row 2", "'abc'"]),
    (lambda p: p.write_text(""), ["empty"]),
])
def test_a_bad_trace_says_what_is_wrong(run, tmp_path, capsys, make, words):
    trace = tmp_path / "trace.csv"
    make(trace)
    spec = tmp_path / "fit.toml"
    spec.write_text(f'''scenario = "{run / 'rig.toml'}"
[[experiments]]
trace = "trace.csv"
ignore_columns = ["valve temperature [degC]"]
[parameters]
"valves.charge.sonic_conductance" = {{ min = "0.1 L/(s*bar)", max = "2 L/(s*bar)" }}
''')
    out = tmp_path / "fit"
    assert main(["fit", str(spec), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "trace.csv" in err and "ignore_columns" not in err, err
    for w in words:
        assert w in err, (w, err)
    assert not out.exists()


def test_compare_overlays_differently_named_muscles(tmp_path, capsys):
    """hip of one run against hip_left of another: RUN:SIGNAL; the CSV holds each run's own numbers."""
    assert main(["simulate", str(ROOT / "examples" / "one-hip.toml"), "--out", str(tmp_path / "one-hip"),
                 "--quiet"]) == 0
    assert main(["simulate", "paper-cycle", "--out", str(tmp_path / "paper"), "--quiet"]) == 0
    out = tmp_path / "cmp"
    assert main(["compare", f"{tmp_path / 'one-hip'}:hip pressure", f"{tmp_path / 'paper'}:hip_left pressure",
                 "--out", str(out), "--quiet"]) == 0
    table = pd.read_csv(out / "hip-pressure.csv")
    own = pd.read_csv(tmp_path / "one-hip" / "timeseries.csv")
    paper = pd.read_csv(tmp_path / "paper" / "timeseries.csv")
    assert list(table.columns) == ["time [s]", "one-hip [bar gauge]", "paper [bar gauge]"]
    assert np.array_equal(table["one-hip [bar gauge]"].to_numpy(), own["hip pressure [bar gauge]"].to_numpy())
    assert np.array_equal(table["paper [bar gauge]"].to_numpy(), paper["hip_left pressure [bar gauge]"].to_numpy())
    # a compare CSV and a timeseries.csv are compare inputs too
    out2 = tmp_path / "cmp2"
    assert main(["compare", f"{out / 'hip-pressure.csv'}:one-hip", f"{tmp_path / 'paper' / 'timeseries.csv'}"
                 ":hip_left pressure", "--out", str(out2), "--quiet"]) == 0
    again = pd.read_csv(out2 / "one-hip.csv")
    assert np.array_equal(again.iloc[:, 1].to_numpy(), own["hip pressure [bar gauge]"].to_numpy())
    # a bare muscle name is that muscle's pressure: one-hip:hip with paper:hip_left
    out3 = tmp_path / "cmp3"
    assert main(["compare", f"{tmp_path / 'one-hip'}:hip", f"{tmp_path / 'paper'}:hip_left",
                 "--out", str(out3), "--quiet"]) == 0
    bare = pd.read_csv(out3 / "hip-pressure.csv")
    assert bare.equals(table)


@pytest.mark.parametrize("damage, words", [
    ("extra", ["line 2", "17 fields", "16"]),
    ("truncate", ["truncated"]),
    ("edit", ["manifest.json"]),
    ("rows", ["ends at 0.249 s", "summary.json says 0.5 s", "truncated"]),
])
def test_compare_refuses_a_damaged_run(run, tmp_path, capsys, damage, words):
    folder = tmp_path / "copy"
    shutil.copytree(run / "run", folder)
    csv = folder / "timeseries.csv"
    text = csv.read_text()
    lines = text.splitlines(keepends=True)
    if damage == "extra":       # a field too many in one row (a hand edit): never shifted into the next column
        lines[1] = lines[1].rstrip("\n") + ",999\n"
        csv.write_text("".join(lines))
        (folder / "manifest.json").unlink()
    elif damage == "truncate":
        csv.write_text(text[: len(text) - 7])
        (folder / "manifest.json").unlink()
    elif damage == "rows":      # whole rows cut off at a line's end, the manifest gone too
        csv.write_text("".join(lines[:251]))
        (folder / "manifest.json").unlink()
    else:
        csv.write_text(text.replace(lines[5].split(",")[1], "9.99", 1))
    out = tmp_path / "cmp"
    assert main(["compare", str(folder), "--signal", "hip pressure", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, (w, err)
    assert not out.exists()


def test_the_fit_report_shows_overrides_in_their_units():
    from frogsim.fit.report import overrides_text
    v = frogsim.load_scenario("paper-cycle").variable_paths()
    text = overrides_text({"source.initial_pressure_gauge": 4e5,             # 4e5 Pa = 4 bar
                           "valves.charge.sonic_conductance": 8e-9,          # m^3/(s Pa) = 0.8 L/(s bar)
                           "supply.mode": "physical"}, v)
    assert text == ("source.initial_pressure_gauge = 4 bar, valves.charge.sonic_conductance = 0.8 L/(s*bar), "
                    "supply.mode = 'physical'")
    assert "SI" not in text and "{" not in text
