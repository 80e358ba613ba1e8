"""Run a sweep: chunks of points through the batched engine, locally or on a Dask cluster, written
to NetCDF as they finish, resumable after any interruption.

Execution
    The points are split into a fixed chunk plan (:meth:`SweepSpec.chunks`, from the spec alone).
    A chunk is built (:func:`frogsim.engine.batch.compose_models`, or one full build per point
    when composing would cost more), run (:func:`frogsim.engine.batch.run_models`, in sub-batches
    so that memory stays small) and reduced to metrics (:func:`frogsim.sweep.metrics.evaluate`) by
    :func:`run_chunk`. Locally the chunks run one after the other on ``workers`` threads; with a
    Dask scheduler each chunk is a task. Same plan, same code: the results are identical.

Files (``out = results.nc``)
    ``results.nc``        the whole dataset, with a boolean ``completed`` per point; replaced
                          atomically (written beside it, then ``os.replace``), so it is never half
                          written; rewritten at the start, every few seconds and at the end.
    ``results.nc.parts/`` while the sweep runs: ``manifest.json`` (the spec hash) and one
                          ``chunk-NNNNNN.npz`` per finished chunk, each written atomically the
                          moment the chunk ends (a kill loses at most the chunks in flight); a lock.
                          Removed once ``results.nc`` holds everything.
    Rerunning the same command reads both and runs only the chunks not yet finished. A results
    file or journal from a different spec (hash of base scenario + points + what is recorded)
    is refused unless ``overwrite``.
"""
from __future__ import annotations

import json
import os
import shutil
import sys
import threading
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from frogsim._files import atomic_write
from frogsim._parallel import map_pieces
from frogsim.errors import ScenarioError, SimulationError
from frogsim.scenario.core import Scenario
from frogsim.sweep.metrics import STATES
from frogsim.sweep.spec import SweepSpec, _toml_value, dumps_toml, load_spec

FORMAT = 1                      # version of the results layout, stored in the file
NC_ENGINE = "netcdf4"
_FLUSH_SECONDS = 5.0            # rewrite results.nc at most this often while running
_SUB_BATCH = 64                 # points per thread held in memory at once within a chunk


# --- one chunk (runs locally or as a Dask task) -----------------------------------------------------
def _run_isolating(models, threads: int) -> list:
    """Results in order; a point whose integration fails gets its error text instead."""
    from frogsim.engine.batch import run_models
    try:
        return run_models(models, threads=threads)
    except SimulationError:
        out = []
        for m in models:
            try:
                out.append(run_models([m], threads=1)[0])
            except SimulationError as exc:
                out.append(str(exc))
        return out


def _evaluate(results: list, metrics, muscle) -> dict[str, np.ndarray]:
    """Metrics of results that may not share one time grid (swept duration): grid by grid."""
    from frogsim.sweep.metrics import evaluate
    out = {m: np.full(len(results), np.nan) for m in metrics}
    groups: dict[tuple, list[int]] = {}
    for j, r in enumerate(results):
        groups.setdefault((r.t.size, float(r.t[-1])), []).append(j)
    for idx in groups.values():
        vals = evaluate([results[j] for j in idx], list(metrics), muscle)
        for m in metrics:
            out[m][idx] = vals[m]
    return out


def _run_piece(models, metrics, muscle, timeseries) -> dict:
    """Run a few models on this thread and reduce them at once (their time series are dropped)."""
    results = _run_isolating(models, 1)
    B = len(models)
    res = {"metrics": {m: np.full(B, np.nan) for m in metrics}, "timeseries": {},
           "failed": np.array([isinstance(r, str) for r in results], bool),
           "errors": {j: r for j, r in enumerate(results) if isinstance(r, str)}}
    ok = [j for j, r in enumerate(results) if not isinstance(r, str)]
    if timeseries:
        states, step, n_t = timeseries
        for s in states:
            arr = np.full((B, n_t), np.nan)
            for j in ok:
                series = np.asarray(STATES[s].get(results[j], muscle), float)[::step][:n_t]
                arr[j, :series.size] = series
            res["timeseries"][s] = arr
    if ok:
        vals = _evaluate([results[j] for j in ok], metrics, muscle)
        for m in metrics:
            res["metrics"][m][ok] = vals[m]
    return res


