"""Typed variants: Scenario.replace takes SI values, applies the loader's bounds and cross-field
rules with the same one-line errors, and equals the same values written in a file."""
import numpy as np
import pytest

import frogsim
from frogsim.scenario.schema import Motion, Program
from frogsim.scenario.units import parse_quantity


@pytest.fixture(scope="module")
def sc():
    return frogsim.load_scenario("paper-cycle")


def test_variant_equals_the_file_with_the_same_values(sc):
    file = frogsim.load_scenario({**frogsim.with_overrides(sc.raw, {"source.volume": "8 L",
                                                                    "valves.charge.critical_ratio": 0.3,
                                                                    "programs.stroke.pressurise": "0.5 s"}),
                                  "base_dir": sc.base_dir})
    litres = parse_quantity("8 L", "volume")          # pint's 8 L (its factor is not exactly 1e-3)
    var = sc.replace({"source.volume": litres, "valves.charge.critical_ratio": 0.3,
                      "programs.stroke.pressurise": 0.5})
    assert var == file                      # dataclass equality: every field, every muscle
    a, b = frogsim.build_model(file), frogsim.build_model(var)
    for key in ("g", "mp", "y0", "sched_t", "sched_u", "mot_L"):
        assert np.array_equal(getattr(a, key), getattr(b, key)), key


def test_a_named_program_reaches_every_muscle_using_it(sc):
    var = sc.replace({"programs.stroke.pressurise": 0.4})
    for m in var.muscles.values():
        assert m.program.steps[:2] == ((0.0, "charge"), (0.4, "vent"))
    assert sc.muscles["hip_left"].program.steps[1] == (1.0, "vent")     # the base is untouched


@pytest.mark.parametrize("changes, words", [
    ({"source.volume": -1e-3}, ["source.volume = -1 L", "must be > 0 L"]),
    ({"source.volume": "4 L"}, ["source.volume", "no unit text"]),
    ({"source.volum": 1e-3}, ["source.volum", "did you mean 'volume'"]),
    ({"muscles.elbow.motion.delay": 0.1}, ["muscles.elbow", "no such entry", "hip_left"]),
    ({"pump.on_below_gauge": 6.5e5}, ["pump.on_below_gauge = 6.5 bar", "must be below pump.off_above_gauge"]),
    ({"valves.charge.laminar_ratio": 0.3}, ["valves.charge.laminar_ratio", "must exceed critical_ratio"]),
    ({"muscles.hip_left.motion.fraction": 0.5}, ["muscles.hip_left.motion.fraction", "not used by motion kind"]),
    ({"muscles.hip_left.type": "elbow"}, ["muscles.hip_left.type", "must be one of"]),
    ({"muscle_types.hip.stroke_contraction": 0.3}, ["muscle_types.hip.stroke_contraction", "max_contraction"]),
    ({"source": 1.0}, ["source", "is a table"]),
    ({"source.volume.x": 1.0}, ["source.volume", "is a value"]),
    ({"supply.mode": "magic"}, ["supply.mode", "must be one of"]),
    ({"pump.enabled": 1}, ["pump.enabled", "true or false"]),
    ({"supply.branch_count": 2.5}, ["supply.branch_count", "whole number"]),
    ({"duration": float("nan")}, ["duration", "finite"]),
])
def test_bad_variants_are_refused_in_one_line(sc, changes, words):
    with pytest.raises(frogsim.ScenarioError) as exc:
        sc.replace(changes)
    msg = str(exc.value)
    assert len(msg.splitlines()) == 1
    for w in words:
        assert w in msg, (w, msg)


def test_whole_typed_tables(sc):
    var = sc.replace({"muscles.hip_left.motion": Motion("volume_constant", fraction=0.25),
                      "muscles.knee_left.program": Program(steps=((0.0, "hold"),))})
    assert var.muscles["hip_left"].motion.fraction == 0.25
    assert var.muscles["knee_left"].program_ref == ""
    assert "muscles.hip_left.motion.fraction" in var.variable_paths()
    with pytest.raises(frogsim.ScenarioError, match="fraction"):
        sc.replace({"muscles.hip_left.motion": Motion("volume_constant")})       # required for its kind
    with pytest.raises(frogsim.ScenarioError, match=r"muscles.hip_left.motion.delay = -1 s"):
        sc.replace({"muscles.hip_left.motion": Motion("stroke", delay=-1.0)})


def test_variable_paths_come_from_the_schema(sc):
    paths = sc.variable_paths()
    assert paths["source.initial_pressure_gauge"]["kind"] == "pressure"
    assert paths["supply.mode"]["choices"] == ("paper", "physical", "none")
    assert paths["muscles.hip_left.type"]["choices"] == tuple(sc.muscle_types)
    assert "muscles.hip_left.program.pressurise" not in paths      # the muscle uses programs.stroke
    assert "programs.stroke.pressurise" in paths
    assert "muscles.hip_left.motion.fraction" not in paths          # a stroke motion has none
    for path in paths:                                             # every listed path can be set
        assert path.split(".")[0] in {"duration", "output_interval", "controller", "solver", "air", "source",
                                      "exhaust", "pump", "valves", "supply", "muscle_types", "muscles",
                                      "programs"}
