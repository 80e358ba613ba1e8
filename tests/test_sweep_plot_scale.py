"""Sweep plots: log-spaced parameters on log axes, metrics in their display unit."""
import numpy as np
import pytest
from sweep_helpers import GRID, write_case

import frogsim._plotting as plotting
from frogsim.sweep import read_results, run_sweep
from frogsim.sweep.plot import is_log, plot_sweep

LOG_GRID = GRID.replace('"supply.branch_limit" = { values = [15, 45, 180], unit = "L/min" }',
                        '"supply.branch_limit" = { start = "15 L/min", stop = "180 L/min", num = 3, scale = "log" }'
                        ).replace("num = 4", "num = 2")


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    folder = tmp_path_factory.mktemp("plot")
    run_sweep(write_case(folder, LOG_GRID), out=folder / "r.nc", workers=2, progress=False)
    return folder, read_results(folder / "r.nc")


def drawn(monkeypatch, ds, out, **kw):
    """Draw a sweep plot and return its main axes."""
    seen = {}
    real = plotting.save

    def save(fig, path, note=""):
        seen["ax"] = fig.axes[0]
        seen["label"] = fig.axes[0].get_ylabel()
        seen["lines"] = [ln.get_ydata() for ln in fig.axes[0].get_lines()]
        seen["xscale"], seen["yscale"] = fig.axes[0].get_xscale(), fig.axes[0].get_yscale()
        real(fig, path, note)
    monkeypatch.setattr(plotting, "save", save)
    plot_sweep(ds, out=out, **kw)
    return seen


def test_log_spaced_parameter_on_a_log_axis(results, monkeypatch):
    folder, ds = results
    assert ds["supply.branch_limit"].attrs["scale"] == "log"
    assert is_log(ds, "supply.branch_limit") and not is_log(ds, "source.initial_pressure_gauge")
    sel = {"muscles.hip.motion.fraction": "1", "source.initial_pressure_gauge": "6 bar"}
    seen = drawn(monkeypatch, ds, folder / "a.png", x="supply.branch_limit", metric="final_pressure", select=sel)
    assert seen["xscale"] == "log"
    # the metric is shown in bar gauge, not in the file's Pa
    assert "bar" in seen["label"]
    assert 0 < np.nanmax(seen["lines"][0]) < 7
    seen = drawn(monkeypatch, ds, folder / "b.png", x="source.initial_pressure_gauge", metric="final_pressure",
                 select={"muscles.hip.motion.fraction": "1", "supply.branch_limit": "15 L/min"})
    assert seen["xscale"] == "linear"
    seen = drawn(monkeypatch, ds, folder / "c.png", x="source.initial_pressure_gauge", y="supply.branch_limit",
                 metric="aeration_volume", select={"muscles.hip.motion.fraction": "1"})
    assert (seen["xscale"], seen["yscale"]) == ("linear", "log")
    assert (folder / "c.png").read_bytes()[:4] == b"\x89PNG"


def test_geometric_values_over_a_decade_are_log_without_the_attribute(results):
    _, ds = results
    ds = ds.copy()
    ds["supply.branch_limit"].attrs.pop("scale")
    assert is_log(ds, "supply.branch_limit")                # 15, 52, 180 L/min: geometric, 12x
    ds = ds.assign_coords({"supply.branch_limit": ("supply.branch_limit", [1.0, 2.0, 3.0])})
    assert not is_log(ds, "supply.branch_limit")
