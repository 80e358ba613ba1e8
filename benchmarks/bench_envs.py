"""Stepping rates of the closed-loop interfaces: Swim-v0 and the bare coupled stepper.

Run:  python benchmarks/bench_envs.py [--seconds S]

Cases
    ``frogsim/Swim-v0`` (the shipped ``swim`` robot, 6 muscles, 10 MuJoCo steps of 1 ms per env
    step) driven by an open-loop 1 s / 1 s stroke through ``env.step``; the same robot through
    ``CoupledStepper.step`` with one MuJoCo step per call (the full robot stepped at the
    controller rate, 1 kHz); ``frogsim/HipPressure-v0`` (1 ms per step) with a bang-bang law;
    and, for reference, ``run_coupled`` (the open-loop engine) on the same robot.

What is timed
    wall time of the stepping loop only (models built and Numba code loaded before), pinned to
    one CPU. Reported: env steps per second, MuJoCo steps per second and real-time factor.

Target
    Swim-v0 at least 1,000 env steps/s (10 x real time). Exit status 0 when met.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

TARGET = 1000.0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=8.0, help="simulated seconds per case")
    args = ap.parse_args(argv)
    if hasattr(os, "sched_setaffinity"):
        cpu = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpu})
        print(f"pinned to CPU {cpu}")
    import gymnasium as gym
    import numpy as np

    import frogsim
    from frogsim.engine.coupled import CoupledStepper, build_coupled, run_coupled

    T = args.seconds
    env = gym.make("frogsim/Swim-v0", duration=T)
    n = env.unwrapped.n
    env.reset(seed=0)
    env.step([1] * n + [0])                             # warm up (Numba cache load)
    env.reset(seed=0)
    period = env.unwrapped.stepper.period
    steps = int(round(T / period))
    t0 = time.perf_counter()
    for k in range(steps):
        on = (k * period) % 2.0 < 1.0
        env.step([2] * n + [1] if on else [0] * n + [0])
    wall = time.perf_counter() - t0
    rate = steps / wall
    print(f"Swim-v0: {steps} env steps ({period * 1e3:g} ms each) in {wall:.3f} s: {rate:,.0f} steps/s, "
          f"{rate * env.unwrapped.stepper.steps_per_action:,.0f} MuJoCo steps/s, {T / wall:.1f} x real time")

    rs = frogsim.load_robot_scenario("swim")
    st = CoupledStepper(rs, steps_per_action=1)
    u_on = np.array([1.0, 0.0] * st.n)
    u_off = np.array([0.0, 1.0] * st.n)
    m_steps = int(round(T / st.cm.dt))
    t0 = time.perf_counter()
    for k in range(m_steps):
        on = (k * st.cm.dt) % 2.0 < 1.0
        st.step(u_on if on else u_off, 1.0 if on else 0.0)
    wall1 = time.perf_counter() - t0
    print(f"CoupledStepper, one MuJoCo step per call (1 kHz control): {m_steps / wall1:,.0f} steps/s, "
          f"{T / wall1:.1f} x real time")

    rs_T = frogsim.load_robot_scenario("swim", cycles=max(1, int(round(T / 2.0))))
    cm = build_coupled(rs_T)
    out = run_coupled(cm)
    print(f"run_coupled (open loop, for reference): {cm.n_steps / out['wall_s']:,.0f} MuJoCo steps/s, "
          f"{rs_T.duration / out['wall_s']:.1f} x real time")

    hip = gym.make("frogsim/HipPressure-v0", duration=T, setpoint=3.0)
    obs, _ = hip.reset(seed=0)
    h_steps = hip.unwrapped.max_steps
    t0 = time.perf_counter()
    for _ in range(h_steps):
        obs, *_ = hip.step([2] if obs[0] < 3.0 else [1])
    wall2 = time.perf_counter() - t0
    print(f"HipPressure-v0: {h_steps / wall2:,.0f} steps/s (1 ms each), {T / wall2:.1f} x real time")
    ok = rate >= TARGET
    print(f"Swim-v0 rate {rate:,.0f} steps/s (target >= {TARGET:,.0f}): {'MET' if ok else 'NOT MET'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
