"""A copy of the package with new modules added and no file edited, and a Python run on it: how the
family tests show that a new member (an actuator, valve or sensor type, a controller kind, an
integration method) is one new module (docs/architecture.md, "Families")."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

#: the package under test (this checkout's src/frogsim)
PACKAGE = Path(__file__).resolve().parent.parent / "src" / "frogsim"


def package_copy(root: Path, modules: dict) -> Path:
    """A copy of the package under root/src with ``modules`` ({path inside the package, e.g.
    "circuit/valves/throttled.py": text}) added, each a file the package does not have; no file of
    the copy is edited. Returns root/src."""
    pkg = Path(root) / "src" / "frogsim"
    shutil.copytree(PACKAGE, pkg, ignore=shutil.ignore_patterns("__pycache__"))
    for rel, text in modules.items():
        assert not (pkg / rel).exists(), f"{rel} is a file of the package: a new member is a new module"
        (pkg / rel).write_text(text)
    return Path(root) / "src"


def changed_files(src: Path) -> list:
    """The package's paths (sorted) at which the copy under src differs from the package: new files
    and edited ones."""
    pkg = Path(src) / "frogsim"
    return [p.relative_to(pkg).as_posix() for p in sorted(pkg.rglob("*.py"))
            if not (PACKAGE / p.relative_to(pkg)).exists()
            or (PACKAGE / p.relative_to(pkg)).read_bytes() != p.read_bytes()]


def run_copy(src: Path, *argv, cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess:
    """``python argv...`` in cwd on the copy under src (first on the path), with its own Numba
    cache beside it (shared by every run on that copy)."""
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(Path(src).parent / "numba"))
    return subprocess.run([sys.executable, *argv], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout)
