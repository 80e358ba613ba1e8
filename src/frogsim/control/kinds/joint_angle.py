"""Kind "joint-angle": a cascade on an antagonistic pair (robot scenarios): PID on the joint angle
giving the pair's pressure targets, each muscle's pressure following its target by a relay.

The angle loop (the PID) may run at a lower rate than the pressure relays (``angle_rate``, the
controller rate divided by a whole number N): it runs at every N-th sample, the joints' loops
staggered over the N samples (:func:`angle_schedule`), and its targets hold in between. A board
then computes a few PIDs a sample instead of every one (docs/firmware.md)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from frogsim._jit import jit
from frogsim.circuit.layout import Y_PS
from frogsim.control import fixed
from frogsim.control.kinds.common import SensedLoop
from frogsim.control.kinds.spec import ANGLE_TRACKING, ControllerKind, FirmwareTwin, Gain
from frogsim.control.signals import (SN_SIZE, B_CLIPS, B_INT, B_PHASE, B_SP, B_TARGET, CS_DT, CS_SAMPLE, bang_bang,
                                     fw_relay, fw_sine, sense_joint, setpoint)
from frogsim.control.table import (L_A_BITS, L_A_EVERY, L_A_FS, L_A_LAG, L_A_NOISE, L_A_PHASE, L_A_SEED, L_BAND,
                                   L_GAIN, L_JOINT1, L_KD, L_KI, L_KP, L_MUSCLE, L_P0, L_PATM, L_SIGN, L_STREAM,
                                   valve_row, with_setpoint)
from frogsim.errors import MISSING, ScenarioError
from frogsim.scenario.fields import quantity
from frogsim.scenario.rules import check_below_source
from frogsim.scenario.schema import BAR, GAUGE_MAX, AngleSensor, AngleSetpoint

CODE = 6.0      # the table's kind column (one row per muscle of the pair)


@dataclass(frozen=True)
class JointAngleSettings(SensedLoop):
    """``joint`` names the joint; ``muscle`` (the extensor: its pressure raises the joint angle) and
    ``antagonist`` (the flexor) are derived from it by the robot scenario's loader."""
    KIND = "joint-angle"
    NAMED = "joint"
    joint: str = ""
    antagonist: str = field(default="", metadata={"derived": True})
    setpoint: AngleSetpoint | None = None
    co_contraction: float = quantity("pressure", ge=0.0, le=GAUGE_MAX, display="bar", default=2.0 * BAR,
                                     doc="p0, the pair's common gauge pressure (stiffness)")
    proportional_gain: float = quantity("pressure_per_angle", ge=0.0, display="bar/rad", default=10.0 * BAR,
                                        doc="pressure difference per radian of angle error")
    derivative_gain: float = quantity("pressure_time_per_angle", ge=0.0, display="bar*s/rad", default=0.0,
                                      doc="pressure difference per rad/s of rate error")
    integral_gain: float = quantity("pressure_per_angle_time", ge=0.0, display="bar/(rad*s)", default=0.0,
                                    doc="pressure difference per rad*s of integrated error")
    band: float = quantity("pressure", gt=0.0, le=GAUGE_MAX, display="bar", default=0.1 * BAR,
                           doc="the inner relay's hold band")
    angle_rate: float | None = quantity("frequency", gt=0.0, display="Hz", default=None,
                                        doc="the angle loop's rate: the controller rate divided by a whole "
                                            "number (default: the controller rate, every sample)")
    angle_sensor: AngleSensor = field(default_factory=AngleSensor)

    def angle_every(self, rate: float) -> int:
        """N: the angle loop runs every N samples of a controller at ``rate`` [Hz] (the rules
        checked that rate / angle_rate is a whole number)."""
        if self.angle_rate is None:
            return 1
        return max(1, int(round(rate / self.angle_rate)))

    def driven(self) -> tuple:
        return (self.muscle, self.antagonist)

    def sensed(self) -> tuple:
        """Both muscles' pressures (each inner relay's) and the joint's angle."""
        return (("pressure", self.muscle), ("pressure", self.antagonist), ("angle", self.joint))

    def check_target(self, sc, path: str) -> None:
        """A joint of the robot with an antagonistic pair. The setpoint's range against the
        joint's is checked by the robot's loader, which knows it."""
        if not sc.joints:
            raise ScenarioError(f"{path}.kind", self.kind, "a joint-angle controller needs a robot scenario "
                                                           "([robot] and [gait]; frogsim.load_robot_scenario)")
        if self.joint not in sc.joints:
            raise ScenarioError(f"{path}.joint", self.joint,
                                f"must name a joint of the robot ({', '.join(sc.joints)})")
        if not self.antagonist:
            raise ScenarioError(f"{path}.joint", self.joint,
                                "has no antagonistic pair (robot.recovery = \"spring\"): a joint-angle "
                                "controller needs robot.recovery = \"muscle\"")

    def check(self, sc, path: str, p_top: float) -> None:
        if self.setpoint is None:
            raise ScenarioError(f"{path}.setpoint", MISSING, "required for kind 'joint-angle'")
        self.setpoint.check_complete(f"{path}.setpoint")
        check_below_source(self, "co_contraction", f"{path}.co_contraction", p_top)
        if self.angle_rate is not None:
            rate = sc.controller.rate
            ratio = rate / self.angle_rate
            if self.angle_rate > rate * (1.0 + 1e-9) or abs(ratio - round(ratio)) > 1e-6 * ratio:
                first = max(1, math.ceil(ratio - 1e-6))          # the whole N at or above the ratio
                below = [rate / n for n in range(first, first + 3)]
                raise ScenarioError(f"{path}.angle_rate", f"{self.angle_rate:g} Hz",
                                    f"must be the controller rate ({rate:g} Hz) divided by a whole number: the angle "
                                    f"loop runs every N samples (e.g. {', '.join(f'{r:.6g} Hz' for r in below)})")

    def write_rows(self, name: str, ctx) -> list:
        """Two rows, the extensor's then the flexor's: each drives one muscle's valves from the same
        angle law."""
        row = valve_row(ctx, CODE, self.muscle, self.sensor)
        row[L_BAND] = self.band
        row[L_JOINT1] = 1 + list(ctx.sc.joints).index(self.joint)
        row[L_P0] = ctx.patm + self.co_contraction
        row[L_KP], row[L_KD], row[L_KI] = self.proportional_gain, self.derivative_gain, self.integral_gain
        row[L_A_EVERY], row[L_A_PHASE] = angle_schedule(ctx.sc, name)
        a = self.angle_sensor
        row[L_A_NOISE], row[L_A_SEED], row[L_A_BITS], row[L_A_FS], row[L_A_LAG] = (
            a.noise, a.seed, a.bits or 0, a.full_scale, a.lag)
        flex = row.copy()
        row[L_SIGN], row[L_STREAM] = 1.0, 1.0
        flex[L_SIGN], flex[L_STREAM] = -1.0, 3.0        # the flexor's pressure sensor: its own noise
        flex[L_MUSCLE] = ctx.names.index(self.antagonist)
        flex[L_GAIN] = valve_row(ctx, CODE, self.antagonist, self.sensor)[L_GAIN]
        # a joint-angle setpoint is an angle [rad]: no atmosphere added
        rows = [with_setpoint(row, self.setpoint, 0.0), with_setpoint(flex, self.setpoint, 0.0)]
        if ctx.sc.firmware is not None:
            rows = [self.firmware_row(r, name, ctx) for r in rows]
        return rows

    def firmware_row(self, row, name: str, ctx):
        """The integer twin's block (fixed point: :mod:`frogsim.control.fixed`). Pressures in Q4
        counts of the transducer, angles in Q4 counts of the angle sensor, gains in Q16:
        P = [sign (+1 extensor, -1 flexor), p0, atmosphere, source pressure (the targets' clip
        limits; the firmware does not measure the source: its pressure at the start), Kp
        (pressure Q4 per angle Q4, Q16), Kd / dt (per Q12 angle counts per run, Q16),
        Ki dt (Q16), half band, setpoint table length n, the velocity filter's shift
        (log2 of [firmware] velocity_filter, VELOCITY_SHIFT by default), then the sine block
        (P_SINE.., :func:`frogsim.control.fixed.sine_block`), then the angle loop's schedule N and
        phase (P_EVERY, P_PHASE, :func:`angle_schedule`)], dt the angle loop's period N / rate.
        A sine setpoint is generated by the sine block (T holds nothing); any other (or a sine
        the generator cannot hold) is tabulated, the sine block's first slot -1: T = the angle
        setpoint at each sample (Q4), then its rate at each sample (Q12 counts per run)."""
        sc = ctx.sc
        fw = sc.firmware
        full = fixed.adc_full(sc)
        pline = fixed.pressure_volts(fw)
        aline, afull = fixed.angle_line(sc)
        per_pa = fixed.q4_per_unit(pline, fw, full)
        per_rad = fixed.q4_per_unit(aline, fw, afull)
        every, phase = max(1, int(row[L_A_EVERY])), int(row[L_A_PHASE])
        window = every if fw.velocity_window is None else int(fw.velocity_window)   # at most N: the rules
        dt = every / sc.controller.rate                  # the angle loop's period
        dt_v = window / sc.controller.rate               # the velocity difference's span
        sine = fixed.sine_block(row, sc, aline, afull, 0.0, dt_v * 256.0)
        if sine is None:
            sp, dsp = fixed.setpoint_series(row, sc, 0.0)
            sp_q, dsp_q = fixed.trimmed(fixed.q4(aline, fw, sp, afull),
                                        np.clip(np.floor(dsp * dt_v * per_rad * 256.0 + 0.5), -2**24, 2**24)
                                        .astype(np.int64))
            sine = fixed.NO_SINE
        else:
            sp_q = dsp_q = np.zeros(0, np.int64)
        ratio = per_pa / per_rad * fixed.Q16            # Pa/rad gain -> pressure Q4 per angle Q4, Q16
        gains = [self.proportional_gain * ratio, self.derivative_gain / dt_v / 256.0 * ratio,
                 self.integral_gain * dt * ratio]
        gains = [int(round(x)) for x in gains]
        if max(gains) > fixed.INT32_MAX:
            raise ScenarioError(f"controllers.{name}.proportional_gain", "(the gains)",
                                f"with [firmware] each gain in Q16 must fit int32 (got {max(gains)}): lower "
                                "the gains or widen the transducer's pressure range")
        P = [int(row[L_SIGN]), fixed.q4(pline, fw, self.co_contraction, full), fixed.q4(pline, fw, 0.0, full),
             fixed.q4(pline, fw, fixed.top_pressure(sc), full)] + gains + [
            int(round(0.5 * self.band * per_pa)), max(1, sp_q.size),
            int(fw.velocity_filter).bit_length() - 1] + list(sine) + [every, phase, window]
        T = np.concatenate([sp_q, dsp_q])
        return fixed.firmware_row(row, sc, P, T)


