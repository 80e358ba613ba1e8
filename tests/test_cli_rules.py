"""Rules every command keeps, each tested as the general rule over every command it concerns:

- a bad --out (empty, blank, the filesystem root, a place that cannot be written, an existing
  file, a path under a file, a device, a NUL, a name too long; for sweep and plot a folder or a
  wrong suffix) gives exit 2, one line on stderr, no traceback, and nothing written anywhere;
- a command-line mistake argparse finds is one line too;
- the shipped scenarios are listed (`frogsim scenarios`), an unknown scenario name lists them;
- `frogsim --version` prints the package's version.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import frogsim
from frogsim.cli import build_parser, main
from frogsim.scenario.load import SCENARIOS_DIR

from sweep_helpers import source_pressure_sweep, write_case

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def sweep_results(tmp_path_factory):
    """A small sweep's results (8 points), for plot."""
    folder = tmp_path_factory.mktemp("sweep")
    spec = write_case(folder, spec=SMALL)
    assert main(["sweep", str(spec), "--out", str(folder / "r.nc"), "--quiet"]) == 0
    return folder


SMALL = source_pressure_sweep(4)


def commands(res: Path) -> dict[str, tuple[list[str], str]]:
    """Every command that writes: (its arguments apart from --out, valid ones), and what --out is."""
    return {
        "reproduce": (["reproduce", "aeration"], "dir"),
        "design": (["design", "design-valve"], "dir"),
        "control": (["control", "control-pressure"], "dir"),
        "simulate": (["simulate", "paper-cycle"], "dir"),
        "swim": (["swim", "leg-in-air", "--cycles", "1", "--no-animation"], "dir"),
        "compare": (["compare", "paper-cycle", "--signal", "source pressure"], "dir"),
        "fit": (["fit", str(ROOT / "examples" / "fit" / "FIT.toml")], "dir"),
        "optimize-gait": (["optimize-gait", "swim", "--trials", "1", "--objective", "speed", "--cycles", "1"],
                          "dir"),
        "tune": (["tune", "hip-angle-in-air", "--trials", "1"], "dir"),
        "sweep": (["sweep", str(res / "spec.toml")], ".nc"),
        "plot": (["plot", str(res / "r.nc"), "--x", "source.initial_pressure_gauge", "--metric", "rise_time"],
                 ".png"),
        "firmware": (["firmware", "hold-3bar"], "dir"),
        "sil": (["sil", "hold-3bar", "--firmware", str(res / "no-firmware-here")], "dir"),
        "log": (["log", "--port", str(res / "no-port-here"), "--duration", "1"], "dir"),
    }


def test_every_writing_command_is_covered():
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    writing = {name for name, p in sub.choices.items()
               if any("--out" in a.option_strings for a in p._actions)}
    assert writing == set(commands(Path("."))), writing


def _bad_outs(tmp: Path, kind: str) -> list[str]:
    afile = tmp / "a-file.png" if kind == ".png" else tmp / "a-file.nc" if kind == ".nc" else tmp / "a-file"
    afile.write_text("somebody's file\n")
    suffix = "" if kind == "dir" else kind
    bad = ["", "   ", "/", "//", "/proc/x/y" + suffix, "/sys/frogsim" + suffix, str(afile / ("sub" + suffix)),
           "/dev/null", "a\x00b" + suffix, str(tmp / ("x" * 300 + suffix)), "/proc/self/x" + suffix]
    if kind == "dir":
        bad.append(str(afile))                       # an existing file is no folder
    else:
        bad += [str(tmp), str(tmp / ("fig" + (".txt" if kind == ".png" else ".png"))), str(tmp / kind)]
        if kind == ".png":
            bad.append(str(afile))                   # an existing file is not replaced without --overwrite
    return bad


def _tree(path: Path) -> dict:
    return {str(p.relative_to(path)): (p.stat().st_size, p.stat().st_mtime_ns) for p in path.rglob("*")
            if not p.is_dir()} | {str(p.relative_to(path)) + "/": 0 for p in path.rglob("*") if p.is_dir()}


