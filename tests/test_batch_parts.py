"""Batched model building (frogsim.scenario.variants, frogsim.circuit.model.PARTS): every setting,
rule and model part is made once per distinct combination of the settings it declares, and each
point's model equals build_model(base.replace(point)) array for array, for every variable path."""
import dataclasses

import numpy as np
import pytest

import frogsim
from frogsim.circuit.model import build_model
from frogsim.engine.batch import build_models
from frogsim.scenario import rules
from frogsim.scenario.core import Scenario
from frogsim.scenario.variants import _codes
from frogsim.scenario.view import Settings
from frogsim.sweep.spec import FieldInfo, dumps_toml
from tests.test_sweep_every_path import BASE, current_and_valid

ARRAYS = ("g", "mp", "mot_t", "mot_L", "mot_d", "mot_n", "sched_t", "sched_u", "u0", "y0", "atol", "out_t", "laws")


def assert_same_model(a, b, what):
    for key in ARRAYS:
        x, y = getattr(a, key), getattr(b, key)
        assert x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x, y, equal_nan=True), (what, key)
    assert a.names == b.names, what
    assert len(a.charge_open_times) == len(b.charge_open_times), what
    for x, y in zip(a.charge_open_times, b.charge_open_times):
        assert np.array_equal(x, y), what
    assert a.scenario == b.scenario, what


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    folder = tmp_path_factory.mktemp("parts")
    (folder / "base.toml").write_text(dumps_toml(BASE))
    return frogsim.load_scenario(folder / "base.toml")


def test_every_variable_path_builds_the_per_point_model(base):
    built = 0
    for path, meta in base.variable_paths().items():
        now, good = current_and_valid(base, path, FieldInfo.of(meta))
        if not good:
            continue
        points = [{path: v} for v in ([now] if now is not None else []) + good[:2]]
        for pt, m in zip(points, build_models(base, points)):
            assert_same_model(m, build_model(base.replace(pt)), (path, pt[path]))
        built += 1
    assert built >= 0.9 * len(base.variable_paths())


def test_a_grid_over_several_settings_builds_the_per_point_models(base):
    # settings of different top-level tables, and two in one table, varied together
    points = [{"source.initial_pressure_gauge": ps, "source.volume": vs, "supply.branch_limit": q,
               "muscle_types.hip.stroke_contraction": e, "programs.stroke.pressurise": tp,
               "valves.charge.dead_time": dt}
              for ps in (2e5, 5e5) for vs in (2e-3, 4e-3) for q in (1e-4, 5e-4, None)
              for e in (0.0, 0.1) for tp in (0.3, 0.4) for dt in (0.002, 0.004)]
    models = build_models(base, points)
    assert len(models) == len(points)
    for k in (0, 5, 17, 33, 64, len(points) - 1):
        assert_same_model(models[k], build_model(base.replace(points[k])), k)
    # parts are shared by the points that agree on what they read, yet no model shares an array
    assert not np.shares_memory(models[0].y0, models[1].y0) and not np.shares_memory(models[0].g, models[1].g)
    parts = models.parts
    assert len(parts["g"][0]) == 2 * 3          # source volume x branch limit (the initial pressure is not in g)
    assert len(parts["state"][0]) == 2 * 2      # initial pressure x source volume
    sl = models[3:9]
    for j, k in enumerate(range(3, 9)):
        assert_same_model(sl[j], models[k], k)


def test_equal_values_of_different_types_or_signs_stay_apart():
    # 1, 1.0 and True hash alike; 0.0 and -0.0 compare equal: each is its own value here
    assert len(set(_codes([1, 1.0, True, 1]).tolist())) == 3
    assert len(set(_codes([0.0, -0.0, 0.0]).tolist())) == 2
    assert _codes([0.5, 0.25, 0.5]).tolist()[0] == _codes([0.5, 0.25, 0.5]).tolist()[2]


def test_a_step_sees_only_the_settings_it_declares(base, monkeypatch):
    view = Settings(base.__dict__, ("source",), Scenario)
    assert view.source is base.source
    with pytest.raises(AttributeError, match="'air' is not among the settings"):
        view.air
    # a rule that reads a setting it did not declare fails at once, on every scenario
    monkeypatch.setattr(rules, "RULES", rules.RULES + ((("source",), lambda sc: sc.pump.enabled),))
    with pytest.raises(AttributeError, match="'pump'"):
        base.replace({"source.volume": 5e-3})


def test_the_first_invalid_point_is_named_with_the_point_by_point_message(base):
    points = [{"pump.on_below_gauge": 1e5, "source.volume": 4e-3},
              {"pump.on_below_gauge": 1e5, "source.volume": 5e-3},
              {"pump.on_below_gauge": 9e5, "source.volume": 4e-3},      # on >= off: a cross-field rule
              {"pump.on_below_gauge": 1e5, "source.volume": -1e-3}]     # a bound
    with pytest.raises(frogsim.ScenarioError) as caught:
        base.replace(points[2])
    alone = str(caught.value)
    with pytest.raises(frogsim.ScenarioError) as caught:
        build_models(base, points)
    msg = str(caught.value)
    assert "pump.on_below_gauge" in msg and "in point 2" in msg and "must be below pump.off_above_gauge" in msg
    assert msg.startswith(alone.split(" (")[0])


def test_points_setting_different_paths_still_build(base):
    points = [{"source.volume": 4e-3}, {"supply.branch_limit": 2e-4}]
    models = build_models(base, points)
    for pt, m in zip(points, models):
        assert_same_model(m, build_model(base.replace(pt)), pt)


def test_variants_equal_replace_field_for_field(base):
    points = [{"programs.stroke.pressurise": tp, "muscles.knee.motion.fraction": f}
              for tp in (0.3, 0.35) for f in (0.2, 0.6)]
    models = build_models(base, points)
    for pt, m in zip(points, models):
        one = base.replace(pt)
        assert m.scenario == one
        for f in dataclasses.fields(Scenario):
            assert getattr(m.scenario, f.name) == getattr(one, f.name), f.name
        # the muscle using the named program got its new version
        assert m.scenario.muscles["hip"].program is m.scenario.programs["stroke"]
