"""Freed memory handed back between stages (glibc's malloc_trim), and kept in the
process while a rewrite runs."""

from __future__ import annotations

import platform
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from ncopt.runtime import memory
from ncopt.runtime.memory import _malloc_trim, release_freed_memory


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


_GLIBC = sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc"


@pytest.mark.skipif(not _GLIBC, reason="the thresholds are glibc's")
def test_while_a_rewrite_runs_large_arrays_come_from_the_heap():
    # in a fresh process: glibc's threshold has not grown yet, so a 24 MB array gets a
    # mapping of its own; held, the next one comes from the heap
    code = textwrap.dedent("""
        import ctypes, numpy as np
        from ncopt.runtime import memory
        class Info(ctypes.Structure):
            _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks",
                        "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks", "keepcost")]
        libc = ctypes.CDLL(None)
        libc.mallinfo2.restype = Info
        mapped = lambda: libc.mallinfo2().hblkhd
        m0 = mapped(); own = np.ones(3 << 20); m1 = mapped()
        with memory.working_memory():
            held = np.ones(3 << 20); m2 = mapped()
        print((m1 - m0) >> 20, (m2 - m1) >> 20)
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["24", "0"]


@pytest.mark.skipif(not _GLIBC, reason="malloc_trim is glibc's")
def test_freed_memory_stays_while_held_and_goes_back_after():
    kept = [np.ones(1 << 17) for _ in range(200)]  # 200 x 1 MB
    with memory.working_memory():
        assert memory.holding()
        kept = kept[1::2]  # holes: ~100 MB freed
        rss = _rss_kb()
        release_freed_memory()  # does nothing while held
        assert _rss_kb() > rss - 10_000
    assert not memory.holding()
    release_freed_memory()
    assert _rss_kb() < rss - 50_000
    assert len(kept) == 100


def test_working_memory_nests_and_ends_on_errors():
    with memory.working_memory():
        with memory.working_memory():
            assert memory.holding()
        assert memory.holding()
    assert not memory.holding()
    with pytest.raises(ZeroDivisionError):
        with memory.working_memory():
            1 / 0
    assert not memory.holding()


def test_a_rewrite_holds_its_memory_up_to_the_verification(monkeypatch):
    from ncopt import api
    from ncopt.model import Cutter, Machine

    seen = []
    for name in ("read_text", "interpret", "verify"):
        real = getattr(api, name)

        def spy(*a, _real=real, _name=name, **k):
            seen.append((_name, memory.holding()))
            return _real(*a, **k)
        monkeypatch.setattr(api, name, spy)
    text = Path(__file__).resolve().parents[2].joinpath("samples", "bowl.mpf").read_bytes()
    job = api.Job(cutter=Cutter(16.0, 2), machine=Machine(accel_rad_s2=227.0, max_rpm=15000.0))
    api.rewrite_text(text[:120_000].decode("latin-1").rsplit("\n", 1)[0] + "\nM30\n", job,
                     "bowl.mpf")
    # the verification (and its parse of the output) is the peak: it hands memory back
    assert seen == [("read_text", True), ("interpret", True), ("verify", False),
                    ("read_text", False)]
    assert not memory.holding()


def test_the_mesh_is_freed_once_the_contacts_are_found(monkeypatch, bowl_stl):
    # ~700 MB at 1M triangles: nothing may keep it through the edits and the verification
    import gc
    import weakref
    from concurrent.futures import ThreadPoolExecutor

    from ncopt import api
    from ncopt.contacts.geometry import MeshIndex, load_stl
    from ncopt.model import Cutter, Machine

    alive, refs = [], []
    real = api.block_targets

    def spy(*a, **k):  # called right after the contacts
        gc.collect()
        alive.append(refs[0]() is not None)
        return real(*a, **k)
    monkeypatch.setattr(api, "block_targets", spy)

    def load():
        index = MeshIndex(load_stl(bowl_stl))
        refs.append(weakref.ref(index))
        return index
    text = Path(__file__).resolve().parents[2].joinpath("samples", "bowl.mpf").read_bytes()
    text = text[:120_000].decode("latin-1").rsplit("\n", 1)[0] + "\nM30\n"
    job = api.Job(cutter=Cutter(16.0, 2), machine=Machine(accel_rad_s2=227.0, max_rpm=15000.0))
    with ThreadPoolExecutor(1) as pool:  # as rewrite_file passes it: no other reference
        api.rewrite_text(text, job, "bowl.mpf", pool.submit(load))
    assert alive == [False]


def _huge_pages() -> bool:
    """numpy's current madvise-hugepage setting (read by setting it back at once)."""
    switch = memory._hugepage_switch()
    before = switch(True)
    switch(before)
    return bool(before)


_LINUX = pytest.mark.skipif(not sys.platform.startswith("linux"),
                            reason="numpy marks huge pages on Linux only")


@_LINUX
@pytest.mark.parametrize("before", [True, False])
def test_small_pages_turns_numpy_huge_pages_off_and_back(before):
    switch = memory._hugepage_switch()
    assert switch is not None  # numpy >= 1.19 has it
    original = switch(before)
    try:
        with memory.small_pages():
            assert not _huge_pages()
            with memory.small_pages():
                assert not _huge_pages()
            assert not _huge_pages()  # the outer block still runs
        assert _huge_pages() is before
        with pytest.raises(ZeroDivisionError):
            with memory.small_pages():
                1 / 0
        assert _huge_pages() is before
    finally:
        switch(original)


@_LINUX
def test_a_rewrite_runs_on_small_pages_and_gives_numpy_its_setting_back(monkeypatch, bowl_stl,
                                                                        tmp_path):
    # on the 2-core machine huge-page faults cost ~1 s of system time per rewrite
    from ncopt import api
    from ncopt.model import Cutter, Machine

    seen = []
    for name in ("read_text", "interpret", "verify", "_mesh_index"):
        real = getattr(api, name)

        def spy(*a, _real=real, _name=name, **k):
            seen.append((_name, _huge_pages()))
            return _real(*a, **k)
        monkeypatch.setattr(api, name, spy)
    text = Path(__file__).resolve().parents[2].joinpath("samples", "bowl.mpf").read_bytes()
    path = tmp_path / "bowl.mpf"
    path.write_bytes(text[:120_000].rsplit(b"\n", 1)[0] + b"\nM30\n")
    job = api.Job(cutter=Cutter(16.0, 2), machine=Machine(accel_rad_s2=227.0, max_rpm=15000.0))
    switch = memory._hugepage_switch()
    original = switch(True)  # numpy's default on Linux 4.6 and later
    try:
        api.rewrite_file(path, job, mesh_path=bowl_stl)
        assert _huge_pages()
    finally:
        switch(original)
    assert sorted(set(seen)) == [("_mesh_index", False), ("interpret", False),
                                 ("read_text", False), ("verify", False)]
