"""Wall heat transfer in the engine, against physics.

Each volume's air exchanges heat with its wall (at the ambient temperature) by Newton's law,
Q = h A (T_wall - T) (frogsim.physics.heat). Checked here on whole runs of the engine:

- a closed rigid volume relaxes to the wall temperature with tau = m c_v / (h A), its pressure
  following p = m R T / V (the muscle's wall is its braid cylinder's mantle pi D0 L0 at rest, the
  source's the wall area its parameters give);
- h -> 0 gives the adiabatic run: h = 0 meets the adiabatic first-law closed form of filling a
  rigid volume, and a vanishing h the h = 0 run;
- a large h gives the isothermal filling of a rigid volume through the valve (ISO 6358 flow at the
  wall temperature, integrated independently here);
- the first law of each volume, dU = H_in - H_out - W + Q with U = p V / (k - 1), closes over a run
  of a moving muscle that is charged, held and vented;
- air is conserved as before.

The reference numbers come from the datasheet geometry (DMSP-20: 20 mm bore, 180 mm) and the
paper's constants (conftest), not from the code under test.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import simpson, solve_ivp

import frogsim
from frogsim.circuit import layout as L
from frogsim.circuit.rhs import muscle_volume_state, rhs

from conftest import B_MHJ9, C_MHJ9, K_AIR, P_ATM, P_SOURCE0, R_AIR, RHO_REF, T_REF, one_muscle_scenario, steps

CV = R_AIR / (K_AIR - 1.0)          # J/(kg K)
CP = K_AIR * CV
T_AMB = T_REF                       # fan2017: ambient 293.15 K
D0, L0 = 0.020, 0.180               # hip muscle: DMSP-20 bore, 180 mm (paper Sec. 2.2.2)
A_HIP = math.pi * D0 * L0           # braid mantle at rest [m^2]
V_HIP = math.pi / 4 * D0 ** 2 * L0 + 5e-6   # Eq. (5) at rest plus the 5 cm^3 dead volume


def heat(d: dict, h_muscle=0.0, h_source=0.0, h_exhaust=0.0, source_area=None) -> dict:
    """The scenario dict with the wall heat transfer coefficients [W/(m^2 K)] set."""
    d.setdefault("muscle_types", {}).setdefault("hip", {})["heat_transfer_coefficient"] = f"{h_muscle!r} W/(m^2*K)"
    d.setdefault("source", {})["heat_transfer_coefficient"] = f"{h_source!r} W/(m^2*K)"
    d.setdefault("exhaust", {})["heat_transfer_coefficient"] = f"{h_exhaust!r} W/(m^2*K)"
    if source_area is not None:
        d["source"]["wall_area"] = f"{source_area!r} m^2"
    return d


def run(d: dict):
    return frogsim.simulate(frogsim.load_scenario(d))


def test_closed_rigid_volumes_cool_with_the_closed_form_time_constant():
    # charge a rigid hip muscle for 0.3 s, then hold it closed: muscle and source are closed rigid
    # volumes from t0 on, the muscle hot from the charge, the source cold from its expansion
    # (a 0.5 L source, so that it cools by more than a few kelvin)
    h_m, h_s, A_s = 20.0, 10.0, 0.05
    d = heat(one_muscle_scenario(steps((0.0, "charge"), (0.3, "hold")), 4.0, solver={"rtol": 1e-10},
                                 source={"volume": "0.5 L"}),
             h_muscle=h_m, h_source=h_s, source_area=A_s)
    res = run(d)
    t = res.t
    k0 = np.searchsorted(t, 0.31)            # valves closed at 0.302 s (2 ms dead time)
    tt = t[k0:] - t[k0]
    for which, h, A, V in (("m0", h_m, A_HIP, V_HIP), ("source", h_s, A_s, 5e-4)):
        T = res.temperature(which)
        p = res.muscle_pressure("m0") if which == "m0" else res.source_pressure
        m = p[k0] * V / (R_AIR * T[k0])
        tau = m * CV / (h * A)
        T_closed = T_AMB + (T[k0] - T_AMB) * np.exp(-tt / tau)
        np.testing.assert_allclose(T[k0:], T_closed, rtol=1e-6)
        np.testing.assert_allclose(p[k0:], m * R_AIR * T_closed / V, rtol=1e-6)
        assert abs(T[k0] - T_AMB) > 5.0                           # it had heat to lose or gain
        assert abs(T[-1] - T[k0]) > 0.4 * abs(T[k0] - T_AMB)    # and the run saw it relax


def test_zero_h_is_the_adiabatic_closed_form_and_a_vanishing_h_tends_to_it():
    # first law, open rigid adiabatic volume filled from a reservoir at T_s:
    #   p2/T2 = p1/T1 + (p2 - p1)/(k T_s)
    base = one_muscle_scenario(steps((0.0, "charge")), 1.0, source={"volume": "100000 L"},
                               solver={"rtol": 1e-10})
    res0 = run(heat(base, 0.0))
    p2 = res0.muscle_pressure("m0")[-1]
    assert p2 == pytest.approx(P_SOURCE0, rel=1e-6)
    T2 = p2 / (P_ATM / T_REF + (p2 - P_ATM) / (K_AIR * T_REF))
    assert res0.temperature("m0")[-1] == pytest.approx(T2, rel=1e-6)
    # the same scenario without any heat setting (fan2017's h = 0) is the same run, bit for bit
    res_default = run(one_muscle_scenario(steps((0.0, "charge")), 1.0, source={"volume": "100000 L"},
                                          solver={"rtol": 1e-10}))
    assert np.array_equal(res0.y, res_default.y)
    # h -> 0: the difference to the adiabatic run shrinks in proportion to h
    diffs = []
    for h in (1e-2, 1e-3):
        r = run(heat(one_muscle_scenario(steps((0.0, "charge")), 1.0, source={"volume": "100000 L"},
                                         solver={"rtol": 1e-10}), h))
        diffs.append(np.max(np.abs(r.temperature("m0") - res0.temperature("m0"))))
    assert diffs[0] > 0.0
    assert diffs[1] == pytest.approx(diffs[0] / 10.0, rel=0.05)


def _iso6358_choked_fraction(sigma, b):
    """ISO 6358 (paper Eq. (8)) flow over its choked value at pressure ratio sigma (m = 0.5)."""
    if sigma <= b:
        return 1.0
    return math.sqrt(max(1.0 - ((sigma - b) / (1.0 - b)) ** 2, 0.0))


def test_large_h_fills_a_rigid_volume_isothermally():
    # isothermal filling from a reservoir at ambient temperature:  V dp/dt = R T_a m_dot(p_s, p),
    # m_dot = C rho_ref p_s sqrt(T_ref/T_s) f(p/p_s)  (ISO 6358, the MHJ9 valve); the adiabatic fill
    # rises k times faster at the start
    t_open = 0.002                                           # the charge valve's dead time
    def isothermal(t, y):
        return [R_AIR * T_AMB * C_MHJ9 * RHO_REF * P_SOURCE0 * _iso6358_choked_fraction(y[0] / P_SOURCE0, B_MHJ9)
                / V_HIP]
    t_eval = np.arange(0.0, 0.3, 1e-3)
    ref = solve_ivp(isothermal, (0.0, 0.3), [P_ATM], t_eval=t_eval, rtol=1e-10, atol=1e-6).y[0]
    gauge_span = P_SOURCE0 - P_ATM
    errors = {}
    for h in (0.0, 1e4, 1e5):
        d = heat(one_muscle_scenario(steps((0.0, "charge")), 0.3, source={"volume": "100000 L"},
                                     supply={"mode": "none"}, solver={"rtol": 1e-9}), h)
        res = run(d)
        p = np.interp(t_eval + t_open, res.t, res.muscle_pressure("m0"))
        errors[h] = np.max(np.abs(p - ref)) / gauge_span
    assert errors[0.0] > 0.1                    # adiabatic: far from isothermal
    assert errors[1e4] < 0.02                   # tau = m c_v/(h A) ~ 2 ms against a ~0.15 s fill
    assert errors[1e5] < 0.003 and errors[1e5] < errors[1e4] / 4


def _flows(res, k, u):
    """Mass flows (charge, discharge) [kg/s] of muscle 0 at output k with valve states u."""
    m = res.model
    n = res.n
    dydt = np.empty(res.y.shape[1])
    aux = np.empty(2 * n + 1)
    work = np.zeros(3 * n + 1)
    rhs(float(res.t[k]), np.ascontiguousarray(res.y[k]), np.ascontiguousarray(u, dtype=float), 0.0,
        m.g, m.mp, m.mot_t, m.mot_L, m.mot_d, m.mot_n, dydt, aux, work)
    return aux[0], aux[1]


def test_first_law_of_each_volume_closes_over_a_run():
    # a moving hip muscle (stroke motion) charged, held, vented, with heat through every wall;
    # per volume:  U(t1) - U(t0) = int (H_in - H_out - p dV/dt + Q) dt,  U = p V/(k - 1),
    # H = c_p m_dot T_upstream. Valve switches (command + 2 ms) sit on the 0.1 ms output grid, and
    # each piece between them is integrated on its own (Simpson), the valve states of the piece at
    # both its ends.
    prog = steps((0.0, "charge"), (0.4, "hold"), (0.7, "vent"))
    d = heat(one_muscle_scenario(prog, 1.2, motion={"kind": "stroke"}, output_interval="0.1 ms",
                                 supply={"mode": "none"}, solver={"rtol": 1e-10}),
             h_muscle=20.0, h_source=10.0, h_exhaust=10.0, source_area=0.1845)
    res = run(d)
    g, mp = res.model.g, res.model.mp
    t = res.t
    T_m, T_s, T_e = res.temperature("m0"), res.temperature("source"), res.temperature("exhaust")
    p_m = res.muscle_pressure("m0")
    Lm = res.lengths[:, 0]
    from frogsim.circuit.actuators import mckibben
    b0, nt = mp[0, L.M_AP + mckibben.P_B0], mp[0, L.M_AP + mckibben.P_N]
    D = np.sqrt(b0 ** 2 - Lm ** 2) / (nt * math.pi)              # braid diameter at length L
    V = np.array([muscle_volume_state(float(tk), 0, mp, res.model.mot_t, res.model.mot_L,
                                      res.model.mot_d, res.model.mot_n) for tk in t])
    Vm, dV = V[:, 0], V[:, 1]
    A_s = 0.1845
    A_e = math.pi * (4 * 6e-3 / math.pi) ** (2 / 3) * 1.5       # 6 L cylinder, length = diameter
    Q_m = 20.0 * math.pi * D * Lm * (T_AMB - T_m)
    Q_s = 10.0 * A_s * (T_AMB - T_s)
    Q_e = 10.0 * A_e * (T_AMB - T_e)
    switches = [0.002, 0.402, 0.702]
    edges = [0] + [int(np.argmin(np.abs(t - s))) for s in switches] + [t.size - 1]
    states = [(0, 0), (1, 0), (0, 0), (0, 1)]                   # before 2 ms, charge, hold, vent
    for e in edges[1:-1]:
        assert abs(t[e] - switches[edges.index(e) - 1]) < 1e-9
    dU = {"m0": 0.0, "source": 0.0, "exhaust": 0.0}
    for (a, b), u in zip(zip(edges[:-1], edges[1:]), states):
        if b <= a:
            continue
        idx = np.arange(a, b + 1)
        fl = np.array([_flows(res, k, u) for k in idx])
        mc, md = fl[:, 0], fl[:, 1]
        # mc, md >= 0 here (source above the muscle while charging, muscle above the exhaust venting)
        assert np.all(mc >= 0.0) and np.all(md >= 0.0)
        H_in_m = CP * mc * T_s[idx]
        H_out_m = CP * md * T_m[idx]
        dU["m0"] += simpson(H_in_m - H_out_m - p_m[idx] * dV[idx] + Q_m[idx], x=t[idx])
        dU["source"] += simpson(-H_in_m + Q_s[idx], x=t[idx])
        dU["exhaust"] += simpson(H_out_m + Q_e[idx], x=t[idx])
    U = {"m0": p_m * Vm / (K_AIR - 1.0), "source": res.source_pressure * 4e-3 / (K_AIR - 1.0),
         "exhaust": res.exhaust_pressure * 6e-3 / (K_AIR - 1.0)}
    heat_moved = simpson(np.abs(Q_m), x=t)
    assert heat_moved > 1.0                                      # joules: the walls did matter
    for name in dU:
        change = U[name][-1] - U[name][0]
        scale = abs(change) + CP * T_AMB * res.charged_mass("m0")[-1]   # enthalpy through the valve
        assert abs(change - dU[name]) < 1e-6 * scale, (name, change, dU[name])


def test_air_is_conserved_with_heat_transfer(paper_cycle_raw):
    d = paper_cycle_raw
    d["parameters"] = "fan2017-heat"
    d["duration"] = "4 s"
    d["programs"]["stroke"]["cycles"] = 2
    d["pump"] = {"enabled": True, "on_below_gauge": "5.5 bar", "off_above_gauge": "6 bar"}
    res = run(d)
    M = res.total_air_mass
    assert np.max(np.abs(M / M[0] - 1.0)) < 1e-9
    assert res.pumped_mass[-1] > 0.0
    # and heat did flow: the held hip cools below the adiabatic 359 K
    assert res.temperature("hip_left")[np.searchsorted(res.t, 1.0)] < 350.0


# --- the fit recovers h --------------------------------------------------------------------------

HEAT_RIG = """name = "hip-hold"
parameters = "fan2017"
duration = "1.5 s"
output_interval = "1 ms"

