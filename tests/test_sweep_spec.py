"""Sweep specs: grid, list, random and Latin-hypercube points; units; every error is one line
naming the field (API), and exit 2 with nothing written (CLI)."""
import tomllib

import numpy as np
import pytest
from sweep_helpers import GRID, ONE_HIP, write_case

from frogsim.cli import main
from frogsim.errors import ScenarioError
from frogsim.scenario.load import merged_raw
from frogsim.sweep import load_spec
from frogsim.sweep.spec import dumps_toml

BAR = 1e5
LPM = 1e-3 / 60.0      # 1 L/min in m^3/s


def spec_dict(parameters: dict, method: str = "grid", **sweep) -> dict:
    return {"base": {"scenario": "one-hip.toml"},
            "sweep": {"method": method, "parameters": parameters, **sweep},
            "record": {"metrics": ["rise_time"], "muscle": "hip"}}


@pytest.fixture
def folder(tmp_path):
    write_case(tmp_path)
    return tmp_path


def test_grid_points_units_and_order(folder):
    spec = load_spec(folder / "spec.toml")
    assert spec.shape == (4, 3, 2) and spec.n_points == 24
    p, q, f = spec.parameters
    assert p.written == ("3 bar", "4 bar", "5 bar", "6 bar")
    assert np.allclose(p.si, [3 * BAR, 4 * BAR, 5 * BAR, 6 * BAR], rtol=1e-15)
    assert q.written == ("15 L/min", "45 L/min", "180 L/min")
    assert np.allclose(q.si, [15 * LPM, 45 * LPM, 180 * LPM], rtol=1e-15)
    assert (p.display_unit, q.display_unit) == ("bar", "L/min")
    assert f.written == (0.0, 1.0) and f.info.si_unit == ""
    # C order: the last parameter varies fastest
    # points are typed variants: SI values, no unit text
    assert spec.point(0) == pytest.approx({"source.initial_pressure_gauge": 3 * BAR, "supply.branch_limit": 15 * LPM,
                                           "muscles.hip.motion.fraction": 0.0}, rel=1e-15)
    assert spec.point(1)["muscles.hip.motion.fraction"] == 1.0
    assert spec.point(23) == pytest.approx({"source.initial_pressure_gauge": 6 * BAR,
                                            "supply.branch_limit": 180 * LPM,
                                            "muscles.hip.motion.fraction": 1.0}, rel=1e-15)
    assert np.allclose(spec.si[7], [4 * BAR, 15 * LPM, 1.0])
    # the chunk plan covers every point exactly once
    assert np.array_equal(np.concatenate(spec.chunks()), np.arange(24))


def test_log_grid_and_mixed_units(folder):
    spec = load_spec(spec_dict({"supply.branch_limit": {"start": "10 L/min", "stop": "1000 L/min", "num": 3,
                                                        "scale": "log"},
                                "source.volume": {"start": "2 L", "stop": "4000 cm^3", "num": 3}}), folder)
    assert spec.parameters[0].written == ("10 L/min", "100 L/min", "1000 L/min")
    assert spec.parameters[1].written == ("2 L", "3 L", "4 L")
    assert np.allclose(spec.parameters[1].si, [2e-3, 3e-3, 4e-3])


def test_list_zips_parameters(folder):
    spec = load_spec(spec_dict({"source.initial_pressure_gauge": ["3 bar", "600 kPa", "4 bar"],
                                "muscles.hip.motion.fraction": [0.1, 0.2, 0.3]}, method="list"), folder)
    assert spec.shape == (3,) and spec.dims == ("point",)
    assert spec.point(1) == {"source.initial_pressure_gauge": 6e5, "muscles.hip.motion.fraction": 0.2}
    assert np.allclose(spec.si[:, 0], [3e5, 6e5, 4e5])
    assert spec.parameters[0].display_unit == "Pa"       # mixed units: plots fall back to SI


