"""Adaptive Dormand-Prince 5(4) integration of the circuit, segment by segment.

Valve states are piecewise constant: they change only at known times (open-loop commands sampled
on the controller grid plus the valve dead time) or at controller samples when a state-dependent
rule (the pump's pressure band, :mod:`frogsim.control.sampled`) is active. The integrator stops
exactly at those times, so no step straddles a discontinuity; between them the step size adapts
to the error estimate and carries over from one segment to the next. :func:`advance` is the one
loop that does this, for the pneumatics-only engine (:func:`run_schedule`, one call per run) and
the coupled engine (:mod:`frogsim.engine.coupled_kernel`, one call per MuJoCo step).

Method: Dormand and Prince (1980), coefficients as in Hairer, Norsett and Wanner, Solving ODEs I,
Table 5.2; error norm and step control as in Hairer's DOPRI5 (safety 0.9, factor limits 0.2..5).
Step control: Hairer's PI controller (exponent 0.2 - 0.75 beta, beta = 0.04).
Dense output: Dormand and Prince's continuous extension of order 4 (Hairer's DOPRI5 coefficients
d1..d7), which needs no extra right-hand-side evaluations.
"""
from __future__ import annotations

import math

import numpy as np
from frogsim._jit import jit, jit_alloc, jit_step

from frogsim.circuit.layout import muscle_count, physical_size
from frogsim.circuit.rhs import rhs
from frogsim.control.sampled import (CS_PUMP, apply_due, next_due_time, next_sample_time, sample_controllers,
                                    start_controllers)

STATUS_OK = 0
STATUS_STEP_UNDERFLOW = 1
STATUS_NOT_FINITE = 2
STATUS_MAX_STEPS = 3
STATUS_PAUSED = 4        # stopped after ds[D_PAUSE] accepted steps, to be resumed (not a failure)
STATUS_NONPHYSICAL = 5   # an accepted step left an air mass or pressure <= 0 (or NaN): ds[D_T], y show it
STATUS_ROWS_UNWRITTEN = 6  # the run reached its end with output rows it never wrote (a grid past the end)
STATUS_TEXT = {STATUS_STEP_UNDERFLOW: "step size fell below 1e-14 s",
               STATUS_NOT_FINITE: "the state became non-finite (NaN or inf)",
               STATUS_MAX_STEPS: "more than 50 million steps",
               STATUS_NONPHYSICAL: "an air mass or pressure became zero or negative",
               STATUS_ROWS_UNWRITTEN: "the run ended with output rows it never wrote (an output time "
                                      "past the end of the run)"}

# --- driver state ds[:] (see advance) ----------------------------------------------------------------
D_T = 0          # time reached [s]
D_H = 1          # next trial step [s]
D_ERR = 2        # PI step control: error norm of the last accepted step
D_SI = 3         # index of the next valve-schedule entry
D_OUT = 4        # next output row
D_PAUSE = 5      # > 0: pause once this many steps are accepted in all (stats[0]); 0: never
D_STIFF = 6      # 1: steps by the Rosenbrock method (the circuit found stiff), 0: Dormand-Prince
D_NSTIFF = 7     # stiffness test: accepted Dormand-Prince steps at the stability limit so far
D_NONSTIFF = 8   # ... and steps below it since the last one at it
D_HSWITCH = 9    # the Dormand-Prince step [s] when the method switched to Rosenbrock
D_NBACK = 10     # Rosenbrock steps in a row proposing less than D_HSWITCH
D_JAC_AGE = 11   # Rosenbrock steps since its Jacobian was made (-1: none); J, df/dt follow D_SIZE
D_F_VALID = 12   # 1: dy/dt at (ds[D_T], y) is kept after J and df/dt (written by every call that ends well)
D_REUSE_F = 13   # 1: the caller changed nothing that dy/dt reads since the last call: start from the kept one
D_SIZE = 14
STATS_SIZE = 4   # stats[:]: accepted steps, rejected steps, rhs evaluations, accepted Rosenbrock steps
EPS = 1e-12      # [s] stop times closer than this are one stop (they come from different sums)

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
# stiffness switch (Hairer's DOPRI5 test): h |lambda| estimated from the last two stages
STIFF_HLAMBDA = 3.25         # the Dormand-Prince stability boundary on the negative real axis
STIFF_AFTER = 6              # steps at the boundary before the switch to Rosenbrock
NONSTIFF_RESET = 6           # steps below it that clear the count
BACK_AFTER = 3               # Rosenbrock steps below the switch step before switching back
JAC_EVERY = 8                # Rosenbrock steps on one finite-difference Jacobian at most
# Shampine and Reichelt's modified Rosenbrock triple (ode23s; SIAM J. Sci. Comput. 18, 1997)
RB_D = 1.0 / (2.0 + math.sqrt(2.0))
RB_E32 = 6.0 + math.sqrt(2.0)
SQRT_EPS = 1.4901161193847656e-08


