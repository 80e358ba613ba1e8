"""The loader's registry of actuator types: a ``[muscle_types.NAME]`` table's settings class is
found here by its ``actuator`` key, so the scenario layer never imports the circuit layer's
actuator family (:mod:`frogsim.circuit.actuators`).

Each actuator type is one module of :mod:`frogsim.circuit.actuators` (docs/architecture.md,
"Adding an actuator type"); it declares ``ACTUATOR = ActuatorType(...)`` with a frozen dataclass
of its settings derived from :class:`ActuatorSettings`, and the family's registry puts that class
into :data:`TYPES` (:func:`register`). Importing :mod:`frogsim.circuit.actuators` (``import
frogsim`` does) registers every shipped type.

A muscle type without ``actuator`` is the paper's braided McKibben muscle (:data:`DEFAULT`,
:class:`frogsim.scenario.schema.MuscleType`); an ``actuator`` no module declares is refused with
the types there are, never replaced by the default.

What every actuator type's settings give the rest of frogsim (the motions, the crank mounting,
the engines): the fields of :class:`frogsim.scenario.schema.MuscleType` other than its braid
(``nominal_length`` the rest length, ``max_contraction``, ``stroke_contraction``,
``dead_volume``, the crank's ``crank_radius``, ``anchor_distance``, ``rest_angle``, ``side``, and
``heat_transfer_coefficient``); a new type derives its settings from ``MuscleType`` or gives the
same fields.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from frogsim.errors import ScenarioError
from frogsim.scenario.fields import build, register_settings, unwrap

#: the type of a muscle type that names none: the paper's braided (McKibben) muscle
DEFAULT = "mckibben"
#: the key of a [muscle_types.NAME] table that names its actuator type
KEY = "actuator"
#: type name -> its settings class (filled by :func:`register`)
TYPES: dict[str, type] = {}


def register(cls):
    """Make ``cls`` (an :class:`ActuatorSettings` dataclass) the settings of actuator type
    ``cls.TYPE``; ImportError when another class holds the name, naming both modules."""
    register_settings(TYPES, cls, cls.TYPE, "actuator types", "type name", "actuator type")
    return cls


@dataclass(frozen=True)
class ActuatorSettings:
    """What every actuator type's settings class has: its name (``TYPE``) and its checks."""
    TYPE: ClassVar[str] = ""

    @property
    def actuator(self) -> str:
        return self.TYPE

    def check(self, path: str) -> None:
        """The type's cross-field checks; ScenarioError on the first one broken."""

    def volume(self, L: float) -> float:
        """The air volume [m^3] inside the actuator at length L [m] (without dead volume), for the
        scenario layer's own sums (a muscle held at a constant volume); the engines call the
        type's compiled ``volume`` (:mod:`frogsim.circuit.actuators`), which must agree."""
        raise NotImplementedError(f"actuator type {self.TYPE!r} gives no volume")


def from_raw(raw, path: str) -> ActuatorSettings:
    """The settings of the actuator type ``raw["actuator"]`` names (the default when it names
    none), every value checked (one-line ScenarioError naming the setting otherwise)."""
    if not isinstance(raw, dict):
        raise ScenarioError(path, raw, "expected a table of settings")
    name = unwrap(raw[KEY]) if KEY in raw else DEFAULT
    if name not in TYPES:
        raise ScenarioError(f"{path}.{KEY}", name, "must be one of " + ", ".join(repr(k) for k in TYPES)
                            if TYPES else "no actuator type is registered: import frogsim first")
    return build(TYPES[name], {k: v for k, v in raw.items() if k != KEY}, path)
