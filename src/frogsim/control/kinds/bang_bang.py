"""Kind "bang-bang": a three-position relay with a hold band on the muscle's pressure."""
from __future__ import annotations

from dataclasses import dataclass

from frogsim._jit import jit
from frogsim.control.kinds.common import PressureTracking
from frogsim.control.signals import B_SP, bang_bang, setpoint
from frogsim.control.table import L_BAND, valve_row, with_setpoint
from frogsim.scenario.fields import quantity
from frogsim.scenario.kinds import register
from frogsim.scenario.schema import BAR, GAUGE_MAX

CODE = 2.0      # the table's kind column


@register
@dataclass(frozen=True)
class BangBangSettings(PressureTracking):
    """Charge below setpoint - band/2, vent above setpoint + band/2, hold between."""
    KIND = "bang-bang"
    band: float = quantity("pressure", gt=0.0, le=GAUGE_MAX, display="bar", default=0.1 * BAR,
                           doc="charge below setpoint - band/2, vent above setpoint + band/2")

    def write_rows(self, name: str, ctx) -> list:
        row = valve_row(ctx, CODE, self.muscle, self.sensor)
        row[L_BAND] = self.band
        return [with_setpoint(row, self.setpoint, ctx.patm)]


@jit
def law(laws, c, cs, b, y, p, ts):
    """The relay on the sensed pressure p [Pa abs] against the setpoint at ts."""
    sp, _ = setpoint(laws, c, ts)
    cs[b + B_SP] = sp
    return bang_bang(p, sp, laws[c, L_BAND])
