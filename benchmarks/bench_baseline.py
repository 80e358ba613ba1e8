"""The same warm workloads on this code and on an earlier commit, in turns, in one run: is anything
slower than before?

Run:  python benchmarks/bench_baseline.py [--baseline REV] [--rounds 5] [--instructions]

The baseline's ``src`` folder is taken from the repository's history (``git archive``) into a
temporary folder; each workload runs in a fresh Python process with that folder (or this
checkout's ``src``) first on the path, after one untimed call that loads (or compiles) its Numba
cache. The two codes run in turns, round after round, and the best of the rounds counts: this
machine's speed drifts by tens of percent within minutes, so only a baseline timed in turns with
the run says whether it got slower.

Workloads (each timed as one block, seconds per call):
  simulate    frogsim.simulate of paper-cycle (six muscles, 2 s), 20 calls
  closed-loop frogsim.simulate of a bang-bang hold (one muscle, 2 s), 20 calls
  batch       run_models of 64 variants of paper-cycle (source pressure 3-6 bar) on 2 threads
  swim        frogsim.swim of "swim", 2 cycles (MuJoCo + pneumatics, 4000 steps)
  joint       frogsim.swim of "hip-angle-in-air" (closed-loop hip, 3000 steps)
  cold        ``frogsim reproduce`` with an empty Numba cache (compilation included), one run a round
              (wall time only: callgrind cannot count a compilation in reasonable time)

``--instructions`` also counts each workload's instructions with valgrind's callgrind, switched on
only around the timed calls (``callgrind_control -i on/off`` from the workload itself, so imports
and cache loading are not counted): instruction counts do not drift with the machine's load, so a
few percent show. It is slow (a few minutes a workload and code).

Verdict: exit 0 when no warm workload is more than 5 % slower than the baseline (best of rounds;
with --instructions, by instruction count) and the cold reproduce no more than 10 % (wall time).
"""
from __future__ import annotations

import argparse
import io
import json
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
#: the last commit before the controller kinds moved to one module each and the state layout
#: became one module (the change this benchmark was written to check)
BASELINE = "779615c"
TOLERANCE = 1.05
#: the cold run is judged by wall time alone, which drifts by about 10 % here even as best of rounds
TOLERANCE_COLD = 1.10

#: a workload's timed block: ``n`` calls of its ``once`` timed into ``wall``, and counted by
#: callgrind (started with --instr-atstart=no) only around them when BENCH_CALLGRIND=1, so that
#: imports and cache loading are not counted. Shared with bench_heat.py.
TIMED_CALLS = r'''
counting = os.environ.get("BENCH_CALLGRIND") == "1"     # under callgrind --instr-atstart=no
if counting:
    subprocess.run(["callgrind_control", "-i", "on", str(os.getpid())], check=True, capture_output=True)
t0 = time.perf_counter()
for _ in range(n):
    once()
wall = time.perf_counter() - t0
if counting:
    subprocess.run(["callgrind_control", "-i", "off", str(os.getpid())], check=True, capture_output=True)
'''

WORKLOAD = r'''
import json, os, subprocess, sys, time
import numpy as np
import frogsim
name, n = sys.argv[1], int(sys.argv[2])
if name == "simulate":
    sc = frogsim.load_scenario("paper-cycle")
    def once():
        frogsim.simulate(sc)
elif name == "closed-loop":
    sc = frogsim.load_scenario({"name": "hold", "parameters": "fan2017", "duration": "2 s",
        "output_interval": "1 ms", "controller": {"rate": "1 kHz"},
        "muscles": {"hip": {"type": "hip", "motion": {"kind": "constant"}}},
        "controllers": {"hold": {"kind": "bang-bang", "muscle": "hip", "band": "0.1 bar",
            "setpoint": {"kind": "sine", "mean": "3 bar", "amplitude": "1 bar", "frequency": "0.5 Hz"}}}})
    def once():
        frogsim.simulate(sc)
elif name == "batch":
    from frogsim.engine.batch import build_models, run_models
    base = frogsim.load_scenario("paper-cycle")
    pts = [{"source.initial_pressure_gauge": float(p)} for p in np.linspace(3e5, 6e5, 64)]
    def once():
        run_models(build_models(base, pts), threads=2)
elif name == "swim":
    rs = frogsim.load_robot_scenario("swim", cycles=2)
    def once():
        frogsim.swim(rs)
elif name == "joint":
    rs = frogsim.load_robot_scenario("hip-angle-in-air")
    def once():
        frogsim.swim(rs)
else:
    raise SystemExit(f"unknown workload {name}")
if n < 0:                       # warm-up only: load or compile the cache
    once()
    raise SystemExit(0)
once()
''' + TIMED_CALLS + r'''print(json.dumps({"seconds_per_call": wall / max(n, 1)}))
'''
CALLS = {"simulate": 20, "closed-loop": 20, "batch": 3, "swim": 2, "joint": 2}


def cold_reproduce(src: str, env: dict, folder: str) -> float:
    """Wall time [s] of ``frogsim reproduce`` into a new folder with a new, empty Numba cache."""
    import time
    out = tempfile.mkdtemp(dir=folder)
    e = dict(env, PYTHONPATH=src, PYTHONHASHSEED="0", NUMBA_CACHE_DIR=os.path.join(out, "numba"))
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "frogsim", "reproduce", "--out", os.path.join(out, "r")],
                       capture_output=True, text=True, env=e)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"cold reproduce failed with PYTHONPATH={src}:\n{p.stderr[-2000:]}")
    shutil.rmtree(out, ignore_errors=True)
    return wall


