"""Bad input is refused in one line (exit 2, nothing written); impossible states and endless runs
stop with the quantity, the value and the time."""
from __future__ import annotations

import math
import os
import time

import numpy as np
import pytest

import frogsim
from frogsim.circuit import layout as L
from frogsim.cli import main
from frogsim.engine import pneumatic
from frogsim.io.results import run_summary
from conftest import P_ATM, one_muscle_scenario, paper_cycle_dict, steps

GOOD = """
name = "cli-refusal"
duration = "20 ms"
[programs.stroke]
pressurise = "10 ms"
release = "10 ms"
[muscles.hip]
type = "hip"
program = "stroke"
"""


def _cli(tmp_path, capsys, scenario_path):
    out = tmp_path / "out"
    code = main(["simulate", str(scenario_path), "--out", str(out)])
    err = capsys.readouterr().err.strip()
    return code, err, out


def _refused(code, err, out, *needles):
    assert code == 2, err
    assert len(err.splitlines()) == 1, err
    assert err.startswith("frogsim: error: ") and "Traceback" not in err
    assert not out.exists()
    for n in needles:
        assert n in err, err


def _joint(tmp_path, csv_name="angles.csv"):
    return GOOD + f'motion = {{ kind = "joint_angles", file = "{csv_name}", column = "hip" }}\n'


