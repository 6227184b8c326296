"""Nothing the user owns is lost by ``ncopt batch``: output folders that would overwrite the
inputs are refused, modes are kept, and random sequences of batch runs (with and without
--in-place, with new CAM versions and hand edits between them) interrupted at random
points always leave every version the user wrote recoverable byte for byte.

Each file of a simulated batch is processed in a forked child, as the real pool does; a
fault stops the child at a chosen write step either as a kill (``os._exit``: no cleanup at
all, as a pool worker ends on SIGTERM or SIGKILL) or as an exception unwinding through the
write (SystemExit: the cleanup that Ctrl-C in ``ncopt rewrite`` runs).
"""

from __future__ import annotations

import json
import os
import re
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from rich.console import Console
from typer.testing import CliRunner

from ncopt.runtime import fileio
from ncopt.cli.batch import FileReport, Task, process_one
from ncopt.cli.batchview import BatchView
from ncopt.cli.app import Exit, app, make_job
from ncopt.runtime.fileio import TMP_SUFFIX, backups_of, clean_stale_temporaries
from programs import dome

ROOT = Path(__file__).resolve().parents[1]
BOWL_MPF = ROOT / "samples" / "bowl.mpf"
OPTIONS = ["--diameter", "6", "--accel", "227", "--max-rpm", "15000"]
JOBS = {"A": dict(diameter=6, accel=227, max_rpm=15000),
        "B": dict(diameter=6, accel=100, max_rpm=12000)}
NAMES = ("a.nc", "sub/b.ngc", "c.tap")  # c.tap has no spindle speed: nothing to plan


def invoke(args):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "80"})
    result = runner.invoke(app, [str(a) for a in args], catch_exceptions=False)
    assert "Traceback" not in result.stderr
    return result


def files_under(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.is_symlink()}


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setattr("ncopt.planning.profiles.user_file", lambda: tmp_path / "user" / "ncopt.toml")
    monkeypatch.chdir(tmp_path)
    src = tmp_path / "in"
    (src / "sub").mkdir(parents=True)
    for i, name in enumerate(NAMES):
        (src / name).write_bytes(dome(8, rev=i, spindle=name != "c.tap"))
    return src


# ------------------------------------------------------ refused output folders ----
REFUSED = "the originals would be overwritten or read again; write to another folder, or " \
          "use --in-place (which keeps backups)"


@pytest.mark.parametrize("where", ["same", "dot", "inside", "link"])
def test_an_output_folder_on_the_inputs_is_refused(folder, tmp_path, monkeypatch, where):
    before = files_under(tmp_path)
    if where == "link":
        (tmp_path / "link").symlink_to(folder)
    out = {"same": folder, "dot": Path("."), "inside": folder / "opt",
           "link": tmp_path / "link"}[where]
    if where == "dot":
        monkeypatch.chdir(folder)
    result = invoke(["batch", folder, *OPTIONS, "-o", out])
    assert result.exit_code == Exit.USAGE, result.stderr
    what = "inside the input folder" if where == "inside" else "the input folder"
    assert result.stderr == f"{out}: the output folder is {what} {folder}: {REFUSED}\n"
    assert files_under(tmp_path) == before and not (folder / "opt").exists()


def test_a_glob_whose_outputs_land_on_inputs_is_refused(folder, tmp_path):
    before = files_under(tmp_path)
    result = invoke(["batch", f"{folder}/*.nc", *OPTIONS, "-o", folder])
    assert result.exit_code == Exit.USAGE
    assert result.stderr == (f"{folder / 'a.nc'}: this output would overwrite an input "
                             "program; write to another folder, or use --in-place (which "
                             "keeps backups)\n")
    assert files_under(tmp_path) == before
    # a glob into a folder beside it is what it is for
    ok = invoke(["batch", f"{folder}/*.nc", *OPTIONS, "-o", tmp_path / "opt"])
    assert ok.exit_code == Exit.OK and (tmp_path / "opt" / "a.nc").is_file()


