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
from frogsim.control import fixed
from frogsim.control.kinds import joint_angle
from frogsim.control.signals import FW_MEM, SN_SIZE, fw_sine
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


def _joint_cases(rng, n: int, sine: bool):
    """Joint-angle cases aimed at the fast path's edges (as tests/test_firmware_laws.py's)."""
    edges = np.array([-2**15 - 1, -2**15, -2**15 + 1, -1, 0, 1, 2**15 - 2, 2**15 - 1, 2**15])
    gains = np.array([0, 1, 0xFFFF, 0x10000, 0x10001, 2**29 - 1, 2**29, -2**29, -2**29 - 1, 2**30, 617662, 80425, 618])

    def diff():
        u = rng.random()
        return int(rng.choice(edges)) if u < 0.3 else int(rng.integers(-2**15 - 4, 2**15 + 5)) if u < 0.8 \
            else int(rng.integers(-2**24, 2**24))

    def gain():
        return int(rng.choice(gains)) if rng.random() < 0.5 else int(rng.integers(-2**31 + 1, 2**31))
    cases = []
    for _ in range(n):
        ca = int(rng.integers(0, 1024)) if rng.random() < 0.9 else 65535
        aq = 16 * ca + 8
        mem = [int(rng.choice([rng.integers(-2**30, 2**30 + 1), rng.choice([-2**30, 2**30, 0, 65535, -65537])])),
               int(rng.integers(0, 16 * 1023 + 9)), int(rng.integers(0, 2)), int(rng.integers(0, 2**31 - 1)),
               int(rng.integers(-2**24, 2**24))]
        shift = int(rng.integers(0, 9))
        dth = aq - mem[1] if mem[2] > 0 else 0
        vf = mem[4] + ((256 * dth - mem[4]) >> shift)
        lo = int(rng.integers(0, 20000))
        P = [int(rng.choice([-1, 1])), int(rng.integers(0, 30000)), lo, int(rng.integers(lo, 30001)), gain(), gain(),
             gain(), int(rng.integers(0, 2001)), 1, shift]
        if sine:
            P += [int(rng.integers(0, 50)), int(rng.integers(-2**31 + 1, 2**31)),
                  int(rng.integers(-2**31 + 1, 2**31)), aq + diff(), int(rng.integers(0, 2**17)),
                  int(rng.integers(0, 2**15)), int(rng.integers(0, 2**16))]
            k = int(rng.integers(0, 10**7))
        else:
            P += fixed.NO_SINE
            k = int(rng.integers(0, 5))
        every = int(rng.integers(1, 7))                  # the angle loop's schedule, its memory
        P += [every, int(rng.integers(0, every)), int(rng.integers(0, every + 2))]
        mem += [int(rng.integers(0, every + 1)), int(rng.integers(0, 30001)), int(rng.integers(-2**20, 2**20))]
        T = [max(-2**31 + 1, min(2**31 - 1, aq + diff())), max(-2**31 + 1, min(2**31 - 1, vf + diff()))]
        cases.append((P, T, mem, k, int(rng.integers(0, 1024)), ca))
    return cases


@pytest.mark.parametrize("sine, seed", [(False, 1), (False, 2), (True, 3), (True, 4)])
def test_the_joint_angle_law_on_the_avr_is_the_numba_twin(tmp_path, sine, seed):
    need_avr_tools()
    cases = _joint_cases(np.random.default_rng(seed), BATCH, sine)
    n_p = len(cases[0][0])
    decls = (_c_ints("PP", [c[0] for c in cases], flash=True) + _c_ints("TT", [c[1] for c in cases], flash=True)
             + _c_ints("MM", [c[2] for c in cases], flash=True)
             + _c_ints("KK", [[c[3], c[4], c[5]] for c in cases], "uint32_t", flash=True))
    body = (f"        int32_t P_ram[{n_p}], mem[{FW_MEM}];\n        uint8_t j;\n"
            f"        for (j = 0; j < {n_p}; j++) P_ram[j] = (int32_t)pgm_read_dword(&PP[i][j]);\n"
            f"        for (j = 0; j < {FW_MEM}; j++) mem[j] = (int32_t)pgm_read_dword(&MM[i][j]);\n"
            "        out[i][0] = fs_joint_angle(pgm_read_dword(&KK[i][0]), (uint16_t)pgm_read_dword(&KK[i][1]),\n"
            "                                   (uint16_t)pgm_read_dword(&KK[i][2]), mem, P_ram, TT[i]);\n"
            f"        for (j = 0; j < {FW_MEM}; j++) out[i][1 + j] = mem[j];")
    got = _run_on_avr(tmp_path, "joint", decls, body, 1 + FW_MEM, BATCH)
    for i, (P, T, mem, k, cp, ca) in enumerate(cases):
        m = np.array(mem, float)
        mode = joint_angle.fw_law(np.array(P, float), np.array(T, float), m, k, cp, ca)
        assert [int(got[i][0])] + list(got[i][1:]) == [mode] + [int(v) for v in m], (P, T, mem, k, cp, ca)


def test_sine_setpoints_generated_on_the_board_command_the_valves_the_model_commands(tmp_path):
    """tests/firmware/robot-every-kind.toml with a sine setpoint (and a start) for each closed-loop
    kind: exported, built and run in the loop; the board's machine code (its sine generator)
    decides as the model's compiled laws (the Numba twins) at every sample."""
    import json
    import re
    from pathlib import Path

    from frogsim.cli import main
    need_avr_tools()
    text = (Path(__file__).with_name("firmware") / "robot-every-kind.toml").read_text()
    sines = {"hip": '{ kind = "sine", mean = "15 deg", amplitude = "8 deg", frequency = "2 Hz", start = "0.1 s" }',
             "relay": '{ kind = "sine", mean = "2.5 bar", amplitude = "1 bar", frequency = "3 Hz", start = "0.05 s" }',
             "sliding": '{ kind = "sine", mean = "2 bar", amplitude = "0.8 bar", frequency = "2 Hz" }',
             "pulses": '{ kind = "sine", mean = "1.5 bar", amplitude = "0.5 bar", frequency = "2 Hz" }'}
    for name, sp in sines.items():
        text, n = re.subn(rf"(\[controllers\.{name}\][^\[]*?\nsetpoint = )[^\n]*", rf"\g<1>{sp}", text)
        assert n == 1, name
    scenario = tmp_path / "robot-sines.toml"
    scenario.write_text(text)
    fw, out = tmp_path / "fw", tmp_path / "sil"
    # robot-every-kind is at the board's edge (docs/firmware.md, the timing table): written anyway
    assert main(["firmware", str(scenario), "--out", str(fw), "--build", "--allow-overrun", "--quiet"]) == 0
    from frogsim.scenario.load import with_firmware
    plan = fwm.firmware_plan(frogsim.load_robot_scenario(with_firmware(str(scenario))))
    generated = [law for law in plan.laws if law.module is not fwm.program and law.P[law.module.P_SINE] >= 0]
    assert len(generated) == 5                          # both rows of the joint and the three pressure laws
    assert main(["sil", str(scenario), "--firmware", str(fw), "--timing", "grid", "--out", str(out),
                 "--no-animation", "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["sil"]["mismatched_samples"] == 0 and s["sil"]["samples"] == 601
