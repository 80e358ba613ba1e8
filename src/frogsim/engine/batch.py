"""Batched pneumatic runs: many scenarios spread over threads.

Every scenario in a batch runs through exactly the same compiled serial code as
:func:`frogsim.simulate` (:func:`frogsim.engine.integrator.run_schedule`, compiled without the GIL),
on a pool of threads, so a point's result is bit-for-bit the same whether it runs alone, in a batch
of 10 or of 10,000, and whatever the chunking. No second copy of the engine is compiled.

Building thousands of models through the scenario loader would cost far more than running them,
so :func:`compose_models` builds one model per swept value and assembles each point from the
array entries each parameter changes. That is exact when every array entry depends on at most one
swept parameter; it checks this (no two parameters touch the same entry, and a few joint points
built in full match the composed ones) and otherwise builds every point in full.
"""
from __future__ import annotations

import dataclasses
import itertools

import numpy as np
from frogsim.circuit.model import PneumaticModel, build_model
from frogsim.engine.integrator import STATUS_OK, run_schedule
from frogsim.engine.result import Result
from frogsim.errors import SimulationError
from frogsim.io.scenario import scenario_from_raw, with_overrides

# model fields that are arrays of the same shape in every point of a batch
_ARRAYS = ("g", "mp", "mot_t", "mot_L", "mot_d", "mot_n", "sched_t", "sched_u", "u0", "y0", "atol")
# scenario-level scalars the engine reads
_SCALARS = ("duration", "rtol", "max_step", "ctrl_dt")


def _scalars(model: PneumaticModel) -> np.ndarray:
    sc = model.scenario
    return np.array([sc.duration, sc.solver.rtol, sc.solver.max_step, 1.0 / sc.controller.rate])


def _run_one(m: PneumaticModel):
    sc = m.scenario
    return run_schedule(m.y0, 0.0, sc.duration, m.g, m.mp, m.mot_t, m.mot_L, m.mot_d, m.mot_n,
                        m.sched_t, m.sched_u, m.u0, 1.0 / sc.controller.rate, m.out_t, sc.solver.rtol,
                        m.atol, sc.solver.max_step, 1e-4)


