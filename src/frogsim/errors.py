"""Errors frogsim raises on purpose, each with a message a user can act on."""
from __future__ import annotations


UNKNOWN = "(unknown key)"     # value placeholder for a key that is not a setting
MISSING = "(missing)"         # value placeholder for a required setting that is absent


class Shown(str):
    """A value already formatted for a reader (e.g. "6.2 bar" from an SI value): shown unquoted."""


class FrogsimError(Exception):
    """Base class of frogsim's own errors."""


class ScenarioError(FrogsimError, ValueError):
    """A scenario or parameter value that cannot be used: names the field, the value, what is allowed."""

    def __init__(self, field: str, value, allowed: str):
        self.field = field
        self.value = value
        self.allowed = allowed
        if isinstance(value, str) and value in (UNKNOWN, MISSING):
            super().__init__(f"{field}: {allowed}")
            return
        plain = isinstance(value, Shown) or (isinstance(value, (int, float)) and not isinstance(value, bool))
        shown = value if plain else repr(value)
        super().__init__(f"{field} = {shown}: {allowed}")


    def __reduce__(self):
        # rebuilt from its three parts when it crosses a process boundary (study workers, Dask)
        return (type(self), (self.field, self.value, self.allowed))


class SimulationError(FrogsimError, RuntimeError):
    """The integration could not continue (non-finite state, step-size underflow)."""
