"""The stamp a rewrite writes is ncopt's, never a CAM notice or an operation's name: an
operation has the same name in a program and in ncopt's rewrite of it, so a second
rewrite with the same ``--operations NAME`` plans the same operation and changes nothing
(ncopt issue 28: the stamp's lines, read as the notices Fusion writes before a name,
made the comment after them the operation's name)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest
from typer.testing import CliRunner

from ncopt.cli.app import Exit, app
from ncopt.model import Cutter, CuttingData
from ncopt.planning.opnames import operation_comments
from ncopt.reading.parse import parse_text
from ncopt.reading.stamp import StampInfo, read_stamps, stamp_edit, unstamped_line

SPINDLE = ["--accel", "227", "--max-rpm", "15000"]  # rad/s^2, RPM


def dome_program() -> str:
    """A serpentine finish over the dome z = 10 - 0.025 (x^2 + y^2) mm (the case the
    options' judge found): its first comment opens the program and names no operation
    (no blank line or tool call before it, none after it), so the operation is T1."""
    grid = [-10, -6, -2, 2, 6, 10]  # mm
    lines = ["(surface dome 6x6)", "G21 G90 G94 G17", "T1 M6", "S4000 M3",
             "G0 X-10.000 Y-10.000 Z15.000", "G1 X-10.000 Y-10.000 Z5.000 F800"]
    for k, y in enumerate(grid):
        for x in grid if k % 2 == 0 else grid[::-1]:
            lines.append(f"G1 X{x:.3f} Y{y:.3f} Z{10 - 0.025 * (x * x + y * y):.3f}")
    return "\n".join(lines + ["G0 Z15.000", "M5", "M30"]) + "\n"


def hypermill_program() -> str:
    """hyperMILL's G-code post: a ``JOB:`` line names the operation, after a header."""
    return "\n".join([
        "%", "O1000", "(hyperMILL post)", "( *   - JOB: 68: FreePar12_FRA-SP0140 )",
        "T4 M6", "S6000 M3", "G0 X0 Y0 Z5", "G1 Z0 F500", "G1 X10", "G1 Y2", "G1 X0",
        "M30", "%"]) + "\n"


def fusion_program() -> str:
    """Fusion's form: the tool list, its notices, a blank line, the name, the tool call."""
    return "\n".join([
        "%", "O01001", "(T1 D=6. CR=3. - ZMIN=-9. - ball end mill)", "G90 G94 G17", "G21",
        "(When using Fusion for Personal Use, the feedrate of rapid)",
        "(moves is reduced to match the feedrate of cutting moves,)", "G53 G0 Z0.", "",
        "(PARALLEL1)", "T1 M6", "S8000 M3", "G0 X0 Y0 Z5", "G1 Z0 F600", "G1 X10", "G1 Y1",
        "G1 X0", "M30", "%"]) + "\n"


def names(text: str) -> dict[int, str]:
    """1-based line (numbered without the stamp lines) -> operation name."""
    prog = parse_text(text)
    stamps = read_stamps(prog)
    return {unstamped_line(stamps, i): name for i, name in operation_comments(prog).items()}


def with_a_stamp(text: str) -> str:
    """The program with a stamp inserted where a rewrite writes one."""
    prog = parse_text(text)
    plan = SimpleNamespace(tool=1, lines=(1, prog.n_lines), cutting=CuttingData(90.0, 0.05),
                           s0_rpm=4000.0, cutting_feed_mm_min=800.0, cutter=Cutter(6.0, 2, 3.0))
    info = StampInfo("2026-11-27", "prog.nc", "227 rad/s2, 15000 RPM", 1.0, 0.5)
    edit = stamp_edit(prog, [plan], 2.0, info)
    return text[:edit.start] + edit.text + text[edit.end:]


def corpus_text(corpus_dir: Path, name: str) -> str:
    return (corpus_dir / name).read_text(encoding="latin-1")


@pytest.mark.parametrize("make", [dome_program, hypermill_program, fusion_program])
def test_a_stamp_changes_no_operation_name_of_a_generated_program(make):
    text = make()
    assert names(with_a_stamp(text)) == names(text)


@pytest.mark.parametrize("name, named", [
    ("pygcode/Skull2.tap", {}),  # "( SKULL2 )" opens the program: no operation's name
    ("pygcode/Snow White.tap", {}),
    ("pygcode/Disc3.tap", {}),
    ("more2/fusion-haas-es_1001.nc", {13: "Paralelo2"}),
    ("linuxcnc/5axis/boat-xyzac.ngc", {8: "ROUGH7 Z LEVEL SRF_MILL1"}),
])
def test_a_stamp_changes_no_operation_name_of_a_corpus_program(corpus_dir, name, named):
    text = corpus_text(corpus_dir, name)
    before = names(text)
    assert names(with_a_stamp(text)) == before
    assert named.items() <= before.items()


def invoke(args):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100"})
    return runner.invoke(app, [str(a) for a in args], catch_exceptions=False)


@pytest.mark.parametrize("name, options", [
    ("dome", ["--diameter", "6", "--teeth", "2", "--operations", "T1"]),
    ("pygcode/Skull2.tap", ["--diameter", "3", "--shape", "ball", "--operations", "T1"]),
    ("pygcode/Snow White.tap", ["--diameter", "3", "--shape", "ball", "--operations", "T1"]),
    ("more2/fusion-haas-es_1001.nc", ["--diameter", "6", "--operations", "Paralelo2"]),
])
def test_a_second_rewrite_with_the_same_operations_plans_them_again(
        corpus_dir, tmp_path, name, options):
    text = dome_program() if name == "dome" else corpus_text(corpus_dir, name)
    source = tmp_path / ("prog" + Path(name).suffix)
    source.write_bytes(text.encode("latin-1"))
    first, again = tmp_path / ("out" + source.suffix), tmp_path / ("again" + source.suffix)
    result = invoke(["rewrite", source, *options, *SPINDLE, "-q", "-o", first])
    assert result.exit_code == Exit.OK, result.output
    out = first.read_bytes()
    assert out != text.encode("latin-1")  # planned and stamped
    assert names(out.decode("latin-1")) == names(text)
    result = invoke(["rewrite", first, *options, *SPINDLE, "-q", "-o", again])
    assert result.exit_code == Exit.OK, result.output
    assert again.read_bytes() == out
