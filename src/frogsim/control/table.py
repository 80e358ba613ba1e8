"""The table of sampled laws ``laws[c, :]`` a run's controllers are compiled from: its columns and
its assembly, written and read in this layer only.

One row per sampled law: the pump's pressure band (first, when the pump is enabled) and the rows
of the scenario's closed-loop controllers (``[controllers.NAME]``), each written by its kind's
module (:mod:`frogsim.control.kinds`, ``write_rows``) and read by that module's compiled law and
the driver (:mod:`frogsim.control.sampled`). This module fixes the columns (compile-time
constants for Numba) and assembles the table; :func:`build_table` is registered with
:mod:`frogsim.scenario.kinds`, through which :func:`frogsim.circuit.model.build_model` calls it
(the circuit layer does not import this one). A row is L_SIZE columns plus the setpoint's knots
(t_j [s], p_j [Pa abs]) in pairs from column L_SP0 on; the table is as wide as its widest row.
The table holds no valve constant: a law that models the valves (the sliding-mode kind's) reads
their constants from the model's muscle rows ``mp[i, M_VALVE:]`` (valve code and block; i = the row's
L_MUSCLE), the plant's own numbers, which the compiled sample receives with the table.

With a ``[firmware]`` section each valve row also carries its sensors' transfer functions
(columns L_ADC_*, L_AADC_*) and, after its knots, its firmware block (column L_FW points to it):
the integer parameters and flash tables of the kind's integer twin (:mod:`frogsim.control.fixed`).

Pressures are absolute [Pa] inside; times [s]; the PWM period and minimum pulse in controller
samples (the commands change only on the controller's grid).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from frogsim.circuit.layout import (G_BRANCH_LIMIT, G_K, G_PATM, G_PUMP_ENABLED, G_PUMP_OFF, G_PUMP_ON, G_R,
                                    G_RHOREF, G_SUPPLY_MODE, G_TAMB, G_TREF, SUPPLY_PAPER, Y_PS)
from frogsim.scenario import kinds as registry

# --- kinds of sampled law (a controller kind's code is its module's CODE) ------------------------------
KIND_PUMP_BAND = 1.0
#: a muscle whose valves a Python function drives (frogsim.simulate(..., controller=fn)): the
#: compiled sample only senses its pressure; the commands come from Python
KIND_EXTERNAL = 5.0

# --- setpoint generators -----------------------------------------------------------------------------
DUTY_CLOSED = -1.0
DUTY_SCHEDULED = -2.0
SP_CONSTANT = 0.0
SP_STEPS = 1.0
SP_SINE = 2.0
SP_TABLE = 3.0

# --- columns ---------------------------------------------------------------------------------------------
L_KIND = 0       # KIND_*
L_INPUT = 1      # pump band: index of the state entry the rule reads (Y_PS)
L_LOW = 2        # pump band: switch on below this value
L_HIGH = 3       # pump band: switch off above this value
L_MUSCLE = 4     # muscle index i (valves u[2i] charge, u[2i+1] discharge; pressure y[pressure_index(i)])
L_DEAD_C = 5     # charge valve dead time [s]
L_DEAD_D = 6     # discharge valve dead time [s]
L_BAND = 7       # bang-bang: width of the hold band [Pa]
L_PERIOD_N = 8   # pwm: period [controller samples]
L_DUTY = 9       # pwm: open-loop duty [-]; DUTY_CLOSED: closed loop (duty from the pressure error);
                 # DUTY_SCHEDULED: open loop, the duty from the schedule in the setpoint columns
L_PBAND = 10     # pwm closed loop: proportional band [Pa] (error giving 100 % duty)
L_MINPULSE_N = 11  # pwm: minimum pulse [controller samples]
L_REST = 12      # pwm open loop: 1 vent, 0 hold between the charge pulses
L_HORIZON = 13   # sliding mode: lambda [s] of s = e + lambda de/dt
L_PENALTY = 14   # sliding mode: switching penalty rho [Pa] (J = s^2 + rho^2 per mode change)
L_GAIN = 15      # sliding mode: k R T_amb / V_nominal [Pa/kg]: pressure rate per mass flow
L_PATM = 16      # atmospheric pressure [Pa]: the sensor reads gauge pressure
L_NOISE = 17     # sensor noise standard deviation [Pa]
L_SEED = 18      # sensor noise seed
L_BITS = 19      # ADC bits (0: no quantisation)
L_FS = 20        # ADC full scale [Pa gauge] (the range is 0..full scale)
L_LAG = 21       # sensor first-order lag time constant [s] (0: none)
L_RHOREF = 22    # the controller's gas model: ISO 6358 reference density [kg/m^3]
L_TREF = 23      # ISO 6358 reference temperature [K]
L_TAMB = 24      # ambient temperature [K] (every gas in the law's valve model)
L_BRANCH = 25    # charge-flow limit of the supply [kg/s] (inf: none)
L_SP_KIND = 26   # SP_*
L_SP_A = 27      # constant: value; sine: mean [Pa abs]
L_SP_B = 28      # sine: amplitude [Pa]
L_SP_C = 29      # sine: frequency [Hz]
L_SP_D = 30      # sine: start time [s]
L_SP_N = 31      # steps / table: number of knots
L_JOINT1 = 32    # joint-angle: 1 + index of the joint whose angle the law reads (0: none)
L_SIGN = 33      # joint-angle: +1 the extensor (target p0 + dp/2), -1 the flexor (p0 - dp/2)
L_P0 = 34        # joint-angle: co-contraction level p0 [Pa abs]
L_KP = 35        # joint-angle: proportional gain [Pa/rad]
L_KD = 36        # joint-angle: derivative gain [Pa s/rad]
L_KI = 37        # joint-angle: integral gain [Pa/(rad s)]
L_STREAM = 38    # first noise stream of the pressure sensor (0: stream 1)
L_A_NOISE = 39   # angle sensor: noise standard deviation [rad]
L_A_SEED = 40    # angle sensor: noise seed
L_A_BITS = 41    # angle sensor: encoder bits (0: no quantisation)
L_A_FS = 42      # angle sensor: full scale [rad] (the range is 0..full scale)
L_A_LAG = 43     # angle sensor: first-order lag time constant [s] (0: none)
# [firmware] (frogsim.control.fixed): the row's law runs in its integer twin on ADC counts
L_FW = 44        # column where the row's firmware block starts (0: none, the float law runs)
L_ADC_V0 = 45    # pressure transducer: volts at L_ADC_Q0 [V]
L_ADC_K = 46     # ... volts per Pa [V/Pa]
L_ADC_Q0 = 47    # ... its low pressure [Pa gauge]
L_ADC_FULL = 48  # the ADC's 2^bits (1024 at 10 bits)
L_ADC_VREF = 49  # the ADC's reference [V]
L_AADC_V0 = 50   # angle sensor: volts at L_AADC_Q0 [V]
L_AADC_K = 51    # ... volts per rad [V/rad]
L_AADC_Q0 = 52   # ... its low angle [rad]
L_AADC_FULL = 53  # ... the angle count's 2^bits (the ADC's, or 65536 for a quadrature encoder's counter)
# [firmware] sensor faults (frogsim.control.fixed.fault_columns): a count below LO or above HI is a fault
L_FAULT_PLO = 54   # the pressure count's fault limits (LO -1: the pressure is not checked)
L_FAULT_PHI = 55
L_FAULT_ALO = 56   # the angle count's (LO -1: not checked)
L_FAULT_AHI = 57
L_FAULT_MODE = 58  # the mode while in fault: -1 vent, 0 hold
L_FAULT_N = 59     # good samples after a fault before the law runs again
L_INJ_P_AT = 60    # a fault put into the plant (SensorFault): from this time [s] (inf: none) ...
L_INJ_P_COUNT = 61  # ... the pressure channel reads this count
L_INJ_A_AT = 62    # the same for the angle channel
L_INJ_A_COUNT = 63
# joint-angle: the angle loop's schedule (frogsim.control.kinds.joint_angle): it runs every
# L_A_EVERY samples (0 or 1: every sample), first at sample L_A_PHASE; between runs its targets hold
L_A_EVERY = 64
L_A_PHASE = 65
L_ADC_CODE = 66   # the pressure sensor's type: its CODE in the sensor family (frogsim.circuit.sensors)
L_AADC_CODE = 67  # the angle sensor's type (a potentiometer's or an encoder's CODE)
L_SIZE = 68
L_SP0 = L_SIZE   # knots (t_j, p_j) from here on; the firmware block after them


def pump_row(g) -> np.ndarray:
    """The pump band's row: switch on below G_PUMP_ON, off above G_PUMP_OFF, on the source pressure."""
    row = np.zeros(L_SIZE)
    row[L_KIND] = KIND_PUMP_BAND
    row[L_INPUT] = Y_PS
    row[L_LOW] = g[G_PUMP_ON]
    row[L_HIGH] = g[G_PUMP_OFF]
    return row


