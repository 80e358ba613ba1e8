"""Kind "bang-bang": a three-position relay with a hold band on the muscle's pressure."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frogsim._jit import jit
from frogsim.control import fixed
from frogsim.control.kinds.common import PressureTracking
from frogsim.control.kinds.spec import PRESSURE_TRACKING, ControllerKind, FirmwareTwin, Gain
from frogsim.control.signals import B_SP, bang_bang, fw_at, fw_relay, fw_sine, setpoint
from frogsim.control.table import L_BAND, valve_row, with_setpoint
from frogsim.scenario.fields import quantity
from frogsim.scenario.schema import BAR, GAUGE_MAX

CODE = 2.0      # the table's kind column


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


P_SINE = 2      # P[P_SINE:P_SINE + SN_SIZE]: the sine block (P[P_SINE] < 0: the table)
SINE = True     # the C twin calls the sine generator (its table is linked)


def firmware_row(row, band: float, ctx):
    """The row's integer twin's block: P = [half band (Q4 counts), setpoint table length, the
    sine block (:func:`frogsim.control.fixed.sine_block`)]; a sine setpoint is generated (T
    empty), any other tabulated: T = the setpoint at each sample (Q4 counts of the transducer)."""
    sc = ctx.sc
    fw = sc.firmware
    full = fixed.adc_full(sc)
    line = fixed.pressure_volts(fw)
    sine = fixed.sine_block(row, sc, line, full, ctx.patm, 0.0)
    if sine is None:
        sp, _ = fixed.setpoint_series(row, sc, ctx.patm)
        T, = fixed.trimmed(fixed.q4(line, fw, sp, full))
        sine = fixed.NO_SINE
    else:
        T = np.zeros(0, np.int64)
    half = int(round(0.5 * band * fixed.q4_per_unit(line, fw, full)))
    return fixed.firmware_row(row, sc, [half, max(1, T.size)] + list(sine), T)


@jit
def fw_law(P, T, mem, k, cp, ca):
    """The integer twin: the relay on the count cp (its middle, 16 cp + 8 in Q4) against the
    setpoint at sample k (the sine block's, or the table's entry), hold band +-P[0] (Q4). No
    memory."""
    if P[P_SINE] >= 0:
        sp, _ = fw_sine(P, P_SINE, k)
    else:
        sp = fw_at(T, k, int(P[1]))
    return fw_relay(16 * cp + 8, sp, int(P[0]))


C_NAME = "fs_bang_bang"


def c_source() -> str:
    """The C twin of :func:`fw_law` (C99, stdint only)."""
    return """int8_t fs_bang_bang(uint32_t k, uint16_t cp, uint16_t ca, int32_t *mem, const int32_t *P,
                    const int32_t *T) {
    (void)ca; (void)mem;
    return fs_relay((int32_t)fs_muluu(cp, 16) + 8, P[2] >= 0 ? fs_sine(k, &P[2], 0) : fs_at(T, k, P[1]), P[0]);
}
"""


@jit
def law(laws, mp, c, cs, b, y, p, ts):
    """The relay on the sensed pressure p [Pa abs] against the setpoint at ts."""
    sp, _ = setpoint(laws, c, ts)
    cs[b + B_SP] = sp
    return bang_bang(p, sp, laws[c, L_BAND])


KIND = ControllerKind(
    settings=BangBangSettings, code=CODE, law=law,
    firmware=FirmwareTwin(fw_law=fw_law, c_name=C_NAME, c_source=c_source, sine=SINE),
    tracks="pressure", metrics=PRESSURE_TRACKING,
    # the band: from about one count of a 10-bit ADC on a 10 bar transducer (0.01 bar) up to 1 bar
    gains=(Gain("band", "bar", 0.01, 1.0, log=True),))
