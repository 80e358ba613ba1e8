"""The joints' end stops as elastomer pads (frogsim.physics.stop) and what they do to the thrust.

The bound on the thrust's jumps is Eq. (J) of frogsim.physics.stop (the most a pad's torque rises
between two samples: its damping at the impact speed plus its spring over one interval of
penetration) times the gain from a joint torque to the legs' added-mass force along the heading.
The gain is computed here from MuJoCo's own Jacobians and mass matrix (not from the engine's
force computation, which differences velocities): -h^T sum_p M_A,p J_p M^-1 e_j.
"""
import math

import mujoco
import numpy as np
import pytest

import frogsim
from frogsim.engine import coupled as C
from frogsim.engine.coupled_kernel import apply_added_mass
from frogsim.engine.swim import swim
from frogsim.physics.hydro import fan_added_mass
from frogsim.physics.stop import stop_torque, torque_jump
from frogsim.robot.water import E_BODY, E_FAN, E_IA, E_LIMB, E_MA, E_XA, P_PHI_FOLD, P_PHI_OPEN

K, CD = 13100.0, 55.0         # the hip's pad (params/fan2017.toml)


def test_stop_torque_is_zero_inside_the_range_and_a_spring_damper_past_either_end():
    assert stop_torque(0.3, 5.0, 0.0, 0.7, K, CD) == 0.0
    # 0.01 rad past the extended end, still entering at 0.5 rad/s: -(k delta + c w)
    assert stop_torque(0.71, 0.5, 0.0, 0.7, K, CD) == pytest.approx(-(K * 0.01 + CD * 0.5))
    # past the flexed end the pad pushes the other way
    assert stop_torque(-0.01, -0.5, 0.0, 0.7, K, CD) == pytest.approx(K * 0.01 + CD * 0.5)


def test_a_pad_pushes_but_never_pulls():
    # leaving the pad fast: spring 13.1 N m, damping -55 N m would pull the joint back in
    assert stop_torque(0.701, -1.0, 0.0, 0.7, K, CD) == 0.0
    assert stop_torque(-0.001, 1.0, 0.0, 0.7, K, CD) == 0.0


def test_a_stop_stores_the_pads_energy_k_delta_squared_over_two_without_damping():
    # a rigid body on the pad (no damping) comes back out at its impact speed: integrate
    # I w' = tau with a small step and check the rebound speed and the deepest penetration,
    # omega_0 sqrt(I / k) (energy: I w^2 / 2 = k delta^2 / 2)
    inertia, w0, dt = 2.5, 1.6, 1e-5
    q, w, deepest = 0.7, w0, 0.0
    for _ in range(200000):
        w += dt * stop_torque(q, w, 0.0, 0.7, K, 0.0) / inertia
        q += dt * w
        deepest = max(deepest, q - 0.7)
        if q < 0.7 and w < 0:
            break
    assert w == pytest.approx(-w0, rel=1e-3)
    assert deepest == pytest.approx(w0 * math.sqrt(inertia / K), rel=1e-3)


def _torque_to_thrust_gains(cm, qpos, palm_open):
    """d(thrust)/d(tau_j) for every leg joint j at a configuration: -h^T sum_p M_A,p J_p M^-1 e_j,
    with the added masses the engine puts into the model (isotropic m_iso, in M) and the parts'
    own anisotropic M_A (in the force)."""
    m = cm.mjm
    d = mujoco.MjData(m)
    a = cm.arrays
    el, pa = a["el"], a["pa"]
    frac = np.asarray(palm_open, float).copy()
    apply_added_mass(el, pa, frac, False, m.body_mass, m.body_ipos, m.body_inertia,
                     m.body_subtreemass, m.body_parentid)
    d.qpos[:] = qpos
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    Minv = np.linalg.inv(M)
    tb = int(a["sc"][C.S_TRUNK])
    h = d.xmat[tb].reshape(3, 3)[:, 0]
    total = np.zeros(m.nv)
    for e in range(el.shape[0]):
        if el[e, E_LIMB] < 0.5:
            continue
        b = int(el[e, E_BODY])
        p = int(el[e, E_FAN])
        phi = 1.0
        if p >= 0:
            phi = pa[p, P_PHI_FOLD] + frac[p] * (pa[p, P_PHI_OPEN] - pa[p, P_PHI_FOLD])
        m1, m2, m3, *_ = fan_added_mass(*el[e, E_MA:E_MA + 3], *el[e, E_IA:E_IA + 3], phi)
        R = d.xmat[b].reshape(3, 3)
        MA = R @ np.diag([m1, m2, m3]) @ R.T
        point = d.xpos[b] + R @ el[e, E_XA:E_XA + 3]
        jacp = np.zeros((3, m.nv))
        mujoco.mj_jac(m, d, jacp, None, point, b)
        total -= h @ MA @ jacp
    dofs = a["leg_dof"]
    return np.abs(total @ Minv[:, dofs])


