"""Sampled controllers: valve and pump commands decided from the state at the controller's samples.

The controller samples the circuit at t_k = k ctrl_dt (ctrl_dt = 1 / rate: 1 ms at the paper's
1 kHz) and sets commands that hold until it changes them: the valves' states u (1 open, 0 shut)
and the pump's switch. Two sorts of controller give them:

* open-loop programs (the scenario's programs, the gait). Their commands are known before the run,
  so they are not evaluated while it runs: :func:`frogsim.circuit.model.build_schedule` turns them
  into the schedule (sched_t, sched_u) of the times at which the valves change (the sample that
  issues a command plus the valve's dead time), and the driver
  (:func:`frogsim.engine.integrator.advance`) applies it;
* sampled rules (this module): evaluated at every sample from the state at that instant: the
  pump's pressure band (:func:`pump_band`), a hysteresis (bang-bang) switch on the source pressure
  that acts at once (the pump's motor has no dead time in the model), and the closed-loop valve
  controllers of the scenario's ``[controllers]`` sections (:func:`bang_bang`, :func:`pwm_mode`,
  :func:`sliding_mode`; docs/control.md), each of which drives one muscle's two valves.

A run's sampled rules are the rows of a table ``laws[c, :]`` (a kind and its parameters, columns
L_* of :mod:`frogsim.circuit.laws`), built with the model (``PneumaticModel.laws``; the pump's band
alone: :func:`sampled_laws`); their memory (and the pump's switch) is a small array ``cs``
(columns CS_*) made by :func:`start_controllers`. The driver knows only three functions:
:func:`start_controllers` (once, at the start of a run), :func:`next_control_time` (where it has
to stop next for the controllers) and :func:`sample_controllers` (called there; returns True when a
command changed, so that the driver evaluates the right-hand side again).

Adding a closed-loop rule (bang-bang or PWM on a muscle pressure, sliding mode, ...) touches this
module only: a KIND_* constant and its parameter columns, the law as a small compiled function of
(parameters, t, y, u), a branch in :func:`sample_controllers` that writes its commands, and its row
in :func:`sampled_laws`. A rule that commands a valve must respect the valve's dead time: it keeps
the command with its due time (decision time + dead time) in ``cs`` (make ``cs`` longer in
:func:`start_controllers`), :func:`next_control_time` returns the earliest of the next sample and
the due times, and :func:`sample_controllers` writes a command into u when its time has come.
"""
from __future__ import annotations

import math

import numpy as np

from frogsim._jit import jit, jit_alloc, jit_step
from frogsim.circuit.laws import (  # noqa: F401  (the table's layout, re-exported)
    KIND_BANG_BANG, KIND_PUMP_BAND, KIND_PWM, KIND_SLIDING, L_BAND, L_BITS, L_BRANCH, L_CB, L_CC, L_CM,
    L_CRL, L_DB, L_DC, L_DEAD_C, L_DEAD_D, L_DM, L_DRL, L_DUTY, L_FS, L_GAIN, L_HIGH, L_HORIZON, L_INPUT,
    L_KIND, L_LAG, L_LOW, L_MINPULSE_N, L_MUSCLE, L_NOISE, L_PATM, L_PBAND, L_PENALTY, L_PERIOD_N,
    L_REST, L_RHOREF, L_SEED, L_SIZE, L_SP0, L_SP_A, L_SP_B, L_SP_C, L_SP_D, L_SP_KIND, L_SP_N,
    L_TAMB, L_TREF, SP_CONSTANT, SP_SINE, SP_STEPS, SP_TABLE,
    KIND_JOINT, L_A_BITS, L_A_FS, L_A_LAG, L_A_NOISE, L_A_SEED, L_JOINT1, L_KD, L_KI, L_KP, L_P0,
    L_SIGN, L_STREAM)  # noqa: F401
from frogsim.circuit.laws import DUTY_SCHEDULED, laws_table
from frogsim.circuit.layout import Y_PE, Y_PS, pressure_index
from frogsim.physics.flow import iso6358_mass_flow

#: a muscle whose valves a Python function drives (frogsim.simulate(..., controller=fn)): the
#: compiled sample only senses its pressure; the commands come from Python (:func:`command_valves`)
KIND_EXTERNAL = 5.0

