"""Wall heat transfer on against off: the workloads of bench_engine.py and bench_joint_control.py,
each with the parameter set "fan2017-heat" and with fan2017, in one run.

Run:  python benchmarks/bench_heat.py [--rounds 5] [--instructions]

Workloads (each in a fresh Python process running this checkout's ``src``, after one untimed call
that loads the Numba cache):
  engine  frogsim.simulate of bench_engine.py's cycle (one hip muscle, 2 s), 20 calls
  joint   frogsim.swim of bench_joint_control.py's closed-loop robot (12 muscles, 4 s), 1 call

Wall time: the two runs in turns, round after round, best of the rounds (this machine's speed
drifts with its load). ``--instructions`` also counts each workload's instructions with valgrind's
callgrind, switched on only around the timed calls (as bench_baseline.py does): counts do not drift
with the load. The verdict takes the instruction ratio when counted, else the wall ratio.

Target: heat on at most 15 % slower than off. Part of the difference is the engine's work per
right-hand side and part the dynamics: with heat, a vented muscle keeps warming and its air keeps
moving after the adiabatic run has come to rest, so the integrator takes more steps (shown).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from bench_baseline import TIMED_CALLS, callgrind_prefix, callgrind_total

HERE = Path(__file__).resolve().parent
TARGET = 1.15
CALLS = {"engine": 20, "joint": 1}

WORKLOAD = r'''
import json, os, subprocess, sys, time
sys.path.insert(0, sys.argv[4])
import frogsim
name, heat, n = sys.argv[1], sys.argv[2] == "on", int(sys.argv[3])
if name == "engine":
    from bench_engine import SCENARIO
    m = frogsim.build_model(frogsim.load_scenario({**SCENARIO, "parameters": "fan2017-heat"} if heat else SCENARIO))
    def once():
        return frogsim.simulate(m)
else:
    import bench_joint_control as B
    sc = B.scenario(True, B.HEAT_PARAMETERS if heat else None)
    def once():
        return frogsim.swim(sc)
stats = once().stats
''' + TIMED_CALLS + r'''print(json.dumps({"seconds_per_call": wall / n, "stats": stats}))
'''


def run(name: str, heat: str, env: dict, prefix=()) -> dict:
    p = subprocess.run([*prefix, sys.executable, "-c", WORKLOAD, name, heat, str(CALLS[name]), str(HERE)],
                       capture_output=True, text=True, env=env)
    if p.returncode != 0:
        raise SystemExit(f"{name} (heat {heat}) failed:\n{p.stderr[-2000:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def instructions(name: str, heat: str, env: dict, folder: str) -> float:
    out = os.path.join(folder, f"cg-{name}-{heat}.out")
    run(name, heat, dict(env, BENCH_CALLGRIND="1"), callgrind_prefix(out))
    return callgrind_total(out) / CALLS[name]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=5, help="rounds of turns, best taken (default 5)")
    ap.add_argument("--instructions", action="store_true", help="also count instructions with callgrind")
    args = ap.parse_args(argv)
    if args.instructions and shutil.which("valgrind") is None:
        raise SystemExit("--instructions needs valgrind (apt-get install valgrind)")
    # this checkout's code, whatever frogsim the interpreter has installed
    env = dict(os.environ, PYTHONHASHSEED="0", PYTHONPATH=str(HERE.parent / "src"))
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        for name in CALLS:
            best, stats = {"off": float("inf"), "on": float("inf")}, {}
            for _ in range(args.rounds):
                for heat in ("off", "on"):
                    r = run(name, heat, env)
                    best[heat] = min(best[heat], r["seconds_per_call"])
                    stats[heat] = r["stats"]
            ratio = best["on"] / best["off"]
            evals = {k: stats[k]["rhs_evaluations"] for k in stats}
            line = (f"{name:<7} off {best['off'] * 1e3:8.2f} ms  on {best['on'] * 1e3:8.2f} ms  wall ratio {ratio:.3f} "
                    f"(best of {args.rounds}; rhs evaluations {evals['off']} -> {evals['on']})")
            if args.instructions:
                ins = {heat: instructions(name, heat, env, tmp) for heat in ("off", "on")}
                ratio = ins["on"] / ins["off"]
                line += f"  instructions {ins['off'] / 1e6:.2f} M -> {ins['on'] / 1e6:.2f} M (ratio {ratio:.4f})"
            verdict = ratio <= TARGET
            ok &= verdict
            print(line + ("" if verdict else "  SLOWER than the target"), flush=True)
    print(f"{'PASS' if ok else 'FAIL'}: heat on at most {TARGET:g} x heat off")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
