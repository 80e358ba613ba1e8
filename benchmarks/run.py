"""Run every benchmark in this folder, one after another, and report each verdict.

Run:  python benchmarks/run.py

Each benchmark prints its own measurements (ratios against a baseline measured in the same run)
and exits 0 when its targets are met. Run on an otherwise idle machine: wall times depend on load.
"""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
BENCHMARKS = ("bench_engine.py", "bench_variants.py", "bench_sweep.py", "bench_swim.py", "bench_fit.py",
              "bench_control.py", "bench_envs.py", "bench_rl.py", "bench_joint_control.py", "bench_tune_joint.py",
              "bench_heat.py", "bench_sil.py", "bench_tune_board.py",
              "bench_fw_laws.py", "bench_solver_methods.py",
              "bench_baseline.py")


def main() -> int:
    verdicts = []
    for name in BENCHMARKS:
        print(f"\n===== {name} =====", flush=True)
        t0 = time.perf_counter()
        code = subprocess.call([sys.executable, str(HERE / name)])
        verdicts.append((name, code, time.perf_counter() - t0))
    print("\n===== summary =====")
    for name, code, wall in verdicts:
        print(f"{name:<18} {'PASS' if code == 0 else 'FAIL'}   ({wall:.0f} s)")
    return 0 if all(code == 0 for _, code, _ in verdicts) else 1


if __name__ == "__main__":
    sys.exit(main())
