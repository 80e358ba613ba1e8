"""The coupled engine's compiled step: muscles on cranks, legs, palms, water, pneumatics.

Each MuJoCo step of length dt (``robot.timestep``) runs

    mj_step1 (positions, velocities, tendon lengths)  ->  step_kernel (one Numba call)  ->  mj_step2

and the kernel does, with the state at the start of the step:

1. muscle tensions from the muscle pressures at t and the tendon lengths MuJoCo reports
   (the actuator type's force, :mod:`frogsim.circuit.actuators`: for the McKibben muscle
   :func:`frogsim.physics.muscle_force.muscle_force`; with hysteresis on, less the slip
   elements' force, :func:`frogsim.physics.muscle_force.hysteretic_tension`, which slides their
   anchors: the memory is updated once per MuJoCo step, exactly, as the model is rate independent),
   written as actuator controls; the joints' end stops (:mod:`frogsim.physics.stop`), as joint
   torques and dof damping ("The stops" below);
2. the steering motors move the palms toward their commanded opening at their travel rate;
3. the water's forces on every part (:mod:`frogsim.physics.hydro`, :mod:`frogsim.robot.water`):
   strip drag, buoyancy and added mass, written to ``xfrc_applied``;
4. the pneumatics advanced from t to t + dt by the one stepping driver
   (:func:`frogsim.engine.integrator.advance`, with the scenario's integration method: by default
   adaptive Dormand-Prince, split at valve switching times and controller samples), each muscle's
   length following a cubic Hermite path that starts
   where the previous step's path ended (value and slope) and ends at MuJoCo's length plus
   velocity x dt: the muscle's volume (Eq. (5)) and its force come from the same length.

Added mass. An added-mass force -m_A a taken from the last step's acceleration is unstable when
m_A exceeds the part's own mass, as it does for the palms (about 3 kg of water for 0.3 kg of palm).
So the added mass enters MuJoCo's mass matrix: each part's body gets an extra mass
m_iso = max_j m_j (:func:`frogsim.physics.hydro.isotropic_added_mass`) at the centre of its added
mass, and its added inertia I_A (``body_mass``, ``body_ipos``, ``body_inertia`` are changed at run
time; for the palms at every step, as they open and fold: :func:`apply_added_mass`). The excess
(m_iso - m_j) in the directions where the water adds less is taken back by an explicit force
(m_iso - m_j) a_j, a_j the part's acceleration over the last step: that iteration contracts
(factor (m_iso - m_j)/(m + m_iso) < 1), so it is stable, and converges to the true
(m + m_j) a_j = F. The velocity terms of Kirchhoff's equations
(:func:`frogsim.physics.hydro.kirchhoff_velocity_force`, :func:`frogsim.physics.hydro.munk_moment`)
and the change of an opening palm's added mass, -dM_A/dt v and -dI_A/dt omega
(:func:`frogsim.physics.hydro.added_mass_rate_force`), are applied as forces. The weight MuJoCo
gives the extra mass is cancelled by an equal upward force at the same point.

The record. The thrust and hull force recorded at t_k are the water's forces over the step that
ended there, [t_k-1, t_k], all of them from that one step: its drag and velocity terms (computed
at t_k-1, kept in st[T_LAST_*]) and its -M_A a, with the added masses and axes of that step
(vprev[e, V_MA]) and its acceleration, (v_k - v_k-1) / dt, known only once MuJoCo has taken the
step. Before, a record took the drag and velocity terms of the step starting at t_k but -M_A a of
the step before it: wherever a force changed at once (a palm's motor reaching its end, where
-dM_A/dt v stops; a joint touching its stop) the record showed the change one step before the
water's answer to it, a one-sample dip of up to 35 N that the next sample took back. At t = 0 the
record holds the first step's forces without acceleration (the robot starts at rest).

The stops. A joint past either end of its range meets an elastomer pad, a one-sided spring and
damper (:mod:`frogsim.physics.stop`): the spring, from the joint's angle at t, is written to
``qfrc_applied``; the pad's damping is added to the joint's ``dof_damping``, which MuJoCo's
implicitfast integrator takes at the step's end velocity (an explicit damping would overshoot
on the light distal segments in air). mj_step1 has already applied -dof_damping v with the last
step's coefficient; ``qfrc_applied`` makes up the difference (the same step as a model damped so
from the start, bit for bit). The stop used to be MuJoCo's limit constraint with a 5 ms time
constant: it stopped a swimming leg, with about 2.5 kg m^2 of leg and water about the hip, in a
few milliseconds, and the legs' added-mass reaction -M_A a made a -100 to -175 N thrust step at
every hip stop (the added mass was right: the constraint solver saw it in the mass matrix; the
stop was too stiff for a real one). A pad of a real stiffness takes tens of milliseconds for the
same momentum; :mod:`frogsim.physics.stop` bounds the jump it can make.

Every step checks the state: a non-finite position or velocity, a leg joint faster than
``sc[S_WMAX]`` or a hull faster than ``sc[S_VMAX]`` stops the run with a FAIL_* code that
:mod:`frogsim.engine.coupled` turns into a message.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from frogsim._jit import jit
from frogsim.circuit import layout as CL
from frogsim.circuit.actuators import actuator_force
from frogsim.control.sampled import CS_PUMP, observe_joints
from frogsim.engine.coupled_layout import (
    FAIL_BODY_SPEED, FAIL_JOINT_SPEED, FAIL_PNEUMATIC, FAIL_QPOS, FAIL_QVEL, R_AIR, R_CHARGED,
    R_EXERGY, R_HULL, R_PE, R_PS, R_PUMP_ON, R_PUMPED, R_THRUST, R_THRUST_AM, R_TIME, R_V,
    R_X, R_YAW, STOP_C, STOP_DAMPING, STOP_K, STOP_LOWER, STOP_UPPER, S_CTRL_DT, S_DT,
    S_G, S_LAW, S_MAXSTEP, S_METHOD, S_RHO, S_RTOL, S_TRUNK, S_VMAX, S_WMAX, T_EXERGY, T_FAIL, T_FAIL_ARG, T_FAIL_VAL, T_FIRST, T_LAST_HEADING, T_LAST_HULL,
    T_LAST_THRUST, T_LAST_THRUST_AM, T_PALM_CMD, T_PALM_TARGET, T_PEAK, T_PEAK_TIME, U_ACT,
    U_FITTINGS, U_TENDON, V_MA, V_VEL, rec_angle, rec_charged, rec_length, rec_omega, rec_palm,
    rec_pressure, rec_qpos, rec_tension, rec_valve)
from frogsim.engine.integrator import D_REUSE_F, advance
from frogsim.engine.methods.spec import PAR_SIZE
from frogsim.physics.hydro import (added_mass_rate_force, buoyancy, cross, fan_added_mass,
                                   isotropic_added_mass, kirchhoff_velocity_force, munk_moment,
                                   strip_drag_wrench)
from frogsim.physics.muscle_force import hysteretic_tension
from frogsim.physics.stop import pad_spring_and_damping
from frogsim.robot.water import (E_BODY, E_C0, E_FAN, E_HEAVE, E_I0, E_IA, E_LIMB, E_M0, E_MA,
                                 E_VOL, E_XA, E_XB, P_PHI_FOLD, P_PHI_OPEN, P_RATE)


@jit
def _fan_angle(pa, p, frac):
    """Fan angle [rad] of palm p at opening fraction frac (0 folded, 1 open)."""
    return pa[p, P_PHI_FOLD] + frac * (pa[p, P_PHI_OPEN] - pa[p, P_PHI_FOLD])


@jit
def _part_added_mass(el, e, pa, frac):
    """(m1, m2, m3, I1, I2, I3, m_iso) of element e, a palm at its opening in frac."""
    phi = 1.0
    p = int(el[e, E_FAN])
    if p >= 0:
        phi = _fan_angle(pa, p, frac[p])
    m1, m2, m3, i1, i2, i3 = fan_added_mass(el[e, E_MA], el[e, E_MA + 1], el[e, E_MA + 2],
                                            el[e, E_IA], el[e, E_IA + 1], el[e, E_IA + 2], phi)
    return m1, m2, m3, i1, i2, i3, isotropic_added_mass(m1, m2, m3, el[e, E_HEAVE] > 0.5)


@jit
def apply_added_mass(el, pa, frac, only_palms, body_mass, body_ipos, body_inertia,
                     body_subtreemass, body_parentid):
    """Put each part's isotropic added mass m_iso and added inertia into its MuJoCo body.

    Body mass m0 + m_iso at the joint centre of mass; inertia about it = own + added + the
    parallel-axis terms of both (the two centres lie on one axis of the part's frame, so the
    inertia stays diagonal in it). Then the subtree masses MuJoCo uses for centres of mass.
    """
    for e in range(el.shape[0]):
        if only_palms and el[e, E_FAN] < 0.0:
            continue
        b = int(el[e, E_BODY])
        m1, m2, m3, i1, i2, i3, miso = _part_added_mass(el, e, pa, frac)
        m0 = el[e, E_M0]
        M = m0 + miso
        for k in range(3):
            body_ipos[b, k] = (m0 * el[e, E_C0 + k] + miso * el[e, E_XA + k]) / M
        d0x = el[e, E_C0] - body_ipos[b, 0]
        d0y = el[e, E_C0 + 1] - body_ipos[b, 1]
        d0z = el[e, E_C0 + 2] - body_ipos[b, 2]
        dax = el[e, E_XA] - body_ipos[b, 0]
        day = el[e, E_XA + 1] - body_ipos[b, 1]
        daz = el[e, E_XA + 2] - body_ipos[b, 2]
        body_inertia[b, 0] = el[e, E_I0] + i1 + m0 * (d0y * d0y + d0z * d0z) + miso * (day * day + daz * daz)
        body_inertia[b, 1] = el[e, E_I0 + 1] + i2 + m0 * (d0x * d0x + d0z * d0z) + miso * (dax * dax + daz * daz)
        body_inertia[b, 2] = el[e, E_I0 + 2] + i3 + m0 * (d0x * d0x + d0y * d0y) + miso * (dax * dax + day * day)
        body_mass[b] = M
    nb = body_mass.size
    for b in range(nb):
        body_subtreemass[b] = body_mass[b]
    for b in range(nb - 1, 0, -1):
        body_subtreemass[body_parentid[b]] += body_subtreemass[b]


# --- step_kernel's arguments: one list, its groups named ---------------------------------------------
#: The arrays step_kernel takes after (k, stepping, row), in groups: (the group's class name, its
#: parameter name in step_kernel, its members). The one place that orders them: the groups are
#: named tuples made from this list (step_kernel reads their members by name), and
#: :func:`step_kernel_loose` (its parameters and the groups it makes) and
#: :func:`frogsim.engine.coupled.kernel_args` are made from it. The members are the names of
#: ``CoupledModel.arrays`` (MuJoCo's: of its model or data, :func:`frogsim.engine.coupled.kernel_args`),
#: except ``circuit``: the right-hand side's model tuple (g, mp, mot_t, mot_L, mot_d, mot_n), which
#: goes to :func:`frogsim.engine.integrator.advance` as its ``model`` (a plain tuple, the type the
#: pneumatic engine passes, so that the driver is compiled once for both engines).
CIRCUIT = CL.MODEL_GROUP
KERNEL_GROUPS = (
    ("Records", "records", ("sc", "st", "rec")),
    ("Water", "water", ("el", "strip_s", "strip_k", "pa", "vprev")),
    ("Body", "body", ("pal_t", "pal_target", "frac", "frac_new", "leg_qpos", "leg_dof", "stops")),
    ("Muscles", "muscles", ("mu", "tension", "anchors", "slip_k", "slip_f")),
    ("Pneumatics", "pneumatics", ("y", "u", "ds", "cs", "circuit", "sched_t", "sched_u", "laws", "atol", "stats")),
    ("MuJoCo", "mujoco", ("ten_length", "ten_velocity", "xpos", "xmat", "xipos", "cvel", "subtree_com",
                          "body_rootid", "body_parentid", "body_mass", "body_ipos", "body_inertia",
                          "body_subtreemass", "ctrl", "xfrc", "qpos", "qvel", "qfrc", "dof_damping")),
)
Records = namedtuple("Records", KERNEL_GROUPS[0][2])
Water = namedtuple("Water", KERNEL_GROUPS[1][2])
Body = namedtuple("Body", KERNEL_GROUPS[2][2])
Muscles = namedtuple("Muscles", KERNEL_GROUPS[3][2])
Pneumatics = namedtuple("Pneumatics", KERNEL_GROUPS[4][2])
MuJoCo = namedtuple("MuJoCo", KERNEL_GROUPS[5][2])
#: the group classes, in KERNEL_GROUPS' order (module-level names: Numba's cache finds them by name)
GROUP_CLASSES = (Records, Water, Body, Muscles, Pneumatics, MuJoCo)
assert tuple(c.__name__ for c in GROUP_CLASSES) == tuple(name for name, _, _ in KERNEL_GROUPS)


def loose_names() -> tuple:
    """step_kernel_loose's parameters after (k, stepping, row): every group's members in order,
    ``circuit`` as its six arrays."""
    return tuple(a for _, _, members in KERNEL_GROUPS for m in members
                 for a in (CIRCUIT if m == "circuit" else (m,)))


@jit
def step_kernel(k, stepping, row, records, water, body, muscles, pneumatics, mujoco):
    """One coupled step at t = k dt (see the module docstring). Returns 0, or a FAIL_* code.

    ``stepping`` = 0 only checks, computes forces and records (the last row of a run).
    ``row`` >= 0 records the state at t into rec[row]. The arrays come in groups, each a named
    tuple of :data:`KERNEL_GROUPS` whose members are read by name here
    (:func:`frogsim.engine.coupled.kernel_args`):

    * ``records``: the constants sc (S_*), the kernel's state st (T_*) and the record rec (R_*);
    * ``water``: the parts in the water (el, strip_s, strip_k, pa: :mod:`frogsim.robot.water`) and
      each part's velocity at the last step (vprev);
    * ``body``: palms' command times and targets (pal_t, pal_target), their openings now and after
      the step (frac, frac_new), the leg joints' qpos and dof addresses (leg_qpos, leg_dof) and
      their end stops (stops: STOP_*);
    * ``muscles``: the muscle table (mu: U_*), the muscles' tensions, and their hysteresis: the
      slip elements' anchors (n, N: the memory), stiffness and slip per pascal (N each); N = 0
      for a force law without memory (:func:`frogsim.physics.hysteresis.muscle_hysteresis_force`);
    * ``pneumatics``, as :func:`frogsim.engine.integrator.advance` takes them: state y, valve
      states u, driver and controller states ds and cs, the circuit (g, mp and the muscles'
      length paths mot_*: advance's ``model`` tuple), schedule (sched_t, sched_u), sampled rules
      (laws), atol, stats;
    * ``mujoco``: MuJoCo's arrays (ten_length, ten_velocity, xpos, xmat, xipos, cvel, subtree_com,
      body_rootid, body_parentid, body_mass, body_ipos, body_inertia, body_subtreemass, ctrl,
      xfrc_applied, qpos, qvel, qfrc_applied, dof_damping).

    The compiled loop (:func:`frogsim.engine.coupled_loop.run_steps`) passes the groups on from
    compiled code, at no cost per step. Python calls :func:`step_kernel_loose` instead: Numba's
    dispatcher unboxes tuples of arrays far slower than loose arrays (about 8,600 more
    instructions a call for these 48 arrays, measured with callgrind).
    """
    sc, st, rec = records.sc, records.st, records.rec
    el, strip_s, strip_k, pa, vprev = water.el, water.strip_s, water.strip_k, water.pa, water.vprev
    pal_t, pal_target, frac, frac_new = body.pal_t, body.pal_target, body.frac, body.frac_new
    leg_qpos, leg_dof, stops = body.leg_qpos, body.leg_dof, body.stops
    mu, tension, anchors, slip_k, slip_f = muscles.mu, muscles.tension, muscles.anchors, muscles.slip_k, muscles.slip_f
    y, u, ds, cs, circuit = pneumatics.y, pneumatics.u, pneumatics.ds, pneumatics.cs, pneumatics.circuit
    sched_t, sched_u, laws, atol, stats = (pneumatics.sched_t, pneumatics.sched_u, pneumatics.laws, pneumatics.atol,
                                           pneumatics.stats)
    g, mp, mot_t, mot_L, mot_d, mot_n = circuit          # advance's model tuple (CIRCUIT)
    ten_length, ten_velocity, xpos, xmat, xipos = (mujoco.ten_length, mujoco.ten_velocity, mujoco.xpos, mujoco.xmat,
                                                   mujoco.xipos)
    cvel, subtree_com = mujoco.cvel, mujoco.subtree_com
    body_rootid, body_parentid = mujoco.body_rootid, mujoco.body_parentid
    body_mass, body_ipos, body_inertia, body_subtreemass = (mujoco.body_mass, mujoco.body_ipos, mujoco.body_inertia,
                                                            mujoco.body_subtreemass)
    ctrl, xfrc, qpos, qvel, qfrc, dof_damping = (mujoco.ctrl, mujoco.xfrc, mujoco.qpos, mujoco.qvel, mujoco.qfrc,
                                                 mujoco.dof_damping)
    dt = sc[S_DT]
    t = k * dt
    n = mu.shape[0]
    nj = leg_qpos.size
    # -- 0. is the state MuJoCo produced still sane? --------------------------------------------
    for j in range(qpos.size):
        if not math.isfinite(qpos[j]):
            st[T_FAIL], st[T_FAIL_ARG], st[T_FAIL_VAL] = FAIL_QPOS, j, qpos[j]
            return FAIL_QPOS
    for j in range(qvel.size):
        if not math.isfinite(qvel[j]):
            st[T_FAIL], st[T_FAIL_ARG], st[T_FAIL_VAL] = FAIL_QVEL, j, qvel[j]
            return FAIL_QVEL
    for j in range(nj):
        w = qvel[leg_dof[j]]
        if abs(w) > sc[S_WMAX]:
            st[T_FAIL], st[T_FAIL_ARG], st[T_FAIL_VAL] = FAIL_JOINT_SPEED, j, w
            return FAIL_JOINT_SPEED
    tb = int(sc[S_TRUNK])
    root = body_rootid[tb]
    wx, wy, wz = cvel[tb, 0], cvel[tb, 1], cvel[tb, 2]
    cx, cy, cz = cross(wx, wy, wz, xpos[tb, 0] - subtree_com[root, 0],
                       xpos[tb, 1] - subtree_com[root, 1], xpos[tb, 2] - subtree_com[root, 2])
    vbx, vby, vbz = cvel[tb, 3] + cx, cvel[tb, 4] + cy, cvel[tb, 5] + cz
    speed = math.sqrt(vbx * vbx + vby * vby + vbz * vbz)
    if speed > sc[S_VMAX]:
        st[T_FAIL], st[T_FAIL_ARG], st[T_FAIL_VAL] = FAIL_BODY_SPEED, 0, speed
        return FAIL_BODY_SPEED
    # -- 1. muscle tensions from the pressures at t ------------------------------------------------
    patm = g[CL.G_PATM]
    elements = anchors.shape[1]
    for i in range(n):
        L = ten_length[int(mu[i, U_TENDON])] - mu[i, U_FITTINGS]
        # the muscle's actuator type's force (frogsim.circuit.actuators), its force law at sc[S_LAW:]
        tension[i] = actuator_force(mp[i, CL.M_ACT], mp, i, y[CL.pressure_index(i)] - patm, L, sc, S_LAW)
        if elements > 0:
            tension[i] = hysteretic_tension(tension[i], y[CL.pressure_index(i)] - patm,
                                            1.0 - L / mp[i, CL.M_L0], anchors[i], slip_k, slip_f)
        ctrl[int(mu[i, U_ACT])] = tension[i]
    # -- 1b. the joints' end stops (elastomer pads): the spring as a joint torque, the damping as
    # MuJoCo's dof damping, which its implicitfast integrator takes at the step's end velocity.
    # mj_step1 has already applied -dof_damping v with the coefficient left by the last step:
    # the joint torque makes up the difference, so that the force is -(damping + pad) v at once.
    for j in range(nj):
        dof = leg_dof[j]
        w = qvel[dof]
        spring, pad = pad_spring_and_damping(qpos[leg_qpos[j]], w, stops[j, STOP_LOWER],
                                             stops[j, STOP_UPPER], stops[j, STOP_K], stops[j, STOP_C])
        c_new = stops[j, STOP_DAMPING] + pad
        qfrc[dof] = spring - (c_new - dof_damping[dof]) * w
        if stepping != 0:
            dof_damping[dof] = c_new
    # -- 2. palms: commands on the controller grid, motors at their travel rate ----------------------
    npal = pa.shape[0]
    while int(st[T_PALM_CMD]) < pal_t.size and pal_t[int(st[T_PALM_CMD])] <= t + 1e-12:
        st[T_PALM_TARGET] = pal_target[int(st[T_PALM_CMD])]
        st[T_PALM_CMD] += 1.0
    for p in range(npal):
        step = pa[p, P_RATE] * dt
        d = st[T_PALM_TARGET] - frac[p]
        frac_new[p] = frac[p] + (d if abs(d) <= step else math.copysign(step, d))
        if stepping == 0:
            frac_new[p] = frac[p]
    # -- 3. water ------------------------------------------------------------------------------------
    rho = sc[S_RHO]
    grav = sc[S_G]
    hx, hy, hz = xmat[tb, 0], xmat[tb, 3], xmat[tb, 6]          # heading: the hull's x axis
    # the record's forces (module docstring, "The record"): this step's drag and velocity terms
    # along this step's heading, and the last step's -M_A a along the last step's heading
    thrust = 0.0
    thrust_am = 0.0
    hull = 0.0
    inert_limb = 0.0
    inert_hull = 0.0
    first = st[T_FIRST] > 0.5
    if first:
        px_, py_, pz_ = hx, hy, hz
    else:
        px_, py_, pz_ = st[T_LAST_HEADING], st[T_LAST_HEADING + 1], st[T_LAST_HEADING + 2]
    for e in range(el.shape[0]):
        b = int(el[e, E_BODY])
        xfrc[b, 0] = 0.0
        xfrc[b, 1] = 0.0
        xfrc[b, 2] = 0.0
        xfrc[b, 3] = 0.0
        xfrc[b, 4] = 0.0
        xfrc[b, 5] = 0.0
    for e in range(el.shape[0]):
        b = int(el[e, E_BODY])
        r = body_rootid[b]
        ox, oy, oz = xpos[b, 0], xpos[b, 1], xpos[b, 2]
        e1x, e1y, e1z = xmat[b, 0], xmat[b, 3], xmat[b, 6]
        e2x, e2y, e2z = xmat[b, 1], xmat[b, 4], xmat[b, 7]
        e3x, e3y, e3z = xmat[b, 2], xmat[b, 5], xmat[b, 8]
        wx, wy, wz = cvel[b, 0], cvel[b, 1], cvel[b, 2]
        lx, ly, lz = cvel[b, 3], cvel[b, 4], cvel[b, 5]
        comx, comy, comz = subtree_com[r, 0], subtree_com[r, 1], subtree_com[r, 2]
        gx, gy, gz = xipos[b, 0], xipos[b, 1], xipos[b, 2]
        fan = int(el[e, E_FAN])
        kscale = 1.0
        if fan >= 0:
            kscale = _fan_angle(pa, fan, frac[fan])
        # strip drag, Eq. (D); cvel's linear part is the velocity at the root's subtree centre
        Fx, Fy, Fz, Tx, Ty, Tz = strip_drag_wrench(
            strip_s[e], strip_k[e], kscale, (ox, oy, oz), (e1x, e1y, e1z), (e2x, e2y, e2z),
            (e3x, e3y, e3z), (wx, wy, wz), (lx, ly, lz), (comx, comy, comz), (gx, gy, gz))
        drag_h = Fx * hx + Fy * hy + Fz * hz
        # added mass (module docstring): explicit part at the added-mass centre
        m1, m2, m3, i1, i2, i3, miso = _part_added_mass(el, e, pa, frac)
        n1, n2, n3, j1, j2, j3 = m1, m2, m3, i1, i2, i3          # a part of fixed shape
        if fan >= 0:
            n1, n2, n3, j1, j2, j3, _ = _part_added_mass(el, e, pa, frac_new)
        ax_, ay_, az_ = el[e, E_XA], el[e, E_XA + 1], el[e, E_XA + 2]
        qx = ox + e1x * ax_ + e2x * ay_ + e3x * az_
        qy = oy + e1y * ax_ + e2y * ay_ + e3y * az_
        qz = oz + e1z * ax_ + e2z * ay_ + e3z * az_
        cx, cy, cz = cross(wx, wy, wz, qx - comx, qy - comy, qz - comz)
        vx, vy, vz = lx + cx, ly + cy, lz + cz
        if first:
            acx, acy, acz = 0.0, 0.0, 0.0
        else:
            acx = (vx - vprev[e, V_VEL]) / dt
            acy = (vy - vprev[e, V_VEL + 1]) / dt
            acz = (vz - vprev[e, V_VEL + 2]) / dt
            # the last step's -M_A a: its added masses and axes, the acceleration over it
            fix = -(vprev[e, V_MA] * acx + vprev[e, V_MA + 3] * acy + vprev[e, V_MA + 4] * acz)
            fiy = -(vprev[e, V_MA + 3] * acx + vprev[e, V_MA + 1] * acy + vprev[e, V_MA + 5] * acz)
            fiz = -(vprev[e, V_MA + 4] * acx + vprev[e, V_MA + 5] * acy + vprev[e, V_MA + 2] * acz)
            if el[e, E_LIMB] > 0.5:
                inert_limb += fix * px_ + fiy * py_ + fiz * pz_
            else:
                inert_hull += fix * px_ + fiy * py_ + fiz * pz_
        if stepping != 0:
            vprev[e, V_VEL], vprev[e, V_VEL + 1], vprev[e, V_VEL + 2] = vx, vy, vz
            vprev[e, V_MA] = m1 * e1x * e1x + m2 * e2x * e2x + m3 * e3x * e3x
            vprev[e, V_MA + 1] = m1 * e1y * e1y + m2 * e2y * e2y + m3 * e3y * e3y
            vprev[e, V_MA + 2] = m1 * e1z * e1z + m2 * e2z * e2z + m3 * e3z * e3z
            vprev[e, V_MA + 3] = m1 * e1x * e1y + m2 * e2x * e2y + m3 * e3x * e3y
            vprev[e, V_MA + 4] = m1 * e1x * e1z + m2 * e2x * e2z + m3 * e3x * e3z
            vprev[e, V_MA + 5] = m1 * e1y * e1z + m2 * e2y * e2z + m3 * e3y * e3z
        v1 = e1x * vx + e1y * vy + e1z * vz
        v2 = e2x * vx + e2y * vy + e2z * vz
        v3 = e3x * vx + e3y * vy + e3z * vz
        a1 = e1x * acx + e1y * acy + e1z * acz
        a2 = e2x * acx + e2y * acy + e2z * acz
        a3 = e3x * acx + e3y * acy + e3z * acz
        w1 = e1x * wx + e1y * wy + e1z * wz
        w2 = e2x * wx + e2y * wy + e2z * wz
        w3 = e3x * wx + e3y * wy + e3z * wz
        k1, k2, k3 = kirchhoff_velocity_force(m1, m2, m3, w1, w2, w3, v1, v2, v3)
        vel1 = k1 + added_mass_rate_force(m1, n1, dt, v1)
        vel2 = k2 + added_mass_rate_force(m2, n2, dt, v2)
        vel3 = k3 + added_mass_rate_force(m3, n3, dt, v3)
        g1 = (miso - m1) * a1 + vel1                                   # applied (explicit) part
        g2 = (miso - m2) * a2 + vel2
        g3 = (miso - m3) * a3 + vel3
        am1, am2, am3 = vel1, vel2, vel3               # added-mass force less -M_A a (recorded apart)
        mu1, mu2, mu3 = munk_moment(m1, m2, m3, v1, v2, v3)
        mu1 += added_mass_rate_force(i1, j1, dt, w1)
        mu2 += added_mass_rate_force(i2, j2, dt, w2)
        mu3 += added_mass_rate_force(i3, j3, dt, w3)
        fx = g1 * e1x + g2 * e2x + g3 * e3x
        fy = g1 * e1y + g2 * e2y + g3 * e3y
        fz = g1 * e1z + g2 * e2z + g3 * e3z + miso * grav          # cancel the extra mass's weight
        Fx += fx
        Fy += fy
        Fz += fz
        tx, ty, tz = cross(qx - gx, qy - gy, qz - gz, fx, fy, fz)
        Tx += tx + mu1 * e1x + mu2 * e2x + mu3 * e3x
        Ty += ty + mu1 * e1y + mu2 * e2y + mu3 * e3y
        Tz += tz + mu1 * e1z + mu2 * e2z + mu3 * e3z
        am_h = ((am1 * e1x + am2 * e2x + am3 * e3x) * hx + (am1 * e1y + am2 * e2y + am3 * e3y) * hy
                + (am1 * e1z + am2 * e2z + am3 * e3z) * hz)
        # buoyancy at the centre of the displaced volume
        bx_, by_, bz_ = el[e, E_XB], el[e, E_XB + 1], el[e, E_XB + 2]
        fb = buoyancy(rho, grav, el[e, E_VOL])
        tx, ty, tz = cross(ox + e1x * bx_ + e2x * by_ + e3x * bz_ - gx,
                           oy + e1y * bx_ + e2y * by_ + e3y * bz_ - gy,
                           oz + e1z * bx_ + e2z * by_ + e3z * bz_ - gz, 0.0, 0.0, fb)
        Fz += fb
        Tx += tx
        Ty += ty
        Tz += tz
        xfrc[b, 0] += Fx
        xfrc[b, 1] += Fy
        xfrc[b, 2] += Fz
        xfrc[b, 3] += Tx
        xfrc[b, 4] += Ty
        xfrc[b, 5] += Tz
        if el[e, E_LIMB] > 0.5:
            thrust += drag_h + am_h
            thrust_am += am_h
        else:
            hull += drag_h + am_h
    if first:                   # t = 0: this step's forces, at rest (no acceleration yet)
        thrust_rec, thrust_am_rec, hull_rec = thrust, thrust_am, hull
    else:                       # the last step's forces, all of them
        thrust_rec = st[T_LAST_THRUST] + inert_limb
        thrust_am_rec = st[T_LAST_THRUST_AM] + inert_limb
        hull_rec = st[T_LAST_HULL] + inert_hull
    if stepping != 0:
        st[T_FIRST] = 0.0
        st[T_LAST_THRUST], st[T_LAST_THRUST_AM], st[T_LAST_HULL] = thrust, thrust_am, hull
        st[T_LAST_HEADING], st[T_LAST_HEADING + 1], st[T_LAST_HEADING + 2] = hx, hy, hz
    if thrust_rec > st[T_PEAK]:
        st[T_PEAK] = thrust_rec
        st[T_PEAK_TIME] = t
    # -- 4. record the state at t -------------------------------------------------------------------
    if row >= 0:
        rr = rec[row]
        rr[R_TIME] = t
        rr[R_X], rr[R_X + 1], rr[R_X + 2] = xpos[tb, 0], xpos[tb, 1], xpos[tb, 2]
        rr[R_YAW] = math.atan2(xmat[tb, 3], xmat[tb, 0])
        rr[R_V], rr[R_V + 1], rr[R_V + 2] = vbx, vby, vbz
        rr[R_THRUST] = thrust_rec
        rr[R_THRUST_AM] = thrust_am_rec
        rr[R_HULL] = hull_rec
        rr[R_PS] = y[CL.Y_PS]
        rr[R_PE] = y[CL.Y_PE]
        q = 0.0
        air = y[CL.Y_MS] + y[CL.Y_ME]
        for i in range(n):
            q += y[CL.charged_index(i, n)]
            air += y[CL.mass_index(i)]
        rr[R_CHARGED] = q
        rr[R_PUMPED] = y[CL.pump_index(n)]
        rr[R_AIR] = air
        rr[R_EXERGY] = st[T_EXERGY]
        rr[R_PUMP_ON] = cs[CS_PUMP]
        for i in range(n):
            rr[rec_pressure(i, n)] = y[CL.pressure_index(i)]
            rr[rec_length(i, n)] = ten_length[int(mu[i, U_TENDON])] - mu[i, U_FITTINGS]
            rr[rec_tension(i, n)] = tension[i]
            rr[rec_charged(i, n)] = y[CL.charged_index(i, n)]
            rr[rec_valve(i, n, CL.VALVE_CHARGE)] = u[CL.charge_valve(i)]
            rr[rec_valve(i, n, CL.VALVE_VENT)] = u[CL.vent_valve(i)]
        for p in range(npal):
            rr[rec_palm(p, n)] = frac[p]
        for j in range(nj):
            rr[rec_angle(j, n, npal)] = qpos[leg_qpos[j]]
            rr[rec_omega(j, n, npal, nj)] = qvel[leg_dof[j]]
        for j in range(qpos.size):
            rr[rec_qpos(j, n, npal, nj)] = qpos[j]
    if stepping == 0:
        return 0
    # -- 5. pneumatics from t to t + dt, muscle lengths following MuJoCo's -----------------------------
    t_end = (k + 1) * dt
    for i in range(n):
        tid = int(mu[i, U_TENDON])
        L = ten_length[tid] - mu[i, U_FITTINGS]
        v = ten_velocity[tid]
        if first:
            Ls, slope = L, v
        else:
            Ls, slope = mot_L[i, 2], mot_d[i, 2]
        mot_t[i, 0], mot_L[i, 0], mot_d[i, 0] = t - dt, Ls - slope * dt, slope
        mot_t[i, 1], mot_L[i, 1], mot_d[i, 1] = t, Ls, slope
        mot_t[i, 2], mot_L[i, 2], mot_d[i, 2] = t_end, L + v * dt, v
        mot_t[i, 3], mot_L[i, 3], mot_d[i, 3] = t_end + dt, L + 2.0 * v * dt, v
        mot_n[i] = 4
    q0 = 0.0
    for i in range(n):
        q0 += y[CL.charged_index(i, n)]
    ps0 = y[CL.Y_PS]
    no_output = (y[:0], mot_t[:0], mot_t[:0])         # no output rows: empty views, no allocation
    observe_joints(laws, cs, qpos, qvel, leg_qpos, leg_dof)     # what joint-angle laws read
    # the new length paths start with the old ones' value and slope: dy/dt at t is the one the
    # last step ended with (up to the rounding of the slope), so the driver starts from it
    ds[D_REUSE_F] = 1.0
    status = advance(t_end, y, u, ds, cs, circuit, (sched_t, sched_u, laws, sc[S_CTRL_DT]),
                     (sc[S_RTOL], atol, sc[S_MAXSTEP], sc[S_METHOD:S_METHOD + PAR_SIZE]), no_output, stats)
    if status != 0:
        st[T_FAIL], st[T_FAIL_ARG], st[T_FAIL_VAL] = FAIL_PNEUMATIC, status, t
        return FAIL_PNEUMATIC
    q1 = 0.0
    for i in range(n):
        q1 += y[CL.charged_index(i, n)]
    if ps0 > patm:
        st[T_EXERGY] += (q1 - q0) * g[CL.G_R] * g[CL.G_TAMB] * math.log(ps0 / patm)
    # -- 6. palms' added mass for the next step (after the first step, only when a palm moved: the
    # model holds the values for the present openings already) ------------------------------------------
    moved = first
    for p in range(npal):
        moved |= frac_new[p] != frac[p]
        frac[p] = frac_new[p]
    if moved:
        apply_added_mass(el, pa, frac, np.bool_(True), body_mass, body_ipos, body_inertia,
                         body_subtreemass, body_parentid)
    return 0


def _loose_source() -> str:
    """The source of :func:`step_kernel_loose`, made from KERNEL_GROUPS."""
    groups = ", ".join(
        f"{cls}(" + ", ".join(f"({', '.join(CIRCUIT)})" if m == "circuit" else m for m in members) + ")"
        for cls, _, members in KERNEL_GROUPS)
    return (f"def step_kernel_loose(k, stepping, row, {', '.join(loose_names())}):\n"
            f"    return step_kernel(k, stepping, row, {groups})\n")


# compiled under this file's name, so that Numba caches it as it caches the functions written here
exec(compile(_loose_source(), __file__, "exec"))
step_kernel_loose.__doc__ = """:func:`step_kernel` for callers in Python (the Python loops, one call per
    MuJoCo step): its groups' arrays loose, in the order of :func:`loose_names`
    (:func:`frogsim.engine.coupled.kernel_loose_args`), which Numba's dispatcher unboxes faster than
    tuples; the groups are made again in compiled code. Made from :data:`KERNEL_GROUPS` (its
    source: :func:`_loose_source`)."""
step_kernel_loose = jit(step_kernel_loose)


def _check_groups() -> None:
    """step_kernel's group parameters are KERNEL_GROUPS' (its one hand-written order: a mismatch is
    an ImportError)."""
    import inspect
    params = tuple(inspect.signature(getattr(step_kernel, "py_func", step_kernel)).parameters)
    if params != ("k", "stepping", "row") + tuple(p for _, p, _ in KERNEL_GROUPS):
        raise ImportError(f"step_kernel's parameters {params} are not KERNEL_GROUPS' groups in their order")


_check_groups()
