"""Integration methods, one module each, and their registry (docs/architecture.md, "Adding an
integration method").

No list of methods is kept by hand: every module of this package is imported here (pkgutil, in the
order of their file names) and a module that declares ``METHOD = IntegrationMethod(...)``
(:mod:`frogsim.engine.methods.spec`) is a method; ``spec`` is a helper. What the rest of frogsim
reads comes from here: the loader's settings classes (registered with
:mod:`frogsim.scenario.methods`, so ``[solver] method = "..."`` finds them), the parameter block
a run hands the driver (:func:`parameter_block`), and the driver's compiled dispatch
(:mod:`frogsim.engine.integrator`, built from :func:`ordered`).

Checked at import by the shared registry (:mod:`frogsim._registry`), each failure an ImportError
naming the modules: two methods with one name or
one code, a code that is not a finite float > 0, a declaration whose parts are missing (step,
continuous extension, step-size control), a part that takes another number of arguments than
the driver passes it (:data:`frogsim.engine.methods.spec.PART_ARGS`, the one list the driver's
dispatch is generated from), more scratch vectors than the driver has, a settings
class without its ``METHOD`` declaration, and a registry without the default method
(:data:`DEFAULT`). A method lives in this package (not outside it): the compiled code's cache is
keyed on the files of :mod:`frogsim.engine` (:mod:`frogsim._jit`), so a new method module starts
a fresh cache and never meets the machine code of a dispatch that did not know it.
"""
from __future__ import annotations

import inspect

import numpy as np

from frogsim._registry import Registry
from frogsim.engine.methods.spec import PART_ARGS, PAR_SIZE, R_OWN, ROWS, IntegrationMethod, StepControl
from frogsim.scenario import methods as settings_registry
from frogsim.scenario.methods import MethodSettings

#: the method a scenario without ``[solver] method`` runs (today's adaptive method)
DEFAULT = "dopri-rosenbrock"


def _check(m, module: str) -> None:
    """The methods' own checks (module docstring) beyond the shared registry's."""
    s = m.settings
    for part in ("step", "dense"):
        if not callable(getattr(m, part)):
            REGISTRY.refuse(f"{module}: method {s.METHOD!r} has no {part} (a compiled function)")
    if not isinstance(m.control, StepControl) or not all(
            callable(getattr(m.control, p)) for p in ("propose", "accepted", "rejected")):
        REGISTRY.refuse(f"{module}: method {s.METHOD!r} has no step-size control (a StepControl of compiled "
                        "functions, frogsim.engine.stepsize)")
    if m.restart is not None and not callable(m.restart):
        REGISTRY.refuse(f"{module}: method {s.METHOD!r}'s restart is not a compiled function")
    parts = {"step": m.step, "dense": m.dense, "propose": m.control.propose, "accepted": m.control.accepted,
             "rejected": m.control.rejected, "restart": m.restart}
    for part, fn in parts.items():
        if fn is None:
            continue
        want = [a.strip() for a in PART_ARGS[part].split(",")]
        got = _arguments(fn)
        if got is not None and len(got) != len(want):
            REGISTRY.refuse(f"{module}: method {s.METHOD!r}'s {part} takes {len(got)} arguments ({', '.join(got)}); "
                            f"the driver passes {len(want)}: {', '.join(want)} (frogsim.engine.methods.spec.PART_ARGS)")
    if not isinstance(m.order, int) or m.order < 1:
        REGISTRY.refuse(f"{module}: method {s.METHOD!r} has order {m.order!r}: a whole number >= 1")
    if not isinstance(m.vectors, int) or not 0 <= m.vectors <= ROWS - R_OWN:
        REGISTRY.refuse(f"{module}: method {s.METHOD!r} asks for {m.vectors!r} scratch vectors; the driver has "
                        f"{ROWS - R_OWN} for a method's own stages")


def _arguments(fn):
    """The parameter names of a compiled function's Python source (None when it has none to read)."""
    try:
        return list(inspect.signature(getattr(fn, "py_func", fn)).parameters)
    except (TypeError, ValueError):
        return None


REGISTRY = Registry("integration methods", "METHOD", IntegrationMethod, MethodSettings, "METHOD", "method",
                    loader=lambda cls, m: settings_registry.register(cls, default=m.name == DEFAULT), check=_check)
#: method name -> its declaration, in the order of the modules' file names
METHODS: dict[str, IntegrationMethod] = REGISTRY.by_name
#: dispatch code -> the method
BY_CODE: dict[float, IntegrationMethod] = REGISTRY.by_code


def _discover() -> None:
    REGISTRY.discover(__name__, __path__)
    if DEFAULT not in METHODS:
        REGISTRY.refuse(f"no module declares the default method {DEFAULT!r} (methods: {', '.join(METHODS) or 'none'})")


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
