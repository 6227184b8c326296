"""Errors a control would raise on a program (the LinuxCNC interpreter's own checks):
two codes of one modal group on a line, words no code uses, arcs without a centre,
cutter compensation that cannot be followed, feed moves without a feed."""

from __future__ import annotations

import math

import numpy as np

from ncopt.model import MM_PER_INCH, LineKind, Program
from ncopt.motion.linetable import LineTable
from ncopt.motion.modal import (CANNED, G_ARC_DISTANCE, G_COMP, G_DISTANCE, G_FEED_MODE, G_MOTION,
                                G_NON_MODAL_MOVE, G_PLANE, G_UNITS, ffill)
from ncopt.reading.refuse import check_arc_centres, check_signs, check_words
from ncopt.runtime.errors import NcoptError


def fail(prog: Program, line: int, message: str) -> None:
    """Raise the error ``message`` at 0-based ``line`` of ``prog``."""
    raise NcoptError(message, prog.path, int(line) + 1, 1)


def check_semantics(prog: Program, lines: LineTable, executed: np.ndarray) -> None:
    """Errors a control would raise (the LinuxCNC interpreter's own checks)."""
    check_words(prog, lines.has_g({650, 660}))
    check_signs(prog, lines, executed)
    # G80 beside a motion code is accepted by Mach3/Fanuc posts (N100G00G21G17G90G40G49G80)
    groups = [G_MOTION - {800}, G_NON_MODAL_MOVE | {40}, G_PLANE, G_DISTANCE, G_UNITS,
              G_FEED_MODE, G_COMP]
    for group in groups:
        line = lines.g_line[np.isin(lines.g_code, list(group))]  # in text order
        twice = line[1:][line[1:] == line[:-1]]  # the lines holding two of the group
        bad = twice[executed[twice]]
        if bad.size:
            fail(prog, bad[0], "two G codes from the same modal group on one line; "
                 "put them on separate lines")
    motion = ffill(lines.g_group(G_MOTION))
    rotary = lines.present_any("ABC")
    bad = np.flatnonzero(np.isin(motion, list(CANNED)) & rotary & executed)
    if bad.size:
        fail(prog, bad[0], "a rotary axis word (A/B/C) in a canned cycle; remove it")
    probe = lines.has_g({382, 383, 384, 385})
    axes = lines.present_any("XYZ")
    bad = np.flatnonzero(probe & ~axes & executed)
    if bad.size:
        fail(prog, bad[0], "all axes missing with a probe move (G38.x); give a target")
    r_used = np.isin(motion, [20, 30] + list(CANNED))
    r_used |= lines.has_g({640, 100, 760, 700, 710, 711, 712, 720, 721, 722, 51})  # G05.1 R: level
    r_used |= lines.has_m({19}) | lines.unread_g()  # an unknown code may take R
    bad = np.flatnonzero(lines.present("R") & ~r_used & executed)
    if bad.size:
        fail(prog, bad[0], "R word with no G code that uses it; remove the R word")
    arc = np.isin(motion, [20, 30]) & executed & (axes | lines.has_g({20, 30}))
    no_centre = ~lines.present_any("IJKR")
    # an arc whose line holds what ncopt does not read (Sinumerik CR=R1*2, AR=90, I=AC(5))
    # may give its centre there: it is no move ncopt reads, and the position is lost after it
    no_centre &= prog.line_kind != LineKind.OPAQUE
    if (arc & no_centre).any():
        fail(prog, np.flatnonzero(arc & no_centre)[0],
             "arc with none of I, J, K or R; give the centre or the radius")
    check_arc_centres(prog, lines, arc, plane=ffill(lines.g_group(G_PLANE), 170.0),
                      incremental=ffill(lines.g_group(G_ARC_DISTANCE), 911.0) == 911.0,
                      inch=ffill(lines.g_group(G_UNITS), 210.0) == 200.0)
    _check_comp_exit(prog, lines, motion, executed)
    both = lines.present("R") & lines.has_g({640}) & lines.has_m({19})
    if both.any():
        fail(prog, np.flatnonzero(both)[0], "R word is ambiguous with both G64 and M19; "
             "use separate lines")


