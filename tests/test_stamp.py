"""The stamp a rewrite leaves: short lines in the program's comment syntax that say which
ncopt, when, from which file, for which machine, the new cutting time, and the data a
re-run plans from; a re-run that plans the same keeps it, old stamps are still read."""

from __future__ import annotations

import re
from dataclasses import replace

import pytest

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.model import Machine
from ncopt.reading.stamp import STAMP_LINE, read_stamps
from ncopt.reading.parse import parse_text

JOB = Job(machine=Machine(accel_rad_s2=227.0, max_rpm=15000.0))


def raster(header: str = "(T1 D=6. CR=3. - ball end mill)\nG21 G90 G94\nT1 M6\nS4000 M3\n"
           ) -> str:
    """Parallel passes over z = -0.005 x^2 - 0.02 y^2 at F800 (no plunge into the part)."""
    lines = [header.rstrip("\n"), "G0 X0. Y0. Z5."]
    for k in range(8):
        xs = [0.5 * i for i in range(31)]
        xs = xs if k % 2 == 0 else xs[::-1]
        y = 0.5 * k
        lines.append(f"G0 X{xs[0]:.3f} Y{y:.3f} Z{-0.005 * xs[0] ** 2 - 0.02 * y * y:.3f}")
        lines.append(f"G1 X{xs[1]:.3f} Z{-0.005 * xs[1] ** 2 - 0.02 * y * y:.3f} F800.")
        lines += [f"X{x:.3f} Z{-0.005 * x * x - 0.02 * y * y:.3f}" for x in xs[2:]]
        lines.append("G0 Z5.")
    return "\n".join(lines + ["M30", ""])


def stamp_of(text: str) -> list[str]:
    return [line for line in text.splitlines() if STAMP_LINE.match(line)]


