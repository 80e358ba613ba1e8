"""The pneumatics coupled with the MuJoCo body: muscles on cranks, legs, palms, water.

Each MuJoCo step of length dt (``robot.timestep``) runs

    mj_step1 (positions, velocities, tendon lengths)  ->  step_kernel (one Numba call)  ->  mj_step2

and the kernel does, with the state at the start of the step:

1. muscle tensions from the muscle pressures at t and the tendon lengths MuJoCo reports
   (:func:`frogsim.physics.muscle_force.muscle_force`), written as actuator controls;
2. the steering motors move the palms toward their commanded opening at their travel rate;
3. the water's forces on every part (:mod:`frogsim.physics.hydro`, :mod:`frogsim.robot.water`):
   strip drag, buoyancy and added mass, written to ``xfrc_applied``;
4. the pneumatics advanced from t to t + dt (:func:`frogsim.engine.integrator.integrate_span`,
   adaptive Dormand-Prince, split at valve switching times and controller samples exactly as
   :func:`frogsim.engine.integrator.run_schedule` does), each muscle's length following a cubic
   Hermite path that starts where the previous step's path ended (value and slope) and ends at
   MuJoCo's length plus velocity x dt: the muscle's volume (Eq. (5)) and its force come from the
   same length.

Added mass. An added-mass force -m_A a taken from the last step's acceleration is unstable when
m_A exceeds the part's own mass, as it does for the palms (about 3 kg of water for 0.3 kg of palm).
So the added mass enters MuJoCo's mass matrix: each part's body gets an extra mass
m_iso = max_j m_j at the centre of its added mass, and its added inertia I_A (``body_mass``,
``body_ipos``, ``body_inertia`` are changed at run time; for the palms at every step, as they open
and fold). The excess (m_iso - m_j) in the directions where the water adds less is taken back by
an explicit force (m_iso - m_j) a_j, a_j the part's acceleration over the last step: that
iteration contracts (factor (m_iso - m_j)/(m + m_iso) < 1), so it is stable, and converges to the
true (m + m_j) a_j = F. The velocity terms of Kirchhoff's equations, M_A (omega x v) -
omega x (M_A v) and the Munk moment (M_A v) x v, and the change of an opening palm's added mass,
-dM_A/dt v and -dI_A/dt omega, are applied as forces. The weight MuJoCo gives the extra mass is
cancelled by an equal upward force at the same point.

Every step checks the state: a non-finite position or velocity, a leg joint faster than
200 rad/s or a hull faster than 20 m/s stops the run with a SimulationError that names the
quantity and the time.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from frogsim._jit import jit
from frogsim.circuit import layout as CL
from frogsim.circuit.model import build_model
from frogsim.circuit.rhs import rhs
from frogsim.engine.integrator import integrate_span, pump_band
from frogsim.errors import SimulationError
from frogsim.physics.hydro import strip_drag
from frogsim.physics.muscle_force import MODEL_DMSP20, MODEL_IDEAL, muscle_force
from frogsim.robot import import_mujoco
from frogsim.robot.water import (E_BODY, E_C0, E_FAN, E_HEAVE, E_I0, E_IA, E_LIMB, E_M0, E_MA,
                                 E_VOL, E_XA, E_XB, P_PHI_FOLD, P_PHI_OPEN, P_RATE, P_SIZE,
                                 hydro_tables)

# --- muscle table mu[i, :] -------------------------------------------------------------------------
U_TENDON = 0     # MuJoCo tendon id
U_ACT = 1        # MuJoCo actuator id
U_FITTINGS = 2   # tendon length - muscle length [m]
U_SIZE = 3

# --- constants sc[:] ---------------------------------------------------------------------------------
S_DT = 0         # MuJoCo step [s]
S_RHO = 1        # density of the medium [kg/m^3]
S_G = 2          # gravity [m/s^2]
S_CTRL_DT = 3    # controller period [s]
S_RTOL = 4       # pneumatic relative tolerance
S_MAXSTEP = 5    # pneumatic largest step [s]
S_LAW = 6        # muscle force model (MODEL_*)
S_BLADDER = 7    # bladder constants A, eps_c, k, a, b (5)
S_TRUNK = 12     # MuJoCo body id of the hull
S_VMAX = 13      # hull speed limit [m/s]
S_WMAX = 14      # joint speed limit [rad/s]
S_SIZE = 15

# --- mutable state st[:] -----------------------------------------------------------------------------
T_H = 0          # pneumatic step size carried between calls [s]
T_SI = 1         # index of the next valve schedule entry
T_PUMP = 2       # pump running (1) or not (0)
T_SAMPLE = 3     # index of the last controller sample
T_PALM_CMD = 4   # index of the next palm command
T_PALM_TARGET = 5  # commanded palm opening (0 folded, 1 open)
T_FIRST = 6      # 1 until the first step has run (no acceleration history yet)
T_FAIL = 7       # FAIL_* code
T_FAIL_ARG = 8   # which dof / joint / status
T_FAIL_VAL = 9   # the offending value
T_EXERGY = 10    # isothermal exergy of the air charged into muscles since t = 0 [J]
T_PEAK = 11      # largest thrust so far [N]
T_PEAK_TIME = 12
T_SIZE = 13

FAIL_PNEUMATIC = 1
FAIL_QPOS = 2
FAIL_QVEL = 3
FAIL_BODY_SPEED = 4
FAIL_JOINT_SPEED = 5

# --- per-step record rec[row, :] -------------------------------------------------------------------
R_TIME = 0
R_X = 1          # hull centre, world x, y, z [m] (3)
R_YAW = 4        # heading of the hull [rad]
R_V = 5          # velocity of the hull centre, world (3) [m/s]
R_THRUST = 8     # water force on the legs along the heading [N]
R_THRUST_AM = 9  # its added-mass part [N]
R_HULL = 10      # water force on the hull along the heading [N]
R_PS = 11        # source pressure [Pa abs]
R_PE = 12        # exhaust pressure [Pa abs]
R_CHARGED = 13   # air charged into all muscles since t = 0 [kg]
R_PUMPED = 14    # air moved by the pump since t = 0 [kg]
R_AIR = 15       # air in source, exhaust and muscles [kg]
R_EXERGY = 16    # exergy of the charged air since t = 0 [J]
R_PUMP_ON = 17
R_FIXED = 18     # then: n pressures, n lengths, n tensions, n charged masses, 2n valve states,
                 # np palm openings, nj joint angles, nj joint velocities, nq MuJoCo positions


def record_columns(n: int, npal: int, nj: int, nq: int) -> dict:
    """Start column of each per-muscle / per-palm / per-joint block in a record row."""
    c = {"pressure": R_FIXED, "length": R_FIXED + n, "tension": R_FIXED + 2 * n,
         "charged": R_FIXED + 3 * n, "valves": R_FIXED + 4 * n, "palm": R_FIXED + 6 * n}
    c["angle"] = c["palm"] + npal
    c["omega"] = c["angle"] + nj
    c["qpos"] = c["omega"] + nj
    c["size"] = c["qpos"] + nq
    return c


@jit
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@jit
def _fan_scales(el, e, pa, frac):
    """(phi^2, phi^4) of a palm's fan angle for element e, (1, 1) for other parts."""
    p = int(el[e, E_FAN])
    if p < 0:
        return 1.0, 1.0
    phi = pa[p, P_PHI_FOLD] + frac[p] * (pa[p, P_PHI_OPEN] - pa[p, P_PHI_FOLD])
    return phi * phi, phi * phi * phi * phi


