"""Stepping rates of the closed-loop interfaces: Swim-v0, Swim-v1 and the bare coupled stepper.

Run:  python benchmarks/bench_envs.py [--seconds S] [--rounds R] [--instructions]

Cases
    ``frogsim/Swim-v0`` (the shipped ``swim`` robot, 6 muscles, 10 MuJoCo steps of 1 ms per env
    step) driven by an open-loop 1 s / 1 s stroke through ``env.step``; the same robot through
    ``CoupledStepper.step`` with one MuJoCo step per call (the full robot stepped at the
    controller rate, 1 kHz); ``frogsim/HipPressure-v0`` (1 ms per step) with a bang-bang law;
    and, for reference, ``run_coupled`` (the open-loop engine) on the same robot. Then v0 against
    v1 on the same stroke (``Swim-v0``/``Swim-v1``, ``HipPressure-v0``/``HipPressure-v1``
    with the bang-bang law), in turns, ``--rounds`` times, best round each; and Swim-v1 through
    Gymnasium's vector environments: two copies in this process (``SyncVectorEnv``) and in two
    processes (``AsyncVectorEnv``), env steps per second summed over the copies.

What is timed
    wall time of the stepping loop only (models built and Numba code loaded before), pinned to
    one CPU. Reported: env steps per second, MuJoCo steps per second and real-time factor.

    With ``--instructions`` the v0 / v1 pairs are also counted by valgrind's callgrind
    (``bench_baseline.py``'s helpers), switched on around the stepping loop only: instructions per
    env step, which the machine's load does not move.

Target
    Swim-v0 at least 1,000 env steps/s (10 x real time); a v1 step no slower than its v0's
    (best rounds within 5 %, in steps per CPU second of the process).
    Exit status 0 when all are met.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

TARGET = 1000.0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=8.0, help="simulated seconds per case")
    ap.add_argument("--rounds", type=int, default=3, help="v0 / v1 rounds in turns")
    ap.add_argument("--instructions", action="store_true", help="also count instructions per step with callgrind")
    ap.add_argument("--count", help=argparse.SUPPRESS)      # the child callgrind runs: one env id
    args = ap.parse_args(argv)
    if args.count:
        return _count_child(args.count, args.seconds)
    if hasattr(os, "sched_setaffinity"):
        cpu = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpu})
        print(f"pinned to CPU {cpu}")
    import gymnasium as gym

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
    ok = versions(T, args.rounds) and ok
    if args.instructions:
        ok = instruction_counts(min(T, 1.0)) and ok
    vector_rates(T)
    return 0 if ok else 1


PAIRS_KW = {"Swim": ({}, {}), "HipPressure": ({"setpoint": 3.0}, {"setpoint": 3.0})}


def _count_child(env_id: str, T: float) -> int:
    """Under callgrind (counting off): step env_id for T simulated seconds, counting on around the
    loop only; prints the steps."""
    import subprocess
    import gymnasium as gym

    import frogsim  # noqa: F401
    name = env_id.split("/")[1].rsplit("-", 1)[0]
    kw = dict(PAIRS_KW[name][0 if env_id.endswith("v0") else 1])
    if env_id.endswith("v0"):
        kw["duration"] = T + 1.0
    env = gym.make(env_id, **kw).unwrapped
    swim = name == "Swim"
    period = env.stepper.period if swim else env.plant.period
    steps = int(round(T / period))
    n = env.n if swim else 1
    acts = [_swim_action(n, k, period) for k in range(steps)] if swim else None
    env.reset(seed=0)
    env.step(acts[0] if swim else np.array([1]))                 # warm
    obs, _ = env.reset(seed=0)
    on, hold = np.array([2]), np.array([1])
    subprocess.run(["callgrind_control", "-i", "on", str(os.getpid())], check=True, capture_output=True)
    for k in range(steps):
        if swim:
            env.step(acts[k])
        else:
            obs, *_ = env.step(on if obs[0] < 3.0 else hold)
    subprocess.run(["callgrind_control", "-i", "off", str(os.getpid())], check=True, capture_output=True)
    print(steps)
    return 0


def instruction_counts(T: float) -> bool:
    """Instructions per env step of each v0 / v1 pair (callgrind); True when no v1 counts more
    than 1 % above its v0."""
    import subprocess
    import tempfile
    from pathlib import Path

    from bench_baseline import callgrind_prefix, callgrind_total
    ok = True
    with tempfile.TemporaryDirectory(prefix="frogsim-bench-envs-") as tmp:
        for name in PAIRS_KW:
            per = {}
            for v in ("v0", "v1"):
                out = str(Path(tmp) / f"{name}-{v}.out")
                p = subprocess.run([*callgrind_prefix(out), sys.executable, __file__, "--count", f"frogsim/{name}-{v}",
                                    "--seconds", str(T)], capture_output=True, text=True)
                if p.returncode != 0:
                    raise SystemExit(f"callgrind of {name}-{v} failed:\n{p.stderr[-2000:]}")
                steps = int(p.stdout.split()[-1])
                per[v] = callgrind_total(out) / steps
            met = per["v1"] <= 1.01 * per["v0"]
            ok = ok and met
            print(f"{name}-v1 {per['v1'] / 1e6:.3f} M instructions per step against {name}-v0 {per['v0'] / 1e6:.3f} M "
                  f"(callgrind): {per['v1'] / per['v0']:.3f} x, {'MET' if met else 'NOT MET'} (at most 1 % more)")
    return ok


def _swim_action(n, k, period):
    on = (k * period) % 2.0 < 1.0
    return np.array([2] * n + [1] if on else [0] * n + [0])


def _rate(env_id, T, **kw):
    """env steps per CPU second of one env over T simulated seconds (the stroke or the bang-bang):
    CPU time of this process, which the other work on a shared machine disturbs less than wall time."""
    import gymnasium as gym
    env = gym.make(env_id, **kw).unwrapped
    obs, _ = env.reset(seed=0)
    swim = "Swim" in env_id
    period = env.stepper.period if swim else env.plant.period
    steps = int(round(T / period))
    n = env.n if swim else 1
    acts = [_swim_action(n, k, period) for k in range(steps)] if swim else None
    env.step(acts[0] if swim else np.array([1]))            # warm
    env.reset(seed=0)
    t0 = time.process_time()
    if swim:
        for k in range(steps):
            env.step(acts[k])
    else:
        obs, _ = env.reset(seed=0)
        on, hold = np.array([2]), np.array([1])
        for _ in range(steps):
            obs, *_ = env.step(on if obs[0] < 3.0 else hold)
    return steps / (time.process_time() - t0)


def versions(T, rounds) -> bool:
    """v0 against v1, in turns, best of the rounds; True when no v1 is more than 5 % slower."""
    pairs = {"Swim": ({"duration": T}, {}), "HipPressure": ({"duration": T, "setpoint": 3.0},
                                                            {"setpoint": 3.0})}
    ok = True
    for name, (kw0, kw1) in pairs.items():
        best = {0: 0.0, 1: 0.0}
        for _ in range(rounds):
            best[0] = max(best[0], _rate(f"frogsim/{name}-v0", T, **kw0))
            best[1] = max(best[1], _rate(f"frogsim/{name}-v1", T, **kw1))
        met = best[1] >= 0.95 * best[0]
        ok = ok and met
        print(f"{name}-v1 {best[1]:,.0f} steps per CPU second against {name}-v0 {best[0]:,.0f} (best of {rounds} rounds in "
              f"turns): {best[1] / best[0]:.2f} x, {'MET' if met else 'NOT MET'} (no slower than v0 within 5 %)")
    return ok


def vector_rates(T) -> None:
    """Swim-v1 in Gymnasium's vector environments, two copies: summed env steps per second."""
    import gymnasium as gym
    steps = int(round(T / 0.01))
    for kind in ("SyncVectorEnv", "AsyncVectorEnv"):
        cls = getattr(gym.vector, kind)
        envs = cls([lambda: gym.make("frogsim/Swim-v1") for _ in range(2)])
        n = envs.single_action_space.shape[0] - 1
        envs.reset(seed=[0, 1])
        envs.step(np.stack([_swim_action(n, 0, 0.01)] * 2))
        t0 = time.perf_counter()
        for k in range(steps):
            envs.step(np.stack([_swim_action(n, k, 0.01)] * 2))
        wall = time.perf_counter() - t0
        envs.close()
        print(f"Swim-v1 x 2 in {kind}: {2 * steps / wall:,.0f} env steps/s summed over the copies")


if __name__ == "__main__":
    sys.exit(main())
