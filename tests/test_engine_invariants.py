"""Engine invariants of frogsim.simulate: equilibria, conservation of air, convergence with the
tolerance, independence of the output grid, and the supply modes (paper Eq. (9), no limit,
physical shared tube).
"""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

import frogsim
from frogsim.circuit.layout import G_VE, G_VS, Y_ME, Y_MS
from conftest import (C_MHJ9, K_AIR, MAIN_BORE, N_BRANCHES, P_ATM, P_SOURCE0, R_AIR, RHO_REF,
                      T_REF, one_muscle_scenario, paper_cycle_dict, steps)


def run(d: dict):
    return frogsim.simulate(frogsim.load_scenario(d))


# paper Eq. (9) with the paper's setting (Sec. 4: 4 mm bore, sonic velocity 343.2 m/s,
# one main pipe, six branches): per-branch standard volume flow [m^3/s], 43.1 L/min
EQ9_BRANCH_LIMIT = math.pi * (0.5 * MAIN_BORE) ** 2 * 343.2 / N_BRANCHES


def valve_choked_mass_flow(p1, T1):
    """Eq. (8), choked: m_dot = C rho_ref p1 sqrt(T_ref/T1) with the MHJ9's C (paper Sec. 3.3)."""
    return C_MHJ9 * RHO_REF * p1 * np.sqrt(T_REF / T1)


# ---------------------------------------------------------------------------------------------
# a. equilibria
# ---------------------------------------------------------------------------------------------

def test_charge_reaches_source_pressure():
    # A muscle held open to a 1000 L source for 3 s must end at the source pressure: with the
    # valve open and no flow left, the pressures on both sides are equal (Eq. (8): flow = 0 only
    # at sigma = 1). The source barely drops (61 cm^3 muscle vs 1000 L).
    d = one_muscle_scenario(steps((0.0, "charge")), 3.0, source={"volume": "1000 L"})
    res = run(d)
    p_m = res.muscle_pressure("m0")[-1]
    p_s = res.source_pressure[-1]
    assert p_m == pytest.approx(p_s, rel=1e-3)
    assert p_s == pytest.approx(P_SOURCE0, rel=1e-3)       # fan2017: 6 bar gauge source
    # the muscle really started at the exhaust pressure (fan2017: 0 bar gauge)
    assert res.muscle_pressure("m0")[0] == pytest.approx(P_ATM, rel=1e-12)


def test_vent_reaches_exhaust_pressure():
    # Charged for 1.5 s, then vented for 3 s into the exhaust chamber: it ends at the exhaust
    # pressure (which itself has risen a little from 1 atm with the muscle's air).
    d = one_muscle_scenario(steps((0.0, "charge"), (1.5, "vent")), 4.5, source={"volume": "1000 L"})
    res = run(d)
    p_m = res.muscle_pressure("m0")
    p_e = res.exhaust_pressure
    i_vent = np.searchsorted(res.t, 1.5)
    assert p_m[i_vent] > 0.9 * P_SOURCE0           # it was charged
    assert abs(p_m[-1] - p_e[-1]) <= 1e-3 * p_e[-1]
    assert p_e[-1] > P_ATM                         # the exhaust received the air
    # mass balance: what left the muscle through the discharge valve is what the exhaust gained
    d_e = res.y[-1, Y_ME] - res.y[0, Y_ME]
    assert res.vented_mass("m0")[-1] == pytest.approx(d_e, rel=1e-9)


# ---------------------------------------------------------------------------------------------
# b. conservation of air with the pump running
# ---------------------------------------------------------------------------------------------

def test_total_air_mass_conserved_with_pump_running(paper_cycle_raw):
    # Closed circuit: source, six muscles, exhaust, and the pump returning exhaust air to the
    # source under its pressure band. Every transfer moves mass from one volume to another, so
    # the total mass is constant (to rounding and the integrator's linear-invariant preservation).
    d = paper_cycle_raw
    d["duration"] = "20 s"
    d["programs"]["stroke"]["cycles"] = 10
    d["pump"] = {"enabled": True, "on_below_gauge": "5.5 bar", "off_above_gauge": "6 bar"}
    res = run(d)
    M = res.total_air_mass
    assert np.max(np.abs(M / M[0] - 1.0)) < 1e-9
    # the pump actually ran and moved air
    n = res.n
    assert np.any(res.u[:, 2 * n] > 0.5)
    assert res.pumped_mass[-1] > 0.0
    # source ledger: m_s(t) - m_s(0) = pumped - sum(charged) (charged counts backflow negative)
    charged = sum(res.charged_mass(m) for m in res.names)
    vented = sum(res.vented_mass(m) for m in res.names)
    ms, me = res.y[:, Y_MS], res.y[:, Y_ME]
    scale = M[0]
    assert np.max(np.abs((ms - ms[0]) - (res.pumped_mass - charged))) < 1e-9 * scale
    # exhaust ledger: m_e(t) - m_e(0) = sum(vented) - pumped
    assert np.max(np.abs((me - me[0]) - (vented - res.pumped_mass))) < 1e-9 * scale


