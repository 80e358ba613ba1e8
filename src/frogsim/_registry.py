"""The one registry every family of swappable parts uses (docs/architecture.md, "Families").

A family is a package whose modules each declare one member: ``KIND = ControllerKind(...)``,
``VALVE = ValveType(...)``, ``METHOD = IntegrationMethod(...)``, ``ACTUATOR = ActuatorType(...)``,
``SENSOR = SensorType(...)``. No list of members is kept by hand: :meth:`Registry.discover`
imports every module of the package (pkgutil, in the order of their file names) and registers
what each declares. What every family checks, here once, each failure an ImportError
``"<family>: ..."`` naming the modules:

* the declaration is of the family's spec class, its ``settings`` a dataclass derived from the
  family's settings base, with its name (``settings.<name_attr>``) a non-empty string;
* its ``code`` (the float that selects it in compiled code) finite and > 0, not a reserved one;
  None only in a family that allows members without compiled rows (the controller kinds'
  ``program``);
* no two members with one name or one code;
* no module that defines a settings class with a name but declares nothing (an orphan: a
  forgotten declaration would otherwise be a member nobody can choose);
* the family's own checks (``check(decl, module)``, raising through :meth:`Registry.refuse`).

Each member's settings class goes to the loader's registry (``loader(cls, decl)``) so that the
scenario layer finds it by name without importing the family.

:func:`dispatch` makes the compiled entry of a family from its members: one inlined branch per
member (:func:`frogsim._jit.jit_inner`), trying its code and handing on to the next; the last
branch raises for a code no member declares (``unknown``), or takes any code (when an earlier
dispatch of the same call has refused unknown codes already), or, for an optional function, does
nothing. The branches are written out from the argument names (Python source made here, the same
code the families wrote by hand before), so a dispatch is generated from the registry and never
falls back to a default in silence.
"""
from __future__ import annotations

import dataclasses
import importlib
import math
import pkgutil
from typing import Callable


