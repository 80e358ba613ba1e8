"""Batched pneumatic runs: many scenarios spread over threads.

Every scenario in a batch runs through exactly the same compiled serial code as
:func:`frogsim.simulate` (:func:`frogsim.engine.integrator.run_schedule`, compiled without the GIL),
on a pool of threads (:func:`frogsim._parallel.map_pieces`), so a point's result is bit-for-bit the
same whether it runs alone, in a batch of 10 or of 10,000, and whatever the chunking.

Points are variants of one base scenario (:meth:`frogsim.scenario.core.Scenario.replace`: dotted
path -> SI value). :func:`build_models` makes them all at once (:class:`frogsim.scenario.variants.Variants`):
each top-level setting, cross-field rule and model part (:data:`frogsim.circuit.model.PARTS`) is
made once per distinct combination of the settings it declares it reads (and it can read no
other), so a point's model *is* ``build_model(base.replace(point))``: exact by construction, and
tested array for array. The result, a :class:`ModelBatch`, is a sequence of models made on demand
(:func:`frogsim.circuit.model.assemble`, the last step of build_model); the runners here read the
shared parts directly and never make the 10,000 model objects.

:func:`run_outputs` returns the raw outputs of the runs (:class:`Outputs`, no Result objects) for
code that only reduces them (sweep metrics); :func:`run_models` returns Result objects.
"""
from __future__ import annotations

import threading
from collections.abc import Sequence

import numpy as np

from frogsim._jit import jit_alloc
from frogsim._parallel import default_threads, map_pieces
from frogsim.circuit import layout as L
from frogsim.circuit.model import PARTS, PneumaticModel, assemble, build_model
from frogsim.engine import methods
from frogsim.engine.integrator import STATUS_OK, run_schedule
from frogsim.engine.result import Result
from frogsim.engine.run_result import valve_switchings
from frogsim.errors import ScenarioError, SimulationError
from frogsim.scenario.core import Scenario
from frogsim.scenario.variants import Variants, group

#: what a run reads from its scenario besides the model's arrays
RUN_SETTINGS = ("duration", "controller", "solver")


def run_settings(sc) -> tuple:
    """(end time [s], controller sample time [s], rtol, max step [s], the integration method's
    parameter block) of a run."""
    return (sc.duration, 1.0 / sc.controller.rate, sc.solver.rtol, sc.solver.max_step,
            methods.parameter_block(sc.solver.method))


