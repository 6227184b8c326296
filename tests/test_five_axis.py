"""5-axis ball-end finishing against closed forms: a plane cut at fixed lead and tilt
(R_eff exact), a tilt sweeping along a pass, the same part programmed in three styles
(Sinumerik TRAORI vectors, Fanuc G43.5 vectors, xyzac-trt angles) giving the same S and
F, and a 3+2 program (G68.2 + G53.1) equal to its untilted twin."""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.contacts.geometry import MeshIndex, mesh_from_triangles
from ncopt.motion.kinematics import KINEMATICS, euler_zxz
from ncopt.model import Cutter, CuttingData, Machine
from ncopt.contacts.pathnormals import CONFIDENT

R = 5.0
JOB = Job(machine=Machine(227, 18000), cutter=Cutter(10, 2), cutting=CuttingData(150, 0.08))


ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def gen():
    """bench/make_5axis.py, the case generator (registered: it holds dataclasses)."""
    spec = importlib.util.spec_from_file_location("make_5axis", ROOT / "bench" / "make_5axis.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["make_5axis"] = module
    spec.loader.exec_module(module)
    return module


def plane_index(half=40.0):
    V = np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]], float)
    return MeshIndex(mesh_from_triangles(V[np.array([[0, 1, 2], [0, 2, 3]])]))


def plane_program(lead_deg, tilt_deg, style="g43.5", passes=6, length=20.0):
    """Zig-zag passes along X on z = 0, the tool leaning lead_deg(x) toward the feed and
    tilt_deg sideways; returns the text and the exact R_eff per CL point."""
    lines = ["G21 G90 G94", "S3000 M3", "G0 X0 Y0 Z20"] + (["G43.5 H1"] if style == "g43.5"
                                                          else ["M428"])
    r_eff = []
    for j in range(passes):
        d = 1.0 if j % 2 == 0 else -1.0
        xs = np.arange(0.0, length + 1e-9, 0.5)[::int(d)]
        for k, x in enumerate(xs):
            lead, tilt = np.radians(lead_deg(x)), np.radians(tilt_deg)
            e = np.array([np.sin(lead) * d, np.cos(lead) * np.sin(tilt),
                          np.cos(lead) * np.cos(tilt)])
            tip = np.array([x, j * 0.8, R]) - R * e
            if style == "g43.5":
                ori = f" I{e[0]:.9f} J{e[1]:.9f} K{e[2]:.9f}"
            else:  # xyzac-trt: A = acos(ez), C = atan2(ex, -ey)
                ori = f" A{np.degrees(np.arccos(e[2])):.9f} " \
                      f"C{np.degrees(np.arctan2(e[0], -e[1])):.9f}"
            lines.append(f"G1 X{tip[0]:.9f} Y{tip[1]:.9f} Z{tip[2]:.9f}{ori}"
                         + (" F1000" if j == 0 and k == 0 else ""))
            r_eff.append(R * np.sqrt(1 - e[2] ** 2))
    return "\n".join(lines + ["M30"]) + "\n", np.array(r_eff)


def contacts(text: str, mesh, kinematics=None):
    """The toolpath of ``text`` and the contacts ncopt plans its feed moves with."""
    from ncopt.contacts.locate import contacts_for
    from ncopt.motion.interp import interpret
    from ncopt.reading.parse import parse_text
    from ncopt.planning.judging import plannable_points

    tp = interpret(parse_text(text, "p.nc"), kinematics=kinematics)
    return tp, contacts_for(tp, JOB.cutter, plannable_points(tp, True), mesh, 1.0, 0.05)


def test_a_plane_at_fixed_lead_and_tilt_r_eff_is_exact():
    text, exact = plane_program(lambda x: 15.0, 10.0)
    expected = exact[0]
    assert np.allclose(exact, expected)
    sampled = contacts(text, plane_index())[1]
    with_mesh = sampled.contacts
    # where the ball touches at the sample itself (the stepovers, which swing the axis
    # from one lead to the other, lift it off: their samples past the edge of the contact
    # stand for the stretch that still touches, at the R_eff there)
    touching = with_mesh.cutting & (sampled.gap_mm <= 0.05)
    assert touching.sum() > 200
    assert np.allclose(with_mesh.r_eff_mm[touching], expected, rtol=1e-9)
    free = contacts(text, None)[1]
    sure = free.contacts.cutting & (free.estimate.confidence == CONFIDENT)
    assert sure.sum() > 100
    assert np.allclose(free.contacts.r_eff_mm[sure], expected, rtol=1e-6)
    # the edge passes are planned steeper (a larger R_eff, a lower speed), never faster
    assert np.all(free.contacts.r_eff_mm[free.contacts.cutting] >= expected * (1 - 1e-6))
    # and the rewrite plans it: a 3D finish for ncopt although the tip stays at one Z
    assert rewrite_text(text, JOB, "p.nc", plane_index()).summary.cutting_blocks > 200


