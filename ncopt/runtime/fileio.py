"""Reading programs and writing files so that nothing the user owns is lost.

* A file is never half-written: the bytes go to a hidden temporary in the target's
  folder (``.NAME.PID-XXXXXXXX.ncopt-tmp``), are flushed to disk and renamed over the
  target.  A run killed before the rename leaves only that temporary; the next ncopt
  run that writes into the folder removes temporaries whose process is gone.
* A new file gets the mode a new file normally gets (0666 less the umask); a file that
  is replaced keeps its mode, and its owner where the user may set it.
* ``-o`` onto a device or a FIFO writes into it, as the shell's ``>`` would; onto a
  symbolic link it replaces the file the link points to; a read-only file is refused.
* In place, the version replaced is kept as a backup under the next name of
  ``NAME.bak``, ``NAME.1.bak``, ``NAME.2.bak``, ... (so ``NAME.bak`` holds the first
  original, and later versions follow in order): no backup is ever overwritten or
  removed, and none is made of a version a backup already holds byte for byte.  An
  exclusive lock on the file and a compare with the bytes that were planned make two
  runs at once safe: a file that changed since it was read is left as it is.  Only a
  regular file counts as a backup: a ``NAME.bak`` that is a symbolic link (to the program
  itself, say) holds nothing, and a backup is given its name by a hard link, which never
  follows or replaces a link that has the name already.
* Every file a run writes is checked before any work starts (:func:`guard_outputs`):
  never one of the run's inputs (the program, the original it is compared with, the
  mesh, the profile file; stdin read from a file), compared by device and inode through
  links; never another output of the same run; never a backup's name.
* A FIFO given as input that no program writes into is refused after
  :data:`FIFO_WAIT_S` seconds, rather than waited on for ever.
"""

from __future__ import annotations

import errno
import os
import re
import select
import stat
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator

from ncopt.runtime.errors import FileError, UsageError

TMP_SUFFIX = ".ncopt-tmp"
STALE_AFTER_S = 3600.0  # a temporary whose writer cannot be asked is stale after an hour
FIFO_WAIT_S = 10.0  # a FIFO given as input with no writer is refused after this long
_TMP_PID = re.compile(r"\.(\d+)-[a-z0-9_]+" + re.escape(TMP_SUFFIX) + "$")
_HINTS = {errno.ENOENT: "check the path", errno.EACCES: "check its permissions",
          errno.EPERM: "check its permissions", errno.EROFS: "the file system is read-only",
          errno.ENOSPC: "free some space", errno.EDQUOT: "free some space (disk quota)",
          errno.EISDIR: "give a file, not a folder", errno.ENOTDIR: "check the path",
          errno.EPIPE: "the reading end of the pipe was closed before the output was complete"}


def hint(exc: OSError) -> str:
    """What the user can do about an OSError, by its errno."""
    return _HINTS.get(exc.errno, "check the path and its permissions")


def read_input(name: str) -> bytes:
    """A program's bytes: a file, or stdin for ``-``; raises FileError naming it."""
    if name == "-":
        if sys.stdin is None:
            raise FileError("standard input is closed; give a file name", "<stdin>")
        try:
            return sys.stdin.buffer.read()
        except OSError as exc:
            raise FileError(f"cannot read standard input: {exc.strerror}", "<stdin>") from None
    try:
        if _stat_kind(name) == stat.S_IFIFO and os.name == "posix":
            return _read_fifo(name)
        return Path(name).read_bytes()
    except OSError as exc:
        raise FileError(f"cannot read the file: {exc.strerror}; {hint(exc)}", name) from None


def _read_fifo(name: str) -> bytes:
    """A FIFO's bytes (a named pipe, or a shell's ``<(command)``), refused when no program
    has written into it, nor holds it open to write, after :data:`FIFO_WAIT_S`: opening
    it for reading would otherwise wait for a writer for ever."""
    fd = os.open(name, os.O_RDONLY | os.O_NONBLOCK)  # never waits for a writer
    try:
        poller = select.poll()
        poller.register(fd, select.POLLIN | select.POLLHUP)
        first = b""
        if not poller.poll(int(FIFO_WAIT_S * 1000)):
            try:
                first = os.read(fd, 1 << 16)
            except BlockingIOError:  # a writer holds it open, nothing written yet: wait
                first = None
            if first == b"":
                raise FileError(f"is a FIFO (named pipe) that nothing wrote into for "
                                f"{FIFO_WAIT_S:g} s; start the program that writes it "
                                "first, or give a file", name)
        os.set_blocking(fd, True)
        chunks = [first] if first else []
        while chunk := os.read(fd, 1 << 20):
            chunks.append(chunk)
        return b"".join(chunks)
    finally:
        os.close(fd)