@jit
def _added(el, e, s2, s4):
    """(m1, m2, m3, I1, I2, I3, m_iso) of element e at fan scales s2, s4."""
    m1 = el[e, E_MA] * s2
    m2 = el[e, E_MA + 1] * s2
    m3 = el[e, E_MA + 2] * s2
    i1 = el[e, E_IA] * s4
    i2 = el[e, E_IA + 1] * s2
    i3 = el[e, E_IA + 2] * s2
    miso = max(m1, m2)
    if el[e, E_HEAVE] > 0.5:
        miso = max(miso, m3)
    return m1, m2, m3, i1, i2, i3, miso


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
        s2, s4 = _fan_scales(el, e, pa, frac)
        m1, m2, m3, i1, i2, i3, miso = _added(el, e, s2, s4)
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


@jit
def _advance_pneumatics(t, t_end, sc, st, g, mp, y, f, u, mot_t, mot_L, mot_d, mot_n, sched_t,
                        sched_u, atol, stats, work, aux, out_t, out_y, out_u):
    """Advance the circuit from t to t_end, stopping at valve switches and controller samples."""
    nu = u.size
    ns = sched_t.size
    ctrl_dt = sc[S_CTRL_DT]
    pump_active = g[CL.G_PUMP_ENABLED] > 0.5
    eps = 1e-12
    tc = t
    while tc < t_end - eps:
        t_seg = t_end
        si = int(st[T_SI])
        if si < ns and sched_t[si] < t_end - eps:
            t_seg = max(sched_t[si], tc)
        at_sample = False
        if pump_active:
            t_sample = (st[T_SAMPLE] + 1.0) * ctrl_dt
            if t_sample <= t_seg + eps:
                t_seg = min(t_seg, t_sample) if t_sample < t_end - eps else t_end
                at_sample = True
        if t_seg > tc:
            # np.int64(0), not 0: a bare constant is typed Literal[int](0) and would compile a second
            # copy of the integrator (several seconds on a first run) beside run_schedule's int64 one
            h, _, status = integrate_span(y, f, tc, t_seg, st[T_H], u, st[T_PUMP], g, mp, mot_t,
                                          mot_L, mot_d, mot_n, sc[S_RTOL], atol, sc[S_MAXSTEP],
                                          out_t, out_y, out_u, np.int64(0), stats, work)
            st[T_H] = h
            if status != 0:
                return status
        tc = t_seg
        changed = False
        while si < ns and sched_t[si] <= tc + eps:
            for j in range(nu):
                if u[j] != sched_u[si, j]:
                    changed = True
                u[j] = sched_u[si, j]
            si += 1
        st[T_SI] = si
        if at_sample:
            st[T_SAMPLE] += 1.0
            on = pump_band(y[CL.Y_PS], st[T_PUMP], g)
            if on != st[T_PUMP]:
                changed = True
                st[T_PUMP] = on
        if changed:
            rhs(tc, y, u, st[T_PUMP], g, mp, mot_t, mot_L, mot_d, mot_n, f, aux, work)
            stats[2] += 1
    return 0