@jit_step
def _lu(a, piv):
    """In-place LU factorisation with partial pivoting of the small dense matrix a (n x n), the
    row swaps in piv (row indices, stored as floats); returns False if a pivot is zero (a is
    singular)."""
    n = a.shape[0]
    for k in range(n):
        p = k
        big = abs(a[k, k])
        for i in range(k + 1, n):
            if abs(a[i, k]) > big:
                big = abs(a[i, k])
                p = i
        piv[k] = float(p)
        if big == 0.0:
            return False
        if p != k:
            for j in range(n):
                tmp = a[k, j]
                a[k, j] = a[p, j]
                a[p, j] = tmp
        inv = 1.0 / a[k, k]
        for i in range(k + 1, n):
            a[i, k] *= inv
            m = a[i, k]
            if m != 0.0:
                for j in range(k + 1, n):
                    a[i, j] -= m * a[k, j]
    return True


@jit_step
def _lu_solve(a, piv, b):
    """Solve a x = b in place (b becomes x) with the factors of :func:`_lu`."""
    n = a.shape[0]
    for k in range(n):
        p = int(piv[k])
        if p != k:
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
    for i in range(n):
        acc = b[i]
        for j in range(i):
            acc -= a[i, j] * b[j]
        b[i] = acc
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= a[i, j] * b[j]
        b[i] = acc / a[i, i]


@jit_step
def _rosenbrock_step(t, h, t_new, y, f0, u, pump_on, model, atol, rtol, nphys, wk, fresh, yn, fn,
                     rc1, rc2, rc3, rc4, aux, work, stats):
    """One step of the modified Rosenbrock triple of Shampine and Reichelt (1997, Sec. 3; MATLAB's
    ode23s) from (t, y), dy/dt = f0: L-stable, order 2 with a 3rd-order error estimate, for the
    stiff stretches of a run (a muscle resting against the source or the exhaust through an open
    valve, time constant ~2 ms, where an explicit method is held to its stability limit):

        W = I - h d J,  d = 1/(2 + sqrt 2),  e32 = 6 + sqrt 2,  T = df/dt
        k1 = W^-1 (f0 + h d T)
        f1 = f(t + h/2, y + h/2 k1);   k2 = W^-1 (f1 - k1) + k1
        y1 = y + h k2;   f2 = f(t + h, y1)
        k3 = W^-1 (f2 - e32 (k2 - f1) - 2 (k1 - f0) + h d T);   error = h/6 (k1 - 2 k2 + k3)

    J = df/dy by forward differences over the first ``nphys`` states (the masses and pressures:
    the right-hand side does not read the cumulative masses after them), T by a forward difference
    in t, both made when ``fresh`` and otherwise kept from an earlier step: the formula for y1 is a
    W-method (Wolfbrandt's; its order 2 holds for any matrix in W, which the expansion of k1, k2
    to O(h^2) shows), so a Jacobian a few steps old costs accuracy of the error estimate only, and
    the driver renews it every JAC_EVERY steps and after every rejected step. Dense output (Sec. 3 of the paper): y(t + s h) = y + h [s(1-s) k1 + s(s-2d) k2] / (1-2d),
    written in the Dormand-Prince interpolant's form (rc1 = h k2, rc2 = h (k1 - k2)/(1-2d),
    rc3 = rc4 = 0). Writes y1 into yn and f(t_new, y1) into fn; returns the error norm (inf if W
    is singular). ``wk`` = (W, piv, ft, k1, k2, k3, yt, f1, tder, J, T)."""
    J, piv, ft, k1, k2, k3, yt, f1, tder, Jd, Td = wk
    g, mp, mot_t, mot_L, mot_d, mot_n = model
    ny = y.size
    if fresh:
        # df/dy (columns of the masses and pressures) and df/dt by forward differences, kept in
        # Jd, Td for the steps that follow (a W-method: order 2 with any matrix in W)
        for j in range(ny):
            yt[j] = y[j]
        for c in range(ny):
            if c < nphys:
                dc = SQRT_EPS * max(abs(y[c]), atol[c] / rtol)
                yt[c] = y[c] + dc
                rhs(t, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, ft, aux, work)
                yt[c] = y[c]
                inv = 1.0 / dc
                for r in range(ny):
                    Jd[r, c] = (ft[r] - f0[r]) * inv
            else:
                for r in range(ny):
                    Jd[r, c] = 0.0
        dt = SQRT_EPS * max(abs(t), h)
        rhs(t + dt, y, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, ft, aux, work)
        for j in range(ny):
            Td[j] = (ft[j] - f0[j]) / dt
        stats[2] += nphys + 1
    for r in range(ny):
        for c in range(ny):
            J[r, c] = -h * RB_D * Jd[r, c]
        J[r, r] += 1.0
        tder[r] = h * RB_D * Td[r]
    stats[2] += 2
    if not _lu(J, piv):                   # J now holds W = I - h d J, factorised
        return math.inf
    for j in range(ny):
        k1[j] = f0[j] + tder[j]
    _lu_solve(J, piv, k1)
    for j in range(ny):
        yt[j] = y[j] + 0.5 * h * k1[j]
    rhs(t + 0.5 * h, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, f1, aux, work)
    for j in range(ny):
        k2[j] = f1[j] - k1[j]
    _lu_solve(J, piv, k2)
    for j in range(ny):
        k2[j] += k1[j]
        yn[j] = y[j] + h * k2[j]
    rhs(t_new, yn, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, fn, aux, work)
    for j in range(ny):
        k3[j] = fn[j] - RB_E32 * (k2[j] - f1[j]) - 2.0 * (k1[j] - f0[j]) + tder[j]
    _lu_solve(J, piv, k3)
    err = 0.0
    a = 1.0 / (1.0 - 2.0 * RB_D)
    for j in range(ny):
        e = h / 6.0 * (k1[j] - 2.0 * k2[j] + k3[j])
        sc = atol[j] + rtol * max(abs(y[j]), abs(yn[j]))
        err += (e / sc) ** 2
        rc1[j] = yn[j] - y[j]
        rc2[j] = h * a * (k1[j] - k2[j])
        rc3[j] = 0.0
        rc4[j] = 0.0
    return math.sqrt(err / ny)


