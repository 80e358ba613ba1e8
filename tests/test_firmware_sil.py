"""The firmware path with a hand-written plan (tests/fw_stub.py: a bang-bang law in C on ADC
counts): the sketch builds for the ATmega2560, runs on the emulated board in lockstep with the
plant, counts overruns when its conversions cannot fit the period, and its serial log is read back
through a pseudo-terminal by `frogsim log` into the same CSV SIL writes.

Expected values come from the datasheet's arithmetic (Timer1 CTC frequency, 13 ADC clocks a
conversion) and from the C law re-implemented here on the logged counts, not from the runtime's
own output."""
from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from avr_tools import need_avr_tools
from fw_stub import bang_bang_plan, count_of

import frogsim
from frogsim.circuit import layout as L
from frogsim.circuit.model import build_model
from frogsim.export import board, sil, sketch
from frogsim.export.serial_log import log_table, parse_log, write_log_csv

SCENARIO = Path(__file__).with_name("firmware") / "bang-bang.toml"


@pytest.mark.parametrize("rate", [1000.0, 500.0, 100.0, 50.0, 2000.0, 10.0])
def test_timer1_runs_at_the_controller_rate(rate):
    """F_CPU / (N (1 + OCR1A)) is the rate exactly (datasheet Sec. 17.9.2), OCR1A within 16 bits."""
    n, _, ocr = sketch.timer1_setting(int(round(16e6 / rate)))
    assert 0 <= ocr <= 65535
    assert 16e6 / (n * (1 + ocr)) == pytest.approx(rate, rel=1e-12)


def test_timer1_refuses_a_period_it_cannot_make():
    with pytest.raises(ValueError, match="Timer1"):
        sketch.timer1_setting(16_000_001)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    need_avr_tools()
    out = tmp_path_factory.mktemp("fw")
    plan = bang_bang_plan()
    files = sketch.write_sketch(plan, out, "fw-bang-bang")
    return plan, out, files, sketch.build_sketch(out, plan.name)


def _counts(plan, model, y, qpos):
    patm = model.g[L.G_PATM]
    return [count_of(y[L.pressure_index(0)] - patm)] * len(plan.channels)


def test_the_sketch_is_an_arduino_folder_and_builds_for_the_atmega2560(built):
    plan, out, files, b = built
    assert files["ino"] == out / "stub" / "stub.ino"
    text = files["ino"].read_text()
    assert "ISR(TIMER1_COMPA_vect)" in text and "frogsim_sample" in text
    assert (out / "stub" / "frogsim_laws.h").read_text() == plan.c_source
    assert b.architecture == "avr6"
    assert 0 < b.flash_bytes < board.FLASH_BYTES - board.BOOTLOADER_BYTES
    assert 0 < b.ram_bytes < board.SRAM_BYTES
    rec = sketch.read_plan_record(out)
    assert rec["period_cycles"] == 16000 and rec["channels"][0]["analog_input"] == 0


@pytest.fixture(scope="module")
def sil_run(built):
    plan, out, _, b = built
    rec = sketch.read_plan_record(out)
    model = build_model(frogsim.load_scenario(SCENARIO))
    return model, rec, sil.run_pneumatic(model, rec, b.elf, plan, _counts)


def test_sil_runs_the_machine_code_in_lockstep(sil_run):
    model, rec, run = sil_run
    s = run.sil
    assert s["samples"] == 601                      # 0.6 s at 1 kHz: samples 0..600
    assert s["overruns"] == 0 and s["both_valves_open_samples"] == 0
    # one conversion: at least 13 ADC clocks of 128 CPU cycles (the first 25) of the 16000
    assert s["cpu_load_percent"]["max"] >= 100 * 25 * 128 / 16000
    assert 100 * 13 * 128 / 16000 <= s["cpu_load_percent"]["mean"] < 50
    # the logged valve bits are the C law on the logged counts (re-implemented here)
    log = parse_log(run.serial, rec)
    assert log.header.startswith("# frogsim stub rate=1000")
    ks = [r[0] for r in log.records if r[0] <= 600]
    assert ks == list(range(0, 601, 10))
    low, high = count_of(2.9e5), count_of(3.1e5)
    for k, c, bits, *_ in log.records:
        want = 1 if c < low else (2 if c > high else 0)
        assert bits == want, (k, c, bits)
    # and the plant holds the pressure in the law's band after the rise (counts 0.0122 bar each,
    # plus what one period and the valve's dead time add)
    r = run.result
    p = (r.muscle_pressure("hip") - model.g[L.G_PATM]) / 1e5
    late = p[r.t >= 0.3]
    assert late.min() > 2.7 and late.max() < 3.3


