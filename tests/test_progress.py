"""Signs of life: a command that may work for more than about 2 s says so on stderr (a first run's
Numba compilation included), and says nothing there under --quiet.

The slow paths are forced, so the test does not depend on this machine's speed or cache: the
compiled code is reported as not cached (frogsim._jit.cache_is_warm), the pneumatic engine's bar
appears from its first pause (PROGRESS_AFTER_S = 0, a pause every 20 steps) and the swim's
progress line at every report (PROGRESS_EVERY_S = 0)."""
from __future__ import annotations

import pytest

import frogsim._jit as jit
import frogsim.cli as cli
import frogsim.engine.pneumatic as pneumatic
from frogsim.cli import main

from sweep_helpers import source_pressure_sweep, write_case

SMALL = source_pressure_sweep(2)


@pytest.fixture
def slow(monkeypatch):
    monkeypatch.setattr(jit, "cache_is_warm", lambda dispatcher: False)
    monkeypatch.setattr(pneumatic, "PROGRESS_AFTER_S", 0.0)
    monkeypatch.setattr(pneumatic, "STEPS_PER_CALL", 20)
    monkeypatch.setattr(cli, "PROGRESS_EVERY_S", 0.0)


def _stderr(capsys, argv) -> str:
    capsys.readouterr()
    assert main(argv) == 0
    return capsys.readouterr().err


def _loud_then_quiet(capsys, argv, out, expected):
    err = _stderr(capsys, argv + ["--out", str(out / "loud")])
    for text in expected:
        assert text in err, (text, err[-2000:])
    assert _stderr(capsys, argv + ["--out", str(out / "quiet"), "--quiet"]) == ""


def test_simulate_says_it_compiles_and_shows_the_run_going(slow, capsys, tmp_path):
    _loud_then_quiet(capsys, ["simulate", "paper-cycle"], tmp_path,
                     ["compiling the pneumatic engine, once per machine", "(simulated s)"])


def test_compare_running_a_scenario_shows_the_same_signs(slow, capsys, tmp_path):
    _loud_then_quiet(capsys, ["compare", "paper-cycle", "--signal", "source pressure"], tmp_path,
                     ["compiling the pneumatic engine, once per machine", "simulating 'paper-cycle'",
                      "(simulated s)"])


def test_swim_says_it_compiles_and_how_far_it_has_got(slow, capsys, tmp_path):
    _loud_then_quiet(capsys, ["swim", "leg-in-air", "--cycles", "1", "--no-animation"], tmp_path,
                     ["compiling the swim engine, once per machine", "% (", "s simulated)"])


def test_sweep_says_it_compiles(slow, capsys, tmp_path):
    spec = write_case(tmp_path / "case", spec=SMALL)
    err = _stderr(capsys, ["sweep", str(spec), "--out", str(tmp_path / "loud.nc")])
    assert "compiling the batched pneumatic engine, once per machine" in err and "sweep small" in err
    assert _stderr(capsys, ["sweep", str(spec), "--out", str(tmp_path / "quiet.nc"), "--quiet"]) == ""


@pytest.mark.parametrize("quiet", [False, True])
def test_studies_still_running_are_named_while_they_run(tmp_path, capsys, monkeypatch, quiet):
    """reproduce: between one study's end and the next, a line every STUDY_HEARTBEAT_S names the
    studies still running (forced to 1 ms here: leg-in-air takes longer than that), none under
    --quiet."""
    monkeypatch.setattr(cli, "STUDY_HEARTBEAT_S", 0.001)
    args = ["reproduce", "leg-in-air", "fig13", "--out", str(tmp_path / "r"), *(["--quiet"] if quiet else [])]
    assert main(args) == 0
    err = capsys.readouterr().err
    if quiet:
        assert err == ""
    else:
        lines = [line for line in err.splitlines() if "still running:" in line]
        assert lines and all("of 2 done" in line for line in lines), err
        assert any("leg-in-air" in line for line in lines), err
