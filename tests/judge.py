"""LinuxCNC's RS-274NGC interpreter (``rs274`` from Debian's linuxcnc-uspace) as
an independent judge of rewrites: nobody here wrote it.

The canonical motion calls carry every axis, A B C included; in G93 rs274 turns each
block's F (1 / minutes) into the feed rate over the block's length, and
:func:`feed_in_program_units` turns it back.

``canon(text)`` runs ``rs274 -g`` and returns the canonical calls; constructs it
rejects that are dialect, not geometry, are stripped from *both* programs
before the comparison (see ``STRIPPED``), and the tests say so.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

RS274 = shutil.which("rs274")

# dialect constructs rs274 rejects, removed from both programs before comparing
STRIPPED = (
    (re.compile(r"(?<![A-Za-z])[Dd]\s*\d+(?![.\d])(?=[^()\n]*$)", re.M), ""),  # D01 without G41/G42
    (re.compile(r"^\s*[Oo]\d+\b(?![^(\n]*\b(?:sub|call|if|while|do|endsub)\b)", re.M), ""),  # O1001
    (re.compile(r"[\x01-\x08\x0e-\x1f\x7f]"), ""),  # tape leader control codes
    # M428-M430 switch kinematics in LinuxCNC's 5-axis sim configs (remaps rs274 alone lacks)
    (re.compile(r"(?<![A-Za-z0-9.])[Mm]\s*4(?:28|29|30)(?![\d.])"), ""),
)
_G80 = re.compile(r"\b[Gg]0*80\b")
_MOTION = re.compile(r"\b[Gg]0*[0-3]\b(?!\.)")
_CALL = re.compile(r"(STRAIGHT_TRAVERSE|STRAIGHT_FEED|ARC_FEED|SET_FEED_RATE|SET_SPINDLE_SPEED|"
                   r"STRAIGHT_PROBE)\((.*)\)\s*$")


@dataclass(frozen=True)
class Canon:
    """Motion calls and, for each feed call, the feed and spindle speed in force."""

    motion: list  # (name, args string) for every traverse/feed/arc
    feed_state: list  # (args, feed rate, spindle speed) for every STRAIGHT_FEED / ARC_FEED


def strip_dialect(text: str) -> str:
    for pattern, repl in STRIPPED:
        text = pattern.sub(repl, text)
    # Fanuc moves axis words after G80 in rapid; LinuxCNC wants a motion code, so a lone
    # G80 becomes G0 (which ends the cycle too) and one beside a motion code goes
    lines = text.split("\n")
    for i, line in enumerate(lines):
        if _G80.search(line):
            lines[i] = _G80.sub("" if _MOTION.search(_G80.sub("", line)) else "G0", line)
    return "\n".join(lines)


def tool_table(path: Path) -> Path:
    path.write_text("".join(f"T{t} P{t} Z0 D6 ;judge\n" for t in range(1, 100)))
    return path


def feed_in_program_units(feed: float, inverse_time: bool, length: float) -> float:
    """The F word that gives rs274's feed rate: itself in G94, feed / length in G93
    (rs274 reports F x the move's length for an inverse-time move)."""
    return feed / length if inverse_time and length > 0 else feed


def canon(text: str, workdir: Path | None = None) -> Canon:
    """Run rs274 on a program (given as text); raise if it rejects it."""
    work = Path(workdir or tempfile.mkdtemp(prefix="judge"))
    prog = work / "prog.ngc"
    prog.write_bytes(strip_dialect(text).encode("latin-1"))
    env = dict(os.environ, HOME=str(work))  # rs274 keeps $HOME/.tool.mmap: one per run
    done = subprocess.run([RS274, "-g", "-t", str(tool_table(work / "tool.tbl")), str(prog)],
                          capture_output=True, text=True, env=env, timeout=300,
                          encoding="latin-1")
    if done.returncode != 0:
        raise RuntimeError(f"rs274 rejected the program: {done.stderr.strip()[-300:]}")
    motion, state = [], []
    feed = speed = None
    for line in done.stdout.splitlines():
        m = _CALL.search(line)
        if not m:
            continue
        name, args = m.groups()
        if name == "SET_FEED_RATE":
            feed = float(args)
        elif name == "SET_SPINDLE_SPEED":
            speed = float(args.split(",")[-1])
        else:
            motion.append((name, args))
            if name in ("STRAIGHT_FEED", "ARC_FEED"):
                state.append((args, feed, speed))
    return Canon(motion, state)
