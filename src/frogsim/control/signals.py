"""What every compiled valve law shares: the controller's memory layout (``cs``), the modes a law
returns, the setpoint generators, the sensor models and the three-position relay.

The driver (:mod:`frogsim.control.sampled`) and each kind's law (:mod:`frogsim.control.kinds`)
import these; a law reads its parameters from its row of the table (:mod:`frogsim.control.table`)
and keeps its memory in its block of ``cs`` (offsets B_*; a kind with memory of its own names
its slots here).
"""
from __future__ import annotations

import math

import numpy as np

from numba.extending import register_jitable

from frogsim.circuit.sensors.spec import line_count
from frogsim._jit import jit, jit_step
from frogsim.control.table import (L_A_BITS, L_A_FS, L_A_LAG, L_A_NOISE, L_A_SEED, L_BITS, L_FS, L_LAG,
                                   L_NOISE, L_PATM, L_SEED, L_SP0, L_SP_A, L_SP_B, L_SP_C, L_SP_D,
                                   L_SP_KIND, L_SP_N, L_STREAM, SP_CONSTANT, SP_SINE, SP_STEPS)

MODE_VENT = -1.0
MODE_HOLD = 0.0
MODE_CHARGE = 1.0

# --- controller state cs[:] ------------------------------------------------------------------------------
CS_SAMPLE = 0    # index k of the last sample taken
CS_PUMP = 1      # the pump's switch: 1 running, 0 stopped
CS_DT = 2        # the controller period [s]
CS_BLOCK = 3     # length of each law's block of memory
CS_Q = 4         # capacity of each valve's queue of pending commands
CS_FW = 5        # 1 if some row of the table has a firmware block (its integer twin runs), else 0
CS_DUE = 6       # the earliest due time [s] among the queues' first entries (inf: every queue empty),
                 # kept by the queue's writers (frogsim.control.sampled: _push, apply_due)
CS_SIZE = 7      # law c's block follows (law_block)
# a valve law's block (offsets)
B_MODE = 0       # the mode last commanded (MODE_*)
B_CMD_C = 1      # the charge valve's last commanded state (queued or applied)
B_CMD_D = 2      # the discharge valve's
B_SW_C = 3       # switchings of the charge valve so far (applied)
B_SW_D = 4       # switchings of the discharge valve
B_FILT = 5       # sensor lag: filtered gauge pressure [Pa]
B_FILT_ON = 6    # 1 once the filter holds a value
B_PHASE = 7      # pwm: sample index within the period; joint-angle: samples until its angle loop
                 # runs again plus one (0: not started), see frogsim.control.kinds.joint_angle
B_PULSE = 8      # pwm: this period's pulse, samples (sign: +charge, -vent)
B_QC_HEAD = 9    # charge queue: first entry, number of entries
B_QC_N = 10
B_QD_HEAD = 11   # discharge queue
B_QD_N = 12
B_SENSED = 13    # the pressure the law read at the last sample [Pa abs]
B_SP = 14        # the setpoint at the last sample [Pa abs; joint-angle: rad]
# joint-angle laws (frogsim.control.kinds.joint_angle) and external rows with a joint
B_ANGLE = 15     # observation: the joint angle [rad] (written by the coupled engine, observe_joints)
B_OMEGA = 16     # observation: the joint's angular velocity [rad/s]
B_A_FILT = 17    # angle sensor lag: filtered angle [rad], filtered velocity [rad/s]
B_W_FILT = 18
B_A_FILT_ON = 19
B_A_SENSED = 20  # the angle and velocity the law read at the last sample
B_W_SENSED = 21
B_INT = 22       # integral of the tracked error: joint-angle [rad s], pid [Pa s]
B_TARGET = 23    # this muscle's pressure target at the last sample [Pa abs]
B_CLIPS = 24     # samples at which the pair's targets p0 +- dp/2 were clipped to [atmosphere, source]
B_FW0 = 25       # [firmware]: the integer twin's memory (FW_MEM slots, whole numbers; the C
FW_MEM = 8       # twin's int32_t mem[FW_MEM]), see frogsim.control.fixed
B_FAULT_P = 33   # [firmware]: good samples still needed after a fault of the pressure channel (0: none)
B_FAULT_A = 34   # ... of the angle channel
B_VALVE = 35     # the valve's memory between samples (a proportional valve: its spool position [-]),
                 # carried by the valve type's controller view (frogsim.circuit.valves)