def test_lhs_one_sample_per_stratum_and_reproducible(folder):
    n = 20
    d = spec_dict({"source.initial_pressure_gauge": {"min": "3 bar", "max": "6 bar"},
                   "supply.branch_limit": {"min": "15 L/min", "max": "180 L/min"},
                   "muscles.hip.motion.fraction": {"min": 0.0, "max": 1.0}},
                  method="lhs", samples=n, seed=7)
    a = load_spec(d, folder)
    lo = np.array([3 * BAR, 15 * LPM, 0.0])
    hi = np.array([6 * BAR, 180 * LPM, 1.0])
    assert a.si.shape == (n, 3)
    assert np.all(a.si >= lo) and np.all(a.si < hi)
    strata = np.floor((a.si - lo) / (hi - lo) * n).astype(int)
    for j in range(3):                 # every dimension: each of the n strata holds one sample
        assert sorted(strata[:, j]) == list(range(n))
    b = load_spec(d, folder)
    assert a.written == b.written and a.hash == b.hash
    c = load_spec({**d, "sweep": {**d["sweep"], "seed": 8}}, folder)
    assert c.written != a.written and c.hash != a.hash
    # values as written carry the range's unit
    assert all(w[0].endswith(" bar") and w[1].endswith(" L/min") for w in a.written)


def test_random_samples_within_range(folder):
    d = spec_dict({"source.volume": {"min": "1 L", "max": "8 L", "scale": "log"},
                   "supply.branch_count": {"min": 1, "max": 6}}, method="random", samples=200, seed=1)
    spec = load_spec(d, folder)
    v = spec.si[:, 0]
    assert v.min() >= 1e-3 and v.max() < 8e-3
    # log scale: about as many samples below the geometric mean as above
    assert 70 < np.sum(v < np.sqrt(8) * 1e-3) < 130
    counts = np.bincount(spec.si[:, 1].astype(int), minlength=7)
    assert counts[0] == 0 and np.all(counts[1:] > 15)       # whole numbers 1..6, all reached
    assert all(isinstance(w[1], int) for w in spec.written)


def test_base_overrides_and_shipped_base(tmp_path):
    d = {"base": {"scenario": "paper-cycle",
                  "overrides": {"duration": "1 s", "source": {"volume": "3 L"},
                                "muscles.hip_left.motion": {"kind": "volume_constant", "fraction": 0.5}}},
         "sweep": {"parameters": {"muscles": {"hip_left": {"motion": {"fraction": [0.0, 1.0]}}}}},
         "record": {"muscle": "hip_left"}}
    spec = load_spec(d, tmp_path)
    assert spec.paths == ["muscles.hip_left.motion.fraction"]       # nested tables read as a path
    assert spec.base_raw["duration"] == "1 s" and spec.base_raw["source"]["volume"] == "3 L"
    assert spec.base_raw["source"]["initial_pressure_gauge"]["value"] == "6 bar"   # merged, not replaced
    assert spec.base_raw["muscles"]["hip_left"]["motion"] == {"kind": "volume_constant", "fraction": 0.5}
    assert len(spec.metrics) >= 4          # default: every registered metric


def test_hash_ignores_name_and_comments_but_not_values(folder):
    a = load_spec(folder / "spec.toml")
    (folder / "b.toml").write_text("# a comment\n" + GRID.replace('name = "grid-test"', 'name = "other"'))
    assert load_spec(folder / "b.toml").hash == a.hash
    (folder / "c.toml").write_text(GRID.replace('num = 4', 'num = 5'))
    assert load_spec(folder / "c.toml").hash != a.hash
    (folder / "one-hip.toml").write_text(ONE_HIP.replace('"0.5 s"', '"0.6 s"'))   # the base changed
    assert load_spec(folder / "spec.toml").hash != a.hash


def test_base_scenario_text_round_trips(folder):
    raw, _ = merged_raw("paper-cycle")
    assert tomllib.loads(dumps_toml(raw)) == raw
    spec = load_spec(folder / "spec.toml")
    assert tomllib.loads(spec.base_toml()) == spec.base_raw


