"""Argument, option and action checks shared by the Gymnasium environments.

Every check raises :class:`frogsim.ScenarioError` (a ``ValueError``) naming the argument, the value
given and what is allowed, before anything is built or stepped:

* :func:`real` a finite real number in a range (never a bool, a complex number, text or NaN);
* :func:`whole` a whole number (an ``int``, never a bool or a float) in a range;
* :func:`options` the keys of ``reset(options=...)``;
* :func:`action` an action that :meth:`gymnasium.spaces.MultiDiscrete.contains` accepts: an array
  (or list) of the space's shape whose entries are whole numbers of an integer dtype within the
  space's bounds; bools, floats (even 1.0) and complex numbers are refused.

:class:`Episode` keeps an environment's episode state: :meth:`Episode.check_step` raises
``gymnasium.error.ResetNeeded`` on a step before the first reset or after the episode ended
(terminated or truncated), as the episode must be reset to go on; after :meth:`Episode.close`
(the environment's ``close()``) a step or a reset raises ``gymnasium.error.ClosedEnvironmentError``.
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Sequence

import numpy as np

from frogsim.errors import ScenarioError


def real(name: str, value, low: float | None = None, high: float | None = None,
         low_open: bool = False, unit: str = "") -> float:
    """value as a float if it is a finite real number within [low, high] (low excluded when
    ``low_open``); ScenarioError naming ``name`` otherwise."""
    u = f" {unit}" if unit else ""
    lo = "" if low is None else (f"> {low:g}{u}" if low_open else f">= {low:g}{u}")
    hi = "" if high is None else f"<= {high:g}{u}"
    bounds = " and ".join(b for b in (lo, hi) if b)
    allowed = "a finite real number" + (f" {bounds}" if bounds else "")
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ScenarioError(name, value, f"expected {allowed}")
    x = float(value)
    if not math.isfinite(x) or (low is not None and (x <= low if low_open else x < low)) or \
            (high is not None and x > high):
        raise ScenarioError(name, value, f"must be {allowed}")
    return x


def whole(name: str, value, low: int, high: int | None = None) -> int:
    """value as an int if it is a whole number (int type) within [low, high]."""
    allowed = f"a whole number >= {low}" + (f" and <= {high}" if high is not None else "")
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise ScenarioError(name, value, f"expected {allowed}")
    k = int(value)
    if k < low or (high is not None and k > high):
        raise ScenarioError(name, value, f"must be {allowed}")
    return k


def options(given, allowed: tuple) -> dict:
    """The reset options as a dict (None -> {}); an unknown key or a non-dict is refused."""
    if given is None:
        return {}
    what = f"the keys {', '.join(map(repr, allowed))}" if allowed else "no keys (this environment takes no options)"
    if not isinstance(given, dict):
        raise ScenarioError("options", given, f"expected a dict with {what}")
    for key in given:
        if key not in allowed:
            raise ScenarioError(f"options[{key!r}]", given[key], f"unknown option; allowed: {what}")
    return dict(given)


def action(space, value, meaning: str) -> np.ndarray:
    """value as an int64 array if ``space.contains(value)`` and no entry is a bool; ScenarioError
    naming the action, its shape and ``meaning`` (what each entry selects) otherwise."""
    bools = isinstance(value, (bool, np.bool_)) or (isinstance(value, np.ndarray) and value.dtype == bool) or \
        (isinstance(value, Sequence) and not isinstance(value, (str, bytes))
         and any(isinstance(x, (bool, np.bool_)) for x in value))
    ok = False
    if not bools:
        try:
            ok = space.contains(value)
        except (TypeError, ValueError):     # ragged lists, objects numpy cannot compare
            ok = False
    if not ok:
        raise ScenarioError("action", value, f"must lie in the action space {space} (an integer array of "
                                             f"shape {space.shape}: {meaning}; bools and floats are refused)")
    return np.asarray(value, dtype=np.int64)


class Episode:
    """Whether an episode is running: none before the first reset, ended once terminated or
    truncated (then a step raises ``gymnasium.error.ResetNeeded`` until the next reset)."""

    def __init__(self):
        self.state = "new"
        self.why = ""

    def start(self) -> None:
        self.check_open("reset")
        self.state = "running"

    def close(self) -> None:
        self.state = "closed"

    def check_open(self, call: str) -> None:
        """``gymnasium.error.ClosedEnvironmentError`` once the environment is closed."""
        from gymnasium.error import ClosedEnvironmentError
        if self.state == "closed":
            raise ClosedEnvironmentError(f"{call}() after close(): the environment is closed; make another "
                                         "with gymnasium.make")

    def end(self, terminated: bool, truncated: bool, why: str) -> None:
        if terminated or truncated:
            self.state, self.why = "ended", why

    def check_step(self) -> None:
        from gymnasium.error import ResetNeeded
        self.check_open("step")
        if self.state == "new":
            raise ResetNeeded("step() before reset(): call reset() to start an episode")
        if self.state == "ended":
            raise ResetNeeded(f"step() after the episode ended ({self.why}): call reset() to start "
                              "another")
