"""Running sweeps: each point's metrics equal a one-by-one frogsim.simulate run; the NetCDF layout;
Dask gives the same numbers as a local run; a file of another spec is refused; plots."""
import json
import tomllib

import numpy as np
import pytest
from sweep_helpers import write_case

import frogsim
from frogsim.cli import main
from frogsim.sweep import load_spec, read_results, run_sweep
from frogsim.errors import ScenarioError

LHS = """
name = "lhs-test"
[base]
scenario = "one-hip.toml"
[sweep]
method = "lhs"
samples = 12
seed = 3
[sweep.parameters]
"source.initial_pressure_gauge" = { min = "3 bar", max = "6 bar" }
"valves.charge.sonic_conductance" = { min = "0.2 L/(s*bar)", max = "0.8 L/(s*bar)" }
"muscles.hip.motion.fraction" = { min = 0.0, max = 1.0 }
[record]
metrics = ["rise_time", "final_pressure", "aeration_volume", "source_drop", "source_final", "air_used"]
[run]
chunk_size = 5
"""


def one_by_one(spec, k):
    """The point's Result from frogsim.simulate of the point's variant, through the public API."""
    base = frogsim.load_scenario(spec.base_dir + "/one-hip.toml")
    return frogsim.simulate(base.replace(spec.point(k)))


def expected_metrics(r, m="hip"):
    """The metrics as the results file stores them: SI (Pa, m^3 at standard state). The registry
    computes bar and litres; the file multiplies by the factor, so the same product is taken here."""
    patm, rho = r.atmospheric_pressure, r.reference_density
    ps = r.source_pressure
    return {"rise_time": r.rise_time(m),
            "final_pressure": (r.pressure_at_close(m) - patm) / 1e5 * 1e5,
            "aeration_volume": r.aeration_volume(m) * 1e3 * 1e-3,
            "source_drop": (ps[0] - ps.min()) / 1e5 * 1e5,
            "source_final": (ps[-1] - patm) / 1e5 * 1e5,
            "air_used": r.charged_mass(m)[-1] / rho * 1e3 * 1e-3}


@pytest.fixture(scope="module")
def grid_case(tmp_path_factory):
    folder = tmp_path_factory.mktemp("grid")
    path = write_case(folder)
    ds = run_sweep(path, out=folder / "results.nc", workers=2, progress=False)
    return folder, path, ds


def test_grid_metrics_equal_one_by_one_runs(grid_case):
    folder, path, ds = grid_case
    spec = load_spec(path)
    assert bool(ds["completed"].all()) and not bool(ds["failed"].any())
    for k in range(spec.n_points):
        at = dict(zip(spec.dims, np.unravel_index(k, spec.shape)))
        r = one_by_one(spec, k)
        for name, value in expected_metrics(r).items():
            if name in spec.metrics:       # NaN == NaN: a rise not reached in both
                assert np.array_equal(ds[name].isel(at).item(), value, equal_nan=True), (k, name)
        # time series: every 10th output sample of the same run
        assert np.array_equal(ds["muscle_pressure"].isel(at).values, r.muscle_pressure("hip")[::10])
        assert np.array_equal(ds["source_pressure"].isel(at).values, r.source_pressure[::10])
    # the sweep changes what it should: a higher branch limit fills faster. The 103 cm^3 muscle
    # needs V dp/(k R T rho_ref) = 103e-6 * 5.4e5 / (1.4 * 287 * 293.15 * 1.189) = 0.40 L standard
    # for 90 % of its 6 bar rise (Eq. 6); in the 0.3 s charge 15 and 45 L/min pass at most 0.075
    # and 0.225 L: not reached, so no rise time (NaN) rather than a clipped one; 180 L/min gets there
    at6 = {"source.initial_pressure_gauge": 6e5}
    rt = ds["rise_time"].sel(at6).isel({"muscles.hip.motion.fraction": 1})
    assert np.isnan(rt.values[0]) and np.isnan(rt.values[1]) and np.isfinite(rt.values[2])
    fp = ds["final_pressure"].sel(at6).isel({"muscles.hip.motion.fraction": 1})
    assert np.all(np.diff(fp.values) > 0)


def test_lhs_metrics_equal_one_by_one_runs(tmp_path):
    path = write_case(tmp_path, LHS)
    spec = load_spec(path)
    ds = run_sweep(spec, workers=2, progress=False)
    assert ds["rise_time"].dims == ("point",) and ds.sizes["point"] == 12
    for k in range(spec.n_points):
        r = one_by_one(spec, k)
        for name, value in expected_metrics(r).items():
            assert np.array_equal(ds[name].isel(point=k).item(), value, equal_nan=True), (k, name)
        assert ds["source.initial_pressure_gauge"].values[k] == r.model.scenario.source.initial_pressure_gauge


