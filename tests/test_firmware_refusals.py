"""The firmware path's refusals, each a CLI run: exit 2, one line on stderr naming the field (or
--firmware and the file) and the value, no traceback, no output folder.

`frogsim sil` refuses a firmware folder whose ELF is older than its sources, an ELF simavr cannot
run as the ATmega2560's (not an ELF, damaged, truncated, of another machine, of another AVR), a
firmware.json frogsim did not write, and a plan of another scenario, naming the likely cause.
`frogsim firmware` (and, for the scenario's own rules, `simulate`) refuses a controller rate
Timer1 cannot make exactly, a sensor span so narrow that the fixed point overflows, and a setpoint
or a band outside its sensor's range."""
from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
from pathlib import Path

import pytest
from avr_tools import need_avr_tools

import frogsim
from frogsim.cli import main
from frogsim.errors import ScenarioError
from frogsim.export import sketch

HERE = Path(__file__).with_name("firmware")
SHIPPED = Path(frogsim.__file__).with_name("scenarios")


def _run(capsys, *argv) -> tuple[int, str]:
    code = main([*map(str, argv)])
    return code, capsys.readouterr().err.strip()


def _refused(code: int, err: str, out: Path, *needles: str) -> None:
    assert code == 2, err
    assert len(err.splitlines()) == 1, err
    assert err.startswith("frogsim: error: ") and "Traceback" not in err, err
    assert not out.exists()
    for n in needles:
        assert n in err, (n, err)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """hold-3bar exported and built (each test works on a copy)."""
    need_avr_tools()
    fw = tmp_path_factory.mktemp("built") / "fw"
    assert main(["firmware", "hold-3bar", "--out", str(fw), "--build", "--quiet"]) == 0
    return fw


def _copy(built: Path, tmp_path: Path) -> tuple[Path, Path, str]:
    fw = tmp_path / "fw"
    shutil.copytree(built, fw)
    name = json.loads((fw / "firmware.json").read_text())["name"]
    return fw, fw / "build" / f"{name}.elf", name


# -- sil: the ELF -------------------------------------------------------------------------------------
def test_sil_refuses_an_elf_older_than_its_sources(built, tmp_path, capsys):
    fw, elf, name = _copy(built, tmp_path)
    t = elf.stat().st_mtime + 10
    os.utime(fw / name / "frogsim_laws.h", (t, t))
    code, err = _run(capsys, "sil", "hold-3bar", "--firmware", fw, "--out", tmp_path / "o")
    _refused(code, err, tmp_path / "o", "--firmware", f"build/{elf.name} is older", f"{name}/frogsim_laws.h",
             "rebuild it")


def _elf_328p(tmp_path: Path) -> bytes:
    """A program built for the ATmega328P (an Arduino Uno's: architecture avr5)."""
    src = tmp_path / "uno.c"
    src.write_text("int main(void) { return 0; }\n")
    subprocess.run(["avr-gcc", "-mmcu=atmega328p", "-Os", "-o", str(tmp_path / "uno.elf"), str(src)], check=True)
    return (tmp_path / "uno.elf").read_bytes()


def _other_machine(good: bytes) -> bytes:
    b = bytearray(good)
    b[18:20] = (3).to_bytes(2, "little")         # e_machine 3: Intel 80386
    return bytes(b)


def _sections(b: bytes) -> list[tuple[int, tuple]]:
    """(offset of the header, its ten fields) of each section."""
    shoff, = struct.unpack_from("<I", b, 32)
    shnum, = struct.unpack_from("<H", b, 48)
    return [(shoff + 40 * k, struct.unpack_from("<10I", b, shoff + 40 * k)) for k in range(shnum)]


def _section_name_outside(good: bytes) -> bytes:
    """Section 1's name far past the name table (libsimavr crashed on it: a segmentation fault)."""
    b = bytearray(good)
    struct.pack_into("<I", b, _sections(good)[1][0], 0x7fffff)
    return bytes(b)


def _symbol_table_entries_of_size_0(good: bytes) -> bytes:
    """libsimavr divides the symbol table's size by its entries' (a floating-point exception)."""
    b = bytearray(good)
    at = next(off for off, sh in _sections(good) if sh[1] == 2)
    struct.pack_into("<I", b, at + 36, 0)
    return bytes(b)


