"""Water forces (frogsim.physics.hydro, frogsim.robot.water, the coupled engine): drag of a plate
against its closed forms, a coasting body's velocity decay, added-mass coefficients, buoyancy."""
from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

import frogsim
from frogsim.engine import coupled as C
from frogsim.physics.hydro import (ellipsoid_added_mass, gauss_strips, plate_added_mass_coefficient,
                                   quadratic_drag)
from frogsim.robot.water import hull_part

RHO = 998.2            # fresh water at 20 degC [kg/m^3]
S_OPEN = 0.0335        # paper Table 1: palm area [m^2]
L_PALM = 0.336         # paper Table 1: palm length [m]


def test_quadratic_drag_closed_form():
    # F = -1/2 rho C A |v| v; the open palm (C = 1.17) at 1 m/s: -19.56 N
    assert quadratic_drag(RHO, 1.17, S_OPEN, 1.0) == pytest.approx(-0.5 * RHO * 1.17 * S_OPEN, rel=1e-12)
    assert quadratic_drag(RHO, 1.17, S_OPEN, -2.0) == pytest.approx(4 * 0.5 * RHO * 1.17 * S_OPEN, rel=1e-12)


def test_gauss_strips_integrate_polynomials_exactly():
    s, ds = gauss_strips(6, 0.0, L_PALM)
    for k in range(12):              # degree 2n - 1 = 11
        assert np.sum(ds * s ** k) == pytest.approx(L_PALM ** (k + 1) / (k + 1), rel=1e-12)


def test_added_mass_sphere_and_prolate_spheroid():
    # sphere: m = rho V / 2 in every direction, no added inertia (Lamb 1932 art. 92)
    R = 0.1
    m, inertia = ellipsoid_added_mass(R, R, R, RHO)
    V = 4 / 3 * math.pi * R ** 3
    assert m == pytest.approx((RHO * V / 2,) * 3, rel=1e-6)
    assert inertia == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    # prolate spheroid along its axis (Lamb art. 115): alpha0 = 2 (1 - e^2)/e^3 (artanh(e) - e)
    a, b = 0.3, 0.1
    e = math.sqrt(1 - (b / a) ** 2)
    alpha0 = 2 * (1 - e * e) / e ** 3 * (0.5 * math.log((1 + e) / (1 - e)) - e)
    beta0 = 1 / e ** 2 - (1 - e * e) / (2 * e ** 3) * math.log((1 + e) / (1 - e))
    m, _ = ellipsoid_added_mass(a, b, b, RHO)
    V = 4 / 3 * math.pi * a * b * b
    assert m[0] == pytest.approx(RHO * V * alpha0 / (2 - alpha0), rel=1e-6)
    assert m[1] == pytest.approx(RHO * V * beta0 / (2 - beta0), rel=1e-6)


def test_plate_added_mass_coefficient_table():
    # DNV-RP-H103 Table A-2: square plate 0.579, b/a = 2: 0.757; towards the 2-D value 1
    assert plate_added_mass_coefficient(1.0) == pytest.approx(0.579)
    assert plate_added_mass_coefficient(2.0) == pytest.approx(0.757)
    assert 0.947 < plate_added_mass_coefficient(40.0) < 1.0


@pytest.fixture(scope="module")
def robot():
    """The swim robot (planar, in water) with both palms open and nothing moving."""
    cm = C.build_coupled(frogsim.load_robot_scenario("swim", cycles=1))
    cm.arrays["frac"][:] = 1.0
    cm.arrays["frac_new"][:] = 1.0
    return cm


def _body(cm, name):
    return mujoco.mj_name2id(cm.mjm, mujoco.mjtObj.mjOBJ_BODY, name)


def _still(cm):
    cm.mjd.qpos[:] = 0.0
    cm.mjd.qvel[:] = 0.0


