"""The command line: outputs, the summary.json contract, and bad input (exit 2, nothing written)."""
import json
import subprocess
import sys

import pytest

from frogsim.cli import main

BASE = """
name = "cli-test"
duration = "2 s"
[programs.stroke]
pressurise = "1 s"
release = "1 s"
[muscles.hip]
type = "hip"
program = "stroke"
"""

BAD = {
    "unknown key": ("[source]\nvolum = \"4 L\"\n", "source.volum"),
    "wrong unit": ("[source]\nvolume = \"4 bar\"\n", "source.volume"),
    "negative volume": ("[source]\nvolume = \"-4 L\"\n", "source.volume"),
    "gauge below -1 bar": ("[source]\ninitial_pressure_gauge = \"-1.5 bar\"\n", "source.initial_pressure_gauge"),
    "contraction beyond limit": ("[muscles.hip.motion]\nkind = \"constant\"\ncontraction = \"30 %\"\n",
                                 "muscles.hip.motion.contraction"),
    "unknown motion kind": ("[muscles.hip.motion]\nkind = \"wiggle\"\n", "muscles.hip.motion.kind"),
    "pump band inverted": ("[pump]\non_below_gauge = \"6.5 bar\"\n", "pump.on_below_gauge"),
    "bare number for a length": ("[supply]\nmain_tube_inner_diameter = 4\n", "supply.main_tube_inner_diameter"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scenario_exit_2_one_line_nothing_written(tmp_path, capsys, case):
    extra, field = BAD[case]
    scen = tmp_path / "bad.toml"
    if case.startswith(("contraction", "unknown motion")):
        scen.write_text(BASE + "\n" + extra.replace("[muscles.hip.motion]", "[muscles.hip.motion]"))
    else:
        scen.write_text(BASE + "\n" + extra)
    out = tmp_path / "out"
    code = main(["simulate", str(scen), "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1, err
    assert field in err and "Traceback" not in err
    assert not out.exists()


def test_bad_scenario_through_real_process(tmp_path):
    scen = tmp_path / "bad.toml"
    scen.write_text(BASE + "[source]\nvolume = \"-4 L\"\n")
    p = subprocess.run([sys.executable, "-m", "frogsim", "simulate", str(scen), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert p.returncode == 2
    assert p.stderr.strip().splitlines() == ["frogsim: error: source.volume = '-4 L': must be > 0 L"]
    assert not (tmp_path / "o").exists()


def test_unknown_study_exit_2(tmp_path, capsys):
    assert main(["reproduce", "fig99", "--out", str(tmp_path / "r")]) == 2
    assert "fig99" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_simulate_writes_csv_plot_summary(tmp_path):
    scen = tmp_path / "ok.toml"
    scen.write_text(BASE)
    assert main(["simulate", str(scen), "--out", str(tmp_path / "o")]) == 0
    csv = (tmp_path / "o" / "timeseries.csv").read_text().splitlines()
    header = csv[0].split(",")
    assert "hip pressure [bar gauge]" in header and "time [s]" in header
    assert len(csv) == 2001 + 1       # 0..2 s every 1 ms, plus the header
    assert (tmp_path / "o" / "pressures.png").read_bytes()[:4] == b"\x89PNG"
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    # one muscle from a 6 bar source: it ends the pressurise phase near the source pressure
    assert 5.0 < s["source"]["final_pressure_bar_gauge"] <= 6.0
    assert s["air_mass_relative_drift"] < 1e-9


def test_reproduce_summary_contract(tmp_path):
    out = tmp_path / "r"
    assert main(["reproduce", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert set(s["aeration_volume_L"]) == {"hip", "knee", "ankle"}
    assert isinstance(s["branch_saturation_L_per_min"], float)
    assert "pressure_drop_bar" in s["source_chamber"]
    for label in ("saturated", "unsaturated"):
        rows = s["source_pressure_sweep"][label]
        assert [r["source_pressure_bar_gauge"] for r in rows] == [3, 4, 5, 6]
        for r in rows:
            assert {"rise_time_90_s", "final_muscle_pressure_bar_gauge"} <= set(r)
    assert all({"volume_constant_percent", "rise_time_90_s"} <= set(r) for r in s["muscle_volume_sweep"])
    assert all({"branch_limit_L_per_min", "rise_time_90_s"} <= set(r) for r in s["saturation_sweep"])
    for mode in ("paper", "physical"):
        assert {"one_branch_L_per_min", "six_branches_L_per_min"} <= set(s["tube_modes"][mode])
    from frogsim.studies import studies_in
    for name in studies_in("paper"):
        assert (out / f"{name}.png").exists() and (out / f"{name}.csv").exists()
    for name in studies_in("design"):           # the design studies belong to `frogsim design`
        assert not (out / f"{name}.png").exists()


def test_named_robot_study_adds_to_the_folders_summary(tmp_path):
    out = tmp_path / "r"
    assert main(["reproduce", "aeration", "--out", str(out)]) == 0
    assert main(["reproduce", "leg-in-air", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert "aeration_volume_L" in s                       # kept from the first run
    assert len(s) > 1 and (out / "leg-in-air.png").exists()


def test_design_command_writes_conclusions(tmp_path):
    out = tmp_path / "d"
    assert main(["design", "design-valve", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert "C^" in s["design_valve"]["conclusion"]
    assert (out / "design-valve.png").read_bytes()[:4] == b"\x89PNG"


def test_studies_and_params_listing(capsys):
    assert main(["studies"]) == 0
    listed = capsys.readouterr().out
    for name in ("fig13", "fig14", "fig15", "fig16", "fig17", "aeration", "tube-modes"):
        assert name in listed
    assert main(["params"]) == 0
    text = capsys.readouterr().out
    assert "source.volume" in text and "paper Sec. 2.2.1" in text