def test_validation_checks_combinations_within_a_group(folder):
    # each value alone is valid; only (on 6.2 bar, off 6 bar) inverts the pump band
    d = spec_dict({"pump.on_below_gauge": ["5 bar", "6.2 bar"], "pump.off_above_gauge": ["6 bar", "7 bar"],
                   "source.volume": ["2 L", "4 L"]})
    spec = load_spec(d, folder)
    with pytest.raises(ScenarioError) as exc:
        spec.validate_points()
    msg = str(exc.value)
    assert "pump.on_below_gauge" in msg and "6.2 bar" in msg and "6 bar" in msg
    assert len(msg.splitlines()) == 1
    # the same values zipped never meet: valid
    ok = load_spec(spec_dict({"pump.on_below_gauge": ["5 bar", "6.2 bar"],
                              "pump.off_above_gauge": ["6 bar", "7 bar"]}, method="list"), folder)
    ok.validate_points()


def test_validation_checks_every_point_of_a_sample(folder):
    # the contraction limit depends on the muscle type's max_contraction: checked together
    base = ONE_HIP.replace('motion = { kind = "volume_constant", fraction = 0.5 }',
                           'motion = { kind = "constant", contraction = "0 %" }')
    write_case(folder, base=base)
    d = spec_dict({"muscles.hip.motion.contraction": {"min": 0.1, "max": 0.3},
                   "muscle_types.hip.max_contraction": {"min": 0.15, "max": 0.3}}, method="lhs", samples=30)
    with pytest.raises(ScenarioError, match=r"max_contraction.*in sweep point \d+"):
        load_spec(d, folder).validate_points()


BAD = {
    # case: (spec changes, text the one-line message must hold)
    "unknown parameter path": ({"sweep.parameters": {"source.volum": ["1 L"]}}, "'volume'"),
    "unknown section": ({"sweep.parameters": {"sourc.volume": ["1 L"]}}, "did you mean 'source'"),
    "unknown muscle": ({"sweep.parameters": {"muscles.knee.motion.fraction": [0.5]}}, "no muscles.knee"),
    "empty values": ({"sweep.parameters": {"source.volume": []}}, "non-empty"),
    "empty range": ({"sweep.parameters": {"source.volume": {"start": "2 L", "stop": "2 L", "num": 3}}},
                    "range is empty"),
    "num zero": ({"sweep.parameters": {"source.volume": {"start": "2 L", "stop": "3 L", "num": 0}}},
                 "sweep.parameters.source.volume.num"),
    "non-numeric value": ({"sweep.parameters": {"source.initial_pressure_gauge": ["3 bar", "lots"]}},
                          "values[1] = 'lots'"),
    "wrong unit": ({"sweep.parameters": {"source.volume": ["3 bar"]}}, "expected a volume"),
    "bare number needs a unit": ({"sweep.parameters": {"source.volume": [3]}}, "write the unit out"),
    "bad unit option": ({"sweep.parameters": {"source.volume": {"values": [1, 2], "unit": "bar"}}},
                        "sweep.parameters.source.volume.unit"),
    "unknown metric": ({"record.metrics": ["rise_time", "speed"]}, "record.metrics = 'speed'"),
    "unknown record muscle": ({"record.muscle": "knee"}, "record.muscle = 'knee'"),
    "unknown method": ({"sweep.method": "sobol"}, "sweep.method = 'sobol'"),
    "lhs without range": ({"sweep.method": "lhs", "sweep.samples": 4}, "takes a range"),
    "lhs min above max": ({"sweep.method": "lhs", "sweep.samples": 4,
                           "sweep.parameters": {"source.volume": {"min": "4 L", "max": "2 L"}}}, "range is empty"),
    "list lengths differ": ({"sweep.method": "list",
                             "sweep.parameters": {"source.volume": ["1 L", "2 L"], "supply.branch_limit": ["9 L/min"]}},
                            "as many values"),
    "unknown spec key": ({"recrod": {}}, "'record'"),
    "bad time series state": ({"record.timeseries": {"states": ["muscle_presure"]}}, "muscle_presure"),
    "time series interval": ({"record.timeseries": {"states": ["muscle_pressure"], "interval": "1.5 ms"}},
                             "whole multiple"),
    "missing base": ({"base": None}, "base"),
    "bad base file": ({"base": {"scenario": "nowhere.toml"}}, "base.scenario = 'nowhere.toml'"),
    "bad base override": ({"base": {"scenario": "one-hip.toml", "overrides": {"source.volume": "-1 L"}}},
                          "source.volume = '-1 L': must be > 0 L (in the base scenario)"),
    "point out of bounds": ({"sweep.parameters": {"source.volume": ["2 L", "-2 L"]}}, "source.volume = '-2 L'"),
}


