"""The loader's registry of controller kinds: the loader finds a ``[controllers.NAME]`` section's
settings class here by its ``kind``, so the scenario layer never imports :mod:`frogsim.control`.

Each kind is one module of :mod:`frogsim.control.kinds` (docs/architecture.md, "Adding a
controller kind"); it defines a frozen dataclass of its settings, derived from
:class:`ControllerSettings`, and declares the kind (``KIND = ControllerKind(...)``); the kinds'
registry (:mod:`frogsim.control.kinds`) finds every such module and puts its settings class into
:data:`KINDS` (:func:`register`). Importing :mod:`frogsim.control` (``import frogsim`` does)
registers every shipped kind.

The settings class of a kind holds, besides its fields (with their metadata: unit kind, bounds,
choices, read by the loader, :meth:`frogsim.scenario.core.Scenario.replace` and the sweeps):

* ``KIND`` (its name in files) and ``NAMED`` ("muscle", or "joint" for a kind that names a joint);
* ``setpoint``: what the controller tracks (None for a kind that tracks nothing), which the
  results read for their tracking metrics;
* :meth:`ControllerSettings.check`: its cross-field checks, run with every scenario rule;
* :meth:`ControllerSettings.write_rows`: its rows of the compiled table of laws.

The table of laws itself (its columns, the pump's row, the assembly) belongs to
:mod:`frogsim.control.table`, which registers its builder here (:func:`register_table`) for
:func:`frogsim.circuit.model.build_model` to call (:func:`build_table`).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

from frogsim.errors import MISSING, ScenarioError
from frogsim.scenario.fields import _type_hints, build_value, register_settings, unknown_key_error, unwrap

#: kind name -> its settings class (filled by :func:`register`)
KINDS: dict[str, type] = {}
_TABLE: list = []     # the table builder (frogsim.control.table.build_table), once registered


def register(cls):
    """Make ``cls`` (a :class:`ControllerSettings` dataclass) the settings of kind ``cls.KIND``
    (the kinds' registry, :mod:`frogsim.control.kinds`, calls this for each kind it finds);
    ImportError when another class already holds the name, naming both modules."""
    register_settings(KINDS, cls, cls.KIND, "controller kinds", "kind name", "kind")
    return cls


def register_table(builder) -> None:
    """Set the function that compiles a scenario's table of laws (see module docstring)."""
    _TABLE[:] = [builder]


def build_table(sc, g, names: tuple, volumes: tuple):
    """The compiled table of laws of scenario ``sc`` (the registered builder's)."""
    if not _TABLE:
        raise RuntimeError("no table builder registered: import frogsim.control first")
    return _TABLE[0](sc, g, names, volumes)


@dataclass(frozen=True)
class ControllerSettings:
    """What every controller kind's settings class has: the muscle it drives and the registry's
    protocol. A kind's own settings are the fields of its subclass (no flags, no shared fields it
    does not read)."""
    KIND: ClassVar[str] = ""
    NAMED: ClassVar[str] = "muscle"     # the setting that names what the controller drives
    #: True when the controller takes its muscles' valves (they then have no program)
    closed_loop: ClassVar[bool] = True
    muscle: str = ""

    @property
    def kind(self) -> str:
        return self.KIND

    @property
    def setpoint(self):
        """What the controller tracks (a :class:`frogsim.scenario.schema.Setpoint` or
        :class:`~frogsim.scenario.schema.AngleSetpoint`), or None: the results measure tracking
        against it. A kind with a setpoint declares it as a field of that name, which takes the
        place of this property; for the others (``program``, an open-loop ``pwm``) it is None."""
        return None

    def driven(self) -> tuple:
        """The muscles whose valves the controller commands."""
        return (self.muscle,)

    def sensed(self) -> tuple:
        """What the controller reads, as (quantity, name) pairs: ("pressure", muscle) for each
        muscle of a closed-loop controller; a kind that reads otherwise says so (an open-loop
        PWM reads nothing, a joint-angle controller also its joint's angle)."""
        return tuple(("pressure", m) for m in self.driven()) if self.closed_loop else ()

    def where(self, path: str) -> tuple:
        """(the setting that names what the controller drives, its value), for messages."""
        return f"{path}.{self.NAMED}", getattr(self, self.NAMED)

    def check_target(self, sc, path: str) -> None:
        """Checks on what the controller names, before its muscles are looked up (a joint-angle
        controller: its joint and pair)."""

    def check(self, sc, path: str, p_top: float) -> None:
        """The kind's cross-field checks on scenario ``sc`` (``p_top``: the highest source
        pressure [Pa gauge]); ScenarioError on the first one broken."""

    def write_rows(self, name: str, ctx) -> list:
        """The kind's rows of the table of laws (:mod:`frogsim.control.table`)."""
        raise NotImplementedError

    @classmethod
    def from_raw(cls, raw, path: str) -> "ControllerSettings":
        """The settings of the kind ``raw["kind"]`` names, every value checked (one-line
        ScenarioError naming the setting otherwise)."""
        if not isinstance(raw, dict) or "kind" not in raw:
            raise ScenarioError(path, raw, f"expected a table with kind = one of {', '.join(KINDS)}")
        kind = unwrap(raw["kind"])
        if kind not in KINDS:
            raise ScenarioError(f"{path}.kind", kind, f"must be one of {', '.join(repr(k) for k in KINDS)}")
        return KINDS[kind].parse(raw, path)

    @classmethod
    def settings(cls) -> dict:
        """{name: field} of the settings a file may write for this kind."""
        return {f.name: f for f in dataclasses.fields(cls) if f.init and f.name != "muscle"
                and not f.metadata.get("derived")}

    @classmethod
    def parse(cls, raw: dict, path: str) -> "ControllerSettings":
        """This kind's settings from a file's table (``kind`` already checked)."""
        fields = cls.settings()
        named = cls.NAMED
        allowed = set(fields) | {"kind", named}
        for key in raw:
            if key not in allowed:
                raise unknown_key_error(path, key, allowed)
        if named not in raw:
            raise ScenarioError(f"{path}.{named}", MISSING, "required setting is missing")
        what = unwrap(raw[named])
        if not isinstance(what, str) or not what:
            raise ScenarioError(f"{path}.{named}", what, f"expected the name of a {named}")
        hints = _type_hints(cls)
        kw = {named: what}
        for key, val in raw.items():
            if key in ("kind", named):
                continue
            kw[key] = cls.parse_value(key, val, hints[key], fields[key].metadata, f"{path}.{key}")
        return cls(**kw)

    @classmethod
    def parse_value(cls, key: str, raw, hint, meta, path: str):
        """One setting's value (a kind may refuse a form with its own message first)."""
        return build_value(hint, raw, meta, path)
