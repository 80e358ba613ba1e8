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
    want = math.floor(th * 2000 / (2 * math.pi)) + 32768
    assert full == 65536
    assert adc_count(v0, k, q0, float(full), rs.pneumatic.firmware.vref, th) == want


def test_twelve_pressures_and_six_encoders_fit_the_board():
    plan = fwm.firmware_plan(_board())
    analog = [ch for ch in plan.channels if not ch.pins]
    enc = [ch for ch in plan.channels if ch.pins]
    assert len(analog) == 12 and sorted(ch.analog_input for ch in analog) == list(range(12))
    assert len(enc) == 6 and sorted(ch.pins[0] for ch in enc) == [2, 3, 18, 19, 20, 21]
    assert all(ch.start_count == 32768 and ch.unit_per_count == pytest.approx(2 * math.pi / 2000) for ch in enc)
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