class Registry:
    """The members of one family, by name and by code (see module docstring).

    ``family``: the words every refusal starts with ("valve types"); ``attr``: the name each
    module declares its member under ("VALVE"); ``spec``: the declaration's class; ``settings_base``:
    the class every member's settings derive from; ``name_attr``: the settings' class attribute
    holding the member's name in files ("TYPE"); ``member``: what one member is called ("type"); ``loader``: ``loader(settings_class, decl)``,
    the scenario layer's registration; ``check``: the family's own checks; ``parts``: the names of
    the declaration's functions every member must give; ``reserved``: codes members may not take,
    with what holds them; ``code_optional``: members may have code None."""

    def __init__(self, family: str, attr: str, spec: type, settings_base: type, name_attr: str, member: str, *,
                 loader: Callable | None = None, check: Callable | None = None, parts: tuple = (),
                 reserved: dict | None = None, code_optional: bool = False):
        self.family = family
        self.member = member
        self.attr = attr
        self.spec = spec
        self.settings_base = settings_base
        self.name_attr = name_attr
        self.loader = loader
        self.check = check
        self.parts = tuple(parts)
        self.reserved = dict(reserved or {})
        self.code_optional = code_optional
        #: member name -> its declaration, in the order of the modules' file names
        self.by_name: dict = {}
        #: code -> the member
        self.by_code: dict = {}

    def refuse(self, text: str):
        raise ImportError(f"{self.family}: {text}")

    def _check(self, decl, module: str) -> None:
        if not isinstance(decl, self.spec):
            self.refuse(f"{module}.{self.attr} is a {type(decl).__name__}, not a {self.spec.__name__} "
                        f"({self.spec.__module__})")
        s = decl.settings
        if not (isinstance(s, type) and issubclass(s, self.settings_base) and dataclasses.is_dataclass(s)):
            self.refuse(f"{module}: settings {s!r} is not a dataclass derived from {self.settings_base.__name__}")
        name = getattr(s, self.name_attr, None)
        if not isinstance(name, str) or not name:
            self.refuse(f"{module}: settings class {s.__name__} has no {self.name_attr} (the name in files)")
        code = decl.code
        if code is None and self.code_optional:
            pass
        elif not isinstance(code, float) or not math.isfinite(code) or code <= 0.0:
            self.refuse(f"{module}: {self._what(decl)} has code {code!r}: a code is a finite float > 0")
        elif code in self.reserved:
            self.refuse(f"{module}: {self._what(decl)} has code {code!r}, which is reserved for "
                        f"{self.reserved[code]}")
        for part in self.parts:
            if not callable(getattr(decl, part, None)):
                self.refuse(f"{module}: {self._what(decl)} has no {part}")
        if self.check is not None:
            self.check(decl, module)

    def _what(self, decl) -> str:
        return f"{self.member} {getattr(decl.settings, self.name_attr, '?')!r}"

    def register(self, decl, module: str):
        """Check ``decl`` (declared in ``module``), put it into the registry and its settings class
        into the loader's; ImportError when its name or code is another member's, naming both."""
        self._check(decl, module)
        name = getattr(decl.settings, self.name_attr)
        other = self.by_name.get(name)
        if other is not None:
            self.refuse(f"{self.member} name {name!r} of {module} is already taken by {other.module}: each "
                        f"{self.member} needs its own name")
        if decl.code is not None and decl.code in self.by_code:
            o = self.by_code[decl.code]
            self.refuse(f"CODE {decl.code!r} of {module} ({self.member} {name!r}) is already taken by {o.module} "
                        f"({self.member} {getattr(o.settings, self.name_attr)!r}): each {self.member} needs its own CODE")
        decl = dataclasses.replace(decl, module=module)
        if self.loader is not None:
            self.loader(decl.settings, decl)
        self.by_name[name] = decl
        if decl.code is not None:
            self.by_code[decl.code] = decl
        return decl

    def _orphans(self, module) -> list:
        return [obj for obj in vars(module).values()
                if isinstance(obj, type) and issubclass(obj, self.settings_base) and obj.__module__ == module.__name__
                and getattr(obj, self.name_attr, "")]

    def discover(self, package: str, path) -> None:
        """Import every module of ``package`` (its ``__path__``) and register what each declares."""
        for info in pkgutil.iter_modules(path):
            name = f"{package}.{info.name}"
            module = importlib.import_module(name)
            declared = getattr(module, self.attr, None)
            if declared is None:
                orphans = self._orphans(module)
                if orphans:
                    self.refuse(f"{name} defines the settings of {self.member} {getattr(orphans[0], self.name_attr)!r} "
                                f"({orphans[0].__name__}) but declares no {self.attr} = {self.spec.__name__}(...) "
                                f"({self.spec.__module__})")
                continue
            self.register(declared, name)

    def discover_all(self, package: str, path) -> list:
        """:meth:`discover`, refusing a package in which no module declares a member; the members
        with a code, by code (:meth:`ordered`)."""
        self.discover(package, path)
        if not self.by_name:
            self.refuse(f"no module of {package} declares {self.attr} = {self.spec.__name__}(...)")
        return self.ordered()

    def write_block(self, row, settings, code_col: int, block_col: int, width: int, width_name: str) -> None:
        """Write the code of the member whose settings ``settings`` are into ``row[code_col]`` and
        its parameter block (its declaration's ``block(settings)``) into ``row[block_col:]``, the rest
        of the ``width`` entries zero; ValueError when the block is longer than ``width`` (the
        layout's ``width_name``)."""
        decl = self.of(settings)
        block = tuple(float(v) for v in decl.block(settings))
        if len(block) > width:
            raise ValueError(f"{self.family}: {self._what(decl)} ({decl.module}) writes {len(block)} parameters; "
                             f"the row holds {width} ({width_name})")
        row[code_col] = decl.code
        row[block_col:block_col + width] = 0.0
        row[block_col:block_col + len(block)] = block

    def ordered(self) -> list:
        """The members with a code, by code."""
        return [self.by_code[c] for c in sorted(self.by_code)]

    def of(self, settings):
        """The member whose settings ``settings`` are (an instance or the class)."""
        return self.by_name[getattr(settings, self.name_attr)]

    def by(self, code: float):
        """The member of code ``code``; KeyError naming the codes there are."""
        try:
            return self.by_code[float(code)]
        except KeyError:
            raise KeyError(f"{self.family}: code {float(code)!r} is no {self.member}'s (codes: "
                           + ", ".join(f"{c:g} {getattr(m.settings, self.name_attr)}"
                                       for c, m in sorted(self.by_code.items())) + ")") from None