def test_energy_conserved_with_rigid_muscles():
    # Adiabatic closed circuit, pump off, muscles of constant volume: no heat and no work, and every
    # transfer carries the enthalpy cp T m_dot of the volume it leaves into the one it enters (a
    # valve or tube is an adiabatic throttle). So the total internal energy
    #   U = sum cv m T = sum p V / (k - 1)
    # is constant: sum p_i V_i over source, exhaust and muscles stays at its initial value.
    prog = steps((0.0, "charge"), (0.4, "vent"), (0.8, "charge"), (1.2, "hold"), (1.4, "vent"))
    for mode in ("paper", "none", "physical"):
        d = one_muscle_scenario(prog, 2.0, n_muscles=3, supply={"mode": mode})
        res = run(d)
        g = res.model.g
        V_s, V_e = g[G_VS], g[G_VE]
        pv = res.source_pressure * V_s + res.exhaust_pressure * V_e
        for i, m in enumerate(res.names):
            pv = pv + res.muscle_pressure(m) * res.volumes[:, i]
        assert V_s == pytest.approx(4e-3) and V_e == pytest.approx(6e-3)   # fan2017: 4 L, 6 L
        assert np.max(np.abs(pv / pv[0] - 1.0)) < 1e-9, mode
        # the run did move air: the muscles were charged well above atmosphere at some point
        assert res.muscle_pressure("m0").max() > 5e5


def test_rigid_muscle_charged_from_huge_source_reaches_first_law_temperature():
    # Filling a rigid adiabatic volume from a reservoir at constant T_s (first law, open system):
    #   m2 cv T2 - m1 cv T1 = (m2 - m1) cp T_s,  with m = p V/(R T)
    #   => p2/T2 = p1/T1 + (p2 - p1)/(k T_s),   m2 - m1 = (p2 - p1) V / (k R T_s)
    # (textbook result: the filled tank is hotter than the supply, up to k T_s from vacuum.)
    # A 100 m^3 source keeps p_s, T_s constant to < 1e-6 while filling a 61.5 cm^3 muscle.
    d = one_muscle_scenario(steps((0.0, "charge")), 2.0, source={"volume": "100000 L"},
                            solver={"rtol": 1e-10})
    res = run(d)
    T_s = T_REF                        # fan2017 ambient 293.15 K
    p1, T1 = P_ATM, T_REF              # muscle starts at 0 bar gauge, ambient temperature
    p2 = res.muscle_pressure("m0")[-1]
    assert p2 == pytest.approx(P_SOURCE0, rel=1e-6)
    T2_expected = p2 / (p1 / T1 + (p2 - p1) / (K_AIR * T_s))     # about 388 K
    assert res.temperature("m0")[-1] == pytest.approx(T2_expected, rel=1e-6)
    V = res.volumes[-1, 0]
    assert res.charged_mass("m0")[-1] == pytest.approx((p2 - p1) * V / (K_AIR * R_AIR * T_s), rel=1e-5)
    # then venting it: the air left in the rigid muscle expands isentropically (paper Eq. (7),
    # outflow at its own temperature => Eq. (3) form): T/T2 = (p/p2)^((k-1)/k) all the way down
    d = one_muscle_scenario(steps((0.0, "charge"), (1.0, "vent")), 3.0,
                            source={"volume": "100000 L"}, solver={"rtol": 1e-10})
    res = run(d)
    t = res.t
    k0 = np.searchsorted(t, 1.0)       # last output before the discharge valve opens (2 ms later)
    p_m, T_m = res.muscle_pressure("m0"), res.temperature("m0")
    after = t > 1.003
    expected = T_m[k0] * (p_m[after] / p_m[k0]) ** ((K_AIR - 1.0) / K_AIR)
    assert p_m[-1] < 1.2 * P_ATM                     # it did vent
    assert np.max(np.abs(T_m[after] / expected - 1.0)) < 1e-6


