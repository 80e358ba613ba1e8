"""The one Numba decorator frogsim compiles its hot code with, and where its machine code is cached.

cache=True keeps the machine code between runs (the first run compiles, about 8 s).
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
import tempfile
from pathlib import Path

import numba
from numba import njit

_PACKAGE = Path(__file__).resolve().parent
# robot/water.py: its table layout (E_*, P_*) is compiled into the coupled engine as constants
_COMPILED_SOURCES = ("_jit.py", "physics", "circuit", "control", "engine", "robot/water.py")


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
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    for root in (base, tempfile.gettempdir()):
        path = os.path.join(root, "frogsim", "numba", _source_hash())
        try:
            os.makedirs(path, exist_ok=True)
            if os.access(path, os.W_OK):
                return path
        except OSError:
            continue
    return ""


if not os.environ.get("NUMBA_CACHE_DIR"):
    numba.config.CACHE_DIR = _cache_dir()


def jit(func):
    """Compile func with frogsim's Numba settings."""
    return njit(cache=True, nogil=True, error_model="numpy", fastmath={"arcp", "contract"})(func)


def cache_is_warm() -> bool:
    """True if compiled engine code is already cached (the first run compiles, about 8 s)."""
    d = numba.config.CACHE_DIR
    return bool(d) and os.path.isdir(d) and any(n.endswith(".nbi") for _, _, fs in os.walk(d) for n in fs)

