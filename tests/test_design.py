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


def test_design_group_is_registered_around_the_papers_design_point(tubes, endurance, valve):
    """The design studies, in the order `frogsim design` runs them (the valve-type comparison last),
    the first three sweeping through the paper's own robot: one 4 mm main pipe (paper Sec. 4) in the Eq. (9) mode, the 4 L source with
    the 10 L/min pump, the MHJ9 valve's C = 0.4 L/(s bar) (paper Sec. 3.3). And the valve study agrees
    with the tube study's valve-only run (no tube limit, C = 0.4, the MHJ9's b = 0.38): a larger
    critical ratio b only adds flow (ISO 6358), so that run's rise time lies between the valve
    study's at b = 0.35 and at b = 0.4, the same C."""
    assert studies_in("design") == ["design-tubes", "design-endurance", "design-valve", "design-valve-type"]
    t = tubes.table
    assert len(t[(t["mode"] == "paper") & (t["main tube count [-]"] == 1)
                 & np.isclose(t["main tube inner diameter [mm]"], 4.0)]) == 1
    e = endurance.table
    assert len(e[(e["source volume [L]"] == 4) & (e["pump displacement [L/min]"] == 10)]) == 1
    v = valve.table
    at = v[np.isclose(v["sonic conductance [L/(s bar)]"], 0.4)].set_index("critical ratio [-]")
    at.index = np.round(at.index.to_numpy(float), 2)
    vo = tubes.summary["design_tubes"]["valve_only_rise_time_90_s"]
    slow, fast = at.loc[0.35, "hip rise time 90 % [s]"], at.loc[0.4, "hip rise time 90 % [s]"]
    assert fast <= vo <= slow, (fast, vo, slow)


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


def _numbers(pattern: str, text: str) -> list:
    m = re.search(pattern, text)
    assert m, (pattern, text)
    return [float(g) for g in m.groups()]


def _row(table, **where):
    sub = table
    for col, value in where.items():
        sub = sub[np.isclose(sub[col], value)] if not isinstance(value, str) else sub[sub[col] == value]
    assert len(sub) == 1, where
    return sub.iloc[0]


def test_conclusions_state_the_studys_numbers(tubes, endurance, valve):
    """Every number a conclusion quotes is the one its table (located here by the test) or summary
    holds, at the design point the sentence names; and the quoted numbers keep the relations the
    sentences claim from the geometry (Eq. 9: n tubes of diameter d carry n d^2, so two and three
    tubes take over at 1/sqrt(2) and 1/sqrt(3) of one tube's bore) and the paper's timing."""
    rise, d, n = "hip rise time 90 % [s]", "main tube inner diameter [mm]", "main tube count [-]"
    t, s = tubes.table, tubes.summary["design_tubes"]
    text = s["conclusion"]
    x = s["valve_limited_from_inner_diameter_mm"]
    (vo,) = _numbers(r"valves alone \(MHJ9, C = 0\.4 L/\(s bar\)\) give a hip rise time of ([\d.]+) s", text)
    assert vo == pytest.approx(s["valve_only_rise_time_90_s"], abs=5e-4)
    (paper4,) = _numbers(r"one 4 mm main tube gives ([\d.]+) s", text)
    assert paper4 == pytest.approx(_row(t, mode="paper", **{n: 1, d: 4.0})[rise], abs=5e-4)
    one, two, three = _numbers(r"from ([\d.]+) mm with one tube, ([\d.]+) mm with two, ([\d.]+) mm with three", text)
    assert [one, two, three] == pytest.approx([x["paper"][k] for k in "123"], abs=0.05)
    assert two == pytest.approx(one / np.sqrt(2), rel=0.08) and three == pytest.approx(one / np.sqrt(3), rel=0.08)
    (phys4,) = _numbers(r"gives ([\d.]+) s with one 4 mm tube", text)
    assert phys4 == pytest.approx(_row(t, mode="physical", **{n: 1, d: 4.0})[rise], abs=5e-4)
    p1, p2 = _numbers(r"take over from ([\d.]+) mm \(([\d.]+) mm with two tubes\)", text)
    assert [p1, p2] == pytest.approx([x["physical"]["1"], x["physical"]["2"]], abs=0.05)
    missing, layouts = _numbers(r"(\d+) of the (\d+) layouts do not reach", text)
    assert layouts == 2 * 3 * 17                     # two modes, 1-3 tubes, 2-10 mm in 0.5 mm steps
    assert missing == np.count_nonzero(~np.isfinite(t[rise]))

    e, s = endurance.table, endurance.summary["design_endurance"]
    text = s["conclusion"]
    (period,) = _numbers(r"a stroke every ([\d.]+) s \(the paper's 1 s pressurise / 1 s release\)", text)
    assert period == 2.0
    (air,) = _numbers(r"one such stroke takes ([\d.]+) L of air", text)
    assert air == pytest.approx(s["air_per_stroke_at_required_swing_L_std"], abs=0.005)
    base = _row(e, **{"source volume [L]": 4, "pump displacement [L/min]": 10})
    strokes, rate, asked = _numbers(r"manages (\d+) full strokes .* sustains ([\d.]+) strokes per minute against "
                                    r"the (\d+) the paper's timing asks", text)
    assert strokes == base["strokes before short [-]"]
    assert rate == pytest.approx(base["sustainable stroke rate [1/min]"], abs=0.05)
    assert asked == 60 / period
    need4, need2, need16 = _numbers(r"about (\d+) L/min displacement with the 4 L source \((\d+) L/min with 2 L, "
                                    r"(\d+) L/min with 16 L", text)
    need = s["pump_for_paper_timing_L_per_min"]
    assert [need4, need2, need16] == pytest.approx([need["source_4_L"], need["source_2_L"], need["source_16_L"]],
                                                   abs=0.5)
    assert need2 > need4 > need16          # the sentence's reason: more air, more mass per pump stroke
    big, small = _numbers(r"16 L gives (\d+) full strokes against (\d+) with 4 L", text)
    assert big == _row(e, **{"source volume [L]": 16, "pump displacement [L/min]": 10})["strokes before short [-]"]
    assert small == base["strokes before short [-]"]

    v, s = valve.table, valve.summary["design_valve"]
    text = s["conclusion"]
    c, b = "sonic conductance [L/(s bar)]", "critical ratio [-]"
    slow, c_lo, fast, c_hi, slope = _numbers(
        r"falls from ([\d.]+) s at C = ([\d.]+) to ([\d.]+) s at C = ([\d.]+) L/\(s bar\), a fitted rise time "
        r"~ C\^(-[\d.]+)", text)
    assert (c_lo, c_hi) == (0.1, 1.0)
    assert slow == pytest.approx(_row(v, **{c: 0.1, b: 0.4})[rise], abs=5e-4)
    assert fast == pytest.approx(_row(v, **{c: 1.0, b: 0.4})[rise], abs=5e-4)
    assert slope == pytest.approx(s["rise_time_exponent_in_C"], abs=0.005)
    # a fitted power law through the two ends is near the fitted exponent over all ten C
    assert np.log(fast / slow) / np.log(c_hi / c_lo) == pytest.approx(slope, abs=0.2)
    (spread,) = _numbers(r"changes the rise time by (\d+)%", text)
    r = v[np.isclose(v[c], 0.4)][rise]
    assert spread == pytest.approx(100 * (r.max() - r.min()) / r.mean(), abs=0.5)