# --------------------------------------------------------------------- modes ----
def test_outputs_get_the_umask_mode_and_in_place_keeps_the_originals(folder, tmp_path):
    saved = os.umask(0o027)
    try:
        (folder / "a.nc").chmod(0o604)
        (folder / "sub" / "b.ngc").chmod(0o600)
        out = tmp_path / "out"
        assert invoke(["batch", folder, *OPTIONS, "-o", out]).exit_code == Exit.OK
        for name in NAMES:  # rewritten and copied alike: a new file's mode
            assert stat.S_IMODE((out / name).stat().st_mode) == 0o640, name
        assert invoke(["batch", folder, *OPTIONS, "--in-place"]).exit_code == Exit.OK
        assert stat.S_IMODE((folder / "a.nc").stat().st_mode) == 0o604
        assert stat.S_IMODE((folder / "sub" / "b.ngc").stat().st_mode) == 0o600
        assert stat.S_IMODE((folder / "a.nc.bak").stat().st_mode) == 0o604
    finally:
        os.umask(saved)


# ------------------------------------------------- a read-only output folder ----
def test_a_read_only_output_folder_blames_the_output_injected(folder, tmp_path, monkeypatch):
    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr("ncopt.cli.batch.tempfile.mkstemp", refuse)
    out = tmp_path / "out"
    result = invoke(["batch", folder, *OPTIONS, "-o", out])
    assert result.exit_code == Exit.IO
    assert result.stderr == (f"{out}: cannot write into the output folder: Permission denied; "
                             "check its permissions\n")


def test_a_read_only_output_folder_blames_the_output(folder, tmp_path, obeys_permissions):
    out = tmp_path / "out"
    out.mkdir()
    out.chmod(0o555)
    try:
        result = subprocess.run(
            [sys.executable, "-c", "from ncopt.cli.app import main; main()", "batch", str(folder),
             *OPTIONS, "-o", str(out)], capture_output=True, text=True, cwd=tmp_path,
            env={**os.environ, "XDG_CONFIG_HOME": str(tmp_path / "cfg")},
            preexec_fn=obeys_permissions)
    finally:
        out.chmod(0o755)
    assert result.returncode == Exit.IO, result.stderr
    assert result.stderr == (f"{out}: cannot write into the output folder: Permission denied; "
                             "check its permissions\n")
    assert list(out.iterdir()) == []


def test_a_subfolder_that_cannot_be_written_fails_that_file_naming_the_output(
        folder, tmp_path, monkeypatch):
    real = fileio.write_temporary

    def refuse_sub(target, *args):
        if target.parent.name == "sub":
            raise PermissionError(13, "Permission denied", str(target.parent))
        return real(target, *args)

    monkeypatch.setattr(fileio, "write_temporary", refuse_sub)
    out = tmp_path / "out"
    report = tmp_path / "r.json"
    job = make_job(**JOBS["A"])
    entries = [process_one(Task(str(folder / n), str(out / n), job)) for n in NAMES]
    assert [e.status for e in entries] == ["ok", "failed", "unchanged"]
    assert entries[1].error == (f"{out / 'sub' / 'b.ngc'}: cannot write the output: "
                                "Permission denied; check its permissions")
    assert not report.exists()


# ----------------------------------------------------- the table at 80 columns ----
def test_the_table_fits_80_columns_failures_first_with_the_time_saved(tmp_path):
    reports = [
        FileReport("/cam/parts/ok-part-with-a-rather-long-name-for-a-program.nc", "o", "ok",
                   151424, 59656, 60000, 112.1, 76.5, 3),
        FileReport("/cam/parts/same.nc", "o", "unchanged", error="nothing to plan (no feed)"),
        FileReport("/cam/parts/deep/folder/of/the/shop/bad.nc", "o", "failed",
                   error="line 3:18: unbalanced comment parentheses; close every '('"),
        FileReport("/cam/parts/b.nc", "o", "ok", 2309, 13, 20, 12.6, 8.2, 21)]
    buffer = Console(file=__import__("io").StringIO(), width=80, color_system=None,
                     soft_wrap=True)
    BatchView(buffer, []).table(reports, Path("/cam/parts"))
    text = buffer.file.getvalue().splitlines()
    table = text[:text.index("failed:")]
    assert all(len(line) <= 80 for line in table), [len(line) for line in table]
    rows = [line.split()[0] for line in table[2:6]]
    assert rows[0].endswith("bad.nc") and rows[-1] == "same.nc"  # failures first, same last
    assert "FAILED" in table[2] and "ok" in table[3].split()
    assert text[text.index("failed:") + 1] == ("  deep/folder/of/the/shop/bad.nc: line 3:18: "
                                               "unbalanced comment parentheses; close every '('")
    assert "  nothing to plan (no feed): same.nc" in text
    assert text[-2] == ("ncopt: estimated cutting time of the 2 rewritten files 124.7 -> 84.7 "
                        "min: 40.0 min saved (-32.1 %)")
    assert text[-1] == "ncopt: 2 rewritten, 1 unchanged (nothing to plan), 1 failed, of 4 files"
    footer = table[-1].split()
    assert footer[:2] == ["4", "files"] and "124.7" in footer and "84.7" in footer


