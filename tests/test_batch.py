"""``ncopt batch`` on the whole shared corpus plus broken files, in place, and interrupted.

The corpus is read from ``../shared/corpus`` and copied into a temporary folder (never into
the project); the batch runs with two worker processes as on the 2-core machine.
"""

from __future__ import annotations

import hashlib
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
import traceback
from pathlib import Path

import pytest
from typer.testing import CliRunner

from ncopt.cli.app import Exit, app
from ncopt.runtime.errors import NcoptError
from ncopt.planning.inspection import inspect_text
from ncopt.reading.parse import parse_text
from ncopt.writing.edits import masked

ROOT = Path(__file__).resolve().parents[1]
CORPUS = Path(__file__).resolve().parents[1].parent / "shared" / "corpus"
BOWL_MPF = ROOT / "samples" / "bowl.mpf"
SUFFIXES = {".nc", ".ngc", ".tap", ".gcode"}
OPTIONS = ["--diameter", "3", "--accel", "227", "--max-rpm", "15000"]
TMP_SUFFIX = ".ncopt-tmp"
STAMP = re.compile(r"^\s*[(;]\s*ncopt ")  # a line of the stamp
LOCATED = re.compile(r"line (\d+)(?::(\d+))?: \S")


def invoke(args):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100"})
    result = runner.invoke(app, [str(a) for a in args])
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise AssertionError(
            f"ncopt crashed with exit code {result.exit_code} instead of a clean result:\n"
            + "".join(traceback.format_exception(*result.exc_info, limit=-3)) + result.stderr)
    for stream in (result.stdout, result.stderr):
        assert "\x1b[" not in stream and "Traceback" not in stream
    return result


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def snapshot(folder: Path) -> dict[str, str]:
    """Every file under a folder (symlinks not followed) and its sha256."""
    return {str(p.relative_to(folder)): sha(p) for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.is_symlink()}


def corpus_programs() -> list[Path]:
    return sorted(p for p in CORPUS.rglob("*") if p.is_file() and p.suffix.lower() in SUFFIXES)


BROKEN = {
    "broken/random.nc": bytes(random.Random(20240611).randrange(256) for _ in range(4000)),
    "broken/unclosed.ngc": b"G21 G90\nS1000 M3\nG1 X1 Y1 Z0 F100 (this comment never ends\n"
                           b"G1 X2\nM30\n",
    "broken/empty.tap": b"",
    "broken/binary.nc": b"\x7fELF\x02\x01\x01\x00" + bytes(range(256)) * 8,
}


def without_stamp(base: str, longer: str) -> str:
    """``longer`` minus the block of stamp comment lines a rewrite adds near the top (four
    of header, two per planned operation)."""
    a, b = base.splitlines(keepends=True), longer.splitlines(keepends=True)
    n = len(b) - len(a)
    assert n >= 6 and n % 2 == 0, n
    i = next((k for k, (x, y) in enumerate(zip(a, b)) if x != y), len(a))
    assert all(STAMP.match(line) for line in b[i:i + n]), b[i:i + n]
    return "".join(b[:i] + b[i + n:])


# --------------------------------------------------- the whole corpus, once ----
@pytest.fixture(scope="module")
def corpus_run(tmp_path_factory):
    if not CORPUS.is_dir():
        pytest.fail(f"the shared corpus is missing at {CORPUS}")
    top = tmp_path_factory.mktemp("batch")
    src, out, cwd = top / "in", top / "out", top / "cwd"
    cwd.mkdir()
    programs = corpus_programs()
    assert len(programs) >= 150
    for p in programs:
        target = src / p.relative_to(CORPUS)
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(p, target)
    for rel, data in BROKEN.items():
        (src / rel).parent.mkdir(parents=True, exist_ok=True)
        (src / rel).write_bytes(data)
    report = top / "report.json"
    before = snapshot(top)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("ncopt.planning.profiles.user_file", lambda: top / "user" / "ncopt.toml")
        mp.chdir(cwd)
        t0 = time.monotonic()
        result = invoke(["batch", src, *OPTIONS, "-o", out, "--report", report, "--jobs", "2"])
        elapsed = time.monotonic() - t0
    inputs = sorted(str(p) for p in src.rglob("*") if p.is_file())
    return dict(top=top, src=src, out=out, cwd=cwd, report=report, result=result,
                elapsed=elapsed, before=before, inputs=inputs,
                entries=json.loads(report.read_text()) if report.exists() else None)


