"""Sensor faults on the robot's board: a reading outside a transducer's line (a dead or
disconnected sensor reads about 0 V, below the 0.5 V live zero) puts the muscles whose laws read
it in their safe state until enough good samples have come, in the firmware's C and in the
model's integer twin alike.

Expected values come from the rule as docs/control.md states it, re-implemented here, from the
transducer's line (0.5-4.5 V over 0-10 bar gauge on a 10-bit ADC at 5 V: the fault limits of a
0.2 V margin are the counts floor(0.3 x 1024 / 5) = 61 and floor(4.7 x 1024 / 5) = 962), and from
physics: a muscle whose valves are both shut keeps its pressure, one vented empties to the
exhaust."""
from __future__ import annotations

import ctypes
import json
from pathlib import Path

import numpy as np
import pytest
from avr_tools import need_avr_tools
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import frogsim
from frogsim.cli import main
from frogsim.control import firmware as fwm
from frogsim.control.signals import fw_fault

SHIPPED = Path(frogsim.__file__).with_name("scenarios")
LO, HI = 61, 962          # the default fault limits of the default transducer (module docstring)


def _hold(tmp_path: Path, extra: str = "", margin: str = "0.2 V") -> Path:
    """hold-3bar with ``extra`` lines added to its [firmware] section and the transducer's fault
    margin ``margin``."""
    text = (SHIPPED / "hold-3bar.toml").read_text()
    old = 'high_pressure_gauge = "10 bar" }'
    assert old in text
    text = text.replace(old, f'high_pressure_gauge = "10 bar", fault_margin = "{margin}" }}')
    text = text.rstrip() + "\n" + extra + "\n"
    path = tmp_path / "hold.toml"
    path.write_text(text)
    return path


def test_the_fault_rule_counts_good_samples_before_the_law_resumes():
    """A bad count faults at once; after it, ``resume`` good samples are still in fault; the next
    one is not."""
    mem = np.zeros(1)
    seq = [500, 10, 500, 500, 500, 500, 2000, 500, 500, 500, 500]
    got = [bool(fw_fault(c, LO, HI, mem, 0, 3)) for c in seq]
    assert got == [False, True, True, True, True, False, True, True, True, True, False]


def test_the_plan_carries_the_transducers_fault_limits(tmp_path):
    plan = fwm.firmware_plan(frogsim.build_model(frogsim.load_scenario(_hold(tmp_path))))
    assert plan.laws[0].faults[:2] == (LO, HI)
    assert plan.fault_mode == -1 and plan.fault_resume == 10
    plan = fwm.firmware_plan(frogsim.build_model(frogsim.load_scenario(_hold(
        tmp_path, 'fault = "hold"\nfault_resume = 3', margin="0.4 V"))))
    # floor(0.1 x 1024 / 5) = 20, floor(4.9 x 1024 / 5) = 1003
    assert plan.laws[0].faults[:2] == (20, 1003) and plan.fault_mode == 0 and plan.fault_resume == 3


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(counts=st.lists(st.one_of(st.integers(0, 1023), st.integers(0, 70), st.integers(950, 1023)),
                       min_size=1, max_size=80))
def test_the_c_and_the_twin_fault_alike_and_as_the_rule_says(tmp_path_factory, counts):
    """frogsim_sample compiled for this machine against firmware_modes and the rule written here:
    the same modes, the C's fault bits where the rule says, the safe state (vent) while in fault."""
    tmp = tmp_path_factory.mktemp("f")
    plan = fwm.firmware_plan(frogsim.build_model(frogsim.load_scenario(_hold(tmp, "fault_resume = 4"))))
    lib = fwm.host_library(plan)
    lib.frogsim_faults.restype = ctypes.c_uint32
    lib.frogsim_reset()
    mem = fwm.firmware_memory(plan)
    left = 0
    for k, c in enumerate(counts):
        adc = (ctypes.c_uint16 * 1)(c)
        modes = (ctypes.c_int8 * 1)()
        lib.frogsim_sample(k, adc, modes)
        twin = fwm.firmware_modes(plan, k, [c], mem)
        # the rule (docs/control.md)
        if c < LO or c > HI:
            left, fault = 4, True
        elif left > 0:
            left, fault = left - 1, True
        else:
            fault = False
        assert modes[0] == twin[0], (k, c)
        assert bool(lib.frogsim_faults() & 1) == fault, (k, c)
        if fault:
            assert modes[0] == -1


