"""Gains tuned on the board's integer laws, confirmed on the board: `frogsim tune` on three gait
cycles of `swim-board`, its best.toml laid over the scenario by `frogsim firmware --patch` and
`frogsim sil --patch`, the firmware's machine code run on the emulated ATmega2560 against the
robot. What the search scored is what the board runs: the SIL run's compiled integer twin (on
time) reproduces the best trial's metrics and every decision of the firmware is the twin's; and
each joint's tracking RMS in SIL is within 10 % of the float law's for the same gains (issue 28's
target; benchmarks/bench_tune_board.py checks it on the full 10 s). The search keeps the two
bounds the board sets (docs/control.md, "The tuned firmware in SIL"): bands of one ADC count or
more, Kd up to 1 bar s/rad. Without them the check fails (the benchmark's --free band --free
derivative_gain), and on one gait cycle (a metric over 1 s) it fails even for the scenario's own
gains: one run's RMS over a second is not a 10 % measure."""
from __future__ import annotations

import json

import pytest

from avr_tools import need_avr_tools
from frogsim.cli import main
from frogsim.scenario.load import scenario_path

TUNE = """
[tune]
tie = [["hip_left", "hip_right"], ["knee_left", "knee_right"], ["ankle_left", "ankle_right"]]
[tune.weights]
tracking = 1.0
[tune.at_most]
air = 1.0
""" + "".join(f'[tune.gains.{j}_left]\nintegral_gain = "0 bar/(rad*s)"\nband = ["0.05 bar", "1 bar"]\n'
              'derivative_gain = ["0 bar*s/rad", "1 bar*s/rad"]\n'
              for j in ("hip", "knee", "ankle"))
TOLERANCE = 0.10
CYCLES = 3             # gait cycles of 2 s: the tracking metric from 1 s, over 5 s


@pytest.fixture(scope="module")
def on_board(tmp_path_factory):
    """CYCLES gait cycles of swim-board: tuned (6 trials), exported with the best gains, built,
    run in SIL; (the tune's summary, the SIL run's "sil" section, the folder)."""
    need_avr_tools()
    tmp = tmp_path_factory.mktemp("tune-board")
    text = scenario_path("swim-board").read_text()
    assert text.count("cycles = 5") == 1
    sc = tmp / "board.toml"
    sc.write_text(text.replace("cycles = 5", f"cycles = {CYCLES}") + TUNE)
    patch = tmp / "t" / "best.toml"
    assert main(["tune", str(sc), "--trials", "6", "--workers", "2", "--out", str(tmp / "t"), "--quiet"]) == 0
    assert main(["firmware", str(sc), "--patch", str(patch), "--out", str(tmp / "fw"), "--build", "--quiet"]) == 0
    assert main(["sil", str(sc), "--patch", str(patch), "--firmware", str(tmp / "fw"), "--out", str(tmp / "sil"),
                 "--no-animation", "--quiet"]) == 0
    tune = json.loads((tmp / "t" / "summary.json").read_text())
    sil = json.loads((tmp / "sil" / "summary.json").read_text())["sil"]
    return tune, sil, tmp


def test_the_board_runs_what_the_search_scored(on_board):
    tune, sil, _ = on_board
    assert tune["best"] is not None
    best = tune["best"]["controllers"]
    compiled = sil["compiled"]["controllers"]
    assert set(best) == set(compiled)
    for c, m in best.items():
        assert compiled[c]["tracking_error_rms_deg"]["compiled"] == m["tracking_rms"], c
        assert compiled[c]["air_used_L_std"]["compiled"] == m["air_used_L_std"], c
    assert sil["mismatched_samples"] == 0 and sil["overruns"] == 0


def test_the_tuned_firmware_tracks_within_10_percent_of_the_float_law(on_board):
    _, sil, _ = on_board
    for c, cell in sil["compiled"]["controllers"].items():
        rms = cell["tracking_error_rms_deg"]
        assert abs(rms["sil"] / rms["compiled_float"] - 1.0) <= TOLERANCE, (c, rms)


def test_sil_without_the_patch_the_firmware_was_exported_with_is_refused(on_board, capsys):
    _, _, tmp = on_board
    out = tmp / "unpatched"
    capsys.readouterr()
    assert main(["sil", str(tmp / "board.toml"), "--firmware", str(tmp / "fw"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("frogsim: error: --firmware") and "patch file" in err, err
    assert not out.exists()