def test_results_file_layout(grid_case):
    folder, path, ds = grid_case
    f = read_results(folder / "results.nc")
    assert not (folder / "results.nc.parts").exists()          # journal removed when complete
    spec = load_spec(path)
    assert list(f["rise_time"].dims) == spec.paths
    p = f["source.initial_pressure_gauge"]
    assert p.attrs["units"] == "Pa" and p.attrs["display_units"] == "bar"
    assert np.allclose(p.values, [3e5, 4e5, 5e5, 6e5], rtol=1e-15)
    assert list(f["supply.branch_limit_as_written"].values) == ["15 L/min", "45 L/min", "180 L/min"]
    assert f["supply.branch_limit"].attrs["units"] == "m3 s-1"          # CF notation
    assert np.allclose(f["supply.branch_limit"].values * 6e4, [15, 45, 180])
    assert f["rise_time"].attrs["units"] == "s" and "90 %" in f["rise_time"].attrs["description"]
    assert f["aeration_volume"].attrs["units"] == "m3"                   # SI, at standard state
    assert "standard reference state" in f["aeration_volume"].attrs["long_name"]
    assert (f["aeration_volume"].attrs["display_units"], f["aeration_volume"].attrs["display_factor"]) == ("L", 1e-3)
    assert f["completed"].dtype == bool and bool(f["completed"].all())
    assert f["muscle_pressure"].dims[-1] == "time" and f["muscle_pressure"].attrs["units"] == "Pa"
    assert np.allclose(f["time"].values, np.arange(51) * 0.01)
    assert f.attrs["sweep_hash"] == spec.hash and f.attrs["complete"] == 1
    assert tomllib.loads(f.attrs["base_scenario_toml"]) == spec.base_raw
    assert f.attrs["spec_toml"] == path.read_text()
    for name in ds.data_vars:
        assert np.array_equal(f[name].values, ds[name].values, equal_nan=True)


def test_dask_local_cluster_gives_identical_results(tmp_path):
    from distributed import LocalCluster
    path = write_case(tmp_path, LHS)
    local = run_sweep(path, workers=1, progress=False)
    # worker processes: the chunks travel to them and their metric arrays come back
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        remote = run_sweep(path, out=tmp_path / "dask.nc", scheduler=cluster.scheduler_address, progress=False)
        prefixes = list(cluster.scheduler.task_prefixes)
    assert any(p.startswith("frogsim-sweep") for p in prefixes), prefixes      # it did go through Dask
    f = read_results(tmp_path / "dask.nc")
    for name in ("rise_time", "final_pressure", "aeration_volume", "source_drop", "completed"):
        assert np.array_equal(remote[name].values, local[name].values, equal_nan=True), name
        assert np.array_equal(f[name].values, local[name].values, equal_nan=True), name


def test_unreachable_scheduler_exit_2_nothing_written(tmp_path, capsys):
    path = write_case(tmp_path)
    out = tmp_path / "out" / "r.nc"
    code = main(["sweep", str(path), "--out", str(out), "--scheduler", "tcp://127.0.0.1:9",
                 "--connect-timeout", "0.5", "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "--scheduler = 'tcp://127.0.0.1:9'" in err, err
    assert not (tmp_path / "out").exists()


def test_a_server_that_is_no_dask_scheduler_is_refused_in_time(tmp_path, capsys):
    """A server that takes the connection and answers something else (an HTTP server: "400 Bad
    request", then it closes) left Dask's handshake waiting for good. Now: one line naming the
    address and what is wrong, exit 2, nothing written, the command back within the connect timeout
    and a few seconds (the test fails if it is not back within a minute)."""
    import http.server
    import threading
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.BaseHTTPRequestHandler)
    server.daemon_threads = True         # a handler still reading the client's bytes does not hold the test
    serve = threading.Thread(target=server.serve_forever, daemon=True)
    serve.start()
    path = write_case(tmp_path)
    out = tmp_path / "out" / "r.nc"
    address = f"tcp://127.0.0.1:{server.server_address[1]}"
    result = {}
    run = threading.Thread(target=lambda: result.update(code=main(
        ["sweep", str(path), "--out", str(out), "--scheduler", address, "--connect-timeout", "1", "--quiet"])))
    run.start()
    run.join(60.0)
    server.shutdown()
    server.server_close()
    assert not run.is_alive(), "the sweep still waits on a server that is no Dask scheduler"
    err = capsys.readouterr().err.strip()
    assert result["code"] == 2 and len(err.splitlines()) == 1, err
    assert f"--scheduler = '{address}'" in err and "not a Dask scheduler" in err, err
    assert not (tmp_path / "out").exists()


def test_other_spec_refused_then_overwritten(grid_case, capsys):
    folder, path, ds = grid_case
    target = folder / "other.nc"
    assert main(["sweep", str(path), "--out", str(target), "--quiet"]) == 0
    before = target.read_bytes()
    other = folder / "other.toml"
    other.write_text(path.read_text().replace("num = 4", "num = 2"))
    capsys.readouterr()
    assert main(["sweep", str(other), "--out", str(target), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "another spec" in err and "--overwrite" in err
    assert target.read_bytes() == before
    assert main(["sweep", str(other), "--out", str(target), "--quiet", "--overwrite"]) == 0
    f = read_results(target)
    assert f.sizes["source.initial_pressure_gauge"] == 2 and f.attrs["sweep_hash"] == load_spec(other).hash
    # a file that is not a sweep result is not replaced either
    junk = folder / "junk.nc"
    junk.write_text("not netcdf")
    assert main(["sweep", str(path), "--out", str(junk), "--quiet"]) == 2
    assert junk.read_text() == "not netcdf"


def test_rerun_of_complete_sweep_does_nothing(grid_case, capsys):
    folder, path, ds = grid_case
    before = (folder / "results.nc").stat().st_mtime_ns
    assert main(["sweep", str(path), "--out", str(folder / "results.nc")]) == 0
    err = capsys.readouterr().err
    assert "24 of 24 points already done" in err
    # the last line says the points were read, not computed ("24 points in 0.31 s" was the bug)
    last = err.strip().splitlines()[-1]
    assert last.startswith("all 24 points already done in ") and "nothing run" in last, err
    assert (folder / "results.nc").stat().st_mtime_ns == before


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "0", "-1"])
@pytest.mark.parametrize("scheduler", [[], ["--scheduler", "tcp://127.0.0.1:9"]])
def test_a_connect_timeout_that_is_no_time_is_refused(tmp_path, capsys, value, scheduler):
    path = write_case(tmp_path)
    out = tmp_path / "out" / "r.nc"
    assert main(["sweep", str(path), "--out", str(out), f"--connect-timeout={value}", "--quiet"] + scheduler) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("frogsim: error: --connect-timeout = ") and "finite time in seconds > 0" in err, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "out").exists()
    with pytest.raises(ScenarioError, match="connect-timeout"):
        run_sweep(path, connect_timeout=float(value))