B_ERR = 36       # pid: the pressure error at the last sample [Pa]
B_Q0 = 37        # queues: charge (due, state) x Q, then discharge (due, state) x Q (queue_start)
TOL = 1e-9       # [s] a due time this close to a sample is that sample
_ENTRY = 2       # a queue entry: (due time [s], state)


@register_jitable(inline="always", _nrt=False)
def law_block(cs, c):
    """Start of law c's block in the controllers' state cs (its fields at the B_* offsets from it):
    every block has cs[CS_BLOCK] entries, after the CS_* ones."""
    return int(CS_SIZE + c * cs[CS_BLOCK])


@register_jitable(inline="always", _nrt=False)
def block_size(Q):
    """Entries of a law's block whose two queues (charge, discharge) hold Q commands each."""
    return B_Q0 + 2 * _ENTRY * Q


@register_jitable(inline="always", _nrt=False)
def controller_state_size(rows, block):
    """Entries of cs for a table of ``rows`` laws whose blocks have ``block`` entries each."""
    return CS_SIZE + rows * block


@register_jitable(inline="always", _nrt=False)
def queue_start(valve, Q):
    """Offset (from a law's block) of the queue of valve path ``valve`` (0 charge, 1 discharge, the
    valve vector's VALVE_CHARGE and VALVE_VENT) for queues of Q commands."""
    return B_Q0 + _ENTRY * Q * valve


@register_jitable(inline="always", _nrt=False)
def queue_due(q, j):
    """Offset of the due time [s] of entry j of the queue at offset q (:func:`queue_start`); its
    state is the next entry."""
    return q + _ENTRY * j


@jit
def pump_band(x, on, low, high):
    """Hysteresis switch: on (1) below ``low``, off (0) above ``high``, else unchanged (``on``).

    The pump's pressure band on the source pressure x [Pa abs]: it starts when the reservoir has
    fallen below the lower limit and stops when it is above the upper one.
    """
    if x < low:
        return 1.0
    if x > high:
        return 0.0
    return on


# --- setpoints and the sensor ------------------------------------------------------------------------------
@jit
def setpoint(laws, c, t):
    """Law c's setpoint at time t: (p [Pa abs], dp/dt [Pa/s])."""
    kind = laws[c, L_SP_KIND]
    if kind == SP_CONSTANT:
        return laws[c, L_SP_A], 0.0
    if kind == SP_SINE:
        if t < laws[c, L_SP_D]:
            return laws[c, L_SP_A], 0.0
        w = 2.0 * math.pi * laws[c, L_SP_C]
        ph = w * (t - laws[c, L_SP_D])
        return laws[c, L_SP_A] + laws[c, L_SP_B] * math.sin(ph), laws[c, L_SP_B] * w * math.cos(ph)
    n = int(laws[c, L_SP_N])
    if kind == SP_STEPS:
        p = laws[c, L_SP0 + 1]
        for j in range(1, n):
            if t >= laws[c, L_SP0 + 2 * j] - TOL:
                p = laws[c, L_SP0 + 2 * j + 1]
        return p, 0.0
    # table: linear between the rows, constant outside
    if t <= laws[c, L_SP0]:
        return laws[c, L_SP0 + 1], 0.0
    for j in range(1, n):
        t1 = laws[c, L_SP0 + 2 * j]
        if t < t1:
            t0 = laws[c, L_SP0 + 2 * j - 2]
            p0 = laws[c, L_SP0 + 2 * j - 1]
            slope = (laws[c, L_SP0 + 2 * j + 1] - p0) / (t1 - t0)
            return p0 + slope * (t - t0), slope
    return laws[c, L_SP0 + 2 * n - 1], 0.0


@jit_step
def _mix64(z):
    """splitmix64's finaliser (Steele, Lea and Flood 2014): a well-mixed 64-bit hash of z."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@jit_step
def _uniform(seed, k, stream):
    """A uniform number in (0, 1) that depends only on (seed, sample k, stream): counter-based, so a
    run's noise is the same however it is advanced and on whichever thread."""
    z = (np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15) + np.uint64(k) * np.uint64(0xD1B54A32D192ED03)
         + np.uint64(stream) * np.uint64(0x8CB92BA72F3D8DD7))
    return (float(_mix64(z) >> np.uint64(11)) + 0.5) * (1.0 / 9007199254740992.0)


@jit_step
def normal_noise(seed, k, stream):
    """Standard normal noise of sample k (Box-Muller on the counter-based uniforms of streams
    ``stream`` and ``stream + 1``)."""
    u1 = _uniform(seed, k, stream)
    u2 = _uniform(seed, k, stream + 1)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@jit
