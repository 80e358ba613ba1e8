"""Closed-loop joint control of the full robot: speed of the coupled engine with a compiled
joint-angle controller on every joint.

Run:  python benchmarks/bench_joint_control.py

Scenario: the shipped ``swim`` robot with antagonistic recovery muscles (12 muscles, 24 valves),
free in water, pump on; each of the six leg joints under a compiled joint-angle controller
(1 kHz, 2 ms valve dead time, PID on the angle, bang-bang band 0.1 bar) tracking a 1 Hz sine
about the middle of its range; 4 s simulated. Baseline in the same run: the same robot open loop
(the scenario's gait, no controllers).

Target: 50x real time on one core. Printed honestly with PASS/FAIL; the coupled loop's own
speed (MuJoCo steps and the per-step kernel) sets most of it.

Wall heat transfer: the closed-loop robot again with the parameter set "fan2017-heat" (heat through
the walls of every muscle, the source and the exhaust), timed in turns with it off; target: at
most 15 % slower (PASS/FAIL).
"""
from __future__ import annotations

import math
import sys
import time

import frogsim
from frogsim.robot.params import JOINTS, SIDES
from frogsim.scenario.load import merged_raw

TARGET = 50.0
DURATION = 4.0
HEAT_PARAMETERS = "fan2017-heat"
HEAT_SLOWDOWN_TARGET = 1.15


def scenario(controlled: bool, parameters: str | None = None):
    return frogsim.load_robot_scenario(case_raw(controlled, parameters))


def case_raw(controlled: bool, parameters: str | None = None) -> dict:
    """The case as a scenario's raw dict (its parameter set merged in, ``base_dir`` set):
    ``bench_tune_joint.py`` writes it as a file for ``frogsim tune``."""
    raw, base = merged_raw("swim")
    if parameters is not None:              # the robot's scenario over another parameter set
        raw, base = merged_raw({**raw_file("swim"), "parameters": parameters, "base_dir": base})
    raw.pop("firmware", None)        # the compiled float laws: six joints would need 18 analog inputs
    raw = {**raw, "base_dir": base, "robot": {**raw["robot"], "recovery": "muscle"},
           "gait": {**raw["gait"], "period": f"{DURATION / 2:g} s", "cycles": 2}}
    if controlled:
        rs0 = frogsim.load_robot_scenario(raw)
        ctls = {}
        for side in SIDES:
            for j in JOINTS:
                rng = math.degrees(rs0.robot.joints[j].range)
                ctls[f"{j}_{side}"] = {
                    "kind": "joint-angle", "joint": f"{j}_{side}", "co_contraction": "2 bar",
                    "proportional_gain": "30 bar/rad", "derivative_gain": "1 bar*s/rad",
                    "integral_gain": "30 bar/(rad*s)", "band": "0.1 bar",
                    "setpoint": {"kind": "sine", "mean": f"{rng / 2:.3f} deg", "amplitude": f"{rng / 4:.3f} deg",
                                 "frequency": "1 Hz"}}
        raw["controllers"] = ctls
    return raw


def raw_file(name: str) -> dict:
    """The shipped scenario's own file, before its parameter set is merged in."""
    from frogsim.scenario.load import read_toml, scenario_path
    return read_toml(scenario_path(name), "scenario")


def best_of(fn, n=3):
    """(best loop wall time [s] (SwimResult.wall_s: the coupled loop, build excluded), best total
    wall time [s] (build included), the last result)."""
    loop, total, out = float("inf"), float("inf"), None
    for _ in range(n):
        t0 = time.perf_counter()
        out = fn()
        total = min(total, time.perf_counter() - t0)
        loop = min(loop, out.wall_s)
    return loop, total, out


def main() -> int:
    closed, open_loop = scenario(True), scenario(False)
    frogsim.swim(closed)                        # compile
    frogsim.swim(open_loop)
    wall_c, total_c, rc = best_of(lambda: frogsim.swim(closed))
    wall_o, total_o, _ = best_of(lambda: frogsim.swim(open_loop))
    m = rc.control_metrics()
    rms = [m[f"{j}_{s}"]["tracking_error_rms_deg"] for s in SIDES for j in JOINTS]
    sw = sum(m[f"{j}_{s}"]["switchings_per_s"] for s in SIDES for j in JOINTS)
    ratio = DURATION / wall_c
    print("full robot, 12 muscles / 24 valves, water, 6 compiled joint-angle controllers at 1 kHz:")
    steps = rc.stats["mujoco_steps"]
    print(f"  closed loop: {wall_c:6.3f} s for {DURATION:g} s simulated -> {ratio:6.1f}x real time, "
          f"{wall_c / steps * 1e6:.1f} us per MuJoCo step "
          f"(with the model's build: {total_c:.3f} s, {DURATION / total_c:.1f}x)")
    print(f"  open loop (same robot, its gait): {wall_o:6.3f} s -> {DURATION / wall_o:6.1f}x real time "
          f"(with build {total_o:.3f} s); closed/open loop wall ratio {wall_c / wall_o:.2f}")
    print(f"  tracking RMS after settle [deg]: {', '.join(f'{x:.2f}' for x in rms)}; "
          f"{sw:.0f} valve switchings/s in all")
    ok = ratio >= TARGET
    print(f"target: closed loop >= {TARGET:g}x real time: {'PASS' if ok else 'FAIL'}")
    # wall heat transfer on against off: the closed-loop robot, in turns, best of rounds
    hot = scenario(True, HEAT_PARAMETERS)
    frogsim.swim(hot)
    walls = {"off": float("inf"), "on": float("inf")}
    for _ in range(3):
        for k, sc in (("off", closed), ("on", hot)):
            walls[k] = min(walls[k], best_of(lambda: frogsim.swim(sc), 1)[0])
    heat_ratio = walls["on"] / walls["off"]
    heat_ok = heat_ratio <= HEAT_SLOWDOWN_TARGET
    print(f"  wall heat transfer ({HEAT_PARAMETERS}): closed loop {walls['on']:.3f} s on, {walls['off']:.3f} s off "
          f"(in turns, best of 3): on / off {heat_ratio:.3f}")
    print(f"target: heat on at most {HEAT_SLOWDOWN_TARGET:g} x heat off: {'PASS' if heat_ok else 'FAIL'}")
    return 0 if ok and heat_ok else 1


if __name__ == "__main__":
    sys.exit(main())
