"""Controller kinds, one module each, and their registry (docs/architecture.md, "Adding a
controller kind").

No list of kinds is kept by hand: every module of this package is imported here (pkgutil, in
the order of their file names) and a module that declares ``KIND = ControllerKind(...)``
(:mod:`frogsim.control.kinds.spec`) is a kind; the others (``common``, ``spec``) are helpers.
What the rest of frogsim reads comes from here: the loader's settings classes (registered with
:mod:`frogsim.scenario.kinds`), the compiled dispatch of the driver's sample and of the firmware
twins (:mod:`frogsim.control.sampled`, built from :func:`with_law` and :func:`with_twin`), the
firmware plan's twins and C (:mod:`frogsim.control.firmware`), the results' tracking metrics and
a search's tunable gains.

Checked at import, each failure an ImportError naming the modules: two kinds with one name or
one ``CODE``, a code the table reserves, a law without a code (or a code without a law), two
twins with one C name, a gain that is not a quantity setting of its kind or has an empty range,
a settings class without its ``KIND`` declaration. A kind lives in this package (not outside
it): the compiled code's cache is keyed on the files of :mod:`frogsim.control`
(:mod:`frogsim._jit`), so a new kind module starts a fresh cache and never meets the machine
code of a dispatch that did not know it.
"""
from __future__ import annotations

import dataclasses
import importlib
import math
import pkgutil
import re

from frogsim.control.kinds.spec import TRACKS, ControllerKind, _field_kind
from frogsim.control.table import KIND_EXTERNAL, KIND_PUMP_BAND
from frogsim.scenario import kinds as settings_registry
from frogsim.scenario.kinds import ControllerSettings

#: kind name -> its declaration, in the order of the modules' file names
KINDS: dict[str, ControllerKind] = {}
#: table code -> the kind writing rows with it
BY_CODE: dict[float, ControllerKind] = {}
#: codes of the table's kind column that are not a kind's (an empty row, the pump's band, a Python law)
RESERVED_CODES = {0.0: "an empty row", KIND_PUMP_BAND: "the pump's pressure band (KIND_PUMP_BAND)",
                  KIND_EXTERNAL: "a muscle driven from Python (KIND_EXTERNAL)"}
_C_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def _refuse(text: str):
    raise ImportError(f"controller kinds: {text}")


def _check(kind, module: str) -> None:
    """The declaration's own checks (module docstring); ImportError naming ``module``."""
    if not isinstance(kind, ControllerKind):
        _refuse(f"{module}.KIND is a {type(kind).__name__}, not a ControllerKind (frogsim.control.kinds.spec)")
    s = kind.settings
    if not (isinstance(s, type) and issubclass(s, ControllerSettings) and dataclasses.is_dataclass(s)):
        _refuse(f"{module}: settings {s!r} is not a dataclass derived from ControllerSettings")
    if not isinstance(s.KIND, str) or not s.KIND:
        _refuse(f"{module}: settings class {s.__name__} has no KIND (the kind's name in files)")
    if kind.code is None:
        if kind.law is not None:
            _refuse(f"{module}: kind {s.KIND!r} has a law but no code (its rows' value in the table's kind column)")
    else:
        if not isinstance(kind.code, float) or not math.isfinite(kind.code) or kind.code <= 0.0:
            _refuse(f"{module}: kind {s.KIND!r} has code {kind.code!r}: a code is a finite float > 0 "
                    "(its rows' value in the table's kind column)")
        if kind.code in RESERVED_CODES:
            _refuse(f"{module}: kind {s.KIND!r} has code {kind.code!r}, which the table reserves for "
                    f"{RESERVED_CODES[kind.code]} (frogsim.control.table)")
        if kind.law is None:
            _refuse(f"{module}: kind {s.KIND!r} has code {kind.code!r} but no law: the sample would have "
                    "nothing to run for its rows")
    if kind.firmware is not None and not _C_NAME.fullmatch(kind.firmware.c_name or ""):
        _refuse(f"{module}: kind {s.KIND!r}'s firmware twin has C name {kind.firmware.c_name!r}, not a C identifier")
    if kind.tracks is not None and kind.tracks not in TRACKS:
        _refuse(f"{module}: kind {s.KIND!r} tracks {kind.tracks!r}: one of {', '.join(TRACKS)}, or None")
    names = set()
    for g in kind.gains:
        where = f"{module}: kind {s.KIND!r}, gain {getattr(g, 'name', g)!r}"
        try:
            _field_kind(s, g.name)
        except (ValueError, AttributeError) as exc:
            _refuse(f"{where}: {exc}")
        if g.name in names:
            _refuse(f"{where}: declared twice")
        names.add(g.name)
        if not (math.isfinite(g.low) and math.isfinite(g.high) and g.low < g.high):
            _refuse(f"{where}: the range {g.low!r}..{g.high!r} {g.unit} must have low < high, both finite")
        if g.log and g.low <= 0.0:
            _refuse(f"{where}: a log-scale range must start above 0 (low = {g.low!r} {g.unit})")


