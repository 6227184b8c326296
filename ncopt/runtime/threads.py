"""Chunked work in a pool of threads, shared by the stages that use one.

numpy's loops, scipy's k-d tree queries and the parse's byte passes release the
GIL, so threads spread them over the cores without copying the arrays.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor


def available_cpus() -> int:
    """CPUs this process may use (its affinity where the system has one)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def map_in_threads(fn, items, threads: int) -> list:
    """``[fn(item) for item in items]``, in order; in up to ``threads`` threads
    when there is more than one item."""
    items = list(items)
    n = min(max(int(threads), 1), len(items))
    if n <= 1:
        return [fn(item) for item in items]
    with ThreadPoolExecutor(n) as pool:
        return list(pool.map(fn, items))
