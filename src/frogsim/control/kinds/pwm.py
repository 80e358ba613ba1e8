"""Kind "pwm": pulses on the controller grid, open loop (a duty, or a duty schedule) or closed
loop (the duty from the pressure error)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from frogsim._jit import jit
from frogsim.control import fixed
from frogsim.control.kinds.common import SensedLoop
from frogsim.control.kinds.spec import PRESSURE_TRACKING, ControllerKind, FirmwareTwin, Gain
from frogsim.control.signals import (B_PHASE, B_PULSE, B_SP, MODE_CHARGE, MODE_HOLD, MODE_VENT, fw_at, fw_sine,
                                     setpoint)
from frogsim.control.table import (DUTY_CLOSED, DUTY_SCHEDULED, L_DUTY, L_MINPULSE_N, L_PBAND, L_PERIOD_N,
                                   L_REST, valve_row, with_setpoint)
from frogsim.errors import MISSING, ScenarioError
from frogsim.scenario.fields import choice, quantity, unwrap
from frogsim.scenario.rules import check_pressure_setpoint, err
from frogsim.scenario.schema import BAR, GAUGE_MAX, DutySchedule, Setpoint

CODE = 3.0      # the table's kind column


@dataclass(frozen=True)
class PwmSettings(SensedLoop):
    """Pulses of round(duty N) samples at the start of each period of N = rate / frequency samples."""
    KIND = "pwm"
    setpoint: Setpoint | None = None
    frequency: float = quantity("frequency", gt=0.0, le=1e4, display="Hz", default=20.0, doc="carrier")
    duty: float | None = quantity("dimensionless", ge=0.0, le=1.0, display="%", default=None,
                                  doc="open-loop duty (no setpoint)")
    duty_schedule: DutySchedule | None = None     # open-loop duty as a function of time
    proportional_band: float = quantity("pressure", gt=0.0, le=GAUGE_MAX, display="bar", default=1.0 * BAR,
                                        doc="with a setpoint: the error giving 100 % duty")
    minimum_pulse: float = quantity("time", ge=0.0, le=1.0, display="ms", default=0.0,
                                    doc="shorter pulses are dropped, shorter gaps filled; below the period")
    rest: str = choice(("vent", "hold"), default="vent", doc="open loop: valve state between pulses")

    def sensed(self) -> tuple:
        """An open-loop PWM (a duty or a duty schedule) reads nothing; a closed-loop one its pressure."""
        return (("pressure", self.muscle),) if self.setpoint is not None else ()

    @classmethod
    def parse_value(cls, key: str, raw, hint, meta, path: str):
        if key == "duty" and isinstance(unwrap(raw), dict):
            raise ScenarioError(path, "(a table)", "a constant duty (0..1 or a percentage); for a duty that "
                                                   "changes with time write duty_schedule = { kind = ... }")
        return super().parse_value(key, raw, hint, meta, path)

    def check(self, sc, path: str, p_top: float) -> None:
        given = [k for k in ("duty", "duty_schedule", "setpoint") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ScenarioError(f"{path}.duty", MISSING if not given else f"{' and '.join(given)} given",
                                "a pwm controller takes one of: a duty or a duty_schedule (open loop), or "
                                "a setpoint")
        if self.duty_schedule is not None:
            _check_duty_schedule(self.duty_schedule, f"{path}.duty_schedule")
        dead = max(sc.valves.charge.dead_time, sc.valves.discharge.dead_time)
        dt = 1.0 / sc.controller.rate
        period = 1.0 / self.frequency
        if period < 2.0 * dead:
            raise err(f"{path}.frequency", self, "frequency",
                      f"the period {period * 1e3:g} ms must be at least twice the valve dead time "
                      f"({dead * 1e3:g} ms): at most {1.0 / (2.0 * dead):g} Hz")
        if period < 2.0 * dt - 1e-12:
            raise err(f"{path}.frequency", self, "frequency",
                      f"the period must span at least two controller samples (at most "
                      f"{sc.controller.rate / 2:g} Hz at controller.rate = {sc.controller.rate:g} Hz)")
        if self.minimum_pulse >= period:
            raise err(f"{path}.minimum_pulse", self, "minimum_pulse",
                      f"must be shorter than the period ({period * 1e3:g} ms at {self.frequency:g} Hz): "
                      "every pulse would be dropped or fill its period")
        if self.setpoint is not None:
            check_pressure_setpoint(sc, self.setpoint, f"{path}.setpoint", p_top)

    def write_rows(self, name: str, ctx) -> list:
        row = valve_row(ctx, CODE, self.muscle, self.sensor)
        dt = 1.0 / ctx.sc.controller.rate
        row[L_PERIOD_N] = max(1, round(1.0 / (self.frequency * dt)))
        row[L_DUTY] = (self.duty if self.duty is not None else
                       DUTY_SCHEDULED if self.duty_schedule is not None else DUTY_CLOSED)
        row[L_PBAND] = self.proportional_band
        row[L_MINPULSE_N] = math.ceil(self.minimum_pulse / dt - 1e-9)
        row[L_REST] = 1.0 if self.rest == "vent" else 0.0
        if self.duty_schedule is not None:
            # open loop: the setpoint columns carry the duty schedule (fractions, no offset)
            row = with_setpoint(row, self.duty_schedule, 0.0)
        elif self.setpoint is not None:
            row = with_setpoint(row, self.setpoint, ctx.patm)
        if ctx.sc.firmware is not None:
            row = self.firmware_row(row, name, ctx)
        return [row]

    def firmware_row(self, row, name: str, ctx):
        """The integer twin's block: P = [N, how (0 closed loop, 1 a duty, 2 a duty schedule),
        the constant duty's pulse round(duty N), the proportional band (Q4 counts), the minimum
        pulse (samples), 1 to vent between open-loop pulses, the table's length, the sine block
        (:func:`frogsim.control.fixed.sine_block`: a closed loop's sine setpoint is generated)];
        T = the setpoint at each sample (Q4 counts, closed loop, unless generated) or the
        schedule's pulse round(duty N) at each sample (open loop)."""
        sc = ctx.sc
        fw = sc.firmware
        full = fixed.adc_full(sc)
        line = fixed.pressure_volts(fw)
        N = int(row[L_PERIOD_N])
        how, n_const, T, sine = 0, 0, [0], fixed.NO_SINE
        pband = max(1, int(round(self.proportional_band * fixed.q4_per_unit(line, fw, full))))
        if self.duty is not None:
            how, n_const = 1, int(math.floor(self.duty * N + 0.5))
        elif self.duty_schedule is not None:
            how = 2
            duty, _ = fixed.setpoint_series(row, sc, 0.0)
            T, = fixed.trimmed(np.floor(duty * N + 0.5).astype(np.int64))
        else:
            sine = fixed.sine_block(row, sc, line, full, ctx.patm, 0.0)
            if sine is None:
                sp, _ = fixed.setpoint_series(row, sc, ctx.patm)
                T, = fixed.trimmed(fixed.q4(line, fw, sp, full))
                sine = fixed.NO_SINE
            if (2 * N + 1) * pband > fixed.INT32_MAX:
                raise ScenarioError(f"controllers.{name}.frequency", f"{self.frequency:g} Hz",
                                    f"with [firmware] a closed-loop pwm's period of {N} samples times its "
                                    f"proportional band ({pband} sixteenths of a count) must stay below 2^30 "
                                    "(int32 on the board): raise the frequency or narrow the band")
        P = [N, how, n_const, pband, int(row[L_MINPULSE_N]), 1 if self.rest == "vent" else 0, len(T)] + list(sine)
        return fixed.firmware_row(row, sc, P, T)


def _check_duty_schedule(ds, path: str) -> None:
    """A duty schedule's settings are there and every duty it takes lies in 0..1."""
    ds.check_complete(path, "kind")
    lo, hi = ds.bounds()
    if lo < 0.0 or hi > 1.0:
        shown = f"{lo:g}..{hi:g} (lowest..highest duty)"
        raise ScenarioError(path, shown, "a duty lies in 0..1 (0 %..100 %): for a sine mean - amplitude >= 0 "
                                         "and mean + amplitude <= 1")


@jit
def law(laws, mp, c, cs, b, y, p, ts):
    """The PWM's mode at ts (the setpoint or the duty schedule read at ts)."""
    sp, _ = setpoint(laws, c, ts)
    cs[b + B_SP] = sp
    return pwm_mode(laws, c, cs, b, p, sp)


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


P_SINE = 7      # P[P_SINE:P_SINE + SN_SIZE]: the sine block of a closed loop's setpoint (< 0: the table)
SINE = True     # the C twin calls the sine generator (its table is linked)


@jit
def fw_law(P, T, mem, k, cp, ca):
    """The integer twin of :func:`pwm_mode`: mem[0] the sample's place in the period, mem[1] this
    period's pulse in samples (sign: charge +, vent -). At a period's first sample the pulse is
    the constant's, the schedule's table entry, or round(min(|e| / band, 1) N) =
    (2 |e| N + band) / (2 band) (whole-number division of non-negative numbers: the same in C)
    with e = setpoint - (16 cp + 8) in Q4 counts (the setpoint from the sine block or the table);
    pulses shorter than the minimum are dropped, gaps shorter than it filled."""
    N = int(P[0])
    how = int(P[1])
    phase = int(mem[0])
    if phase == 0:
        sign = 1
        if how == 1:
            n_on = int(P[2])
        elif how == 2:
            n_on = fw_at(T, k, int(P[6]))
        else:
            if P[P_SINE] >= 0:
                sp, _ = fw_sine(P, P_SINE, k)
            else:
                sp = fw_at(T, k, int(P[6]))
            e = sp - (16 * cp + 8)
            if e < 0:
                sign = -1
                e = -e
            pb = int(P[3])
            n_on = N if e >= pb else (2 * e * N + pb) // (2 * pb)
        nmin = int(P[4])
        if 0 < n_on < nmin:
            n_on = 0
        elif n_on < N and N - n_on < nmin:
            n_on = N
        mem[1] = sign * n_on
    mem[0] = (phase + 1) % N
    pulse = int(mem[1])
    if phase < abs(pulse):
        return 1 if pulse > 0 else -1
    if how != 0 and int(P[5]) > 0:
        return -1
    return 0


C_NAME = "fs_pwm"


def c_source() -> str:
    """The C twin of :func:`fw_law`."""
    return """int8_t fs_pwm(uint32_t k, uint16_t cp, uint16_t ca, int32_t *mem, const int32_t *P, const int32_t *T) {
    int32_t N = P[0], how = P[1], phase = mem[0], pulse;
    (void)ca;
    if (phase == 0) {
        int32_t sign = 1, n_on, nmin = P[4];
        if (how == 1) {
            n_on = P[2];
        } else if (how == 2) {
            n_on = fs_at(T, k, P[6]);
        } else {
            int32_t e = (P[7] >= 0 ? fs_sine(k, &P[7], 0) : fs_at(T, k, P[6])) - ((int32_t)cp * 16 + 8);
            int32_t pb = P[3];
            if (e < 0) { sign = -1; e = -e; }
            n_on = e >= pb ? N : (2 * e * N + pb) / (2 * pb);
        }
        if (n_on > 0 && n_on < nmin) n_on = 0;
        else if (n_on < N && N - n_on < nmin) n_on = N;
        mem[1] = sign * n_on;
    }
    mem[0] = (phase + 1) % N;
    pulse = mem[1];
    if (phase < (pulse < 0 ? -pulse : pulse)) return pulse > 0 ? 1 : -1;
    if (how != 0 && P[5] > 0) return -1;
    return 0;
}
"""


KIND = ControllerKind(
    settings=PwmSettings, code=CODE, law=law,
    firmware=FirmwareTwin(fw_law=fw_law, c_name=C_NAME, c_source=c_source, sine=SINE),
    tracks="pressure", metrics=PRESSURE_TRACKING,     # with a setpoint (closed loop); open loop: none
    gains=(
        # the carrier: 10 to 200 samples a period at 1 kHz, under fan2017's limit of 250 Hz (twice
        # the 2 ms valve dead time)
        Gain("frequency", "Hz", 5.0, 100.0, log=True),
        # closed loop: the pressure error that gives a full period's pulse
        Gain("proportional_band", "bar", 0.1, 5.0, log=True),
        # shorter than the shortest period of the range (10 ms at 100 Hz)
        Gain("minimum_pulse", "ms", 0.0, 5.0),
    ))
