"""The declaration every sensor type's module ends with: ``SENSOR = SensorType(...)``, and the
compiled arithmetic of a linear sensor on the board's ADC, which the shipped types share."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable

from frogsim._jit import jit, jit_inner


@jit
def line_count(v0, k, q0, full, vref, q):
    """The ATmega2560's count of a reading q (a gauge pressure [Pa] or an angle [rad]) of a linear
    sensor: its voltage V = v0 + k (q - q0) [V], then the datasheet's single-ended conversion
    ADC = V full / V_REF (full = 2^bits), truncated and clipped to 0..full - 1
    (:func:`frogsim.components.atmega2560.adc_count` for one voltage)."""
    x = math.floor((v0 + k * (q - q0)) * full / vref)
    return int(min(max(x, 0.0), full - 1.0))


@jit
def line_value(v0, k, q0, full, vref, count):
    """The reading [Pa gauge or rad] in the middle of a count (the inverse of :func:`line_count`
    at count + 1/2)."""
    return q0 + ((count + 0.5) * vref / full - v0) / k


@jit_inner
def linear_count(v0, k, q0, full, vref, q):
    """:func:`line_count` as a type's ``count``: a copy inlined into the family's compiled dispatch
    (the shipped types' integer form)."""
    return line_count(v0, k, q0, full, vref, q)


@jit_inner
def linear_value(v0, k, q0, full, vref, c):
    """:func:`line_value` as a type's ``value``, inlined as :func:`linear_count` is."""
    return line_value(v0, k, q0, full, vref, c)


@dataclass(frozen=True)
class SensorType:
    """What the rest of frogsim reads of a sensor type (docs/architecture.md, "Adding a sensor
    type").

    * ``settings``: its settings class (a frozen dataclass derived from
      :class:`frogsim.scenario.sensors.SensorSettings`: ``TYPE`` its name, ``QUANTITY`` what it
      reads of the plant, "pressure" (a muscle's gauge pressure, from the state y) or "angle" (a
      joint's angle, from MuJoCo's qpos or the observation the coupled kernel writes));
    * ``code``: its value in a row's sensor-code column (``L_ADC_CODE``, ``L_AADC_CODE`` of
      :mod:`frogsim.control.table`; a float > 0, unique);
    * ``line(settings, vref, adc_full) -> ((v0, k, q0), full)``: its parameter block, the line
      V = v0 + k (q - q0) [V] and the count's range ``full`` (the ADC's 2^bits ``adc_full``, or
      the type's own counter), written into the row's L_ADC_* / L_AADC_* columns;
    * ``faults(settings, vref, adc_full) -> (lo, hi) | None``: the counts outside which a reading
      is a sensor fault (None: the type's counts cannot show one);
    * ``count(v0, k, q0, full, vref, q) -> int`` (compiled): the reading q's integer form, the
      count the firmware reads;
    * ``value(v0, k, q0, full, vref, count) -> q`` (compiled): the reading a count stands for (its
      middle), what the model reports as sensed.
    """
    settings: type
    code: float
    line: Callable
    faults: Callable
    count: Callable
    value: Callable
    module: str = ""

    @property
    def name(self) -> str:
        return self.settings.TYPE

    @property
    def quantity(self) -> str:
        return self.settings.QUANTITY

    def registered(self, module: str) -> "SensorType":
        return replace(self, module=module)
