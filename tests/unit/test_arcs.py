"""All arcs of a program at once (ncopt.motion.arcs.arcs_points) give, bit for bit, what
the one-arc reference (arc_points) gives arc by arc, and refuse what it refuses."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ncopt.motion import arcs as arcs_module
from ncopt.motion import points
from ncopt.motion.interp import interpret
from ncopt.reading.parse import parse_text
from ncopt.runtime.errors import NcoptError


def one_by_one(prog, lines, modal, at, p0, p1, tol_mm):
    """The reference: arc_points on each arc, joined."""
    parts = [arcs_module.arc_points(prog, lines, modal, int(i), a, b, tol_mm)
             for i, a, b in zip(at.tolist(), p0, p1)]
    if not parts:
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0)
    return (np.array([p.shape[0] for p, _ in parts], dtype=np.int64),
            np.concatenate([p for p, _ in parts]), np.concatenate([ln for _, ln in parts]))


def _both(text: str):
    """(toolpath or error text) with all arcs at once, and with the reference."""
    out = []
    for fn in (arcs_module.arcs_points, one_by_one):
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(points, "arcs_points", fn)
            try:
                out.append(interpret(parse_text(text)))
            except NcoptError as exc:
                out.append(str(exc))
    return out


NUM = st.floats(-60, 60, allow_nan=False).map(lambda v: round(v, 4))
PLANES = {"G17": "XYZ", "G18": "ZXY", "G19": "YZX"}
OFFSET = {"X": "I", "Y": "J", "Z": "K"}


@st.composite
def arc_programs(draw):
    """Arcs that mostly hold (ends on their circles, to the 4 decimals written), in every
    plane, both directions, I J K incremental or absolute, R short or long, helical, full
    turns; now and then a broken one."""
    plane = draw(st.sampled_from(sorted(PLANES)))
    absolute = draw(st.booleans())
    lines = [draw(st.sampled_from(["G21", "G20"])), plane, "G90.1" if absolute else "G91.1",
             "G0 X0 Y0 Z0", "G1 X1 F500"]
    pos = {"X": 1.0, "Y": 0.0, "Z": 0.0}
    a, b, c = PLANES[plane]
    for _ in range(draw(st.integers(1, 10))):
        g = draw(st.sampled_from(["G2", "G3"]))
        radius = draw(st.floats(0.5, 50))
        phi = draw(st.floats(0, 2 * math.pi))
        sweep = draw(st.floats(0.01, 2 * math.pi - 0.01)) * (-1 if g == "G2" else 1)
        ca, cb = pos[a] - radius * math.cos(phi), pos[b] - radius * math.sin(phi)
        end = {a: round(ca + radius * math.cos(phi + sweep), 4),
               b: round(cb + radius * math.sin(phi + sweep), 4),
               c: round(pos[c] + draw(st.sampled_from([0.0, 0.0, 1.5, -2.25])), 4)}
        words = " ".join(f"{ax}{end[ax]}" for ax in "XYZ")
        if draw(st.integers(0, 4)) == 2:  # (hypothesis leans to both ends: rare cases in the middle)
            long_arc = abs(sweep) > math.pi
            centre = f"R{'-' if long_arc else ''}{radius:.4f}"
        elif absolute:
            centre = f"{OFFSET[a]}{ca:.4f} {OFFSET[b]}{cb:.4f}"
        else:
            centre = f"{OFFSET[a]}{ca - pos[a]:.4f} {OFFSET[b]}{cb - pos[b]:.4f}"
        if draw(st.integers(0, 16)) == 8:
            centre = f"{OFFSET[a]}{draw(NUM)}"  # a broken one: refused alike
        turns = " P2" if draw(st.integers(0, 10)) == 5 and not centre.startswith("R") else ""
        lines.append(f"{g} {words} {centre}{turns}")
        pos = end
    return "\n".join(lines) + "\n"


def _same(a, b):
    if isinstance(a, str) or isinstance(b, str):
        assert a == b
        return
    assert np.array_equal(a.xyz_mm.view(np.uint64), b.xyz_mm.view(np.uint64))
    assert np.array_equal(a.seg_len_mm.view(np.uint64), b.seg_len_mm.view(np.uint64))
    assert np.array_equal(a.line, b.line)


@settings(max_examples=200)
@given(arc_programs())
def test_all_arcs_at_once_are_the_reference_bit_for_bit(text):
    _same(*_both(text))


def test_the_generated_arcs_mostly_hold():
    """The property above is only worth something on arcs that are planned."""
    held = []

    @settings(max_examples=60, database=None)
    @given(arc_programs())
    def count(text):
        held.append(not isinstance(_both(text)[0], str))

    count()
    assert sum(held) >= 0.6 * len(held)


def test_a_full_circle_and_turns_and_an_r_arc():
    text = ("G17 G21 G0 X10 Y0 Z0\nG1 X10 F500\nG2 X10 Y0 I-10 J0\nG3 X10 Y0 I-10 P3\n"
            "G2 X0 Y10 R10\nG2 X10 Y0 R-10\nG18 G3 X0 Z10 I-10 K0\n")
    a, b = _both(text)
    _same(a, b)
    assert not isinstance(a, str)
    # three turns of a circle of radius 10: the path is 3 * 2 pi * 10 long
    on_line = a.line == 3
    assert math.isclose(a.seg_len_mm[on_line].sum(), 3 * 2 * math.pi * 10, rel_tol=1e-12)


@pytest.mark.parametrize("arc", ["G2 X5 Y5", "G2 X30 Y0 I5 J0", "G2 X10 Y0 I0 J0",
                                 "G2 X30 Y0 R1"])
def test_refused_arcs_are_refused_with_the_reference_message(arc):
    text = f"G17 G21 G0 X10 Y0 Z0\nG1 X10 F500\nG2 X0 Y10 R10\n{arc}\n"
    a, b = _both(text)
    assert isinstance(a, str) and a == b


@settings(max_examples=60)
@given(arc_programs())
def test_arcs_in_chunks_are_the_reference_bit_for_bit(text):
    """Arcs go ARC_CHUNK at a time (memory): with chunks of three, the same bits, and a
    refused arc the first in program order as arc by arc."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(arcs_module, "ARC_CHUNK", 3)
        chunked = _both(text)
    _same(chunked[0], _both(text)[1])