def _symbol_name_outside(good: bytes) -> bytes:
    """The last symbol's name far past its string table."""
    b = bytearray(good)
    sh = next(sh for _, sh in _sections(good) if sh[1] == 2)
    struct.pack_into("<I", b, sh[4] + sh[5] - 16, 0x7fffff)
    return bytes(b)


BAD_ELVES = {
    # case: (the ELF's bytes from the good one and tmp_path, text the message must hold)
    "text": (lambda good, tmp: b"not a firmware\n", "not an ELF file"),
    "random bytes": (lambda good, tmp: bytes(os.urandom(4096)).replace(b"\x7fELF", b"xELF"), "not an ELF file"),
    "empty": (lambda good, tmp: b"", "not an ELF file"),
    "a header only": (lambda good, tmp: good[:40], "damaged"),
    "truncated": (lambda good, tmp: good[:len(good) // 2], "truncated"),
    "the host's /bin/true": (lambda good, tmp: Path("/bin/true").read_bytes(), "not a 32-bit one"),
    "another machine": (lambda good, tmp: _other_machine(good), "another machine"),
    "a section's name outside its table": (lambda good, tmp: _section_name_outside(good), "section 1's name"),
    "symbol table entries of size 0": (lambda good, tmp: _symbol_table_entries_of_size_0(good), "symbol table"),
    "a symbol's name outside its table": (lambda good, tmp: _symbol_name_outside(good), "name lies outside"),
    "an ATmega328P's": (lambda good, tmp: _elf_328p(tmp), "avr5"),
}


@pytest.mark.parametrize("case", sorted(BAD_ELVES))
def test_sil_refuses_what_is_not_an_atmega2560_elf(built, tmp_path, capsys, case):
    """Checked before simavr loads it: /bin/true and a damaged section or symbol table made
    libsimavr crash (exit 139 or 136), a truncated ELF stopped avr-nm with a traceback."""
    fw, elf, _ = _copy(built, tmp_path)
    make, needle = BAD_ELVES[case]
    elf.write_bytes(make(elf.read_bytes(), tmp_path))
    code, err = _run(capsys, "sil", "hold-3bar", "--firmware", fw, "--out", tmp_path / "o")
    _refused(code, err, tmp_path / "o", "--firmware", f"build/{elf.name} ", needle)


def test_the_emulator_and_avr_nm_refuse_a_bad_elf_in_one_line(built, tmp_path):
    """Called directly (not through `frogsim sil`): the emulated board checks the ELF before simavr
    loads it; symbol_address turns avr-nm's failure into one line."""
    from frogsim.export.emulator import EmulatedBoard, check_avr_elf, symbol_address
    _, elf, _ = _copy(built, tmp_path)
    check_avr_elf(elf)                                    # the real one passes
    host = tmp_path / "true.elf"
    shutil.copy("/bin/true", host)
    with pytest.raises(ScenarioError, match="--firmware.*not a 32-bit one"):
        EmulatedBoard(host)
    cut = tmp_path / "cut.elf"
    cut.write_bytes(elf.read_bytes()[:3000])
    with pytest.raises(ScenarioError) as info:
        symbol_address(cut, "fs_overruns")
    assert "avr-nm" in str(info.value) and "\n" not in str(info.value)


# -- sil and log: firmware.json -------------------------------------------------------------------------
def _drop(*keys):
    def edit(rec):
        node = rec
        for k in keys[:-1]:
            node = node[k]
        del node[keys[-1]]
        return rec
    return edit


def _set(value, *keys):
    def edit(rec):
        node = rec
        for k in keys[:-1]:
            node = node[k]
        node[keys[-1]] = value
        return rec
    return edit


BAD_PLANS = {
    # case: (an edit of the record, the key the message names)
    "a channel's unit_per_count removed": (_drop("channels", 0, "unit_per_count"), "channels[0].unit_per_count"),
    "a channel's offset text": (_set("x", "channels", 0, "offset"), "channels[0].offset"),
    "a channel's analog input removed": (_drop("channels", 0, "analog_input"), "channels[0].analog_input"),
    "a channel's analog input A16": (_set(16, "channels", 0, "analog_input"), "channels[0].analog_input"),
    "a channel's pin D70": (lambda r: _set(70, "channels", 0, "pin")(_drop("channels", 0, "analog_input")(r)),
                            "channels[0].pin"),
    "rate_hz negative": (_set(-1000.0, "rate_hz"), "rate_hz"),
    "rate_hz NaN": (_set(float("nan"), "rate_hz"), "rate_hz"),
    "rate_hz text": (_set("fast", "rate_hz"), "rate_hz"),
    "period_cycles zero": (_set(0, "period_cycles"), "period_cycles"),
    "period_cycles fractional": (_set(16000.5, "period_cycles"), "period_cycles"),
    "muscles not names": (_set([1], "muscles"), "muscles"),
    "valve_pins not pairs": (_set([[22]], "valve_pins"), "valve_pins"),
    "valve_pins one pair too many": (_set([[22, 23], [24, 25]], "valve_pins"), "valve_pins"),
    "adc.bits 12": (_set(12, "adc", "bits"), "adc.bits"),
    "adc removed": (_drop("adc"), "adc"),
    "busy_pin text": (_set("13", "busy_pin"), "busy_pin"),
    "baud zero": (_set(0, "baud"), "baud"),
    "log_every zero": (_set(0, "log_every"), "log_every"),
    "plan_sha256 short": (_set("abc", "plan_sha256"), "plan_sha256"),
    "name not a C identifier": (_set("1x", "name"), "name"),
    "format 5": (_set(5, "format"), "format"),
    "not a table": (lambda r: [r], "not a JSON table"),
}


@pytest.mark.parametrize("case", sorted(BAD_PLANS))
def test_sil_refuses_a_firmware_json_frogsim_did_not_write(built, tmp_path, capsys, case):
    fw, _, _ = _copy(built, tmp_path)
    edit, key = BAD_PLANS[case]
    path = fw / "firmware.json"
    path.write_text(json.dumps(edit(json.loads(path.read_text()))))
    code, err = _run(capsys, "sil", "hold-3bar", "--firmware", fw, "--out", tmp_path / "o")
    _refused(code, err, tmp_path / "o", "--firmware", "firmware.json", key)


def test_log_refuses_a_firmware_json_frogsim_did_not_write(built, tmp_path, capsys):
    fw, _, _ = _copy(built, tmp_path)
    path = fw / "firmware.json"
    path.write_text(json.dumps(_drop("channels", 0, "offset")(json.loads(path.read_text()))))
    code, err = _run(capsys, "log", "--port", tmp_path / "no-port", "--firmware", fw, "--duration", "1",
                     "--out", tmp_path / "o")
    _refused(code, err, tmp_path / "o", "--firmware", "channels[0].offset")


def test_a_plan_record_may_carry_keys_of_a_later_format(built):
    """Unknown keys are allowed, format 2 is read (it adds a count range per channel)."""
    rec = json.loads((built / "firmware.json").read_text())
    rec["format"] = 2
    rec["channels"][0]["count_range"] = [0, 1023]
    rec["something_new"] = {"x": 1}
    sketch.validate_plan_record(rec, built)


# -- sil: a plan of another scenario ----------------------------------------------------------------------
def test_sil_names_an_edit_of_the_scenario(built, tmp_path, capsys):
    fw, _, _ = _copy(built, tmp_path)
    edited = tmp_path / "hold-3bar.toml"
    edited.write_text((SHIPPED / "hold-3bar.toml").read_text().replace('value = "3 bar"', 'value = "3.2 bar"'))
    code, err = _run(capsys, "sil", edited, "--firmware", fw, "--out", tmp_path / "o")
    _refused(code, err, tmp_path / "o", "--firmware", "before an edit", str(edited))


def test_sil_names_another_scenario(built, tmp_path, capsys):
    fw, _, _ = _copy(built, tmp_path)
    code, err = _run(capsys, "sil", HERE / "every-kind.toml", "--firmware", fw, "--out", tmp_path / "o")
    _refused(code, err, tmp_path / "o", "another scenario", "'hold-3bar'")


def test_sil_names_other_gait_cycles(tmp_path, capsys):
    """Exported with --cycles 1, run without: the message says so (it said "another scenario, or
    ... before an edit")."""
    need_avr_tools()
    fw = tmp_path / "fw"
    assert main(["firmware", "swim", "--cycles", "1", "--out", str(fw), "--build", "--quiet"]) == 0
    assert json.loads((fw / "firmware.json").read_text())["export"]["cycles"] == 1
    code, err = _run(capsys, "sil", "swim", "--firmware", fw, "--out", tmp_path / "o")
    _refused(code, err, tmp_path / "o", "--firmware", "1 gait cycle(s)", "--cycles 1")


# -- firmware (and simulate): the scenario --------------------------------------------------------------
def _hold(**replace) -> str:
    text = (SHIPPED / "hold-3bar.toml").read_text()
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new)
    return text


def _robot(section: str) -> str:
    return (HERE / "robot-every-kind.toml").read_text() + "\n[firmware]\n" + section + "\n"


RATE = 'rate = "1 kHz"'
LOG = 'log_rate = "100 Hz"'
SPAN = 'high_pressure_gauge = "10 bar"'
EXPORT_REFUSALS = {
    # case: (scenario text, field, texts the message holds)
    "3 kHz: 5333.33 cycles": (_hold(**{RATE: 'rate = "3 kHz"'}), "controller.rate",
                              ["'3 kHz'", "5333.33", "2.5 kHz", "3.2 kHz"]),
    "7 Hz": (_hold(**{RATE: 'rate = "7 Hz"', LOG: 'log_rate = "7 Hz"'}), "controller.rate",
             ["'7 Hz'", "whole number of CPU cycles", "8 Hz"]),
    "204.8 Hz: 78125 cycles, no prescaler": (_hold(**{RATE: 'rate = "204.8 Hz"', LOG: 'log_rate = "204.8 Hz"'}),
                                             "controller.rate", ["78125", "Timer1", "200 Hz"]),
    "a transducer span of 1e-9 bar": (_hold(**{SPAN: 'high_pressure_gauge = "1e-9 bar"'}),
                                      "firmware.transducer.high_pressure_gauge", ["1e-09 bar", "overflows"]),
    "an angle sensor span of 1e-9 deg": (_robot('angle_sensor = { low_angle = "0 deg", high_angle = "1e-9 deg" }'),
                                         "firmware.angle_sensor.high_angle", ["1e-09 deg", "overflows"]),
    "3 bar on a 0-2 bar transducer": (_hold(**{SPAN: 'high_pressure_gauge = "2 bar"'}), "controllers.hold.setpoint",
                                      ["'3 bar'", "0..2 bar"]),
    "the band past the transducer's top": (_hold(**{SPAN: 'high_pressure_gauge = "3.02 bar"'}),
                                           "controllers.hold.band", ["'0.1 bar'", "2.95..3.05 bar"]),
    "a sine reaching past the transducer": (
        _hold(**{SPAN: 'high_pressure_gauge = "4 bar"', 'setpoint = { kind = "constant", value = "3 bar" }':
                 'setpoint = { kind = "sine", mean = "3 bar", amplitude = "1.5 bar", frequency = "1 Hz" }'}),
        "controllers.hold.setpoint", ["'4.5 bar (highest value)'", "0..4 bar"]),
    "steps below the transducer's bottom": (
        _hold(**{'low_pressure_gauge = "0 bar"': 'low_pressure_gauge = "1 bar"',
                 'setpoint = { kind = "constant", value = "3 bar" }':
                 'setpoint = { kind = "steps", steps = [ { at = "0 s", value = "3 bar" }, '
                 '{ at = "1 s", value = "0.5 bar" } ] }'}),
        "controllers.hold.setpoint", ["'0.5 bar (lowest value)'", "1..10 bar"]),
    "an angle setpoint past the angle sensor": (_robot('angle_sensor = { high_angle = "20 deg" }'),
                                                "controllers.hip.setpoint",
                                                ["'25 deg (highest value)'", "-90..20 deg"]),
    "a co-contraction past the transducer": (_robot('transducer = { high_pressure_gauge = "2 bar" }'),
                                             "controllers.hip.co_contraction", ["'3 bar'", "0..2 bar"]),
}


@pytest.mark.parametrize("case", sorted(EXPORT_REFUSALS))
def test_firmware_refuses_in_one_line_before_claiming_the_folder(tmp_path, capsys, case):
    text, field, needles = EXPORT_REFUSALS[case]
    path = tmp_path / "s.toml"
    path.write_text(text)
    code, err = _run(capsys, "firmware", path, "--out", tmp_path / "fw", "--build")
    _refused(code, err, tmp_path / "fw", field, *needles)


@pytest.mark.parametrize("case", ["a transducer span of 1e-9 bar", "3 kHz: 5333.33 cycles",
                                  "3 bar on a 0-2 bar transducer"])
def test_simulate_refuses_the_same_scenarios(tmp_path, capsys, case):
    """The refusals are the scenario's rules: `simulate` of a scenario with [firmware] runs the
    board's arithmetic (a span of 1e-9 bar stopped it with an OverflowError)."""
    text, field, needles = EXPORT_REFUSALS[case]
    path = tmp_path / "s.toml"
    path.write_text(text)
    code, err = _run(capsys, "simulate", path, "--out", tmp_path / "sim")
    _refused(code, err, tmp_path / "sim", field, *needles)


def test_a_sine_is_checked_over_the_run_only():
    """A slow sine whose run ends before its peak: only the values the run reaches count (0.01 Hz
    over 2 s reaches 3 + 1.5 sin(0.126) = 3.19 bar, within a 0-3.5 bar transducer)."""
    from frogsim.scenario.firmware import setpoint_range
    text = _hold(**{SPAN: 'high_pressure_gauge = "3.5 bar"', 'setpoint = { kind = "constant", value = "3 bar" }':
                    'setpoint = { kind = "sine", mean = "3 bar", amplitude = "1.5 bar", frequency = "0.01 Hz" }',
                    'band = "0.1 bar"': 'band = "0.02 bar"'})
    sc = frogsim.load_scenario(__import__("tomllib").loads(text))
    lo, hi = setpoint_range(sc.controllers["hold"].setpoint, sc.duration)
    assert lo == pytest.approx(3e5) and hi == pytest.approx(3e5 + 1.5e5 * 0.12533, rel=1e-4)


def test_the_plans_period_is_exact():
    """16e6/rate exactly: a rate Timer1 cannot make raises (it was rounded: 3 kHz ran at
    3000.19 Hz)."""
    from frogsim.components import atmega2560 as chip
    assert chip.period_cycles(1000.0) == 16000 and chip.period_cycles(3200.0) == 5000
    assert chip.period_cycles(0.25) == 64_000_000                   # prescaler 1024, OCR1A 62499
    for rate in (3000.0, 7.0, 204.8, 0.2):
        with pytest.raises(ValueError):
            chip.period_cycles(rate)
    for rate in (2500.0, 2560.0, 3200.0, 5.0, 6.25, 8.0, 200.0, 250.0):
        n = chip.period_cycles(rate)
        p = chip.timer1_prescaler(n)
        assert p is not None and 16e6 / (p * (n // p)) == rate


def test_sil_refuses_a_board_process_it_cannot_run(built, tmp_path, capsys):
    """--board-process yes: refused with --timing grid (each decision at its own sample: a board a
    period behind cannot give it), and where the valves' dead time (here 0.5 ms) does not cover
    the 1 ms period the board would run behind; each in one line, nothing written."""
    fw, _, _ = _copy(built, tmp_path)
    code, err = _run(capsys, "sil", "hold-3bar", "--firmware", fw, "--out", tmp_path / "o", "--timing", "grid",
                     "--board-process", "yes")
    _refused(code, err, tmp_path / "o", "--board-process", "--timing cycle")
    quick = tmp_path / "hold-3bar.toml"
    quick.write_text((SHIPPED / "hold-3bar.toml").read_text()
                     + '\n[valves.charge]\ndead_time = "0.5 ms"\n\n[valves.discharge]\ndead_time = "0.5 ms"\n')
    code, err = _run(capsys, "sil", quick, "--firmware", fw, "--out", tmp_path / "o", "--board-process", "yes")
    _refused(code, err, tmp_path / "o", "--board-process", "dead time")