@pytest.fixture(scope="module")
def swim_every_step():
    raw = frogsim.load_robot_scenario("swim").raw
    rs = frogsim.load_robot_scenario(frogsim.with_overrides(raw, {"output_interval": "1 ms"}),
                                     cycles=2)
    return swim(rs)


def test_no_thrust_sample_jumps_by_more_than_the_pads_allow(swim_every_step):
    r = swim_every_step
    cm = r.model
    h = float(np.diff(r.t)[0])
    assert h == pytest.approx(cm.dt)
    stops = cm.arrays["stops"]
    ang, w = r.joint_angles, r.joint_velocities
    outside = (ang > stops[:, C.STOP_UPPER]) | (ang < stops[:, C.STOP_LOWER])
    touch = outside[1:] & ~outside[:-1]                        # (interval, joint): touched a pad
    assert touch[:, 0].any() and touch[:, 1].any()             # hips and knees do hit their pads
    qcols = cm.columns["qpos"]
    jumps = np.abs(np.diff(r.thrust))
    # the bound of each touch: Eq. (J) at each touching joint's speed, times its gain, summed
    # over the joints touching in that interval (both legs at once); the pad's torque acts over
    # the step after the touch, whose force the record holds at that step's end, and the other
    # joints answer over the next few steps: the touch's bound holds for five intervals
    bound = np.zeros(jumps.size)
    for i in np.nonzero(touch.any(axis=1))[0]:
        gain = _torque_to_thrust_gains(cm, r.rec[i + 1, qcols], r.palm_opening[i + 1])
        b = sum(gain[j] * torque_jump(stops[j, C.STOP_K], stops[j, C.STOP_C], w[i + 1, j], h)
                for j in np.nonzero(touch[i])[0])
        bound[i:i + 5] = np.maximum(bound[i:i + 5], b)
    near = bound > 0.0
    # away from the touches the thrust changes by a few newtons per step at most (the stroke's
    # rise, 60 N in 0.25 s; the valves' switching); near one, by that and at most the pad's bound
    smooth = jumps[~near].max()
    assert smooth < 10.0
    assert np.all(jumps[near] <= bound[near] + smooth)
    # bounds that mean something: below the 174 N jump MuJoCo's 5 ms limit constraint made at the
    # hip's stop in this run (sample 0.732 s, measured before the pads replaced it)
    assert bound.max() < 174.0


def test_each_strokes_impulse_changes_by_less_than_the_pads_rebound_can_give(swim_every_step):
    # The pads take from a leg and its water the momentum they carry at impact, as the rigid stop
    # did: about 3.2 Ns along the heading at the hip stop of the first stroke (the thrust's
    # integral over 0.72-0.80 s with the rigid stop). What a pad adds is its rebound: it gives back
    # a share e of that momentum, e = exp(-pi zeta / sqrt(1 - zeta^2)) = 0.62 for the pads'
    # damping ratio 0.15 (loss factor 0.3), and throws the leg back from its stop just before the
    # valves switch to the recovery. A stroke's impulse can change by no more than e x 3.2 Ns.
    # 9.4495 and 3.3943 Ns: the first two strokes' impulses (trapezoid on every 1 ms step) with
    # MuJoCo's 5 ms limit constraint as the stops, measured before the pads replaced it.
    zeta = 0.5 * 0.3
    e = math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta * zeta))
    r = swim_every_step
    trap = np.trapezoid if hasattr(np, "trapezoid") else np.trapz
    for c, rigid in enumerate((9.4495, 3.3943)):
        m = (r.t >= 2.0 * c) & (r.t < 2.0 * (c + 1))
        assert abs(trap(r.thrust[m], r.t[m]) - rigid) < e * 3.2, c


