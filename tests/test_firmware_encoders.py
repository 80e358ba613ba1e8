"""Joint angles from quadrature encoders: the six joints' angles no longer need analog inputs, so
twelve pressures and six angles fit the Mega 2560 (16 analog inputs).

Expected values: the encoder's count as docs/control.md defines it, floor(angle x cpr / 2 pi) +
32768, worked out here; the x2 decoding rule (an edge of A counts up when A equals B after it)
applied to pins driven on the emulated chip (simavr's external interrupts, not frogsim's
arithmetic); the board's pin map (INT4 on D2, INT5 on D3, INT3..INT0 on D18..D21)."""
from __future__ import annotations

import json
import math
import struct
from pathlib import Path

import numpy as np
import pytest
from avr_tools import need_avr_tools

import frogsim
from frogsim.cli import main
from frogsim.control import fixed
from frogsim.control import firmware as fwm
from frogsim.control.signals import adc_count
from frogsim.errors import ScenarioError
from frogsim.scenario.load import merged_raw


def _board(cycles=1, **firmware):
    raw, base = merged_raw("swim-board")
    raw = {**raw, "base_dir": base, "firmware": {**raw["firmware"], **firmware}}
    return frogsim.load_robot_scenario(raw, cycles=cycles)


@pytest.mark.parametrize("angle_deg", [0.0, 0.01, 10.0, 20.5, -3.0, 37.0, 89.9])
def test_the_encoder_count_is_the_angle_in_counts_from_32768(angle_deg):
    rs = _board()
    (v0, k, q0), full = fixed.angle_line(rs.pneumatic)
    th = math.radians(angle_deg)
    cpr = rs.pneumatic.firmware.angle_encoder.counts_per_revolution      # the scenario's encoder
    want = math.floor(th * cpr / (2 * math.pi)) + 32768
    assert full == 65536
    assert adc_count(v0, k, q0, float(full), rs.pneumatic.firmware.vref, th) == want


def test_twelve_pressures_and_six_encoders_fit_the_board():
    plan = fwm.firmware_plan(_board())
    analog = [ch for ch in plan.channels if not ch.pins]
    enc = [ch for ch in plan.channels if ch.pins]
    assert len(analog) == 12 and sorted(ch.analog_input for ch in analog) == list(range(12))
    assert len(enc) == 6 and sorted(ch.pins[0] for ch in enc) == [2, 3, 18, 19, 20, 21]
    cpr = _board().pneumatic.firmware.angle_encoder.counts_per_revolution
    assert all(ch.start_count == 32768 and ch.unit_per_count == pytest.approx(2 * math.pi / cpr) for ch in enc)
    assert len({p for ch in enc for p in ch.pins}) == 12          # twelve distinct pins


@pytest.mark.parametrize("firmware, field", [
    ({"angle_encoder": None}, "firmware"),                                    # 18 analog signals
    ({"angle_inputs": {"hip_left": 12}}, "firmware.angle_inputs"),            # analog angle with encoders
    ({"encoder_pins": {"hip_left": [22, 53]}}, "firmware.encoder_pins.hip_left"),   # A not an INT pin
    ({"encoder_pins": {"hip_left": [2, 22]}}, "firmware.encoder_pins.hip_left"),    # B on a valve pin
    ({"encoder_pins": {"nose": [2, 50]}}, "firmware.encoder_pins.nose"),      # not a joint read here
    ({"angle_encoder": {"counts_per_revolution": 8}}, "firmware.angle_encoder.counts_per_revolution"),
])
def test_bad_encoder_wiring_is_refused_in_one_line(firmware, field):
    raw, base = merged_raw("swim-board")
    fw = {**raw["firmware"], **firmware}
    if firmware.get("angle_encoder", 0) is None:
        del fw["angle_encoder"]
    with pytest.raises(ScenarioError) as err:
        frogsim.load_robot_scenario({**raw, "base_dir": base, "firmware": fw}, cycles=1)
    assert str(err.value).startswith(field), str(err.value)


