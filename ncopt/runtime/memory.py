"""How a rewrite uses the C library's heap (glibc; elsewhere all of this does nothing).

On a virtual machine, memory the process has not touched before costs far more than
memory it reuses: on the 2-core machine of the benchmarks, filling 1 GB took 1.9 s of
system time the first time and 0.11-0.15 s when the same process filled it again (the
host backs the guest's pages lazily and takes back the ones the guest frees).  A rewrite
of 1M blocks allocates and frees several GB of numpy temporaries on a peak of ~1 GB, so
from its parse to its edits (:func:`working_memory`) glibc keeps what is freed for the
next stage:

* arrays of up to 32 MB come from the heap, not from a fresh mapping each (glibc's
  ``M_MMAP_THRESHOLD``; its own grows there only after the first large frees);
* freed heap memory is not handed back (``M_TRIM_THRESHOLD``), and
  :func:`release_freed_memory` does nothing unless forced;
* at most two arenas (``M_ARENA_MAX``): a thread's freed memory is reused by the
  others, so the peak does not grow by what each thread holds.

It is handed back (forced) where keeping it would raise the peak: when the mesh thread
has built the mesh (its arena), around the contacts while a mesh is alive, and before
the verification, which is the peak of a rewrite and runs without the hold (but for the
chunks of its parse, :func:`ncopt.reading.parse.parse_text`, which reuse each other's memory).

Measured on the dense 1M-block case without a mesh, five alternating pairs against the
rewrite without any of this: whole process median 8.80 -> 8.21 s, system time 1.74-2.28
-> 1.38-2.03 s, peak RSS 1.03-1.10 -> 0.95-0.99 GB.

When the last rewrite running ends, the trim threshold is set back to glibc's default
(the heap's free top is then handed back at the next free, and
:func:`release_freed_memory` hands back the rest).  The mmap threshold stays at 32 MB,
where glibc's own would have grown after the first large frees (setting it turns that
growth off for good), and so does the limit of two arenas (glibc keeps the arenas it
made).

Outside a rewrite, :func:`release_freed_memory` hands freed memory back between
stages (``malloc_trim``), as a long-running process wants.

A rewrite also asks numpy not to mark its arrays for transparent huge pages
(:func:`small_pages`).  numpy does that for every array of 4 MB or more where the kernel's
setting is ``madvise`` (its ``NUMPY_MADVISE_HUGEPAGE``, see numpy's "global state").  On
the 2-core machine a huge page costs more to fault in than the 512 small pages it
replaces: on the dense 1M-block case it faulted about a gigabyte of huge pages and cost
system time for nothing (measured with ``/proc/vmstat`` and alternating runs; the figures
are in the history of bench/README.md).
"""

from __future__ import annotations

import ctypes
import sys
import threading
from contextlib import contextmanager
from functools import lru_cache

# mallopt parameters (glibc's malloc.h)
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD, M_ARENA_MAX = -1, -3, -8
HELD_MMAP_THRESHOLD = 32 << 20  # glibc's largest (HEAP_MAX_SIZE / 2 on 64-bit)
HELD_TRIM_THRESHOLD = 2**31 - 1  # mallopt takes an int: 2 GB, above any peak here
HELD_ARENAS = 2
DEFAULT_TRIM_THRESHOLD = 128 << 10  # glibc's default

_lock = threading.Lock()
_depth = 0
_small_depth = 0
_huge_before = True  # numpy's setting before the first small_pages() that runs


@lru_cache(maxsize=1)
def _glibc():
    """The process's C library if it is glibc (its symbols already loaded), else None."""
    if not sys.platform.startswith("linux"):
        return None
    try:  # no library search (find_library forks ldconfig)
        libc = ctypes.CDLL(None)
        libc.gnu_get_libc_version  # glibc only: musl has no mallopt worth the name
        libc.mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
        libc.mallopt.restype = ctypes.c_int
        return libc
    except (OSError, AttributeError):
        return None


def _malloc_trim():
    libc = _glibc()
    return None if libc is None else libc.malloc_trim


def release_freed_memory(force: bool = False) -> None:
    """Return the memory freed so far to the operating system, where the C library can;
    while a rewrite holds it (:func:`working_memory`), only with ``force`` (where keeping
    it would raise the peak: a mesh's, or everything before the verification)."""
    trim = _malloc_trim()
    if trim is not None and (_depth == 0 or force):
        trim(0)


def holding() -> bool:
    """Is freed memory kept in the process now (a rewrite is running)?"""
    return _depth > 0


@contextmanager
def working_memory():
    """Keep freed memory in the process for the next stage while the block runs
    (module docstring).  Nested and concurrent uses share one setting."""
    global _depth
    libc = _glibc()
    with _lock:
        _depth += 1
        if _depth == 1 and libc is not None:
            libc.mallopt(M_MMAP_THRESHOLD, HELD_MMAP_THRESHOLD)
            libc.mallopt(M_TRIM_THRESHOLD, HELD_TRIM_THRESHOLD)
            libc.mallopt(M_ARENA_MAX, HELD_ARENAS)
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0 and libc is not None:
                libc.mallopt(M_TRIM_THRESHOLD, DEFAULT_TRIM_THRESHOLD)


def _hugepage_switch():
    """numpy's ``_set_madvise_hugepage`` (returns the previous setting), None without it."""
    try:
        from numpy._core import multiarray
    except ImportError:  # numpy 1.x
        from numpy.core import multiarray
    return getattr(multiarray, "_set_madvise_hugepage", None)


@contextmanager
def small_pages():
    """numpy's arrays without transparent huge pages while the block runs (module
    docstring); numpy's own setting is back when the last concurrent use ends.  Only
    arrays allocated inside the block are concerned; elsewhere than Linux it does nothing."""
    global _small_depth, _huge_before
    switch = _hugepage_switch() if sys.platform.startswith("linux") else None
    with _lock:
        _small_depth += 1
        if _small_depth == 1 and switch is not None:
            _huge_before = bool(switch(False))
    try:
        yield
    finally:
        with _lock:
            _small_depth -= 1
            if _small_depth == 0 and switch is not None:
                switch(_huge_before)
