"""The robot in MuJoCo (frogsim.robot, frogsim.engine.coupled, frogsim.swim): the MJCF against Table 1,
the crank geometry, joint equilibria, energy and air conservation, and the two experiments."""
from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from scipy.optimize import brentq

import frogsim
from frogsim.engine import coupled as C
from frogsim.errors import ScenarioError, SimulationError
from frogsim.robot.mjcf import write_mjcf

# paper Table 1
BODY_LENGTH, BODY_WIDTH = 0.590, 0.340
THIGH, CRUS, PALM = 0.280, 0.280, 0.336
TOTAL_MASS, DISPLACEMENT = 12.0, 19e-3
RHO_WATER = 998.2          # fresh water at 20 degC, kg/m^3
# paper Sec. 2.2.2: muscle lengths; parameter set: crank radius 30 mm, anchors 250 / 210 mm
MUSCLE = {"hip": (0.180, 0.030, 0.250), "knee": (0.150, 0.030, 0.210), "ankle": (0.150, 0.030, 0.210)}


@pytest.fixture(scope="module")
def swim10():
    return frogsim.swim("swim", cycles=10)


@pytest.fixture(scope="module")
def in_air():
    return frogsim.swim("leg-in-air")


def _id(m, kind, name):
    i = mujoco.mj_name2id(m, kind, name)
    assert i >= 0, name
    return i


# --- the MJCF -----------------------------------------------------------------------------------
def test_mjcf_file_loads_back_with_table1_masses_and_lengths(tmp_path):
    raw = frogsim.load_robot_scenario("swim").raw
    rs = frogsim.load_robot_scenario(frogsim.with_overrides(raw, {"robot.recovery": "muscle"}))
    path = write_mjcf(rs, tmp_path / "frog.xml")
    m = mujoco.MjModel.from_xml_path(str(path))
    B = mujoco.mjtObj.mjOBJ_BODY
    # the robot weighs Table 1's 12 kg plus the ballast that makes it weigh 19 L of water
    assert m.body_subtreemass[_id(m, B, "body")] == pytest.approx(RHO_WATER * DISPLACEMENT, rel=1e-9)
    legs = sum(m.body_subtreemass[_id(m, B, f"thigh_{s}")] for s in ("left", "right"))
    assert legs == pytest.approx(2 * (1.2 + 1.0 + 0.3), rel=1e-9)   # the parameter set's leg masses
    # segment lengths: joint to joint
    for side in ("left", "right"):
        assert np.linalg.norm(m.body_pos[_id(m, B, f"crus_{side}")]) == pytest.approx(THIGH)
        assert np.linalg.norm(m.body_pos[_id(m, B, f"palm_{side}")]) == pytest.approx(CRUS)
        g = _id(m, mujoco.mjtObj.mjOBJ_GEOM, f"palm_{side}_spoke")
        assert 2 * m.geom_size[g, 1] == pytest.approx(PALM)       # capsule half-length
    hull = _id(m, mujoco.mjtObj.mjOBJ_GEOM, "hull")
    assert 2 * m.geom_size[hull, :2] == pytest.approx([BODY_LENGTH, BODY_WIDTH])
    # the hull's height makes the whole robot displace 19 L
    a, b, c = m.geom_size[hull]
    legs_volume = 2 * (math.pi * 0.035 ** 2 * (THIGH + CRUS) + 0.0335 * 0.003)
    assert 4 / 3 * math.pi * a * b * c + legs_volume == pytest.approx(DISPLACEMENT, rel=1e-9)
    # 12 muscles (two per joint and leg), each a tendon driven by an actuator
    assert m.ntendon == 12 and m.nu == 12


