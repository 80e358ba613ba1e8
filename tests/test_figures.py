"""Figures say what they draw: every labelled curve has a legend entry, no legend covers a bar,
curves that coincide are drawn once and named together, the palm is never scaled onto an angle
axis; and the run's files: a long CSV is written in pieces under a progress bar (the same text),
an interrupted run's manifest says "interrupted"."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import frogsim
import frogsim._plotting as plotting
from frogsim.cli import main
from frogsim.io.results import same_curves
from frogsim.studies import STUDIES, studies_in


@pytest.fixture
def figures(monkeypatch):
    """Every figure saved through frogsim._plotting.save, kept open for inspection."""
    seen = []
    real = plotting.save

    def save(fig, path, note=""):
        fig.canvas.draw()
        seen.append(fig)
        real(fig, path, note)
    import frogsim.studies.paper as paper
    monkeypatch.setattr(plotting, "save", save)
    monkeypatch.setattr(paper, "save", save)
    return seen


def _legend_texts(fig) -> set:
    out = set()
    for a in fig.axes:
        if a.get_legend() is not None:
            out |= {t.get_text() for t in a.get_legend().get_texts()}
    for leg in fig.legends:
        out |= {t.get_text() for t in leg.get_texts()}
    return out


@pytest.mark.parametrize("name", studies_in("paper"))
def test_every_labelled_curve_of_every_paper_figure_is_in_a_legend_and_no_legend_covers_a_bar(
        name, figures, tmp_path, study):
    import copy
    STUDIES[name].draw(copy.deepcopy(study(name)), str(tmp_path / f"{name}.png"))   # the shared run, untouched
    fig = figures[-1]
    texts = _legend_texts(fig)
    for a in fig.axes:
        labelled = [ln.get_label() for ln in a.get_lines() if not ln.get_label().startswith("_")]
        for label in labelled:
            assert any(label == t or t.startswith(label) for t in texts), f"{name}: {label!r} has no legend entry"
        legend = a.get_legend()
        if legend is None:
            continue
        box = legend.get_window_extent()
        for bar in a.patches:
            if type(bar).__name__ == "Rectangle" and bar.get_height() > 0 and bar is not a.patch:
                assert not box.overlaps(bar.get_window_extent()), f"{name}: the legend covers a bar"


def test_coinciding_curves_are_grouped_and_every_name_kept():
    t = np.linspace(0, 1, 50)
    a, b = np.sin(t) * 1e5, np.sin(t) * 1e5 + 50.0          # 50 Pa apart: one line
    c = np.sin(t) * 1e5 + 500.0                              # 500 Pa: a line of its own
    groups = same_curves(t, [("a", a), ("b", b), ("c", c), ("d", a)])
    assert [g[0] for g in groups] == [["a", "b", "d"], ["c"]]


def test_a_long_csv_is_written_in_pieces_with_a_progress_bar_and_the_same_text(tmp_path, monkeypatch, capsys):
    from frogsim import _files
    monkeypatch.setattr(_files, "CSV_PROGRESS_CELLS", 10)
    monkeypatch.setattr(_files, "CSV_PIECE_ROWS", 7)
    rng = np.random.default_rng(0)
    df = pd.DataFrame({"t [s]": np.arange(50) * 1e-3, "p [bar]": rng.normal(size=50), "n": np.arange(50)})
    _files.write_csv(tmp_path / "a.csv", df)
    assert "writing a.csv" in capsys.readouterr().err
    assert (tmp_path / "a.csv").read_text() == df.to_csv(index=False, float_format="%.8g")


def test_an_interrupted_run_says_interrupted_in_its_manifest(tmp_path, monkeypatch, capsys):
    import frogsim._files as files

    def interrupted(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(files, "write_csv", interrupted)
    out = tmp_path / "run"
    assert main(["simulate", "paper-cycle", "--out", str(out)]) == 130
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "interrupted" and manifest["finished"]
    assert not (out / "timeseries.csv").exists()
    monkeypatch.undo()
    assert main(["simulate", "paper-cycle", "--out", str(out)]) == 0     # replaced without --overwrite


def test_a_joint_angle_panel_without_a_written_settle_hatches_the_default(tmp_path, monkeypatch):
    """swim.png of a joint-angle run whose settle is not written: the panel hatches the default
    settle time the metrics used (summary.json's settle_s), not a missing value."""
    from frogsim.scenario.load import merged_raw
    from frogsim.studies.robot import plot_swim
    raw, _ = merged_raw("hip-angle-in-air")
    del raw["controllers"]["hip"]["settle"]
    raw = frogsim.with_overrides(raw, {"gait.period": "0.5 s"})
    run = frogsim.swim(frogsim.load_robot_scenario(raw))
    assert run.control_metrics()["hip"]["settle_s"] == 0.2
    import frogsim.studies.robot as robot_study
    figures = []
    real_save = robot_study.save

    def keep(fig, path, note):
        figures.append(fig)
        real_save(fig, path, note)
    monkeypatch.setattr(robot_study, "save", keep)
    out = tmp_path / "swim.png"
    plot_swim(run, str(out))
    assert out.read_bytes()[:4] == b"\x89PNG"
    # the hip controller's panel: hatched from the run's start to the default settle, 0.2 s
    # (docs/control.md, the `settle` row: "0.2 s"), and its title says the error counts from there
    (fig,) = figures
    (panel,) = [a for a in fig.axes if a.get_title().startswith("hip: joint-angle control")]
    hatched = [p for p in panel.patches if p.get_hatch() == "//"]
    assert len(hatched) == 1
    x0, x1 = sorted(hatched[0].get_path().transformed(hatched[0].get_patch_transform()).vertices[:, 0][[0, 2]])
    assert x0 == pytest.approx(run.t[0]) and x1 == pytest.approx(0.2)
    assert "tracking error from 0.2 s on" in panel.get_title()