def run_built(models, metrics, muscle: str, timeseries: tuple | None = None, threads: int = 1,
              on_progress=None) -> dict:
    """Run built models and reduce them to metrics (and time series), in order.

    Each of ``threads`` threads takes a few points at a time, runs them (the compiled engine,
    without the GIL) and reduces them while their outputs are fresh, so memory stays at a few
    points' time series per thread. Returns {"metrics": name -> (B,), "timeseries": state ->
    (B, samples), "failed": (B,) bool, "errors": {row: text}}.
    """
    B = len(models)
    threads = max(1, int(threads or 1))
    size = max(1, min(_SUB_BATCH, -(-B // threads)))
    starts = list(range(0, B, size))
    lock = threading.Lock()

    def work(piece):
        res = _run_piece(piece, metrics, muscle, timeseries)
        if on_progress is not None:
            with lock:
                on_progress(len(res["failed"]))
        return res
    parts = map_pieces(work, models, size, threads)
    out = {"metrics": {m: np.concatenate([p["metrics"][m] for p in parts]) if parts else np.empty(0)
                       for m in metrics},
           "timeseries": {}, "failed": np.concatenate([p["failed"] for p in parts]) if parts else np.zeros(0, bool),
           "errors": {a + j: text for a, p in zip(starts, parts) for j, text in p["errors"].items()}}
    if timeseries:
        out["timeseries"] = {s: np.concatenate([p["timeseries"][s] for p in parts]) for s in timeseries[0]}
    return out


def run_chunk(base: Scenario, points: list[dict], metrics, muscle: str,
              timeseries: tuple | None = None, threads: int = 1, on_progress=None) -> dict:
    """Build, run and reduce one chunk of points (a Dask task; see :func:`run_built`).

    ``points`` are variants of ``base`` (dotted path -> SI value); ``timeseries`` is (state names,
    step, samples) or None. Returns plain data only (so a Dask worker can send it back): the dict
    of :func:`run_built`.
    """
    from frogsim.engine.batch import build_models
    return run_built(build_models(base, points), metrics, muscle, timeseries, threads, on_progress)


# --- the sweep's data in memory ---------------------------------------------------------------------
class _Store:
    """Flat per-point arrays of a sweep (C order for a grid), filled chunk by chunk."""

    def __init__(self, spec: SweepSpec):
        n = spec.n_points
        self.spec = spec
        self.metrics = {m: np.full(n, np.nan) for m in spec.metrics}
        ts = spec.timeseries
        self.ts = {s: np.full((n, len(ts.times)), np.nan) for s in ts.states} if ts else {}
        self.completed = np.zeros(n, bool)
        self.failed = np.zeros(n, bool)
        self.errors: dict[int, str] = {}

    def put(self, idx: np.ndarray, res: dict) -> None:
        for m in self.metrics:
            self.metrics[m][idx] = res["metrics"][m]
        for s in self.ts:
            self.ts[s][idx] = res["timeseries"][s]
        self.failed[idx] = res["failed"]
        for row, text in res["errors"].items():
            self.errors[int(idx[int(row)])] = text
        self.completed[idx] = True

    def load_dataset(self, ds) -> None:
        """Take the completed points of a results file of the same spec."""
        spec = self.spec
        n = spec.n_points

        def flat(name, extra=()):
            return ds[name].transpose(*spec.dims, *extra).values.reshape((n,) + tuple(ds.sizes[e] for e in extra))
        done = flat("completed").astype(bool)
        for m in self.metrics:
            self.metrics[m][done] = flat(m)[done]
        for s in self.ts:
            self.ts[s][done] = flat(s, ("time",))[done]
        self.failed[done] = flat("failed").astype(bool)[done]
        self.completed |= done
        errors = json.loads(ds.attrs.get("failures", "{}"))
        self.errors.update({int(k): v for k, v in errors.items()})


def _written_text(value) -> str:
    return value if isinstance(value, str) else _toml_value(value)


def to_dataset(spec: SweepSpec, store: _Store):
    """The xarray Dataset of a sweep (see docs/sweeps.md for the layout)."""
    import xarray as xr
    from frogsim.sweep.metrics import METRICS
    shape, dims = spec.shape, spec.dims
    coords = {}

    def param_attrs(p):
        a = {"long_name": p.path, "kind": p.info.kind}
        if p.info.numeric:
            a["units"] = p.info.si_unit
            if p.display_unit:
                a["display_units"] = p.display_unit
                a["display_factor"] = float(p.display_factor)
            if p.path.endswith("_gauge"):
                a["note"] = "gauge pressure: relative to the atmosphere"
        if p.range:
            a.update({"range_min": f"{_fmt_range(p.range['min'])} {p.range['unit']}".strip(),
                      "range_max": f"{_fmt_range(p.range['max'])} {p.range['unit']}".strip(),
                      "range_scale": p.range["scale"]})
        return a

    def values(p, col):
        if p.info.numeric:
            return np.asarray(col, float)
        return np.array([_written_text(v) for v in col], dtype=str)

    if spec.method == "grid":
        for p in spec.parameters:
            coords[p.path] = (p.path, values(p, p.si if p.info.numeric else p.written), param_attrs(p))
            coords[f"{p.path}_as_written"] = (p.path, np.array([_written_text(v) for v in p.written], dtype=str),
                                              {"long_name": f"{p.path} as written in the scenario"})
    else:
        coords["point"] = ("point", np.arange(spec.n_points),
                           {"long_name": "sweep point (index into the sampled points)"})
        for j, p in enumerate(spec.parameters):
            col = spec.si[:, j] if p.info.numeric else [w[j] for w in spec.written]
            coords[p.path] = ("point", values(p, col), param_attrs(p))
            coords[f"{p.path}_as_written"] = ("point", np.array([_written_text(w[j]) for w in spec.written], dtype=str),
                                              {"long_name": f"{p.path} as written in the scenario"})
    data = {}
    for m in spec.metrics:
        data[m] = (dims, store.metrics[m].reshape(shape),
                   {"units": METRICS[m].unit, "description": METRICS[m].description, "muscle": spec.muscle})
    data["completed"] = (dims, store.completed.reshape(shape),
                         {"description": "the point has run (its values are final; NaN where failed)"})
    data["failed"] = (dims, store.failed.reshape(shape),
                      {"description": "the point's integration failed (see the global attribute failures)"})
    if spec.timeseries:
        coords["time"] = ("time", np.asarray(spec.timeseries.times), {"units": "s", "long_name": "time"})
        for s in spec.timeseries.states:
            st = STATES[s]
            desc = st.description + (f" ({spec.muscle})" if s.split("_")[0] in ("muscle", "charged", "vented",
                                                                                "charge", "discharge") else "")
            data[s] = (dims + ("time",), store.ts[s].reshape(shape + (-1,)), {"units": st.unit, "description": desc})
    from frogsim import __version__
    attrs = {
        "title": f"frogsim sweep {spec.name}",
        "frogsim_sweep_format": FORMAT,
        "frogsim_version": __version__,
        "sweep_name": spec.name,
        "sweep_description": spec.description,
        "sweep_method": spec.method,
        "sweep_hash": spec.hash,
        "sweep_parameters": ", ".join(spec.paths),
        "spec_toml": spec.text or dumps_toml(spec.raw),
        "base_scenario": spec.base,
        "base_scenario_toml": spec.base_toml(),
        "muscle": spec.muscle,
        "metrics": ", ".join(spec.metrics),
        "n_points": spec.n_points,
        "n_completed": int(store.completed.sum()),
        "n_failed": int(store.failed.sum()),
        "complete": int(store.completed.all()),
        "chunk_size": spec.chunk_size,
        "failures": json.dumps({str(k): v[:300] for k, v in sorted(store.errors.items())[:1000]}),
        "updated": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    if spec.samples is not None:
        attrs["samples"] = spec.samples
        attrs["seed"] = spec.seed
    return xr.Dataset(data, coords=coords, attrs=attrs)


def _fmt_range(x: float) -> str:
    return f"{x:.12g}"


# --- files ------------------------------------------------------------------------------------------
def write_dataset(ds, path: Path) -> None:
    """Write the dataset beside ``path`` and move it into place (durably)."""
    encoding = {v: {"zlib": True, "complevel": 1} for v in ds.data_vars if "time" in ds[v].dims}
    atomic_write(path, lambda tmp: ds.to_netcdf(tmp, engine=NC_ENGINE, encoding=encoding), durable=True)


def read_results(path) :
    """Open a sweep results file fully into memory (the file is closed afterwards)."""
    import xarray as xr
    with xr.open_dataset(path, engine=NC_ENGINE) as ds:
        return ds.load()


class _Journal:
    """The sidecar folder of a running sweep: manifest, one file per finished chunk, a lock."""

    def __init__(self, out: Path):
        self.out = out
        self.dir = out.parent / f"{out.name}.parts"
        self._lock_fd = None

    def manifest_hash(self) -> str | None:
        try:
            return json.loads((self.dir / "manifest.json").read_text())["hash"]
        except (OSError, ValueError, KeyError):
            return None

    def open(self, spec: SweepSpec, fresh: bool) -> None:
        import fcntl
        self.dir.mkdir(parents=True, exist_ok=True)
        self._lock_fd = os.open(self.dir / "lock", os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(self._lock_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self._lock_fd)
            self._lock_fd = None
            raise ScenarioError("--out", str(self.out),
                                "another frogsim sweep is writing this file right now") from None
        stale = fresh or self.manifest_hash() != spec.hash
        for f in self.dir.iterdir():
            if f.name.startswith(".") or (stale and f.name != "lock"):
                f.unlink()
        for f in self.out.parent.glob(f".{self.out.name}.*"):    # a results file a kill left half written
            f.unlink()
        if stale:
            text = json.dumps({"hash": spec.hash, "n_points": spec.n_points,
                               "chunk_size": spec.chunk_size, "name": spec.name})
            atomic_write(self.dir / "manifest.json", lambda tmp: Path(tmp).write_text(text), durable=True)

    def chunks(self):
        """(chunk number, flat indices, result dict) of every chunk file."""
        for f in sorted(self.dir.glob("chunk-*.npz")):
            try:
                with np.load(f, allow_pickle=False) as z:
                    res = {"metrics": {k[2:]: z[k] for k in z.files if k.startswith("m_")},
                           "timeseries": {k[3:]: z[k] for k in z.files if k.startswith("ts_")},
                           "failed": z["failed"], "errors": json.loads(str(z["errors"]))}
                    yield int(f.stem.split("-")[1]), z["idx"], res
            except (OSError, ValueError, KeyError):
                f.unlink()          # cannot happen with atomic writes; rerun that chunk

    def write_chunk(self, k: int, idx: np.ndarray, res: dict) -> None:
        arrays = {f"m_{m}": v for m, v in res["metrics"].items()}
        arrays.update({f"ts_{s}": v for s, v in res["timeseries"].items()})

        def write(tmp):
            with open(tmp, "wb") as fh:
                np.savez(fh, idx=idx, failed=res["failed"], errors=np.array(json.dumps(res["errors"])), **arrays)
        atomic_write(self.dir / f"chunk-{k:06d}.npz", write, durable=True)

    def remove(self) -> None:
        shutil.rmtree(self.dir, ignore_errors=True)
        self.close()

    def close(self) -> None:
        if self._lock_fd is not None:
            os.close(self._lock_fd)
            self._lock_fd = None


# --- the sweep --------------------------------------------------------------------------------------
def _connect(scheduler, timeout: float):
    """A Dask client for a scheduler address (or a Client / LocalCluster passed in)."""
    try:
        from distributed import Client
    except ImportError:  # pragma: no cover - a pinned dependency
        raise ScenarioError("--scheduler", scheduler, "needs the 'distributed' package") from None
    if isinstance(scheduler, Client):
        return scheduler, False
    address = getattr(scheduler, "scheduler_address", scheduler)
    if not isinstance(address, str) or not address:
        raise ScenarioError("--scheduler", scheduler, "expected a Dask scheduler address such as tcp://host:8786")
    try:
        _probe(address, timeout)         # fail fast, and without a half-made Client complaining at exit
        return Client(address, timeout=f"{timeout}s", set_as_default=False), True
    except Exception as exc:  # refused, timed out, or something that is not a Dask scheduler answered
        msg = " ".join(str(exc).split())[:200] or type(exc).__name__
    import gc
    hook = sys.unraisablehook
    sys.unraisablehook = lambda unraisable: None      # a half-made Client complains when collected
    try:
        gc.collect()
    finally:
        sys.unraisablehook = hook
    raise ScenarioError("--scheduler", address, f"no Dask scheduler reachable within {timeout:g} s ({msg})")


def _probe(address: str, timeout: float) -> None:
    """Open (and close) a TCP connection to a tcp:// or tls:// scheduler address; raise OSError or
    ValueError if it cannot be parsed or reached."""
    import socket
    from distributed.comm import parse_address, parse_host_port
    scheme, location = parse_address(address)
    if scheme in ("tcp", "tls"):
        host, port = parse_host_port(location)
        socket.create_connection((host, port), timeout=timeout).close()


def _bar(spec: SweepSpec, done: int, progress: bool):
    from tqdm import tqdm
    return tqdm(total=spec.n_points, initial=done, desc=f"sweep {spec.name}", unit="pt", file=sys.stderr,
                disable=not progress, mininterval=0.5, smoothing=0.1, dynamic_ncols=True)


def run_sweep(spec_or_path, out=None, workers: int | None = None, scheduler=None, progress: bool = True,
              overwrite: bool = False, connect_timeout: float = 5.0):
    """Run a sweep and return its results as an xarray Dataset.

    spec_or_path: a spec TOML path, a dict, or a SweepSpec (:func:`frogsim.sweep.load_spec`).
    out: a NetCDF path written as the sweep goes and resumed from if it exists (None: nothing is
    written). workers: threads of the local run (default: all cores); with a scheduler, threads
    per Dask task (default 1: the worker's own threads run tasks side by side). scheduler: a Dask
    scheduler address, Client or cluster. overwrite: replace results of a different spec instead
    of refusing.

    Everything is validated first (spec, every point's scenario, the scheduler, the output file);
    a ScenarioError then means nothing was written.
    """
    spec = load_spec(spec_or_path)
    spec.validate_points()
    out = Path(out) if out is not None else None
    existing = None
    journal = None
    if out is not None:
        if out.is_dir():
            raise ScenarioError("--out", str(out), "is a folder; expected a .nc file name")
        if out.exists():
            try:
                existing = read_results(out)
            except Exception as exc:  # netCDF4/xarray raise many types for foreign files
                if not overwrite:
                    raise ScenarioError("--out", str(out), f"exists and is not a readable frogsim sweep "
                                                           f"file ({type(exc).__name__}); use --overwrite "
                                                           "to replace it") from None
            if existing is not None and existing.attrs.get("sweep_hash") != spec.hash:
                if not overwrite:
                    what = "another spec" if "sweep_hash" in existing.attrs else "something that is not a frogsim sweep"
                    raise ScenarioError("--out", str(out), f"holds the results of {what} (or of another base "
                                                           "scenario); use --overwrite to replace it, or "
                                                           "another --out")
                existing = None
        journal = _Journal(out)
        jh = journal.manifest_hash() if journal.dir.exists() else None
        if jh is not None and jh != spec.hash and not overwrite:
            raise ScenarioError("--out", str(out), f"an interrupted sweep of another spec left {journal.dir.name}; "
                                                   "use --overwrite to discard it, or another --out")
        if overwrite:
            existing = None
    client, own_client = (None, False)
    if scheduler is not None:
        client, own_client = _connect(scheduler, connect_timeout)
    # --- from here on files are written ---
    store = _Store(spec)
    try:
        if journal is not None:
            out.parent.mkdir(parents=True, exist_ok=True)
            journal.open(spec, fresh=overwrite)
            if existing is not None:
                store.load_dataset(existing)
            plan = spec.chunks()
            for k, idx, res in journal.chunks():
                if k < len(plan) and np.array_equal(idx, plan[k]):
                    store.put(idx, res)
        plan = spec.chunks()
        pending = [k for k, idx in enumerate(plan) if not store.completed[idx].all()]
        done = int(store.completed.sum())
        if progress and out is not None and done:
            print(f"resuming {out}: {done} of {spec.n_points} points already done", file=sys.stderr, flush=True)
        last = [time.monotonic(), 0.0]

        def flush(force=False):
            if out is None:
                return
            now = time.monotonic()
            if force or now - last[0] >= max(_FLUSH_SECONDS, 10 * last[1]):
                t0 = time.monotonic()
                write_dataset(to_dataset(spec, store), out)
                last[0], last[1] = time.monotonic(), time.monotonic() - t0

        if pending and (existing is None or not existing.attrs.get("complete")):
            flush(force=True)
        ts = None
        if spec.timeseries:
            ts = (spec.timeseries.states, spec.timeseries.step, len(spec.timeseries.times))
        bar = _bar(spec, done, progress)
        try:
            def finished(k, res):
                if journal is not None:
                    journal.write_chunk(k, plan[k], res)
                store.put(plan[k], res)
                flush()

            if client is None:
                _run_local(spec, plan, pending, ts, max(1, workers or os.cpu_count() or 1), bar, finished)
            else:
                _run_dask(client, spec, plan, pending, ts, workers or 1, bar, finished)
        except BaseException:
            bar.close()
            if out is not None:          # the journal has every finished chunk; bring the file up to date
                try:
                    flush(force=True)
                except Exception:
                    pass                 # the journal is enough to resume
            raise
        finally:
            bar.close()
        if out is not None:
            if pending or existing is None or not existing.attrs.get("complete"):
                flush(force=True)
            journal.remove()
            journal = None
        return to_dataset(spec, store)
    finally:
        if journal is not None:
            journal.close()
        if own_client:
            client.close()


def _run_local(spec: SweepSpec, plan, pending, ts, threads: int, bar, finished) -> None:
    """Pending chunks in order, each built, run and reduced on ``threads`` threads."""
    for c in pending:
        finished(c, run_chunk(spec.scenario, spec.points(plan[c]), spec.metrics, spec.muscle, ts, threads,
                              on_progress=bar.update))


def _run_dask(client, spec: SweepSpec, plan, pending, ts, threads: int, bar, finished) -> None:
    """One task per pending chunk; results handled in the order they finish."""
    from distributed import as_completed
    base = client.scatter([spec.scenario], broadcast=True)[0]
    futures = {}
    for k in pending:
        fut = client.submit(run_chunk, base, spec.points(plan[k]), spec.metrics, spec.muscle,
                            ts, threads, key=f"frogsim-sweep-{spec.hash[:12]}-{k}-{time.time_ns()}", pure=False)
        futures[fut] = k
    try:
        for fut in as_completed(list(futures), loop=client.loop):
            k = futures[fut]
            finished(k, fut.result())
            bar.update(len(plan[k]))
    finally:
        client.cancel(list(futures))