MODE_VENT = -1.0
MODE_HOLD = 0.0
MODE_CHARGE = 1.0

# --- controller state cs[:] ------------------------------------------------------------------------------
CS_SAMPLE = 0    # index k of the last sample taken
CS_PUMP = 1      # the pump's switch: 1 running, 0 stopped
CS_DT = 2        # the controller period [s]
CS_BLOCK = 3     # length of each law's block of memory
CS_Q = 4         # capacity of each valve's queue of pending commands
CS_SIZE = 5      # law c's block starts at CS_SIZE + c * cs[CS_BLOCK]
# a valve law's block (offsets)
B_MODE = 0       # the mode last commanded (MODE_*)
B_CMD_C = 1      # the charge valve's last commanded state (queued or applied)
B_CMD_D = 2      # the discharge valve's
B_SW_C = 3       # switchings of the charge valve so far (applied)
B_SW_D = 4       # switchings of the discharge valve
B_FILT = 5       # sensor lag: filtered gauge pressure [Pa]
B_FILT_ON = 6    # 1 once the filter holds a value
B_PHASE = 7      # pwm: sample index within the period
B_PULSE = 8      # pwm: this period's pulse, samples (sign: +charge, -vent)
B_QC_HEAD = 9    # charge queue: first entry, number of entries
B_QC_N = 10
B_QD_HEAD = 11   # discharge queue
B_QD_N = 12
B_SENSED = 13    # the pressure the law read at the last sample [Pa abs]
B_SP = 14        # the setpoint at the last sample [Pa abs; joint-angle: rad]
# joint-angle laws (frogsim.circuit.laws.KIND_JOINT) and external rows with a joint
B_ANGLE = 15     # observation: the joint angle [rad] (written by the coupled engine, observe_joints)
B_OMEGA = 16     # observation: the joint's angular velocity [rad/s]
B_A_FILT = 17    # angle sensor lag: filtered angle [rad], filtered velocity [rad/s]
B_W_FILT = 18
B_A_FILT_ON = 19
B_A_SENSED = 20  # the angle and velocity the law read at the last sample
B_W_SENSED = 21
B_INT = 22       # integral of the angle error [rad s]
B_TARGET = 23    # this muscle's pressure target at the last sample [Pa abs]
B_CLIPS = 24     # samples at which the pair's targets p0 +- dp/2 were clipped to [atmosphere, source]
B_Q0 = 25        # queues: charge (due, state) x Q, then discharge (due, state) x Q
TOL = 1e-9       # [s] a due time this close to a sample is that sample


def sampled_laws(g):
    """The laws of a run without closed-loop controllers: the pump's band as a 1-D row (columns
    L_*; an empty row when the pump is off), as :func:`frogsim.circuit.laws.laws_table` makes it.
    A 1-D table is the open-loop form: the functions below take their ``laws.ndim == 1`` branch,
    which Numba compiles alone, so open-loop runs never compile the closed-loop laws."""
    return laws_table(g, [])


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


# --- the laws ---------------------------------------------------------------------------------------------
@jit
def bang_bang(p, sp, band):
    """Three-position relay: charge below sp - band/2, vent above sp + band/2, else hold."""
    if p < sp - 0.5 * band:
        return MODE_CHARGE
    if p > sp + 0.5 * band:
        return MODE_VENT
    return MODE_HOLD


@jit
def pwm_mode(laws, c, cs, b, p, sp):
    """PWM on the controller grid: each period of N samples starts with a pulse of n samples,
    n = round(duty N) (open loop: the constant duty, or the schedule's duty sp at the period's first
    sample) or round(min(|e|/proportional_band, 1) N) with e = sp - p
    (closed loop: a charge pulse for e > 0, a vent pulse for e < 0, hold after it); pulses shorter
    than the minimum are dropped, a gap after the pulse shorter than it is filled."""
    N = int(laws[c, L_PERIOD_N])
    phase = int(cs[b + B_PHASE])
    duty = laws[c, L_DUTY]
    open_loop = duty >= 0.0 or duty == DUTY_SCHEDULED
    if phase == 0:
        sign = 1.0
        if duty >= 0.0:
            d = duty
        elif duty == DUTY_SCHEDULED:
            d = sp              # the schedule's duty at this sample (checked 0..1 by the loader)
        else:
            d = (sp - p) / laws[c, L_PBAND]
            if d < 0.0:
                sign = -1.0
                d = -d
            d = min(d, 1.0)
        n_on = math.floor(d * N + 0.5)
        nmin = laws[c, L_MINPULSE_N]
        if 0 < n_on < nmin:
            n_on = 0.0
        elif n_on < N and N - n_on < nmin:
            n_on = float(N)
        cs[b + B_PULSE] = sign * n_on
    cs[b + B_PHASE] = float((phase + 1) % N)
    pulse = cs[b + B_PULSE]
    if phase < abs(pulse):
        return MODE_CHARGE if pulse > 0 else MODE_VENT
    if open_loop and laws[c, L_REST] > 0.5:
        return MODE_VENT
    return MODE_HOLD


