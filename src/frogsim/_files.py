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


NAME_MAX = 255           # bytes of one file name (Linux, macOS)
PATH_MAX = 4095          # bytes of a whole path


def _refuse_out(text: str, why: str, field: str = "--out"):
    from frogsim.errors import ScenarioError
    raise ScenarioError(field, text, why)


def _checked_place(text: str, field: str) -> Path:
    """The absolute path of an output given by the user, refused (ScenarioError) if it is empty,
    holds a NUL, is a filesystem root or has a name longer than the system allows."""
    if not isinstance(text, str) or not text.strip():
        _refuse_out(text, "is empty: name the output (a new folder, e.g. --out results)", field)
    if "\0" in text:
        _refuse_out(text, "holds a NUL character, which no file name may hold", field)
    full = Path(os.path.abspath(text))
    if full == Path(full.anchor):
        _refuse_out(text, "is the filesystem root: name a folder of its own, e.g. --out results", field)
    if len(os.fsencode(str(full))) > PATH_MAX:
        _refuse_out(text, f"is longer than the {PATH_MAX} bytes a path may have", field)
    for part in full.parts[1:]:
        if len(os.fsencode(part)) > NAME_MAX:
            _refuse_out(text, f"has a name longer than the {NAME_MAX} bytes a file name may have", field)
    return full


def _check_writable(text: str, where: Path, field: str) -> None:
    """Refuse (ScenarioError) unless ``where`` (an existing folder, or one its nearest existing
    ancestor can hold) can be written: a folder is made in the nearest existing ancestor and
    removed at once, so nothing stays behind."""
    anc = where
    while not os.path.lexists(anc):
        anc = anc.parent
    if not anc.is_dir():
        _refuse_out(text, f"cannot be made: {str(anc)!r} is a file, not a folder", field)
    try:
        probe = tempfile.mkdtemp(prefix=".frogsim-probe-", dir=anc)
    except OSError as exc:
        _refuse_out(text, f"cannot be written: {str(anc)!r} refuses new files "
                          f"({exc.strerror or exc.__class__.__name__})", field)
    os.rmdir(probe)


def out_folder(path, field: str = "--out") -> Path:
    """An output folder given by the user, checked before anything is written: ScenarioError (the
    CLI's exit 2, nothing written) if it is empty, a filesystem root, an existing file, or a place
    no folder can be made or written (a read-only or virtual file system, a path under a file)."""
    text = os.fspath(path) if isinstance(path, os.PathLike) else path
    full = _checked_place(text, field)
    if os.path.lexists(full) and not full.is_dir():
        _refuse_out(text, "exists and is not a directory: name a folder for the outputs", field)
    _check_writable(text, full, field)
    return Path(text)


def out_file(path, suffix: str, field: str = "--out", overwrite: bool = True) -> Path:
    """An output file given by the user (a sweep's .nc, a plot's .png), checked like
    :func:`out_folder`: its name must end in ``suffix``; an existing folder, device or other
    non-regular file is refused, an existing file too unless ``overwrite``."""
    text = os.fspath(path) if isinstance(path, os.PathLike) else path
    full = _checked_place(text, field)
    if full.is_dir():
        _refuse_out(text, f"is a folder: name the {suffix} file to write, e.g. {full.name or 'out'}/out{suffix}",
                    field)
    if not full.name.lower().endswith(suffix) or len(full.name) <= len(suffix):
        _refuse_out(text, f"must be a file name ending in {suffix}", field)
    if os.path.lexists(full):
        if not full.is_file():
            _refuse_out(text, "exists and is not a regular file", field)
        if not overwrite:
            _refuse_out(text, "exists: use --overwrite to replace it, or another --out", field)
    _check_writable(text, full.parent, field)
    return Path(text)


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
