"""5-axis rewrites against an optimum computed without ncopt (bench/optimum_5axis.py), on
the flowline case of bench/make_5axis.py: lead and tilt sweeping 5-25 deg within every
pass, the tool axis turning up to 5.5 deg a block (and 11 deg on 2 mm blocks).  The time
stays within a few per cent of the optimum and vc, judged by simulate with the exact
mesh, never above its target, with the mesh and without; and the pieces that got there:
the one-sided second-order tangent, the balanced and curved cross fit, the lead-in and
lead-out of a run of cuts, and the contact's edge between two mesh samples."""

from __future__ import annotations

import dataclasses
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from ncopt.api import rewrite_text
from ncopt.contacts.geometry import MeshIndex, mesh_from_triangles
from ncopt.contacts.pathnormals import CONFIDENT, path_normals, second_order_ends
from ncopt.contacts.touchedges import with_touch_edges
from ncopt.model import Contacts, Cutter, CuttingData, Job, Machine
from ncopt.simulate.replay import simulate_program

ROOT = Path(__file__).resolve().parents[1]
JOB = Job(machine=Machine(227, 18000), cutter=Cutter(10, 2), cutting=CuttingData(150, 0.08))
HALF_MM = 12.0  # 17 passes of 1.5 mm: the edge passes, planned steeper without a mesh,
# are an eighth of the cut (a fortieth in the bench's 76)


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "bench" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def gen():
    """bench/make_5axis.py, the case generator (registered: it holds dataclasses)."""
    return _load("make_5axis")


@pytest.fixture(scope="module")
def ref():
    """bench/optimum_5axis.py, the optimum computed without ncopt."""
    return _load("optimum_5axis")


@pytest.fixture(scope="module", params=["dome", "bowl"])
def part(request, gen):
    V, F = gen.mesh(request.param, half_mm=HALF_MM + 8.0, pitch_mm=0.5)
    return request.param, MeshIndex(mesh_from_triangles(V[F]))


def _judged(text: str, job: Job, index, mesh):
    """The rewrite of ``text`` (with ``mesh`` or none) simulated against the exact mesh."""
    out = rewrite_text(text, job, "c.nc", mesh).text
    return simulate_program(out, job, index, path="c_out.nc")[0]


def test_the_reference_takes_the_closed_form_r_eff(gen, ref):
    """At every CL point of a pass the optimum's requirement is the generator's closed form
    R sqrt(1 - cos^2 lead cos^2 tilt), through its own slerp and its own xyzac-trt map."""
    case = gen.make_case("bowl", half_mm=6.0, stepover_mm=1.5, **gen.FLOWLINE)
    mv = gen.moves(case)
    exact = np.minimum(18000.0, 150000.0 / (2 * np.pi * case.r_eff_mm))
    tips = {tuple(np.round(t, 9)): k for k, t in enumerate(case.tip_mm)}
    checked = 0
    for angles in (False, True):
        got = ref._samples(gen, case, mv, angles, 0.1)
        for i in range(1, mv.tip_mm.shape[0]):
            k = tips.get(tuple(np.round(mv.tip_mm[i], 9)))
            if mv.rapid[i] or k is None:  # a rapid, or a move that ends off the pass
                continue
            _, f, req, touch = got[i - 1]
            assert touch[-1] and abs(req[-1] / exact[k] - 1.0) < 1e-9
            checked += 1
    assert checked > 2 * 100


@pytest.mark.parametrize("style,kinematics", [("g43.5", "vector"), ("xyzac-trt", "xyzac-trt")])
def test_the_flowline_case_within_a_few_per_cent_of_the_optimum(gen, ref, part, style,
                                                                  kinematics):
    """With the mesh within 2 % of the optimum (1.0-1.1 % here), without it within 3 %
    (2.0-2.5 %: the edge passes), and vc never above its target (at most +0.5 %, S words
    being integers and the mesh faceted)."""
    kind, index = part
    case = gen.make_case(kind, half_mm=HALF_MM, stepover_mm=1.5, **gen.FLOWLINE)
    best = ref.optimum(gen, case, kinematics != "vector").cutting_min
    job = dataclasses.replace(JOB, kinematics=kinematics)
    for mesh, bound in ((index, 1.02), (None, 1.03)):
        rep = _judged(gen.program(case, style), job, index, mesh)
        ratio = rep.cutting_time_min / best
        assert 0.999 < ratio < bound, (mesh is None, ratio)
        assert rep.vc_max_over_pct < 0.5, (mesh is None, rep.vc_max_over_pct)
        assert rep.fz_in_band_pct > 99.9


@pytest.mark.parametrize("style,kinematics", [("g43.5", "vector"), ("xyzac-trt", "xyzac-trt")])
def test_without_a_mesh_vc_holds_on_long_blocks_where_the_axis_turns_fast(gen, part, style,
                                                                         kinematics):
    """2 mm blocks turning the axis up to 11 deg: the normals from the path alone keep vc
    under its target (it was +0.9 % on the dome, +1.3 % on the bowl: the cross fit leaned
    by up to 0.9 deg beside the edge passes and at the passes' ends); in rotary angles too,
    where near A = 0 a block swings C by up to 160 deg and R_eff peaks inside it."""
    kind, index = part
    case = gen.make_case(kind, half_mm=HALF_MM, stepover_mm=1.5, variation="flowline",
                         step_mm=2.0)
    rep = _judged(gen.program(case, style), dataclasses.replace(JOB, kinematics=kinematics),
                  index, None)
    assert rep.vc_max_over_pct < 0.5


