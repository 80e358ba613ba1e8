"""Output folders: file modes follow the umask, a folder belongs to one command, a run is never
replaced without --overwrite (and a refusal writes nothing), manifest.json names what was run and
what was written."""
import hashlib
import json
import os
import stat

import pandas as pd
import pytest

from frogsim import __version__
from frogsim._files import atomic_write, write_csv, write_figure, write_json
from frogsim.cli import main

SCENARIO = """
name = "out-test"
duration = "0.5 s"
[programs.stroke]
pressurise = "0.3 s"
release = "0.2 s"
[muscles.hip]
type = "hip"
program = "stroke"
"""
CONSTANT = 'motion = { kind = "constant" }\n'


def sha(path) -> str:
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


def snapshot(folder):
    """name -> (bytes, mtime) of every file in a folder."""
    return {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(folder.iterdir())}


@pytest.fixture
def umask():
    """Set a umask for the test (restored afterwards)."""
    old = os.umask(0o022)
    os.umask(old)
    yield lambda m: os.umask(m)
    os.umask(old)


@pytest.mark.parametrize("mask", [0o027, 0o002, 0o077])
def test_every_writer_follows_the_umask(tmp_path, umask, mask):
    umask(mask)
    write_json(tmp_path / "a.json", {"x": 1})
    write_csv(tmp_path / "a.csv", pd.DataFrame({"x": [1.0]}))

    def draw(path):
        import matplotlib.pyplot as plt
        fig = plt.figure()
        fig.savefig(path)
        plt.close(fig)
    write_figure(tmp_path / "a.png", draw)
    atomic_write(tmp_path / "a.xml", lambda tmp: open(tmp, "w").write("<x/>"))
    for name in ("a.json", "a.csv", "a.png", "a.xml"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o666 & ~mask, name


def test_simulate_files_follow_the_umask(tmp_path, umask):
    umask(0o002)
    (tmp_path / "s.toml").write_text(SCENARIO + CONSTANT)
    assert main(["simulate", str(tmp_path / "s.toml"), "--out", str(tmp_path / "o")]) == 0
    for p in (tmp_path / "o").iterdir():
        assert stat.S_IMODE(p.stat().st_mode) == 0o664, p.name


def test_simulate_again_refused_without_overwrite_nothing_touched(tmp_path, capsys):
    (tmp_path / "s.toml").write_text(SCENARIO + CONSTANT)
    out = tmp_path / "o"
    assert main(["simulate", str(tmp_path / "s.toml"), "--out", str(out)]) == 0
    before = snapshot(out)
    capsys.readouterr()
    assert main(["simulate", str(tmp_path / "s.toml"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--overwrite" in err and "simulate" in err
    assert snapshot(out) == before                 # refused before any write
    assert main(["simulate", str(tmp_path / "s.toml"), "--out", str(out), "--overwrite"]) == 0
    m = json.loads((out / "manifest.json").read_text())
    assert m["command_line"].endswith("--overwrite") and m["status"] == "complete"


def test_a_folder_belongs_to_one_command(tmp_path, capsys):
    (tmp_path / "s.toml").write_text(SCENARIO + CONSTANT)
    out = tmp_path / "o"
    assert main(["simulate", str(tmp_path / "s.toml"), "--out", str(out)]) == 0
    before = snapshot(out)
    assert main(["reproduce", "aeration", "--out", str(out)]) == 2
    assert "frogsim simulate" in capsys.readouterr().err
    assert snapshot(out) == before
    # --overwrite: the folder changes hands; the simulate run's files go, its summary is not merged
    assert main(["reproduce", "aeration", "--out", str(out), "--overwrite"]) == 0
    names = {p.name for p in out.iterdir()}
    assert names == {"aeration.csv", "aeration.png", "summary.json", "manifest.json"}
    summary = json.loads((out / "summary.json").read_text())
    assert list(summary) == ["aeration_volume_L"]
    m = json.loads((out / "manifest.json").read_text())
    assert m["command"] == "reproduce" and list(m["studies"]) == ["aeration"] and len(m["runs"]) == 1


def test_reproduce_adds_studies_but_replaces_one_only_with_overwrite(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["reproduce", "aeration", "--out", str(out)]) == 0
    assert main(["reproduce", "tube-modes", "--out", str(out)]) == 0
    before = snapshot(out)
    assert main(["reproduce", "tube-modes", "--out", str(out)]) == 2
    assert "tube-modes" in capsys.readouterr().err
    assert snapshot(out) == before
    assert main(["design", "design-valve", "--out", str(out)]) == 2        # another command
    assert snapshot(out) == before
    assert main(["reproduce", "tube-modes", "--out", str(out), "--overwrite"]) == 0
    after = snapshot(out)
    assert after["aeration.csv"] == before["aeration.csv"]                 # the other study kept as it was
    assert after["tube-modes.csv"][1] != before["tube-modes.csv"][1]       # this one rewritten
    summary = json.loads((out / "summary.json").read_text())
    assert {"aeration_volume_L", "tube_modes"} <= set(summary)
    m = json.loads((out / "manifest.json").read_text())
    assert set(m["studies"]) == {"aeration", "tube-modes"} and len(m["runs"]) == 3
    assert {f["name"] for f in m["files"]} == {"aeration.csv", "aeration.png", "tube-modes.csv",
                                                "tube-modes.png", "summary.json"}


def test_a_folder_without_manifest_holding_our_files_is_refused(tmp_path, capsys):
    (tmp_path / "s.toml").write_text(SCENARIO + CONSTANT)
    out = tmp_path / "o"
    out.mkdir()
    (out / "timeseries.csv").write_text("somebody else's\n")
    (out / "notes.txt").write_text("mine\n")
    assert main(["simulate", str(tmp_path / "s.toml"), "--out", str(out)]) == 2
    assert "timeseries.csv" in capsys.readouterr().err
    assert (out / "timeseries.csv").read_text() == "somebody else's\n"
    assert not (out / "manifest.json").exists()
    # a folder holding only unrelated files is fine, and they are left alone
    (out / "timeseries.csv").unlink()
    assert main(["simulate", str(tmp_path / "s.toml"), "--out", str(out)]) == 0
    assert (out / "notes.txt").read_text() == "mine\n"


def test_manifest_names_command_inputs_and_files(tmp_path):
    csv = tmp_path / "angles.csv"
    csv.write_text("time_s,hip_deg\n0,0\n0.1,0\n0.3,5\n0.5,5\n")
    scen = tmp_path / "s.toml"
    scen.write_text(SCENARIO + 'motion = { kind = "joint_angles", file = "angles.csv", column = "hip_deg" }\n')
    out = tmp_path / "o"
    assert main(["simulate", str(scen), "--out", str(out)]) == 0
    m = json.loads((out / "manifest.json").read_text())
    assert m["command"] == "simulate" and m["frogsim_version"] == __version__
    assert m["command_line"] == f"frogsim simulate {scen} --out {out}"
    assert m["status"] == "complete" and m["started"] <= m["finished"]
    from frogsim.scenario.load import PARAMS_DIR
    inputs = {f["role"]: f for f in m["scenario"]["inputs"]}
    assert inputs["scenario"]["sha256"] == sha(scen)
    assert inputs["parameters"]["sha256"] == sha(PARAMS_DIR / "fan2017.toml")
    assert inputs["muscles.hip.motion.file"]["sha256"] == sha(csv)
    expected = hashlib.sha256(json.dumps([[f["role"], f["sha256"]] for f in m["scenario"]["inputs"]]).encode())
    assert m["scenario"]["sha256"] == expected.hexdigest() and m["scenario"]["name"] == "out-test"
    files = {f["name"]: f for f in m["files"]}
    assert set(files) == {"timeseries.csv", "pressures.png", "summary.json"}
    for name, f in files.items():
        assert f["sha256"] == sha(out / name) and f["bytes"] == (out / name).stat().st_size
    # the scenario hash changes with any file the scenario reads
    csv.write_text("time_s,hip_deg\n0,0\n0.1,0\n0.3,6\n0.5,6\n")
    assert main(["simulate", str(scen), "--out", str(tmp_path / "o2")]) == 0
    m2 = json.loads((tmp_path / "o2" / "manifest.json").read_text())
    assert m2["scenario"]["sha256"] != m["scenario"]["sha256"]


def test_bad_input_in_an_owned_folder_writes_nothing(tmp_path):
    (tmp_path / "s.toml").write_text(SCENARIO + CONSTANT)
    out = tmp_path / "o"
    assert main(["simulate", str(tmp_path / "s.toml"), "--out", str(out)]) == 0
    before = snapshot(out)
    (tmp_path / "bad.toml").write_text(SCENARIO + CONSTANT + "[source]\nvolume = \"-4 L\"\n")
    assert main(["simulate", str(tmp_path / "bad.toml"), "--out", str(out), "--overwrite"]) == 2
    assert snapshot(out) == before


def test_swim_folder_has_a_manifest_and_is_not_rerun_by_accident(tmp_path, capsys):
    from test_swim_cli import _scenario
    scen = _scenario(tmp_path)
    out = tmp_path / "swim"
    assert main(["swim", str(scen), "--out", str(out), "--no-animation"]) == 0
    m = json.loads((out / "manifest.json").read_text())
    assert m["command"] == "swim" and m["status"] == "complete"
    assert {f["name"] for f in m["files"]} == {"timeseries.csv", "swim.png", "frog.xml", "summary.json"}
    assert {f["role"] for f in m["scenario"]["inputs"]} == {"scenario", "parameters"}
    assert stat.S_IMODE((out / "frog.xml").stat().st_mode) == 0o666 & ~_current_umask()
    before = snapshot(out)
    assert main(["swim", str(scen), "--out", str(out), "--no-animation"]) == 2
    assert snapshot(out) == before
    assert main(["reproduce", "aeration", "--out", str(out)]) == 2              # another command
    assert "frogsim swim" in capsys.readouterr().err
    assert snapshot(out) == before


def _current_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_fit_folder_is_owned_and_not_rerun_by_accident(tmp_path, capsys):
    from pathlib import Path
    example = Path(__file__).resolve().parent.parent / "examples" / "fit" / "FIT.toml"
    out = tmp_path / "fit"
    assert main(["fit", str(example), "--out", str(out), "--quiet", "--starts", "1"]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["command"] == "fit" and manifest["status"] == "complete"
    assert {"report.html", "summary.json", "fitted-parameters.toml"} <= {f["name"] for f in manifest["files"]}
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    capsys.readouterr()
    assert main(["fit", str(example), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--overwrite" in err
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before       # nothing touched