@jit_step
def ds_size(ny):
    """Length of the driver state ds for a state of ny entries: the D_* columns, then the
    Rosenbrock Jacobian df/dy (ny x ny) and df/dt (ny), then the kept dy/dt (ny), then the
    scratch space of :func:`advance` (:func:`_scratch_size`; its contents are not carried from one
    call to the next)."""
    return D_SIZE + ny * ny + 2 * ny + _scratch_size(ny)


@jit_step
def _scratch_size(ny):
    """Entries of advance's scratch space for a state of ny entries: 22 stage vectors, the
    Rosenbrock matrix (ny x ny), the previous valve states (2n) and the right-hand side's aux
    (2n + 1) and work (4n) vectors, n the muscles of a state of ny entries
    (:func:`frogsim.circuit.layout.muscle_count`)."""
    n = muscle_count(ny)
    return 22 * ny + ny * ny + 2 * n + 6 * n + 1


@jit_step
def _dense(y, rc1, rc2, rc3, rc4, th, out):
    """The continuous extension at th in [0, 1] of the step: out = y(t + th h)."""
    th1 = 1.0 - th
    for j in range(y.size):
        out[j] = y[j] + th * (rc1[j] + th1 * (rc2[j] + th * (rc3[j] + th1 * rc4[j])))


@jit_step
def _stiffness_test(ds, h, num, den):
    """Hairer's stiffness test for DOPRI5 (Hairer and Wanner, Solving ODEs II, Sec. IV.2), on an
    accepted step: h |lambda| ~ h ||k7 - k6|| / ||yn - y6|| (the last two stages are at the same
    time, so their difference quotient estimates the dominant eigenvalue), in the error norm's
    weights (num and den: the two squared norms, summed with the error norm). STIFF_AFTER steps
    at the stability boundary (STIFF_HLAMBDA) without NONSTIFF_RESET steps below it in between
    switch the run to the Rosenbrock method."""
    if den > 0.0 and h * math.sqrt(num / den) > STIFF_HLAMBDA:
        ds[D_NSTIFF] += 1.0
        ds[D_NONSTIFF] = 0.0
        if ds[D_NSTIFF] >= STIFF_AFTER:
            ds[D_STIFF] = 1.0
            ds[D_HSWITCH] = h
            ds[D_NBACK] = 0.0
    else:
        ds[D_NONSTIFF] += 1.0
        if ds[D_NONSTIFF] >= NONSTIFF_RESET:
            ds[D_NSTIFF] = 0.0


@jit_step
def _dopri_dense(h, y, yn, f, k3, k4, k5, k6, k7, rc1, rc2, rc3, rc4):
    """Coefficients of the Dormand-Prince step's 4th-order continuous extension (Hairer's DOPRI5
    d1..d7; no extra right-hand-side evaluations), for :func:`_dense`."""
    for j in range(y.size):
        ydiff = yn[j] - y[j]
        bspl = h * f[j] - ydiff
        rc1[j] = ydiff
        rc2[j] = bspl
        rc3[j] = ydiff - h * k7[j] - bspl
        rc4[j] = h * (D1 * f[j] + D3 * k3[j] + D4 * k4[j] + D5 * k5[j] + D6 * k6[j] + D7 * k7[j])


@jit_step
def _explicit_again(ds):
    """Back to Dormand-Prince with a fresh stiffness count (after a command change: a transient
    follows; or when the Rosenbrock steps have become accuracy-limited)."""
    ds[D_STIFF] = 0.0
    ds[D_NSTIFF] = 0.0
    ds[D_NONSTIFF] = 0.0
    ds[D_NBACK] = 0.0