def test_arcs_in_every_plane_in_one_program_are_the_reference_bit_for_bit():
    """A chunk whose arcs are in more than one plane takes each arc's own axes."""
    text = ("G21 G17 G0 X10 Y0 Z0\nG1 X10 F500\nG3 X0 Y10 I-10 J0\n"
            "G18 G2 X5 Z-5 I5 K0\nG19 G3 Y5 Z0 J-5 K0 \nG17 G2 X10 Y0 R10\n"
            "G18 G3 X10 Z5 R-7\nG19 G2 Y5 Z10 J0 K5\n")
    a, b = _both(text)
    _same(a, b)
    assert not isinstance(a, str)


ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True)


@settings(max_examples=300)
@given(st.lists(st.tuples(ANY_FLOAT, ANY_FLOAT), min_size=1, max_size=40))
def test_numpy_hypot_is_math_hypot_bit_for_bit(pairs):
    from ncopt.motion.mathhypot import hypot
    x, y = (np.array(v, dtype=np.float64) for v in zip(*pairs))
    want = np.array([math.hypot(a, b) for a, b in pairs])
    got = hypot(x, y)
    assert np.array_equal(got.view(np.uint64), want.view(np.uint64)) or (
        np.array_equal(np.isnan(got), np.isnan(want))
        and np.array_equal(got[~np.isnan(got)].view(np.uint64),
                           want[~np.isnan(want)].view(np.uint64)))
    zero = hypot(x, np.zeros_like(x))  # the path where every second part is 0
    want = np.array([math.hypot(a, 0.0) for a in x.tolist()])
    assert np.array_equal(np.isnan(zero), np.isnan(want))
    assert np.array_equal(zero[~np.isnan(zero)], want[~np.isnan(want)])


