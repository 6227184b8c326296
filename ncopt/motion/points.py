"""The cutter locations of the moves (:class:`ncopt.model.Toolpath`): one row per point,
arcs cut into pieces, each segment's length, F and S, and whether ncopt plans it (with a
located reason where it does not)."""

from __future__ import annotations

import functools

import numpy as np

from ncopt.model import MM_PER_INCH, LineKind, Toolpath
from ncopt.motion.arcs import arcs_points
from ncopt.motion.checks import check_feed
from ncopt.motion.feedmode import G93, G95, tip_feed_mm_min
from ncopt.motion.modal import G_MODES_NOT_READ, G_NOT_A_TARGET, SCALED_WHY, row_norms
from ncopt.motion.modalstate import NotRead, not_read_in_force
from ncopt.motion.toolaxis import Orientation


def build_points(prog, lines, modal, pos_mm, known, executed, start, warnings,
                 orient: Orientation | None = None,
                 last_event: np.ndarray | None = None) -> Toolpath:
    """The toolpath of the executed moves: a first point (the first move's end), then one
    row per move's end, or per piece of an arc within ``start.chord_tol_mm``.  A segment
    is ``known`` where ncopt plans it; ``warnings`` gets a located reason where not.

    ``pos_mm``, ``known`` (n, 3) the positions after each line and whether each axis is
    known; ``last_event`` (n,) the last line at or before each after which no position
    can be trusted (:func:`ncopt.motion.positions.positions`).
    """
    motion = modal.motion
    move_lines, is_arc = _move_lines(prog, lines, modal, executed, orient)
    end = np.take(pos_mm, move_lines, axis=0)  # take: rows 4x faster than pos_mm[...]
    end_known = known.all(axis=1)[move_lines]
    prev_pt, prev_known = _move_starts(end, end_known, move_lines, last_event)
    arcs = np.flatnonzero(is_arc[move_lines])
    counts, pieces = _arc_pieces(prog, lines, modal, move_lines, arcs, prev_pt, end,
                                 prev_known & end_known, start.chord_tol_mm)
    not_read = not_read_in_force(prog, lines, executed)
    computed_f = not_read.computed_f
    check_feed(prog, modal,
               move_lines[~computed_f[move_lines]] if computed_f.any() else move_lines)
    xyz, lengths, rows, one_each = _point_rows(end, row_norms(end - prev_pt), counts, pieces)
    rep = functools.partial(_repeat, counts=counts, one_each=one_each)
    feed_mm, g93, g93_ok = _feeds(lines, modal, move_lines, lengths, rows)
    seg_known = end_known & prev_known & g93_ok
    seg_known &= (modal.feed_mode[move_lines] != G95) & (modal.comp[move_lines] == 400)
    not_read_line = not_read.any_line()  # per line: one gather below
    if not_read_line.any():
        seg_known &= ~not_read_line[move_lines]
    if orient is not None:
        seg_known &= orient.blocked[move_lines] == 0
    feed_moves = mcode_is_feed(motion[move_lines])
    no_f = np.zeros(lines.n, dtype=bool)
    no_f[move_lines[~g93_ok]] = True
    _warn_unplanned(prog, move_lines[feed_moves], seg_known[feed_moves], modal, warnings, orient,
                    no_f, not_read)
    mcode = rep(np.nan_to_num(motion[move_lines], nan=-10) // 10, -1).astype(np.int8)
    return Toolpath(
        xyz_mm=xyz, line=rep(move_lines, -1).astype(np.int32), motion=mcode,
        feed_mm_min=rep(np.where(feed_moves, feed_mm, np.nan), np.nan),
        spindle_rpm=rep(modal.spindle_rpm[move_lines], 0.0),
        seg_len_mm=lengths, known=rep(seg_known, False),
        tool=rep(modal.tool[move_lines], -1).astype(np.int32),
        line_inch=modal.inch, spindle_on=rep(modal.spindle_on[move_lines], False),
        warnings=tuple(warnings), inverse_time=rep(g93, False) if g93.any() else None)


def mcode_is_feed(motion_x10: np.ndarray) -> np.ndarray:
    """Whether each motion code (G code x10) is a feed move: G1, G2, G3."""
    return np.isin(motion_x10, [10, 20, 30])


def _move_lines(prog, lines, modal, executed, orient) -> tuple[np.ndarray, np.ndarray]:
    """The executed lines that move the tool (0-based, in order), and (n,) bool the arcs."""
    motion = modal.motion
    axes_present = lines.present_any("XYZ")
    if orient is not None:  # a rotary-only move turns the tool: a move of its own
        axes_present = axes_present | orient.rotary_move
    arc_words = lines.present_any("IJKR")
    special = lines.has_g(G_NOT_A_TARGET) | lines.unread_g()
    is_lin = np.isin(motion, [0, 10]) & axes_present
    is_arc = np.isin(motion, [20, 30]) & (axes_present | arc_words)
    move = (is_lin | is_arc) & executed & ~special & (prog.line_kind == LineKind.WORDS)
    return np.flatnonzero(move), is_arc


def _move_starts(end, end_known, move_lines, last_event) -> tuple[np.ndarray, np.ndarray]:
    """Where each move starts (the last move's end; the first: the origin) and whether
    that is known."""
    prev_pt = np.vstack((np.zeros((1, 3)), end[:-1]))
    prev_known = np.concatenate(([False], end_known[:-1]))
    if last_event is not None and move_lines.size:
        # after a tool change, G28, a canned cycle, compensation... between two moves the
        # next one starts where ncopt does not know, even where it gives every axis again
        prev_line = np.concatenate(([-1], move_lines[:-1]))
        prev_known &= ~(last_event[move_lines] > prev_line)
    return prev_pt, prev_known


def _arc_pieces(prog, lines, modal, move_lines, arcs, prev_pt, end, both_known,
                tol_mm: float) -> tuple[np.ndarray, tuple]:
    """Points per move ((moves,) int64: 1, or an arc's pieces) and the pieces of the arcs
    whose both ends are known (``arcs``: the moves that are): (their moves (m,), points
    (sum, 3), lengths (sum,)), all arcs at once (:func:`ncopt.motion.arcs.arcs_points`)."""
    counts = np.ones(move_lines.shape[0], dtype=np.int64)
    cut = arcs[both_known[arcs]]
    n, pts, lengths = arcs_points(prog, lines, modal, move_lines[cut],  # take: rows, faster
                                  np.take(prev_pt, cut, axis=0), np.take(end, cut, axis=0),
                                  tol_mm)
    counts[cut] = n
    return counts, (cut, n, pts, lengths)


def _point_rows(end, seg_len, counts, pieces) -> tuple:
    """Every point: xyz (n_pts, 3) mm, segment lengths (n_pts,) mm, the first row of each
    move less one (moves + 1,), and whether each move is one point (no arc in pieces)."""
    n_pts = int(counts.sum()) + 1
    one_each = n_pts == end.shape[0] + 1  # no arc cut into pieces: nothing to repeat
    xyz = np.zeros((n_pts, 3))
    rows = np.concatenate(([0], np.cumsum(counts)))  # first row of each move, minus 1
    last_rows = slice(1, None) if one_each else rows[1:]  # each move's last point
    xyz[last_rows] = end
    lengths = np.zeros(n_pts)
    lengths[last_rows] = seg_len
    arc_moves, n, pts, piece_len = pieces
    if arc_moves.size and one_each:  # every arc one piece: its end, written above
        lengths[arc_moves + 1] = piece_len
    elif arc_moves.size:  # each arc's pieces in its rows
        first = np.concatenate(([0], np.cumsum(n)[:-1]))
        within = np.arange(pts.shape[0]) - np.repeat(first, n)
        at = np.repeat(rows[arc_moves] + 1, n) + within
        xyz[at] = pts
        lengths[at] = piece_len
    xyz[0] = end[0] if end.shape[0] else 0.0
    return xyz, lengths, rows, one_each


def _repeat(a: np.ndarray, first, counts: np.ndarray, one_each: bool) -> np.ndarray:
    """A value per move as a value per point: ``first`` at the first point, then each
    move's value on each of its points."""
    return np.concatenate(([first], a if one_each else np.repeat(a, counts)))


def _feeds(lines, modal, move_lines, lengths, rows) -> tuple:
    """Per move: the tip feed (mm/min, the programmed F in mm), (moves,) bool the
    inverse-time (G93) moves, and (moves,) bool whether the feed is known (a G93 block
    without its own F word is not)."""
    scale = np.where(modal.inch, MM_PER_INCH, 1.0)
    feed_mm = (modal.feed * scale)[move_lines]
    g93 = modal.feed_mode[move_lines] == G93
    g93_ok = np.ones(move_lines.shape[0], dtype=bool)
    if g93.any():  # the tip feed each F (1 / minutes) stands for, over the whole block
        block_len = np.add.reduceat(lengths[1:], rows[:-1])
        feed_mm, g93_ok = tip_feed_mm_min(modal.feed_mode[move_lines],
                                          lines.value("F")[move_lines], feed_mm, block_len)
    return feed_mm, g93, g93_ok


def _warn_unplanned(prog, move_lines, seg_known, modal, warnings, orient: Orientation | None,
                    no_f: np.ndarray, not_read: NotRead) -> None:
    """Append to ``warnings`` each stretch of feed moves not planned (the first 20),
    located, with the reason of its first line."""
    unknown = move_lines[~seg_known]
    if unknown.size == 0:
        return
    breaks = np.flatnonzero(np.diff(unknown) > 1)
    starts = np.concatenate(([unknown[0]], unknown[breaks + 1]))
    stops = np.concatenate((unknown[breaks], [unknown[-1]]))
    for a, b in list(zip(starts.tolist(), stops.tolist()))[:20]:
        why = "position not known"
        if not_read.mode[a]:
            why = G_MODES_NOT_READ[not_read.mode[a] - 1][2]
        elif not_read.scaled[a]:
            why = SCALED_WHY
        elif not_read.computed_s[a]:
            why = "the spindle speed is an assignment (S=...) ncopt does not evaluate"
        elif not_read.computed_f[a]:
            why = "the feed is an assignment (F=...) ncopt does not evaluate"
        elif orient is not None and orient.blocked[a]:
            why = orient.reasons[orient.blocked[a]]
        elif modal.feed_mode[a] == G95:
            why = "per-revolution feed (G95)"
        elif no_f[a]:
            why = "an inverse-time (G93) block without its own F word"
        elif modal.comp[a] != 400:
            why = "cutter radius compensation (G41/G42) active"
        warnings.append(f"{prog.path}:{a + 1}-{b + 1}: not planned ({why}); S/F left as programmed")
    if len(starts) > 20:
        warnings.append(f"{prog.path}: {len(starts) - 20} more stretches not planned")