def output_file(output: str | None, input_name: str) -> Path | None:
    """The file a rewrite's ``-o`` names (None: stdout), refused when it is the input."""
    if output is None or output == "-":
        return None
    target = output_target(output, input_name)
    if input_name != "-" and same_file(target, input_name):
        raise UsageError("the output would overwrite the input; write to another file "
                         "(or use ncopt batch --in-place, which keeps a backup)", output)
    return target


def output_target(output: str, input_name: str) -> Path:
    """The file ``-o OUTPUT`` names: OUTPUT, or the input's name inside OUTPUT when OUTPUT
    is a folder (one that exists, or any path ending in a separator)."""
    ends_as_folder = output.endswith(("/", os.sep))
    if not ends_as_folder and not os.path.isdir(output):
        return Path(output)
    if input_name == "-":
        raise UsageError("-o names a folder; give a file name when the program comes from "
                         "stdin", output)
    if not os.path.isdir(output):
        raise FileError("no such folder; create it first, or name a file (without the "
                        "trailing /)", output)
    return Path(output) / Path(input_name).name


def same_file(a: str | Path, b: str | Path) -> bool:
    """Whether two paths name the same existing file (through links, '.' and '..')."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def identity(path: str | Path) -> tuple[int, int] | None:
    """The file a path names, (device, inode), through links; None where there is none
    (or it is no regular file: a device or a FIFO is written into, never replaced)."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return (st.st_dev, st.st_ino) if stat.S_ISREG(st.st_mode) else None


def stdin_identity() -> tuple[int, int] | None:
    """The file stdin reads (``ncopt rewrite - < FILE``), or None (a pipe, a terminal)."""
    try:
        st = os.fstat(sys.stdin.fileno())
    except (OSError, ValueError, AttributeError):
        return None
    return (st.st_dev, st.st_ino) if stat.S_ISREG(st.st_mode) else None


def guard_outputs(inputs: Iterable[tuple[str, object]], outputs: Iterable[tuple[str, object]],
                  in_place: Iterable[Path] = ()) -> None:
    """Refuse, before any work, a run that would write over what it reads or writes twice.

    ``inputs``: (what, path) of every file the run reads (``-``: stdin; None: not given);
    ``outputs``: (option, path) of every file it writes (None and ``-`` are stdout or not
    given); ``in_place``: programs replaced in place (their backups are written beside
    them).  An output may not be an input (the same file, through links and hard links),
    nor another output, nor one of the names a backup of ``in_place`` takes
    (``NAME.bak``, ``NAME.1.bak``, ...).  Raises UsageError naming the output.
    """
    read: dict[tuple, tuple[str, str]] = {}
    for what, path in inputs:
        if path is None:
            continue
        key = stdin_identity() if str(path) == "-" else identity(path)
        if key is not None:
            read.setdefault(key, (what, "-" if str(path) == "-" else str(path)))
    replaced: dict[str, list[str]] = {}  # folder -> names of the programs replaced there
    for p in map(Path, in_place):
        replaced.setdefault(_real(p.parent), []).append(p.name)
    written: dict[object, str] = {}
    for option, path in outputs:
        if path is None or str(path) == "-":
            continue
        key = identity(path)
        if key is not None and key in read:
            what, name = read[key]
            shown = ("the file standard input reads the program from" if name == "-"
                     else f"the {what} {name}")
            raise UsageError(f"{option} names {shown}: writing it would destroy what ncopt "
                             "reads; write to another file", str(path))
        if _stat_kind(path) not in (None, stat.S_IFREG):  # a device, a FIFO: written into
            continue
        real = Path(_real(path))
        if any(_is_backup_name(real.name, name) for name in replaced.get(str(real.parent), ())):
            raise UsageError(f"{option} names a backup ({real.name}) of a program this run "
                             "replaces in place: a backup is never overwritten; write to "
                             "another file", str(path))
        for k in (key, str(real)):
            if k is not None and k in written:
                raise UsageError(f"{option} and {written[k]} name the same file: one would "
                                 "replace the other; give each its own", str(path))
        for k in (key, str(real)):
            if k is not None:
                written[k] = option


def _is_backup_name(name: str, program: str) -> bool:
    """Whether ``name`` is one of the names a backup of ``program`` takes."""
    return re.fullmatch(re.escape(program) + r"(?:\.\d+)?\.bak", name) is not None


def _real(path) -> str:
    return os.path.realpath(os.path.abspath(path))


