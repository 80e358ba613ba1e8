"""Kind "sliding-mode": multi-mode sliding control of the pressure with a switching penalty and a
model-based feedforward from Eq. (8)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from frogsim._jit import jit
from frogsim.circuit.layout import M_SIZE, M_VALVE, Y_PE, Y_PS
from frogsim.circuit.valves import valve_flows, write_block
from frogsim.control import fixed
from frogsim.control.kinds.common import PressureTracking
from frogsim.control.kinds.spec import PRESSURE_TRACKING, ControllerKind, FirmwareTwin, Gain
from frogsim.control.signals import B_MODE, B_SP, MODE_CHARGE, MODE_HOLD, MODE_VENT, fw_at, fw_sine, setpoint
from frogsim.control.table import (L_BRANCH, L_DEAD_C, L_DEAD_D, L_GAIN, L_HORIZON, L_MUSCLE, L_PENALTY,
                                   L_RHOREF, L_TAMB, L_TREF, valve_row, with_setpoint)
from frogsim.scenario.fields import quantity
from frogsim.scenario.schema import BAR, GAUGE_MAX

CODE = 4.0      # the table's kind column


@dataclass(frozen=True)
class SlidingModeSettings(PressureTracking):
    """Sliding surface s = e + lambda de/dt; the mode minimising s^2 + rho^2 [opening a valve]."""
    KIND = "sliding-mode"
    horizon: float = quantity("time", gt=0.0, le=1.0, display="ms", default=2e-3,
                              doc="lambda of s = e + lambda de/dt")
    penalty: float = quantity("pressure", ge=0.0, le=GAUGE_MAX, display="bar", default=0.05 * BAR,
                              doc="switching penalty rho (cost s^2 + rho^2 per change)")

    def write_rows(self, name: str, ctx) -> list:
        row = valve_row(ctx, CODE, self.muscle, self.sensor)
        row[L_HORIZON] = self.horizon
        row[L_PENALTY] = self.penalty
        row = with_setpoint(row, self.setpoint, ctx.patm)
        if ctx.sc.firmware is not None:
            row = firmware_row(row, ctx)
        return [row]


SHIFT = 20              # the dead time and the horizon in Q20 seconds (2^-20 s, about 1 us)
P_SINE = 5              # P[P_SINE:P_SINE + SN_SIZE]: the sine block (P[P_SINE] < 0: the tables)
SINE = True             # the C twin calls the sine generator (its table is linked)
S_MAX = 16383           # |s| is clipped here (Q4 counts) so that s^2 + rho^2 fits int32
RATE_MAX = 2**24        # [Q4 counts/s] table entries are clipped here


def firmware_row(row, ctx):
    """The integer twin's block. P = [dead time (Q20 s), horizon lambda (Q20 s), rho^2 (Q4
    counts squared, rho clipped to S_MAX), setpoint table length n, 2^bits, the sine block
    (:func:`frogsim.control.fixed.sine_block`: a sine setpoint is generated, n = 0)]; T = the
    setpoint (Q4 counts) at each sample and its rate (Q4 counts/s) at each sample (n of each;
    none for a generated sine), then per count c the rates under charge and under vent (Q4
    counts/s): the valve model :func:`mode_rates` at the pressure in the middle of count c, with
    the source and the exhaust at their starting pressures (the firmware measures neither),
    computed here for both twins."""
    sc = ctx.sc
    fw = sc.firmware
    full = fixed.adc_full(sc)
    line = fixed.pressure_volts(fw)
    per_pa = fixed.q4_per_unit(line, fw, full)
    laws = np.ascontiguousarray(row[None, :])
    i = int(row[L_MUSCLE])
    mp = np.zeros((i + 1, M_SIZE))
    write_block(mp[i], sc.valves)       # the valve type's own parameter block, as the model's row holds it
    y = np.zeros(max(Y_PS, Y_PE) + 1)
    y[Y_PS] = ctx.patm + fixed.top_pressure(sc)
    y[Y_PE] = ctx.patm + sc.exhaust.initial_pressure_gauge
    v0, k, q0 = line
    rc = np.empty(full, np.int64)
    rv = np.empty(full, np.int64)
    for c in range(full):
        p = max(ctx.patm + q0 + ((c + 0.5) * fw.vref / full - v0) / k, 1.0)
        r_c, r_v = mode_rates(laws, mp, 0, y, p)
        rc[c] = int(np.clip(np.floor(r_c * per_pa + 0.5), -RATE_MAX, RATE_MAX))
        rv[c] = int(np.clip(np.floor(r_v * per_pa + 0.5), -RATE_MAX, RATE_MAX))
    dead = max(row[L_DEAD_C], row[L_DEAD_D])
    rho = min(int(round(row[L_PENALTY] * per_pa)), S_MAX)
    sine = fixed.sine_block(row, sc, line, full, ctx.patm, 1.0)
    if sine is None:
        sp, dsp = fixed.setpoint_series(row, sc, ctx.patm)
        sp_q, dsp_q = fixed.trimmed(fixed.q4(line, fw, sp, full),
                                    np.clip(np.floor(dsp * per_pa + 0.5), -RATE_MAX, RATE_MAX).astype(np.int64))
        sine = fixed.NO_SINE
    else:
        sp_q = dsp_q = np.zeros(0, np.int64)
    P = [int(round(dead * 2**SHIFT)), int(round(row[L_HORIZON] * 2**SHIFT)), rho * rho, sp_q.size, full] + list(sine)
    T = np.concatenate([sp_q, dsp_q, rc, rv])
    return fixed.firmware_row(row, sc, P, T)


@jit
def law(laws, mp, c, cs, b, y, p, ts):
    """The sliding-mode choice at ts (``mp``: the model's muscle rows, whose valve constants the
    law's valve model reads)."""
    sp, dsp = setpoint(laws, c, ts)
    cs[b + B_SP] = sp
    return sliding_mode(laws, mp, c, cs, b, y, p, sp, dsp)


@jit
def mode_rates(laws, mp, c, y, p):
    """The controller's model of the muscle's pressure rate [Pa/s] under charge and under vent:
    the flows of the muscle's valve type with both paths fully open
    (:func:`frogsim.circuit.valves.valve_flows`, Eq. (8) for the switching valves) at the measured
    pressure p (source and exhaust at their pressures, every gas at ambient temperature, the
    supply's branch limit) times k R T_amb / V. The valve's constants are the plant's: the
    muscle's row of the model's ``mp`` (its valve code and parameter block)."""
    T = laws[c, L_TAMB]
    rho = laws[c, L_RHOREF]
    Tr = laws[c, L_TREF]
    i = int(laws[c, L_MUSCLE])
    mc, md = valve_flows(mp[i, M_VALVE], mp, i, 1.0, 1.0, y[Y_PS], T, p, T, y[Y_PE], T, rho, Tr)
    mc = min(mc, laws[c, L_BRANCH])
    gain = laws[c, L_GAIN]
    return gain * mc, -gain * md


@jit
def sliding_mode(laws, mp, c, cs, b, y, p, sp, dsp):
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
    r_charge, r_vent = mode_rates(laws, mp, c, y, p)
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
def fw_law(P, T, mem, k, cp, ca):
    """The integer twin of :func:`sliding_mode` in Q4 counts (mem[0]: the mode last chosen):
    e = sp - (16 cp + 8) + (dead (dsp - r_last)) >> 20, s(m) = e + (lambda (dsp - r_m)) >> 20
    (products in int64, arithmetic shifts: floor in both twins), s clipped to +-S_MAX, the mode
    minimising s^2 + rho^2 [m opens a valve the last mode kept shut]; ties go to hold, then charge.
    The setpoint and its rate come from the sine block (:func:`frogsim.control.signals.fw_sine`)
    or the tables."""
    n = int(P[3])
    full = int(P[4])
    cq = 16 * cp + 8
    if P[P_SINE] >= 0:
        sp, dsp = fw_sine(P, P_SINE, k)
    else:
        sp = fw_at(T, k, n)
        dsp = int(T[n + (k if k < n else n - 1)])
    rc = int(T[2 * n + cp])
    rv = int(T[2 * n + full + cp])
    last = int(mem[0])
    r_last = rc if last > 0 else (rv if last < 0 else 0)
    e = sp - cq + ((int(P[0]) * (dsp - r_last)) >> SHIFT)
    lam = int(P[1])
    pen = int(P[2])
    best = 0
    cost = 2**31 - 1
    for m in (0, 1, -1):
        r = rc if m > 0 else (rv if m < 0 else 0)
        s = e + ((lam * (dsp - r)) >> SHIFT)
        s = min(max(s, -S_MAX), S_MAX)
        j = s * s + (pen if (m != last and m != 0) else 0)
        if j < cost:
            cost = j
            best = m
    mem[0] = best
    return best


C_NAME = "fs_sliding_mode"


def c_source() -> str:
    """The C twin of :func:`fw_law`."""
    return """int8_t fs_sliding_mode(uint32_t k, uint16_t cp, uint16_t ca, int32_t *mem, const int32_t *P,
                       const int32_t *T) {
    int32_t n = P[3], full = P[4];
    int32_t cq = (int32_t)cp * 16 + 8, sp, dsp;
    if (P[5] >= 0) {
        sp = fs_sine(k, &P[5], &dsp);
    } else {
        uint32_t kk = k < (uint32_t)n ? k : (uint32_t)(n - 1);
        sp = (int32_t)FS_READ32(&T[kk]);
        dsp = (int32_t)FS_READ32(&T[n + kk]);
    }
    int32_t rc = (int32_t)FS_READ32(&T[2 * n + cp]);
    int32_t rv = (int32_t)FS_READ32(&T[2 * n + full + cp]);
    int32_t last = mem[0];
    int32_t r_last = last > 0 ? rc : (last < 0 ? rv : 0);
    int32_t e = sp - cq + (int32_t)(((int64_t)P[0] * (int64_t)(dsp - r_last)) >> 20);
    int32_t cost = INT32_MAX, pen = P[2];
    int8_t best = 0, i;
    static const int8_t order[3] = {0, 1, -1};
    (void)ca;
    for (i = 0; i < 3; i++) {
        int8_t m = order[i];
        int32_t r = m > 0 ? rc : (m < 0 ? rv : 0);
        int32_t s = e + (int32_t)(((int64_t)P[1] * (int64_t)(dsp - r)) >> 20);
        int32_t j;
        if (s > 16383) s = 16383;
        if (s < -16383) s = -16383;
        j = s * s + ((m != last && m != 0) ? pen : 0);
        if (j < cost) { cost = j; best = m; }
    }
    mem[0] = best;
    return best;
}
"""


KIND = ControllerKind(
    settings=SlidingModeSettings, code=CODE, law=law,
    firmware=FirmwareTwin(fw_law=fw_law, c_name=C_NAME, c_source=c_source, sine=SINE),
    tracks="pressure", metrics=PRESSURE_TRACKING,
    gains=(
        # lambda: a tenth of a 2 ms default up to ten times it (about ten valve dead times)
        Gain("horizon", "ms", 0.2, 20.0, log=True),
        # rho: a tenth of the 0.05 bar default up to ten times it (docs/control.md's study spans 0.02-0.15 bar)
        Gain("penalty", "bar", 0.005, 0.5, log=True),
    ))