@jit_step
def _dopri_step(t, h, t_new, y, f, u, pump_on, model, atol, rtol, stages, aux, work, stats):
    """One Dormand-Prince 5(4) trial step from (t, y), whose dy/dt is f, to t_new = t + h (passed
    so that a step that ends a piece ends on it exactly). ``stages`` = (k2, k3, k4, k5, k6, k7, yt,
    yn) receive the stages, the sixth stage's argument (yt) and the 5th-order solution yn; k7 is
    dy/dt at (t_new, yn) (first same as last). Returns (err, num, den): the error norm (Hairer's
    DOPRI5 norm, RMS of the weighted error) and the two squared norms of :func:`_stiffness_test`."""
    g, mp, mot_t, mot_L, mot_d, mot_n = model
    k2, k3, k4, k5, k6, k7, yt, yn = stages
    ny = y.size
    for j in range(ny):
        yt[j] = y[j] + h * A21 * f[j]
    rhs(t + C2 * h, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k2, aux, work)
    for j in range(ny):
        yt[j] = y[j] + h * (A31 * f[j] + A32 * k2[j])
    rhs(t + C3 * h, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k3, aux, work)
    for j in range(ny):
        yt[j] = y[j] + h * (A41 * f[j] + A42 * k2[j] + A43 * k3[j])
    rhs(t + C4 * h, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k4, aux, work)
    for j in range(ny):
        yt[j] = y[j] + h * (A51 * f[j] + A52 * k2[j] + A53 * k3[j] + A54 * k4[j])
    rhs(t + C5 * h, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k5, aux, work)
    for j in range(ny):
        yt[j] = y[j] + h * (A61 * f[j] + A62 * k2[j] + A63 * k3[j] + A64 * k4[j] + A65 * k5[j])
    rhs(t + h, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k6, aux, work)
    for j in range(ny):
        yn[j] = y[j] + h * (B1 * f[j] + B3 * k3[j] + B4 * k4[j] + B5 * k5[j] + B6 * k6[j])
    rhs(t_new, yn, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k7, aux, work)
    stats[2] += 6
    err = 0.0
    num = 0.0
    den = 0.0
    for j in range(ny):
        e = h * (E1 * f[j] + E3 * k3[j] + E4 * k4[j] + E5 * k5[j] + E6 * k6[j] + E7 * k7[j])
        w = 1.0 / (atol[j] + rtol * max(abs(y[j]), abs(yn[j])))
        err += (e * w) ** 2
        num += ((k7[j] - k6[j]) * w) ** 2        # the stiffness test's norms
        den += ((yn[j] - yt[j]) * w) ** 2
    return math.sqrt(err / ny), num, den


@jit_step
def _samples_in_step(laws, mp, cs, t, t_new, h, y, f, stages, dense, ys, u, dense_ready):
    """The controllers' samples t_k inside an accepted step (t, t_new] of length h, in order,
    each taken from the step's continuous extension (``dense`` = rc1..rc4; made here from the
    Dormand-Prince stages f, ``stages`` when ``dense_ready`` is False and a sample needs it) into
    ys, or from the step's solution yn (``stages[7]``) at t_new. A sample whose command acts at
    once ends the step at t_k; a queued command due before the step's end ends it at its due time
    (see :func:`advance`).

    Returns (t_cut, refresh, dense_ready): where the step ends, whether a command changed, and
    whether the continuous extension has been made.
    """
    _, k3, k4, k5, k6, k7, _, yn = stages
    rc1, rc2, rc3, rc4 = dense
    t_cut = t_new
    refresh = False
    t_s = next_sample_time(laws, cs)
    while t_s <= t_cut + EPS:
        if t_s >= t_new - EPS:
            t_s = t_new
            for j in range(y.size):
                ys[j] = yn[j]
        else:
            if not dense_ready:
                _dopri_dense(h, y, yn, f, k3, k4, k5, k6, k7, rc1, rc2, rc3, rc4)
                dense_ready = True
            _dense(y, rc1, rc2, rc3, rc4, (t_s - t) / h, ys)
        if sample_controllers(laws, mp, t_s, ys, u, cs):
            refresh = True
            if t_s < t_new - EPS:
                t_cut = t_s
                break
        t_due = next_due_time(laws, cs)
        if t_due < t_cut - EPS:
            t_cut = max(t_due, t)
        t_s = next_sample_time(laws, cs)
    return t_cut, refresh, dense_ready