def _stat_kind(path) -> int | None:
    try:
        return stat.S_IFMT(os.stat(path).st_mode)
    except (OSError, ValueError):
        return None


def write_output(target: Path, data: bytes, make_parents: bool = False) -> None:
    """Write ``data`` to ``target`` as ``-o`` does (see the module notes); ``make_parents``
    creates missing folders (a batch's mirrored subfolders)."""
    try:
        if make_parents:
            target.parent.mkdir(parents=True, exist_ok=True)
        st = _stat(target)
        if st is not None and not stat.S_ISREG(st.st_mode):
            if stat.S_ISDIR(st.st_mode):
                raise FileError("is a folder; name a file", str(target))
            with open(target, "wb") as handle:  # a device or FIFO: into it, as `>` does
                handle.write(data)
            return
        real = Path(os.path.realpath(target))
        if st is not None and not os.access(real, os.W_OK):
            raise FileError("the file is read-only; nothing written; make it writable or "
                            "write elsewhere", str(target))
        mode = stat.S_IMODE(st.st_mode) if st is not None else new_file_mode()
        owner = (st.st_uid, st.st_gid) if st is not None else None
        clean_stale_temporaries(real.parent)
        tmp = write_temporary(real, data, mode, owner)
        _commit(tmp, real)
    except OSError as exc:
        raise FileError(f"cannot write the output: {exc.strerror}; {hint(exc)}",
                        str(target)) from None


def replace_in_place(path: Path, planned_from: bytes, data: bytes) -> Path | None:
    """Replace the program at ``path`` with ``data``, keeping the version replaced.

    ``planned_from`` is the bytes the rewrite was made from: a file that no longer holds
    them (another run, or the CAM, wrote it meanwhile) is left as it is (FileError),
    unless it already holds ``data``.  Returns the backup made, or None when none was
    needed.
    """
    if os.path.islink(path):
        raise FileError("is a symbolic link; ncopt replaces no file through a link in place; "
                        "rewrite the file it points to", str(path))
    if data == planned_from:
        return None
    try:
        st = os.stat(path)
        if not os.access(path, os.W_OK):
            raise FileError("the file is read-only; left as it is; make it writable to "
                            "rewrite it in place", str(path))
        clean_stale_temporaries(path.parent)
        tmp = write_temporary(path, data, stat.S_IMODE(st.st_mode), (st.st_uid, st.st_gid))
        try:
            with _locked(path) as current:
                if current == data:  # another run did the same already
                    discard(tmp)
                    return None
                if current is None or current != planned_from:
                    raise FileError("changed since ncopt read it (another ncopt run, or the "
                                    "CAM wrote it again); left as it is; run again", str(path))
                backup = keep_version(path, current)
                os.replace(tmp, path)
                return backup
        except BaseException:
            discard(tmp)
            raise
    except OSError as exc:
        raise FileError(f"cannot replace the file: {exc.strerror}; {hint(exc)}",
                        str(path)) from None


def backups_of(path: Path) -> list[Path]:
    """The names of ncopt's backups of a program, oldest first: NAME.bak, NAME.1.bak, ...
    (whatever each is: :func:`keep_version` counts only regular files as backups)."""
    pattern = re.compile(re.escape(path.name) + r"(?:\.(\d+))?\.bak$")
    try:
        names = os.listdir(path.parent)
    except OSError:
        return []
    found = [(int(m[1] or 0), name) for name in names if (m := pattern.fullmatch(name))]
    return [path.parent / name for _, name in sorted(found)]


def keep_version(path: Path, current: bytes) -> Path | None:
    """Keep the version at ``path`` (whose bytes are ``current``) as a new backup after
    the others, unless a backup already holds it; the backup made, or None.

    The backup is a copy with the program's mode and times, never a second name of the
    program's own file: a run killed before the program is replaced must not leave the
    backup sharing a file that a CAM system then overwrites in place.
    """
    kept = backups_of(path)
    for backup in kept:
        if _holds(backup, current):
            return None
    number = _backup_number(kept[-1], path) + 1 if kept else 0
    st = os.stat(path)
    tmp = write_temporary(path, current, stat.S_IMODE(st.st_mode), (st.st_uid, st.st_gid))
    try:
        os.utime(tmp, ns=(st.st_atime_ns, st.st_mtime_ns))
        while True:
            name = path.with_name(path.name + (f".{number}" if number else "") + ".bak")
            if _rename_unless_taken(tmp, name):
                return name
            number += 1
    finally:
        discard(tmp)