def test_a_plan_that_cannot_fit_its_period_overruns(built, tmp_path):
    """Ten conversions at prescaler 128 take 10 x 13 x 128 = 16640 cycles, more than the 16000 of a
    1 ms period (plan_adc would pick a faster ADC clock): exported anyway, the firmware counts
    overruns."""
    assert 10 * board.conversion_time(128) > 1e-3
    plan = bang_bang_plan(channels=10, prescaler=128)
    sketch.write_sketch(plan, tmp_path, "fw-bang-bang")
    b = sketch.build_sketch(tmp_path, plan.name)
    rec = sketch.read_plan_record(tmp_path)
    sc = frogsim.load_scenario(SCENARIO).replace({"duration": 0.1, "controllers.hold.settle": 0.05})
    run = sil.run_pneumatic(build_model(sc), rec, b.elf, plan, _counts)
    assert run.sil["overruns"] > 0
    assert run.sil["cpu_load_percent"]["max"] > 100.0


# --- the board in a process of its own ----------------------------------------------------------
def _same_run(a, b) -> None:
    """Two SIL runs are the same: the plant's record, the summary (but where the wall time went),
    the serial bytes."""
    def same(s):
        return {k: v for k, v in s.items()
                if not k.endswith("wall_s") and k not in ("real_time_factor", "board_process", "plant_waited_s")}
    assert np.array_equal(a.result.y, b.result.y) and np.array_equal(a.result.t, b.result.t)
    assert same(a.sil) == same(b.sil)
    assert a.serial == b.serial


def test_the_board_in_its_own_process_gives_the_same_run(built):
    """The valves' 2 ms dead time covers two 1 ms periods, so the board may run a frame behind
    the plant in a process of its own (what sil does by default): the plant gets the same writes
    at the same times, and the run is the same as in one process."""
    plan, out, _, b = built
    rec = sketch.read_plan_record(out)
    sc = frogsim.load_scenario(SCENARIO).replace({"duration": 0.2, "controllers.hold.settle": 0.1})
    assert sil.pipeline_depth(rec, 2e-3) == 2 and sil.pipeline_depth(rec, 0.999e-3) == 0
    runs = [sil.run_pneumatic(build_model(sc), rec, b.elf, plan, _counts, compare=False, parallel=p)
            for p in (True, False)]
    assert runs[0].sil["board_process"] and not runs[1].sil["board_process"]
    assert runs[0].sil["samples"] == 201
    _same_run(*runs)


def test_a_board_process_that_fails_is_reported_not_waited_for(built, monkeypatch):
    """An error in the board's process reaches the plant as the same error; a board process that
    dies (here: exits at its tenth frame) is reported with its exit code; neither hangs."""
    plan, out, _, b = built
    rec = sketch.read_plan_record(out)
    sc = frogsim.load_scenario(SCENARIO).replace({"duration": 0.05, "controllers.hold.settle": 0.02})
    frame = sil.BoardRun.frame

    def failing(self, *args, **kwargs):
        if self.frames == 10:
            raise frogsim.errors.SimulationError("the board failed at its tenth frame")
        return frame(self, *args, **kwargs)
    monkeypatch.setattr(sil.BoardRun, "frame", failing)
    with pytest.raises(frogsim.errors.SimulationError, match="failed at its tenth frame"):
        sil.run_pneumatic(build_model(sc), rec, b.elf, plan, _counts, compare=False, parallel=True)

    def dying(self, *args, **kwargs):
        if self.frames == 10:
            os._exit(3)
        return frame(self, *args, **kwargs)
    monkeypatch.setattr(sil.BoardRun, "frame", dying)
    with pytest.raises(frogsim.errors.SimulationError, match=r"process ended unexpectedly \(exit code 3\)"):
        sil.run_pneumatic(build_model(sc), rec, b.elf, plan, _counts, compare=False, parallel=True)


