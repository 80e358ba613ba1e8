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


# --- "not reached" is counted and drawn, never averaged away ------------------------------------------
def _with_missed(ds, metric="rise_time"):
    """The results with the metric set by hand: 1.0 everywhere, NaN (not reached) at every point of
    the first branch limit with fraction 0 and at one point of the second; one point not run."""
    ds = ds.copy(deep=True)
    v = np.ones(ds[metric].shape)
    dims = list(ds[metric].dims)
    ib, ifr, ip = dims.index("supply.branch_limit"), dims.index("muscles.hip.motion.fraction"), \
        dims.index("source.initial_pressure_gauge")
    idx = [slice(None)] * 3
    idx[ib], idx[ifr] = 0, 0
    v[tuple(idx)] = np.nan                          # 2 of the 4 points at the first limit not reached
    idx = [0, 0, 0]
    idx[ib], idx[ifr], idx[ip] = 1, 1, 1
    v[tuple(idx)] = np.nan                          # 1 of the 4 at the second limit
    ds[metric].values[...] = v
    comp = np.ones(ds["completed"].shape, bool)
    idx = [0, 0, 0]
    idx[ib] = 2
    comp[tuple(idx)] = False                        # 1 of the 4 at the third limit not run
    ds["completed"].values[...] = comp
    return ds


def test_reduce_mean_never_hides_points_that_were_not_reached(results, monkeypatch):
    from frogsim.sweep.plot import _ran, reduced
    folder, ds = results
    ds = _with_missed(ds)
    da = ds["rise_time"].where(_ran(ds))
    r = reduced(da, _ran(ds), ["source.initial_pressure_gauge", "muscles.hip.motion.fraction"])
    assert list(r["n_run"].values) == [4, 4, 3]
    assert list(r["n_reached"].values) == [2, 3, 3]
    # the mean is drawn only where every run point reached it; elsewhere the count says how many did
    assert np.isnan(r["mean"].values[:2]).all() and r["mean"].values[2] == 1.0
    assert list(r["mean_reached"].values) == [1.0, 1.0, 1.0]
    seen = drawn(monkeypatch, ds, folder / "m.png", x="supply.branch_limit", metric="rise_time",
                 reduce="mean")
    texts = [t.get_text() for t in seen["ax"].texts]
    assert "2 of 4 reached" in texts and "3 of 4 reached" in texts
    labels = seen["ax"].get_legend_handles_labels()[1]
    assert any("reached" in lb for lb in labels)


def test_every_not_reached_point_or_cell_is_marked_with_a_legend_entry(results, monkeypatch):
    folder, ds = results
    ds = _with_missed(ds)
    seen = drawn(monkeypatch, ds, folder / "l.png", x="supply.branch_limit", metric="rise_time",
                 select={"muscles.hip.motion.fraction": "0", "source.initial_pressure_gauge": "3 bar"})
    labels = seen["ax"].get_legend_handles_labels()[1]
    assert "not reached (NaN)" in labels
    seen = drawn(monkeypatch, ds, folder / "h.png", x="source.initial_pressure_gauge", y="supply.branch_limit",
                 metric="rise_time", select={"muscles.hip.motion.fraction": "0"})
    legend = seen["ax"].get_legend()
    assert legend is not None
    assert legend.get_texts()[0].get_text() == "2 of 6 cells not reached; 1 of 6 not run or failed"
