"""Does a firmware plan fit the ATmega2560? The control interrupt's worst case plus the serial
log's share of the CPU against the controller period, known before anything is written.

Two sources for the interrupt's cycles:

* ``emulated``: the built machine code timed on the emulated board
  (:func:`frogsim.export.sil.interrupt_timing`: 200 periods of random counts, the busy pin's
  largest high time), and the share of the time the chip was awake outside the interrupt, which
  is the log's (its formatting in ``loop()`` and the serial port's byte interrupts);
* ``estimate``: a cycle count from the plan without building: each conversion's ADC clocks
  (datasheet Table 26-1: 25 for the first after enabling, 13 after; times the prescaler) and
  its interrupt, converted in the background while the laws run; each law's cycles per call on
  the AVR (:data:`LAW_CYCLES`, measured by ``benchmarks/bench_fw_laws.py`` on the emulated chip,
  the largest per kind with the sensors within their lines; a joint-angle law between its angle
  loop's runs :data:`JOINT_HOLD_CYCLES`, a joint's second law following the first's run
  :data:`JOINT_FOLLOW_CYCLES`; each with :data:`LAW_OVERHEAD_CYCLES`), each law starting when its
  channels are converted, the ADC's interrupts (:data:`ADC_INTERRUPT_CYCLES`) taken from them; the runtime's
  own work (:data:`RUNTIME_CYCLES`, :data:`VALVE_CYCLES`, :data:`HISTORY_CYCLES`), and the log's formatting and sending
  (:data:`FORMAT_CYCLES_PER_DIGIT`, :data:`UART_CYCLES_PER_BYTE`) at its rate.

A plan fits when the interrupt's worst case plus the log's share is at most the period
(:func:`check_fit` refuses it otherwise, naming what would fit: a lower rate, fewer channels, a
faster ADC clock).
"""
from __future__ import annotations

import math

from frogsim.components import atmega2560 as chip
from frogsim.errors import ScenarioError

#: AVR cycles per call of each kind's law, the largest measured on a sensor within its line
#: (benchmarks/bench_fw_laws.py, "typical": the joint-angle law's 16-bit path with a generated sine
#: setpoint, a run of its angle loop). An angle count jumping across its range every sample sends the
#: joint-angle law down its int64 path (up to 2300 cycles): --build's timing on random counts shows
#: that case.
LAW_CYCLES = {"program": 140, "bang_bang": 500, "pwm": 1150, "sliding_mode": 2340, "joint_angle": 1500}
#: a joint-angle law at a sample its angle loop does not run (the schedule, the velocity window's
#: angle, the relay on the held target, the fault check and the channels' reads), and the second law
#: of a joint following the first's run (fs_joint_angle_follow): measured in the interrupt of
#: swim-board on the emulated chip (200 to 370 and 400 to 470 cycles)
JOINT_HOLD_CYCLES = 400
JOINT_FOLLOW_CYCLES = 500
#: the ADC-complete interrupt: entry, the count stored, the next input started, exit
ADC_INTERRUPT_CYCLES = 90
#: per law, in frogsim_sample: its channels read, their fault checks, the call
LAW_OVERHEAD_CYCLES = 100
#: the control interrupt's own cycles: entry and exit, the busy pin, the encoders' copy, the first
#: conversion's start, the call of frogsim_sample, the log record's bookkeeping (measured: an
#: interrupt with one program law and no channel, less the law)
RUNTIME_CYCLES = 300
#: per muscle: its two valve pins written (closing first, then opening) and its bits in a record
VALVE_CYCLES = 16
#: per muscle: its command shifted into its 32-bit valve history each sample, the history copied into
#: a record (log format 3); measured: the interrupt's worst case of tests/firmware/every-kind.toml
#: (five muscles) grew by 507 cycles with the histories, hold-3bar's (one muscle) by 54
HISTORY_CYCLES = 100
#: per muscle: its command compared with the sample before's and, where it switched, stored as a
#: valve event (log format 4) at the worst sample, every muscle switching: measured on swim-board's
#: firmware (12 muscles), sample 0 (every muscle leaving hold) grew by 490 cycles with the events
EVENT_CYCLES = 40
#: loop()'s decimal formatting: about nine subtractions of a power of ten a digit
FORMAT_CYCLES_PER_DIGIT = 90
#: HardwareSerial's data-register-empty interrupt, one a byte sent
UART_CYCLES_PER_BYTE = 80


def _law_key(law) -> str:
    return law.module.__name__.rsplit(".", 1)[-1]


