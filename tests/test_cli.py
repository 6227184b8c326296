"""The ``ncopt`` command line through typer's CliRunner: exit codes and exact messages."""

from __future__ import annotations

import hashlib
import io
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console
from typer.testing import CliRunner

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.cli.app import Exit, app, print_summary
from ncopt.model import Cutter, CuttingData, Machine
from ncopt.reading.parse import parse_text
from ncopt.writing.edits import masked

ROOT = Path(__file__).resolve().parents[1]
BOWL_MPF = ROOT / "samples" / "bowl.mpf"
BOWL_STL = ROOT / "samples" / "bowl.stl"
SPINDLE = ["--diameter", "16", "--teeth", "2", "--accel", "227", "--max-rpm", "15000"]


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def invoke(args, stdin: bytes | None = None):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100"})
    result = runner.invoke(app, [str(a) for a in args], input=stdin, catch_exceptions=False)
    for stream in (result.stdout, result.stderr):
        assert "\x1b[" not in stream  # nothing rendered with colour
        assert "Traceback" not in stream
    return result


def without_one_comment_line(base: str, longer: str) -> str:
    """``longer`` minus the block of comment lines (the stamp: four of header, two per
    planned operation) it holds in addition to ``base``."""
    a, b = base.splitlines(keepends=True), longer.splitlines(keepends=True)
    n = len(b) - len(a)
    assert n >= 6 and n % 2 == 0, n
    i = next((k for k, (x, y) in enumerate(zip(a, b)) if x != y), len(a))
    assert all(line.lstrip().startswith(("(ncopt ", "; ncopt ")) for line in b[i:i + n])
    return "".join(b[:i] + b[i + n:])


# ------------------------------------------------------------- the sample bowl ----
@pytest.fixture(scope="module")
def bowl_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "bowl_out.mpf"
    before = sha(BOWL_MPF)
    result = invoke(["rewrite", BOWL_MPF, "--mesh", BOWL_STL, *SPINDLE, "-o", out])
    return result, out, before


def test_rewrite_the_sample_bowl(bowl_run):
    result, out, before = bowl_run
    assert result.exit_code == Exit.OK, result.stderr
    assert result.stdout == ""  # the program went to the file
    lines = result.stderr.splitlines()
    assert lines and all(line.startswith(("ncopt: ", "warning: ")) for line in lines)
    assert any("cutting blocks planned" in line for line in lines)
    assert sha(BOWL_MPF) == before  # the input is never touched
    text_in = BOWL_MPF.read_bytes().decode("latin-1")
    text_out = out.read_bytes().decode("latin-1")
    assert text_out != text_in
    plain = without_one_comment_line(text_in, text_out)
    assert masked(parse_text(plain)) == masked(parse_text(text_in))


def test_rewrite_of_the_bowl_keeps_s_in_the_machine_range(bowl_run):
    _, out, _ = bowl_run
    prog = parse_text(out.read_bytes().decode("latin-1"))
    s = prog.word_value[prog.word_letter == ord("S")]
    assert s.size > 1 and np.all(s <= 15000) and np.all(s > 0)
    # the spindle-start block carries the first S (N104 S1393 M03 in the input)
    start = [i for i in range(prog.n_lines) if "M03" in prog.line_text(i)][0]
    assert prog.line_text(start).startswith("N104 S")


# ----------------------------------------------------------- stdin and stdout ----
@pytest.fixture(scope="module")
def small_program(make_bowl):
    """A few passes over the bowl wall (a small, fast case for stdin/stdout)."""
    lines = ["; wall", "G21 G90", "T1 M6", "S1393 M3", "G0 X40 Y50 Z10"]
    for i, y in enumerate((50.0, 51.5, 53.0)):
        xs = np.linspace(40, 60, 21)[:: (-1) ** i]
        zs = make_bowl.drop_ball_tip_z_mm(xs, np.full_like(xs, y), 8.0)
        lines += [f"G1 X{x:.3f} Y{y:.3f} Z{z:.3f}" + (" F279" if not lines[-1].startswith("G1")
                                                        else "") for x, z in zip(xs, zs)]
    lines += ["G0 Z10", "M5", "M30"]
    return ("\n".join(lines) + "\n").encode("latin-1")


