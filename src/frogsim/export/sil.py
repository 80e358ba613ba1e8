"""Software in the loop: the built firmware's own machine code on the emulated ATmega2560
(:mod:`frogsim.export.emulator`), in lockstep with frogsim's plant.

At every controller sample t_k the plant's state gives each channel's ADC count (the plan's
``adc_counts``, the function the model's own sensing uses); the emulated board's analog inputs are
set to the voltage simavr reads as that count (:func:`frogsim.export.emulator.millivolts_for_count`),
and the AVR runs until the end of sample k's interrupt (its busy pin falls). The valve pins then
hold the firmware's commands of sample k: charge pin high -> charge, discharge pin high -> vent,
both low -> hold. They go to the plant through the driver's own dead-time queue, exactly as a
compiled law's commands do (the Python-controller drivers with every muscle driven from outside:
:func:`frogsim.engine.pneumatic.run_python_controller` for the pneumatics alone,
:func:`frogsim.engine.coupled_python.run_coupled_python` for the robot), and the plant runs on to
the next sample. The robot's palms keep the gait's commands (their steering motors are not on the
valve board).

The shadow check: the model's compiled law runs beside the firmware on the same states (its own
controller memory, started as the engines start it: :func:`frogsim.control.sampled.start_controllers`,
then :func:`frogsim.control.sampled.sample_controllers` at each sample, with
:func:`frogsim.control.sampled.observe_joints` first on the robot), and a muscle with an
open-loop program or gait is compared against its program's state at the sample. A sample where
any muscle's command differs is a mismatched sample.

What is measured on the emulated AVR, in its cycles: the busy pin's high time in each period (the
interrupt's work from its first to its last instruction: the CPU load), the firmware's overrun
counter (read from its RAM after the last sample, at the address avr-nm gives), and the bytes it sends on its serial port (the log).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from frogsim.errors import FrogsimError, SimulationError
from frogsim.export import board
from frogsim.export.emulator import EmulatedBoard, millivolts_for_count
from frogsim.scenario.motion import command_time

MODE_OF_STATE = {"charge": 1, "vent": -1, "hold": 0}
#: CPU cycles the board may take to reach its first sample (setup, the serial header) [cycles]
START_CYCLES = 40 * board.F_CPU // 10
#: cycles run after the last sample, so that the log lines queued by then are sent
DRAIN_PERIODS = 40


def program_mode(steps, t: float, rate: float) -> int:
    """The mode (1 charge, 0 hold, -1 vent) an open-loop program commands at sample time t:
    its last step whose command sample (:func:`frogsim.scenario.motion.command_time`) is at or
    before t."""
    state = "hold"
    for ts, st in steps:
        if command_time(ts, rate) <= t + 1e-12:
            state = st
    return MODE_OF_STATE[state]


@dataclass
class BoardRun:
    """The firmware on the emulated board, one sample at a time (see the module docstring)."""
    rec: dict
    elf: object
    high: list = field(default_factory=list)       # busy pin high time of each sample [cycles]
    serial: bytearray = field(default_factory=bytearray)
    both_open: int = 0

    def __post_init__(self):
        self.board = EmulatedBoard(self.elf, self.rec["f_cpu_hz"], 5.0)
        pins = board.pin_map()
        self.busy = self.board.watch(pins[self.rec["busy_pin"]])
        self.valve_index = [(self.board.watch(pins[c]), self.board.watch(pins[d])) for c, d in self.rec["valve_pins"]]
        self.level = np.zeros(len(self.board.watched), np.int32)
        self.shift = 10 - int(self.rec["adc"]["bits"])
        self.inputs = [int(ch["analog_input"]) for ch in self.rec["channels"]]
        self.period = int(self.rec["period_cycles"])
        self.mv = [-1] * len(self.inputs)          # the voltages set, changed only when they change
        from frogsim.export.emulator import symbol_address
        self.overrun_address = symbol_address(self.elf, "fs_overruns")
        self.adc_address = symbol_address(self.elf, "fs_adc") if self.inputs else None
        self.adc_differs = 0             # samples whose counts the firmware read are not those fed
        self.first_adc_difference = None
        self.ev_c = np.empty(256, np.uint64)
        self.ev_i = np.empty(256, np.int32)
        self.ev_v = np.empty(256, np.int32)
        self.k = 0
        self.rise = None
        self.avr_s = 0.0

    def sample(self, counts) -> np.ndarray:
        """Sample k: the channels read ``counts``; returns the modes of the muscles (plan order)."""
        t0 = time.perf_counter()
        b = self.board
        for j, (a, c) in enumerate(zip(self.inputs, counts.tolist())):
            mv = millivolts_for_count(c << self.shift)
            if mv != self.mv[j]:
                b.set_analog(a, mv)
                self.mv[j] = mv
        wait = START_CYCLES if self.k == 0 else 50 * self.period
        if not b.run_until_pin(self.busy, 0, b.cycle + wait):
            raise SimulationError(f"firmware {self.rec['name']!r}: sample {self.k} did not end within {wait} AVR "
                                  "cycles (its interrupt never ran or never ended)")
        while True:
            n = b.events_into(self.ev_c, self.ev_i, self.ev_v)
            for cc, ii, vv in zip(self.ev_c[:n].tolist(), self.ev_i[:n].tolist(), self.ev_v[:n].tolist()):
                self.level[ii] = vv
                if ii == self.busy:
                    if vv:
                        self.rise = cc
                    elif self.rise is not None:
                        self.high.append(cc - self.rise)
                        self.rise = None
            if n < self.ev_c.size:
                break
        if self.inputs:
            read = np.frombuffer(b.read_ram(self.adc_address, 2 * len(self.inputs)), "<u2")
            if not np.array_equal(read, counts):
                self.adc_differs += 1
                if self.first_adc_difference is None:
                    self.first_adc_difference = {"sample": self.k, "fed": counts.tolist(), "read": read.tolist()}
        modes = np.zeros(len(self.valve_index), np.int8)
        for j, (ic, idis) in enumerate(self.valve_index):
            ch, dis = self.level[ic], self.level[idis]
            if ch and dis:
                self.both_open += 1
            modes[j] = 1 if ch and not dis else (-1 if dis and not ch else 0)
        if self.k % 1000 == 999:
            self.serial += b.serial()[0]
        self.k += 1
        self.avr_s += time.perf_counter() - t0
        return modes

    def finish(self) -> None:
        """Read the overrun counter, then run on long enough for the queued log lines to leave;
        collect the serial bytes."""
        t0 = time.perf_counter()
        self.overruns = int.from_bytes(self.board.read_ram(self.overrun_address, 2), "little")
        self.board.run_until(self.board.cycle + DRAIN_PERIODS * self.period)
        self.serial += self.board.serial()[0]
        self.avr_s += time.perf_counter() - t0
        if self.board.lost:
            raise FrogsimError(f"firmware {self.rec['name']!r}: the emulated board's queues overflowed "
                               f"({self.board.lost} events or bytes lost)")
        self.board.close()

    def load(self, samples: int) -> np.ndarray:
        """The busy pin's high time of samples 0..samples-1 as a share of the period."""
        return np.array(self.high[:samples], float) / self.period


