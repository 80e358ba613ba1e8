"""Design studies: trends that follow from the physics, closed forms, and conclusions with numbers."""
import re

import numpy as np
import pytest

from frogsim.studies import studies_in


@pytest.fixture(scope="module")
def tubes(study):
    return study("design-tubes")


@pytest.fixture(scope="module")
def endurance(study):
    return study("design-endurance")


@pytest.fixture(scope="module")
def valve(study):
    return study("design-valve")


def test_design_group_registered():
    assert studies_in("design") == ["design-tubes", "design-endurance", "design-valve"]


def test_tubes_wider_is_never_slower_and_ends_at_the_valve_limit(tubes):
    d = tubes.table
    vo = tubes.summary["design_tubes"]["valve_only_rise_time_90_s"]
    for (mode, count), sub in d.groupby(["mode", "main tube count [-]"]):
        sub = sub.sort_values("main tube inner diameter [mm]")
        r = sub["hip rise time 90 % [s]"].to_numpy()
        # a rise not reached in the 1 s pressurise (NaN) only at the narrow end, with less of the
        # rise reached than any layout that gets there
        miss = ~np.isfinite(r)
        k = int(miss.sum())
        assert not miss[k:].any(), (mode, count)
        assert np.all(sub["hip rise reached [%]"].to_numpy()[miss] < 90), (mode, count)
        r = r[k:]
        assert np.all(np.diff(r) <= 1e-3), (mode, count)          # more flow area never slows it
        assert r[-1] == pytest.approx(vo, rel=0.05)                # 10 mm: the valve limits
        assert np.all(r >= vo * (1 - 1e-3))                        # no tube beats the valve alone


def test_tubes_physical_mode_needs_a_smaller_bore_than_eq9(tubes):
    # the physical tube's choked flow uses the real upstream density (about 7 times atmospheric
    # at 6 bar), Eq. (9) the atmospheric one: the valve must take over at a smaller bore
    x = tubes.summary["design_tubes"]["valve_limited_from_inner_diameter_mm"]
    for count in ("1", "2", "3"):
        assert x["physical"][count] < x["paper"][count]
    # Eq. (9): n tubes of diameter d carry n d^2; equal capacity for n = 1 at d1 and n = 2 at d1/sqrt(2)
    assert x["paper"]["2"] == pytest.approx(x["paper"]["1"] / np.sqrt(2), rel=0.08)


def test_endurance_trends_and_closed_forms(endurance):
    d = endurance.table
    for vs, sub in d.groupby("source volume [L]"):
        sub = sub.sort_values("pump displacement [L/min]")
        assert np.all(np.diff(sub["strokes before short [-]"]) >= 0), vs   # a stronger pump never hurts
        # the pump's mass flow is proportional to its displacement (frogsim.physics.flow
        # .pump_mass_flow at fixed pressures), so the sustainable rate is too
        rate = sub["sustainable stroke rate [1/min]"].to_numpy() / sub["pump displacement [L/min]"].to_numpy()
        assert np.allclose(rate, rate[0], rtol=1e-9)
    # steady state: p_s - p_e equals the required swing, and the air of source + exhaust
    # (p V / R T at 293.15 K) equals the initial 6 bar gauge source plus the atmospheric exhaust
    swing = endurance.summary["design_endurance"]["required_swing_bar"]
    patm, R, T, Ve = 1.01325, 287.0, 293.15, 6e-3
    for vs, sub in d.groupby("source volume [L]"):
        ps = sub["steady source pressure [bar gauge]"].iloc[0] + patm
        pe = sub["steady exhaust pressure [bar gauge]"].iloc[0] + patm
        assert ps - pe == pytest.approx(swing, rel=1e-9)
        air0 = (6.0 + patm) * vs * 1e-3 + patm * Ve
        assert ps * vs * 1e-3 + pe * Ve == pytest.approx(air0, rel=1e-9)


def test_valve_rise_time_falls_with_conductance(valve):
    d = valve.table
    for b, sub in d.groupby("critical ratio [-]"):
        r = sub.sort_values("sonic conductance [L/(s bar)]")["hip rise time 90 % [s]"].to_numpy()
        assert np.all(np.diff(r) < 0), b
    # at least as steep as 1/C (a choked fill of a fixed volume), since the volume also grows
    assert valve.summary["design_valve"]["rise_time_exponent_in_C"] <= -1.0


def test_conclusions_state_numbers(tubes, endurance, valve):
    for data, key in ((tubes, "design_tubes"), (endurance, "design_endurance"), (valve, "design_valve")):
        text = data.summary[key]["conclusion"]
        assert len(re.findall(r"\d+\.\d+|\d+ ", text)) >= 4, text