def test_stdin_to_stdout(small_program, bowl_stl):
    result = invoke(["rewrite", "-", "--mesh", bowl_stl, *SPINDLE, "--vc", "70", "--fz", "0.1"],
                    stdin=small_program)
    assert result.exit_code == Exit.OK, result.stderr
    out = result.stdout_bytes.decode("latin-1")
    text = small_program.decode("latin-1")
    plain = without_one_comment_line(text, out)
    assert masked(parse_text(plain)) == masked(parse_text(text))
    assert plain != text  # S and F were rewritten
    # the same as the library gives for the same job
    from ncopt.contacts.geometry import MeshIndex, load_stl
    job = Job(cutter=Cutter(16.0, 2), machine=Machine(227.0, 15000.0),
              cutting=CuttingData(70.0, 0.1))
    assert rewrite_text(text, job, "-", MeshIndex(load_stl(bowl_stl))).text == out
    assert result.stderr.startswith("ncopt: ")


def test_dash_output_is_stdout(small_program, bowl_stl, tmp_path):
    src = tmp_path / "p.nc"
    src.write_bytes(small_program)
    a = invoke(["rewrite", src, "--mesh", bowl_stl, *SPINDLE, "-o", "-", "-q"])
    b = invoke(["rewrite", src, "--mesh", bowl_stl, *SPINDLE, "-q"])
    assert a.exit_code == b.exit_code == Exit.OK
    assert a.stdout_bytes == b.stdout_bytes and len(a.stdout_bytes) > len(small_program)
    assert a.stderr == "" and b.stderr == ""  # --quiet


# --------------------------------------------------------------------- errors ----
def test_missing_program(tmp_path):
    missing = tmp_path / "nope.nc"
    result = invoke(["rewrite", missing, *SPINDLE])
    assert result.exit_code == Exit.IO
    assert result.stderr == f"{missing}: cannot read the file: No such file or directory; " \
                            "check the path\n"
    assert result.stdout == ""


def test_malformed_program(tmp_path, bowl_stl):
    bad = tmp_path / "bad.nc"
    bad.write_bytes(b"G21 G90\nG1 X1.2.3 F100\n")
    before = sha(bad)
    result = invoke(["rewrite", bad, "--mesh", bowl_stl, *SPINDLE])
    assert result.exit_code == Exit.PROGRAM
    first, *context = result.stderr.splitlines()
    assert first == (f"{bad}:2:8: unexpected '.'; expected a word such as X1.5, a comment in "
                     "( ) or after ;, or fix the line")
    assert context == ["    G1 X1.2.3 F100", "           ^"]
    assert result.stdout == ""
    assert sha(bad) == before


def test_program_the_interpreter_rejects(tmp_path, bowl_stl):
    bad = tmp_path / "arc.nc"
    bad.write_bytes(b"G21 G90 G0 X0 Y0 Z0\nS1000 M3\nG2 X30 Y0 R5 F100\n")
    result = invoke(["rewrite", bad, "--mesh", bowl_stl, *SPINDLE])
    assert result.exit_code == Exit.PROGRAM
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{bad}:3:1: ")


def test_bad_mesh(tmp_path, small_program):
    src = tmp_path / "p.nc"
    src.write_bytes(small_program)
    mesh = tmp_path / "part.stl"
    mesh.write_bytes(b"\x00" * 80 + (1000).to_bytes(4, "little") + b"\x01" * 100)
    result = invoke(["rewrite", src, "--mesh", mesh, *SPINDLE])
    assert result.exit_code == Exit.MESH
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{mesh}: ") and "; " in lines[0]


