"""Every file ncopt writes is guarded (issue 28): never an input of the run, never another
output of it, never a backup's name; refused (exit 2, one line naming the output) before any
work starts, and the inputs are left byte for byte.  Backups no link can turn into the
original; FIFOs without a writer, a closed stdout: located errors, never a hang.

The cases are the ones an adversarial run found losing data with exit 0.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from ncopt.runtime import fileio
from ncopt.cli.app import Exit, app
from ncopt.runtime.errors import FileError, UsageError
from ncopt.runtime.fileio import guard_outputs, read_input, replace_in_place
from programs import dome

SPINDLE = ["--diameter", "6", "--accel", "227", "--max-rpm", "15000"]


def invoke(args, **kwargs):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100"})
    result = runner.invoke(app, [str(a) for a in args], catch_exceptions=False, **kwargs)
    assert "Traceback" not in result.stderr
    return result


def run(args, cwd, **kwargs) -> subprocess.CompletedProcess:
    env = {**os.environ, "NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100",
           "XDG_CONFIG_HOME": str(Path(cwd) / "config")}
    return subprocess.run([sys.executable, "-c", "from ncopt.cli.app import main; main()",
                           *[str(a) for a in args]], env=env, cwd=cwd, capture_output=True,
                          timeout=120, **kwargs)


def files_of(folder: Path) -> dict:
    """Every entry under ``folder`` as it is: a file's bytes, a link's target."""
    out = {}
    for p in sorted(folder.rglob("*")):
        out[p.relative_to(folder)] = (("link", os.readlink(p)) if p.is_symlink()
                                      else p.read_bytes() if p.is_file() else "folder")
    return out


def refused(result, output: Path, fragment: str) -> None:
    """Exit 2, one line: ``OUTPUT: ...FRAGMENT...``."""
    assert result.exit_code == Exit.USAGE, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{output}: "), result.stderr
    assert fragment in lines[0], lines[0]


@pytest.fixture
def work(tmp_path) -> Path:
    """A folder with a program (a dome finish, S4000 F800), a link to it and a stand-in
    mesh file (the guard runs before a mesh is read)."""
    (tmp_path / "dome.nc").write_bytes(dome(8))
    (tmp_path / "link.nc").symlink_to("dome.nc")
    (tmp_path / "part.stl").write_bytes(b"solid part\nendsolid part\n")
    return tmp_path


# ------------------------------------------------- a secondary output onto an input ----
@pytest.mark.parametrize("report_name, fragment", [
    ("dome.nc", "--report names the program"),
    ("link.nc", "--report names the program"),  # through a link
    ("part.stl", "--report names the mesh"),
    ("out.nc", "--report and -o name the same file"),  # would replace the rewrite with HTML
])
def test_rewrite_report_never_lands_on_an_input_or_the_output(work, report_name, fragment):
    before = files_of(work)
    result = invoke(["rewrite", work / "dome.nc", *SPINDLE, "--mesh", work / "part.stl",
                     "-o", work / "out.nc", "--report", work / report_name])
    refused(result, work / report_name, fragment)
    assert files_of(work) == before  # nothing read was touched, nothing written


def test_no_output_lands_on_a_profile_file_read(work):
    """--tools FILE and the project's ncopt.toml (found upward from the working folder)
    are read by the run: writing the rewrite over them would lose the machine profiles."""
    profile = "[machines.shop]\naccel_rad_s2 = 227\nmax_rpm = 15000\n"
    (work / "ncopt.toml").write_text(profile)
    (work / "tools.toml").write_text("[tools.ball6]\ndiameter_mm = 6\n")
    before = files_of(work)
    result = run(["rewrite", "dome.nc", "--diameter", "6", "--machine", "shop", "-o",
                  "ncopt.toml"], work)
    assert result.returncode == Exit.USAGE
    assert result.stderr.decode().startswith(
        f"ncopt.toml: -o names the profile file {work / 'ncopt.toml'}: writing it")
    result = invoke(["rewrite", work / "dome.nc", *SPINDLE, "--tools", work / "tools.toml",
                     "-o", work / "out.nc", "--report", work / "tools.toml"])
    refused(result, work / "tools.toml", "--report names the profile file")
    assert files_of(work) == before


def test_a_hard_link_to_the_input_is_the_input(work):
    os.link(work / "dome.nc", work / "hard.nc")
    before = files_of(work)
    result = invoke(["rewrite", work / "dome.nc", *SPINDLE, "-o", work / "hard.nc"])
    assert result.exit_code == Exit.USAGE
    result = invoke(["rewrite", work / "dome.nc", *SPINDLE, "-o", work / "out.nc",
                     "--report", work / "hard.nc"])
    refused(result, work / "hard.nc", "--report names the program")
    assert files_of(work) == before


@pytest.mark.parametrize("target, fragment", [
    ("dome.nc", "-o names the program"),
    ("orig.nc", "-o names the original"),
    ("link-orig.nc", "-o names the original"),
])
def test_report_o_never_names_the_program_or_the_original(work, target, fragment):
    (work / "orig.nc").write_bytes(dome(8, rev=1))
    (work / "link-orig.nc").symlink_to("orig.nc")
    before = files_of(work)
    result = invoke(["report", work / "dome.nc", "--against", work / "orig.nc", *SPINDLE,
                     "-o", work / target])
    refused(result, work / target, fragment)
    assert files_of(work) == before


@pytest.mark.parametrize("option, name", [("--csv", "dome.nc"), ("--csv", "link.nc"),
                                          ("--plot-toolpath", "dome.svg"),
                                          ("--plot", "dome.svg")])
def test_simulate_outputs_never_name_the_program(work, option, name):
    (work / "dome.svg").write_bytes(dome(8))  # a program under a plot's name
    program = work / ("dome.svg" if name == "dome.svg" else "dome.nc")
    before = files_of(work)
    result = invoke(["simulate", program, *SPINDLE, option, work / name])
    if option != "--csv" and result.exit_code == Exit.USAGE and "matplotlib" in result.stderr:
        pytest.skip("no matplotlib: the plot options are refused before the guard")
    refused(result, work / name, f"{option} names the program")
    assert files_of(work) == before


def test_simulate_outputs_are_not_one_file(work):
    before = files_of(work)
    result = invoke(["simulate", work / "dome.nc", *SPINDLE, "--csv", work / "s.svg",
                     "--plot-toolpath", work / "s.svg"])
    if result.exit_code == Exit.USAGE and "matplotlib" in result.stderr:
        pytest.skip("no matplotlib")
    refused(result, work / "s.svg", "--plot-toolpath and --csv name the same file")
    assert files_of(work) == before


# ------------------------------------------------------------------------- batch ----
@pytest.fixture
def folder(tmp_path) -> Path:
    src = tmp_path / "jobs"
    (src / "sub").mkdir(parents=True)
    (src / "a.nc").write_bytes(dome(8))
    (src / "sub" / "b.nc").write_bytes(dome(8, rev=2))
    return src


@pytest.mark.parametrize("mode", ["-o", "--in-place"])
def test_batch_report_never_names_a_program_of_the_folder(folder, tmp_path, mode):
    before = files_of(folder)
    where = ["-o", tmp_path / "out"] if mode == "-o" else ["--in-place"]
    result = invoke(["batch", folder, *SPINDLE, *where, "--report", folder / "sub" / "b.nc"])
    refused(result, folder / "sub" / "b.nc", "--report names the program")
    assert files_of(folder) == before and not (tmp_path / "out").exists()


@pytest.mark.parametrize("name", ["a.nc.bak", "a.nc.2.bak"])
def test_batch_in_place_report_never_takes_a_backups_name(folder, name):
    before = files_of(folder)
    result = invoke(["batch", folder, *SPINDLE, "--in-place", "--report", folder / name])
    refused(result, folder / name, "names a backup")
    assert files_of(folder) == before


def test_batch_report_never_replaces_one_of_its_rewrites(folder, tmp_path):
    out = tmp_path / "out"
    result = invoke(["batch", folder, *SPINDLE, "-o", out, "--report", out / "a.nc"])
    refused(result, out / "a.nc", "--report and -o name the same file")
    assert not out.exists()


def test_batch_in_place_with_a_backup_name_linked_to_the_program(folder):
    """``a.nc.bak -> a.nc``: the link seemed to hold the original byte for byte, so no
    backup was made and the original was lost when a.nc was replaced."""
    original = (folder / "a.nc").read_bytes()
    (folder / "a.nc.bak").symlink_to("a.nc")
    result = invoke(["batch", folder, *SPINDLE, "--in-place", "-q", "-j", "1"])
    assert result.exit_code == Exit.OK, result.stderr
    assert (folder / "a.nc").read_bytes() != original  # rewritten
    assert (folder / "a.nc.1.bak").read_bytes() == original  # the original kept
    assert os.readlink(folder / "a.nc.bak") == "a.nc"  # the user's link left as it was


def test_replace_in_place_counts_no_link_as_a_backup(tmp_path):
    prog = tmp_path / "p.nc"
    prog.write_bytes(b"S4000 M3\nG1 X1 F800\n")
    (tmp_path / "p.nc.bak").symlink_to(prog)  # absolute link: the same file
    backup = replace_in_place(prog, b"S4000 M3\nG1 X1 F800\n", b"S4100 M3\nG1 X1 F820\n")
    assert backup == tmp_path / "p.nc.1.bak"
    assert backup.read_bytes() == b"S4000 M3\nG1 X1 F800\n" and not backup.is_symlink()
    assert prog.read_bytes() == b"S4100 M3\nG1 X1 F820\n"


def test_a_hard_linked_backup_name_still_keeps_the_original(tmp_path):
    """A hard link named p.nc.bak holds the original's inode: replacing p.nc by rename
    leaves it there, so it is a backup and none other is needed."""
    prog = tmp_path / "p.nc"
    prog.write_bytes(b"S4000 M3\nG1 X1 F800\n")
    os.link(prog, tmp_path / "p.nc.bak")
    assert replace_in_place(prog, prog.read_bytes(), b"S4100 M3\nG1 X1 F820\n") is None
    assert (tmp_path / "p.nc.bak").read_bytes() == b"S4000 M3\nG1 X1 F800\n"


# ------------------------------------------------------------ stdin from the output ----
@pytest.mark.parametrize("target", ["dome.nc", "link.nc"])
def test_stdin_read_from_the_output_file_is_refused(work, target):
    """``ncopt rewrite - -o x.ngc < x.ngc`` replaced the original by its rewrite."""
    before = files_of(work)
    with open(work / "dome.nc", "rb") as stdin:
        result = run(["rewrite", "-", *SPINDLE, "-o", target], work, stdin=stdin)
    assert result.returncode == Exit.USAGE
    assert result.stderr.decode() == (
        f"{target}: -o names the file standard input reads the program from: writing it "
        "would destroy what ncopt reads; write to another file\n")
    assert files_of(work) == before


def test_stdin_from_another_file_is_fine(work):
    with open(work / "dome.nc", "rb") as stdin:
        result = run(["rewrite", "-", *SPINDLE, "-o", "out.nc", "-q"], work, stdin=stdin)
    assert result.returncode == Exit.OK, result.stderr
    assert (work / "out.nc").read_bytes() != (work / "dome.nc").read_bytes()


# ------------------------------------------------------------- the guard, as a unit ----
def test_guard_lets_devices_and_distinct_files_through(tmp_path):
    (tmp_path / "p.nc").write_bytes(b"G1 X1\n")
    guard_outputs([("program", tmp_path / "p.nc"), ("mesh", None)],
                  [("-o", tmp_path / "new.nc"), ("--report", tmp_path / "r.html"),
                   ("--csv", os.devnull), ("--plot", os.devnull), ("--json", "-")])


def test_guard_names_a_dangling_link_to_another_output(tmp_path):
    (tmp_path / "later.html").symlink_to(tmp_path / "out.nc")  # out.nc not there yet
    with pytest.raises(UsageError) as exc:
        guard_outputs([], [("-o", tmp_path / "out.nc"), ("--report", tmp_path / "later.html")])
    assert str(exc.value) == (f"{tmp_path / 'later.html'}: --report and -o name the same "
                              "file: one would replace the other; give each its own")


# ------------------------------------------------------------------- FIFOs, stdout ----
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_nothing_writes_into_is_refused_not_waited_on(tmp_path, monkeypatch):
    monkeypatch.setattr(fileio, "FIFO_WAIT_S", 0.3)
    fifo = tmp_path / "pipe.nc"
    os.mkfifo(fifo)
    with pytest.raises(FileError) as exc:
        read_input(str(fifo))
    assert str(exc.value) == (f"{fifo}: is a FIFO (named pipe) that nothing wrote into for "
                              "0.3 s; start the program that writes it first, or give a file")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_whose_writer_is_slow_is_read_whole(tmp_path, monkeypatch):
    """A writer that holds the FIFO open is waited for, however long it takes (a shell's
    ``<(command)`` is such a FIFO)."""
    monkeypatch.setattr(fileio, "FIFO_WAIT_S", 0.2)
    fifo = tmp_path / "pipe.nc"
    os.mkfifo(fifo)
    data = dome(8)

    def write_late():
        with open(fifo, "wb") as handle:  # opens when the reader has
            time.sleep(0.6)  # past the wait: a writer is there, so the reader keeps waiting
            handle.write(data)

    writer = threading.Thread(target=write_late)
    writer.start()
    try:
        assert read_input(str(fifo)) == data
    finally:
        writer.join(10)


def test_a_fifo_program_with_no_writer_is_exit_7_from_the_command(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    os.mkfifo(tmp_path / "pipe.nc")
    env_code = "import ncopt.runtime.fileio as f; f.FIFO_WAIT_S = 0.3; from ncopt.cli.app import main; main()"
    result = subprocess.run([sys.executable, "-c", env_code, "rewrite", "pipe.nc", *SPINDLE],
                            cwd=tmp_path, capture_output=True, timeout=60,
                            env={**os.environ, "NO_COLOR": "1"})
    assert result.returncode == Exit.IO
    assert result.stderr.decode().startswith("pipe.nc: is a FIFO (named pipe) that nothing")


@pytest.mark.parametrize("args", [["diff", "dome.nc", "other.nc"], ["inspect", "dome.nc"],
                                  ["simulate", "dome.nc", *SPINDLE, "--json"], ["profiles"]],
                         ids=["diff", "inspect", "simulate-json", "profiles"])
def test_a_closed_stdout_is_exit_7_not_a_traceback_or_silence(work, args):
    """``ncopt diff a b >&-`` raised AttributeError; inspect, profiles and simulate --json
    ended with exit 0 and showed nothing."""
    (work / "other.nc").write_bytes(dome(8, rev=1))
    result = run(args, work, preexec_fn=lambda: os.close(1))
    err = result.stderr.decode()
    assert result.returncode == Exit.IO, err
    assert err.startswith("<stdout>: standard output is closed; nothing could be shown")
    assert len(err.splitlines()) == 1


def test_diff_q_needs_no_stdout(work):
    (work / "other.nc").write_bytes(dome(8, rev=1))
    result = run(["diff", "-q", "dome.nc", "other.nc"], work, preexec_fn=lambda: os.close(1))
    assert (result.returncode, result.stderr) == (1, b"")
