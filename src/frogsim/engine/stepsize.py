"""Step-size control: where the next step ends, and how long the one after an accepted or a
rejected step is. Shared by the integration methods (:mod:`frogsim.engine.methods`), each of which
declares the control it steps under (:class:`frogsim.engine.methods.spec.StepControl`); the
driver (:func:`frogsim.engine.integrator.advance`) calls the declared control through its
dispatch, so no method's accept carries it.

Two controls:

* adaptive (:data:`ADAPTIVE`): the trial step is the carried step size h, at most ``max_step``
  and shortened to end on the piece's end exactly; after an accepted step Hairer's PI controller
  (Hairer, Norsett and Wanner, Solving ODEs I, Sec. II.4, and Hairer's DOPRI5: safety 0.9, factor
  limits 0.2..10, exponents 0.2 - 0.75 beta and beta = 0.04, for an error estimate of order 5)
  proposes the next; after a rejected one the elementary controller h err^(-1/(q+1)), never
  below 0.2 h (:func:`shrink`);
* fixed (:data:`FIXED`): steps of the method's ``step`` on the grid t_k = k step from t = 0, a
  step cut short only where a piece ends between two grid points (a valve's switching time, a
  queued command's due time, the end of the call); nothing is ever rejected, and a non-finite
  step stops the run (:data:`frogsim.engine.integrator.STATUS_NOT_FINITE`).

Units: times and steps in s; error norms are weighted RMS norms (1 = the tolerance).
"""
from __future__ import annotations

import math

from frogsim._jit import jit_step

SAFETY = 0.9
BETA = 0.04                  # PI step control (Hairer's DOPRI5 default)
EXPO = 0.2 - 0.75 * BETA     # ... for an error estimate of order 4 (a 5(4) pair: 1/(4+1) = 0.2)
EPS = 1e-12                  # [s] stop times closer than this are one stop (they come from different sums)


@jit_step
def propose_adaptive(par, t, t_seg, h, max_step):
    """The adaptive trial step from t: h at most ``max_step``, shortened to end on ``t_seg``
    exactly (then ``last``). Returns (h, h_try, t_new, last): the carried step size (held to
    ``max_step``), the step, where it ends (t_seg itself when last, so that a piece ends on its
    end exactly) and whether it is the piece's last."""
    if h > max_step:
        h = max_step
    last = False
    h_try = h
    if t + h_try >= t_seg:
        h_try = t_seg - t
        last = True
    t_new = t_seg if last else t + h_try
    return h, h_try, t_new, last


@jit_step
def pi_next(h, err, err_old):
    """Hairer's PI step-size controller (DOPRI5) after an accepted step of length h with error norm
    err, the previous accepted step's err_old: h fac, fac = 0.9 err^-(0.2 - 0.75 beta)
    err_old^beta within 0.2..10, the error norm counted at least 1e-4. Returns (h_next, the
    error norm to keep for the next step)."""
    e = max(err, 1e-4)
    fac = min(10.0, max(0.2, SAFETY * e ** -EXPO * err_old ** BETA))
    return h * fac, e


@jit_step
def order_next(h, err, expo):
    """The elementary controller after an accepted step: h 0.9 err^-expo within 0.2..5
    (expo = 1/(q+1) for an error estimate of order q), the error norm counted at least 1e-10."""
    return h * min(5.0, max(0.2, SAFETY * max(err, 1e-10) ** (-expo)))


@jit_step
def shrink(h, err, expo):
    """The step after a rejected one of length h with error norm err > 1: h 0.9 err^-expo, never
    below 0.2 h; after a non-finite trial (err inf or NaN) 0.1 h."""
    if not math.isfinite(err):
        return 0.1 * h
    return h * max(0.2, SAFETY * err ** (-expo))


@jit_step
def accepted_pi(ds, par, h, err, err_old, a1, a2, refresh, stats):
    """The adaptive control after an accepted step: :func:`pi_next`. Returns (h_next, err_old)."""
    return pi_next(h, err, err_old)


@jit_step
def rejected_pi(ds, par, h, err):
    """The adaptive control after a rejected step: :func:`shrink` with the PI exponent."""
    return shrink(h, err, EXPO)


@jit_step
def propose_grid(par, t, t_seg, h, max_step):
    """The fixed step from t: to the next point of the grid k par[1] (par[1] the method's step
    [s]; a point within EPS of t is t's own), or to ``t_seg`` when that comes first (within EPS:
    a piece's end at a grid point is that point). Returns (h, h_try, t_new, last) as
    :func:`propose_adaptive` does (h, the carried step size, unchanged)."""
    step = par[1]
    t_grid = (math.floor((t + EPS) / step) + 1.0) * step
    if t_grid >= t_seg - EPS:
        return h, t_seg - t, t_seg, True
    return h, t_grid - t, t_grid, False


@jit_step
def accepted_fixed(ds, par, h, err, err_old, a1, a2, refresh, stats):
    """The fixed control after a step: the step stays the method's (par[1])."""
    return par[1], err_old


@jit_step
def rejected_fixed(ds, par, h, err):
    """A fixed-step method rejects nothing; a non-finite step (err inf or NaN) returns 0, which
    stops the run (the driver's step underflow: STATUS_NOT_FINITE)."""
    return 0.0