def _check_comp_exit(prog, lines, motion, executed) -> None:
    """The move after leaving cutter compensation (G40) must be straight."""
    comp = lines.g_group(G_COMP)
    moves = np.flatnonzero(executed & np.isin(motion, [0, 10, 20, 30])
                           & lines.present_any("XYZIJKR"))
    for i in np.flatnonzero(comp == 400).tolist():
        before = comp[:i][~np.isnan(comp[:i])]
        if before.size == 0 or before[-1] == 400:
            continue
        nxt = moves[moves >= i]
        if nxt.size and motion[nxt[0]] in (20, 30):
            fail(prog, nxt[0], "the move just after leaving cutter compensation (G40) "
                 "must be straight, not an arc")


def check_comp_corners(prog, lines, modal, pos_mm, known, executed) -> None:
    """Cutter compensation with a stated diameter (G41.1/G42.1 D..): in a concave
    corner between two straight XY moves, the offset lines must meet inside both
    offset moves, or the tool cannot reach the corner without gouging (the
    LinuxCNC interpreter's check)."""
    dynamic = np.isin(modal.comp, [411, 421]) & executed
    if not dynamic.any():
        return
    diameter = ffill(np.where(lines.has_g({411, 421}), lines.value("D"), np.nan))
    feed = dynamic & np.isin(modal.motion, [10]) & lines.present_any("XY")
    # moves under compensation are "unknown" for planning; their programmed path is
    # trusted here when the position was known where compensation began
    begins = np.flatnonzero(dynamic & ~np.concatenate(([False], dynamic[:-1])))
    trusted = np.zeros(lines.n, dtype=bool)
    for c in begins.tolist():
        if c > 0 and known[c - 1, :2].all():
            end = c + int(np.argmin(dynamic[c:])) if not dynamic[c:].all() else lines.n
            trusted[c:end] = True
    moves = np.flatnonzero(feed & trusted)
    for a, b in zip(moves[:-1].tolist(), moves[1:].tolist()):
        prev = pos_mm[a - 1] if a > 0 else None
        if prev is None or modal.comp[a] != modal.comp[b]:
            continue
        r = 0.5 * diameter[b] * (MM_PER_INCH if modal.inch[b] else 1.0)
        side = 1.0 if modal.comp[b] == 411 else -1.0  # tool left (G41) or right of the path
        if _gouges(prev[:2], pos_mm[a, :2], pos_mm[b, :2], r, side):
            fail(prog, b, "straight feed in a concave corner cannot be reached by the tool "
                 "without gouging; lengthen the move or use a smaller tool")


def _gouges(p0, p1, p2, r, side) -> bool:
    """Whether the offset of the corner p0 -> p1 -> p2 (XY, mm) by ``r`` mm on ``side``
    (+1 left) misses one of its two offset moves."""
    d1, d2 = p1 - p0, p2 - p1
    l1, l2 = math.hypot(*d1), math.hypot(*d2)
    if l1 < 1e-12 or l2 < 1e-12 or not r > 0:
        return False
    d1, d2 = d1 / l1, d2 / l2
    turn = d1[0] * d2[1] - d1[1] * d2[0]
    if turn * side <= 1e-12:  # convex corner (or straight on): the tool goes round it
        return False
    n1 = side * np.array([-d1[1], d1[0]])  # offset directions toward the tool
    n2 = side * np.array([-d2[1], d2[0]])
    # X = p1 + r n1 + t1 d1 = p1 + r n2 + t2 d2
    m = np.column_stack((d1, -d2))
    t1, t2 = np.linalg.solve(m, r * (n2 - n1))
    return t1 < -l1 - 1e-9 or t2 > l2 + 1e-9


def check_feed(prog, modal, move_lines) -> None:
    """Feed moves among ``move_lines`` need a feed: F > 0 (G94), an F other than 0 (G93)."""
    feed_moves = move_lines[np.isin(modal.motion[move_lines], [10, 20, 30])]
    bad = feed_moves[(np.nan_to_num(modal.feed[feed_moves], nan=0.0) <= 0)
                     & (modal.feed_mode[feed_moves] == 940)]
    if bad.size:
        fail(prog, bad[0], "feed move with zero feed rate; add an F word before it")
    # inverse time: F is 1/minutes, F0 a move that never ends (LinuxCNC refuses it too)
    zero = feed_moves[(modal.feed[feed_moves] <= 0) & (modal.feed_mode[feed_moves] == 930)]
    if zero.size:
        fail(prog, zero[0], "inverse-time (G93) move with F0 (F is 1/minutes there): give "
             "the move's F")
