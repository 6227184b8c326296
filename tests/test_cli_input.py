"""What ncopt reads, through the command line: refused input gives exit 3 and one located
message (``file:line:col: what; what to do`` and at most one line of context) in every
command that reads a program."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from ncopt.cli.app import Exit, app

SPINDLE = ["--diameter", "2", "--teeth", "2", "--accel", "227", "--max-rpm", "15000"]
KLARTEXT = ("0 BEGIN PGM W5269NS01007C26 MM\n1 ; --- TOOLLIST BEGIN ---\n"
            "2 L Z+0.0 R0 FMAX M92\n3 END PGM W5269NS01007C26 MM\n")


def invoke(args):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100"})
    result = runner.invoke(app, [str(a) for a in args], catch_exceptions=False)
    assert "Traceback" not in result.stdout + result.stderr
    return result


def write(tmp_path: Path, name: str, data: bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(data)
    return path


COMMANDS = [["inspect"], ["rewrite", *SPINDLE], ["simulate", *SPINDLE]]


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c[0])
def test_a_klartext_program_is_named_and_refused(tmp_path, command):
    path = write(tmp_path, "w.h", KLARTEXT.encode())
    result = invoke([command[0], path, *command[1:]])
    assert result.exit_code == Exit.PROGRAM
    assert result.stderr.splitlines() == [
        f"{path}:1:1: `0 BEGIN PGM W5269NS01007C26 MM` starts a Heidenhain conversational "
        "(Klartext) program, not ISO/DIN G-code; ncopt reads G-code only: post the program as "
        "ISO (DIN/ISO), e.g. with the CAM system's Heidenhain ISO post-processor",
        "    0 BEGIN PGM W5269NS01007C26 MM",
        "    ^"]


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c[0])
def test_a_duplicate_word_is_refused_at_it(tmp_path, command):
    path = write(tmp_path, "d.nc", b"G21 G90\nT1 M6\nS1000 M3\nG0 X0 Y0 Z1\nG1 Z0 F100 F200\n")
    result = invoke([command[0], path, *command[1:]])
    assert result.exit_code == Exit.PROGRAM
    assert result.stderr.splitlines() == [
        f"{path}:5:12: `F100` and `F200` on one line: a block takes one F word (LinuxCNC "
        "refuses it: \"Multiple f words on one line\"); keep the one you mean and delete the "
        "other", "    G1 Z0 F100 F200", "               ^"]


def test_a_utf16_file_is_refused_by_name(tmp_path):
    path = write(tmp_path, "u.nc", "G21\nG1 X1 F100\n".encode("utf-16"))
    result = invoke(["inspect", path])
    assert result.exit_code == Exit.PROGRAM
    assert result.stderr == (f"{path}:1:1: the file is UTF-16 text (several bytes per "
                             "character), which NC controls do not read; save it as ASCII or "
                             "UTF-8 and run ncopt again\n")


def test_a_negative_feed_is_not_called_a_zero_feed(tmp_path):
    path = write(tmp_path, "f.nc", b"G21\nG0 X0 Y0 Z0\nG1 X1 F-279\n")
    result = invoke(["inspect", path])
    assert result.exit_code == Exit.PROGRAM
    assert result.stderr.splitlines()[0] == (
        f"{path}:3:7: `F-279` is a negative feed rate (-279); a feed rate is positive: fix the "
        "F word")


def test_a_cr_only_file_echoes_one_line_at_most(tmp_path):
    path = write(tmp_path, "cr.nc", b"G1 X1.123 Y2.456 Z-0.5 F100\r" * 1500)
    result = invoke(["inspect", path])
    assert result.exit_code == Exit.PROGRAM
    assert len(result.stderr) < 500  # not the 41 KB of the file
    assert result.stderr.startswith(f"{path}:1:28: the lines end with CR alone")


def test_a_byte_order_mark_is_refused_and_nothing_is_written(tmp_path):
    src = write(tmp_path, "bom.nc", b"\xef\xbb\xbfG21 G90\nG0 X0 Y0 Z1\nG1 Z0 F300\n")
    out = tmp_path / "out.nc"
    result = invoke(["rewrite", src, *SPINDLE, "-o", out])
    assert result.exit_code == Exit.PROGRAM
    assert result.stderr.startswith(f"{src}:1:1: the file starts with a UTF-8 byte order mark")
    assert not out.exists()
