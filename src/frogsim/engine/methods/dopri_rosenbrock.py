"""The default integration method, "dopri-rosenbrock": adaptive Dormand-Prince 5(4), with a
switch to a modified Rosenbrock triple where Hairer's stiffness test finds the circuit stiff.

Dormand and Prince (1980), coefficients as in Hairer, Norsett and Wanner, Solving ODEs I, Table
5.2; error norm as in Hairer's DOPRI5 (RMS of the error weighted by atol + rtol max(|y|, |yn|));
step control: Hairer's PI controller (:func:`frogsim.engine.stepsize.pi_next`). Dense output:
Dormand and Prince's continuous extension of order 4 (Hairer's DOPRI5 coefficients d1..d7), which
needs no extra right-hand-side evaluations. On stiff stretches (a muscle resting against the
source or the exhaust through an open valve, time constant ~2 ms, where the explicit method is
held to its stability limit): Shampine and Reichelt's modified Rosenbrock triple (ode23s; SIAM J.
Sci. Comput. 18, 1997), L-stable, order 2 with a 3rd-order error estimate, under the elementary
controller of that order (:func:`frogsim.engine.stepsize.order_next`), and back to Dormand-Prince
when accuracy, not stability, holds its steps, or when a command changes (a transient follows).

Settings: the ``[solver]`` section's ``rtol`` (which also scales the state's absolute
tolerances, ``PneumaticModel.atol``) and ``max_step`` [s]; none of its own. Its memory between
steps (the stiffness count, the switch step, the Jacobian's age) is in the driver state's method
columns D_M0.. and its Jacobian df/dy and df/dt in the kept entries ``keep``, so that a run can
pause and resume between any two steps.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from frogsim._jit import jit_inner, jit_step
from frogsim.circuit.layout import muscle_count, physical_size
from frogsim.circuit.rhs import rhs
from frogsim.engine.methods.spec import D_M0, IntegrationMethod, StepControl
from frogsim.engine.stepsize import EXPO, order_next, pi_next, propose_adaptive, shrink
from frogsim.scenario.methods import MethodSettings

CODE = 1.0

# --- its memory: the driver state's method columns ------------------------------------------------------
D_STIFF = D_M0       # 1: steps by the Rosenbrock method (the circuit found stiff), 0: Dormand-Prince
D_NSTIFF = D_M0 + 1  # stiffness test: accepted Dormand-Prince steps at the stability limit so far
D_NONSTIFF = D_M0 + 2   # ... and steps below it since the last one at it
D_HSWITCH = D_M0 + 3    # the Dormand-Prince step [s] when the method switched to Rosenbrock
D_NBACK = D_M0 + 4      # Rosenbrock steps in a row proposing less than D_HSWITCH
D_JAC_AGE = D_M0 + 5    # Rosenbrock steps since its Jacobian was made (-1: none; every Dormand-Prince
#                         step sets it, so the first Rosenbrock step always makes one)

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


@dataclass(frozen=True)
class DopriRosenbrockSettings(MethodSettings):
    """The default method: no settings of its own (it reads ``solver.rtol`` and
    ``solver.max_step``)."""
    METHOD = "dopri-rosenbrock"


# --- the method's side of the driver's protocol (frogsim.engine.methods.spec) ------------------------------
@jit_inner
def step(t, h, t_new, y, f, yn, fn, u, pump_on, model, atol, rtol, par, ds, own, rc, mat, kmat, kvec, aux, work, stats):
    """One trial step: Rosenbrock's when the run is on a stiff stretch (ds[D_STIFF]), with a fresh
    Jacobian after JAC_EVERY steps or a rejected one, otherwise Dormand-Prince's. Returns (err,
    num, den, dense_ready): the error norm, the stiffness test's two norms (a Dormand-Prince
    step; 0 for Rosenbrock) and whether the continuous extension is made (Rosenbrock's is)."""
    if ds[D_STIFF] > 0.5:
        fresh = ds[D_JAC_AGE] < 0 or ds[D_JAC_AGE] >= JAC_EVERY
        wk = (mat, own[6], own[7], own[8], own[9], own[10], own[11], own[12], own[13], kmat, kvec)
        err = _rosenbrock_step(t, h, t_new, y, f, u, pump_on, model, atol, rtol, physical_size(muscle_count(y.size)),
                               wk, fresh, yn, fn, rc[0], rc[1], rc[2], rc[3], aux, work, stats)
        ds[D_JAC_AGE] = 1.0 if fresh else ds[D_JAC_AGE] + 1.0
        if not err <= 1.0:
            ds[D_JAC_AGE] = -1.0      # a rejected step: a fresh Jacobian for the retry
        return err, 0.0, 0.0, True
    ds[D_JAC_AGE] = -1.0              # a later stiff stretch makes its own
    stages = (own[0], own[1], own[2], own[3], own[4], fn, own[5], yn)
    err, num, den = _dopri_step(t, h, t_new, y, f, u, pump_on, model, atol, rtol, stages, aux, work, stats)
    return err, num, den, False


@jit_inner
def dense(h, y, yn, f, fn, own, rc1, rc2, rc3, rc4):
    """The continuous extension of a Dormand-Prince step (:func:`_dopri_dense`, from the stages
    the step left in the method's rows); a Rosenbrock step makes its own with the step."""
    _dopri_dense(h, y, yn, f, own[1], own[2], own[3], own[4], fn, rc1, rc2, rc3, rc4)


@jit_step
def accepted(ds, par, h, err, err_old, num, den, refresh, stats):
    """After an accepted step of length h: the stiffness test (a Dormand-Prince step) or the count
    of Rosenbrock steps (stats[3]); the explicit method again when a command changed in the step;
    the next step by the PI controller (Dormand-Prince) or the order-2 controller (Rosenbrock),
    and back to Dormand-Prince after BACK_AFTER Rosenbrock steps proposing less than the step
    it switched at. Returns (h_next, err_old)."""
    stiff = ds[D_STIFF] > 0.5
    if stiff:
        stats[3] += 1
    else:
        _stiffness_test(ds, h, num, den)
    if refresh:
        # commands changed (or the step was cut): a transient ahead, the explicit method again
        _explicit_again(ds)
    if stiff:
        h_next = order_next(h, err, 1.0 / 3.0)
        # back to Dormand-Prince where it would be held to smaller steps by accuracy
        # than by stability
        ds[D_NBACK] = ds[D_NBACK] + 1.0 if h_next < ds[D_HSWITCH] else 0.0
        if ds[D_NBACK] >= BACK_AFTER:
            _explicit_again(ds)
        return h_next, err_old
    return pi_next(h, err, err_old)


@jit_step
def rejected(ds, par, h, err):
    """After a rejected step: :func:`frogsim.engine.stepsize.shrink` with the exponent of the
    step's error estimate (1/3 Rosenbrock's, the PI exponent Dormand-Prince's)."""
    return shrink(h, err, 1.0 / 3.0 if ds[D_STIFF] > 0.5 else EXPO)


def warm(a) -> list:
    """The parts of a first run's compilation (:mod:`frogsim.engine.warmup`): the LU solve and the
    continuous extension (they need nothing), then the two steps, each for the arguments
    :func:`step` and :func:`dense` pass them."""
    ny = a["y"].size
    wk = (a["mat"],) + a["own"][6:14] + (a["kmat"], a["kvec"])
    stages = a["own"][:8]
    common = (a["t"], a["h"], a["t"] + a["h"], a["y"], a["f"], a["u"], a["pump_on"], a["model"], a["atol"], a["rtol"])
    return [
        ("lu", (), "the LU solve", [(_lu, (a["mat"], a["y"])), (_lu_solve, (a["mat"], a["y"], a["f"]))]),
        ("dense", (), "the Dormand-Prince continuous extension",
         [(_dopri_dense, (a["h"], a["y"], a["yn"], a["f"]) + a["own"][1:5] + (a["fn"],) + a["rc"])]),
        ("rosenbrock", ("rhs", "lu"), "the Rosenbrock step",
         [(_rosenbrock_step, common + (ny, wk, True, a["y"], a["f"], a["f"], a["f"], a["f"], a["f"], a["aux"],
                                       a["work"], a["stats"]))]),
        ("dopri", ("rhs",), "the Dormand-Prince step",
         [(_dopri_step, common + (stages, a["aux"], a["work"], a["stats"]))]),
    ]


METHOD = IntegrationMethod(settings=DopriRosenbrockSettings, code=CODE, step=step, dense=dense,
                           control=StepControl(propose=propose_adaptive, accepted=accepted, rejected=rejected),
                           order=5, vectors=14, restart=_explicit_again, warm=warm)
