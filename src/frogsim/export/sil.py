"""Software in the loop: the built firmware's own machine code on the emulated ATmega2560
(:mod:`frogsim.export.emulator`), in lockstep with frogsim's plant, on the board's own timing.

The clocks are tied at sample 0: the cycle of Timer1's first compare match is plant time 0, and
sample k's period is the cycles [s0 + k P, s0 + (k + 1) P). For each period (:class:`BoardRun`):
the plant's state at t_k gives each analog channel's count (the plan's ``adc_counts``, the
function the model's own sensing uses), the emulated inputs are set to the voltage simavr reads
as that count (:func:`frogsim.export.emulator.millivolts_for_count`), quadrature encoders are
fed their edges, and the AVR runs to the period's end whatever the firmware does in it (an
interrupt that ends late ends in a later period). Every valve pin change goes to the plant at
the cycle the firmware made it, through the driver's own dead-time queue as a compiled law's
commands do (the Python-controller drivers with every muscle driven from outside:
:func:`frogsim.engine.pneumatic.run_python_controller` for the pneumatics alone,
:func:`frogsim.engine.coupled_python.run_coupled_python` for the robot); ``timing="grid"`` gives
each sample's decision at the sample's time instead (a check of the harness). With encoders the
plant runs a period ahead (the edges of period k need the angle at t_k+1). The robot's palms
keep the gait's commands (their steering motors are not on the valve board).

The checks, per execution of the control interrupt: its decision against the model's integer
twin of ``frogsim_sample`` on the counts it read (copied from the emulated RAM at its busy pin's
fall): ``mismatched_samples``; and against the model's compiled law on the plant at its own
sample (:class:`Shadow`: a late board reads later counts): ``samples_off_the_on_time_model``.

What is measured on the emulated AVR, in its cycles: the busy pin's high time of each interrupt
(the CPU load), its response and valve-write latency from the compare match that started it,
late and skipped samples, the sleep cycles (the chip's awake share), the firmware's overrun and
dropped counters (read from its RAM at the end), and the bytes it sends on its serial port (the
log: records made, received, dropped, unsent, fault bits).
"""
from __future__ import annotations

import bisect

import time
from dataclasses import dataclass, field

import numpy as np

from frogsim.errors import FrogsimError, SimulationError
from frogsim.export import board
from frogsim.export.emulator import EmulatedBoard
from frogsim.scenario.motion import command_time

MODE_OF_STATE = {"charge": 1, "vent": -1, "hold": 0}
#: CPU cycles the board may take to reach its first sample (setup, the serial header) [cycles]
START_CYCLES = 40 * board.F_CPU // 10
#: the longest the serial log may take, after the run, to send the records queued by its end [s]
DRAIN_S = 2.0
#: Timer1's compare-match A interrupt: vector 17 of the ATmega2560 (datasheet Table 14-1)
TIMER1_COMPA_VECTOR = 17


def program_mode(steps, t: float, rate: float) -> int:
    """The mode (1 charge, 0 hold, -1 vent) an open-loop program commands at sample time t:
    its last step whose command sample (:func:`frogsim.scenario.motion.command_time`) is at or
    before t."""
    state = "hold"
    for ts, st in steps:
        if command_time(ts, rate) <= t + 1e-12:
            state = st
    return MODE_OF_STATE[state]


