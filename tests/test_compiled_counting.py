"""Functions compiled without Numba's reference counting never take arrays from ones that allocate.

``frogsim._jit.jit`` compiles without reference counting (functions that only use arrays they are
given: Numba refuses an allocation inside them), ``jit_alloc`` with it. One gap Numba leaves open:
a function compiled without counting may call one that allocates and returns the new array; that
array is then never freed (a leak per call: the batched sweep leaked every run's output arrays
that way, and ran at half speed, before this test). This test reads every compiled function's
source and fails on such a call.
"""
from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
import textwrap

from numba.core.registry import CPUDispatcher

import frogsim


def _dispatchers():
    found = {}
    for info in pkgutil.walk_packages(frogsim.__path__, "frogsim."):
        if info.name.endswith("__main__"):
            continue
        mod = importlib.import_module(info.name)
        for name, obj in vars(mod).items():
            if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == mod.__name__:
                found[f"{mod.__name__}.{name}"] = obj
    return found


def _counts(d) -> bool:
    return bool(d.targetoptions.get("_nrt", True))


def _callees(d):
    """The compiled functions ``d`` calls by a name of its module (or an attribute of one)."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(d.py_func)))
    glb = d.py_func.__globals__
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        obj = None
        if isinstance(f, ast.Name):
            obj = glb.get(f.id)
        elif isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name):
            obj = getattr(glb.get(f.value.id), f.attr, None)
        if isinstance(obj, CPUDispatcher):
            yield f"{obj.py_func.__module__}.{obj.py_func.__name__}", obj


def test_both_kinds_exist():
    ds = _dispatchers()
    counting = [k for k, d in ds.items() if _counts(d)]
    assert "frogsim.engine.integrator.advance" in ds and not _counts(ds["frogsim.engine.integrator.advance"])
    assert "frogsim.engine.integrator.begin" in counting       # it allocates the run's arrays


def test_no_uncounted_function_calls_an_allocating_one():
    bad = []
    for name, d in _dispatchers().items():
        if _counts(d):
            continue
        for callee, obj in _callees(d):
            if _counts(obj):
                bad.append(f"{name} calls {callee}")
    assert not bad, "compiled without reference counting but calling a function that allocates " \
                    "(compile the caller with frogsim._jit.jit_alloc): " + "; ".join(bad)
