"""Metrics recorded per sweep point: name -> vectorised function, with its unit and meaning.

A metric receives a :class:`Chunk` (the stacked outputs of many runs on one time grid) and the
index of the muscle it looks at, and returns one value per run. The per-run Result methods use
the same measure functions (:mod:`frogsim.engine.measures`), so a sweep's numbers equal those of
``frogsim.simulate`` point by point. Register more with :func:`register_metric`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from frogsim._parallel import map_pieces

from frogsim.circuit import layout as L
from frogsim.engine.measures import charged_in_phase, rise_times, value_at_close

BAR = 1e5


class Chunk:
    """Outputs of B runs sharing one time grid, stacked column by column on demand.

    Made from :class:`frogsim.engine.batch.Outputs` (the raw outputs of a batch, or of Results:
    :meth:`Outputs.of_results`), so a sweep and a Result are measured by the same code.
    ``t`` (T,) is the grid; ``state(j)`` and ``valve(j)`` give state column j and valve column j
    of every run as (B, T); ``t_open`` (B, n) are the first opening times of each charge valve;
    ``patm`` and ``rho_ref`` (B,) the atmospheric pressure and reference density of each run.
    Only the columns a metric asks for are copied.
    """

    def __init__(self, out):
        self.out = out
        self.t = out.t
        self.n = len(out.names)
        self.t_open = out.t_open
        self.patm = out.patm
        self.rho_ref = out.rho_ref
        self._cache = {}

    def state(self, j):
        key = ("y", j)
        if key not in self._cache:
            self._cache[key] = self.out.state(j)
        return self._cache[key]

    def valve(self, j):
        key = ("u", j)
        if key not in self._cache:
            self._cache[key] = self.out.valve(j)
        return self._cache[key]

    def final_state(self, j):
        return self.out.final_state(j)

    def pressure(self, i):
        return self.state(L.pressure_index(i))

    def charge_valve(self, i):
        return self.valve(L.charge_valve(i))


@dataclass(frozen=True)
class Metric:
    name: str
    unit: str
    description: str
    compute: Callable  # (chunk, muscle index) -> (B,)
    columns: Callable | None = None   # (muscles n, muscle index) -> (state columns, valve columns) it reads


METRICS: dict[str, Metric] = {}


def register_metric(name: str, unit: str, description: str, columns: Callable | None = None):
    """Decorator adding a metric function (chunk, muscle index) -> array (B,) to the registry.

    ``columns(n, i)`` -> (state columns, valve columns) names the output columns it reads, so a
    sweep keeps only those of each run (a column it reads but did not name raises KeyError); None:
    every run keeps all its outputs for it."""
    def deco(fn):
        METRICS[name] = Metric(name, unit, description, fn, columns)
        return fn
    return deco


def kept_columns(metrics: list[str], n: int, i: int) -> tuple[list, list]:
    """(state columns, valve columns) the metrics read for muscle i of n."""
    ys, us = set(), set()
    for m in metrics:
        cols = METRICS[m].columns
        if cols is None:
            return list(range(L.state_size(n))), list(range(L.flows_size(n)))
        y, u = cols(n, i)
        ys.update(y)
        us.update(u)
    return sorted(ys), sorted(us)


def _rise_cols(n, i):
    return (L.pressure_index(i), L.Y_PS), (L.charge_valve(i),)


def _rise(c: Chunk, i: int):
    key = ("rise", i)
    if key not in c._cache:
        c._cache[key] = rise_times(c.t, c.pressure(i), c.state(L.Y_PS), c.charge_valve(i), c.t_open[:, i], 0.9)
    return c._cache[key]


@register_metric("rise_time", "s", "time from the charge valve opening until the muscle pressure first "
                 "reaches 90 % of the way from its opening pressure to the source pressure at the "
                 "valve's close; NaN (a gap) where it does not get there while the valve is open", _rise_cols)
def _rise_time(c: Chunk, i: int):
    return _rise(c, i).seconds


@register_metric("rise_reached", "1", "largest fraction of that rise (muscle pressure from its opening "
                 "value to the source pressure at the close) reached while the charge valve was open; "
                 ">= 0.9 exactly where rise_time is a number", _rise_cols)
def _rise_reached(c: Chunk, i: int):
    return _rise(c, i).reached


@register_metric("final_pressure", "bar (gauge)", "muscle pressure when the first pressurise phase ends",
                 lambda n, i: ((L.pressure_index(i),), (L.charge_valve(i),)))
def _final_pressure(c: Chunk, i: int):
    return (value_at_close(c.t, c.pressure(i), c.charge_valve(i), c.t_open[:, i]) - c.patm) / BAR


@register_metric("aeration_volume", "L (standard)", "air charged into the muscle in its first pressurise phase",
                 lambda n, i: ((L.charged_index(i, n),), (L.charge_valve(i),)))
def _aeration(c: Chunk, i: int):
    q = c.state(L.charged_index(i, c.n))
    return charged_in_phase(c.t, q, c.charge_valve(i), c.t_open[:, i]) / c.rho_ref * 1e3


@register_metric("source_drop", "bar", "largest fall of the source pressure below its initial value",
                 lambda n, i: ((L.Y_PS,), ()))
def _source_drop(c: Chunk, i: int):
    ps = c.state(L.Y_PS)
    return (ps[:, 0] - ps.min(axis=1)) / BAR


@register_metric("source_final", "bar (gauge)", "source pressure at the end of the run",
                 lambda n, i: ((L.Y_PS,), ()))
def _source_final(c: Chunk, i: int):
    return (c.final_state(L.Y_PS) - c.patm) / BAR


@register_metric("air_used", "L (standard)", "air charged into all muscles over the run",
                 lambda n, i: (tuple(L.charged_index(j, n) for j in range(n)), ()))
def _air_used(c: Chunk, i: int):
    q = sum(c.final_state(L.charged_index(j, c.n)) for j in range(c.n))
    return q / c.rho_ref * 1e3


@register_metric("pumped", "L (standard)", "air the pump returned to the source over the run",
                 lambda n, i: ((L.pump_index(n),), ()))
def _pumped(c: Chunk, i: int):
    return c.final_state(L.pump_index(c.n)) / c.rho_ref * 1e3


def _check_names(metrics) -> None:
    unknown = [m for m in metrics if m not in METRICS]
    if unknown:
        raise KeyError(f"unknown metric {unknown[0]!r}; metrics: {', '.join(METRICS)}")


def evaluate(results, metrics: list[str], muscle: str | None = None) -> dict[str, np.ndarray]:
    """Metric values for Results sharing one time grid: name -> array (one value per result)."""
    from frogsim.engine.batch import Outputs
    _check_names(metrics)
    if not results:
        return {m: np.empty(0) for m in metrics}
    t0 = results[0].t
    if any(r.t.shape != t0.shape or not np.array_equal(r.t, t0) for r in results[1:]):
        raise ValueError("evaluate needs results on one time grid; group them by duration and output interval")
    results[0].index(muscle) if muscle else 0          # KeyError naming the muscles
    return evaluate_outputs(Outputs.of_results(results), metrics, muscle)


def evaluate_outputs(out, metrics: list[str], muscle: str | None = None) -> dict[str, np.ndarray]:
    """Metric values of raw outputs on one time grid (:class:`frogsim.engine.batch.Outputs`)."""
    _check_names(metrics)
    if muscle and muscle not in out.names:
        raise KeyError(f"no muscle {muscle!r}; muscles: {', '.join(out.names)}")
    i = out.names.index(muscle) if muscle else 0
    chunk = Chunk(out)
    return {m: np.asarray(METRICS[m].compute(chunk, i), float) for m in metrics}


def evaluate_models(models, metrics: list[str], muscle: str | None = None, threads: int | None = None,
                    chunk: int = 64) -> dict[str, np.ndarray]:
    """Run models and return only their metrics: name -> array, in the order of ``models``.

    Each thread takes ``chunk`` points at a time, runs them (the same compiled engine as
    ``frogsim.simulate``, without the GIL) and reduces their raw outputs to metric values while
    they are still in cache (no Result objects), so memory stays at a few chunks' worth whatever
    the number of points, and one thread's compiled runs overlap the other's reduction. Raises
    SimulationError naming the first point (of its chunk) whose integration failed.
    """
    from frogsim.engine.batch import run_outputs
    from frogsim.errors import SimulationError
    _check_names(metrics)

    def work(piece):
        columns = None
        if hasattr(piece, "names"):          # a ModelBatch: keep only the columns the metrics read
            names = piece.names()
            columns = kept_columns(metrics, len(names), names.index(muscle) if muscle in names else 0)
        groups, failures = run_outputs(piece, columns)
        if failures:
            raise SimulationError(failures[min(failures)])
        vals = {m: np.empty(len(piece)) for m in metrics}
        for rows, out in groups:
            v = evaluate_outputs(out, metrics, muscle)
            for m in metrics:
                vals[m][rows] = v[m]
        return vals
    parts = map_pieces(work, models, chunk, threads)
    return {m: np.concatenate([p[m] for p in parts]) if parts else np.empty(0) for m in metrics}


# --- time series a sweep can store ----------------------------------------------------------------
@dataclass(frozen=True)
class State:
    """A time series that a sweep can store per point: unit, meaning, and how to read it from a
    Result (``get(result, muscle name)``). Muscle states are those of ``record.muscle``."""
    unit: str
    description: str
    get: Callable


STATES: dict[str, State] = {
    "muscle_pressure": State("Pa", "muscle pressure (absolute)", lambda r, m: r.muscle_pressure(m)),
    "muscle_mass": State("kg", "air mass in the muscle", lambda r, m: r.muscle_mass(m)),
    "charged_mass": State("kg", "mass that entered the muscle through its charge valve since t = 0",
                          lambda r, m: r.charged_mass(m)),
    "vented_mass": State("kg", "mass that left the muscle through its discharge valve since t = 0",
                         lambda r, m: r.vented_mass(m)),
    "charge_valve": State("1", "charge valve state (1 = open)", lambda r, m: r.u[:, L.charge_valve(r.index(m))]),
    "discharge_valve": State("1", "discharge valve state (1 = open)",
                             lambda r, m: r.u[:, L.vent_valve(r.index(m))]),
    "source_pressure": State("Pa", "source chamber pressure (absolute)", lambda r, m: r.source_pressure),
    "source_temperature": State("K", "source chamber temperature", lambda r, m: r.temperature("source")),
    "source_mass": State("kg", "air mass in the source chamber", lambda r, m: r.y[:, L.Y_MS]),
    "exhaust_pressure": State("Pa", "exhaust chamber pressure (absolute)", lambda r, m: r.exhaust_pressure),
    "exhaust_mass": State("kg", "air mass in the exhaust chamber", lambda r, m: r.y[:, L.Y_ME]),
    "pumped_mass": State("kg", "mass the pump moved from exhaust to source since t = 0",
                         lambda r, m: r.pumped_mass),
    "pump_on": State("1", "pump running (1) or not (0)", lambda r, m: r.u[:, L.pump_entry(r.n)]),
}