[controller]
rate = "1 kHz"

[supply]
mode = "none"

[programs.charge-hold]
steps = [{ at = "0 s", state = "charge" }, { at = "0.3 s", state = "hold" }]

[muscles.hip]
type = "hip"
program = "charge-hold"
motion = { kind = "constant" }
"""
H_PATH = "muscle_types.hip.heat_transfer_coefficient"
H_TRUE = 20.0                                                  # W/(m^2 K), the order the issue estimates


@pytest.fixture(scope="module")
def heat_rig(tmp_path_factory):
    folder = tmp_path_factory.mktemp("heatfit")
    (folder / "rig.toml").write_text(HEAT_RIG)
    return folder


def _heat_trace(folder, seed: int, noise_bar: float) -> str:
    from fit_helpers import simulate_truth, write_trace
    name = f"hold-{seed}.csv"
    write_trace(folder / name, simulate_truth(folder / "rig.toml", {H_PATH: H_TRUE}), noise_bar, seed)
    return name


def test_fit_recovers_h_within_its_interval_in_at_least_17_of_20_seeds(heat_rig):
    # a hip charged for 0.3 s and held 1.2 s: its pressure sags as the air cools; sampled at 1 kHz
    # (as the fit rig of tests/test_fit.py), sensor noise 0.02 bar (seeds 0..19), h free between 1
    # and 200 W/(m^2 K), started at 50
    from fit_helpers import spec
    from frogsim.fit import fit
    bounds = {H_PATH: {"min": "1 W/(m^2*K)", "max": "200 W/(m^2*K)", "start": "50 W/(m^2*K)"}}
    covered, errors = 0, []
    for seed in range(20):
        res = fit(spec(heat_rig, [_heat_trace(heat_rig, seed, 0.02)], bounds, noise="0.02 bar", starts=1))
        lo, hi = res.ci_low[0], res.ci_high[0]
        covered += int(lo <= H_TRUE <= hi)
        errors.append(res.values[0] / H_TRUE - 1.0)
    print(f"h: 95 % intervals cover the truth in {covered} of 20 seeds; relative errors "
          f"{np.min(errors):+.2%} .. {np.max(errors):+.2%}")
    assert covered >= 17
    assert np.max(np.abs(errors)) < 0.1


def test_a_parameter_set_extends_only_a_shipped_one(tmp_path):
    from frogsim.errors import ScenarioError
    from frogsim.scenario.load import load_parameter_set
    heat_set, base = load_parameter_set("fan2017-heat"), load_parameter_set("fan2017")
    assert heat_set["muscle_types"]["hip"]["heat_transfer_coefficient"]["value"] == "20 W/(m^2*K)"
    assert heat_set["source"]["volume"] == base["source"]["volume"]          # the rest is fan2017's
    (tmp_path / "mine.toml").write_text('[meta]\nextends = "fan2099"\n')
    with pytest.raises(ScenarioError, match="meta.extends"):
        load_parameter_set("mine.toml", str(tmp_path))


def test_a_source_started_away_from_ambient_relaxes_closed_with_its_time_constant():
    # source.initial_temperature: the source's air starts at 250 K (wall and ambient 293.15 K), the
    # valves held shut; a closed rigid volume relaxes with tau = m c_v/(h A), m = p0 V/(R T0) from
    # the stated start, its pressure p = m R T/V; the exhaust, not given one, starts at ambient
    h_s, A_s, T0 = 10.0, 0.05, 250.0
    d = heat(one_muscle_scenario(steps((0.0, "hold"),), 6.0, solver={"rtol": 1e-10}, output_interval="20 ms",
                                 source={"volume": "0.5 L", "initial_temperature": f"{T0!r} K"}),
             h_source=h_s, h_exhaust=10.0, source_area=A_s)
    res = run(d)
    p0 = P_SOURCE0
    m = p0 * 5e-4 / (R_AIR * T0)
    tau = m * CV / (h_s * A_s)
    T_closed = T_AMB + (T0 - T_AMB) * np.exp(-res.t / tau)
    np.testing.assert_allclose(res.temperature("source"), T_closed, rtol=1e-6)
    np.testing.assert_allclose(res.source_pressure, m * R_AIR * T_closed / 5e-4, rtol=1e-6)
    assert res.temperature("source")[-1] - T0 > 0.4 * (T_AMB - T0)          # the run saw it relax
    np.testing.assert_allclose(res.temperature("exhaust"), T_AMB, rtol=1e-9)  # at ambient, stays there
    # and the setting is checked as every temperature is: absolute, above 0 K
    from frogsim.errors import ScenarioError
    d["source"]["initial_temperature"] = "-5 K"
    with pytest.raises(ScenarioError, match="source.initial_temperature"):
        frogsim.load_scenario(d)


def test_the_batched_runners_pass_heat_as_the_single_run_does():
    # a batch of variants (frogsim.engine.batch: sweeps, warm-up, direct run_models calls) runs the
    # model's parts without assembling a model: each point's heat switch must come with them. Points
    # with heat only in the source, only in the muscle, and none, against one-by-one runs
    from frogsim.engine.batch import ModelBatch, build_models, run_models, run_outputs
    sc = frogsim.load_scenario(one_muscle_scenario(steps((0.0, "charge"), (0.3, "hold")), 1.0, output_interval="10 ms"))
    hs, hm = "source.heat_transfer_coefficient", "muscle_types.hip.heat_transfer_coefficient"
    points = [{hs: 10.0, hm: 0.0}, {hs: 0.0, hm: 20.0}, {hs: 0.0, hm: 0.0}]
    single = [frogsim.simulate(sc.replace(p)) for p in points]
    batch = build_models(sc, points)
    assert isinstance(batch, ModelBatch)          # the points set the same paths: one batch
    for r, s in zip(run_models(batch), single):
        np.testing.assert_array_equal(r.y, s.y)
    (rows, out), = run_outputs(batch, columns=((L.Y_PS, L.pressure_index(0)), ()))[0]
    for j, s in zip(rows, single):
        np.testing.assert_array_equal(out.state(L.Y_PS)[j], s.source_pressure)
        np.testing.assert_array_equal(out.state(L.pressure_index(0))[j], s.muscle_pressure("m0"))
    # and heat did change the runs: the held hip sags with h in the muscle, the source with h in it
    assert single[1].muscle_pressure("m0")[-1] < single[2].muscle_pressure("m0")[-1] - 1e4
    assert single[0].source_pressure[-1] > single[2].source_pressure[-1] + 100.0   # 137 Pa: 4 L, 10 W/(m^2 K)