def test_missing_mesh_file(tmp_path, small_program):
    src = tmp_path / "p.nc"
    src.write_bytes(small_program)
    result = invoke(["rewrite", src, "--mesh", tmp_path / "none.stl", *SPINDLE])
    assert result.exit_code == Exit.MESH
    assert result.stderr == f"{tmp_path / 'none.stl'}: no such file; check the mesh path\n"


@pytest.mark.parametrize("extra, fragment", [
    (["--vc", "70"], "give both --vc and --fz"),
    (["--fz", "0.1"], "give both --vc and --fz"),
    (["--min-rpm", "20000"], "--min-rpm is above --max-rpm"),
    (["--planner", "backward"], "--planner must be lookahead or forward"),
    (["--corner-radius", "9"], "--corner-radius"),
])
def test_contradictory_options(tmp_path, small_program, extra, fragment):
    src = tmp_path / "p.nc"
    src.write_bytes(small_program)
    out = tmp_path / "out.nc"
    result = invoke(["rewrite", src, *SPINDLE, *extra, "-o", out])
    assert result.exit_code == Exit.USAGE
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and fragment in lines[0]
    assert not out.exists()


def test_output_equal_to_input_is_refused(tmp_path, small_program, bowl_stl):
    src = tmp_path / "p.nc"
    src.write_bytes(small_program)
    before = sha(src)
    link = tmp_path / "link.nc"
    link.symlink_to(src)
    # the same file under another name: a "." segment, a symlink
    for target in (src, f"{tmp_path}/./p.nc", link):
        result = invoke(["rewrite", src, "--mesh", bowl_stl, *SPINDLE, "-o", target])
        assert result.exit_code == Exit.USAGE
        assert "overwrite the input" in result.stderr
        assert len(result.stderr.splitlines()) == 1
        assert sha(src) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.nc", "p.nc"]  # no temporary


def test_version():
    from ncopt import __version__
    result = invoke(["version"])
    assert result.exit_code == 0 and result.stdout.strip() == __version__


# --------------------------------------------------------- the summary's text ----
def test_summary_renders_without_colour(small_program, bowl_index):
    job = Job(cutter=Cutter(16.0, 2), machine=Machine(227.0, 15000.0),
              cutting=CuttingData(70.0, 0.1))
    result = rewrite_text(small_program.decode("latin-1"), job, "p.nc", bowl_index)
    buffer = io.StringIO()
    print_summary(result.summary, Console(file=buffer, width=100, color_system=None))
    text = buffer.getvalue()
    assert "\x1b[" not in text
    first = text.splitlines()[0]
    s = result.summary
    assert first == (f"ncopt: {s.blocks} blocks, {s.cutting_blocks} cutting blocks planned, "
                     f"{s.s_words} S and {s.f_words} F words written")
    # the counts agree with the text itself
    prog_in = parse_text(small_program.decode("latin-1"))
    assert s.blocks == prog_in.n_lines
    assert "vc 70.0 m/min, fz 0.1000 mm" in text


# ------------------------------------------------- Fanuc decimal-point convention ----
def _fanuc_dome(increments: bool) -> str:
    """A zig-zag finish over a dome, Fanuc style; axis values in IS-B increments
    (X25000 = 25 mm) or in mm with a decimal point."""
    def num(v_mm: float) -> str:
        micrometres = round(v_mm * 1000)
        return f"{micrometres}" if increments else f"{micrometres / 1000:.3f}"

    lines = ["%", "O1000", "G21 G90 G94 G17", "T1 M6", "S4000 M3",
             f"G0 X{num(-20)} Y{num(-20)} Z{num(20)}"]
    for i, y in enumerate(np.arange(-20.0, 20.01, 1.0)):
        xs = np.arange(-20.0, 20.01, 1.0)
        for j, x in enumerate(xs[::-1] if i % 2 else xs):
            z = 10.0 - (x * x + y * y) / 80.0
            lines.append(f"G1 X{num(x)} Y{num(y)} Z{num(z)}" + (" F800" if i == j == 0 else ""))
    lines += [f"G0 Z{num(30)}", "M5", "M30", "%"]
    return "\n".join(lines) + "\n"