# ---------------------------------------------------------------------------------------------
# c. convergence with the tolerance, d. independence of the output grid
# ---------------------------------------------------------------------------------------------

def test_converges_as_tolerance_tightens(paper_cycle_raw):
    runs = {}
    for rtol in (1e-4, 1e-6, 1e-8, 1e-10):
        d = copy.deepcopy(paper_cycle_raw)
        d["solver"] = {"rtol": rtol}
        runs[rtol] = run(d).muscle_pressure("hip_left")
    ref = runs[1e-10]
    err = {r: float(np.max(np.abs(runs[r] - ref))) for r in (1e-4, 1e-6, 1e-8)}
    assert err[1e-4] > err[1e-6] > err[1e-8]
    # 1e-8 against 1e-10: within 10 Pa on a 7 bar signal
    assert err[1e-8] < 10.0


def test_matches_independent_model_of_one_muscle():
    # An independent implementation of the paper's model for the simplest circuit -- source,
    # one rigid muscle, exhaust; Eq. (8) valves (ISO 6358 with the laminar region), Eq. (9)
    # saturation, and the adiabatic open-volume balances of Eqs. (2), (4), (6), (7) -- integrated
    # with scipy's DOP853 at rtol 1e-12, must agree with frogsim at every output point.
    # Parameters are fan2017's, written out: 4 L / 6 L chambers (paper Sec. 2.2.1; chosen), 6 bar
    # gauge source (paper Sec. 4.1), MHJ9 valves C = 0.4 L/(s bar), b = 0.38 (paper Sec. 3.3), laminar
    # ratio 0.999 and 2 ms dead time (fan2017 "chosen"), DMSP-20 hip 180 mm x 20 mm plus 5 cm^3
    # dead volume, Eq. (9) limit 43.1 L/min.
    from scipy.integrate import solve_ivp

    t_charge, t_vent, t_end, dead = 0.0, 0.5, 1.0, 2e-3
    d = one_muscle_scenario(steps((t_charge, "charge"), (t_vent, "vent")), t_end,
                            solver={"rtol": 1e-10})
    res = run(d)

    k, R = K_AIR, R_AIR
    V_s, V_e = 4e-3, 6e-3
    V_m = math.pi * 0.02 ** 2 / 4 * 0.18 + 5e-6
    limit = RHO_REF * EQ9_BRANCH_LIMIT

    def q(p1, T1, p2, T2):
        if p1 >= p2:
            s = p2 / p1
            x = (min(s, 0.999) - 0.38) / 0.62
            w = 1.0 if s <= 0.38 else math.sqrt(max(0.0, 1 - x * x))
            if s > 0.999:
                w *= (1 - s) / 0.001
            return C_MHJ9 * RHO_REF * p1 * math.sqrt(T_REF / T1) * w
        return -q(p2, T2, p1, T1)

    def f(t, y, charge, vent):
        m_s, p_s, m_e, p_e, m_m, p_m = y
        T_s, T_e, T_m = p_s * V_s / (m_s * R), p_e * V_e / (m_e * R), p_m * V_m / (m_m * R)
        mc = min(max(q(p_s, T_s, p_m, T_m), -limit), limit) if charge else 0.0
        md = q(p_m, T_m, p_e, T_e) if vent else 0.0
        # enthalpy carried at the temperature of the volume the air leaves
        hc = mc * (T_s if mc >= 0 else T_m)
        hd = md * (T_m if md >= 0 else T_e)
        return [-mc, -k * R * hc / V_s, md, k * R * hd / V_e, mc - md, k * R * (hc - hd) / V_m]

    y0 = [P_SOURCE0 * V_s / (R * T_REF), P_SOURCE0, P_ATM * V_e / (R * T_REF), P_ATM,
          P_ATM * V_m / (R * T_REF), P_ATM]
    phases = [(0.0, t_charge + dead, False, False), (t_charge + dead, t_vent + dead, True, False),
              (t_vent + dead, t_end, False, True)]
    ref = np.empty((res.t.size, 6))
    y = y0
    for a, b, ch, ve in phases:
        sol = solve_ivp(f, (a, b), y, method="DOP853", rtol=1e-12,
                        atol=[1e-14, 1e-6, 1e-14, 1e-6, 1e-16, 1e-6], args=(ch, ve),
                        dense_output=True)
        assert sol.success
        sel = (res.t >= a) & (res.t <= b)
        ref[sel] = sol.sol(res.t[sel]).T
        y = sol.y[:, -1]
    # closed-form sanity of the reference itself: the muscle got close to the source, then vented
    i_v = np.searchsorted(res.t, t_vent)
    assert ref[i_v, 5] > 0.99 * ref[i_v, 1]
    assert ref[-1, 5] < 1.01 * ref[-1, 3]
    for col, series in ((1, res.source_pressure), (3, res.exhaust_pressure),
                        (5, res.muscle_pressure("m0"))):
        assert np.max(np.abs(series - ref[:, col])) < 0.1     # Pa, on 1..7 bar
    assert np.max(np.abs(res.muscle_mass("m0") / ref[:, 4] - 1.0)) < 1e-7
    assert np.max(np.abs(res.temperature("m0") / (ref[:, 5] * V_m / (ref[:, 4] * R)) - 1.0)) < 1e-7


