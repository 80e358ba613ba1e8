"""Every figure frogsim makes shows what it draws: no legend holds a piece of a data line, a
scatter marker, a bar or a text; no text written in an axes (labels, annotations, contour labels)
lies on a data line or on another text; no text or legend leaves the figure.

The check is :func:`frogsim._plotting.layout_problems`, computed from matplotlib's own layout (window
extents from the figure's renderer against the display coordinates of every line's points and the
segments drawn between them). Each figure is checked at the moment it is saved (``Figure.savefig``
patched), after its layout is final, so every path that writes a PNG is covered the same way: the
registered studies, ``simulate``'s pressures.png, ``swim``'s swim.png (a fixed base in air, a free
swim in water, a closed-loop controller), ``compare``, the sweep plots, the fit's figures,
``optimize-gait``'s trials.png and the DMSP-20 force figure. Runs are as short as still draws every
artist.

The last tests plant the faults the check exists for (a legend over a line, a text on a line, two
texts on each other, a text cut at the figure's edge) and check that it reports each, and that a
figure without them passes.
"""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure
from sweep_helpers import GRID, write_case

import frogsim._plotting as plotting
from frogsim._plotting import layout_problems
from frogsim.cli import main
from frogsim.studies import STUDIES

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.fixture
def checked(monkeypatch):
    """{PNG file name: the layout problems of its figure}, filled as frogsim saves figures."""
    seen = {}
    real = Figure.savefig

    def savefig(fig, fname, *a, **k):
        seen[Path(str(fname)).name] = layout_problems(fig)
        return real(fig, fname, *a, **k)
    monkeypatch.setattr(Figure, "savefig", savefig)
    return seen


def assert_clean(seen: dict, at_least: int = 1) -> None:
    assert len(seen) >= at_least, f"expected {at_least} figure(s), saw {sorted(seen)}"
    bad = {name: p for name, p in seen.items() if p}
    assert not bad, "\n".join(f"{name}: {line}" for name, p in bad.items() for line in p)


# --- the registered studies ---------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(STUDIES))
def test_every_study_figure_hides_nothing(name, checked, tmp_path, study):
    import copy
    STUDIES[name].draw(copy.deepcopy(study(name)), str(tmp_path / f"{name}.png"))   # the shared run, untouched
    assert_clean(checked)


# --- single runs ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("scenario", ["paper-cycle", "hold-3bar"])
def test_simulate_pressures_figure_hides_nothing(scenario, checked, tmp_path):
    assert main(["simulate", scenario, "--out", str(tmp_path / "run"), "--quiet"]) == 0
    assert_clean(checked)


def test_simulate_draws_a_controllers_setpoint_dashed_in_its_muscles_colour(tmp_path, monkeypatch):
    """hold-3bar holds its hip at a constant 3 bar gauge (its scenario file): pressures.png draws
    that setpoint as a dashed line in the hip's colour, named in the legend."""
    seen = {}
    real = Figure.savefig

    def savefig(fig, fname, *a, **k):
        seen["lines"] = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
        return real(fig, fname, *a, **k)
    monkeypatch.setattr(Figure, "savefig", savefig)
    assert main(["simulate", "hold-3bar", "--out", str(tmp_path / "run"), "--quiet"]) == 0
    lines = seen["lines"]
    sp = [ln for label, ln in lines.items() if label.startswith("hip setpoint")]
    assert len(sp) == 1, sorted(lines)
    assert sp[0].get_linestyle() == "--" and sp[0].get_color() == lines["hip"].get_color()
    assert np.allclose(sp[0].get_ydata(), 3.0)


@pytest.mark.parametrize("scenario, cycles", [("leg-in-air", 1), ("hip-angle-in-air", 1), ("swim", 1)])
def test_swim_figure_hides_nothing(scenario, cycles, checked, tmp_path):
    assert main(["swim", scenario, "--cycles", str(cycles), "--no-animation", "--out", str(tmp_path / "run"),
                 "--quiet"]) == 0
    assert_clean(checked)


def test_a_fixed_base_run_says_it_does_not_swim(tmp_path, monkeypatch, capsys):
    """leg-in-air holds the body on a fixed base in air: no distance or velocity panel, forces named
    for air, and no speed printed as if one had been measured."""
    seen = {}
    real = Figure.savefig

    def savefig(fig, fname, *a, **k):
        seen["ylabels"] = [a.get_ylabel() for a in fig.axes]
        return real(fig, fname, *a, **k)
    monkeypatch.setattr(Figure, "savefig", savefig)
    assert main(["swim", "leg-in-air", "--cycles", "1", "--no-animation", "--out", str(tmp_path / "run")]) == 0
    err = capsys.readouterr().err
    assert "no swimming speed" in err and "mean speed" not in err
    assert not any(label.startswith(("distance", "velocity")) for label in seen["ylabels"])
    assert any(label.startswith("air force") for label in seen["ylabels"])
    assert not any("water" in label for label in seen["ylabels"])


def test_compare_figure_hides_nothing(checked, tmp_path):
    assert main(["compare", "paper-cycle", "hold-3bar", "--signal", "source_pressure",
                 "--out", str(tmp_path / "cmp"), "--quiet"]) == 0
    assert_clean(checked)


