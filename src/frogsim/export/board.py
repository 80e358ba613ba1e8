"""The Arduino Mega 2560 the robot's valves run from (paper, Sec. 4: "The switch valves are
controlled by the control card (Arduino Mega 2560)"): the facts a firmware design is checked
against, and the ATmega2560's ADC conversion timing. The part's own facts (memories, pins, the
ADC's timing and transfer function) live in :mod:`frogsim.components.atmega2560`, where the
scenario and control layers read them; they are re-exported here, beside the pin map read from
the installed Arduino core.

Sources:

* Atmel, *ATmega640/V-1280/V-1281/V-2560/V-2561/V* datasheet (2549Q-AVR-02/2014), Sec. 26.4
  "Prescaling and Conversion Timing" and Table 26-1: "A normal conversion takes 13 ADC clock
  cycles. The first conversion after the ADC is switched on (ADEN in ADCSRA is set) takes 25 ADC
  clock cycles"; auto-triggered conversions 13.5; "the successive approximation circuitry requires
  an input clock frequency between 50 kHz and 200 kHz to get maximum resolution. If a lower
  resolution than 10 bits is needed, the input clock frequency to the ADC can be higher than 200
  kHz"; the ADC prescaler divides the CPU clock by 2, 4, 8, 16, 32, 64 or 128 (ADPS2:0).
* Atmel's ADC documentation for the megaAVR ADC ("ADC Clock and Conversion Timing"): "it is not
  recommended to use an ADC clock with a frequency higher than 1 MHz. At 1 MHz we can expect
  maximum 8 bits of resolution."
* Arduino Mega 2560 Rev3: ATmega2560 at 16 MHz, 256 KB flash of which 8 KB are used by the
  bootloader, 8 KB SRAM, 54 digital pins and 16 analog inputs (A0-A15 = digital pins 54-69);
  pins 0 and 1 carry USART0 (the USB serial port). The pin-to-port map is read from the installed
  Arduino AVR core's ``variants/mega/pins_arduino.h`` (:func:`pin_map`), not written here.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from frogsim.components.atmega2560 import (  # noqa: F401  (the part's facts, re-exported)
    ADC_CYCLES, ADC_CYCLES_FIRST, ADC_FULL_RESOLUTION_HZ, ADC_MAX_CLOCK_HZ, ADC_PRESCALERS, ANALOG_INPUTS,
    BOOTLOADER_BYTES, DIGITAL_PINS, F_CPU, FLASH_BYTES, INTERRUPT_PINS, SERIAL_PINS, SRAM_BYTES, AdcPlan,
    adc_bits, adc_count, analog_pin, conversion_time, cycles, plan_adc)

ARDUINO_CORE = Path("/usr/share/arduino/hardware/arduino/avr")     # Debian's arduino-core-avr


@dataclass(frozen=True)
class Pin:
    """A digital pin's place on the chip: port letter ('A'..'L') and bit (0..7)."""
    number: int
    port: str
    bit: int


def _variant_file() -> Path:
    return ARDUINO_CORE / "variants" / "mega" / "pins_arduino.h"


@lru_cache(maxsize=1)
def pin_map() -> dict:
    """Digital pin number -> :class:`Pin`, read from the Arduino AVR core's Mega variant
    (``digital_pin_to_port_PGM`` and ``digital_pin_to_bit_mask_PGM`` in pins_arduino.h), the
    table the Arduino core's own digitalWrite uses. FileNotFoundError if the core is missing."""
    text = _variant_file().read_text()

    def table(name: str) -> list:
        body = re.search(name + r"\[\]\s*=\s*\{(.*?)\};", text, re.S).group(1)
        body = re.sub(r"//[^\n]*", "", body)
        return [x.strip() for x in body.split(",") if x.strip()]
    ports = table("digital_pin_to_port_PGM")
    masks = table("digital_pin_to_bit_mask_PGM")
    out = {}
    for k, (p, m) in enumerate(zip(ports, masks)):
        port = re.fullmatch(r"P([A-L])", p)
        bit = re.fullmatch(r"_BV\(\s*(\d)\s*\)", m)
        if port and bit:
            out[k] = Pin(k, port.group(1), int(bit.group(1)))
    return out

