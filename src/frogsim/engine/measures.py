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
    T = t.size
    t_open = np.asarray(t_open, float)
    k0 = np.minimum(np.searchsorted(t, np.nan_to_num(t_open, nan=np.inf)), T - 1)
    closed = (t[None, :] > t_open[:, None]) & (u_charge < 0.5)
    has = closed.any(axis=1)
    first = np.argmax(closed, axis=1)
    k_closed = np.where(has, first, T - 1)
    k_last = np.where(has, np.maximum(first - 1, k0), T - 1)
    return k0, k_closed, k_last


def valve_closes(t, u_charge, t_open):
    """True where the charge valve closes again inside the run (False: still open at its end)."""
    closed = (t[None, :] > np.asarray(t_open, float)[:, None]) & (u_charge < 0.5)
    return closed.any(axis=1)


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
    pressure at the valve's close (module docstring): p, p_source (B, T) [Pa abs]."""
    p = np.asarray(p, float)
    p_source = np.asarray(p_source, float)
    t_open = np.asarray(t_open, float)
    B = p.shape[0]
    rows = np.arange(B)
    k0, _, k1 = pressurise_window(t, u_charge, t_open)
    has_phase = np.isfinite(t_open) & (t_open <= t[-1])
    p0 = p[rows, k0]
    ptarget = p_source[rows, k1]
    rise = ptarget - p0
    level = p0 + fraction * rise
    idx = np.arange(t.size)[None, :]
    inside = (idx >= k0[:, None]) & (idx <= k1[:, None])
    hit = inside & (p >= level[:, None])
    with np.errstate(invalid="ignore", divide="ignore"):
        best = np.where(inside, p, -np.inf).max(axis=1)
        reached = np.where(rise > 0, (best - p0) / rise, np.nan)
    status = np.full(B, NOT_REACHED)
    status[hit.any(axis=1)] = REACHED
    status[~(rise > 0)] = NO_RISE
    status[~has_phase] = NO_PHASE
    j = np.argmax(hit, axis=1)
    jm = np.maximum(j - 1, 0)
    pa, pb = p[rows, jm], p[rows, j]
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(pb > pa, (level - pa) / (pb - pa), 1.0)
        t_hit = np.where(j <= k0, t[j], t[jm] + frac * (t[j] - t[jm]))
    seconds = np.where(status == REACHED, np.maximum(t_hit - t_open, 0.0), np.nan)
    return RiseTimes(seconds, p0, ptarget, level, reached, status,
                     valve_closes(t, u_charge, t_open), fraction)


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
