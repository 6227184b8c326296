"""Safe file output (ncopt.runtime.fileio): modes, devices, links, folders, faults, backups, races.

Permission faults are tested twice: for real where permission bits bind (not root), and
with the OSError injected, so that the error path runs on every machine (CI runs as root).
"""

from __future__ import annotations

import errno
import multiprocessing as mp
import os
import stat
import threading
import time
from pathlib import Path

import pytest

from ncopt.runtime import fileio
from ncopt.runtime.errors import FileError, UsageError
from ncopt.runtime.fileio import (TMP_SUFFIX, backups_of, clean_stale_temporaries, output_file,
                          output_target, read_input, replace_in_place, write_output)

ROOT_USER = os.name == "posix" and os.geteuid() == 0


def temporaries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(TMP_SUFFIX))


@pytest.fixture
def umask():
    """Set the process's umask for one test (restored after it)."""
    saved = os.umask(0o022)
    os.umask(saved)
    yield lambda mask: os.umask(mask)
    os.umask(saved)


# ---------------------------------------------------------------- modes ----
@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o027, 0o640), (0o002, 0o664)])
def test_a_new_file_gets_the_mode_the_umask_gives(tmp_path, umask, mask, mode):
    umask(mask)
    out = tmp_path / "new.nc"
    write_output(out, b"G1 X1\n")
    assert stat.S_IMODE(out.stat().st_mode) == mode
    assert out.read_bytes() == b"G1 X1\n" and temporaries(tmp_path) == []


def test_a_replaced_file_keeps_its_mode_and_is_replaced_whole(tmp_path, umask):
    umask(0o077)
    out = tmp_path / "old.nc"
    out.write_bytes(b"old\n")
    out.chmod(0o640)
    inode = out.stat().st_ino
    write_output(out, b"new\n")
    assert out.read_bytes() == b"new\n"
    assert stat.S_IMODE(out.stat().st_mode) == 0o640
    assert out.stat().st_ino != inode  # renamed over, never written in place


