"""One rule for every temperature: absolute temperatures in K, degC or degF; a difference unit refused
where a temperature is meant and an absolute unit where a difference is meant; gas and wall
temperatures within 150 K to 1000 K, in a scenario, a variant, the Python API and a fit trace."""
from __future__ import annotations

import numpy as np
import pytest

import frogsim
from frogsim.cli import main
from frogsim.errors import ScenarioError
from frogsim.scenario.units import to_si
from conftest import paper_cycle_dict

# the kelvin's definition: T/K = t/degC + 273.15, and t/degF = 1.8 t/degC + 32
ABSOLUTE = [("293.15 K", 293.15), ("20 degC", 293.15), ("68 degF", 293.15), ("-40 degC", 233.15),
            ("-40 degF", 233.15), ("300 kelvin", 300.0), ("527.67 degR", 293.15)]
DIFFERENCE = [("1 K", 1.0), ("500 mK", 0.5), ("2 delta_degC", 2.0), ("9 delta_degF", 5.0)]
LOW, HIGH = 150.0, 1000.0       # the air stays an ideal gas of constant k in between


@pytest.mark.parametrize("text, kelvin", ABSOLUTE)
def test_absolute_temperatures_in_every_unit(text, kelvin):
    assert to_si(text, "temperature", "t") == pytest.approx(kelvin, rel=1e-12)


@pytest.mark.parametrize("text, kelvin", DIFFERENCE)
def test_temperature_differences(text, kelvin):
    assert to_si(text, "temperature_difference", "dt") == pytest.approx(kelvin, rel=1e-12)


@pytest.mark.parametrize("text", ["20 delta_degC", "20 delta_degF", "20", "20 bar", "20 K/s"])
def test_a_difference_or_another_quantity_is_not_a_temperature(text):
    with pytest.raises(ScenarioError, match="^t = .*absolute temperature") as exc:
        to_si(text, "temperature", "t")
    if "delta" in text:
        assert "temperature difference" in str(exc.value)


@pytest.mark.parametrize("text", ["1 degC", "1 degF", "1 bar"])
def test_an_absolute_temperature_is_not_a_difference(text):
    with pytest.raises(ScenarioError, match="^dt = .*temperature difference") as exc:
        to_si(text, "temperature_difference", "dt")
    if "deg" in text:
        assert "absolute" in str(exc.value)


@pytest.mark.parametrize("section, key", [("source", "initial_temperature"), ("exhaust", "initial_temperature"),
                                          ("air", "ambient_temperature"), ("air", "reference_temperature")])
@pytest.mark.parametrize("text, kelvin", [("20 degC", 293.15), ("68 degF", 293.15), ("150 K", LOW),
                                          ("1000 K", HIGH), ("726.85 degC", HIGH),
                                          ("-123.15 degC", LOW)])
def test_scenario_temperatures_in_degc_and_degf_and_on_the_bounds(section, key, text, kelvin):
    d = paper_cycle_dict()
    d[section] = {key: text}
    sc = frogsim.load_scenario(d)
    assert getattr(getattr(sc, section), key) == pytest.approx(kelvin, rel=1e-12)


REFUSED = [  # (section, key, value, text in the message) -- the cases first
    ("source", "initial_temperature", "20 delta_degC", "temperature difference"),
    ("source", "initial_temperature", "1e6 K", "<= 1000 K"),
    ("source", "initial_temperature", "1e-300 K", ">= 150 K"),
    ("exhaust", "initial_temperature", "1e5 K", "<= 1000 K"),
    ("air", "ambient_temperature", "1e6 K", "<= 1000 K"),
    ("air", "ambient_temperature", "-5 K", ">= 150 K"),
    ("air", "reference_temperature", "0 K", ">= 150 K"),
    ("source", "initial_temperature", "-300 degC", ">= 150 K"),
    ("source", "initial_temperature", "149.99 K", ">= 150 K"),
    ("exhaust", "initial_temperature", "1000.01 K", "<= 1000 K"),
]


