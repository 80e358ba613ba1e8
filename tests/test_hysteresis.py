"""Force hysteresis of the muscle (Maxwell-slip on the contraction, frogsim.physics.hysteresis), as the
engines and the force-table fit use it, against closed forms and the energy balance.

* a loop closes and repeats; its area in the (length, tension) plane equals the work the slipping
  elements dissipate (sum of f_j |da_j|) and the closed form sum_j 4 f_j (X - w_j): the static law
  is conservative and adds nothing to the area;
* a minor loop returns to the major loop where it left it (return-point memory);
* the loop does not depend on the rate (how finely the same path is sampled) in the model, nor on
  the cycling frequency in the coupled engine beyond what the dynamics change;
* off (the default): the coupled engine's tensions are the static law's, bit for bit, computed
  again from the recorded pressures and lengths; on, they are the static law less the slip force
  replayed over the recorded path;
* force tables: a direction column (loading / unloading) is read and checked, and the fit recovers
  the slip parameters of a loop made with known ones and noise.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import frogsim
from frogsim.errors import ScenarioError
from frogsim.physics.hysteresis import (element_table, loop_area, maxwell_slip_force,
                                        muscle_hysteresis_force, settle_on_major_loop, slip_work)
from frogsim.physics.muscle import braid_parameters
from frogsim.physics.muscle_force import MODEL_DMSP20, hysteretic_tension, muscle_force
from frogsim.scenario.load import merged_raw

BAR = 1e5
L0 = 0.18
B0, NT = braid_parameters(L0, 0.020, math.radians(25.3))
BLADDER = (141.6, 0.02155, 552.9, 6302.0, 229100.0)          # fan2017 [muscle_force]
C_SLIP = 10.0 / BAR        # 10 N/bar: half the loop's height per gauge pressure [N/Pa]
S_SLIP = 0.01              # the widest element's width (1 % contraction)
K, F = element_table(4, C_SLIP, S_SLIP)


def static(p, eps):
    return muscle_force(MODEL_DMSP20, p, L0 * (1.0 - eps), L0, B0, NT, *BLADDER)


def run(p, path, anchors):
    """Tensions along a contraction path at gauge pressure p, and the slip work [J] (per unit
    contraction x L0: the work in the length coordinate)."""
    T, work = [], 0.0
    for eps in path:
        before = anchors.copy()
        T.append(hysteretic_tension(static(p, eps), p, eps, anchors, K, F))
        work += slip_work(before, anchors, p * F) * L0
    return np.array(T), work


def cycle(lo, hi, n=2001):
    up = np.linspace(lo, hi, n)
    return np.concatenate([up, up[::-1][1:]])


def test_element_table_splits_the_slip_force_and_widens_the_elements_evenly():
    widths = F / K
    np.testing.assert_allclose(widths, S_SLIP * np.array([1, 2, 3, 4]) / 4, rtol=1e-14)
    assert F.sum() == pytest.approx(C_SLIP, rel=1e-14)
    # fully slid, the elements give the loop's half height c p_g
    a = np.zeros(4)
    assert muscle_hysteresis_force(6 * BAR, 0.05, a, K, F) == pytest.approx(C_SLIP * 6 * BAR, rel=1e-12)
    assert muscle_hysteresis_force(6 * BAR, -0.05, a, K, F) == pytest.approx(-C_SLIP * 6 * BAR, rel=1e-12)


def test_loop_closes_and_its_area_is_the_slip_work_and_the_closed_form():
    p, lo, hi = 4 * BAR, 0.04, 0.10
    a = np.full(4, 0.07)
    run(p, cycle(lo, hi), a)                           # settle onto the loop
    path = cycle(lo, hi)
    T, work = run(p, path, a)
    assert T[-1] == pytest.approx(T[0], abs=1e-9)     # closes
    T2, _ = run(p, path, a.copy())
    np.testing.assert_allclose(T2, T, atol=1e-9)       # and repeats
    L = L0 * (1.0 - path)
    area = abs(np.trapezoid(T, L))                     # work the muscle takes in over the cycle
    X = (hi - lo) / 2                                  # swing about the middle, in contraction
    closed = loop_area(K * p, F * p, X) * L0           # sum_j 4 f_j (X - w_j), in the length coordinate
    assert closed == pytest.approx(sum(4 * f * p * (X - f / k) for k, f in zip(K, F)) * L0, rel=1e-12)
    assert work == pytest.approx(closed, rel=1e-9)
    assert area == pytest.approx(work, rel=2e-3)
    # the loop's height where every element slides: 2 c p_g, shortening below stretching
    mid = np.searchsorted(path[:2001], 0.07)         # 2 s away from both turning points
    up, down = T[mid], T[len(path) - 1 - mid]
    assert down - up == pytest.approx(2 * C_SLIP * p, rel=1e-9)


def test_minor_loop_returns_to_the_major_loop_where_it_left_it():
    p, lo, hi, x1, x2 = 5 * BAR, 0.02, 0.12, 0.08, 0.065
    a = np.full(4, 0.07)
    run(p, cycle(lo, hi), a)
    up_to_x1 = np.linspace(lo, x1, 600)
    onward = np.linspace(x1, hi, 400)[1:]
    T_major, _ = run(p, np.concatenate([up_to_x1, onward]), a.copy())
    a1 = a.copy()
    T_left, _ = run(p, up_to_x1, a1)
    T_minor, _ = run(p, np.concatenate([np.linspace(x1, x2, 300), np.linspace(x2, x1, 300)[1:]]), a1)
    assert T_minor[-1] == pytest.approx(T_left[-1], abs=1e-9)
    assert T_minor.min() < T_left[-1] - 1.0 or T_minor.max() > T_left[-1] + 1.0   # a real minor loop
    T_after, _ = run(p, onward, a1)
    np.testing.assert_allclose(T_after, T_major[600:], atol=1e-9)


def test_the_loop_does_not_depend_on_the_rate_or_the_step():
    p, lo, hi = 3 * BAR, 0.03, 0.09
    coarse = cycle(lo, hi, 11)
    fine = cycle(lo, hi, 1001)
    T_c, w_c = run(p, coarse, np.full(4, 0.06))
    T_f, w_f = run(p, fine, np.full(4, 0.06))
    np.testing.assert_allclose(T_f[::100], T_c, atol=1e-9)
    assert w_f == pytest.approx(w_c, rel=1e-12)


def test_zero_pressure_or_zero_slip_force_gives_the_static_law_exactly():
    a = np.zeros(4)
    for eps in cycle(0.0, 0.1, 51):
        s = static(3 * BAR, eps)
        assert hysteretic_tension(s, 0.0, eps, a, K, F) == s
        assert hysteretic_tension(s, 3 * BAR, eps, a, K * 0.0, F * 0.0) == s


def test_settled_branches_are_the_loop_the_path_traces():
    lo, hi = 0.03, 0.11
    a = np.full(4, 0.07)
    for x in cycle(lo, hi, 201):
        maxwell_slip_force(x, a, K, F)
    # the path has just come down to lo: the rising branch starts here
    b = np.zeros(4)
    settle_on_major_loop(b, lo, hi, K, F, True)
    np.testing.assert_allclose(b, a, atol=1e-15)


# --- the coupled engine ----------------------------------------------------------------------------
def hip_run(hysteresis: dict | None, frequency="2 Hz", period="1 s"):
    """The left hip tracking a sine in air (hip-angle-in-air), every MuJoCo step recorded."""
    raw, base = merged_raw("hip-angle-in-air")
    ctl = dict(raw["controllers"]["hip"],
               setpoint={"kind": "sine", "mean": "20 deg", "amplitude": "8 deg", "frequency": frequency,
                         "start": "0.3 s"}, settle="0.3 s")
    law = dict(raw["muscle_force"], **(hysteresis or {}))
    raw = {**raw, "base_dir": base, "output_interval": "1 ms", "gait": {**raw["gait"], "period": period},
           "controllers": {"hip": ctl}, "muscle_force": law}
    rs = frogsim.load_robot_scenario(raw)
    return rs, frogsim.swim(rs)


ON = {"hysteresis": "maxwell-slip", "slip_per_pressure": "10 N/bar", "slip_strain": "1 %"}


@pytest.fixture(scope="module")
def runs():
    return {"off": hip_run(None), "on": hip_run(ON)}


def static_tensions(rs, r, i):
    """The static law at muscle i's recorded pressures and lengths (the kernel's inputs)."""
    from frogsim.circuit import layout as CL
    from frogsim.circuit.model import build_model
    law = rs.robot.muscle_force
    mp = build_model(rs.pneumatic).mp[i]
    bl = (law.force_scale, law.strain_scale, law.stiffness, law.stretch_stiffness, law.stretch_quadratic)
    patm = r.atmospheric_pressure
    from frogsim.circuit.actuators.mckibben import P_B0, P_N
    return np.array([muscle_force(MODEL_DMSP20, float(p) - patm, float(L), mp[CL.M_L0], mp[CL.M_AP + P_B0],
                                  mp[CL.M_AP + P_N], *bl)
                     for p, L in zip(r.pressures[:, i], r.lengths[:, i])]), mp[CL.M_L0]


def test_off_the_tensions_are_the_static_law_bit_for_bit(runs):
    rs, r = runs["off"]
    assert rs.robot.muscle_force.hysteresis == "none"          # the default: fan2017 unchanged
    for i in range(len(r.muscle_names)):
        expect, _ = static_tensions(rs, r, i)
        assert np.array_equal(expect, r.tensions[:, i])


def test_on_the_tensions_are_the_static_law_less_the_slip_force_replayed_over_the_path(runs):
    rs, r = runs["on"]
    assert not np.array_equal(r.tensions, runs["off"][1].tensions)
    patm = r.atmospheric_pressure
    moved = 0
    for name in ("hip_left", "hip_left_recovery"):
        i = r.muscle_names.index(name)
        st, l0 = static_tensions(rs, r, i)
        eps = 1.0 - r.lengths[:, i] / l0
        a = np.full(K.size, eps[0])                 # the muscle starts relaxed
        replay = np.array([hysteretic_tension(s, float(p) - patm, float(e), a, K, F)
                           for s, p, e in zip(st, r.pressures[:, i], eps)])
        np.testing.assert_allclose(r.tensions[:, i], replay, rtol=0, atol=1e-9)
        gap = st - r.tensions[:, i]
        moved += int(np.sum(np.abs(gap) > 0.5 * C_SLIP * (r.pressures[:, i] - patm)))
    assert moved > 100                              # the elements slid: the loop is there


def test_hysteresis_settings_are_checked_in_one_line():
    raw, base = merged_raw("hip-angle-in-air")
    for key, value in (("hysteresis", "coulomb"), ("slip_strain", "0 %"), ("slip_elements", 0),
                       ("slip_per_pressure", "-1 N/bar")):
        bad = {**raw, "base_dir": base, "muscle_force": {**raw["muscle_force"], key: value}}
        with pytest.raises(ScenarioError) as e:
            frogsim.load_robot_scenario(bad)
        assert f"muscle_force.{key}" in str(e.value) and "\n" not in str(e.value)


# --- force tables with a direction ---------------------------------------------------------------
TRUE_SLIP = {"slip_per_pressure": 8.0 / BAR, "slip_strain": 0.015}     # chosen by the test
SLIP_BOUNDS = {"muscle_force.slip_per_pressure": {"min": "0 N/bar", "max": "40 N/bar", "start": "15 N/bar"},
               "muscle_force.slip_strain": {"min": "0.2 %", "max": "5 %", "start": "0.5 %"}}


def loop_rows(lo=0.02, hi=0.14, n=25):
    """A measured-loop stand-in: at 2, 4, 6 bar the contraction swept lo -> hi -> lo twice, the
    second sweep written down, each point with its branch; forces from the physics module's law
    and elements followed along the path (not from the fit's branch model)."""
    k, f = element_table(4, TRUE_SLIP["slip_per_pressure"], TRUE_SLIP["slip_strain"])
    rows = []
    up = np.linspace(lo, hi, n)
    for bar in (2, 4, 6):
        p = bar * BAR
        a = np.full(4, lo)
        for sweep in range(2):
            for eps, d in [(e, "unloading") for e in up] + [(e, "loading") for e in up[::-1][1:]]:
                t = hysteretic_tension(static(p, eps), p, float(eps), a, k, f)
                if sweep == 1:
                    rows.append((bar, float(eps), t, d))
    return rows


def write_loop(path, rows, noise_n=0.0, seed=0):
    import pandas as pd
    rng = np.random.default_rng(seed)
    bar, eps, force, d = zip(*rows)
    force = np.array(force) + rng.normal(0.0, noise_n, len(force)) * (noise_n > 0)
    pd.DataFrame({"pressure [bar gauge]": bar, "contraction [%]": np.array(eps) * 100, "force [N]": force,
                  "direction": d}).to_csv(path, index=False, float_format="%.12g")
    return path


@pytest.fixture(scope="module")
def rig_dir(tmp_path_factory):
    from fit_helpers import write_rig
    folder = tmp_path_factory.mktemp("loop")
    write_rig(folder)
    return folder


def loop_spec(folder, table, noise="5 N", **extra):
    return {"base_dir": str(folder), "scenario": "rig.toml",
            "force_tables": [{"table": table, "muscle": "hip", "noise": noise}], "parameters": SLIP_BOUNDS, **extra}


def test_fit_recovers_the_slip_parameters_from_a_loop(rig_dir):
    from frogsim.fit import fit
    write_loop(rig_dir / "loop.csv", loop_rows())
    res = fit(loop_spec(rig_dir, "loop.csv", starts=2))
    truth = np.array([TRUE_SLIP["slip_per_pressure"], TRUE_SLIP["slip_strain"]])
    assert np.all(np.abs(res.values - truth) / truth < 1e-4), res.values
    write_loop(rig_dir / "loop-noisy.csv", loop_rows(), noise_n=5.0, seed=3)
    res = fit(loop_spec(rig_dir, "loop-noisy.csv", starts=1))
    assert np.all((res.ci_low <= truth) & (truth <= res.ci_high)), (res.ci_low, res.values, res.ci_high)


def test_without_a_direction_the_table_is_the_static_law_and_the_slip_cannot_be_fitted(rig_dir):
    from frogsim.fit import fit
    import pandas as pd
    rows = loop_rows()
    write_loop(rig_dir / "nodir.csv", rows)
    df = pd.read_csv(rig_dir / "nodir.csv").drop(columns=["direction"])
    df.to_csv(rig_dir / "nodir.csv", index=False)
    res = fit(loop_spec(rig_dir, "nodir.csv", starts=1))
    assert any("no effect" in w for w in res.warnings)


@pytest.mark.parametrize("value", ["up", "", "1"])
def test_a_bad_direction_is_refused_naming_file_column_and_row(rig_dir, value):
    import frogsim
    from frogsim.fit.force import read_force_table
    (rig_dir / "bad.csv").write_text("pressure [bar gauge],contraction [%],force [N],direction\n"
                                     f"4,5,800,loading\n4,6,780,{value}\n")
    with pytest.raises(ScenarioError) as e:
        read_force_table(rig_dir / "bad.csv", frogsim.load_scenario(rig_dir / "rig.toml"))
    msg = str(e.value)
    assert "bad.csv" in msg and "direction" in msg and "row 2" in msg and "\n" not in msg


# --- the pneumatic engine: tensions as an output ---------------------------------------------------
def test_pneumatic_result_tensions_off_are_the_static_law_and_on_lag_the_motion():
    import dataclasses
    from frogsim.circuit import layout as CL
    from frogsim.robot.params import parameter_set_law
    r = frogsim.simulate("paper-cycle")
    law = parameter_set_law(r.model.scenario)
    assert law.hysteresis == "none"
    T = r.tensions()
    patm = r.atmospheric_pressure
    mp = r.model.mp
    bl = (law.force_scale, law.strain_scale, law.stiffness, law.stretch_stiffness, law.stretch_quadratic)
    i = 0
    from frogsim.circuit.actuators.mckibben import P_B0, P_N
    expect = [muscle_force(MODEL_DMSP20, float(p) - patm, float(L), mp[i, CL.M_L0], mp[i, CL.M_AP + P_B0],
                           mp[i, CL.M_AP + P_N], *bl) for p, L in zip(r.muscle_pressure(r.names[i]), r.lengths[:, i])]
    assert np.array_equal(np.array(expect), T[:, i])
    on = dataclasses.replace(law, hysteresis="maxwell-slip", slip_per_pressure=C_SLIP, slip_strain=S_SLIP)
    T_on = r.tensions(on)
    shortening = 0
    for i, name in enumerate(r.names):
        p = r.muscle_pressure(name) - patm
        gap = T[:, i] - T_on[:, i]
        pulling = (T_on[:, i] > 0) & (T[:, i] > 0)
        assert np.all(np.abs(gap[pulling]) <= C_SLIP * p[pulling] * (1 + 1e-12) + 1e-9)
        eps = 1.0 - r.lengths[:, i] / mp[i, CL.M_L0]
        d = np.diff(eps, prepend=eps[0])
        # after a contraction change of 2 s in one direction every element slides: F_h = +-c p_g
        run_up = np.convolve(d > 0, np.ones(5), "same") == 5
        slid = pulling & run_up & (p > 1 * BAR)
        assert np.all(gap[slid] > 0)          # shortening: the muscle pulls less than the static law
        shortening += int(slid.sum())
    assert shortening > 100


def test_the_pneumatic_tensions_follow_turning_points_between_output_samples():
    """A hip muscle (valves as in the fit rig: charged 0.25 s, vented 0.25 s) moved along a zigzag
    table whose reversals (monotone cubic: dL/dt = 0 there) fall between the 10 ms output samples:
    the elements must still see each reversal. Reference: the anchors replayed along the exact
    motion sampled every 10 us (rate independence: a dense enough sampling is the path), the
    tension at each output point the static one less the slip force there."""
    import dataclasses
    import tomllib
    from fit_helpers import RIG
    from frogsim.circuit import layout as CL
    from frogsim.circuit.rhs import length_turning_times, motion_length
    from frogsim.robot.params import parameter_set_law
    raw = tomllib.loads(RIG.replace("MOTION", "constant").replace('"1 ms"', '"10 ms"'))
    raw["muscles"]["hip"]["motion"] = {
        "kind": "table", "time_s": [0, 0.0437, 0.1013, 0.1571, 0.2129, 0.2683, 0.3241, 0.3797, 0.4353, 0.5],
        "contraction_percent": [2, 9, 3, 10, 4, 11, 2, 8, 3, 6]}
    r = frogsim.simulate(frogsim.load_scenario(raw))
    law = dataclasses.replace(parameter_set_law(r.model.scenario), hysteresis="maxwell-slip",
                              slip_per_pressure=C_SLIP, slip_strain=S_SLIP / 4)
    T_on, T_off = r.tensions(law), r.tensions()
    k, f = element_table(law.slip_elements, law.slip_per_pressure, law.slip_strain)
    m = r.model
    motion = (m.mot_t, m.mot_L, m.mot_d, m.mot_n)
    turns = length_turning_times(0, *motion)
    assert np.sum(np.min(np.abs(turns[:, None] - r.t[None, :]), axis=1) > 1e-4) >= 8    # off the grid
    L0 = m.mp[0, CL.M_L0]
    p = r.muscle_pressure("hip") - r.atmospheric_pressure
    a = np.full(k.size, 1.0 - r.lengths[0, 0] / L0)
    expect = np.empty(r.t.size)
    for j in range(r.t.size):
        if j > 0:
            for tt in np.arange(r.t[j - 1], r.t[j], 1e-5)[1:]:
                maxwell_slip_force(1.0 - motion_length(float(tt), 0, *motion)[0] / L0, a, k, f)
        expect[j] = hysteretic_tension(T_off[j, 0], float(p[j]), 1.0 - r.lengths[j, 0] / L0, a, k, f)
    # the replay's own error: a reversal falls up to 10 us from a sample of it
    np.testing.assert_allclose(T_on[:, 0], expect, rtol=0, atol=0.02 * C_SLIP * BAR)


def test_the_pneumatic_engines_loop_does_not_change_with_the_cycling_rate():
    """A sealed hip muscle (3 bar gauge at the start, valves shut) cycled between 2 and 10 %
    contraction twice, once in 1 s and once in 4 s: its air is adiabatic, so its pressure is the
    same function of the length at both rates (to the solver's tolerance), and the slip elements
    are rate independent: the second cycle's hysteresis force at the same contraction on the same
    branch, and the loop's area, are the same."""
    import dataclasses
    from frogsim.circuit import layout as CL
    from frogsim.robot.params import parameter_set_law

    def cycle_loop(T):
        sc = frogsim.load_scenario({
            "name": "sealed", "parameters": "fan2017", "duration": f"{4 * T:g} s", "output_interval": "1 ms",
            "programs": {"hold": {"steps": [{"at": "0 s", "state": "hold"}]}},
            "muscles": {"hip": {"type": "hip", "initial_pressure_gauge": "3 bar", "program": "hold",
                                "motion": {"kind": "table", "time_s": [0, T, 2 * T, 3 * T, 4 * T],
                                           "contraction_percent": [2, 10, 2, 10, 2]}}}})
        r = frogsim.simulate(sc)
        law = dataclasses.replace(parameter_set_law(sc), hysteresis="maxwell-slip")
        on, off = r.tensions(law)[:, 0], r.tensions()[:, 0]
        eps = 1.0 - r.lengths[:, 0] / r.model.mp[0, CL.M_L0]
        t = r.t
        up = (t >= 2 * T) & (t <= 3 * T)
        down = (t >= 3 * T) & (t <= 4 * T)
        grid = np.linspace(0.021, 0.099, 157)
        f_up = np.interp(grid, eps[up], (off - on)[up])
        f_down = np.interp(grid, eps[down][::-1], (off - on)[down][::-1])
        last = t >= 2 * T
        area = abs(np.trapezoid(on[last], r.lengths[last, 0]))
        # linear interpolation across an element's kink (slope change <= its stiffness k_j p_g)
        # errs by at most k_j p_g h / 4 for samples h apart in contraction
        k, _ = element_table(law.slip_elements, law.slip_per_pressure, law.slip_strain)
        p_max = float(np.max(r.muscle_pressure("hip"))) - r.atmospheric_pressure
        kink = k.max() * p_max * float(np.max(np.abs(np.diff(eps[last])))) / 4
        return f_up, f_down, area, kink

    fast, slow = cycle_loop(0.25), cycle_loop(1.0)
    tol = fast[3] + slow[3] + 0.01                    # interpolation, plus the solver's pressures
    np.testing.assert_allclose(fast[0], slow[0], atol=tol)
    np.testing.assert_allclose(fast[1], slow[1], atol=tol)
    assert np.max(fast[0] - fast[1]) > 40.0            # a loop: shortening minus stretching, ~2 c p_g
    assert fast[2] == pytest.approx(slow[2], rel=2e-3)


def test_the_studys_loop_width_and_area_are_the_ellipses_closed_forms():
    """Angle lagging a sine setpoint by phi: th = m + A sin(wt - phi) against sp = m + A sin(wt)
    crosses the mean at m -+ A sin(phi) (width 2 A sin(phi)) and encloses pi A^2 sin(phi)."""
    from frogsim.studies.hysteresis import setpoint_loop
    A, m, phi = 8.0, 20.0, 0.3
    t = np.linspace(0.0, 3.0, 3001)
    sp = m + A * np.sin(2 * np.pi * t)
    th = m + A * np.sin(2 * np.pi * t - phi)
    out = setpoint_loop(t, sp, th, 1.0)
    assert out["loop_width_deg"] == pytest.approx(2 * A * np.sin(phi), rel=1e-4)
    assert out["loop_area_deg2"] == pytest.approx(np.pi * A * A * np.sin(phi), rel=1e-4)


def test_a_pneumatic_scenarios_own_force_law_settings_are_used_and_kept_by_variants():
    # [muscle_force] in a pneumatic scenario lies over its parameter set's (tensions, force-table
    # fits); a variant keeps it (it has no typed field to live in)
    from frogsim.robot.params import parameter_set_law
    from fit_helpers import RIG, STROKE
    import tomllib
    raw = tomllib.loads(RIG.replace("MOTION", STROKE))
    plain = frogsim.load_scenario(raw)
    assert parameter_set_law(plain).hysteresis == "none"             # fan2017's
    own = frogsim.load_scenario({**raw, "muscle_force": {"hysteresis": "maxwell-slip", "slip_strain": "0.1 %"}})
    law = parameter_set_law(own)
    assert law.hysteresis == "maxwell-slip" and law.slip_strain == pytest.approx(1e-3)
    assert law.force_scale == parameter_set_law(plain).force_scale   # the rest is the set's
    variant = own.replace({"duration": 0.2})
    assert parameter_set_law(variant) == law
    assert parameter_set_law(plain.replace({"duration": 0.2})).hysteresis == "none"
