"""The firmware's laws on the ATmega2560: AVR cycles per call of each kind's C twin, measured on
the emulated chip (simavr).

Run:  python benchmarks/bench_fw_laws.py                    # this checkout
      python benchmarks/bench_fw_laws.py --baseline REV     # also REV's laws (git history), same inputs

What is measured: the plan of a robot scenario with every kind (the fixed-base robot in air; the
left hip under a joint-angle controller with bench_joint_control.py's gains, 30 bar/rad,
1 bar*s/rad, 30 bar/(rad*s), tracking a 0.5 Hz sine of 10 deg about 20 deg, the right hip the same
on steps; bang-bang on a sine, sliding mode, closed-loop and open-loop PWM on steps) is generated
as the firmware's C (``FirmwarePlan.c_source``, tables in flash through PROGMEM as the sketch has
them) and compiled with a small harness by avr-gcc with the flags the sketch's build uses
(arduino-mk's defaults for C: ``-mmcu=atmega2560 -Os -std=gnu11 -flto -ffunction-sections
-fdata-sections``, linked with ``--gc-sections``). The harness calls each law through a function
pointer (a call as the interrupt's ``frogsim_sample`` makes it, never inlined) once per sample
k = 0, 1, ... on a sequence of counts, with the law's own memory carried from call to call (a
joint-angle pair: both rows at each sample, as the board calls them), and raises pin D22 (the
pair's second row: D24) just before each call and lowers it just after; the emulated board
(:class:`frogsim.export.emulator.EmulatedBoard`) records the pins' edges with their AVR cycle.
Cycles per call = falling edge less rising edge: the law, its call and return and the harness's
argument loads (an empty function of the same signature, measured the same way, is the floor:
``empty``). Every call's mode is read back from the chip's RAM and checked against the Numba
twin's; the harness's flash data must end below 64 KB (LPM).

Inputs (the same for every revision, made here from the scenario's numbers, not from the law):

* ``typical``: the angle count follows the setpoint plus a tracking error wandering within
  about +-2000 Q4 counts (+-125 counts of a 10-bit sensor) and one count of noise; each pressure
  count a random walk within the transducer's working range;
* ``worst`` (joint-angle only): the angle count jumping between 0 and its full scale every sample
  (the largest angle steps, the velocity filter far out of its range: the law's int64 path).

Prints, per law: mean, largest and smallest cycles per call, and the share of the 16000-cycle
period (1 kHz) twelve such calls would take. A benchmark, not a test: no verdict (it fails only
when the chip's modes differ from the twin's).
"""
from __future__ import annotations

import argparse
import io
import json
import os
import re
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
PERIOD_CYCLES = 16000
CALLS = 1000            # samples per sequence (1 s at 1 kHz)
CFLAGS = ["-mmcu=atmega2560", "-DF_CPU=16000000L", "-Wall", "-ffunction-sections", "-fdata-sections", "-Os",
          "-std=gnu11", "-flto", "-fno-fat-lto-objects"]
LDFLAGS = ["-mmcu=atmega2560", "-Wl,--gc-sections", "-Os", "-flto", "-fuse-linker-plugin"]

SINE = {"mean": 20.0, "amplitude": 10.0, "frequency": 0.5}          # [deg, deg, Hz] the left hip's setpoint
JOINTS = {"hip_left": "sine setpoint", "hip_right": "steps setpoint"}