def _bad_spec(case):
    d = {"base": {"scenario": "one-hip.toml"},
         "sweep": {"method": "grid", "parameters": {"source.volume": ["2 L", "4 L"]}},
         "record": {"metrics": ["rise_time"], "muscle": "hip"}}
    for key, val in BAD[case][0].items():
        if "." in key:
            section, k = key.split(".")
            d[section][k] = val
        elif val is None:
            d.pop(key)
        else:
            d[key] = val
    return d


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_spec_raises_one_line(folder, case):
    with pytest.raises(ScenarioError) as exc:
        load_spec(_bad_spec(case), folder).validate_points()
    msg = str(exc.value)
    assert BAD[case][1] in msg, msg
    assert len(msg.splitlines()) == 1


@pytest.mark.parametrize("case", ["unknown parameter path", "empty range", "non-numeric value", "unknown metric",
                                  "point out of bounds", "list lengths differ"])
def test_bad_spec_cli_exit_2_nothing_written(folder, capsys, case):
    spec = folder / "bad.toml"
    spec.write_text(dumps_toml(_bad_spec(case)))
    out = folder / "out" / "results.nc"
    assert main(["sweep", str(spec), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("frogsim: error: ") and BAD[case][1] in err, err
    assert not (folder / "out").exists()


@pytest.mark.parametrize("name", ["sweep-source-saturation.toml", "sweep-lhs-valves.toml"])
def test_shipped_examples_are_valid(name):
    from pathlib import Path
    spec = load_spec(Path(__file__).resolve().parent.parent / "examples" / name)
    assert spec.n_points in (336, 1000)
    if spec.method == "grid":
        assert spec.validate_points() == spec.n_points  # every point made as the run makes it


def test_shared_overrides_equal_copied_ones_and_leave_the_base_alone():
    import copy

    from frogsim import load_scenario, with_overrides
    raw, _ = merged_raw("paper-cycle")
    before = copy.deepcopy(raw)
    over = {"source.volume": "2 L", "valves.charge.sonic_conductance": "0.3 L/(s*bar)",
            "valves.charge.dead_time": "1 ms", "muscles.hip_left.motion": {"kind": "constant"}}
    assert with_overrides(raw, over, share=True) == with_overrides(raw, over)
    assert raw == before
    with pytest.raises(ScenarioError, match="source.volume.x"):
        with_overrides(raw, {"source.volume.x": 1}, share=True)
    with pytest.raises(ScenarioError, match="nosuch"):      # a misspelt table: refused on loading
        load_scenario(with_overrides(raw, {"nosuch.volume": "1 L"}, share=True))


def test_a_valve_sweep_under_the_paper_branch_cap_says_so(folder):
    # in paper mode the Eq. (9) cap (43.1 L/min for fan2017's main tube and six branches) binds
    # long before a 0.4 L/(s bar) valve does: doubling C cannot show; the spec says so
    d = spec_dict({"valves.charge.sonic_conductance": {"values": [0.4, 0.8], "unit": "L/(s*bar)"}})
    d["base"]["overrides"] = {"supply.mode": "paper"}
    notes = load_spec(d, folder).notes
    assert len(notes) == 1 and "caps every branch" in notes[0] and "valves.charge.sonic_conductance" in notes[0]
    d["base"]["overrides"] = {"supply.mode": "none"}
    assert load_spec(d, folder).notes == []
    both = spec_dict({"valves.charge.sonic_conductance": {"values": [0.4, 0.8], "unit": "L/(s*bar)"},
                      "supply.mode": ["paper", "none"]})
    assert load_spec(both, folder).notes == []          # the mode is swept: the comparison is there
