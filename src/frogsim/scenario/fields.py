"""Build frozen dataclasses from nested dicts (parsed TOML), validating every value.

Each dataclass field carries metadata: the kind of quantity (see :data:`frogsim.scenario.units.SI_UNITS`),
bounds in SI, a display unit for messages, allowed choices, and an optional default. Errors name the
dotted path of the field, the value as written and what is allowed; unknown keys get a "did you
mean". A value may be written plain ("4 L") or with its source ({ value = "4 L", source = "..." }).
"""
from __future__ import annotations

import dataclasses
import difflib
import functools
import math
import operator
import types
import typing

import numpy as np
from dataclasses import MISSING as NO_FIELD_DEFAULT, field

from frogsim.errors import MISSING, UNKNOWN, ScenarioError, Shown
from frogsim.scenario.units import display_factor, to_si

_NO_DEFAULT = object()


def _field(meta: dict, default):
    meta["default"] = default
    if default is _NO_DEFAULT:
        return field(metadata=meta)
    return field(default=default, metadata=meta)


def quantity(kind: str, *, gt=None, ge=None, lt=None, le=None, display: str | None = None,
             default=_NO_DEFAULT, doc: str = "", **extra):
    """A float field holding an SI value of the given kind, with bounds (SI) and a display unit."""
    return _field(dict(kind=kind, gt=gt, ge=ge, lt=lt, le=le, display=display, doc=doc, **extra), default)


def choice(options: tuple, *, default=_NO_DEFAULT, doc: str = "", **extra):
    """A field whose value must be one of options."""
    return _field(dict(choices=options, doc=doc, **extra), default)


def integer(*, ge=None, le=None, default=_NO_DEFAULT, doc: str = "", **extra):
    """An integer field with bounds."""
    return _field(dict(integer=True, ge=ge, le=le, doc=doc, **extra), default)


def flag(*, default=_NO_DEFAULT, doc: str = "", **extra):
    """A boolean field."""
    return _field(dict(boolean=True, doc=doc, **extra), default)


def unwrap(value):
    """Take the value out of a { value = ..., source = ... } table; leave other values alone."""
    if isinstance(value, dict) and "value" in value and set(value) <= {"value", "source", "note"}:
        return value["value"]
    return value


def _fmt_bound(x: float, meta: dict) -> str:
    disp = meta.get("display")
    kind = meta.get("kind")
    if disp and kind:
        return f"{x / display_factor(disp, kind):g} {disp}"
    return f"{x:g}"


_BOUNDS = (("gt", operator.gt, ">"), ("ge", operator.ge, ">="), ("lt", operator.lt, "<"), ("le", operator.le, "<="))


def _allowed_range(meta: dict) -> str:
    """" (allowed: 150 K to 1000 K)" for a field bounded on both sides ("" otherwise); an open end
    is marked ("above 0 Hz, up to 76923.1 Hz")."""
    lo = next((k for k in ("gt", "ge") if meta.get(k) is not None), None)
    hi = next((k for k in ("lt", "le") if meta.get(k) is not None), None)
    if lo is None or hi is None:
        return ""
    a, b = _fmt_bound(meta[lo], meta), _fmt_bound(meta[hi], meta)
    if lo == "ge" and hi == "le":
        return f" (allowed: {a} to {b})"
    return f" (allowed: {'above' if lo == 'gt' else 'from'} {a}, {'up to' if hi == 'le' else 'below'} {b})"


def check_bounds(x: float, meta: dict, path: str, raw) -> None:
    """Raise ScenarioError unless x lies within the metadata bounds. ``raw`` is the value shown in
    the message (a callable is called for it, only when the check fails). A field bounded on both
    sides names its whole range, and one whose metadata has a ``why`` says it."""
    for key, ok, word in _BOUNDS:
        bound = meta.get(key)
        if bound is not None and not ok(x, bound):
            why = f": {meta['why']}" if meta.get("why") else ""
            raise ScenarioError(path, raw() if callable(raw) else raw,
                                f"must be {word} {_fmt_bound(bound, meta)}{_allowed_range(meta)}{why}")


def parse_field(raw, meta: dict, path: str):
    """Validate and convert one raw value according to its field metadata."""
    raw = unwrap(raw)
    if meta.get("boolean"):
        if not isinstance(raw, bool):
            raise ScenarioError(path, raw, "expected true or false")
        return raw
    if "choices" in meta:
        if raw not in meta["choices"]:
            allowed = ", ".join(repr(c) for c in meta["choices"])
            raise ScenarioError(path, raw, f"must be one of {allowed}")
        return raw
    if meta.get("integer"):
        if isinstance(raw, bool) or not isinstance(raw, int):
            raise ScenarioError(path, raw, "expected a whole number")
        check_bounds(raw, meta, path, raw)
        return raw
    kind = meta["kind"]
    x = to_si(raw, kind, path)
    if x != x or x in (float("inf"), float("-inf")):
        raise ScenarioError(path, raw, "must be a finite number")
    check_bounds(x, meta, path, raw)
    return x