def scenario_raw() -> dict:
    """The robot with every kind (tests/firmware/robot-every-kind.toml's layout, the hip on a sine)."""
    deg = f"{SINE['mean']:g} deg"
    return {
        "name": "fw-laws-bench", "parameters": "fan2017", "output_interval": "2 ms", "firmware": {},
        "robot": {"environment": "air", "base": "fixed", "planar": True, "recovery": "muscle", "timestep": "1 ms"},
        "controller": {"rate": "1 kHz"}, "solver": {"max_step": "1 ms"},
        "gait": {"period": "1 s", "cycles": 1, "drive": [{"at": "0 s", "state": "hold"}],
                 "recover": [{"at": "0 s", "state": "hold"}], "palms": [{"at": "0 s", "state": "fold"}]},
        "controllers": {
            "hip": {"kind": "joint-angle", "joint": "hip_left", "co_contraction": "3 bar",
                    "proportional_gain": "30 bar/rad", "derivative_gain": "1 bar*s/rad",
                    "integral_gain": "30 bar/(rad*s)", "band": "0.1 bar",
                    "setpoint": {"kind": "sine", "mean": deg, "amplitude": f"{SINE['amplitude']:g} deg",
                                 "frequency": f"{SINE['frequency']:g} Hz"}},
            "hold": {"kind": "joint-angle", "joint": "hip_right", "co_contraction": "3 bar",
                     "proportional_gain": "30 bar/rad", "derivative_gain": "1 bar*s/rad",
                     "integral_gain": "30 bar/(rad*s)", "band": "0.1 bar",
                     "setpoint": {"kind": "steps", "steps": [{"at": "0 s", "value": deg},
                                                             {"at": "0.5 s", "value": f"{SINE['mean'] + 5:g} deg"}]}},
            "relay": {"kind": "bang-bang", "muscle": "knee_left", "band": "0.1 bar",
                      "setpoint": {"kind": "sine", "mean": "3 bar", "amplitude": "1 bar", "frequency": "0.5 Hz"}},
            "sliding": {"kind": "sliding-mode", "muscle": "ankle_left",
                        "setpoint": {"kind": "steps", "steps": [{"at": "0 s", "value": "2.5 bar"},
                                                                {"at": "0.4 s", "value": "1 bar"}]}},
            "pulses": {"kind": "pwm", "muscle": "knee_right", "frequency": "20 Hz", "proportional_band": "1 bar",
                       "setpoint": {"kind": "steps", "steps": [{"at": "0 s", "value": "2 bar"},
                                                               {"at": "0.3 s", "value": "1 bar"}]}},
            "duty": {"kind": "pwm", "muscle": "ankle_right", "frequency": "20 Hz", "duty": 0.3, "rest": "vent"}}}


def jobs(plan) -> list:
    """(label, law indices, cp sequence, ca sequence): each kind's first law, a joint-angle
    controller's two rows (called one after the other at each sample, as frogsim_sample calls them;
    each row timed on its own) and its worst case."""
    rng = np.random.default_rng(0)
    t = np.arange(CALLS) / plan.rate
    groups = {}          # each kind's first law; each joint-angle pair (both rows)
    for j, law in enumerate(plan.laws):
        key = (law.module.C_NAME, plan.channels[law.angle].name if law.angle >= 0 else "")
        groups.setdefault(key, []).append(j)
    full = 2 ** plan.adc.bits
    out = []
    for (name, joint), rows in groups.items():
        law = plan.laws[rows[0]]
        walk = np.cumsum(rng.integers(-3, 4, CALLS))
        cp = np.clip(300 + (walk - walk.mean()) % 200, 0, full - 1).astype(int)
        ca = np.zeros(CALLS, int)
        label = name
        if law.angle < 0:
            rows = rows[:1]
        else:
            rows = rows[:2]
            label = f"{name} ({JOINTS[joint]})"
            ch = plan.channels[law.angle]
            sp = np.radians(SINE["mean"] + SINE["amplitude"] * np.sin(2 * np.pi * SINE["frequency"] * t))
            err = np.radians(27.0) * np.sin(2 * np.pi * 0.7 * t + 1.0) * np.cos(2 * np.pi * 0.23 * t)
            ca = np.clip(np.floor((sp + err - ch.offset) / ch.unit_per_count + 0.5) + rng.integers(-1, 2, CALLS),
                         0, full - 1).astype(int)
        out.append((f"{label} typical", rows, cp, ca))
        if law.angle >= 0:
            worst = np.where(np.arange(CALLS) % 2 == 0, 0, full - 1)
            out.append((f"{label} worst", rows, cp, worst))
    return out


HARNESS = r"""
#include <stdint.h>
#include <avr/io.h>
#include <avr/pgmspace.h>
#define FS_TABLE PROGMEM
#define FS_READ16(p) pgm_read_word(p)
#define FS_READ32(p) pgm_read_dword(p)
#include "laws.h"

typedef int8_t (*fs_law_t)(uint32_t, uint16_t, uint16_t, int32_t *, const int32_t *, const int32_t *);
static int8_t fs_empty(uint32_t k, uint16_t cp, uint16_t ca, int32_t *mem, const int32_t *P, const int32_t *T) {
    (void)k; (void)cp; (void)ca; (void)mem; (void)P; (void)T;
    return 0;
}
volatile int8_t fs_sink;
/* each call's mode, read back and checked against the Numba twin */
volatile int8_t fs_modes[2][%(calls)d] __attribute__((used, externally_visible));
%(inputs)s
static void run(fs_law_t law, fs_law_t law2, int32_t *mem, int32_t *mem2, const int32_t *P, const int32_t *P2,
                const int32_t *T, const int32_t *T2, const uint16_t *cp, const uint16_t *ca) {
    fs_law_t volatile f = law, f2 = law2;
    uint32_t k;
    uint8_t i;
    for (i = 0; i < FS_BENCH_MEM; i++) mem[i] = mem2[i] = 0;
    for (k = 0; k < %(calls)d; k++) {
        uint16_t c_p = pgm_read_word(&cp[k]), c_a = pgm_read_word(&ca[k]);
        fs_law_t g = f;
        PORTA |= 1;
        fs_sink = g(k, c_p, c_a, mem, P, T);
        PORTA &= (uint8_t)~1;
        fs_modes[0][k] = fs_sink;
        if (law2) {
            g = f2;
            PORTA |= 4;
            fs_sink = g(k, c_p, c_a, mem2, P2, T2);
            PORTA &= (uint8_t)~4;
            fs_modes[1][k] = fs_sink;
        }
    }
    PORTA |= 2;     /* one sequence done */
    PORTA &= (uint8_t)~2;
}

int main(void) {
    DDRA = 7;
%(calls_main)s
    for (;;) {}
}
"""