def test_a_dead_hip_sensor_vents_the_muscle_instead_of_charging_it(tmp_path):
    """hold-3bar with its transducer dead (0 V) from 1 s: the law would read -1.25 bar and
    charge to the source's 6 bar; instead the muscle vents: it ends near the exhaust's pressure
    and never rises above the band it held. With fault = "hold" both valves stay shut and the
    pressure stays where it was at 1 s (a closed muscle of constant volume)."""
    from frogsim.circuit import layout as L
    sc = frogsim.load_scenario(_hold(tmp_path, 'sensor_faults = [ { signal = "hip pressure", at = "1 s", '
                                               'voltage = "0 V" } ]'))
    r = frogsim.simulate(sc)
    p = (r.muscle_pressure("hip") - r.model.g[L.G_PATM]) / 1e5
    late = p[r.t >= 1.0]
    assert late.max() < 3.0 + 0.05 + 0.02          # never above the band's top (sp + band / 2, a count's step)
    assert p[-1] < 0.1                             # emptied to the exhaust (near the atmosphere)
    held = frogsim.simulate(frogsim.load_scenario(_hold(tmp_path, 'fault = "hold"\nsensor_faults = [ { signal = '
                                                                  '"hip pressure", at = "1 s", voltage = "0 V" } ]')))
    ph = (held.muscle_pressure("hip") - held.model.g[L.G_PATM]) / 1e5
    at1 = ph[np.searchsorted(held.t, 1.0 + 0.01)]
    assert abs(ph[-1] - at1) < 0.01 and 2.9 < at1 < 3.1


def test_a_dead_hip_sensor_on_the_board(tmp_path):
    """The same on the emulated ATmega2560: the firmware vents as the model does (0 mismatched
    samples), its log's fault bit is set from 1 s on, and the muscle never charges."""
    need_avr_tools()
    path = _hold(tmp_path, 'sensor_faults = [ { signal = "hip pressure", at = "1 s", voltage = "0 V" } ]')
    assert main(["firmware", str(path), "--out", str(tmp_path / "fw"), "--build", "--quiet"]) == 0
    assert main(["sil", str(path), "--firmware", str(tmp_path / "fw"), "--out", str(tmp_path / "sil"),
                 "--quiet"]) == 0
    s = json.loads((tmp_path / "sil" / "summary.json").read_text())
    assert s["sil"]["mismatched_samples"] == 0 and s["sil"]["samples_off_the_on_time_model"] == 0
    import pandas as pd
    ts = pd.read_csv(tmp_path / "sil" / "timeseries.csv")
    p = ts[[c for c in ts.columns if c.startswith("hip pressure")][0]]
    assert p[ts["time [s]"] >= 1.0].max() < 3.07 and p.iloc[-1] < 0.1
    # the log's records (one each 10 samples) carry the fault bit from the first at or after 1 s
    faults = s["sil"]["log_records"]["faults"]
    assert faults["hip pressure"]["first_sample"] == 1000
    assert faults["hip pressure"]["records"] == len(range(1000, 2001, 10))
    assert any("fault" in w for w in s["sil"]["warnings"])


def test_a_dead_sensor_on_one_muscle_of_the_swimming_robot_on_the_board(tmp_path):
    """swim-board with hip_left's transducer dead from 1 s, one gait cycle in SIL: the firmware
    decides as the integer twin on the counts it read (the hip's two laws, which share one run of
    the joint's loop while both run, part there), logs the fault, and hip_left vents instead of
    charging towards the source pressure (6 bar gauge at the start)."""
    need_avr_tools()
    text = (SHIPPED / "swim-board.toml").read_text()
    assert text.rstrip().splitlines()[-1].startswith("velocity_window")   # [firmware] is the file's last section
    path = tmp_path / "dead.toml"
    path.write_text(text.rstrip() + '\nsensor_faults = [ { signal = "hip_left pressure", at = "1 s", '
                                   'voltage = "0 V" } ]\n')
    fw, out = tmp_path / "fw", tmp_path / "sil"
    assert main(["firmware", str(path), "--cycles", "1", "--out", str(fw), "--build", "--quiet"]) == 0
    assert main(["sil", str(path), "--cycles", "1", "--firmware", str(fw), "--out", str(out), "--no-animation",
                 "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())["sil"]
    assert s["mismatched_samples"] == 0
    assert s["log_records"]["faults"]["hip_left pressure"]["records"] > 0
    import pandas as pd
    ts = pd.read_csv(out / "timeseries.csv")
    late = ts["time [s]"] >= 1.2
    p = ts["hip_left pressure [bar gauge]"][late]
    p_e = ts["exhaust pressure [bar gauge]"][late]
    p_s = ts["source pressure [bar gauge]"][late]
    # vented: its discharge valve open to the exhaust chamber, whose pressure it follows (the
    # robot's exhaust is a closed chamber the vents fill; the valve's conductance lets the
    # muscle, whose volume the moving joint changes, lag it by a fifth of a bar), far below the
    # source's (a dead sensor read as "far below the setpoint" would have charged it towards it)
    assert (ts["hip_left discharge valve [1 = open]"][late] == 1).all()
    assert (ts["hip_left charge valve [1 = open]"][late] == 0).all()
    assert (p - p_e).abs().max() < 0.2 and (p_s - p).min() > 1.5
