"""Batched engine: batch, chunking and threads change nothing; composed models equal built ones."""
import numpy as np
import pytest

import frogsim
from frogsim.engine.batch import compose_models, run_models
from frogsim.sweep.metrics import METRICS, evaluate, evaluate_models

BASE = {"name": "batch", "parameters": "fan2017", "duration": "1.2 s",
        "programs": {"s": {"pressurise": "0.6 s", "release": "0.6 s"}},
        "muscles": {"hip": {"type": "hip", "program": "s"}}}


@pytest.fixture(scope="module")
def raw():
    return frogsim.load_scenario(BASE).raw


@pytest.fixture(scope="module")
def points():
    return [{"source.initial_pressure_gauge": f"{ps} bar", "supply.branch_limit": f"{q} L/min",
             "muscle_types.hip.stroke_contraction": f"{e} %"}
            for ps in (3, 6) for q in (30, 90) for e in (0, 10, 20)]


def test_composed_models_equal_exact_builds(raw, points):
    models, method = compose_models(raw, points)
    assert method == "composed"
    for pt, m in zip(points, models):
        exact = frogsim.build_model(frogsim.load_scenario(frogsim.with_overrides(raw, pt)))
        for a in ("g", "mp", "y0", "atol", "u0"):
            assert np.array_equal(getattr(exact, a), getattr(m, a)), a
        n = exact.mot_n[0]
        assert np.array_equal(exact.mot_L[0, :n], m.mot_L[0, :n])
        assert np.array_equal(exact.sched_t, m.sched_t[np.isfinite(m.sched_t)])


def test_batch_equals_one_by_one_whatever_threads_and_chunks(raw, points):
    models, _ = compose_models(raw, points)
    singles = [frogsim.simulate(frogsim.load_scenario(frogsim.with_overrides(raw, pt))) for pt in points]
    for threads in (1, 2):
        batch = run_models(models, threads=threads)
        for a, b in zip(batch, singles):
            assert np.array_equal(a.y, b.y)        # same compiled code, same inputs: bit for bit
    for chunk in (1, 5, 64):
        vals = evaluate_models(models, list(METRICS), "hip", threads=2, chunk=chunk)
        ref = evaluate(singles, list(METRICS), "hip")
        for m in METRICS:
            assert np.array_equal(vals[m], ref[m]), (m, chunk)


def test_metrics_equal_result_methods(raw, points):
    models, _ = compose_models(raw, points)
    results = run_models(models)
    vals = evaluate(results, ["rise_time", "aeration_volume", "final_pressure"], "hip")
    for k, r in enumerate(results):
        assert vals["rise_time"][k] == r.rise_time("hip")
        assert vals["aeration_volume"][k] == pytest.approx(r.aeration_volume("hip") * 1e3, rel=1e-12)
        assert vals["final_pressure"][k] == pytest.approx(
            (r.pressure_at_close("hip") - r.atmospheric_pressure) / 1e5, rel=1e-12)


def test_overlapping_parameters_fall_back_to_full_builds(raw):
    # main tube diameter and count both set the Eq. (9) limit (one array entry): composing them
    # from single-parameter builds would be wrong, so every point must be built in full
    pts = [{"supply.main_tube_inner_diameter": f"{d} mm", "supply.main_tube_count": c}
           for d in (3, 5) for c in (1, 2)]
    models, method = compose_models(raw, pts)
    assert method == "built"
    # Eq. (9): the per-branch limit grows with d^2 and with the count
    lim = [m.g[frogsim.circuit.layout.G_BRANCH_LIMIT] for m in models]
    assert lim[3] / lim[0] == pytest.approx((5 / 3) ** 2 * 2, rel=1e-12)


def test_bad_point_is_refused_before_running(raw):
    with pytest.raises(frogsim.ScenarioError, match="source.volume"):
        compose_models(raw, [{"source.volume": "4 L"}, {"source.volume": "-1 L"}])


def test_metrics_refuse_mixed_time_grids(raw):
    a = frogsim.simulate(frogsim.load_scenario(raw))
    b = frogsim.simulate(frogsim.load_scenario(frogsim.with_overrides(raw, {"duration": "1.5 s"})))
    with pytest.raises(ValueError, match="one time grid"):
        evaluate([a, b], ["rise_time"], "hip")