def test_the_emulated_chip_counts_the_edges_as_x2_decoding_says(tmp_path):
    """Drive encoder 0 (A on D2 = INT4, B on D53) up 7 counts and encoder 5 (A on D21 = INT0, B on
    D48) down 4, each edge with B set first as a quadrature signal has it: the firmware's
    counters read 32775 and 32764."""
    need_avr_tools()
    from frogsim.export import board, sketch
    from frogsim.export.emulator import EmulatedBoard, symbol_address
    plan = fwm.firmware_plan(_board())
    sketch.write_sketch(plan, tmp_path, "swim-board")
    built = sketch.build_sketch(tmp_path, plan.name)
    pins = board.pin_map()
    b = EmulatedBoard(built.elf)
    busy = b.watch(pins[13])
    assert b.run_until_pin(busy, 1, 10_000_000)             # the firmware has set its interrupts up
    for a, bp, steps, d in ((2, 53, 7, 1), (21, 48, 4, -1)):
        c = 32768
        for _ in range(steps):
            c += d
            level = c & 1
            b.set_pin(pins[bp], level if d > 0 else 1 - level)
            b.set_pin(pins[a], level)
            b.run_until(b.cycle + 400)
    counts = struct.unpack("<6H", b.read_ram(symbol_address(built.elf, "fs_enc"), 12))
    b.close()
    assert counts == (32775, 32768, 32768, 32768, 32768, 32764)


@pytest.mark.slow
def test_swim_board_on_the_board_reads_the_encoders_as_the_model(tmp_path):
    """One gait cycle of swim-board in SIL: every count the firmware read on time (twelve
    pressures, six encoder counters fed edge by edge) is the plant's, and every decision is the
    integer twin's on those counts."""
    need_avr_tools()
    out = tmp_path / "fw"
    assert main(["firmware", "swim-board", "--cycles", "1", "--out", str(out), "--build", "--allow-overrun",
                 "--quiet"]) == 0
    assert main(["sil", "swim-board", "--cycles", "1", "--firmware", str(out), "--out", str(tmp_path / "sil"),
                 "--no-animation", "--quiet"]) == 0
    s = json.loads((tmp_path / "sil" / "summary.json").read_text())["sil"]
    assert s["mismatched_samples"] == 0 and s["adc_read_differs_samples"] == 0
    rec = json.loads((out / "firmware.json").read_text())
    assert [ch["pins"][0] for ch in rec["channels"] if "pins" in ch] == [2, 3, 18, 19, 20, 21]
    assert np.isfinite(s["awake_percent"])


# --- the angle loop at a lower rate than the pressure relays ----------------------------------------
@pytest.mark.parametrize("rate, ok", [("250 Hz", True), ("500 Hz", True), ("1 kHz", True), ("300 Hz", False),
                                      ("2 kHz", False), ("333 Hz", False)])
def test_an_angle_rate_must_divide_the_controller_rate(rate, ok):
    """1 kHz over a whole number N (1, 2, 4: accepted); 300 Hz (3.33), 333 Hz (3.003) and 2 kHz
    (faster than the samples) refused in one line naming the setting, its value and rates that
    work."""
    raw, base = merged_raw("swim-board")
    ctls = {n: {**c, "angle_rate": rate} for n, c in raw["controllers"].items()}
    fw = {k: v for k, v in raw["firmware"].items() if k != "velocity_window"}   # the window: the loop's period
    raw = {**raw, "base_dir": base, "controllers": ctls, "firmware": fw}
    if ok:
        rs = frogsim.load_robot_scenario(raw, cycles=1)
        assert all(c.angle_every(1000.0) == round(1000.0 / float(rate.split()[0]) / (1000.0 if "k" in rate else 1.0))
                   for c in rs.pneumatic.controllers.values())
        return
    with pytest.raises(ScenarioError) as exc:
        frogsim.load_robot_scenario(raw, cycles=1)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("controllers.hip_left.angle_rate = ") and rate.split()[0] in msg, msg
    assert "divided by a whole number" in msg and "Hz" in msg.split("(e.g. ")[1], msg


def test_a_velocity_window_longer_than_the_loops_period_is_refused():
    """swim-board's loops run every 4 samples: a window of 4 is accepted, 5 refused (one line)."""
    _board(velocity_window=4)
    with pytest.raises(ScenarioError) as exc:
        _board(velocity_window=5)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("firmware.velocity_window = 5") and "(4 samples" in msg, msg


@pytest.mark.parametrize("every, phase", [(1, 0), (4, 0), (4, 1), (4, 3), (6, 5), (3, 2)])
def test_the_angle_loop_runs_at_its_phase_and_every_n_samples_after(every, phase):
    """The schedule (both twins' angle_loop_due) against its definition: the loop runs at the
    sample indices phase, phase + N, phase + 2N, ... counted from the first sample."""
    from frogsim.control.kinds.joint_angle import angle_loop_due
    left, runs = 0, []
    for k in range(40):
        due, left = angle_loop_due(float(every), float(phase), left)
        if due:
            runs.append(k)
    assert runs == list(range(phase, 40, every))