def sensor_noise(seed, k):
    """Standard normal noise of sample k (streams 1 and 2: the pressure sensor's)."""
    return normal_noise(seed, k, 1)


@jit_step
def sensor_chain(x, k, noise, seed, stream, bits, fs):
    """The sensor model's noise and ADC on a (lagged) reading x at sample k: noise of standard
    deviation ``noise`` (counter-based, streams ``stream`` and ``stream + 1``), then ``bits``
    over 0..fs (rounded to fs / (2^bits - 1), clipped to the range)."""
    if noise > 0.0:
        x += noise * normal_noise(int(seed), k, stream)
    if bits > 0.0:
        lsb = fs / (2.0 ** bits - 1.0)
        x = min(max(math.floor(x / lsb + 0.5) * lsb, 0.0), fs)
    return x


@jit
def sense(laws, c, p, cs, b, k, dt):
    """The pressure [Pa abs] law c reads at sample k when the muscle's is p [Pa abs]: first-order
    lag, then noise, then the ADC (gauge pressure rounded to full_scale / (2^bits - 1), clipped
    to 0..full_scale)."""
    patm = laws[c, L_PATM]
    x = p - patm
    lag = laws[c, L_LAG]
    if lag > 0.0:
        if cs[b + B_FILT_ON] < 0.5:
            cs[b + B_FILT] = x
            cs[b + B_FILT_ON] = 1.0
        else:
            cs[b + B_FILT] += (1.0 - math.exp(-dt / lag)) * (x - cs[b + B_FILT])
        x = cs[b + B_FILT]
    stream = max(1, int(laws[c, L_STREAM]))
    x = sensor_chain(x, k, laws[c, L_NOISE], laws[c, L_SEED], stream, laws[c, L_BITS], laws[c, L_FS])
    return x + patm


@jit
def sense_joint(laws, c, cs, b, k, dt):
    """The joint angle [rad] and velocity [rad/s] law c reads at sample k from the observation
    in cs (:func:`observe_joints`): both through the angle sensor's first-order lag, then the
    angle through its noise (streams 5, 6) and encoder (bits over 0..full scale). Kept in
    cs[b + B_A_SENSED], cs[b + B_W_SENSED]."""
    th = cs[b + B_ANGLE]
    w = cs[b + B_OMEGA]
    lag = laws[c, L_A_LAG]
    if lag > 0.0:
        if cs[b + B_A_FILT_ON] < 0.5:
            cs[b + B_A_FILT] = th
            cs[b + B_W_FILT] = w
            cs[b + B_A_FILT_ON] = 1.0
        else:
            a = 1.0 - math.exp(-dt / lag)
            cs[b + B_A_FILT] += a * (th - cs[b + B_A_FILT])
            cs[b + B_W_FILT] += a * (w - cs[b + B_W_FILT])
        th = cs[b + B_A_FILT]
        w = cs[b + B_W_FILT]
    th = sensor_chain(th, k, laws[c, L_A_NOISE], laws[c, L_A_SEED], 5, laws[c, L_A_BITS], laws[c, L_A_FS])
    cs[b + B_A_SENSED] = th
    cs[b + B_W_SENSED] = w
    return th, w


#: the ATmega2560's count of a linear sensor's reading (the sensor family's shared arithmetic,
#: :func:`frogsim.circuit.sensors.spec.line_count`; the model's sample reaches it through the family's
#: dispatch, :func:`frogsim.circuit.sensors.sensor_count`)
adc_count = line_count


@jit
def fw_at(T, k, n):
    """Entry k of a firmware table of n entries, its last after the end (both twins: T[min(k, n-1)])."""
    return int(T[k if k < n else n - 1])


@jit
def fw_fault(count, lo, hi, mem, i, resume):
    """The firmware's fault check of one channel's count (both twins): a count below ``lo`` or
    above ``hi`` is a fault and sets mem[i] to ``resume``, the good samples needed before the
    channel is trusted again; a good count with mem[i] > 0 counts one of them down. True while
    the channel is in fault (this sample's count bad, or good samples still to come)."""
    if count < lo or count > hi:
        mem[i] = resume
        return True
    if mem[i] > 0:
        mem[i] -= 1
        return True
    return False


@jit
def fw_relay(cq, target, half_band):
    """The three-position relay in Q4 counts: charge below target - half_band, vent above
    target + half_band, else hold (the integer twin of :func:`bang_bang`)."""
    if cq < target - half_band:
        return 1
    if cq > target + half_band:
        return -1
    return 0


