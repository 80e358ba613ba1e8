"""Software in the loop of the whole robot on its own board: the exported firmware's machine code
on the emulated ATmega2560 (simavr) in lockstep with the coupled plant, on the board's own timing.

Run:  python benchmarks/bench_sil.py [--cycles N]          # default 5 gait cycles: 10 s

Workloads:

* ``swim-board`` (the shipped scenario): the swimming robot free in water, pump on, 12 muscles, a
  joint-angle controller on each of its six joints following the gait's angle profile (PD angle
  loops at 250 Hz, staggered; pressure relays at 1 kHz), twelve pressures on the ADC and six
  quadrature encoders of 8000 counts per revolution, serial log at 50 Hz;
* ``earlier robot``: the robot as this benchmark ran it before ``swim-board`` existed (the robot
  with antagonistic muscles, five joint-angle controllers on potentiometers holding constant
  angles, the sixth joint on its gait: 15 analog inputs), the firmware that overran every sample.

For each the firmware is exported and built first (not timed; written even where it does not
fit, as --allow-overrun would), then the SIL run of swim-board is timed twice in one process
(both printed: the first includes the start-up, loading the compiled code's caches and building
the model; the best counts), the earlier robot once, split into the emulated AVR and the rest
(the plant, the twins' checks).

Targets for swim-board (printed with PASS/FAIL): SIL at least 2x real time on one core; mean
interrupt load at most 60 %, worst at most 85 %, chip awake at most 90 %, 0 overruns, 0 dropped
log records, 0 valve events lost (its log's format 4: every valve command in the log), 0
mismatched samples, each joint's tracking RMS within 10 % of the compiled float run's. Printed
too: the valve events the log carried, the most in one record against its slots, and the
switchings read back from them.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from bench_joint_control import scenario as joint_scenario  # noqa: E402

SPEED_TARGET = 2.0


def earlier_robot(cycles: int):
    """The robot with five joint-angle controllers on potentiometers (constant setpoints)."""
    import frogsim
    rs0 = joint_scenario(controlled=True)
    raw = {**rs0.raw, "base_dir": rs0.pneumatic.base_dir, "firmware": {}}
    raw["controllers"] = {name: {**c, "setpoint": c["setpoint"]["mean"]}
                          for name, c in list(raw["controllers"].items())[:5]}
    raw["gait"] = {**raw["gait"], "period": "2 s", "cycles": cycles}
    return frogsim.load_robot_scenario(raw)


def run(rs, rounds: int):
    from frogsim.control import firmware as fw
    from frogsim.export import sil, sketch
    plan = fw.firmware_plan(rs)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        sketch.write_sketch(plan, out, rs.name)
        built = sketch.build_sketch(out, plan.name)
        rec = sketch.read_plan_record(out)
        rec["flash_bytes"], rec["ram_bytes"] = built.flash_bytes, built.ram_bytes
        best, result, walls = float("inf"), None, []
        for _ in range(rounds):
            t0 = time.perf_counter()
            r = sil.run_robot(rs, rec, built.elf, plan, fw.adc_counts, compare=False)
            wall = time.perf_counter() - t0
            walls.append(wall)
            if wall < best:
                best, result = wall, r
    if rounds > 1:
        print(f"  {rs.name}: {rounds} runs of {rs.duration:g} s: "
              + ", ".join(f"{w:.2f} s wall ({rs.duration / w:.2f} x)" for w in walls)
              + " (the first loads the compiled code's caches and builds the model: start-up included)")
    return plan, built, best, result, rec


def report(name, rs, plan, built, wall, r, rec) -> dict:
    s = r.sil
    speed = rs.duration / wall
    load = s["cpu_load_percent"]
    lr = s["log_records"]
    print(f"{name}: {len(plan.muscles)} muscles, {len(plan.channels)} channels, ADC prescaler {plan.adc.prescaler} "
          f"({plan.adc.bits} bits); flash {built.flash_bytes} B, RAM {built.ram_bytes} B")
    if s["board_process"]:
        where = (f"the board in its own process: emulated AVR {s['avr_wall_s']:.1f} s; the plant "
                 f"{s['plant_wall_s']:.1f} s, waiting for the board {s['plant_waited_s']:.1f} s")
    else:
        where = f"in one process: emulated AVR {s['avr_wall_s']:.1f} s, plant and checks {wall - s['avr_wall_s']:.1f} s"
    print(f"  SIL of {rs.duration:g} s: {wall:.1f} s wall = {speed:.2f} x real time; {where}")
    print(f"  interrupt load mean {load['mean']:.1f} % max {load['max']:.1f} %, chip awake {s['awake_percent']:.1f} %, "
          f"{s['effective_rate_hz']:.1f} Hz effective, overruns {s['overruns']}, late {s['samples_late']}, "
          f"skipped {s['samples_skipped']}, log records {lr['received']}/{lr['made']} (dropped {lr['dropped']}, "
          f"unsent {lr['unsent']}), mismatched {s['mismatched_samples']}, response max "
          f"{s['response_us']['max']:.0f} us")
    from frogsim.export.serial_log import commands, parse_log
    log = parse_log(r.serial, rec)
    out = {"speed": speed, **s, "events_lost": None}
    if rec.get("event_slots"):
        n_ch = len(rec["channels"])
        per = [row[1 + n_ch + 4] for row in log.records]
        out["events_lost"] = log.events_lost
        print(f"  valve events (format 4): {sum(per)} in {len(per)} records, at most {max(per)} in one of "
              f"{rec['event_slots']} slots, {log.events_lost} lost in {log.records_with_lost} records")
        if not log.events_lost:
            k, modes = commands(log, rec, last_sample=s["samples"] - 1)
            print(f"  commands of samples {k[0]}..{k[-1]} from the log: {int((modes[1:] != modes[:-1]).sum())} "
                  "switchings")
    elif rec.get("history_samples"):
        print(f"  valve histories of {rec['history_samples']} samples (format 3)")
    else:
        print("  no valve commands in the log (format 3 without histories)")
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cycles", type=int, default=5, help="gait cycles of 2 s (default 5: 10 s)")
    args = ap.parse_args()
    import dataclasses

    import frogsim
    from frogsim.export.emulator import ToolMissing
    try:
        board = frogsim.load_robot_scenario("swim-board", cycles=args.cycles)
        rounds = 2
        res = run(board, rounds)
        s = report("swim-board", board, *res)
        floats = dataclasses.replace(board, pneumatic=dataclasses.replace(board.pneumatic, firmware=None))
        r_float = frogsim.swim(floats).control_metrics()
        r_sil = res[3].result.control_metrics()
        worst = 0.0
        for name, entry in r_float.items():
            if name == "robot" or "tracking_error_rms_deg" not in entry:
                continue
            a, b = r_sil[name]["tracking_error_rms_deg"], entry["tracking_error_rms_deg"]
            worst = max(worst, a / b)
            print(f"  {name}: tracking RMS {a:.2f} deg on the board, {b:.2f} deg compiled float ({a / b:.2f} x)")
        earlier = earlier_robot(min(args.cycles, 1))
        report("earlier robot (one cycle)", earlier, *run(earlier, 1))
    except ToolMissing as exc:
        print(f"FAIL: {exc}")
        return 1
    load = s["cpu_load_percent"]
    checks = [("SIL speed", s["speed"] >= SPEED_TARGET, f"{s['speed']:.2f} x real time (target {SPEED_TARGET:g}x)"),
              ("mean load", load["mean"] <= 60.0, f"{load['mean']:.1f} % (<= 60 %)"),
              ("worst load", load["max"] <= 85.0, f"{load['max']:.1f} % (<= 85 %)"),
              ("awake", s["awake_percent"] <= 90.0, f"{s['awake_percent']:.1f} % (<= 90 %)"),
              ("overruns", s["overruns"] == 0, str(s["overruns"])),
              ("dropped records", s["log_records"]["dropped"] == 0, str(s["log_records"]["dropped"])),
              ("valve events lost", not s["events_lost"], str(s["events_lost"])),
              ("mismatched samples", s["mismatched_samples"] == 0, str(s["mismatched_samples"])),
              ("tracking against float", worst <= 1.10, f"worst joint {worst:.2f} x the compiled float RMS (<= 1.10)")]
    for name, ok, text in checks:
        print(f"{'PASS' if ok else 'FAIL'}: swim-board {name}: {text}")
    return 0 if all(ok for _, ok, _ in checks) else 1


if __name__ == "__main__":
    sys.exit(main())
