"""The coupled loop in compiled code: MuJoCo's C functions called from Numba, many steps per call.

The coupled engine's step is ``mj_step1 -> step_kernel -> mj_step2``. Called from Python, each
MuJoCo step costs three trips through a binding layer (pybind11 for MuJoCo, Numba's dispatcher
for the kernel, which unboxes its groups of arrays on every call): more time than the two
MuJoCo calls themselves. :func:`run_steps` runs a whole stretch of steps inside one Numba call
instead: it calls ``mj_step1`` and ``mj_step2`` of MuJoCo's shared library through their addresses
(:func:`mujoco_c`), the kernel with its argument tuple unpacked (``step_kernel(k, stepping, row,
*args)``: the groups :func:`frogsim.engine.coupled.kernel_args` returns pass from compiled code to
compiled code as they are, so grouping them costs nothing per step), and returns to Python between
stretches (progress, MuJoCo's warnings) or at the first failure.

The calls and their order are those of the Python loop, so the runs are the same bit for bit
(tested against the Python loop, which :func:`frogsim.engine.coupled.run_coupled` keeps as
``compiled=False``).

The library is the one the ``mujoco`` package ships next to its bindings (the same copy the
bindings use, so MuJoCo's warning callback set through ``mujoco.set_mju_user_warning`` is called
from here too; the bindings take Python's GIL for it). If it cannot be found or is not that copy,
:func:`mujoco_c` returns None and the engine falls back to the Python loop with a one-time warning.
One behaviour differs: a MuJoCo *error* (``mju_error``, e.g. its stack arena exhausted) cannot be
turned into a Python exception from compiled code and ends the process with MuJoCo's message;
the robot's models disable contacts, so their memory use per step is fixed and no such error
occurs after the first step.

The addresses are arguments, not constants compiled in, so the machine code can be cached
between processes (the library's address differs from one process to the next).
"""
from __future__ import annotations

import ctypes
import glob
import os
import warnings

from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from frogsim._jit import jit
from frogsim.engine.coupled_kernel import step_kernel


@intrinsic
def call_model_data(typingctx, fn, m, d):
    """Call the C function at address ``fn`` as ``void fn(const mjModel* m, mjData* d)``."""
    if not all(isinstance(a, types.Integer) for a in (fn, m, d)):
        return None
    sig = types.void(fn, m, d)

    def codegen(context, builder, signature, args):
        vp = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [vp, vp])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(f, [builder.inttoptr(args[1], vp), builder.inttoptr(args[2], vp)])
        return context.get_dummy_value()

    return sig, codegen


@jit
def run_steps(step1, step2, m, d, k0, k1, n_steps, every, fresh, last_step1, args):
    """MuJoCo steps k0 .. k1 - 1 of the coupled loop; returns (k, status).

    Each step: ``mj_step1`` (skipped for the first step if ``fresh``: its derived quantities are
    already up to date), ``step_kernel(k, stepping, row, *args)`` with stepping = 0 only for
    k = n_steps (the last record), then ``mj_step2`` if stepping. ``every`` > 0 records every
    ``every``-th step into row k // every (and the last one into the next row), ``every`` = 0
    records nothing. ``last_step1`` calls ``mj_step1`` once more after the last step (the derived
    quantities at the new time). ``step1``, ``step2``: addresses of MuJoCo's functions, ``m``,
    ``d``: of the model and data. Returns (k1, 0), or (k, status) for the step whose kernel
    failed (nothing after it has run).
    """
    for k in range(k0, k1):
        if not (fresh and k == k0):
            call_model_data(step1, m, d)
        stepping = 1 if k < n_steps else 0
        row = -1
        if every > 0:
            if k % every == 0:
                row = k // every
            elif stepping == 0:
                row = k // every + 1
        status = step_kernel(k, stepping, row, *args)
        if status != 0:
            return k, status
        if stepping != 0:
            call_model_data(step2, m, d)
    if last_step1:
        call_model_data(step1, m, d)
    return k1, 0


_LIB = None
_WARNED = False


def _library_files(mujoco) -> list:
    here = os.path.dirname(mujoco.__file__)
    found = []
    for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
        found += sorted(glob.glob(os.path.join(here, pattern)))
    return found


def _load(mujoco):
    """(address of mj_step1, of mj_step2) in the copy of MuJoCo the bindings use, or the reason
    why not."""
    files = _library_files(mujoco)
    if not files:
        return f"no MuJoCo shared library next to {os.path.dirname(mujoco.__file__)}"
    try:
        lib = ctypes.CDLL(files[0])
        lib.mj_version.restype = ctypes.c_int
        if lib.mj_version() != mujoco.mj_version():
            return f"{files[0]} is MuJoCo {lib.mj_version()}, the bindings {mujoco.mj_version()}"
        # the same copy as the bindings': a warning callback set through them is seen here
        hook = ctypes.c_void_p.in_dll(lib, "mju_user_warning")
        previous = mujoco.get_mju_user_warning()
        try:
            mujoco.set_mju_user_warning(lambda msg: None)
            shared = bool(hook.value)
            mujoco.set_mju_user_warning(None)
            shared = shared and not hook.value
        finally:
            mujoco.set_mju_user_warning(previous)
        if not shared:
            return f"{files[0]} is not the copy of MuJoCo the bindings use"
        return (ctypes.cast(lib.mj_step1, ctypes.c_void_p).value,
                ctypes.cast(lib.mj_step2, ctypes.c_void_p).value, lib)
    except (OSError, AttributeError, ValueError) as exc:
        return f"{files[0]}: {exc}"


def mujoco_c(mujoco):
    """(address of mj_step1, address of mj_step2) of MuJoCo's C library, or None (then a
    RuntimeWarning, once per process, says why and that the Python loop is used)."""
    global _LIB, _WARNED
    if _LIB is None:
        _LIB = _load(mujoco)
    if isinstance(_LIB, str):
        if not _WARNED:
            _WARNED = True
            warnings.warn(f"coupled engine: {_LIB}; running the loop from Python (slower)",
                          RuntimeWarning, stacklevel=3)
        return None
    return _LIB[0], _LIB[1]