def test_quiet_batch_prints_only_the_failures(folder, tmp_path):
    (folder / "bad.nc").write_bytes(b"G21\nG1 X1 (open\n")
    result = invoke(["batch", folder, *OPTIONS, "-o", tmp_path / "out", "-q"])
    assert result.exit_code == Exit.SOME_FAILED
    assert result.stderr == (f"{folder / 'bad.nc'}: line 2:7: unbalanced comment parentheses; "
                             "close every '(' with ')' on the same line\n")
    assert (tmp_path / "out" / "a.nc").is_file()


# ---------------------------------------------- random runs, random interruptions ----
STEPS = ("write_temporary", "keep_version", "replace")
fault_st = st.none() | st.tuples(st.sampled_from(NAMES), st.sampled_from(STEPS),
                                 st.sampled_from(["before", "after"]),
                                 st.sampled_from(["kill", "term"]))
action_st = st.one_of(
    st.tuples(st.just("batch"), st.booleans(), st.sampled_from(sorted(JOBS)), fault_st),
    st.tuples(st.just("cam"), st.sampled_from(NAMES)),
    st.tuples(st.just("edit"), st.sampled_from(NAMES)))


class Killed(Exception):
    pass


def _install_fault(step: str, when: str, kind: str) -> None:
    """In the child: stop at the step, as a kill (no cleanup) or a termination."""
    def stop():
        if kind == "kill":
            os._exit(137)
        raise SystemExit(143)

    if step == "replace":
        real, holder, name = os.replace, os, "replace"
    else:
        real, holder, name = getattr(fileio, step), fileio, step

    def faulty(*args, **kwargs):
        if when == "before":
            stop()
        result = real(*args, **kwargs)
        stop()
        return result

    setattr(holder, name, faulty)


def _run_file(task: Task, fault) -> bool:
    """process_one in a forked child, as a pool worker runs it; False when it was stopped."""
    pid = os.fork()
    if pid == 0:
        code = 0
        try:
            if fault is not None and task.source.endswith(fault[0]):
                _install_fault(*fault[1:])
            process_one(task)
        except SystemExit as exc:
            code = exc.code
        except BaseException:  # noqa: BLE001 - anything else is a failure of the test
            code = 99
        os._exit(code)
    _, status = os.waitpid(pid, 0)
    code = os.waitstatus_to_exitcode(status)
    assert code in (0, 137, 143), f"the worker failed with {code}"
    return code == 0


def _batch(src: Path, out: Path, in_place: bool, options: str, fault) -> bool:
    """One batch run over the folder; False when a fault stopped it."""
    job = make_job(**JOBS[options])
    tasks = [Task(str(src / n), str(src / n if in_place else out / n), job, None, in_place)
             for n in NAMES]
    for task in tasks:
        if not _run_file(task, fault):
            if fault[3] == "kill":
                return False  # the whole batch died with its worker: no cleanup
            break
    for folder in {Path(t.target).parent for t in tasks}:  # run_batch's last step
        clean_stale_temporaries(folder)
    return fault is None or fault[3] != "kill"


def _check(src: Path, seen: dict, backups: dict) -> None:
    for name, versions in seen.items():
        path = src / name
        kept = {path.read_bytes(), *(b.read_bytes() for b in backups_of(path))}
        for v in versions:
            assert v in kept, f"a version of {name} is lost"
    for b, data in backups.items():  # a backup is never overwritten
        assert b.read_bytes() == data, f"{b} changed"
    for name in NAMES:
        for b in backups_of(src / name):
            backups.setdefault(b, b.read_bytes())
    allowed = set(NAMES) | {str(b.relative_to(src)) for b in backups}
    for p in src.rglob("*"):
        if p.is_file():
            rel = str(p.relative_to(src))
            assert rel in allowed or p.name.endswith(TMP_SUFFIX), rel