def test_independent_of_output_interval(paper_cycle_raw):
    a = copy.deepcopy(paper_cycle_raw)
    b = copy.deepcopy(paper_cycle_raw)
    a["output_interval"] = "1 ms"
    b["output_interval"] = "0.5 ms"
    ra, rb = run(a), run(b)
    assert rb.t.size == 2 * (ra.t.size - 1) + 1
    assert np.allclose(rb.t[::2], ra.t, rtol=0, atol=1e-12)
    rtol = ra.model.scenario.solver.rtol     # fan2017 default 1e-7
    # both grids sample the same solution; allow 10x the solver tolerance on pressures (~1 Pa)
    for m in ra.names:
        pa, pb = ra.muscle_pressure(m), rb.muscle_pressure(m)[::2]
        assert np.max(np.abs(pa - pb)) <= 10 * rtol * P_SOURCE0
    assert np.max(np.abs(ra.source_pressure - rb.source_pressure[::2])) <= 10 * rtol * P_SOURCE0
    assert np.max(np.abs(ra.total_air_mass - rb.total_air_mass[::2])) <= 10 * rtol * ra.total_air_mass[0]


# ---------------------------------------------------------------------------------------------
# e. supply modes: paper (Eq. (9) saturation) and none
# ---------------------------------------------------------------------------------------------

def test_paper_mode_never_exceeds_branch_limit(paper_cycle_raw):
    res = run(paper_cycle_raw)
    q = np.array([res.charge_flow(m) for m in res.names]) / res.reference_density
    # Eq. (9) with the paper's setting: 43.1 L/min per branch (paper: "45 L/min")
    assert np.max(q) <= EQ9_BRANCH_LIMIT * (1 + 1e-12)
    # and the saturation is actually reached (choked MHJ9 from 6 bar: 168 L/min > 43 L/min)
    assert np.max(q) >= EQ9_BRANCH_LIMIT * (1 - 1e-9)
    assert 42.0 <= np.max(q) * 6e4 <= 46.0


def test_supply_none_initial_flow_is_valve_choked_flow():
    d = one_muscle_scenario(steps((0.0, "charge")), 0.01, supply={"mode": "none"})
    res = run(d)
    u = res.u[:, 0]
    k = int(np.argmax(u > 0.5))              # first output with the charge valve open
    assert u[k] > 0.5 and res.t[k] < 0.005   # opens after fan2017's 2 ms dead time
    p_s, T_s = res.source_pressure[k], res.temperature("source")[k]
    p_m = res.muscle_pressure("m0")[k]
    assert p_m / p_s < 0.38                  # still choked (paper Sec. 3.3: b = 0.38)
    mdot = res.charge_flow("m0")[k]
    # Eq. (8) choked at the source state at that instant
    assert mdot == pytest.approx(valve_choked_mass_flow(p_s, T_s), rel=1e-9)
    # ... which is the MHJ9's 0.4 L/(s bar) * 7.01325 bar = 168.3 L/min from the initial source
    assert mdot / RHO_REF == pytest.approx(0.4e-3 * 7.01325, rel=1e-3)
    # no tube limit in this mode: well above Eq. (9)'s branch value
    assert mdot / RHO_REF > 3 * EQ9_BRANCH_LIMIT


# ---------------------------------------------------------------------------------------------
# f. physical tube mode
# ---------------------------------------------------------------------------------------------

