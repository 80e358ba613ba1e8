"""The firmware tests' tools (the AVR tool chain, the Arduino AVR core, simavr): in CI a missing
tool fails the test with the apt line to run (the README's test command installs them); outside
CI the test is skipped with that line."""
import os
import shutil
from pathlib import Path

import pytest

from frogsim.export.emulator import APT_LINE

TOOLS = ("avr-gcc", "avr-objdump", "avr-size", "avr-nm", "gcc", "make")
FILES = (Path("/usr/include/simavr/sim_avr.h"), Path("/usr/share/arduino/hardware/arduino/avr/cores/arduino"),
         Path("/usr/share/arduino/Arduino.mk"))


def missing() -> list:
    return [t for t in TOOLS if shutil.which(t) is None] + [str(f) for f in FILES if not f.exists()]


def need_tool(name: str) -> None:
    """One tool on PATH (gcc for the host-compiled laws): missing, the test fails in CI with the
    line to install it, and is skipped elsewhere."""
    if shutil.which(name) is not None:
        return
    text = f"{name} missing: apt-get install {name}"
    if os.environ.get("CI"):
        pytest.fail(text)
    pytest.skip(text)


def need_avr_tools() -> None:
    gone = missing()
    if not gone:
        return
    text = f"firmware tools missing ({', '.join(gone)}): {APT_LINE}"
    if os.environ.get("CI"):
        pytest.fail(text)
    pytest.skip(text)
