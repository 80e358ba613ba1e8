"""Shared figure helpers (matplotlib, headless)."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def figure(nrows: int = 1, ncols: int = 1, width: float = 7.5, height: float = 4.2, **kw):
    """A figure with a consistent size and style."""
    fig, axes = plt.subplots(nrows, ncols, figsize=(width, height), squeeze=False, **kw)
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
    return fig, axes


def save(fig, path: str, source_note: str = "") -> None:
    """Save and close a figure, with an optional note on where the inputs came from."""
    if source_note:
        fig.text(0.01, 0.005, source_note, fontsize=7, color="0.35", ha="left", va="bottom")
    fig.tight_layout(rect=(0, 0.03 if source_note else 0, 1, 1))
    fig.savefig(path, dpi=120)
    plt.close(fig)


def legend_in(lax, *axes, **kw):
    """The legend of ``axes`` (their entries in order, twin axes included) drawn in ``lax``, an axes of
    the figure's grid that shows nothing else: the layout then keeps it clear of every panel's
    curves and labels, however the data fill their panels. ``kw`` go to ``legend`` (default: upper
    left corner of ``lax``, no frame)."""
    handles, labels = [], []
    for a in axes:
        h, lab = a.get_legend_handles_labels()
        handles += h
        labels += lab
    lax.axis("off")
    return lax.legend(handles, labels, **{"loc": "upper left", "frameon": False, "borderaxespad": 0.0, **kw})


def away_from(ax, xy, other):
    """Unit directions (display frame, x right, y up) in which to write a label beside each point of
    the curve ``xy`` (data coordinates, in order along the curve): across the curve, on the side
    away from the nearest point of ``other`` (data coordinates; the points of the curves the labels
    must not land on). Use after the axes' scales and limits are set."""
    import numpy as np
    ax.autoscale_view()
    p = ax.transData.transform(np.asarray(xy, float))
    q = ax.transData.transform(np.asarray(other, float)) if len(other) else np.empty((0, 2))
    out = []
    for i in range(len(p)):
        d = p[min(i + 1, len(p) - 1)] - p[max(i - 1, 0)]
        n = np.array([-d[1], d[0]]) / (np.hypot(*d) or 1.0)
        if len(q):
            near = q[np.argmin(np.hypot(*(q - p[i]).T))] - p[i]
            if np.dot(n, near) > 0:
                n = -n
        elif n[1] < 0:
            n = -n
        out.append((float(n[0]), float(n[1])))
    return out


def shade_valve_phases(ax, t_open: float, t_close: float) -> None:
    """Shade the pressurise phase (charge valve open) on a time axis."""
    ax.axvspan(t_open, t_close, color="tab:orange", alpha=0.08, lw=0, label="charge valve open")


