"""A hand-written firmware plan for the firmware tests: one muscle under a bang-bang law written
here in C (integer counts), with the plan's fields as frogsim.control.firmware makes them."""
from __future__ import annotations

from dataclasses import dataclass, field

from frogsim.export import board

BANG_BANG_C = """
#include <stdint.h>
/* bang-bang on channel 0: charge below LOW counts, vent above HIGH, hold between */
#define FS_LOW %(low)d
#define FS_HIGH %(high)d
uint32_t frogsim_faults(void) { return 0; }
void frogsim_sample(uint32_t k, const uint16_t *adc, int8_t *modes) {
    (void)k;
    int32_t c = (int32_t)adc[0];
    if (c < FS_LOW) modes[0] = 1;
    else if (c > FS_HIGH) modes[0] = -1;
    else modes[0] = 0;
}
"""


@dataclass(frozen=True)
class Channel:
    signal: str
    quantity: str
    name: str
    analog_input: int
    unit_per_count: float
    offset: float


@dataclass(frozen=True)
class Adc:
    prescaler: int = 128
    bits: int = 10
    first_cycles: int = 25         # ADC clocks
    cycles: int = 13


@dataclass(frozen=True)
class Plan:
    name: str = "stub"
    rate: float = 1000.0
    muscles: list = field(default_factory=lambda: ["hip"])
    valve_pins: list = field(default_factory=lambda: [(22, 23)])
    channels: list = field(default_factory=list)
    adc: Adc = Adc()
    busy_pin: int = 13
    baud: int = 115200
    log_every: int = 10
    c_source: str = ""

    @property
    def period_cycles(self) -> int:
        return int(round(board.F_CPU / self.rate))


#: the 0.5-4.5 V over 0-10 bar gauge transducer on a 10-bit ADC at 5 V: V = 0.5 + 0.4 p[bar],
#: count = floor(V / 5 x 1024); a count's pressure (the middle of its step)
#: p = ((count + 1/2) x 5/1024 - 0.5) / 0.4
PA_PER_COUNT = 5.0 / 1024 / 0.4 * 1e5
OFFSET_PA = (0.5 * 5.0 / 1024 - 0.5) / 0.4 * 1e5


def count_of(p_gauge_pa: float) -> int:
    v = 0.5 + 0.4 * p_gauge_pa / 1e5
    return max(0, min(1023, int(v / 5.0 * 1024)))


def bang_bang_plan(low_bar=2.9, high_bar=3.1, channels=1, prescaler=128, rate=1000.0, **kw) -> Plan:
    chans = [Channel(f"hip pressure" if i == 0 else f"extra{i} pressure", "pressure", "hip", i,
                     PA_PER_COUNT, OFFSET_PA) for i in range(channels)]
    bits = board.adc_bits(prescaler) if board.F_CPU / prescaler <= board.ADC_MAX_CLOCK_HZ else 8
    src = BANG_BANG_C % {"low": count_of(low_bar * 1e5), "high": count_of(high_bar * 1e5)}
    return Plan(rate=rate, channels=chans, adc=Adc(prescaler, bits),
                c_source=src, **kw)
