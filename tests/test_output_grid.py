"""Every output row is written: the output grid is made of whole sample indices (t_k = k dt, the last
row at the duration exactly), in every engine, and a result with a row nobody wrote is never returned.

The failures this guards against: with ``duration = "0.3 s"`` and ``output_interval = "100 ms"``
the grid used to be 0, 0.1, 0.2, 0.30000000000000004, one unit in the last place past the end of
the run, so the last row was uninitialised memory (1e-323, 1.2e214, ...) in the result, its CSV,
its summary and sweep metrics.
"""
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from sweep_helpers import write_case

import frogsim
from frogsim.circuit import layout as L
from frogsim.engine.batch import build_models, run_models, run_outputs
from frogsim.errors import ScenarioError, SimulationError
from frogsim.scenario.load import merged_raw
from frogsim.scenario.motion import output_times
from frogsim.sweep import run_sweep

# the four (duration, interval) pairs of the bug report: k * interval lands one ulp past the end
REPORTED = [(0.3, 0.1), (0.6, 0.2), (0.7, 0.1), (1.2, 0.2)]


@st.composite
def grids(draw, shortest=1e-4, longest=10.0, finest=1e-5, max_rows=200_000):
    """(duration, interval): a duration from 1e-4 s to 10 s (log-uniform, often a round decimal),
    an interval from 1e-5 s to the duration with at most ``max_rows`` rows."""
    exp = draw(st.floats(math.log10(shortest), math.log10(longest)))
    duration = 10.0 ** exp
    if draw(st.booleans()):                      # round decimals, where k * dt misses by an ulp
        duration = float(f"{duration:.1g}")
    lo = max(finest, duration / max_rows)
    frac = draw(st.floats(0.0, 1.0))
    interval = min(duration, lo * (duration / lo) ** frac)
    if draw(st.booleans()):
        interval = min(duration, max(lo, float(f"{interval:.1g}")))
    return duration, interval


def _physical_rows(r, duration):
    """Every row finite; times from 0 to the duration exactly, increasing; pressures and air
    masses positive; cumulative masses not negative."""
    assert r.t[0] == 0.0 and r.t[-1] == duration
    assert np.all(np.diff(r.t) > 0)
    assert np.isfinite(r.y).all() and np.isfinite(r.u).all()
    n = r.n
    masses_and_pressures = r.y[:, :L.physical_size(n)]
    assert (masses_and_pressures > 0).all()
    assert (r.y[:, L.physical_size(n):] >= -1e-12).all()
    p_max = max(r.y[0, L.Y_PS], r.y[0, L.Y_PE], *r.y[0, L.pressure_slice(n)])
    assert r.y[:, [L.Y_PS, L.Y_PE]].max() <= 1.5 * p_max        # the pump's band ends near 6 bar
    assert set(np.unique(r.u[:, :2 * n])) <= {0.0, 1.0}


@pytest.fixture(scope="module")
def paper():
    return frogsim.load_scenario("paper-cycle")


@settings(max_examples=400, deadline=None)
@given(grids(longest=1e4, max_rows=5_000_000))
def test_grid_is_whole_sample_indices_ending_at_the_duration(pair):
    duration, interval = pair
    t = output_times(duration, interval)
    assert t[0] == 0.0 and t[-1] == duration
    assert np.all(np.diff(t) > 0)
    k = np.arange(t.size - 1)
    np.testing.assert_array_equal(t[:-1], k * interval)       # t_k = k dt, each a whole index
    # the last step is a full interval (to rounding), or the shorter remainder of the duration
    assert t[-1] - t[-2] <= interval * (1 + 1e-6)


@pytest.mark.parametrize("duration, interval", REPORTED)
def test_reported_grids_end_at_the_duration(duration, interval):
    t = output_times(duration, interval)
    assert t.size == round(duration / interval) + 1 and t[-1] == duration


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(grids())
def test_pneumatic_engine_writes_every_row(paper, pair):
    duration, interval = pair
    r = frogsim.simulate(paper.replace({"duration": duration, "output_interval": interval}))
    _physical_rows(r, duration)