def test_the_board_process_is_refused_where_the_dead_time_does_not_cover_its_period(built):
    plan, out, _, b = built
    rec = sketch.read_plan_record(out)
    sc = frogsim.load_scenario(SCENARIO).replace({"duration": 0.05, "controllers.hold.settle": 0.02, "valves.charge.dead_time": 0.5e-3,
                                                  "valves.discharge.dead_time": 0.5e-3})
    with pytest.raises(frogsim.errors.SimulationError, match="dead time"):
        sil.run_pneumatic(build_model(sc), rec, b.elf, plan, _counts, compare=False, parallel=True)
    run = sil.run_pneumatic(build_model(sc), rec, b.elf, plan, _counts, compare=False)   # auto: one process
    assert not run.sil["board_process"]


def _log_through_pty(data: bytes, argv: list, out: Path) -> int:
    """Run `frogsim log` on one end of a pseudo-terminal while ``data`` is written into the other,
    from the moment the port is open (pyserial empties the input buffer when it opens a port: bytes
    written before would be lost, as a board's before the reader starts; on a loaded machine the
    reader may take a while to start)."""
    import tty

    import serial
    from frogsim.cli import main
    master, slave = os.openpty()
    tty.setraw(slave)
    port = os.ttyname(slave)
    opened = threading.Event()
    real = serial.Serial

    class Opened(real):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            opened.set()

    def feed():
        if not opened.wait(60.0):
            return
        for k in range(0, len(data), 64):
            os.write(master, data[k:k + 64])
            time.sleep(0.002)
    th = threading.Thread(target=feed)
    th.start()
    serial.Serial = Opened
    try:
        return main(["log", "--port", port, *argv, "--duration", "2.5", "--out", str(out), "--quiet"])
    finally:
        serial.Serial = real
        opened.set()
        th.join()
        os.close(master)
        os.close(slave)


def test_log_reads_the_boards_bytes_through_a_pseudo_terminal(sil_run, built, tmp_path):
    """The bytes the emulated board sent, written into a pty, read by `frogsim log` (pyserial on
    the other end): the same CSV as SIL's serial.csv."""
    model, rec, run = sil_run
    _, out, _, _ = built
    write_log_csv(tmp_path / "sil.csv", parse_log(run.serial, rec), rec)
    assert _log_through_pty(run.serial, ["--firmware", str(out)], tmp_path / "log") == 0
    assert (tmp_path / "log" / "serial.csv").read_text() == (tmp_path / "sil.csv").read_text()


def test_log_without_the_firmware_folder_writes_raw_counts(sil_run, tmp_path):
    import pandas as pd
    _, rec, run = sil_run
    assert _log_through_pty(run.serial, [], tmp_path / "log") == 0
    df = pd.read_csv(tmp_path / "log" / "serial.csv")
    assert list(df.columns) == ["time [s]", "hip pressure [count]", "hip charge valve [1 = open]",
                                "hip discharge valve [1 = open]"]
    records = parse_log(run.serial, rec).records
    assert df["hip pressure [count]"].tolist() == [r[1] for r in records]
    assert df["time [s]"].tolist() == pytest.approx([r[0] / 1000 for r in records])


def test_log_table_units_and_scaling(sil_run):
    """Counts become bar gauge with the channel's scale; a 3 bar pressure reads within one count."""
    _, rec, _ = sil_run
    from frogsim.export.serial_log import Log
    c = count_of(3e5)
    df = log_table(Log(records=[(0, c, 1, 0, 0, 0), (10, c, 2, 0, 0, 0)]), rec)
    assert list(df.columns) == ["time [s]", "hip pressure [bar gauge]", "hip charge valve [1 = open]",
                                "hip discharge valve [1 = open]"]
    assert df["time [s]"].tolist() == [0.0, 0.01]
    assert abs(df["hip pressure [bar gauge]"][0] - 3.0) <= 5 / 1024 / 0.4
    assert df["hip charge valve [1 = open]"].tolist() == [1, 0]
    assert df["hip discharge valve [1 = open]"].tolist() == [0, 1]


def test_sil_refuses_a_folder_without_firmware(tmp_path, capsys):
    from frogsim.cli import main
    code = main(["sil", str(SCENARIO), "--firmware", str(tmp_path), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and "firmware.json" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_log_refuses_a_port_it_cannot_open_and_writes_nothing(tmp_path, capsys):
    from frogsim.cli import main
    code = main(["log", "--port", str(tmp_path / "no-such-port"), "--duration", "1", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and err.startswith("frogsim: error: --port")
    assert not (tmp_path / "o").exists()
