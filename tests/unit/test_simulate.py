"""The machine simulation (ncopt.simulate.replay): closed forms, lag detection, the bowl end to end.

Closed-form cases run on small planes written as STL files: a D16 ball whose tip
follows the plane at the right height touches it all along (gap 0), with
``R_eff = 8 sin(theta)`` on a plane tilted by ``theta``.  Spindle accelerations
are chosen so that ``a`` is a round number of RPM/s.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from stl import mesh as stl_mesh

from ncopt.api import rewrite_file, rewrite_text
from ncopt.model import Job
from ncopt.contacts.locate import mesh_contacts_at_samples
from ncopt.runtime.errors import UsageError
from ncopt.contacts.geometry import MeshIndex, load_stl
from ncopt.motion.interp import interpret
from ncopt.model import Cutter, CuttingData, Machine, PlanOptions
from ncopt.reading.parse import parse_text
from ncopt.simulate import spindle
from ncopt.simulate.replay import simulate_file, simulate_program
from ncopt.simulate.spindle import _run_start_speeds

ROOT = Path(__file__).resolve().parents[2]
BALL16 = Cutter(16, 2)
R = 8.0
A_RPM_S = 1000.0
ALPHA = A_RPM_S * 2 * math.pi / 60  # rad/s^2 giving a = 1000 RPM/s
MACHINE = Machine(accel_rad_s2=ALPHA, max_rpm=20000, rapid_mm_min=600)
JOB = Job(cutter=BALL16, machine=MACHINE, cutting=CuttingData(vc_m_min=70.0, fz_mm=0.1))


def write_plane_stl(path: Path, theta_deg: float) -> Path:
    """The plane z = x tan(theta) over x, y in [-40, 40] x [-20, 20], 1 mm grid."""
    xs, ys = np.linspace(-40, 40, 81), np.linspace(-20, 20, 41)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    P = np.stack([X, Y, X * math.tan(math.radians(theta_deg))], axis=-1)
    a, b, c, d = P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]
    tri = np.concatenate([np.stack([a, b, c], -2).reshape(-1, 3, 3),
                          np.stack([a, c, d], -2).reshape(-1, 3, 3)])
    m = stl_mesh.Mesh(np.zeros(tri.shape[0], dtype=stl_mesh.Mesh.dtype))
    m.vectors[:] = tri
    m.save(str(path))
    return path


@pytest.fixture(scope="module")
def flat(tmp_path_factory) -> MeshIndex:
    return MeshIndex(load_stl(write_plane_stl(tmp_path_factory.mktemp("flat") / "p.stl", 0.0)))


@pytest.fixture(scope="module")
def tilted45(tmp_path_factory) -> MeshIndex:
    return MeshIndex(load_stl(write_plane_stl(tmp_path_factory.mktemp("t45") / "p.stl", 45.0)))


def program(*lines: str) -> str:
    return "\n".join(("G21 G90 G17",) + lines + ("M30",)) + "\n"


def line_of(text: str, needle: str) -> int:
    """1-based line holding ``needle``."""
    return next(i for i, s in enumerate(text.splitlines(), 1) if needle in s)


def block(series, text: str, needle: str):
    """Mask of the series rows of the block holding ``needle``."""
    return series.line == line_of(text, needle)


# ---------------------------------------------------------------- closed forms


def test_constant_speed_block(flat):
    text = program("S2000 M3", "G0 X-15 Y0 Z5", "G0 Z0", "G1 X15 F400", "G0 Z5", "M5")
    job = Job(cutter=BALL16, machine=MACHINE)  # targets from the program itself
    rep, ser = simulate_program(text, job, flat)
    cut = block(ser, text, "G1 X15")
    assert ser.time_s[cut][-1] - ser.time_s[cut][0] == pytest.approx(60 * 30 / 400, rel=1e-12)
    assert rep.cutting_time_min == pytest.approx(30 / 400, rel=1e-12)
    assert rep.rapid_time_min == pytest.approx(10 / 600, rel=1e-12)  # first rapid: unknown start
    assert rep.total_time_min == pytest.approx(30 / 400 + 10 / 600, rel=1e-12)
    assert rep.cut_length_mm == pytest.approx(30.0)
    assert np.all(ser.cutting == cut) and np.all(ser.s_rpm == 2000.0)
    assert np.all(ser.fz_mm[cut] == 400 / (2 * 2000))
    assert np.diff(ser.dist_mm[cut]).max() <= 0.1 + 1e-12
    assert rep.fz_target_mm == 0.1 and rep.vc_target_m_min == pytest.approx(math.pi * 16 * 2)
    assert rep.fz_in_band_pct == 100.0 and rep.fz_max_over_pct == pytest.approx(0, abs=1e-12)
    assert rep.s_words == 1 and rep.max_rpm == 2000.0 and not rep.spindle_lag_breaks_fz
    assert np.all(ser.d_eff_mm[cut] < 1e-6)  # the tip cuts a flat plane
    assert np.all(np.isnan(ser.fz_mm[ser.line == line_of(text, "G0 Z0")]))


def test_ramp_over_two_blocks(flat):
    # 0.5 s at 1000; S5000 at t=0.5 s ramps 2 s in block A (to 3000), 2 s + 1 s hold in B
    text = program("S1000 M3", "G0 X-30 Y0 Z0", "G1 X-25 F600", "S5000 G1 X-5", "G1 X25")
    rep, ser = simulate_program(text, JOB, flat)
    expected = np.minimum(1000 + A_RPM_S * np.maximum(ser.time_s - 0.5, 0), 5000)
    np.testing.assert_allclose(ser.s_rpm, expected, rtol=1e-12)
    np.testing.assert_allclose(ser.time_s, (ser.xyz_mm[:, 0] + 30) / 10, rtol=1e-12)
    a, b = block(ser, text, "S5000"), block(ser, text, "X25")
    assert ser.s_rpm[a][0] == 1000 and ser.s_rpm[a][-1] == pytest.approx(3000, rel=1e-12)
    assert ser.s_rpm[b][0] == pytest.approx(3000, rel=1e-12) and ser.s_rpm[b][-1] == 5000
    at_speed = ser.xyz_mm[b, 0][np.argmax(ser.s_rpm[b] == 5000)]
    assert at_speed == pytest.approx(15.0, abs=0.15)  # t = 4.5 s at 10 mm/s from X-30
    assert rep.cutting_time_min == pytest.approx(5.5 / 60, rel=1e-12)
    np.testing.assert_allclose(ser.fz_mm[ser.cutting], 600 / (2 * ser.s_rpm[ser.cutting]))


def test_deceleration(flat):
    text = program("S5000 M3", "G0 X-30 Y0 Z0", "G1 X-25 F600", "S1000 G1 X-5", "G1 X25")
    rep, ser = simulate_program(text, JOB, flat)
    expected = np.maximum(5000 - A_RPM_S * np.maximum(ser.time_s - 0.5, 0), 1000)
    np.testing.assert_allclose(ser.s_rpm, expected, rtol=1e-12)
    assert rep.max_rpm == 5000 and rep.max_rpm_line == line_of(text, "G0 X-30")
    assert ser.s_rpm[block(ser, text, "S1000")][-1] == pytest.approx(3000, rel=1e-12)


def test_spindle_ramps_during_rapids(flat):
    # pass 1 (1.5 s), then S5000 on 20 mm of rapids at 600 mm/min (2 s): 2000 -> 4000
    text = program("S2000 M3", "G0 X-30 Y0 Z0", "G1 X0 F1200", "S5000 G0 Z5", "G0 Y10",
                   "G0 Z0", "G1 X-30")
    rep, ser = simulate_program(text, JOB, flat)
    second = block(ser, text, "G1 X-30")
    assert ser.time_s[second][0] == pytest.approx(3.5, rel=1e-12)
    assert ser.s_rpm[second][0] == pytest.approx(4000, rel=1e-12)
    assert ser.s_rpm[second][-1] == 5000
    reach = ser.xyz_mm[second, 0][np.argmax(ser.s_rpm[second] == 5000)]
    assert reach == pytest.approx(-20.0, abs=0.15)  # 1 s at 20 mm/s
    assert rep.rapid_time_min == pytest.approx(2.0 / 60, rel=1e-12)
    assert rep.cutting_time_min == pytest.approx(3.0 / 60, rel=1e-12)
    rapid = ~ser.cutting & (ser.time_s > 1.5) & (ser.time_s < 3.5)
    assert np.all(ser.f_mm_min[rapid] == 600)


def test_s_jump_faster_than_the_spindle_is_flagged(flat):
    # hand-made: S and F jump 5x together; the spindle needs 1.85 s (31 mm) to follow
    machine = Machine(accel_rad_s2=227, max_rpm=15000)
    job = Job(cutter=BALL16, machine=machine, cutting=CuttingData(vc_m_min=50.0, fz_mm=0.1))
    text = program("S1000 M3", "G0 X-30 Y0 Z0", "G1 X-20 F200", "S5000 G1 X30 F1000")
    rep, ser = simulate_program(text, job, flat)
    jump = line_of(text, "S5000")
    assert rep.spindle_lag_breaks_fz and len(rep.lag) == 1
    lag = rep.lag[0]
    assert lag.first_line == lag.last_line == jump
    assert lag.worst_fz_pct == pytest.approx(400.0) and lag.s_real_rpm == 1000.0
    assert lag.s_cmd_rpm == 5000.0
    assert rep.fz_max_over_pct == pytest.approx(400.0) and rep.fz_max_over_line == jump
    # fz is back in its band once S >= 1000 / (2 * 0.102)
    s_in = 1000 / (2 * 0.1 * 1.02)
    out_mm = (s_in - 1000) / machine.accel_rpm_s * 1000 / 60
    assert lag.length_mm == pytest.approx(out_mm, abs=0.1)
    assert rep.fz_in_band_pct == pytest.approx(100 * (60 - out_mm) / 60, abs=0.2)
    assert rep.to_dict()["spindle_lag_breaks_fz"] is True


def plane_pass(theta_deg: float, s_rpm: int, f_mm_min: int) -> str:
    """One pass up the plane z = x tan(theta), the ball touching it (tip programmed)."""
    th = math.radians(theta_deg)
    lift = R / math.cos(th) - R  # the tip's height above the plane where the ball touches

    def z(x):
        return x * math.tan(th) + lift

    return program(f"S{s_rpm} M3", f"G0 X-15 Y0 Z{z(-15) + 5:.4f}", f"G0 Z{z(-15):.4f}",
                   f"G1 X15 Z{z(15):.4f} F{f_mm_min}")


def test_vc_overshoot_tilted_vs_flat(flat, tilted45):
    # S too high for a 45 deg wall: vc = 2 pi (8 sin 45) 2100 / 1000 = 74.6 m/min > 70
    rep45, ser45 = simulate_program(plane_pass(45, 2100, 420), JOB, tilted45)
    assert ser45.cutting.sum() > 400  # 42.4 mm of cut
    np.testing.assert_allclose(ser45.d_eff_mm[ser45.cutting], 2 * R * math.sin(math.pi / 4),
                               rtol=1e-6)
    vc = math.pi * 2 * R * math.sin(math.pi / 4) * 2100 / 1000
    assert rep45.vc_max_over_pct == pytest.approx(100 * (vc / 70 - 1), abs=1e-3)
    assert rep45.vc_max_over_pct > 6.0 and rep45.fz_in_band_pct == 100.0
    # the same S on a flat plane: the tip cuts, R_eff = 0, vc far below target
    rep0, ser0 = simulate_program(plane_pass(0, 2100, 420), JOB, flat)
    assert ser0.cutting.sum() > 300
    assert rep0.vc_max_over_pct < -99.0 and np.all(ser0.d_eff_mm[ser0.cutting] < 1e-6)


def test_machine_limits_clamp_s_and_f(flat):
    machine = replace(MACHINE, max_rpm=3000, max_feed_mm_min=500)
    text = program("S2000 M3", "G0 X-15 Y0 Z0", "S9000 G1 X15 F900")
    rep, ser = simulate_program(text, replace(JOB, machine=machine), flat)
    assert rep.max_rpm == 3000 and np.all(ser.f_mm_min[ser.cutting] == 500)
    assert rep.cutting_time_min == pytest.approx(30 / 500, rel=1e-12)
    assert any("S9000 is above" in w for w in rep.warnings)


def test_spindle_start_waits_for_speed(flat):
    # M5 then M3 with a new S: the control waits, the speed is there at once
    text = program("S2000 M3", "G0 X-15 Y0 Z0", "G1 X0 F400", "M5", "S6000 M3", "G1 X15")
    _, ser = simulate_program(text, JOB, flat)
    assert np.all(ser.s_rpm[block(ser, text, "G1 X15")] == 6000)


# ---------------------------------------------------------------- API and errors


def test_without_a_mesh_the_toolpath_gives_the_contacts(bowl):
    """Mesh-free: normals from the passes themselves; the judgement of the bowl
    rewrite matches the one made with the exact mesh."""
    original, (rep0, _), (rep_mesh, _), _ = bowl
    job = Job(cutter=BALL16, machine=Machine(accel_rad_s2=227, max_rpm=15000),
              cutting=CuttingData(rep0.vc_target_m_min, rep0.fz_target_mm))
    rep_free, _ = simulate_program(original, job, sample_mm=0.5)
    assert rep_free.cutting_time_min == pytest.approx(rep0.cutting_time_min, rel=1e-3)
    assert rep_free.vc_max_over_pct == pytest.approx(rep0.vc_max_over_pct, abs=1.0)


def test_bad_contacts_and_spacing(flat):
    text = program("S1000 M3", "G0 X0 Y0 Z0", "G1 X5 F100")
    tp = interpret(parse_text(text))
    good = mesh_contacts_at_samples(tp, BALL16, flat, 0.1, 0.05)
    rep_c, _ = simulate_program(text, JOB, contacts=good)
    rep_m, _ = simulate_program(text, JOB, flat)
    assert rep_c.to_dict() == rep_m.to_dict()
    with pytest.raises(UsageError, match="rows but the program has"):
        simulate_program(text, JOB, sample_mm=0.5, contacts=good)
    with pytest.raises(UsageError, match="sample spacing must be positive"):
        simulate_program(text, JOB, flat, sample_mm=0.0)


def test_several_tools_need_a_choice(flat):
    text = program("T1 M6", "S1000 M3", "G0 X0 Y0 Z0", "G1 X5 F100", "T2 M6", "G0 X0 Y0 Z0",
                   "G1 X5 F100")
    with pytest.raises(UsageError, match=r"several tools \(T1, T2\)"):
        simulate_program(text, JOB, flat)
    rep, _ = simulate_program(text, replace(JOB, tool=2), flat)
    assert rep.cut_length_mm == pytest.approx(5.0)


def test_report_json_and_csv(flat, tmp_path):
    text = program("S1000 M3", "G0 X-30 Y0 Z0", "G1 X-20 F200", "S5000 G1 X30 F1000")
    rep, ser = simulate_program(text, JOB, flat)
    d = json.loads(json.dumps(rep.to_dict(), allow_nan=False))
    assert d["lag_count"] == len(rep.lag) == len(d["lag"]) == 1
    assert d["fz_in_band_pct"] == rep.fz_in_band_pct
    out = tmp_path / "s.csv"
    ser.write_csv(out)
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    assert rows.shape == (len(ser), 13)
    assert out.read_text().splitlines()[0].startswith("dist_mm,time_s,line,x_mm")
    np.testing.assert_allclose(rows[:, 6], ser.s_rpm, atol=0.01)


# ---------------------------------------------------------------- the bowl


@pytest.fixture(scope="module")
def bowl():
    """The sample bowl, its lookahead rewrite and both simulations on the same contacts."""
    job = Job(cutter=BALL16, machine=Machine(accel_rad_s2=227, max_rpm=15000))
    mpf, stl = ROOT / "samples" / "bowl.mpf", ROOT / "samples" / "bowl.stl"
    original = mpf.read_bytes().decode("latin-1")
    rewritten = rewrite_file(mpf, job, mesh_path=stl).text
    rep0, ser0 = simulate_file(mpf, job, stl)
    target = CuttingData(rep0.vc_target_m_min, rep0.fz_target_mm)
    tp = interpret(parse_text(original))
    index = MeshIndex(load_stl(stl))
    contacts = mesh_contacts_at_samples(tp, BALL16, index, 0.1, job.contact_tol_mm)
    rep1, ser1 = simulate_program(rewritten, replace(job, cutting=target), contacts=contacts)
    below = replace(job, options=PlanOptions(fz_policy="below"))
    rewritten_below = rewrite_file(mpf, below, mesh_path=stl).text
    rep2, ser2 = simulate_program(rewritten_below, replace(job, cutting=target), contacts=contacts)
    return original, (rep0, ser0), (rep1, ser1), (rep2, ser2)


def test_bowl_original(bowl):
    original, (rep, ser), _, _ = bowl
    assert rep.vc_target_m_min == pytest.approx(math.pi * 16 * 1393 / 1000)
    assert rep.fz_target_mm == pytest.approx(279 / (2 * 1393))
    assert rep.fz_in_band_pct >= 99.9 and not rep.spindle_lag_breaks_fz
    assert rep.s_words == 1 and rep.max_rpm == 1393
    assert 58 < rep.cutting_time_min < 61  # 16.5 m of cut at F279
    bottom = ser.cutting & (np.hypot(ser.xyz_mm[:, 0], ser.xyz_mm[:, 1]) < 40)
    assert bottom.sum() > 10000
    assert np.all(ser.vc_m_min[bottom] < 0.15 * rep.vc_target_m_min)  # flat bottom: rubbing


def worst_lines(ser, excess: np.ndarray, n: int = 8) -> list[int]:
    """Source lines (1-based) of the cut samples with the largest ``excess``, worst first."""
    c = ser.cutting
    order = np.argsort(-excess[c], kind="stable")
    lines = ser.line[c][order]
    return list(dict.fromkeys(lines[excess[c][order] > 0].tolist()))[:n]


def test_bowl_rewrite_time_and_limits(bowl):
    _, (rep0, _), (rep, _), _ = bowl
    assert rep.cut_length_mm == pytest.approx(rep0.cut_length_mm)
    assert rep.cutting_time_min < 0.55 * rep0.cutting_time_min  # issue: at least -45 %
    assert rep.max_rpm <= 15000 and rep.s_words > 1000
    # F centred in the band: fz moves both ways but stays inside +-2 %; only the plunges
    # onto the land fall below it (their F279 is never raised under the faster spindle)
    assert rep.fz_max_over_pct < 2.0
    lines = bowl[0].splitlines()
    under = lines[rep.fz_min_under_line - 7]  # the rewrite has six stamp lines more
    plunge = "Z" in under and "X" not in under and "Y" not in under
    assert rep.fz_min_under_pct < 2.0 or plunge, under
    assert rep.fz_in_band_pct >= 99.0


def test_bowl_rewrite_with_f_below_never_exceeds_fz(bowl):
    _, (rep0, _), _, (rep, _) = bowl
    assert rep.fz_max_over_pct <= 0.15  # F from the lower speed (the target itself is 0.14 % low)
    assert rep.fz_in_band_pct >= 99.0
    assert rep.vc_max_over_pct <= 0.5
    assert rep.cutting_time_min < 0.6 * rep0.cutting_time_min


def test_bowl_rewrite_vc_never_over_target(bowl):
    _, _, (rep, ser), _ = bowl
    over = ser.vc_m_min / rep.vc_target_m_min - 1.0 - 0.005
    assert rep.vc_max_over_pct <= 0.5, f"vc over target at lines {worst_lines(ser, over)}"


def test_bowl_rewrite_fz_in_band(bowl):
    _, _, (rep, ser), _ = bowl
    out = np.abs(ser.fz_mm / rep.fz_target_mm - 1.0) - 0.02
    assert rep.fz_in_band_pct >= 99.0, (f"fz out of its band (worst {-rep.fz_min_under_pct:.2f} "
                                        f"%) at lines {worst_lines(ser, out)}...")


def test_cutting_with_the_spindle_stopped_is_reported(flat):
    text = program("S1000", "G0 X0 Y0 Z0", "G1 X5 F100")
    rep, ser = simulate_program(text, JOB, flat)
    assert np.all(ser.s_rpm == 0) and rep.fz_max_over_pct == math.inf
    assert rep.fz_in_band_pct == 0.0 and rep.to_dict()["fz_max_over_pct"] is None
    assert any("spindle stopped" in w for w in rep.warnings)


def test_lagging_blocks_finds_an_s_jump_the_spindle_cannot_make():
    """S1000 -> S10000 on a 10 mm move at F2000: the spindle (2168 RPM/s) needs 4.2 s, the
    move takes 0.3 s: fz is far out of its band there; a move at the steady S is not."""
    from ncopt.simulate.spindle import lagging_blocks
    text = "G21 G90\nS1000 M3\nG0 X0 Y0 Z0\nG1 X10 F200\nG1 X20 S10000 F2000\nG1 X30\nM5\nM30\n"
    prog = parse_text(text)
    tp = interpret(prog)
    rev = np.full(tp.n, 0.2)  # F/S = 0.2 mm per revolution is the target on every move
    bad = lagging_blocks(prog, tp, tp.spindle_rpm, tp.feed_mm_min,
                         Machine(accel_rad_s2=227, max_rpm=15000), rev, 0.02)
    assert (tp.line[bad] + 1).tolist() == [5, 6]  # X20 (the jump) and X30 (still ramping)


def test_a_rewrite_checks_its_own_spindle_and_finds_the_bowl_clean(bowl):
    original, _, _, _ = bowl
    result = rewrite_text(original, Job(cutter=BALL16, machine=Machine(227, 15000)), "bowl.mpf")
    assert not [w for w in result.summary.warnings if "cannot follow" in w]


def _raster(name: str, z_of_x, y0: float, z_up: float) -> str:
    """An operation ``(name)``: passes along X, 0.4 mm apart from ``y0``, z = z_of_x(x)."""
    out = ["", f"({name})", f"G0 X0 Y{y0:.3f}", f"G0 Z{z_up:.3f}"]  # as Fusion writes it
    for k in range(12):
        y = y0 + 0.4 * k
        xs = np.arange(0.0, 20.01, 0.5)[:: 1 if k % 2 == 0 else -1]
        out += [f"G1 X{x:.3f} Y{y:.3f} Z{z_of_x(x):.3f} F800" for x in xs]
    out.append(f"G0 Z{z_up:.3f}")
    return "\n".join(out) + "\n"


def test_mesh_free_simulation_estimates_each_operation_from_its_own_moves():
    """Without a mesh the normals come from the toolpath; a roughing level 1 mm above a
    finishing pass (BowlTest's pocket beside its scallop: vc +108 % where there was
    none) is not the surface the finish cuts: the finish's D_eff is the same with it."""
    slope = math.tan(math.radians(20.0))
    finish = _raster("Scallop1", lambda x: slope * x, 0.0, 30.0)
    rough = _raster("Pocket1", lambda x: slope * x + 1.0, 0.2, 30.0)
    head = "G21 G90 G17\nT1 M6\nS3000 M3\n"
    _, s_alone = simulate_program(head + finish + "M30\n", JOB)
    _, s_both = simulate_program(head + rough + finish + "M30\n", JOB)
    first = head.count("\n") + 6  # 1-based: the finish's second cutting block
    last = head.count("\n") + finish.count("\n") - 1  # its last cutting block
    shift = rough.count("\n")
    mine_a = (s_alone.line >= first) & (s_alone.line <= last)
    mine_b = (s_both.line >= first + shift) & (s_both.line <= last + shift)
    a, b = s_alone.d_eff_mm[mine_a], s_both.d_eff_mm[mine_b]
    assert a.shape == b.shape
    np.testing.assert_allclose(b, a, rtol=1e-9, equal_nan=True)
    # 20 deg: R_eff = 8 sin 20 = 2.74 mm on the finish's inner passes, D_eff 5.47 mm
    inner = mine_a & np.isfinite(s_alone.vc_m_min) & s_alone.cutting
    assert np.median(s_alone.d_eff_mm[inner]) == pytest.approx(2 * R * math.sin(math.radians(20)),
                                                               rel=0.02)


