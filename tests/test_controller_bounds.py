"""Controllers within what the model and the board can mean, each bound refused in one line naming
the setting and the allowed range: a PWM period within the run and above the valves' switching
time, a controller rate the board can sample at and, on the robot, a whole number of MuJoCo steps
per period, joint-angle gains that do not make a PID a relay."""
from __future__ import annotations

import math
import tomllib

import pytest

import frogsim
from frogsim.cli import main
from frogsim.errors import ScenarioError
from frogsim.scenario.load import SCENARIOS_DIR
from tests.test_control import closed_loop

BAR = 1e5
# fan2017 (paper Sec. 4 and its parameter file): 2 ms valve dead time, the MHJ9's switching time;
# 6 bar gauge in the source; the hip's range 41 deg
DEAD = 2e-3
SOURCE = 6 * BAR
HIP_RANGE = math.radians(41.0)
# ATmega2560 datasheet, Table 26-1: 13 ADC clocks a conversion; 1 MHz the fastest recommended
# ADC clock (16 MHz / 16): 13 us a sample at least
BOARD_RATE = 1.0 / (13 / 1e6)


def _one_line(exc) -> str:
    msg = str(exc.value)
    assert "\n" not in msg, msg
    return msg


# --- PWM period ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("freq", ["1e-9 Hz", "0.5 Hz", "0.99 Hz"])
def test_a_pwm_period_longer_than_the_run_is_refused(freq):
    with pytest.raises(ScenarioError) as exc:
        frogsim.load_scenario(closed_loop({"kind": "pwm", "duty": 0.3, "frequency": freq}, 1.0))
    msg = _one_line(exc)
    # allowed: a period within the 1 s run (1 Hz) up to twice the 2 ms dead time (250 Hz; the
    # controller's two samples at 1 kHz would allow 500 Hz)
    top = 1.0 / (2 * DEAD)
    assert msg.startswith("controllers.loop.frequency = ") and "Hz" in msg.split(":")[0], msg
    assert "within the run" in msg and f"allowed 1 Hz to {top:g} Hz" in msg, msg


def test_a_pwm_period_of_the_whole_run_runs():
    frogsim.load_scenario(closed_loop({"kind": "pwm", "duty": 0.3, "frequency": "1 Hz"}, 1.0))


def test_a_pwm_period_below_twice_the_valve_switching_time_is_refused():
    top = 1.0 / (2 * DEAD)        # 250 Hz
    frogsim.load_scenario(closed_loop({"kind": "pwm", "duty": 0.3, "frequency": f"{top:g} Hz"}))
    with pytest.raises(ScenarioError, match=r"controllers\.loop\.frequency.*dead time.*at most 250 Hz"):
        frogsim.load_scenario(closed_loop({"kind": "pwm", "duty": 0.3, "frequency": "260 Hz"}))