@pytest.mark.corpus
def test_corpus_batch_finishes_with_some_failed(corpus_run):
    """(How long it takes is a benchmark's question, not a test's: machines differ by 2x.)"""
    result = corpus_run["result"]
    assert result.exit_code == Exit.SOME_FAILED, result.stderr[-2000:]
    assert result.stdout == ""
    entries = corpus_run["entries"]
    counts = {k: sum(e["status"] == k for e in entries) for k in ("ok", "unchanged", "failed")}
    assert all(counts.values())
    assert result.stderr.splitlines()[-1] == (
        f"ncopt: {counts['ok']} rewritten, {counts['unchanged']} unchanged (nothing to plan), "
        f"{counts['failed']} failed, of {len(entries)} files")


@pytest.mark.corpus
def test_report_lists_every_input_once(corpus_run):
    entries, src, out = corpus_run["entries"], corpus_run["src"], corpus_run["out"]
    sources = [e["source"] for e in entries]
    assert sorted(sources) == corpus_run["inputs"]  # each exactly once, nothing else
    assert len(sources) == len(set(sources)) == len(corpus_programs()) + len(BROKEN)
    for e in entries:
        assert e["status"] in ("ok", "unchanged", "failed")
        assert Path(e["target"]) == (out / Path(e["source"]).relative_to(src)).resolve()
        assert "internal error" not in e["error"], e
    status = {str(Path(e["source"]).relative_to(src)): e for e in entries}
    assert status["fusion/BowlTest.nc"]["status"] == "ok"
    # a 10 mm ball's raster with --diameter 3: passes further apart than a 3 mm ball's
    # finish (and its F is a parameter expression worth 4.5e6 mm/min): left alone
    assert status["linuxcnc/3D_Chips.ngc"]["status"] == "unchanged"
    assert status["broken/empty.tap"]["status"] == "unchanged"
    for rel in ("broken/random.nc", "broken/unclosed.ngc", "broken/binary.nc"):
        assert status[rel]["status"] == "failed"
    for e in entries:
        if "/interp-tests/bad/" in e["source"]:
            assert e["status"] == "failed", e


@pytest.mark.corpus
def test_failed_files_carry_located_messages(corpus_run):
    entries, src = corpus_run["entries"], corpus_run["src"]
    failed = [e for e in entries if e["status"] == "failed"]
    unclosed = next(e for e in failed if e["source"].endswith("broken/unclosed.ngc"))
    assert unclosed["error"] == ("line 3:18: unbalanced comment parentheses; close every '(' "
                                 "with ')' on the same line")
    for e in failed:
        path = Path(e["source"])
        error = e["error"]
        assert error and not error.startswith(str(path)), e  # the report names the file
        assert e["blocks"] == e["s_words"] == e["f_words"] == 0
        # where the program itself is unreadable, the report says where, as inspect does
        try:
            inspect_text(path.read_bytes().decode("latin-1"), str(path))
        except NcoptError as exc:
            assert exc.line is not None, exc
            where = f"line {exc.line}" + (f":{exc.column}" if exc.column else "")
            assert error == f"{where}: {exc.message}", (e, str(exc))
            continue
        # readable programs fail as a whole (no S/F, several tools): what is wrong; what to do
        assert "; " in error, e
    for rel in ("broken/random.nc", "broken/binary.nc"):
        e = next(e for e in failed if e["source"] == str(src / rel))
        m = LOCATED.match(e["error"])
        assert m and m[2] is not None, e


@pytest.mark.corpus
def test_originals_are_byte_identical(corpus_run):
    src, top = corpus_run["src"], corpus_run["top"]
    before = {k: v for k, v in corpus_run["before"].items() if k.startswith("in/")}
    assert snapshot(src) == {k.removeprefix("in/"): v for k, v in before.items()}
    for p in corpus_programs():  # and the shared corpus itself
        assert (src / p.relative_to(CORPUS)).read_bytes() == p.read_bytes()
    assert top.joinpath("in").is_dir()


