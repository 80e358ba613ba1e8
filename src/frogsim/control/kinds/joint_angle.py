"""Kind "joint-angle": a cascade on an antagonistic pair (robot scenarios): PID on the joint angle
giving the pair's pressure targets, each muscle's pressure following its target by a relay."""
from __future__ import annotations

from dataclasses import dataclass, field

from frogsim._jit import jit
from frogsim.circuit.layout import Y_PS
from frogsim.control.kinds.common import SensedLoop
from frogsim.control.signals import (B_CLIPS, B_INT, B_SP, B_TARGET, CS_DT, CS_SAMPLE, bang_bang, sense_joint,
                                     setpoint)
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
        return [with_setpoint(row, self.setpoint, 0.0), with_setpoint(flex, self.setpoint, 0.0)]


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
