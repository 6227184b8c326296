"""Handing freed memory back to the operating system between stages.

glibc keeps the heap pages of freed numpy temporaries mapped (its mmap threshold
grows with the first large frees, so later arrays come from the heap), and memory
freed in one thread's arena is not reused by another: on 1M blocks the process
held ~500 MB it no longer used when the verification began, and its peak was the
sum of such leftovers and the next stage's temporaries.  ``malloc_trim`` returns
them (all arenas) in a few tens of milliseconds.  Elsewhere (Windows, macOS,
musl) this does nothing.
"""

from __future__ import annotations

import ctypes
import sys
from functools import lru_cache


@lru_cache(maxsize=1)
def _malloc_trim():
    if not sys.platform.startswith("linux"):
        return None
    try:  # the symbols already loaded: no library search (find_library forks ldconfig)
        return ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError):  # not glibc
        return None


def release_freed_memory() -> None:
    """Return the memory freed so far to the operating system, where the C library can."""
    trim = _malloc_trim()
    if trim is not None:
        trim(0)
