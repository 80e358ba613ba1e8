"""The tuned firmware of `swim-board` confirmed in software in the loop: `frogsim tune` on the
board's own integer laws, the best gains patched in, exported, built and run on the emulated
ATmega2560 against the swimming robot, and each joint's tracking RMS compared with the float law's
for the same gains.

Run:  python benchmarks/bench_tune_board.py [--trials 100] [--workers 2] [--out DIR] [--free band] [--free derivative_gain]

The steps are the user's commands, each in a fresh process:

1. ``frogsim tune swim-board --spec tune.toml --trials N --workers 2``: the shipped scenario (the
   swimming robot free in water, six joint-angle controllers following the gait's 0.5 Hz sines,
   10 s), each trial a compiled run with the board's integer twins (the scenario has
   ``[firmware]``); left and right tied (15 gains searched), the integral gains fixed at 0 (the
   board's loops are PD: it does not measure the source pressure, and an integral winds up
   against targets the valves cannot reach, scenario file and docs/firmware.md), and two bounds
   the board sets: the relays' bands from 0.05 bar up (one count of the board's 8-bit conversion
   of the 0-10 bar transducer is 0.0488 bar: a narrower band is not a band on the board) and the
   derivative gains up to 1 bar s/rad (the board's velocity is the angle's backward difference
   over 3 ms: one encoder count, 2 pi / 8000 rad, in 3 ms is 0.26 rad/s, a step of Kd x 0.26 rad/s
   in the pressure difference; at 1 bar s/rad, the starting gains', 0.26 bar); tracking minimised
   at no more air than the scenario's own gains (``[tune.at_most] air = 1``); ``--free band``,
   ``--free derivative_gain`` search a gain over the kind's default range instead (0.01-1 bar,
   0-8 bar s/rad);
2. ``frogsim firmware swim-board --patch best.toml --build`` and ``frogsim sil swim-board --patch
   best.toml --firmware fw``: the tuned firmware's machine code in SIL (summary.json "sil",
   "compiled": the SIL run's RMS against the compiled integer twin on time and against the
   compiled float laws, the same gains without ``[firmware]``);
3. the same SIL run for the scenario's own gains, for comparison.

Target (issue 28, printed PASS or FAIL): each joint's SIL tracking RMS with the tuned gains within
10 % of the float law's RMS for the same gains (|SIL / float - 1| <= 0.10). Printed beside it, per
joint: the starting and tuned RMS in SIL, in the compiled integer twin and in the float law, and
the two ratios that split the gap: the board's timing (SIL over the integer twin on time) and the
integer law (the twin over the float law). docs/control.md, "The tuned firmware in SIL", quotes
these figures.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_tune_joint import machine  # noqa: E402

JOINTS = ("hip", "knee", "ankle")
SIDES = ("left", "right")
TOLERANCE = 0.10           # |SIL / float - 1| for the tuned gains
BOUNDED = ("band", "derivative_gain")       # the board's bounds on the search (module docstring)
BOUND_TEXT = {"band": "bands >= 0.05 bar", "derivative_gain": "Kd <= 1 bar s/rad"}
JOINT_TARGETS = {"hip": 3.0, "knee": 2.0, "ankle": 1.5}     # [deg] issue 28's, for bench_tune_joint.py's case
SPEC = """[tune]
tie = [["hip_left", "hip_right"], ["knee_left", "knee_right"], ["ankle_left", "ankle_right"]]
[tune.weights]
tracking = 1.0
[tune.at_most]
air = 1.0
[tune.gains.hip_left]
integral_gain = "0 bar/(rad*s)"
band = ["0.05 bar", "1 bar"]
derivative_gain = ["0 bar*s/rad", "1 bar*s/rad"]
[tune.gains.knee_left]
integral_gain = "0 bar/(rad*s)"
band = ["0.05 bar", "1 bar"]
derivative_gain = ["0 bar*s/rad", "1 bar*s/rad"]
[tune.gains.ankle_left]
integral_gain = "0 bar/(rad*s)"
band = ["0.05 bar", "1 bar"]
derivative_gain = ["0 bar*s/rad", "1 bar*s/rad"]
"""


def unbounded(spec: str, free) -> str:
    """The spec without the board's bounds on the gains ``free`` (they take the kind's default
    ranges)."""
    return "".join(line for line in spec.splitlines(keepends=True)
                   if not line.startswith(tuple(f"{g} =" for g in free)))


def frogsim(*argv) -> float:
    """Run ``python -m frogsim ARGV --quiet`` in a fresh process; its wall time [s]."""
    env = {**os.environ, "PYTHONPATH": str(HERE.parent / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "frogsim", *map(str, argv), "--quiet"], env=env,
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"FAIL: frogsim {' '.join(map(str, argv))} exited {done.returncode}: "
                         f"{done.stderr.strip()[-2000:]}")
    return time.perf_counter() - t0


def on_board(folder: Path, patch: Path | None) -> dict:
    """Export, build and run in SIL the scenario (with ``patch`` laid over it); the summary's
    "sil" section."""
    extra = ["--patch", patch] if patch is not None else []
    frogsim("firmware", "swim-board", *extra, "--out", folder / "fw", "--build")
    frogsim("sil", "swim-board", *extra, "--firmware", folder / "fw", "--out", folder / "sil", "--no-animation")
    return json.loads((folder / "sil" / "summary.json").read_text())["sil"]


def rms(sil: dict, controller: str) -> dict:
    """SIL, integer twin on time and float law tracking RMS [deg] of one controller."""
    cell = sil["compiled"]["controllers"][controller]["tracking_error_rms_deg"]
    return {"sil": cell["sil"], "twin": cell["compiled"], "float": cell["compiled_float"]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=None, help="a folder for the runs (default: a temporary one)")
    ap.add_argument("--free", action="append", choices=BOUNDED, default=[],
                    help="search this gain over the kind's default range, not the board's bound (repeatable)")
    args = ap.parse_args()
    print(f"machine: {machine()}")
    tmp = tempfile.TemporaryDirectory(prefix="bench-tune-board-")
    root = Path(args.out) if args.out else Path(tmp.name)
    root.mkdir(parents=True, exist_ok=True)
    spec = root / "tune.toml"
    spec.write_text(unbounded(SPEC, args.free))
    bounds = ", ".join([f"{g} over the kind's range" for g in args.free]
                       + [BOUND_TEXT[g] for g in BOUNDED if g not in args.free])
    print(f"running: frogsim tune swim-board --spec tune.toml --trials {args.trials} --workers {args.workers} "
          f"(left = right, integral gains 0, {bounds}, tracking minimised at no more air than the starting gains)",
          flush=True)
    wall = frogsim("tune", "swim-board", "--spec", spec, "--trials", args.trials, "--workers", args.workers,
                   "--out", root / "tune", "--overwrite")
    s = json.loads((root / "tune" / "summary.json").read_text())
    print(f"  {s['trials']} trials in {wall:.0f} s ({s['trials_complete']} complete, {s['trials_pruned']} pruned, "
          f"{s['trials_failed']} failed); best trial {s['best_trial']}: objective {s['best']['score']:.3f} "
          f"(start 1), air {s['best']['terms']['air']:.3f} x the start's")
    gains = s["best_gains"]
    for j in JOINTS:
        g = {k.rsplit(".", 1)[1]: v for k, v in gains.items() if k.startswith(f"controllers.{j}_left.")}
        print(f"  tuned {j}: " + ", ".join(f"{k} {v}" for k, v in sorted(g.items())))
    print("SIL of the starting gains, then of the tuned ones (export, build, 10 s on the emulated board) ...",
          flush=True)
    start = on_board(root / "start", None)
    tuned = on_board(root / "tuned", root / "tune" / "best.toml")
    print(f"  tuned firmware: mismatched samples {tuned['mismatched_samples']}, overruns {tuned['overruns']}, "
          f"interrupt load mean {tuned['cpu_load_percent']['mean']:.1f} % max {tuned['cpu_load_percent']['max']:.1f} %")
    print("tracking RMS [deg] (SIL / integer twin on time / float law) and ratios:")
    worst, rows = 0.0, []
    for j in JOINTS:
        for side in SIDES:
            c = f"{j}_{side}"
            a, b = rms(start, c), rms(tuned, c)
            ratio = b["sil"] / b["float"]
            worst = max(worst, abs(ratio - 1.0))
            rows.append((c, ratio))
            print(f"  {c:<12} start {a['sil']:.2f} / {a['twin']:.2f} / {a['float']:.2f} (SIL/float {a['sil'] / a['float']:.2f})"
                  f"   tuned {b['sil']:.2f} / {b['twin']:.2f} / {b['float']:.2f}: SIL/float {ratio:.2f} = "
                  f"timing (SIL/twin) {b['sil'] / b['twin']:.2f} x integer law (twin/float) {b['twin'] / b['float']:.2f}")
    air = {k: sum(v["air_used_L_std"]["sil"] for v in r["compiled"]["controllers"].values())
           for k, r in (("start", start), ("tuned", tuned))}
    print(f"  air in SIL over 10 s: start {air['start']:.2f} L std, tuned {air['tuned']:.2f} L std")
    for j, target in JOINT_TARGETS.items():
        got = max(tuned["compiled"]["controllers"][f"{j}_{side}"]["tracking_error_rms_deg"]["sil"] for side in SIDES)
        print(f"  {j}: {got:.2f} deg in SIL, the worse side, against issue 28's {target:g} deg for the 1 Hz case of "
              f"bench_tune_joint.py ({'under' if got <= target else 'over'} it; this case's sines are 0.5 Hz)")
    ok = worst <= TOLERANCE
    print(f"{'PASS' if ok else 'FAIL'}: tuned swim-board firmware in SIL within {TOLERANCE:.0%} of the float law's "
          f"RMS: worst joint {max(rows, key=lambda r: abs(r[1] - 1))[0]} at {max(rows, key=lambda r: abs(r[1] - 1))[1]:.2f} x")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
