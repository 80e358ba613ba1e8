"""Measures of a pressurise phase, on arrays with a leading batch dimension (B runs, T samples).

One implementation serves a single Result (B = 1) and a sweep's stacked chunk (B = thousands).
All take the shared time grid ``t`` (T,), the charge-valve state ``u_charge`` (B, T) and the times
the charge valve actually opens ``t_open`` (B,) [s].

A run that ends before its charge valve opens (``t_open`` after the last sample, or NaN) has no
pressurise phase: every measure is NaN for it (never an index past the end of the run).
"""
from __future__ import annotations

import numpy as np


def pressurise_window(t, u_charge, t_open):
    """Indices (k0, k_closed, k_last) of one pressurise phase per run.

    k0: first sample at or after the opening; k_closed: first sample after the opening where the
    valve is closed (the end of the run if it never closes); k_last: the last sample with the
    valve still open (k_closed - 1, or the end of the run).
    """
    T = t.size
    k0 = np.minimum(np.searchsorted(t, t_open), T - 1)    # no opening within the run: see opened()
    closed = (t[None, :] > t_open[:, None]) & (u_charge < 0.5)
    has = closed.any(axis=1)
    first = np.argmax(closed, axis=1)
    k_closed = np.where(has, first, T - 1)
    k_last = np.where(has, first - 1, T - 1)
    return k0, k_closed, k_last


def opened(t, t_open):
    """True where the charge valve opens within the run (a pressurise phase exists)."""
    return np.asarray(t_open, float) <= t[-1]


def rise_time(t, p, u_charge, t_open, fraction=0.9):
    """Time [s] from the valve opening until p first reaches ``fraction`` of its rise over the
    phase (rise = p at the last open sample - p at the opening); linear interpolation between
    samples; NaN where the pressure does not rise or the valve does not open within the run."""
    B = p.shape[0]
    k0, _, k1 = pressurise_window(t, u_charge, t_open)
    rows = np.arange(B)
    p0 = p[rows, k0]
    p1 = p[rows, k1]
    target = p0 + fraction * (p1 - p0)
    idx = np.arange(t.size)[None, :]
    hit = (idx >= k0[:, None]) & (idx <= k1[:, None]) & (p >= target[:, None])
    valid = hit.any(axis=1) & (p1 > p0)
    j = np.argmax(hit, axis=1)
    jm = np.maximum(j - 1, 0)
    pa, pb = p[rows, jm], p[rows, j]
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(pb > pa, (target - pa) / (pb - pa), 1.0)
    t_hit = np.where(j == k0, t[j], t[jm] + frac * (t[j] - t[jm]))
    return np.where(valid & opened(t, t_open), t_hit - t_open, np.nan)


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