def test_plot_line_and_heatmap(grid_case, capsys):
    folder, path, ds = grid_case
    res = str(folder / "results.nc")
    line = folder / "line.png"
    assert main(["plot", res, "--x", "source.initial_pressure_gauge", "--metric", "rise_time",
                 "--select", "supply.branch_limit=45 L/min", "--select", "muscles.hip.motion.fraction=1",
                 "--out", str(line)]) == 0
    assert line.read_bytes()[:4] == b"\x89PNG"
    heat = folder / "heat.png"
    assert main(["plot", res, "--x", "source.initial_pressure_gauge", "--y", "supply.branch_limit",
                 "--metric", "aeration_volume", "--reduce", "mean", "--out", str(heat)]) == 0
    assert heat.read_bytes()[:4] == b"\x89PNG"
    capsys.readouterr()
    # another swept parameter neither on an axis nor fixed: exit 2, names it, nothing written
    bad = folder / "bad.png"
    assert main(["plot", res, "--x", "source.initial_pressure_gauge", "--metric", "rise_time",
                 "--out", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "supply.branch_limit" in err and "--select" in err and not bad.exists()
    assert main(["plot", res, "--x", "source.volume", "--metric", "rise_time", "--out", str(bad)]) == 2
    assert main(["plot", res, "--x", "supply.branch_limit", "--metric", "rise_time",
                 "--select", "source.initial_pressure_gauge=7 bar", "--reduce", "mean", "--out", str(bad)]) == 2
    assert "3 bar, 4 bar" in capsys.readouterr().err and not bad.exists()


def test_failures_attribute_is_json(grid_case):
    folder, path, ds = grid_case
    assert json.loads(read_results(folder / "results.nc").attrs["failures"]) == {}


def test_failed_point_is_isolated_and_reported(tmp_path, monkeypatch, capsys):
    """A point whose integration fails gets NaN metrics and failed = true; the others run as usual."""
    import frogsim.engine.batch as batch
    from frogsim.circuit import layout as L
    from frogsim.errors import SimulationError
    real = batch.run_outputs

    def run_outputs(models, columns=None):
        for m in models:
            if abs(m.g[L.G_VS] - 3e-3) < 1e-12:          # the 3 L source fails
                raise SimulationError(f"batch point 0 ({m.scenario.name!r}): integration stopped (test)")
        return real(models, columns)
    monkeypatch.setattr(batch, "run_outputs", run_outputs)
    spec = GRID_FAIL
    path = write_case(tmp_path, spec)
    out = tmp_path / "r.nc"
    assert main(["sweep", str(path), "--out", str(out), "--quiet"]) == 0
    assert "1 point failed (its metrics are NaN)" in capsys.readouterr().err
    f = read_results(out)
    failed = f["failed"].values
    assert failed.tolist() == [False, True, False] and bool(f["completed"].all())
    assert np.isnan(f["rise_time"].values[1]) and np.isnan(f["final_pressure"].values[1])
    assert np.all(np.isfinite(f["final_pressure"].values[[0, 2]]))
    assert "integration stopped (test)" in json.loads(f.attrs["failures"])["1"]
    monkeypatch.setattr(batch, "run_outputs", real)
    ok = run_sweep(path, progress=False)
    for name in ("rise_time", "final_pressure"):
        assert np.array_equal(ok[name].values[[0, 2]], f[name].values[[0, 2]], equal_nan=True)


GRID_FAIL = """
[base]
scenario = "one-hip.toml"
[sweep.parameters]
"source.volume" = ["2 L", "3 L", "4 L"]
[record]
metrics = ["rise_time", "final_pressure"]
"""