@jit
def mode_rates(laws, c, y, p):
    """The controller's model of the muscle's pressure rate [Pa/s] under charge and under vent:
    Eq. (8) flows at the measured pressure p (source and exhaust at their pressures, every gas at
    ambient temperature, the supply's branch limit) times k R T_amb / V."""
    T = laws[c, L_TAMB]
    rho = laws[c, L_RHOREF]
    Tr = laws[c, L_TREF]
    mc = iso6358_mass_flow(y[Y_PS], T, p, T, laws[c, L_CC], laws[c, L_CB], laws[c, L_CM], laws[c, L_CRL],
                           rho, Tr)
    mc = min(mc, laws[c, L_BRANCH])
    md = iso6358_mass_flow(p, T, y[Y_PE], T, laws[c, L_DC], laws[c, L_DB], laws[c, L_DM], laws[c, L_DRL],
                           rho, Tr)
    gain = laws[c, L_GAIN]
    return gain * mc, -gain * md


@jit
def sliding_mode(laws, c, cs, b, y, p, sp, dsp):
    """Multi-mode sliding control of the pressure with a switching penalty (after Hodgson et al.'s
    seven-mode sliding control, reduced to one muscle's three modes).

    Sliding surface s = e + lambda de/dt, e = sp - p. For each mode m (charge, hold, vent) the
    error rate is de/dt = dsp/dt - dp/dt(m), dp/dt(m) from the valve model (:func:`mode_rates`,
    a model-based feedforward from Eq. (8)); the error is first carried over the valve dead time
    under the mode already commanded. The mode chosen minimises s(m)^2 + rho^2 [m opens a valve
    that the mode in force keeps shut]: closing (going to hold) is free, opening a valve must
    reduce s^2 by at least rho^2, which is a dead band around s = 0 whose width the penalty rho
    sets.
    """
    r_charge, r_vent = mode_rates(laws, c, y, p)
    last = cs[b + B_MODE]
    r_last = r_charge if last > 0 else (r_vent if last < 0 else 0.0)
    dead = max(laws[c, L_DEAD_C], laws[c, L_DEAD_D])
    e = sp - p + dead * (dsp - r_last)
    lam = laws[c, L_HORIZON]
    pen = laws[c, L_PENALTY] ** 2
    best = MODE_HOLD
    cost = math.inf
    for m in (MODE_HOLD, MODE_CHARGE, MODE_VENT):
        r = r_charge if m > 0 else (r_vent if m < 0 else 0.0)
        s = e + lam * (dsp - r)
        j = s * s + (pen if (m != last and m != MODE_HOLD) else 0.0)
        if j < cost:
            cost = j
            best = m
    return best