@pytest.mark.corpus
def test_outputs_mirror_the_inputs(corpus_run):
    entries, src, out = corpus_run["entries"], corpus_run["src"], corpus_run["out"]
    expected = set()
    for e in entries:
        rel = Path(e["source"]).relative_to(src)
        target = out / rel
        if e["status"] == "failed":
            assert not target.exists(), e
            continue
        expected.add(str(rel))
        data, original = target.read_bytes(), Path(e["source"]).read_bytes()
        if e["status"] == "unchanged":
            assert data == original, e
            continue
        # a rewrite: one stamp line more, and with S and F masked the input's own text
        text, base = data.decode("latin-1"), original.decode("latin-1")
        plain = without_stamp(base, text)
        assert masked(parse_text(plain)) == masked(parse_text(base)), e
        # S/F rewritten, unless the program already runs as fast as the machine allows
        # (camotics/bear.nc: S15000 on a 15000 RPM spindle), when only the stamp is added
        gained = e["time_after_min"] < e["time_before_min"] * (1 - 1e-9)
        assert e["blocks"] > 0 and (not gained or e["s_words"] + e["f_words"] > 0), e
    assert set(snapshot(out)) == expected  # nothing else in OUT


@pytest.mark.corpus
def test_no_temporary_and_nothing_outside_out(corpus_run):
    top, out = corpus_run["top"], corpus_run["out"]
    assert not [p for p in top.rglob("*") if p.name.endswith(TMP_SUFFIX)]
    assert not [p for p in out.rglob(".*")]  # no hidden leftovers either
    after = {k: v for k, v in snapshot(top).items()
             if not k.startswith("out/") and k != "report.json"}
    assert after == corpus_run["before"]
    assert not any(corpus_run["cwd"].iterdir())  # the working folder stays empty
    assert not (top / "user").exists()


# ----------------------------------------------------------------- in place ----
# two programs ncopt plans (a 3D finish; Clamp.nc and flowsnake, 2D programs with an end
# mill, were planned before operations were told apart), one it leaves, one it refuses
SMALL = {"Wave.nc": "camotics/wave.gcode", "Smiley001.nc": "pygcode/Smiley001.nc",
         "Colt.tap": "pygcode/Colt.tap", "sub/wave.ngc": "camotics/wave.gcode"}