def harness(plan) -> tuple:
    """(C source of the harness, the labels of its sequences in the order it runs them: each a
    list of one label per timed row)."""
    calls = {}
    for line in plan.c_source.splitlines():
        # "modes[j] = fs_kind(k, cp, ca, M, P, T);", behind the fault check's "bad ? FS_FAULT_MODE : "
        # (a joint's second row: "(pairN ? fs_joint_angle_follow(...) : fs_joint_angle(k, ...))", its own law timed)
        m = re.match(r"\s*modes\[(\d+)\] = (?:bad \? FS_FAULT_MODE : )?(?:\(pair\d+ \? \w+\([^)]*\) : )?"
                     r"(\w+)\(k, [^,]+, [^,]+, (\w+), (\w+), (\w+)\)\)?;", line)
        if m:
            calls[int(m.group(1))] = m.groups()[1:]
    inputs, runs, labels = [], [], []
    from frogsim.control.signals import FW_MEM
    mem = f"#define FS_BENCH_MEM {FW_MEM}\nstatic int32_t fs_bench_mem[FS_BENCH_MEM], fs_bench_mem2[FS_BENCH_MEM];\n"
    for n, (label, rows, cp, ca) in enumerate(jobs(plan)):
        fn, _, P, T = calls[rows[0]]
        fn2, P2, T2 = (calls[rows[1]][0], calls[rows[1]][2], calls[rows[1]][3]) if len(rows) > 1 else ("0", P, T)
        inputs.append(f"static const uint16_t in_cp{n}[{CALLS}] PROGMEM = {{{','.join(map(str, cp))}}};\n"
                      f"static const uint16_t in_ca{n}[{CALLS}] PROGMEM = {{{','.join(map(str, ca))}}};\n")
        runs.append(f"    run({fn}, {fn2}, fs_bench_mem, fs_bench_mem2, {P}, {P2}, {T}, {T2}, in_cp{n}, in_ca{n});")
        labels.append([label] if len(rows) == 1 else [f"{label}, 1st row", f"{label}, 2nd row"])
        if n == 0:
            runs.append(f"    run(fs_empty, 0, fs_bench_mem, fs_bench_mem2, {P}, {P}, {T}, {T}, in_cp{n}, in_ca{n});")
            labels.append(["empty"])
    src = HARNESS % {"inputs": mem + "".join(inputs), "calls": CALLS, "calls_main": "\n".join(runs)}
    return src, labels


def build(plan, folder: Path) -> Path:
    src, labels = harness(plan)
    (folder / "laws.h").write_text(plan.c_source)
    (folder / "bench.c").write_text(src)
    elf = folder / "bench.elf"
    obj = folder / "bench.o"
    for cmd in (["avr-gcc", *CFLAGS, "-c", "-o", str(obj), str(folder / "bench.c")],
                ["avr-gcc", *LDFLAGS, "-o", str(elf), str(obj)]):
        run = subprocess.run(cmd, capture_output=True, text=True)
        if run.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed:\n{run.stderr[-3000:]}")
    # the flash data (the laws' tables, the sine table, the inputs: PROGMEM, read by LPM) must end
    # below 64 KB, where LPM reaches
    nm = subprocess.run(["avr-nm", str(elf)], capture_output=True, text=True, check=True).stdout
    end = [int(line.split()[0], 16) for line in nm.splitlines() if line.endswith(" __trampolines_start")]
    if not end or end[0] > 0x10000:
        raise SystemExit(f"the harness's flash data end at {end}, beyond the 64 KB LPM reaches: shorten it")
    return elf, labels