@pytest.mark.slow
@pytest.mark.skipif(not hasattr(os, "fork"), reason="fork")
@settings(max_examples=15)
@given(actions=st.lists(action_st, min_size=1, max_size=5))
# the cases of issue 13: a second run with other options, a new CAM version in between
@example(actions=[("batch", True, "A", None), ("batch", True, "B", None)])
@example(actions=[("batch", True, "A", None), ("cam", "a.nc"), ("batch", True, "B", None)])
# killed between the backup and the rename, then the CAM overwrites the program in place:
# a backup that were a second name of the program's file would change with it
@example(actions=[("batch", True, "A", ("a.nc", "keep_version", "after", "kill")),
                  ("cam", "a.nc")])
# killed with its temporary on disk: the next run in the folder removes it
@example(actions=[("batch", True, "A", ("sub/b.ngc", "write_temporary", "after", "kill")),
                  ("batch", True, "B", None)])
def test_random_interrupted_runs_never_lose_a_version(tmp_path_factory, actions):
    """Every version the user wrote (the first, a new CAM output, a hand edit) that an ncopt
    run replaced stays in NAME.bak, NAME.1.bak, ...; a run into another folder changes
    nothing in the input folder; backups are never changed."""
    top = tmp_path_factory.mktemp("runs")
    src, out = top / "in", top / "out"
    (src / "sub").mkdir(parents=True)
    written = {}  # every version the user wrote, per file
    for i, name in enumerate(NAMES):
        (src / name).write_bytes(dome(8, rev=i, spindle=name != "c.tap"))
        written[name] = [(src / name).read_bytes()]
    seen = {name: [] for name in NAMES}  # user versions an ncopt run replaced
    backups: dict = {}
    for k, action in enumerate(actions):
        if action[0] == "batch":
            _, in_place, options, fault = action
            before = files_under(src)
            finished = _batch(src, out, in_place, options, fault)
            _replaced(src, before, written, seen)
            if not in_place:
                assert files_under(src) == before
            if finished:  # a finished or terminated run leaves no temporary where it wrote
                where = src if in_place else out
                assert not [p for p in where.rglob("*") if p.name.endswith(TMP_SUFFIX)]
        else:
            path = src / action[1]
            new = dome(8, rev=10 + k) if action[0] == "cam" else path.read_bytes() + b"(edited)\n"
            with open(path, "r+b") as handle:  # in place, as many editors and posts write
                handle.truncate(0)
                handle.write(new)
            written[action[1]].append(new)
        _check(src, seen, backups)
    # a last complete run in place cleans what killed runs left, and still loses nothing
    before = files_under(src)
    _batch(src, out, True, "A", None)
    _replaced(src, before, written, seen)
    _check(src, seen, backups)
    assert not [p for p in src.rglob("*") if p.name.endswith(TMP_SUFFIX)]


def _replaced(src: Path, before: dict, written: dict, seen: dict) -> None:
    for name in NAMES:
        if (src / name).read_bytes() != before[name] and before[name] in written[name]:
            seen[name].append(before[name])


# ------------------------------------------------------ a SIGKILLed batch parent ----
COPIES = 8