_RPM = st.one_of(st.sampled_from([0.0, 1000.0, 1500.0, 12000.0]),
                 st.floats(0.0, 20000.0, allow_nan=False))
_REACH = st.one_of(st.sampled_from([0.0, 500.0, math.inf]), st.floats(0.0, 5000.0))


@given(st.lists(st.tuples(_RPM, st.booleans(), _REACH), max_size=40),
       st.sampled_from([(200, 3), (1, 3), (2, 3), (200, 1)]))
def test_run_start_speeds_are_the_run_by_run_ramp(runs, limits):
    """Each run starts where the one before left the spindle (ramping toward its command
    by at most its reach, never past it), or at its command where it starts the spindle;
    the same where the rounds run out and the rest goes run by run."""
    t = np.array([r[0] for r in runs], dtype=np.float64)
    s = np.array([r[1] for r in runs], dtype=bool)
    reach = np.array([r[2] for r in runs], dtype=np.float64)
    w, expected = 0.0, []
    for target, starts, d in runs:
        w = target if starts else w
        expected.append(w)
        w = min(w + d, target) if w < target else max(w - d, target)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(spindle, "RUN_ROUNDS", limits[0])
        mp.setattr(spindle, "RUN_WORK", limits[1])
        got = _run_start_speeds(t, s, reach)
    assert np.array_equal(got, np.array(expected, dtype=np.float64))
