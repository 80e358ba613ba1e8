"""Joint-angle control of an antagonistic pair on the robot (kind "joint-angle", docs/control.md),
checked against statics, Eq. (8) and the law's definition, not against the code's own output.

Statics of a joint (no gravity on it: the legs move in the horizontal plane): a muscle of length
L(theta) pulling with tension F does work -F dL when it changes length, so the pair's torque
about the joint is tau = -F_ext dL_ext/dtheta - F_flex dL_flex/dtheta; a joint at rest with
Coulomb friction tau_f has |tau| <= tau_f. The tensions come from the muscle force law
(:func:`frogsim.physics.muscle_force.muscle_force`, fitted to the DMSP-20 datasheet and tested
there), the lengths from the crank's law of cosines.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import frogsim
from frogsim.cli import main
from frogsim.errors import ScenarioError
from frogsim.physics.muscle import crank_muscle_length
from frogsim.physics.muscle_force import MODEL_DMSP20, muscle_force
from tests.conftest import B_MHJ9, C_MHJ9, K_AIR, P_ATM, R_AIR, RHO_REF, T_REF  # noqa: F401

BAR = 1e5
DT = 1e-3                  # controller period (1 kHz) = MuJoCo step
DEAD = 2e-3                # fan2017's valve dead time
HIP_V = math.pi * 0.020 ** 2 * 0.180 / 4 + 5e-6   # DMSP-20 hip at rest; contraction only adds volume
FRICTION = 0.2             # fan2017 joints.hip.friction [N m]
P_SOURCE = P_ATM + 6.0 * BAR
# the largest pressure step one valve makes while a command waits one period and acts one dead
# time: choked from the source into the smallest volume (the muscle at rest length), adiabatic
STEP = K_AIR * R_AIR * T_REF * C_MHJ9 * RHO_REF * P_SOURCE * (DT + DEAD) / HIP_V


def hip_raw(controller: dict | None = None, period: str = "1 s", **robot) -> dict:
    """The shipped hip-angle-in-air scenario (body fixed in air) with the hip controller replaced."""
    from frogsim.scenario.load import merged_raw
    raw, base = merged_raw("hip-angle-in-air")
    raw = {**raw, "base_dir": base, "gait": {**raw["gait"], "period": period},
           "robot": {**raw["robot"], **robot}, "output_interval": "1 ms"}
    if controller is None:
        raw.pop("controllers")
    else:
        raw["controllers"] = {"hip": {"kind": "joint-angle", "joint": "hip_left", **controller}}
    return raw


def pair_torque(rs, theta, p_ext, p_flex) -> float:
    """The hip pair's torque [N m] at angle theta [rad], gauge pressures p_ext, p_flex [Pa]
    (positive: towards extension), by virtual work on the crank geometry."""
    mt = rs.pneumatic.muscle_types["hip"]
    law = rs.robot.muscle_force
    r, d, L0 = mt.crank_radius, mt.anchor_distance, mt.nominal_length
    rng = rs.robot.joints["hip"].range
    b0 = L0 / math.cos(mt.braid_angle)                 # braid fibre length
    n = b0 * math.sin(mt.braid_angle) / (math.pi * mt.inner_diameter)   # turns
    h = 1e-6

    def length(th, which):
        return (crank_muscle_length(th, d, r, 0.0, L0, 1.0) if which == "ext"
                else crank_muscle_length(th, d, r, rng, L0, -1.0))

    def tension(p, L):
        return muscle_force(MODEL_DMSP20, p, L, L0, b0, n, law.force_scale, law.strain_scale, law.stiffness,
                            law.stretch_stiffness, law.stretch_quadratic)
    tau = 0.0
    for which, p in (("ext", p_ext), ("flex", p_flex)):
        L = length(theta, which)
        dL = (length(theta + h, which) - length(theta - h, which)) / (2 * h)
        tau -= tension(p, L) * dL
    return tau


# --- statics: a pair of constant pressures holds the angle of the torque balance -------------------------------
def test_a_held_pair_of_pressures_rests_where_the_muscle_torques_balance_within_friction():
    from frogsim.engine.coupled import build_coupled, run_coupled
    from frogsim.engine.swim import SwimResult
    rs = frogsim.load_robot_scenario(hip_raw(None, "1.5 s"))         # every valve held shut
    cm = build_coupled(rs)
    cm.set_muscle_pressure("hip_left", P_ATM + 3.0 * BAR)
    cm.set_muscle_pressure("hip_left_recovery", P_ATM + 2.0 * BAR)
    r = SwimResult(rec=run_coupled(cm)["rec"], model=cm)
    j, ie, jf = 0, r.muscle_names.index("hip_left"), r.muscle_names.index("hip_left_recovery")
    assert r.joint_names[j] == "hip_left"
    th = r.joint_angles[-1, j]
    assert np.max(np.abs(r.joint_velocities[-200:, j])) < 1e-3          # at rest
    rng = rs.robot.joints["hip"].range
    assert 0.02 < th < rng - 0.02                                       # not on a stop
    pe, pf = r.pressures[-1, ie] - P_ATM, r.pressures[-1, jf] - P_ATM
    assert abs(pair_torque(rs, th, pe, pf)) <= FRICTION * 1.001
    # the balance pins the angle: 2 degrees either side the muscles' torque exceeds the friction
    assert pair_torque(rs, th - math.radians(2), pe, pf) > FRICTION
    assert pair_torque(rs, th + math.radians(2), pe, pf) < -FRICTION


# --- the inner loop alone: outer gains 0 -------------------------------------------------------------------
def test_with_the_outer_gains_zero_both_muscles_stay_within_band_and_one_step_of_p0():
    band, p0 = 0.2 * BAR, 3.0 * BAR
    rs = frogsim.load_robot_scenario(hip_raw(
        {"setpoint": "20 deg", "co_contraction": "3 bar", "proportional_gain": "0 bar/rad",
         "band": "0.2 bar"}, "1.5 s"))
    r = frogsim.swim(rs)
    for name in ("hip_left", "hip_left_recovery"):
        i = r.muscle_names.index(name)
        p = r.pressures[:, i] - P_ATM
        inside = np.nonzero(np.abs(p - p0) <= band / 2)[0]
        assert inside.size, f"{name} never reached the band"
        # after the first entry, the pressure also moves with the muscle's volume: adiabatic
        # compression dp = k p dV / V over one period and a dead time
        L = r.lengths[:, i]
        mt = rs.pneumatic.muscle_types["hip"]
        b0 = mt.nominal_length / math.cos(mt.braid_angle)
        nt = b0 * math.sin(mt.braid_angle) / (math.pi * mt.inner_diameter)
        V = L * (b0 ** 2 - L ** 2) / (4 * math.pi * nt ** 2) + mt.dead_volume
        w = int(round((DT + DEAD) / 1e-3))
        dV = np.max(np.abs(V[w:] - V[:-w])[inside[0]:]) if V.size > w else 0.0
        bound = band / 2 + STEP + K_AIR * (P_ATM + p0 + band) * dV / HIP_V
        after = p[inside[0]:]
        assert np.max(np.abs(after - p0)) <= bound, name
        assert np.max(np.abs(after - p0)) > band / 4                      # the valves do work


# --- the cascade converges to the angle statics and the band allow ------------------------------------------
@pytest.mark.parametrize("environment", ["air", "water"])
def test_the_controlled_angle_settles_where_statics_allow_for_the_band_and_friction(environment):
    # held on its base, in air or in water: still water puts no torque on a joint at rest whose
    # axis is vertical (buoyancy and weight are vertical), so the same statics hold in both
    kp, p0, band = 20.0 * BAR, 2.5 * BAR, 0.1 * BAR
    sp = math.radians(10.0)
    rs = frogsim.load_robot_scenario(hip_raw(
        {"setpoint": "10 deg", "co_contraction": "2.5 bar", "proportional_gain": "20 bar/rad",
         "derivative_gain": "0.5 bar*s/rad", "band": "0.1 bar"}, "2 s", environment=environment))
    r = frogsim.swim(rs)
    th_end = r.joint_angles[-1, 0]
    assert np.max(np.abs(r.joint_velocities[-100:, 0])) < 0.05
    tol = band / 2 + STEP
    # P-law statics: targets p0 +- kp (sp - theta) / 2; each true pressure within tol of its
    # target; the angle is admissible where some such pressures make |tau| <= friction (tau rises
    # with the extensor's pressure and falls with the flexor's)
    grid = np.radians(np.linspace(0.5, 40.5, 801))
    ok = []
    for th in grid:
        dp = kp * (sp - th)
        te = min(max(p0 + dp / 2, 0.0), P_SOURCE - P_ATM)
        tf = min(max(p0 - dp / 2, 0.0), P_SOURCE - P_ATM)
        hi = pair_torque(rs, th, te + tol, max(tf - tol, 0.0))
        lo = pair_torque(rs, th, max(te - tol, 0.0), tf + tol)
        ok.append(lo <= FRICTION and hi >= -FRICTION)
    ok = np.array(ok)
    admissible = grid[ok]
    assert admissible.size and admissible.max() - admissible.min() < math.radians(6)   # not vacuous
    # equal pressures balance at the middle of the range (the pair is mirror-symmetric about it):
    # the controller has moved the joint away from there
    assert admissible.max() < rs.robot.joints["hip"].range / 2 - math.radians(3)
    assert admissible.min() - 1e-3 <= th_end <= admissible.max() + 1e-3


# --- commands on the controller grid, one dead time later ---------------------------------------------------
@pytest.mark.parametrize("rate", ["1 kHz", "500 Hz"])
def test_python_commands_come_on_the_grid_and_act_one_dead_time_later(rate):
    raw = hip_raw({"setpoint": "20 deg"}, "0.4 s")
    raw["controller"] = {"rate": rate}
    rs = frogsim.load_robot_scenario(raw)
    T = 1.0 / rs.pneumatic.controller.rate
    calls = []
    plan = {0.05: "charge", 0.08: "hold", 0.12: "vent", 0.15: "charge", 0.2: "vent"}

    def fn(t, obs):
        calls.append(t)
        for at, mode in plan.items():
            if abs(t - at) < 1e-9:
                return {"hip_left": mode}
        return {}
    r = frogsim.swim(rs, controller=fn)
    calls = np.array(calls)
    np.testing.assert_allclose(calls, np.arange(calls.size) * T, atol=1e-12)   # every sample, on the grid
    assert calls[-1] >= 0.4 - T - 1e-9
    i = r.muscle_names.index("hip_left")
    uc, ud = r.valves[:, 2 * i], r.valves[:, 2 * i + 1]
    want_c = np.zeros_like(r.t)
    want_d = np.zeros_like(r.t)
    for at, m in plan.items():          # the state a row shows: commanded at or before t - dead
        sel = r.t >= at + DEAD - 1e-9
        want_c[sel] = 1.0 if m == "charge" else 0.0
        want_d[sel] = 1.0 if m == "vent" else 0.0
    np.testing.assert_array_equal(uc, want_c)
    np.testing.assert_array_equal(ud, want_d)


# --- the same law compiled and in Python ------------------------------------------------------------------
def test_the_joint_law_compiled_and_in_python_gives_the_same_valve_sequence():
    ctl = {"setpoint": {"kind": "steps", "steps": [{"at": "0 s", "value": "10 deg"}, {"at": "0.3 s", "value": "25 deg"}]},
           "co_contraction": "2 bar", "proportional_gain": "25 bar/rad", "derivative_gain": "0.5 bar*s/rad",
           "integral_gain": "20 bar/(rad*s)", "band": "0.1 bar",
           "angle_sensor": {"noise": "0.2 deg", "seed": 3, "bits": 12, "full_scale": "90 deg", "lag": "2 ms"},
           "sensor": {"noise": "0.01 bar", "seed": 5, "bits": 10, "full_scale": "10 bar"}}
    rs = frogsim.load_robot_scenario(hip_raw(ctl, "0.6 s"))
    c = rs.pneumatic.controllers["hip"]
    kp, kd, ki, band = c.proportional_gain, c.derivative_gain, c.integral_gain, c.band
    p0 = P_ATM + c.co_contraction
    steps = c.setpoint.steps
    memory = {"integral": 0.0}

    def law(t, obs):       # docs/control.md, written out
        sp = steps[0][1] if t < steps[1][0] - 1e-9 else steps[1][1]
        e = sp - obs["angle"]["hip_left"]
        integral = memory["integral"] + e * DT
        dp = kp * e + kd * (0.0 - obs["velocity"]["hip_left"]) + ki * integral
        up, down = p0 + 0.5 * dp, p0 - 0.5 * dp
        lo, hi = P_ATM, obs["source"]
        if not (up > hi or up < lo or down > hi or down < lo):
            memory["integral"] = integral
        out = {}
        for m, target in (("hip_left", up), ("hip_left_recovery", down)):
            target = min(max(target, lo), hi)
            p = obs[m]
            out[m] = "charge" if p < target - band / 2 else ("vent" if p > target + band / 2 else "hold")
        return out
    compiled = frogsim.swim(rs)
    python = frogsim.swim(rs, controller=law)
    np.testing.assert_array_equal(compiled.valves, python.valves)
    assert compiled.control_metrics()["hip"]["switchings"] == python.control_metrics()["hip"]["switchings"]
    assert compiled.control_metrics()["hip"]["switchings_per_s"] > 20           # not vacuous
    # and the valves of one muscle are never open together
    for i in range(len(compiled.muscle_names)):
        assert not np.any((compiled.valves[:, 2 * i] > 0) & (compiled.valves[:, 2 * i + 1] > 0))


# --- air ---------------------------------------------------------------------------------------------------
def test_air_is_conserved_in_closed_loop_and_the_metric_is_the_charged_mass():
    rs = frogsim.load_robot_scenario(hip_raw({"setpoint": {"kind": "sine", "mean": "20 deg", "amplitude": "8 deg",
                                                           "frequency": "2 Hz"}}, "1 s"))
    r = frogsim.swim(rs)
    total = r.total_air_mass
    assert np.ptp(total) / total[0] < 1e-9
    m = r.control_metrics()
    ie, jf = r.muscle_names.index("hip_left"), r.muscle_names.index("hip_left_recovery")
    charged = (r.charged[-1, ie] - r.charged[0, ie] + r.charged[-1, jf] - r.charged[0, jf])
    assert m["hip"]["air_used_L_std"] == pytest.approx(charged / RHO_REF * 1e3, rel=1e-12)
    assert m["hip"]["air_used_L_std"] > 0.05
    assert set(m) == {"hip"}                 # one entry per controller, nothing else
    # the body is fixed: no distance, so no air per metre and no cost of transport, and why
    s = r.summary()
    assert s["air_per_metre_L_std_per_m"] is None and s["cost_of_transport"] is None
    assert s["cost_of_transport_reason"].startswith("not reached: no forward distance")


# --- scenario: paths, refusals ------------------------------------------------------------------------------
def test_joint_controller_settings_are_variable_paths_with_their_units():
    rs = frogsim.load_robot_scenario("hip-angle-in-air")
    paths = rs.pneumatic.variable_paths()
    for key, unit in (("proportional_gain", "bar/rad"), ("derivative_gain", "bar*s/rad"),
                      ("integral_gain", "bar/(rad*s)"), ("co_contraction", "bar"), ("band", "bar"),
                      ("angle_sensor.noise", "deg"), ("setpoint.steps", None)):
        if unit is None:
            continue
        assert paths[f"controllers.hip.{key}"]["display"] == unit
    assert "controllers.hip.frequency" not in paths and "controllers.hip.horizon" not in paths
    v = rs.pneumatic.replace({"controllers.hip.proportional_gain": 5e5})
    assert v.controllers["hip"].proportional_gain == 5e5
    assert rs.pneumatic.controllers["hip"].muscle == "hip_left"
    assert rs.pneumatic.controllers["hip"].antagonist == "hip_left_recovery"
    # the controlled muscles take no gait commands, the others keep theirs
    assert not rs.pneumatic.muscles["hip_left"].program.steps
    assert not rs.pneumatic.muscles["hip_left_recovery"].program.steps
    assert rs.pneumatic.muscles["knee_left"].program.steps


REFUSALS = [
    ({"kind": "joint-angle", "joint": "hip_middle", "setpoint": "20 deg"}, "controllers.hip.joint"),
    ({"kind": "joint-angle", "joint": "hip_left", "setpoint": "50 deg"}, "controllers.hip.setpoint"),
    ({"kind": "joint-angle", "joint": "hip_left", "setpoint": "-5 deg"}, "controllers.hip.setpoint"),
    ({"kind": "joint-angle", "joint": "hip_left", "setpoint": {"kind": "sine", "mean": "30 deg",
                                                               "amplitude": "15 deg", "frequency": "1 Hz"}},
     "controllers.hip.setpoint"),
    ({"kind": "joint-angle", "joint": "hip_left", "setpoint": "20 deg", "co_contraction": "7 bar"},
     "controllers.hip.co_contraction"),
    ({"kind": "joint-angle", "joint": "hip_left", "setpoint": "20 deg", "duty": 0.5}, "controllers.hip"),
    ({"kind": "joint-angle", "joint": "hip_left"}, "controllers.hip.setpoint"),
    ({"kind": "joint-angle", "setpoint": "20 deg"}, "controllers.hip.joint"),
    ({"kind": "joint-angle", "joint": "hip_left", "setpoint": "20 deg", "proportional_gain": "-1 bar/rad"},
     "controllers.hip.proportional_gain"),
    ({"kind": "joint-angle", "joint": "hip_left", "setpoint": "20 deg", "proportional_gain": "3 m"},
     "controllers.hip.proportional_gain"),
    ({"kind": "angle-pid", "joint": "hip_left", "setpoint": "20 deg"}, "controllers.hip.kind"),
    ({"kind": "bang-bang", "muscle": "hip_middle", "setpoint": "2 bar"}, "controllers.hip.muscle"),
]


@pytest.mark.parametrize("controller,field", REFUSALS)
def test_bad_joint_controllers_are_refused_in_one_line(controller, field):
    raw = hip_raw({"setpoint": "20 deg"})
    raw["controllers"] = {"hip": controller}
    with pytest.raises(ScenarioError) as exc:
        frogsim.load_robot_scenario(raw)
    assert str(exc.value).startswith(field) and "\n" not in str(exc.value)


def test_a_joint_controller_needs_the_antagonistic_pair_and_the_robot():
    with pytest.raises(ScenarioError, match=r"^controllers.hip.joint.*recovery"):
        frogsim.load_robot_scenario(hip_raw({"setpoint": "20 deg"}, recovery="spring"))
    d = {"name": "p", "duration": "1 s", "muscles": {"hip": {"type": "hip", "motion": {"kind": "constant"}}},
         "controllers": {"hip": {"kind": "joint-angle", "joint": "hip_left", "setpoint": "20 deg"}}}
    with pytest.raises(ScenarioError, match=r"^controllers.hip.kind.*robot"):
        frogsim.load_scenario(d)


def test_cli_swim_refuses_a_bad_joint_controller_with_exit_2_and_writes_nothing(tmp_path, capsys):
    f = tmp_path / "bad.toml"
    f.write_text('name = "bad"\nparameters = "fan2017"\n[robot]\nenvironment = "air"\nbase = "fixed"\n'
                 'recovery = "muscle"\n[gait]\nperiod = "1 s"\ncycles = 1\n'
                 'drive = [ { at = "0 s", state = "hold" } ]\nrecover = [ { at = "0 s", state = "hold" } ]\n'
                 'palms = [ { at = "0 s", state = "fold" } ]\n'
                 '[controllers.hip]\nkind = "joint-angle"\njoint = "hip_left"\nsetpoint = "60 deg"\n')
    out = tmp_path / "out"
    assert main(["swim", str(f), "--out", str(out), "--no-animation"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "controllers.hip.setpoint" in err and "range" in err
    assert not out.exists() or not any(out.iterdir())


def test_control_command_writes_the_control_joint_study(tmp_path):
    import json
    out = tmp_path / "out"
    assert main(["control", "control-joint", "--out", str(out)]) == 0
    for name in ("control-joint.png", "control-joint.csv", "summary.json"):
        assert (out / name).exists()
    s = json.loads((out / "summary.json").read_text())["control_joint"]
    assert len(s["runs"]) == 2 and s["conclusion"]
    for level in s["runs"].values():
        assert level["sine"]["tracking_error_rms_deg"] < 3.0           # it tracks
        assert level["step"]["rise_time_s"] is not None


def test_every_closed_loop_controller_is_drawn_with_setpoint_antagonist_and_numbers(monkeypatch, tmp_path):
    """swim.png of a joint-angle run: the setpoint and the tracked angle on one axis, the muscle's
    and the antagonist's pressures, the tracking numbers of summary.json in the panel's title;
    the palm on an axis of its own (never scaled onto a degree axis)."""
    import frogsim._plotting as plotting
    from frogsim.studies import robot as R
    seen = {}
    real = plotting.save

    def save(fig, path, note=""):
        seen["fig"] = fig
        seen["titles"] = [a.get_title() for a in fig.axes]
        seen["labels"] = [[ln.get_label() for ln in a.get_lines()] for a in fig.axes]
        seen["ylabels"] = [a.get_ylabel() for a in fig.axes]
        real(fig, path, note)
    monkeypatch.setattr(R, "save", save)
    r = frogsim.swim("hip-angle-in-air")
    s = r.summary()
    R.plot_swim(r, str(tmp_path / "swim.png"), s)
    m = s["control"]["hip"]
    title = next(t for t in seen["titles"] if t.startswith("hip: joint-angle control"))
    assert f"RMS {m['tracking_error_rms_deg']:.3g} deg" in title
    assert f"max {m['tracking_error_max_deg']:.3g} deg" in title
    k = seen["titles"].index(title)
    assert seen["labels"][k] == ["hip_left setpoint", "hip_left angle"]            # one axis
    twins = [lb for labels in seen["labels"] for lb in labels if "antagonist" in lb]
    assert twins == ["hip_left_recovery (antagonist) pressure, right axis"]
    assert not any("x 40" in lb for labels in seen["labels"] for lb in labels)
    palm = [i for i, labels in enumerate(seen["labels"]) if any("palm" in lb for lb in labels)]
    assert palm and all("deg" not in seen["ylabels"][i] for i in palm)