MALFORMED = {
    # name: (writes the case into tmp_path, returns the scenario path; text expected in the message)
    "directory": (lambda p: p, "is a directory"),
    "fifo": (lambda p: (os.mkfifo(p / "s.toml"), p / "s.toml")[1], "FIFO"),
    "device": (lambda p: "/dev/zero", "device"),
    "binary": (lambda p: (p / "s.toml").write_bytes(b"\x00\x01\x02name") and p / "s.toml", "binary"),
    "invalid utf-8": (lambda p: (p / "s.toml").write_bytes(b'name = "\xff\xfe"\n') and p / "s.toml", "UTF-8"),
    "deeply nested": (lambda p: (p / "s.toml").write_text("x = " + "[" * 10000 + "]" * 10000) and p / "s.toml",
                      "nested"),
    "nested 40 levels": (lambda p: (p / "s.toml").write_text(GOOD + "x = " + "[" * 40 + "]" * 40) and p / "s.toml",
                         "nested more than 32"),
    "unknown key": (lambda p: (p / "s.toml").write_text(GOOD + "[source]\nvolum = \"4 L\"\n") and p / "s.toml",
                    "source.volum"),
    "nan": (lambda p: (p / "s.toml").write_text(GOOD.replace('"20 ms"', "nan")) and p / "s.toml", "duration"),
    "nan in a table motion": (lambda p: (p / "s.toml").write_text(
        GOOD + 'motion = { kind = "table", time_s = [0, nan], contraction_percent = [0, 5] }\n') and p / "s.toml",
        "muscles.hip.motion.time_s"),
    "inf in a table motion": (lambda p: (p / "s.toml").write_text(
        GOOD + 'motion = { kind = "table", time_s = [0, 1], contraction_percent = [0, inf] }\n') and p / "s.toml",
        "muscles.hip.motion.contraction_percent"),
    "parameters is a directory": (lambda p: (p / "s.toml").write_text(f'parameters = "{p}"\n' + GOOD)
                                  and p / "s.toml", "parameters"),
    "parameters is /dev/zero": (lambda p: (p / "s.toml").write_text('parameters = "/dev/zero"\n' + GOOD)
                                and p / "s.toml", "device"),
    "joint-angle file is a directory": (lambda p: ((p / "sub").mkdir(), (p / "s.toml").write_text(_joint(p, "sub")))
                                        and p / "s.toml", "muscles.hip.motion.file"),
    "joint-angle file is a FIFO": (lambda p: (os.mkfifo(p / "a.csv"), (p / "s.toml").write_text(_joint(p, "a.csv")))
                                   and p / "s.toml", "FIFO"),
    "joint-angle file is binary": (lambda p: ((p / "a.csv").write_bytes(b"\x89PNG\x00\x00"),
                                              (p / "s.toml").write_text(_joint(p, "a.csv"))) and p / "s.toml",
                                   "binary"),
    "joint-angle file has NaN": (lambda p: ((p / "a.csv").write_text("time_s,hip\n0,0\n0.01,nan\n"),
                                            (p / "s.toml").write_text(_joint(p, "a.csv"))) and p / "s.toml",
                                 "finite"),
    "joint-angle file has text": (lambda p: ((p / "a.csv").write_text("time_s,hip\n0,0\n0.01,ten\n"),
                                             (p / "s.toml").write_text(_joint(p, "a.csv"))) and p / "s.toml",
                                  "numbers"),
    "missing setting in a table": (lambda p: (p / "s.toml").write_text(GOOD.replace('release = "10 ms"\n', ""))
                                   and p / "s.toml", "programs.stroke.release"),
    "percent twice": (lambda p: (p / "s.toml").write_text(
        GOOD + 'motion = { kind = "constant", contraction = "38 %%" }\n') and p / "s.toml", "once"),
    "power tower": (lambda p: (p / "s.toml").write_text(GOOD + '[source]\nvolume = "10**10**10 L"\n')
                    and p / "s.toml", "source.volume"),
    "huge integer": (lambda p: (p / "s.toml").write_text(GOOD + "[supply]\nbranch_count = " + "9" * 5000 + "\n")
                     and p / "s.toml", "not valid TOML"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_input_exit_2_one_line_nothing_written(tmp_path, capsys, case):
    make, needle = MALFORMED[case]
    path = make(tmp_path)
    t0 = time.perf_counter()
    code, err, out = _cli(tmp_path, capsys, path)
    assert time.perf_counter() - t0 < 20
    _refused(code, err, out, needle)


def test_long_values_are_shown_clipped(tmp_path, capsys):
    (tmp_path / "s.toml").write_text(GOOD + f'[source]\nvolume = "{"9" * 25000} L"\n')
    code, err, out = _cli(tmp_path, capsys, tmp_path / "s.toml")
    _refused(code, err, out, "source.volume")
    shown = err.split(" = ", 1)[1].split(": ", 1)[0]
    assert len(shown) <= 80 and shown.endswith("…"), shown
    assert len(err) < 400


def test_abs_twin_of_a_gauge_setting_is_converted_with_the_atmosphere():
    d = paper_cycle_dict()
    d["source"] = {"initial_pressure_abs": "7 bar"}
    sc = frogsim.load_scenario(d)
    # gauge = absolute - atmosphere; the fan2017 atmosphere is the standard one, 101325 Pa
    assert sc.source.initial_pressure_gauge == pytest.approx(7e5 - P_ATM, abs=1e-6)
    d["muscles"]["hip_left"]["initial_pressure_abs"] = "101.325 kPa"
    d["pump"] = {"on_below_abs": "5 bar", "off_above_abs": "6 bar"}
    sc = frogsim.load_scenario(d)
    assert sc.muscles["hip_left"].initial_pressure_gauge == pytest.approx(0.0, abs=1e-6)
    assert sc.pump.on_below_gauge == pytest.approx(5e5 - P_ATM, abs=1e-6)
    d["air"] = {"atmospheric_pressure_abs": "90 kPa"}
    assert frogsim.load_scenario(d).source.initial_pressure_gauge == pytest.approx(7e5 - 9e4, abs=1e-6)


def test_abs_and_gauge_together_or_out_of_range_are_refused():
    d = paper_cycle_dict()
    d["source"] = {"initial_pressure_abs": "7 bar", "initial_pressure_gauge": "6 bar"}
    with pytest.raises(frogsim.ScenarioError, match="source.initial_pressure_abs.*either"):
        frogsim.load_scenario(d)
    d["source"] = {"initial_pressure_abs": "20 bar"}      # 18.99 bar gauge > 16 bar
    with pytest.raises(frogsim.ScenarioError, match="source.initial_pressure_abs"):
        frogsim.load_scenario(d)
    d["source"] = {"initial_pressure_abs": "-1 bar"}
    with pytest.raises(frogsim.ScenarioError, match="source.initial_pressure_abs"):
        frogsim.load_scenario(d)


def test_initial_pressure_below_absolute_zero_is_refused():
    d = paper_cycle_dict()
    d["air"] = {"atmospheric_pressure_abs": "50 kPa"}
    d["exhaust"] = {"initial_pressure_gauge": "-0.8 bar"}     # 50 kPa - 80 kPa < 0
    with pytest.raises(frogsim.ScenarioError, match="exhaust.initial_pressure_gauge"):
        frogsim.load_scenario(d)


@pytest.mark.parametrize("angle", ["1e-8 deg", "0.001 deg"])
def test_braid_too_thin_for_eq5_is_refused(angle):
    d = paper_cycle_dict()
    d["muscle_types"] = {"hip": {"braid_angle": angle}}
    with pytest.raises(frogsim.ScenarioError, match="muscle_types.hip.braid_angle"):
        frogsim.load_scenario(d)


def test_thin_but_computable_braid_runs_with_the_cylinder_volume_at_rest():
    d = one_muscle_scenario(steps((0, "charge")), 0.02, muscle_type="hip", motion={"kind": "constant"},
                            muscle_types={"hip": {"braid_angle": "0.01 deg"}})
    r = frogsim.simulate(frogsim.load_scenario(d), progress=False)
    # at rest length the braid is a cylinder: V = pi D0^2 L0 / 4 (+ dead volume), D0 = 20 mm, L0 = 180 mm
    v_cyl = math.pi * 0.020 ** 2 * 0.180 / 4
    assert r.volumes[0, 0] == pytest.approx(v_cyl + 5e-6, rel=1e-6)
    assert np.all(r.temperature("m0") > 0)


def test_negative_state_stops_with_quantity_value_and_time():
    sc = frogsim.load_scenario(paper_cycle_dict())
    model = frogsim.build_model(sc)
    t = np.array([0.0, 0.1, 0.2])
    y = np.tile(model.y0, (3, 1))
    y[2, L.mass_index(1)] = -1e-6            # muscle 1 (hip_right): its air mass
    with pytest.raises(frogsim.SimulationError, match=r"t = 0\.2 s: hip_right mass = -1e-06 kg"):
        pneumatic.check_state(model, t, y)
    y[1, L.Y_PS] = float("nan")
    with pytest.raises(frogsim.SimulationError, match=r"t = 0\.1 s: source pressure = nan"):
        pneumatic.check_state(model, t, y)
    model.mp[0, L.M_DEAD] = -1.0                  # a volume that cannot be
    with pytest.raises(frogsim.SimulationError, match="hip_left volume = -"):
        pneumatic.check_volumes(model)


def test_run_ending_before_the_charge_valve_opens_has_nan_measures(tmp_path, capsys):
    d = paper_cycle_dict()
    d["duration"] = "50 ms"
    d["programs"]["stroke"]["start"] = "1 s"
    r = frogsim.simulate(frogsim.load_scenario(d), progress=False)
    s = run_summary(r)["muscles"]["hip_left"]
    assert s["rise_time_90_s"] is None and "no pressurise phase" in s["rise_time_90_reason"], s
    assert s["aeration_volume_L"] is None or math.isnan(s["aeration_volume_L"])
    assert math.isnan(r.pressure_at_close("hip_left"))


def test_a_very_stiff_circuit_runs_and_conserves_air():
    # a 1 mm^3 source behind six charge valves: tau = V / (k p_ref C) = 1e-9 / (1.4e5 * 2.4e-8) = 3e-7 s,
    # a million times shorter than the run; the explicit method alone would need ~1e7 steps, the
    # stiffness switch (Rosenbrock where the chamber rests) a few thousand at most
    d = paper_cycle_dict()
    d["source"] = {"volume": "1e-9 m^3"}
    r = frogsim.simulate(frogsim.load_scenario(d))
    assert r.stats["steps"] < 20_000, r.stats
    m = r.total_air_mass
    m = m() if callable(m) else m
    assert abs(m[-1] - m[0]) <= 1e-12 * m[0]


def test_slow_run_stops_at_the_wall_time_limit_with_a_hint(capsys):
    d = paper_cycle_dict()
    d["source"] = {"volume": "1e-9 m^3"}
    d["solver"] = {"max_wall_time": "1.5 s", "max_step": "0.2 us"}
    t0 = time.perf_counter()
    with pytest.raises(frogsim.SimulationError) as info:
        frogsim.simulate(frogsim.load_scenario(d))
    took = time.perf_counter() - t0
    assert took < 6, took
    msg = str(info.value)
    assert "solver.max_step = 2e-07 s" in msg and "max_wall_time" in msg and "\n" not in msg
    assert "simulated s" in capsys.readouterr().err       # the progress bar was shown
    # the stiffness hint itself: tau = V / (k p_ref C) with 6 charge valves of 0.4 L/(s bar):
    # 1e-9 / (1.4e5 * 2.4e-8) = 3e-7 s
    from frogsim.engine.pneumatic import stiffness_hint
    hint = stiffness_hint(frogsim.build_model(frogsim.load_scenario(d)))
    assert "source volume 1e-09 m^3" in hint and "3e-07 s" in hint


def test_simulate_equals_the_batched_engine_bit_for_bit():
    d = paper_cycle_dict()
    d["duration"] = "0.4 s"
    sc = frogsim.load_scenario(d)
    from frogsim.engine.batch import run_models
    ref = run_models([frogsim.build_model(sc)], threads=1)[0]
    whole = frogsim.simulate(sc)
    assert np.array_equal(whole.y, ref.y) and np.array_equal(whole.u, ref.u)   # bit for bit

def test_a_long_path_in_a_message_keeps_its_file_name():
    """A path longer than a message shows (SHOWN_MAX) is cut in its middle, not at its end: the
    file's name, what a reader needs to act, stays (a test folder under pytest-xdist is long)."""
    from frogsim.errors import SHOWN_MAX, ScenarioError, shown_value
    path = "/tmp/" + "/".join(["a-rather-long-folder-name"] * 6) + "/trace.csv"
    shown = shown_value(path)
    assert len(shown) <= SHOWN_MAX and shown.endswith("trace.csv'") and "…" in shown
    assert shown.startswith("'/tmp/")
    msg = str(ScenarioError("trace file", path, "file not found"))
    assert "trace.csv" in msg and "\n" not in msg
    assert shown_value("a/b.csv") == "'a/b.csv'"                  # a short path as it is
