"""The ATmega2560 on the Arduino Mega 2560 (paper, Sec. 4: "The switch valves are controlled by the
control card (Arduino Mega 2560)"): the part's facts that a firmware design is checked against,
and its ADC's conversion timing and transfer function. Pure facts of the catalogue part, read by
the scenario layer (the ``[firmware]`` section's refusals), the control layer (the firmware's
plan) and the export layer (:mod:`frogsim.export.board`, which adds the Arduino core's pin map).

Sources:

* Atmel, *ATmega640/V-1280/V-1281/V-2560/V-2561/V* datasheet (2549Q-AVR-02/2014), Sec. 26.4
  "Prescaling and Conversion Timing" and Table 26-1: "A normal conversion takes 13 ADC clock
  cycles. The first conversion after the ADC is switched on (ADEN in ADCSRA is set) takes 25 ADC
  clock cycles"; auto-triggered conversions 13.5; "the successive approximation circuitry requires
  an input clock frequency between 50 kHz and 200 kHz to get maximum resolution. If a lower
  resolution than 10 bits is needed, the input clock frequency to the ADC can be higher than 200
  kHz"; the ADC prescaler divides the CPU clock by 2, 4, 8, 16, 32, 64 or 128 (ADPS2:0).
  Sec. 26.7 "ADC Conversion Result": "For single ended conversion, the result is
  ADC = V_IN * 1024 / V_REF" (the converter truncates: the result is the largest count whose
  threshold the input reaches, 0..1023).
* Atmel's ADC documentation for the megaAVR ADC ("ADC Clock and Conversion Timing"): "it is not
  recommended to use an ADC clock with a frequency higher than 1 MHz. At 1 MHz we can expect
  maximum 8 bits of resolution."
* Arduino Mega 2560 Rev3: ATmega2560 at 16 MHz, 256 KB flash of which 8 KB are used by the
  bootloader, 8 KB SRAM, 54 digital pins and 16 analog inputs (A0-A15 = digital pins 54-69);
  pins 0 and 1 carry USART0 (the USB serial port).
* The datasheet, Sec. 17.9.2 "Clear Timer on Compare Match (CTC) Mode" and Table 17-6: the
  16-bit Timer1 in CTC mode interrupts at f_clk / (N (1 + OCR1A)), N the clock prescaler (1, 8,
  64, 256 or 1024: CS12:0), OCR1A 0..65535. The controller's period is therefore a whole number
  of CPU cycles, N (1 + OCR1A).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

F_CPU = 16_000_000            # [Hz] the Mega 2560's crystal
FLASH_BYTES = 256 * 1024      # [B] program memory
BOOTLOADER_BYTES = 8 * 1024   # [B] taken by the Arduino bootloader (stk500v2)
SRAM_BYTES = 8 * 1024         # [B] data memory
DIGITAL_PINS = 70             # D0..D69 (D54..D69 are A0..A15)
ANALOG_INPUTS = 16            # A0..A15
SERIAL_PINS = (0, 1)          # USART0 RX, TX: the USB serial port the log streams over
#: [V] highest ADC reference: AREF lies between 1.0 V and AVCC, and AVCC at most VCC + 0.3 V with
#: VCC at most 5.5 V (datasheet Sec. 26.5 and Table 31-1, "Operating Voltage")
VREF_MAX = 5.5
ADC_PRESCALERS = (2, 4, 8, 16, 32, 64, 128)
ADC_CYCLES = 13               # ADC clock cycles of a normal single-ended conversion
ADC_CYCLES_FIRST = 25         # ... of the first one after the ADC is enabled
ADC_FULL_RESOLUTION_HZ = 200e3  # ADC clock at or below which the 10-bit result is specified
ADC_MAX_CLOCK_HZ = 1e6        # highest recommended ADC clock; 8 bits expected there
#: external interrupt pins of the Mega 2560 (INT4, INT5, INT3, INT2, INT1, INT0)
INTERRUPT_PINS = (2, 3, 18, 19, 20, 21)
#: digital pin -> its external interrupt INTn (datasheet Table 13-5 and the Mega's pin map:
#: D21 = PD0 = INT0, D20 = PD1 = INT1, D19 = PD2 = INT2, D18 = PD3 = INT3, D2 = PE4 = INT4, D3 = PE5 = INT5)
EXTERNAL_INTERRUPT = {21: 0, 20: 1, 19: 2, 18: 3, 2: 4, 3: 5}
TIMER1_PRESCALERS = (1, 8, 64, 256, 1024)   # Timer1's clock prescalers (CS12:0 = 1..5)
TIMER1_TOP = 65535            # OCR1A's largest value (16 bits)

def conversion_time(prescaler: int, f_cpu: float = F_CPU, first: bool = False) -> float:
    """Time of one single-ended conversion [s]: 13 ADC clock cycles (25 for the first after the
    ADC is enabled) of the ADC clock f_cpu / prescaler (datasheet Table 26-1).

    >>> round(conversion_time(128) * 1e6, 1)     # Arduino's default: 125 kHz ADC clock
    104.0
    """
    return (ADC_CYCLES_FIRST if first else ADC_CYCLES) * prescaler / f_cpu


def adc_bits(prescaler: int, f_cpu: float = F_CPU) -> int:
    """The resolution [bits] the datasheet supports at the ADC clock f_cpu / prescaler: 10 up to
    200 kHz, 8 up to 1 MHz (the firmware then reads the left-adjusted high byte ADCH only);
    ValueError above 1 MHz (not recommended at all)."""
    f_adc = f_cpu / prescaler
    if f_adc <= ADC_FULL_RESOLUTION_HZ:
        return 10
    if f_adc <= ADC_MAX_CLOCK_HZ:
        return 8
    raise ValueError(f"ADC clock {f_adc / 1e3:g} kHz is above the recommended 1 MHz")


@dataclass(frozen=True)
class AdcPlan:
    """How a control period's conversions are made: the prescaler, the resolution it allows, the
    time of the period's conversions and the share of the period they take."""
    channels: int
    prescaler: int
    bits: int
    conversion_s: float
    total_s: float
    period_s: float

    @property
    def share(self) -> float:
        return self.total_s / self.period_s

    def describe(self) -> str:
        return (f"{self.channels} conversions x {self.conversion_s * 1e6:.1f} us (13 ADC clocks at "
                f"{F_CPU / self.prescaler / 1e3:g} kHz, prescaler {self.prescaler}) = "
                f"{self.total_s * 1e6:.0f} us of the {self.period_s * 1e6:.0f} us period "
                f"({100 * self.share:.0f} %), {self.bits}-bit results")