class ModelBatch(Sequence):
    """The models of variants of one base scenario (see the module docstring).

    ``batch[k]`` is the PneumaticModel of point k, made on demand and equal to
    ``build_model(base.replace(point))`` array for array; a slice is a ModelBatch of those points.
    """

    def __init__(self, variants: Variants, parts: dict, rows: np.ndarray, shared: dict | None = None):
        self.variants = variants
        self.parts = parts            # part name -> (distinct values, index of each point's)
        self.rows = rows
        self._shared = {} if shared is None else shared     # made once per batch, shared by its slices

    def __len__(self) -> int:
        return int(self.rows.size)

    def __getitem__(self, k):
        if isinstance(k, slice):
            return ModelBatch(self.variants, self.parts, self.rows[k], self._shared)
        r = int(self.rows[k])
        return assemble(self.variants.scenario(r), self._parts(r))

    def _parts(self, r: int) -> dict:
        return {n: made[inv[r]] for n, (made, inv) in self.parts.items()}

    def run(self, k: int):
        """The raw run of point k (:func:`run_schedule`'s tuple), from the shared parts."""
        p = self._parts(int(self.rows[k]))
        return _run_parts(p)

    def names(self) -> list:
        """The muscles (the same for every point: a variant cannot add or remove one)."""
        made, inv = self.parts["motion"]
        return list(made[inv[self.rows[0]]][0]) if len(self) else []

    def _stacks(self) -> dict:
        """The distinct parts' arrays stacked, per kind of part and per class of shapes
        (:func:`_stack_parts`); made once per batch."""
        with _LOCK:
            if "stacks" not in self._shared:
                self._shared["stacks"] = _stack_parts(self.parts)
            return self._shared["stacks"]

    def run_columns(self, ycols, ucols) -> tuple[list, dict]:
        """Run every point (compiled, one call per time grid and class of array shapes, without the
        GIL) keeping only state columns ``ycols`` and valve columns ``ucols``: ([(rows, Outputs)],
        {row: error text}), rows indexing this batch."""
        st = self._stacks()
        ycols = np.asarray(ycols, np.int64)
        ucols = np.asarray(ucols, np.int64)
        item = {n: inv[self.rows] for n, (_, inv) in self.parts.items()}
        cls = {k: st[k][0][item[k]] for k in _KINDS}
        within = {k: st[k][1][item[k]] for k in _KINDS}
        which, first = group([cls[k] for k in _KINDS] + [item["out_t"]], np.arange(len(self)))
        groups, failures = [], {}
        for w, f in enumerate(first):
            rows = np.flatnonzero(which == w)
            a = {k: st[k][2][cls[k][f]] for k in _KINDS}
            ix = {k: within[k][rows] for k in _KINDS}
            t = self.parts["out_t"][0][item["out_t"][f]]
            Y = np.empty((ycols.size, rows.size, t.size))
            U = np.empty((ucols.size, rows.size, t.size))
            status = np.empty(rows.size, np.int64)
            t_reached = np.empty(rows.size)
            m, r = a["motion"], a["run"]
            _run_rows(ix["motion"], ix["sched_u"], ix["laws"], ix["state"], ix["g"], ix["run"],
                      a["state"]["y0"], r["t_end"], a["g"]["g"], m["mp"], m["mot_t"], m["mot_L"], m["mot_d"],
                      m["mot_n"], m["sched_t"], a["sched_u"]["sched_u"], m["u0"], r["ctrl_dt"], t, r["rtol"],
                      a["state"]["atol"], r["max_step"], r["par"], a["laws"]["laws"], ycols, ucols, Y, U, status,
                      t_reached)
            ok = status == STATUS_OK
            for j in np.flatnonzero(~ok):
                failures[int(rows[j])] = _failure(int(rows[j]), self.variants.base.name, t_reached[j], status[j])
            keep = slice(None) if ok.all() else ok
            if ok.any():
                g = a["g"]["g"][ix["g"][keep]]
                groups.append((rows[keep], Outputs(t, self.names(), m["t_open"][ix["motion"][keep]], g[:, L.G_PATM],
                                                   g[:, L.G_RHOREF], columns=(ycols, Y[:, keep], ucols, U[:, keep]))))
        return groups, failures

    def point(self, k: int) -> tuple:
        """(name, output times, muscle names, first charge-valve opening per muscle (NaN: none),
        g) of point k."""
        r = int(self.rows[k])
        p = self._parts(r)
        names, motion, _ = p["motion"]
        return self.variants.base.name, p["out_t"], names, _first_opens(motion[7]), p["g"]


_LOCK = threading.Lock()


_KINDS = ("motion", "sched_u", "laws", "state", "g", "run")


def _arrays(kind: str, x) -> dict:
    """The arrays a run takes from one part."""
    if kind == "motion":
        _, m, mp = x
        return {"mp": mp, "mot_t": m[0], "mot_L": m[1], "mot_d": m[2], "mot_n": m[3], "sched_t": m[4],
                "u0": m[6], "t_open": _first_opens(m[7])}
    if kind == "state":
        return {"y0": x[0], "atol": x[1]}
    if kind == "run":
        return {"t_end": np.float64(x[0]), "ctrl_dt": np.float64(x[1]), "rtol": np.float64(x[2]),
                "max_step": np.float64(x[3]), "par": x[4]}
    return {kind: x}


def _stack_parts(parts: dict) -> dict:
    """{kind: (class of each distinct part (D,), its row in its class's stacks (D,), [per class of
    array shapes: {array name: the parts' arrays stacked (rows, ...)}])}."""
    out = {}
    for kind in _KINDS:
        classes: dict = {}
        cls, row, members = [], [], []
        for x in parts[kind][0]:
            arrays = _arrays(kind, x)
            sig = tuple((n, np.shape(a)) for n, a in arrays.items())
            c = classes.setdefault(sig, len(classes))
            if c == len(members):
                members.append([])
            cls.append(c)
            row.append(len(members[c]))
            members[c].append(arrays)
        stacks = [{n: np.ascontiguousarray(np.stack([a[n] for a in mem])) for n in mem[0]} for mem in members]
        out[kind] = (np.array(cls, np.int64), np.array(row, np.int64), stacks)
    return out


