"""The loader's registry of sensor types: the settings classes of the sensors the firmware reads
(``[firmware] transducer``, ``angle_sensor``, ``angle_encoder``), so that the scenario layer never
imports the circuit layer's sensor family (:mod:`frogsim.circuit.sensors`). A sensor's table names
its type (``transducer = { type = "transducer", ... }``; without ``type`` the key's shipped one),
and :func:`from_raw` builds that type's settings: a type no module declares, or one that reads
another quantity, is refused with the types there are.

Each sensor type is one module of :mod:`frogsim.circuit.sensors` (docs/architecture.md, "Adding a
sensor type"); it declares ``SENSOR = SensorType(...)`` with a frozen dataclass of its settings
derived from :class:`SensorSettings`, and the family's registry puts that class into
:data:`TYPES` (:func:`register`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from frogsim.errors import ScenarioError
from frogsim.scenario.fields import build, register_settings, unwrap

#: type name -> its settings class (filled by :func:`register`)
TYPES: dict[str, type] = {}


def register(cls):
    """Make ``cls`` (a :class:`SensorSettings` dataclass) the settings of sensor type ``cls.TYPE``;
    ImportError when another class holds the name, naming both modules."""
    register_settings(TYPES, cls, cls.TYPE, "sensor types", "type name", "sensor type")
    return cls


@dataclass(frozen=True)
class SensorSettings:
    """What every sensor type's settings class has: its name (``TYPE``) and what it measures
    (``QUANTITY``: "pressure", a muscle's gauge pressure [Pa], or "angle", a joint's angle [rad])."""
    TYPE: ClassVar[str] = ""
    QUANTITY: ClassVar[str] = ""
    #: how the board reads it: "adc" (on an analog input, through the ADC) or "counter" (a
    #: quadrature encoder's pins, counted by the firmware's interrupts)
    CHANNEL: ClassVar[str] = "adc"

    def measured_range(self) -> tuple:
        """(lo, hi): the readings [Pa gauge or rad] over which the sensor's output is its line
        (beyond them it saturates; a setpoint must lie within them). Unbounded by default."""
        return -math.inf, math.inf

    def check(self, path: str, vref: float) -> None:
        """The type's own checks of its settings on an ADC of reference ``vref`` [V]; a one-line
        ScenarioError naming the setting (``path.field``) on the first one broken."""


def from_raw(raw, path: str, quantity: str, default: str) -> SensorSettings:
    """The settings of the sensor type ``raw["type"]`` names (``default`` when it names none), a
    type that reads ``quantity`` ("pressure" or "angle"); every value checked (one-line
    ScenarioError naming the setting otherwise)."""
    raw = unwrap(raw)
    if not isinstance(raw, dict):
        raise ScenarioError(path, raw, "expected a table of the sensor's settings, e.g. { type = "
                                       f"{default!r}, ... }}")
    name = unwrap(raw.get("type", default))
    fits = [k for k, cls in TYPES.items() if cls.QUANTITY == quantity]
    if name not in TYPES:
        raise ScenarioError(f"{path}.type", name, f"must be one of the sensor types that read {quantity}: "
                            + (", ".join(repr(k) for k in fits) or "none is registered (import frogsim first)"))
    cls = TYPES[name]
    if cls.QUANTITY != quantity:
        raise ScenarioError(f"{path}.type", name, f"reads {cls.QUANTITY}; {path} is a sensor that reads {quantity}: "
                            + ", ".join(repr(k) for k in fits))
    return build(cls, {k: v for k, v in raw.items() if k != "type"}, path)
