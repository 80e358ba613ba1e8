"""Closed-loop valve control ([controllers] sections, frogsim.control.sampled), checked against
Eq. (8), closed forms and the control laws' definitions, not against the code's own output.

Valve flows (Eq. 8, ISO 6358): choked flow m_dot = C rho_ref p_up sqrt(T_ref/T_up); a muscle of
volume V filled adiabatically from gas at T changes its pressure at dp/dt = k R T m_dot / V.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import frogsim
from frogsim.cli import main
from frogsim.errors import ScenarioError
from tests.conftest import B_MHJ9, C_MHJ9, K_AIR, P_ATM, R_AIR, RHO_REF, T_REF

BAR = 1e5
DT = 1e-3            # controller period at the default 1 kHz
DEAD = 2e-3          # fan2017's valve dead time (both valves)
HIP_V = math.pi * 0.020 ** 2 * 0.180 / 4 + 5e-6   # DMSP-20 hip at rest: cylinder + 5 cm^3 dead volume


def closed_loop(controller: dict, duration: float = 1.0, **extra) -> dict:
    """One hip muscle at rest length (constant volume) under one controller named "loop"."""
    d = {"name": "loop", "duration": f"{duration!r} s", "output_interval": "1 ms",
         "muscles": {"hip": {"type": "hip", "motion": {"kind": "constant"}}},
         "controllers": {"loop": {"muscle": "hip", **controller}}}
    d.update(extra)
    return d


def gauge(p):
    return (p - P_ATM) / BAR


# --- the bang-bang band ----------------------------------------------------------------------------------
def test_bang_bang_stays_in_its_band_plus_the_largest_step_one_period_and_a_dead_time_allow():
    """Setpoint 3 bar, then 1 bar from 0.75 s, band 0.5 bar, the muscle's volume constant and no
    pump: the law charges while p < sp - band/2 and vents while p > sp + band/2, so a charge stops
    within one step (the pressure change over one period and one dead time, bounded below from
    Eq. 8) above sp - band/2, and a vent within one step below sp + band/2. Both edges are checked
    from both sides: a threshold moved to sp + band or sp - band leaves its window."""
    band = 0.5 * BAR
    sp, sp2, t2 = 3.0 * BAR, 1.0 * BAR, 0.75
    d = closed_loop({"kind": "bang-bang", "band": "0.5 bar", "setpoint": {"kind": "steps", "steps": [
        {"at": "0 s", "value": "3 bar"}, {"at": f"{t2} s", "value": "1 bar"}]}}, 1.5,
        supply={"mode": "none"}, output_interval="0.1 ms")
    r = frogsim.simulate(frogsim.load_scenario(d))
    p = r.muscle_pressure("hip") - P_ATM
    # largest pressure step while a command waits (one period) and acts (one dead time):
    # charge: choked from the source (at most its initial 6 bar, at T_ref; the source only cools)
    p_s = P_ATM + 6.0 * BAR
    horizon = DT + DEAD
    step_charge = K_AIR * R_AIR * T_REF * C_MHJ9 * RHO_REF * p_s * horizon / HIP_V
    # vent: at most choked from the band's top, the muscle's air at most k T_ref (adiabatic filling)
    def step_vent(p_gauge):
        return K_AIR * R_AIR * C_MHJ9 * RHO_REF * (P_ATM + p_gauge) * math.sqrt(T_REF * K_AIR * T_REF) \
            * horizon / HIP_V
    p_top = sp + band / 2 + step_charge
    bound = band / 2 + max(step_charge, step_vent(p_top))
    first = r.t <= t2
    inside = np.nonzero(first & (np.abs(p - sp) <= band / 2))[0]
    assert inside.size, "never reached the band"
    after = p[inside[0]:np.count_nonzero(first)]
    assert np.max(np.abs(after - sp)) <= bound
    # the charge stopped within one step above the band's bottom (0.19 bar here, under band/2:
    # the window excludes the band's top and a bottom moved to sp - band); nothing vented after
    assert step_charge < band / 2
    assert np.all(after >= sp - band / 2) and np.all(after <= sp - band / 2 + step_charge), (after.min(), after.max())
    # the step down to 1 bar: vented from above until the pressure fell to the band's top, then held
    # within one vent step below it (0.07 bar here), never above it
    settled = p[r.t >= t2 + 0.3]
    top = sp2 + band / 2
    lo = top - step_vent(top)
    assert np.all(settled <= top) and np.all(settled >= lo), (settled.min(), settled.max(), lo, top)


@pytest.mark.parametrize("dead_ms", [0, 2, 5])
def test_commands_change_on_the_grid_and_act_one_dead_time_later(dead_ms):
    # output rows at the samples t_k: row k holds the state at t_k and the valve states in force
    # over (t_{k-1}, t_k]. A command decided at t_k from p(t_k) is in force over
    # (t_k + dead, t_k + dead + T], so it shows in row k + dead/T + 1.
    sp, band = 3.0 * BAR, 0.1 * BAR
    d = closed_loop({"kind": "bang-bang", "setpoint": {"kind": "steps", "steps": [
        {"at": "0 s", "value": "3 bar"}, {"at": "0.3 s", "value": "1 bar"}]}, "band": "0.1 bar"}, 0.6)
    d["valves"] = {"charge": {"dead_time": f"{dead_ms} ms"}, "discharge": {"dead_time": f"{dead_ms} ms"}}
    r = frogsim.simulate(frogsim.load_scenario(d))
    p = r.muscle_pressure("hip") - P_ATM
    target = np.where(r.t < 0.3 - 1e-9, sp, 1.0 * BAR)
    charge = p < target - band / 2
    vent = p > target + band / 2
    lag = dead_ms + 1
    k = np.arange(r.t.size - lag)
    np.testing.assert_array_equal(r.u[k + lag, 0], charge[k].astype(float))
    np.testing.assert_array_equal(r.u[k + lag, 1], vent[k].astype(float))
    assert not np.any((r.u[:, 0] > 0) & (r.u[:, 1] > 0))      # never both open
    # and the valves do change (the test is not vacuous): charge, then vent after the step down
    assert r.switchings["hip"][0] >= 2 and r.switchings["hip"][1] >= 1
    # samples lie just outside each edge of the band, within a band of it: a relay whose
    # thresholds sat at target +- band (not +- band / 2) would hold there, and fail above
    assert np.any((p[k] > target[k] + band / 2) & (p[k] <= target[k] + band))
    assert np.any((p[k] < target[k] - band / 2) & (p[k] >= target[k] - band))


def test_valve_changes_fall_on_the_grid_plus_dead_time_on_a_fine_output_grid():
    d = closed_loop({"kind": "sliding-mode", "setpoint": {"kind": "sine", "mean": "3 bar", "amplitude": "1 bar",
                                                          "frequency": "2 Hz"}}, 1.0, output_interval="0.05 ms")
    d["muscles"]["hip"]["initial_pressure_gauge"] = "3 bar"
    r = frogsim.simulate(frogsim.load_scenario(d))
    for j in (0, 1):
        rows = np.nonzero(np.diff(r.u[:, j]))[0] + 1        # first row showing a new state
        assert rows.size > 4
        # the change happened after the row before, at or before this row (a row exactly at the
        # change time may fall either side of it by rounding)
        k_this = (r.t[rows] - DEAD) / DT
        k_before = (r.t[rows] - 0.05e-3 - DEAD) / DT
        off = np.minimum(np.abs(k_this - np.round(k_this)), np.abs(k_before - np.round(k_before)))
        assert np.all(off < 1e-6)


# --- the sliding-mode law's valve model is the plant's valves ---------------------------------------------
def test_sliding_mode_row_holds_no_valve_constant_and_its_model_follows_the_scenario_valves():
    from frogsim.circuit import layout as L
    from frogsim.control import table
    from frogsim.control.kinds import sliding_mode
    sc = frogsim.load_scenario(closed_loop({"kind": "sliding-mode", "setpoint": "3 bar"}, 0.004,
                                           output_interval="0.01 ms", supply={"mode": "none"}))
    base = frogsim.build_model(sc)
    # no column of the table for a valve constant, and a table that does not move when every ISO 6358
    # constant of both valves does (while the plant's muscle rows do)
    assert not [n for n in dir(table) if n in ("L_CC", "L_CB", "L_CM", "L_CRL", "L_DC", "L_DB", "L_DM", "L_DRL")]
    other = frogsim.build_model(sc.replace({"valves.charge.sonic_conductance": 3 * C_MHJ9,
                                            "valves.charge.critical_ratio": 0.3,
                                            "valves.charge.subsonic_index": 0.6,
                                            "valves.charge.laminar_ratio": 0.99,
                                            "valves.discharge.sonic_conductance": 2 * C_MHJ9,
                                            "valves.discharge.critical_ratio": 0.25,
                                            "valves.discharge.subsonic_index": 0.45,
                                            "valves.discharge.laminar_ratio": 0.98}))
    assert np.array_equal(base.laws, other.laws)
    from frogsim.circuit.valves import switching
    assert other.mp[0, L.M_VALVE] == switching.CODE
    assert other.mp[0, L.M_VP + switching.P_CC] == 3 * C_MHJ9 and other.mp[0, L.M_VP + switching.P_DB] == 0.25
    [c] = [c for c in range(base.laws.shape[0]) if base.laws[c, table.L_KIND] == sliding_mode.CODE]
    T = base.g[L.G_TAMB]
    p_s = P_ATM + 6.0 * BAR
    for factor in (1.0, 2.0):
        varied = sc.replace({"valves.charge.sonic_conductance": factor * C_MHJ9,
                             "valves.discharge.sonic_conductance": factor * C_MHJ9})
        m = frogsim.build_model(varied)
        # the law's prediction: Eq. (8) choked flows (pressure ratio below b = 0.38), every gas at
        # ambient temperature, times the row's k R T_amb / V
        y = m.y0.copy()
        y[L.Y_PS], y[L.Y_PE] = p_s, P_ATM
        gain = m.laws[c, table.L_GAIN]
        r_charge, _ = sliding_mode.mode_rates(m.laws, m.mp, c, y, P_ATM)
        assert r_charge == pytest.approx(gain * factor * C_MHJ9 * RHO_REF * p_s * math.sqrt(T_REF / T), rel=1e-12)
        p_top = P_ATM + 4.0 * BAR
        _, r_vent = sliding_mode.mode_rates(m.laws, m.mp, c, y, p_top)
        assert r_vent == pytest.approx(-gain * factor * C_MHJ9 * RHO_REF * p_top * math.sqrt(T_REF / T), rel=1e-12)
        # the plant: the first charge (commanded at t = 0, open one dead time later) is choked from
        # the source at the initial 6 bar and T_ref, at the same conductance
        r = frogsim.simulate(m)
        i0, i1 = np.searchsorted(r.t, [DEAD - 1e-12, DEAD + 0.05e-3 - 1e-12])
        q = r.charged_mass("hip")
        slope = (q[i1] - q[i0]) / (r.t[i1] - r.t[i0])
        assert slope == pytest.approx(factor * C_MHJ9 * RHO_REF * p_s, rel=1e-3)


# --- PWM -----------------------------------------------------------------------------------------------
def pwm_run(duty: float):
    d = closed_loop({"kind": "pwm", "frequency": "10 Hz", "duty": duty, "rest": "vent"}, 0.5,
                    supply={"mode": "none"}, source={"volume": "400 L"}, exhaust={"volume": "400 L"},
                    output_interval="0.5 ms")
    return frogsim.simulate(frogsim.load_scenario(d))


def test_pwm_mean_charged_flow_grows_with_duty_and_matches_the_choked_closed_form():
    p_s = P_ATM + 6.0 * BAR
    choked = C_MHJ9 * RHO_REF * p_s              # Eq. (8), sigma <= b, T_up = T_ref
    flows = []
    for duty in (0.05, 0.1, 0.15, 0.2, 0.3, 0.5):
        r = pwm_run(duty)
        mean = r.charged_mass("hip")[-1] / 0.5   # five whole pulses in 0.5 s
        flows.append(mean)
        if duty <= 0.2:
            # the valve stays choked: the muscle never rises above b times the source pressure
            assert np.max(r.muscle_pressure("hip")) <= B_MHJ9 * np.min(r.source_pressure)
            assert mean == pytest.approx(choked * duty, rel=2e-3)
    assert all(b > a for a, b in zip(flows, flows[1:]))
    # at 90 % the muscle reaches the source pressure within each pulse: the charged air is then
    # what the short vent lets out, less than at 50 % (monotone only while the pulse limits it)
    assert pwm_run(0.9).charged_mass("hip")[-1] / 0.5 < flows[-1]


def test_pwm_duty_schedule_gives_each_period_its_duty_and_the_choked_charge():
    # steps 0.05 -> 0.2 at 0.3 s on a 10 Hz carrier: periods starting at 0, 0.1, 0.2 s get 5 % (5 ms
    # pulses), those at 0.3, 0.4 s 20 % (20 ms); choked throughout (as in the constant-duty test)
    d = closed_loop({"kind": "pwm", "frequency": "10 Hz", "rest": "vent", "duty_schedule": {
        "kind": "steps", "steps": [{"at": "0 s", "value": 0.05}, {"at": "0.3 s", "value": "20 %"}]}}, 0.5,
        supply={"mode": "none"}, source={"volume": "400 L"}, exhaust={"volume": "400 L"}, output_interval="0.5 ms")
    r = frogsim.simulate(frogsim.load_scenario(d))
    p_s = P_ATM + 6.0 * BAR
    choked = C_MHJ9 * RHO_REF * p_s
    q = r.charged_mass("hip")
    i3 = int(np.searchsorted(r.t, 0.3 - 1e-9))
    assert q[i3] == pytest.approx(choked * 3 * 5e-3, rel=2e-3)          # three 5 ms pulses
    assert q[-1] - q[i3] == pytest.approx(choked * 2 * 20e-3, rel=2e-3)  # two 20 ms pulses
    opened = np.sum(r.u[1:, 0] > 0) * 0.5e-3
    assert opened == pytest.approx(3 * 5e-3 + 2 * 20e-3, abs=1e-9)


def test_pwm_duty_schedule_refusals():
    def load(ctl):
        return frogsim.load_scenario(closed_loop({"kind": "pwm", "frequency": "10 Hz", **ctl}, 0.5))
    with pytest.raises(frogsim.ScenarioError, match=r"duty_schedule = .*0\.2\.\.1\.2.*0\.\.1"):
        load({"duty_schedule": {"kind": "sine", "mean": 0.7, "amplitude": 0.5, "frequency": "1 Hz"}})
    with pytest.raises(frogsim.ScenarioError, match=r"\.duty = .*one of"):
        load({"duty": 0.3, "duty_schedule": {"kind": "constant", "value": 0.2}})
    with pytest.raises(frogsim.ScenarioError, match=r"\.duty = .*duty_schedule"):
        load({"duty": {"kind": "steps", "steps": [{"at": "0 s", "value": 0.1}]}})
    with pytest.raises(frogsim.ScenarioError, match=r"duty_schedule.steps"):
        load({"duty_schedule": {"kind": "steps", "steps": [{"at": "0 s", "value": 1.5}]}})


def test_pwm_pulses_are_whole_controller_samples_and_the_minimum_pulse_drops_short_ones():
    r = pwm_run(0.1)
    opened = np.sum(r.u[1:, 0] > 0) * 0.5e-3
    assert opened == pytest.approx(5 * 0.1 * 0.1, abs=1e-9)
    d = closed_loop({"kind": "pwm", "frequency": "10 Hz", "duty": 0.03, "minimum_pulse": "5 ms"}, 0.5)
    r = frogsim.simulate(frogsim.load_scenario(d))
    assert r.switchings["hip"][0] == 0                  # 3 ms pulses < 5 ms: dropped


# --- compiled and Python forms ------------------------------------------------------------------------
def test_the_same_law_compiled_and_in_python_gives_the_same_run():
    d = closed_loop({"kind": "bang-bang", "band": "0.1 bar", "setpoint": {"kind": "steps", "steps": [
        {"at": "0 s", "value": "3 bar"}, {"at": "0.4 s", "value": "2 bar"}, {"at": "0.7 s", "value": "4 bar"}]},
        "sensor": {"bits": 10, "full_scale": "10 bar", "noise": "0.01 bar", "seed": 3}}, 1.0,
        output_interval="0.1 ms")
    sc = frogsim.load_scenario(d)
    compiled = frogsim.simulate(sc)
    band = 0.1 * BAR
    calls = []

    def law(t, obs):
        calls.append(t)
        sp = P_ATM + (3.0 * BAR if t < 0.4 - 1e-9 else 2.0 * BAR if t < 0.7 - 1e-9 else 4.0 * BAR)
        p = obs["hip"]
        if p < sp - 0.5 * band:
            return {"hip": "charge"}
        if p > sp + 0.5 * band:
            return {"hip": "vent"}
        return {"hip": "hold"}

    python = frogsim.simulate(sc, controller=law)
    assert len(calls) == 1001                           # every sample, 0 to 1 s
    np.testing.assert_array_equal(compiled.u, python.u)         # the same valve sequence, exactly
    assert compiled.switchings == python.switchings
    # the compiled driver reads its samples from the steps' continuous extension, the Python one
    # stops on every sample: two integrations of the same ODE at rtol 1e-7 with other steps, so
    # the states agree to the global error (a few hundred rtol), not bit for bit
    np.testing.assert_allclose(compiled.y, python.y, rtol=2e-5, atol=0.0)
    assert compiled.switchings["hip"][0] > 3


def test_python_controller_may_only_drive_free_muscles():
    sc = frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": "3 bar"}, 0.01))
    with pytest.raises(frogsim.SimulationError, match="not free"):
        frogsim.simulate(sc, controller=lambda t, obs: {"knee": "charge"})


# --- air ------------------------------------------------------------------------------------------------
def test_air_is_conserved_in_closed_loop():
    d = closed_loop({"kind": "sliding-mode", "setpoint": {"kind": "sine", "mean": "3 bar", "amplitude": "1 bar",
                                                          "frequency": "1 Hz"}}, 2.0)
    d["pump"] = {"enabled": True, "on_below_gauge": "5.9 bar", "off_above_gauge": "6 bar"}
    r = frogsim.simulate(frogsim.load_scenario(d))
    total = r.total_air_mass            # source + muscle + exhaust (the exhaust holds what is vented)
    assert np.ptp(total) / total[0] < 1e-10
    m = r.muscle_mass("hip")
    np.testing.assert_allclose(m - m[0], r.charged_mass("hip") - r.vented_mass("hip"), atol=1e-9 * m.max())
    assert r.pumped_mass[-1] > 0 and r.vented_mass("hip")[-1] > 0


# --- setpoints and the sensor ------------------------------------------------------------------------------
def test_setpoint_generators_against_their_formulas(tmp_path):
    (tmp_path / "sp.csv").write_text("time_s,pressure_bar\n0,1\n1,3\n2,2\n")
    d = closed_loop({"kind": "bang-bang", "setpoint": {"kind": "table", "file": "sp.csv"}}, 0.01)
    d["base_dir"] = str(tmp_path)
    sc = frogsim.load_scenario(d)
    r = frogsim.simulate(sc.replace({"duration": 2.5}))
    t = r.t
    expect = P_ATM + BAR * np.interp(t, [0, 1, 2], [1, 3, 2])
    np.testing.assert_allclose(r.setpoint("loop"), expect, rtol=1e-12)
    d = closed_loop({"kind": "bang-bang", "setpoint": {"kind": "sine", "mean": "3 bar", "amplitude": "1 bar",
                                                       "frequency": "0.5 Hz", "start": "0.2 s"}}, 1.0)
    r = frogsim.simulate(frogsim.load_scenario(d))
    expect = P_ATM + 3 * BAR + np.where(r.t >= 0.2, BAR * np.sin(2 * np.pi * 0.5 * (r.t - 0.2)), 0.0)
    np.testing.assert_allclose(r.setpoint("loop"), expect, rtol=1e-12, atol=1e-6)


def test_sensor_quantisation_lag_and_seeded_noise():
    from frogsim.control.table import L_BITS, L_FS, L_LAG, L_NOISE, L_PATM, L_SEED, L_SIZE
    from frogsim.control.sampled import sense, sensor_noise
    from frogsim.control.signals import B_Q0
    laws = np.zeros((1, L_SIZE))
    laws[0, L_PATM] = P_ATM
    laws[0, L_BITS], laws[0, L_FS] = 10, 10 * BAR          # 10 bits over 0-10 bar
    cs = np.zeros(B_Q0 + 8)
    lsb = 10 * BAR / 1023
    p = P_ATM + 3.0041 * BAR
    assert sense(laws, 0, p, cs, 0, 0, DT) == pytest.approx(P_ATM + round(3.0041 * BAR / lsb) * lsb, abs=1e-6)
    assert sense(laws, 0, P_ATM - 0.2 * BAR, cs, 0, 0, DT) == P_ATM       # below the range: 0 gauge
    assert sense(laws, 0, P_ATM + 12 * BAR, cs, 0, 0, DT) == pytest.approx(P_ATM + 10 * BAR)
    # first-order lag: after n samples of a unit step, 1 - exp(-n dt / tau)
    laws[0, L_BITS] = 0
    laws[0, L_LAG] = 5e-3
    cs[:] = 0
    sense(laws, 0, P_ATM, cs, 0, 0, DT)                 # starts at 0 gauge
    for n in range(1, 11):
        x = sense(laws, 0, P_ATM + BAR, cs, 0, n, DT) - P_ATM
    assert x == pytest.approx(BAR * (1 - math.exp(-10 * DT / 5e-3)), rel=1e-12)
    # noise: standard normal, the same for the same seed and sample
    z = np.array([sensor_noise(7, k) for k in range(20000)])
    assert abs(z.mean()) < 0.03 and abs(z.std() - 1) < 0.03
    assert sensor_noise(7, 5) == sensor_noise(7, 5) != sensor_noise(8, 5)
    laws[0, L_LAG], laws[0, L_NOISE], laws[0, L_SEED] = 0.0, 0.01 * BAR, 7
    assert sense(laws, 0, P_ATM, cs, 0, 5, DT) == pytest.approx(P_ATM + 0.01 * BAR * sensor_noise(7, 5))


# --- the scenario format -----------------------------------------------------------------------------------
def test_controller_settings_are_variable_paths():
    sc = frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": "3 bar", "band": "0.1 bar"}, 0.2))
    paths = sc.variable_paths()
    assert {"controllers.loop.band", "controllers.loop.setpoint.value", "controllers.loop.sensor.noise",
            "controllers.loop.settle"} <= set(paths)
    assert "controllers.loop.frequency" not in paths            # pwm only
    v = sc.replace({"controllers.loop.band": 0.3 * BAR, "controllers.loop.setpoint.value": 2.0 * BAR})
    assert v.controllers["loop"].band == 0.3 * BAR
    with pytest.raises(ScenarioError, match="controllers.loop.frequency"):
        sc.replace({"controllers.loop.frequency": 10.0})
    with pytest.raises(ScenarioError, match="source pressure"):
        sc.replace({"controllers.loop.setpoint.value": 6.5 * BAR})


REFUSALS = [
    ({"kind": "pid", "setpoint": "3 bar"}, "controllers.loop.kind"),
    ({"kind": "bang-bang", "setpoint": "6.5 bar"}, "controllers.loop.setpoint"),
    ({"kind": "bang-bang", "setpoint": {"kind": "sine", "mean": "5 bar", "amplitude": "2 bar",
                                        "frequency": "1 Hz"}}, "controllers.loop.setpoint"),
    ({"kind": "pwm", "duty": 0.5, "frequency": "300 Hz"}, "controllers.loop.frequency"),
    ({"kind": "bang-bang", "setpoint": "3 bar", "muscle": "tail"}, "controllers.loop.muscle"),
    ({"kind": "bang-bang"}, "controllers.loop.setpoint"),
    ({"kind": "pwm", "frequency": "10 Hz"}, "controllers.loop.duty"),
    ({"kind": "bang-bang", "setpoint": "3 bar", "frequency": "10 Hz"}, "controllers.loop.frequency"),
]


@pytest.mark.parametrize("controller,field", REFUSALS)
def test_bad_controllers_are_refused_in_one_line(controller, field):
    with pytest.raises(ScenarioError) as exc:
        frogsim.load_scenario(closed_loop(controller))
    assert str(exc.value).startswith(field) and "\n" not in str(exc.value)


def test_a_closed_loop_muscle_takes_no_program_and_an_open_loop_one_needs_one():
    d = closed_loop({"kind": "bang-bang", "setpoint": "3 bar"})
    d["muscles"]["hip"]["program"] = {"pressurise": "0.5 s", "release": "0.5 s"}
    with pytest.raises(ScenarioError, match=r"^muscles.hip.program.*closed-loop"):
        frogsim.load_scenario(d)
    d = closed_loop({"kind": "bang-bang", "setpoint": "3 bar"})
    d["muscles"]["knee"] = {"type": "knee", "motion": {"kind": "constant"}}
    with pytest.raises(ScenarioError, match=r"^muscles.knee.program"):
        frogsim.load_scenario(d)
    d["muscles"]["knee"]["program"] = {"pressurise": "0.5 s", "release": "0.5 s"}
    r = frogsim.simulate(frogsim.load_scenario(d))       # one closed-loop muscle beside a programmed one
    assert r.u[:, 2].max() == 1.0 and r.switchings["hip"][0] >= 1 and "knee" not in r.switchings


def test_cli_refuses_a_bad_controller_with_exit_2_and_writes_nothing(tmp_path, capsys):
    f = tmp_path / "c.toml"
    f.write_text('name = "c"\nduration = "1 s"\n[muscles.hip]\ntype = "hip"\n'
                 '[controllers.hold]\nkind = "pwm"\nmuscle = "hip"\nduty = 0.5\nfrequency = "400 Hz"\n')
    out = tmp_path / "out"
    assert main(["simulate", str(f), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "controllers.hold.frequency" in err and "dead time" in err
    assert not out.exists() or not any(out.iterdir())


def test_summary_reports_the_closed_loop_metrics(tmp_path):
    import json
    f = tmp_path / "c.toml"
    f.write_text('name = "c"\nduration = "0.5 s"\n[muscles.hip]\ntype = "hip"\nmotion = { kind = "constant" }\n'
                 '[controllers.hold]\nkind = "bang-bang"\nmuscle = "hip"\nsetpoint = "3 bar"\nband = "0.1 bar"\n')
    out = tmp_path / "out"
    assert main(["simulate", str(f), "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())["control"]["hold"]
    assert {"tracking_error_rms_bar", "tracking_error_max_bar", "switchings_per_s", "air_used_L_std",
            "switchings"} <= set(s)
    assert set(s["switchings"]) == {"hip"} and set(s["switchings"]["hip"]) == {"charge", "discharge"}
    # air used: the charged mass at the standard state. Filling a rigid volume adiabatically from
    # a source at T_ref: U = c_v p V / R, so dm = V dp / (k R T_ref) (the air in it stays hot)
    p = json.loads((out / "summary.json").read_text())["muscles"]["hip"]["final_pressure_bar_gauge"] * BAR
    held = p * HIP_V / (K_AIR * R_AIR * T_REF) / RHO_REF * 1e3
    assert s["air_used_L_std"] == pytest.approx(held, rel=5e-3)


def test_control_command_writes_the_control_pressure_study(tmp_path):
    import json
    out = tmp_path / "c"
    assert main(["control", "--out", str(out), "--workers", "1"]) == 0
    s = json.loads((out / "summary.json").read_text())["control_pressure"]
    assert (out / "control-pressure.png").read_bytes()[:4] == b"\x89PNG"
    assert (out / "control-pressure.csv").exists()
    for exp in ("step", "sine"):
        for ctl in ("pwm", "bang-bang", "sliding-mode"):
            m = s["runs"][exp][ctl]
            assert m["tracking_error_rms_bar"] < 0.1 and m["switchings_per_s"] > 0 and m["air_used_L_std"] > 0
    answer = "yes" if s["sliding_mode_fewer_switchings_no_worse_rms"] else "no"
    assert f"error? {answer}:" in s["conclusion"]
