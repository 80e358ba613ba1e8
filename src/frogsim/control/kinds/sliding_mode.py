"""Kind "sliding-mode": multi-mode sliding control of the pressure with a switching penalty and a
model-based feedforward from Eq. (8)."""
from __future__ import annotations

import math
from dataclasses import dataclass

from frogsim._jit import jit
from frogsim.circuit.layout import M_CB, M_CC, M_CM, M_CRL, M_DB, M_DC, M_DM, M_DRL, Y_PE, Y_PS
from frogsim.control.kinds.common import PressureTracking
from frogsim.control.signals import B_MODE, B_SP, MODE_CHARGE, MODE_HOLD, MODE_VENT, setpoint
from frogsim.control.table import (L_BRANCH, L_DEAD_C, L_DEAD_D, L_GAIN, L_HORIZON, L_MUSCLE, L_PENALTY,
                                   L_RHOREF, L_TAMB, L_TREF, valve_row, with_setpoint)
from frogsim.physics.flow import iso6358_mass_flow
from frogsim.scenario.fields import quantity
from frogsim.scenario.kinds import register
from frogsim.scenario.schema import BAR, GAUGE_MAX

CODE = 4.0      # the table's kind column


@register
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
        return [with_setpoint(row, self.setpoint, ctx.patm)]


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
    Eq. (8) flows at the measured pressure p (source and exhaust at their pressures, every gas at
    ambient temperature, the supply's branch limit) times k R T_amb / V. The valves' ISO 6358
    constants are the plant's: the muscle's row of the model's ``mp`` (columns M_CC..M_DRL)."""
    T = laws[c, L_TAMB]
    rho = laws[c, L_RHOREF]
    Tr = laws[c, L_TREF]
    i = int(laws[c, L_MUSCLE])
    mc = iso6358_mass_flow(y[Y_PS], T, p, T, mp[i, M_CC], mp[i, M_CB], mp[i, M_CM], mp[i, M_CRL], rho, Tr)
    mc = min(mc, laws[c, L_BRANCH])
    md = iso6358_mass_flow(p, T, y[Y_PE], T, mp[i, M_DC], mp[i, M_DB], mp[i, M_DM], mp[i, M_DRL], rho, Tr)
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