def test_a_pwm_period_refused_on_the_command_line(tmp_path, capsys):
    lines = ['name = "pwm"', 'duration = "1 s"', 'output_interval = "1 ms"',
             '[muscles.hip]', 'type = "hip"', 'motion = { kind = "constant" }',
             '[controllers.loop]', 'kind = "pwm"', 'muscle = "hip"', 'duty = 0.3', 'frequency = "1e-9 Hz"']
    path = tmp_path / "pwm.toml"
    path.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    assert main(["simulate", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("frogsim: error: controllers.loop.frequency = 1e-09 Hz") and "\n" not in err, err
    assert not out.exists()


# --- controller rate ----------------------------------------------------------------------------------
def _paper(rate: str) -> dict:
    d = tomllib.loads((SCENARIOS_DIR / "paper-cycle.toml").read_text())
    d["controller"] = {"rate": rate}
    return d


@pytest.mark.parametrize("rate", ["1 MHz", "100 kHz", f"{BOARD_RATE * 1.001:.6g} Hz"])
def test_a_controller_rate_faster_than_the_board_samples_is_refused(rate):
    with pytest.raises(ScenarioError) as exc:
        frogsim.load_scenario(_paper(rate))
    msg = _one_line(exc)
    assert msg.startswith(f"controller.rate = {rate!r}: must be <= {BOARD_RATE:g} Hz"), msg
    assert f"allowed: above 0 Hz, up to {BOARD_RATE:g} Hz" in msg and "ADC" in msg, msg


def test_a_controller_rate_the_board_can_sample_at_loads():
    assert frogsim.load_scenario(_paper(f"{BOARD_RATE * 0.999:.6g} Hz")).controller.rate < BOARD_RATE
    with pytest.raises(ScenarioError, match="controller.rate"):
        frogsim.load_scenario("paper-cycle").replace({"controller.rate": 1e6})


def _robot(**changes) -> dict:
    d = tomllib.loads((SCENARIOS_DIR / "hip-angle-in-air.toml").read_text())
    for path, value in changes.items():
        node = d
        keys = path.split(".")
        for k in keys[:-1]:
            node = node.setdefault(k, {})
        node[keys[-1]] = value
    return d


@pytest.mark.parametrize("rate, period_ms", [("300 Hz", 10 / 3), ("3 kHz", 1 / 3), ("1500 Hz", 2 / 3),
                                             ("400 Hz", 2.5)])
def test_a_robot_controller_period_must_be_whole_mujoco_steps(rate, period_ms):
    # robot.timestep 1 ms in the shipped scenario: allowed 1000 Hz / n
    with pytest.raises(ScenarioError) as exc:
        frogsim.load_robot_scenario(_robot(**{"controller.rate": rate}))
    msg = _one_line(exc)
    assert msg.startswith("controller.rate = ") and f"its period {period_ms:g} ms" in msg, msg
    assert "whole number of robot.timestep steps (1 ms)" in msg and "1000 Hz / n" in msg, msg


@pytest.mark.parametrize("rate, hz", [("1 kHz", 1000.0), ("500 Hz", 500.0), ("250 Hz", 250.0), ("100 Hz", 100.0)])
def test_a_robot_controller_of_whole_steps_loads(rate, hz):
    assert frogsim.load_robot_scenario(_robot(**{"controller.rate": rate})).pneumatic.controller.rate == hz


def test_a_robot_controller_rate_refused_on_the_command_line(tmp_path, capsys):
    text = (SCENARIOS_DIR / "hip-angle-in-air.toml").read_text()
    assert 'rate = "1 kHz"' in text
    path = tmp_path / "robot.toml"
    path.write_text(text.replace('rate = "1 kHz"', 'rate = "300 Hz"'))
    out = tmp_path / "out"
    assert main(["swim", str(path), "--out", str(out), "--quiet", "--no-animation"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("frogsim: error: controller.rate = '300 Hz'") and "\n" not in err, err
    assert not out.exists()


# --- joint-angle gains --------------------------------------------------------------------------------
# the targets p0 +- dp/2 stay within [atmosphere, source] only while |dp| <= 6 bar; a term may reach
# that no sooner than at 0.1 % of the hip's range e* (the angle, its change over one 1 ms sample
# read as a rate, its integral over one sample)
E_STAR = 1e-3 * HIP_RANGE
DT = 1e-3
LIMITS = {"proportional_gain": (SOURCE / E_STAR / BAR, "bar/rad"),
          "derivative_gain": (SOURCE * DT / E_STAR / BAR, "bar*s/rad"),
          "integral_gain": (SOURCE / (E_STAR * DT) / BAR, "bar/(rad*s)")}


@pytest.mark.parametrize("key", sorted(LIMITS))
def test_each_joint_gain_of_1e9_is_refused_with_its_allowed_range(key):
    top, unit = LIMITS[key]
    with pytest.raises(ScenarioError) as exc:
        frogsim.load_robot_scenario(_robot(**{f"controllers.hip.{key}": f"1e9 {unit}"}))
    msg = _one_line(exc)
    assert msg.startswith(f"controllers.hip.{key} = 1e+09 {unit}: allowed: 0 to "), msg
    shown = float(msg.split("allowed: 0 to ", 1)[1].split(" ", 1)[0])
    assert shown == pytest.approx(top, rel=1e-5), msg
    assert "[atmosphere, source] (6 bar)" in msg and "41 deg" in msg, msg


@pytest.mark.parametrize("key", sorted(LIMITS))
def test_a_joint_gain_just_below_its_bound_loads_and_just_above_is_refused(key):
    top, unit = LIMITS[key]
    rs = frogsim.load_robot_scenario(_robot(**{f"controllers.hip.{key}": f"{top * 0.999:.8g} {unit}"}))
    assert getattr(rs.pneumatic.controllers["hip"], key) == pytest.approx(top * 0.999 * BAR, rel=1e-6)
    with pytest.raises(ScenarioError, match=rf"^controllers\.hip\.{key} = "):
        frogsim.load_robot_scenario(_robot(**{f"controllers.hip.{key}": f"{top * 1.001:.8g} {unit}"}))


def test_all_three_gains_of_1e9_are_refused_and_the_shipped_gains_load():
    with pytest.raises(ScenarioError, match=r"^controllers\.hip\.\w+_gain = 1e\+09"):
        frogsim.load_robot_scenario(_robot(**{"controllers.hip.proportional_gain": "1e9 bar/rad",
                                              "controllers.hip.derivative_gain": "1e9 bar*s/rad",
                                              "controllers.hip.integral_gain": "1e9 bar/(rad*s)"}))
    for name in ("hip-angle-in-air", "swim-board"):
        assert frogsim.load_robot_scenario(name).pneumatic.controllers


def test_a_joint_gain_bound_follows_the_controller_period():
    # at 500 Hz the sample is 2 ms: Kd may be twice as large, Ki half
    top_d = SOURCE * 2e-3 / E_STAR / BAR
    frogsim.load_robot_scenario(_robot(**{"controller.rate": "500 Hz",
                                          "controllers.hip.derivative_gain": f"{top_d * 0.999:.8g} bar*s/rad"}))
    top_i = SOURCE / (E_STAR * 2e-3) / BAR
    with pytest.raises(ScenarioError, match=r"controllers\.hip\.integral_gain"):
        frogsim.load_robot_scenario(_robot(**{"controller.rate": "500 Hz",
                                              "controllers.hip.integral_gain": f"{top_i * 1.001:.8g} bar/(rad*s)"}))


def test_a_joint_gain_refused_on_the_command_line(tmp_path, capsys):
    text = (SCENARIOS_DIR / "hip-angle-in-air.toml").read_text()
    assert 'proportional_gain = "30 bar/rad"' in text
    path = tmp_path / "robot.toml"
    path.write_text(text.replace('proportional_gain = "30 bar/rad"', 'proportional_gain = "1e9 bar/rad"'))
    out = tmp_path / "out"
    assert main(["swim", str(path), "--out", str(out), "--quiet", "--no-animation"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("frogsim: error: controllers.hip.proportional_gain = 1e+09 bar/rad: allowed: 0 to"), err
    assert "\n" not in err and not out.exists()