def setpoint_columns(sp, patm: float) -> tuple[dict, list]:
    """Columns of a setpoint generator (a :class:`frogsim.scenario.schema.Setpoint`) and its knots
    [(t, p_abs)] (steps: the step times and values; table: the file's rows, read by the loader)."""
    cols = {L_SP_KIND: {"constant": SP_CONSTANT, "steps": SP_STEPS, "sine": SP_SINE,
                        "table": SP_TABLE}[sp.kind]}
    pts = []
    if sp.kind == "constant":
        cols[L_SP_A] = patm + sp.value
    elif sp.kind == "sine":
        cols[L_SP_A] = patm + sp.mean
        cols[L_SP_B] = sp.amplitude
        cols[L_SP_C] = sp.frequency
        cols[L_SP_D] = sp.start
    else:
        pts = [(t, patm + p) for t, p in sp.points()]
    cols[L_SP_N] = len(pts)
    return cols, pts


class RowContext(NamedTuple):
    """What a kind's ``write_rows`` reads besides its settings: the scenario, the globals g, the
    muscle names in the model's order and each muscle's volume at the start [m^3] (the
    controller's model of it)."""
    sc: object
    g: np.ndarray
    names: list
    volumes: dict

    @property
    def patm(self) -> float:
        """The atmospheric pressure [Pa abs]: a gauge setpoint's offset."""
        return float(self.g[G_PATM])