def expected_modes(plan, jobs_list) -> list:
    """Each sequence's modes from the Numba twins (per row, its own memory from zero)."""
    from frogsim.control.signals import FW_MEM
    out = []
    for _, rows, cp, ca in jobs_list:
        seq = []
        for j in rows:
            law = plan.laws[j]
            mem = np.zeros(FW_MEM)
            seq.append([int(law.module.fw_law(law._Pf, law._Tf, mem, k, int(cp[k]), int(ca[k])))
                        for k in range(CALLS)])
        out.append(seq)
    out.insert(1, [[0] * CALLS])           # the empty function
    return out


def measure(elf: Path, labels: list, want: list) -> dict:
    """{label: cycles of each call (array)} from the pins' edges on the emulated chip (D22 around
    the first row's call, D24 around the second's; D23 ends a sequence), each sequence's modes
    checked against the Numba twins' (``want``)."""
    from frogsim.export import board
    from frogsim.export.emulator import EmulatedBoard, symbol_address
    pins = board.pin_map()
    out = {label: [] for seq in labels for label in seq}
    modes_at = symbol_address(elf, "fs_modes")
    with EmulatedBoard(elf) as b:
        busy, done, busy2 = b.watch(pins[22]), b.watch(pins[23]), b.watch(pins[24])
        for seq, names in enumerate(labels):
            if not b.run_until_pin(done, 1, b.cycle + 100_000_000):
                raise SystemExit(f"sequence {names[0]!r} did not finish")
            c, i, v = b.events()
            rise = {}
            for cyc, idx, val in zip(c.tolist(), i.tolist(), v.tolist()):
                if idx in (busy, busy2):
                    if val:
                        rise[idx] = cyc
                    elif idx in rise:
                        out[names[0 if idx == busy else 1]].append(cyc - rise.pop(idx))
            got = np.frombuffer(b.read_ram(modes_at, 2 * CALLS), np.int8).reshape(2, CALLS)
            for row, name in enumerate(names):
                if name != "empty" and list(got[row]) != want[seq][row]:
                    k = int(np.nonzero(got[row] != np.array(want[seq][row]))[0][0])
                    raise SystemExit(f"{name}: the AVR's mode at sample {k} is {got[row][k]}, the Numba "
                                     f"twin's {want[seq][row][k]}")
            b.run_until_pin(done, 0, b.cycle + 1000)
        if b.lost:
            raise SystemExit(f"{b.lost} pin events lost")
    return {k: np.asarray(v) for k, v in out.items()}


def measure_here() -> dict:
    """Cycles per call of this interpreter's frogsim (whichever ``src`` is on its path)."""
    import frogsim
    from frogsim.control import firmware as fwm
    plan = fwm.firmware_plan(frogsim.load_robot_scenario(scenario_raw()))
    want = expected_modes(plan, jobs(plan))
    with tempfile.TemporaryDirectory() as tmp:
        elf, labels = build(plan, Path(tmp))
        cyc = measure(elf, labels, want)
    return {k: [float(v.mean()), int(v.max()), int(v.min()), int(v.size)] for k, v in cyc.items()}


def src_of(rev: str, folder: str) -> str:
    blob = subprocess.run(["git", "-C", str(REPO), "archive", rev, "src"], capture_output=True, check=True).stdout
    with tarfile.open(fileobj=io.BytesIO(blob)) as tar:
        tar.extractall(folder)
    return os.path.join(folder, "src")


def measured_in(src: str) -> dict:
    env = dict(os.environ, PYTHONPATH=src)
    p = subprocess.run([sys.executable, __file__, "--json"], capture_output=True, text=True, env=env)
    if p.returncode != 0:
        raise SystemExit(f"the measurement with PYTHONPATH={src} failed:\n{p.stderr[-3000:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def table(title: str, res: dict) -> None:
    print(f"\n{title}")
    print(f"  {'law, inputs':<36} {'mean':>8} {'max':>6} {'min':>6}   12 calls / 16000-cycle period (mean, max)")
    for label, (mean, hi, lo, n) in res.items():
        print(f"  {label:<36} {mean:8.1f} {hi:6d} {lo:6d}   {100 * 12 * mean / PERIOD_CYCLES:5.1f} % "
              f"{100 * 12 * hi / PERIOD_CYCLES:5.1f} %   ({n} calls)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", metavar="REV", help="also measure this revision's laws (git archive of its src)")
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.json:
        print(json.dumps(measure_here()))
        return 0
    here = measured_in(str(REPO / "src"))
    if args.baseline:
        with tempfile.TemporaryDirectory() as tmp:
            table(f"baseline {args.baseline}: AVR cycles per call (avr-gcc -Os, simavr)",
                  measured_in(src_of(args.baseline, tmp)))
    table("this checkout: AVR cycles per call (avr-gcc -Os, simavr)", here)
    return 0


if __name__ == "__main__":
    sys.exit(main())
