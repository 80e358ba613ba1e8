"""Many variants of one scenario at once, each distinct piece made once.

``Variants(base, points)`` holds, for every point (dotted path -> SI value, as for
:meth:`frogsim.scenario.core.Scenario.replace`), the top-level settings of
``base.replace(point)``, without making one Scenario per point:

* a top-level setting (``source``, ``supply``, ``muscle_types``...) of a variant is made from the
  point's values under it alone (:func:`frogsim.scenario.core._top_change`, the code ``replace``
  runs), so it is made once per distinct combination of those values, checked field by field as
  ``replace`` checks it, and shared by every point with that combination;
* each cross-field rule (:data:`frogsim.scenario.rules.RULES`) and every later step that declares
  the top-level settings it reads (:meth:`Variants.each`) runs once per distinct combination of
  those settings. The step sees them through a :class:`frogsim.scenario.view.Settings`, which
  refuses to read any other, so sharing its answer is exact by construction.

A point that fails anywhere is marked (:attr:`ok`); :meth:`first_failure` is the first such point,
whose error the caller reproduces with ``base.replace(point)`` (the message of the point-by-point
path, word for word).
"""
from __future__ import annotations

import numpy as np

from frogsim.errors import ScenarioError
from frogsim.scenario import rules
from frogsim.scenario.core import Scenario, _parse, _relinked, _top_change, _with, variant_raw
from frogsim.scenario.view import Settings

_PLAIN = (bool, int, float, str, np.generic)


def _codes(column: list) -> np.ndarray:
    """One integer per value, equal exactly where the values are the same value of the same type
    (so 0.0 and -0.0, 1 and 1.0 and True stay apart); other objects by identity."""
    if all(type(v) is float or type(v) is np.float64 for v in column):
        bits = np.array(column, dtype=np.float64).view(np.int64)
        return np.unique(bits, return_inverse=True)[1].reshape(-1)
    seen: dict = {}
    out = np.empty(len(column), np.int64)
    for j, v in enumerate(column):
        key = (type(v), repr(v)) if isinstance(v, _PLAIN) else ("object", id(v))
        out[j] = seen.setdefault(key, len(seen))
    return out


def group(columns: list, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct combinations of integer columns over ``rows``: (combination of each row (len(rows),),
    first row of each combination, as an index into ``rows``)."""
    if not columns or rows.size == 0:
        return np.zeros(rows.size, np.int64), np.zeros(min(1, rows.size), np.int64)
    key = np.zeros(rows.size, np.int64)
    span = 1
    for c in columns:
        c = c[rows]
        m = int(c.max()) + 1
        if span * m >= 2 ** 62:              # too many combinations for one integer key
            stacked = np.stack([col[rows] for col in columns], axis=1)
            _, first, inv = np.unique(stacked, axis=0, return_index=True, return_inverse=True)
            return inv.reshape(-1), first
        key = key * m + c
        span *= m
    _, first, inv = np.unique(key, return_index=True, return_inverse=True)
    return inv.reshape(-1), first


def _content(x):
    """A key equal for two results exactly when they hold the same values (arrays byte for byte,
    numbers by type and repr, so 0.0 and -0.0 differ); other objects by identity."""
    if isinstance(x, np.ndarray):
        return ("array", x.dtype.str, x.shape, x.tobytes())
    if isinstance(x, (tuple, list)):
        return (type(x).__name__,) + tuple(_content(v) for v in x)
    if x is None or isinstance(x, _PLAIN):
        return (type(x), repr(x))
    return ("object", id(x))


class Variants:
    """The variants ``base.replace(point)`` of a list of points that all set the same paths."""

    def __init__(self, base: Scenario, points: list[dict]):
        self.base = base
        self.points = points
        B = self.size = len(points)
        self.ok = np.ones(B, bool)
        self.values = {}       # varied top-level setting -> (distinct values, index of each point's)
        paths = tuple(points[0]) if points else ()
        if any(tuple(pt) != paths for pt in points):
            raise ValueError("Variants needs points that all set the same paths")
        try:
            _parse(points[0] if points else {})
        except ScenarioError:
            self.ok[:] = False
            return
        tops: dict[str, list] = {}
        for p in paths:
            tops.setdefault(p.split(".")[0], []).append(p)
        codes = {p: _codes([pt[p] for pt in points]) for p in paths}
        every = np.arange(B)
        for name, under in tops.items():
            inv, first = group([codes[p] for p in under], every)
            made = []
            for j, r in enumerate(first):
                pt = points[int(r)]
                try:
                    made.append(_top_change(base, name, _parse({p: pt[p] for p in under})[name])[name])
                except ScenarioError:
                    made.append(None)
                    self.ok[inv == j] = False
            self.values[name] = (made, inv)
        if "programs" in tops:      # muscles that use a named program get its present version
            relinked, inv = self.each(("programs", "muscles"), lambda s: _relinked(s.programs, s.muscles))
            self.values["muscles"] = (relinked, inv)
        for names, rule in rules.RULES:
            self.each(names, rule)

    def value(self, name: str, k: int):
        """Top-level setting ``name`` of point k's variant."""
        if name in self.values:
            made, inv = self.values[name]
            return made[inv[k]]
        return getattr(self.base, name)

    def scenario(self, k: int) -> Scenario:
        """The Scenario of point k: equal to ``base.replace(points[k])``, field for field."""
        return _with(self.base, raw=variant_raw(self.base), **{n: made[inv[k]] for n, (made, inv) in self.values.items()})

    def each(self, names: tuple, step, deps: tuple = ()) -> tuple[list, np.ndarray]:
        """Run ``step(Settings of names, *dependencies)`` once per distinct combination of the
        top-level settings ``names`` and of the results ``deps`` ((results, index per point) pairs
        of earlier steps), over the points still valid. Returns (results, index per point; -1 for
        points that failed earlier); a point whose combination raises ScenarioError is marked."""
        rows = np.flatnonzero(self.ok)
        cols = [self.values[n][1] for n in names if n in self.values] + [inv for _, inv in deps]
        inv_rows, first = group(cols, rows)
        out = []
        for j, f in enumerate(first):
            r = int(rows[f])
            try:
                out.append(step(Settings({n: self.value(n, r) for n in names}, names, type(self.base)),
                                *(res[inv[r]] for res, inv in deps)))
            except ScenarioError:
                out.append(None)
                self.ok[rows[inv_rows == j]] = False
        if len(out) > 1:            # results equal in content are one (the next steps read content only)
            merged: dict = {}
            keep, where = [], np.empty(len(out), np.int64)
            for j, x in enumerate(out):
                key = _content(x)
                if key not in merged:
                    merged[key] = len(keep)
                    keep.append(x)
                where[j] = merged[key]
            out, inv_rows = keep, where[inv_rows]
        inv = np.full(self.size, -1, np.int64)
        inv[rows] = inv_rows
        return out, inv

    def first_failure(self) -> int | None:
        """The first point marked invalid (None if every point is valid)."""
        bad = np.flatnonzero(~self.ok)
        return int(bad[0]) if bad.size else None