def _law_cycles(plan) -> list:
    """[[cycles of law j at sample s] for each law] over the samples in which every joint-angle
    law's schedule runs its course twice (the first sample included): a joint-angle law costs a
    run of its loop at the samples its schedule gives (:func:`frogsim.control.kinds.joint_angle.
    angle_loop_due`), a hold at the others, and the second law of a joint (the C's pairs,
    :func:`frogsim.control.firmware._joint_pairs`) a follow where the first runs."""
    from frogsim.control import firmware as fwm
    from frogsim.control.kinds import joint_angle
    laws = plan.laws
    every = [max(1, int(law.P[joint_angle.P_EVERY])) if law.module is joint_angle else 1 for law in laws]
    samples = 2 * max(every, default=1) + 1
    followers = fwm._joint_pairs(laws, fwm._table_names(laws))
    out = []
    for j, law in enumerate(laws):
        key = _law_key(law)
        if law.module is not joint_angle:
            out.append([LAW_CYCLES.get(key, max(LAW_CYCLES.values()))] * samples)
            continue
        row, left = [], 0
        for _ in range(samples):
            due, left = joint_angle.angle_loop_due(law.P[joint_angle.P_EVERY], law.P[joint_angle.P_PHASE], left)
            row.append((JOINT_FOLLOW_CYCLES if j in followers else LAW_CYCLES[key]) if due else JOINT_HOLD_CYCLES)
        out.append(row)
    return out


def estimate(plan, line_bytes: int) -> dict:
    """The plan's worst interrupt [CPU cycles] and the log's share of the CPU, from the cycle
    counts above (module docstring); ``line_bytes`` the longest log line.

    The analog channels are converted in the background, one after the other in the order the
    laws read them (the first 25 ADC clocks, the others 13, each followed by the ADC interrupt);
    each law starts when the conversions it reads are done and the law before it has ended. The
    worst sample of the laws' schedules is the estimate's."""
    from frogsim.export.sketch import _conversion_order
    order = [i for i, _ in _conversion_order(plan)]
    n_analog = len(order)
    one = plan.adc.cycles * plan.adc.prescaler + ADC_INTERRUPT_CYCLES
    first = (plan.adc.first_cycles - plan.adc.cycles) * plan.adc.prescaler if n_analog else 0
    done = {i: first + (q + 1) * one for q, i in enumerate(order)}          # [cycles] each channel's count
    chain = first + n_analog * one
    per_law = _law_cycles(plan)
    worst_laws, worst = 0, 0.0
    for s in range(len(per_law[0]) if per_law else 1):
        t, total = 0, 0
        for j, law in enumerate(plan.laws):
            ready = max(done.get(law.pressure, 0), done.get(law.angle, 0))
            t = max(t, ready) + per_law[j][s] + LAW_OVERHEAD_CYCLES
            total += per_law[j][s] + LAW_OVERHEAD_CYCLES
        # the ADC's interrupts take their cycles from the laws' (none waits for them but the chain)
        t = max(t + n_analog * ADC_INTERRUPT_CYCLES, chain)
        if t >= worst:
            worst, worst_laws = t, total
    from frogsim.export.sketch import event_slots, history_samples
    history = HISTORY_CYCLES if history_samples(plan) else (EVENT_CYCLES if event_slots(plan) else 0)
    interrupt = RUNTIME_CYCLES + worst + (VALVE_CYCLES + history) * len(plan.muscles)
    log_rate = plan.rate / plan.log_every
    log_cycles_per_s = log_rate * line_bytes * (FORMAT_CYCLES_PER_DIGIT + UART_CYCLES_PER_BYTE)
    return {"method": "estimate", "period_cycles": int(plan.period_cycles), "interrupt_max_cycles": int(interrupt),
            "conversion_cycles": int(n_analog * plan.adc.cycles * plan.adc.prescaler + first),
            "law_cycles": int(worst_laws),
            "interrupt_max_percent": 100.0 * interrupt / plan.period_cycles,
            "log_percent": 100.0 * log_cycles_per_s / chip.F_CPU}


def emulated(timing: dict) -> dict:
    """The fit from the build's timing on the emulated board (:func:`frogsim.export.sil.interrupt_timing`)."""
    return {"method": "emulated", "period_cycles": int(timing["period_cycles"]),
            "interrupt_max_cycles": int(round(timing["max_percent"] / 100.0 * timing["period_cycles"])),
            "interrupt_max_percent": float(timing["max_percent"]),
            "interrupt_mean_percent": float(timing["mean_percent"]),
            "log_percent": float(timing["awake_outside_interrupt_percent"]),
            "samples_late": int(timing.get("samples_late", 0))}