def _iso_omega(sigma, b, m=0.5):
    """ISO 6358 / paper Eq. (8) subsonic-choked flow function (no laminar region needed here)."""
    if sigma <= b:
        return 1.0
    return max(0.0, 1.0 - ((sigma - b) / (1.0 - b)) ** 2) ** m


def _series_manifold_flow(p_s, T_s, p_m, n_open):
    """Per-branch mass flow of n_open identical branches fed by one tube, solved independently.

    Two ISO 6358 restrictions in series with mass balance at the manifold (pressure pm, stagnation
    temperature T_s of the source: an adiabatic throttle keeps it): tube flow(p_s -> pm) =
    n_open * valve flow(pm -> p_m). The tube is an isentropic nozzle: C_t = A psi/(rho_ref
    sqrt(T_ref)), b_t = (2/(k+1))^(k/(k-1)) (textbook choked flow written in ISO form).
    """
    from scipy.optimize import brentq
    k, R = K_AIR, R_AIR
    psi = math.sqrt(k / R) * (2 / (k + 1)) ** ((k + 1) / (2 * (k - 1)))
    C_t = math.pi * (0.5 * MAIN_BORE) ** 2 * psi / (RHO_REF * math.sqrt(T_REF))
    b_t = (2 / (k + 1)) ** (k / (k - 1))
    w = math.sqrt(T_REF / T_s) * RHO_REF

    def residual(pm):
        tube = C_t * w * p_s * _iso_omega(pm / p_s, b_t)
        valve = C_MHJ9 * w * pm * _iso_omega(p_m / pm, 0.38)
        return tube - n_open * valve

    pm = brentq(residual, p_m * 1.000001, p_s, xtol=1e-6, rtol=1e-14)
    return C_MHJ9 * w * pm * _iso_omega(p_m / pm, 0.38)


def _first_open_flows(n_muscles):
    d = one_muscle_scenario(steps((0.0, "charge")), 0.01, n_muscles=n_muscles,
                            supply={"mode": "physical"})
    res = run(d)
    k = int(np.argmax(res.u[:, 0] > 0.5))
    assert np.all(res.u[k, 0:2 * n_muscles:2] > 0.5)
    flows = np.array([res.charge_flow(m)[k] for m in res.names])
    p_s, T_s = res.source_pressure[k], res.temperature("source")[k]
    # the closed-form series solution for this instant (all muscles at the same pressure)
    p_m = res.muscle_pressure(res.names[0])[k]
    expected = _series_manifold_flow(p_s, T_s, p_m, n_muscles)
    assert np.allclose(flows, expected, rtol=1e-6, atol=0.0)
    return flows, p_s, T_s


def test_physical_tube_mode():
    one, p1, T1 = _first_open_flows(1)
    six, p6, T6 = _first_open_flows(N_BRANCHES)
    choked1 = valve_choked_mass_flow(p1, T1)
    # one branch: the 4 mm bore (sonic conductance ~2.5 L/(s bar)) is six times the valve's
    # 0.4 L/(s bar), so the manifold stays near the source and the valve is nearly choked at the
    # source pressure. In series the tube can only reduce the flow.
    assert one[0] <= choked1 * (1 + 1e-9)
    assert one[0] >= 0.98 * choked1
    # six identical branches share the tube equally, each getting less than a lone branch
    assert np.allclose(six, six[0], rtol=1e-9)
    assert six[0] < one[0] * (1 - 0.05)
    # both are far above Eq. (9)'s per-branch value (the bore really carries much more)
    assert one[0] / RHO_REF > EQ9_BRANCH_LIMIT
    assert six[0] / RHO_REF > EQ9_BRANCH_LIMIT
    # the six together cannot exceed the tube's own choked (isentropic nozzle) flow
    # A p1 sqrt(k/(R T1)) (2/(k+1))^((k+1)/(2(k-1))) with A = pi (2 mm)^2 and C_d = 1 (fan2017)
    A = math.pi * (0.5 * MAIN_BORE) ** 2
    tube = A * p6 * math.sqrt(K_AIR / (R_AIR * T6)) * (2 / (K_AIR + 1)) ** ((K_AIR + 1) / (2 * (K_AIR - 1)))
    assert six.sum() <= tube * (1 + 1e-9)
    # and several times Eq. (9)'s whole-pipe value (pi r^2 v = 258.8 L/min)
    assert six.sum() / RHO_REF > 2 * N_BRANCHES * EQ9_BRANCH_LIMIT
