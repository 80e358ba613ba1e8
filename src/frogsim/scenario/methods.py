"""The loader's registry of integration methods: ``[solver] method = "..."`` finds the method's
settings class here by its name, so the scenario layer never imports :mod:`frogsim.engine`.

Each method is one module of :mod:`frogsim.engine.methods` (docs/architecture.md, "Adding an
integration method"); it defines a frozen dataclass of its settings, derived from
:class:`MethodSettings`, and declares the method (``METHOD = IntegrationMethod(...)``); the
methods' registry finds every such module and puts its settings class here (:func:`register`).
Importing :mod:`frogsim.engine.methods` (``import frogsim`` does) registers every shipped method.

In a file the method is written by name, with its defaults, or as a table with its settings::

    [solver]
    method = "rk4"                                   # the method's defaults
    method = { name = "rk4", step = "0.25 ms" }      # or with its settings

and its settings are variable paths (``solver.method.step``) like every other setting.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

from frogsim.errors import ScenarioError
from frogsim.scenario.fields import build, register_settings, unwrap

#: method name -> its settings class (filled by :func:`register`, in the registry's order)
METHODS: dict[str, type] = {}
#: the name of the method a scenario without ``method`` runs (the registry sets it)
DEFAULT: list[str] = []


def register(cls, default: bool = False):
    """Make ``cls`` (a :class:`MethodSettings` dataclass) the settings of method ``cls.METHOD``
    (the methods' registry calls this for each method it finds; ``default`` for the one a scenario
    without ``method`` runs); ImportError when another class already holds the name."""
    register_settings(METHODS, cls, cls.METHOD, "integration methods", "method name", "method")
    if default:
        DEFAULT[:] = [cls.METHOD]
    return cls


def default_settings() -> "MethodSettings":
    """The default method's settings, with their defaults."""
    if not DEFAULT:
        raise RuntimeError("no integration method registered: import frogsim.engine.methods first")
    return METHODS[DEFAULT[0]]()


@dataclass(frozen=True)
class MethodSettings:
    """What every integration method's settings class has: its name (``METHOD``) and the
    protocol. A method's own settings are the fields of its subclass, each with its unit kind,
    bounds and display unit (:func:`frogsim.scenario.fields.quantity`)."""
    METHOD: ClassVar[str] = ""

    @property
    def name(self) -> str:
        return self.METHOD

    def params(self) -> tuple:
        """The method's parameter block: the floats its compiled functions read (SI), in the
        order they read them (none for a method without settings)."""
        return ()

    def check(self, sc, path: str) -> None:
        """The method's cross-field checks on scenario ``sc`` (``path``: "solver.method");
        ScenarioError naming the setting, its value and what is allowed."""

    @classmethod
    def from_raw(cls, raw, path: str) -> "MethodSettings":
        """The settings of the method ``raw`` names: a name ("rk4") or a table with ``name`` and
        the method's settings; one-line ScenarioError naming the setting otherwise (an unknown
        name is refused, never replaced by the default)."""
        raw = unwrap(raw)
        if isinstance(raw, str):
            name, table = raw, {}
        elif isinstance(raw, dict) and "name" in raw:
            name, table = unwrap(raw["name"]), {k: v for k, v in raw.items() if k != "name"}
        else:
            raise ScenarioError(path, raw, f"expected a method's name ({_names()}) or a table with name = "
                                           "one of them and its settings")
        if name not in METHODS:
            where = path if isinstance(raw, str) else f"{path}.name"
            raise ScenarioError(where, name, f"must be one of {_names()}")
        return build(METHODS[name], table, path)


def _names() -> str:
    return ", ".join(repr(n) for n in METHODS)


def settings_fields(cls) -> dict:
    """{name: field} of the settings a file may write for method class ``cls``."""
    return {f.name: f for f in dataclasses.fields(cls) if f.init}
