"""Plots of a sweep's results: a metric against one swept parameter (line) or two (heatmap).

Swept parameters not on an axis must be fixed with ``select`` (a value as written, e.g. "45 L/min",
or a number in SI) or averaged over with ``reduce="mean"``. Random, LHS and list sweeps are drawn
as scatter plots over their points; ``select`` there keeps the points with that value.

"Not reached" is never hidden. A metric is NaN at a point that ran to the end (``completed``, not
``failed``) when the run never got there (a rise time while the pressure stays below its 90 %
mark): such points are *not reached*. Unfinished and failed points are *not run* and are left out
(counted in the figure's note).

* line: a not-reached point is drawn as an "x" on the axis' bottom edge, with a legend entry;
* ``reduce="mean"`` (line): the mean is drawn (filled markers, the line) only where every run
  point of the averaged ones reached the metric; where only some did, the mean of those is drawn
  as an open marker labelled "27 of 42 reached", and where none did, an "x" labelled "0 of 42
  reached". :func:`reduced` returns these numbers;
* heatmap: a cell whose value is NaN (not reached; with ``reduce="mean"``: not reached at one or
  more of the averaged points) is hatched grey and the legend says so.
"""
from __future__ import annotations

import numpy as np

from frogsim._words import count
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


def _ran(ds):
    """Points that ran to the end: completed and not failed."""
    ran = ds["completed"].astype(bool)
    return ran & ~ds["failed"].astype(bool) if "failed" in ds else ran


def reduced(da, ran, dims) -> dict:
    """The mean of ``da`` over ``dims`` honest about not-reached points (module docstring):
    ``n_run`` points that ran, ``n_reached`` of them with a value, ``mean`` over all of them (NaN
    unless every run point reached it, or none ran) and ``mean_reached`` over those that did."""
    reached = da.notnull() & ran
    n_run = ran.sum(dim=dims)
    n_reached = reached.sum(dim=dims)
    mean_reached = da.where(reached).mean(dim=dims, skipna=True)
    mean = mean_reached.where((n_reached == n_run) & (n_run > 0))
    return {"mean": mean, "mean_reached": mean_reached, "n_run": n_run, "n_reached": n_reached}


def _mark_missed(a, xs, missed, label: str) -> None:
    """An "x" on the bottom edge of the axes at every x whose point was not reached."""
    missed = np.asarray(missed, bool)
    if missed.any():
        a.plot(np.asarray(xs)[missed], np.zeros(int(missed.sum())), "x", color="tab:red", ms=8, mew=2,
               clip_on=False, transform=a.get_xaxis_transform(), label=label)


def _draw_partial(a, xv, r: dict, xlog: bool = False) -> None:
    """Open markers (mean of the points that reached it) and "k of n reached" where only some
    averaged points reached the metric; an "x" on the bottom edge where none did."""
    n_run, n_reached = np.asarray(r["n_run"]), np.asarray(r["n_reached"])
    some = (n_reached > 0) & (n_reached < n_run)
    if some.any():
        a.plot(np.asarray(xv)[some], np.asarray(r["mean_reached"])[some], "o", mfc="none", color="tab:red",
               ms=8, label="mean of the points that reached it (k of n)")
        ys = np.asarray(r["mean_reached"], float)           # every mean drawn: the y range
        for xk, yk, k, n in zip(np.asarray(xv)[some], ys[some], n_reached[some], n_run[some]):
            _count_label(a, f"{k} of {n} reached", (xk, yk), xv, ys, xlog)
    none = (n_reached == 0) & (n_run > 0)
    if none.any():
        _mark_missed(a, xv, none, "no averaged point reached it")
        for xk, n in zip(np.asarray(xv)[none], n_run[none]):
            _count_label(a, f"0 of {n} reached", (xk, 0.02), xv, None, xlog)


def _count_label(a, text: str, xy, xs, ys, xlog: bool) -> None:
    """A count written beside its point, towards the middle of the data: to the left of a point in
    the right half of the x values, below one in the upper half of ``ys`` (None: the point is on
    the axes' bottom edge, the label above it), so that it never leaves the axes at an edge; the
    middle of a log x axis (``xlog``) is the geometric one."""
    xs = np.asarray(xs, float)
    lo, hi = np.nanmin(xs), np.nanmax(xs)
    mid = np.sqrt(lo * hi) if xlog and lo > 0 else 0.5 * (lo + hi)
    left = xy[0] > mid
    if ys is None:
        below = False
    else:
        ys = np.asarray(ys, float)
        below = bool(xy[1] > 0.5 * (np.nanmin(ys) + np.nanmax(ys)))
    a.annotate(text, xy, xycoords="data" if ys is not None else a.get_xaxis_transform(),
               textcoords="offset points", xytext=(-6 if left else 6, -6 if below else 6),
               ha="right" if left else "left", va="top" if below else "bottom", fontsize=7, color="tab:red")