class BoardRun:
    """The firmware on the emulated board, one controller period (a frame) at a time.

    The board's clock and the plant's are tied at sample 0: cycle ``s0``, the cycle of Timer1's
    first compare match (the hardware event, not the interrupt's entry), is plant time 0, and
    sample k's period is the cycles [s0 + k P, s0 + (k + 1) P). :meth:`frame` sets the analog
    inputs from the plant's state at t_k and runs the AVR to the end of that period, whatever the
    firmware does in it: an interrupt that ends late ends in a later frame, a compare match the
    firmware could not take is lost as on the chip. Every valve pin change is returned with its
    own cycle, so the plant receives it at the time the firmware wrote it (plus the valve's dead
    time), not on the nominal grid.

    Per execution j of the control interrupt (the busy pin's rise and fall): its start and end
    cycles, the valve modes at its end (its decision), the counts it read (``fs_adc`` in the
    emulated RAM, read at its end), the cycle of its last valve write."""

    def __init__(self, rec: dict, elf):
        from frogsim.export.emulator import symbol_address
        self.rec, self.elf = rec, elf
        self.board = EmulatedBoard(elf, rec["f_cpu_hz"], 5.0)
        pins = board.pin_map()
        self.busy = self.board.watch(pins[rec["busy_pin"]])
        self.valve_index = [(self.board.watch(pins[c]), self.board.watch(pins[d])) for c, d in rec["valve_pins"]]
        self.tick = self.board.watch_vector(TIMER1_COMPA_VECTOR)
        self.owner = {}
        for j, (ic, idis) in enumerate(self.valve_index):
            self.owner[ic] = j
            self.owner[idis] = j
        self.shift = 10 - int(rec["adc"]["bits"])
        chans = rec["channels"]
        self.analog = [i for i, ch in enumerate(chans) if "analog_input" in ch]
        self.inputs = [int(chans[i]["analog_input"]) for i in self.analog]
        # quadrature encoders: (channel index, A pin, B pin); their counts as fed so far
        self.encoders = [(i, pins[int(ch["pins"][0])], pins[int(ch["pins"][1])]) for i, ch in enumerate(chans)
                         if "pins" in ch]
        self.enc_count = np.array([int(chans[i]["start_count"]) for i, _, _ in self.encoders], np.int32)
        self.enc_pins = [(a, bpin) for _, a, bpin in self.encoders]
        # the most counts an encoder may move in a period: n edges spread over it come
        # P / (n + 1) cycles apart, at least MIN_EDGE_CYCLES
        self.most_counts = int(rec["period_cycles"]) // self.MIN_EDGE_CYCLES - 1
        for (i, a, bpin), c in zip(self.encoders, self.enc_count):
            # A's level is the count's parity (see frame); a pin is low unless driven, and simavr
            # 1.6 must not see an external-interrupt pin driven low before the firmware has set
            # its interrupt up (it then hangs in the low-level mode the reset leaves)
            if c & 1:
                self.board.set_pin(a, 1)
                self.board.set_pin(bpin, 1)
        self.period = int(rec["period_cycles"])
        self.input_array = np.array(self.inputs, np.int32)
        # the analog channels' place among the counts (a slice where they are consecutive)
        a = self.analog
        self.analog_slice = slice(a[0], a[-1] + 1) if a and a == list(range(a[0], a[-1] + 1)) else np.array(a, np.int64)
        self.overrun_address = symbol_address(elf, "fs_overruns")
        self.dropped_address = symbol_address(elf, "fs_dropped")
        self.k_address = symbol_address(elf, "fs_k")
        self.adc_address = symbol_address(elf, "fs_adc") if chans else None
        # the counts each interrupt read, copied from RAM at its end (the busy pin's fall)
        self.snap_address = self.adc_address if chans else 0
        self.snap = np.zeros((8, 2 * len(chans)), np.uint8)
        # the pin events are read in C (EmulatedBoard.track), each period set and run in one call
        # (EmulatedBoard.frame) on these arrays, written here before each call
        self.board.track(self.busy, self.tick, self.valve_index)
        self.adc_counts = np.zeros(len(self.inputs), np.int64)
        self.enc_targets = self.enc_count.copy()
        self.board.frame_setup(self.input_array, self.adc_counts, self.shift, self.enc_pins, self.enc_count,
                               self.enc_targets, self.most_counts, self.busy, self.snap_address, self.snap)
        self.s0 = None
        self.frames = 0
        self.ticks = []            # cycles of Timer1's compare matches (flag raised)
        self.starts, self.ends = [], []     # busy pin rise and fall of each execution
        self.decisions = []        # the muscles' modes at each execution's end
        self.counts_read = []      # the counts each execution read
        self.write_cycle = []      # cycle of each execution's last valve change (-1: none)
        self.fed = []              # the counts fed in each frame
        self.avr_s = 0.0

    # -- the run ---------------------------------------------------------------------------------
    def _drain(self, out, drained: bool = False) -> None:
        """Read the queued pin events (in C, :meth:`EmulatedBoard.drain`; ``drained``: the last
        call did, as :meth:`EmulatedBoard.frame` does for its period): the executions that ended,
        the compare matches and, into ``out``, the valve mode changes [(cycle, muscle index,
        mode)], in order."""
        b = self.board
        if not drained:
            b.drain()
        more = self._take(out)
        while more:
            b.drain()
            more = self._take(out)

    def _take(self, out) -> bool:
        """What the last drain read, into the run's lists; True if events are still queued."""
        b = self.board
        cnt = b.counters
        n_ex, n_tk = int(cnt[b.TR_EXECUTIONS]), int(cnt[b.TR_TICKS])
        if n_ex:
            start, end, write, dec = b.executions
            self.starts += start[:n_ex].tolist()
            self.ends += end[:n_ex].tolist()
            self.write_cycle += write[:n_ex].tolist()
            self.decisions += list(dec[:n_ex, :len(self.valve_index)].copy())
        if n_tk:
            self.ticks += b.ticks[:n_tk].tolist()
        n_ch = int(cnt[b.TR_CHANGES])
        if out is not None and n_ch:
            c, j, m = b.changes
            out += zip(c[:n_ch].tolist(), j[:n_ch].tolist(), m[:n_ch].tolist())
        cnt[b.TR_EXECUTIONS] = cnt[b.TR_TICKS] = cnt[b.TR_CHANGES] = 0
        return bool(cnt[b.TR_MORE])

    @property
    def rise(self):
        """The cycle of the busy pin's last rise while it is high, else None."""
        r = int(self.board.counters[self.board.TR_RISE])
        return r if r >= 0 else None

    @property
    def both_open(self) -> int:
        """Valve pin changes that left a muscle's charge and discharge valves both open."""
        return int(self.board.counters[self.board.TR_BOTH_OPEN])

    def begin(self) -> None:
        """Run the board's setup until its first control interrupt has begun (the busy pin's first
        rise): sample 0's start, plant time 0, is Timer1's compare match just before it (the
        flag's last raise: before setup starts Timer1 in CTC mode, the Arduino core's PWM mode
        raises it too, without the interrupt enabled). The analog inputs are set by
        :meth:`frame` before the interrupt starts its first conversion."""
        b = self.board
        if not b.run_until_pin(self.busy, 1, b.cycle + START_CYCLES):
            raise SimulationError(f"firmware {self.rec['name']!r}: its control interrupt never ran within "
                                  f"{START_CYCLES} AVR cycles of the start (its timer never started)")
        self._drain(None)
        before = [c for c in self.ticks if c <= self.rise]
        if not before:
            raise SimulationError(f"firmware {self.rec['name']!r}: its control interrupt ran without a Timer1 "
                                  "compare match (not frogsim's runtime?)")
        self.s0 = before[-1]
        self.ticks = [self.s0]
        self.sleep0 = b.sleep_cycles
        self.sleep_busy0 = b.sleep_busy_cycles

    def frame(self, counts, encoder_counts=None) -> list:
        """Sample k's period: the analog channels read ``counts`` (the plant's state at t_k, held
        for the period: the converter samples it then), the AVR runs to the period's end. The
        quadrature encoders move from the counts they have to ``encoder_counts`` (one per encoder,
        the plant's at t_k+1; None: they stay): each count is an edge of A, B set before it to
        give the direction, the edges spread evenly over the period. Returns the valve mode
        changes in it, [(cycle, muscle index, mode)], in order."""
        t0 = time.perf_counter()
        if self.s0 is None:
            self.begin()
        b = self.board
        counts = np.array(counts, np.int64)
        self.fed.append(counts)
        if self.inputs:                   # each at millivolts_for_count(count << shift)
            self.adc_counts[:] = counts[self.analog_slice]
        start = self.s0 + self.frames * self.period
        end = start + self.period
        if encoder_counts is not None and self.encoders:
            self.enc_targets[:] = encoder_counts
        else:
            self.enc_targets[:] = self.enc_count
        falls = b.frame(start, end)
        if falls < 0:                     # edges closer than MIN_EDGE_CYCLES: nothing was run
            e = -1 - falls
            n = abs(int(self.enc_targets[e]) - int(self.enc_count[e]))
            raise SimulationError(f"encoder of {self.rec['channels'][self.encoders[e][0]]['signal']!r}: {n} "
                                  f"counts in one controller period ({self.period / (n + 1):.0f} CPU cycles "
                                  "apart): faster than the firmware counts them; use fewer counts per revolution")
        if falls > self.snap.shape[0]:
            raise SimulationError(f"firmware {self.rec['name']!r}: {falls} interrupts ended in one period")
        out = []
        self._drain(out, drained=True)
        for j in range(falls):
            self.counts_read.append(self.snap[j].view("<u2").astype(np.int64))
        self.frames += 1
        self.avr_s += time.perf_counter() - t0
        return out

    #: fewest CPU cycles between two edges of one encoder: the edge interrupt must have counted
    #: the last one (about 40 cycles with its entry and exit), or the chip would lose it too
    MIN_EDGE_CYCLES = 80

    def cycle_time(self, cycle: int) -> float:
        """Plant time [s] of an AVR cycle (sample 0's compare match is t = 0)."""
        return (cycle - self.s0) / self.board.f_cpu

    def finish(self) -> None:
        """Read the firmware's counters at the run's end, then let it send the log records it
        queued (at most DRAIN_S of emulated time); collect the serial bytes."""
        t0 = time.perf_counter()
        b = self.board
        self.end_cycle = b.cycle
        self.awake = 1.0 - (b.sleep_cycles - self.sleep0) / max(1, b.cycle - self.s0) if self.s0 is not None else None
        self.overruns = int.from_bytes(b.read_ram(self.overrun_address, 2), "little")
        self.dropped = int.from_bytes(b.read_ram(self.dropped_address, 2), "little")
        self.executed = int.from_bytes(b.read_ram(self.k_address, 4), "little")
        self.serial = bytearray(b.serial()[0])
        every = int(self.rec["log_every"])
        made = -(-self.executed // every)
        limit = b.cycle + int(DRAIN_S * b.f_cpu)
        while b.cycle < limit:
            from frogsim.export.serial_log import parse_log
            got = sum(1 for r in parse_log(bytes(self.serial), self.rec).records if r[0] < self.executed)
            if got + self.dropped >= made:
                break
            b.run_until(min(limit, b.cycle + 20 * self.period))
            self._drain(None)
            self.serial += b.serial()[0]
        self.avr_s += time.perf_counter() - t0
        if b.lost:
            raise FrogsimError(f"firmware {self.rec['name']!r}: the emulated board's queues overflowed "
                               f"({b.lost} events or bytes lost)")
        b.close()

    # -- what it measured --------------------------------------------------------------------------
    def timing(self, executions: int | None = None) -> dict:
        """The executions' timing [cycles]: busy time (the interrupt's work), and from the compare
        match that started each one (its sample's start: the last match before it began) its
        response (to its end) and valve write latency (to the last valve change it made); late:
        it ended after the next period began. ``lag``: how far each execution's start trails
        its nominal sample s0 + j P (grows when samples are skipped)."""
        n = len(self.ends) if executions is None else min(executions, len(self.ends))
        P = self.period
        starts = np.array(self.starts[:n], float)
        ticks = np.array(self.ticks, float)
        at = np.searchsorted(ticks, starts, side="right") - 1
        trigger = ticks[np.maximum(at, 0)] if ticks.size else starts
        ends = np.array(self.ends[:n], float)
        busy = ends - starts
        response = ends - trigger
        writes = np.array(self.write_cycle[:n], float)
        wrote = writes >= 0
        latency = writes[wrote] - trigger[wrote]
        lag = starts - (self.s0 + P * np.arange(n)) if n else np.zeros(0)
        us = 1e6 / self.board.f_cpu

        def stat(x, scale):
            return {"mean": float(x.mean()) * scale if x.size else None,
                    "max": float(x.max()) * scale if x.size else None}
        return {"executions": n, "busy": busy, "response": response,
                "cpu_load_percent": stat(busy, 100.0 / P),
                "response_us": stat(response, us),
                "valve_write_latency_us": {**stat(latency, us), "samples_with_a_valve_change": int(wrote.sum()),
                                           # sample 0's conversion is the ADC's first (25 clocks, not 13):
                                           # a replay of the log's commands takes the two apart
                                           "first_sample": float(latency[0]) * us if wrote.size and wrote[0] else None,
                                           "mean_after_the_first_sample": (float(latency[1:].mean()) * us
                                                                           if wrote.size and wrote[0] and latency.size > 1
                                                                           else float(latency.mean()) * us
                                                                           if latency.size and not wrote[0] else None)},
                "lag_behind_the_nominal_sample_us": stat(lag, us),
                "samples_late": int((response > P).sum())}

    def sample_of(self, j: int) -> int:
        """The sample (plant frame) execution j belongs to: that of the compare match that started
        it, the last before its busy pin rose. After a skipped sample it is no longer j."""
        start = self.starts[j]
        i = bisect.bisect_right(self.ticks, start) - 1
        tick = self.ticks[max(i, 0)]
        return int(round((tick - self.s0) / self.period))     # the matches come every period, to a cycle

    def load(self, samples: int) -> np.ndarray:
        """The busy pin's high time of executions 0..samples-1 as a share of the period."""
        return (np.array(self.ends[:samples], float) - np.array(self.starts[:samples], float)) / self.period


def interrupt_timing(rec: dict, elf, samples: int = 200, seed: int = 0) -> dict:
    """The built firmware's interrupt timed on the emulated board before any plant is attached:
    ``samples`` periods whose channels read counts drawn uniformly over each sensor's line (its
    fault limits: outside them the laws would not run; a seeded generator: the same firmware gives
    the same figures), the busy pin's high time in AVR cycles.

    The ADC's plan (:func:`frogsim.components.atmega2560.plan_adc`) counts the conversions only;
    the laws' own arithmetic (a joint-angle row takes some 1000-2200 AVR cycles) is measured
    here, on the machine code itself (:mod:`frogsim.export.fit` judges the fit). Returns the period
    [cycles], the mean and largest share of it the interrupt took [%], the samples over the
    period, the firmware's overrun counter, the share of the time the chip was awake [%] and the share
    it was awake outside the interrupt (the log's: formatting and sending) [%]."""
    run = BoardRun(rec, elf)
    rng = np.random.default_rng(seed)
    top = (1 << int(rec["adc"]["bits"])) - 1
    # each channel's counts within its sensor's line (its fault limits): a reading outside them
    # puts its laws in the safe state without running them, which would time the cheaper path
    lo = np.array([ch.get("fault_limits", [0, top])[0] for ch in rec["channels"]], np.int64)
    hi = np.array([ch.get("fault_limits", [0, ch.get("count_range", [0, top])[1]])[1] for ch in rec["channels"]],
                  np.int64)
    try:
        for _ in range(samples):
            run.frame(rng.integers(lo, hi + 1).astype(np.int64))
        b = run.board
        run.overruns = int.from_bytes(b.read_ram(run.overrun_address, 2), "little")
        span = max(1, b.cycle - run.s0)
        asleep = b.sleep_cycles - run.sleep0
        asleep_busy = b.sleep_busy_cycles - run.sleep_busy0
        awake = 1.0 - asleep / span
    finally:
        run.board.close()
    timing = run.timing()
    load = timing["busy"] / run.period * 100.0
    # awake outside the interrupt: the log's formatting and its serial interrupts (the time the
    # interrupt idled waiting for conversions is the interrupt's, not the log's)
    outside = (span - float(timing["busy"].sum()) - (asleep - asleep_busy)) / span
    return {"samples": samples, "executions": timing["executions"], "period_cycles": run.period,
            "mean_percent": float(load.mean()) if load.size else None,
            "max_percent": float(load.max()) if load.size else None,
            "samples_over_period": int((load > 100.0).sum()) + max(0, samples - timing["executions"]),
            "samples_late": timing["samples_late"], "overruns": run.overruns,
            "awake_percent": 100.0 * awake, "awake_outside_interrupt_percent": 100.0 * max(0.0, outside)}


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
        from frogsim.control.sampled import B_CLIPS, law_block
        if self.cs is None:
            return
        for c in self.rows.values():
            cs[law_block(cs, c) + B_CLIPS] = self.cs[law_block(self.cs, c) + B_CLIPS]

    def modes(self, k: int, y, qpos=None, qvel=None) -> np.ndarray:
        from frogsim.control.sampled import B_MODE, law_block, observe_joints, sample_controllers, start_controllers
        t = k * self.dt
        if self.rows:
            y = np.asarray(y, float)
            if self.cs is None:
                self.u = np.zeros(2 * len(self.mp))
                self.cs = start_controllers(self.laws, self.mp, 0.0, y, self.u, self.dt)
                # where each muscle's mode is: its law's B_MODE slot, or its program
                self.law_of = [j for j, m in enumerate(self.muscles) if m in self.rows]
                self.mode_at = np.array([law_block(self.cs, self.rows[m]) + B_MODE
                                         for m in self.muscles if m in self.rows], np.int64)
            else:
                if self.joints is not None:
                    observe_joints(self.laws, self.cs, qpos, qvel, *self.joints)
                self.u[:] = 0.0
                sample_controllers(self.laws, self.mp, t, y, self.u, self.cs)
        out = np.zeros(len(self.muscles), np.int8)
        if self.rows:
            out[self.law_of] = self.cs[self.mode_at]
        for j, m in enumerate(self.muscles):
            if m in self.programs:
                out[j] = program_mode(self.programs[m], t, self.rate)
        return out


@dataclass
class SilRun:
    """What a SIL run gives: the plant's result (a Result or a SwimResult), the ``sil`` summary
    section, the serial bytes."""
    result: object
    sil: dict
    serial: bytes


class _Checks:
    """Each execution of the control interrupt checked (module docstring): its decision against
    the integer twin on the counts it read (``mismatched_samples``) and against the compiled law
    on the plant at its own sample (the on-time model, :class:`Shadow`: differs when the firmware
    read other counts, late). It runs in the plant's process, where the shadow's decisions are
    made, on what the board reports of each execution (:meth:`_BoardSide.step`)."""

    def __init__(self, rec, plan):
        self.rate = float(rec["rate_hz"])
        self.plan = plan
        # the integer twin of frogsim_sample on the counts the firmware read (a plan made by
        # frogsim.control.firmware has it; a hand-written one is checked against the shadow)
        self.twin_mem = None
        if getattr(plan, "laws", None):
            from frogsim.control.firmware import firmware_memory
            self.twin_mem = firmware_memory(plan)
        self.shadow_modes = []       # the compiled law on the plant's state, per sample
        self.fed = []                # the counts each frame was given
        self.checked = 0
        self.mismatched = 0
        self.first_mismatch = None
        self.off_model = 0
        self.first_off_model = None

    def sample(self, row, counts) -> None:
        """Sample k's shadow decision ``row``, and the counts its frame is given (None: no frame)."""
        self.shadow_modes.append(np.asarray(row, np.int8))
        if counts is not None:
            self.fed.append(counts)

    def executions(self, ended) -> None:
        """The executions that ended since the last call, in order: (sample, decision, counts read)."""
        from frogsim.control.firmware import firmware_modes
        for f, got, read in ended:
            j = self.checked
            if self.twin_mem is not None:
                want = firmware_modes(self.plan, j, read, self.twin_mem)
            else:
                want = self.shadow_modes[j] if j < len(self.shadow_modes) else got
            if got.tobytes() != np.asarray(want, np.int8).tobytes():
                self.mismatched += 1
                if self.first_mismatch is None:
                    self.first_mismatch = {"sample": j, "time_s": j / self.rate, "counts_read": read.tolist(),
                                           "firmware": got.tolist(), "twin": np.asarray(want).tolist()}
            if f < len(self.shadow_modes) and got.tobytes() != self.shadow_modes[f].tobytes():
                self.off_model += 1
                if self.first_off_model is None:
                    self.first_off_model = {"sample": f, "execution": j, "counts_fed": self.fed[f].tolist(),
                                            "counts_read": read.tolist(), "firmware": got.tolist(),
                                            "model": self.shadow_modes[f].tolist()}
            self.checked += 1

    def into(self, s: dict) -> dict:
        """The board's summary ``s`` with the checks' figures in their places."""
        out = {}
        for key, value in s.items():
            if key == "mismatched_samples":
                out[key] = self.mismatched
                if self.first_mismatch:
                    out["first_mismatch"] = self.first_mismatch
            elif key == "samples_off_the_on_time_model":
                out[key] = self.off_model
                if self.first_off_model:
                    out["first_off_the_on_time_model"] = self.first_off_model
            else:
                out[key] = value
        return out


class _BoardSide:
    """The board's half of the loop: the firmware on the emulated board (:class:`BoardRun`), one
    frame per call of :meth:`step`, which reports each execution that ended for the checks
    (:class:`_Checks`, on the plant's side), and at the end the summary's board figures. It runs
    in the plant's process, or in a process of its own (:class:`_BoardProcess`)."""

    def __init__(self, rec, elf, plan):
        self.rec, self.plan = rec, plan
        self.board = BoardRun(rec, elf)
        self.reported = 0            # executions reported so far

    def step(self, counts, encoder_counts) -> tuple:
        """One frame run on ``counts`` (None: no frame yet, the first sample with encoders;
        ``encoder_counts`` as :meth:`BoardRun.frame` takes them). Returns (the frame's valve mode
        changes as [(plant time [s], muscle index, mode)], the decision of the last execution
        that ended in it or None, the executions that ended in it as [(sample, decision, counts
        read)])."""
        if counts is None:
            return [], None, []
        b = self.board
        before = len(b.decisions)
        changes = b.frame(counts, encoder_counts)
        t0 = (b.frames - 1) / float(self.rec["rate_hz"])     # the frame's start (a write in the
        timed = [(max(t0, b.cycle_time(c)), j, m) for c, j, m in changes]    # setup: at sample 0)
        return timed, (b.decisions[-1] if len(b.decisions) > before else None), self._ended()

    def _ended(self) -> list:
        b = self.board
        out = [(b.sample_of(j), b.decisions[j], b.counts_read[j]) for j in range(self.reported, len(b.decisions))]
        self.reported = len(b.decisions)
        return out

    def summary(self, rec) -> tuple:
        """(the summary's board figures, the serial bytes): the board run to its end
        (:meth:`BoardRun.finish`, the log's last records sent)."""
        from frogsim.export.serial_log import parse_log
        b = self.board
        b.finish()
        ran = b.frames                              # the plant's samples (periods run)
        done = sum(1 for e in b.ends if e < b.s0 + ran * b.period) if b.s0 is not None else 0
        timing = b.timing(done)
        log = parse_log(bytes(b.serial), rec)
        every = int(rec["log_every"])
        made = -(-done // every)
        received = sum(1 for r in log.records if r[0] < done)
        dropped = max((r[4 + len(rec["channels"])] for r in log.records if r[0] < done), default=0)
        unsent = max(0, made - received - dropped)
        n_ch = len(rec["channels"])
        faults = {}
        for i, ch in enumerate(rec["channels"]):
            ks = [r[0] for r in log.records if r[0] < done and (r[2 + n_ch] >> i) & 1]
            if ks:
                faults[ch["signal"]] = {"records": len(ks), "first_sample": ks[0], "last_sample": ks[-1]}
        rate = float(rec["rate_hz"])
        span = ran / rate
        s = {
            "samples": ran,
            "firmware_samples": done,
            "effective_rate_hz": done / span if span > 0 else None,
            "samples_skipped": ran - done,
            "samples_late": timing["samples_late"],
            "mismatched_samples": None,              # the checks' (_Checks.into)
            "samples_off_the_on_time_model": None,
            "cpu_load_percent": timing["cpu_load_percent"],
            "response_us": timing["response_us"],
            "valve_write_latency_us": timing["valve_write_latency_us"],
            "lag_behind_the_nominal_sample_us": timing["lag_behind_the_nominal_sample_us"],
            "awake_percent": 100.0 * b.awake if b.awake is not None else None,
            "overruns": b.overruns,
            "both_valves_open_samples": b.both_open,
            "adc_read_differs_samples": self.adc_differs(timing["response"], b.period),
            "log_records": {"made": made, "received": received, "dropped": dropped, "unsent": unsent,
                            # the stream is cut where the emulation stops: its last line may be partial
                            "lines_unreadable": log.bad - log.discarded.get("partial_last_line", 0),
                            "faults": faults},
            "log_lines": received,
            "log_lines_dropped": dropped,
            "flash_bytes": rec.get("flash_bytes"),
            "ram_bytes": rec.get("ram_bytes"),
            "avr_wall_s": b.avr_s,
            "log_csv": "serial.csv",
        }
        return s, bytes(b.serial)

    def adc_differs(self, response, period) -> int:
        """On-time executions (ended within their own period) that read other counts than the
        plant gave at their sample: a check of the emulation itself, 0 (a late execution reads a
        later frame's counts, as on the board)."""
        b = self.board
        n = min(len(b.counts_read), len(response))
        out = 0
        for j in range(n):
            f = b.sample_of(j)
            if response[j] <= period and f < len(b.fed) and not np.array_equal(b.counts_read[j], b.fed[f]):
                out += 1
        return out

    def close(self) -> None:
        self.board.board.close()


def _portable(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling (to cross to the plant's process), else a FrogsimError with
    its message."""
    import pickle
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:
        return FrogsimError(f"{type(exc).__name__}: {exc}")


class _Wire:
    """The per-frame messages between the plant and the board's process, as raw bytes (pickling
    the arrays each period cost more than the frame's own Python): to the board ``S`` (counts
    int64, encoder counts int32), ``E`` for the summary; back ``K`` + the result (a frame's
    changes as float64 times, int32 muscles, int8 modes; its decision or nothing; the executions
    that ended as int32 samples, int8 decisions, int64 counts read), ``X`` + a pickled exception."""

    def __init__(self, rec):
        self.n_ch = len(rec["channels"])
        self.n_enc = sum(1 for ch in rec["channels"] if "pins" in ch)
        self.n_m = len(rec["muscles"])

    def step(self, counts, encoder_counts) -> bytes:
        enc = np.asarray(encoder_counts if encoder_counts is not None else [], np.int32).tobytes()
        return b"S" + np.asarray(counts, np.int64).tobytes() + enc

    def read_step(self, msg: bytes) -> tuple:
        m = memoryview(msg)
        c_end = 1 + 8 * self.n_ch
        counts = np.frombuffer(m[1:c_end], np.int64).copy()
        enc = np.frombuffer(m[c_end:c_end + 4 * self.n_enc], np.int32).copy() if self.n_enc else None
        return counts, enc

    def result(self, changes, decision, ended) -> bytes:
        n, ne = len(changes), len(ended)
        parts = [b"K", np.array([n, 0 if decision is None else 1, ne], np.int32).tobytes()]
        if n:
            t, j, mode = zip(*changes)
            parts += [np.array(t, np.float64).tobytes(), np.array(j, np.int32).tobytes(),
                      np.array(mode, np.int8).tobytes()]
        if decision is not None:
            parts.append(np.asarray(decision, np.int8).tobytes())
        if ne:
            f, dec, read = zip(*ended)
            parts += [np.array(f, np.int32).tobytes(), np.asarray(dec, np.int8).tobytes(),
                      np.asarray(read, np.int64).tobytes()]
        return b"".join(parts)

    def read_result(self, m: memoryview) -> tuple:
        n, has, ne = np.frombuffer(m[:12], np.int32).tolist()
        at = 12
        t = np.frombuffer(m[at:at + 8 * n], np.float64).tolist()
        j = np.frombuffer(m[at + 8 * n:at + 12 * n], np.int32).tolist()
        mode = np.frombuffer(m[at + 12 * n:at + 13 * n], np.int8).tolist()
        at += 13 * n
        decision = None
        if has:
            decision = np.frombuffer(m[at:at + self.n_m], np.int8).copy()
            at += self.n_m
        ended = []
        if ne:
            f = np.frombuffer(m[at:at + 4 * ne], np.int32).tolist()
            at += 4 * ne
            dec = np.frombuffer(m[at:at + ne * self.n_m], np.int8).reshape(ne, self.n_m).copy()
            at += ne * self.n_m
            read = np.frombuffer(m[at:at + 8 * ne * self.n_ch], np.int64).reshape(ne, self.n_ch).copy()
            ended = list(zip(f, dec, read))
        return list(zip(t, j, mode)), decision, ended


def _serve_board(conn, rec, elf, plan) -> None:
    """The board's process: a :class:`_BoardSide` that answers the plant's messages in order (a
    frame -> its result, the summary request -> (figures, serial bytes), then it ends; the
    wire: :class:`_Wire`); an error is sent back as the exception and ends the process."""
    import pickle
    side = None
    wire = _Wire(rec)
    try:
        side = _BoardSide(rec, elf, plan)
        conn.send_bytes(b"K")
        while True:
            msg = conn.recv_bytes()
            if msg[:1] == b"S":
                conn.send_bytes(wire.result(*side.step(*wire.read_step(msg))))
            elif msg[:1] == b"E":
                conn.send_bytes(b"K" + pickle.dumps(side.summary(rec)))
                return
            else:
                return
    except EOFError:                     # the plant's process went away
        return
    except BaseException as exc:       # noqa: BLE001: every failure goes back to the plant
        try:
            conn.send_bytes(b"X" + pickle.dumps(_portable(exc)))
        except Exception:
            pass
    finally:
        if side is not None:
            try:
                side.close()
            except Exception:
                pass
        conn.close()


class _BoardProcess:
    """:class:`_BoardSide` in a process of its own, a frame behind the plant: :meth:`step` sends
    sample k's frame and returns the previous frame's result, so that the emulated AVR runs
    period k while the plant integrates the next one (on another core). The valve writes of a
    frame then reach the plant one period later than in one process, still before they act when
    the valves' dead time covers the extra period (:func:`pipeline_depth`); the plant receives the
    same commands at the same times, so the run is the same (tested)."""

    def __init__(self, rec, elf, plan):
        import multiprocessing
        ctx = multiprocessing.get_context("fork")
        self.wire = _Wire(rec)
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_serve_board, args=(child, rec, elf, plan), daemon=True,
                                name="frogsim-board")
        self.proc.start()
        child.close()
        self.waiting = False
        self.wait_s = 0.0            # the plant's time spent waiting for the board [s]
        self._get()

    def _get(self) -> memoryview:
        import pickle
        t0 = time.perf_counter()
        try:
            msg = self.conn.recv_bytes()
        except (EOFError, OSError):
            self.proc.join(5.0)
            raise SimulationError(f"the emulated board's process ended unexpectedly (exit code "
                                  f"{self.proc.exitcode})") from None
        finally:
            self.wait_s += time.perf_counter() - t0
        if msg[:1] == b"X":
            self.close()
            raise pickle.loads(msg[1:])
        return memoryview(msg)[1:]

    def _send(self, msg: bytes) -> None:
        try:
            self.conn.send_bytes(msg)
        except OSError:                  # the process has ended: why, if it said so before
            while True:
                self._get()              # raises its error, or that it ended unexpectedly

    def step(self, counts, encoder_counts) -> tuple:
        if counts is None:
            return [], None, []
        self._send(self.wire.step(counts, encoder_counts))
        out = self.wire.read_result(self._get()) if self.waiting else ([], None, [])
        self.waiting = True
        return out

    def summary(self, rec) -> tuple:
        """(the board's figures, the serial bytes, the executions that ended in the last frame)."""
        import pickle
        ended = []
        if self.waiting:               # the last frame's result: its writes act after the run
            ended = self.wire.read_result(self._get())[2]
            self.waiting = False
        self._send(b"E")
        s, serial = pickle.loads(self._get())
        self.close()
        return s, serial, ended

    def close(self) -> None:
        try:
            self.conn.close()
        except Exception:
            pass
        self.proc.join(5.0)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join()


def pipeline_depth(rec: dict, dead: float | None) -> int:
    """How many frames the board may run behind the plant's sample and its valve writes still act
    in time: the valves' dead time ``dead`` [s] in controller periods, less the period the plant
    runs ahead with encoders (:meth:`_Loop.__call__`). 0: the board must run in the plant's
    process, frame by frame."""
    if dead is None:
        return 0
    encoders = any("pins" in ch for ch in rec["channels"])
    periods = int(np.floor(dead * float(rec["rate_hz"]) + 1e-9))
    return max(0, periods - (1 if encoders else 0))


def free_core() -> bool:
    """Whether a second core is free for the board's process: this process may run on two or
    more, and one of them is idle now (the pipeline hands a frame over every period: on a machine
    whose cores are all busy each hand-over waits for the scheduler, and one process is faster).
    "Now" is the share of idle time of all cores over a fifth of a second (:func:`idle_cores`),
    not the load average, which trails a change of load by a minute. Without fork (not Linux)
    there is no board process."""
    import multiprocessing
    import os
    if "fork" not in multiprocessing.get_all_start_methods():
        return False
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:
        n = os.cpu_count() or 1
    if n < 2:
        return False
    idle = idle_cores()
    if idle is None:
        try:
            return os.getloadavg()[0] < n - 0.5
        except OSError:
            return True
    return idle >= 0.8


def idle_cores(window: float = 0.2) -> float | None:
    """Cores' worth of idle time over the next ``window`` seconds (from /proc/stat: the idle and
    I/O-wait ticks of all cores, over the ticks of one core); None where /proc/stat is not."""
    def ticks():
        with open("/proc/stat") as f:
            fields = [int(x) for x in f.readline().split()[1:]]
        return fields[3] + fields[4], sum(fields[:8]), os.cpu_count() or 1
    import os
    try:
        idle0, total0, n = ticks()
        time.sleep(window)
        idle1, total1, _ = ticks()
    except (OSError, ValueError, IndexError):
        return None
    if total1 <= total0:
        return None
    return n * (idle1 - idle0) / (total1 - total0)


def _parallel(rec: dict, valves, asked: bool | None, timing: str) -> bool:
    """Whether the board runs in its own process: ``asked`` (None: wherever the valves' dead time
    allows it, :func:`pipeline_depth`, and a core is free for it, :func:`free_core`); asked where
    the dead time does not allow it, an error."""
    depth = pipeline_depth(rec, min(valves.charge.dead_time, valves.discharge.dead_time))
    if asked is None:
        return depth >= 1 and timing == "cycle" and free_core()
    if asked and timing != "cycle":
        raise SimulationError("the board in its own process gives the plant its writes a period late, which "
                              "timing='grid' (each decision at its own sample) cannot take")
    if asked and depth < 1:
        raise SimulationError("the board in its own process runs a controller period behind the plant, which "
                              "needs the valves' dead time to cover that period too (encoders take one "
                              "already): run it in the plant's process (parallel=False)")
    return bool(asked)


class _Loop:
    """The controller function the Python-controller drivers call at each sample: one frame of
    the board per sample, its valve writes returned at their own times. With ``parallel`` (a
    pipeline depth of at least 1, :func:`pipeline_depth`) the board runs in its own process a
    frame behind (:class:`_BoardProcess`)."""

    #: what it reads of the driver's observations (the coupled driver then builds no more)
    observes = ("state", "qpos", "qvel")

    def __init__(self, rec, elf, plan, counts, shadow, model, progress, duration, robot, timing="cycle",
                 parallel: bool = False):
        if timing not in ("cycle", "grid"):
            raise ValueError(f"timing {timing!r}: 'cycle' or 'grid'")
        self.timing = timing
        self.rec, self.plan, self.counts, self.shadow, self.model = rec, plan, counts, shadow, model
        self.parallel = bool(parallel)
        self.side = _BoardProcess(rec, elf, plan) if self.parallel else _BoardSide(rec, elf, plan)
        self.checks = _Checks(rec, plan)
        self.muscles = list(rec["muscles"])
        self.robot = robot
        self.joint_names, self.joint_qpos = robot if robot else ((), ())
        chans = rec["channels"]
        self.encoders = [i for i, ch in enumerate(chans) if "pins" in ch]
        self.enc_start = [int(chans[i]["start_count"]) for i in self.encoders]
        self.pending = None          # with encoders: the counts of the sample whose period runs next
        self.progress = progress
        self.duration = duration
        self.wall0 = time.perf_counter()
        self.shown = self.wall0
        self.k = 0
        self.serial = b""

    def __call__(self, t, obs):
        y = obs["state"]
        qpos, qvel = obs.get("qpos"), obs.get("qvel")
        angles = None
        if qpos is not None:
            angles = {n: float(qpos[self.joint_qpos[j]]) for j, n in enumerate(self.joint_names)}
        counts = np.asarray(self.counts(self.plan, self.model, y, angles), np.int64)
        for i, at, count in getattr(self.plan, "injected", ()):
            if t >= at:                   # a sensor fault put into the plant: the wire's count
                counts[i] = count
        row = self.shadow.modes(self.k, y, qpos, qvel)
        if self.encoders:
            # the plant runs a period ahead: period k - 1 is run now that the joints' angles at
            # t_k are known, its encoder edges spread over it; its valve writes, made before
            # t_k, act a dead time later, after t_k (run_* checks the dead time covers a period)
            enc = [int(counts[i]) for i in self.encoders]
            if self.pending is None:
                for i, c0, c in zip(self.encoders, self.enc_start, enc):
                    if c != c0:
                        raise SimulationError(f"the joint of {self.rec['channels'][i]['signal']!r} starts at encoder "
                                              f"count {c}, not at the count the firmware starts from ({c0}, angle "
                                              "0): the robot must start at its encoders' zero")
                self.checks.sample(row, None)
                changes, decision, ended = self.side.step(None, None)
            else:
                self.checks.sample(row, self.pending)
                changes, decision, ended = self.side.step(self.pending, enc)
            self.pending = counts
            t = (self.k - 1) / float(self.rec["rate_hz"]) if self.k else t
        else:
            self.checks.sample(row, counts)
            changes, decision, ended = self.side.step(counts, None)
        self.checks.executions(ended)
        self.k += 1
        now = time.perf_counter()
        if self.progress is not None and now - self.shown > 2.0:
            self.shown = now
            self.progress(f"      SIL at {t:.2f} s of {self.duration:g} s simulated "
                          f"({t / (now - self.wall0):.2f} x real time)")
        if self.timing == "grid":         # the last decision ended in this period, at the sample
            if decision is None:
                return {}
            return [(float(t), m, int(x)) for m, x in zip(self.muscles, decision)]
        return [(tc, self.muscles[j], int(m)) for tc, j, m in changes]

    def summary(self, rec) -> dict:
        if self.parallel:
            s, self.serial, ended = self.side.summary(rec)
            self.checks.executions(ended)
        else:
            s, self.serial = self.side.summary(rec)
        s = self.checks.into(s)
        s["warnings"] = warnings_of(s, rec)
        s["board_process"] = self.parallel
        if self.parallel:
            s["plant_waited_s"] = self.side.wait_s
        return s

    def close(self) -> None:
        """End the board (its process, if it has one) without a summary: after a failed run."""
        if self.parallel:
            self.side.close()


def warnings_of(s: dict, rec: dict) -> list:
    """The SIL summary's findings a user must not miss, one line each (also printed on stderr)."""
    out = []
    period_ms = 1e3 / float(rec["rate_hz"])
    if s["overruns"]:
        out.append(f"the firmware overran its {period_ms:g} ms period {s['overruns']} times in {s['samples']} "
                   f"samples (CPU load up to {s['cpu_load_percent']['max']:.0f} %): on the board those samples "
                   "come late, and so they did here")
    if s["samples_late"] or s["samples_skipped"]:
        out.append(f"{s['samples_late']} samples ended after the next one was due and {s['samples_skipped']} "
                   f"were never taken: the board ran at {s['effective_rate_hz']:.1f} Hz, not "
                   f"{float(rec['rate_hz']):g} Hz (response up to {s['response_us']['max']:.0f} us)")
    lr = s["log_records"]
    if lr["dropped"]:
        out.append(f"the serial log dropped {lr['dropped']} of {lr['made']} records (its ring was full: the "
                   "board's idle time or the baud rate cannot carry it)")
    if lr["unsent"]:
        out.append(f"{lr['unsent']} of {lr['made']} log records were not sent {DRAIN_S:g} s after the run")
    if s["mismatched_samples"]:
        out.append(f"the firmware's valve commands differ from the integer twin's on the same counts at "
                   f"{s['mismatched_samples']} samples; the first: {s.get('first_mismatch')}")
    for signal, f in lr.get("faults", {}).items():
        out.append(f"sensor {signal!r} was in fault in {f['records']} log records (samples {f['first_sample']}.."
                   f"{f['last_sample']}): its muscles were put in the safe state")
    if s["both_valves_open_samples"]:
        out.append(f"a muscle's charge and discharge valves were open together {s['both_valves_open_samples']} "
                   "times")
    return out


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


#: the per-controller metrics compared between the SIL run and the compiled runs
COMPARED = ("tracking_error_rms_bar", "tracking_error_max_bar", "tracking_error_rms_deg", "tracking_error_max_deg",
            "switchings_per_s", "air_used_L_std")


def compare_runs(sil_metrics: dict, runs: dict) -> dict:
    """{controller: {metric: {"sil": x, run name: y, ..., "sil_over_<run name>": x / y}}} for the
    metrics of :data:`COMPARED` that each run reports (``runs``: {name: control metrics})."""
    out = {}
    for name, entry in sil_metrics.items():
        row = {}
        for key in COMPARED:
            x = entry.get(key)
            if not isinstance(x, (int, float)):
                continue
            cell = {"sil": float(x)}
            for run, metrics in runs.items():
                y = metrics.get(name, {}).get(key)
                if isinstance(y, (int, float)):
                    cell[run] = float(y)
                    cell[f"sil_over_{run}"] = float(x) / float(y) if y else None
            row[key] = cell
        if row:
            out[name] = row
    return out


def _compiled_block(result, compiled, float_run) -> dict:
    """The "compiled" section: the SIL run's tracking against the compiled runs of the same
    scenario: its integer twin (what an on-time board does) and its float laws (no [firmware])."""
    return {"runs": {"compiled": "the scenario's compiled laws in firmware mode (the integer twin, on time)",
                     "compiled_float": "the scenario's compiled float laws (without [firmware])"},
            "controllers": compare_runs(result.control_metrics(), {"compiled": compiled.control_metrics(),
                                                                   "compiled_float": float_run.control_metrics()})}


def _finish_sil(loop, rec, wall: float, duration: float) -> dict:
    sil = loop.summary(rec)
    sil["wall_s"] = wall
    # in one process the plant's share is what the board did not take; with the board in its
    # own process, what the plant did not spend waiting for it
    sil["plant_wall_s"] = wall - (sil["plant_waited_s"] if sil["board_process"] else sil["avr_wall_s"])
    sil["real_time_factor"] = duration / wall if wall > 0 else None
    return sil


def run_pneumatic(model, rec: dict, elf, plan, counts, progress=None, compare: bool = True,
                  timing: str = "cycle", parallel: bool | None = None) -> SilRun:
    """SIL of a pneumatic scenario (its built model ``model``) against the firmware ``elf``; with
    ``compare`` the scenario's compiled runs too (the "compiled" block).

    ``timing``: "cycle" (what `frogsim sil` runs) gives the plant each valve write at the cycle
    the firmware made it; "grid" gives it each sample's decision at the sample's own time, as the
    compiled model does (a check of the harness and the plant: an on-time firmware's SIL run is
    then the compiled run, to the solver's tolerance; the board's timing is measured the same)."""
    import dataclasses

    from frogsim.circuit.model import build_model
    from frogsim.engine.pneumatic import run_python_controller, simulate
    sc = model.scenario
    dt = 1.0 / sc.controller.rate
    shadow = Shadow(model.laws, model.mp, sc, rec["muscles"], dt, model.names)
    parallel = _parallel(rec, sc.valves, parallel, timing)
    loop = _Loop(rec, elf, plan, counts, shadow, model, progress, sc.duration, None, timing, parallel)
    t0 = time.perf_counter()
    try:
        result = run_python_controller(model, loop, every_muscle=True)
    except BaseException:
        loop.close()
        raise
    wall = time.perf_counter() - t0
    result.python_law = None           # measured against the scenario's own setpoints, as compiled
    sil = _finish_sil(loop, rec, wall, sc.duration)
    if compare:
        sil["compiled"] = _compiled_block(result, simulate(model),
                                          simulate(build_model(dataclasses.replace(sc, firmware=None))))
    return SilRun(result, sil, loop.serial)


def run_robot(rs, rec: dict, elf, plan, counts, progress=None, compare: bool = True,
              timing: str = "cycle", parallel: bool | None = None) -> SilRun:
    """SIL of a robot scenario: the coupled engine (MuJoCo and the pneumatics) as the plant; with
    ``compare`` the scenario's compiled runs too (the "compiled" block); ``timing`` as
    :func:`run_pneumatic` takes it."""
    import dataclasses

    from frogsim.engine.coupled import build_coupled
    from frogsim.engine.coupled_python import run_coupled_python
    from frogsim.engine.swim import SwimResult, swim
    cm = build_coupled(rs)
    a = cm.arrays
    dt = 1.0 / rs.pneumatic.controller.rate
    if any("pins" in ch for ch in rec["channels"]):
        v = rs.pneumatic.valves
        dead = min(v.charge.dead_time, v.discharge.dead_time)
        if dead < dt:
            raise SimulationError(f"SIL with encoders runs the plant a controller period ahead of the board, "
                                  f"which needs the valves' dead time ({dead * 1e3:g} ms) to be at least the "
                                  f"period ({dt * 1e3:g} ms)")
    shadow = Shadow(a["laws"].copy(), a["mp"], cm.pneumatic.scenario, rec["muscles"], dt, list(cm.muscle_names),
                    joints=(a["leg_qpos"], a["leg_dof"]))
    parallel = _parallel(rec, rs.pneumatic.valves, parallel, timing)
    loop = _Loop(rec, elf, plan, counts, shadow, cm.pneumatic, progress, rs.duration,
                 (list(cm.joint_names), a["leg_qpos"]), timing, parallel)
    try:
        out = run_coupled_python(cm, loop, every_muscle=True)
    except BaseException:
        loop.close()
        raise
    shadow.copy_counters(a["cs"])
    result = SwimResult(rec=out["rec"], model=cm, stats=out["stats"], wall_s=out["wall_s"],
                        compile_s=out.get("compile_s", 0.0), python_law=None)
    sil = _finish_sil(loop, rec, out["wall_s"], rs.duration)
    if compare:
        floats = dataclasses.replace(rs, pneumatic=dataclasses.replace(rs.pneumatic, firmware=None))
        sil["compiled"] = _compiled_block(result, swim(rs), swim(floats))
    return SilRun(result, sil, loop.serial)