def _orphan_settings(module) -> list:
    """The settings classes ``module`` defines (with a KIND) that no declaration of it names."""
    out = []
    for obj in vars(module).values():
        if (isinstance(obj, type) and issubclass(obj, ControllerSettings) and obj.__module__ == module.__name__
                and obj.KIND):
            out.append(obj)
    return out


def _register(kind: ControllerKind, module: str) -> ControllerKind:
    """Put ``kind`` (declared in ``module``) into the registry and its settings class into the
    loader's (:func:`frogsim.scenario.kinds.register`); ImportError when its name or code is
    another kind's, naming both modules."""
    _check(kind, module)
    other = KINDS.get(kind.name)
    if other is not None:
        _refuse(f"kind name {kind.name!r} of {module} is already taken by {other.module}: each kind needs "
                "its own name")
    if kind.code is not None and kind.code in BY_CODE:
        _refuse(f"CODE {kind.code!r} of {module} (kind {kind.name!r}) is already taken by "
                f"{BY_CODE[kind.code].module} (kind {BY_CODE[kind.code].name!r}): each kind needs its own CODE")
    if kind.firmware is not None:
        for k in KINDS.values():
            if k.firmware is not None and k.firmware.c_name == kind.firmware.c_name:
                _refuse(f"C name {kind.firmware.c_name!r} of {module}'s firmware twin is already taken by "
                        f"{k.module}'s")
    kind = kind.registered(module)
    settings_registry.register(kind.settings)
    KINDS[kind.name] = kind
    if kind.code is not None:
        BY_CODE[kind.code] = kind
    return kind


def _discover() -> None:
    for info in pkgutil.iter_modules(__path__):
        name = f"{__name__}.{info.name}"
        module = importlib.import_module(name)
        declared = getattr(module, "KIND", None)
        if declared is None:
            orphans = _orphan_settings(module)
            if orphans:
                _refuse(f"{name} defines the settings of kind {orphans[0].KIND!r} ({orphans[0].__name__}) but "
                        "declares no KIND = ControllerKind(...) (frogsim.control.kinds.spec)")
            continue
        _register(declared, name)


def of(settings) -> ControllerKind:
    """The declaration of the kind of ``settings`` (a controller's settings, or its class)."""
    return KINDS[settings.KIND]


def of_module(module) -> ControllerKind:
    """The kind declared by ``module`` (a kind's module, or its name)."""
    name = module if isinstance(module, str) else module.__name__
    for k in KINDS.values():
        if k.module == name:
            return k
    raise KeyError(f"{name} declares no controller kind")


def by_code(code: float) -> ControllerKind:
    """The kind whose rows carry ``code`` in the table's kind column; KeyError naming the known codes."""
    try:
        return BY_CODE[float(code)]
    except KeyError:
        raise KeyError(f"no controller kind has code {code!r} (codes: "
                       f"{', '.join(f'{c:g} {k.name}' for c, k in sorted(BY_CODE.items()))})") from None


def with_law() -> list:
    """The kinds that write rows, each with its compiled law, by code."""
    return [BY_CODE[c] for c in sorted(BY_CODE)]


def with_twin() -> list:
    """The kinds with a firmware twin, in the order the firmware's C defines them: those without
    rows (``program``) first, then by code."""
    twins = [k for k in KINDS.values() if k.firmware is not None]
    return sorted(twins, key=lambda k: (k.code is not None, k.code or 0.0))


_discover()
