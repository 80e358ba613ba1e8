"""Fit benchmark: four parameters fitted to one 2 s trace sampled at 1 kHz.

Run:  python benchmarks/bench_fit.py [--starts 4]

Case
    The example hip rig (examples/fit/rig.toml), its 6 bar trace (examples/fit/trace-6bar.csv:
    made from known parameters with 0.02 bar sensor noise and a 10-bit ADC over 0..10 bar). Fitted:
    the charge valve's sonic conductance C and critical ratio b, the hip's dead volume and the charge
    valve's dead time, from the spec's start plus Latin-hypercube starts.

Measured in one run
    * frogsim.fit: every Jacobian one batch of variants on the batched engine, the starts side by
      side on the 2 threads, the final central-difference Jacobian and the before/after runs included;
    * baseline: the same residuals, bounds, scaling and starts, driven by a plain loop of
      ``frogsim.simulate`` calls (scipy's least_squares with its own 2-point Jacobian, the same step),
      plus the same final central-difference Jacobian by the same loop.
    Both report wall time, model runs and the fitted values (they must agree: same problem).

Target: the frogsim.fit run in <= 10 s on a 2-core machine. Exit status 0 when met and both ways
find the truth within their 95 % intervals' reach, 1 otherwise.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import frogsim
from frogsim.fit import fit_spec, load_fit_spec
from frogsim.fit.core import Evaluator, start_points
from frogsim.fit.traces import simulated

TARGET_S = 10.0
EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "fit"
SPEC = {"base_dir": str(EXAMPLE), "scenario": "rig.toml", "noise": "0.02 bar", "seed": 1,
        "experiments": [{"trace": "trace-6bar.csv", "ignore_columns": ["valve temperature [degC]"]}],
        "parameters": {
            "valves.charge.sonic_conductance": {"min": "0.1 L/(s*bar)", "max": "1 L/(s*bar)", "start": "0.4 L/(s*bar)"},
            "valves.charge.critical_ratio": {"min": "0.1", "max": "0.6", "start": "0.38"},
            "muscle_types.hip.dead_volume": {"min": "1 cm^3", "max": "40 cm^3", "start": "5 cm^3"},
            "valves.charge.dead_time": {"min": "0 ms", "max": "20 ms", "start": "2 ms"}}}
TRUE = np.array([0.3e-8, 0.30, 12e-6, 5e-3])       # examples/fit/make_trace.py


def plain_loop(spec) -> tuple[np.ndarray, int, float]:
    """The same fit with one frogsim.simulate per residual: (values SI, model runs, seconds)."""
    from scipy.optimize import least_squares
    ev = Evaluator(spec)
    e = spec.experiments[0]
    runs = [0]

    def fun(theta):
        runs[0] += 1
        r = frogsim.simulate(e.scenario.replace(dict(zip(ev.paths, map(float, ev.x(theta))))))
        return ev.residual([r])

    t0 = time.perf_counter()
    best = None
    for th0 in start_points(spec, ev):
        sol = least_squares(fun, th0, jac="2-point", bounds=(0.0, 1.0), method="trf", x_scale=1.0,
                            diff_step=spec.diff_step, max_nfev=spec.max_evaluations)
        if best is None or sol.cost < best.cost:
            best = sol
    p = len(best.x)
    for j in range(p):                    # the final central-difference Jacobian, as the fit does
        for s in (+1, -1):
            fun(np.clip(best.x + s * spec.diff_step * np.eye(p)[j], 0.0, 1.0))
    fun(start_points(spec, ev)[0])        # and the before/after runs
    fun(best.x)
    return ev.x(best.x), runs[0], time.perf_counter() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--starts", type=int, default=4)
    args = ap.parse_args()
    spec = load_fit_spec({**SPEC, "starts": args.starts}, threads=2)
    frogsim.simulate(spec.base)                       # load the compiled engine outside the timings
    fit_spec(load_fit_spec({**SPEC, "starts": args.starts, "max_evaluations": 2}, threads=2))   # and the batch path
    print(f"4 parameters, one {spec.base.duration:g} s trace of {spec.experiments[0].trace.time.size} samples, "
          f"{args.starts} starts")
    t0 = time.perf_counter()
    res = fit_spec(spec)
    t_fit = time.perf_counter() - t0
    x_loop, n_loop, t_loop = plain_loop(spec)
    ok_time = t_fit <= TARGET_S
    within = np.all(np.abs(res.values - TRUE) <= 3 * np.maximum(res.ci_high - res.ci_low, 0) / 2)
    agree = np.allclose(x_loop, res.values, rtol=1e-3)
    print(f"  frogsim.fit (batched Jacobians): {t_fit:6.2f} s, {res.model_runs:5d} model runs "
          f"({t_fit / res.model_runs * 1e3:.1f} ms per model run, the fit's own work included)")
    print(f"  plain simulate loop            : {t_loop:6.2f} s, {n_loop:5d} model runs "
          f"({t_loop / n_loop * 1e3:.1f} ms per model run; {t_loop / t_fit:.2f} x the batched time)")
    for j, prm in enumerate(spec.parameters):
        print(f"  {prm.path:<34} fit {prm.shown(res.values[j]):>20}  loop {prm.shown(x_loop[j]):>20}  "
              f"truth {prm.shown(TRUE[j]):>20}  95 % CI {prm.shown(res.ci_low[j])} .. {prm.shown(res.ci_high[j])}")
    for w in res.warnings:
        print(f"  warning: {w}")
    print(f"target <= {TARGET_S:g} s: {'met' if ok_time else 'MISSED'}; truth within reach of the intervals: "
          f"{'yes' if within else 'NO'}; loop agrees with the fit: {'yes' if agree else 'no (different path, see values)'}")
    return 0 if ok_time and within else 1


if __name__ == "__main__":
    sys.exit(main())
