"""Adaptive Dormand-Prince 5(4) integration of the circuit, segment by segment.

Valve states are piecewise constant: they change only at known times (open-loop commands sampled
on the controller grid plus the valve dead time) or at controller samples when a state-dependent
rule (the pump's pressure band) is active. The integrator stops exactly at those times, so no step
straddles a discontinuity; between them the step size adapts to the error estimate and carries
over from one segment to the next.

Method: Dormand and Prince (1980), coefficients as in Hairer, Norsett and Wanner, Solving ODEs I,
Table 5.2; error norm and step control as in Hairer's DOPRI5 (safety 0.9, factor limits 0.2..5).
Step control: Hairer's PI controller (exponent 0.2 - 0.75 beta, beta = 0.04).
Dense output: Dormand and Prince's continuous extension of order 4 (Hairer's DOPRI5 coefficients
d1..d7), which needs no extra right-hand-side evaluations.
"""
from __future__ import annotations

import math

import numpy as np
from frogsim._jit import jit

from frogsim.circuit.layout import G_PUMP_ENABLED, G_PUMP_OFF, G_PUMP_ON, Y_PS
from frogsim.circuit.rhs import rhs

STATUS_OK = 0
STATUS_STEP_UNDERFLOW = 1
STATUS_NOT_FINITE = 2
STATUS_MAX_STEPS = 3

# Dormand-Prince 5(4) tableau
A21 = 1.0 / 5.0
A31, A32 = 3.0 / 40.0, 9.0 / 40.0
A41, A42, A43 = 44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0
A51, A52, A53, A54 = 19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0
A61, A62, A63, A64, A65 = 9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0
B1, B3, B4, B5, B6 = 35.0 / 384.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0
E1, E3, E4, E5, E6, E7 = (71.0 / 57600.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0,
                          22.0 / 525.0, -1.0 / 40.0)
C2, C3, C4, C5 = 0.2, 0.3, 0.8, 8.0 / 9.0
D1, D3, D4, D5, D6, D7 = (-12715105075.0 / 11282082432.0, 87487479700.0 / 32700410799.0,
                          -10690763975.0 / 1880347072.0, 701980252875.0 / 199316789632.0,
                          -1453857185.0 / 822651844.0, 69997945.0 / 29380423.0)
SAFETY = 0.9
BETA = 0.04                  # PI step control (Hairer's DOPRI5 default)
EXPO = 0.2 - 0.75 * BETA


@jit
def integrate_span(y, f, t, t_end, h, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n,
                   rtol, atol, max_step, out_t, out_y, out_u, out_i, stats, work):
    """Advance y from t to exactly t_end with valve states u held constant.

    ``f`` must hold dy/dt at (t, y) on entry and holds it at the end on return (FSAL). Output
    times out_t[out_i:] that fall inside (t, t_end] are filled into out_y/out_u by dense output.
    ``stats`` accumulates [accepted steps, rejected steps, rhs evaluations]; ``work`` is scratch
    for the right-hand side (3n) and the PI controller's previous error (its last entry).

    Returns (h_next, out_i, status).
    """
    ny = y.size
    k2 = np.empty(ny)
    k3 = np.empty(ny)
    k4 = np.empty(ny)
    k5 = np.empty(ny)
    k6 = np.empty(ny)
    k7 = np.empty(ny)
    yt = np.empty(ny)
    yn = np.empty(ny)
    rc1 = np.empty(ny)
    rc2 = np.empty(ny)
    rc3 = np.empty(ny)
    rc4 = np.empty(ny)
    aux = np.empty(2 * mp.shape[0] + 1)
    n_out = out_t.size
    nu = u.size
    err_old = work[work.size - 1]
    while t < t_end:
        if h > max_step:
            h = max_step
        last = False
        h_try = h
        if t + h_try >= t_end:
            h_try = t_end - t
            last = True
        for j in range(ny):
            yt[j] = y[j] + h_try * A21 * f[j]
        rhs(t + C2 * h_try, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k2, aux, work)
        for j in range(ny):
            yt[j] = y[j] + h_try * (A31 * f[j] + A32 * k2[j])
        rhs(t + C3 * h_try, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k3, aux, work)
        for j in range(ny):
            yt[j] = y[j] + h_try * (A41 * f[j] + A42 * k2[j] + A43 * k3[j])
        rhs(t + C4 * h_try, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k4, aux, work)
        for j in range(ny):
            yt[j] = y[j] + h_try * (A51 * f[j] + A52 * k2[j] + A53 * k3[j] + A54 * k4[j])
        rhs(t + C5 * h_try, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k5, aux, work)
        for j in range(ny):
            yt[j] = y[j] + h_try * (A61 * f[j] + A62 * k2[j] + A63 * k3[j] + A64 * k4[j] + A65 * k5[j])
        rhs(t + h_try, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k6, aux, work)
        for j in range(ny):
            yn[j] = y[j] + h_try * (B1 * f[j] + B3 * k3[j] + B4 * k4[j] + B5 * k5[j] + B6 * k6[j])
        t_new = t_end if last else t + h_try
        rhs(t_new, yn, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k7, aux, work)
        stats[2] += 6
        err = 0.0
        for j in range(ny):
            e = h_try * (E1 * f[j] + E3 * k3[j] + E4 * k4[j] + E5 * k5[j] + E6 * k6[j] + E7 * k7[j])
            sc = atol[j] + rtol * max(abs(y[j]), abs(yn[j]))
            err += (e / sc) ** 2
        err = math.sqrt(err / ny)
        if not math.isfinite(err):
            # a non-finite trial: shrink hard and retry; give up only at step underflow
            stats[1] += 1
            h = 0.1 * h_try
            if h < 1e-14 * max(1.0, abs(t)):
                return h, out_i, STATUS_NOT_FINITE
            continue
        if err <= 1.0:
            # dense output on (t, t_new]: the 4th-order continuous extension, its coefficients
            # computed once per step that holds output points
            if out_i < n_out and out_t[out_i] <= t_new:
                for j in range(ny):
                    ydiff = yn[j] - y[j]
                    bspl = h_try * f[j] - ydiff
                    rc1[j] = ydiff
                    rc2[j] = bspl
                    rc3[j] = ydiff - h_try * k7[j] - bspl
                    rc4[j] = h_try * (D1 * f[j] + D3 * k3[j] + D4 * k4[j] + D5 * k5[j]
                                      + D6 * k6[j] + D7 * k7[j])
            while out_i < n_out and out_t[out_i] <= t_new:
                th = (out_t[out_i] - t) / h_try
                th1 = 1.0 - th
                row = out_y[out_i]
                for j in range(ny):
                    row[j] = y[j] + th * (rc1[j] + th1 * (rc2[j] + th * (rc3[j] + th1 * rc4[j])))
                for j in range(nu):
                    out_u[out_i, j] = u[j]
                out_u[out_i, nu] = pump_on
                out_i += 1
            for j in range(ny):
                y[j] = yn[j]
                f[j] = k7[j]
            t = t_new
            stats[0] += 1
            e = max(err, 1e-4)
            fac = min(10.0, max(0.2, SAFETY * e ** -EXPO * err_old ** BETA))
            err_old = e
            h_next = h_try * fac
            h = max(h, h_next) if last else h_next
        else:
            stats[1] += 1
            h = h_try * max(0.2, SAFETY * err ** -EXPO)
            if h < 1e-14 * max(1.0, abs(t)):
                work[work.size - 1] = err_old
                return h, out_i, STATUS_STEP_UNDERFLOW
        if stats[0] + stats[1] > 50_000_000:
            work[work.size - 1] = err_old
            return h, out_i, STATUS_MAX_STEPS
    work[work.size - 1] = err_old
    return h, out_i, STATUS_OK