def test_palm_drag_translating_at_constant_speed(robot):
    # the whole robot moving forward at U with its legs still: the open palm (a fan of area S) sees
    # -U along x. Normal drag 1/2 rho C_n S (U n.x)^2, friction on both faces 1/2 rho C_f 2S (U e1.x)^2
    cm, U = robot, 0.8
    _still(cm)
    cm.mjd.qvel[0] = U
    f = C.forces_now(cm)[_body(cm, "palm_left")]
    hy = cm.rs.robot.hydro
    xmat = cm.mjd.xmat[_body(cm, "palm_left")].reshape(3, 3)
    e1, e2 = xmat[:, 0], xmat[:, 1]
    v1, v2 = U * e1[0], U * e2[0]
    F1 = -0.5 * RHO * hy.skin_friction * 2 * S_OPEN * abs(v1) * v1
    F2 = -0.5 * RHO * hy.plate_normal_drag * S_OPEN * abs(v2) * v2
    expected = F1 * e1 + F2 * e2
    assert f[:2] == pytest.approx(expected[:2], rel=1e-9, abs=1e-9)
    assert np.hypot(*f[:2]) > 1.0


def test_palm_drag_turning_about_the_ankle(robot):
    # only the ankle turns at omega: strip speed omega s, strip height s phi (fan of angle
    # phi = 2 S / l^2). Normal force 1/2 rho C_n phi omega^2 l^4 / 4, moment about the ankle
    # 1/2 rho C_n phi omega^2 l^5 / 5 (Gauss strips integrate both exactly)
    cm, w = robot, 2.5
    _still(cm)
    dof = cm.mjm.jnt_dofadr[mujoco.mj_name2id(cm.mjm, mujoco.mjtObj.mjOBJ_JOINT, "ankle_left")]
    cm.mjd.qvel[dof] = w
    b = _body(cm, "palm_left")
    f = C.forces_now(cm)[b]
    Cn, phi = cm.rs.robot.hydro.plate_normal_drag, 2 * S_OPEN / L_PALM ** 2
    xmat = cm.mjd.xmat[b].reshape(3, 3)
    e2 = xmat[:, 1]
    normal = float(f[:3] @ e2)
    assert abs(normal) == pytest.approx(0.5 * RHO * Cn * phi * w * w * L_PALM ** 4 / 4, rel=1e-9)
    # moment about the ankle (joint at the palm frame's origin): torque about the centre of mass
    # plus the lever of the force
    r = cm.mjd.xipos[b] - cm.mjd.xpos[b]
    tz = f[5] + np.cross(r, f[:3])[2]
    assert abs(tz) == pytest.approx(0.5 * RHO * Cn * phi * w * w * L_PALM ** 5 / 5, rel=1e-9)
    # and it resists the motion (the left ankle turns about +z)
    assert tz * w < 0


