"""Plots of a sweep's results: a metric against one swept parameter (line) or two (heatmap).

Swept parameters not on an axis must be fixed with ``select`` (a value as written, e.g. "45 L/min",
or a number in SI) or averaged over with ``reduce="mean"`` (NaN of unfinished or failed points
skipped). Random, LHS and list sweeps are drawn as scatter plots over their points; ``select``
there keeps the points with that value.
"""
from __future__ import annotations

import numpy as np

from frogsim.errors import ScenarioError


def _params(ds) -> list[str]:
    return [p.strip() for p in ds.attrs.get("sweep_parameters", "").split(",") if p.strip()]


def _metrics(ds) -> list[str]:
    return [m.strip() for m in ds.attrs.get("metrics", "").split(",") if m.strip()]


def _axis(ds, path):
    """(values in the display unit, axis label) of a swept parameter."""
    c = ds[path]
    if c.dtype.kind in "US":
        return np.asarray(c.values), path
    factor = float(c.attrs.get("display_factor", 1.0))
    unit = c.attrs.get("display_units", c.attrs.get("units", ""))
    unit = "" if unit == "1" else unit
    return np.asarray(c.values, float) / factor, f"{path} [{unit}]" if unit else path


def is_log(ds, path) -> bool:
    """Draw this swept parameter on a log axis: the spec asked for scale = "log", or its values are
    positive, geometrically spaced (three or more) and span more than a decade."""
    c = ds[path]
    if c.dtype.kind in "USb":
        return False
    if "log" in (c.attrs.get("scale"), c.attrs.get("range_scale")):
        v = np.asarray(c.values, float)
        return bool(v.size and np.all(v[np.isfinite(v)] > 0))
    v = np.unique(np.asarray(c.values, float))
    v = v[np.isfinite(v)]
    if v.size < 3 or np.any(v <= 0) or v[-1] / v[0] <= 10.0:
        return False
    steps = np.diff(np.log(v))
    return bool(np.ptp(steps) <= 0.01 * steps.mean())


def _edges(v: np.ndarray, log: bool) -> np.ndarray:
    """Cell edges around sorted centres v (geometric midpoints on a log axis)."""
    x = np.log(v) if log else np.asarray(v, float)
    if x.size == 1:
        e = np.array([x[0] - 0.5, x[0] + 0.5]) if not log else np.array([x[0] - 0.1, x[0] + 0.1])
    else:
        mid = (x[1:] + x[:-1]) / 2
        e = np.concatenate([[x[0] - (mid[0] - x[0])], mid, [x[-1] + (x[-1] - mid[-1])]])
    return np.exp(e) if log else e


def _plain_log_ticks(axis) -> None:
    """Log axis ticks as plain numbers (15, 20, 50, 100), labelling minor ticks at 2 and 5."""
    from matplotlib.ticker import FuncFormatter

    def label(v, _pos, minor=False):
        if v <= 0:
            return ""
        mant = v / 10 ** np.floor(np.log10(v) + 1e-9)
        if minor and round(mant) not in (2, 5):
            return ""
        return f"{v:g}"
    axis.set_major_formatter(FuncFormatter(label))
    axis.set_minor_formatter(FuncFormatter(lambda v, p: label(v, p, True)))


def _metric(ds, metric):
    """(factor to divide by, axis label) of a metric: its display unit (bar, L) if it has one."""
    a = ds[metric].attrs
    factor = float(a.get("display_factor", 1.0))
    unit = a.get("display_units", a.get("units", ""))
    unit = "" if unit == "1" else unit
    if unit and "standard" in a.get("long_name", "") and unit in ("L", "m3"):
        unit += " (standard)"
    if unit and "gauge" in a.get("long_name", "") and "gauge" not in unit:
        unit += " gauge"
    return factor, f"{metric} [{unit}]" if unit else metric


def _match(ds, path: str, text: str):
    """Index positions (grid) or mask (points) where the parameter equals the selected value."""
    written = np.asarray(ds[f"{path}_as_written"].values).astype(str)
    norm = " ".join(text.split())
    hit = np.array([" ".join(w.split()) == norm for w in written])
    if not hit.any() and ds[path].dtype.kind == "f":
        kind = ds[path].attrs.get("kind", "")
        try:
            from frogsim.scenario.units import parse_quantity
            x = float(text) if kind in ("integer", "dimensionless") or not any(ch.isalpha() for ch in text) \
                else parse_quantity(text, kind)
        except Exception:
            x = None
        if x is not None:
            hit = np.isclose(np.asarray(ds[path].values, float), x, rtol=1e-9, atol=0.0)
    if not hit.any():
        shown = ", ".join(dict.fromkeys(written[:12]))
        raise ScenarioError("--select", f"{path}={text}", f"no such value (values: {shown}"
                                                          f"{', ...' if len(set(written)) > 12 else ''})")
    return hit