@jit_step
def _accept(ds, laws, mp, cs, t, t_new, h, err, err_old, stiff, st_num, st_den, y, f, stages, dense, ys, u, u_prev,
            pump_on, out, out_i, stats):
    """An accepted step of length h from t to t_new (error norm err; the previous one err_old):
    the stiffness test (a Dormand-Prince step), the controllers' samples inside the step
    (:func:`_samples_in_step`; the step may end early at t_cut), the output rows it covers (from
    the continuous extension ``dense``), y and f moved on (f = dy/dt at the step's end, k7, unless
    a command changed), the physical check, and the next step size (Rosenbrock's order-2
    controller, or the PI controller of Dormand-Prince).

    Returns (t, h_next, err_old, pump_on, out_i, refresh, status): the time reached, the proposed
    next step, the PI memory, the pump's switch, the next output row, whether a command changed
    (the caller evaluates dy/dt again; the explicit method is set again here) and a STATUS_* code
    (STATUS_NONPHYSICAL when an air mass or pressure is no longer positive; the rest is then
    not done).
    """
    _, k3, k4, k5, k6, k7, _, yn = stages        # yn: the step's solution at t_new
    rc1, rc2, rc3, rc4 = dense
    out_t, out_y, out_u = out
    ny = y.size
    nu = u.size
    n_out = out_t.size
    n = nu // 2
    status = STATUS_OK
    h_try = h
    refresh = False
    # the continuous extension on (t, t_new] (rc1..rc4), for the controllers'
    # samples and the output rows inside the step: Rosenbrock's is made with the
    # step, Dormand-Prince's only when one of them falls inside it (a step that ends
    # on its sample, as every coupled-engine step does, needs none)
    dense_ready = stiff
    if not stiff:
        _stiffness_test(ds, h_try, st_num, st_den)
    # -- the controllers' samples inside the step, read from the dense output. A
    # command that acts at once (the pump's switch, a valve without dead time) or a
    # valve command that comes due before t_new ends the step there: the state at
    # that time is the continuous extension's, the rest of the step is dropped.
    for j in range(nu):
        u_prev[j] = u[j]
    pump_prev = pump_on
    t_cut, refresh, dense_ready = _samples_in_step(laws, mp, cs, t, t_new, h_try, y, f, stages, dense, ys, u,
                                                   dense_ready)
    if not dense_ready and (t_cut < t_new - EPS or (out_i < n_out and out_t[out_i] <= t_cut)):
        _dopri_dense(h_try, y, yn, f, k3, k4, k5, k6, k7, rc1, rc2, rc3, rc4)
    if t_cut < t_new - EPS:
        # the step ends at t_cut (a sample that changed a command, or a due time)
        _dense(y, rc1, rc2, rc3, rc4, (t_cut - t) / h_try, yn)
        t_new = t_cut
        apply_due(laws, t_new, u, cs)
        refresh = True
    pump_on = cs[CS_PUMP]
    while out_i < n_out and out_t[out_i] <= t_new:
        th = (out_t[out_i] - t) / h_try
        _dense(y, rc1, rc2, rc3, rc4, th, out_y[out_i])
        for j in range(nu):
            out_u[out_i, j] = u_prev[j]
        out_u[out_i, nu] = pump_prev
        out_i += 1
    for j in range(ny):
        y[j] = yn[j]
        f[j] = k7[j]
    t = t_new
    stats[0] += 1
    if stiff:
        stats[3] += 1
    for j in range(physical_size(n)):
        if not y[j] > 0.0:          # every air mass and pressure; NaN fails too
            status = STATUS_NONPHYSICAL
    if status != STATUS_OK:
        return t, h_try, err_old, pump_on, out_i, refresh, status
    if refresh:
        # commands changed (or the step was cut): a transient ahead, the explicit method again
        _explicit_again(ds)
    if stiff:
        h_next = h_try * min(5.0, max(0.2, SAFETY * max(err, 1e-10) ** (-1.0 / 3.0)))
        # back to Dormand-Prince where it would be held to smaller steps by accuracy
        # than by stability
        ds[D_NBACK] = ds[D_NBACK] + 1.0 if h_next < ds[D_HSWITCH] else 0.0
        if ds[D_NBACK] >= BACK_AFTER:
            _explicit_again(ds)
    else:
        e = max(err, 1e-4)
        fac = min(10.0, max(0.2, SAFETY * e ** -EXPO * err_old ** BETA))
        err_old = e
        h_next = h_try * fac
    return t, h_next, err_old, pump_on, out_i, refresh, status


@jit_alloc
def start(t0, h0, y, u, mp, commands):
    """Driver state ``ds`` and controller state ``cs`` of a run that starts at t0.

    ``commands`` = (sched_t, sched_u, laws, ctrl_dt); ``mp`` the model's muscle rows (a law that
    models the valves reads their constants there). The schedule entries due at t0 are written
    into u, the controllers take the sample at or just before t0 (:func:`frogsim.control.sampled
    .start_controllers`), the first trial step is h0 [s].
    """
    sched_t, sched_u, laws, ctrl_dt = commands
    ds = np.zeros(ds_size(y.size))
    ds[D_JAC_AGE] = -1.0
    ds[D_T] = t0
    ds[D_H] = h0
    ds[D_ERR] = 1e-4
    si = 0
    while si < sched_t.size and sched_t[si] <= t0 + EPS:
        for j in range(u.size):
            if sched_u[si, j] == sched_u[si, j]:      # NaN: a valve under closed-loop control
                u[j] = sched_u[si, j]
        si += 1
    ds[D_SI] = si
    return ds, start_controllers(laws, mp, t0, y, u, ctrl_dt)


