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
    return np.asarray(c.values, float) / factor, f"{path} [{unit}]" if unit else path


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
    da = ds[metric].where(ds["completed"].astype(bool))
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
    unit = ds[metric].attrs.get("units", "")
    mlabel = f"{metric} [{unit}]" if unit else metric
    xv, xlabel = _axis(ds, x)
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
        else:
            mesh = a.pcolormesh(xv, yv, vals, shading="nearest")
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
    done = int(ds["completed"].sum())
    title = f"{ds.attrs.get('sweep_name', 'sweep')}: {metric} ({ds.attrs.get('muscle', '')})"
    if done < ds["completed"].size:
        title += f" - {done} of {ds['completed'].size} points done"
    a.set_title(title, fontsize=10)
    write_figure(out, lambda p: save(fig, p, "frogsim sweep; " + "; ".join(note) if note else "frogsim sweep"))