@jit
def joint_angle_mode(laws, c, cs, b, y, p, ts, th, w):
    """One muscle of an antagonistic pair under the joint-angle cascade (docs/control.md).

    Outer loop, PID on the joint angle read th [rad] (velocity w [rad/s]) against the angle
    setpoint sp(t): dp = Kp e + Kd (dsp/dt - w) + Ki integral(e dt), e = sp - th. The pair's
    pressure targets are p0 + dp/2 (extensor, L_SIGN = +1: its pressure raises the angle) and
    p0 - dp/2 (flexor), each clipped to [atmosphere, source pressure]; a sample at which either is
    clipped counts in cs[b + B_CLIPS] and adds nothing to the integral (anti-windup; both rows
    decide the same, as they see the same inputs). Inner loop: this muscle's sensed pressure p
    follows its target through :func:`bang_bang` with the row's band."""
    sp, dsp = setpoint(laws, c, ts)
    cs[b + B_SP] = sp
    e = sp - th
    dt = cs[CS_DT]
    integral = cs[b + B_INT] + e * dt
    dp = laws[c, L_KP] * e + laws[c, L_KD] * (dsp - w) + laws[c, L_KI] * integral
    p0 = laws[c, L_P0]
    lo = laws[c, L_PATM]
    hi = y[Y_PS]
    up = p0 + 0.5 * dp
    down = p0 - 0.5 * dp
    clipped = up > hi or up < lo or down > hi or down < lo
    if clipped:
        cs[b + B_CLIPS] += 1.0
    else:
        cs[b + B_INT] = integral
    target = up if laws[c, L_SIGN] > 0.0 else down
    target = min(max(target, lo), hi)
    cs[b + B_TARGET] = target
    return bang_bang(p, target, laws[c, L_BAND])


@jit
def observe_joints(laws, cs, qpos, qvel, leg_qpos, leg_dof):
    """Write each joint-angle row's observation into its memory: the angle qpos[leg_qpos[j]] and
    velocity qvel[leg_dof[j]] of its joint j (the coupled engine calls this before advancing the
    pneumatics over a step, so a sample in that step reads the state at the step's start)."""
    if laws.ndim == 1:
        return
    for c in range(laws.shape[0]):
        j = int(laws[c, L_JOINT1]) - 1
        if j < 0 or not _is_valve_law(laws[c, L_KIND]):
            continue
        b = _block(cs, c)
        cs[b + B_ANGLE] = qpos[leg_qpos[j]]
        cs[b + B_OMEGA] = qvel[leg_dof[j]]


# --- commands, their dead time and the driver's protocol ------------------------------------------------
@jit_step
def _block(cs, c):
    return int(CS_SIZE + c * cs[CS_BLOCK])


@jit_step
def _push(cs, b, head, q0, due, state):
    Q = int(cs[CS_Q])
    n = int(cs[b + head + 1])
    j = (int(cs[b + head]) + n) % Q
    cs[b + q0 + 2 * j] = due
    cs[b + q0 + 2 * j + 1] = state
    cs[b + head + 1] = n + 1


@jit
def command_valves(laws, c, cs, mode, ts):
    """Law c commands ``mode`` at sample time ts: each valve whose state changes gets a queued
    command due one dead time later. Charge opens only with discharge shut and the other way
    round; an opening is never due before the other valve's closing (with unequal dead times the
    valves are never open together)."""
    b = _block(cs, c)
    Q = int(cs[CS_Q])
    want_c = 1.0 if mode > 0 else 0.0
    want_d = 1.0 if mode < 0 else 0.0
    close_c = -math.inf
    close_d = -math.inf
    if want_c < cs[b + B_CMD_C]:
        close_c = ts + laws[c, L_DEAD_C]
        _push(cs, b, B_QC_HEAD, B_Q0, close_c, 0.0)
        cs[b + B_CMD_C] = 0.0
    if want_d < cs[b + B_CMD_D]:
        close_d = ts + laws[c, L_DEAD_D]
        _push(cs, b, B_QD_HEAD, B_Q0 + 2 * Q, close_d, 0.0)
        cs[b + B_CMD_D] = 0.0
    if want_c > cs[b + B_CMD_C]:
        _push(cs, b, B_QC_HEAD, B_Q0, max(ts + laws[c, L_DEAD_C], close_d), 1.0)
        cs[b + B_CMD_C] = 1.0
    if want_d > cs[b + B_CMD_D]:
        _push(cs, b, B_QD_HEAD, B_Q0 + 2 * Q, max(ts + laws[c, L_DEAD_D], close_c), 1.0)
        cs[b + B_CMD_D] = 1.0
    cs[b + B_MODE] = mode


@jit
def _is_valve_law(kind):
    return (kind == KIND_BANG_BANG or kind == KIND_PWM or kind == KIND_SLIDING or kind == KIND_EXTERNAL
            or kind == KIND_JOINT)


