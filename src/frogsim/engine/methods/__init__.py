"""Integration methods, one module each, and their registry (docs/architecture.md, "Adding an
integration method").

No list of methods is kept by hand: every module of this package is imported here (pkgutil, in the
order of their file names) and a module that declares ``METHOD = IntegrationMethod(...)``
(:mod:`frogsim.engine.methods.spec`) is a method; ``spec`` is a helper. What the rest of frogsim
reads comes from here: the loader's settings classes (registered with
:mod:`frogsim.scenario.methods`, so ``[solver] method = "..."`` finds them), the parameter block
a run hands the driver (:func:`parameter_block`), and the driver's compiled dispatch
(:mod:`frogsim.engine.integrator`, built from :func:`ordered`).

Checked at import, each failure an ImportError naming the modules: two methods with one name or
one code, a code that is not a finite float > 0, a declaration whose parts are missing (step,
continuous extension, step-size control), more scratch vectors than the driver has, a settings
class without its ``METHOD`` declaration, and a registry without the default method
(:data:`DEFAULT`). A method lives in this package (not outside it): the compiled code's cache is
keyed on the files of :mod:`frogsim.engine` (:mod:`frogsim._jit`), so a new method module starts
a fresh cache and never meets the machine code of a dispatch that did not know it.
"""
from __future__ import annotations

import dataclasses
import importlib
import math
import pkgutil

import numpy as np

from frogsim.engine.methods.spec import PAR_SIZE, R_OWN, ROWS, IntegrationMethod, StepControl
from frogsim.scenario import methods as settings_registry
from frogsim.scenario.methods import MethodSettings

#: the method a scenario without ``[solver] method`` runs (today's adaptive method)
DEFAULT = "dopri-rosenbrock"
#: method name -> its declaration, in the order of the modules' file names
METHODS: dict[str, IntegrationMethod] = {}
#: dispatch code -> the method
BY_CODE: dict[float, IntegrationMethod] = {}


def _refuse(text: str):
    raise ImportError(f"integration methods: {text}")


def _check(m, module: str) -> None:
    """The declaration's own checks (module docstring); ImportError naming ``module``."""
    if not isinstance(m, IntegrationMethod):
        _refuse(f"{module}.METHOD is a {type(m).__name__}, not an IntegrationMethod (frogsim.engine.methods.spec)")
    s = m.settings
    if not (isinstance(s, type) and issubclass(s, MethodSettings) and dataclasses.is_dataclass(s)):
        _refuse(f"{module}: settings {s!r} is not a dataclass derived from MethodSettings")
    if not isinstance(s.METHOD, str) or not s.METHOD:
        _refuse(f"{module}: settings class {s.__name__} has no METHOD (the method's name in files)")
    if not isinstance(m.code, float) or not math.isfinite(m.code) or m.code <= 0.0:
        _refuse(f"{module}: method {s.METHOD!r} has code {m.code!r}: a code is a finite float > 0")
    for part in ("step", "dense"):
        if not callable(getattr(m, part)):
            _refuse(f"{module}: method {s.METHOD!r} has no {part} (a compiled function)")
    if not isinstance(m.control, StepControl) or not all(
            callable(getattr(m.control, p)) for p in ("propose", "accepted", "rejected")):
        _refuse(f"{module}: method {s.METHOD!r} has no step-size control (a StepControl of compiled functions, "
                "frogsim.engine.stepsize)")
    if m.restart is not None and not callable(m.restart):
        _refuse(f"{module}: method {s.METHOD!r}'s restart is not a compiled function")
    if not isinstance(m.order, int) or m.order < 1:
        _refuse(f"{module}: method {s.METHOD!r} has order {m.order!r}: a whole number >= 1")
    if not isinstance(m.vectors, int) or not 0 <= m.vectors <= ROWS - R_OWN:
        _refuse(f"{module}: method {s.METHOD!r} asks for {m.vectors!r} scratch vectors; the driver has "
                f"{ROWS - R_OWN} for a method's own stages")


def _orphan_settings(module) -> list:
    """The settings classes ``module`` defines (with a METHOD) that no declaration of it names."""
    return [obj for obj in vars(module).values()
            if isinstance(obj, type) and issubclass(obj, MethodSettings) and obj.__module__ == module.__name__
            and obj.METHOD]


def _register(m: IntegrationMethod, module: str) -> IntegrationMethod:
    """Put ``m`` (declared in ``module``) into the registry and its settings class into the
    loader's; ImportError when its name or code is another method's, naming both modules."""
    _check(m, module)
    other = METHODS.get(m.name)
    if other is not None:
        _refuse(f"method name {m.name!r} of {module} is already taken by {other.module}: each method needs its "
                "own name")
    if m.code in BY_CODE:
        _refuse(f"code {m.code!r} of {module} (method {m.name!r}) is already taken by {BY_CODE[m.code].module} "
                f"(method {BY_CODE[m.code].name!r}): each method needs its own code")
    m = m.registered(module)
    settings_registry.register(m.settings, default=m.name == DEFAULT)
    METHODS[m.name] = m
    BY_CODE[m.code] = m
    return m


def _discover() -> None:
    for info in pkgutil.iter_modules(__path__):
        name = f"{__name__}.{info.name}"
        module = importlib.import_module(name)
        declared = getattr(module, "METHOD", None)
        if declared is None:
            orphans = _orphan_settings(module)
            if orphans:
                _refuse(f"{name} defines the settings of method {orphans[0].METHOD!r} ({orphans[0].__name__}) but "
                        "declares no METHOD = IntegrationMethod(...) (frogsim.engine.methods.spec)")
            continue
        _register(declared, name)
    if DEFAULT not in METHODS:
        _refuse(f"no module declares the default method {DEFAULT!r} (methods: {', '.join(METHODS) or 'none'})")


def ordered() -> list:
    """The methods in the order the driver's dispatch tries them: the default first (its runs pay
    one comparison a call), then by code."""
    return [METHODS[DEFAULT]] + [BY_CODE[c] for c in sorted(BY_CODE) if BY_CODE[c].name != DEFAULT]


def of(settings) -> IntegrationMethod:
    """The declaration of the method of ``settings`` (a method's settings, or its class)."""
    return METHODS[settings.METHOD]


def parameter_block(settings) -> np.ndarray:
    """The parameter block ``par`` a run hands the driver for method settings ``settings``:
    PAR_SIZE floats, [code, *settings.params()], zeros after."""
    values = of(settings).block(settings)
    if len(values) > PAR_SIZE:
        raise ValueError(f"method {settings.METHOD!r} has {len(values) - 1} parameters; the block holds "
                         f"{PAR_SIZE - 1}")
    par = np.zeros(PAR_SIZE)
    par[:len(values)] = values
    return par


_discover()
