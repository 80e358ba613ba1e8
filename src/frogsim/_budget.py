"""One size check before any large job: how many points or rows, how much memory and disk.

A job (a sweep's points, a run's output rows, a results or CSV file) states what it would need as
a :class:`Need` before it materialises anything; :func:`check` refuses it with one
:class:`frogsim.ScenarioError` that gives the figures (count and limit, bytes of memory needed
against what the machine has available, bytes of disk against what is free) when

* the count exceeds the job's fixed limit (a sweep's 2,000,000 points, a run's 5,000,000 output
  rows), or
* the memory it would hold exceeds :data:`MEMORY_SHARE` of the memory available now
  (``MemAvailable`` of ``/proc/meminfo``, else ``os.sysconf``), or
* the bytes it would write exceed the free space of the disk it writes to.

Jobs within their limits run as before: the check refuses, it never shrinks a job. Memory and
disk figures are estimates from the array sizes (8 bytes a float) plus a stated per-item
overhead; they are lower bounds of what the job uses, so a refusal is never a false alarm by a
wide margin. The system is asked only when the estimate is large enough to matter
(:data:`ASK_ABOVE`), so the check costs nothing on small jobs.
"""
from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from frogsim.errors import ScenarioError

MEMORY_SHARE = 0.5              # a job may plan to hold at most this share of the available memory
ASK_ABOVE = 64 * 2**20          # [bytes]: smaller needs are never compared with the system's figures


@dataclass(frozen=True)
class Need:
    """What a job would take: ``count`` items (``unit``: "points", "rows") of at most ``limit``,
    ``memory`` bytes held at once, ``disk`` bytes written under ``disk_path``."""
    what: str                   # "a sweep of 1,000,000,000 points"
    count: int
    unit: str
    limit: int
    memory: float = 0.0
    disk: float = 0.0
    disk_path: str | os.PathLike | None = None


def fmt_bytes(n: float) -> str:
    """Bytes for a reader: "512 B", "3.4 MB", "7.6 GB", "1.2 TB" (powers of 1000)."""
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def available_memory() -> int | None:
    """Bytes of memory available to a new job now (None if the system does not say)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, OSError, ValueError):
        return None


def free_disk(path) -> int | None:
    """Free bytes on the disk that holds ``path`` (or its nearest existing parent); None if unknown."""
    p = Path(path).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    try:
        return shutil.disk_usage(p).free
    except OSError:
        return None


def check(field: str, value, need: Need) -> None:
    """Refuse ``need`` (ScenarioError on ``field = value``) if it breaks its count limit or needs
    more memory or disk than there is (module docstring); the message gives every figure."""
    big = need.count > need.limit
    mem = disk = None
    if big or need.memory > ASK_ABOVE:
        mem = available_memory()
    if need.disk_path is not None and (big or need.disk > ASK_ABOVE):
        disk = free_disk(need.disk_path)
    short_mem = mem is not None and need.memory > MEMORY_SHARE * mem
    short_disk = disk is not None and need.disk > disk
    if not (big or short_mem or short_disk):
        return
    figures = []
    if need.memory:
        figures.append(f"about {fmt_bytes(need.memory)} of memory"
                       + (f" ({fmt_bytes(mem)} available, a job may use half)" if mem is not None else ""))
    if need.disk:
        figures.append(f"about {fmt_bytes(need.disk)} of disk"
                       + (f" ({fmt_bytes(disk)} free)" if disk is not None else ""))
    why = [f"more than the {need.limit:,} {need.unit} allowed"] if big else []
    why += ["not enough memory"] if short_mem else []
    why += ["not enough disk"] if short_disk else []
    raise ScenarioError(field, value, f"{need.what} would need {' and '.join(figures) or 'too much'}: "
                                      f"refused before anything was made ({', '.join(why)})")
