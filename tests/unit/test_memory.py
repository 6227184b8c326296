"""Freed memory handed back between stages (glibc's malloc_trim)."""

from __future__ import annotations

import platform
import sys

import numpy as np
import pytest

from ncopt.memory import _malloc_trim, release_freed_memory


def _rss_kb() -> int:
    with open("/proc/self/status") as fh:
        return next(int(line.split()[1]) for line in fh if line.startswith("VmRSS:"))


@pytest.mark.skipif(not (sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc"),
                    reason="malloc_trim is glibc's")
def test_freed_heap_pages_go_back_to_the_system():
    """Many 1 MB arrays come from the heap once glibc's mmap threshold has grown: freed,
    their pages stay in the process until they are trimmed."""
    assert _malloc_trim() is not None
    big = np.ones(2 << 20)  # 16 MB freed: the mmap threshold grows to its size
    del big
    kept = [np.ones(1 << 17) for _ in range(200)]  # 200 x 1 MB, now from the heap
    kept = kept[1::2]  # free every other one: holes the heap cannot shrink past
    before = _rss_kb()
    release_freed_memory()
    assert _rss_kb() < before - 50_000  # ~100 MB of holes handed back
    assert len(kept) == 100


def test_release_is_harmless_anywhere():
    release_freed_memory()
    release_freed_memory()