# --- the firmware's sine setpoint generator (both twins; the C twin is fs_sine in fixed.C_COMMON) -----
SINE_BITS = 10
SINE_N = 1 << SINE_BITS      # entries of the firmware's sine table: one full turn, 2 KB of int16 in flash
SINE_ONE = 32767             # the table's 1.0 (so that +-1 fit int16; the amplitudes carry 32768 / 32767)


def _sine_table() -> np.ndarray:
    """SINE_ONE sin(2 pi i / SINE_N), rounded: the firmware's sine table."""
    i = np.arange(SINE_N)
    return np.floor(SINE_ONE * np.sin(2.0 * np.pi * i / SINE_N) + 0.5).astype(np.int64)


FW_SINE = _sine_table()
# a sine block: SN_SIZE parameters of a law's P (frogsim.control.fixed.sine_block); SN_K0 < 0: none
SN_K0 = 0        # the first sample of the sine (t_k >= start); before it the mean, rate 0
SN_PHI0 = 1      # the phase at sample 0, extended back from k0 (turns x 2^32, uint32 held as int32)
SN_DPHI = 2      # the phase step per sample, round(f / rate 2^32) (uint32 held as int32)
SN_MEAN = 3      # the mean, rounded to the law's unit (Q4 counts)
SN_FRAC = 4      # the mean's remainder below that unit plus one half, in 2^-17 units (0..2^17 - 1)
SN_AMP = 5       # the amplitude in quarters of the unit, times 32768 / SINE_ONE (0..2^15 - 1)
SN_RATE = 6      # the rate's amplitude (amplitude x 2 pi f in the law's rate unit) x 32768 / SINE_ONE
                 # (0..2^16 - 1)
SN_SIZE = 7
MASK32 = 0xFFFFFFFF


@jit
def fw_sine(P, at, k):
    """The integer sine setpoint at sample k from the sine block P[at:at + SN_SIZE]: (value, rate).

    Before the block's first sample k0: (mean, 0). From it the phase is a 32-bit accumulator,
    phi = (phi0 + k dphi) mod 2^32 (the turn is 2^32; exact in both twins: uint32 in C, here
    masked, with the product split in 16-bit halves so that it stays below 2^63); the sine is
    the table's entry at phi's top SINE_BITS bits linearly interpolated over its next 16 bits,
    s = S[i] + ((S[i + 1] - S[i]) frac + 2^15) >> 16 (1.0 = SINE_ONE), the value
    mean + (amp s + frac_mean) >> 17 (amp in quarters, frac_mean holding the mean's remainder and
    the rounding half), the rate (R c + 2^14) >> 15 with c the table's entry nearest a quarter
    turn ahead (the cosine). Amplitudes are masked to their widths (15 and 16 bits) and the
    mean's remainder to 17 bits in both twins, so no sum leaves int32."""
    k = k & MASK32
    if k < (int(P[at + SN_K0]) & MASK32):
        return int(P[at + SN_MEAN]), 0
    d = int(P[at + SN_DPHI]) & MASK32
    phi = (int(P[at + SN_PHI0]) + k * (d & 0xFFFF) + (((k * (d >> 16)) & 0xFFFF) << 16)) & MASK32
    i = phi >> (32 - SINE_BITS)
    frac = (phi >> (16 - SINE_BITS)) & 0xFFFF
    s0 = FW_SINE[i]
    s = s0 + (((FW_SINE[(i + 1) & (SINE_N - 1)] - s0) * frac + 32768) >> 16)
    sp = int(P[at + SN_MEAN]) + (((int(P[at + SN_AMP]) & 0x7FFF) * s + (int(P[at + SN_FRAC]) & 0x1FFFF)) >> 17)
    c = FW_SINE[((phi + (1 << 30) + (1 << (31 - SINE_BITS))) & MASK32) >> (32 - SINE_BITS)]
    rate = ((int(P[at + SN_RATE]) & 0xFFFF) * c + 16384) >> 15
    return sp, rate


# --- the relay the laws share ---------------------------------------------------------------------------
@jit
def bang_bang(p, sp, band):
    """Three-position relay: charge below sp - band/2, vent above sp + band/2, else hold."""
    if p < sp - 0.5 * band:
        return MODE_CHARGE
    if p > sp + 0.5 * band:
        return MODE_VENT
    return MODE_HOLD


