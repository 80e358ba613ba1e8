"""The fixed-step integration method ("rk4") against the default ("dopri-rosenbrock"): accuracy,
stability and speed on the paper's pneumatic cycle and on the swimming robot.

Run:  python benchmarks/bench_solver_methods.py [--steps 1 0.5 0.25 0.1] [--cycles 4] [--repeats 3]

Cases
    paper-cycle  the shipped scenario (six muscles, 2 s, the paper's Figure 8 cycle), pneumatics
                 alone (frogsim.simulate): max |p - p_default| over the six muscles and the source
                 [bar], at the 1 ms output rows; wall time per run (best of --repeats, after one
                 untimed run that loads the Numba cache); accepted steps.
    swim         the shipped robot scenario (MuJoCo coupled, the pneumatics advanced once per 1 ms
                 MuJoCo step), --cycles gait cycles: max |angle - angle_default| over the six
                 joints [deg], max pressure error [bar], distance swum (forward position at the
                 end) [m] and its difference to the default's [um]; wall time of the steps.
    stiffness    the spectral radius |lambda| of the circuit's Jacobian df/dy (central differences
                 of frogsim.circuit.rhs.rhs over the masses and pressures) at every 10th output row
                 of the default run of paper-cycle, and the step the classical Runge-Kutta method's
                 stability interval allows there, 2.785 / |lambda| (Hairer and Wanner, Solving ODEs
                 II, Sec. IV.2).

Each difference is given to the default method as shipped (rtol 1e-7) and to the default at rtol
1e-12 (the reference), so that a difference smaller than
the default's own error shows as such. Prints one table per case, headed with the machine (host
name, CPU, cores). Exit status 0.
"""
from __future__ import annotations

import argparse
import os
import platform
import time