def test_numpy_hypot_on_many_random_pairs():
    from ncopt.motion.mathhypot import hypot
    rng = np.random.default_rng(5)
    x = rng.normal(size=200_000) * 10.0 ** rng.uniform(-6, 6, 200_000)
    y = np.round(rng.uniform(-100, 100, 200_000), 4)
    want = np.fromiter(map(math.hypot, x.tolist(), y.tolist()), np.float64, x.size)
    assert np.array_equal(hypot(x, y).view(np.uint64), want.view(np.uint64))


def _scalar_refused(r0, r1, inch):
    """arc_points's radius test (math.hypot's r1)."""
    t_abs = 2 * math.sqrt(2) * (0.001 * 25.4 if inch else 0.01)
    err = abs(r0 - r1)
    return (min(r0, r1) < arcs_module.MIN_ARC_RADIUS_MM * (1.0 - 1e-9) or err > 100 * t_abs
            or (err > t_abs and err / max(r0, r1) > 0.001))


def test_radius_tests_at_their_thresholds_are_the_reference():
    """The end's radius is numpy's hypot but math.hypot's wherever a test is close."""
    rng = np.random.default_rng(8)
    n = 20_000
    inch = rng.integers(0, 2, n).astype(bool)
    t_abs = 2 * math.sqrt(2) * np.where(inch, 0.001 * 25.4, 0.01)
    phi = rng.uniform(0, 2 * math.pi, n)
    r1_target = rng.uniform(0.5, 20, n)
    u1, v1 = r1_target * np.cos(phi), r1_target * np.sin(phi)
    r1 = np.array([math.hypot(a, b) for a, b in zip(u1.tolist(), v1.tolist())])
    # start radii a hair either side of each threshold
    edge = np.choose(rng.integers(0, 3, n), [r1 + t_abs, r1 + 100 * t_abs, r1 / (1 - 0.001)])
    r0 = edge * (1 + rng.choice([-1, 0, 1], n) * 2.0 ** -52)
    small = rng.random(n) < 0.05  # and at the smallest radius
    r0[small] = arcs_module.MIN_ARC_RADIUS_MM * (1.0 - 1e-9) * (1 + rng.choice([-1, 0, 1]) * 1e-15)
    got = arcs_module._radii_refused(r0, u1, v1, inch)
    want = [_scalar_refused(a, b, c) for a, b, c in zip(r0.tolist(), r1.tolist(), inch.tolist())]
    assert got.tolist() == want


def test_piece_counts_are_the_reference_next_to_whole_numbers():
    rng = np.random.default_rng(9)
    tol_mm = 0.005
    r = np.concatenate([rng.uniform(0.001, 0.01, 500), rng.uniform(0.01, 100, 5000)])
    step = np.array([2 * math.acos(max(1 - tol_mm / x, -1.0)) if tol_mm < x else math.pi / 2
                     for x in r.tolist()])
    whole = rng.integers(1, 2000, r.size).astype(np.float64)
    sweep = whole * np.maximum(step, 1e-6) * (1 + rng.choice([-1, 0, 1, 1e6], r.size) * 2.0 ** -52)
    got = arcs_module._piece_counts(sweep, r, tol_mm)
    want = [min(max(int(math.ceil(s / max(st_, 1e-6))), 1), 100000)
            for s, st_ in zip(sweep.tolist(), step.tolist())]
    assert got.tolist() == want


@settings(max_examples=300)
@given(st.lists(st.tuples(ANY_FLOAT, ANY_FLOAT), min_size=1, max_size=40))
def test_angles_of_many_pairs_are_math_atan2_bit_for_bit(pairs):
    """cmath.phase's path and its fallback where atan2 underflows (tiny y over large x)."""
    y, x = (np.array(v, dtype=np.float64) for v in zip(*pairs))
    want = np.array([math.atan2(a, b) for a, b in pairs])
    got = arcs_module._atan2(y, x)
    assert np.array_equal(np.isnan(got), np.isnan(want))
    ok = ~np.isnan(want)
    assert np.array_equal(got[ok].view(np.uint64), want[ok].view(np.uint64))
    tiny = arcs_module._atan2(np.array([5e-324, 1.0]), np.array([3.0, 2.0]))
    assert tiny.tolist() == [math.atan2(5e-324, 3.0), math.atan2(1.0, 2.0)]