def angle_schedule(sc, name: str) -> tuple:
    """(N, phase) of joint-angle controller ``name``'s angle loop: it runs every N samples
    (:meth:`JointAngleSettings.angle_every`), first at its phase-th sample (0..N - 1) and then
    every N. The scenario's joint-angle controllers with the same N are staggered: the i-th of
    them (in the scenario's order) takes phase i mod N, so that the N samples share the loops
    evenly (six joints at N = 4: two loops at samples 0 and 1 of every four, one at 2 and 3)."""
    rate = sc.controller.rate
    n = sc.controllers[name].angle_every(rate)
    same = [c for c, s in sc.controllers.items() if isinstance(s, JointAngleSettings) and s.angle_every(rate) == n]
    return n, same.index(name) % n


@jit
def law(laws, mp, c, cs, b, y, p, ts):
    """The cascade's mode for this row's muscle at ts (the angle read through its sensor)."""
    th, w = sense_joint(laws, c, cs, b, int(cs[CS_SAMPLE]), cs[CS_DT])
    return joint_angle_mode(laws, c, cs, b, y, p, ts, th, w)


@jit
def angle_loop_due(every, phase, left):
    """The angle loop's schedule, both twins. ``left`` is the samples until its next run (0 before
    the first sample). Returns (runs at this sample, the new ``left``): at the first sample the
    count starts from the phase, at the others from left - 1; the loop runs when it is 0 (or
    less) and left becomes N (every; N <= 1: every sample), else left is the count. Counted in
    samples the law ran, not in sample indices: on the board a law in fault does not run and
    its schedule waits with it."""
    n = max(1, int(every))
    s = int(phase) if left <= 0 else int(left) - 1
    if s <= 0:
        return True, n
    return False, s