def _holds(backup: Path, current: bytes) -> bool:
    """Whether ``backup`` is a regular file of its own (not a symbolic link: one to the
    program itself would seem to hold its bytes until the program is replaced) that
    holds ``current``."""
    try:
        st = os.lstat(backup)
        if not stat.S_ISREG(st.st_mode) or st.st_size != len(current):
            return False
        return backup.read_bytes() == current
    except OSError:
        return False


def _backup_number(backup: Path, path: Path) -> int:
    middle = backup.name[len(path.name):-len(".bak")]
    return int(middle[1:]) if middle else 0


def _rename_unless_taken(tmp: Path, name: Path) -> bool:
    """Give the temporary the name unless a file has it (a hard link fails then, all in
    one step; where the file system has none, the lock on the program keeps other ncopt
    runs out between the check and the rename)."""
    try:
        os.link(tmp, name)
        return True
    except FileExistsError:
        return False
    except OSError:
        pass
    if os.path.lexists(name):
        return False
    os.rename(tmp, name)
    return True


@contextmanager
def _locked(path: Path) -> Iterator[bytes | None]:
    """Hold an exclusive lock on the program and give its current bytes; None when the
    file was replaced while this run waited for the lock."""
    if os.name != "posix":
        with _lock_file(path):
            yield path.read_bytes()
        return
    import fcntl

    with open(path, "rb") as handle:
        try:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX)
        except OSError:  # a file system without locks: the compare below still holds
            pass
        replaced = os.fstat(handle.fileno()).st_ino != os.stat(path).st_ino
        yield None if replaced else handle.read()


@contextmanager
def _lock_file(path: Path, wait_s: float = 30.0) -> Iterator[None]:
    """Windows: a lock file created exclusively next to the program (the program itself
    cannot stay open while it is replaced there)."""
    lock = path.with_name(f".{path.name}.ncopt-lock")
    deadline = time.monotonic() + wait_s
    while True:
        try:
            os.close(os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            break
        except FileExistsError:
            if _age_s(lock) > STALE_AFTER_S or time.monotonic() > deadline:
                lock.unlink(missing_ok=True)
            time.sleep(0.05)
    try:
        yield
    finally:
        lock.unlink(missing_ok=True)


def write_temporary(target: Path, data: bytes, mode: int, owner: tuple | None) -> Path:
    """``data`` in a new hidden temporary next to ``target``, on disk, with ``mode``."""
    fd, name = tempfile.mkstemp(prefix=f".{target.name}.{os.getpid()}-", suffix=TMP_SUFFIX,
                                dir=target.parent)
    tmp = Path(name)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, mode)
        if owner is not None and hasattr(os, "chown"):
            try:
                os.chown(tmp, *owner)
            except OSError:  # only root may give a file away; the mode still holds
                pass
        return tmp
    except BaseException:
        discard(tmp)
        raise


def _commit(tmp: Path, target: Path) -> None:
    try:
        os.replace(tmp, target)
    except BaseException:
        discard(tmp)
        raise


def discard(tmp: Path) -> None:
    """Remove a temporary of ours; never fails."""
    try:
        os.unlink(tmp)
    except OSError:
        pass


def clean_stale_temporaries(folder: Path) -> int:
    """Remove ncopt's temporaries in ``folder`` whose writing process is gone; the count."""
    removed = 0
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return 0
    for entry in entries:
        if entry.name.startswith(".") and entry.name.endswith(TMP_SUFFIX) and _stale(entry):
            try:
                os.unlink(entry.path)
                removed += 1
            except OSError:
                pass
    return removed


def _stale(entry: os.DirEntry) -> bool:
    m = _TMP_PID.search(entry.name)
    if m is not None and os.name == "posix":
        return not _alive(int(m[1]))
    return _age_s(entry.path) > STALE_AFTER_S


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    if not 0 < pid < 2 ** 22:  # above Linux's highest pid: no process
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return not _zombie(pid)


def _zombie(pid: int) -> bool:
    """The process has ended and waits to be reaped (a worker of a killed batch, until
    init reaps it; some containers' first process never does): its temporary is stale."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            return fh.read().rsplit(b")", 1)[1].split()[0] == b"Z"
    except (OSError, IndexError):
        return False  # no /proc (not Linux): alive as kill(pid, 0) says


def _age_s(path) -> float:
    try:
        return time.time() - os.stat(path).st_mtime
    except OSError:
        return 0.0


def _stat(path: Path) -> os.stat_result | None:
    try:
        return os.stat(path)
    except FileNotFoundError:
        return None


def new_file_mode() -> int:
    """The mode a new file gets here: 0666 less the process's umask."""
    return 0o666 & ~_umask()


def _umask() -> int:
    try:  # Linux says it without changing it
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
