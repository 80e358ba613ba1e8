"""The stiffness switch of the one stepping driver (frogsim.engine.integrator).

A muscle that rests against the source (charge valve open) or the exhaust (discharge valve open)
relaxes with a time constant of about 2 ms (Jacobian eigenvalue about -500 1/s at the paper's valve);
Dormand-Prince is then held to its stability limit, h |lambda| <= 3.3, whatever the tolerance. The
driver detects that (Hairer's test) and takes L-stable Rosenbrock steps (Shampine and Reichelt's
ode23s triple) until the next command. Checked here against physics and against the same run at a
much tighter tolerance, not against the code's own earlier output.
"""
from __future__ import annotations

import numpy as np
import pytest

import frogsim

HIP = {"name": "hip", "parameters": "fan2017", "duration": "2 s", "output_interval": "1 ms",
       "programs": {"stroke": {"pressurise": "1 s", "release": "1 s"}},
       "muscles": {"hip": {"type": "hip", "program": "stroke",
                           "motion": {"kind": "stroke", "delay": "0.1 s", "rise": "0.3 s", "fall": "0.3 s"}}}}


def test_resting_stretches_switch_to_rosenbrock_and_keep_the_tolerance():
    sc = frogsim.load_scenario(HIP)
    r = frogsim.simulate(sc)
    ref = frogsim.simulate(sc.replace({"solver.rtol": 1e-12}))
    n_stiff = r.stats["stiff_steps"]
    assert n_stiff > 0
    # the explicit method alone would need a step per ~6 ms of rest (stability: 3.3 / 500 1/s);
    # rest covers 0.6..1.0 s and 1.6..2.0 s: at least 130 steps; with the switch far fewer
    assert r.stats["steps"] < 130, r.stats
    p, p_ref = r.muscle_pressure("hip"), ref.muscle_pressure("hip")
    rtol = sc.solver.rtol
    for a, b in ((0.8, 1.0), (1.6, 2.0)):          # the muscle resting: Rosenbrock steps
        m = (r.t >= a) & (r.t <= b)
        err = np.max(np.abs(p[m] - p_ref[m]) / p_ref[m])
        # each accepted step's local error is within rtol (plus atol); over the run's stiff steps
        # the global error cannot exceed their sum
        assert err <= n_stiff * rtol, (a, b, err)


def test_at_rest_the_muscle_sits_at_the_pressure_it_is_open_to():
    # equilibrium of Eq. (8): no flow through an open valve when both sides have one pressure
    r = frogsim.simulate(frogsim.load_scenario(HIP))
    i_charge = int(np.searchsorted(r.t, 0.999))            # charge valve open, motion over
    assert r.muscle_pressure("hip")[i_charge] == pytest.approx(r.source_pressure[i_charge], rel=1e-6)
    assert r.muscle_pressure("hip")[-1] == pytest.approx(r.exhaust_pressure[-1], rel=1e-6)
    m = r.total_air_mass
    m = m() if callable(m) else m
    assert abs(m[-1] - m[0]) <= 1e-12 * m[0]               # air conserved across the switches


def test_a_valve_command_after_a_stiff_stretch_is_integrated_explicitly_and_accurately():
    # the vent at 1 s starts a transient (choked outflow) right after the Rosenbrock stretch; the
    # vented pressure at 1.2 s must match the tight-tolerance run to the explicit method's tolerance
    sc = frogsim.load_scenario(HIP)
    r = frogsim.simulate(sc)
    ref = frogsim.simulate(sc.replace({"solver.rtol": 1e-12}))
    i = int(np.searchsorted(r.t, 1.2))
    assert r.muscle_pressure("hip")[i] == pytest.approx(ref.muscle_pressure("hip")[i], rel=1e-5)
