"""The Arduino Mega 2560 the robot's valves run from (paper, Sec. 4: "The switch valves are
controlled by the control card (Arduino Mega 2560)"): the facts a firmware design is checked
against, and the ATmega2560's ADC conversion timing. The part's own facts (memories, pins, the
ADC's timing and transfer function) live in :mod:`frogsim.components.atmega2560`, where the
scenario and control layers read them; they are re-exported here, beside the pin map read from
the installed Arduino core.

Sources (the datasheet's ADC timing is quoted in :mod:`frogsim.components.atmega2560`):

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