# --- layout check -----------------------------------------------------------------------------------
def layout_problems(fig, pad: float = 0.5) -> list[str]:
    """What in a drawn figure hides what it shows, from matplotlib's own layout (display pixels):

    * a legend whose box holds a piece of a data line (any :class:`~matplotlib.lines.Line2D` of any
      axes, its vertices and the segments between them as drawn, steps included, clipped to its
      axes), a marker of a scatter, a bar, or a text (titles, axis and tick labels, other texts);
    * a text written in an axes (``ax.text``, annotations, contour labels) whose box holds a piece of
      a data line or a scatter marker, that overlaps another text of the figure, or that reaches
      out of its axes (across the frame, the tick labels or the title);
    * tick labels of one axis (major and minor) that overlap each other;
    * a text or legend not wholly inside the figure.

    ``pad`` [px] shrinks each box before the test, so that touching at the edge is not overlap.
    Returns one line per problem (empty: none); call after the figure's layout is final (e.g. after
    ``tight_layout``)."""
    import numpy as np
    from matplotlib.cbook import STEP_LOOKUP_MAP
    from matplotlib.collections import PathCollection
    from matplotlib.path import Path
    from matplotlib.text import Text
    from matplotlib.transforms import Bbox

    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()

    def shrunk(box):
        return Bbox.from_extents(box.x0 + pad, box.y0 + pad, box.x1 - pad, box.y1 - pad)

    def name(artist) -> str:
        if isinstance(artist, Text):
            return f"text {artist.get_text()!r}"
        label = artist.get_label() or ""
        return f"{type(artist).__name__} {label!r}" if not label.startswith("_") else type(artist).__name__

    def where(ax) -> str:
        title = ax.get_title() or ax.get_ylabel() or "an axes"
        return f"[{title[:60]}]"

    # what the figure shows: (axes, artist, runs of display points, whether the segments are drawn)
    data = []
    for ax in fig.axes:
        for ln in ax.get_lines():
            if not ln.get_visible():
                continue
            xy = np.asarray(ln.get_xydata(), dtype=float)
            if len(xy) == 0:
                continue
            style = ln.get_drawstyle()
            if style in STEP_LOOKUP_MAP and style != "default":
                xy = np.column_stack(STEP_LOOKUP_MAP[style](xy[:, 0], xy[:, 1]))
            drawn = ln.get_linestyle() not in ("None", "none", "", " ")
            data.append((ax, ln, ln.get_transform().transform(xy), drawn, ln.get_clip_on()))
        for coll in ax.collections:
            if isinstance(coll, PathCollection) and coll.get_visible() and len(coll.get_offsets()):
                pts = coll.get_offset_transform().transform(np.asarray(coll.get_offsets(), dtype=float))
                data.append((ax, coll, pts, False, coll.get_clip_on()))
    bars = [(ax, bar) for ax in fig.axes for c in ax.containers for bar in getattr(c, "patches", [])
            if bar.get_visible()]

    def covered(box, ax, pts, drawn, clip) -> bool:
        region = Bbox.intersection(box, ax.bbox) if clip else box
        if region is None or region.width <= 0 or region.height <= 0:
            return False
        ok = np.isfinite(pts).all(axis=1)
        if drawn:
            # each finite run as its own path: a gap (NaN) is not a segment
            cuts = np.flatnonzero(np.diff(ok.astype(int)) != 0) + 1
            for run, good in zip(np.split(pts, cuts), np.split(ok, cuts)):
                if good[0] and (len(run) > 1 and Path(run).intersects_bbox(region, filled=False)):
                    return True
        p = pts[ok]
        return bool(np.any((p[:, 0] >= region.x0) & (p[:, 0] <= region.x1)
                           & (p[:, 1] >= region.y0) & (p[:, 1] <= region.y1)))

    def shown(t) -> bool:
        return t.get_visible() and bool(t.get_text().strip())

    def axis_texts(axis) -> list:
        if not (axis.axes.axison and axis.get_visible()):
            return []                                # axis("off"): nothing of it is drawn
        try:                                         # the ticks drawn: those inside the view
            ticks = axis._update_ticks()
        except AttributeError:                       # pragma: no cover (older matplotlib)
            ticks = axis.get_major_ticks()
        return [lab for tk in ticks for lab in (tk.label1, tk.label2)] + [axis.label, axis.get_offset_text()]

    all_texts = list(fig.texts)
    for ax in fig.axes:
        all_texts += [ax.title, ax._left_title, ax._right_title, *ax.texts]
        all_texts += axis_texts(ax.xaxis) + axis_texts(ax.yaxis)
    all_texts = [t for t in all_texts if shown(t)]
    legends = [(ax, ax.get_legend()) for ax in fig.axes if ax.get_legend() is not None] \
        + [(None, leg) for leg in fig.legends]
    written = [(ax, t) for ax in fig.axes for t in ax.texts if shown(t)]
    problems = []
    fbox = fig.bbox

    def inside(box, outer) -> bool:
        return box.x0 >= outer.x0 and box.y0 >= outer.y0 and box.x1 <= outer.x1 and box.y1 <= outer.y1
    for ax, leg in legends:
        if not leg.get_visible():
            continue
        box = shrunk(leg.get_window_extent(renderer))
        what = f"legend {where(ax) if ax is not None else '[figure]'}"
        if not inside(box, fbox):
            problems.append(f"{what} leaves the figure")
        for dax, artist, pts, drawn, clip in data:
            if covered(box, dax, pts, drawn, clip):
                problems.append(f"{what} covers {name(artist)} {where(dax)}")
        for bax, bar in bars:
            if box.overlaps(bar.get_window_extent(renderer)):
                problems.append(f"{what} covers a bar {where(bax)}")
        for t in all_texts:
            if box.overlaps(shrunk(t.get_window_extent(renderer))):
                problems.append(f"{what} covers {name(t)}")
    for ax, t in written:
        box = shrunk(t.get_window_extent(renderer))
        if not inside(box, ax.bbox):
            problems.append(f"{name(t)} {where(ax)} reaches out of its axes")
        for dax, artist, pts, drawn, clip in data:
            if covered(box, dax, pts, drawn, clip):
                problems.append(f"{name(t)} {where(ax)} lies on {name(artist)} {where(dax)}")
        for u in all_texts:
            if u is not t and box.overlaps(shrunk(u.get_window_extent(renderer))):
                if not any(u is v for _, v in written) or id(u) > id(t):   # each written pair once
                    problems.append(f"{name(t)} {where(ax)} overlaps {name(u)}")
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if not axis_texts(axis):
                continue
            labels = [t for t in axis_texts(axis)[:-2] if shown(t)]
            labels += [t for tk in axis.get_minor_ticks() for t in (tk.label1, tk.label2)
                       if shown(t) and tk.get_visible() and axis.get_view_interval().min()
                       <= tk.get_loc() <= axis.get_view_interval().max()]
            boxes = [shrunk(t.get_window_extent(renderer)) for t in labels]
            for i in range(len(labels)):
                for j in range(i + 1, len(labels)):
                    if boxes[i].overlaps(boxes[j]):
                        problems.append(f"tick labels {labels[i].get_text()!r} and {labels[j].get_text()!r} "
                                        f"{where(ax)} overlap")
    for t in all_texts:
        box = shrunk(t.get_window_extent(renderer))
        if not inside(box, fbox):
            problems.append(f"{name(t)} leaves the figure")
    return problems