@jit_alloc
def _run_rows(im, iu, il, ist, ig, ir, y0, t_end, g, mp, mot_t, mot_L, mot_d, mot_n, sched_t, sched_u, u0,
              ctrl_dt, out_t, rtol, atol, max_step, par, laws, ycols, ucols, Y, U, status, t_reached):
    """Run points one after the other, each from its parts (row im[b] of the motion stacks, iu[b]
    of the schedule states, il[b] of the laws, ist[b] of the initial state, ig[b] of g, ir[b] of
    the run settings), through :func:`run_schedule` exactly as :func:`_run_one` calls it; copy
    state columns ``ycols`` and valve columns ``ucols`` of each run's output to Y[:, b], U[:, b]
    while they are in cache."""
    for b in range(im.size):
        m, v, c, s, q, r = im[b], iu[b], il[b], ist[b], ig[b], ir[b]
        oy, ou, _, _, st, t_r, _, _, _ = run_schedule(
            y0[s], u0[m], 0.0, t_end[r], (g[q], mp[m], mot_t[m], mot_L[m], mot_d[m], mot_n[m]),
            (sched_t[m], sched_u[v], laws[c], ctrl_dt[r]), (rtol[r], atol[s], max_step[r], par[r]), out_t, 1e-4,
            0)
        status[b] = st
        t_reached[b] = t_r
        for i in range(ycols.size):
            j = ycols[i]
            for k in range(out_t.size):
                Y[i, b, k] = oy[k, j]
        for i in range(ucols.size):
            j = ucols[i]
            for k in range(out_t.size):
                U[i, b, k] = ou[k, j]


def _first_opens(opens) -> np.ndarray:
    return np.array([o[0] if len(o) else np.nan for o in opens])


def _run_parts(p: dict):
    names, motion, mp = p["motion"]
    mot_t, mot_L, mot_d, mot_n, sched_t, _, u0, _, _, _ = motion
    laws, sched_u = p["laws"], p["sched_u"]
    y0, atol = p["state"]
    t_end, ctrl_dt, rtol, max_step, par = p["run"]
    return run_schedule(y0, u0, 0.0, t_end, (p["g"], mp, mot_t, mot_L, mot_d, mot_n),
                        (sched_t, sched_u, laws, ctrl_dt), (rtol, atol, max_step, par), p["out_t"], 1e-4, 0)


def build_models(base: Scenario, points: list[dict]):
    """The model of ``base.replace(point)`` for every point (dicts of dotted path -> SI value): a
    :class:`ModelBatch` (a list of models if the points set different paths).

    Raises ScenarioError on the first invalid point, naming it, before anything runs.
    """
    if not points:
        return []
    try:
        variants = Variants(base, points)
    except ValueError:                # points that set different paths: one by one
        return [_one(base, pt, k) for k, pt in enumerate(points)]
    parts: dict = {}
    for name, names, deps, make in PARTS + (("run", RUN_SETTINGS, (), run_settings),):
        parts[name] = variants.each(names, make, tuple(parts[d] for d in deps))
    bad = variants.first_failure()
    if bad is not None:
        _one(base, points[bad], bad)          # raises the point-by-point path's own error
        raise AssertionError(f"point {bad} failed in the batch but not alone")  # pragma: no cover
    return ModelBatch(variants, parts, np.arange(len(points)))


def _one(base: Scenario, pt: dict, k: int) -> PneumaticModel:
    try:
        return build_model(base.replace(pt))
    except ScenarioError as exc:
        shown = ", ".join(f"{p} = {v!r}" for p, v in pt.items()) or "the base scenario"
        raise ScenarioError(exc.field, exc.value, f"{exc.allowed} (in point {k}: {shown})") from None


def _run_one(m: PneumaticModel):
    t_end, ctrl_dt, rtol, max_step, par = run_settings(m.scenario)
    y0, atol = m.start
    sched_t, sched_u, u0, _ = m.schedule
    return run_schedule(y0, u0, 0.0, t_end, m.rhs_model, (sched_t, sched_u, m.laws, ctrl_dt),
                        (rtol, atol, max_step, par), m.out_t, 1e-4, 0)


def _failure(b: int, name: str, t_r: float, status: int) -> str:
    return f"batch point {b} ({name!r}): integration stopped at t = {t_r:.6g} s (status {status})"


