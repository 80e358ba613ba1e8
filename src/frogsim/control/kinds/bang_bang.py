"""Kind "bang-bang": a three-position relay with a hold band on the muscle's pressure."""
from __future__ import annotations

from dataclasses import dataclass

from frogsim._jit import jit
from frogsim.control import fixed
from frogsim.control.kinds.common import PressureTracking
from frogsim.control.signals import B_SP, bang_bang, fw_at, fw_relay, setpoint
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
        row = with_setpoint(row, self.setpoint, ctx.patm)
        if ctx.sc.firmware is not None:
            row = firmware_row(row, self.band, ctx)
        return [row]


def firmware_row(row, band: float, ctx):
    """The row's integer twin's block: P = [half band (Q4 counts), setpoint table length],
    T = the setpoint at each sample (Q4 counts of the transducer)."""
    sc = ctx.sc
    fw = sc.firmware
    full = fixed.adc_full(sc)
    line = fixed.pressure_volts(fw)
    sp, _ = fixed.setpoint_series(row, sc, ctx.patm)
    T, = fixed.trimmed(fixed.q4(line, fw, sp, full))
    half = int(round(0.5 * band * fixed.q4_per_unit(line, fw, full)))
    return fixed.firmware_row(row, sc, [half, T.size], T)


@jit
def fw_law(P, T, mem, k, cp, ca):
    """The integer twin: the relay on the count cp (its middle, 16 cp + 8 in Q4) against the
    setpoint table's entry at sample k, hold band +-P[0] (Q4). No memory."""
    return fw_relay(16 * cp + 8, fw_at(T, k, int(P[1])), int(P[0]))


C_NAME = "fs_bang_bang"


def c_source() -> str:
    """The C twin of :func:`fw_law` (C99, stdint only)."""
    return """int8_t fs_bang_bang(uint32_t k, uint16_t cp, uint16_t ca, int32_t *mem, const int32_t *P,
                    const int32_t *T) {
    (void)ca; (void)mem;
    return fs_relay((int32_t)cp * 16 + 8, fs_at(T, k, P[1]), P[0]);
}
"""


@jit
def law(laws, c, cs, b, y, p, ts):
    """The relay on the sensed pressure p [Pa abs] against the setpoint at ts."""
    sp, _ = setpoint(laws, c, ts)
    cs[b + B_SP] = sp
    return bang_bang(p, sp, laws[c, L_BAND])
