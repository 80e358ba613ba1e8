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


def shade_valve_phases(ax, t_open: float, t_close: float) -> None:
    """Shade the pressurise phase (charge valve open) on a time axis."""
    ax.axvspan(t_open, t_close, color="tab:orange", alpha=0.08, lw=0, label="charge valve open")
