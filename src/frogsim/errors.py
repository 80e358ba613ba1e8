"""Errors frogsim raises on purpose, each with a message a user can act on."""
from __future__ import annotations

import os

import reprlib


UNKNOWN = "(unknown key)"     # value placeholder for a key that is not a setting
MISSING = "(missing)"         # value placeholder for a required setting that is absent


SHOWN_MAX = 80          # characters of a value shown in a message (longer values end in "…")
FIELD_MAX = 120         # characters of a field path shown in a message

_REPR = reprlib.Repr()
_REPR.maxlevel = 3      # nested lists/tables shown a few levels deep (never recursing without end)
_REPR.maxlist = _REPR.maxtuple = _REPR.maxset = 8
_REPR.maxdict = 4
_REPR.maxstring = _REPR.maxother = SHOWN_MAX + 2


def clip(text: str, limit: int = SHOWN_MAX) -> str:
    """text on one line (control characters escaped), at most ``limit`` characters ("…" at the end)."""
    if not text.isprintable():
        text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    return text if len(text) <= limit else text[:limit - 1] + "…"


def clip_path(text: str, limit: int = SHOWN_MAX) -> str:
    """A path on one line in at most ``limit`` characters: its end kept (the file's name, the
    part a reader needs), its middle cut ("…")."""
    text = clip(text, 10 * limit)
    if len(text) <= limit:
        return text
    head = limit // 4
    return text[:head] + "…" + text[len(text) - (limit - head - 1):]


def shown_value(value) -> str:
    """A value as a message shows it: numbers and Shown text plain, the rest as repr, clipped (a
    path in the middle, so that its file name stays)."""
    try:
        if isinstance(value, (str, os.PathLike)) and not isinstance(value, Shown) and (
                isinstance(value, os.PathLike) or os.sep in value) and len(repr(str(value))) > SHOWN_MAX:
            return clip_path(repr(str(value)))
        if isinstance(value, Shown):
            text = str(value)
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            text = str(value) if not isinstance(value, int) or value.bit_length() < 256 else \
                f"<a whole number of {value.bit_length()} bits>"
        elif isinstance(value, (str, bytes)):
            text = repr(value[:4 * SHOWN_MAX])
        else:
            text = _REPR.repr(value)
    except Exception:   # a value whose repr fails (or recurses without end) is shown by its type
        text = f"<{type(value).__name__}>"
    return clip(text)


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
        where = clip(str(field), FIELD_MAX)
        what = clip(str(allowed), 1000)
        if isinstance(value, str) and value in (UNKNOWN, MISSING):
            super().__init__(f"{where}: {what}")
            return
        super().__init__(f"{where} = {shown_value(value)}: {what}")


    def __reduce__(self):
        # rebuilt from its three parts when it crosses a process boundary (study workers, Dask)
        return (type(self), (self.field, self.value, self.allowed))


class SimulationError(FrogsimError, RuntimeError):
    """The integration could not continue (non-finite or non-physical state, step-size underflow,
    the wall-time limit): names the quantity, its value and the time."""
