"""The one stepping driver (frogsim.engine.integrator.advance) and the sampled controllers it calls
(frogsim.control.sampled): the pump's band, where the driver stops, and a run advanced in many
calls (as the coupled engine does) against the same run in one call."""
from __future__ import annotations

import math

import numpy as np
import pytest

import frogsim
from frogsim.circuit import layout as L
from frogsim.control.sampled import (CS_PUMP, CS_SAMPLE, KIND_PUMP_BAND, L_HIGH, L_INPUT, L_KIND,
                                     L_LOW, next_control_time, pump_band, sample_controllers,
                                     sampled_laws, start_controllers)
from frogsim.engine.integrator import D_OUT, D_T, STATS_SIZE, STATUS_OK, advance, solver_group, start

BAR = 1e5


def test_pump_band_is_a_hysteresis_switch():
    low, high = 6.0 * BAR, 6.5 * BAR
    assert pump_band(5.9 * BAR, 0.0, low, high) == 1.0         # below the band: on
    assert pump_band(6.6 * BAR, 1.0, low, high) == 0.0         # above: off
    assert pump_band(6.2 * BAR, 1.0, low, high) == 1.0         # inside: keeps its state
    assert pump_band(6.2 * BAR, 0.0, low, high) == 0.0


def test_rule_table_and_samples():
    g = np.zeros(L.G_SIZE)
    mp = np.zeros((0, L.M_SIZE))                               # no muscle
    assert sampled_laws(g).size == 0                           # no pump: no sampled rule
    cs = start_controllers(sampled_laws(g), mp, 0.0035, np.zeros(5), np.zeros(0), 1e-3)
    assert next_control_time(sampled_laws(g), cs, 1e-3) == math.inf   # the driver never stops for it
    g[L.G_PUMP_ENABLED], g[L.G_PUMP_ON], g[L.G_PUMP_OFF] = 1.0, 6.0 * BAR, 6.5 * BAR
    row = sampled_laws(g)                                      # the open-loop form: one 1-D row
    assert row.ndim == 1 and row[L_KIND] == KIND_PUMP_BAND
    assert (row[L_INPUT], row[L_LOW], row[L_HIGH]) == (L.Y_PS, 6.0 * BAR, 6.5 * BAR)
    # the same band as a row of the closed-loop table must sample exactly alike
    for laws in (row, row.reshape(1, -1)):
        y = np.zeros(5)
        y[L.Y_PS] = 5.0 * BAR
        # a run starting at 3.5 ms takes the sample of 3 ms; the next is at 4 ms
        cs = start_controllers(laws, mp, 0.0035, y, np.zeros(0), 1e-3)
        assert cs[CS_SAMPLE] == 3.0 and cs[CS_PUMP] == 1.0
        assert next_control_time(laws, cs, 1e-3) == pytest.approx(4e-3, rel=1e-15)
        y[L.Y_PS] = 6.2 * BAR
        assert not sample_controllers(laws, mp, 4e-3, y, np.zeros(0), cs)   # inside the band: unchanged
        y[L.Y_PS] = 6.6 * BAR
        assert sample_controllers(laws, mp, 5e-3, y, np.zeros(0), cs)       # above: switched off
        assert cs[CS_SAMPLE] == 5.0 and cs[CS_PUMP] == 0.0


