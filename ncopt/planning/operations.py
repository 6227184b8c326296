"""Toolpath -> operations: which parts of the program ncopt plans, and why.

A program holds several operations (roughing, finishing, drilling, 2D contours...),
often with the same tool.  The contact-point method is the physics of *finishing*: the
cutter follows the surface and removes a thin layer, so it cuts near the contact
point.  Roughing with a ball (a pocket with 3 mm step-downs, adaptive clearing) cuts
with the whole side of the cutter, and a drill or a 2D contour is no surface at all:
raising S there breaks tools.  So every operation is classified, and only surface
finishing is planned; everything else is left exactly as programmed, with the reason.

Splitting: the operation comments CAM posts write (Fusion's ``(PARALLEL1)`` after a
blank line or before the tool call, FreeCAD's ``(Begin operation: ...)``, ...) and the
tool changes (:mod:`ncopt.planning.opnames` reads the names).  Each operation is cut
further into parts at its rapid moves, and the parts are classified from their geometry
first and their name second:

* a **3D surface finish**: the cut's Z changes along the passes (raster, scallop,
  spiral, flow...) and neighbouring passes lie within a finishing stepover;
* a **Z-level finish**: passes at constant Z, levels closely spaced (at most
  ``ZLEVEL_STEP_D`` of the diameter apart), each level a contour, not an area;
* left alone: roughing levels (constant-Z levels further apart), area clearing at a
  level (pocket, adaptive: the cutter sweeps an area), one Z level only (2D contour,
  facing, engraving, 2D pocket), isolated 3D passes with no neighbouring pass (pencil,
  trace), canned cycles (drilling), and parts whose name says roughing, drilling or 2D
  even where their geometry looks like finishing.

Geometry features are computed on samples about R/2 apart along the feed moves, with
the whole operation as context (so a one-way raster whose passes are separated by
rapids still sees its neighbouring passes): :mod:`ncopt.planning.opgeometry`.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass

import numpy as np

from ncopt.model import LineKind, Motion, Program, Toolpath
from ncopt.motion.modal import row_norms
from ncopt.planning.medians import weighted_median
from ncopt.planning.opgeometry import Levels, Samples, levels, neighbour_pass, retraced, samples
from ncopt.planning.opnames import operation_comments

FINISH_3D, FINISH_ZLEVEL = "3D surface finishing", "Z-level finishing"
ROUGH_LEVELS, CLEARING, TWO_D = "roughing levels", "area clearing", "2D contour"
ISOLATED, CANNED, NO_CUT, FLAT_TOOL = "isolated passes", "canned cycles", "no cut", "tool"
STAMPED, LEFT_BEFORE = "planned before (ncopt stamp)", "left before (ncopt stamp)"
UNPLACED = "moves ncopt cannot place"  # feed moves whose position or tool axis is unknown
PLANNED_KINDS = (FINISH_3D, FINISH_ZLEVEL)

SLOPED_SHARE = 0.2  # a part whose sloped share reaches this follows a 3D surface
NEIGHBOUR_D = 0.75  # a neighbouring pass within this many diameters: a finishing stepover
NEIGHBOUR_SHARE = 0.5
ZLEVEL_STEP_D = 0.15  # constant-Z levels at most this many diameters apart: finishing
INTERIOR_SHARE = 0.25  # a level whose cells are this often surrounded: an area is cleared
RETRACE_SHARE = 0.6
# moves slower than this share of the operation's typical feed are entries (ramps,
# plunges, lead-ins at a reduced feed), not its surface
SLOW_FEED = 0.6
MIN_PART_D = 20.0  # a part of an operation cuts at least this many diameters

# names that say what the geometry may not: roughing, holes, 2D, pencil/trace (a word
# of the name, digits around it allowed: POCKET4, 2D CONTOUR1; not SURFACE for FACE)
_LEFT_BY_NAME = re.compile(
    r"(?<![A-Z])(?:ADAPTIVE|POCKET|ROUGH\w*|CLEAR\w*|FACE|FACING|DRILL\w*|BORE|BORING|"
    r"CHAMFER|ENGRAV\w*|TRACE|SLOT\w*|THREAD\w*|TAP|TAPPING|REAM\w*|PROFILE|SPOT\w*|PENCIL|"
    r"HOLES?|CIRCULAR|DEBURR\w*|V-?CARVE\w*|SCHRUPP\w*|PLUNGE|2D)(?![A-Z])", re.I)
ROUGH_SHARE = 0.2  # an operation this much area clearing or roughing levels is roughing


@dataclass(frozen=True)
class Operation:
    """One operation (or one part of one) of the program.

    name : as the program names it (a comment), or ``T3`` where it names none
    tool : T number of its moves (-1: none)
    first_line, last_line : 0-based span of source lines (inclusive)
    kind : what it is (FINISH_3D, FINISH_ZLEVEL, ROUGH_LEVELS, ...)
    planned : ncopt plans its S and F
    reason : why it is planned or left alone, for the summary
    step_mm : typical distance between its constant-Z levels (NaN if none), mm
    stepover_mm : typical distance to the neighbouring pass (NaN if none), mm
    name_line : 1-based line of the comment that names it (None: no comment)
    """

    name: str
    tool: int
    first_line: int
    last_line: int
    kind: str
    planned: bool
    reason: str
    step_mm: float = float("nan")
    stepover_mm: float = float("nan")
    name_line: int | None = None

    @property
    def lines(self) -> str:
        return f"lines {self.first_line + 1}-{self.last_line + 1}"


# ------------------------------------------------------------------ splitting ----
@dataclass(frozen=True)
class Span:
    """Lines [first_line, last_line] of one operation, as the program delimits it."""

    first_line: int
    last_line: int
    name: str | None
    name_line: int | None


def spans(prog: Program, tp: Toolpath) -> list[Span]:
    """The operations as the program delimits them: by its operation comments and its
    tool changes; a start with no cut before the next start joins that next one."""
    ls = tp.lines
    names = operation_comments(prog)
    change = np.flatnonzero(np.diff(ls.tool) != 0) + 1
    starts = sorted(set(names) | set(change.tolist()) | {0})
    cuts = np.zeros(prog.n_lines + 1, dtype=np.int64)
    feed_lines = tp.line[1:][tp.motion[1:] >= Motion.LINEAR]
    cuts[feed_lines + 1] = 1
    cuts[np.flatnonzero(ls.canned & (prog.line_kind == LineKind.WORDS)) + 1] = 1
    cuts = np.cumsum(cuts)  # cuts[i]: cutting lines before line i
    out: list[Span] = []
    begin, name, name_line = 0, None, None
    for k, start in enumerate(starts):
        if start in names:
            name, name_line = names[start], start + 1
        end = starts[k + 1] if k + 1 < len(starts) else prog.n_lines
        if cuts[end] > cuts[begin] or end == prog.n_lines:
            out.append(Span(begin, end - 1, name, name_line))
            begin, name, name_line = end, None, None
    return out


# ------------------------------------------------------------- classification ----
@dataclass(frozen=True)
class _Part:
    first_point: int  # index into the operation's points
    kind: str
    step_mm: float
    stepover_mm: float
    why: str
    length_mm: float


def _kind_of(sm: Samples, sel: np.ndarray, nb: tuple, lv: Levels,
             diameter_mm: float) -> tuple[str, float, float, str]:
    """Kind of the samples ``sel`` of one part: (kind, step mm, stepover mm, why).

    ``nb``: (neighbour pass per sample, a callable giving the retraced samples): the
    retrace test (a k-d tree over every move of the operation) runs only for the
    constant-Z parts that get that far, not for a 3D surface finish."""
    w = sm.weight_mm[sel]
    total = float(w.sum())
    if total <= 0:
        return NO_CUT, np.nan, np.nan, "no feed move"
    nb, retraced = nb
    sloped = float(w[sm.sloped[sel]].sum()) / total
    if sloped >= SLOPED_SHARE:
        share = float(w[nb[sel]].sum()) / total
        if share < NEIGHBOUR_SHARE:
            return ISOLATED, np.nan, np.nan, (
                f"single 3D passes: only {100 * share:.0f} % of the cut has a neighbouring "
                f"pass within {NEIGHBOUR_D:g} D (pencil, trace or engraving: the cutter may "
                "touch along an arc, not at one point)")
        return FINISH_3D, np.nan, np.nan, f"Z follows the surface on {100 * sloped:.0f} % of the cut"
    flat = sel & ~sm.sloped
    wf = sm.weight_mm[flat]
    inner = float(wf[lv.interior[flat]].sum()) / max(float(wf.sum()), 1e-12)
    finite = np.isfinite(lv.step_mm[flat])
    above = float(wf[finite].sum()) / max(float(wf.sum()), 1e-12)
    step = weighted_median(lv.step_mm[flat][finite], wf[finite], in_order=False)
    if inner >= INTERIOR_SHARE:
        return CLEARING, step, np.nan, (
            f"constant-Z levels that sweep an area ({100 * inner:.0f} % of the cut inside the "
            "cleared area: pocket or adaptive clearing, the cutter cuts with its side)")
    if above < 0.2:
        return TWO_D, np.nan, np.nan, "one Z level (2D contour, facing, engraving or 2D pocket)"
    near = flat & nb
    retrace = (float(sm.weight_mm[near & retraced()].sum())
               / max(float(sm.weight_mm[near].sum()), 1e-12))
    if retrace >= RETRACE_SHARE:
        return TWO_D, step, np.nan, (
            f"the same contour at several depths {step:.3g} mm apart (vertical walls: a 2D "
            "contour or slot cut in depth passes, the cutter cuts with its side)")
    if step > ZLEVEL_STEP_D * diameter_mm:
        return ROUGH_LEVELS, step, np.nan, (
            f"constant-Z levels {step:.3g} mm apart (more than {ZLEVEL_STEP_D:g} D: roughing "
            "with step-downs, the cutter cuts with its side)")
    return FINISH_ZLEVEL, step, np.nan, f"constant-Z passes {step:.3g} mm apart"


def classify(prog: Program, tp: Toolpath, span: Span, diameters: dict) -> list[Operation]:
    """The parts of one operation (cut at its rapids, merged where alike), classified;
    ``diameters``: T number -> cutter diameter in mm (absent: not known)."""
    ls = tp.lines
    lo, hi = span.first_line, span.last_line
    p0, p1 = np.searchsorted(tp.line[1:], [lo, hi + 1]) + 1  # tp.line rises with the points
    pts = np.arange(p0, p1)
    feed = pts[(tp.motion[pts] >= Motion.LINEAR) & tp.known[pts]] if pts.size else pts
    tool = int(tp.tool[feed[0]]) if feed.size else int(ls.tool[hi])
    name = span.name or (f"T{tool}" if tool >= 0 else "the program")
    base = dict(name=name, tool=tool, name_line=span.name_line)
    canned = bool(ls.canned[lo:hi + 1].any())
    diameter_mm = diameters.get(tool)
    if feed.size == 0:
        kind = CANNED if canned else NO_CUT
        why = "drilling or another canned cycle" if canned else "no feed move"
        return [Operation(first_line=lo, last_line=hi, kind=kind, planned=False, reason=why, **base)]
    if diameter_mm is None:
        return [Operation(first_line=lo, last_line=hi, kind=FLAT_TOOL, planned=False,
                          reason="its cutter is not one ncopt plans", **base)]
    parts = _parts(tp, pts, feed, diameter_mm)
    return _operations(tp, span, parts, pts, base, canned)


def _parts(tp: Toolpath, pts: np.ndarray, feed: np.ndarray, diameter_mm: float) -> list[_Part]:
    """Cut the operation's points (``pts``: consecutive) at each rapid that follows a cut;
    classify each chunk with the whole operation as context; merge neighbours of the
    same kind.  Geometry comes from the moves near the typical feed (a helical ramp at a
    reduced feed is no surface; an ncopt output, whose F follows S, keeps most of its
    moves)."""
    is_feed = np.zeros(pts.shape, dtype=bool)
    is_feed[feed - pts[0]] = True  # pts: consecutive points; feed: some of them
    cf = np.cumsum(is_feed)
    r = np.flatnonzero(tp.motion[pts] == Motion.RAPID)
    prev = np.concatenate(([0], cf[r[:-1]])) if r.size else r
    starts = r[(cf[r] - prev) > 0] if r.size else r
    d = np.take(tp.xyz_mm, feed, axis=0) - np.take(tp.xyz_mm, feed - 1, axis=0)
    plunge = np.abs(d[:, 2]) > 0.9 * np.maximum(row_norms(d), 1e-12)
    f = tp.feed_mm_min[feed]
    typical = weighted_median(f[~plunge], tp.seg_len_mm[feed][~plunge],  # plunges aside
                              in_order=False)
    at_feed = f >= SLOW_FEED * typical
    geo = feed[~plunge & at_feed]
    if geo.size == 0:
        return [_Part(0, NO_CUT, np.nan, np.nan, "no cut at the cutting feed", 0.0)]
    radius = 0.5 * diameter_mm
    sm = samples(tp, geo, 0.5 * radius)
    nb = (neighbour_pass(sm, NEIGHBOUR_D * diameter_mm),
          functools.cache(lambda: retraced(tp, geo, sm, NEIGHBOUR_D * diameter_mm)))
    lv = levels(sm, max(0.5 * radius, 0.05))
    chunk_of_sample = np.searchsorted(starts, sm.point - pts[0], side="right")
    groups = _groups(starts, chunk_of_sample, sm.weight_mm, MIN_PART_D * diameter_mm)
    parts: list[_Part] = []
    said_mm: list[float] = []  # length of the piece whose reason each part gives
    for first_chunk, last_chunk in groups:
        sel = (chunk_of_sample >= first_chunk) & (chunk_of_sample <= last_chunk)
        first = 0 if first_chunk == 0 else int(starts[first_chunk - 1])
        length = float(sm.weight_mm[sel].sum())
        kind, step, stepover, why = _kind_of(sm, sel, nb, lv, diameter_mm) if sel.any() else (
            NO_CUT, np.nan, np.nan, "no feed move")
        if parts and (kind == parts[-1].kind or kind == NO_CUT):
            last = parts[-1]
            said = last if said_mm[-1] >= length or kind == NO_CUT else _Part(
                0, kind, step, stepover, why, 0.0)  # the longest piece says why
            said_mm[-1] = max(said_mm[-1], length)
            parts[-1] = _Part(last.first_point, last.kind, said.step_mm, said.stepover_mm,
                              said.why, last.length_mm + length)
            continue  # the same kind goes on (a chunk without a cut joins the one before)
        if parts and parts[-1].kind == NO_CUT:
            parts[-1] = _Part(parts[-1].first_point, kind, step, stepover, why, length)
            said_mm[-1] = length
            continue
        parts.append(_Part(first, kind, step, stepover, why, length))
        said_mm.append(length)
    return parts


def _groups(starts, chunk_of_sample, weight, min_mm: float) -> list[tuple[int, int]]:
    """Consecutive chunks (between rapids) joined until each group cuts ``min_mm`` at
    least: a few short moves between two rapids are judged with their neighbours, not
    alone (a part of 8 lines is no operation)."""
    n = starts.size + 1
    length = np.bincount(chunk_of_sample, weights=weight, minlength=n)[:n]
    groups, begin, acc = [], 0, 0.0
    for c in range(n):
        acc += float(length[c])
        if acc >= min_mm:
            groups.append((begin, c))
            begin, acc = c + 1, 0.0
    if begin < n:
        if groups:
            groups[-1] = (groups[-1][0], n - 1)
        else:
            groups.append((begin, n - 1))
    return groups


def _operations(tp, span, parts, pts, base, canned) -> list[Operation]:
    """Operations from the classified parts of one span.

    An operation that is largely roughing (``ROUGH_SHARE`` of its cut) is left whole:
    its contour passes at each level cut the pocket's wall with the side of the cutter,
    even where their spacing alone would pass for a Z-level finish.  An operation left
    whole is one entry, named by its main kind."""
    total = sum(p.length_mm for p in parts) or 1.0
    rough = sum(p.length_mm for p in parts if p.kind in (CLEARING, ROUGH_LEVELS)) / total
    named = _LEFT_BY_NAME.search(base["name"]) if base["name_line"] else None
    main = max(parts, key=lambda p: p.length_mm)
    keep = [p.kind in PLANNED_KINDS for p in parts]
    if any(keep) and rough >= ROUGH_SHARE:
        why = (f"{100 * rough:.0f} % of it is roughing (area clearing or constant-Z levels "
               "with step-downs): the cutter cuts with its side")
        kind = max((p for p in parts if p.kind in (CLEARING, ROUGH_LEVELS)),
                   key=lambda p: p.length_mm).kind
        return [_whole(span, main, base, why, kind)]
    if any(keep) and named:
        kinds = " and ".join(sorted({p.kind.lower() for p, k in zip(parts, keep) if k}))
        why = (f"named '{base['name']}' ({named.group(0).lower()}), although its geometry "
               f"looks like {kinds}")
        return [_whole(span, main, base, why, _named_kind(named.group(0)))]
    if not any(keep):
        return [_whole(span, main, base, main.why)]
    out = []
    for k, part in enumerate(parts):
        first = span.first_line if k == 0 else int(tp.line[pts[part.first_point]])
        last = (span.last_line if k + 1 == len(parts)
                else int(tp.line[pts[parts[k + 1].first_point]]) - 1)
        name = base["name"] if len(parts) == 1 else f"{base['name']} (part {k + 1})"
        out.append(Operation(name=name, tool=base["tool"], first_line=first, last_line=last,
                             kind=part.kind, planned=keep[k], reason=part.why,
                             step_mm=part.step_mm, stepover_mm=part.stepover_mm,
                             name_line=base["name_line"]))
    return out


def _named_kind(word: str) -> str:
    """What an operation named with ``word`` is."""
    w = word.upper()
    if w.startswith(("DRILL", "BOR", "TAP", "REAM", "SPOT", "HOLE", "THREAD")):
        return CANNED if w.startswith(("DRILL", "TAP", "REAM", "SPOT")) else CLEARING
    if w.startswith(("ADAPTIVE", "POCKET", "ROUGH", "CLEAR", "SCHRUPP", "CIRCULAR", "PLUNGE")):
        return CLEARING
    if w == "PENCIL":
        return ISOLATED
    return TWO_D


def _whole(span: Span, main: _Part, base: dict, why: str, kind: str | None = None) -> Operation:
    return Operation(name=base["name"], tool=base["tool"], first_line=span.first_line,
                     last_line=span.last_line, kind=kind or main.kind, planned=False, reason=why,
                     step_mm=main.step_mm, stepover_mm=main.stepover_mm,
                     name_line=base["name_line"])


def find(prog: Program, tp: Toolpath, diameters: dict) -> list[Operation]:
    """Every operation of the program, classified, in program order."""
    out: list[Operation] = []
    if prog.n_lines == 0:
        return out
    for span in spans(prog, tp):
        out += classify(prog, tp, span, diameters)
    return out