def _hatch_nan(a, label: str) -> None:
    """Hatch what shows through NaN cells (the axes' background) and say so in a legend."""
    from matplotlib.patches import Patch
    a.set_facecolor("0.85")
    a.patch.set_hatch("//")
    a.patch.set_edgecolor("0.55")
    a.legend(handles=[Patch(facecolor="0.85", edgecolor="0.55", hatch="//", label=label)],
             fontsize=8, loc="upper left", bbox_to_anchor=(0.0, -0.12), frameon=False)


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
    ran = _ran(ds)
    da = ds[metric].where(ran) / mfactor
    grid = ds.attrs.get("sweep_method") == "grid"
    note = []
    partial = None
    if grid:
        for p, text in select.items():
            k = int(np.argmax(_match(ds, p, text)))
            da, ran = da.isel({p: k}), ran.isel({p: k})
            note.append(f"{p} = {text}")
        rest = [d for d in da.dims if d not in (x, y)]
        if rest and reduce != "mean":
            p = rest[0]
            shown = ", ".join(np.asarray(ds[f"{p}_as_written"].values).astype(str)[:8])
            raise ScenarioError("--select", p, f"is swept too: fix it with --select '{p}=VALUE' "
                                               f"(values: {shown}) or average with --reduce mean")
        if rest:
            partial = reduced(da, ran, rest)
            da = partial["mean"]
            note.append("mean over " + ", ".join(rest) + " (only where every point reached it)")
    else:
        keep = np.ones(ds.sizes["point"], bool)
        for p, text in select.items():
            keep &= _match(ds, p, text)
            note.append(f"{p} = {text}")
        da, ran = da.isel(point=np.flatnonzero(keep)), ran.isel(point=np.flatnonzero(keep))
    n_ran = int(ran.sum())
    n_not_run = int(ran.size - n_ran)
    n_missed = int((ran & da.isnull()).sum()) if partial is None else None
    if n_not_run:
        note.append(f"{n_not_run} point(s) not run or failed, left out")
    xv, xlabel = _axis(ds, x)
    xlog, ylog = is_log(ds, x), (y is not None and is_log(ds, y))
    fig, ax = figure(1, 1, width=7.0, height=4.8)
    a = ax[0, 0]
    if grid and y is None:
        vals = da.transpose(x).values
        if partial is None:
            a.plot(xv, vals, "o-", label=metric if n_missed else None)
            _mark_missed(a, xv, (ran & da.isnull()).transpose(x).values, "not reached (NaN)")
        else:
            a.plot(xv, vals, "o-", label="mean (every point reached it)")
            _draw_partial(a, xv, {k: v.transpose(x).values for k, v in partial.items()}, xlog)
        if a.get_legend_handles_labels()[0]:
            a.legend(fontsize=8, loc="best")
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
        if partial is None:
            n_cells_missed, n_cells_not_run = int((ran & da.isnull()).sum()), int((~ran).sum())
        else:
            n_run, n_reached = partial["n_run"], partial["n_reached"]
            n_cells_missed = int(((n_reached < n_run) & (n_run > 0)).sum())
            n_cells_not_run = int((n_run == 0).sum())
        if n_cells_missed or n_cells_not_run:
            what = [f"{n_cells_missed} of {vals.size} cells not reached"
                    + (" at one or more averaged points" if partial is not None else "")] * bool(n_cells_missed)
            what += [f"{n_cells_not_run} of {vals.size} not run or failed"] * bool(n_cells_not_run)
            _hatch_nan(a, "; ".join(what))
        a.set_xlabel(xlabel)
        a.set_ylabel(ylabel)
        a.grid(False)
    else:
        xs = xv[da["point"].values]
        if y is None:
            a.plot(xs, da.values, "o", ms=3, label=metric)
            _mark_missed(a, xs, (ran & da.isnull()).values, "not reached (NaN)")
            if n_missed:
                a.legend(fontsize=8, loc="best")
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
        if y is not None and n_missed:
            note.append(f"{n_missed} of {count(n_ran, 'point')} not reached (not drawn)")
    for on, axis, set_scale in ((xlog, a.xaxis, a.set_xscale), (ylog, a.yaxis, a.set_yscale)):
        if on:
            set_scale("log")
            _plain_log_ticks(axis)
    done = int(ds["completed"].sum())
    title = f"{ds.attrs.get('sweep_name', 'sweep')}: {metric} ({ds.attrs.get('muscle', '')})"
    if done < ds["completed"].size:
        title += f" - {done} of {count(ds['completed'].size, 'point')} done"
    a.set_title(title, fontsize=10)
    write_figure(out, lambda p: save(fig, p, "frogsim sweep; " + "; ".join(note) if note else "frogsim sweep"))
