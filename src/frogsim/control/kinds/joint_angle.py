"""Kind "joint-angle": a cascade on an antagonistic pair (robot scenarios): PID on the joint angle
giving the pair's pressure targets, each muscle's pressure following its target by a relay."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from frogsim._jit import jit
from frogsim.circuit.layout import Y_PS
from frogsim.control import fixed
from frogsim.control.kinds.common import SensedLoop
from frogsim.control.signals import (B_CLIPS, B_INT, B_SP, B_TARGET, CS_DT, CS_SAMPLE, bang_bang, fw_relay,
                                     fw_sine, sense_joint, setpoint)
from frogsim.control.table import (L_A_BITS, L_A_FS, L_A_LAG, L_A_NOISE, L_A_SEED, L_BAND, L_GAIN, L_JOINT1,
                                   L_KD, L_KI, L_KP, L_MUSCLE, L_P0, L_PATM, L_SIGN, L_STREAM, valve_row,
                                   with_setpoint)
from frogsim.errors import MISSING, ScenarioError
from frogsim.scenario.fields import quantity
from frogsim.scenario.kinds import register
from frogsim.scenario.rules import check_below_source
from frogsim.scenario.schema import BAR, GAUGE_MAX, AngleSensor, AngleSetpoint

CODE = 6.0      # the table's kind column (one row per muscle of the pair)


@register
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
    angle_sensor: AngleSensor = field(default_factory=AngleSensor)

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

    def write_rows(self, name: str, ctx) -> list:
        """Two rows, the extensor's then the flexor's: each drives one muscle's valves from the same
        angle law."""
        row = valve_row(ctx, CODE, self.muscle, self.sensor)
        row[L_BAND] = self.band
        row[L_JOINT1] = 1 + list(ctx.sc.joints).index(self.joint)
        row[L_P0] = ctx.patm + self.co_contraction
        row[L_KP], row[L_KD], row[L_KI] = self.proportional_gain, self.derivative_gain, self.integral_gain
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
        (pressure Q4 per angle Q4, Q16), Kd / dt (per Q12 angle counts per sample, Q16),
        Ki dt (Q16), half band, setpoint table length n, the velocity filter's shift
        (log2 of [firmware] velocity_filter, VELOCITY_SHIFT by default), then the sine block (P_SINE.., :func:`frogsim.control.fixed.sine_block`)].
        A sine setpoint is generated by the sine block (T holds nothing); any other (or a sine
        the generator cannot hold) is tabulated, the sine block's first slot -1: T = the angle
        setpoint at each sample (Q4), then its rate at each sample (Q12 counts per sample)."""
        sc = ctx.sc
        fw = sc.firmware
        full = fixed.adc_full(sc)
        pline = fixed.pressure_volts(fw)
        aline, afull = fixed.angle_line(sc)
        per_pa = fixed.q4_per_unit(pline, fw, full)
        per_rad = fixed.q4_per_unit(aline, fw, afull)
        dt = 1.0 / sc.controller.rate
        sine = fixed.sine_block(row, sc, aline, afull, 0.0, dt * 256.0)
        if sine is None:
            sp, dsp = fixed.setpoint_series(row, sc, 0.0)
            sp_q, dsp_q = fixed.trimmed(fixed.q4(aline, fw, sp, afull),
                                        np.clip(np.floor(dsp * dt * per_rad * 256.0 + 0.5), -2**24, 2**24)
                                        .astype(np.int64))
            sine = fixed.NO_SINE
        else:
            sp_q = dsp_q = np.zeros(0, np.int64)
        ratio = per_pa / per_rad * fixed.Q16            # Pa/rad gain -> pressure Q4 per angle Q4, Q16
        gains = [self.proportional_gain * ratio, self.derivative_gain / dt / 256.0 * ratio,
                 self.integral_gain * dt * ratio]
        gains = [int(round(x)) for x in gains]
        if max(gains) > fixed.INT32_MAX:
            raise ScenarioError(f"controllers.{name}.proportional_gain", "(the gains)",
                                f"with [firmware] each gain in Q16 must fit int32 (got {max(gains)}): lower "
                                "the gains or widen the transducer's pressure range")
        P = [int(row[L_SIGN]), fixed.q4(pline, fw, self.co_contraction, full), fixed.q4(pline, fw, 0.0, full),
             fixed.q4(pline, fw, fixed.top_pressure(sc), full)] + gains + [
            int(round(0.5 * self.band * per_pa)), max(1, sp_q.size),
            int(fw.velocity_filter).bit_length() - 1] + list(sine)
        T = np.concatenate([sp_q, dsp_q])
        return fixed.firmware_row(row, sc, P, T)