# ------------------------------------------------- devices, FIFOs, links ----
def test_a_device_is_written_into_not_replaced(tmp_path):
    write_output(Path(os.devnull), b"G1 X1\n")
    assert stat.S_ISCHR(os.stat(os.devnull).st_mode)


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full here")
def test_a_full_device_is_a_located_error():
    with pytest.raises(FileError) as exc:
        write_output(Path("/dev/full"), b"G1 X1\n" * 10000)
    assert str(exc.value) == ("/dev/full: cannot write the output: No space left on device; "
                              "free some space")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_is_written_into(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    write_output(fifo, b"G1 X1\n")
    reader.join(10)
    assert got == [b"G1 X1\n"]
    assert stat.S_ISFIFO(fifo.lstat().st_mode)


def test_a_symlink_gets_its_target_replaced_not_itself(tmp_path):
    real = tmp_path / "real.nc"
    real.write_bytes(b"old\n")
    real.chmod(0o640)
    link = tmp_path / "link.nc"
    link.symlink_to("real.nc")
    write_output(link, b"new\n")
    assert link.is_symlink() and os.readlink(link) == "real.nc"
    assert real.read_bytes() == b"new\n" and stat.S_IMODE(real.stat().st_mode) == 0o640
    dangling = tmp_path / "dangling.nc"
    dangling.symlink_to("made.nc")
    write_output(dangling, b"made\n")  # as `>` does: the file the link names is made
    assert dangling.is_symlink() and (tmp_path / "made.nc").read_bytes() == b"made\n"
    assert temporaries(tmp_path) == []


def test_a_path_ending_in_a_separator_is_a_folder(tmp_path):
    (tmp_path / "out").mkdir()
    assert output_target(f"{tmp_path}/out/", "cam/part.nc") == tmp_path / "out" / "part.nc"
    assert output_target(f"{tmp_path}/out", "cam/part.nc") == tmp_path / "out" / "part.nc"
    assert output_target(f"{tmp_path}/o.nc", "cam/part.nc") == tmp_path / "o.nc"
    with pytest.raises(FileError) as exc:
        output_target(f"{tmp_path}/newdir/", "part.nc")
    assert str(exc.value) == (f"{tmp_path}/newdir/: no such folder; create it first, or name "
                              "a file (without the trailing /)")
    assert not (tmp_path / "newdir").exists()
    with pytest.raises(UsageError) as exc:
        output_target(f"{tmp_path}/out/", "-")
    assert "give a file name when the program comes from stdin" in str(exc.value)


def test_the_input_itself_is_refused_as_output(tmp_path):
    src = tmp_path / "p.nc"
    src.write_bytes(b"G1 X1\n")
    (tmp_path / "ln.nc").symlink_to(src)
    for output in (str(src), f"{tmp_path}/", str(tmp_path / "ln.nc"), f"{tmp_path}/./p.nc"):
        with pytest.raises(UsageError, match="the output would overwrite the input"):
            output_file(output, str(src))
    assert output_file(None, str(src)) is None and output_file("-", str(src)) is None


# -------------------------------------------------------------- faults ----
@pytest.mark.skipif(ROOT_USER or os.name != "posix", reason="root ignores permission bits "
                    "(the injected variant below runs everywhere)")
def test_a_read_only_file_is_refused(tmp_path):
    out = tmp_path / "ro.nc"
    out.write_bytes(b"keep\n")
    out.chmod(0o444)
    with pytest.raises(FileError) as exc:
        write_output(out, b"new\n")
    assert str(exc.value) == (f"{out}: the file is read-only; nothing written; make it "
                              "writable or write elsewhere")
    assert out.read_bytes() == b"keep\n"


def test_a_read_only_file_is_refused_injected(tmp_path, monkeypatch):
    out = tmp_path / "ro.nc"
    out.write_bytes(b"keep\n")
    monkeypatch.setattr(fileio.os, "access", lambda path, mode: False)
    with pytest.raises(FileError) as exc:
        write_output(out, b"new\n")
    assert str(exc.value) == (f"{out}: the file is read-only; nothing written; make it "
                              "writable or write elsewhere")
    assert out.read_bytes() == b"keep\n" and temporaries(tmp_path) == []


@pytest.mark.parametrize("err, hint", [(errno.EACCES, "check its permissions"),
                                       (errno.EROFS, "the file system is read-only"),
                                       (errno.ENOSPC, "free some space")])
def test_a_folder_that_cannot_be_written_is_blamed_on_the_output(tmp_path, monkeypatch,
                                                                 err, hint):
    def refuse(*args, **kwargs):
        raise OSError(err, os.strerror(err), str(tmp_path / ".x.ncopt-tmp"))

    monkeypatch.setattr(fileio.tempfile, "mkstemp", refuse)
    out = tmp_path / "o.nc"
    with pytest.raises(FileError) as exc:
        write_output(out, b"G1\n")
    assert str(exc.value) == f"{out}: cannot write the output: {os.strerror(err)}; {hint}"


def test_a_failed_rename_leaves_no_temporary(tmp_path, monkeypatch):
    def fail(src, dst):
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(fileio.os, "replace", fail)
    out = tmp_path / "o.nc"
    with pytest.raises(FileError, match="Input/output error"):
        write_output(out, b"G1\n")
    assert list(tmp_path.iterdir()) == []


def test_an_interrupt_while_writing_leaves_no_temporary(tmp_path, monkeypatch):
    def interrupted(fd):
        raise KeyboardInterrupt

    monkeypatch.setattr(fileio.os, "fsync", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_output(tmp_path / "o.nc", b"G1\n")
    assert list(tmp_path.iterdir()) == []


def test_unreadable_and_missing_inputs_name_the_file(tmp_path, monkeypatch):
    with pytest.raises(FileError) as exc:
        read_input(str(tmp_path / "none.nc"))
    assert str(exc.value) == (f"{tmp_path / 'none.nc'}: cannot read the file: No such file or "
                              "directory; check the path")
    with pytest.raises(FileError) as exc:
        read_input(str(tmp_path))
    assert str(exc.value) == (f"{tmp_path}: cannot read the file: Is a directory; give a "
                              "file, not a folder")

    def refuse(self):
        raise PermissionError(errno.EACCES, "Permission denied", str(self))

    monkeypatch.setattr(Path, "read_bytes", refuse)
    with pytest.raises(FileError) as exc:
        read_input(str(tmp_path / "p.nc"))
    assert str(exc.value) == (f"{tmp_path / 'p.nc'}: cannot read the file: Permission denied; "
                              "check its permissions")


def test_stdin_closed_is_an_error(monkeypatch):
    monkeypatch.setattr(fileio.sys, "stdin", None)
    with pytest.raises(FileError) as exc:
        read_input("-")
    assert str(exc.value) == "<stdin>: standard input is closed; give a file name"


# --------------------------------------------------------- temporaries ----
def test_stale_temporaries_are_removed_and_live_ones_kept(tmp_path):
    gone = mp.get_context("fork").Process(target=lambda: None)
    gone.start()
    gone.join()
    names = {"dead": f".p.nc.{gone.pid}-abcd_123{TMP_SUFFIX}",
             "impossible": f".p.nc.99999999-zzzzzzzz{TMP_SUFFIX}",
             "mine": f".p.nc.{os.getpid()}-abcdefgh{TMP_SUFFIX}",
             "old-style-old": f".q.nc.k2j4h5g6{TMP_SUFFIX}",
             "old-style-new": f".q.nc.a1b2c3d4{TMP_SUFFIX}",
             "not-ours": ".p.nc.swp"}
    for name in names.values():
        (tmp_path / name).write_bytes(b"partial")
    hour_ago = time.time() - 2 * fileio.STALE_AFTER_S
    os.utime(tmp_path / names["old-style-old"], (hour_ago, hour_ago))
    write_output(tmp_path / "p.nc", b"G1\n")  # the next run in the folder cleans up
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted([names["mine"], names["old-style-new"], names["not-ours"], "p.nc"])
    assert clean_stale_temporaries(tmp_path / "none") == 0


# ------------------------------------------------------------ in place ----
def test_in_place_keeps_every_version_and_never_overwrites_a_backup(tmp_path):
    prog = tmp_path / "p.nc"
    prog.write_bytes(b"v1\n")
    prog.chmod(0o640)
    os.utime(prog, (1e9, 1e9))
    assert replace_in_place(prog, b"v1\n", b"r1\n") == tmp_path / "p.nc.bak"
    backup = (tmp_path / "p.nc.bak").stat()
    assert backup.st_mtime == 1e9 and stat.S_IMODE(backup.st_mode) == 0o640  # as it was
    assert backup.st_nlink == 1  # a file of its own, not a second name of the program
    assert prog.read_bytes() == b"r1\n" and stat.S_IMODE(prog.stat().st_mode) == 0o640
    # the rewrite replaced again (other options): kept after the original
    assert replace_in_place(prog, b"r1\n", b"r2\n") == tmp_path / "p.nc.1.bak"
    # a version a backup holds already gets no second backup
    prog.write_bytes(b"v1\n")
    assert replace_in_place(prog, b"v1\n", b"r3\n") is None
    assert [p.name for p in backups_of(prog)] == ["p.nc.bak", "p.nc.1.bak"]
    assert [p.read_bytes() for p in backups_of(prog)] == [b"v1\n", b"r1\n"]
    # nothing to change: nothing touched
    assert replace_in_place(prog, b"r3\n", b"r3\n") is None
    assert temporaries(tmp_path) == []


def test_in_place_never_overwrites_a_users_own_backup(tmp_path):
    prog = tmp_path / "p.nc"
    prog.write_bytes(b"mine\n")
    (tmp_path / "p.nc.bak").write_bytes(b"a backup my editor made\n")
    (tmp_path / "p.nc.9.bak").write_bytes(b"an older one\n")
    assert replace_in_place(prog, b"mine\n", b"new\n") == tmp_path / "p.nc.10.bak"
    assert (tmp_path / "p.nc.bak").read_bytes() == b"a backup my editor made\n"
    assert (tmp_path / "p.nc.10.bak").read_bytes() == b"mine\n"
    assert [p.name for p in backups_of(prog)] == ["p.nc.bak", "p.nc.9.bak", "p.nc.10.bak"]


def test_in_place_without_hard_links_copies(tmp_path, monkeypatch):
    prog = tmp_path / "p.nc"
    prog.write_bytes(b"v1\n")

    def no_links(src, dst):
        raise OSError(errno.EPERM, "Operation not permitted")

    monkeypatch.setattr(fileio.os, "link", no_links)
    assert replace_in_place(prog, b"v1\n", b"r1\n") == tmp_path / "p.nc.bak"
    assert (tmp_path / "p.nc.bak").read_bytes() == b"v1\n" and prog.read_bytes() == b"r1\n"
    assert temporaries(tmp_path) == []


def test_in_place_leaves_a_file_that_changed_since_it_was_read(tmp_path):
    prog = tmp_path / "p.nc"
    prog.write_bytes(b"the CAM wrote this meanwhile\n")
    with pytest.raises(FileError) as exc:
        replace_in_place(prog, b"what ncopt planned from\n", b"rewrite\n")
    assert str(exc.value) == (f"{prog}: changed since ncopt read it (another ncopt run, or the "
                              "CAM wrote it again); left as it is; run again")
    assert prog.read_bytes() == b"the CAM wrote this meanwhile\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.nc"]
    # the same rewrite already there (another run did it): fine, nothing to do
    prog.write_bytes(b"rewrite\n")
    assert replace_in_place(prog, b"what ncopt planned from\n", b"rewrite\n") is None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.nc"]


def test_in_place_refuses_links_and_read_only_files(tmp_path, monkeypatch):
    real = tmp_path / "real.nc"
    real.write_bytes(b"v1\n")
    link = tmp_path / "link.nc"
    link.symlink_to(real)
    with pytest.raises(FileError, match="is a symbolic link; ncopt replaces no file through a "
                                        "link in place"):
        replace_in_place(link, b"v1\n", b"r1\n")
    monkeypatch.setattr(fileio.os, "access", lambda path, mode: False)
    with pytest.raises(FileError) as exc:
        replace_in_place(real, b"v1\n", b"r1\n")
    assert str(exc.value) == (f"{real}: the file is read-only; left as it is; make it "
                              "writable to rewrite it in place")
    assert real.read_bytes() == b"v1\n" and sorted(p.name for p in tmp_path.iterdir()) == [
        "link.nc", "real.nc"]


def _race(path: str, data: bytes, start, results) -> None:
    start.wait()
    try:
        replace_in_place(Path(path), b"original\n", data)
        results.put(("ok", data))
    except FileError as exc:
        results.put(("refused", str(exc)))


@pytest.mark.skipif(os.name != "posix", reason="fork")
def test_two_runs_at_once_cannot_both_replace_a_file(tmp_path):
    ctx = mp.get_context("fork")
    for attempt in range(5):
        prog = tmp_path / f"p{attempt}.nc"
        prog.write_bytes(b"original\n")
        start, results = ctx.Barrier(2), ctx.Queue()
        runs = [ctx.Process(target=_race, args=(str(prog), data, start, results))
                for data in (b"rewrite A\n", b"rewrite B\n")]
        for r in runs:
            r.start()
        outcomes = sorted(results.get(timeout=30) for _ in runs)
        for r in runs:
            r.join(30)
        kinds = [k for k, _ in outcomes]
        assert kinds == ["ok", "refused"], outcomes
        winner = next(d for k, d in outcomes if k == "ok")
        assert prog.read_bytes() == winner
        assert "changed since ncopt read it" in next(d for k, d in outcomes if k == "refused")
        assert [p.read_bytes() for p in backups_of(prog)] == [b"original\n"]
    assert temporaries(tmp_path) == []


@pytest.mark.skipif(not ROOT_USER, reason="only root may give a file to another user")
def test_in_place_keeps_the_owner_where_it_may(tmp_path):
    prog = tmp_path / "p.nc"
    prog.write_bytes(b"v1\n")
    os.chown(prog, 1234, 5678)
    replace_in_place(prog, b"v1\n", b"r1\n")
    for path in (prog, tmp_path / "p.nc.bak"):
        st = path.stat()
        assert (st.st_uid, st.st_gid) == (1234, 5678), path
    out = tmp_path / "o.nc"
    out.write_bytes(b"old\n")
    os.chown(out, 1234, 5678)
    write_output(out, b"new\n")  # a replaced output keeps its owner too
    assert (out.stat().st_uid, out.stat().st_gid) == (1234, 5678)


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux's /proc")
def test_a_temporary_of_an_ended_unreaped_process_is_stale(tmp_path):
    """A batch worker killed with its parent stays a zombie until init reaps it (in some
    containers never): its temporary must still count as stale."""
    import subprocess
    import sys
    import time

    from ncopt.runtime import fileio

    child = subprocess.Popen([sys.executable, "-c", "pass"])
    t0 = time.monotonic()
    while time.monotonic() - t0 < 10:  # ended, not yet waited for: a zombie
        state = Path(f"/proc/{child.pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        if state == "Z":
            break
        time.sleep(0.01)
    try:
        assert state == "Z"
        tmp = tmp_path / f".p.nc.{child.pid}-abcd1234{fileio.TMP_SUFFIX}"
        tmp.write_bytes(b"partial")
        live = tmp_path / f".q.nc.{os.getpid()}-abcd1234{fileio.TMP_SUFFIX}"
        live.write_bytes(b"being written")
        assert fileio.clean_stale_temporaries(tmp_path) == 1
        assert not tmp.exists() and live.exists()
    finally:
        child.wait()