@jit
def pump_band(p_s, pump_on, g):
    """Pump switching rule at a controller sample: on below the band, off above it."""
    if g[G_PUMP_ENABLED] < 0.5:
        return 0.0
    if p_s < g[G_PUMP_ON]:
        return 1.0
    if p_s > g[G_PUMP_OFF]:
        return 0.0
    return pump_on


@jit
def run_schedule(y0, t0, t_end, g, mp, mot_t, mot_L, mot_d, mot_n, sched_t, sched_u, u0,
                 ctrl_dt, out_t, rtol, atol, max_step, h0):
    """Integrate from t0 to t_end under an open-loop valve schedule.

    ``sched_t`` (sorted) are the times at which valve states become ``sched_u[k]``; before the
    first, ``u0`` holds. Entries may repeat the current state: they only make the integrator stop
    there (used for kinks in the prescribed motion). With the pump band active the run also stops at every controller sample
    (multiples of ctrl_dt) to apply the band rule.

    Returns (out_y, out_u, y_end, stats, status, t_reached).
    """
    ny = y0.size
    nu = u0.size
    n_out = out_t.size
    out_y = np.empty((n_out, ny))
    out_u = np.empty((n_out, nu + 1))
    stats = np.zeros(3, dtype=np.int64)
    y = y0.copy()
    u = u0.copy()
    f = np.empty(ny)
    aux = np.empty(2 * mp.shape[0] + 1)
    work = np.zeros(3 * mp.shape[0] + 1)
    work[work.size - 1] = 1e-4
    t = t0
    si = 0
    while si < sched_t.size and sched_t[si] <= t0:
        for j in range(nu):
            u[j] = sched_u[si, j]
        si += 1
    pump_active = g[G_PUMP_ENABLED] > 0.5
    pump_on = pump_band(y[Y_PS], 0.0, g)
    out_i = 0
    while out_i < n_out and out_t[out_i] <= t0:
        for j in range(ny):
            out_y[out_i, j] = y[j]
        for j in range(nu):
            out_u[out_i, j] = u[j]
        out_u[out_i, nu] = pump_on
        out_i += 1
    k_sample = int(math.floor(t0 / ctrl_dt + 1e-9))
    rhs(t, y, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, f, aux, work)
    stats[2] += 1
    h = h0
    status = 0
    while t < t_end:
        t_seg = t_end
        if si < sched_t.size and sched_t[si] < t_seg:
            t_seg = sched_t[si]
        at_sample = False
        if pump_active:
            t_sample = (k_sample + 1) * ctrl_dt
            if t_sample <= t_seg:
                t_seg = t_sample
                at_sample = True
        h, out_i, status = integrate_span(y, f, t, t_seg, h, u, pump_on, g, mp, mot_t, mot_L,
                                          mot_d, mot_n, rtol, atol, max_step, out_t, out_y,
                                          out_u, out_i, stats, work)
        if status != 0:
            return out_y, out_u, y, stats, status, t
        t = t_seg
        changed = False
        while si < sched_t.size and sched_t[si] <= t:
            for j in range(nu):
                if u[j] != sched_u[si, j]:
                    changed = True
                u[j] = sched_u[si, j]
            si += 1
        if at_sample:
            k_sample += 1
            new_on = pump_band(y[Y_PS], pump_on, g)
            if new_on != pump_on:
                changed = True
                pump_on = new_on
        if changed:
            rhs(t, y, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, f, aux, work)
            stats[2] += 1
    return out_y, out_u, y, stats, status, t