@pytest.mark.parametrize("joint", ["hip", "knee", "ankle"])
def test_tendon_length_and_moment_arm_follow_the_crank(joint):
    # driving muscle between an anchor at distance d from the axis and a pin at radius r that is
    # perpendicular to the anchor line at theta = 0: law of cosines s = sqrt(d^2 + r^2 - 2 d r sin(theta)),
    # moment arm |ds/dtheta| = d r cos(theta) / s
    L0, r, d = MUSCLE[joint]
    raw = frogsim.load_robot_scenario("swim").raw
    rs = frogsim.load_robot_scenario(frogsim.with_overrides(raw, {"robot.recovery": "muscle"}), cycles=1)
    cm = C.build_coupled(rs)
    m, dd = cm.mjm, cm.mjd
    q = m.jnt_qposadr[_id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{joint}_left")]
    ten = _id(m, mujoco.mjtObj.mjOBJ_TENDON, f"{joint}_left")
    rec = _id(m, mujoco.mjtObj.mjOBJ_TENDON, f"{joint}_left_recovery")
    theta_r = rs.robot.joints[joint].range
    def tendon_lengths(th):
        dd.qpos[:] = 0
        dd.qpos[q] = th
        mujoco.mj_forward(m, dd)
        return dd.ten_length[ten], dd.ten_length[rec]

    h = 1e-6
    for th in np.linspace(0, theta_r, 5):
        s = math.sqrt(d * d + r * r - 2 * d * r * math.sin(th))
        arm = abs(tendon_lengths(th + h)[0] - tendon_lengths(th - h)[0]) / (2 * h)
        assert arm == pytest.approx(d * r * math.cos(th) / s, rel=1e-6)
        assert tendon_lengths(th)[0] == pytest.approx(s, rel=1e-9)
        # the recovery muscle is the mirror image about the middle of the range
        s_rec = math.sqrt(d * d + r * r - 2 * d * r * math.sin(theta_r - th))
        assert tendon_lengths(th)[1] == pytest.approx(s_rec, rel=1e-9)
    # the muscle's rest length at theta = 0: fittings = sqrt(d^2 + r^2) - L0
    assert rs.layout.cranks[joint].fittings == pytest.approx(math.hypot(d, r) - L0)


def test_joint_range_is_the_calibrated_stroke_and_within_the_25_percent_limit():
    # the range is where the driving muscle reaches the calibrated stroke contraction
    # (muscle_types: hip 11.3 %, knee and ankle 12.5 %), well inside the DMSP-20's 25 %
    rs = frogsim.load_robot_scenario("swim")
    for joint, stroke in (("hip", 0.113), ("knee", 0.125), ("ankle", 0.125)):
        L0, r, d = MUSCLE[joint]
        theta = rs.robot.joints[joint].range
        contraction = (math.hypot(d, r) - math.sqrt(d * d + r * r - 2 * d * r * math.sin(theta))) / L0
        assert contraction == pytest.approx(stroke, abs=0.002)


# --- mechanics ------------------------------------------------------------------------------------
def test_equal_pressures_rest_at_the_symmetric_angle():
    # both antagonistic muscles of every joint charged from one large source at 3 bar: at rest their
    # pressures are equal (the source's), and the joint settles where the two muscles are equally
    # long, by the mirror symmetry of the crank the middle of its range. The joints start at the
    # flexed stop. Without joint friction (it would leave a dead band around the equilibrium), with
    # more damping to settle sooner (the equilibrium does not depend on it).
    raw = frogsim.load_robot_scenario("leg-in-air").raw
    over = {f"joints.{j}.{k}": v for j in ("hip", "knee", "ankle")
            for k, v in (("friction", "0 N*m"), ("damping", "5 N*m*s"))}
    raw = frogsim.with_overrides(raw, {**over, "robot.recovery": "muscle",
                                       "source.initial_pressure_gauge": "3 bar",
                                       "source.volume": "1000 L",
                                       "gait.drive": [{"at": "0 s", "state": "charge"}],
                                       "gait.recover": [{"at": "0 s", "state": "charge"}]})
    r = frogsim.swim(raw, cycles=1)
    patm = r.atmospheric_pressure
    assert r.pressures[-1] == pytest.approx(np.full(12, patm + 3e5), abs=0.01e5)
    for j, name in enumerate(r.joint_names):
        joint = name.split("_")[0]
        theta_r = r.rs.robot.joints[joint].range
        # where the two crank lengths are equal (solved here, not taken from the code)
        sym = brentq(lambda th: math.sin(th) - math.sin(theta_r - th), 0, theta_r)
        assert math.degrees(r.joint_angles[-1, j]) == pytest.approx(math.degrees(sym), abs=0.5), name
        assert abs(r.joint_velocities[-1, j]) < 1e-2


def _swing_energy_error(xml: str, dt: float) -> tuple:
    m = mujoco.MjModel.from_xml_string(xml)
    m.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    m.opt.timestep = dt
    m.opt.gravity[:] = (0.0, -9.81, 0.0)
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    m.dof_damping[:] = 0
    m.dof_frictionloss[:] = 0
    m.jnt_limited[:] = 0
    d = mujoco.MjData(m)
    d.qvel[:] = np.tile([1.0, -2.0, 3.0], 2)
    mujoco.mj_forward(m, d)
    e0, kinetic, err = d.energy.sum(), 0.0, 0.0
    for _ in range(int(round(1.0 / dt))):          # 1 s
        mujoco.mj_step(m, d)
        err = max(err, abs(d.energy.sum() - e0))
        kinetic = max(kinetic, d.energy[1])
    return err, kinetic


def test_leg_swinging_in_air_without_muscles_conserves_energy():
    # no muscles, springs, friction, damping, stops or water: kinetic + potential energy is
    # constant to the integrator's tolerance. Gravity is turned into the plane of the legs so that
    # they swing like triple pendulums; RK4, and the error shrinks with the step as an integrator's does.
    raw = frogsim.load_robot_scenario("leg-in-air").raw
    rs = frogsim.load_robot_scenario(frogsim.with_overrides(raw, {"robot.recovery": "muscle"}))
    xml = C.build_coupled(rs).xml
    err_fine, kinetic = _swing_energy_error(xml, 1e-4)
    err_coarse, _ = _swing_energy_error(xml, 2e-4)
    assert kinetic > 1.0                                   # joules: the legs did swing
    assert err_fine < 1e-6 * kinetic
    assert err_coarse > 4 * err_fine                       # at least second order in the step


def test_air_mass_conserved_in_the_coupled_run():
    # the full robot (12 muscles, 24 valves) with the pump: air only moves between volumes
    raw = frogsim.load_robot_scenario("swim").raw
    r = frogsim.swim(frogsim.with_overrides(raw, {"robot.recovery": "muscle"}), cycles=2)
    air = r.total_air_mass
    assert np.ptp(air) / air[0] < 1e-10
    assert r.rec[-1, C.R_PUMPED] > 0 and r.rec[-1, C.R_CHARGED] > 0


# --- the experiments ------------------------------------------------------------------------------
def test_leg_in_air_delay_and_range(in_air):
    s = in_air.summary()
    for name, delay in s["joint_delay_s"].items():
        assert 0.03 <= delay <= 0.3, name                      # acceptance window
    for name, j in s["joints"].items():
        assert j["max_deg"] > 0.9 * j["range_limit_deg"]      # it moves through its range...
        assert j["max_deg"] < j["range_limit_deg"] + 1.0      # ...stopped at the joint's stop
    for name, c in s["max_contraction_percent"].items():
        assert 0 < c <= 25.0                                   # within the DMSP-20's limit
    # with the joints stopped where the calibrated stroke ends, the hip takes the paper's
    # aeration volume, 0.455 L (Sec. 4.2), here from the coupled model
    assert s["aeration_volume_L_std"]["hip_left"] == pytest.approx(0.455, rel=0.05)
    assert s["aeration_volume_L_std"]["knee_left"] == pytest.approx(0.401, rel=0.05)


def test_leg_in_air_pressure_matches_the_pneumatic_model_driven_by_its_joint_angles(in_air, tmp_path):
    # Fig. 13's construction: the pneumatic model alone (frogsim.simulate), with the muscle lengths
    # taken from the coupled run's joint angles through the crank, gives the same hip pressure
    t = in_air.t
    csv = tmp_path / "angles.csv"
    cols = {"time_s": t}
    for j in ("hip", "knee", "ankle"):
        # the soft joint stop lets an angle dip a fraction of a degree below 0, which would stretch
        # the muscle past its rest length; the pneumatic model's crank refuses that
        cols[j] = np.degrees(np.clip(in_air.joint_angles[:, in_air.joint_names.index(f"{j}_left")], 0, None))
    import pandas as pd
    pd.DataFrame(cols).to_csv(csv, index=False)
    raw = frogsim.load_scenario("paper-cycle").raw
    over = {"solver": {"max_step": "1 ms"}}
    for name in raw["muscles"]:
        joint = name.split("_")[0]
        over[f"muscles.{name}.motion"] = {"kind": "joint_angles", "file": str(csv), "column": joint}
    r = frogsim.simulate(frogsim.load_scenario({**frogsim.with_overrides(raw, {k: v for k, v in over.items()
                                                                             if k != "solver"}),
                                                "solver": over["solver"]}))
    p_coupled = in_air.pressures[:, in_air.muscle_names.index("hip_left")]
    p_alone = np.interp(t, r.t, r.muscle_pressure("hip_left"))
    assert np.max(np.abs(p_coupled - p_alone)) < 0.03e5          # 0.03 bar of a 5 bar swing


def test_swim_ten_cycles_moves_forward_with_thrust_in_extension(swim10):
    s = swim10.summary()
    assert s["cycles"] == 10
    # forward, in the direction the frog faces (its heading at t = 0), every cycle
    assert s["distance_m"] > 0
    assert all(d > 0 for d in s["distance_each_cycle_m"])
    assert abs(swim10.position[-1, 1]) < 0.01 * s["distance_m"]      # straight: the legs are symmetric
    # thrust positive during leg extension; the body decelerates during recovery (Gal and Blake 1988)
    assert s["thrust_mean_extension_N"] > 0
    assert s["forward_acceleration_mean_recovery_m_per_s2"] < 0
    assert s["forward_acceleration_mean_extension_m_per_s2"] > 0
    # the figures in their units, from their definitions (docs/robot.md) and the scenario's gait
    duration = 10 * frogsim.load_robot_scenario("swim").gait.period
    assert s["mean_speed_m_per_s"] == pytest.approx(s["distance_m"] / duration, rel=1e-6)
    assert s["mean_speed_body_lengths_per_s"] == pytest.approx(s["mean_speed_m_per_s"] / BODY_LENGTH)
    assert s["distance_per_cycle_m"] == pytest.approx(s["distance_m"] / 10)
    assert sum(s["distance_each_cycle_m"]) == pytest.approx(s["distance_m"], rel=1e-6)
    assert s["thrust_peak_N"] >= s["thrust_mean_extension_N"] > s["thrust_mean_N"]
    # air: no muscle takes more per cycle than one charge from empty to 6 bar, the paper's aeration
    # volume (Sec. 4.2: 0.455 L hip, 0.401 L knee and ankle); twelve muscles charged at most once
    assert 0 < s["air_used_per_cycle_L_std"] <= 4 * (0.455 + 2 * 0.401) * 1.05
    # cost of transport E / (m g d): E = m_air R T ln(p_source / p_atm), the isothermal exergy of
    # the air charged from the source, so E / (m_air R T) lies between ln(p / p_atm) at the
    # source's lowest and highest pressure of the run; m_air from litres at the ISO 8778 state
    # (100 kPa, 293.15 K); m the robot ballasted to neutral buoyancy, 998.2 kg/m^3 x 19 L (Table 1)
    assert s["robot_mass_with_ballast_kg"] == pytest.approx(RHO_WATER * DISPLACEMENT, rel=1e-3)
    m_air = s["air_used_L_std"] * 1e-3 * 1e5 / (287.0 * 293.15)
    ln_ratio = s["cost_of_transport"] * RHO_WATER * DISPLACEMENT * 9.80665 * s["distance_m"] / (m_air * 287.0 * 293.15)
    ps = swim10.source_pressure
    assert math.log(ps.min() / 101325.0) * 0.999 <= ln_ratio <= math.log(ps.max() / 101325.0) * 1.001, \
        (ln_ratio, ps.min(), ps.max())
    assert 0 < s["air_used_per_cycle_L_std"] < 10
    assert s["source_pressure_after_cycles_bar_gauge"] < s["source_pressure_initial_bar_gauge"]


def test_gait_is_data(tmp_path):
    # a later knee: its charge valve opens 50 ms (plus the 2 ms valve dead time) after the command
    raw = frogsim.load_robot_scenario("leg-in-air").raw
    raw = frogsim.with_overrides(raw, {"gait.joints": {"knee": {"drive": [
        {"at": "0.05 s", "state": "charge"}, {"at": "1 s", "state": "vent"}]}}})
    r = frogsim.swim(raw)
    i = r.muscle_names.index("knee_left")
    opened = r.t[np.argmax(r.valves[:, 2 * i] > 0.5)]
    assert opened == pytest.approx(0.052, abs=2e-3)
    assert r.joint_delay("knee_left") > 0.05


def test_runs_are_deterministic(in_air):
    again = frogsim.swim("leg-in-air")
    assert np.array_equal(in_air.rec, again.rec)


# --- bad input and instability ----------------------------------------------------------------------
BAD = {
    "robot.environment": ("lava", "robot.environment"),
    "robot.timestep": ("1 bar", "robot.timestep"),
    "robot.wings": (True, "robot.wings"),
    "gait.period": ("-2 s", "gait.period"),
    "joints.hip.range": ("95 deg", "joints.hip.range"),
    "palms.folded_area": ("0.05 m^2", "palms.folded_area"),
    "body.ballast": ("lots", "body.ballast"),
    "hydro.plate_normal_drag": ("1.2 N", "hydro.plate_normal_drag"),
}


@pytest.mark.parametrize("path", sorted(BAD))
def test_bad_robot_input_names_the_field(path):
    value, field = BAD[path]
    raw = frogsim.load_robot_scenario("swim").raw
    with pytest.raises(ScenarioError, match=field.replace(".", r"\.")):
        frogsim.load_robot_scenario(frogsim.with_overrides(raw, {path: value}))


def test_bad_gait_step_and_cycles():
    raw = frogsim.load_robot_scenario("swim").raw
    late = frogsim.with_overrides(raw, {"gait.drive": [{"at": "0 s", "state": "charge"},
                                                       {"at": "3 s", "state": "vent"}]})
    with pytest.raises(ScenarioError, match=r"gait\.drive\[1\]\.at"):
        frogsim.load_robot_scenario(late)
    with pytest.raises(ScenarioError, match="cycles"):
        frogsim.load_robot_scenario("swim", cycles=0)


def test_robot_scenario_refused_by_simulate():
    with pytest.raises(ScenarioError, match="frogsim swim"):
        frogsim.load_scenario("swim")


def test_range_beyond_the_muscles_limit_is_refused():
    # a 60 mm crank turned 80 deg shortens the hip muscle by 36.6 % (law of cosines), beyond 25 %
    raw = frogsim.load_robot_scenario("swim").raw
    raw = frogsim.with_overrides(raw, {"muscle_types.hip.crank_radius": "60 mm", "joints.hip.range": "80 deg"})
    with pytest.raises(ScenarioError, match=r"joints\.hip\.range.*max_contraction"):
        frogsim.load_robot_scenario(raw)


@pytest.mark.parametrize("value,expected", [(float("nan"), "velocity = nan (not finite)"),
                                            (1e4, "angular velocity = 1e+04 rad/s exceeds")])
def test_unstable_state_stops_with_quantity_and_time(value, expected):
    # a run that went unstable (NaN, exploding velocity) stops at once with the quantity and the
    # time, instead of writing NaN-filled output; here the bad state is planted at t = 0
    cm = C.build_coupled(frogsim.load_robot_scenario("leg-in-air"))
    cm.mjd.qvel[cm.arrays["leg_dof"][1]] = value                # knee_left
    with pytest.raises(SimulationError) as exc:
        C.run_coupled(cm)
    msg = str(exc.value)
    assert "unstable at t = 0.0000 s" in msg and "knee_left" in msg and expected in msg