@pytest.mark.slow
def test_a_killed_batch_parent_leaves_no_traceback_and_no_temporary(tmp_path):
    src, out = tmp_path / "in", tmp_path / "out"
    src.mkdir()
    data = BOWL_MPF.read_bytes()
    for i in range(COPIES):
        (src / f"bowl_{i:02d}.mpf").write_bytes(data)
    log = tmp_path / "stderr.txt"
    cmd = [sys.executable, "-c", "from ncopt.cli.app import main; main()", "batch", str(src),
           "--accel", "227", "--max-rpm", "15000", "-o", str(out), "--jobs", "2"]
    env = {**os.environ, "NO_COLOR": "1", "XDG_CONFIG_HOME": str(tmp_path / "config")}
    with open(log, "wb") as stderr:
        proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.DEVNULL,
                                stderr=stderr)
    try:
        t0 = time.monotonic()
        while time.monotonic() - t0 < 60 and not (out.is_dir() and list(out.glob("*.mpf"))):
            time.sleep(0.02)
        assert proc.poll() is None, "the batch ended before it could be killed"
        workers = _children(proc.pid)
        assert workers, "no worker processes found"
        proc.send_signal(signal.SIGKILL)
        proc.wait(30)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 30 and any(_alive(w) for w in workers):
            time.sleep(0.05)
        assert not any(_alive(w) for w in workers), "workers outlived their parent"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    text = log.read_text(errors="replace")
    assert "Traceback" not in text and "Error" not in text, text[-3000:]
    for p in out.glob("*.mpf"):  # whatever was finished is whole
        assert p.read_bytes().rstrip().endswith(data.rstrip().rsplit(b"\n", 1)[-1])
    # a worker stopped mid-write may leave its temporary: the next run in the folder removes it
    (src / "small.nc").write_bytes(dome(6))
    again = subprocess.run(cmd[:3] + ["rewrite", str(src / "small.nc"), *OPTIONS, "-q", "-o",
                                      str(out / "small.nc")], cwd=tmp_path, env=env)
    assert again.returncode == 0
    assert not [p for p in tmp_path.rglob("*") if p.name.endswith(TMP_SUFFIX)]


def _children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        pytest.skip("no /proc children list here")
    return [int(c) for c in text.split()]


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_the_report_of_a_real_in_place_run_names_its_backups(folder, tmp_path):
    report = tmp_path / "r.json"
    result = invoke(["batch", folder, *OPTIONS, "--in-place", "--report", report, "-j", "1"])
    assert result.exit_code == Exit.OK, result.stderr
    entries = {Path(e["source"]).name: e for e in json.loads(report.read_text())}
    assert entries["a.nc"]["backup"] == str(folder / "a.nc.bak")
    assert entries["c.tap"]["status"] == "unchanged" and entries["c.tap"]["backup"] == ""
    top = (folder / "a.nc").read_text().splitlines()[:8]
    assert any(re.match(r"\(ncopt T1 lines=\d+-\d+ vc=", line) for line in top), top


def test_two_in_place_batches_at_once_keep_the_originals(tmp_path):
    """Two --in-place batches with other options over one folder at the same time: the
    first original of every file stays in NAME.bak, each later backup is a whole rewrite,
    and a file one run finds changed under it is reported, not replaced."""
    src = tmp_path / "in"
    src.mkdir()
    originals = {}
    for i in range(6):
        originals[f"p{i}.nc"] = dome(14, rev=i)
        (src / f"p{i}.nc").write_bytes(originals[f"p{i}.nc"])
    env = {**os.environ, "NO_COLOR": "1", "XDG_CONFIG_HOME": str(tmp_path / "config")}
    runs = [subprocess.Popen([sys.executable, "-c", "from ncopt.cli.app import main; main()",
                              "batch", str(src), "--in-place", "-q", "-j", "1", "--diameter",
                              "6", "--accel", accel, "--max-rpm", "15000"],
                             cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True) for accel in ("227", "100")]
    results = [(r.wait(120), r.stderr.read()) for r in runs]
    # A run that finds every file already replaced by the other reports each one and exits
    # NOTHING_DONE; each file is then rewritten by the run that took it first (checked below).
    for code, err in results:
        assert code in (Exit.OK, Exit.SOME_FAILED, Exit.NOTHING_DONE), err
        for line in err.splitlines():
            assert line.count(str(src)) <= 1, line  # the file named once
            assert line.endswith("changed since ncopt read it (another ncopt run, or the CAM "
                                 "wrote it again); left as it is; run again"), line
    for name, original in originals.items():
        kept = backups_of(src / name)
        assert kept[0].name == f"{name}.bak" and kept[0].read_bytes() == original
        for b in [src / name, *kept[1:]]:
            text = b.read_text()
            assert re.search(r"^\(ncopt T1 lines=\d+-\d+ vc=", text, re.M), b
            assert text.endswith("M30\n"), b
    assert not [p for p in src.iterdir() if p.name.endswith(TMP_SUFFIX)]
