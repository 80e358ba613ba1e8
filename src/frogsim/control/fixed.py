"""Fixed point: the integer arithmetic the firmware's laws run in, shared by each kind's two twins
(the Numba law the model runs and the C law the board runs, both in the kind's module).

Why fixed point: the robot's board is an ATmega2560, an 8-bit AVR at 16 MHz without a floating
point unit; avr-gcc's software floats take some 100-200 cycles per operation (and its ``double``
is 32 bits), integer additions and shifts take one or a few. Integer arithmetic is also exact and
the same on every machine, so the model's twin and the firmware command the same valves at the
same samples, bit for bit.

The numbers:

* **Counts.** A sensor's reading is the ADC's count c (0..2^bits - 1; 10 bits: 0..1023,
  :func:`frogsim.control.signals.adc_count`). A count stands for the readings whose voltage lies
  in [c, c + 1) LSB; the laws take its middle.
* **Q4 counts.** Pressures and angles inside the laws are in sixteenths of a count (Q4: x16), so
  a setpoint or a band finer than one count keeps its place: the middle of count c is 16 c + 8.
  A setpoint p [Pa gauge] is round(16 x(p)), x(p) the count as a real number (the transducer's
  voltage times 2^bits / V_REF). Ranges: 16 x 1023 + 8 = 16376 fits int16; sums are int32.
* **Gains.** A fractional gain (the joint-angle PID's, the sliding mode's times) is a Q16 integer
  (x65536): products are taken in int64 (avr-gcc's 64-bit multiply, a few hundred cycles, only
  where the range needs it) and shifted right by 16 (an arithmetic shift: floor, the same in C
  and in Numba; no division anywhere, since C's truncates and Python's floors).
* **Tables.** What varies in time (a setpoint, a duty schedule, a program's valve states) is a
  table computed here, in Python, once, from the scenario's own functions, and read by both
  twins: the value at sample k is ``T[min(k, n - 1)]`` (after the table ends its last entry
  holds; a table ends at its last change, :func:`trimmed`, and at the latest at the run's last
  sample). Tables are int32, in flash on the board (FS_TABLE); the run's tables must fit the
  64 KB of flash the AVR's LPM instruction reaches (:data:`TABLE_BYTES_MAX`).

A row's firmware block (after its knots, from column ``laws[c, L_FW]``) is
``[len(P), len(T), P..., T...]``: the kind's integer parameters P (in RAM on the board) and its
table T (whole numbers held in floats, exact below 2^53).
"""
from __future__ import annotations

import math

import numpy as np

from frogsim.components import atmega2560 as chip
from frogsim.control.signals import setpoint
from frogsim.control.table import (L_FAULT_AHI, L_FAULT_ALO, L_FAULT_MODE, L_FAULT_N, L_FAULT_PHI,
                                   L_FAULT_PLO, L_INJ_A_AT, L_INJ_A_COUNT, L_INJ_P_AT, L_INJ_P_COUNT, L_JOINT1,
                                   L_MUSCLE)
from frogsim.control.table import (L_AADC_FULL, L_AADC_K, L_AADC_Q0, L_AADC_V0, L_ADC_FULL, L_ADC_K, L_ADC_Q0, L_ADC_V0,
                                   L_ADC_VREF, L_FW, L_SP_KIND, SP_CONSTANT)
from frogsim.scenario.firmware import ENCODER_ZERO, sensed_signals

Q4 = 16                 # sixteenths of a count
Q16 = 65536             # gains
INT32_MAX = 2**31 - 1
TABLE_BYTES_MAX = 60 * 1024     # [B] the run's flash tables: below the 64 KB LPM reaches, with room
TABLE_BYTES_ONE = 32767         # [B] one table: avr-gcc's largest object (its size_t is 16 bits)
ADC_BITS = 10


def samples(sc) -> int:
    """The samples k = 0..n-1 of a run: t_k = k / rate up to the duration."""
    return int(math.floor(sc.duration * sc.controller.rate + 1e-9)) + 1


def sample_times(sc, n: int) -> np.ndarray:
    """t_k [s] of the first n samples, as the compiled sample computes them (k times 1 / rate)."""
    dt = 1.0 / sc.controller.rate
    return np.arange(n, dtype=float) * dt


def pressure_volts(fw) -> tuple:
    """(v0 [V], k [V/Pa], q0 [Pa gauge]): the transducer's line V = v0 + k (p - q0)."""
    t = fw.transducer
    return (t.low_voltage, (t.high_voltage - t.low_voltage) / (t.high_pressure_gauge - t.low_pressure_gauge),
            t.low_pressure_gauge)


def angle_volts(fw) -> tuple:
    """(v0 [V], k [V/rad], q0 [rad]): the angle sensor's line."""
    a = fw.angle_sensor
    return a.low_voltage, (a.high_voltage - a.low_voltage) / (a.high_angle - a.low_angle), a.low_angle


#: an encoder count's range: the firmware's uint16 counter
ENCODER_FULL = 65536