# --- sweeps -------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def sweep_results(tmp_path_factory):
    from frogsim.sweep import run_sweep
    folder = tmp_path_factory.mktemp("sweep")
    run_sweep(write_case(folder, GRID), out=folder / "r.nc", workers=2, progress=False)
    return folder / "r.nc"


@pytest.mark.parametrize("how", [
    ["--x", "supply.branch_limit", "--select", "source.initial_pressure_gauge=6 bar",
     "--select", "muscles.hip.motion.fraction=0"],
    ["--x", "source.initial_pressure_gauge", "--reduce", "mean"],
    ["--x", "muscles.hip.motion.fraction", "--reduce", "mean"],
    ["--x", "source.initial_pressure_gauge", "--y", "supply.branch_limit", "--reduce", "mean"],
], ids=["line", "line-mean", "line-mean-right-edge", "heatmap-mean"])
def test_sweep_plot_hides_nothing(how, sweep_results, checked, tmp_path):
    # rise_time: the 15 L/min limit does not reach 90 % of the rise within the 0.3 s charge, so the
    # reduced plots write "k of n reached" at points, also at the right edge (the largest volume)
    assert main(["plot", str(sweep_results), *how, "--metric", "rise_time", "--out", str(tmp_path / "p.png"),
                 "--quiet"]) == 0
    assert_clean(checked)


# --- fits and searches --------------------------------------------------------------------------------
@pytest.mark.parametrize("spec", ["FIT.toml", "force/FIT.toml"])
def test_fit_figures_hide_nothing(spec, checked, tmp_path):
    src = tmp_path / "spec"
    shutil.copytree(EXAMPLES / "fit", src)
    assert main(["fit", str(src / spec), "--starts", "1", "--out", str(tmp_path / "fit"), "--quiet"]) == 0
    assert_clean(checked)


def test_trials_figure_hides_nothing(checked, tmp_path):
    assert main(["optimize-gait", "swim", "--objective", "speed", "--cycles", "1", "--trials", "12",
                 "--workers", "2", "--out", str(tmp_path / "opt"), "--quiet"]) == 0
    assert_clean(checked)


def test_dmsp20_force_figure_hides_nothing(checked, tmp_path):
    from frogsim.components import dmsp20
    dmsp20.plot_fit(str(tmp_path / "dmsp20-force.png"), dmsp20.fit_bladder())
    assert_clean(checked)


# --- the check itself can fail ------------------------------------------------------------------------
def _panel():
    """A figure with one line rising across its axes: y = x on 0..1."""
    fig, ax = plotting.figure()
    a = ax[0, 0]
    x = np.linspace(0, 1, 50)
    a.plot(x, x, label="rising line")
    return fig, a


def test_the_check_reports_a_legend_over_a_line():
    fig, a = _panel()
    # a legend centred on (0.5, 0.5) in axes fraction: the line y = x passes through its middle
    a.legend(loc="center")
    problems = layout_problems(fig)
    assert any(p.startswith("legend") and "rising line" in p for p in problems), problems


def test_the_check_reports_a_legend_over_a_line_between_its_points():
    """Two points only, at the corners: the legend in the middle holds none of them, but the segment
    drawn between them crosses it."""
    fig, ax = plotting.figure()
    a = ax[0, 0]
    a.plot([0, 1], [0, 1], label="two points")
    a.legend(loc="center")
    assert any("two points" in p for p in layout_problems(fig))


def test_the_check_reports_a_text_on_a_line_texts_on_each_other_and_texts_cut_at_an_edge():
    fig, a = _panel()
    a.text(0.5, 0.5, "on the line", ha="center", va="center")
    a.text(0.1, 0.9, "first", ha="left", va="center")
    a.text(0.1, 0.9, "second", ha="left", va="center")
    fig.text(0.99, 0.5, "cut at the right edge", ha="left")
    a.annotate("past the frame", (1, 0.2), xytext=(6, 0), textcoords="offset points")
    problems = layout_problems(fig)
    assert any("'on the line'" in p and "lies on" in p and "rising line" in p for p in problems), problems
    assert any("'first'" in p and "overlaps" in p and "'second'" in p for p in problems), problems
    assert any("'cut at the right edge'" in p and "leaves the figure" in p for p in problems), problems
    assert any("'past the frame'" in p and "reaches out of its axes" in p for p in problems), problems


def test_the_check_reports_crowded_tick_labels():
    fig, a = _panel()
    a.set_xticks(np.linspace(0, 1, 60))          # 60 labels on a 7.5 inch axis: they run together
    assert any(p.startswith("tick labels") and "overlap" in p for p in layout_problems(fig))


def test_the_check_passes_a_legend_beside_the_line():
    fig, a = _panel()
    # y = x leaves the upper-left and lower-right corners empty; a small legend there is clear
    a.legend(loc="upper left", fontsize=8)
    a.text(0.95, 0.05, "clear", ha="right", va="bottom", transform=a.transAxes)
    fig.tight_layout()
    assert layout_problems(fig) == []
