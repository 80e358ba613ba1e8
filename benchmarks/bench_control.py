"""Closed-loop control speed: one muscle under compiled bang-bang control, and the same law as a
Python function called at every sample.

Run:  python benchmarks/bench_control.py

Target: the compiled run at least 2000x real time. Scenario: the hip muscle at rest length tracking
a 0.5 Hz sine between 2 and 4 bar (bang-bang, band 0.1 bar, 1 kHz, 2 ms dead time), 10 s simulated,
the scenario's default solver settings (max_step 50 ms): the driver reads the controller's samples
from each step's dense output and ends a step only where a command changes.

Baseline in the same run: the same scenario with solver.max_step = 1 ms, the controller period,
which forces a step end on every sample (what the driver did before it read samples from dense
output); both must give the same valve sequence. The Python-callable path is measured and its cost
per sample printed (docs/control.md quotes it).
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
    sc = scenario("50 ms")
    frogsim.simulate(sc)                                   # compile
    wall = best_of(lambda: frogsim.simulate(sc))
    ratio = DURATION / wall
    sc_sample = scenario("1 ms")
    wall_sample = best_of(lambda: frogsim.simulate(sc_sample), 3)
    patm = sc.air.atmospheric_pressure_abs
    band = 0.1 * BAR

    def law(t, obs):
        sp = patm + 3 * BAR + BAR * math.sin(2 * math.pi * 0.5 * t)
        p = obs["hip"]
        return {"hip": "charge" if p < sp - band / 2 else "vent" if p > sp + band / 2 else "hold"}

    wall_py = best_of(lambda: frogsim.simulate(sc, controller=law), 2)
    samples = DURATION * sc.controller.rate + 1
    # the valve sequences, compared half-way between samples (at a sample itself the row may show
    # the state just before or just after a command that acts there, by floating-point rounding)
    half = {"output_interval": 0.5e-3}
    r = frogsim.simulate(sc.replace(half))
    r1 = frogsim.simulate(sc_sample.replace(half))
    same = r.switchings == r1.switchings and bool((r.u[1::2] == r1.u[1::2]).all())
    print(f"compiled bang-bang, default max_step 50 ms: {wall * 1e3:8.2f} ms for {DURATION:g} s -> {ratio:8.0f}x "
          f"real time ({r.stats['steps']} steps, switchings {r.switchings['hip']})")
    print(f"baseline, max_step 1 ms (a step per sample): {wall_sample * 1e3:8.2f} ms -> "
          f"{DURATION / wall_sample:8.0f}x real time ({r1.stats['steps']} steps); "
          f"dense-output sampling is {wall_sample / wall:.1f}x faster; same valve sequence: {same}")
    print(f"Python controller function:                 {wall_py * 1e3:8.2f} ms -> {DURATION / wall_py:8.0f}x "
          f"real time, {(wall_py - wall) / samples * 1e6:.1f} us per sample more than compiled")
    ok = ratio >= TARGET and same
    print(f"target: compiled >= {TARGET:g}x real time, same valves: {'PASS' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
