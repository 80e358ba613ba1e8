"""Measures of a pressurise phase, on arrays with a leading batch dimension (B runs, T samples).

One implementation serves a single Result (B = 1) and a sweep's stacked chunk (B = thousands).
All take the shared time grid ``t`` (T,), the charge-valve state ``u_charge`` (B, T) and the times
the charge valve actually opens ``t_open`` (B,) [s]. The definitions are in docs/metrics.md.

Rise time (the one definition used by Result, sweeps, studies and their conclusions)
------------------------------------------------------------------------------------
A muscle whose charge valve stays open settles at the source pressure: Eq. (8) passes air until
the pressure ratio across the valve is 1, and neither the Eq. (9) branch limit nor a tube changes
that end point, only how fast it is reached. So:

* ``p_start``  = muscle pressure when the charge valve opens (command + dead time);
* ``p_target`` = source pressure at the last output sample with the charge valve still open: the
  level the muscle is heading for when the phase ends. (If the valve stayed open longer the source
  would give a little more air and sag a little further, so the true end point is at most this
  high: the target is never set low, and a muscle cannot pass for filled when it is not.) If the
  muscle has settled before the valve closes, its pressure and the source's are equal and the
  target is simply that common steady pressure;
* ``level``    = p_start + fraction * (p_target - p_start)   (fraction = 0.9 for the 90 % rise);
* rise time    = first time the muscle pressure reaches ``level``, minus the opening time, with
  linear interpolation between output samples.

If the muscle does not reach ``level`` while its charge valve is open, the rise time is *not
reached*: NaN here, ``null`` in JSON, with a reason (:func:`rise_reason`); never a clipped number.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frogsim._jit import jit_alloc

# status codes of a rise-time measurement
REACHED = 0
NOT_REACHED = 1          # the valve closed (or the run ended) before the level was reached
NO_RISE = 2              # the source was not above the muscle when the valve closed
NO_PHASE = 3             # no pressurise phase inside the run (valve never opens in it)


def pressurise_window(t, u_charge, t_open):
    """Indices (k0, k_closed, k_last) of one pressurise phase per run.

    k0: first sample at or after the opening; k_closed: first sample after the opening where the
    valve is closed (the end of the run if it never closes); k_last: the last sample with the
    valve still open (k_closed - 1, or the end of the run). Runs whose opening time is NaN or
    after the end of the run get k0 = k_closed = k_last = T - 1.
    """
    k0, kc, kl, _ = _windows(np.asarray(t, float), _rows(u_charge), np.asarray(t_open, float))
    return k0, kc, kl


def valve_closes(t, u_charge, t_open):
    """True where the charge valve closes again inside the run (False: still open at its end)."""
    return _windows(np.asarray(t, float), _rows(u_charge), np.asarray(t_open, float))[3]


def _rows(x):
    return np.ascontiguousarray(x, dtype=float)


@jit_alloc
def _window(t, u, t_open):
    """(k0, k_closed, k_last, closes) of one run (:func:`pressurise_window`): u (T,) its valve."""
    T = t.size
    k0 = T - 1 if t_open != t_open else min(np.searchsorted(t, t_open), T - 1)
    for k in range(T):
        if t[k] > t_open and u[k] < 0.5:
            return k0, k, max(k - 1, k0), True
    return k0, T - 1, T - 1, False


@jit_alloc
def _windows(t, u, t_open):
    B = u.shape[0]
    k0, kc, kl = np.empty(B, np.int64), np.empty(B, np.int64), np.empty(B, np.int64)
    closes = np.empty(B, np.bool_)
    for b in range(B):
        k0[b], kc[b], kl[b], closes[b] = _window(t, u[b], t_open[b])
    return k0, kc, kl, closes


@jit_alloc
def _rise(t, p, p_source, u, t_open, fraction):
    """The rise measurement of one run (module docstring): (seconds, p_start, p_target, level,
    reached, status, closes)."""
    k0, _, k1, closes = _window(t, u, t_open)
    has_phase = np.isfinite(t_open) and t_open <= t[-1]
    p0 = p[k0]
    ptarget = p_source[k1]
    rise = ptarget - p0
    level = p0 + fraction * rise
    best = -np.inf
    hit = -1
    for k in range(k0, k1 + 1):           # the samples with the valve open
        if p[k] != p[k] or best != best:
            best = np.nan
        elif p[k] > best:
            best = p[k]
        if hit < 0 and p[k] >= level:
            hit = k
    reached = (best - p0) / rise if rise > 0 else np.nan
    status = NOT_REACHED
    if hit >= 0:
        status = REACHED
    if not rise > 0:
        status = NO_RISE
    if not has_phase:
        status = NO_PHASE
    j = max(hit, 0)
    jm = max(j - 1, 0)
    pa, pb = p[jm], p[j]
    frac = (level - pa) / (pb - pa) if pb > pa else 1.0
    t_hit = t[j] if j <= k0 else t[jm] + frac * (t[j] - t[jm])
    seconds = max(t_hit - t_open, 0.0) if status == REACHED else np.nan
    return seconds, p0, ptarget, level, reached, status, closes


@jit_alloc
def _rises(t, p, p_source, u, t_open, fraction):
    B = p.shape[0]
    out = np.empty((5, B))
    status = np.empty(B, np.int64)
    closes = np.empty(B, np.bool_)
    for b in range(B):
        (out[0, b], out[1, b], out[2, b], out[3, b], out[4, b],
         status[b], closes[b]) = _rise(t, p[b], p_source[b], u[b], t_open[b], fraction)
    return out, status, closes


@dataclass
class RiseTimes:
    """Rise-time measurement of B runs (see the module docstring); arrays of shape (B,).

    seconds: rise time [s], NaN unless status == REACHED; p_start, p_target, level [Pa abs];
    reached: largest fraction of the rise (p - p_start)/(p_target - p_start) the muscle attained
    while its valve was open; status: REACHED, NOT_REACHED, NO_RISE or NO_PHASE; closes: whether
    the valve closed inside the run; fraction: the rise fraction asked for (0.9).
    """
    seconds: np.ndarray
    p_start: np.ndarray
    p_target: np.ndarray
    level: np.ndarray
    reached: np.ndarray
    status: np.ndarray
    closes: np.ndarray
    fraction: float

    def reason(self, b: int = 0) -> str | None:
        """Why run b has no rise time (None when it has one)."""
        return rise_reason(int(self.status[b]), float(self.reached[b]), bool(self.closes[b]),
                           self.fraction)


def rise_reason(status: int, reached: float, closes: bool = True, fraction: float = 0.9) -> str | None:
    """The reason string for a rise time that is not a number; None when it was reached."""
    if status == REACHED:
        return None
    if status == NO_PHASE:
        return "no pressurise phase in the run"
    if status == NO_RISE:
        return "no rise: the source was not above the muscle when the charge valve closed"
    when = "before the charge valve closed" if closes else "before the run ended (charge valve still open)"
    return f"not reached {when} (reached {100 * reached:.0f} % of the rise, needs {100 * fraction:.0f} %)"


def rise_times(t, p, p_source, u_charge, t_open, fraction=0.9) -> RiseTimes:
    """Rise time to ``fraction`` of the way from the muscle's opening pressure to the source
    pressure at the valve's close (module docstring): p, p_source (B, T) [Pa abs]. Each run is
    measured by one compiled function (:func:`_rise`), the only definition."""
    out, status, closes = _rises(np.asarray(t, float), _rows(p), _rows(p_source), _rows(u_charge),
                                 np.asarray(t_open, float).reshape(-1), float(fraction))
    return RiseTimes(out[0], out[1], out[2], out[3], out[4], status, closes, fraction)


def rise_time(t, p, p_source, u_charge, t_open, fraction=0.9):
    """Rise time [s] per run (:func:`rise_times`), NaN where not reached."""
    return rise_times(t, p, p_source, u_charge, t_open, fraction).seconds


def opened(t, t_open):
    """True where the charge valve opens within the run (a pressurise phase exists)."""
    return np.asarray(t_open, float) <= t[-1]


def charged_in_phase(t, q, u_charge, t_open):
    """Cumulative quantity q (e.g. charged mass) gained between the opening and the closing
    (NaN where the valve does not open within the run)."""
    k0, kc, _ = pressurise_window(t, u_charge, t_open)
    rows = np.arange(q.shape[0])
    return np.where(opened(t, t_open), q[rows, kc] - q[rows, k0], np.nan)


def value_at_close(t, x, u_charge, t_open):
    """x at the last sample with the valve still open (NaN where it does not open within the run)."""
    _, _, k1 = pressurise_window(t, u_charge, t_open)
    return np.where(opened(t, t_open), x[np.arange(x.shape[0]), k1], np.nan)


def fraction_of_window(t, flag, t_start, t_end):
    """Fraction of the time between ``t_start`` and ``t_end`` (B,) [s] during which ``flag``
    (B, T) holds. Each output interval counts with its overlap with the window, weighted by the
    mean of the flag at its two ends; NaN for an empty window."""
    f = np.asarray(flag, float)
    a = np.asarray(t_start, float)[:, None]
    b = np.asarray(t_end, float)[:, None]
    lo = np.maximum(t[None, :-1], a)
    hi = np.minimum(t[None, 1:], b)
    overlap = np.clip(hi - lo, 0.0, None)
    total = overlap.sum(axis=1)
    held = (0.5 * (f[:, 1:] + f[:, :-1]) * overlap).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, held / total, np.nan)


def format_rise(seconds, digits: int = 3) -> str:
    """A rise time for text: "0.081 s", or "not reached" for NaN/None (never a number)."""
    if seconds is None or not np.isfinite(seconds):
        return "not reached"
    return f"{seconds:.{digits}f} s"