def plot_sweep(ds, x: str, metric: str, out, y: str | None = None, select: dict | None = None,
               reduce: str | None = None) -> None:
    """Draw ``metric`` against swept parameter ``x`` (and ``y``: heatmap) into the PNG ``out``."""
    from frogsim._files import write_figure
    from frogsim._plotting import figure, save
    params, metrics = _params(ds), _metrics(ds)
    if not params:
        raise ScenarioError("results", ds.attrs.get("title", "?"), "is not a frogsim sweep results file")
    for flag, p in (("--x", x), ("--y", y)):
        if p is not None and p not in params:
            raise ScenarioError(flag, p, f"must be a swept parameter ({', '.join(params)})")
    if y == x:
        raise ScenarioError("--y", y, "must differ from --x")
    if metric not in metrics:
        raise ScenarioError("--metric", metric, f"must be a recorded metric ({', '.join(metrics)})")
    if reduce not in (None, "mean"):
        raise ScenarioError("--reduce", reduce, "must be 'mean'")
    select = dict(select or {})
    for p in select:
        if p not in params:
            raise ScenarioError("--select", p, f"must be a swept parameter ({', '.join(params)})")
        if p in (x, y):
            raise ScenarioError("--select", p, "is on an axis already")
    mfactor, mlabel = _metric(ds, metric)
    da = ds[metric].where(ds["completed"].astype(bool)) / mfactor
    grid = ds.attrs.get("sweep_method") == "grid"
    note = []
    if grid:
        for p, text in select.items():
            da = da.isel({p: int(np.argmax(_match(ds, p, text)))})
            note.append(f"{p} = {text}")
        rest = [d for d in da.dims if d not in (x, y)]
        if rest and reduce != "mean":
            p = rest[0]
            shown = ", ".join(np.asarray(ds[f"{p}_as_written"].values).astype(str)[:8])
            raise ScenarioError("--select", p, f"is swept too: fix it with --select '{p}=VALUE' "
                                               f"(values: {shown}) or average with --reduce mean")
        if rest:
            da = da.mean(dim=rest, skipna=True)
            note.append("mean over " + ", ".join(rest))
    else:
        keep = np.ones(ds.sizes["point"], bool)
        for p, text in select.items():
            keep &= _match(ds, p, text)
            note.append(f"{p} = {text}")
        da = da.isel(point=np.flatnonzero(keep))
    xv, xlabel = _axis(ds, x)
    xlog, ylog = is_log(ds, x), (y is not None and is_log(ds, y))
    fig, ax = figure(1, 1, width=7.0, height=4.8)
    a = ax[0, 0]
    if grid and y is None:
        vals = da.transpose(x).values
        a.plot(xv, vals, "o-")
        a.set_xlabel(xlabel)
        a.set_ylabel(mlabel)
    elif grid:
        yv, ylabel = _axis(ds, y)
        vals = da.transpose(y, x).values
        if xv.dtype.kind in "US" or yv.dtype.kind in "US":
            mesh = a.imshow(vals, origin="lower", aspect="auto")
            a.set_xticks(range(len(xv)), xv)
            a.set_yticks(range(len(yv)), yv)
            xlog = ylog = False             # index axes
        else:
            ix, iy = np.argsort(xv), np.argsort(yv)          # cells need sorted centres
            xv, yv, vals = xv[ix], yv[iy], vals[np.ix_(iy, ix)]
            mesh = a.pcolormesh(_edges(xv, xlog), _edges(yv, ylog), vals, shading="flat")
            if vals.shape[0] > 2 and vals.shape[1] > 2 and np.isfinite(vals).sum() > 3:
                cs = a.contour(xv, yv, vals, colors="k", linewidths=0.6)
                a.clabel(cs, fontsize=7)
        fig.colorbar(mesh, ax=a, label=mlabel)
        a.set_xlabel(xlabel)
        a.set_ylabel(ylabel)
        a.grid(False)
    else:
        xs = xv[da["point"].values]
        if y is None:
            a.plot(xs, da.values, "o", ms=3)
            a.set_ylabel(mlabel)
        else:
            yv, ylabel = _axis(ds, y)
            sc = a.scatter(xs, yv[da["point"].values], c=da.values, s=14)
            fig.colorbar(sc, ax=a, label=mlabel)
            a.set_ylabel(ylabel)
        a.set_xlabel(xlabel)
        others = [p for p in params if p not in (x, y) and p not in select]
        if others:
            note.append("varying: " + ", ".join(others))
    for on, axis, set_scale in ((xlog, a.xaxis, a.set_xscale), (ylog, a.yaxis, a.set_yscale)):
        if on:
            set_scale("log")
            _plain_log_ticks(axis)
    done = int(ds["completed"].sum())
    title = f"{ds.attrs.get('sweep_name', 'sweep')}: {metric} ({ds.attrs.get('muscle', '')})"
    if done < ds["completed"].size:
        title += f" - {done} of {ds['completed'].size} points done"
    a.set_title(title, fontsize=10)
    write_figure(out, lambda p: save(fig, p, "frogsim sweep; " + "; ".join(note) if note else "frogsim sweep"))