@pytest.fixture
def small_folder(tmp_path, monkeypatch):
    monkeypatch.setattr("ncopt.planning.profiles.user_file", lambda: tmp_path / "user" / "ncopt.toml")
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    src = tmp_path / "in"
    for name, rel in SMALL.items():
        (src / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(CORPUS / rel, src / name)
    return src


def test_in_place_keeps_a_backup_and_replaces_atomically(small_folder, tmp_path):
    src = small_folder
    ok = [src / "Wave.nc", src / "sub" / "wave.ngc"]
    unchanged, failed = src / "Smiley001.nc", src / "Colt.tap"
    original = {p: p.read_bytes() for p in src.rglob("*") if p.is_file()}
    inode = {p: p.stat().st_ino for p in original}
    mtime = {p: p.stat().st_mtime_ns for p in original}
    report = tmp_path / "report.json"
    result = invoke(["batch", src, *OPTIONS, "--in-place", "--report", report, "--jobs", "2"])
    assert result.exit_code == Exit.SOME_FAILED, result.stderr
    status = {Path(e["source"]).name: e["status"] for e in json.loads(report.read_text())}
    assert status == {"Wave.nc": "ok", "wave.ngc": "ok", "Smiley001.nc": "unchanged",
                      "Colt.tap": "failed"}
    for p in ok:
        backup = p.with_name(p.name + ".bak")
        assert backup.read_bytes() == original[p]
        assert backup.stat().st_mtime_ns == mtime[p]  # the original as it was, a file of its own
        assert backup.stat().st_nlink == 1
        assert p.stat().st_ino != inode[p]  # a new file renamed over it, never rewritten in place
        text = p.read_bytes().decode("latin-1")
        plain = without_stamp(original[p].decode("latin-1"), text)
        assert masked(parse_text(plain)) == masked(parse_text(original[p].decode("latin-1")))
    for p in (unchanged, failed):
        assert p.read_bytes() == original[p] and p.stat().st_ino == inode[p]
        assert not p.with_name(p.name + ".bak").exists()
    assert not [p for p in tmp_path.rglob("*") if p.name.endswith(TMP_SUFFIX)]
    names = sorted(str(p.relative_to(src)) for p in src.rglob("*") if p.is_file())
    assert names == ["Colt.tap", "Smiley001.nc", "Wave.nc", "Wave.nc.bak", "sub/wave.ngc",
                     "sub/wave.ngc.bak"]

    # again: a stamped program plans from its stamp and comes out the same; the backup
    # still holds the very original
    first = {p: p.read_bytes() for p in ok}
    again = invoke(["batch", src, *OPTIONS, "--in-place", "--jobs", "2"])
    assert again.exit_code == Exit.SOME_FAILED, again.stderr
    for p in ok:
        assert p.read_bytes() == first[p]
        assert p.with_name(p.name + ".bak").read_bytes() == original[p]


def test_in_place_on_a_new_version_keeps_that_version(small_folder):
    """After a first --in-place run, the CAM writes a new Wave.nc; a second --in-place run
    rewrites it, but the existing Wave.nc.bak (the old version) is kept as it is and the
    new original is lost: nothing in the folder holds its bytes any more."""
    src = small_folder
    clamp = src / "Wave.nc"
    assert invoke(["batch", src, *OPTIONS, "--in-place"]).exit_code == Exit.SOME_FAILED
    new_version = b"(revision 2)\n" + (CORPUS / "camotics" / "wave.gcode").read_bytes()
    assert new_version != (CORPUS / "camotics" / "wave.gcode").read_bytes()
    clamp.unlink()
    clamp.write_bytes(new_version)
    assert invoke(["batch", src, *OPTIONS, "--in-place"]).exit_code == Exit.SOME_FAILED
    assert clamp.read_bytes() != new_version  # rewritten
    kept = [p for p in src.rglob("*") if p.is_file() and p.read_bytes() == new_version]
    assert kept, "the original of the second run is gone"


def test_output_folder_and_in_place_together_are_refused(small_folder, tmp_path):
    src = small_folder
    before = snapshot(tmp_path)
    out = tmp_path / "out"
    result = invoke(["batch", src, *OPTIONS, "-o", out, "--in-place"])
    assert result.exit_code == Exit.USAGE
    lines = result.stderr.splitlines()
    assert len(lines) == 1
    assert lines[0].removeprefix("<input>: ") == "give either -o OUTDIR or --in-place, not both"
    assert not out.exists() and snapshot(tmp_path) == before


def test_no_output_folder_is_refused(small_folder, tmp_path):
    before = snapshot(tmp_path)
    result = invoke(["batch", small_folder, *OPTIONS])
    assert result.exit_code == Exit.USAGE
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].removeprefix("<input>: ") == (
        "give an output folder with -o, or --in-place to replace the originals")
    assert snapshot(tmp_path) == before


def test_nothing_to_do(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    empty = tmp_path / "empty"
    empty.mkdir()
    result = invoke(["batch", empty, *OPTIONS, "-o", tmp_path / "out"])
    assert result.exit_code == Exit.NOTHING_DONE
    assert result.stderr == f"ncopt: no NC programs found in {empty}\n"
    assert not (tmp_path / "out").exists()
    # no program among the files (a mesh, notes, a hidden file)
    (empty / "part.stl").write_bytes(b"solid x\nendsolid x\n")
    (empty / "notes.md").write_text("# notes\n")
    (empty / ".hidden.nc").write_text("G1 X1\n")
    result = invoke(["batch", empty, *OPTIONS, "-o", tmp_path / "out"])
    assert result.exit_code == Exit.NOTHING_DONE
    assert not (tmp_path / "out").exists()
    # every file failed
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "unclosed.ngc").write_bytes(BROKEN["broken/unclosed.ngc"])
    (bad / "random.nc").write_bytes(BROKEN["broken/random.nc"])
    report = tmp_path / "report.json"
    result = invoke(["batch", bad, *OPTIONS, "-o", tmp_path / "out", "--report", report])
    assert result.exit_code == Exit.NOTHING_DONE
    assert [e["status"] for e in json.loads(report.read_text())] == ["failed", "failed"]
    assert not [p for p in (tmp_path / "out").rglob("*") if p.is_file()]