def valve_row(ctx: RowContext, code: float, muscle: str, sensor) -> np.ndarray:
    """The columns every valve law has: its kind code, its muscle, the valves' dead times, the
    atmosphere, the pressure sensor, the controller's gas model of the muscle (gain k R T_amb / V,
    reference density and temperature, the supply's branch limit)."""
    sc, g = ctx.sc, ctx.g
    row = np.zeros(L_SIZE)
    row[L_KIND] = code
    row[L_MUSCLE] = ctx.names.index(muscle)
    row[L_DEAD_C] = sc.valves.charge.dead_time
    row[L_DEAD_D] = sc.valves.discharge.dead_time
    row[L_GAIN] = g[G_K] * g[G_R] * g[G_TAMB] / ctx.volumes[muscle]
    row[L_PATM] = g[G_PATM]
    s = sensor
    row[L_NOISE], row[L_SEED], row[L_BITS], row[L_FS], row[L_LAG] = (
        s.noise, s.seed, s.bits or 0, s.full_scale, s.lag)
    row[L_RHOREF], row[L_TREF], row[L_TAMB] = g[G_RHOREF], g[G_TREF], g[G_TAMB]
    row[L_BRANCH] = g[G_BRANCH_LIMIT] if int(g[G_SUPPLY_MODE]) == SUPPLY_PAPER else np.inf
    return row


def with_setpoint(row: np.ndarray, sp, offset: float) -> np.ndarray:
    """The row with setpoint ``sp``'s generator columns and its knots appended (values plus
    ``offset``: the atmosphere for a gauge pressure, 0 for an angle or a duty)."""
    cols, pts = setpoint_columns(sp, offset)
    for col, val in cols.items():
        row[col] = val
    return np.concatenate([row, np.array([v for pt in pts for v in pt], float)])


def build_table(sc, g, names: tuple, volumes: tuple) -> np.ndarray:
    """The table of laws of scenario ``sc``: the pump's band, then each controller's rows from its
    kind (``write_rows``) in the scenario's order."""
    ctx = RowContext(sc, g, list(names), dict(zip(names, volumes)))
    rows = [r for cname, c in sc.controllers.items() for r in c.write_rows(cname, ctx)]
    return laws_table(g, rows)


registry.register_table(build_table)


def laws_table(g, rows: list) -> np.ndarray:
    """The pump band's row (when the pump is enabled) then the controllers' rows, zero-padded to
    the widest. Without controllers: the 1-D open-loop form of
    :func:`frogsim.control.sampled.sampled_laws` (the pump's row, or an empty row)."""
    if not rows:
        return pump_row(g) if g[G_PUMP_ENABLED] >= 0.5 else np.zeros(0)
    allrows = ([pump_row(g)] if g[G_PUMP_ENABLED] >= 0.5 else []) + list(rows)
    width = max([L_SIZE] + [r.size for r in allrows])
    laws = np.zeros((len(allrows), width))
    for c, r in enumerate(allrows):
        laws[c, :r.size] = r
    return laws