def machine() -> str:
    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next(line.split(":", 1)[1].strip() for line in fh if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{platform.node()} ({cpu or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()})"


def _scenario(name, method, rtol=None):
    """The shipped scenario ``name`` as a raw table, with [solver] method (and rtol) set."""
    import tomllib
    from frogsim.scenario.load import SCENARIOS_DIR
    with open(SCENARIOS_DIR / f"{name}.toml", "rb") as fh:
        raw = tomllib.load(fh)
    raw.setdefault("solver", {})["method"] = method
    if rtol is not None:
        raw["solver"]["rtol"] = rtol
    return raw


TIGHT = 1e-12     # the reference: the default method at this rtol


def paper_cycle(steps, repeats):
    import numpy as np
    import frogsim
    from frogsim.errors import SimulationError

    def run(method, rtol=None, timed=True):
        sc = frogsim.load_scenario(_scenario("paper-cycle", method, rtol))
        r = frogsim.simulate(sc, progress=False)          # loads (or compiles) the cache
        best = float("inf")
        for _ in range(repeats if timed else 0):
            t0 = time.perf_counter()
            r = frogsim.simulate(sc, progress=False)
            best = min(best, time.perf_counter() - t0)
        return r, best

    tight, _ = run("dopri-rosenbrock", TIGHT, timed=False)
    ref, t_ref = run("dopri-rosenbrock")
    names = ref.model.names

    def pressures(r):
        return np.column_stack([r.muscle_pressure(m) for m in names] + [r.source_pressure])

    p_ref, p_tight = pressures(ref), pressures(tight)
    print("\npaper-cycle (pneumatics alone, 2 s, six muscles; max |dp| over the muscles and the source at the "
          "1 ms output rows)")
    print(f"{'method':28s} {'vs default [bar]':>17s} {f'vs rtol {TIGHT:g} [bar]':>21s} {'steps':>7s} "
          f"{'rhs evals':>10s} {'wall [ms]':>10s} {'x real time':>12s}")

    def row(label, r, t):
        print(f"{label:28s} {np.max(np.abs(pressures(r) - p_ref)) / 1e5:17.2e} "
              f"{np.max(np.abs(pressures(r) - p_tight)) / 1e5:21.2e} {r.stats['steps']:7d} "
              f"{r.stats['rhs_evaluations']:10d} {t * 1e3:10.2f} {2.0 / t:12.0f}")

    row("dopri-rosenbrock (default)", ref, t_ref)
    for h in steps:
        label = f"rk4, step {h:g} ms"
        try:
            r, t = run({"name": "rk4", "step": f"{h} ms"})
        except SimulationError as exc:
            print(f"{label:28s} failed: {str(exc)[:80]}")
            continue
        row(label, r, t)


def swim(steps, cycles):
    import numpy as np
    import frogsim
    from frogsim.errors import SimulationError
    from frogsim.robot.scenario import load_robot_scenario

    def run(method, rtol=None):
        rs = load_robot_scenario(_scenario("swim", method, rtol))
        frogsim.swim(rs, cycles=1)                        # loads (or compiles) the cache
        return frogsim.swim(rs, cycles=cycles)

    tight = run("dopri-rosenbrock", TIGHT)
    ref = run("dopri-rosenbrock")

    def distance(r):
        return float(r.forward[-1] - r.forward[0])

    print(f"\nswim (MuJoCo coupled, {cycles} cycles = {cycles * 2} s, 1 ms MuJoCo step; differences to the "
          f"default, and [in brackets] to the default at rtol {TIGHT:g})")
    print(f"{'method':28s} {'max |dangle| [deg]':>22s} {'max |dp| [bar]':>20s} {'distance [m]':>13s} "
          f"{'ddist [um]':>20s} {'steps':>7s} {'wall [s]':>9s} {'x real time':>12s}")

    def row(label, r):
        da = [np.degrees(np.max(np.abs(r.joint_angles - x.joint_angles))) for x in (ref, tight)]
        dp = [np.max(np.abs(r.pressures - x.pressures)) / 1e5 for x in (ref, tight)]
        dd = [(distance(r) - distance(x)) * 1e6 for x in (ref, tight)]
        print(f"{label:28s} {da[0]:10.2e} [{da[1]:9.2e}] {dp[0]:9.2e} [{dp[1]:8.2e}] {distance(r):13.4f} "
              f"{dd[0]:9.3f} [{dd[1]:8.3f}] {r.stats['pneumatic_steps']:7d} {r.wall_s:9.3f} {2.0 * cycles / r.wall_s:12.1f}")

    row("dopri-rosenbrock (default)", ref)
    for h in steps:
        label = f"rk4, step {h:g} ms"
        try:
            r = run({"name": "rk4", "step": f"{h} ms"})
        except SimulationError as exc:
            print(f"{label:28s} failed: {str(exc)[:80]}")
            continue
        row(label, r)


def stiffness():
    import numpy as np
    import frogsim
    from frogsim.circuit.layout import physical_size
    from frogsim.circuit.rhs import rhs
    r = frogsim.simulate(frogsim.load_scenario("paper-cycle"), progress=False)
    g, mp, mot_t, mot_L, mot_d, mot_n = r.model.rhs_model
    n = mp.shape[0]
    ny = r.y.shape[1]
    m = physical_size(n)
    aux, work, f1, f2 = np.zeros(2 * n + 1), np.zeros(4 * n), np.zeros(ny), np.zeros(ny)
    radius = []
    for k in range(0, r.t.size, 10):
        y, u, pump = r.y[k].copy(), r.u[k, :-1].copy(), float(r.u[k, -1])
        J = np.zeros((m, m))
        for c in range(m):
            d = 1e-7 * max(abs(y[c]), 1e-12)
            yp, ym = y.copy(), y.copy()
            yp[c] += d
            ym[c] -= d
            rhs(r.t[k], yp, u, pump, g, mp, mot_t, mot_L, mot_d, mot_n, f1, aux, work)
            rhs(r.t[k], ym, u, pump, g, mp, mot_t, mot_L, mot_d, mot_n, f2, aux, work)
            J[:, c] = (f1[:m] - f2[:m]) / (2 * d)
        radius.append(np.max(np.abs(np.linalg.eigvals(J))))
    radius = np.array(radius)
    print("\nstiffness of paper-cycle's circuit (spectral radius of df/dy at every 10th output row)")
    for q in (50, 90, 99, 100):
        rho = np.percentile(radius, q)
        print(f"  {q:3d}th percentile |lambda| = {rho:10.3g} 1/s: rk4 stable up to {2.785 / rho * 1e3:8.3g} ms")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=float, nargs="+", default=[1.0, 0.5, 0.25, 0.1], help="rk4 steps [ms]")
    ap.add_argument("--cycles", type=int, default=4, help="swim cycles")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    print(f"bench_solver_methods on {machine()}")
    paper_cycle(args.steps, args.repeats)
    swim(args.steps, args.cycles)
    stiffness()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