@jit
def joint_angle_mode(laws, c, cs, b, y, p, ts, th, w):
    """One muscle of an antagonistic pair under the joint-angle cascade (docs/control.md).

    Outer loop, PID on the joint angle read th [rad] (velocity w [rad/s]) against the angle
    setpoint sp(t): dp = Kp e + Kd (dsp/dt - w) + Ki integral(e dt), e = sp - th. The pair's
    pressure targets are p0 + dp/2 (extensor, L_SIGN = +1: its pressure raises the angle) and
    p0 - dp/2 (flexor), each clipped to [atmosphere, source pressure]; a run at which either is
    clipped counts in cs[b + B_CLIPS] and adds nothing to the integral (anti-windup; both rows
    decide the same, as they see the same inputs). The outer loop runs every N samples
    (:func:`angle_loop_due`; its integral steps N dt); between its runs, and before its first,
    the target holds (p0 before the first). Inner loop, every sample: this muscle's sensed
    pressure p follows its target through :func:`frogsim.control.signals.bang_bang` with the
    row's band."""
    sp, dsp = setpoint(laws, c, ts)
    cs[b + B_SP] = sp
    if cs[b + B_PHASE] <= 0.0:
        cs[b + B_TARGET] = laws[c, L_P0]
    due, left = angle_loop_due(laws[c, L_A_EVERY], laws[c, L_A_PHASE], cs[b + B_PHASE])
    cs[b + B_PHASE] = left
    if due:
        e = sp - th
        dt = cs[CS_DT] * max(1.0, laws[c, L_A_EVERY])
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
        cs[b + B_TARGET] = min(max(target, lo), hi)
    return bang_bang(p, cs[b + B_TARGET], laws[c, L_BAND])


