"""5-axis rewrites judged by LinuxCNC's rs274 (see judge.py): LinuxCNC's own 5-axis demos
(the boat hulls from a Hermle, the 7-blade impeller in G93) and generated xyzac-trt cases
in G94 and G93.  The canonical motion, A B C included, is identical call for call, and the
spindle speed and feed in force at every planned feed move are the planned ones."""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.model import Cutter, Machine, Motion, PlanOptions

from judge import RS274, canon, feed_in_program_units

ROOT = Path(__file__).resolve().parents[1]
FIVE = ROOT.parent / "shared" / "corpus" / "linuxcnc" / "5axis"
MACHINE = Machine(accel_rad_s2=227, max_rpm=18000)
# the boats' comment calls T1 an end mill: judged as a ball (--shape ball), as a user would
BALL = dict(shape_named=True)

if RS274 is None:
    if os.environ.get("CI"):
        raise RuntimeError("rs274 (Debian package linuxcnc-uspace) is not installed")
    pytest.skip("rs274 not installed", allow_module_level=True)


pytestmark = pytest.mark.judge  # the judge tier: rs274 judges five 5-axis rewrites


def _generated(feed: str) -> str:
    spec = importlib.util.spec_from_file_location("make_5axis", ROOT / "bench" / "make_5axis.py")
    gen = importlib.util.module_from_spec(spec)
    sys.modules["make_5axis"] = gen
    spec.loader.exec_module(gen)
    case = gen.make_case("dome", half_mm=6.0, step_mm=1.0, stepover_mm=1.5)
    return gen.program(case, "xyzac-trt", feed=feed)


CASES = {
    "boat-xyzac": (lambda: (FIVE / "boat-xyzac.ngc").read_bytes().decode("latin-1"),
                   Job(machine=MACHINE, cutter=Cutter(10, 2), kinematics="xyzac-trt-linuxcnc",
                       **BALL)),
    "boat-xyzbc": (lambda: (FIVE / "boat-xyzbc.ngc").read_bytes().decode("latin-1"),
                   Job(machine=MACHINE, cutter=Cutter(10, 2), kinematics="xyzbc-trt-linuxcnc",
                       decimal_point="calculator", **BALL)),
    "impeller": (lambda: (FIVE / "impeller-7bl-xyzac.ngc").read_bytes().decode("latin-1"),
                 Job(machine=MACHINE, cutter=Cutter(6, 2), kinematics="xyzac-trt-linuxcnc",
                     options=PlanOptions(fz_tolerance=0.05))),
    "dome-g94": (lambda: _generated("g94"),
                 Job(machine=MACHINE, cutter=Cutter(10, 2), kinematics="xyzac-trt")),
    "dome-g93": (lambda: _generated("g93"),
                 Job(machine=MACHINE, cutter=Cutter(10, 2), kinematics="xyzac-trt")),
}


@pytest.fixture(scope="module", params=sorted(CASES))
def judged(request, tmp_path_factory):
    read, job = CASES[request.param]
    text = read()
    result = rewrite_text(text, job, request.param)
    tmp = tmp_path_factory.mktemp("judge5")
    (tmp / "a").mkdir()
    (tmp / "b").mkdir()
    return result, canon(text, tmp / "a"), canon(result.text, tmp / "b")


def test_the_motion_is_identical_rotary_axes_included(judged):
    result, a, b = judged
    assert len(a.motion) > 100
    assert a.motion == b.motion
    rotary = [m for m in a.motion if any(abs(float(v)) > 1e-9 for v in m[1].split(",")[3:6])]
    assert rotary  # the rotary axes do move


def test_speed_and_feed_in_force_are_the_planned_ones(judged):
    result, _, b = judged
    tp, idx, targets = result.toolpath, result.block_index, result.targets
    fp = idx.first_point
    last = np.concatenate((fp[1:] - 1, [tp.n - 1]))
    length = np.add.reduceat(tp.seg_len_mm[1:], fp - 1)
    g93 = tp.inverse_time[fp] if tp.inverse_time is not None else np.zeros(fp.shape, bool)
    planned = np.flatnonzero(np.isin(tp.motion[fp], [Motion.LINEAR, Motion.ARC_CW,
                                                      Motion.ARC_CCW]) & tp.known[fp])
    calls = [c for c in b.feed_state]
    ends = np.array([[float(v) for v in args.split(",")[:3]] for args, _, _ in calls])
    checked, j = 0, 0
    for blk in planned.tolist():
        # rs274's feed call that ends where this block ends, at or after the last match
        hit = np.flatnonzero(np.all(np.abs(ends[j:j + 50] - tp.xyz_mm[last[blk]]) < 2e-3,
                                    axis=1))
        if hit.size == 0:
            continue
        j += int(hit[0])
        _, feed, speed = calls[j]
        j += 1
        f = feed_in_program_units(feed, bool(g93[blk]), length[blk])
        assert f == pytest.approx(targets.f_value[blk], rel=2e-4, abs=2e-3), \
            f"line {targets.line[blk] + 1}: F in force {f}, planned {targets.f_value[blk]}"
        assert speed == pytest.approx(targets.s_value[blk], abs=1e-3)
        checked += 1
    assert checked >= 0.95 * planned.size and planned.size > 100