def run_models(models: list[PneumaticModel], threads: int | None = None) -> list[Result]:
    """Run many models on ``threads`` threads (default: all cores); one Result per model, in order,
    each identical to ``simulate(model)``. Raises SimulationError naming the first failed point."""
    import os
    from concurrent.futures import ThreadPoolExecutor
    if not models:
        return []
    threads = max(1, threads or os.cpu_count() or 1)
    if threads == 1 or len(models) == 1:
        raw = [_run_one(m) for m in models]
    else:
        with ThreadPoolExecutor(threads) as pool:
            raw = list(pool.map(_run_one, models, chunksize=max(1, len(models) // (8 * threads))))
    results = []
    for b, (m, (oy, ou, y_end, stats, status, t_r)) in enumerate(zip(models, raw)):
        if status != STATUS_OK:
            raise SimulationError(f"batch point {b} ({m.scenario.name!r}): integration stopped at "
                                  f"t = {t_r:.6g} s (status {status})")
        results.append(Result(t=m.out_t, y=oy, u=ou, model=m,
                              stats={"steps": int(stats[0]), "rejected": int(stats[1]),
                                     "rhs_evaluations": int(stats[2])}))
    return results


# --- building many models fast ----------------------------------------------------------------------
def _pad_knots(model: PneumaticModel, K: int) -> dict:
    """Motion tables padded to K knots (repeating the last knot; mot_n says how many are real)."""
    out = {}
    for a in ("mot_t", "mot_L", "mot_d"):
        arr = getattr(model, a)
        if arr.shape[1] < K:
            pad = np.repeat(arr[:, -1:], K - arr.shape[1], axis=1)
            if a == "mot_d":
                pad[:] = 0.0
            arr = np.concatenate([arr, pad], axis=1)
        out[a] = arr
    return out


def _pad_schedule(model: PneumaticModel, S: int) -> dict:
    """Schedule padded to S entries with times +inf (never reached) and the last valve states."""
    t, u = model.sched_t, model.sched_u
    if t.size < S:
        last = u[-1:] if t.size else model.u0[None, :]
        t = np.concatenate([t, np.full(S - t.size, np.inf)])
        u = np.concatenate([u, np.repeat(last, S - u.shape[0], axis=0)])
    return {"sched_t": t, "sched_u": u}


def _flat(model: PneumaticModel, K: int = 0, S: int = 0) -> dict:
    d = {a: getattr(model, a) for a in _ARRAYS}
    d.update(_pad_knots(model, max(K, model.mot_t.shape[1])))
    d.update(_pad_schedule(model, max(S, model.sched_t.size)))
    d["_scalars"] = _scalars(model)
    d["_opens"] = np.concatenate([np.asarray(x, float) for x in model.charge_open_times] + [np.zeros(0)])
    return d


def _build(base_raw: dict, overrides: dict, base_dir: str) -> PneumaticModel:
    return build_model(scenario_from_raw(with_overrides(base_raw, overrides), base_dir))


def _with_arrays(base: PneumaticModel, flat: dict) -> PneumaticModel:
    """A copy of base with its engine arrays replaced (the scenario object stays the base's)."""
    opens, k = [], 0
    for x in base.charge_open_times:
        opens.append(flat["_opens"][k:k + len(x)])
        k += len(x)
    s = flat["_scalars"]
    sc = base.scenario
    sc = dataclasses.replace(sc, duration=float(s[0]),
                             solver=dataclasses.replace(sc.solver, rtol=float(s[1]), max_step=float(s[2])),
                             controller=dataclasses.replace(sc.controller, rate=float(1.0 / s[3])))
    return dataclasses.replace(base, scenario=sc, charge_open_times=opens,
                               **{a: flat[a] for a in _ARRAYS})


def compose_models(base_raw: dict, points: list[dict], base_dir: str = ".",
                   verify: int = 3, seed: int = 0) -> tuple[list[PneumaticModel], str]:
    """Models for many points (dicts of dotted path -> value as written in a scenario file).

    Returns (models, method) with method "composed" or "built" (see the module docstring). Raises
    ScenarioError on the first invalid value, naming its path, before anything runs.
    """
    base = build_model(scenario_from_raw(base_raw, base_dir))
    paths = sorted({p for pt in points for p in pt})
    if not paths:
        return [base for _ in points], "composed"
    single = {}
    for p in paths:
        for v in {_key(pt[p]) for pt in points if p in pt}:
            raw_value = next(pt[p] for pt in points if p in pt and _key(pt[p]) == v)
            single[(p, v)] = _build(base_raw, {p: raw_value}, base_dir)
    K = max([base.mot_t.shape[1]] + [m.mot_t.shape[1] for m in single.values()])
    S = max([base.sched_t.size] + [m.sched_t.size for m in single.values()])
    base_flat = _flat(base, K, S)
    per_value: dict[tuple, dict] = {}
    touched: dict[str, dict[str, np.ndarray]] = {p: {} for p in paths}
    structural = False
    for (p, v), m in single.items():
        flat = _flat(m, K, S)
        per_value[(p, v)] = flat
        for a, arr in flat.items():
            if arr.shape != base_flat[a].shape:
                structural = True
                continue
            diff = arr != base_flat[a]
            if diff.any():
                touched[p][a] = touched[p].get(a, np.zeros(arr.shape, bool)) | diff
    disjoint = not structural and all(
        not (touched[p][a] & touched[q][a]).any()
        for p, q in itertools.combinations(paths, 2) for a in set(touched[p]) & set(touched[q]))
    if disjoint:
        models = []
        for pt in points:
            flat = {a: arr.copy() for a, arr in base_flat.items()}
            for p, val in pt.items():
                src = per_value[(p, _key(val))]
                for a, mask in touched[p].items():
                    flat[a][mask] = src[a][mask]
            models.append(_with_arrays(base, flat))
        rng = np.random.default_rng(seed)
        for i in rng.choice(len(points), size=min(verify, len(points)), replace=False):
            exact = _flat(_build(base_raw, points[i], base_dir), K, S)
            got = _flat(models[i], K, S)
            if any(exact[a].shape != got[a].shape or not np.array_equal(exact[a], got[a]) for a in exact):
                disjoint = False
                break
        if disjoint:
            return models, "composed"
    return [_build(base_raw, pt, base_dir) for pt in points], "built"


def _key(value):
    """A hashable key for a value as written in a scenario (text, number, bool or table)."""
    if isinstance(value, dict):
        return tuple(sorted((k, _key(v)) for k, v in value.items()))
    if isinstance(value, list):
        return tuple(_key(v) for v in value)
    return value