def run_models(models, threads: int | None = None) -> list[Result]:
    """Run many models on ``threads`` threads (default: all cores); one Result per model, in order,
    each identical to ``simulate(model)``. Raises SimulationError naming the first failed point."""
    if not len(models):
        return []
    piece = max(1, len(models) // (8 * default_threads(threads)))

    def work(ms):
        if isinstance(ms, ModelBatch):
            return [ms.run(j) for j in range(len(ms))]
        return [_run_one(m) for m in ms]
    raw = [r for part in map_pieces(work, models, piece, threads) for r in part]
    results = []
    for b, (m, (oy, ou, y_end, stats, status, t_r, cs, _, _)) in enumerate(zip(models, raw)):
        if status != STATUS_OK:
            raise SimulationError(_failure(b, m.scenario.name, t_r, status))
        results.append(Result(t=m.out_t, y=oy, u=ou, model=m,
                              stats={"steps": int(stats[0]), "rejected": int(stats[1]),
                                     "rhs_evaluations": int(stats[2]),
                                     "stiff_steps": int(stats[3])},
                              switchings=valve_switchings(m.laws, m.names, cs)))
    return results


class Outputs:
    """The raw outputs of B runs on one time grid, for code that reduces them (no Result objects).

    ``t`` (T,) the grid [s]; ``names`` the muscles; ``t_open`` (B, n) the first opening time of
    each muscle's charge valve (NaN: it never opens); ``patm``, ``rho_ref`` (B,) the atmospheric
    pressure [Pa] and reference density [kg/m^3]. The series (:mod:`frogsim.circuit.layout`) are
    either every run's whole outputs (``y``, ``u``: lists of (T, state size) and (T, 2n + 1)
    arrays) or only some columns (``columns`` = (state columns, (k, B, T) array, valve columns,
    (k', B, T) array)); :meth:`state` and :meth:`valve` give a column of every run as (B, T).
    """

    def __init__(self, t, names, t_open, patm, rho_ref, y=None, u=None, columns=None):
        self.t, self.names = t, list(names)
        self.t_open, self.patm, self.rho_ref = t_open, patm, rho_ref
        self.y, self.u = y, u
        if columns is not None:
            ycols, self._Y, ucols, self._U = columns
            self._ycol = {int(j): k for k, j in enumerate(ycols)}
            self._ucol = {int(j): k for k, j in enumerate(ucols)}

    @classmethod
    def of_results(cls, results) -> "Outputs":
        """The outputs of Results sharing one time grid."""
        t_open = np.array([_first_opens(r.model.charge_open_times) for r in results])
        return cls(results[0].t, results[0].names, t_open, np.array([r.model.g[L.G_PATM] for r in results]),
                   np.array([r.model.g[L.G_RHOREF] for r in results]), [r.y for r in results], [r.u for r in results])

    def state(self, j: int) -> np.ndarray:
        """State column j of every run, (B, T)."""
        if self.y is not None:
            return np.stack([y[:, j] for y in self.y])
        return self._Y[self._kept(self._ycol, j, "state")]

    def valve(self, j: int) -> np.ndarray:
        """Valve (or pump) column j of every run, (B, T)."""
        if self.u is not None:
            return np.stack([u[:, j] for u in self.u])
        return self._U[self._kept(self._ucol, j, "valve")]

    def final_state(self, j: int) -> np.ndarray:
        """State column j of every run at the end of the run, (B,)."""
        if self.y is not None:
            return np.array([y[-1, j] for y in self.y])
        return self.state(j)[:, -1]

    @staticmethod
    def _kept(cols: dict, j: int, what: str) -> int:
        if j not in cols:
            raise KeyError(f"{what} column {j} was not kept by this run (kept: {sorted(cols)})")
        return cols[j]


def run_outputs(models, columns: tuple | None = None) -> tuple[list, dict]:
    """Run models one after the other on this thread and keep only their raw outputs.

    Returns ([(rows, Outputs) per time grid], {row: error text of a run that failed}); rows index
    ``models``. The same compiled runs as :func:`run_models`, bit for bit. ``columns`` = (state
    columns, valve columns) keeps only those (a ModelBatch then runs in one compiled call per
    time grid); None keeps everything.
    """
    lean = isinstance(models, ModelBatch)
    if lean and columns is not None and len(models):
        return models.run_columns(*columns)
    grids: dict = {}
    failures = {}
    for b in range(len(models)):
        if lean:
            raw = models.run(b)
            name, t, names, t_open, g = models.point(b)
        else:
            m = models[b]
            raw = _run_one(m)
            name, t, names, t_open, g = m.scenario.name, m.out_t, m.names, _first_opens(m.charge_open_times), m.g
        oy, ou, _, _, status, t_r = raw[:6]
        if status != STATUS_OK:
            failures[b] = _failure(b, name, t_r, status)
            continue
        # one group per distinct time grid (grids of the same length and end can still differ:
        # 1 s at 0.2 s and at 0.237 s both have six rows)
        same = grids.setdefault((t.size, float(t[-1])), [])
        grid = next((gr for gr in same if gr[0] is t or np.array_equal(gr[0], t)), None)
        if grid is None:
            grid = [t, names, [], [], [], [], [], []]
            same.append(grid)
        grid[2].append(b)
        grid[3].append(oy)
        grid[4].append(ou)
        grid[5].append(t_open)
        grid[6].append(g[L.G_PATM])
        grid[7].append(g[L.G_RHOREF])
    groups = [(np.array(rows), Outputs(t, names, np.array(opens), np.array(patm), np.array(rho), ys, us))
              for same in grids.values() for t, names, rows, ys, us, opens, patm, rho in same]
    return groups, failures