@jit
def apply_due(laws, t, u, cs):
    """Write into u every queued valve command due at or before t; True if a valve changed."""
    if laws.ndim == 1:                     # open loop: no valve laws, no command queue
        return False
    changed = False
    Q = int(cs[CS_Q])
    for c in range(laws.shape[0]):
        if not _is_valve_law(laws[c, L_KIND]):
            continue
        b = _block(cs, c)
        i = int(laws[c, L_MUSCLE])
        for valve in range(2):
            head = B_QC_HEAD if valve == 0 else B_QD_HEAD
            q0 = B_Q0 if valve == 0 else B_Q0 + 2 * Q
            while cs[b + head + 1] > 0:
                h = int(cs[b + head])
                if cs[b + q0 + 2 * h] > t + TOL:
                    break
                state = cs[b + q0 + 2 * h + 1]
                if u[2 * i + valve] != state:
                    u[2 * i + valve] = state
                    cs[b + B_SW_C + valve] += 1.0
                    changed = True
                cs[b + head] = float((h + 1) % Q)
                cs[b + head + 1] -= 1.0
    return changed


@jit
def next_control_time(laws, cs, ctrl_dt):
    """The next time [s] at which the controllers need the integrator to stop (inf if never): the
    next sample, or a queued valve command's due time if earlier."""
    return min(next_sample_time(laws, cs), next_due_time(laws, cs))


@jit_step
def next_sample_time(laws, cs):
    """The time [s] of the controllers' next sample (inf when the run has no sampled rule)."""
    if laws.ndim == 1:
        return (cs[CS_SAMPLE] + 1.0) * cs[CS_DT] if laws.size else math.inf
    if laws.shape[0] == 0:
        return math.inf
    return (cs[CS_SAMPLE] + 1.0) * cs[CS_DT]


@jit_step
def next_due_time(laws, cs):
    """The earliest due time [s] of the valve commands waiting in the queues (inf if none): the
    times at which a valve's state will change, known since the sample that decided it. A due
    time within TOL of a sample time k dt (a dead time that is a whole number of periods, summed
    in floating point) is that sample time when the sample is earlier: the command acts there, as
    :func:`apply_due` (tolerance TOL) applies it at that sample."""
    t = math.inf
    if laws.ndim == 1:
        return t
    Q = int(cs[CS_Q])
    for c in range(laws.shape[0]):
        if not _is_valve_law(laws[c, L_KIND]):
            continue
        b = _block(cs, c)
        if cs[b + B_QC_N] > 0:
            t = min(t, cs[b + B_Q0 + 2 * int(cs[b + B_QC_HEAD])])
        if cs[b + B_QD_N] > 0:
            t = min(t, cs[b + B_Q0 + 2 * Q + 2 * int(cs[b + B_QD_HEAD])])
    if t < math.inf:
        dt = cs[CS_DT]
        ts = math.floor(t / dt + 0.5) * dt
        if ts < t and t - ts <= TOL:
            t = ts
    return t


@jit
def sample_controllers(laws, t, y, u, cs):
    """At a stop t: write the valve commands that have come due into u; if t is the next sample,
    take it: evaluate every law on the state y and write or queue its commands (the pump's switch
    cs[CS_PUMP] at once, valve commands one dead time later). True if a command changed."""
    if laws.ndim == 1:                     # open loop (see sampled_laws): the pump's band only
        if t < (cs[CS_SAMPLE] + 1.0) * cs[CS_DT] - TOL:
            return False
        cs[CS_SAMPLE] += 1.0
        if laws.size == 0:
            return False
        on = pump_band(y[int(laws[L_INPUT])], cs[CS_PUMP], laws[L_LOW], laws[L_HIGH])
        if on != cs[CS_PUMP]:
            cs[CS_PUMP] = on
            return True
        return False
    changed = apply_due(laws, t, u, cs)
    dt = cs[CS_DT]
    if t < (cs[CS_SAMPLE] + 1.0) * dt - TOL:
        return changed              # a due time between samples
    cs[CS_SAMPLE] += 1.0
    k = int(cs[CS_SAMPLE])
    ts = cs[CS_SAMPLE] * dt
    valves = False
    for c in range(laws.shape[0]):
        kind = laws[c, L_KIND]
        if kind == KIND_PUMP_BAND:
            on = pump_band(y[int(laws[c, L_INPUT])], cs[CS_PUMP], laws[c, L_LOW], laws[c, L_HIGH])
            if on != cs[CS_PUMP]:
                cs[CS_PUMP] = on
                changed = True
            continue
        if not _is_valve_law(kind):
            continue
        valves = True
        b = _block(cs, c)
        i = int(laws[c, L_MUSCLE])
        p = sense(laws, c, y[pressure_index(i)], cs, b, k, dt)
        cs[b + B_SENSED] = p
        if kind == KIND_EXTERNAL:
            if laws[c, L_JOINT1] > 0.0:
                sense_joint(laws, c, cs, b, k, dt)
            continue                # commanded from Python (command_valves)
        if kind == KIND_JOINT:
            th, w = sense_joint(laws, c, cs, b, k, dt)
            command_valves(laws, c, cs, joint_angle_mode(laws, c, cs, b, y, p, ts, th, w), ts)
            continue
        sp, dsp = setpoint(laws, c, ts)
        cs[b + B_SP] = sp
        if kind == KIND_BANG_BANG:
            mode = bang_bang(p, sp, laws[c, L_BAND])
        elif kind == KIND_PWM:
            mode = pwm_mode(laws, c, cs, b, p, sp)
        else:
            mode = sliding_mode(laws, c, cs, b, y, p, sp, dsp)
        command_valves(laws, c, cs, mode, ts)
    if valves and apply_due(laws, t, u, cs):       # commands without dead time act at once
        changed = True
    return changed


