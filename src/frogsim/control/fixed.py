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
  (x65536): products are shifted right by 16 (an arithmetic shift: floor, the same in C and in
  Numba; no division anywhere, since C's truncates and Python's floors). The Numba twins take
  them in int64; the C takes 16 x 16 -> 32-bit products where the ranges allow, with the same
  result (the joint-angle law: :func:`frogsim.control.kinds.joint_angle.c_source`), and int64
  elsewhere (avr-gcc's 64-bit multiply, a few hundred cycles). On the AVR the 16-bit products
  are its MUL instructions (:data:`C_ARITHMETIC`).
* **Tables.** What varies in time (a setpoint, a duty schedule, a program's valve states) is a
  table computed here, in Python, once, from the scenario's own functions, and read by both
  twins: the value at sample k is ``T[min(k, n - 1)]`` (after the table ends its last entry
  holds; a table ends at its last change, :func:`trimmed`, and at the latest at the run's last
  sample). Tables are int32, in flash on the board (FS_TABLE); the run's tables must fit the
  64 KB of flash the AVR's LPM instruction reaches (:data:`TABLE_BYTES_MAX`).
* **Sines.** A sine setpoint is generated instead, by both twins alike, from a sine block in the
  law's parameters (:func:`sine_params`, :func:`frogsim.control.signals.fw_sine`, the C
  ``fs_sine``): a 32-bit phase accumulator and a 1024-entry int16 sine table in flash,
  interpolated; within one Q4 count of the closed form (see :func:`sine_params`), and no table
  that grows with the run.

A row's firmware block (after its knots, from column ``laws[c, L_FW]``) is
``[len(P), len(T), P..., T...]``: the kind's integer parameters P (in RAM on the board) and its
table T (whole numbers held in floats, exact below 2^53).
"""
from __future__ import annotations

import math

import numpy as np

from frogsim.circuit import sensors
from frogsim.components import atmega2560 as chip
from frogsim.control.signals import FW_SINE, SINE_BITS, SINE_N, SINE_ONE, SN_SIZE, setpoint
from frogsim.control.table import (L_FAULT_AHI, L_FAULT_ALO, L_FAULT_MODE, L_FAULT_N, L_FAULT_PHI,
                                   L_FAULT_PLO, L_INJ_A_AT, L_INJ_A_COUNT, L_INJ_P_AT, L_INJ_P_COUNT, L_JOINT1,
                                   L_MUSCLE)
from frogsim.control.table import (L_AADC_CODE, L_ADC_CODE, L_AADC_FULL, L_AADC_K, L_AADC_Q0, L_AADC_V0, L_ADC_FULL, L_ADC_K, L_ADC_Q0,
                                   L_ADC_V0, L_ADC_VREF, L_FW, L_SP_A, L_SP_B, L_SP_C, L_SP_D, L_SP_KIND,
                                   SP_CONSTANT, SP_SINE)
from frogsim.scenario.firmware import sensed_signals

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
    """(v0 [V], k [V/Pa], q0 [Pa gauge]): the transducer's line V = v0 + k (p - q0) (its sensor
    type's, :mod:`frogsim.circuit.sensors`)."""
    return sensors.line(fw.transducer, fw.vref, 2**ADC_BITS)[0]


def angle_volts(fw) -> tuple:
    """(v0 [V], k [V/rad], q0 [rad]): the angle sensor's line (its sensor type's)."""
    return sensors.line(fw.angle_sensor, fw.vref, 2**ADC_BITS)[0]


def angle_sensor(fw):
    """The settings of the sensor the firmware reads joint angles with: the quadrature encoders
    (``angle_encoder``) when given, else the potentiometer (``angle_sensor``)."""
    return fw.angle_encoder if fw.angle_encoder is not None else fw.angle_sensor


def angle_line(sc) -> tuple:
    """(line (v0 [V], k [V/rad], q0 [rad]), full): how the firmware's angle count is made from a
    joint angle, in the form of an ADC line (count = floor((v0 + k (angle - q0)) full / V_REF),
    clipped to 0..full - 1): the potentiometer's line and the run's ADC resolution, or for
    quadrature encoders (``[firmware] angle_encoder``) the line that gives
    count = floor(angle cpr / 2 pi) + 32768 on the 16-bit counter (v0 = 0, q0 the angle of count 0,
    k cpr / (2 pi) V_REF / full)."""
    fw = sc.firmware
    s = angle_sensor(fw)
    return sensors.line(s, fw.vref, adc_full(sc) if fw.angle_encoder is None else 2**ADC_BITS)


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
    row[L_ADC_CODE] = sensors.of(fw.transducer).code
    row[L_AADC_CODE] = sensors.of(angle_sensor(fw)).code


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
    """{"pressure": (lo, hi) or None, "angle": (lo, hi) or None}: the counts outside which a reading is a
    sensor fault (a transducer's live zero, low_voltage, less its ``fault_margin``, and its top
    plus the margin: lo = floor((low_voltage - margin) full / V_REF), hi = floor((high_voltage +
    margin) full / V_REF); a count below lo or above hi is a fault). A limit beyond the ADC's
    range cannot be crossed. Encoder angles have none (None): their counts are not a voltage; nor
    has a sensor type whose ``faults`` gives None (frogsim.circuit.sensors)."""
    fw = sc.firmware
    full = adc_full(sc)
    return {"pressure": sensors.faults(fw.transducer, fw.vref, full),
            "angle": sensors.faults(angle_sensor(fw), fw.vref, full)}


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
    # (-1, 0): no limits (a channel not read, or a sensor type whose counts cannot show a fault)
    row[L_FAULT_PLO], row[L_FAULT_PHI] = (limits["pressure"] if ("pressure", muscle) in sensed
                                          and limits["pressure"] is not None else (-1, 0))
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


def _uint32_as_int32(v: int) -> int:
    """A uint32 (turns x 2^32) as the int32 that holds its bits, -2^31 moved to -2^31 + 1 (a
    parameter is at most 2^31 - 1 in magnitude, :func:`with_block`: 2^-32 of a turn)."""
    v %= 2**32
    v = v - 2**32 if v >= 2**31 else v
    return max(v, -INT32_MAX)


NO_SINE = [-1] + [0] * (SN_SIZE - 1)     # a sine block that says "no sine: the table"


def sine_block(row: np.ndarray, sc, line: tuple, full: int, offset: float, rate_unit: float):
    """The integer sine generator's parameters (:func:`sine_params`) for a row whose setpoint is a
    sine, or None (another kind of setpoint, or a sine the generator cannot hold: it is then
    tabulated). The setpoint is read on the sensor ``line`` (its value less ``offset``: the
    atmosphere for a pressure) in Q4 counts; its rate in Q4 counts per second times
    ``rate_unit`` (the joint-angle law's Q12 counts per sample: dt 256)."""
    if row[L_SP_KIND] != SP_SINE:
        return None
    fw = sc.firmware
    mean, amp, f, start = (float(row[L_SP_A]), float(row[L_SP_B]), float(row[L_SP_C]), float(row[L_SP_D]))
    return sine_params(Q4 * float(real_count(line, fw, mean - offset, full)), amp * q4_per_unit(line, fw, full),
                       f, start, float(sc.controller.rate), rate_unit)


SINE_AMP_MAX = 8191.0       # [Q4 counts] the largest amplitude the generator holds (the 10-bit range's half)


def sine_params(m: float, a: float, f: float, start: float, rate: float, rate_unit: float):
    """The sine block (slots SN_* of :mod:`frogsim.control.signals`, read by ``fw_sine`` and the C
    ``fs_sine``) of the setpoint m + a sin(2 pi f (t - start)) from t = start, m before
    (m and a in Q4 counts as real numbers, f [Hz], start [s]) sampled at t_k = k / rate, its rate
    in Q4 counts per second times ``rate_unit``; None if the generator cannot hold it: an
    amplitude above SINE_AMP_MAX or below 0, a rate amplitude of 2^16 units or more (the
    joint-angle law: 16 counts per sample), a mean beyond 2^30 or a start after sample 2^31 - 1.

    k0 is the first sample with k dt >= start (dt = 1 / rate, in the floating point of the
    float setpoint, :func:`frogsim.control.signals.setpoint`); the phase there is
    f (k0 dt - start) turns, rounded to 2^-32 turn, and each sample adds dphi = round(f dt 2^32)
    turns / 2^32 (the frequency is within 2^-33 / dt of f). The value's error against the
    closed form, in Q4 counts, is at most 1/2 (the rounding) + 1/8 (the amplitude's quarters)
    + 2^-18 (the mean) + a 1.16 / 32767 (the table's and the interpolation's roundings and the
    interpolation's curvature, (2 pi / SINE_N)^2 / 8 of SINE_ONE) + a 2 pi (64.5 + |k - k0| / 2)
    / 2^32 (the phase: the 6 bits below the interpolation, the rounding of the phase at k0, the
    step's rounding): below 0.98 for a <= SINE_AMP_MAX over 10^4 samples (10 s at 1 kHz); the
    step's error adds a pi / 2^32 (7.3e-10 a) per sample after that."""
    if not (0.0 <= a <= SINE_AMP_MAX and f > 0.0):
        return None
    dt = 1.0 / rate
    A = int(math.floor(4.0 * a * 32768.0 / SINE_ONE + 0.5))
    R = int(math.floor(a * 2.0 * math.pi * f * rate_unit * 32768.0 / SINE_ONE + 0.5))
    k0 = max(0, int(math.ceil(start * rate)))
    while k0 > 0 and (k0 - 1) * dt >= start:
        k0 -= 1
    while k0 * dt < start:
        k0 += 1
    W = int(math.floor(m * 2**17 + 0.5)) + 2**16          # the mean in 2^-17 units, plus a half
    if A >= 2**15 or R >= 2**16 or k0 > INT32_MAX or abs(W >> 17) > 2**30:
        return None
    dphi = int(math.floor(f / rate * 2**32 + 0.5))
    phi_k0 = int(math.floor(f * (k0 * dt - start) * 2**32 + 0.5))
    return [k0, _uint32_as_int32(phi_k0 - k0 * dphi), _uint32_as_int32(dphi), W >> 17, W & (2**17 - 1), A, R]


#: 16 x 16 -> 32 bit products and the top 10 bits of a uint32, for the laws' C. avr-gcc (5.4, -Os)
#: compiles a product of two 16-bit halves of 32-bit values as its full 32-bit multiply (__mulsi3,
#: about 100 cycles with its calls) and a 32-bit shift by n bits as a loop of n passes (6 to 8 cycles
#: each), so on the AVR the products are the chip's MUL, MULS and MULSU in a few lines of inline
#: assembly (about 20 cycles; the schoolbook sum of four 8 x 8 products, as Atmel's application
#: note AVR201 writes it) and the shifts are whole bytes; elsewhere (the tests' host build) plain C.
#: The tests check the AVR build against the Numba twins on the emulated chip
#: (tests/test_firmware_laws_avr.py).
C_ARITHMETIC = r"""#if defined(__GNUC__)
#define FS_INLINE static inline __attribute__((always_inline))
#define FS_COLD static __attribute__((noinline))
#else
#define FS_INLINE static inline
#define FS_COLD static
#endif
#if defined(__AVR_HAVE_MUL__)
FS_INLINE int32_t fs_mulss(int16_t a, int16_t b) {
    int32_t r;
    uint8_t z;
    __asm__ ("clr %[z]\n\t"
             "muls %B[a], %B[b]\n\t" "movw %C[r], r0\n\t"
             "mul %A[a], %A[b]\n\t" "movw %A[r], r0\n\t"
             "mulsu %B[a], %A[b]\n\t" "sbc %D[r], %[z]\n\t" "add %B[r], r0\n\t" "adc %C[r], r1\n\t"
             "adc %D[r], %[z]\n\t"
             "mulsu %B[b], %A[a]\n\t" "sbc %D[r], %[z]\n\t" "add %B[r], r0\n\t" "adc %C[r], r1\n\t"
             "adc %D[r], %[z]\n\t"
             "clr __zero_reg__"
             : [r] "=&r" (r), [z] "=&r" (z) : [a] "a" (a), [b] "a" (b) : "r0");
    return r;
}

FS_INLINE int32_t fs_mulsu(int16_t a, uint16_t b) {
    int32_t r;
    uint8_t z;
    __asm__ ("clr %[z]\n\t"
             "mulsu %B[a], %B[b]\n\t" "movw %C[r], r0\n\t"
             "mul %A[a], %A[b]\n\t" "movw %A[r], r0\n\t"
             "mulsu %B[a], %A[b]\n\t" "sbc %D[r], %[z]\n\t" "add %B[r], r0\n\t" "adc %C[r], r1\n\t"
             "adc %D[r], %[z]\n\t"
             "mul %A[a], %B[b]\n\t" "add %B[r], r0\n\t" "adc %C[r], r1\n\t" "adc %D[r], %[z]\n\t"
             "clr __zero_reg__"
             : [r] "=&r" (r), [z] "=&r" (z) : [a] "a" (a), [b] "a" (b) : "r0");
    return r;
}

FS_INLINE uint32_t fs_muluu(uint16_t a, uint16_t b) {
    uint32_t r;
    uint8_t z;
    __asm__ ("clr %[z]\n\t"
             "mul %B[a], %B[b]\n\t" "movw %C[r], r0\n\t"
             "mul %A[a], %A[b]\n\t" "movw %A[r], r0\n\t"
             "mul %B[a], %A[b]\n\t" "add %B[r], r0\n\t" "adc %C[r], r1\n\t" "adc %D[r], %[z]\n\t"
             "mul %A[a], %B[b]\n\t" "add %B[r], r0\n\t" "adc %C[r], r1\n\t" "adc %D[r], %[z]\n\t"
             "clr __zero_reg__"
             : [r] "=&r" (r), [z] "=&r" (z) : [a] "r" (a), [b] "r" (b) : "r0");
    return r;
}
#else
FS_INLINE int32_t fs_mulss(int16_t a, int16_t b) { return (int32_t)a * b; }
FS_INLINE int32_t fs_mulsu(int16_t a, uint16_t b) { return (int32_t)a * (int32_t)b; }
FS_INLINE uint32_t fs_muluu(uint16_t a, uint16_t b) { return (uint32_t)a * b; }
#endif

/* x >> 22 from its two top bytes */
FS_INLINE uint16_t fs_top10(uint32_t x) {
    return (uint16_t)(((uint16_t)(uint8_t)(x >> 24) << 2) | ((uint8_t)(x >> 16) >> 6));
}
"""


def _c_sine() -> str:
    """The sine table and fs_sine, the C twin of :func:`frogsim.control.signals.fw_sine` (the same
    integers: k dphi mod 2^32 from 16-bit products, the shifts by 6, 15, 17 and 22 as whole bytes:
    floor(x / 2^15) = 2 floor(x / 2^16) + bit 15 of x, floor(x / 2^17) = floor(floor(x / 2^16) / 2))."""
    body = ",".join(str(int(v)) for v in FW_SINE)
    assert SINE_BITS == 10              # fs_top10 and the fraction's bytes below
    return f"""/* {SINE_ONE} sin(2 pi i / {SINE_N}): the sine generator's table (frogsim.control.signals.FW_SINE) */
static const int16_t fs_sine_table[{SINE_N}] FS_TABLE = {{{body}}};

/* The sine block S's setpoint at sample k (twin of frogsim.control.signals.fw_sine): its value,
 * its rate in *rate (unless rate is 0: a law that reads no rate). Before S[0], the mean; then phase
 * phi = S[1] + k S[2] (mod 2^32), the table interpolated over phi's 16 bits below its index, the
 * cosine at the nearest entry. */
int32_t fs_sine(uint32_t k, const int32_t *S, int32_t *rate) {{
    uint32_t phi;
    uint16_t klo = (uint16_t)k, khi = (uint16_t)(k >> 16);
    uint16_t dlo = (uint16_t)S[2], dhi = (uint16_t)((uint32_t)S[2] >> 16), i, frac;
    int16_t s0, s, c;
    int32_t y;
    if (k < (uint32_t)S[0]) {{
        if (rate) *rate = 0;
        return S[3];
    }}
    /* k S[2] mod 2^32 = klo dlo + ((klo dhi + khi dlo) mod 2^16) 2^16 */
    phi = (uint32_t)S[1] + fs_muluu(klo, dlo)
          + ((uint32_t)(uint16_t)((unsigned)klo * dhi + (unsigned)khi * dlo) << 16);
    i = fs_top10(phi);
    frac = (uint16_t)(((uint16_t)(phi >> 8) << 2) | ((uint8_t)phi >> 6));       /* phi >> 6, mod 2^16 */
    s0 = (int16_t)FS_READ16(&fs_sine_table[i]);
    s = (int16_t)FS_READ16(&fs_sine_table[(i + 1) & {SINE_N - 1}]);
    s = (int16_t)(s0 + (int16_t)((fs_mulsu((int16_t)(s - s0), frac) + 32768L) >> 16));
    if (rate) {{
        c = (int16_t)FS_READ16(&fs_sine_table[fs_top10(phi + {(1 << 30) + (1 << (31 - SINE_BITS))}UL)]);
        y = fs_mulsu(c, (uint16_t)S[6]) + 16384L;
        *rate = (y >> 16) * 2 + ((uint16_t)y >> 15);
    }}
    return S[3] + ((int16_t)((fs_mulsu(s, (uint16_t)(S[5] & 0x7FFF)) + (S[4] & 0x1FFFFL)) >> 16) >> 1);
}}
"""


#: C shared by every law: the arithmetic, the table read, the relay and the sine generator (twins
#: of signals.fw_at, fw_relay and fw_sine)
C_COMMON = C_ARITHMETIC + """
int32_t fs_sine(uint32_t k, const int32_t *S, int32_t *rate);

static int32_t fs_at(const int32_t *T, uint32_t k, int32_t n) {
    return (int32_t)FS_READ32(&T[k < (uint32_t)n ? k : (uint32_t)(n - 1)]);
}

static int8_t fs_relay(int32_t cq, int32_t target, int32_t half_band) {
    if (cq < target - half_band) return 1;
    if (cq > target + half_band) return -1;
    return 0;
}

""" + _c_sine()


def clamp32(x):
    """x clipped to int32's range (what the C twin's int32 variables hold)."""
    return np.clip(x, -INT32_MAX, INT32_MAX)
