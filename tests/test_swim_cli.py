"""`frogsim swim`: its files, summary.json's contract, bad input (exit 2, nothing written), and the
offscreen animation (skipped where this machine has no OpenGL backend)."""
import json
import math
import subprocess
import sys

import pytest

from conftest import assert_unit_headers
from frogsim.cli import main

# a small robot scenario (the leg in air for half a second), as TOML tables of literal values
BASE = {
    "": {"name": '"cli-swim"', "parameters": '"fan2017"', "output_interval": '"10 ms"'},
    "robot": {"environment": '"air"', "base": '"fixed"', "recovery": '"spring"'},
    "gait": {"period": '"1 s"', "cycles": "1",
             "drive": '[ { at = "0 s", state = "charge" }, { at = "0.5 s", state = "vent" } ]',
             "palms": '[ { at = "0 s", state = "open" } ]'},
}

# (table, key, literal) laid over BASE, and the field the one-line error must name
BAD = {
    "unknown robot key": (("robot", "wings", "true"), "robot.wings"),
    "wrong unit": (("palms", "open_area", '"0.0335 m"'), "palms.open_area"),
    "bad environment": (("robot", "environment", '"lava"'), "robot.environment"),
    "gait step past the period": (("gait", "drive", '[ { at = "2 s", state = "charge" } ]'), "gait.drive[0].at"),
    "unknown valve state": (("gait", "drive", '[ { at = "0 s", state = "blow" } ]'), "gait.drive[0].state"),
    "bare number": (("legs", "thigh_length", "0.28"), "legs.thigh_length"),
    "muscles in a robot scenario": (("muscles.hip", "type", '"hip"'), "muscles"),
}


def _scenario(tmp_path, override=None):
    tables = {k: dict(v) for k, v in BASE.items()}
    if override:
        table, key, literal = override
        tables.setdefault(table, {})[key] = literal
    lines = []
    for table, entries in tables.items():
        if table:
            lines.append(f"[{table}]")
        lines += [f"{k} = {v}" for k, v in entries.items()]
    path = tmp_path / "s.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_robot_scenario_exit_2_one_line_nothing_written(tmp_path, capsys, case):
    override, field = BAD[case]
    out = tmp_path / "out"
    code = main(["swim", str(_scenario(tmp_path, override)), "--out", str(out), "--no-animation"])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1, err
    assert field in err and "Traceback" not in err
    assert not out.exists()


def test_bad_cycles_through_real_process(tmp_path):
    p = subprocess.run([sys.executable, "-m", "frogsim", "swim", "swim", "--cycles", "0", "--out",
                        str(tmp_path / "o")], capture_output=True, text=True)
    assert p.returncode == 2
    assert p.stderr.strip().splitlines() == ["frogsim: error: cycles = 0: must be a whole number from 1 to 100000"]
    assert not (tmp_path / "o").exists()


def test_swim_writes_files_and_summary(tmp_path):
    out = tmp_path / "o"
    assert main(["swim", str(_scenario(tmp_path)), "--out", str(out), "--no-animation"]) == 0
    for name in ("timeseries.csv", "swim.png", "summary.json", "frog.xml"):
        assert (out / name).stat().st_size > 0, name
    assert not (out / "animation.gif").exists()
    header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
    for col in ("time [s]", "x [m]", "forward velocity [m/s]", "thrust [N]", "hip_left angle [deg]",
                "hip_left pressure [bar gauge]", "source pressure [bar gauge]", "palm_left opening [%]"):
        assert col in header, col
    assert_unit_headers(out / "timeseries.csv")         # every column: name [unit], a known unit
    rows = (out / "timeseries.csv").read_text().splitlines()
    assert len(rows) == 1 + 101                         # 0..1 s every 10 ms, plus the header
    s = json.loads((out / "summary.json").read_text())
    for key in ("mean_speed_m_per_s", "mean_speed_body_lengths_per_s", "distance_per_cycle_m",
                "thrust_peak_N", "thrust_mean_N", "air_used_per_cycle_L_std",
                "source_pressure_after_cycles_bar_gauge", "cost_of_transport", "joint_delay_s"):
        assert key in s, key
    # fixed in air: it goes nowhere, so its cost of transport is undefined (null), not a number
    assert s["distance_m"] == 0.0 and s["cost_of_transport"] is None
    assert all(0.03 <= d <= 0.3 for d in s["joint_delay_s"].values())
    assert (out / "swim.png").read_bytes()[:4] == b"\x89PNG"
    assert (out / "frog.xml").read_text().startswith("<mujoco")


def test_animation_renders_offscreen(tmp_path):
    import frogsim
    from frogsim.robot.render import RenderUnavailable, render_animation
    r = frogsim.swim(str(_scenario(tmp_path)))
    try:
        path = render_animation(r, tmp_path / "a.gif", fps=8, width=160, height=120)
    except RenderUnavailable as exc:
        import os
        if os.environ.get("CI"):              # CI has what the README's install gives: a failure there
            pytest.fail(f"no offscreen OpenGL: {exc}")
        pytest.skip(f"no offscreen OpenGL here: {exc}")
    from PIL import Image
    with Image.open(path) as im:
        assert im.format == "GIF" and im.size == (160, 120)
        assert im.n_frames == 9                          # 1 s at 8 frames per second, both ends
        frames = []
        for k in (0, im.n_frames - 1):
            im.seek(k)
            frames.append(im.convert("RGB").tobytes())
    assert frames[0] != frames[1]                        # the leg moved
