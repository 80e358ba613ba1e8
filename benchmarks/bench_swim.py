"""Speed of the coupled robot simulation: 10 swim cycles of the full robot on one core.

Run:  python benchmarks/bench_swim.py [--cycles N] [--repeats N]

Case
    The shipped ``swim`` scenario with ``robot.recovery = "muscle"``: the full robot, two
    antagonistic DMSP-20 muscles per joint (12 muscles, 24 valves), free in water (strip drag,
    added mass, buoyancy), the pump on, the paper's 1 s / 1 s open-loop timing, 10 cycles = 20 s of
    simulated time at MuJoCo's 1 ms step, the pneumatics adapting their own steps inside it.

What is timed
    ``frogsim.engine.coupled.run_coupled`` on a freshly built model, best of N: the whole loop
    (mj_step1, the Numba kernel with pneumatics, muscle forces and water, mj_step2). Building the
    model (MJCF compile, tables) and the first call's Numba compilation or cache load are timed
    and printed apart. The process is pinned to one CPU.

Target
    at least 20 x faster than real time (20 s simulated in at most 1 s). Exit status 0 when met.
    Wall times depend on the machine and its load: run it on an otherwise idle machine.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

TARGET = 20.0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cycles", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    if hasattr(os, "sched_setaffinity"):
        cpu = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpu})
        print(f"pinned to CPU {cpu}")

    import mujoco
    import numba

    import frogsim
    from frogsim.engine.coupled import build_coupled, run_coupled

    raw = frogsim.load_robot_scenario("swim").raw
    raw = frogsim.with_overrides(raw, {"robot.recovery": "muscle"})
    rs = frogsim.load_robot_scenario(raw, cycles=args.cycles)
    print(f"frogsim {frogsim.__version__}, MuJoCo {mujoco.__version__}, Numba {numba.__version__}, "
          f"Python {sys.version.split()[0]}")
    print(f"case: {rs.name!r}, {len(rs.muscles)} muscles, {2 * len(rs.muscles)} valves, "
          f"{rs.options.environment}, {rs.gait.cycles} cycles = {rs.duration:g} s simulated, "
          f"MuJoCo step {rs.options.timestep * 1e3:g} ms")

    t0 = time.perf_counter()
    cm = build_coupled(rs)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    first = run_coupled(cm)
    t_first = time.perf_counter() - t0
    print(f"build model: {t_build:.3f} s; first run (Numba compile or cache load included): {t_first:.2f} s")

    walls = []
    for _ in range(args.repeats):
        cm = build_coupled(rs)
        out = run_coupled(cm)
        walls.append(out["wall_s"])
    best = min(walls)
    factor = rs.duration / best
    st = out["stats"]
    per_step = best / st["mujoco_steps"] * 1e6
    print(f"loop: best {best:.3f} s of {args.repeats} ({', '.join(f'{w:.3f}' for w in walls)} s); "
          f"{per_step:.1f} us per MuJoCo step; {st['pneumatic_steps']} pneumatic steps, "
          f"{st['rhs_evaluations']} right-hand-side evaluations")

    # MuJoCo's own share: the same number of mj_step1 + mj_step2 calls on the same model
    m, d = cm.mjm, cm.mjd
    mujoco.mj_resetData(m, d)
    t0 = time.perf_counter()
    for _ in range(st["mujoco_steps"]):
        mujoco.mj_step1(m, d)
        mujoco.mj_step2(m, d)
    t_mj = time.perf_counter() - t0
    print(f"of which MuJoCo alone (mj_step1 + mj_step2, no forces): about {t_mj:.3f} s "
          f"({t_mj / st['mujoco_steps'] * 1e6:.1f} us per step)")
    s = frogsim.SwimResult(rec=out["rec"], model=cm, stats=st, wall_s=best).summary()
    print(f"result: {s['distance_m']:.2f} m in {s['duration_s']:g} s, {s['mean_speed_m_per_s']:.3f} m/s, "
          f"{s['air_used_per_cycle_L_std']:.2f} L air per cycle")
    ok = factor >= TARGET
    print(f"real-time factor: {factor:.1f} x (target >= {TARGET:g} x): {'MET' if ok else 'NOT MET'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
