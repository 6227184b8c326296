"""Every fault a user can hit is one located line and a documented exit code, never a
traceback: closed and full stdout, unreadable inputs and config folders, read-only
outputs, devices, SIGTERM.

Real processes where the fault lives in the process (pipes, closed descriptors, signals);
permission faults run for real with permission bits binding (as root the child drops the
capabilities that let root ignore them, see conftest.obeys_permissions) and again
in-process with the OSError injected.
"""

from __future__ import annotations

import errno
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from ncopt.cli.app import Exit, app
from programs import dome

SPINDLE = ["--diameter", "6", "--accel", "227", "--max-rpm", "15000"]
PIPE_CLOSED = ("<stdout>: cannot write the output: Broken pipe; the reading end of the pipe "
               "was closed before the output was complete")
UNREADABLE_PROFILE = ("cannot read the profile: Permission denied; check the folder's "
                      "permissions, or point HOME (or XDG_CONFIG_HOME) at a folder of this "
                      "user (sudo -H)")


@pytest.fixture
def prog(tmp_path) -> Path:
    path = tmp_path / "dome.nc"
    path.write_bytes(dome(12))
    return path


@pytest.fixture
def big(tmp_path) -> Path:
    """A program whose rewrite (132 KB) does not fit in a pipe (64 KB)."""
    path = tmp_path / "dome.nc"
    path.write_bytes(dome(60))
    return path


def ncopt(args, tmp_path, **kwargs) -> subprocess.Popen:
    env = {**os.environ, "NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100",
           "XDG_CONFIG_HOME": str(tmp_path / "config"), **kwargs.pop("env", {})}
    return subprocess.Popen([sys.executable, "-c", "from ncopt.cli.app import main; main()",
                             *[str(a) for a in args]], env=env, cwd=tmp_path, **kwargs)


def run(args, tmp_path, **kwargs) -> subprocess.CompletedProcess:
    proc = ncopt(args, tmp_path, stdout=kwargs.pop("stdout", subprocess.PIPE),
                 stderr=subprocess.PIPE, **kwargs)
    out, err = proc.communicate(timeout=120)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err.decode())


def invoke(args, env=None):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100", **(env or {})})
    result = runner.invoke(app, [str(a) for a in args], catch_exceptions=False)
    assert "Traceback" not in result.stderr
    return result


# --------------------------------------------------------------------- stdout ----
@pytest.mark.parametrize("read_first", [True, False], ids=["head -1", "true"])
def test_a_closed_pipe_is_one_line_and_exit_7(big, tmp_path, read_first):
    proc = ncopt(["rewrite", big, *SPINDLE], tmp_path, stdout=subprocess.PIPE,
                 stderr=subprocess.PIPE)
    if read_first:
        assert proc.stdout.readline().startswith(b"(")
    proc.stdout.close()  # the reader is gone
    err = proc.stderr.read().decode()
    proc.wait(120)
    assert proc.returncode == Exit.IO, err
    assert err == PIPE_CLOSED + "\n"


