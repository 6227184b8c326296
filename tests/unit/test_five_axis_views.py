"""simulate, inspect and the plots with a tilted tool: the axis is read from the program
text (so a 3-axis rewrite of a 5-axis program is judged with its real R_eff), inspect
names the kinematics and the range of tilt, the plots show the tilt."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ncopt.model import Job
from ncopt.contacts.geometry import MeshIndex, mesh_from_triangles
from ncopt.planning.inspection import inspect_text, render_inspection
from ncopt.model import Cutter, CuttingData, Machine
from ncopt.simulate.replay import simulate_program

R = 5.0
JOB = Job(machine=Machine(227, 18000), cutter=Cutter(10, 2), cutting=CuttingData(150, 0.08))
LEAD, TILT = np.radians(15.0), np.radians(10.0)


def plane_mesh():
    V = np.array([[-40, -40, 0], [40, -40, 0], [40, 40, 0], [-40, 40, 0]], float)
    return MeshIndex(mesh_from_triangles(V[np.array([[0, 1, 2], [0, 2, 3]])]))


def program(style: str) -> str:
    """Passes along X on z = 0 at fixed lead and tilt, S3000 F1000."""
    out = ["G21 G90 G94", "S3000 M3", "G0 X0 Y0 Z20"] + (["G43.5 H1"] if style == "ijk" else ["M428"])
    for j in range(5):
        d = 1.0 if j % 2 == 0 else -1.0
        e = np.array([np.sin(LEAD) * d, np.cos(LEAD) * np.sin(TILT), np.cos(LEAD) * np.cos(TILT)])
        a, c = np.degrees(np.arccos(e[2])), np.degrees(np.arctan2(e[0], -e[1]))
        ori = f" I{e[0]:.9f} J{e[1]:.9f} K{e[2]:.9f}" if style == "ijk" else \
            f" A{a:.9f} C{c:.9f}"
        for k, x in enumerate(np.arange(0, 20.01, 1.0)[::int(d)]):
            tip = np.array([x, j * 0.8, R]) - R * e
            if k == 0:  # turn the tool above the pass, then go down
                out += [f"G0 X{tip[0]:.6f} Y{tip[1]:.6f} Z20{ori}", "G0 Z10"]
            out.append(f"G1 X{tip[0]:.6f} Y{tip[1]:.6f} Z{tip[2]:.6f}{ori}"
                       + (" F1000" if j == k == 0 else ""))
    return "\n".join(out + ["M30"]) + "\n"


def test_simulate_takes_the_tool_axis_from_the_text():
    r_eff = R * np.sqrt(1 - (np.cos(LEAD) * np.cos(TILT)) ** 2)
    vc = 2 * np.pi * r_eff * 3000 / 1000
    mesh = plane_mesh()
    report, series = simulate_program(program("ijk"), JOB, mesh)
    assert report.vc_mean_m_min == pytest.approx(vc, rel=1e-6)
    assert series.tool_axis is not None
    # rotary angles: judged with the kinematics, not at all without them
    job = replace(JOB, kinematics="xyzac-trt")
    report, _ = simulate_program(program("ac"), job, mesh)
    assert report.vc_mean_m_min == pytest.approx(vc, rel=1e-6)
    report, _ = simulate_program(program("ac"), JOB, mesh)
    assert report.cut_length_mm == 0.0
    assert any("with a tool axis ncopt cannot read are not timed" in w for w in report.warnings)


def test_inspect_names_the_kinematics_and_the_tilt():
    tilt = np.degrees(np.arccos(np.cos(LEAD) * np.cos(TILT)))
    info = inspect_text(program("ac"), "p.nc", kinematics="xyzac-trt")
    assert info.kinematics == "xyzac-trt"
    assert info.tilt_range_deg == pytest.approx((tilt, tilt), abs=1e-6)
    info = inspect_text(program("ijk"), "p.nc")
    assert info.kinematics == "vector" and info.to_dict()["tilt_range_deg"][1] > 17
    from io import StringIO

    from rich.console import Console
    out = StringIO()
    render_inspection(info, Console(file=out, width=100, color_system=None, soft_wrap=True))
    assert (f"  5-axis: tool axes from the program's tool vectors, tilted {tilt:.1f}..{tilt:.1f} "
            "deg from +Z on the moves ncopt can plan") in out.getvalue()


def test_plots_and_csv_show_the_tilt(tmp_path):
    matplotlib = pytest.importorskip("matplotlib")
    from ncopt.report.plots import plot_along_path, plot_toolpath

    matplotlib.rcParams["svg.fonttype"] = "none"  # text as text, to be read back
    report, series = simulate_program(program("ijk"), JOB, plane_mesh())
    plot_along_path([("p.nc", series, report)], tmp_path / "a.png")
    plot_toolpath(series, tmp_path / "p.svg")
    assert (tmp_path / "a.png").stat().st_size > 1000
    svg = (tmp_path / "p.svg").read_text()
    tilt = np.degrees(np.arccos(np.cos(LEAD) * np.cos(TILT)))
    assert f"tool axis tilted {tilt:.1f}..{tilt:.1f} deg from +Z" in svg
    series.write_csv(tmp_path / "s.csv")
    head, first = (tmp_path / "s.csv").read_text().splitlines()[:2]
    assert head.endswith(",cutting,tilt_deg")