@jit
def advance(t_end, y, u, ds, cs, model, commands, solver, out, stats):
    """Advance the circuit's state y from ds[D_T] to t_end: the one stepping loop of frogsim.

    The span is cut at every valve-schedule time and at every due time of a queued valve command
    (:func:`frogsim.control.sampled.next_due_time`), times closer than EPS to each other or to
    t_end counting as one. Each piece is integrated by adaptive Dormand-Prince steps with the
    valve states u and the pump's switch held, the last step shortened to end on the piece's end
    exactly; the step size carries over from piece to piece. At a piece's end the schedule
    entries and the queued commands due are written into u, and if a command changed the
    right-hand side is evaluated again (the FSAL derivative no longer holds).

    Controller samples are not stops. After each accepted step the samples t_k inside it
    (:func:`frogsim.control.sampled.next_sample_time`) are taken in order from the step's
    continuous extension (:func:`frogsim.control.sampled.sample_controllers`). A sample whose
    command acts at once (the pump's switch, a valve without dead time), or whose valve command
    comes due before the step's end, ends the step there: the state at that time is the
    continuous extension's (as an event-locating solver restarts from its interpolant) and the
    rest of the step is dropped. Steps are therefore as long as accuracy allows while the
    controllers hold their commands, and commands still change only at t_k (plus dead time).
    The Python-controller driver (:func:`frogsim.engine.pneumatic.run_python_controller`) calls
    this with t_end on every sample, so there each sample is a step's end.

    dy/dt is evaluated at entry: the caller may have changed the model since the last call. A
    caller that changed nothing dy/dt reads at (t, y) sets ds[D_REUSE_F] = 1, and the call starts
    from the dy/dt the last call ended with (kept in ds; the coupled engine, whose new length path
    starts with the old one's value and slope). Time reached, step size, PI
    memory, schedule index and output row are carried in ``ds`` (columns D_*), the controllers'
    memory and the pump's switch in ``cs``, so a run can be advanced in as many calls as wanted:
    the coupled engine calls this once per MuJoCo step, :func:`run_schedule` once for the run.

    ``model`` = (g, mp, mot_t, mot_L, mot_d, mot_n), the right-hand side's circuit and length
    paths; ``commands`` = (sched_t, sched_u, laws, ctrl_dt); ``solver`` = (rtol, atol, max_step);
    ``out`` = (out_t, out_y, out_u): the rows from ds[D_OUT] on whose times fall inside the span
    are filled by dense output (state, valve states and the pump's switch); ``stats``
    accumulates [accepted steps, rejected steps, rhs evaluations, accepted Rosenbrock steps].

    With ds[D_PAUSE] > 0 the call returns STATUS_PAUSED once stats[0] has reached it, after an
    accepted step inside a piece or at a piece's end (after its commands); calling again goes on
    with exactly the steps an uninterrupted call would take, since dy/dt, evaluated again at
    entry, is a pure function of t, y, u and cs (the caller's clock and progress bar live between
    the calls).

    Returns a STATUS_* code; on failure ds[D_T] and y are the last accepted step's.
    """
    if stats.size < STATS_SIZE or ds.size < ds_size(y.size):
        raise ValueError("advance: stats needs STATS_SIZE entries and ds D_SIZE + ny^2 + 2 ny (make them with "
                         "begin or start)")
    g, mp, mot_t, mot_L, mot_d, mot_n = model
    sched_t, sched_u, laws, ctrl_dt = commands
    rtol, atol, max_step = solver
    ny = y.size
    nu = u.size
    ns = sched_t.size
    n = mp.shape[0]
    # the scratch space at ds's end, cut into the stages' vectors (views, no copies): nothing is
    # allocated per call (the coupled engine calls this once per MuJoCo step)
    scratch = ds[D_SIZE + ny * ny + 2 * ny:]
    vectors = scratch[:22 * ny].reshape((22, ny))         # 22 stage vectors of ny entries
    f, k2, k3, k4, k5, k6, k7, yt, yn = (vectors[0], vectors[1], vectors[2], vectors[3], vectors[4], vectors[5],
                                         vectors[6], vectors[7], vectors[8])
    rc1, rc2, rc3, rc4, ys = vectors[9], vectors[10], vectors[11], vectors[12], vectors[13]
    # Rosenbrock: (W, pivots, ft, k1, k2, k3, yt, f1, tder, J, T); J and T (df/dy, df/dt) live in
    # ds after D_SIZE, with their age ds[D_JAC_AGE], so that a pause keeps them
    wk = (scratch[22 * ny:22 * ny + ny * ny].reshape((ny, ny)), vectors[14], vectors[15], vectors[16], vectors[17],
          vectors[18], vectors[19], vectors[20], vectors[21], ds[D_SIZE:D_SIZE + ny * ny].reshape((ny, ny)),
          ds[D_SIZE + ny * ny:D_SIZE + ny * ny + ny])
    stages = (k2, k3, k4, k5, k6, k7, yt, yn)
    dense = (rc1, rc2, rc3, rc4)
    o = 22 * ny + ny * ny
    u_prev = scratch[o:o + nu]
    aux = scratch[o + nu:o + nu + 2 * n + 1]
    work = scratch[o + nu + 2 * n + 1:o + nu + 6 * n + 1]
    nphys = physical_size(n)
    t = ds[D_T]
    h = ds[D_H]
    err_old = ds[D_ERR]
    out_i = int(ds[D_OUT])
    status = STATUS_OK
    pump_on = cs[CS_PUMP]
    f_kept = ds[D_SIZE + ny * ny + ny:D_SIZE + ny * ny + 2 * ny]
    if ds[D_REUSE_F] > 0.5 and ds[D_F_VALID] > 0.5:
        for j in range(ny):
            f[j] = f_kept[j]
    else:
        rhs(t, y, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, f, aux, work)
        stats[2] += 1
    ds[D_F_VALID] = 0.0
    while t < t_end - EPS:
        # -- the piece's end: t_end, the next schedule entry or the next queued valve command ----
        t_seg = t_end
        si = int(ds[D_SI])
        if si < ns and sched_t[si] < t_end - EPS:
            t_seg = max(sched_t[si], t)
        t_due = next_due_time(laws, cs)
        if t_due < t_seg - EPS:
            t_seg = max(t_due, t)
        # -- Dormand-Prince steps from t to exactly t_seg ---------------------------------------
        while t < t_seg:
            if h > max_step:
                h = max_step
            last = False
            h_try = h
            if t + h_try >= t_seg:
                h_try = t_seg - t
                last = True
            t_new = t_seg if last else t + h_try
            stiff = ds[D_STIFF] > 0.5
            st_num = 0.0
            st_den = 0.0
            if stiff:
                fresh = ds[D_JAC_AGE] < 0 or ds[D_JAC_AGE] >= JAC_EVERY
                err = _rosenbrock_step(t, h_try, t_new, y, f, u, pump_on, model, atol, rtol, nphys, wk, fresh,
                                       yn, k7, rc1, rc2, rc3, rc4, aux, work, stats)
                ds[D_JAC_AGE] = 1.0 if fresh else ds[D_JAC_AGE] + 1.0
                if not err <= 1.0:
                    ds[D_JAC_AGE] = -1.0      # a rejected step: a fresh Jacobian for the retry
            else:
                ds[D_JAC_AGE] = -1.0          # a later stiff stretch makes its own
                err, st_num, st_den = _dopri_step(t, h_try, t_new, y, f, u, pump_on, model, atol, rtol, stages,
                                                  aux, work, stats)
            if not math.isfinite(err):
                # a non-finite trial: shrink hard and retry; give up only at step underflow
                stats[1] += 1
                h = 0.1 * h_try
                if h < 1e-14 * max(1.0, abs(t)):
                    status = STATUS_NOT_FINITE
                    break
                continue
            if err <= 1.0:
                t, h_next, err_old, pump_on, out_i, refresh, status = _accept(
                    ds, laws, mp, cs, t, t_new, h_try, err, err_old, stiff, st_num, st_den, y, f, stages, dense, ys, u,
                    u_prev, pump_on, out, out_i, stats)
                if status != STATUS_OK:
                    break
                if refresh:
                    # commands changed (or the step was cut): dy/dt at the new point under them
                    rhs(t, y, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, f, aux, work)
                    stats[2] += 1
                h = max(h, h_next) if (last and t >= t_seg) else h_next
                if t < t_seg:
                    # a sample in the step may have queued a command due before the piece's end
                    t_due = next_due_time(laws, cs)
                    if t_due < t_seg - EPS:
                        t_seg = max(t_due, t)
                if t < t_seg and ds[D_PAUSE] > 0 and stats[0] >= ds[D_PAUSE]:
                    # a pause inside a piece: everything the next call needs is in y, ds and cs
                    # (dy/dt is a pure function of them), so pausing changes no step
                    status = STATUS_PAUSED
                    break
            else:
                stats[1] += 1
                h = h_try * max(0.2, SAFETY * err ** (-1.0 / 3.0 if stiff else -EXPO))
                if h < 1e-14 * max(1.0, abs(t)):
                    status = STATUS_STEP_UNDERFLOW
                    break
            if stats[0] + stats[1] > 50_000_000:
                status = STATUS_MAX_STEPS
                break
        if status != STATUS_OK:
            break
        # -- at t_seg: the schedule's commands due and the queued valve commands due ------------
        t = t_seg
        changed = False
        while si < ns and sched_t[si] <= t + EPS:
            for j in range(nu):
                if sched_u[si, j] != sched_u[si, j]:
                    continue            # NaN: the valve is a closed-loop controller's, not the schedule's
                if u[j] != sched_u[si, j]:
                    changed = True
                u[j] = sched_u[si, j]
            si += 1
        ds[D_SI] = si
        if apply_due(laws, t, u, cs):
            changed = True
        if changed:
            _explicit_again(ds)               # (before a pause: ds carries it to the next call)
        if ds[D_PAUSE] > 0 and stats[0] >= ds[D_PAUSE] and t < t_end - EPS:
            status = STATUS_PAUSED            # between pieces: the next call starts the next one
            break
        if changed:
            rhs(t, y, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, f, aux, work)
            stats[2] += 1
    ds[D_T] = t
    ds[D_H] = h
    ds[D_ERR] = err_old
    ds[D_OUT] = out_i
    if status == STATUS_OK or status == STATUS_PAUSED:
        for j in range(ny):
            f_kept[j] = f[j]
        ds[D_F_VALID] = 1.0
    return status