def src_of(rev: str, folder: str) -> str:
    blob = subprocess.run(["git", "-C", str(REPO), "archive", rev, "src"], capture_output=True,
                          check=True).stdout
    with tarfile.open(fileobj=io.BytesIO(blob)) as tar:
        tar.extractall(folder)
    return os.path.join(folder, "src")


def run(src: str, name: str, n: int, env: dict, prefix=()) -> subprocess.CompletedProcess:
    e = dict(env, PYTHONPATH=src, PYTHONHASHSEED="0")
    return subprocess.run([*prefix, sys.executable, "-c", WORKLOAD, name, str(n)], capture_output=True,
                          text=True, env=e)


def timed(src: str, name: str, env: dict) -> float:
    p = run(src, name, CALLS[name], env)
    if p.returncode != 0:
        raise SystemExit(f"{name} failed with PYTHONPATH={src}:\n{p.stderr[-2000:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])["seconds_per_call"]


def instructions(src: str, name: str, env: dict, folder: str) -> float:
    """Instructions per call: callgrind counting only around the timed calls (the workload
    switches it on and off with callgrind_control; imports and cache loading are not counted)."""
    n = CALLS[name]
    out = os.path.join(folder, f"cg-{name}-{abs(hash(src))}.out")
    p = run(src, name, n, dict(env, BENCH_CALLGRIND="1"), callgrind_prefix(out))
    if p.returncode != 0:
        raise SystemExit(f"callgrind of {name} failed:\n{p.stderr[-2000:]}")
    return callgrind_total(out) / n


def callgrind_prefix(out: str) -> tuple:
    """The command prefix that runs a workload under callgrind, counting off until the workload
    switches it on (:data:`TIMED_CALLS`), its output to ``out``."""
    return ("valgrind", "--tool=callgrind", "--instr-atstart=no", f"--callgrind-out-file={out}")


def callgrind_total(out: str) -> int:
    """The instructions callgrind counted (its last ``totals:`` line; ``summary:`` is the count at
    the start, 0 with --instr-atstart=no)."""
    totals = [int(line.split()[1]) for line in open(out) if line.startswith("totals:")]
    if not totals:
        raise SystemExit(f"no totals in {out}")
    return totals[-1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", default=BASELINE, help=f"the earlier commit (default {BASELINE})")
    ap.add_argument("--rounds", type=int, default=5, help="rounds of turns, best taken (default 5)")
    ap.add_argument("--only", nargs="*", choices=sorted(CALLS) + ["cold"], help="run only these workloads")
    ap.add_argument("--instructions", action="store_true", help="also count instructions with callgrind")
    args = ap.parse_args(argv)
    if args.instructions and shutil.which("valgrind") is None:
        raise SystemExit("--instructions needs valgrind (apt-get install valgrind)")
    names = args.only or list(CALLS) + ["cold"]
    with tempfile.TemporaryDirectory() as tmp:
        base = src_of(args.baseline, os.path.join(tmp, "base"))
        here = str(REPO / "src")
        env = dict(os.environ, NUMBA_CACHE_DIR="")
        codes = {"baseline": base, "this code": here}
        caches = {k: os.path.join(tmp, f"numba-{i}") for i, k in enumerate(codes)}
        print(f"baseline {args.baseline} against this checkout; {args.rounds} rounds in turns, best counts")
        for name in names:                       # warm-up: each code's own Numba cache
            if name == "cold":
                continue
            for k, src in codes.items():
                p = run(src, name, -1, dict(env, NUMBA_CACHE_DIR=caches[k]))
                if p.returncode != 0:
                    raise SystemExit(f"{name} ({k}) failed:\n{p.stderr[-2000:]}")
        ok = True
        for name in names:
            best = {k: float("inf") for k in codes}
            for _ in range(args.rounds):
                for k, src in codes.items():
                    t = (cold_reproduce(src, env, tmp) if name == "cold"
                         else timed(src, name, dict(env, NUMBA_CACHE_DIR=caches[k])))
                    best[k] = min(best[k], t)
            ratio = best["this code"] / best["baseline"]
            line = (f"{name:<12} baseline {best['baseline'] * 1e3:9.2f} ms  this code "
                    f"{best['this code'] * 1e3:9.2f} ms  ratio {ratio:.3f} (wall, best of {args.rounds})")
            if args.instructions and name != "cold":
                ins = {k: instructions(src, name, dict(env, NUMBA_CACHE_DIR=caches[k]), tmp)
                       for k, src in codes.items()}
                ratio = ins["this code"] / ins["baseline"]
                line += (f"  instructions {ins['baseline'] / 1e6:.2f} M -> {ins['this code'] / 1e6:.2f} M "
                         f"(ratio {ratio:.4f})")
            verdict = ratio <= (TOLERANCE_COLD if name == "cold" else TOLERANCE)
            ok &= verdict
            print(line + ("" if verdict else "  SLOWER"), flush=True)
    print("PASS: nothing slower than the baseline" if ok else f"FAIL: slower than {TOLERANCE:.2f} x the baseline")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