SPHEROID = """
<mujoco>
  <option timestep="{dt}" integrator="implicitfast" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="body">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="y" type="slide" axis="0 1 0"/>
      <joint name="yaw" type="hinge" axis="0 0 1"/>
      <inertial pos="0 0 0" mass="{m}" diaginertia="{ix} {iy} {iy}"/>
      <geom type="ellipsoid" size="{a} {b} {b}" contype="0" conaffinity="0" mass="0"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_coasting_spheroid_decays_as_closed_form():
    # a prolate spheroid (semi-axes a, b, b) coasting along its axis:
    #   (m + m_A) dv/dt = -k v^2,  k = 1/2 rho C pi b^2  ->  v = v0 / (1 + k v0 t / (m + m_A)),
    #   x = (m + m_A)/k ln(1 + k v0 t / (m + m_A)),   m_A = rho V alpha0 / (2 - alpha0) (Lamb art. 115)
    # Its sideways added mass is larger, so the engine carries the larger one in MuJoCo's mass
    # matrix and takes the difference back explicitly: this checks that split too.
    a, b, Cx, v0, T = 0.3, 0.1, 0.3, 1.5, 3.0
    V = 4 / 3 * math.pi * a * b * b
    m = RHO * V
    ix, iy = 0.4 * m * b * b, 0.2 * m * (a * a + b * b)
    xml = SPHEROID.format(dt=1e-3, m=m, ix=ix, iy=iy, a=a, b=b)
    row, s, k = hull_part(1, (a, b, b), m, (0, 0, 0), (ix, iy, iy), RHO, Cx, 0.6, 1.2, 6, 0.0)
    cm = C.build_bare(xml, (row[None], s[None], k[None], np.zeros((0, 4))), RHO, 9.81, T, 0.01)
    cm.mjd.qvel[0] = v0
    rec = C.run_coupled(cm)["rec"]
    e = math.sqrt(1 - (b / a) ** 2)
    alpha0 = 2 * (1 - e * e) / e ** 3 * (0.5 * math.log((1 + e) / (1 - e)) - e)
    M = m + RHO * V * alpha0 / (2 - alpha0)
    kd = 0.5 * RHO * Cx * math.pi * b * b
    t = rec[:, C.R_TIME]
    v = v0 / (1 + kd * v0 * t / M)
    x = M / kd * np.log(1 + kd * v0 * t / M)
    assert rec[:, C.R_V] == pytest.approx(v, rel=2e-3)
    assert rec[:, C.R_X] == pytest.approx(x, rel=2e-3, abs=1e-4)
    assert np.abs(rec[:, C.R_V + 1]).max() < 1e-9        # no sideways motion
    assert v[-1] < 0.8 * v0                               # it did slow down noticeably


def test_neutral_buoyancy_free_robot_neither_sinks_nor_floats():
    # ballast "neutral": weight = water displaced (Archimedes), so the centre of mass of an idle
    # robot free in 3-D keeps its depth; the ballast below the centre of buoyancy keeps it upright
    # (it pitches a little: the legs are slightly heavier than the water they displace)
    raw = frogsim.load_robot_scenario("swim").raw
    raw = frogsim.with_overrides(raw, {"robot.planar": False,
                                       "gait.drive": [{"at": "0 s", "state": "hold"}],
                                       "gait.palms": [{"at": "0 s", "state": "fold"}]})
    r = frogsim.swim(raw, cycles=1)
    m = r.model.mjm
    d = mujoco.MjData(m)
    c = r.model.columns["qpos"]
    com_z, tilt = [], []
    for row in r.rec:
        d.qpos[:] = row[c]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        com_z.append(d.subtree_com[1, 2])
        tilt.append(math.degrees(2 * math.acos(min(1.0, abs(d.qpos[3])))))
    assert np.ptp(com_z) < 0.01
    assert max(tilt) < 45.0


def test_the_idle_robots_pitch_in_3d_is_the_pages():
    """docs/robot.md: in 3-D the idle robot (legs held, palms folded, six seconds) pitches to X°
    after T1 s and back to Y° at T2 s: its tilt's first maximum and the minimum after it, at the
    page's precision."""
    import re
    from pathlib import Path
    page = " ".join((Path(__file__).resolve().parents[1] / "docs" / "robot.md").read_text().split())
    m = re.search(r"lightly damped swing: (\d+)° after (\d+\.\d) s, back to (\d+)° at (\d+\.\d) s", page)
    assert m, "docs/robot.md no longer gives the idle robot's pitch"
    raw = frogsim.load_robot_scenario("swim").raw
    raw = frogsim.with_overrides(raw, {"robot.planar": False,
                                       "gait.drive": [{"at": "0 s", "state": "hold"}],
                                       "gait.palms": [{"at": "0 s", "state": "fold"}]})
    r = frogsim.swim(raw, cycles=3)
    c = r.model.columns["qpos"]
    tilt = np.array([math.degrees(2 * math.acos(min(1.0, abs(row[c][3])))) for row in r.rec])
    t = np.asarray(r.t)
    i = int(np.argmax(tilt))
    j = i + int(np.argmin(tilt[i:]))
    assert [f"{tilt[i]:.0f}", f"{t[i]:.1f}", f"{tilt[j]:.0f}", f"{t[j]:.1f}"] == list(m.groups())
