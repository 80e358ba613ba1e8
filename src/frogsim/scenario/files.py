"""Reading the files a scenario names (scenario, parameter set, joint-angle CSV) without surprises.

A path given by a user may be a directory, a device (/dev/zero never ends, /dev/null is empty),
a FIFO (reading it waits forever), a huge or binary file. :func:`read_text` opens it without
blocking, accepts only a regular file of bounded size holding UTF-8 text, and otherwise raises a
one-line ScenarioError. :func:`check_raw` refuses data nested deeper than any scenario needs (deep
nesting makes copying and printing recurse without end), keys that are not text and whole numbers
beyond TOML's 64 bits.
"""
from __future__ import annotations

import os
import stat

from frogsim.errors import ScenarioError

MAX_FILE_BYTES = 64 * 1024 * 1024     # no scenario, parameter set or joint-angle table is this big
INT_MIN, INT_MAX = -2**63, 2**63 - 1  # TOML's integers
MAX_DEPTH = 32                        # tables and arrays inside each other; scenarios use < 8


def read_text(path, what: str, max_bytes: int = MAX_FILE_BYTES) -> str:
    """The UTF-8 text of a regular file; ScenarioError(what, path, why) for anything else."""
    shown = str(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise ScenarioError(what, shown, "file not found") from None
    except IsADirectoryError:
        raise ScenarioError(what, shown, "is a directory, not a file") from None
    except (OSError, ValueError) as exc:    # permission, a name too long, a NUL in the path
        raise ScenarioError(what, shown, f"cannot be opened ({exc.__class__.__name__}: "
                                         f"{getattr(exc, 'strerror', None) or exc})") from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise ScenarioError(what, shown, "is a directory, not a file")
        if not stat.S_ISREG(st.st_mode):
            kind = ("a FIFO" if stat.S_ISFIFO(st.st_mode) else "a device" if
                    stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else
                    "a socket" if stat.S_ISSOCK(st.st_mode) else "not a regular file")
            raise ScenarioError(what, shown, f"is {kind}, not a regular file")
        if st.st_size > max_bytes:
            raise ScenarioError(what, shown, f"is {st.st_size} bytes, more than the "
                                             f"{max_bytes // 2**20} MiB a {what} file may have")
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb", closefd=True) as fh:
            fd = None
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        raise ScenarioError(what, shown, f"cannot be read ({exc.strerror or exc})") from None
    finally:
        if fd is not None:
            os.close(fd)
    if len(data) > max_bytes:
        raise ScenarioError(what, shown, f"is more than the {max_bytes // 2**20} MiB a {what} file may have")
    if b"\x00" in data:
        raise ScenarioError(what, shown, "is a binary file, not text")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(what, shown, f"is not UTF-8 text (byte {exc.start})") from None


def check_raw(value, what: str, shown, limit: int = MAX_DEPTH) -> None:
    """What every raw scenario (file or dict) must be before any field reads it, checked without
    recursion: tables and arrays nested at most ``limit`` levels deep (else ScenarioError(what,
    shown, ...)), table keys that are text, whole numbers within TOML's 64-bit range."""
    stack = [(value, 1, "")]
    while stack:
        node, depth, path = stack.pop()
        if isinstance(node, dict):
            items = node.items()
        elif isinstance(node, (list, tuple)):
            items = ((f"[{j}]", v) for j, v in enumerate(node))
        else:
            continue
        if depth > limit:
            raise ScenarioError(what, shown, f"tables or arrays nested more than {limit} levels deep "
                                             "(a scenario needs fewer than 8)")
        for key, child in items:
            if isinstance(node, dict):
                if not isinstance(key, str):
                    raise ScenarioError(f"{path}.{key!r}" if path else repr(key), child,
                                        "a table's keys must be text")
                where = f"{path}.{key}" if path else key
            else:
                where = f"{path}{key}"
            if isinstance(child, int) and not isinstance(child, bool) and not INT_MIN <= child <= INT_MAX:
                raise ScenarioError(where, child, "a whole number must lie within +-9.2e18 (64 bits)")
            if isinstance(child, (dict, list, tuple)):
                stack.append((child, depth + 1, where))