def plan_adc(channels: int, period: float, budget: float = 0.6, f_cpu: float = F_CPU) -> AdcPlan:
    """The slowest (most accurate) ADC clock whose ``channels`` conversions take at most
    ``budget`` of the control ``period`` [s], leaving the rest for the law, the valve writes and
    the serial log. ValueError with the arithmetic if none fits (not even at the 1 MHz the
    datasheet allows) or the board has too few analog inputs."""
    if channels > ANALOG_INPUTS:
        raise ValueError(f"{channels} analog channels: the Mega 2560 has {ANALOG_INPUTS} analog inputs (A0-A15)")
    if channels == 0:
        return AdcPlan(0, 128, 10, conversion_time(128, f_cpu), 0.0, period)
    for prescaler in sorted(ADC_PRESCALERS, reverse=True):
        if f_cpu / prescaler > ADC_MAX_CLOCK_HZ:
            break
        t = conversion_time(prescaler, f_cpu)
        if channels * t <= budget * period:
            return AdcPlan(channels, prescaler, adc_bits(prescaler, f_cpu), t, channels * t, period)
    fastest = min(p for p in ADC_PRESCALERS if f_cpu / p <= ADC_MAX_CLOCK_HZ)
    t = conversion_time(fastest, f_cpu)
    raise ValueError(f"{channels} conversions do not fit the {period * 1e6:.0f} us control period: even at "
                     f"the fastest recommended ADC clock ({f_cpu / fastest / 1e6:g} MHz, 8 bits) they take "
                     f"{channels} x {t * 1e6:.1f} us = {channels * t * 1e6:.0f} us, more than "
                     f"{100 * budget:.0f} % of it ({budget * period * 1e6:.0f} us); lower the controller "
                     f"rate or sense fewer channels")


def analog_pin(channel: int) -> int:
    """The digital pin number of analog input A<channel> (A0 = D54)."""
    return 54 + channel


def cycles(seconds: float, f_cpu: float = F_CPU) -> int:
    """Whole CPU cycles in ``seconds`` (rounded to the nearest)."""
    return int(math.floor(seconds * f_cpu + 0.5))


def timer1_prescaler(period_cycles: int) -> int | None:
    """The smallest Timer1 prescaler N with ``period_cycles`` = N (1 + OCR1A), OCR1A in
    0..65535 (CTC mode, Sec. 17.9.2); None if there is none."""
    for n in TIMER1_PRESCALERS:
        if period_cycles % n == 0 and 1 <= period_cycles // n <= TIMER1_TOP + 1:
            return n
    return None


def period_cycles(rate: float, f_cpu: int = F_CPU) -> int:
    """The controller period [CPU cycles] of ``rate`` [Hz]: f_cpu / rate exactly, in rational
    arithmetic on the rate as written (the decimal a float holds, to a millionth), never rounded.
    ValueError if that is no whole number of cycles, or a whole number Timer1 cannot make
    (:func:`timer1_prescaler`)."""
    from fractions import Fraction
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"a rate of {rate} Hz")
    ratio = Fraction(f_cpu) / Fraction(rate).limit_denominator(10**6)
    clock = f"{f_cpu / 1e6:g}e6"
    if ratio.denominator != 1:
        raise ValueError(f"{clock}/rate must be a whole number of CPU cycles: {rate_text(rate)} gives "
                         f"{float(ratio):.2f}".rstrip("0").rstrip("."))
    cycles = ratio.numerator
    if timer1_prescaler(cycles) is None:
        raise ValueError(f"{clock}/rate = {cycles} CPU cycles, which Timer1 cannot count: N (1 + OCR1A) with N "
                         f"{', '.join(map(str, TIMER1_PRESCALERS))} and OCR1A at most {TIMER1_TOP}")
    return cycles


def rate_text(rate: float) -> str:
    """A rate as a scenario writes it: "3 kHz", "7 Hz"."""
    return f"{rate / 1000:g} kHz" if rate >= 1000 else f"{rate:g} Hz"


def adc_count(volts: float, vref: float, bits: int = 10) -> int:
    """The single-ended conversion result of an input of ``volts`` [V] against the reference
    ``vref`` [V] (datasheet Sec. 26.7: ADC = V_IN 1024 / V_REF, truncated, clipped to 0..1023);
    with 8 bits (the left-adjusted high byte ADCH) the 10-bit result shifted right by two.

    >>> adc_count(0.5, 5.0), adc_count(4.5, 5.0), adc_count(5.0, 5.0)
    (102, 921, 1023)
    """
    x = math.floor(volts * 1024.0 / vref)
    x = min(max(x, 0), 1023)
    return x >> (10 - bits)