@pytest.mark.parametrize("command", ["reproduce", "design", "control", "simulate", "swim", "compare", "fit",
                                     "optimize-gait", "sweep", "plot", "firmware", "sil", "log"])
def test_bad_out_exit_2_one_line_nothing_written(command, sweep_results, tmp_path, monkeypatch, capsys):
    argv, kind = commands(sweep_results)[command]
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    bad = _bad_outs(tmp_path, kind)
    root_before = sorted(os.listdir("/"))
    res_before = _tree(sweep_results)
    before = _tree(tmp_path)
    for out in bad:
        capsys.readouterr()
        code = main([*argv, "--out", out])
        err = capsys.readouterr().err
        assert code == 2, (command, out, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("frogsim: error: --out") and "Traceback" not in err, \
            (command, out, err)
        assert _tree(tmp_path) == before, (command, out)
    assert sorted(os.listdir("/")) == root_before
    assert _tree(sweep_results) == res_before
    assert (tmp_path / ("a-file" + ("" if kind == "dir" else kind))).read_text() == "somebody's file\n"


def test_plot_overwrites_its_file_only_when_told(sweep_results, tmp_path, capsys):
    argv, _ = commands(sweep_results)["plot"]
    fig = tmp_path / "fig.png"
    assert main([*argv, "--out", str(fig)]) == 0
    assert fig.read_bytes()[:4] == b"\x89PNG"
    fig.write_bytes(b"mine")
    assert main([*argv, "--out", str(fig)]) == 2 and "--overwrite" in capsys.readouterr().err
    assert fig.read_bytes() == b"mine"
    assert main([*argv, "--out", str(fig), "--overwrite"]) == 0
    assert fig.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("argv", [
    ["simulate"], ["simulate", "paper-cycle"], ["swim", "swim", "--cycles", "x", "--out", "o"],
    ["nosuch"], ["compare", "--out", "o"], ["plot", "r.nc", "--out", "f.png"], ["simulate", "a", "b", "--out", "o"],
    [],
])
def test_command_line_mistakes_are_one_line(argv, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    p = subprocess.run([sys.executable, "-m", "frogsim", *argv], capture_output=True, text=True)
    assert p.returncode == 2, p
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("frogsim: error: ") and "Traceback" not in p.stderr, p.stderr
    assert list(tmp_path.iterdir()) == []


def test_scenarios_lists_every_shipped_scenario(capsys):
    import tomllib
    assert main(["scenarios"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    files = sorted(SCENARIOS_DIR.glob("*.toml"), key=lambda p: p.stem)      # listed by name
    assert len(lines) == len(files)
    for line, f in zip(lines, files):
        raw = tomllib.loads(f.read_text())
        name, command, about = line.split(None, 2)[0], line.split()[2], line.split(None, 3)[3]
        assert name == f.stem
        assert command == ("swim" if "gait" in raw else "simulate")
        assert about == raw["description"]          # every shipped scenario says what it is


@pytest.mark.parametrize("argv", [["simulate", "nosuch"], ["swim", "nosuch"], ["optimize-gait", "nosuch",
                                                                               "--trials", "1", "--objective",
                                                                               "speed"],
                                  ["compare", "nosuch", "--signal", "source pressure"]])
def test_an_unknown_scenario_name_lists_the_shipped_ones(argv, tmp_path, capsys):
    out = tmp_path / "o"
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "'nosuch'" in err
    for f in SCENARIOS_DIR.glob("*.toml"):
        assert f.stem in err, (f.stem, err)
    assert not out.exists()


def test_version():
    p = subprocess.run([sys.executable, "-m", "frogsim", "--version"], capture_output=True, text=True)
    assert p.returncode == 0 and p.stdout.strip() == f"frogsim {frogsim.__version__}"
    import tomllib
    assert tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"] == frogsim.__version__


@pytest.mark.parametrize("command, foreign", [("design", "fig13"), ("reproduce", "design-valve"),
                                              ("control", "aeration"), ("design", "control-pressure")])
def test_a_study_command_runs_only_its_own_studies(command, foreign, tmp_path, capsys):
    out = tmp_path / "o"
    assert main([command, foreign, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"'{foreign}'" in err and "it is a study of `frogsim" in err, err
    assert not out.exists()
