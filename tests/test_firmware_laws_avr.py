"""The firmware's laws as the board runs them: the generated C compiled by avr-gcc for the
ATmega2560 (with the sketch's -Os, the 16-bit int and the inline MUL/MULS/MULSU products the host
build does not take) and run on the emulated chip (simavr), against the Numba twins on the same
cases, bit for bit. tests/test_firmware_laws.py checks the same C compiled for this machine."""
from __future__ import annotations

import subprocess

import numpy as np
import pytest

import frogsim
from frogsim.control import firmware as fwm
from frogsim.control.signals import SN_SIZE, fw_sine
from tests.avr_tools import need_avr_tools

BATCH = 150             # cases per build (their results in the AVR's 8 KB of RAM)


def _hold_plan():
    d = {"name": "fw", "duration": "0.2 s", "output_interval": "1 ms",
         "muscles": {"hip": {"type": "hip", "motion": {"kind": "constant"}}},
         "controllers": {"hold": {"kind": "bang-bang", "muscle": "hip", "setpoint": "3 bar", "band": "0.1 bar"}},
         "firmware": {}}
    return fwm.firmware_plan(frogsim.build_model(frogsim.load_scenario(d)))


def _run_on_avr(tmp_path, name: str, decls: str, body: str, n_out: int, n: int) -> np.ndarray:
    """Compile the laws' C with a main that runs ``body`` for i = 0..n-1 (writing ``out[i][...]``,
    int32) and return out (n, n_out) read from the emulated chip's RAM."""
    from frogsim.export import board
    from frogsim.export.emulator import EmulatedBoard, symbol_address
    src = ("#include <stdint.h>\n#include <avr/io.h>\n#include <avr/pgmspace.h>\n#define FS_TABLE PROGMEM\n"
           "#define FS_READ16(p) pgm_read_word(p)\n#define FS_READ32(p) pgm_read_dword(p)\n"
           + _hold_plan().c_source + decls
           + f"\nvolatile int32_t out[{n}][{n_out}];\nint main(void) {{\n    uint16_t i;\n    DDRA = 2;\n"
           f"    for (i = 0; i < {n}; i++) {{\n{body}\n    }}\n    PORTA |= 2;\n    for (;;) {{}}\n}}\n")
    c = tmp_path / f"{name}.c"
    elf = tmp_path / f"{name}.elf"
    c.write_text(src)
    run = subprocess.run(["avr-gcc", "-mmcu=atmega2560", "-DF_CPU=16000000L", "-Wall", "-Os", "-std=gnu11",
                          "-ffunction-sections", "-fdata-sections", "-Wl,--gc-sections", "-o", str(elf), str(c)],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    with EmulatedBoard(elf) as b:
        done = b.watch(board.pin_map()[23])
        assert b.run_until_pin(done, 1, 400_000_000), "the cases did not finish"
        raw = b.read_ram(symbol_address(elf, "out"), 4 * n * n_out)
    return np.frombuffer(raw, "<i4").reshape(n, n_out).astype(np.int64)


def _c_ints(name: str, rows, ctype: str = "int32_t", flash: bool = False) -> str:
    rows = [list(map(int, r)) for r in rows]
    body = ",".join("{" + ",".join(str(v) for v in r) + "}" for r in rows)
    return f"static const {ctype} {name}[{len(rows)}][{len(rows[0])}]{' PROGMEM' if flash else ''} = {{{body}}};\n"


def _sine_cases(rng, n: int):
    blocks, ks = [], []
    for i in range(n):
        k0 = int(rng.integers(0, 300)) if i % 3 else int(rng.integers(0, 2**31 - 1))
        block = [k0, int(rng.integers(-2**31 + 1, 2**31)), int(rng.integers(-2**31 + 1, 2**31)),
                 int(rng.integers(-2**14, 2**15)), int(rng.integers(0, 2**17)), int(rng.integers(0, 2**15)),
                 int(rng.integers(0, 2**16))]
        if i % 5 == 0:      # the masked slots out of their ranges
            block[4], block[5], block[6] = (int(rng.integers(-2**31 + 1, 2**31)) for _ in range(3))
        blocks.append(block)
        ks.append(int(rng.choice([rng.integers(0, 10**7), rng.integers(0, 2**32), rng.integers(0, 400)])))
    return blocks, ks


@pytest.mark.parametrize("seed", [1, 2])
def test_the_sine_generator_on_the_avr_is_the_numba_twin(tmp_path, seed):
    need_avr_tools()
    rng = np.random.default_rng(seed)
    blocks, ks = _sine_cases(rng, BATCH)
    decls = (_c_ints("S", blocks, flash=True) + _c_ints("K", [[k] for k in ks], "uint32_t", flash=True))
    body = (f"        int32_t S_ram[{SN_SIZE}], rate;\n        uint8_t j;\n"
            f"        for (j = 0; j < {SN_SIZE}; j++) S_ram[j] = (int32_t)pgm_read_dword(&S[i][j]);\n"
            "        out[i][0] = fs_sine(pgm_read_dword(&K[i][0]), S_ram, &rate);\n        out[i][1] = rate;")
    got = _run_on_avr(tmp_path, "sine", decls, body, 2, BATCH)
    for i, (block, k) in enumerate(zip(blocks, ks)):
        assert tuple(got[i]) == fw_sine(np.array(block, float), 0, k), (block, k)
