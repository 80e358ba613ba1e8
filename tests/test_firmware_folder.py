"""The exported firmware folder as something a user carries: its Makefile's paths are relative (a
copy builds into its own build/ and leaves the original's alone), its README.md holds the wiring
of the plan and the ways to build it, and `--overwrite` removes what the earlier export wrote,
subfolders included, but no file frogsim did not write."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest
from avr_tools import need_avr_tools

from frogsim.cli import main
from frogsim.export import sketch

HERE = Path(__file__).with_name("firmware")


def _cli(*argv) -> int:
    return main([*map(str, argv), "--quiet"])


def _table(readme: str) -> list[list[str]]:
    """The wiring table's rows (cells stripped), header and rule left out."""
    rows = [line for line in readme.splitlines() if line.startswith("| ")]
    assert rows[0].startswith("| signal |")
    return [[c.strip() for c in r.strip("|").split("|")] for r in rows[1:]]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """hold-3bar exported and built."""
    need_avr_tools()
    fw = tmp_path_factory.mktemp("built") / "fw"
    assert _cli("firmware", "hold-3bar", "--out", fw, "--build") == 0
    return fw


def test_a_copied_export_folder_builds_into_its_own_build_folder(built, tmp_path):
    """`make -C COPY/NAME` after an edit of a source rebuilds COPY/build/NAME.elf; the original's
    ELF keeps its bytes and time (an absolute OBJDIR would have rebuilt the original's)."""
    rec = json.loads((built / "firmware.json").read_text())
    name = rec["name"]
    mk = (built / name / "Makefile").read_text()
    assert "OBJDIR = ../build" in mk and str(built) not in mk
    elf = built / "build" / f"{name}.elf"
    before = (elf.read_bytes(), elf.stat().st_mtime_ns)
    copy = tmp_path / "carried"
    shutil.copytree(built, copy)
    copied_elf = copy / "build" / f"{name}.elf"
    old = copied_elf.stat().st_mtime
    source = copy / name / "frogsim_laws.h"
    source.write_text(source.read_text() + "\n/* edited in the copy */\n")
    os.utime(source, (old + 5, old + 5))          # newer than the copy's ELF, whatever the clock's grain
    run = subprocess.run(["make", "-s", "-C", str(copy / name)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]
    assert copied_elf.is_file() and copied_elf.stat().st_mtime > old
    assert (elf.read_bytes(), elf.stat().st_mtime_ns) == before
    # the sketch folder alone, carried without any build, builds too
    bare = tmp_path / "bare"
    shutil.copytree(built / name, bare / name)
    run = subprocess.run(["make", "-s", "-C", str(bare / name)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]
    assert (bare / "build" / f"{name}.elf").is_file()


@pytest.mark.parametrize("scenario", ["hold-3bar", HERE / "robot-every-kind.toml"])
def test_the_readme_wires_every_muscle_and_channel_of_the_plan(tmp_path, scenario):
    """Without --build the folder is complete (Makefile, README.md); the README's table gives each
    muscle's charge and discharge pins, each channel's analog input, the busy pin and the serial
    port as the plan has them, and the build three ways."""
    need_avr_tools()
    fw = tmp_path / "fw"
    assert _cli("firmware", scenario, "--out", fw) == 0
    rec = json.loads((fw / "firmware.json").read_text())
    name = rec["name"]
    assert (fw / name / "Makefile").is_file()
    listed = {f["name"] for f in json.loads((fw / "manifest.json").read_text())["files"]}
    assert {f"{name}/README.md", f"{name}/Makefile"} <= listed
    readme = (fw / name / "README.md").read_text()
    rows = {r[0]: r for r in _table(readme)}
    assert len(rec["muscles"]) >= 1
    for m, (c, d) in zip(rec["muscles"], rec["valve_pins"]):
        assert rows[f"{m} charge valve"][1] == f"D{c}"
        assert rows[f"{m} discharge valve"][1] == f"D{d}"
    for k, ch in enumerate(rec["channels"]):
        assert rows[f"{ch['signal']} (channel {k})"][1] == f"A{ch['analog_input']}"
    assert rows["busy pin"][1] == f"D{rec['busy_pin']}"
    assert f"{rec['baud']} baud" in rows["serial log"][2]
    assert f"prescaler {rec['adc']['prescaler']}" in readme and f"{rec['adc']['bits']}-bit" in readme
    assert f"make -C {name}" in readme
    assert f"arduino-cli compile --fqbn arduino:avr:mega:cpu=atmega2560 {name}" in readme
    assert "Tools > Processor > ATmega2560" in readme
    assert "-DDECIMAL_DIG=__DECIMAL_DIG__" in readme


def test_the_readme_names_the_pins_of_a_channel_read_through_pins():
    """A channel with ``pin`` (one or several digital pins, an encoder's) instead of an analog
    input is wired to those pins."""
    rec = {"name": "enc", "scenario": "enc", "rate_hz": 1000.0, "period_cycles": 16000, "muscles": ["hip"],
           "valve_pins": [[22, 23]], "busy_pin": 13, "baud": 115200, "log_every": 10,
           "adc": {"prescaler": 128, "bits": 10, "adc_clocks": 13},
           "channels": [{"signal": "hip_left angle", "quantity": "angle", "name": "hip_left", "pin": [2, 3],
                         "unit_per_count": 0.01, "offset": 0.0, "unit": "rad"},
                        {"signal": "index", "quantity": "count", "name": "index", "pin": 18,
                         "unit_per_count": 1.0, "offset": 0.0, "unit": "count"}]}
    rows = {r[0]: r for r in _table(sketch.readme_text(rec))}
    assert rows["hip_left angle (channel 0)"][1] == "D2, D3"
    assert rows["index (channel 1)"][1] == "D18"


def test_overwrite_removes_the_earlier_exports_sketch_and_build(built, tmp_path, capsys):
    """Export A (hold-3bar, built), then `--overwrite` B (every-kind, not built) into the same
    folder: nothing of A is left (its sketch folder, its build folder with the compiler's
    objects), every file there is B's; a file someone else put into A's sketch folder stays,
    with a warning."""
    fw = tmp_path / "fw"
    shutil.copytree(built, fw)
    a = json.loads((fw / "firmware.json").read_text())["name"]
    listed = {f["name"] for f in json.loads((fw / "manifest.json").read_text())["files"]}
    objects = {p.relative_to(fw).as_posix() for p in (fw / "build").rglob("*") if p.is_file()}
    assert objects <= listed and any(f.startswith("build/core/") for f in objects)   # the objects are listed
    (fw / a / "notes.txt").write_text("mine")
    assert main(["firmware", str(HERE / "every-kind.toml"), "--out", str(fw), "--overwrite", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "warning:" in err and f"{a}/notes.txt" in err
    b = json.loads((fw / "firmware.json").read_text())["name"]
    assert b != a
    assert not (fw / "build").exists()
    assert sorted(p.name for p in (fw / a).iterdir()) == ["notes.txt"]
    assert (fw / a / "notes.txt").read_text() == "mine"
    manifest = json.loads((fw / "manifest.json").read_text())
    now = {p.relative_to(fw).as_posix() for p in fw.rglob("*") if p.is_file()}
    assert now == {f["name"] for f in manifest["files"]} | {"manifest.json", f"{a}/notes.txt"}
    assert all(not f.startswith(f"{a}/") or f == f"{a}/notes.txt" for f in now)


def test_overwrite_never_deletes_outside_the_folder(tmp_path):
    """A manifest naming files outside its folder (../x, an absolute path, through a symbolic
    link) does not make --overwrite delete them."""
    from frogsim.io.outputs import OutputFolder
    out = tmp_path / "out"
    out.mkdir()
    outside = tmp_path / "precious.txt"
    outside.write_text("keep")
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "elsewhere" / "f.txt").write_text("keep")
    (out / "link").symlink_to(tmp_path / "elsewhere")
    (out / "manifest.json").write_text(json.dumps({
        "command": "firmware", "status": "complete",
        "files": [{"name": "../precious.txt"}, {"name": str(outside)}, {"name": "link/f.txt"}]}))
    folder = OutputFolder(out, "firmware", [], overwrite=True, files=["firmware.json"])
    folder.check()
    folder.begin()
    assert outside.read_text() == "keep" and (tmp_path / "elsewhere" / "f.txt").read_text() == "keep"