def check_value(value, meta: dict, path: str):
    """Validate an SI value (no unit text) for a field with this metadata; return it as stored.

    The typed twin of :func:`parse_field`: the same bounds and choices, the same messages, for
    values that are already numbers in SI (a variant, a sweep point, a fit iterate).
    """
    if meta.get("boolean"):
        if not isinstance(value, (bool, np.bool_)):
            raise ScenarioError(path, value, "expected true or false")
        return bool(value)
    if "choices" in meta:
        if value not in meta["choices"]:
            raise ScenarioError(path, value, f"must be one of {', '.join(repr(c) for c in meta['choices'])}")
        return value
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ScenarioError(path, value, "expected a number in SI units (no unit text past the loader)")
    if meta.get("integer"):
        if int(value) != value:
            raise ScenarioError(path, value, "expected a whole number")
        value = int(value)
        check_bounds(value, meta, path, value)
        return value
    x = float(value)
    if not math.isfinite(x):
        raise ScenarioError(path, value, "must be a finite number")
    check_bounds(x, meta, path, lambda: shown(x, meta))
    return x


def shown(x: float, meta: dict) -> str:
    """An SI value as a user reads it in messages: in the field's display unit."""
    disp, kind = meta.get("display"), meta.get("kind")
    if disp and kind:
        return Shown(f"{x / display_factor(disp, kind):g} {disp}")
    return Shown(f"{x:g}")


def unknown_key_error(path: str, key: str, known) -> ScenarioError:
    """ScenarioError for a key that is not a field, with the closest known names."""
    where = f"{path}.{key}" if path else key
    close = difflib.get_close_matches(key, list(known), n=2)
    hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    allowed = ", ".join(sorted(known))
    return ScenarioError(where, UNKNOWN, f"unknown setting{hint} (known here: {allowed})")


@functools.lru_cache(maxsize=None)
def _type_hints(cls) -> dict:
    """typing.get_type_hints, once per class (it re-evaluates the string annotations on every call,
    which was 40 % of loading a scenario; sweeps validate thousands)."""
    return typing.get_type_hints(cls)


def build(cls, raw, path: str = ""):
    """Build dataclass cls from the dict raw, validating every field (see module docstring)."""
    if not isinstance(raw, dict):
        raise ScenarioError(path or cls.__name__, raw, f"expected a table of {cls.__name__} settings")
    hints = _type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init and not f.name.startswith("_")}
    for key in raw:
        if key not in fields:
            raise unknown_key_error(path, key, fields)
    values = {}
    for name, f in fields.items():
        sub = f"{path}.{name}" if path else name
        hint = hints[name]
        if name not in raw:
            default = f.metadata.get("default", _NO_DEFAULT) if f.metadata else _NO_DEFAULT
            if default is not _NO_DEFAULT:
                values[name] = default
                continue
            if f.default is not NO_FIELD_DEFAULT or f.default_factory is not NO_FIELD_DEFAULT:
                continue
            if typing.get_origin(hint) is typing.Union and type(None) in typing.get_args(hint):
                values[name] = None
                continue
            raise ScenarioError(sub, MISSING, "required setting is missing")
        values[name] = build_value(hint, raw[name], f.metadata, sub)
    return cls(**values)


def build_value(hint, raw, meta, path):
    """Build one value of the type hint: a dataclass, dict[str, dataclass], optional or a leaf."""
    origin = typing.get_origin(hint)
    if origin is typing.Union or origin is types.UnionType:      # Optional[X], X | None
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        return build_value(args[0], raw, meta, path)
    if dataclasses.is_dataclass(hint):
        if hasattr(hint, "from_raw"):
            return hint.from_raw(unwrap(raw), path)
        return build(hint, unwrap(raw), path)
    if origin is dict:
        _, vtype = typing.get_args(hint)
        if not isinstance(raw, dict):
            raise ScenarioError(path, raw, "expected a table of named entries")
        return {str(k): build_value(vtype, v, meta, f"{path}.{k}") for k, v in raw.items()}
    if hint is str and not meta:
        raw = unwrap(raw)
        if not isinstance(raw, str):
            raise ScenarioError(path, raw, "expected text")
        return raw
    return parse_field(raw, meta, path)


def register_settings(table: dict, cls, name: str, family: str, what: str, each: str):
    """Put the settings class ``cls`` of a family member into ``table`` under its ``name`` (the
    loader's registry of one family: kinds, methods, valve, actuator and sensor types); ImportError
    "``family``: ``what`` 'name' of <module> is already taken by <module>: each ``each`` needs its
    own name" when another class holds the name. Returns cls."""
    other = table.get(name)
    if other is not None and other is not cls:
        raise ImportError(f"{family}: {what} {name!r} of {cls.__module__} is already taken by "
                          f"{other.__module__}: each {each} needs its own name")
    table[name] = cls
    return cls