def interrupt_timing(rec: dict, elf, samples: int = 200, seed: int = 0) -> dict:
    """The built firmware's interrupt timed on the emulated board before any plant is attached:
    ``samples`` periods whose channels read counts drawn uniformly over the ADC's range (a seeded
    generator: the same firmware gives the same figures), the busy pin's high time in AVR cycles.

    The export's fit check (:func:`frogsim.components.atmega2560.plan_adc`) counts the ADC's
    conversions only; the laws' own arithmetic (a joint-angle law's 64-bit products take about a
    quarter of a 1 ms period) is measured here, on the machine code itself. Returns the period
    [cycles], the mean and largest share of it the interrupt took [%], the samples over the
    period and the firmware's overrun counter."""
    run = BoardRun(rec, elf)
    rng = np.random.default_rng(seed)
    top = (1 << int(rec["adc"]["bits"])) - 1
    try:
        for _ in range(samples):
            run.sample(rng.integers(0, top + 1, len(run.inputs)).astype(np.int64))
        run.overruns = int.from_bytes(run.board.read_ram(run.overrun_address, 2), "little")
    finally:
        run.board.close()
    load = run.load(samples) * 100.0
    return {"samples": samples, "period_cycles": run.period, "mean_percent": float(load.mean()),
            "max_percent": float(load.max()), "samples_over_period": int((load > 100.0).sum()),
            "overruns": run.overruns}


