"""One result shape: a pneumatic run (frogsim.Result) and a robot run (frogsim.engine.swim.SwimResult)
report their controllers' metrics through one function, with one set of keys (docs/metrics.md,
"Controller metrics"), and each metric means what its name says.

Expected values are closed forms on the output grid, not the code's output: a square-wave error
of known levels and duty gives RMS sqrt((n_hi a^2 + n_lo b^2) / (n_hi + n_lo)) and max max(a, b),
the sample counts n_hi, n_lo counted by hand on the grid; a hand-built valve sequence has its
switchings counted by hand (a repeated command changes nothing; a command whose dead time ends
after the run was never applied); the reference density is ISO 8778's state through the ideal gas.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import frogsim
from tests.conftest import P_ATM, RHO_REF
from tests.test_control import closed_loop

BAR = 1e5
DT = 1e-3          # controller period and output interval of every run here [s]
BANG_BANG = {"kind": "bang-bang", "band": "0.1 bar", "settle": "0.25 s",
             "setpoint": {"kind": "sine", "mean": "3 bar", "amplitude": "1 bar", "frequency": "2 Hz"}}


def robot_raw(controllers: dict, period: str = "1 s", drive=None) -> dict:
    """hip-angle-in-air (the body fixed in air, every muscle's valves shut by the gait) with its
    controllers replaced, 1 ms output rows."""
    from frogsim.scenario.load import merged_raw
    raw, base = merged_raw("hip-angle-in-air")
    gait = {**raw["gait"], "period": period}
    if drive is not None:
        gait["drive"] = drive
    return {**raw, "base_dir": base, "gait": gait, "output_interval": "1 ms", "controllers": controllers}


def _shape(x):
    """The shape of a metrics value: dicts by their keys, lists by length, leaves by type."""
    if isinstance(x, dict):
        return {k: _shape(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_shape(v) for v in x]
    return type(x).__name__


# --- one shape ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def same_controller_runs():
    """The same bang-bang controller on one muscle, alone and on the robot (named "robot" there: a
    controller may have that name, and nothing else may sit beside it in the metrics)."""
    pneumatic = frogsim.simulate(frogsim.load_scenario(closed_loop(BANG_BANG, 1.0)))
    robot = frogsim.swim(robot_raw({"robot": {**BANG_BANG, "muscle": "hip_left"}}))
    return pneumatic, robot


def test_a_pneumatic_and_a_robot_run_give_one_key_set_and_shape(same_controller_runs):
    pneumatic, robot = same_controller_runs
    a, b = pneumatic.control_metrics(), robot.control_metrics()
    assert list(a) == ["loop"] and list(b) == ["robot"]          # the controllers, and nothing else
    ea, eb = a["loop"], b["robot"]
    assert _shape(ea) == {
        "kind": "str", "muscles": ["str"], "settle_s": "float",
        "tracking_error_rms_bar": "float", "tracking_error_max_bar": "float",
        "switchings": {"hip": {"charge": "int", "discharge": "int"}},
        "switchings_per_s": "float", "air_used_L_std": "float"}
    shape_b = _shape(eb)
    shape_b["switchings"] = {"hip": shape_b["switchings"].pop("hip_left")}     # the muscle's own name
    assert shape_b == _shape(ea)
    assert ea["muscles"] == ["hip"] and eb["muscles"] == ["hip_left"]
    assert ea["kind"] == eb["kind"] == "bang-bang" and ea["settle_s"] == eb["settle_s"] == 0.25
    # both track and switch (not vacuous), and both summaries carry the same dict
    for r, e in ((pneumatic, ea), (robot, eb)):
        sw = next(iter(e["switchings"].values()))
        assert sw["charge"] > 10 and sw["discharge"] > 10 and 0 < e["tracking_error_rms_bar"] < 0.5
    from frogsim.io.results import run_summary
    assert run_summary(pneumatic, notes=False)["control"] == a
    assert robot.summary()["control"] == b


def test_the_shared_methods_mean_the_same_on_both(same_controller_runs):
    """setpoint [Pa abs], switchings {muscle: (charge, discharge)}, the circuit's constants: one
    meaning whatever the run."""
    pneumatic, robot = same_controller_runs
    t = pneumatic.t
    sp = P_ATM + 3 * BAR + BAR * np.sin(2 * math.pi * 2.0 * t)
    np.testing.assert_allclose(pneumatic.setpoint("loop"), sp, rtol=0, atol=1e-6)
    np.testing.assert_allclose(robot.setpoint("robot"), sp, rtol=0, atol=1e-6)
    assert set(pneumatic.switchings) == {"hip"} and set(robot.switchings) == {"hip_left"}
    m = robot.control_metrics()["robot"]["switchings"]["hip_left"]
    assert robot.switchings["hip_left"] == (m["charge"], m["discharge"])
    for r in (pneumatic, robot):
        assert r.atmospheric_pressure == P_ATM
        assert r.reference_density == pytest.approx(RHO_REF, rel=1e-12)
    with pytest.raises(KeyError, match="no muscle 'elbow'"):
        robot.index("elbow")
    with pytest.raises(KeyError, match="no closed-loop controller 'x'"):
        robot.setpoint("x")


# --- each metric means what its name says ------------------------------------------------------------
def _square(k: np.ndarray, period: int, high: int) -> np.ndarray:
    """1 where sample k is in the first ``high`` samples of its ``period``, else 0."""
    return (np.asarray(k) % period < high).astype(float)


def test_a_square_wave_pressure_error_gives_its_closed_form_rms_and_max():
    """The muscle held shut at its start pressure p0 (constant volume, valves closed: dp/dt = 0),
    measured against a Python law's setpoint p0 + a on the first 25 samples of every 100 and
    p0 - b on the rest. Over t >= 0.2 s of a 1 s run (samples 200..1000) the wave is high on 8
    periods x 25 samples plus sample 1000 (1000 mod 100 = 0): 201 high, 600 low."""
    a, b = 0.3 * BAR, 0.1 * BAR
    sc = frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": "3 bar", "settle": "0.2 s"}, 1.0,
                                           muscles={"hip": {"type": "hip", "motion": {"kind": "constant"},
                                                            "initial_pressure_gauge": "2 bar"}}))
    p0 = P_ATM + 2 * BAR

    def hold(t, obs):
        return {"hip": "hold"}
    hold.setpoint = lambda t: p0 + (a if round(t / DT) % 100 < 25 else -b)
    r = frogsim.simulate(sc, controller=hold)
    np.testing.assert_allclose(r.muscle_pressure("hip"), p0, rtol=1e-12)
    m = r.control_metrics()["loop"]
    n_hi, n_lo = 201, 600
    assert m["tracking_error_rms_bar"] == pytest.approx(math.sqrt((n_hi * a ** 2 + n_lo * b ** 2) / (n_hi + n_lo))
                                                        / BAR, rel=1e-9)
    assert m["tracking_error_max_bar"] == pytest.approx(a / BAR, rel=1e-9)
    assert m["settle_s"] == 0.2 and m["kind"] == "python:hold"
    # before the settle time the wave does not count: a setpoint far off there changes nothing
    hold.setpoint = lambda t: p0 + (10 * BAR if t < 0.2 - DT / 2 else a if round(t / DT) % 100 < 25 else -b)
    m2 = frogsim.simulate(sc, controller=hold).control_metrics()["loop"]
    assert m2["tracking_error_rms_bar"] == m["tracking_error_rms_bar"]
    assert m2["tracking_error_max_bar"] == m["tracking_error_max_bar"]


def test_a_square_wave_angle_error_gives_its_closed_form_rms_and_max_in_degrees():
    """The robot's hip pair under a joint-angle controller whose valves a Python law holds shut:
    the joint moves as it will, the same in two runs of the same law (deterministic). The second
    run's setpoint is the first run's recorded angle plus a square wave of +2 deg on 10 samples of
    every 40 and -1 deg on the rest, so its error is that wave exactly. Over t >= 0.5 s of a 1 s
    run (samples 500..1000): 12 periods x 10 high samples plus sample 1000 (1000 mod 40 = 0):
    121 high, 380 low."""
    controller = {"hip": {"kind": "joint-angle", "joint": "hip_left", "setpoint": "20 deg", "settle": "0.5 s"}}
    rs = frogsim.load_robot_scenario(robot_raw(controller))

    def hold(t, obs):
        return {}
    first = frogsim.swim(rs, controller=hold)
    theta = first.joint_angles[:, first.joint_names.index("hip_left")].copy()
    a, b = math.radians(2.0), math.radians(1.0)
    hold.setpoint = lambda t: theta[round(t / DT)] + (a if round(t / DT) % 40 < 10 else -b)
    r = frogsim.swim(rs, controller=hold)
    np.testing.assert_array_equal(r.joint_angles[:, r.joint_names.index("hip_left")], theta)
    m = r.control_metrics()["hip"]
    n_hi, n_lo = 121, 380
    assert m["tracking_error_rms_deg"] == pytest.approx(
        math.degrees(math.sqrt((n_hi * a ** 2 + n_lo * b ** 2) / (n_hi + n_lo))), rel=1e-9)
    assert m["tracking_error_max_deg"] == pytest.approx(2.0, rel=1e-9)
    assert m["joint"] == "hip_left" and m["muscles"] == ["hip_left", "hip_left_recovery"]
    assert "tracking_error_rms_bar" not in m
    assert m["samples_pressure_target_clipped"] == 0       # a Python law computes no targets


# the hand-built sequence: (command time [s], mode), issued at those controller samples
SEQUENCE = [(0.010, "charge"), (0.011, "charge"), (0.020, "hold"), (0.030, "vent"), (0.040, "hold"),
            (0.050, "charge"), (0.060, "vent"), (0.070, "hold"), (0.099, "charge")]
# by hand: charge valve opens at 10, closes at 20, opens at 50, closes at 60 ms (the repeat at 11 ms
# changes nothing): 4; discharge valve opens at 30, closes at 40, opens at 60, closes at 70 ms: 4.
# The charge at 99 ms acts at 101 ms (2 ms dead time), after the 0.1 s run: never applied.
CHARGE_SWITCHINGS, DISCHARGE_SWITCHINGS, RUN_S = 4, 4, 0.1


def _sequence_law(muscle: str):
    todo = dict((round(t / DT), mode) for t, mode in SEQUENCE)

    def law(t, obs):
        mode = todo.get(round(t / DT))
        return {muscle: mode} if mode is not None else {}
    return law


@pytest.mark.parametrize("kind", ["pneumatic", "robot"])
def test_switchings_are_the_valve_changes_applied_in_a_hand_built_sequence(kind):
    ctl = {"kind": "bang-bang", "setpoint": "3 bar"}
    if kind == "pneumatic":
        sc = frogsim.load_scenario(closed_loop(ctl, RUN_S))
        r = frogsim.simulate(sc, controller=_sequence_law("hip"))
        name, muscle = "loop", "hip"
    else:
        rs = frogsim.load_robot_scenario(robot_raw({"hip": {**ctl, "muscle": "hip_left"}}, period=f"{RUN_S} s"))
        r = frogsim.swim(rs, controller=_sequence_law("hip_left"))
        name, muscle = "hip", "hip_left"
    m = r.control_metrics()[name]
    assert m["switchings"] == {muscle: {"charge": CHARGE_SWITCHINGS, "discharge": DISCHARGE_SWITCHINGS}}
    assert m["switchings_per_s"] == pytest.approx((CHARGE_SWITCHINGS + DISCHARGE_SWITCHINGS) / RUN_S, rel=1e-12)
    # and they are the changes of the valve states the run recorded (both charge phases open, close)
    u = r._charge_valve(muscle)
    assert np.count_nonzero(np.diff(u) != 0) == CHARGE_SWITCHINGS and u[-1] == 0.0
    # air used: the mass that entered through the charge valve, at ISO 8778's 100 kPa and 293.15 K
    charged = r.charged_mass(muscle)
    assert charged[-1] > 0 and m["air_used_L_std"] == pytest.approx((charged[-1] - charged[0]) / RHO_REF * 1e3,
                                                                    rel=1e-12)


# --- the robot's whole-run figures and its aeration volumes ------------------------------------------
def test_the_robots_whole_run_figures_are_in_its_summary_with_a_reason_when_null(same_controller_runs):
    _, robot = same_controller_runs
    s = robot.summary()
    assert s["distance_m"] == 0.0                                       # the base is fixed
    assert s["cost_of_transport"] is None and s["air_per_metre_L_std_per_m"] is None
    assert s["cost_of_transport_reason"] == "not reached: no forward distance (0 m; base 'fixed')"
    assert s["air_used_L_std"] == robot.control_metrics()["robot"]["air_used_L_std"]   # one muscle charged


def test_aeration_volume_is_one_measure_in_m3_on_both_and_null_without_a_phase():
    """The robot's knee driving muscles charged once by the gait (0.1 s to 0.4 s): the air each took
    in during that phase is all it took in, in m^3 from the method and litres in the summary; a
    muscle no program opens (the hip pair under the controller, the recovery muscles) has no phase."""
    drive = [{"at": "0 s", "state": "hold"}, {"at": "0.1 s", "state": "charge"}, {"at": "0.4 s", "state": "hold"}]
    raw = robot_raw({"hip": {**BANG_BANG, "muscle": "hip_left"}}, period="0.6 s", drive=drive)
    r = frogsim.swim(raw)
    s = r.summary()["aeration_volume_L_std"]
    q = r.charged_mass("knee_left")
    assert q[-1] > 1e-4                                              # it charged (kg)
    assert r.aeration_volume("knee_left") == pytest.approx((q[-1] - q[0]) / RHO_REF, rel=1e-12)      # m^3
    assert s["knee_left"] == pytest.approx(1e3 * (q[-1] - q[0]) / RHO_REF, rel=1e-12)                 # L
    assert s["hip_left"] is None and s["knee_left_recovery"] is None
    with pytest.raises(IndexError, match="has 0 pressurise phases"):
        r.aeration_volume("hip_left")


def test_the_heat_studys_charge_openings_are_openings_not_switchings(study):
    """The heat study's bang-bang hold reports its charge valve's openings. The switch counter counts
    every change of the valve (an opening and a closing each); the valve starts shut, so n
    switchings are ceil(n / 2) openings. Adiabatic: the controller charges once and holds."""
    from frogsim.studies.heat import MODELS, scenarios
    runs = study("heat").summary["heat"]["runs"]
    for model, params in MODELS.items():
        r = frogsim.simulate(scenarios(params)["bang-bang-3bar"])
        charge, _ = r.switchings["hip"]
        assert runs[model]["bang_bang_charge_valve_openings"] == (charge + 1) // 2
    assert runs["adiabatic"]["bang_bang_charge_valve_openings"] == 1
    text = study("heat").summary["heat"]["conclusion"]
    assert f"({runs['heat']['bang_bang_charge_valve_openings']} charge openings" in text