def test_the_pages_stop_numbers_are_this_runs(swim_every_step):
    """docs/robot.md's figures for the pads, recomputed on the run above, at the precision the page
    writes them: the largest bound at a hip's touch (N) and that hip's speed (rad/s), the largest
    jump seen near a touch (N), the first stroke's impulse (Ns)."""
    import re
    from pathlib import Path
    page = (Path(__file__).resolve().parents[1] / "docs" / "robot.md").read_text()
    m = re.search(r"at most (\d+) N at the hips' touch \((\d+\.\d) rad/s\), (\d+) N seen", page)
    imp = re.search(r"The first stroke's impulse \(0–2 s\) is (\d+\.\d+) Ns", page)
    assert m and imp, "docs/robot.md no longer states the pads' figures this test reads"
    r = swim_every_step
    cm = r.model
    h = float(np.diff(r.t)[0])
    stops = cm.arrays["stops"]
    ang, w = r.joint_angles, r.joint_velocities
    outside = (ang > stops[:, C.STOP_UPPER]) | (ang < stops[:, C.STOP_LOWER])
    touch = outside[1:] & ~outside[:-1]
    qcols = cm.columns["qpos"]
    hips = [j for j, name in enumerate(cm.joint_names) if name.startswith("hip")]
    best = (0.0, 0.0)
    bound = np.zeros(len(r.t) - 1)
    for i in np.nonzero(touch.any(axis=1))[0]:
        gain = _torque_to_thrust_gains(cm, r.rec[i + 1, qcols], r.palm_opening[i + 1])
        b = sum(gain[j] * torque_jump(stops[j, C.STOP_K], stops[j, C.STOP_C], w[i + 1, j], h)
                for j in np.nonzero(touch[i])[0])
        bound[i:i + 5] = np.maximum(bound[i:i + 5], b)
        if any(touch[i, j] for j in hips) and b > best[0]:
            best = (b, max(abs(w[i + 1, j]) for j in hips if touch[i, j]))
    jumps = np.abs(np.diff(r.thrust))
    assert f"{best[0]:.0f}" == m.group(1) and f"{best[1]:.1f}" == m.group(2), (best, m.groups())
    assert f"{jumps[bound > 0].max():.0f}" == m.group(3), (jumps[bound > 0].max(), m.group(3))
    trap = np.trapezoid if hasattr(np, "trapezoid") else np.trapz
    first = r.t < 2.0
    assert f"{trap(r.thrust[first], r.t[first]):.2f}" == imp.group(1)


def test_the_pages_rebound_angles_are_this_runs(swim_every_step):
    """docs/robot.md: the pads' rebound throws the extended hip (and knee) back by the page's
    angles before the valves switch, in each of the first two strokes: from the joint's largest
    angle in the stroke's first second to its smallest after it, one decimal."""
    import re
    from pathlib import Path
    page = " ".join((Path(__file__).resolve().parents[1] / "docs" / "robot.md").read_text().split())
    m = re.search(r"throws the extended hip back by (\d+\.\d)° in each of the first two strokes \(the knee by "
                  r"(\d+\.\d)° and (\d+\.\d)°\)", page)
    assert m, "docs/robot.md no longer gives the rebound's angles"
    r = swim_every_step
    t = np.asarray(r.t)
    names = list(r.model.joint_names)
    for c in (0, 1):
        m_ = (t >= 2.0 * c) & (t < 2.0 * c + 1.0)
        for joint, want in (("hip_left", m.group(1)), ("knee_left", m.group(2 + c))):
            x = np.degrees(r.joint_angles[m_, names.index(joint)])
            i = int(np.argmax(x))
            assert f"{x[i] - x[i:].min():.1f}" == want, (c, joint, x[i] - x[i:].min())