def test_the_stamp_says_version_date_source_machine_and_time(monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")  # 2026-01-01
    result = rewrite_text(raster(), replace(JOB, machine_name="shop-dmu"), "parts/a.nc")
    stamp = stamp_of(result.text)
    assert stamp[0].startswith("(ncopt ") and stamp[0].endswith(
        " 2026-01-01: S and F for constant vc and fz)")
    assert stamp[1] == "(ncopt from a.nc)"
    assert stamp[2] == "(ncopt machine shop-dmu: 227 rad/s2, 15000 RPM)"
    s = result.summary
    assert stamp[3] == (f"(ncopt cutting time {s.cut_time_before_min:.1f} -> "
                        f"{s.cut_time_after_min:.1f} min, estimated)")
    assert stamp[4].startswith("(ncopt T1 lines=1-") and " vc=75.39822369 fz=0.100000" in stamp[4]
    assert stamp[5] == "(ncopt T1 D=6mm r=3mm z=2 S0=4000 F0=800mm/min)"
    assert all(len(line) <= 72 for line in stamp)
    # the CAM's comments in the corpus are at most 67 characters; a stamp line never runs on
    assert len(stamp) == 6


def test_a_long_file_name_is_cut_and_brackets_never_end_the_comment():
    name = "/shop/programs/" + "very-long-file-name-" * 4 + "mould (rev B) final;2.nc"
    stamp = stamp_of(rewrite_text(raster(), JOB, name).text)
    assert all(len(line) <= 72 for line in stamp)
    assert stamp[1].startswith("(ncopt from ...") and stamp[1].endswith("final_2.nc)")
    assert stamp[1].count("(") == 1 and stamp[1].count(")") == 1
    assert set(parse_text("\n".join(stamp)).line_kind.tolist()) == {0}  # comments only


def test_a_program_without_t_words_is_stamped_t_question_mark():
    """``T-1`` read like a tool number; a program that names no tool says so."""
    text = raster("(6mm ball end mill)\nG21 G90 G94\nS4000 M3\n")
    out = rewrite_text(text, replace(JOB, machine=Machine(227.0, 15000.0)), "a.nc").text
    stamp = stamp_of(out)
    assert stamp[4].startswith("(ncopt T? lines=") and stamp[5].startswith("(ncopt T? D=6mm")
    assert "T-1" not in out
    [(tool, _)] = read_stamps(parse_text(out)).keys()
    assert tool == -1
    assert rewrite_text(out, JOB, "a.nc").text == out


def test_a_rerun_that_plans_the_same_keeps_the_stamp_its_date_and_source(monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")
    once = rewrite_text(raster(), JOB, "a.nc").text
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1798761600")  # a year later, another name
    assert rewrite_text(once, JOB, "a_opt.nc").text == once


def test_a_rerun_for_another_machine_says_so_and_keeps_the_source(monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")
    once = rewrite_text(raster(), JOB, "a.nc").text
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1798761600")  # 2027-01-01
    slow = replace(JOB, machine=Machine(accel_rad_s2=131.0, max_rpm=8000.0))
    again = stamp_of(rewrite_text(once, slow, "a_opt.nc").text)
    assert again[0].endswith(" 2027-01-01: S and F for constant vc and fz)")
    assert again[1] == "(ncopt from a.nc)"  # the program it was first planned from
    assert again[2] == "(ncopt machine 131 rad/s2, 8000 RPM)"


@pytest.mark.parametrize("semicolon", [False, True])
def test_an_old_one_line_stamp_is_still_read(semicolon):
    """A program stamped by an earlier ncopt (one line per operation) is planned from that
    stamp, as from a new one: the same S and F words, the stamp in the new form."""
    text = raster()
    if semicolon:
        text = text.replace("(T1 D=6. CR=3. - ball end mill)", "; T1 D=6. CR=3. - ball end mill")
    new = rewrite_text(text, JOB, "a.nc").text
    data = stamp_of(new)[4:6]
    body = lambda line: line.strip()[1:-1] if line.startswith("(") else line[2:]  # noqa: E731
    a, b = body(data[0]), body(data[1])
    lines = re.search(r"lines=\S+", a)[0]
    vc_fz = re.search(r"vc=\S+ fz=\S+", a)[0]
    band = re.search(r"band=\S+", a)[0]
    d_r_z = re.search(r"D=\S+ r=\S+ z=\d+", b)[0]
    s0_f0 = re.search(r"S0=\S+ F0=\S+", b)[0]
    old = (f"ncopt 0.1.0 T1 {lines} {vc_fz} {d_r_z} {band} {s0_f0} "
           "- S and F for constant vc and fz")
    old = f"; {old}" if semicolon else f"({old})"
    stamped_old = "\n".join([old] + [ln for ln in new.splitlines() if not STAMP_LINE.match(ln)])
    stamped_old += "\n"
    again = rewrite_text(stamped_old, JOB, "a.nc").text
    strip = lambda t: [ln for ln in t.splitlines() if not STAMP_LINE.match(ln)]  # noqa: E731
    assert strip(again) == strip(new)
    assert stamp_of(again)[4:] == stamp_of(new)[4:]


def test_a_program_without_s_words_rewrites_the_same_twice():
    """The issue's case: the stamp read S0=0/F0=0 on a program that had no S word and a
    second rewrite changed it (to the S ncopt had written).  Planned from the options' vc and
    fz, the stamp says S0=0 and the program's own cutting feed, and the second rewrite is
    byte-identical."""
    from ncopt.model import Cutter, CuttingData

    text = raster("(T1 D=6. CR=3. - ball end mill)\nG21 G90 G94\nT1 M6\nM3\n")
    job = replace(JOB, cutter=Cutter(6.0, 2), cutting=CuttingData(80.0, 0.05))
    once = rewrite_text(text, job, "a.nc").text
    assert once != text and "(ncopt T1 D=6mm r=3mm z=2 S0=0 F0=800mm/min)" in once
    assert rewrite_text(once, job, "a.nc").text == once


def test_an_old_stamp_names_no_spindle_and_the_rewrite_says_so():
    text = raster()
    new = rewrite_text(text, JOB, "a.nc").text
    a, b = stamp_of(new)[4:6]
    old = "(ncopt 0.1.0 " + a[len("(ncopt "):-1] + " " + b[len("(ncopt T1 "):-1] + ")"
    old = re.sub(r" band=2 (D=\S+ r=\S+ z=\d+)", r" \1 band=2", old)
    body = [ln for ln in new.splitlines() if not STAMP_LINE.match(ln)]
    result = rewrite_text("\n".join([old] + body) + "\n", JOB, "a.nc")
    assert read_stamps(parse_text(result.text)).spindle == (227.0, 15000.0)
    assert any(w.startswith("a.nc:1: the stamp of an earlier ncopt does not say which spindle")
               for w in result.summary.warnings)


@pytest.mark.corpus
def test_a_roughing_operation_included_is_planned_on_the_same_material_again(corpus_dir,
                                                                            tmp_path):
    """A roughing operation a user includes is planned where the edge meets the remaining
    material of its step-down; its S and F words in the output no longer show it roughing,
    so the stamp says so (``roughing ap=``) and a second rewrite plans the same (it
    planned it at the contact before: S up to 15000 where 10868 was planned, 470 lines)."""
    from typer.testing import CliRunner

    from ncopt.cli.app import app

    program = corpus_dir / "more" / "freecad_Starlink_suport.nc"
    args = ["--diameter", "3", "--shape", "ball", "--operations", "Surface", "--accel",
            "227", "--max-rpm", "15000", "-q"]
    runner = CliRunner()
    first, second = tmp_path / "o1.nc", tmp_path / "o2.nc"
    assert runner.invoke(app, ["rewrite", str(program), *args, "-o", str(first)]).exit_code == 0
    text = first.read_text(encoding="latin-1")
    rough = [line for line in stamp_of(text) if " roughing ap=" in line]
    assert len(rough) == 1 and re.fullmatch(r"\(ncopt T\? roughing ap=[\d.]+mm\)", rough[0])
    assert max(len(line) for line in stamp_of(text)) <= 72
    stamps = read_stamps(parse_text(text))
    assert [st.ap_mm for st in stamps.values()] == [float(rough[0].split("=")[1][:-3])]
    assert runner.invoke(app, ["rewrite", str(first), *args, "-o", str(second)]).exit_code == 0
    assert second.read_bytes() == first.read_bytes()


def test_the_stamp_is_no_operation_of_its_own_in_inspect(tmp_path):
    """A stamp at the top of a program with no header before it belongs to the operation
    after it: inspect lists the same operations for a program and its rewrite."""
    from typer.testing import CliRunner

    from ncopt.cli.app import app

    program = tmp_path / "raster.nc"
    program.write_text(raster())
    out = tmp_path / "out.nc"
    runner = CliRunner()
    assert runner.invoke(app, ["rewrite", str(program), "--accel", "227", "--max-rpm", "15000",
                               "-q", "-o", str(out)]).exit_code == 0
    assert stamp_of(out.read_text())[0] == out.read_text().splitlines()[0]  # at the top
    names = []
    for path in (program, out):
        shown = runner.invoke(app, ["inspect", str(path), "--json"])
        assert shown.exit_code == 0, shown.output
        import json

        names.append([op["name"] for op in json.loads(shown.stdout)["operations"]])
    assert names[0] == names[1] and len(names[0]) == 1


@pytest.mark.parametrize("s_plunge, f_plunge, options", [
    (3000, 1000, {"cutting": "vc"}), (4000, 600, {"options": "forward"})])
def test_a_second_run_keeps_plunges_the_program_gives_their_own_faster_s(
        s_plunge, f_plunge, options):
    """Passes of the sample bowl plunging at their own S3000 F1000 (S4000 F600) while the
    cut runs S1393 F279: a second run read a plunge's feed per revolution at the stamped S0
    (1393, not the S3000 the output no longer holds) and moved S and F on 7-126 lines by up
    to 5.4 %.  The stamp says the S varied (``S0~1393``): the second run reads such plunges
    at the speed replayed, and is the first byte for byte."""
    import importlib.util
    from pathlib import Path

    import numpy as np

    from ncopt.contacts.geometry import MeshIndex, load_stl
    from ncopt.model import Cutter, CuttingData, PlanOptions
    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("make_bowl_plunges", root / "samples/make_bowl.py")
    bowl = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bowl)
    xs = np.arange(-90.0, 90.0 + 1e-9, 3.0)
    lines = ["(bowl strip with plunges)", "G21 G90 G94 G17", "T4 M6", "S1393 M3"]
    for i, y in enumerate((44.0, 52.0, 60.0)):
        row = xs if i % 2 == 0 else xs[::-1]
        z = bowl.drop_ball_tip_z_mm(row, np.full(row.shape, y), 8.0)
        lines += [f"G0 X{row[0]:.3f} Y{y:.3f} Z{z[0] + 5:.3f}", f"S{s_plunge}",
                  f"G1 Z{z[0]:.3f} F{f_plunge}", "S1393", f"G1 X{row[1]:.3f} Z{z[1]:.3f} F279"]
        lines += [f"G1 X{x:.3f} Z{h:.3f}" for x, h in zip(row[2:], z[2:])]
        lines.append(f"G0 Z{z[-1] + 5:.3f}")
    text = "\n".join(lines + ["M5", "M30"]) + "\n"
    extra = ({"cutting": CuttingData(150, 0.08)} if options.get("cutting") else
             {"options": PlanOptions(planner="forward")})
    job = Job(machine=Machine(227, 15000), cutter=Cutter(16, 2), shape_named=True,
              operations=("all",), **extra)
    mesh = MeshIndex(load_stl(root / "samples/bowl.stl"))
    first = rewrite_text(text, job, "p.nc", mesh).text
    assert first != text
    assert "(ncopt T4 D=16mm r=8mm z=2 S0~1393 F0=279mm/min)" in first  # S varied: S0~
    assert rewrite_text(first, job, "p.nc", mesh).text == first
