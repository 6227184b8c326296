"""Golden cases: tests/golden/cases/NAME/{input.*, args, expected.*}, one parametrized test.

Each case is also checked for equivalence (only S/F words and one stamp comment line
differ; same toolpath) and stability (rewriting the expected output gives it back).
Regenerate with ``python tests/golden/make_golden.py --expected`` and inspect the diff.
"""

from __future__ import annotations

import shlex
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from ncopt.cli.app import Exit, app
from ncopt.motion.interp import interpret
from ncopt.model import LineKind
from ncopt.reading.parse import parse_text
from ncopt.writing.edits import masked

CASES = Path(__file__).resolve().parent / "golden" / "cases"
CASE_DIRS = sorted(p for p in CASES.iterdir() if (p / "args").is_file()) if CASES.is_dir() else []


# the stamp's date, as make_golden.py writes the expected outputs
GOLDEN_ENV = {"SOURCE_DATE_EPOCH": "1767225600"}


def _args(case: Path) -> list[str]:
    args = shlex.split((case / "args").read_text())
    return [str((case / a).resolve()) if i and args[i - 1] == "--mesh" else a
            for i, a in enumerate(args)]


def _rewrite(src: Path, case: Path, out: Path) -> bytes:
    result = CliRunner(env=GOLDEN_ENV).invoke(app, ["rewrite", str(src), *_args(case), "-o",
                                                    str(out), "-q"])
    assert result.exit_code == Exit.OK, result.stderr
    assert "\x1b[" not in result.stderr
    return out.read_bytes()


def _drop_stamp(base: str, longer: str) -> tuple[str, str]:
    """``longer`` without the block of comment lines it has in addition to ``base``, and
    that block."""
    a, b = base.splitlines(keepends=True), longer.splitlines(keepends=True)
    n = len(b) - len(a)
    assert n >= 6
    i = next((k for k, (x, y) in enumerate(zip(a, b)) if x != y), len(a))
    return "".join(b[:i] + b[i + n:]), "".join(b[i:i + n])


def test_golden_cases_exist():
    assert len(CASE_DIRS) >= 3
    for case in CASE_DIRS:
        assert len(list(case.glob("input.*"))) == 1 and len(list(case.glob("expected.*"))) == 1


@pytest.mark.parametrize("case", CASE_DIRS, ids=lambda p: p.name)
def test_golden(case, tmp_path):
    src = next(case.glob("input.*"))
    expected_path = next(case.glob("expected.*"))
    expected = expected_path.read_bytes()
    got = _rewrite(src, case, tmp_path / f"out{src.suffix}")
    assert got == expected, f"{case.name}: output differs from {expected_path.name}"

    # equivalence: one stamp comment line, S/F words; the same toolpath
    text_in, text_out = src.read_bytes().decode("latin-1"), expected.decode("latin-1")
    plain, stamp = _drop_stamp(text_in, text_out)
    assert "ncopt" in stamp
    assert set(parse_text(stamp).line_kind.tolist()) == {LineKind.BLANK}
    a, b = parse_text(text_in, str(src)), parse_text(plain, str(src))
    assert masked(a) == masked(b)
    tp_a, tp_b = interpret(a), interpret(b)
    assert np.array_equal(tp_a.xyz_mm, tp_b.xyz_mm)
    assert np.array_equal(interpret(parse_text(text_out)).xyz_mm, tp_a.xyz_mm)
    n_stamp = stamp.count("\n")
    assert text_out.count("\r\n") == text_in.count("\r\n") + (n_stamp if "\r\n" in text_in else 0)

    # stability: the expected output rewritten with the same flags is itself
    again = _rewrite(expected_path, case, tmp_path / f"again{src.suffix}")
    assert again == expected


def test_golden_meshes_are_small():
    for stl in (CASES.parent / "meshes").glob("*.stl"):
        assert stl.stat().st_size < 200_000