LIMIT = 2**30           # the integral and the pressure difference are clipped to +-LIMIT
VELOCITY_SHIFT = 3      # the firmware's velocity filter: 2^3 = 8 samples (8 ms at 1 kHz)
P_SINE = 10             # P[P_SINE:P_SINE + SN_SIZE]: the sine block (P[P_SINE] < 0: the table)
P_EVERY = P_SINE + SN_SIZE   # the angle loop runs every P[P_EVERY] samples (angle_loop_due) ...
P_PHASE = P_EVERY + 1        # ... first at sample P[P_PHASE]
P_WINDOW = P_PHASE + 1       # the velocity's difference spans P[P_WINDOW] samples (velocity_window)
SINE = True             # the C twin calls the sine generator (its table is linked)


@jit
def velocity_window(P):
    """W: the samples the firmware's velocity difference spans, 1..N (N the angle loop's period;
    W = N, every sample since the last run, when P[P_WINDOW] is 0 or not in 1..N)."""
    n = max(1, int(P[P_EVERY]))
    w = int(P[P_WINDOW])
    return w if 1 <= w <= n else n


@jit
def fw_law(P, T, mem, k, cp, ca):
    """The integer twin of :func:`joint_angle_mode` (memory: mem[0] the integral of the error, sum
    of Q4 errors; mem[1] the angle at the last run (Q4); mem[2] 1 once it holds one; mem[3] the
    runs with clipped targets; mem[4] the filtered velocity; mem[5] the angle loop's schedule
    (:func:`angle_loop_due` on P[P_EVERY], P[P_PHASE]; 0 before the first sample); mem[6] this
    muscle's target (Q4), held between the runs, p0 before the first; mem[7] the pair's half
    difference dp >> 1 at the last run). At a run: the setpoint sp (Q4) and its rate dsp
    (Q12 counts per run) come from the sine block (:func:`frogsim.control.signals.fw_sine`) or the
    table T[min(k, n - 1)], T[n + min(k, n - 1)]. The angle is the count ca's middle 16 ca + 8,
    e = sp - angle; the rate term is Kd (dsp - w): the board has no velocity sensor, its w is the
    backward difference of the angle since the last run (zero at the first) through a first-order
    filter of 2^P[9] runs, vf += (256 dtheta - vf) >> P[9] (Q12 counts per run; one count a
    sample is 3.8 rad/s at 1 kHz, too coarse to use raw). dp = (Kp e + Kd' (dsp - vf) + Ki'
    integral) >> 16 (int64 products here; the C twin takes 32-bit products where the ranges
    allow, with the same result); targets p0 +- dp >> 1, clipped to [atmosphere, source]; a clip
    counts and keeps the integral (anti-windup). Every sample: the muscle's relay on its count cp
    against its target."""
    if mem[5] <= 0:
        mem[6] = P[1]
    due, left = angle_loop_due(P[P_EVERY], P[P_PHASE], mem[5])
    mem[5] = left
    window = velocity_window(P)
    if not due and left == window:            # the velocity's window opens: the angle now
        mem[1] = 16 * ca + 8
        mem[2] = 1
    if due:
        if P[P_SINE] >= 0:
            sp, dsp = fw_sine(P, P_SINE, k)
        else:
            n = int(P[8])
            kk = k if k < n else n - 1
            sp = int(T[kk])
            dsp = int(T[n + kk])
        aq = 16 * ca + 8
        e = sp - aq
        dth = aq - int(mem[1]) if mem[2] > 0 else 0
        if window >= max(1, int(P[P_EVERY])):     # the window is the loop's period: it opens now
            mem[1] = aq
            mem[2] = 1
        vf = int(mem[4])
        vf = vf + ((256 * dth - vf) >> int(P[9]))
        mem[4] = vf
        integ = min(max(int(mem[0]) + e, -LIMIT), LIMIT)
        acc = int(P[4]) * e + int(P[5]) * (dsp - vf) + int(P[6]) * integ
        dp = min(max(acc >> 16, -LIMIT), LIMIT)
        half = dp >> 1
        mem[7] = half
        p0 = int(P[1])
        lo = int(P[2])
        hi = int(P[3])
        up = p0 + half
        down = p0 - half
        if up > hi or up < lo or down > hi or down < lo:
            if mem[3] < 2**31 - 1:
                mem[3] = mem[3] + 1
        else:
            mem[0] = integ
        target = up if P[0] > 0 else down
        mem[6] = min(max(target, lo), hi)
    return fw_relay(16 * cp + 8, int(mem[6]), int(P[7]))