@pytest.mark.parametrize("duration, interval", REPORTED)
def test_last_row_equals_a_longer_run_truncated(paper, duration, interval):
    """The last row of the run equals the row at the same time of a run one sample longer (solver
    tolerance: that row comes from the longer run's dense output)."""
    r = frogsim.simulate(paper.replace({"duration": duration, "output_interval": interval}))
    longer = frogsim.simulate(paper.replace({"duration": duration + interval, "output_interval": interval}))
    _physical_rows(r, duration)
    k = r.t.size - 1
    assert longer.t[k] == pytest.approx(duration, rel=1e-12)
    np.testing.assert_allclose(r.y[-1], longer.y[k], rtol=1e-4, atol=1e-9)
    np.testing.assert_array_equal(r.u[-1], longer.u[k])


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(grids(longest=3.0), min_size=2, max_size=5))
@example([(1.0, 0.2371373705661655), (1.0, 0.2)])     # two grids of six rows ending at 1 s
def test_batched_engine_writes_every_row(paper, pairs):
    pairs = pairs + REPORTED[:1]
    points = [{"duration": d, "output_interval": i} for d, i in pairs]
    models = build_models(paper, points)
    for r, (d, _) in zip(run_models(models, threads=2), pairs):
        _physical_rows(r, d)
    groups, failures = run_outputs(models)
    assert not failures
    assert sorted(b for rows, _ in groups for b in rows) == list(range(len(pairs)))
    for rows, outs in groups:
        for b, y in zip(rows, outs.y):
            d, i = pairs[b]
            np.testing.assert_array_equal(outs.t, output_times(d, i))   # each run on its own grid
            assert np.isfinite(y).all()


def test_a_row_the_run_never_reached_is_refused(paper):
    """A grid with a row past the end (the old bug, planted) stops the run with a clear error
    instead of returning uninitialised memory: in simulate and in the batched engine."""
    m = frogsim.build_model(paper.replace({"duration": 0.3, "output_interval": 0.1}))
    m.out_t[-1] = 0.3 + 1e-15
    with pytest.raises(SimulationError, match="output rows it never wrote"):
        frogsim.simulate(m)
    with pytest.raises(SimulationError, match="status 6"):
        run_models([m])


def test_sweep_over_durations_and_intervals_gives_finite_metrics(tmp_path):
    durations = [d for d, _ in REPORTED] + [0.05, 1.0]
    intervals = [i for _, i in REPORTED] + [0.003, 0.3]
    spec = f"""
name = "grid-ends"
[base]
scenario = "one-hip.toml"
[sweep]
method = "list"
[sweep.parameters]
duration = {{ values = {durations}, unit = "s" }}
output_interval = {{ values = {intervals}, unit = "s" }}
[record]
metrics = ["final_pressure", "source_final", "air_used", "source_drop"]
muscle = "hip"
"""
    path = write_case(tmp_path, spec)
    ds = run_sweep(path, out=tmp_path / "r.nc", workers=1, progress=False)
    for name in ("final_pressure", "source_final", "air_used", "source_drop"):
        v = ds[name].values
        assert np.isfinite(v).all(), (name, v)
    assert (ds["air_used"].values >= 0).all() and (ds["air_used"].values < 1e-2).all()
    assert (ds["source_final"].values > 0).all() and (ds["source_final"].values < 7e5).all()


def test_robot_records_every_step_row_to_the_end():
    """The coupled engine records whole MuJoCo steps: every row written, the last at the end."""
    rs = frogsim.load_robot_scenario("hip-angle-in-air")
    run = frogsim.swim(rs)
    t = run.t
    assert np.isfinite(run.rec).all()
    assert t[0] == 0.0 and t[-1] == pytest.approx(rs.duration, abs=1e-12)
    np.testing.assert_allclose(np.diff(t), rs.pneumatic.output_interval, rtol=1e-9)


@pytest.mark.parametrize("key, value", [("output_interval", "2.5 ms"), ("output_interval", "0.3 ms")])
def test_robot_output_interval_must_be_whole_steps(key, value):
    with pytest.raises(ScenarioError, match="whole number of robot.timestep"):
        raw, _ = merged_raw("hip-angle-in-air")
        frogsim.load_robot_scenario(frogsim.with_overrides(raw, {key: value}))


@settings(max_examples=6, deadline=None)
@given(st.integers(5, 1500), st.data())
def test_coupled_engine_writes_every_row(period_ms, data):
    """The robot (MuJoCo + pneumatics, closed-loop hip) over Hypothesis-drawn durations and output
    intervals, both whole numbers of its 1 ms steps: every row written, finite, at k * interval,
    the last at the end of the run."""
    interval_ms = data.draw(st.integers(1, period_ms))
    raw, _ = merged_raw("hip-angle-in-air")
    raw = frogsim.with_overrides(raw, {"gait.period": f"{period_ms} ms", "output_interval": f"{interval_ms} ms",
                                       "controllers.hip.setpoint": "20 deg",
                                       "controllers.hip.settle": "0 s"})
    rs = frogsim.load_robot_scenario(raw)
    run = frogsim.swim(rs)
    t = run.t
    assert np.isfinite(run.rec).all()
    assert t[0] == 0.0 and t[-1] == pytest.approx(period_ms * 1e-3, abs=1e-12)
    steps = np.rint(t / 1e-3).astype(int)
    np.testing.assert_allclose(t, steps * 1e-3, rtol=0, atol=1e-12)
    assert (steps[:-1] % interval_ms == 0).all() and np.all(np.diff(steps) > 0)
    assert t.size == period_ms // interval_ms + 1 + (1 if period_ms % interval_ms else 0)
    assert (run.source_pressure > 0).all()
