"""Variant benchmark: 10,000 Latin-hypercube points of four parameters, from spec to built models.

Run:  python benchmarks/bench_variants.py [--points 10000] [--ref-points 200]

Case
    One hip muscle, the paper's 2 s cycle. Four parameters sampled by a Latin hypercube: source
    pressure 3..6 bar gauge, charge valve sonic conductance 0.2..0.8 L/(s bar), its critical ratio
    0.2..0.5, the muscle's dead volume 5..25 cm^3. Every value is distinct, so nothing is shared
    between points but what the cached model parts find unchanged.

Measured in one run
    * the sweep spec read and its 10,000 points generated (values parsed once, at the spec's edge);
    * the 10,000 typed variants (``scenario.replace``: field bounds and cross-field rules);
    * their 10,000 models (``build_model`` from cached parts);
    * baseline, the way before typed variants: each point written as unit text into the scenario
      dict, parsed and validated by the loader and built (``with_overrides`` + ``load_scenario`` +
      ``build_model``), timed on ``--ref-points`` points and scaled;
    * the check that both ways give the same model arrays on those points (up to the last bit of
      a unit conversion).

    * the same spec read by the code before typed variants (commit BASELINE, taken from this
      repository's history with ``git archive`` and run in a subprocess), whose every generated value
      was written as text and parsed back.

Target: the spec read and its 10,000 points generated in <= 0.3 s. The variants and models are
reported beside it (they are the per-point cost a sweep pays when it runs). Exit status 0 when the
target is met and the models agree with the loader's, 1 otherwise.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

import frogsim
from frogsim.engine.batch import build_models
from frogsim.sweep import load_spec

TARGET_S = 0.3
BASELINE = "e625af2"           # the last commit before typed variants
BASE = {"name": "bench-variants", "parameters": "fan2017", "duration": "2 s", "output_interval": "1 ms",
        "programs": {"stroke": {"pressurise": "1 s", "release": "1 s"}},
        "muscles": {"hip": {"type": "hip", "program": "stroke"}}}
RANGES = {"source.initial_pressure_gauge": ("3 bar", "6 bar"),
          "valves.charge.sonic_conductance": ("0.2 L/(s*bar)", "0.8 L/(s*bar)"),
          "valves.charge.critical_ratio": (0.2, 0.5),
          "muscle_types.hip.dead_volume": ("5 cm^3", "25 cm^3")}
UNITS = {"source.initial_pressure_gauge": (1e5, "bar"), "valves.charge.sonic_conductance": (1e-8, "L/(s*bar)"),
         "valves.charge.critical_ratio": (1.0, ""), "muscle_types.hip.dead_volume": (1e-6, "cm^3")}


def baseline_spec_seconds(spec_dict: dict, folder) -> float | None:
    """Seconds the code of BASELINE takes to read the same spec (warm, in its own process), or
    None when the repository's history is not at hand."""
    import json
    import subprocess
    import tarfile
    import io
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    try:
        blob = subprocess.run(["git", "-C", repo, "archive", BASELINE, "src"], capture_output=True,
                              check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        print("  (baseline skipped: no git history here)")
        return None
    old = folder / "baseline"
    with tarfile.open(fileobj=io.BytesIO(blob)) as tar:
        tar.extractall(old)
    code = ("import json, sys, time; from frogsim.sweep import load_spec; d = json.loads(sys.argv[1]); "
            "load_spec(d, sys.argv[2]); t = time.perf_counter(); load_spec(d, sys.argv[2]); "
            "print(time.perf_counter() - t)")
    out = subprocess.run([sys.executable, "-c", code, json.dumps(spec_dict), str(folder)], capture_output=True,
                         text=True, env={**os.environ, "PYTHONPATH": str(old / "src")})
    if out.returncode != 0:
        print(f"  (baseline failed: {out.stderr.strip().splitlines()[-1] if out.stderr.strip() else '?'})")
        return None
    return float(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=int, default=10000)
    ap.add_argument("--ref-points", type=int, default=200)
    args = ap.parse_args(argv)
    import tempfile
    from pathlib import Path
    from frogsim.sweep.spec import dumps_toml
    folder = Path(tempfile.mkdtemp())
    (folder / "base.toml").write_text(dumps_toml(BASE))
    spec_dict = {"base": "base.toml", "sweep": {"method": "lhs", "samples": args.points, "seed": 1,
                                                 "parameters": {p: {"min": lo, "max": hi} for p, (lo, hi) in RANGES.items()}},
                 "record": {"metrics": ["rise_time"], "muscle": "hip"}}
    print(f"frogsim {frogsim.__version__} variant benchmark: {args.points} LHS points x 4 parameters, "
          f"{os.cpu_count()} CPUs")
    load_spec(spec_dict, folder)              # warm: imports, unit registry, caches of the base
    t0 = time.perf_counter()
    spec = load_spec(spec_dict, folder)
    t1 = time.perf_counter()
    points = spec.points()
    variants = [spec.scenario.replace(p) for p in points]
    t2 = time.perf_counter()
    models = [frogsim.build_model(v) for v in variants]
    t3 = time.perf_counter()
    total = t3 - t0
    n = len(points)
    print(f"  spec and points          {t1 - t0:7.3f} s")
    print(f"  typed variants           {t2 - t1:7.3f} s   ({(t2 - t1) / n * 1e6:.0f} us per point)")
    print(f"  models                   {t3 - t2:7.3f} s   ({(t3 - t2) / n * 1e6:.0f} us per point)")
    print(f"  total                    {total:7.3f} s")
    points_s = t1 - t0
    old_spec = baseline_spec_seconds(spec_dict, folder)
    if old_spec is not None:
        print(f"  the same spec before typed variants ({BASELINE}): {old_spec:.3f} s -> "
              f"{old_spec / points_s:.1f}x faster now")
    base = frogsim.load_scenario(folder / "base.toml")
    raw = base.raw
    ref = range(min(args.ref_points, n))
    t0 = time.perf_counter()
    old = []
    for k in ref:
        text = {}
        for p, x in points[k].items():
            f, unit = UNITS[p]
            text[p] = f"{x / f!r} {unit}" if unit else x
        old.append(frogsim.build_model(frogsim.load_scenario(frogsim.with_overrides(raw, text))))
    per_old = (time.perf_counter() - t0) / len(ref)
    print(f"  unit-text overrides + loader + build: {per_old * 1e6:.0f} us per point -> "
          f"{per_old * n:.2f} s for {n}; typed variants are {per_old * n / total:.1f}x faster")
    worst = 0.0
    for k, m in zip(ref, old):
        for a in ("g", "mp", "y0", "atol", "mot_L", "sched_t"):
            x, y = getattr(m, a), getattr(models[k], a)
            worst = max(worst, float(np.max(np.abs(x - y) / np.maximum(np.abs(y), 1e-300))))
    print(f"  largest relative difference of the model arrays: {worst:.1e}")
    ok = points_s <= TARGET_S and worst < 1e-14
    print(("PASS" if ok else "FAIL") + f": spec and points {points_s:.3f} s (target {TARGET_S:g} s), "
          f"variants + models {t3 - t1:.2f} s, agreement {worst:.1e}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