@jit_alloc
def begin(y0, t0, u0, mp, laws, sched_t, sched_u, ctrl_dt, out_t, h0):
    """Everything a run from t0 needs before its first :func:`advance`: output arrays (the rows at
    or before t0 hold the initial state), the state and valve vectors, the driver and controller
    states, the step statistics and the commands tuple. ``laws`` is the run's table of sampled
    laws (``PneumaticModel.laws``: the pump's band and the closed-loop controllers), ``mp`` the
    model's muscle rows (the valves' constants a law's valve model reads)."""
    ny = y0.size
    nu = u0.size
    n_out = out_t.size
    out_y = np.empty((n_out, ny))
    out_u = np.empty((n_out, nu + 1))
    stats = np.zeros(STATS_SIZE, dtype=np.int64)
    y = y0.copy()
    u = u0.copy()
    commands = (sched_t, sched_u, laws, ctrl_dt)
    ds, cs = start(t0, h0, y, u, mp, commands)
    out_i = 0
    while out_i < n_out and out_t[out_i] <= t0:
        for j in range(ny):
            out_y[out_i, j] = y[j]
        for j in range(nu):
            out_u[out_i, j] = u[j]
        out_u[out_i, nu] = cs[CS_PUMP]
        out_i += 1
    ds[D_OUT] = out_i
    return out_y, out_u, y, u, ds, cs, stats, commands