@jit_alloc
def start_controllers(laws, t0, y, u, ctrl_dt):
    """Controller state at the start of a run at t0: pump stopped, valves under control shut, then
    the sample at or just before t0 taken (its commands hold from t0 on, or a dead time later)."""
    if laws.ndim == 1:                     # open loop: no valve laws, no command queue
        cs = np.zeros(CS_SIZE)
        cs[CS_DT] = ctrl_dt
        cs[CS_SAMPLE] = math.floor(t0 / ctrl_dt + 1e-9) - 1.0
        sample_controllers(laws, t0, y, u, cs)
        return cs
    dead = 0.0
    for c in range(laws.shape[0]):
        if _is_valve_law(laws[c, L_KIND]):
            dead = max(dead, laws[c, L_DEAD_C], laws[c, L_DEAD_D])
    Q = int(math.ceil(dead / ctrl_dt)) + 3
    block = B_Q0 + 4 * Q
    cs = np.zeros(CS_SIZE + laws.shape[0] * block)
    cs[CS_DT] = ctrl_dt
    cs[CS_BLOCK] = block
    cs[CS_Q] = Q
    cs[CS_SAMPLE] = math.floor(t0 / ctrl_dt + 1e-9) - 1.0
    sample_controllers(laws, t0, y, u, cs)
    return cs


def switch_counts(laws, cs) -> dict:
    """{law row c: (charge valve switchings, discharge valve switchings)} of the valve laws."""
    out = {}
    if laws.ndim == 1:
        return out
    for c in range(laws.shape[0]):
        if _is_valve_law(laws[c, L_KIND]):
            b = int(CS_SIZE + c * cs[CS_BLOCK])
            out[c] = (int(cs[b + B_SW_C]), int(cs[b + B_SW_D]))
    return out


_MODES = {"charge": MODE_CHARGE, "hold": MODE_HOLD, "vent": MODE_VENT,
          1: MODE_CHARGE, 0: MODE_HOLD, -1: MODE_VENT}


def command_from_python(laws, rows: dict, cs, cmds: dict, t_k: float, u, t_now: float) -> None:
    """A Python controller function's commands at sample t_k, {muscle: "charge" | "hold" | "vent"
    (or +1, 0, -1)}, checked and queued like a compiled law's (:func:`command_valves`; ``rows``:
    muscle -> its law row); commands without dead time act at once (written into u at t_now)."""
    from frogsim.errors import SimulationError
    for name, mode in (cmds or {}).items():
        if name not in rows:
            raise SimulationError(f"controller function: muscle {name!r} is not free for closed-loop "
                                  f"control (free: {', '.join(rows) or 'none'})")
        if mode not in _MODES:
            raise SimulationError(f"controller function: mode {mode!r} for {name!r} must be "
                                  "'charge', 'hold' or 'vent'")
        command_valves(laws, rows[name], cs, _MODES[mode], t_k)
    apply_due(laws, t_now, u, cs)
