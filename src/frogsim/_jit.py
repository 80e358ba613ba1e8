"""The Numba decorators frogsim compiles its hot code with (one set of settings), and where its machine
code is cached.

cache=True keeps the machine code between runs (the first run compiles: about 15 s of compiler
work, spread over the cores by :mod:`frogsim.engine.warmup`). no_cfunc_wrapper: Numba would also
build a C-callable wrapper of every function, for passing it as a function pointer, which frogsim
never does.
error_model="numpy" lets a division by zero give inf/NaN instead of raising, which removes a
branch from every division in the hot loop; non-finite values are caught by the integrator's error
norm and reported. fastmath is limited to "arcp" (x/y may become x*(1/y)) and "contract" (fused
multiply-add): no reassociation, no assumptions about NaN or inf. nogil=True lets threads run
compiled code side by side (the batched engine runs points on a thread pool).

Numba checks a cached function only against its own source file, not the files of the functions
it calls, so an edit to ``circuit/rhs.py`` would leave the integrator's cached machine code stale.
The cache therefore lives in a folder named after a hash of every source file that holds compiled
code: any edit there starts a fresh cache. A NUMBA_CACHE_DIR set by the user is respected.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numba
from numba import njit
from numba.core.registry import CPUDispatcher

from frogsim._files import user_cache_folder

_PACKAGE = Path(__file__).resolve().parent
# _registry.py: it writes the families' compiled dispatch; robot/water.py: its table layout (E_*, P_*) is compiled into the coupled engine as constants
_COMPILED_SOURCES = ("_jit.py", "_registry.py", "physics", "circuit", "control", "engine", "robot/water.py")


def _source_hash() -> str:
    h = hashlib.sha256(numba.__version__.encode())
    for entry in _COMPILED_SOURCES:
        path = _PACKAGE / entry
        files = sorted(path.rglob("*.py")) if path.is_dir() else [path]
        for f in files:
            h.update(str(f.relative_to(_PACKAGE)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()[:16]


def _cache_dir() -> str:
    return user_cache_folder("numba", _source_hash()) or ""


if not os.environ.get("NUMBA_CACHE_DIR"):
    numba.config.CACHE_DIR = _cache_dir()


_OPTIONS_NO_CACHE = dict(nogil=True, error_model="numpy", fastmath={"arcp", "contract"}, no_cfunc_wrapper=True)
_OPTIONS = dict(cache=True, **_OPTIONS_NO_CACHE)


def _options(func) -> dict:
    """The options for ``func``: cached, unless it has no source file (defined in ``python -c``,
    at the interactive prompt or by ``exec``), which Numba cannot cache by and would refuse."""
    return _OPTIONS if _has_file(func) else _OPTIONS_NO_CACHE


def _has_file(func) -> bool:
    return func.__code__.co_filename not in ("<string>", "<stdin>")


def jit(func):
    """Compile func with frogsim's Numba settings, without Numba's reference counting (NRT).

    With NRT, every array argument of a compiled function is counted up on entry and down on
    every exit (two atomic operations per array per call), and every view made inside it too.
    The hot functions are called millions of times per run with a dozen arrays each (the
    circuit's right-hand side: 13 arguments, about 30,000 calls in a 4 s robot run), and that
    counting took about a tenth of the coupled engine's time. Functions compiled with this
    decorator only read and write arrays they are given, so nothing needs counting: they must
    not allocate (``np.empty``, ``.copy()``, returning a new array), which Numba refuses to
    compile here. Functions that allocate use :func:`jit_alloc`. (``_nrt`` is a Numba option
    without a public name; the Numba version is pinned in pyproject.toml.)
    """
    return njit(_nrt=False, **_options(func))(func)


class _CompiledCallersOnly(CPUDispatcher):
    """A dispatcher compiled without the wrapper that lets Python call it (see :func:`jit_step`):
    calling it from Python raises instead of jumping to the missing wrapper."""

    def __call__(self, *args, **kwargs):
        raise TypeError(f"{self.py_func.__module__}.{self.py_func.__qualname__} is compiled for compiled callers "
                        f"only (frogsim._jit.jit_step) and cannot be called from Python")


def jit_step(func):
    """:func:`jit` for the engine's internal pieces that only compiled code calls (the driver's
    steps, an accepted step's work, the LU solve, the right-hand side's manifold pressure and
    motion pieces, the controllers' queue, noise and timing helpers, the driver's memory sizes):
    compiled without the wrappers that let Python (``no_cpython_wrapper``) or C
    (``no_cfunc_wrapper``) call them. Numba builds the Python wrapper
    for every compiled function, with code to unpack each argument (these take up to two dozen,
    tuples of arrays among them), and optimises it again in every caller's module; leaving it out
    shortens a first run's compilation. Calling one from Python raises TypeError; compile one
    ahead with ``func.compile(signature)`` (:mod:`frogsim.engine.warmup`). With NUMBA_DISABLE_JIT
    set (running the engine as plain Python, for a debugger) it returns func itself, as njit does."""
    if numba.config.DISABLE_JIT:
        return func
    disp = _CompiledCallersOnly(py_func=func, locals={}, targetoptions=dict(
        _nrt=False, no_cpython_wrapper=True, nopython=True, **_OPTIONS_NO_CACHE))
    if _has_file(func):
        disp.enable_caching()
    return disp


def jit_inner(func):
    """:func:`jit_step` without a cache of its own, and inlined into its callers, for the small
    functions made at import from data (the controller kinds' dispatch, which
    :mod:`frogsim.control.sampled` assembles from the registry as a chain of closures).

    Numba caches a function by its source file and line, which such a function shares with every
    other made by the same code; its callers' cached machine code holds it instead, and their
    cache folder is keyed on every compiled source file, the kinds' modules included, so a change
    of the registry never meets a stale dispatch. ``inline="always"``: Numba copies its body into
    each caller before typing (a chain of closures becomes the caller's own if/elif on the kind
    code), so the dispatch costs no call (a called chain added about 4 % of instructions to a
    closed-loop run)."""
    if numba.config.DISABLE_JIT:
        return func
    return _CompiledCallersOnly(py_func=func, locals={}, targetoptions=dict(
        _nrt=False, no_cpython_wrapper=True, nopython=True, inline="always", **_OPTIONS_NO_CACHE))


_FOR_PYTHON: dict = {}


def for_python(fn):
    """A family member's compiled function (inlined into its compiled callers, :func:`jit_inner`,
    which Python cannot call) compiled once more for Python callers (:func:`jit`), once per
    function."""
    out = _FOR_PYTHON.get(fn)
    if out is None:
        out = _FOR_PYTHON[fn] = jit(getattr(fn, "py_func", fn))
    return out


def jit_alloc(func):
    """Compile func with frogsim's Numba settings and Numba's reference counting, for the few
    compiled functions that allocate arrays (a run's start, the measures over whole results).
    The setting is explicit on every decorator: a callee left unset would take its first
    caller's."""
    return njit(_nrt=True, **_options(func))(func)


def cache_is_warm(dispatcher) -> bool:
    """True if the cache holds compiled code of ``dispatcher`` (a compiled function), for a
    progress message before a first run's compilation. Read from the names of Numba's index files
    (``<module>.<function>-<line>.py<version>.nbi``), not from their contents."""
    d = numba.config.CACHE_DIR
    f = dispatcher.py_func
    prefix = f"{f.__module__.rsplit('.', 1)[-1]}.{f.__qualname__}-"
    return bool(d) and os.path.isdir(d) and any(n.startswith(prefix) and n.endswith(".nbi")
                                                for _, _, fs in os.walk(d) for n in fs)
