"""Metrics a user reads, checked against closed forms (docs/metrics.md).

Rise time: a rigid volume filled through a valve from a very large source. Eq. (6) with dV = 0 is
V dp = k R T_s dm, and Eq. (8) gives the mass flow, so

    dp/dt = a                     while choked (sigma = p/p_s <= b),  a = k R T_s m_c / V,
    dp/dt = a sqrt(1 - x^2)       subsonic, x = (sigma - b)/(1 - b),

with m_c = C rho_ref p_s sqrt(T_ref/T_s). The choked part is linear in time; the subsonic part
integrates to t = p_s (1 - b)/a * arcsin(x). The time to the 90 % level
p_90 = p_0 + 0.9 (p_s - p_0) is the sum of the two. Every number below comes from the paper, ISO
8778 and the parameter set's geometry, not from frogsim.
"""
import math

import numpy as np
import pytest

import frogsim
from frogsim.engine.measures import NOT_REACHED, REACHED, format_rise, rise_times
from frogsim.io.results import run_summary

from conftest import B_MHJ9, C_MHJ9, K_AIR, P_ATM, R_AIR, RHO_REF, T_REF, one_muscle_scenario, steps

# hip muscle at rest length: DMSP-20 (inner diameter 20 mm, paper Sec. 2.2.2), 180 mm long; at
# rest Eq. (5) is the cylinder pi D^2/4 L; plus the parameter set's 5 cm^3 dead volume
V_HIP_REST = math.pi * 0.020 ** 2 / 4 * 0.180 + 5e-6
T_SOURCE = 293.15            # parameter set: ambient = ISO reference temperature


def choked_fill_t90(p_s, p_0, V, C=C_MHJ9, b=B_MHJ9, fraction=0.9):
    """Closed-form time [s] for a rigid volume V at p_0 to reach p_0 + fraction (p_s - p_0) when
    filled through an Eq. (8) valve from a constant source p_s at T_SOURCE (module docstring)."""
    m_c = C * RHO_REF * p_s * math.sqrt(T_REF / T_SOURCE)
    a = K_AIR * R_AIR * T_SOURCE * m_c / V                 # Pa/s while choked
    p_level = p_0 + fraction * (p_s - p_0)
    p_crit = b * p_s
    if p_level <= p_crit:
        return (p_level - p_0) / a
    x = (p_level / p_s - b) / (1 - b)
    return (p_crit - p_0) / a + p_s * (1 - b) / a * math.asin(x)


def choked_fill_pressure(t, p_s, p_0, V, C=C_MHJ9, b=B_MHJ9):
    """Closed-form pressure [Pa abs] t seconds after the valve opens (inverse of the above):
    linear while choked, then p = p_s (b + (1 - b) sin(a (t - t_c) / (p_s (1 - b))))."""
    m_c = C * RHO_REF * p_s * math.sqrt(T_REF / T_SOURCE)
    a = K_AIR * R_AIR * T_SOURCE * m_c / V
    t_c = (b * p_s - p_0) / a
    if t <= t_c:
        return p_0 + a * t
    return p_s * (b + (1 - b) * math.sin(min(a * (t - t_c) / (p_s * (1 - b)), math.pi / 2)))


def _rigid_fill(source_gauge=6e5, duration=0.4, pressurise=None, **sections):
    program = steps((0.0, "charge"), (pressurise, "hold")) if pressurise else steps((0.0, "charge"))
    sections.setdefault("supply", {"mode": "none"})
    raw = one_muscle_scenario(program, duration, motion={"kind": "constant"}, output_interval="0.1 ms",
                              source={"volume": "1000 L", "initial_pressure_gauge": f"{source_gauge / 1e5!r} bar"},
                              solver={"rtol": 1e-10}, **sections)
    return frogsim.simulate(frogsim.load_scenario(raw))


def test_closed_form_volume_is_the_engines():
    # guard on the test's own input: the rigid volume the closed form assumes is the muscle's
    r = _rigid_fill(duration=0.01)
    assert r.volumes[:, 0] == pytest.approx(V_HIP_REST, rel=1e-9)


@pytest.mark.parametrize("source_gauge", [1e5, 3e5, 6e5])
def test_rise_time_of_a_rigid_volume_matches_the_closed_form(source_gauge):
    r = _rigid_fill(source_gauge)
    p_s = P_ATM + source_gauge
    expected = choked_fill_t90(p_s, P_ATM, V_HIP_REST)
    # the 1000 L source gives ~1e-4 of its mass: its pressure stays within 1e-4 of p_s
    assert r.rise_time("m0") == pytest.approx(expected, rel=2e-3)
    assert r.rise_time_reason("m0") is None


def test_rise_to_a_level_inside_the_choked_regime_is_linear():
    # sigma <= b up to 0.38 p_s: the level at 20 % of the rise lies inside the choked regime, where
    # the pressure rises at the constant rate a (no arcsin part)
    r = _rigid_fill(6e5)
    p_s = P_ATM + 6e5
    assert P_ATM + 0.2 * (p_s - P_ATM) < B_MHJ9 * p_s
    expected = choked_fill_t90(p_s, P_ATM, V_HIP_REST, fraction=0.2)
    assert r.rise_time("m0", fraction=0.2) == pytest.approx(expected, rel=2e-3)