def test_fanuc_values_without_a_decimal_point_need_the_convention(tmp_path):
    isb, mm = tmp_path / "isb.nc", tmp_path / "mm.nc"
    isb.write_text(_fanuc_dome(True))
    mm.write_text(_fanuc_dome(False))
    common = ["--diameter", "6", "--accel", "227", "--max-rpm", "15000", "--vc", "60",
              "--fz", "0.03"]
    refused = invoke(["rewrite", isb, *common, "-o", tmp_path / "out.nc"])
    assert refused.exit_code == Exit.PROGRAM
    assert f"{isb}:6:4: `X-20000` has no decimal point" in refused.stderr
    assert "--decimal-point calculator, is-b or is-c" in refused.stderr
    assert not (tmp_path / "out.nc").exists()
    # read in IS-B, the program is the same part as the one written in mm: same S and F
    a = invoke(["rewrite", isb, *common, "--decimal-point", "is-b", "-o", tmp_path / "a.nc"])
    b = invoke(["rewrite", mm, *common, "-o", tmp_path / "b.nc"])
    assert a.exit_code == b.exit_code == Exit.OK, a.stderr + b.stderr

    def sf(path):
        prog = parse_text(path.read_text())
        keep = np.isin(prog.word_letter, [ord("S"), ord("F")])
        return list(zip(prog.word_line[keep].tolist(), prog.word_letter[keep].tolist(),
                        prog.word_value[keep].tolist()))

    assert sf(tmp_path / "a.nc") == sf(tmp_path / "b.nc")
    assert len(sf(tmp_path / "a.nc")) > 100
    out = (tmp_path / "a.nc").read_text()
    base = masked(parse_text(isb.read_text()))
    assert without_one_comment_line(base, masked(parse_text(out))) == base  # X-20000 stays
    # the same program read as calculator input is 1000 times larger: its passes lie 1 m
    # apart, no finish ncopt recognises; planned all the same, other speeds
    c = invoke(["rewrite", isb, *common, "--decimal-point", "calculator", "-o", tmp_path / "c.nc"])
    assert c.exit_code == Exit.PLANNING
    assert "single 3D passes" in c.stderr
    c = invoke(["rewrite", isb, *common, "--decimal-point", "calculator", "--operations", "all",
                "-o", tmp_path / "c.nc"])
    assert c.exit_code == Exit.OK, c.stderr
    assert sf(tmp_path / "c.nc") != sf(tmp_path / "a.nc")


def test_a_named_dialect_refuses_another_dialects_construct(tmp_path):
    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90\nR1=5\nG1 X1. F100\n")
    result = invoke(["inspect", prog, "--dialect", "fanuc"])
    assert result.exit_code == Exit.PROGRAM
    assert f"{prog}:2:3: `R1=5` is a Sinumerik" in result.stderr
    assert "--dialect sinumerik" in result.stderr
    assert invoke(["inspect", prog]).exit_code == Exit.OK  # the generic grammar reads it
    bad = invoke(["inspect", prog, "--decimal-point", "is-x"])
    assert bad.exit_code == Exit.USAGE and "is-b" in bad.stderr


def test_a_machine_profile_sets_the_decimal_point(tmp_path):
    isb = tmp_path / "isb.nc"
    isb.write_text(_fanuc_dome(True))
    profiles = tmp_path / "p.toml"
    profiles.write_text('[machines.f]\naccel_rad_s2 = 227\nmax_rpm = 15000\n'
                        'control = "fanuc"\ndecimal_point = "is-b"\n')
    result = invoke(["rewrite", isb, "--diameter", "6", "--vc", "60", "--fz", "0.03",
                     "--machine", "f", "--tools", profiles, "-o", tmp_path / "o.nc"])
    assert result.exit_code == Exit.OK, result.stderr