def test_a_symlink_out_of_the_folder_does_not_stop_the_batch(tmp_path, monkeypatch):
    """A program linked from elsewhere (in/link.nc -> ../other/x.nc): today the whole batch
    stops with a ValueError traceback (exit 1) before any file is done."""
    monkeypatch.chdir(tmp_path)
    src, other, out = tmp_path / "in", tmp_path / "other", tmp_path / "out"
    src.mkdir()
    other.mkdir()
    shutil.copyfile(CORPUS / "pygcode" / "Clamp.nc", other / "x.nc")
    shutil.copyfile(CORPUS / "pygcode" / "Clamp.nc", src / "real.nc")
    (src / "link.nc").symlink_to(Path("..") / "other" / "x.nc")
    before = sha(other / "x.nc")
    result = invoke(["batch", src, *OPTIONS, "-o", out])
    assert result.exit_code in (Exit.OK, Exit.SOME_FAILED), result.stderr
    assert (out / "real.nc").is_file()
    assert sha(other / "x.nc") == before and sorted(os.listdir(other)) == ["x.nc"]
    assert all(p.resolve().is_relative_to(out.resolve()) for p in out.rglob("*"))


# ---------------------------------------------------------------- interrupted ----
COPIES = 40  # a batch far longer than the second it runs before the signal, on any machine


@pytest.mark.slow
@pytest.mark.parametrize("signame, to_group", [("SIGINT", True), ("SIGTERM", False)],
                         ids=["ctrl-c", "sigterm"])
def test_an_interrupted_batch_leaves_no_partial_file(tmp_path, signame, to_group):
    src, out = tmp_path / "in", tmp_path / "out"
    src.mkdir()
    data = BOWL_MPF.read_bytes()
    last_line = data.rstrip(b"\r\n").rsplit(b"\n", 1)[-1]
    for i in range(COPIES):
        (src / f"bowl_{i:02d}.mpf").write_bytes(data)
    cmd = [sys.executable, "-c", "from ncopt.cli.app import main; main()", "batch", str(src),
           "--accel", "227", "--max-rpm", "15000", "-o", str(out), "--jobs", "2"]
    env = {**os.environ, "NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100",
           "XDG_CONFIG_HOME": str(tmp_path / "config")}
    # a Ctrl-C at a terminal: SIGINT at its default in the batch, even where this suite runs
    # in the background of a shell without job control, which starts it ignored (inherited)
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        # once the batch is under way (a first file is complete)
        t0 = time.monotonic()
        while proc.poll() is None and time.monotonic() - t0 < 60:
            done = [p for p in out.glob("*.mpf")] if out.is_dir() else []
            if done:
                break
            time.sleep(0.02)
        assert proc.poll() is None, "the batch ended before it could be interrupted"
        sig = getattr(signal, signame)
        os.killpg(proc.pid, sig) if to_group else proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == Exit.INTERRUPTED, stderr.decode(errors="replace")[-3000:]
    assert stderr.decode().splitlines()[-1] == (
        "ncopt: interrupted; finished files are complete, no partial file was left")
    assert not [p for p in tmp_path.rglob("*") if p.name.endswith(TMP_SUFFIX)]
    outputs = sorted(p for p in out.rglob("*") if p.is_file())
    assert 1 <= len(outputs) < COPIES  # some were complete, the rest never started or stopped
    assert {p.name for p in outputs} <= {f"bowl_{i:02d}.mpf" for i in range(COPIES)}
    def but_its_name(text: bytes) -> bytes:  # the stamp names the file it was planned from
        return re.sub(rb"(?m)^; ncopt from .*$", b"; ncopt from", text)

    first = but_its_name(outputs[0].read_bytes())
    for p in outputs:  # every output is whole: the same rewrite of the same program
        text = p.read_bytes()
        assert text.rstrip(b"\r\n").endswith(last_line)
        parse_text(text.decode("latin-1"), str(p))
        assert but_its_name(text) == first
        assert f"; ncopt from {p.name}\n".encode() in text
    for p in src.iterdir():
        assert p.read_bytes() == data
    # the workers are gone too
    if Path("/proc").is_dir():
        time.sleep(0.2)
        left = []
        for d in Path("/proc").iterdir():
            try:
                if d.name.isdigit() and str(src).encode() in (d / "cmdline").read_bytes():
                    left.append(d.name)
            except OSError:
                pass
        assert not left, f"worker processes still running: {left}"
