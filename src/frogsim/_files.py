"""The one way frogsim writes a file: atomically (a reader never sees half a file), plus the JSON,
CSV and PNG writers built on it."""
from __future__ import annotations

import json
import math
import os
import tempfile
import threading
from pathlib import Path

import numpy as np


def _clean(obj):
    """JSON-safe copy: numpy scalars to Python, NaN/inf to None."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        x = float(obj)
        return x if math.isfinite(x) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


_UMASK_LOCK = threading.Lock()


def umask() -> int:
    """The process's file-creation mask, read without changing it where the system allows."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    with _UMASK_LOCK:                   # elsewhere: set and restore (briefly process-wide)
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def out_folder(path) -> Path:
    """An output folder given by the user: ScenarioError (the CLI's exit 2, nothing written) if the
    path exists and is not a directory."""
    from frogsim.errors import ScenarioError
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise ScenarioError("--out", str(out), "exists and is not a directory")
    return out


def user_cache_folder(*parts: str) -> str | None:
    """A writable folder for frogsim's caches: <user cache>/frogsim/<parts...>, created if need be
    ($XDG_CACHE_HOME or ~/.cache, else the temporary folder); None if neither can hold it."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    for root in (base, tempfile.gettempdir()):
        path = os.path.join(root, "frogsim", *parts)
        try:
            os.makedirs(path, exist_ok=True)
            if os.access(path, os.W_OK):
                return path
        except OSError:
            continue
    return None


def atomic_write(path: str | os.PathLike, write, durable: bool = False) -> None:
    """Call write(tmp_path) then move the file into place, so readers never see half a file.

    The temporary file lies beside ``path`` (same filesystem, name starting with "."). With
    ``durable`` its content is flushed to disk before the move, so a crash leaves either the
    old file or the whole new one (the sweep journal relies on it). The file gets the mode an
    ordinary ``open`` would give it (0o666 less the umask), not mkstemp's private 0o600.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~umask())
        if durable:
            fd = os.open(tmp, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_json(path, data: dict) -> None:
    def w(tmp):
        with open(tmp, "w") as fh:
            json.dump(_clean(data), fh, indent=2)
            fh.write("\n")
    atomic_write(path, w)


CSV_FLOAT = "%.8g"
CSV_CELL_BYTES = 8           # [bytes] a cell written with up to 8 digits and its separator, on the low side
CSV_PROGRESS_CELLS = 2_000_000   # tables with more cells are written in pieces under a progress bar
CSV_PIECE_ROWS = 20_000


def write_csv(path, df, progress: bool = True) -> None:
    """Write a table atomically (floats with 8 significant digits).

    Its size is checked first (:func:`frogsim._budget.check`: 8 bytes a cell against the
    disk's free space). A table of more than :data:`CSV_PROGRESS_CELLS` cells is written in pieces
    of rows, the same text as in one piece, under a progress bar on stderr (``progress``), so a
    long write shows how far it is and stops promptly on Ctrl-C (leaving no file)."""
    from frogsim._budget import Need, check
    rows, cols = df.shape
    cells = rows * max(cols, 1)
    check("--out", str(path), Need(f"writing {Path(path).name} ({rows:,} rows x {cols} columns)", rows, "rows",
                                   2**62, disk=float(cells * CSV_CELL_BYTES), disk_path=Path(path).parent))
    if cells <= CSV_PROGRESS_CELLS:
        atomic_write(path, lambda tmp: df.to_csv(tmp, index=False, float_format=CSV_FLOAT))
        return

    def pieces(tmp):
        import sys

        from tqdm import tqdm
        with open(tmp, "w", newline="") as fh, \
                tqdm(total=rows, desc=f"writing {Path(path).name}", unit="row", unit_scale=True, file=sys.stderr,
                     disable=not progress, mininterval=0.5, dynamic_ncols=True) as bar:
            for a in range(0, rows, CSV_PIECE_ROWS):
                df.iloc[a:a + CSV_PIECE_ROWS].to_csv(fh, index=False, header=a == 0, float_format=CSV_FLOAT)
                bar.update(min(CSV_PIECE_ROWS, rows - a))
    atomic_write(path, pieces)


def write_figure(path, draw) -> None:
    """draw(tmp_path) must save a PNG at tmp_path."""
    def w(tmp):
        png = tmp + ".png"
        try:
            draw(png)
            os.replace(png, tmp)
        finally:
            if os.path.exists(png):
                os.unlink(png)
    atomic_write(path, w)