C_NAME = "fs_joint_angle"


def c_source() -> str:
    """The C twin of :func:`fw_law`.

    dp = floor((Kp e + Kd' r + Ki' i) / 2^16) (r = dsp - vf, i the clipped integral) is what
    :func:`fw_law` computes in int64. The AVR has no 64-bit multiply (avr-gcc's __muldi3 and the
    64-bit adds, shifts and compares took about 1000 of the 1500 cycles a call took), so the C
    takes 16 x 16 -> 32 bit products where the ranges allow (the fast path, exact) and the int64
    sums otherwise (fs_joint_angle_dp64, out of line):

    * each gain G = Kp or Kd' in [-2^29, 2^29) is split G = a 2^16 + b (a = G >> 16 in
      [-2^13, 2^13), b = G & 0xFFFF in [0, 2^16)); with x = e or r in [-2^15, 2^15),
      G x = (a x) 2^16 + b x: dp collects the a x, L the b x, and the sum of floor(G x / 2^16)
      is dp + floor(L / 2^16) exactly (floor((H 2^16 + L) / 2^16) = H + floor(L / 2^16));
    * Ki' in [0, 2^16) (a = 0) meets the integral i in [-2^30, 2^30], split instead:
      i = ih 2^16 + il (ih = i >> 16 in [-2^14, 2^14], il in [0, 2^16)), Ki' i = (Ki' ih) 2^16 +
      Ki' il, and Ki' il < 2^32 (unsigned) adds its high half to dp and its low half to L;
    * L is folded after each gain's term (dp += L >> 16, L &= 0xFFFF), so it stays in int32:
      |b x| <= 65535 x 32768 = 2147450880 and 65535 + 65535 x 32767 = 2147450880, both below
      2^31; at the end L <= 2 x 65535;
    * |dp| <= 2 x 2^13 x 2^15 (the a x) + 2 x 2^15 (the folds) + 65535 x 2^14 (Ki' ih) + 2^16
      < 2^29 + 2^30 + 2^17 < 2^31 before its clip: no sum overflows
      (tests/test_firmware_laws.py checks these corners).

    e and r are taken modulo 2^32 (uint32 differences; the true ones lie within 2^31 + 2^29 of 0,
    so a wrapped one never lands in [-2^15, 2^15)) and the fast path requires them in
    [-2^15, 2^15), where the difference is the true one. A zero half of a gain skips its
    product. The products are fs_mulss, fs_mulsu and fs_muluu (:data:`frogsim.control.fixed.
    C_ARITHMETIC`: the AVR's MUL instructions; avr-gcc would call its 32-bit multiply). The
    setpoint, the velocity filter, the clip and the relay are the same code on both paths.
    Compiled with FS_CHECK_FAST defined (the tests' probe), the law returns 2 where it leaves
    the fast path."""
    return """/* dp and the clipped integral in int64, as fw_law sums them (the joint-angle law's slow path):
 * int32 operands into the int64 products where e = sp - aq and r = dsp - vf fit int32, int64
 * operands otherwise (a setpoint or rate near the ends of int32) */
FS_COLD int32_t fs_joint_angle_dp64(int32_t sp, int32_t aq, int32_t dsp, int32_t vf, const int32_t *P,
                                    int32_t *integ) {
    int32_t e = (int32_t)((uint32_t)sp - (uint32_t)aq), r = (int32_t)((uint32_t)dsp - (uint32_t)vf), i;
    int64_t acc;
    if (((sp ^ aq) & (sp ^ e)) < 0 || ((dsp ^ vf) & (dsp ^ r)) < 0) {
        int64_t e64 = (int64_t)sp - aq, i64 = (int64_t)*integ + e64;
        if (i64 > 1073741824L) i64 = 1073741824L;
        if (i64 < -1073741824L) i64 = -1073741824L;
        *integ = (int32_t)i64;
        acc = (int64_t)P[4] * e64 + (int64_t)P[5] * ((int64_t)dsp - vf) + (int64_t)P[6] * i64;
    } else {
        if (e > -1073741824L && e < 1073741824L) {
            i = *integ + e;         /* |integ| <= 2^30: no overflow */
            if (i > 1073741824L) i = 1073741824L;
            if (i < -1073741824L) i = -1073741824L;
        } else if (e > 0) {
            i = *integ + (e - 1073741824L);         /* integ + e - 2^30, in [-2^30, 2^31) */
            i = i >= 0 ? 1073741824L : i + 1073741824L;
        } else {
            i = *integ + (e + 1073741824L);         /* integ + e + 2^30, in [-2^31, 2^30] */
            i = i <= 0 ? -1073741824L : i - 1073741824L;
        }
        *integ = i;
        acc = (int64_t)P[4] * e + (int64_t)P[5] * r + (int64_t)P[6] * i;
    }
    acc >>= 16;
    if (acc > 1073741824L) acc = 1073741824L;
    if (acc < -1073741824L) acc = -1073741824L;
    return (int32_t)acc;
}

/* W: the samples the velocity difference spans (velocity_window): P[19] within 1..N, else N */
FS_INLINE int32_t fs_ja_window(const int32_t *P) {
    int32_t n = P[17] > 1 ? P[17] : 1, w = P[19];
    return (w >= 1 && w <= n) ? w : n;
}

/* the angle loop's schedule (angle_loop_due) at this sample: 1 when the loop runs; else 0, the
 * schedule counted down and, W samples before the next run, the angle kept for the velocity */
FS_INLINE uint8_t fs_ja_due(uint16_t ca, int32_t *mem, const int32_t *P) {
    int32_t s;
    if (mem[5] <= 0) {
        mem[6] = P[1];
        s = P[18];
    } else {
        s = mem[5] - 1;
    }
    if (s <= 0) return 1;
    mem[5] = s;
    if (s == fs_ja_window(P)) {
        mem[1] = (int32_t)fs_muluu(ca, 16) + 8;
        mem[2] = 1;
    }
    return 0;
}

/* a run of the angle loop: the PID, the pair's targets, this muscle's relay (fs_joint_angle calls
 * it at the samples the loop's schedule gives; out of line, so that the samples between stay short) */
FS_COLD int8_t fs_joint_angle_run(uint32_t k, uint16_t cp, uint16_t ca, int32_t *mem, const int32_t *P,
                                  const int32_t *T) {
    int32_t aq, sp, dsp, vf, e, r, integ, dp, up, down, lo, hi;
    mem[5] = P[17] > 1 ? P[17] : 1;
    aq = (int32_t)fs_muluu(ca, 16) + 8;
    integ = mem[0];
    if (P[10] >= 0) {
        sp = fs_sine(k, &P[10], &dsp);
    } else {
        int32_t n = P[8];
        uint32_t kk = k < (uint32_t)n ? k : (uint32_t)(n - 1);
        sp = (int32_t)FS_READ32(&T[kk]);
        dsp = (int32_t)FS_READ32(&T[n + kk]);
    }
    vf = mem[4];
    vf += (((mem[2] > 0 ? aq - mem[1] : 0) * 256) - vf) >> P[9];
    if (fs_ja_window(P) >= (P[17] > 1 ? P[17] : 1)) {     /* the window is the loop's period: it opens now */
        mem[1] = aq;
        mem[2] = 1;
    }
    mem[4] = vf;
    e = (int32_t)((uint32_t)sp - (uint32_t)aq);
    r = (int32_t)((uint32_t)dsp - (uint32_t)vf);
    if ((uint32_t)((uint32_t)e + 0x8000UL) < 0x10000UL && (uint32_t)((uint32_t)r + 0x8000UL) < 0x10000UL
        && (uint16_t)((uint16_t)(P[4] >> 16) + 0x2000U) < 0x4000U
        && (uint16_t)((uint16_t)(P[5] >> 16) + 0x2000U) < 0x4000U && (uint16_t)(P[6] >> 16) == 0) {
        /* the fast path: 16 x 16 -> 32 bit products, exact (see joint_angle.c_source) */
        int16_t e16 = (int16_t)e, r16 = (int16_t)r, a;
        uint16_t b;
        int32_t L = 0;
        uint32_t u;
        integ += e16;
        if (integ > 1073741824L) integ = 1073741824L;
        if (integ < -1073741824L) integ = -1073741824L;
        dp = 0;
        a = (int16_t)(P[4] >> 16);
        b = (uint16_t)P[4];
        if (a) dp = fs_mulss(a, e16);
        if (b) {
            L = fs_mulsu(e16, b);
            dp += L >> 16;
            L &= 0xFFFF;
        }
        a = (int16_t)(P[5] >> 16);
        b = (uint16_t)P[5];
        if (a) dp += fs_mulss(a, r16);
        if (b) {
            L += fs_mulsu(r16, b);
            dp += L >> 16;
            L &= 0xFFFF;
        }
        b = (uint16_t)P[6];
        if (b) {
            dp += fs_mulsu((int16_t)(integ >> 16), b);
            u = fs_muluu(b, (uint16_t)integ);
            dp += (int32_t)(u >> 16);
            L += (int32_t)(u & 0xFFFF);
        }
        dp += L >> 16;
        if (dp > 1073741824L) dp = 1073741824L;
        if (dp < -1073741824L) dp = -1073741824L;
    } else {
#ifdef FS_CHECK_FAST
        return 2;       /* the tests' probe of the path taken (tests/test_firmware_laws.py) */
#endif
        dp = fs_joint_angle_dp64(sp, aq, dsp, vf, P, &integ);
    }
    dp >>= 1;
    mem[7] = dp;
    up = P[1] + dp;
    down = P[1] - dp;
    lo = P[2];
    hi = P[3];
    if (up > hi || up < lo || down > hi || down < lo) {
        if (mem[3] < INT32_MAX) mem[3]++;
    } else {
        mem[0] = integ;
    }
    if (P[0] <= 0) up = down;
    if (up < lo) up = lo;
    if (up > hi) up = hi;
    mem[6] = up;
    return fs_relay((int32_t)fs_muluu(cp, 16) + 8, up, P[7]);
}

int8_t fs_joint_angle(uint32_t k, uint16_t cp, uint16_t ca, int32_t *mem, const int32_t *P,
                      const int32_t *T) {
    if (!fs_ja_due(ca, mem, P))                 /* between the loop's runs its target holds */
        return fs_relay((int32_t)fs_muluu(cp, 16) + 8, mem[6], P[7]);
    return fs_joint_angle_run(k, cp, ca, mem, P, T);
}

/* The other muscle of a joint whose loop law `lead` (the same parameters but the sign, the same
 * table) has just run on a memory that was this one's: the loop's run would compute what the
 * leader's did, so its memory is copied and this muscle's target taken from the pair's half
 * difference (frogsim_sample calls it only while the two memories agree, before the leader's
 * call; the result is fs_joint_angle's, exactly) */
int8_t fs_joint_angle_follow(uint16_t cp, uint16_t ca, const int32_t *lead, int32_t *mem, const int32_t *P) {
    int32_t t;
    uint8_t i;
    if (!fs_ja_due(ca, mem, P))
        return fs_relay((int32_t)fs_muluu(cp, 16) + 8, mem[6], P[7]);
    for (i = 0; i < 6; i++) mem[i] = lead[i];
    mem[7] = lead[7];
    t = P[0] > 0 ? P[1] + mem[7] : P[1] - mem[7];
    if (t < P[2]) t = P[2];
    if (t > P[3]) t = P[3];
    mem[6] = t;
    return fs_relay((int32_t)fs_muluu(cp, 16) + 8, t, P[7]);
}

/* whether law b (memory b, parameters P) runs its angle loop at this sample and the memory a of
 * the other law of its joint agrees with b's in everything but the muscle's own target (mem[6]):
 * then b may follow a's run (fs_joint_angle_follow); at the other samples b holds, cheaply */
uint8_t fs_joint_angle_pair(const int32_t *a, const int32_t *b, const int32_t *P) {
    if ((b[5] <= 0 ? P[18] : b[5] - 1) > 0) return 0;
    return a[0] == b[0] && a[1] == b[1] && a[2] == b[2] && a[3] == b[3] && a[4] == b[4] && a[5] == b[5]
        && a[7] == b[7];
}
"""


