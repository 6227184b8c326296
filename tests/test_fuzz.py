"""Hostile input: random bytes, mutated corpus lines, odd encodings and sizes.

Whatever comes in, parse_text / interpret / rewrite end either with a result or with an
NcoptError that says where (path, and the line for anything about a line), and a program
file given to the CLI is never modified.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.cli.app import Exit, app
from ncopt.runtime.errors import NcoptError, NcParseError, PlanningError, UsageError
from ncopt.motion.interp import interpret
from ncopt.model import Cutter, CuttingData, Machine
from ncopt.reading.parse import parse_text

ROOT = Path(__file__).resolve().parents[1]
CORPUS = (ROOT / "../shared/corpus").resolve()
PATH = "fuzz.nc"
# every operation planned, whatever it is: hostile input should reach every stage
JOB = Job(cutter=Cutter(10.0, 2), machine=Machine(accel_rad_s2=100.0, max_rpm=12000.0),
          cutting=CuttingData(vc_m_min=100.0, fz_mm=0.05), operations=("all",))
STAMP_LINE = re.compile(r"^\s*[(;]\s*ncopt ")
HEADER = "G21 G90 G17\nT1 M6\nS5000 M3\nG0 X0 Y0 Z5\nG1 Z0 F500\n"


def _sample_lines() -> list[str]:
    """Lines of several real programs, read once (the mutation seeds)."""
    out = []
    for rel in ("camotics/flower_mold.nc", "fusion/chess_engraved_box.nc", "camotics/bear.nc",
                "linuxcnc/3D_Chips.ngc", "pygcode/Mach3 write.tap",
                "linuxcnc/interp-tests/flowsnake/flowsnake.ngc"):
        path = CORPUS / rel
        if path.is_file():
            lines = path.read_bytes().decode("latin-1").splitlines()
            out += lines[:: max(1, len(lines) // 150)][:150]
    return out or ["G1 X1 Y2 Z3 F100"]


SEED_LINES = _sample_lines()


def located(exc: NcoptError, path: str, need_line: bool) -> None:
    assert isinstance(exc, NcoptError)
    assert exc.path == path, str(exc)
    assert str(exc).startswith(path + ":")
    if need_line:
        assert exc.line is not None and exc.line >= 1, str(exc)


def run_chain(text: str, path: str = PATH) -> str | None:
    """parse -> interpret -> rewrite (no mesh); only located NcoptErrors may stop it."""
    try:
        prog = parse_text(text, path)
    except NcoptError as exc:
        assert isinstance(exc, NcParseError)
        located(exc, path, need_line=True)
        assert 1 <= exc.line <= text.count("\n") + 1
        return None
    assert prog.text == text
    try:
        interpret(prog)
    except NcoptError as exc:
        located(exc, path, need_line=True)
        return None
    try:
        return rewrite_text(text, JOB, path).text
    except (UsageError, PlanningError) as exc:
        located(exc, path, need_line=False)  # about the whole program (no cut, tools...)
    except NcoptError as exc:
        located(exc, path, need_line=True)
    return None


# ------------------------------------------------------------------ random bytes ----
@settings(max_examples=150)
@given(st.binary(max_size=400))
def test_random_bytes(data):
    run_chain(data.decode("latin-1"))


@settings(max_examples=100)
@given(st.lists(st.text(st.sampled_from("GXYZFSMNIJKR0123456789.-+ #[]()=;%\n\r\t/O"),
                        max_size=30), max_size=20))
def test_random_gcode_alphabet(lines):
    run_chain(HEADER + "\n".join(lines))


# ----------------------------------------------------------- mutated real lines ----
INSERTABLE = list("GXYZFS0123456789.-+ ()[]#=;%/\t\x00\xff")


@st.composite
def mutated_programs(draw):
    lines = draw(st.lists(st.sampled_from(SEED_LINES), min_size=1, max_size=25))
    out = []
    for line in lines:
        chars = list(line)
        for _ in range(draw(st.integers(0, 3))):
            op = draw(st.sampled_from(["delete", "insert", "swap"]))
            i = draw(st.integers(0, max(len(chars) - 1, 0)))
            if op == "insert":
                chars.insert(i, draw(st.sampled_from(INSERTABLE)))
            elif chars and op == "delete":
                del chars[i]
            elif len(chars) > 1:
                j = min(i + 1, len(chars) - 1)
                chars[i], chars[j] = chars[j], chars[i]
        out.append("".join(chars))
    newline = draw(st.sampled_from(["\n", "\r\n"]))
    final = draw(st.booleans())
    return HEADER.replace("\n", newline) + newline.join(out) + (newline if final else "")


@settings(max_examples=120)
@given(mutated_programs())
def test_mutated_corpus_lines(text):
    out = run_chain(text)
    if out is not None:  # a rewrite that succeeds keeps the line structure
        stamp = sum(1 for line in out.splitlines() if STAMP_LINE.match(line))
        assert out.count("\r\n") - text.count("\r\n") in (0, stamp)  # the stamp's lines
        assert out.count("\n") - text.count("\n") in (0, stamp)


# ------------------------------------------------- encodings, endings, sizes ----
@pytest.mark.parametrize("newline, final", [("\n", True), ("\r\n", True), ("\n", False),
                                            ("\r\n", False)])
def test_non_utf8_comments_and_line_endings_survive(newline, final):
    body = ["(caf\xe9 \xff\xfe \x80 Gr\xfc\xdfe)", "G21 G90", "T1 M6", "S5000 M3",
            "G0 X0 Y0 Z5", "G1 Z-1 F500 ; \xb0C \xa0nbsp"]
    body += [f"X{i} Y{(i % 7) * 0.5:.1f} Z{-1 - 0.1 * (i % 5):.1f}" for i in range(1, 60)]
    body += ["M5", "M30"]
    text = newline.join(body) + (newline if final else "")
    out = run_chain(text)
    assert out is not None
    raw_out = out.encode("latin-1")
    for needle in (b"(caf\xe9 \xff\xfe \x80 Gr\xfc\xdfe)", b"; \xb0C \xa0nbsp"):
        assert raw_out.count(needle) == 1
    assert out.endswith(newline if final else "M30")
    if newline == "\r\n":  # every line ending stays CRLF, the stamp's too
        assert out.count("\n") == out.count("\r\n")
    else:
        assert "\r" not in out


def test_a_100_kb_comment_line():
    text = HEADER + "(" + "x" * 100_000 + ")\nG1 X1\nM30\n"
    prog = parse_text(text, PATH)
    assert prog.n_lines == 8 and prog.line_kind[5] == 0  # a blank (comment) line
    run_chain(text)


def test_a_100_kb_word_line():
    words = " ".join(f"X{i % 97}.{i % 10}" for i in range(18_000))
    assert len(words) > 100_000
    text = HEADER + words + "\nM30\n"
    prog = parse_text(text, PATH)
    assert prog.n_words == 15 + 18_000  # 14 words in HEADER, M30
    run_chain(text)


def test_a_100_kb_garbage_line_fails_located():
    junk = "G1 X1 " + "?" * 100_000
    with pytest.raises(NcParseError) as info:
        parse_text(HEADER + junk + "\n", PATH)
    err = info.value
    assert (err.path, err.line, err.column) == (PATH, 6, 7)


def test_nul_bytes_and_tape_leaders():
    text = "\x00\x00\x00%\nO1\n" + HEADER + "X1\x00\nX2\n%\n\x00\x00"
    run_chain(text)


def test_empty_and_blank_programs():
    for text in ("", "\n", "\r\n", "   ", "%\n%\n", "(only a comment)"):
        run_chain(text)


# ----------------------------------------------------------- through the CLI ----
def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@settings(max_examples=25)
@given(st.one_of(mutated_programs(), st.binary(max_size=200).map(lambda b: b.decode("latin-1"))))
def test_cli_never_modifies_its_input(tmp_path_factory, text):
    folder = tmp_path_factory.mktemp("fuzz")
    src = folder / "in.nc"
    src.write_bytes(text.encode("latin-1"))
    before = _sha(src)
    out = folder / "out.nc"
    result = CliRunner().invoke(app, ["rewrite", str(src), "--diameter", "10", "--teeth", "2",
                                      "--accel", "100", "--max-rpm", "12000", "--vc", "100",
                                      "--fz", "0.05", "-o", str(out)])
    assert _sha(src) == before
    assert result.exit_code in {int(e) for e in Exit} - {Exit.INTERNAL}, result.output
    assert "Traceback" not in result.stderr
    if result.exit_code == Exit.OK:
        assert out.is_file()
    else:
        assert not out.exists()
        assert result.stderr.startswith(f"{src}:")
    assert sorted(p.name for p in folder.iterdir()) in (["in.nc"], ["in.nc", "out.nc"])
