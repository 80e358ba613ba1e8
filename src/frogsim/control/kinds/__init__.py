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

Checked at import by the shared registry (:mod:`frogsim._registry`), each failure an ImportError
naming the modules: two kinds with one name or
one ``CODE``, a code the table reserves, a law without a code (or a code without a law), two
twins with one C name, a gain that is not a quantity setting of its kind or has an empty range,
a settings class without its ``KIND`` declaration. A kind lives in this package (not outside
it): the compiled code's cache is keyed on the files of :mod:`frogsim.control`
(:mod:`frogsim._jit`), so a new kind module starts a fresh cache and never meets the machine
code of a dispatch that did not know it.
"""
from __future__ import annotations

import math
import re

from frogsim._registry import Registry
from frogsim.control.kinds.spec import TRACKS, ControllerKind, _field_kind
from frogsim.control.table import KIND_EXTERNAL, KIND_PUMP_BAND
from frogsim.scenario import kinds as settings_registry
from frogsim.scenario.kinds import ControllerSettings

#: codes of the table's kind column that are not a kind's (an empty row, the pump's band, a Python law)
RESERVED_CODES = {0.0: "an empty row", KIND_PUMP_BAND: "the pump's pressure band (KIND_PUMP_BAND)",
                  KIND_EXTERNAL: "a muscle driven from Python (KIND_EXTERNAL)"}
_C_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def _refuse(text: str):
    REGISTRY.refuse(text)


def _check(kind, module: str) -> None:
    """The kinds' own checks (module docstring) beyond the shared registry's; ImportError naming
    ``module``."""
    s = kind.settings
    if kind.code is None and kind.law is not None:
        _refuse(f"{module}: kind {s.KIND!r} has a law but no code (its rows' value in the table's kind column)")
    if kind.code is not None and kind.law is None:
        _refuse(f"{module}: kind {s.KIND!r} has code {kind.code!r} but no law: the sample would have "
                "nothing to run for its rows")
    if kind.firmware is not None and not _C_NAME.fullmatch(kind.firmware.c_name or ""):
        _refuse(f"{module}: kind {s.KIND!r}'s firmware twin has C name {kind.firmware.c_name!r}, not a C identifier")
    if kind.firmware is not None:
        for k in KINDS.values():
            if k.firmware is not None and k.firmware.c_name == kind.firmware.c_name:
                _refuse(f"C name {kind.firmware.c_name!r} of {module}'s firmware twin is already taken by "
                        f"{k.module}'s")
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


REGISTRY = Registry("controller kinds", "KIND", ControllerKind, ControllerSettings, "KIND", "kind",
                    loader=lambda cls, kind: settings_registry.register(cls), check=_check,
                    reserved={c: f"{w} (frogsim.control.table)" for c, w in RESERVED_CODES.items()},
                    code_optional=True)
#: kind name -> its declaration, in the order of the modules' file names
KINDS: dict[str, ControllerKind] = REGISTRY.by_name
#: table code -> the kind writing rows with it
BY_CODE: dict[float, ControllerKind] = REGISTRY.by_code


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


REGISTRY.discover(__name__, __path__)