class Shadow:
    """The model's compiled laws on the plant's states, sample by sample (module docstring)."""

    def __init__(self, laws, mp, scenario, muscles: list, dt: float, names: list, joints=None):
        from frogsim.control.sampled import L_KIND, L_MUSCLE, _is_valve_law
        self.laws, self.mp, self.dt = laws, mp, dt
        self.rate = 1.0 / dt
        self.rows = {}
        if laws.ndim == 2:
            for c in range(laws.shape[0]):
                if _is_valve_law(laws[c, L_KIND]):
                    self.rows[names[int(laws[c, L_MUSCLE])]] = c
        self.programs = {m: scenario.muscles[m].program.steps for m in muscles
                         if m not in self.rows and scenario.muscles[m].program.steps}
        self.muscles = list(muscles)
        self.joints = joints          # (leg_qpos, leg_dof) on the robot
        self.cs = None

    def copy_counters(self, cs) -> None:
        """Write the shadow's per-law counters that only a compiled law keeps (a joint-angle law's
        clipped pressure targets, B_CLIPS) into the run's controller memory ``cs`` (whose rows of
        these laws are the same rows, run from outside), so that the run's metrics report them
        as the compiled run does."""
        from frogsim.control.sampled import B_CLIPS, CS_BLOCK, CS_SIZE
        if self.cs is None:
            return
        for c in self.rows.values():
            cs[int(CS_SIZE + c * cs[CS_BLOCK]) + B_CLIPS] = self.cs[int(CS_SIZE + c * self.cs[CS_BLOCK]) + B_CLIPS]

    def modes(self, k: int, y, qpos=None, qvel=None) -> np.ndarray:
        from frogsim.control.sampled import (B_MODE, CS_BLOCK, CS_SIZE, observe_joints, sample_controllers,
                                             start_controllers)
        t = k * self.dt
        u = np.zeros(2 * len(self.mp))
        if self.rows:
            if self.cs is None:
                self.cs = start_controllers(self.laws, self.mp, 0.0, np.array(y, float), u, self.dt)
            else:
                if self.joints is not None:
                    observe_joints(self.laws, self.cs, qpos, qvel, *self.joints)
                sample_controllers(self.laws, self.mp, t, np.array(y, float), u, self.cs)
        out = np.zeros(len(self.muscles), np.int8)
        for j, m in enumerate(self.muscles):
            if m in self.rows:
                b = int(CS_SIZE + self.rows[m] * self.cs[CS_BLOCK])
                out[j] = int(self.cs[b + B_MODE])
            elif m in self.programs:
                out[j] = program_mode(self.programs[m], t, self.rate)
        return out


@dataclass
class SilRun:
    """What a SIL run gives: the plant's result (a Result or a SwimResult), the ``sil`` summary
    section, the serial bytes."""
    result: object
    sil: dict
    serial: bytes


class _Loop:
    """The controller function the Python-controller drivers call at each sample."""

    def __init__(self, rec, elf, plan, counts, shadow, model, progress, duration, robot):
        self.rec, self.plan, self.counts, self.shadow, self.model = rec, plan, counts, shadow, model
        self.board = BoardRun(rec, elf)
        self.muscles = list(rec["muscles"])
        self.robot = robot
        self.joint_names, self.joint_qpos = robot if robot else ((), ())
        self.mismatched = 0
        self.first_mismatch = None
        self.progress = progress
        self.duration = duration
        self.wall0 = time.perf_counter()
        self.shown = self.wall0
        self.k = 0

    def __call__(self, t, obs):
        y = obs["state"]
        qpos, qvel = obs.get("qpos"), obs.get("qvel")
        angles = None
        if qpos is not None:
            angles = {n: float(qpos[self.joint_qpos[j]]) for j, n in enumerate(self.joint_names)}
        counts = self.counts(self.plan, self.model, y, angles)
        modes = self.board.sample(np.asarray(counts, np.int64))
        want = self.shadow.modes(self.k, y, qpos, qvel)
        if not np.array_equal(modes, want):
            self.mismatched += 1
            if self.first_mismatch is None:
                self.first_mismatch = {"sample": self.k, "time_s": float(t), "counts": [int(c) for c in counts],
                                       "firmware": modes.tolist(), "model": want.tolist()}
        self.k += 1
        now = time.perf_counter()
        if self.progress is not None and now - self.shown > 2.0:
            self.shown = now
            self.progress(f"      SIL at {t:.2f} s of {self.duration:g} s simulated "
                          f"({t / (now - self.wall0):.2f} x real time)")
        return {m: int(x) for m, x in zip(self.muscles, modes)}

    def summary(self, rec) -> dict:
        from frogsim.export.serial_log import parse_log
        self.board.finish()
        lines = parse_log(bytes(self.board.serial), rec)
        last = [r for r in lines.records if r[0] < self.k]
        load = self.board.load(self.k) * 100.0
        return {
            "samples": self.k,
            "mismatched_samples": self.mismatched,
            **({"first_mismatch": self.first_mismatch} if self.first_mismatch else {}),
            "cpu_load_percent": {"mean": float(load.mean()) if load.size else None,
                                 "max": float(load.max()) if load.size else None},
            "overruns": self.board.overruns,
            "both_valves_open_samples": self.board.both_open,
            "adc_read_differs_samples": self.board.adc_differs,
            **({"first_adc_difference": self.board.first_adc_difference} if self.board.adc_differs else {}),
            "log_lines": len(last),
            "log_lines_dropped": lines.dropped,
            "flash_bytes": rec.get("flash_bytes"),
            "ram_bytes": rec.get("ram_bytes"),
            "avr_wall_s": self.board.avr_s,
            "log_csv": "serial.csv",
        }