@jit
def law(laws, c, cs, b, y, p, ts):
    """The cascade's mode for this row's muscle at ts (the angle read through its sensor)."""
    th, w = sense_joint(laws, c, cs, b, int(cs[CS_SAMPLE]), cs[CS_DT])
    return joint_angle_mode(laws, c, cs, b, y, p, ts, th, w)


@jit
def joint_angle_mode(laws, c, cs, b, y, p, ts, th, w):
    """One muscle of an antagonistic pair under the joint-angle cascade (docs/control.md).

    Outer loop, PID on the joint angle read th [rad] (velocity w [rad/s]) against the angle
    setpoint sp(t): dp = Kp e + Kd (dsp/dt - w) + Ki integral(e dt), e = sp - th. The pair's
    pressure targets are p0 + dp/2 (extensor, L_SIGN = +1: its pressure raises the angle) and
    p0 - dp/2 (flexor), each clipped to [atmosphere, source pressure]; a sample at which either is
    clipped counts in cs[b + B_CLIPS] and adds nothing to the integral (anti-windup; both rows
    decide the same, as they see the same inputs). Inner loop: this muscle's sensed pressure p
    follows its target through :func:`frogsim.control.signals.bang_bang` with the row's band."""
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


LIMIT = 2**30           # the integral and the pressure difference are clipped to +-LIMIT
VELOCITY_SHIFT = 3      # the firmware's velocity filter: 2^3 = 8 samples (8 ms at 1 kHz)
P_SINE = 10             # P[P_SINE:P_SINE + SN_SIZE]: the sine block (P[P_SINE] < 0: the table)
SINE = True             # the C twin calls the sine generator (its table is linked)


@jit
def fw_law(P, T, mem, k, cp, ca):
    """The integer twin of :func:`joint_angle_mode` (memory: mem[0] the integral of the error, sum
    of Q4 errors; mem[1] the last angle (Q4); mem[2] 1 once it holds one; mem[3] the samples
    with clipped targets; mem[4] the filtered velocity). The setpoint sp (Q4) and its rate dsp
    (Q12 counts per sample) come from the sine block (:func:`frogsim.control.signals.fw_sine`)
    or the table T[min(k, n - 1)], T[n + min(k, n - 1)]. The angle is the count ca's middle
    16 ca + 8, e = sp - angle; the rate term is Kd (dsp - w): the board has no velocity sensor,
    its w is the backward difference of the angle (zero at the first sample) through a
    first-order filter of 2^P[9] samples, vf += (256 dtheta - vf) >> P[9] (Q12 counts per
    sample; one count a sample is 3.8 rad/s at 1 kHz, too coarse to use raw).
    dp = (Kp e + Kd' (dsp - vf) + Ki' integral) >> 16 (int64 products here; the C twin takes
    32-bit products where the ranges allow, with the same result); targets p0 +- dp >> 1,
    clipped to [atmosphere, source]; a clip counts and keeps the integral (anti-windup); the
    muscle's relay on its count cp against its target."""
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
    mem[1] = aq
    mem[2] = 1
    vf = int(mem[4])
    vf = vf + ((256 * dth - vf) >> int(P[9]))
    mem[4] = vf
    integ = min(max(int(mem[0]) + e, -LIMIT), LIMIT)
    acc = int(P[4]) * e + int(P[5]) * (dsp - vf) + int(P[6]) * integ
    dp = min(max(acc >> 16, -LIMIT), LIMIT)
    half = dp >> 1
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
    target = min(max(target, lo), hi)
    return fw_relay(16 * cp + 8, target, int(P[7]))


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

int8_t fs_joint_angle(uint32_t k, uint16_t cp, uint16_t ca, int32_t *mem, const int32_t *P,
                      const int32_t *T) {
    int32_t aq = (int32_t)fs_muluu(ca, 16) + 8;
    int32_t sp, dsp, vf, e, r, integ = mem[0], dp, up, down, lo, hi;
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
    mem[1] = aq;
    mem[2] = 1;
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
    return fs_relay((int32_t)fs_muluu(cp, 16) + 8, up, P[7]);
}
"""
