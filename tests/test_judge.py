"""Every rewrite of a LinuxCNC-readable corpus program, judged by LinuxCNC's own
interpreter: the canonical motion is identical, and the spindle speed and feed
rate in force at every feed move are the ones ncopt planned."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.model import Cutter, CuttingData, Machine, Motion

from judge import RS274, canon

ROOT = Path(__file__).resolve().parents[1]
CORPUS = ROOT.parent / "shared" / "corpus"
MACHINE = Machine(accel_rad_s2=227, max_rpm=15000)

if RS274 is None:  # CI installs linuxcnc-uspace; a missing judge must not pass silently there
    if os.environ.get("CI"):
        raise RuntimeError("rs274 (Debian package linuxcnc-uspace) is not installed")
    pytest.skip("rs274 not installed: apt-get install --no-install-recommends linuxcnc-uspace",
                allow_module_level=True)

pytestmark = pytest.mark.judge  # the judge tier: rs274 judges the rewrites of ten corpus programs


SPEC = CuttingData(vc_m_min=60.0, fz_mm=0.03)  # for programs that run M3 with no S word
ALL = ("all",)  # 2D engravings ncopt leaves by default: planned here to judge the edits
# (program, cutter on the command line or None to read it from the program, cutting data,
# operations); 3D_Chips's own F is a parameter expression worth 4.5e6 mm/min, which ncopt
# refuses to scale: planned here from given cutting data
PROGRAMS = [
    ("linuxcnc/3D_Chips.ngc", None, SPEC, None),
    ("fusion/BowlTest.nc", None, None, None),
    ("fusion/chess_engraved_box.nc", None, None, None),
    ("camotics/bear.nc", Cutter(3.175, 2), None, None),
    ("camotics/cameo.nc", Cutter(3.175, 2), SPEC, None),
    ("camotics/flower_mold.nc", Cutter(3.175, 2), None, None),
    ("camotics/wave.gcode", Cutter(6.0, 2), None, None),
    ("pygcode/Heart.tap", Cutter(3.0, 2), SPEC, ALL),
    ("pygcode/Smiley face.tap", Cutter(3.0, 2), SPEC, ALL),
    ("pygcode/Mach3 write.tap", Cutter(3.0, 2), None, ALL),
]
WINDOW = 50  # canonical feed calls ncopt does not plan (canned cycles) are skipped


@pytest.fixture(scope="module", params=PROGRAMS, ids=[p[0] for p in PROGRAMS])
def case(request, tmp_path_factory):
    """The program, its rewrite, and rs274's canonical calls for both (once per program)."""
    rel, cutter, cutting, operations = request.param
    path = CORPUS / rel
    text = path.read_bytes().decode("latin-1")
    job = Job(machine=MACHINE, cutter=cutter, cutting=cutting, operations=operations)
    result = rewrite_text(text, job, str(path))
    tmp = tmp_path_factory.mktemp("judge")
    (tmp / "a").mkdir()
    (tmp / "b").mkdir()
    return text, result, canon(text, tmp / "a"), canon(result.text, tmp / "b")


def test_motion_is_identical(case):
    text, result, a, b = case
    assert len(a.motion) > 0
    assert a.motion == b.motion


def test_speed_and_feed_in_force_are_the_planned_ones(case):
    text, result, _, b = case
    tp, idx, targets = result.toolpath, result.block_index, result.targets
    feed_block = np.isin(tp.motion[idx.first_point], [Motion.LINEAR, Motion.ARC_CW, Motion.ARC_CCW])
    last_point = np.concatenate((idx.first_point[1:] - 1, [tp.n - 1]))
    inch = tp.line_inch[idx.line]
    end = (tp.xyz_mm[last_point] / np.where(inch, 25.4, 1.0)[:, None]).tolist()
    blocks = np.flatnonzero(feed_block)
    known = tp.known[idx.first_point]
    checked, j = 0, 0
    for args, feed, speed in b.feed_state:
        # the ncopt feed block ending where rs274's feed call ends, a few blocks ahead at most
        ahead = blocks[j:j + WINDOW].tolist()
        hit = [k for k, blk in enumerate(ahead) if _ends_at(args, end[blk])]
        if not hit:
            continue
        blk = ahead[hit[0]]
        j += hit[0] + 1
        if not known[blk]:
            continue
        assert feed == pytest.approx(targets.f_value[blk], rel=1e-6, abs=1e-3), \
            f"line {targets.line[blk] + 1}: F in force {feed}, planned {targets.f_value[blk]}"
        assert speed == pytest.approx(targets.s_value[blk], abs=1e-3), \
            f"line {targets.line[blk] + 1}: S in force {speed}, planned {targets.s_value[blk]}"
        checked += 1
    n_known = int(np.sum(known[blocks]))
    assert checked >= 0.95 * n_known, f"only {checked} of {n_known} feed blocks matched"


def _ends_at(args: str, point: list, tol: float = 2e-3) -> bool:
    """Does a canonical STRAIGHT_FEED (x, y, z, ...) or ARC_FEED call end at point?"""
    v = [float(a) for a in args.split(",")]
    if len(v) >= 9:  # ARC_FEED(first_end, second_end, first_axis, second_axis, rotation, axis_end, ...)
        options = ((v[0], v[1], v[5]), (v[5], v[0], v[1]), (v[1], v[5], v[0]))
    else:
        options = ((v[0], v[1], v[2]),)
    return any(all(abs(c - p) <= tol for c, p in zip(o, point)) for o in options)