def total(fit: dict) -> float:
    """[%] the period the worst interrupt and the log's share take together."""
    return fit["interrupt_max_percent"] + fit["log_percent"]


def check_fit(fit: dict, plan, allow: bool = False) -> dict:
    """``fit`` with its verdict (``fits``, ``total_percent``); ScenarioError naming what would fit
    unless it fits or ``allow`` (--allow-overrun)."""
    fit = dict(fit, total_percent=total(fit))
    fit["fits"] = fit["total_percent"] <= 100.0 and not fit.get("samples_late")
    if fit["fits"] or allow:
        fit["allowed_overrun"] = not fit["fits"]
        return fit
    P = fit["period_cycles"]
    used = fit["total_percent"] / 100.0 * P                 # cycles a period needs
    n_analog = sum(1 for ch in plan.channels if not getattr(ch, "pins", ()))
    conv = _conversions(n_analog, plan.adc.prescaler, plan.adc)
    other = fit["interrupt_max_cycles"] - conv              # the laws' and the runtime's cycles
    log_per_s = fit["log_percent"] / 100.0 * chip.F_CPU
    ways = []
    rate = _rate_that_fits(n_analog, other, log_per_s, plan)
    if rate is not None:
        ways.append(f"a controller rate of at most {rate:g} Hz")
    conv1 = plan.adc.cycles * plan.adc.prescaler
    if n_analog:
        fewer = math.ceil((used - P) / conv1)
        if fewer < n_analog:
            ways.append(f"{fewer} fewer analog channel(s) ({conv1} cycles each)")
        faster = [p for p in chip.ADC_PRESCALERS if p < plan.adc.prescaler and chip.F_CPU / p <= chip.ADC_MAX_CLOCK_HZ]
        if faster:
            p = max(faster)
            saved = n_analog * plan.adc.cycles * (plan.adc.prescaler - p)
            if saved >= used - P:
                ways.append(f"a faster ADC clock (prescaler {p}, {chip.F_CPU / p / 1e3:g} kHz, "
                            f"{chip.adc_bits(p)}-bit results)")
    ways.append("fewer or cheaper laws")
    raise ScenarioError("controller.rate", f"{plan.rate:g} Hz",
                        f"the firmware does not fit its {P}-cycle period ({fit['method']}): the interrupt takes up to "
                        f"{fit['interrupt_max_percent']:.0f} % and the serial log {fit['log_percent']:.0f} %, "
                        f"{fit['total_percent']:.0f} % in all; what would fit: " + ", or ".join(ways)
                        + " (--allow-overrun writes it anyway)")


def _conversions(n: int, prescaler: int, adc) -> int:
    """[cycles] the worst sample's conversions: the first after enabling takes 25 ADC clocks."""
    return n * adc.cycles * prescaler + ((adc.first_cycles - adc.cycles) * prescaler if n else 0)


def _rate_that_fits(n_analog: int, other: float, log_per_s: float, plan) -> float | None:
    """The highest controller rate below the plan's, a whole number of Timer1 ticks in a divisor
    of 16 MHz (1000, 800, 640, 500 Hz, ...) and a multiple of the log's rate, at which the interrupt fits with the ADC clock the
    export would plan there (:func:`frogsim.components.atmega2560.plan_adc`: a slower rate leaves
    time for a slower, finer clock, whose conversions take more cycles) and the log's cycles a
    second (the same at any rate); None if none down to 1 Hz does."""
    from frogsim.export.sketch import timer1_setting
    log_rate = plan.rate / plan.log_every
    for r in _divisor_rates():
        if r >= plan.rate or abs(r / log_rate - round(r / log_rate)) > 1e-9 or r < log_rate:
            continue
        cycles = chip.F_CPU / r
        try:
            timer1_setting(int(cycles))
            a = chip.plan_adc(n_analog, 1.0 / r)
        except ValueError:
            continue
        if _conversions(n_analog, a.prescaler, plan.adc) + other + log_per_s / r <= cycles:
            return r
    return None


_RATES = None


def _divisor_rates() -> list:
    """Rates [Hz] of at least 1 Hz that divide 16 MHz into whole cycles, highest first."""
    global _RATES
    if _RATES is None:
        f = chip.F_CPU
        ds = set()
        for d in range(1, int(math.isqrt(f)) + 1):
            if f % d == 0:
                ds.update((d, f // d))
        _RATES = sorted((f / d for d in ds if f / d >= 1.0), reverse=True)
    return _RATES