@jit
def fw_report(cs, b, mem):
    """After a firmware sample: the twin's count of runs with a clipped target (its memory's
    word 3) into the row's B_CLIPS, where the results read it as in a float run."""
    cs[b + B_CLIPS] = mem[3]


KIND = ControllerKind(
    settings=JointAngleSettings, code=CODE, law=law,
    firmware=FirmwareTwin(fw_law=fw_law, c_name=C_NAME, c_source=c_source, sine=SINE, report=fw_report),
    tracks="angle", metrics=ANGLE_TRACKING + ("samples_pressure_target_clipped",),
    gains=(
        # the shipped robot scenarios use Kp 30 bar/rad, Kd 1 bar*s/rad, Ki 0 or 30 bar/(rad*s)
        Gain("proportional_gain", "bar/rad", 1.0, 100.0, log=True),
        # up to 8: in water the hip's best Kd lay at the old top, 3 bar*s/rad (a tune of the
        # swimming robot, benchmarks/bench_tune_joint.py): the water's drag asks for a pressure
        # difference in step with the joint's rate, which Kd (dsp/dt - w) gives. The top stays under
        # the rules' bound (a Kd that spans the source's 6 bar for a change of 0.1 % of the joint's
        # range per period is a relay): 6 bar over the hip's 41 deg, 8.4 bar*s/rad with fan2017
        Gain("derivative_gain", "bar*s/rad", 0.0, 8.0),
        Gain("integral_gain", "bar/(rad*s)", 0.0, 100.0),
        # the pair's common pressure (stiffness), below fan2017's 6 bar source with room for dp/2
        Gain("co_contraction", "bar", 0.5, 4.0),
        # the inner relays' band, as the bang-bang kind's: from about one count of a 10-bit ADC on a
        # 10 bar transducer (0.01 bar) to 1 bar (in water the knee's best band lay at the old top,
        # 0.5 bar, the hip's and ankle's near the old bottom, 0.02 bar)
        Gain("band", "bar", 0.01, 1.0, log=True),
    ))