@jit_step
def finished_status(status, ds, n_out):
    """A run's final status: STATUS_ROWS_UNWRITTEN in place of STATUS_OK when the run reached its
    end but its output row counter ds[D_OUT] stopped short of the n_out rows (empty rows left
    uninitialised are never returned as results)."""
    if status == STATUS_OK and ds[D_OUT] < n_out:
        return STATUS_ROWS_UNWRITTEN
    return status


@jit_alloc
def run_schedule(y0, u0, t0, t_end, model, commands, solver, out_t, h0, pause_every):
    """Integrate from t0 to t_end under an open-loop valve schedule and the run's sampled laws
    (the pump's band and the closed-loop controllers, ``PneumaticModel.laws``): :func:`begin`, then
    one :func:`advance`, whose groups it takes: ``model`` = (g, mp, mot_t, mot_L, mot_d, mot_n),
    ``commands`` = (sched_t, sched_u, laws, ctrl_dt), ``solver`` = (rtol, atol, max_step).

    ``sched_t`` (sorted) are the times at which valve states become ``sched_u[k]``; before the
    first, ``u0`` holds. Entries may repeat the current state: they only make the integrator stop
    there (used for kinks in the prescribed motion). Output rows at out_t (sorted); the rows at or
    before t0 hold the initial state. ``pause_every`` > 0 pauses after that many accepted steps
    (STATUS_PAUSED; go on with :func:`advance` and the returned u, ds, cs); 0 never pauses.

    Returns (out_y, out_u, y_end, stats, status, t_reached, cs, u, ds).
    """
    sched_t, sched_u, laws, ctrl_dt = commands
    out_y, out_u, y, u, ds, cs, stats, commands = begin(y0, t0, u0, model[1], laws, sched_t, sched_u, ctrl_dt,
                                                        out_t, h0)
    ds[D_PAUSE] = pause_every
    status = advance(t_end, y, u, ds, cs, model, commands, solver, (out_t, out_y, out_u), stats)
    status = finished_status(status, ds, out_t.size)
    return out_y, out_u, y, stats, status, ds[D_T], cs, u, ds
