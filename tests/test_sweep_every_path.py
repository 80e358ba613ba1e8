"""A sweep over any schema field works with no list to edit: every path a variant may change in a
scenario of the fan2017 set is swept (two values each) and every point's metrics equal those of
``frogsim.simulate(scenario.replace(point))`` bit for bit."""
import numpy as np
import pytest

import frogsim
from frogsim.sweep import METRICS, load_spec, run_sweep
from frogsim.sweep.metrics import evaluate
from frogsim.sweep.runner import metric_unit
from frogsim.sweep.spec import FieldInfo, dumps_toml

BASE = {"name": "every-path", "parameters": "fan2017", "duration": "0.8 s", "output_interval": "2 ms",
        "programs": {"stroke": {"pressurise": "0.4 s", "release": "0.4 s"}},
        "muscles": {"hip": {"type": "hip", "program": "stroke",
                            "motion": {"kind": "stroke", "delay": "0.05 s", "rise": "0.2 s", "fall": "0.2 s"}},
                    "knee": {"type": "knee", "program": {"steps": [{"at": "0 s", "state": "charge"},
                                                                   {"at": "0.25 s", "state": "vent"}]},
                             "motion": {"kind": "volume_constant", "fraction": "50 %"},
                             "initial_pressure_gauge": "0.1 bar"}}}
FALLBACK = {"pressure": 1e4, "volume_flow": 5e-4, "dimensionless": 0.05, "time": 0.01}


def _inside(x, meta) -> bool:
    return all(b is None or op(x, b) for b, op in ((meta.get("gt"), float.__gt__), (meta.get("ge"), float.__ge__),
                                                   (meta.get("lt"), float.__lt__), (meta.get("le"), float.__le__)))


def _candidates(value, info: FieldInfo):
    """Values a careful user might try for a setting, nearest first."""
    if info.kind == "flag":
        return [not value]
    if info.kind == "choice":
        return [c for c in info.choices if c != value]
    if info.kind == "integer":
        return [value + 1, value - 1]
    if value is None:
        return [FALLBACK.get(info.kind, 1.0)]
    return [x for x in (value * 1.05, value * 0.95, value + 0.01) if _inside(float(x), info.meta)]


def current_and_valid(base, path: str, info: FieldInfo):
    """(the path's present value in base, the candidate values base.replace accepts for it)."""
    node = base
    for key in path.split("."):
        node = node[key] if isinstance(node, dict) else getattr(node, key)
    good = []
    for v in _candidates(node, info):
        try:
            base.replace({path: v})
            good.append(v)
        except frogsim.ScenarioError:
            continue
    return node, good


def _spec_values(values, info: FieldInfo):
    if info.kind in ("flag", "choice", "integer"):
        return {"values": list(values)}
    return {"values": [float(v) for v in values], "unit": "" if info.kind == "dimensionless" else
            info.si_unit.replace("^", "**")}


def test_every_variable_path_sweeps_and_matches_single_runs(tmp_path):
    (tmp_path / "base.toml").write_text(dumps_toml(BASE))
    base = frogsim.load_scenario(tmp_path / "base.toml")
    paths = base.variable_paths()
    assert len(paths) > 60           # the schema's settings, found without a list
    for group in ("air.", "source.", "exhaust.", "pump.", "valves.charge.", "valves.discharge.", "supply.",
                  "muscle_types.hip.", "muscles.hip.motion.", "muscles.knee.motion.fraction",
                  "muscles.knee.initial_pressure_gauge", "programs.stroke.",
                  "controller.", "solver."):
        assert any(p.startswith(group) for p in paths), group
    swept = 0
    for path, meta in paths.items():
        info = FieldInfo.of(meta)
        node, good = current_and_valid(base, path, info)
        if not good:
            continue                  # no nearby value is valid here (e.g. a bound is already met)
        values = [node, good[0]] if node is not None else good[:1]
        spec = load_spec({"base": "base.toml", "record": {"metrics": list(METRICS), "muscle": "hip"},
                          "sweep": {"method": "list", "parameters": {path: _spec_values(values, info)}}}, tmp_path)
        ds = run_sweep(spec, progress=False, workers=2)
        for k in range(spec.n_points):
            ref = evaluate([frogsim.simulate(base.replace(spec.point(k)))], list(METRICS), "hip")
            for m in METRICS:
                si = ref[m][0] * metric_unit(m).factor      # the file stores SI (docs/sweeps.md)
                assert np.array_equal(ds[m].values[k], si, equal_nan=True), (path, m, ds[m].values, ref[m])
        swept += 1
    assert swept >= 0.9 * len(paths), (swept, len(paths))