@pytest.mark.parametrize("section, key, value, expect", REFUSED)
def test_bad_temperatures_are_refused_in_one_line_naming_the_setting(tmp_path, capsys, section, key, value,
                                                                     expect):
    d = paper_cycle_dict()
    d[section] = {key: value}
    with pytest.raises(ScenarioError) as exc:
        frogsim.load_scenario(d)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(f"{section}.{key} = {value!r}") and expect in msg, msg
    if "difference" not in expect:
        assert "allowed: 150 K to 1000 K" in msg, msg
    # the CLI: exit 2, one line, nothing written
    text = (frogsim.scenario.load.SCENARIOS_DIR / "paper-cycle.toml").read_text()
    path = tmp_path / "s.toml"
    path.write_text(text.replace("[programs", f"[{section}]\n{key} = \"{value}\"\n\n[programs", 1))
    out = tmp_path / "out"
    assert main(["simulate", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(f"frogsim: error: {section}.{key} = "), err
    assert expect in err and "Traceback" not in err and not out.exists()


@pytest.mark.parametrize("path", ["source.initial_temperature", "exhaust.initial_temperature",
                                  "air.ambient_temperature"])
@pytest.mark.parametrize("kelvin", [1e6, 1e-300, 0.0, -5.0, 149.9, 1000.1])
def test_a_variant_is_held_to_the_same_bounds(path, kelvin):
    sc = frogsim.load_scenario("paper-cycle")
    with pytest.raises(ScenarioError, match=rf"^{path} = .* K: must be [<>]= .*allowed: 150 K to 1000 K"):
        sc.replace({path: kelvin})
    assert sc.replace({path: 400.0}).replace({path: LOW}).replace({path: HIGH}) is not None


def test_the_python_api_reads_degc_through_overrides():
    raw = frogsim.with_overrides(paper_cycle_dict(), {"source.initial_temperature": "40 degC"})
    assert frogsim.load_scenario(raw).source.initial_temperature == pytest.approx(313.15, rel=1e-12)
    raw = frogsim.with_overrides(paper_cycle_dict(), {"source.initial_temperature": "40 delta_degC"})
    with pytest.raises(ScenarioError, match="source.initial_temperature.*temperature difference"):
        frogsim.load_scenario(raw)


def test_a_sweep_reads_temperatures_in_degc_and_makes_ranges_in_kelvin(tmp_path):
    from frogsim.sweep import load_spec
    from sweep_helpers import write_case
    write_case(tmp_path)

    def spec(param, method="grid"):
        return {"base": {"scenario": "one-hip.toml"},
                "sweep": {"method": method, "parameters": {"source.initial_temperature": param}},
                "record": {"metrics": ["rise_time"], "muscle": "hip"}}

    listed = load_spec(spec({"values": ["0 degC", "20 degC", "32 degF"]}), tmp_path).parameters[0]
    assert np.allclose(listed.si, [273.15, 293.15, 273.15], rtol=1e-12)
    assert (listed.display_unit, listed.display_factor) == ("K", 1.0)       # no axis in degC "sizes"
    ranged = load_spec(spec({"start": "0 degC", "stop": "40 degC", "num": 3}), tmp_path).parameters[0]
    assert ranged.written == ("273.15 K", "293.15 K", "313.15 K")
    assert np.allclose(ranged.si, [273.15, 293.15, 313.15], rtol=1e-12)
    lhs = spec({"min": "0 degC", "max": "40 degC"}, method="lhs")
    lhs["sweep"].update(samples=8, seed=1)
    sampled = load_spec(lhs, tmp_path)
    si = np.asarray(sampled.si)[:, 0]
    assert si.size == 8 and np.all((si >= 273.15) & (si <= 313.15))
    assert all(w[0].endswith(" K") for w in sampled.written)
    # every point is a variant held to the bounds: a range reaching past 1000 K is refused
    bad = spec({"start": "20 degC", "stop": "800 degC", "num": 3})
    with pytest.raises(ScenarioError, match="source.initial_temperature.*1000 K"):
        load_spec(bad, tmp_path).validate_points()