def test_a_tilt_sweeping_along_a_pass():
    """Lead 5 -> 25 deg along each pass in xyzac-trt angles: R_eff at every mesh sample is
    the closed form for the axis the control turns the tool through (the angles
    interpolated linearly between the block ends)."""
    from ncopt.motion.kinematics import KINEMATICS

    text, _ = plane_program(lambda x: 5.0 + x, 8.0, style="xyzac-trt", passes=3)
    tp, sampled = contacts(text, plane_index(), "xyzac-trt")
    c = sampled.contacts
    ok = c.cutting & tp.known[sampled.point]
    assert ok.sum() > 100
    # n = +Z: R_eff = R |e x n|, e the sample's axis
    assert np.allclose(c.r_eff_mm[ok], R * np.linalg.norm(sampled.axis[ok, :2], axis=1),
                       atol=1e-9)
    lead = np.degrees(np.arcsin(np.abs(sampled.axis[ok, 0])))
    assert lead.min() < 5.5 and lead.max() > 24.5
    # each sample's axis is that of the angles turned linearly from the block's start
    from ncopt.contacts.locate import AXIS_SAMPLE_MM, sample_fractions
    point, frac = sample_fractions(tp, AXIS_SAMPLE_MM)  # as contacts_for with a mesh
    a0, a1 = tp.tool_angles_deg[np.maximum(point - 1, 0)], tp.tool_angles_deg[point]
    both = ok & np.isfinite(a0).all(1) & np.isfinite(a1).all(1)
    turned = KINEMATICS["xyzac-trt"].tool_axis(a0[both] + (a1[both] - a0[both]) * frac[both, None])
    assert both.sum() > 100 and np.allclose(sampled.axis[both], turned, atol=1e-12)


def _s_and_f(result):
    t = result.targets
    moving = np.isfinite(t.f_value)
    return t.s_value[moving], t.f_value[moving]


@pytest.mark.parametrize("kind", ["dome", "bowl"])
def test_the_same_part_in_three_styles_gives_the_same_s_and_f(gen, kind):
    case = gen.make_case(kind, half_mm=6.0, step_mm=1.0, stepover_mm=1.5)
    V, F = gen.mesh(kind, half_mm=16.0, pitch_mm=1.0)
    index = MeshIndex(mesh_from_triangles(V[F]))
    for mesh in (index, None):
        got = {}
        for style, kin in (("traori", "vector"), ("g43.5", "vector"),
                           ("xyzac-trt", "xyzac-trt")):
            job = replace(JOB, kinematics=kin)
            got[style] = _s_and_f(rewrite_text(gen.program(case, style), job, "c.nc", mesh))
        s0, f0 = got["g43.5"]
        assert s0.size > 50
        for style in ("traori", "xyzac-trt"):
            s, f = got[style]
            assert s.shape == s0.shape
            # the vectors are printed to 1e-6, the angles to 1e-4 deg and blended through
            # their own interpolation: S within 0.2 %, F within 0.2 % and a quantum
            assert np.allclose(s, s0, rtol=2e-3, equal_nan=True), style
            assert np.allclose(f, f0, rtol=2e-3, atol=1.0, equal_nan=True), style
        if mesh is None:
            assert np.array_equal(got["traori"][0], s0)  # the same vectors: the same S


def test_a_3_plus_2_program_equals_its_untilted_twin(gen):
    """A 3-axis finish of the dome, and the same lines under G68.2 (tilted by 35 deg about a
    turned X) with G53.1: without a mesh the same S and F, word for word; with the mesh
    carried into the tilted frame, within 0.1 %."""
    kind = "dome"
    case = gen.make_case(kind, half_mm=6.0, step_mm=1.0, stepover_mm=1.5)
    z = np.array([0.0, 0.0, 1.0])
    tips = case.contact_mm + R * case.normal - R * z
    body = ["G0 X0 Y0 Z30"]
    for k, (x, y, zz) in enumerate(tips):
        first = k == 0 or case.pass_id[k] != case.pass_id[k - 1]
        if first and k:
            body += [f"G0 Z{tips[k - 1][2] + 5:.4f}", f"G0 X{x:.4f} Y{y:.4f}"]
        body.append(f"G1 X{x:.4f} Y{y:.4f} Z{zz:.4f}" + (" F1000" if k == 0 else ""))
    twin = "G21 G90 G94\nS3000 M3\n" + "\n".join(body) + "\nM30\n"
    origin, ijk = np.array([10.0, -5.0, 2.0]), (30.0, 35.0, -20.0)
    tilted = ("G21 G90 G94\nS3000 M3\n"
              f"G68.2 X{origin[0]} Y{origin[1]} Z{origin[2]} I{ijk[0]} J{ijk[1]} K{ijk[2]}\n"
              "G53.1\n" + "\n".join(body) + "\nG69\nM30\n")
    a, b = rewrite_text(twin, JOB, "t.nc"), rewrite_text(tilted, JOB, "t.nc")
    sa, fa = _s_and_f(a)
    sb, fb = _s_and_f(b)
    assert sa.size > 50
    assert np.array_equal(sa, sb) and np.array_equal(fa, fb)
    rot = euler_zxz(*ijk)
    assert np.allclose(b.toolpath.tool_axis[b.toolpath.known], rot[:, 2])
    V, F = gen.mesh(kind, half_mm=16.0, pitch_mm=1.0)
    flat = MeshIndex(mesh_from_triangles(V[F]))
    turned = MeshIndex(mesh_from_triangles((origin + V @ rot.T)[F]))
    a, b = rewrite_text(twin, JOB, "t.nc", flat), rewrite_text(tilted, JOB, "t.nc", turned)
    sa, fa = _s_and_f(a)
    sb, fb = _s_and_f(b)
    assert np.allclose(sa, sb, rtol=1e-3, equal_nan=True)
    # F alike where both cut (a move that only ends on the part, within the contact
    # tolerance, may touch in one mesh and not in the other turned one)
    both = _cutting(a) & _cutting(b)
    assert both.sum() > 50
    assert np.allclose(fa[both], fb[both], rtol=1e-3, atol=1.0)


def _cutting(result) -> np.ndarray:
    """Per block of _s_and_f: planned as a cut at the cutting feed."""
    out = np.zeros(result.targets.line.shape, dtype=bool)
    for p in result.plans:
        lo, hi = p.window
        out[lo:hi] = p.blocks.cutting & p.blocks.planned & ~p.reduced
    return out[np.isfinite(result.targets.f_value)]
