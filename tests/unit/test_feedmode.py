"""Inverse-time feed (G93): a block's F is 1 / minutes; ncopt plans the tip feed it stands
for and scales the block's own word by the same factor; rotary-only moves keep their F."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.motion.feedmode import inverse_time_words, tip_feed_mm_min
from ncopt.motion.interp import interpret
from ncopt.model import Cutter, CuttingData, Machine
from ncopt.reading.parse import parse_text
from ncopt.runtime.errors import NcoptError
from ncopt.simulate.replay import simulate_program

JOB = Job(machine=Machine(227, 18000), cutter=Cutter(10, 2), cutting=CuttingData(150, 0.08))


def raster(inverse: bool, inch: bool = False) -> str:
    """Zig-zag passes over a gentle saddle, the same moves in G94 (F1000) or G93."""
    u = 25.4 if inch else 1.0
    out = ["G20" if inch else "G21", "G90 G94", "S3000 M3", f"G0 X0 Y0 Z{5 / u:.4f}"]
    prev = None
    for j in range(6):
        xs = np.arange(0, 20.01, 0.5) if j % 2 == 0 else np.arange(20, -0.01, -0.5)
        for x in xs:
            p = np.array([x, j * 0.8, 0.01 * (x - 10) ** 2 - 0.02 * (j * 0.8 - 2) ** 2])
            words = f"G1 X{p[0] / u:.5f} Y{p[1] / u:.5f} Z{p[2] / u:.5f}"
            if prev is None:  # a rapid to the first point: no plunge into the saddle
                out += [words.replace("G1", "G0"), f"F{1000 / u:.4f}"]
                out += ["G93"] if inverse else []
            elif inverse:
                out.append(words + f" F{1000.0 / np.linalg.norm(p - prev):.4f}")
            else:
                out.append(words)
            prev = p
    return "\n".join(out + (["G94"] if inverse else []) + ["M30"]) + "\n"


def test_tip_feed_and_words_are_inverse():
    mode = np.array([930, 940, 930])
    feed, ok = tip_feed_mm_min(mode, np.array([2.0, np.nan, np.nan]),
                               np.array([7.0, 500.0, 7.0]), np.array([10.0, 3.0, 4.0]))
    assert feed[0] == 20.0 and feed[1] == 500.0 and np.isnan(feed[2])
    assert ok.tolist() == [True, True, False]
    words = inverse_time_words(np.array([20.0, 30.0]), np.array([10.0, 0.0]))
    assert words.tolist() == [2.0, 30.0]  # no length: the word itself
    feed, _ = tip_feed_mm_min(mode[:1], np.array([2.0]), np.array([7.0]), np.array([0.0]))
    assert feed[0] == 2.0


def test_g93_moves_are_read_as_tip_feeds():
    tp = interpret(parse_text("G21 G90\nS1000 M3\nG0 X0 Y0 Z0\nG93\nG1 X10 F6\n"
                              "G2 X20 Y0 I5 J0 F3\nG1 X30 F2\nG94\nG1 X40 F100\n", "t.nc"))
    by_line = {int(l): (f, k) for l, f, k in zip(tp.line, tp.feed_mm_min, tp.known)}
    assert by_line[4] == (60.0, True)  # 10 mm in 1/6 min
    arc = tp.line == 5
    assert np.allclose(tp.feed_mm_min[arc], 3 * 5 * np.pi) and tp.known[arc].all()
    assert by_line[6] == (20.0, True)  # 10 mm in 1/2 min
    assert tp.warnings == ()
    assert tp.inverse_time.tolist() == [False, False, True] + [True] * int(arc.sum()) + \
        [True, False]


def test_a_g93_move_without_its_own_f_is_refused_at_its_line():
    """LinuxCNC refuses it ("F word missing with inverse time G1 move"): no F in force."""
    with pytest.raises(NcoptError) as err:
        interpret(parse_text("G21 G90\nS1000 M3\nG0 X0 Y0 Z0\nG93\nG1 X10 F6\n"
                             "G1 X30\nG94\n", "t.nc"))
    assert err.value.line == 6


@pytest.mark.parametrize("inch", [False, True])
def test_g93_plans_like_g94_and_scales_each_word(inch):
    a = rewrite_text(raster(False, inch), JOB, "a.nc")
    b = rewrite_text(raster(True, inch), JOB, "b.nc")
    pa, pb = a.plan, b.plan
    cut = pa.blocks.cutting
    assert cut.sum() > 200 and np.array_equal(cut, pb.blocks.cutting)
    assert np.array_equal(pa.s_cmd_rpm, pb.s_cmd_rpm)
    # each G93 word is the planned tip feed over the block's length, rounded down
    length = pb.blocks.length_mm
    words = b.targets.f_value[cut]
    assert np.all(words * length[cut] <= pb.f_mm_min[cut] + 1e-9)
    assert np.all(words * length[cut] > pb.f_mm_min[cut] * (1 - 1e-3))
    # and the same factor on the programmed word as on the feed it stands for
    src = interpret(parse_text(raster(True, inch), "b.nc"))
    old = src.feed_mm_min[b.block_index.first_point] / length
    assert np.allclose(words / old[cut], pb.f_mm_min[cut] / (old[cut] * length[cut]), rtol=1e-3)
    assert b.summary.cut_time_before_min == pytest.approx(a.summary.cut_time_before_min, rel=1e-3)
    assert b.summary.cut_time_after_min == pytest.approx(a.summary.cut_time_after_min, rel=2e-3)


def test_g93_simulated_times_are_the_blocks_own_minutes():
    text = raster(True)
    report, _ = simulate_program(text, JOB)
    tp = interpret(parse_text(text, "t.nc"))
    g93 = tp.inverse_time & tp.known & (tp.motion == 1)
    # every cutting G93 block lasts 1 / F minutes: 1000 mm/min along its length
    assert report.cutting_time_min == pytest.approx(tp.seg_len_mm[g93].sum() / 1000.0, rel=1e-3)


def test_a_rotary_only_move_keeps_its_feed_in_g93_and_g94():
    for mode, f in (("G93", "F12.5"), ("G94", "F360")):
        text = ("G21 G90 G94\nS3000 M3\nG0 X0 Y0 Z0 A0 C0\nG1 X1 F500\n" + mode + "\n"
                + "".join(f"G1 X{x} F{500 / 0.5 if mode == 'G93' else 500:g}\n"
                          for x in np.arange(1.5, 10, 0.5))
                + f"G1 C30 {f}\n"  # rotary-only: turns the table, the tip stays
                + ("G1 X11 F500\n" if mode == "G93" else "G1 X11\n") + "G94\nM30\n")
        job = replace(JOB, kinematics="xyzac-trt", operations=("all",))  # a few lines
        result = rewrite_text(text, job, "r.nc")
        line = text.splitlines().index(f"G1 C30 {f}")
        k = list(result.targets.line).index(line)
        assert result.targets.f_value[k] == float(f[1:])
        assert result.text.splitlines()[line + 1].startswith("(ncopt") is False
        assert f"G1 C30 {f}" in result.text.splitlines()


def test_g93_blocks_are_timed_as_their_own_minutes_rotary_only_too():
    from ncopt.motion.times import feed_minutes, untimed_moves

    text = ("G21 G90 G94 M428\nS3000 M3\nG0 X0 Y0 Z0 A0 C0\nG1 X1 F500\nG93\n"
            "G1 X3 F250\nG1 C30 F12.5\nG1 X4 F100\nG94\nM30\n")
    tp = interpret(parse_text(text, "t.nc"), kinematics="xyzac-trt")
    minutes = feed_minutes(tp)
    by_line = {int(ln): minutes[tp.line == ln].sum() for ln in (5, 6, 7)}
    # 1 / F minutes each: 2 mm at F250, a table turn at F12.5, 1 mm at F100
    assert by_line == pytest.approx({5: 1 / 250, 6: 1 / 12.5, 7: 1 / 100})
    assert untimed_moves(tp) == 0
