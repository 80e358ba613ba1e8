"""Run a sweep: chunks of points through the batched engine, locally or on a Dask cluster, written
to NetCDF as they finish, resumable after any interruption.

Execution
    The points are split into a fixed chunk plan (:meth:`SweepSpec.chunks`, from the spec alone).
    A chunk is built (:func:`frogsim.engine.batch.build_models`: each distinct part once), run in
    sub-batches so that memory stays small (:func:`frogsim.engine.batch.run_outputs`: compiled,
    keeping only the output columns the metrics read; Result objects only when time series are
    stored) and reduced to metrics (:func:`frogsim.sweep.metrics.evaluate_outputs`) by
    :func:`run_chunk`. Locally the chunks run one after the other on ``workers`` threads; with a
    Dask scheduler each chunk is a task. Same plan, same code: the results are identical.

Files (``out = results.nc``)
    ``results.nc``        the whole dataset, with a boolean ``completed`` per point; replaced
                          atomically (written beside it, then ``os.replace``), so it is never half
                          written; rewritten at the start, every few seconds and at the end.
    ``results.nc.parts/`` while the sweep runs: ``manifest.json`` (the spec hash and the input
                          files' SHA-256) and one ``chunk-NNNNNN.npz`` per finished chunk, each
                          written atomically the moment the chunk ends (a kill loses at most the
                          chunks in flight) and carrying a SHA-256 of its arrays; a lock.
                          Removed once ``results.nc`` holds everything.
    Rerunning the same command reads both and runs only the chunks not yet finished; a chunk file
    that is truncated or altered (its checksum does not match) is dropped and run again. A
    results file or journal from a different spec (hash of base scenario + the content of every
    file it reads + points + what is recorded) is refused unless ``overwrite``, naming the input
    file that changed.

Units (docs/sweeps.md)
    Every variable and coordinate of the file is in SI with a CF-style ``units`` string ("Pa",
    "m3 s-1", "m3 s-1 Pa-1", "s", "1"), a ``long_name``, and ``display_units`` /
    ``display_factor`` (value / display_factor is in display_units) for plots. Metrics
    registered in another unit (bar, litres at standard state) are converted as they enter the
    store: :data:`METRIC_UNITS`.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import sys
import threading
import time
from datetime import datetime, timezone
from pathlib import Path

from dataclasses import dataclass

import numpy as np

from frogsim._budget import check as check_size
from frogsim._files import atomic_write
from frogsim._parallel import map_pieces
from frogsim._words import count
from frogsim.errors import ScenarioError, Shown, SimulationError
from frogsim.scenario.core import Scenario
from frogsim.sweep.metrics import STATES
from frogsim.sweep.spec import SweepSpec, _flatten_parameters, _toml_value, changed_inputs, dumps_toml, load_spec

FORMAT = 2                      # version of the results layout, stored in the file (2: SI metrics, CF units)
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
    """Run a few models on this thread and reduce them at once (their time series are dropped).

    Without time series to store, the runs keep only the output columns the metrics read and are
    reduced from those raw outputs (:func:`frogsim.engine.batch.run_outputs`, no Result objects)."""
    if timeseries:
        return _run_piece_results(models, metrics, muscle, timeseries)
    from frogsim.engine.batch import run_outputs
    from frogsim.sweep.metrics import evaluate_outputs, kept_columns
    B = len(models)
    columns = None
    if hasattr(models, "names"):
        names = models.names()
        columns = kept_columns(metrics, len(names), names.index(muscle) if muscle in names else 0)
    try:
        groups, failures = run_outputs(models, columns)
    except SimulationError:                 # isolate the point(s) that fail
        groups, failures = [], {}
        for j in range(B):
            try:
                g, f = run_outputs(models[j:j + 1], columns)
            except SimulationError as exc:
                failures[j] = str(exc)
                continue
            groups += [(rows + j, out) for rows, out in g]
            failures.update({j + k: text for k, text in f.items()})
    res = {"metrics": {m: np.full(B, np.nan) for m in metrics}, "timeseries": {},
           "failed": np.zeros(B, bool), "errors": dict(failures)}
    res["failed"][list(failures)] = True
    for rows, out in groups:
        vals = evaluate_outputs(out, list(metrics), muscle)
        for m in metrics:
            res["metrics"][m][rows] = vals[m]
    return res


def _run_piece_results(models, metrics, muscle, timeseries) -> dict:
    """:func:`_run_piece` through Result objects, for the time series a sweep stores."""
    results = _run_isolating(models, 1)
    B = len(models)
    res = {"metrics": {m: np.full(B, np.nan) for m in metrics}, "timeseries": {},
           "failed": np.array([isinstance(r, str) for r in results], bool),
           "errors": {j: r for j, r in enumerate(results) if isinstance(r, str)}}
    ok = [j for j, r in enumerate(results) if not isinstance(r, str)]
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


# --- units ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Unit:
    """How a unit as registered (metrics, states, scenario kinds) is stored: CF units string, the
    factor that takes a value to it, the display unit and its size in the stored unit, and what
    to say about it in the long_name."""
    cf: str
    factor: float = 1.0
    display: str = ""
    display_factor: float = 1.0
    note: str = ""


_STD = "air volume at the standard reference state (ISO 8778: 100 kPa, 293.15 K)"
#: unit as written in the registries (frogsim.sweep.metrics, frogsim.scenario.units) -> how it is stored
METRIC_UNITS = {
    "s": Unit("s", 1.0, "s", 1.0),
    "bar": Unit("Pa", 1e5, "bar", 1e5),
    "bar (gauge)": Unit("Pa", 1e5, "bar", 1e5, "gauge pressure: relative to the atmosphere"),
    "L (standard)": Unit("m3", 1e-3, "L", 1e-3, _STD),
    "m3 (standard)": Unit("m3", 1.0, "L", 1e-3, _STD),
    "Pa": Unit("Pa", 1.0, "bar", 1e5),
    "Pa (gauge)": Unit("Pa", 1.0, "bar", 1e5, "gauge pressure: relative to the atmosphere"),
    "kg": Unit("kg", 1.0, "g", 1e-3),
    "K": Unit("K", 1.0, "K", 1.0),
    "1": Unit("1", 1.0, "", 1.0),
    "": Unit("1", 1.0, "", 1.0),
}

#: SI units of frogsim.scenario.units.SI_UNITS (pint notation) -> CF / UDUNITS notation
_CF = {"": "1", "m**3": "m3", "m/s": "m s-1", "m**3/s": "m3 s-1", "m**3/(s*Pa)": "m3 s-1 Pa-1",
       "J/(kg*K)": "J kg-1 K-1", "m**2": "m2", "kg/m**3": "kg m-3", "m/s**2": "m s-2", "N/m": "N m-1",
       "N*m": "N m", "N*m*s": "N m s", "m^3": "m3", "m^3/s": "m3 s-1", "m^3/(s*Pa)": "m3 s-1 Pa-1",
       "m^2": "m2", "kg/m^3": "kg m-3", "m/s^2": "m s-2", "L (standard)": "m3"}


def cf_units(unit: str) -> str:
    """A unit in CF / UDUNITS notation ("m**3/(s*Pa)" -> "m3 s-1 Pa-1"; "" -> "1")."""
    return _CF.get(unit, unit)


def metric_unit(name: str) -> Unit:
    """How metric ``name`` is stored (its registered unit converted to SI)."""
    from frogsim.sweep.metrics import METRICS
    unit = METRICS[name].unit
    return METRIC_UNITS.get(unit, Unit(cf_units(unit), 1.0, unit, 1.0))


# --- the sweep's data in memory ---------------------------------------------------------------------
class _Store:
    """Flat per-point arrays of a sweep (C order for a grid), filled chunk by chunk. Metrics are
    held in SI (:func:`metric_unit`): a chunk's values, in their registered units, are converted
    once as they come in, so a resumed sweep holds the same numbers as an uninterrupted one."""

    def __init__(self, spec: SweepSpec):
        n = spec.n_points
        self.spec = spec
        self.factors = {m: metric_unit(m).factor for m in spec.metrics}
        self.metrics = {m: np.full(n, np.nan) for m in spec.metrics}
        ts = spec.timeseries
        self.ts = {s: np.full((n, len(ts.times)), np.nan) for s in ts.states} if ts else {}
        self.completed = np.zeros(n, bool)
        self.failed = np.zeros(n, bool)
        self.errors: dict[int, str] = {}

    def put(self, idx: np.ndarray, res: dict) -> None:
        for m in self.metrics:
            f = self.factors[m]
            vals = np.asarray(res["metrics"][m], float)
            self.metrics[m][idx] = vals * f if f != 1.0 else vals
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


def _scales(spec: SweepSpec) -> dict[str, str]:
    """The spacing each swept parameter was given ("log" or "linear") in the spec."""
    try:
        flat = _flatten_parameters(spec.raw.get("sweep", {}).get("parameters", {}))
    except Exception:  # a dict spec of unusual shape: no scale known
        flat = {}
    out = {}
    for p in spec.parameters:
        raw = flat.get(p.path)
        out[p.path] = raw.get("scale", "linear") if isinstance(raw, dict) else "linear"
    return out


def to_dataset(spec: SweepSpec, store: _Store):
    """The xarray Dataset of a sweep (see docs/sweeps.md for the layout and the units)."""
    import xarray as xr
    from frogsim.sweep.metrics import METRICS
    shape, dims = spec.shape, spec.dims
    coords = {}
    scales = _scales(spec)

    def param_attrs(p):
        a = {"long_name": f"swept scenario setting {p.path}", "kind": p.info.kind}
        if p.info.numeric:
            a["units"] = cf_units(p.info.si_unit)
            a["display_units"] = p.display_unit if p.display_unit else a["units"]
            a["display_factor"] = float(p.display_factor) if p.display_unit else 1.0
            if p.path.endswith("_gauge"):
                a["note"] = "gauge pressure: relative to the atmosphere"
                a["long_name"] += " (gauge pressure: relative to the atmosphere)"
        else:
            a["units"] = "1"
            a["note"] = "text values (a choice or a flag): no physical unit"
        a["scale"] = scales.get(p.path, "linear")
        if p.range:
            a.update({"range_min": f"{_fmt_range(p.range['min'])} {p.range['unit']}".strip(),
                      "range_max": f"{_fmt_range(p.range['max'])} {p.range['unit']}".strip(),
                      "range_scale": p.range["scale"]})
            a["scale"] = p.range["scale"]
        return a

    def values(p, col):
        if p.info.numeric:
            return np.asarray(col, float)
        return np.array([_written_text(v) for v in col], dtype=str)

    def written_attrs(p):
        return {"long_name": f"{p.path} as written in the scenario", "units": "1",
                "note": "text: the value with the unit it was written in"}

    if spec.method == "grid":
        for p in spec.parameters:
            coords[p.path] = (p.path, values(p, p.si if p.info.numeric else p.written), param_attrs(p))
            coords[f"{p.path}_as_written"] = (p.path, np.array([_written_text(v) for v in p.written], dtype=str),
                                              written_attrs(p))
    else:
        coords["point"] = ("point", np.arange(spec.n_points),
                           {"long_name": "sweep point (index into the sampled points)", "units": "1"})
        for j, p in enumerate(spec.parameters):
            col = spec.si[:, j] if p.info.numeric else [w[j] for w in spec.written]
            coords[p.path] = ("point", values(p, col), param_attrs(p))
            coords[f"{p.path}_as_written"] = ("point", np.array([_written_text(w[j]) for w in spec.written], dtype=str),
                                              written_attrs(p))
    data = {}
    for m in spec.metrics:
        u = metric_unit(m)
        desc = METRICS[m].description
        long_name = desc + (f" ({spec.muscle})" if "muscle" in desc else "") + (f"; {u.note}" if u.note else "")
        data[m] = (dims, store.metrics[m].reshape(shape),
                   {"units": u.cf, "long_name": long_name, "description": desc, "muscle": spec.muscle,
                    "display_units": u.display or u.cf, "display_factor": float(u.display_factor),
                    "registered_units": METRICS[m].unit})
    data["completed"] = (dims, store.completed.reshape(shape),
                         {"long_name": "the point has run (its values are final; NaN where failed)", "units": "1",
                          "description": "the point has run (its values are final; NaN where failed)"})
    data["failed"] = (dims, store.failed.reshape(shape),
                      {"long_name": "the point's integration failed (see the global attribute failures)",
                       "units": "1",
                       "description": "the point's integration failed (see the global attribute failures)"})
    if spec.timeseries:
        coords["time"] = ("time", np.asarray(spec.timeseries.times),
                          {"units": "s", "long_name": "time since the start of the run"})
        for s in spec.timeseries.states:
            st = STATES[s]
            desc = st.description + (f" ({spec.muscle})" if s.split("_")[0] in ("muscle", "charged", "vented",
                                                                                "charge", "discharge") else "")
            u = METRIC_UNITS.get(st.unit, Unit(cf_units(st.unit), 1.0, st.unit, 1.0))
            attrs = {"units": u.cf, "long_name": desc, "description": desc,
                     "display_units": u.display or u.cf, "display_factor": float(u.display_factor)}
            if u.cf == "Pa":
                attrs["display_units"], attrs["display_factor"] = "Pa", 1.0     # absolute: shown as stored
            data[s] = (dims + ("time",), store.ts[s].reshape(shape + (-1,)), attrs)
    from frogsim import __version__
    attrs = {
        "title": f"frogsim sweep {spec.name}",
        "Conventions": "CF-1.8",
        "units_convention": "SI throughout, CF/UDUNITS unit strings in each variable's units attribute; "
                            "display_units/display_factor give the unit plots use (value / display_factor)",
        "frogsim_sweep_format": FORMAT,
        "frogsim_version": __version__,
        "sweep_name": spec.name,
        "sweep_description": spec.description,
        "notes": "\n".join(spec.notes),
        "sweep_method": spec.method,
        "sweep_hash": spec.hash,
        "sweep_parameters": ", ".join(spec.paths),
        "spec_toml": spec.text or dumps_toml(spec.raw),
        "base_scenario": spec.base,
        "base_scenario_toml": spec.base_toml(),
        "input_files": json.dumps(list(spec.inputs)),
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


def read_results(path):
    """Open a sweep results file fully into memory (the file is closed afterwards). A file of an
    earlier layout (format 1: metrics in bar and standard litres, pint-style unit strings) is
    brought to the current convention (SI, CF unit strings) in memory."""
    import xarray as xr
    with xr.open_dataset(path, engine=NC_ENGINE) as ds:
        return upgrade(ds.load())


def upgrade(ds):
    """A format-1 dataset in the current units convention (see :data:`METRIC_UNITS`)."""
    if int(ds.attrs.get("frogsim_sweep_format", FORMAT)) >= 2:
        return ds
    metrics = [m.strip() for m in ds.attrs.get("metrics", "").split(",") if m.strip()]
    for name in list(ds.variables):
        var = ds[name]
        unit = var.attrs.get("units")
        if name in metrics and unit in METRIC_UNITS:
            u = METRIC_UNITS[unit]
            converted = var * u.factor if u.factor != 1.0 else var
            converted.attrs = {**var.attrs, "units": u.cf, "registered_units": unit,
                               "display_units": u.display or u.cf, "display_factor": float(u.display_factor)}
            ds[name] = converted
        elif unit is not None:
            ds[name].attrs["units"] = cf_units(unit)
        else:
            ds[name].attrs["units"] = "1"
    ds.attrs["frogsim_sweep_format"] = FORMAT
    ds.attrs["upgraded_from_format"] = 1
    return ds


def _digest(arrays: dict) -> str:
    """SHA-256 of named arrays: names, dtypes, shapes and bytes, in name order."""
    import hashlib
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


class _Journal:
    """The sidecar folder of a running sweep: manifest, one file per finished chunk, a lock.

    Each chunk file holds its arrays and ``sha256``, the :func:`_digest` of those arrays; a file
    that cannot be read or whose arrays do not match it is dropped (and its chunk runs again).
    """

    def __init__(self, out: Path):
        self.out = out
        self.dir = out.parent / f"{out.name}.parts"
        self._lock_fd = None
        self.damaged: list[str] = []

    def manifest(self) -> dict | None:
        try:
            data = json.loads((self.dir / "manifest.json").read_text())
        except (OSError, ValueError):
            return None
        return data if isinstance(data, dict) and "hash" in data else None

    def manifest_hash(self) -> str | None:
        m = self.manifest()
        return m["hash"] if m else None

    def open(self, spec: SweepSpec, fresh: bool) -> None:
        import fcntl
        self.dir.mkdir(parents=True, exist_ok=True)
        self._lock_fd = os.open(self.dir / "lock", os.O_RDWR | os.O_CREAT, 0o666)
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
            text = json.dumps({"hash": spec.hash, "n_points": spec.n_points, "chunk_size": spec.chunk_size,
                               "name": spec.name, "inputs": list(spec.inputs),
                               "chunk_checksum": "sha256 of the arrays, stored in each chunk file as 'sha256'"},
                              indent=1)
            atomic_write(self.dir / "manifest.json", lambda tmp: Path(tmp).write_text(text), durable=True)

    @staticmethod
    def _read(f: Path):
        """(idx, result dict) of a chunk file whose checksum holds; ValueError otherwise."""
        try:
            with np.load(f, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}         # reads (and CRC-checks) every member
        except Exception as exc:  # truncated or scrambled zip: BadZipFile, EOFError, ValueError, OSError...
            raise ValueError(f"unreadable ({type(exc).__name__})") from None
        stored = arrays.pop("sha256", None)
        if stored is None or str(stored) != _digest(arrays):
            raise ValueError("checksum mismatch")
        try:
            res = {"metrics": {k[2:]: v for k, v in arrays.items() if k.startswith("m_")},
                   "timeseries": {k[3:]: v for k, v in arrays.items() if k.startswith("ts_")},
                   "failed": arrays["failed"], "errors": json.loads(str(arrays["errors"]))}
            return arrays["idx"], res
        except (KeyError, ValueError) as exc:
            raise ValueError(f"incomplete ({exc})") from None

    def chunks(self):
        """(chunk number, flat indices, result dict) of every sound chunk file; a damaged one is
        deleted and named in :attr:`damaged` (its chunk is then run again)."""
        for f in sorted(self.dir.glob("chunk-*.npz")):
            try:
                k = int(f.stem.split("-")[1])
                idx, res = self._read(f)
            except ValueError as exc:
                self.damaged.append(f"{f.name}: {exc}")
                f.unlink(missing_ok=True)
                continue
            yield k, idx, res

    def write_chunk(self, k: int, idx: np.ndarray, res: dict) -> None:
        arrays = {f"m_{m}": np.asarray(v) for m, v in res["metrics"].items()}
        arrays.update({f"ts_{s}": np.asarray(v) for s, v in res["timeseries"].items()})
        arrays.update(idx=np.asarray(idx), failed=np.asarray(res["failed"]),
                      errors=np.array(json.dumps({str(j): t for j, t in res["errors"].items()})))
        arrays["sha256"] = np.array(_digest(arrays))

        def write(tmp):
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)
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
    reached = False
    try:
        _probe(address, timeout)         # fail fast, and without a half-made Client complaining at exit
        reached = True
        return _client_within(Client, address, timeout), True
    except Exception as exc:  # refused, timed out, or something that is not a Dask scheduler answered
        msg = " ".join(str(exc).split())[:200] or type(exc).__name__
    import gc
    hook = sys.unraisablehook
    sys.unraisablehook = lambda unraisable: None      # a half-made Client complains when collected
    try:
        gc.collect()
    finally:
        sys.unraisablehook = hook
    if reached:      # a server took the connection, but its answer was no Dask scheduler's
        raise ScenarioError("--scheduler", address, "something answers at this address, but not a Dask scheduler "
                                                    f"(connecting failed with: {msg})")
    raise ScenarioError("--scheduler", address, f"no Dask scheduler reachable within {timeout:g} s ({msg})")


def _client_within(Client, address: str, timeout: float):
    """Client(address), given up after the timeout (and a few seconds of its own): a server that
    takes the connection but answers something else (an HTTP server) can leave Dask's handshake
    waiting for good. The attempt is made on a daemon thread, left behind if it hangs."""
    import threading
    box = {}

    def make():
        try:
            box["client"] = Client(address, timeout=f"{timeout}s", set_as_default=False)
        except BaseException as exc:        # handed to the caller
            box["error"] = exc
    th = threading.Thread(target=make, name="frogsim-dask-connect", daemon=True)
    th.start()
    th.join(timeout + 5.0)
    if th.is_alive():
        raise TimeoutError(f"the connection was taken but no Dask handshake came back within {timeout + 5.0:g} s")
    if "error" in box:
        raise box["error"]
    return box["client"]


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
    a ScenarioError then means nothing was written. The Dataset's attribute ``n_points_read``
    (not written to ``out``) counts the points read from ``out`` and its journal instead of run.
    """
    if not (isinstance(connect_timeout, (int, float)) and not isinstance(connect_timeout, bool)
            and math.isfinite(connect_timeout) and connect_timeout > 0):
        raise ScenarioError("--connect-timeout", connect_timeout, "must be a finite time in seconds > 0")
    spec = load_spec(spec_or_path)
    out = Path(out) if out is not None else None
    check_size("record.timeseries" if spec.timeseries else "sweep", Shown(f"{spec.n_points} points"),
               spec.need(out))
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
                    changed = _changed_inputs(existing.attrs.get("input_files"), spec)
                    if changed:
                        raise ScenarioError("--out", str(out), f"cannot resume: the {changed} changed since this "
                                                               "sweep started; use --overwrite to start afresh, "
                                                               "or another --out")
                    what = "another spec" if "sweep_hash" in existing.attrs else "something that is not a frogsim sweep"
                    raise ScenarioError("--out", str(out), f"holds the results of {what} (or of another base "
                                                           "scenario); use --overwrite to replace it, or "
                                                           "another --out")
                existing = None
        journal = _Journal(out)
        if journal.dir.exists() and not journal.dir.is_dir():
            raise ScenarioError("--out", str(out), f"its journal {journal.dir} is a file, not the folder a sweep "
                                                   "keeps its finished chunks in; move or delete that file, or "
                                                   "use another --out")
        jm = journal.manifest() if journal.dir.exists() else None
        if jm is not None and jm["hash"] != spec.hash and not overwrite:
            changed = _changed_inputs(jm.get("inputs"), spec)
            if changed:
                raise ScenarioError("--out", str(out), f"cannot resume: the {changed} changed since this sweep "
                                                       "started; use --overwrite to start afresh, or another --out")
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
            if journal.damaged and progress:
                print(f"warning: {len(journal.damaged)} damaged chunk file(s) in {journal.dir.name} dropped and "
                      f"run again ({'; '.join(journal.damaged[:3])})", file=sys.stderr, flush=True)
        plan = spec.chunks()
        pending = [k for k, idx in enumerate(plan) if not store.completed[idx].all()]
        done = int(store.completed.sum())
        if progress and out is not None and done:
            print(f"resuming {out}: {done} of {count(spec.n_points, 'point')} already done", file=sys.stderr,
                  flush=True)
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
        result = to_dataset(spec, store)
        result.attrs["n_points_read"] = done     # this call's only: the points it read, not ran
        return result
    finally:
        if journal is not None:
            journal.close()
        if own_client:
            client.close()


def _changed_inputs(stored, spec: SweepSpec) -> str:
    """"parameters file /x/p.toml" (and others) whose content differs from when the results or
    journal were written; "" if none (or nothing was stored)."""
    if isinstance(stored, str):
        try:
            stored = json.loads(stored)
        except ValueError:
            return ""
    if not isinstance(stored, list) or not stored:
        return ""
    return ", ".join(changed_inputs(stored, spec.inputs))


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
