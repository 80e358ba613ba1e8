"""The one thread-pool runner: pieces of work on a pool of threads, results in order.

frogsim's hot code is compiled without the GIL (:mod:`frogsim._jit`), so threads run it side by
side. Every batched path (engine batches, sweep chunks, metrics) goes through :func:`map_pieces`.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Sequence


def default_threads(threads: int | None = None) -> int:
    """``threads`` if given, else every core; at least 1."""
    return max(1, int(threads or os.cpu_count() or 1))


def map_pieces(work: Callable, items: Sequence, piece: int, threads: int | None = None) -> list:
    """``[work(items[a:a + piece]) for a in range(0, len(items), piece)]``, on ``threads`` threads.

    The pieces are the same whatever the thread count, so results never depend on it.
    """
    piece = max(1, int(piece))
    pieces = [items[a:a + piece] for a in range(0, len(items), piece)]
    threads = default_threads(threads)
    if threads == 1 or len(pieces) <= 1:
        return [work(p) for p in pieces]
    with ThreadPoolExecutor(threads) as pool:
        return list(pool.map(work, pieces))