def test_six_joints_share_the_samples_of_their_loops_evenly():
    """swim-board: six joints at N = 4 take phases 0, 1, 2, 3, 0, 1 in the scenario's order."""
    from frogsim.control.kinds.joint_angle import angle_schedule
    sc = _board().pneumatic
    assert [angle_schedule(sc, n) for n in sc.controllers] == [(4, 0), (4, 1), (4, 2), (4, 3), (4, 0), (4, 1)]


def test_the_float_laws_targets_change_only_where_the_loop_runs():
    """On the robot without [firmware] (the float law), with the loops at 250 Hz: each muscle's
    pressure target (its controller memory's B_TARGET, read after each sample of the compiled
    sample function, the joint angle made to wander) changes only at the samples its loop runs."""
    import dataclasses

    import numpy as np

    from frogsim.control.sampled import start_controllers, sample_controllers
    from frogsim.control.signals import B_ANGLE, B_TARGET, CS_BLOCK, CS_SIZE
    from frogsim.engine.coupled import build_coupled
    rs = _board()
    rs = dataclasses.replace(rs, pneumatic=dataclasses.replace(rs.pneumatic, firmware=None))
    cm = build_coupled(rs)
    a = cm.arrays
    laws, mp = a["laws"].copy(), a["mp"]
    y = np.array(cm.pneumatic.y0, float)
    u = np.zeros(2 * len(cm.muscle_names) + 1)
    dt = 1e-3
    cs = start_controllers(laws, mp, 0.0, y, u, dt)
    block = int(cs[CS_BLOCK])
    from frogsim.control.table import L_A_EVERY, L_A_PHASE, L_KIND
    from frogsim.control.kinds import joint_angle
    rows = [c for c in range(laws.shape[0]) if laws[c, L_KIND] == joint_angle.CODE]
    rng = np.random.default_rng(0)
    targets = {c: [] for c in rows}
    for k in range(1, 41):
        for c in rows:                      # the joint wanders: the loop's output moves when it runs
            cs[CS_SIZE + c * block + B_ANGLE] = 0.2 + 0.05 * rng.standard_normal()
        sample_controllers(laws, mp, k * dt, y, u, cs)
        for c in rows:
            targets[c].append(cs[CS_SIZE + c * block + B_TARGET])
    for c in rows:
        n, ph = int(laws[c, L_A_EVERY]), int(laws[c, L_A_PHASE])
        t = np.array(targets[c])
        moved = {k + 1 for k in range(1, len(t)) if t[k] != t[k - 1]}
        assert moved and all((k - ph) % n == 0 for k in moved), (c, n, ph, sorted(moved))


@pytest.mark.slow
def test_swim_board_with_the_board_in_its_own_process_is_the_same_run(tmp_path):
    """With encoders the plant runs a period ahead of the board, and swim-board's 2 ms valve dead
    time covers one more: the board runs a frame behind in a process of its own (sil's default)
    and gives the plant the same writes at the same times: the same run as in one process."""
    from frogsim.export import sil, sketch
    need_avr_tools()
    rs = _board()
    plan = fwm.firmware_plan(rs)
    sketch.write_sketch(plan, tmp_path, rs.name)
    built = sketch.build_sketch(tmp_path, plan.name)
    rec = sketch.read_plan_record(tmp_path)
    assert sil.pipeline_depth(rec, rs.pneumatic.valves.charge.dead_time) == 1
    runs = [sil.run_robot(rs, rec, built.elf, plan, fwm.adc_counts, compare=False, parallel=p) for p in (True, False)]
    a, b = runs
    assert a.sil["board_process"] and not b.sil["board_process"]
    assert np.array_equal(a.result.rec, b.result.rec)

    def same(s):
        return {k: v for k, v in s.items()
                if not k.endswith("wall_s") and k not in ("real_time_factor", "board_process", "plant_waited_s")}
    assert same(a.sil) == same(b.sil) and a.serial == b.serial
    assert a.sil["mismatched_samples"] == 0 and a.sil["samples"] == 2000     # 2 s of 1 ms periods