# --- the compiled dispatch ------------------------------------------------------------------------------
_LINK = """
def make(code, fn, rest, jit_inner):
    @jit_inner
    def branch(_code, {args}):
        if _code == code:
            {ret}fn({args})
        else:
            {ret}rest(_code, {args})
    return branch
"""
_LAST_RAISE = """
def make(code, fn, jit_inner):
    @jit_inner
    def branch(_code, {args}):
        if _code != code:
            raise ValueError({message!r})
        {ret}fn({args})
    return branch
"""
_LAST_ANY = """
def make(fn, jit_inner):
    @jit_inner
    def branch(_code, {args}):
        {ret}fn({args})
    return branch
"""
_NONE = """
def make(jit_inner):
    @jit_inner
    def branch(_code, {args}):
        return
    return branch
"""


def _maker(template: str, **fmt):
    scope: dict = {}
    exec(compile(template.format(**fmt), f"<frogsim dispatch ({fmt['args']})>", "exec"), scope)
    return scope["make"]


def dispatch(pairs, args: str, *, unknown: str | None = None, returns: bool = True, optional: bool = False):
    """The compiled entry ``entry(code, <args>)`` over ``pairs`` [(code, compiled function), ...]
    (in the order the branches try them): the function of the member whose code is ``code``
    called with ``args`` (a comma-separated list of argument names).

    The last branch: with ``unknown`` (a message) it raises ValueError for a code that is not its
    own; with ``optional`` (a function only some members have, ``returns`` False) a code no pair
    names does nothing; else it calls its function for any code (a dispatch whose caller has
    refused unknown codes already). Every branch is inlined into its callers
    (:func:`frogsim._jit.jit_inner`)."""
    from frogsim._jit import jit_inner
    pairs = list(pairs)
    ret = "return " if returns else ""
    if optional:
        if returns:
            raise ValueError("an optional dispatch returns nothing")
        out = _maker(_NONE, args=args)(jit_inner)
        rest_pairs = pairs
    else:
        if not pairs:
            raise ValueError("a dispatch needs at least one member")
        code, fn = pairs[-1]
        if unknown is not None:
            out = _maker(_LAST_RAISE, args=args, ret=ret, message=unknown)(code, fn, jit_inner)
        else:
            out = _maker(_LAST_ANY, args=args, ret=ret)(fn, jit_inner)
        rest_pairs = pairs[:-1]
    link = _maker(_LINK, args=args, ret=ret)
    for code, fn in reversed(rest_pairs):
        out = link(code, fn, out, jit_inner)
    return out


def membership(codes, name: str = "known"):
    """``known(code) -> bool``, compiled and inlined: True when ``code`` is one of ``codes`` (a
    family's registered codes, at import). A hot loop that dispatches with a last branch taking any
    code (:func:`dispatch` without ``unknown``) is entered only after this test passed for every
    code it will meet, so an unknown code still stops the run (through the raising dispatch of the
    path taken instead)."""
    from frogsim._jit import jit_inner
    codes = [float(c) for c in codes]
    test = " or ".join(f"_code == {c!r}" for c in codes) or "False"
    scope: dict = {}
    exec(compile(f"def {name}(_code):\n    return {test}\n", f"<frogsim membership ({name})>", "exec"), scope)
    return jit_inner(scope[name])
