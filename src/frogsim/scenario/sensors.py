"""The loader's registry of sensor types: the settings classes of the sensors the firmware reads
(``[firmware] transducer``, ``angle_sensor``, ``angle_encoder``), so that the scenario layer never
imports the circuit layer's sensor family (:mod:`frogsim.circuit.sensors`).

Each sensor type is one module of :mod:`frogsim.circuit.sensors` (docs/architecture.md, "Adding a
sensor type"); it declares ``SENSOR = SensorType(...)`` with a frozen dataclass of its settings
derived from :class:`SensorSettings`, and the family's registry puts that class into
:data:`TYPES` (:func:`register`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

#: type name -> its settings class (filled by :func:`register`)
TYPES: dict[str, type] = {}


def register(cls):
    """Make ``cls`` (a :class:`SensorSettings` dataclass) the settings of sensor type ``cls.TYPE``;
    ImportError when another class holds the name, naming both modules."""
    other = TYPES.get(cls.TYPE)
    if other is not None and other is not cls:
        raise ImportError(f"sensor types: type name {cls.TYPE!r} of {cls.__module__} is already taken by "
                          f"{other.__module__}: each sensor type needs its own name")
    TYPES[cls.TYPE] = cls
    return cls


@dataclass(frozen=True)
class SensorSettings:
    """What every sensor type's settings class has: its name (``TYPE``) and what it measures
    (``QUANTITY``: "pressure", a muscle's gauge pressure [Pa], or "angle", a joint's angle [rad])."""
    TYPE: ClassVar[str] = ""
    QUANTITY: ClassVar[str] = ""