def angle_line(sc) -> tuple:
    """(line (v0 [V], k [V/rad], q0 [rad]), full): how the firmware's angle count is made from a
    joint angle, in the form of an ADC line (count = floor((v0 + k (angle - q0)) full / V_REF),
    clipped to 0..full - 1): the potentiometer's line and the run's ADC resolution, or for
    quadrature encoders (``[firmware] angle_encoder``) the line that gives
    count = floor(angle cpr / 2 pi) + 32768 on the 16-bit counter (v0 = 0, q0 the angle of count 0,
    k cpr / (2 pi) V_REF / full)."""
    fw = sc.firmware
    enc = fw.angle_encoder
    if enc is None:
        return angle_volts(fw), adc_full(sc)
    cpr = float(enc.counts_per_revolution)
    return (0.0, cpr / (2.0 * math.pi) * fw.vref / ENCODER_FULL, -ENCODER_ZERO * 2.0 * math.pi / cpr), ENCODER_FULL


def real_count(line: tuple, fw, q, full: int = 2**ADC_BITS):
    """The count as a real number (before truncation) of reading q on the sensor line."""
    v0, k, q0 = line
    return (v0 + k * (np.asarray(q, float) - q0)) * full / fw.vref


def q4(line: tuple, fw, q, full: int = 2**ADC_BITS):
    """Reading q [Pa gauge or rad] in Q4 counts, rounded (an int, or an int64 array)."""
    x = np.floor(Q4 * real_count(line, fw, q, full) + 0.5)
    return int(x) if np.ndim(x) == 0 else x.astype(np.int64)


def q4_per_unit(line: tuple, fw, full: int = 2**ADC_BITS) -> float:
    """Q4 counts per Pa (pressure) or per rad (angle)."""
    return Q4 * line[1] * full / fw.vref


def adc_columns(row: np.ndarray, sc) -> None:
    """Write the sensors' transfer functions into a valve row (columns L_ADC_*, L_AADC_*)."""
    fw = sc.firmware
    row[L_ADC_V0], row[L_ADC_K], row[L_ADC_Q0] = pressure_volts(fw)
    (row[L_AADC_V0], row[L_AADC_K], row[L_AADC_Q0]), row[L_AADC_FULL] = angle_line(sc)
    row[L_ADC_FULL] = adc_full(sc)
    row[L_ADC_VREF] = fw.vref


def with_block(row: np.ndarray, P, T) -> np.ndarray:
    """The row with its firmware block [len(P), len(T), P..., T...] appended, L_FW pointing to it."""
    P = [int(v) for v in P]
    T = np.asarray(T, np.int64).ravel()
    for v in P:
        if abs(v) > INT32_MAX:
            raise OverflowError(f"firmware parameter {v} does not fit int32")
    if T.size and np.abs(T).max() > INT32_MAX:
        raise OverflowError("firmware table entry does not fit int32")
    row = row.copy()
    row[L_FW] = row.size
    return np.concatenate([row, np.array([len(P), T.size] + P, float), T.astype(float)])


def block(row: np.ndarray) -> tuple:
    """(P, T) of a row's firmware block, as int64 arrays (the C twin's int32 values)."""
    at = int(row[L_FW])
    n_p, n_t = int(row[at]), int(row[at + 1])
    P = row[at + 2:at + 2 + n_p].astype(np.int64)
    T = row[at + 2 + n_p:at + 2 + n_p + n_t].astype(np.int64)
    return P, T


def adc_full(sc) -> int:
    """2^bits of the run's conversions: 10 bits, or 8 where the controller period needs the faster
    ADC clock (:func:`frogsim.components.atmega2560.plan_adc`, the resolution it costs)."""
    return 2 ** chip.plan_adc(analog_signals(sc), 1.0 / sc.controller.rate).bits


def analog_signals(sc) -> int:
    """How many of the signals the firmware reads go through the ADC (all but encoder angles)."""
    wanted = sensed_signals(sc)
    if sc.firmware.angle_encoder is None:
        return len(wanted)
    return sum(1 for q, _ in wanted if q != "angle")


def setpoint_series(row: np.ndarray, sc, offset: float) -> tuple:
    """A row's setpoint at the run's samples, less ``offset`` (the atmosphere for a pressure):
    (values, rates per second) from the compiled law's own generator
    (:func:`frogsim.control.signals.setpoint`) at t_k = k / rate; one sample for a constant."""
    laws = np.ascontiguousarray(row[None, :])
    n = 1 if row[L_SP_KIND] == SP_CONSTANT else samples(sc)
    vals = np.empty(n)
    rates = np.empty(n)
    for k, t in enumerate(sample_times(sc, n)):
        vals[k], rates[k] = setpoint(laws, 0, t)
    return vals - offset, rates


