"""The loader's registry of valve types: the loader finds the ``[valves]`` section's settings class
here by its ``type``, so the scenario layer never imports the circuit layer's valve family.

Each valve type is one module of :mod:`frogsim.circuit.valves` (docs/architecture.md, "Adding a
valve type"); it declares ``VALVE = ValveType(...)`` with a frozen dataclass of its settings
derived from :class:`ValveSettings`, and the family's registry puts that class into
:data:`TYPES` (:func:`register`). Importing :mod:`frogsim.circuit.valves` (``import frogsim``
does) registers every shipped type.

A ``[valves]`` section without ``type`` is the paper's switching valves (:data:`DEFAULT`, written
out in every shipped parameter set's docs); a ``type`` no module declares is refused with the
types there are, never replaced by a default.

What every valve type's settings give the rest of frogsim (the engines, the controllers' dead-time
queue, the stiffness hint, the sliding-mode law's rate tables):

* ``charge`` and ``discharge``: the path from the source into a muscle and from the muscle to the
  exhaust, each as an ISO 6358 description of the path fully open (``sonic_conductance``,
  ``critical_ratio``, ``subsonic_index``, ``laminar_ratio``) and its ``dead_time`` [s] (the delay
  from a command to the valve's response).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from frogsim.errors import ScenarioError
from frogsim.scenario.fields import build, register_settings, unwrap

#: the type of a [valves] section that names none: the paper's switching valves
DEFAULT = "switching"
#: type name -> its settings class (filled by :func:`register`)
TYPES: dict[str, type] = {}


def register(cls):
    """Make ``cls`` (a :class:`ValveSettings` dataclass) the settings of valve type ``cls.TYPE``;
    ImportError when another class holds the name, naming both modules."""
    register_settings(TYPES, cls, cls.TYPE, "valve types", "type name", "valve type")
    return cls


@dataclass(frozen=True)
class ValveSettings:
    """What every valve type's settings class has (its own fields are those of its subclass)."""
    TYPE: ClassVar[str] = ""

    @property
    def type(self) -> str:
        return self.TYPE

    def check(self, path: str) -> None:
        """The type's cross-field checks; ScenarioError on the first one broken."""


def type_of(raw) -> str:
    """The valve type a raw ``[valves]`` table names (:data:`DEFAULT` when it names none)."""
    if isinstance(raw, dict) and "type" in raw:
        return unwrap(raw["type"])
    return DEFAULT


def from_raw(raw, path: str = "valves") -> ValveSettings:
    """The settings of the valve type ``raw["type"]`` names (every value checked: one-line
    ScenarioError naming the setting otherwise)."""
    if not isinstance(raw, dict):
        raise ScenarioError(path, raw, "expected a table of settings")
    name = type_of(raw)
    if name not in TYPES:
        raise ScenarioError(f"{path}.type", name, "must be one of " + ", ".join(repr(k) for k in TYPES)
                            if TYPES else "no valve type is registered: import frogsim first")
    cls = TYPES[name]
    table = {k: v for k, v in raw.items() if k != "type"}
    return build(cls, table, path)