def test_diff_into_a_closed_pipe_ends_quietly(big, tmp_path):
    opt = tmp_path / "opt.nc"
    assert run(["rewrite", big, *SPINDLE, "-o", opt, "-q"], tmp_path).returncode == 0
    proc = ncopt(["diff", big, opt], tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout.readline().startswith(b"--- ")
    proc.stdout.close()
    err = proc.stderr.read().decode()
    proc.wait(120)
    assert (proc.returncode, err) == (1, "")  # they differ; the reader saw what it wanted


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full here")
def test_a_full_stdout_is_one_line_and_exit_7(big, tmp_path):
    prog = big
    with open("/dev/full", "wb") as full:
        result = run(["rewrite", prog, *SPINDLE], tmp_path, stdout=full)
    assert result.returncode == Exit.IO
    assert result.stderr == ("<stdout>: cannot write the output: No space left on device; "
                             "free some space\n")
    with open("/dev/full", "wb") as full:  # -o onto the device writes into it: same fault
        result = run(["rewrite", prog, *SPINDLE, "-o", "/dev/full"], tmp_path, stdout=full)
    assert result.returncode == Exit.IO
    assert result.stderr == ("/dev/full: cannot write the output: No space left on device; "
                             "free some space\n")


def test_a_closed_stdout_is_one_line_and_exit_7(prog, tmp_path):
    result = run(["rewrite", prog, *SPINDLE], tmp_path, stdout=None,
                 preexec_fn=lambda: os.close(1))
    assert result.returncode == Exit.IO
    assert result.stderr == "<stdout>: standard output is closed; give -o FILE\n"


def test_a_closed_stdin_is_one_line_and_exit_7(tmp_path):
    result = run(["inspect", "-"], tmp_path, preexec_fn=lambda: os.close(0))
    assert result.returncode == Exit.IO
    assert result.stderr == "<stdin>: standard input is closed; give a file name\n"


def test_output_onto_a_device_writes_into_it(prog, tmp_path):
    result = run(["rewrite", prog, *SPINDLE, "-o", os.devnull, "-q"], tmp_path)
    assert (result.returncode, result.stderr) == (0, "")
    assert stat.S_ISCHR(os.stat(os.devnull).st_mode)


# --------------------------------------------------------------------- SIGTERM ----
def test_sigterm_ends_a_rewrite_with_130(tmp_path):
    proc = ncopt(["rewrite", "-", *SPINDLE], tmp_path, stdin=subprocess.PIPE,
                 stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    wchan = Path(f"/proc/{proc.pid}/wchan")
    t0 = time.monotonic()
    while time.monotonic() - t0 < 60:  # until it waits for the program on stdin
        try:
            if "pipe" in wchan.read_text():
                break
        except OSError:
            time.sleep(3)
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == Exit.INTERRUPTED, err
    assert (out, err.decode()) == (b"", "ncopt: interrupted\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


# ------------------------------------------------------------- permissions ----
def test_an_unreadable_input_names_it(prog, tmp_path, obeys_permissions):
    prog.chmod(0)
    result = run(["rewrite", prog, *SPINDLE], tmp_path, preexec_fn=obeys_permissions)
    assert result.returncode == Exit.IO
    assert result.stderr == (f"{prog}: cannot read the file: Permission denied; check its "
                             "permissions\n")


def test_output_into_a_read_only_folder_names_the_output(prog, tmp_path, obeys_permissions):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    result = run(["rewrite", prog, *SPINDLE, "-o", folder / "o.nc"], tmp_path,
                 preexec_fn=obeys_permissions)
    folder.chmod(0o755)
    assert result.returncode == Exit.IO
    assert result.stderr == (f"{folder / 'o.nc'}: cannot write the output: Permission denied; "
                             "check its permissions\n")
    assert list(folder.iterdir()) == []


def test_output_onto_a_read_only_file_is_refused(prog, tmp_path, obeys_permissions):
    out = tmp_path / "o.nc"
    out.write_bytes(b"keep\n")
    out.chmod(0o444)
    result = run(["rewrite", prog, *SPINDLE, "-o", out], tmp_path, preexec_fn=obeys_permissions)
    assert result.returncode == Exit.IO
    assert result.stderr == (f"{out}: the file is read-only; nothing written; make it "
                             "writable or write elsewhere\n")
    assert out.read_bytes() == b"keep\n"


def test_output_into_a_read_only_folder_injected(prog, tmp_path, monkeypatch):
    def refuse(*args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied", str(tmp_path))

    monkeypatch.setattr("ncopt.runtime.fileio.tempfile.mkstemp", refuse)
    out = tmp_path / "o.nc"
    result = invoke(["rewrite", prog, *SPINDLE, "-o", out])
    assert result.exit_code == Exit.IO
    assert result.stderr == (f"{out}: cannot write the output: Permission denied; check its "
                             "permissions\n")


@pytest.mark.parametrize("command", [["profiles"], ["rewrite", "PROG", *SPINDLE]])
def test_an_unreadable_home_is_one_line_and_exit_7(prog, tmp_path, obeys_permissions,
                                                   command):
    home = tmp_path / "home"
    (home / ".config" / "ncopt").mkdir(parents=True)
    home.chmod(0)
    env = {"HOME": str(home), "XDG_CONFIG_HOME": ""}
    args = [str(prog) if a == "PROG" else a for a in command]
    try:
        result = run(args, tmp_path, env=env, preexec_fn=obeys_permissions)
    finally:
        home.chmod(0o755)
    assert result.returncode == Exit.IO, result.stderr
    assert result.stderr == f"{home}/.config/ncopt/ncopt.toml: {UNREADABLE_PROFILE}\n"


def test_an_unreadable_config_folder_injected(tmp_path, monkeypatch):
    user = tmp_path / "home" / ".config" / "ncopt" / "ncopt.toml"
    monkeypatch.setattr("ncopt.planning.profiles.user_file", lambda: user)
    real = Path.is_file

    def is_file(self):
        if self == user:
            raise PermissionError(errno.EACCES, "Permission denied", str(self))
        return real(self)

    monkeypatch.setattr(Path, "is_file", is_file)
    result = invoke(["profiles"])
    assert result.exit_code == Exit.IO
    assert result.stderr == f"{user}: {UNREADABLE_PROFILE}\n"


def test_stale_temporaries_of_a_killed_run_are_removed_by_the_next(prog, tmp_path):
    stale = tmp_path / f".o.nc.99999999-k1llk1ll{'.ncopt-tmp'}"
    stale.write_bytes(b"half a program")
    result = run(["rewrite", prog, *SPINDLE, "-o", tmp_path / "o.nc", "-q"], tmp_path)
    assert result.returncode == 0, result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dome.nc", "o.nc"]


# --------------------------------------------------------------------- memory ----
def test_running_out_of_memory_is_one_line_exit_10_and_nothing_written(prog, tmp_path,
                                                                        monkeypatch):
    """A program larger than the memory the machine gives the run (a 5M-block mould
    program under a 2 GB limit): a located line that says what to do, not a traceback."""
    def no_memory(*args, **kwargs):
        raise MemoryError("Unable to allocate 12.8 MiB for an array")

    monkeypatch.setattr("ncopt.api.plan_program", no_memory)
    out = tmp_path / "out.nc"
    result = invoke(["rewrite", prog, *SPINDLE, "-o", out])
    assert result.exit_code == Exit.MEMORY == 10
    assert "not enough memory to finish" in result.stderr
    assert "split the program" in result.stderr
    assert not out.exists()
