"""Closed-loop control speed: one muscle under compiled bang-bang control, and the same law as a
Python function called at every sample.

Run:  python benchmarks/bench_control.py

Target: the compiled run at least 2000x real time. The Python-callable path is measured and its
cost per sample printed (docs/control.md quotes it). Scenario: the hip muscle at rest length
tracking a 0.5 Hz sine between 2 and 4 bar (bang-bang, band 0.1 bar, 1 kHz, 2 ms dead time),
10 s simulated, solver.max_step = 1 ms (the controller period: every step ends on a sample anyway).
"""
from __future__ import annotations

import sys
import time

import frogsim

TARGET = 2000.0
DURATION = 10.0
BAR = 1e5


def scenario(max_step: str = "1 ms"):
    return frogsim.load_scenario({
        "name": "bench-control", "duration": f"{DURATION} s", "output_interval": "10 ms",
        "solver": {"max_step": max_step},
        "muscles": {"hip": {"type": "hip", "motion": {"kind": "constant"}, "initial_pressure_gauge": "3 bar"}},
        "controllers": {"hip": {"kind": "bang-bang", "muscle": "hip", "band": "0.1 bar", "setpoint": {
            "kind": "sine", "mean": "3 bar", "amplitude": "1 bar", "frequency": "0.5 Hz"}}}})


def best_of(fn, n=5):
    best = float("inf")
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> int:
    import math
    sc = scenario()
    frogsim.simulate(sc)                                   # compile
    wall = best_of(lambda: frogsim.simulate(sc))
    ratio = DURATION / wall
    sc_default = scenario("0.05 ms")
    wall_default = best_of(lambda: frogsim.simulate(sc_default), 3)
    patm = sc.air.atmospheric_pressure_abs
    band = 0.1 * BAR

    def law(t, obs):
        sp = patm + 3 * BAR + BAR * math.sin(2 * math.pi * 0.5 * t)
        p = obs["hip"]
        return {"hip": "charge" if p < sp - band / 2 else "vent" if p > sp + band / 2 else "hold"}

    wall_py = best_of(lambda: frogsim.simulate(sc, controller=law), 2)
    samples = DURATION * sc.controller.rate + 1
    r = frogsim.simulate(sc)
    print(f"compiled bang-bang, max_step 1 ms:    {wall * 1e3:8.2f} ms for {DURATION:g} s -> {ratio:8.0f}x real time "
          f"({r.switchings['hip']} switchings)")
    print(f"compiled bang-bang, max_step 0.05 ms: {wall_default * 1e3:8.2f} ms -> {DURATION / wall_default:8.0f}x real time")
    print(f"Python controller function:          {wall_py * 1e3:8.2f} ms -> {DURATION / wall_py:8.0f}x real time, "
          f"{(wall_py - wall) / samples * 1e6:.1f} us per sample more than compiled")
    ok = ratio >= TARGET
    print(f"target: compiled >= {TARGET:g}x real time: {'PASS' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