def trimmed(*tables) -> list:
    """Per-sample tables of one length cut after their last change (all to the same length n >= 1):
    read as T[min(k, n - 1)] they give the same values at every sample, and a setpoint with steps
    takes as many entries as samples up to its last step."""
    n = 1
    for t in tables:
        t = np.asarray(t)
        change = np.nonzero(t[1:] != t[:-1])[0]
        if change.size:
            n = max(n, int(change[-1]) + 2)
    return [np.asarray(t)[:n] for t in tables]


def top_pressure(sc) -> float:
    """[Pa gauge] the highest source pressure (the source's, or the pump's upper limit when it
    runs): the firmware does not measure the source and takes this as its pressure."""
    p_top = sc.source.initial_pressure_gauge
    if sc.pump.enabled and sc.pump.displacement > 0:
        p_top = max(p_top, sc.pump.off_above_gauge)
    return p_top


def fault_limits(sc) -> dict:
    """{"pressure": (lo, hi), "angle": (lo, hi) or None}: the counts outside which a reading is a
    sensor fault (a transducer's live zero, low_voltage, less its ``fault_margin``, and its top
    plus the margin: lo = floor((low_voltage - margin) full / V_REF), hi = floor((high_voltage +
    margin) full / V_REF); a count below lo or above hi is a fault). A limit beyond the ADC's
    range cannot be crossed. Encoder angles have none (None): their counts are not a voltage."""
    fw = sc.firmware
    full = adc_full(sc)

    def limits(sensor):
        lo = math.floor((sensor.low_voltage - sensor.fault_margin) * full / fw.vref)
        hi = math.floor((sensor.high_voltage + sensor.fault_margin) * full / fw.vref)
        return max(lo, 0), min(hi, full - 1)
    return {"pressure": limits(fw.transducer),
            "angle": None if fw.angle_encoder is not None else limits(fw.angle_sensor)}


def injected_fault(sc, signal: str):
    """(from when [s], the count it reads) of a [firmware] sensor_faults entry for ``signal``
    (the first that names it), or None."""
    fw = sc.firmware
    for f in fw.sensor_faults:
        if f.signal == signal:
            full = adc_full(sc)
            return f.at, min(max(math.floor(f.voltage * full / fw.vref), 0), full - 1)
    return None


def fault_columns(row: np.ndarray, sc) -> None:
    """Write a valve row's sensor-fault columns (L_FAULT_*, L_INJ_*): the limits of the channels
    its law reads (its muscle's pressure if a controller senses it, its joint's angle), the mode
    while in fault and the good samples before the law resumes; a fault put into the plant."""
    from frogsim.scenario.firmware import sensed_signals as _sensed
    fw = sc.firmware
    limits = fault_limits(sc)
    sensed = set(_sensed(sc))
    muscle = list(sc.muscles)[int(row[L_MUSCLE])]
    j = int(row[L_JOINT1]) - 1
    joint = list(sc.joints)[j] if j >= 0 else None
    row[L_FAULT_PLO], row[L_FAULT_PHI] = limits["pressure"] if ("pressure", muscle) in sensed else (-1, 0)
    row[L_FAULT_ALO], row[L_FAULT_AHI] = (limits["angle"] if joint is not None and limits["angle"] is not None
                                          else (-1, 0))
    row[L_FAULT_MODE] = -1.0 if fw.fault == "vent" else 0.0
    row[L_FAULT_N] = fw.fault_resume
    inj_p = injected_fault(sc, f"{muscle} pressure")
    inj_a = injected_fault(sc, f"{joint} angle") if joint is not None else None
    row[L_INJ_P_AT], row[L_INJ_P_COUNT] = inj_p if inj_p else (math.inf, 0)
    row[L_INJ_A_AT], row[L_INJ_A_COUNT] = inj_a if inj_a else (math.inf, 0)


def firmware_row(row: np.ndarray, sc, P, T) -> np.ndarray:
    """A valve row in firmware mode: its sensors' transfer functions and fault limits written
    and its firmware block (P, T) appended."""
    row = row.copy()
    adc_columns(row, sc)
    fault_columns(row, sc)
    return with_block(row, list(P) or [0], T if len(T) else [0])


def c_array(name: str, values, flash: bool) -> str:
    """A C definition of an int32 array (in flash through FS_TABLE when ``flash``)."""
    vals = [int(v) for v in values] or [0]
    body = ",".join(str(v) for v in vals)
    return f"static const int32_t {name}[{len(vals)}]{' FS_TABLE' if flash else ''} = {{{body}}};\n"


#: C shared by every law: the table read and the relay (twins of signals.fw_at and fw_relay)
C_COMMON = """static int32_t fs_at(const int32_t *T, uint32_t k, int32_t n) {
    return (int32_t)FS_READ32(&T[k < (uint32_t)n ? k : (uint32_t)(n - 1)]);
}

static int8_t fs_relay(int32_t cq, int32_t target, int32_t half_band) {
    if (cq < target - half_band) return 1;
    if (cq > target + half_band) return -1;
    return 0;
}
"""


def clamp32(x):
    """x clipped to int32's range (what the C twin's int32 variables hold)."""
    return np.clip(x, -INT32_MAX, INT32_MAX)
