"""Kind "pid": a PID law on the muscle's pressure commanding a proportional valve's spool
(continuous command, the valve type "proportional" of :mod:`frogsim.circuit.valves`).

The command is a voltage about the valve's mid position, as the MPYE's 0-10 V input takes it:

    e = sp - p                                               [Pa]
    V - V_mid = K_p e + K_i int e dt + K_d de/dt             [V]
    x = (V - V_mid) / V_span, clipped to -1..1               (the spool's commanded position)

with de/dt = dsp/dt - (p_k - p_{k-1}) / T (the setpoint's own rate and the measured pressure's
difference over one period T: no derivative kick at a setpoint step), and the integral held while
the command is clipped and the error drives it further out (conditional integration: no wind-up).
The valve's spool then follows x with its lag (the controllers' view of the valve,
:func:`frogsim.circuit.valves.proportional.openings`). No firmware twin: the robot's board has no
DAC for the valve's 0-10 V input, and ``frogsim firmware`` refuses the kind by name.
"""
from __future__ import annotations

from dataclasses import dataclass

from frogsim._jit import jit
from frogsim.circuit.valves import of as valve_type
from frogsim.control.kinds.common import PressureTracking
from frogsim.control.kinds.spec import PRESSURE_TRACKING, ControllerKind, Gain
from frogsim.control.signals import B_ERR, B_INT, B_SP, CS_DT, setpoint
from frogsim.control.table import L_KD, L_KI, L_KP, valve_row, with_setpoint
from frogsim.errors import ScenarioError
from frogsim.scenario.fields import quantity

CODE = 10.0     # the table's kind column
BAR = 1e5


@dataclass(frozen=True)
class PidSettings(PressureTracking):
    """PID on the pressure error, its output the proportional valve's command voltage about mid."""
    KIND = "pid"
    proportional_gain: float = quantity("voltage_per_pressure", ge=0.0, le=1e-2, display="V/bar",
                                        default=6.0 / BAR, doc="K_p: volts of command per bar of error")
    integral_gain: float = quantity("voltage_per_pressure_time", ge=0.0, le=1.0, display="V/(bar*s)",
                                    default=100.0 / BAR, doc="K_i: volts per bar of error and second")
    derivative_gain: float = quantity("voltage_time_per_pressure", ge=0.0, le=1e-3, display="V*s/bar",
                                      default=0.005 / BAR, doc="K_d: volts per bar/s of error rate")

    def check(self, sc, path: str, p_top: float) -> None:
        super().check(sc, path, p_top)
        if not valve_type(sc.valves).continuous:
            raise ScenarioError(f"{path}.kind", self.KIND,
                                f"commands a proportional valve's spool, but valves.type is {sc.valves.type!r} "
                                "(open or shut): write [valves] type = \"proportional\", or use a kind for "
                                "switching valves (bang-bang, pwm, sliding-mode)")

    def write_rows(self, name: str, ctx) -> list:
        row = valve_row(ctx, CODE, self.muscle, self.sensor)
        span = ctx.sc.valves.signal_span            # [V] from mid to either end of the spool's travel
        row[L_KP] = self.proportional_gain / span   # spool travel per Pa
        row[L_KI] = self.integral_gain / span       # per Pa s
        row[L_KD] = self.derivative_gain / span     # per Pa/s
        return [with_setpoint(row, self.setpoint, ctx.patm)]


@jit
def law(laws, mp, c, cs, b, y, p, ts):
    """The spool command in -1..1 at sample time ts (module docstring); memory: the error's
    integral at B_INT [Pa s], the last measured pressure at B_ERR [Pa abs] (0 before the first
    sample: no derivative then)."""
    sp, dsp = setpoint(laws, c, ts)
    cs[b + B_SP] = sp
    dt = cs[CS_DT]
    e = sp - p
    last = cs[b + B_ERR]
    de = dsp - (p - last) / dt if last > 0.0 else 0.0
    cs[b + B_ERR] = p
    integral = cs[b + B_INT] + e * dt
    x = laws[c, L_KP] * e + laws[c, L_KI] * integral + laws[c, L_KD] * de
    if x > 1.0:
        x = 1.0
        if e > 0.0:                 # clipped and driven further out: hold the integral
            integral = cs[b + B_INT]
    elif x < -1.0:
        x = -1.0
        if e < 0.0:
            integral = cs[b + B_INT]
    cs[b + B_INT] = integral
    return x


KIND = ControllerKind(
    settings=PidSettings, code=CODE, law=law, firmware=None, tracks="pressure", metrics=PRESSURE_TRACKING,
    gains=(
        # about a tenth to ten times the defaults (6 V/bar, 100 V/(bar s), 0.005 V s/bar: tuned on the hip
        # at constant volume with the MPYE-class valve, docs/control.md)
        Gain("proportional_gain", "V/bar", 0.5, 60.0, log=True),
        Gain("integral_gain", "V/(bar*s)", 10.0, 1000.0, log=True),
        Gain("derivative_gain", "V*s/bar", 5e-4, 0.05, log=True),
    ))