def test_a_lead_out_that_leaves_steeply_is_planned_as_a_cut(gen, part):
    """Ramps along the tips' last chord, which the turning axis tilts up to 19 deg off the
    surface: a lead-out touches over its first tenths of a mm only, between the start and
    the first mesh sample.  It was planned as air, at the program's F (fz -45 %)."""
    kind, index = part
    case = gen.make_case(kind, half_mm=HALF_MM, stepover_mm=1.5, variation="flowline",
                         step_mm=2.0)
    case = dataclasses.replace(case, variation="sweep")  # the ramps along the tips' chords
    job = dataclasses.replace(JOB, kinematics="vector")
    for mesh in (index, None):
        rep = _judged(gen.program(case, "g43.5"), job, index, mesh)
        assert rep.fz_min_under_pct < 2.0 and rep.fz_in_band_pct > 99.99, mesh is None
        assert rep.vc_max_over_pct < 0.5, mesh is None


def test_the_one_sided_second_order_tangent_on_a_circle():
    """At the ends of an arc of points (R 60, 2 mm apart, uneven) the tangent is the
    circle's to 1e-4 rad; the chord, the first-order one, leans by half a step's turn."""
    rng = np.random.default_rng(5)
    phi = np.cumsum(np.r_[0.0, rng.uniform(1.5, 2.5, 20)]) / 60.0
    pts = np.column_stack((60 * np.sin(phi), np.zeros_like(phi), 60 * np.cos(phi)))
    s = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))))
    chord = np.tile([1.0, 0.0, 0.0], (phi.size, 1))
    chord[0] = (pts[1] - pts[0]) / np.linalg.norm(pts[1] - pts[0])
    chord[-1] = (pts[-1] - pts[-2]) / np.linalg.norm(pts[-1] - pts[-2])
    t = second_order_ends(pts, s, chord)
    exact = np.column_stack((np.cos(phi), np.zeros_like(phi), -np.sin(phi)))
    for k in (0, -1):
        assert np.arccos(min(1.0, t[k] @ exact[k])) < 1e-4
        assert np.arccos(min(1.0, chord[k] @ exact[k])) > 0.01
    assert np.array_equal(t[1:-1], chord[1:-1])  # points inside keep their tangent


def test_the_balanced_curved_fit_on_a_sphere():
    """Ball centres on an R55 sphere, passes 0.8 mm apart, points 2 mm apart along them:
    the straight fit to the twelve nearest, with chords for tangents at the passes' ends,
    leans up to 0.6 deg inside the passes (the twelfth neighbour one of four at the same
    distance) and 1 deg at their ends (half a step's turn); the balanced, curved fit with
    second-order tangents at the ends is within 0.02 deg but at the corners beside the
    edge passes, where every neighbour lies behind and one side has a single pass."""
    xs, ys = np.arange(-20.0, 20.01, 2.0), np.arange(-20.0, 20.01, 0.8)
    rows = [np.column_stack((xs if j % 2 == 0 else xs[::-1], np.full(xs.size, y)))
            for j, y in enumerate(ys)]
    xy = np.vstack(rows)
    z = -np.sqrt(55.0 ** 2 - (xy ** 2).sum(axis=1))  # the lower half: normals toward +z
    pts = np.column_stack((xy, z))
    exact = -pts / 55.0
    axis = exact.copy()
    path = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))))
    cutting = np.ones(len(pts), bool)
    cutting[::xs.size] = False  # each pass entered from a link that does not cut
    inside = np.abs(xy[:, 0]) < 19.0
    corner = ~inside & (np.abs(np.abs(xy[:, 1]) - 19.2) < 0.01)
    errors = {}
    for name, kw in (("straight", {}),
                     ("balanced", dict(balanced=True, curved=True, end_order=2))):
        est = path_normals(pts, path, cutting, axis=axis, **kw)
        sure = (est.confidence == CONFIDENT) & cutting
        dots = np.clip(np.einsum("ij,ij->i", est.normal, exact), -1.0, 1.0)
        err = np.degrees(np.arccos(dots))
        errors[name] = (err[sure & inside].max(), err[sure & ~inside & ~corner].max())
    assert errors["straight"][0] > 0.2 and errors["straight"][1] > 0.8
    assert errors["balanced"][0] < 0.02 and errors["balanced"][1] < 0.02


def test_the_contact_edge_between_two_samples():
    """Samples of a lead-out: touching, then clear of the part.  The first clear one stands
    for the stretch that still touches: cutting, at the R_eff where the clearance crosses
    the tolerance (interpolated); entering, the larger of that and its own."""
    r = np.array([2.0, 2.1, 2.2, 2.3, 2.4, 2.5])
    gap = np.array([0.0, 0.02, 0.04, 0.06, 0.08, 0.0])
    cut = gap <= 0.05
    c = Contacts(cc_mm=np.zeros((6, 3)), normal=np.tile([0.0, 0.0, 1.0], (6, 1)), r_eff_mm=r,
                 cutting=cut)
    got = with_touch_edges(c, gap, 0.05)
    assert got.cutting.tolist() == [True, True, True, True, False, True]
    assert got.r_eff_mm[3] == pytest.approx(2.25)  # leaving, halfway from 0.04 to 0.06
    assert got.r_eff_mm[5] == pytest.approx(2.5)  # entering: its own, the larger
    assert np.array_equal(got.r_eff_mm[[0, 1, 2, 4]], r[[0, 1, 2, 4]])