def test_rise_time_is_measured_from_the_valve_opening_not_the_command():
    # the command is at 0; the valve opens after its 2 ms dead time (parameter set): same rise
    # time whenever the command comes
    early = _rigid_fill(6e5)
    raw = one_muscle_scenario(steps((0.0, "hold"), (0.05, "charge")), 0.4, motion={"kind": "constant"},
                              output_interval="0.1 ms", supply={"mode": "none"},
                              source={"volume": "1000 L", "initial_pressure_gauge": "6 bar"},
                              solver={"rtol": 1e-10})
    late = frogsim.simulate(frogsim.load_scenario(raw))
    assert late.charge_open_times("m0")[0] == pytest.approx(0.052, abs=1e-9)
    assert late.rise_time("m0") == pytest.approx(early.rise_time("m0"), rel=1e-3)


def test_not_reached_when_the_valve_closes_first():
    # choked all the way to 0.38 p_s: the time for the 90 % level is at least
    # (0.9 (p_s - p_0)) / a > 60 ms; holding after 30 ms leaves the muscle well short of it
    p_s = P_ATM + 6e5
    t90 = choked_fill_t90(p_s, P_ATM, V_HIP_REST)
    r = _rigid_fill(6e5, duration=0.2, pressurise=0.03)
    assert 0.03 < t90
    assert math.isnan(r.rise_time("m0"))
    reason = r.rise_time_reason("m0")
    assert reason.startswith("not reached before the charge valve closed")
    # share of the rise reached at the close: the valve opens and closes 2 ms after its commands
    # (dead time), so it is open 30 ms (choked for the first 26 ms, then subsonic)
    reached = (choked_fill_pressure(0.030, p_s, P_ATM, V_HIP_REST) - P_ATM) / (p_s - P_ATM)
    assert r.rise("m0").reached[0] == pytest.approx(reached, rel=2e-3)
    assert f"reached {100 * reached:.0f} % of the rise" in reason
    s = run_summary(r)["muscles"]["m0"]
    assert s["rise_time_90_s"] is None and s["rise_time_90_reason"] == reason


def test_not_reached_under_a_low_branch_limit():
    # Eq. (9) cap of 5 L/min standard for 0.3 s passes 5/60 * 0.3 = 0.025 L standard, i.e.
    # 0.025e-3 * rho_ref kg, which raises a rigid 61.55 cm^3 from 1 atm by
    # k R T_s dm / V (Eq. 6): well under 90 % of the 6 bar rise
    limit = 5e-3 / 60
    r = _rigid_fill(6e5, duration=0.5, pressurise=0.302,
                    supply={"mode": "paper", "branch_limit": "5 L/min"})
    dm = limit * RHO_REF * 0.300
    dp = K_AIR * R_AIR * T_SOURCE * dm / V_HIP_REST
    assert dp < 0.9 * 6e5
    assert math.isnan(r.rise_time("m0"))
    assert "not reached before the charge valve closed" in r.rise_time_reason("m0")
    assert r.rise("m0").reached[0] == pytest.approx(dp / 6e5, rel=0.01)
    # the cap bound for the whole charge: it says so
    assert r.branch_limited_fraction("m0") > 0.99
    notes = run_summary(r, notes=False)["notes"]
    assert len(notes) == 1 and "branch limit (5.0 L/min)" in notes[0] and "m0 for 100 %" in notes[0]


def test_no_note_without_a_binding_limit():
    r = _rigid_fill(6e5)
    assert run_summary(r, notes=False)["notes"] == []
    assert r.branch_limited_fraction("m0") == 0.0


def test_rise_target_is_the_source_pressure_at_the_close():
    # synthetic series: the muscle follows 1 - exp(-t/tau) toward a source that sags linearly;
    # the target is the source at the last open sample, the level 90 % of the way to it
    t = np.linspace(0.0, 1.0, 10001)
    ps = 7e5 - 0.5e5 * t
    tau = 0.1
    p = 1e5 + 5.5e5 * (1 - np.exp(-t / tau))
    u = (t < 0.8).astype(float)
    m = rise_times(t, p[None], ps[None], u[None], np.array([0.0]))
    target = 7e5 - 0.5e5 * t[t < 0.8][-1]
    assert m.p_target[0] == pytest.approx(target)
    level = 1e5 + 0.9 * (target - 1e5)
    expected = -tau * math.log(1 - (level - 1e5) / 5.5e5)
    assert m.status[0] == REACHED
    assert m.seconds[0] == pytest.approx(expected, abs=1e-6)
    # a muscle capped far below: not reached, with the share it got to
    p_low = 1e5 + 2.0e5 * (1 - np.exp(-t / tau))
    m = rise_times(t, p_low[None], ps[None], u[None], np.array([0.0]))
    assert m.status[0] == NOT_REACHED and math.isnan(m.seconds[0])
    assert m.reached[0] == pytest.approx((p_low[t < 0.8].max() - 1e5) / (target - 1e5))
    # 2 bar of a 5.6 bar rise (to the source's 6.6 bar abs at the close, 0.8 s): 36 %
    assert "reached 36 % of the rise" in m.reason(0)


def test_format_rise():
    assert format_rise(0.0806) == "0.081 s"
    assert format_rise(float("nan")) == "not reached"
    assert format_rise(None) == "not reached"