@jit
def step_kernel(k, advance, row, sc, st, el, strip_s, strip_k, pa, pal_t, pal_target, frac,
                frac_new, mu, mp, g, y, f, u, mot_t, mot_L, mot_d, mot_n, sched_t, sched_u, atol,
                stats, work, aux, out_t, out_y, out_u, vprev, tension, rec, leg_qpos, leg_dof,
                ten_length, ten_velocity, xpos, xmat, xipos, cvel, subtree_com, body_rootid,
                body_parentid, body_mass, body_ipos, body_inertia, body_subtreemass, ctrl, xfrc,
                qpos, qvel):
    """One coupled step at t = k dt (see the module docstring). Returns 0, or a FAIL_* code.

    ``advance`` = 0 only checks, computes forces and records (the last row of a run).
    ``row`` >= 0 records the state at t into rec[row].
    """
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
    cx, cy, cz = _cross(wx, wy, wz, xpos[tb, 0] - subtree_com[root, 0],
                        xpos[tb, 1] - subtree_com[root, 1], xpos[tb, 2] - subtree_com[root, 2])
    vbx, vby, vbz = cvel[tb, 3] + cx, cvel[tb, 4] + cy, cvel[tb, 5] + cz
    speed = math.sqrt(vbx * vbx + vby * vby + vbz * vbz)
    if speed > sc[S_VMAX]:
        st[T_FAIL], st[T_FAIL_ARG], st[T_FAIL_VAL] = FAIL_BODY_SPEED, 0, speed
        return FAIL_BODY_SPEED
    # -- 1. muscle tensions from the pressures at t ------------------------------------------------
    patm = g[CL.G_PATM]
    law = int(sc[S_LAW])
    for i in range(n):
        L = ten_length[int(mu[i, U_TENDON])] - mu[i, U_FITTINGS]
        tension[i] = muscle_force(law, y[CL.Y_MUSCLE0 + 2 * i + 1] - patm, L, mp[i, CL.M_L0],
                                  mp[i, CL.M_B0], mp[i, CL.M_N], sc[S_BLADDER], sc[S_BLADDER + 1],
                                  sc[S_BLADDER + 2], sc[S_BLADDER + 3], sc[S_BLADDER + 4])
        ctrl[int(mu[i, U_ACT])] = tension[i]
    # -- 2. palms: commands on the controller grid, motors at their travel rate ----------------------
    npal = pa.shape[0]
    while int(st[T_PALM_CMD]) < pal_t.size and pal_t[int(st[T_PALM_CMD])] <= t + 1e-12:
        st[T_PALM_TARGET] = pal_target[int(st[T_PALM_CMD])]
        st[T_PALM_CMD] += 1.0
    for p in range(npal):
        step = pa[p, P_RATE] * dt
        d = st[T_PALM_TARGET] - frac[p]
        frac_new[p] = frac[p] + (d if abs(d) <= step else math.copysign(step, d))
        if advance == 0:
            frac_new[p] = frac[p]
    # -- 3. water ------------------------------------------------------------------------------------
    rho = sc[S_RHO]
    grav = sc[S_G]
    hx, hy, hz = xmat[tb, 0], xmat[tb, 3], xmat[tb, 6]          # heading: the hull's x axis
    thrust = 0.0
    thrust_am = 0.0
    hull = 0.0
    first = st[T_FIRST] > 0.5
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
            kscale = pa[fan, P_PHI_FOLD] + frac[fan] * (pa[fan, P_PHI_OPEN] - pa[fan, P_PHI_FOLD])
        Fx = 0.0
        Fy = 0.0
        Fz = 0.0
        Tx = 0.0
        Ty = 0.0
        Tz = 0.0
        # strip drag, Eq. (D)
        for s in range(strip_s.shape[1]):
            sk = strip_s[e, s]
            px, py, pz = ox + e1x * sk, oy + e1y * sk, oz + e1z * sk
            cx, cy, cz = _cross(wx, wy, wz, px - comx, py - comy, pz - comz)
            vx, vy, vz = lx + cx, ly + cy, lz + cz
            f1, f2, f3 = strip_drag(strip_k[e, s, 0] * kscale, strip_k[e, s, 1] * kscale,
                                    strip_k[e, s, 2] * kscale, e1x * vx + e1y * vy + e1z * vz,
                                    e2x * vx + e2y * vy + e2z * vz, e3x * vx + e3y * vy + e3z * vz)
            fx = f1 * e1x + f2 * e2x + f3 * e3x
            fy = f1 * e1y + f2 * e2y + f3 * e3y
            fz = f1 * e1z + f2 * e2z + f3 * e3z
            Fx += fx
            Fy += fy
            Fz += fz
            tx, ty, tz = _cross(px - gx, py - gy, pz - gz, fx, fy, fz)
            Tx += tx
            Ty += ty
            Tz += tz
        drag_h = Fx * hx + Fy * hy + Fz * hz
        # added mass (module docstring): explicit part at the added-mass centre
        s2, s4 = _fan_scales(el, e, pa, frac)
        m1, m2, m3, i1, i2, i3, miso = _added(el, e, s2, s4)
        s2n, s4n = _fan_scales(el, e, pa, frac_new)
        n1, n2, n3, j1, j2, j3, _ = _added(el, e, s2n, s4n)
        ax_, ay_, az_ = el[e, E_XA], el[e, E_XA + 1], el[e, E_XA + 2]
        qx = ox + e1x * ax_ + e2x * ay_ + e3x * az_
        qy = oy + e1y * ax_ + e2y * ay_ + e3y * az_
        qz = oz + e1z * ax_ + e2z * ay_ + e3z * az_
        cx, cy, cz = _cross(wx, wy, wz, qx - comx, qy - comy, qz - comz)
        vx, vy, vz = lx + cx, ly + cy, lz + cz
        if first:
            acx, acy, acz = 0.0, 0.0, 0.0
        else:
            acx = (vx - vprev[e, 0]) / dt
            acy = (vy - vprev[e, 1]) / dt
            acz = (vz - vprev[e, 2]) / dt
        if advance != 0:
            vprev[e, 0], vprev[e, 1], vprev[e, 2] = vx, vy, vz
        v1 = e1x * vx + e1y * vy + e1z * vz
        v2 = e2x * vx + e2y * vy + e2z * vz
        v3 = e3x * vx + e3y * vy + e3z * vz
        a1 = e1x * acx + e1y * acy + e1z * acz
        a2 = e2x * acx + e2y * acy + e2z * acz
        a3 = e3x * acx + e3y * acy + e3z * acz
        w1 = e1x * wx + e1y * wy + e1z * wz
        w2 = e2x * wx + e2y * wy + e2z * wz
        w3 = e3x * wx + e3y * wy + e3z * wz
        ox1, ox2, ox3 = _cross(w1, w2, w3, v1, v2, v3)                # omega x v
        p1, p2, p3 = m1 * v1, m2 * v2, m3 * v3                         # M_A v
        oy1, oy2, oy3 = _cross(w1, w2, w3, p1, p2, p3)                 # omega x (M_A v)
        vel1 = m1 * ox1 - oy1 - (n1 - m1) / dt * v1
        vel2 = m2 * ox2 - oy2 - (n2 - m2) / dt * v2
        vel3 = m3 * ox3 - oy3 - (n3 - m3) / dt * v3
        g1 = (miso - m1) * a1 + vel1                                   # applied (explicit) part
        g2 = (miso - m2) * a2 + vel2
        g3 = (miso - m3) * a3 + vel3
        am1, am2, am3 = -m1 * a1 + vel1, -m2 * a2 + vel2, -m3 * a3 + vel3   # whole added-mass force
        mu1, mu2, mu3 = _cross(p1, p2, p3, v1, v2, v3)                 # Munk moment (M_A v) x v
        mu1 -= (j1 - i1) / dt * w1
        mu2 -= (j2 - i2) / dt * w2
        mu3 -= (j3 - i3) / dt * w3
        fx = g1 * e1x + g2 * e2x + g3 * e3x
        fy = g1 * e1y + g2 * e2y + g3 * e3y
        fz = g1 * e1z + g2 * e2z + g3 * e3z + miso * grav          # cancel the extra mass's weight
        Fx += fx
        Fy += fy
        Fz += fz
        tx, ty, tz = _cross(qx - gx, qy - gy, qz - gz, fx, fy, fz)
        Tx += tx + mu1 * e1x + mu2 * e2x + mu3 * e3x
        Ty += ty + mu1 * e1y + mu2 * e2y + mu3 * e3y
        Tz += tz + mu1 * e1z + mu2 * e2z + mu3 * e3z
        am_h = ((am1 * e1x + am2 * e2x + am3 * e3x) * hx + (am1 * e1y + am2 * e2y + am3 * e3y) * hy
                + (am1 * e1z + am2 * e2z + am3 * e3z) * hz)
        # buoyancy at the centre of the displaced volume
        bx_, by_, bz_ = el[e, E_XB], el[e, E_XB + 1], el[e, E_XB + 2]
        fb = rho * grav * el[e, E_VOL]
        tx, ty, tz = _cross(ox + e1x * bx_ + e2x * by_ + e3x * bz_ - gx,
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
    if advance != 0:
        st[T_FIRST] = 0.0
    if thrust > st[T_PEAK]:
        st[T_PEAK] = thrust
        st[T_PEAK_TIME] = t
    # -- 4. record the state at t -------------------------------------------------------------------
    if row >= 0:
        rr = rec[row]
        rr[R_TIME] = t
        rr[R_X], rr[R_X + 1], rr[R_X + 2] = xpos[tb, 0], xpos[tb, 1], xpos[tb, 2]
        rr[R_YAW] = math.atan2(xmat[tb, 3], xmat[tb, 0])
        rr[R_V], rr[R_V + 1], rr[R_V + 2] = vbx, vby, vbz
        rr[R_THRUST] = thrust
        rr[R_THRUST_AM] = thrust_am
        rr[R_HULL] = hull
        rr[R_PS] = y[CL.Y_PS]
        rr[R_PE] = y[CL.Y_PE]
        q = 0.0
        air = y[CL.Y_MS] + y[CL.Y_ME]
        for i in range(n):
            q += y[CL.Y_MUSCLE0 + 2 * n + i]
            air += y[CL.Y_MUSCLE0 + 2 * i]
        rr[R_CHARGED] = q
        rr[R_PUMPED] = y[CL.Y_MUSCLE0 + 4 * n]
        rr[R_AIR] = air
        rr[R_EXERGY] = st[T_EXERGY]
        rr[R_PUMP_ON] = st[T_PUMP]
        c = R_FIXED
        for i in range(n):
            rr[c + i] = y[CL.Y_MUSCLE0 + 2 * i + 1]
            rr[c + n + i] = ten_length[int(mu[i, U_TENDON])] - mu[i, U_FITTINGS]
            rr[c + 2 * n + i] = tension[i]
            rr[c + 3 * n + i] = y[CL.Y_MUSCLE0 + 2 * n + i]
            rr[c + 4 * n + 2 * i] = u[2 * i]
            rr[c + 4 * n + 2 * i + 1] = u[2 * i + 1]
        c += 6 * n
        for p in range(npal):
            rr[c + p] = frac[p]
        c += npal
        for j in range(nj):
            rr[c + j] = qpos[leg_qpos[j]]
            rr[c + nj + j] = qvel[leg_dof[j]]
        c += 2 * nj
        for j in range(qpos.size):
            rr[c + j] = qpos[j]
    if advance == 0:
        return 0
    # -- 5. pneumatics from t to t + dt, muscle lengths following MuJoCo's -----------------------------
    t_end = (k + 1) * dt
    for i in range(n):
        tid = int(mu[i, U_TENDON])
        L = ten_length[tid] - mu[i, U_FITTINGS]
        v = ten_velocity[tid]
        if first:
            Ls, ds = L, v
        else:
            Ls, ds = mot_L[i, 2], mot_d[i, 2]
        mot_t[i, 0], mot_L[i, 0], mot_d[i, 0] = t - dt, Ls - ds * dt, ds
        mot_t[i, 1], mot_L[i, 1], mot_d[i, 1] = t, Ls, ds
        mot_t[i, 2], mot_L[i, 2], mot_d[i, 2] = t_end, L + v * dt, v
        mot_t[i, 3], mot_L[i, 3], mot_d[i, 3] = t_end + dt, L + 2.0 * v * dt, v
        mot_n[i] = 4
    q0 = 0.0
    for i in range(n):
        q0 += y[CL.Y_MUSCLE0 + 2 * n + i]
    ps0 = y[CL.Y_PS]
    rhs(t, y, u, st[T_PUMP], g, mp, mot_t, mot_L, mot_d, mot_n, f, aux, work)
    stats[2] += 1
    status = _advance_pneumatics(t, t_end, sc, st, g, mp, y, f, u, mot_t, mot_L, mot_d, mot_n,
                                 sched_t, sched_u, atol, stats, work, aux, out_t, out_y, out_u)
    if status != 0:
        st[T_FAIL], st[T_FAIL_ARG], st[T_FAIL_VAL] = FAIL_PNEUMATIC, status, t
        return FAIL_PNEUMATIC
    q1 = 0.0
    for i in range(n):
        q1 += y[CL.Y_MUSCLE0 + 2 * n + i]
    if ps0 > patm:
        st[T_EXERGY] += (q1 - q0) * g[CL.G_R] * g[CL.G_TAMB] * math.log(ps0 / patm)
    # -- 6. palms' added mass for the next step -------------------------------------------------------
    for p in range(npal):
        frac[p] = frac_new[p]
    apply_added_mass(el, pa, frac, np.bool_(True), body_mass, body_ipos, body_inertia, body_subtreemass,
                     body_parentid)
    return 0


# ---------------------------------------------------------------------------------------------------
# Python side: build the model once, run the loop, hand back the records
# ---------------------------------------------------------------------------------------------------
_PNEUMATIC_TEXT = {1: "step size fell below 1e-14 s", 2: "the state became non-finite (NaN or inf)",
                   3: "more than 50 million steps"}
BODY_SPEED_LIMIT = 20.0       # [m/s]: ten times anything the robot can swim
JOINT_SPEED_LIMIT = 200.0     # [rad/s]: a leg joint swinging its whole range in 4 ms


@dataclass
class CoupledModel:
    """The MuJoCo model and data, the pneumatic model and every table the kernel loops over."""
    name: str
    rs: object                  # the RobotScenario (None for a bare body, see build_bare)
    mjm: object
    mjd: object
    pneumatic: object           # frogsim.circuit.model.PneumaticModel (None for a bare body)
    xml: str
    muscle_names: list
    joint_names: list
    arrays: dict
    n_steps: int
    rec_every: int
    columns: dict = field(default_factory=dict)

    @property
    def dt(self) -> float:
        return float(self.arrays["sc"][S_DT])

    def set_muscle_pressure(self, name: str, pressure_abs: float) -> None:
        """Start a muscle at a given absolute pressure [Pa] (before :func:`run_coupled`), with its
        air at ambient temperature in its present volume."""
        from frogsim.physics.muscle import muscle_volume
        i = self.muscle_names.index(name)
        y, g, mp, mu = (self.arrays[k] for k in ("y", "g", "mp", "mu"))
        L = self.mjd.ten_length[int(mu[i, U_TENDON])] - mu[i, U_FITTINGS]
        V = muscle_volume(L, mp[i, CL.M_B0], mp[i, CL.M_N]) + mp[i, CL.M_DEAD]
        y[CL.Y_MUSCLE0 + 2 * i] = pressure_abs * V / (g[CL.G_R] * g[CL.G_TAMB])
        y[CL.Y_MUSCLE0 + 2 * i + 1] = pressure_abs


def _assemble(name, rs, xml, m, d, pm, circuit, mu, tables, palms_cmd, sc, joints, duration,
              output_interval) -> CoupledModel:
    """Allocate every array the kernel needs and put the static added masses into the model."""
    mujoco = import_mujoco()
    g, mp, y, u, sched_t, sched_u, atol = circuit
    el, strip_s, strip_k, pa = tables
    pal_t, pal_target = palms_cmd
    n = mu.shape[0]
    ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in joints]
    leg_qpos = np.array([m.jnt_qposadr[i] for i in ids], np.int64)
    leg_dof = np.array([m.jnt_dofadr[i] for i in ids], np.int64)
    st = np.zeros(T_SIZE)
    st[T_H] = 1e-4
    st[T_FIRST] = 1.0
    st[T_PEAK] = -np.inf
    st[T_PUMP] = pump_band(y[CL.Y_PS], 0.0, g)
    while int(st[T_SI]) < sched_t.size and sched_t[int(st[T_SI])] <= 1e-12:
        u[:] = sched_u[int(st[T_SI])]
        st[T_SI] += 1
    dt = sc[S_DT]
    n_steps = int(round(duration / dt))
    rec_every = max(1, int(round(output_interval / dt)))
    cols = record_columns(n, pa.shape[0], len(joints), m.nq)
    ny = y.size
    frac = np.zeros(pa.shape[0])
    arrays = dict(
        sc=sc, st=st, el=el, strip_s=np.ascontiguousarray(strip_s),
        strip_k=np.ascontiguousarray(strip_k), pa=pa.reshape(-1, P_SIZE), pal_t=pal_t,
        pal_target=pal_target, frac=frac, frac_new=frac.copy(), mu=mu, mp=mp, g=g, y=y,
        f=np.zeros(ny), u=u, mot_t=np.zeros((n, 4)), mot_L=np.zeros((n, 4)),
        mot_d=np.zeros((n, 4)), mot_n=np.full(n, 4, np.int64), sched_t=sched_t, sched_u=sched_u,
        atol=atol, stats=np.zeros(3, np.int64), work=np.zeros(3 * n + 1), aux=np.zeros(2 * n + 1),
        out_t=np.zeros(0), out_y=np.zeros((0, ny)), out_u=np.zeros((0, 2 * n + 1)),
        vprev=np.zeros((el.shape[0], 3)), tension=np.zeros(n),
        rec=np.full((n_steps // rec_every + 2, cols["size"]), np.nan), leg_qpos=leg_qpos,
        leg_dof=leg_dof)
    arrays["work"][-1] = 1e-4
    apply_added_mass(el, arrays["pa"], frac, False, m.body_mass, m.body_ipos, m.body_inertia,
                     m.body_subtreemass, m.body_parentid)
    # MuJoCo keeps the mass-matrix entries of "simple" dofs (a body whose dofs do not couple)
    # as constants computed at compile time (dof_M0): recompute them for the new masses, and
    # refuse a palm (whose mass changes every step) on such a dof
    mujoco.mj_setConst(m, mujoco.MjData(m))
    for p in range(pa.shape[0]):
        b = int(el[int(pa[p, 0]), E_BODY])
        dofs = np.nonzero(m.dof_bodyid == b)[0]
        if np.any(m.dof_simplenum[dofs] > 0):
            raise AssertionError(f"body {b}: its mass changes at run time but MuJoCo treats it as simple")
    return CoupledModel(name=name, rs=rs, mjm=m, mjd=d, pneumatic=pm, xml=xml,
                        muscle_names=list(rs.muscles) if rs is not None else [],
                        joint_names=list(joints), arrays=arrays, n_steps=n_steps,
                        rec_every=rec_every, columns=cols)


def _constants(dt, rho, gravity, trunk, ctrl_rate=1000.0, rtol=1e-7, max_step=1e-3, law=None):
    sc = np.zeros(S_SIZE)
    sc[S_DT], sc[S_RHO], sc[S_G] = dt, rho, gravity
    sc[S_CTRL_DT], sc[S_RTOL], sc[S_MAXSTEP] = 1.0 / ctrl_rate, rtol, max_step
    if law is not None:
        sc[S_LAW] = MODEL_DMSP20 if law.model == "dmsp20" else MODEL_IDEAL
        sc[S_BLADDER:S_BLADDER + 5] = (law.force_scale, law.strain_scale, law.stiffness,
                                       law.stretch_stiffness, law.stretch_quadratic)
    sc[S_TRUNK] = trunk
    sc[S_VMAX] = BODY_SPEED_LIMIT
    sc[S_WMAX] = JOINT_SPEED_LIMIT
    return sc


def build_coupled(rs) -> CoupledModel:
    """MuJoCo model (from the generated MJCF), pneumatic model and tables for a robot scenario."""
    mujoco = import_mujoco()

    from frogsim.control.gait import palm_commands
    from frogsim.physics.muscle import muscle_volume
    from frogsim.robot.mjcf import build_mjcf

    xml = build_mjcf(rs)
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    pm = build_model(rs.pneumatic)
    names = list(rs.muscles)
    if pm.names != names:
        raise AssertionError("pneumatic muscles and robot muscles out of order")

    def oid(kind, name):
        i = mujoco.mj_name2id(m, kind, name)
        if i < 0:
            raise AssertionError(f"MJCF has no {name!r}")
        return i

    mu = np.zeros((len(names), U_SIZE))
    for i, name in enumerate(names):
        mu[i, U_TENDON] = oid(mujoco.mjtObj.mjOBJ_TENDON, name)
        mu[i, U_ACT] = oid(mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        mu[i, U_FITTINGS] = rs.layout.cranks[rs.muscles[name][0]].fittings
    tables = hydro_tables(rs, lambda b: oid(mujoco.mjtObj.mjOBJ_BODY, b))
    sc = _constants(rs.options.timestep, rs.medium_density, rs.robot.water.gravity,
                    oid(mujoco.mjtObj.mjOBJ_BODY, "body"), rs.pneumatic.controller.rate,
                    rs.pneumatic.solver.rtol, rs.pneumatic.solver.max_step, rs.robot.muscle_force)
    # the muscles' air at ambient temperature in their actual initial volumes
    y = pm.y0.copy()
    for i in range(len(names)):
        L = d.ten_length[int(mu[i, U_TENDON])] - mu[i, U_FITTINGS]
        V = muscle_volume(L, pm.mp[i, CL.M_B0], pm.mp[i, CL.M_N]) + pm.mp[i, CL.M_DEAD]
        y[CL.Y_MUSCLE0 + 2 * i] = y[CL.Y_MUSCLE0 + 2 * i + 1] * V / (pm.g[CL.G_R] * pm.g[CL.G_TAMB])
    circuit = (pm.g, pm.mp, y, pm.u0.copy(), pm.sched_t, pm.sched_u, pm.atol)
    joints = [f"{j}_{s}" for s in ("left", "right") for j in ("hip", "knee", "ankle")]
    return _assemble(rs.name, rs, xml, m, d, pm, circuit, mu, tables,
                     palm_commands(rs.gait, rs.pneumatic.controller.rate), sc, joints,
                     rs.duration, rs.pneumatic.output_interval)


def build_bare(xml: str, tables, density: float, gravity: float, duration: float,
               output_interval: float, trunk: str = "body") -> CoupledModel:
    """A body in water without muscles or pneumatics (e.g. a hull coasting): the MJCF's timestep,
    the parts' tables as made by :mod:`frogsim.robot.water` (body ids of this model)."""
    mujoco = import_mujoco()
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    g = np.zeros(CL.G_SIZE)
    g[CL.G_K], g[CL.G_R], g[CL.G_PATM] = 1.4, 287.0, 101325.0
    g[CL.G_RHOREF], g[CL.G_TREF], g[CL.G_TAMB] = 1e5 / (287.0 * 293.15), 293.15, 293.15
    g[CL.G_VS] = g[CL.G_VE] = 1e-3
    m_air = g[CL.G_PATM] * 1e-3 / (287.0 * 293.15)
    y = np.array([m_air, g[CL.G_PATM], m_air, g[CL.G_PATM], 0.0])
    circuit = (g, np.zeros((0, CL.M_SIZE)), y, np.zeros(0), np.zeros(0), np.zeros((0, 0)),
               np.full(5, 1e-9))
    sc = _constants(float(m.opt.timestep), density, gravity,
                    mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, trunk))
    return _assemble("bare", None, xml, m, d, None, circuit, np.zeros((0, U_SIZE)), tables,
                     (np.zeros(0), np.zeros(0)), sc, [], duration, output_interval)


_KERNEL_ARRAYS = ("sc", "st", "el", "strip_s", "strip_k", "pa", "pal_t", "pal_target", "frac",
                  "frac_new", "mu", "mp", "g", "y", "f", "u", "mot_t", "mot_L", "mot_d", "mot_n",
                  "sched_t", "sched_u", "atol", "stats", "work", "aux", "out_t", "out_y", "out_u",
                  "vprev", "tension", "rec", "leg_qpos", "leg_dof")


def kernel_args(cm: CoupledModel) -> tuple:
    """The arrays step_kernel takes after (k, advance, row): the tables, then MuJoCo's views."""
    m, d = cm.mjm, cm.mjd
    return tuple(cm.arrays[k] for k in _KERNEL_ARRAYS) + (
        d.ten_length, d.ten_velocity, d.xpos, d.xmat, d.xipos, d.cvel, d.subtree_com,
        m.body_rootid, m.body_parentid, m.body_mass, m.body_ipos, m.body_inertia,
        m.body_subtreemass, d.ctrl, d.xfrc_applied, d.qpos, d.qvel)


def forces_now(cm: CoupledModel) -> np.ndarray:
    """The forces the kernel would apply in the present state, without advancing anything:
    ``xfrc_applied`` (per body: force [N] and torque about its centre of mass [N m], world frame)
    after MuJoCo's forward pass and the kernel's force computation (muscles and water)."""
    mujoco = import_mujoco()
    mujoco.mj_forward(cm.mjm, cm.mjd)
    status = step_kernel(0, 0, -1, *kernel_args(cm))
    if status:
        raise SimulationError(f"{cm.name!r}: {_failure(cm)}")
    return cm.mjd.xfrc_applied.copy()


def _failure(cm: CoupledModel) -> str:
    st = cm.arrays["st"]
    code, arg, val = int(st[T_FAIL]), int(st[T_FAIL_ARG]), float(st[T_FAIL_VAL])
    m = cm.mjm
    mujoco = import_mujoco()
    if code == FAIL_PNEUMATIC:
        return f"the pneumatic integration stopped: {_PNEUMATIC_TEXT.get(arg, arg)}"
    if code in (FAIL_QPOS, FAIL_QVEL):
        what = "position" if code == FAIL_QPOS else "velocity"
        jid = (np.searchsorted(m.jnt_qposadr, arg, side="right") - 1 if code == FAIL_QPOS
               else np.searchsorted(m.jnt_dofadr, arg, side="right") - 1)
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, int(jid)) or f"dof {arg}"
        return f"joint {name!r} {what} = {val:g} (not finite)"
    if code == FAIL_BODY_SPEED:
        return f"hull speed = {val:.4g} m/s exceeds {BODY_SPEED_LIMIT:g} m/s"
    if code == FAIL_JOINT_SPEED:
        return (f"joint {cm.joint_names[arg]!r} angular velocity = {val:.4g} rad/s exceeds "
                f"{JOINT_SPEED_LIMIT:g} rad/s")
    return f"failure code {code}"


def run_coupled(cm: CoupledModel, progress=None) -> dict:
    """Run the loop to the end of the scenario; returns {"rec", "wall_s", "stats", ...}.

    Raises SimulationError with the quantity and the time when the run goes unstable.
    """
    mujoco = import_mujoco()
    m, d = cm.mjm, cm.mjd
    a = cm.arrays
    args = kernel_args(cm)
    step1, step2 = mujoco.mj_step1, mujoco.mj_step2
    kernel = step_kernel
    n_steps, every = cm.n_steps, cm.rec_every
    chunk = max(1, n_steps // 20)
    warnings = []            # MuJoCo's own warnings, kept instead of written to MUJOCO_LOG.TXT
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: warnings.append(str(msg).strip()))
    t0 = time.perf_counter()
    try:
        for k in range(n_steps + 1):
            step1(m, d)
            advance = 1 if k < n_steps else 0
            row = k // every if k % every == 0 else (-1 if advance else k // every + 1)
            if kernel(k, advance, row, *args):
                t = k * cm.dt
                said = f" (MuJoCo: {warnings[0]})" if warnings else ""
                raise SimulationError(f"scenario {cm.name!r}: unstable at t = {t:.4f} s: "
                                      f"{_failure(cm)}{said}; try a smaller robot.timestep "
                                      f"(now {cm.dt * 1e3:g} ms)")
            if advance:
                step2(m, d)
            if progress is not None and k % chunk == 0:
                progress(k / n_steps)
    finally:
        mujoco.set_mju_user_warning(previous)
    wall = time.perf_counter() - t0
    rec = a["rec"]
    rec = rec[~np.isnan(rec[:, R_TIME])]
    return {"rec": rec, "wall_s": wall, "stats": {"mujoco_steps": n_steps,
                                                  "pneumatic_steps": int(a["stats"][0]),
                                                  "pneumatic_rejected": int(a["stats"][1]),
                                                  "rhs_evaluations": int(a["stats"][2])}}
