"""The firmware path's refusals, each a CLI run: exit 2, one line on stderr naming the field (or
--firmware and the file) and the value, no traceback, no output folder.

`frogsim sil` refuses a firmware folder whose ELF is older than its sources, an ELF simavr cannot
run as the ATmega2560's (not an ELF, damaged, truncated, of another machine, of another AVR), a
firmware.json frogsim did not write, and a plan of another scenario, naming the likely cause."""
from __future__ import annotations

import json
import os
import shutil
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


BAD_ELVES = {
    # case: (the ELF's bytes from the good one and tmp_path, text the message must hold)
    "text": (lambda good, tmp: b"not a firmware\n", "not an ELF file"),
    "random bytes": (lambda good, tmp: bytes(os.urandom(4096)).replace(b"\x7fELF", b"xELF"), "not an ELF file"),
    "empty": (lambda good, tmp: b"", "not an ELF file"),
    "a header only": (lambda good, tmp: good[:40], "damaged"),
    "truncated": (lambda good, tmp: good[:len(good) // 2], "truncated"),
    "the host's /bin/true": (lambda good, tmp: Path("/bin/true").read_bytes(), "not a 32-bit one"),
    "another machine": (lambda good, tmp: _other_machine(good), "another machine"),
    "an ATmega328P's": (lambda good, tmp: _elf_328p(tmp), "avr5"),
}


@pytest.mark.parametrize("case", sorted(BAD_ELVES))
def test_sil_refuses_what_is_not_an_atmega2560_elf(built, tmp_path, capsys, case):
    """Checked before simavr loads it: /bin/true made libsimavr crash (exit 139), a truncated ELF
    stopped avr-nm with a traceback."""
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
    "format 3": (_set(3, "format"), "format"),
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