def check_plan(rec: dict, plan, scenario: str | None = None, cycles: int | None = None,
               inputs: list | None = None) -> None:
    """ScenarioError unless the firmware folder was exported from this plan (same digest). When it
    was not, the message names the likely cause from what the export kept (firmware.json's
    "export": the scenario's name, the gait cycles, the input files' digests) against this run's
    ``scenario`` name, ``cycles`` (a robot's gait cycles, None for the pneumatics) and described
    ``inputs`` (:func:`frogsim.io.outputs.scenario_inputs`)."""
    from frogsim.errors import ScenarioError
    from frogsim.export.sketch import plan_record
    if plan_record(plan)["plan_sha256"] == rec.get("plan_sha256"):
        return
    again = "export and build it again (frogsim firmware SCENARIO --out DIR --build)"
    export = rec.get("export") if isinstance(rec.get("export"), dict) else {}
    if not export:
        raise ScenarioError("--firmware", rec.get("name"), "was exported from another scenario, or from this "
                                                           f"one before an edit: {again}")
    was = export.get("scenario")
    if scenario is not None and was != scenario:
        why = f"was exported from another scenario ({was!r}, not {scenario!r})"
    elif export.get("cycles") != cycles:
        gave = export.get("cycles")
        why = f"was exported for {gave} gait cycle(s), this run has {cycles} (a different --cycles)"
        again = f"give --cycles {gave}, or {again}"
    else:
        from frogsim.sweep.spec import changed_inputs
        changed = changed_inputs(export.get("inputs"), inputs) if inputs is not None else []
        if changed:
            why = f"was exported from scenario {was!r} before an edit (its {', '.join(changed[:3])} differ now)"
        else:
            why = (f"was exported from scenario {was!r} with the same files, but another plan (another "
                   "frogsim version?)")
    raise ScenarioError("--firmware", rec.get("name"), f"{why}: {again}")


def run_pneumatic(model, rec: dict, elf, plan, counts, progress=None) -> SilRun:
    """SIL of a pneumatic scenario (its built model ``model``) against the firmware ``elf``."""
    from frogsim.engine.pneumatic import run_python_controller
    sc = model.scenario
    dt = 1.0 / sc.controller.rate
    shadow = Shadow(model.laws, model.mp, sc, rec["muscles"], dt, model.names)
    loop = _Loop(rec, elf, plan, counts, shadow, model, progress, sc.duration, None)
    t0 = time.perf_counter()
    result = run_python_controller(model, loop, every_muscle=True)
    wall = time.perf_counter() - t0
    result.python_law = None           # measured against the scenario's own setpoints, as compiled
    sil = loop.summary(rec)
    sil["wall_s"] = wall
    sil["plant_wall_s"] = wall - sil["avr_wall_s"]
    sil["real_time_factor"] = sc.duration / wall if wall > 0 else None
    return SilRun(result, sil, bytes(loop.board.serial))


def run_robot(rs, rec: dict, elf, plan, counts, progress=None) -> SilRun:
    """SIL of a robot scenario: the coupled engine (MuJoCo and the pneumatics) as the plant."""
    from frogsim.engine.coupled import build_coupled
    from frogsim.engine.coupled_python import run_coupled_python
    from frogsim.engine.swim import SwimResult
    cm = build_coupled(rs)
    a = cm.arrays
    dt = 1.0 / rs.pneumatic.controller.rate
    shadow = Shadow(a["laws"].copy(), a["mp"], cm.pneumatic.scenario, rec["muscles"], dt, list(cm.muscle_names),
                    joints=(a["leg_qpos"], a["leg_dof"]))
    loop = _Loop(rec, elf, plan, counts, shadow, cm.pneumatic, progress, rs.duration,
                 (list(cm.joint_names), a["leg_qpos"]))
    out = run_coupled_python(cm, loop, every_muscle=True)
    shadow.copy_counters(a["cs"])
    result = SwimResult(rec=out["rec"], model=cm, stats=out["stats"], wall_s=out["wall_s"],
                        compile_s=out.get("compile_s", 0.0), python_law=None)
    sil = loop.summary(rec)
    wall = out["wall_s"]
    sil["wall_s"] = wall
    sil["plant_wall_s"] = wall - sil["avr_wall_s"]
    sil["real_time_factor"] = rs.duration / wall if wall > 0 else None
    return SilRun(result, sil, bytes(loop.board.serial))
