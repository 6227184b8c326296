"""batch, rewrite and simulate on a real terminal: a pseudo-terminal with a real TERM.

The other tests run ncopt with pipes, where rich draws nothing live; a shop runs it by hand
in a terminal, where the progress display is drawn. Each command here runs as its own
process with stdin, stdout and stderr on a pty, as a shell gives them.
"""

from __future__ import annotations

import os
import pty
import select
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BOWL_MPF = ROOT / "samples" / "bowl.mpf"
SPINDLE = ["--diameter", "16", "--teeth", "2", "--accel", "227", "--max-rpm", "15000"]
TIMEOUT_S = 600  # a hang ends the test instead of the suite; not a speed budget


def on_terminal(args: list[str], cwd: Path, term: str) -> tuple[int, str]:
    """Run ``ncopt ARGS`` with every standard stream on one pty: (exit code, what the
    terminal showed, escape sequences included)."""
    main, sub = pty.openpty()
    env = {k: v for k, v in os.environ.items() if k not in ("NO_COLOR", "FORCE_COLOR", "CI")}
    env.update(TERM=term, COLUMNS="100", LINES="40")
    proc = subprocess.Popen([sys.executable, "-m", "ncopt", *args], cwd=cwd, stdin=sub,
                            stdout=sub, stderr=sub, env=env, close_fds=True)
    os.close(sub)
    shown = bytearray()
    deadline = time.monotonic() + TIMEOUT_S
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([main], [], [], 0.5)
            if ready:
                try:
                    chunk = os.read(main, 65536)
                except OSError:  # EIO: the process closed its side
                    break
                if not chunk:
                    break
                shown += chunk
            elif proc.poll() is not None:
                break
        else:
            proc.kill()
            pytest.fail(f"ncopt {' '.join(args)} did not end within {TIMEOUT_S} s on a pty")
        code = proc.wait(timeout=60)
    finally:
        os.close(main)
    return code, shown.decode("utf-8", "replace")


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    (tmp_path / "in" / "sub").mkdir(parents=True)
    shutil.copy(BOWL_MPF, tmp_path / "in" / "bowl.mpf")
    shutil.copy(BOWL_MPF, tmp_path / "in" / "sub" / "bowl2.mpf")
    return tmp_path


@pytest.mark.slow
@pytest.mark.parametrize("term", ["xterm-256color", "dumb"])
def test_batch_runs_on_a_terminal_with_progress(folder: Path, term: str) -> None:
    code, shown = on_terminal(["batch", "in", "-o", "out", *SPINDLE], folder, term)
    assert code == 0, shown
    assert "Traceback" not in shown and "Error" not in shown, shown
    assert (folder / "out" / "bowl.mpf").read_bytes() != BOWL_MPF.read_bytes()
    assert (folder / "out" / "sub" / "bowl2.mpf").is_file()
    # the two bars were drawn and reached their ends; the table and the totals follow
    assert "files" in shown and "2/2" in shown, shown
    assert "2 rewritten, 0 unchanged (nothing to plan), 0 failed, of 2 files" in shown


def test_rewrite_shows_its_stages_on_a_terminal(folder: Path) -> None:
    code, shown = on_terminal(["rewrite", "in/bowl.mpf", "-o", "out.mpf", *SPINDLE],
                              folder, "xterm-256color")
    assert code == 0, shown
    assert "Traceback" not in shown, shown
    assert "ncopt: finding the contacts and planning S and F" in shown, shown
    assert "ncopt: checking the output" in shown, shown
    assert "S and 20" in shown and "F words written" in shown  # the summary after it
    assert b"; ncopt sample: bowl mould" in (folder / "out.mpf").read_bytes()


def test_rewrite_to_the_terminal_keeps_the_program_clean(folder: Path) -> None:
    """With stdout on the terminal too, the program is printed; the stage display (on
    stderr) is removed when the work ends, so the program's last line is intact."""
    code, shown = on_terminal(["rewrite", "in/bowl.mpf", "-q", *SPINDLE], folder,
                              "xterm-256color")
    assert code == 0, shown
    assert "N100 T04 D01" in shown and "M30" in shown[-4000:], shown[-2000:]
    assert "planning S and F" not in shown  # -q: no stage display either


def test_simulate_shows_its_stages_on_a_terminal(folder: Path) -> None:
    code, shown = on_terminal(["simulate", "in/bowl.mpf", "--sample", "1", *SPINDLE],
                              folder, "xterm-256color")
    assert code == 0, shown
    assert "Traceback" not in shown, shown
    assert "ncopt: simulating in/bowl.mpf" in shown, shown
    assert "fz within +-" in shown  # the report printed after the display ended


def test_no_progress_when_stderr_is_not_a_terminal(folder: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "ncopt", "batch", "in", "-o", "out", *SPINDLE],
                          cwd=folder, capture_output=True, text=True, timeout=TIMEOUT_S,
                          env={**os.environ, "TERM": "xterm-256color"})
    assert proc.returncode == 0, proc.stderr
    assert "\x1b[" not in proc.stderr and "━" not in proc.stderr, proc.stderr
    assert "of 2 files" in proc.stderr
