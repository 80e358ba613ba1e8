"""Speed of the coupled robot simulation: 10 swim cycles of the full robot on one core.

Run:  python benchmarks/bench_swim.py [--cycles N] [--repeats N] [--recovery spring]

Case
    The shipped ``swim`` scenario with ``robot.recovery = "muscle"``: the full robot, two
    antagonistic DMSP-20 muscles per joint (12 muscles, 24 valves), free in water (strip drag,
    added mass, buoyancy), the pump on, the paper's 1 s / 1 s open-loop timing, 10 cycles = 20 s of
    simulated time at MuJoCo's 1 ms step, the pneumatics adapting their own steps inside it.
    ``--recovery spring``: the shipped ``swim`` scenario as it is (six driving muscles, springs
    recover the legs).

What is timed
    ``frogsim.engine.coupled.run_coupled`` on a freshly built model, best of N: the whole loop
    (mj_step1, the Numba kernel with pneumatics, muscle forces and water, mj_step2). The compiled
    loop (the default: MuJoCo's C functions and the kernel called from one Numba function, many
    steps per call) and, in the same run as the baseline, the Python loop (``compiled=False``: one
    trip through MuJoCo's bindings and Numba's dispatcher per call), alternating, so that both see
    the same machine load; the two runs are checked to be the same bit for bit. Building the model
    (MJCF compile, tables) and the first call's Numba compilation or cache load are timed and
    printed apart. The process is pinned to one CPU.

Target
    at least 50 x faster than real time (the compiled loop; 20 s simulated in at most 0.4 s).
    Exit status 0 when met. Wall times depend on the machine and its load: run it on an
    otherwise idle machine.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

TARGET = 50.0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cycles", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--recovery", choices=("muscle", "spring"), default="muscle",
                    help="muscle: the full robot (default); spring: the shipped swim scenario as it is")
    args = ap.parse_args(argv)
    if hasattr(os, "sched_setaffinity"):
        cpu = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpu})
        print(f"pinned to CPU {cpu}")

    import mujoco
    import numba
    import numpy as np

    import frogsim
    from frogsim.engine.coupled import build_coupled, run_coupled
    from frogsim.engine.coupled_loop import call_model_data, mujoco_c

    @numba.njit
    def mujoco_steps(step1, step2, m, d, n):
        for _ in range(n):
            call_model_data(step1, m, d)
            call_model_data(step2, m, d)

    raw = frogsim.load_robot_scenario("swim").raw
    raw = frogsim.with_overrides(raw, {"robot.recovery": args.recovery})
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
    run_coupled(build_coupled(rs), compiled=False)
    t_first = time.perf_counter() - t0
    print(f"build model: {t_build:.3f} s; first runs (Numba compile or cache load included): {t_first:.2f} s")

    walls = {True: [], False: []}
    for _ in range(args.repeats):
        for compiled in (True, False):
            cm = build_coupled(rs)
            out = run_coupled(cm, compiled=compiled)
            walls[compiled].append(out["wall_s"])
            if not np.array_equal(out["rec"], first["rec"], equal_nan=True):
                print(f"compiled={compiled}: the record differs from the first run's")
                return 1
            if compiled:
                kept = cm, out
    cm, out = kept
    st = out["stats"]
    best = {c: min(w) for c, w in walls.items()}
    for compiled, label in ((True, "compiled loop"), (False, "Python loop (baseline)")):
        w = walls[compiled]
        print(f"{label}: best {best[compiled]:.3f} s of {len(w)} ({', '.join(f'{x:.3f}' for x in w)} s); "
              f"{best[compiled] / st['mujoco_steps'] * 1e6:.1f} us per MuJoCo step, "
              f"{rs.duration / best[compiled]:.1f} x real time")
    print(f"compiled loop / Python loop: {best[False] / best[True]:.2f} x faster; "
          f"{st['pneumatic_steps']} pneumatic steps, {st['rhs_evaluations']} right-hand-side evaluations")
    factor = rs.duration / best[True]

    # MuJoCo's own share: the same number of mj_step1 + mj_step2 calls on the same model, through
    # the bindings and from compiled code
    m, d = cm.mjm, cm.mjd
    mujoco.mj_resetData(m, d)
    t0 = time.perf_counter()
    for _ in range(st["mujoco_steps"]):
        mujoco.mj_step1(m, d)
        mujoco.mj_step2(m, d)
    t_mj = time.perf_counter() - t0
    lib = mujoco_c(mujoco)
    mujoco.mj_resetData(m, d)
    mujoco_steps(lib[0], lib[1], m._address, d._address, 1)
    mujoco.mj_resetData(m, d)
    t0 = time.perf_counter()
    mujoco_steps(lib[0], lib[1], m._address, d._address, st["mujoco_steps"])
    t_mjc = time.perf_counter() - t0
    print(f"of which MuJoCo alone (mj_step1 + mj_step2, no forces): {t_mj / st['mujoco_steps'] * 1e6:.1f} us "
          f"per step through the bindings, {t_mjc / st['mujoco_steps'] * 1e6:.1f} us from compiled code")
    s = frogsim.SwimResult(rec=out["rec"], model=cm, stats=st, wall_s=best[True]).summary()
    print(f"result: {s['distance_m']:.2f} m in {s['duration_s']:g} s, {s['mean_speed_m_per_s']:.3f} m/s, "
          f"{s['air_used_per_cycle_L_std']:.2f} L air per cycle")
    ok = factor >= TARGET
    print(f"real-time factor: {factor:.1f} x (target >= {TARGET:g} x): {'MET' if ok else 'NOT MET'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