def test_a_run_advanced_in_many_calls_matches_one_call(paper_cycle_raw):
    # the coupled engine calls advance once per MuJoCo step; the pneumatic engine once per run.
    # With the pump's band active, 10 ms calls must give the same run: the same pump switchings
    # at the same samples, and the states within the solver's tolerance.
    d = paper_cycle_raw
    d["pump"] = {"enabled": True, "on_below_gauge": "5.5 bar", "off_above_gauge": "6 bar"}
    model = frogsim.build_model(frogsim.load_scenario(d))
    res = frogsim.simulate(model)
    sc = model.scenario
    commands = (model.sched_t, model.sched_u, sampled_laws(model.g), 1.0 / sc.controller.rate)
    y, u = model.y0.copy(), model.u0.copy()
    ds, cs = start(0.0, 1e-4, y, u, model.mp, commands)
    circuit = (model.g, model.mp, model.mot_t, model.mot_L, model.mot_d, model.mot_n)
    solver = solver_group(sc.solver, model.atol)
    no_output = (np.zeros(0), np.zeros((0, y.size)), np.zeros((0, u.size + 1)))
    stats = np.zeros(STATS_SIZE, np.int64)
    switched = 0
    for k in range(1, 201):
        t_end = k * 0.01
        assert advance(t_end, y, u, ds, cs, circuit, commands, solver, no_output, stats) == STATUS_OK
        assert ds[D_T] == t_end and ds[D_OUT] == 0
        row = int(round(t_end / sc.output_interval))
        assert res.t[row] == pytest.approx(t_end, abs=1e-12)
        assert np.array_equal(u, res.u[row, :u.size])
        assert cs[CS_PUMP] == res.u[row, u.size]
        switched += cs[CS_PUMP] != res.u[row - 10, u.size]
        scale = np.maximum(np.abs(res.y[row]), model.atol / sc.solver.rtol)
        assert np.max(np.abs(y - res.y[row]) / scale) < 1e-5
    assert switched > 0                                          # the pump did switch


def test_pausing_the_driver_changes_no_step(monkeypatch):
    """simulate() pauses the driver every STEPS_PER_CALL steps to read the clock: with a pause
    every step and every 7 steps (inside pieces and between them, pump band active, Rosenbrock
    stretches) the run is bit for bit the run of the batched engine, which never pauses."""
    import numpy as np

    import frogsim
    from frogsim.engine import pneumatic
    from frogsim.engine.batch import build_models, run_models
    sc = frogsim.load_scenario("paper-cycle").replace({"pump.enabled": True, "pump.displacement": 3e-4,
                                                       "duration": 3.0, "programs.stroke.cycles": 2})
    whole = run_models(build_models(sc, [{}]))[0]
    assert whole.stats["stiff_steps"] > 0          # pauses in and around Rosenbrock stretches too
    for every in (1, 7):                           # 1: a pause after every step and at every piece's end
        monkeypatch.setattr(pneumatic, "STEPS_PER_CALL", every)
        paused = frogsim.simulate(sc)
        assert paused.stats["rhs_evaluations"] > whole.stats["rhs_evaluations"]     # it did pause
        assert paused.stats["steps"] == whole.stats["steps"]
        assert np.array_equal(paused.y, whole.y) and np.array_equal(paused.u, whole.u)
        assert set(np.unique(paused.u[:, -1])) == {0.0, 1.0}                          # the pump switched


def test_open_loop_row_and_table_forms_give_the_same_run():
    """Open-loop runs pass the pump's band as a 1-D row (so the closed-loop laws are never
    compiled for them); the same band as a one-row table takes the general path: same run, bit
    for bit."""
    import frogsim
    from frogsim.engine.integrator import run_schedule
    sc = frogsim.load_scenario("paper-cycle").replace({"pump.enabled": True, "pump.displacement": 3e-4,
                                                       "duration": 3.0, "programs.stroke.cycles": 2})
    m = frogsim.build_model(sc)
    assert m.laws.ndim == 1
    runs = [run_schedule(m.y0, m.u0, 0.0, sc.duration, m.rhs_model,
                         (m.sched_t, m.sched_u, laws, 1.0 / sc.controller.rate), solver_group(sc.solver, m.atol),
                         m.out_t, 1e-4, 0) for laws in (m.laws, m.laws.reshape(1, -1))]
    assert np.array_equal(runs[0][0], runs[1][0]) and np.array_equal(runs[0][1], runs[1][1])
    assert set(np.unique(runs[0][1][:, -1])) == {0.0, 1.0}                   # the pump switched
