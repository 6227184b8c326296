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
tool changes.  Each operation is cut further into parts at its rapid moves, and the
parts are classified from their geometry first and their name second:

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
rapids still sees its neighbouring passes).
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass

import numpy as np

from ncopt.motion.modal import row_norms
from ncopt.contacts.kdtree import cKDTree
from ncopt.model import Cutter, LineKind, Motion, Program, Toolpath
from ncopt.planning.toolcomments import read_comment

FINISH_3D, FINISH_ZLEVEL = "3D surface finishing", "Z-level finishing"
ROUGH_LEVELS, CLEARING, TWO_D = "roughing levels", "area clearing", "2D contour"
ISOLATED, CANNED, NO_CUT, FLAT_TOOL = "isolated passes", "canned cycles", "no cut", "tool"
STAMPED, LEFT_BEFORE = "planned before (ncopt stamp)", "left before (ncopt stamp)"
UNPLACED = "moves ncopt cannot place"  # feed moves whose position or tool axis is unknown
PLANNED_KINDS = (FINISH_3D, FINISH_ZLEVEL)

SLOPE = 0.03  # |dz|/ds above which a move is sloped (1.7 deg)
SLOPED_SHARE = 0.2  # a part whose sloped share reaches this follows a 3D surface
NEIGHBOUR_D = 0.75  # a neighbouring pass within this many diameters: a finishing stepover
NEIGHBOUR_SHARE = 0.5
ZLEVEL_STEP_D = 0.15  # constant-Z levels at most this many diameters apart: finishing
INTERIOR_SHARE = 0.25  # a level whose cells are this often surrounded: an area is cleared
MAX_SAMPLES = 60000
RETRACE_SAMPLES = 15000  # samples judged for vertical walls (each looks at 48 moves)
OTHER_PASS_RATIO = 3.0  # path distance > ratio * straight distance: another pass
VERTICAL = 0.98  # the nearest other pass this close to straight above: a retraced contour
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


# ------------------------------------------------------------------ comments ----
_FREECAD = re.compile(r"^\s*\(\s*Begin operation:\s*(.*?)\s*\)\s*$", re.I)
_ESTLCAM = re.compile(r"^\s*\(\s*No\.\s*\d+\s*:\s*(.*?)\s*\)\s*$", re.I)
# ``( OPERATION=  ROUGH7  Z LEVEL  SRF_MILL1  )`` (the LinuxCNC 5-axis demos' post)
_OPERATION_IS = re.compile(r"^\s*\(\s*OPERATION\s*=\s*([^()]*?)\s*\)\s*$", re.I)
# a keyed name: hyperMILL's ``*   - JOB: 68: FreePar12_...`` (``;`` or ``( )`` in its
# G-code posts), ``; Operation: CAVITY_MILL``, ``(TOOLPATH NAME: Finish)``
_KEYED = re.compile(r"^[\s*-]*(?:OPERATION(?:\s+NAME)?|OP\s*NAME|TOOLPATH(?:\s+NAME)?|JOB)"
                    r"\s*:\s*(?:\d+\s*:\s*)?(\S.*?)\s*$", re.I)
_COMMENT_ONLY = re.compile(r"^\s*(?:N[0-9.]+\s*)?\(\s*([^()]*?)\s*\)\s*$|^\s*;\s*(.*?)\s*$")
_DASHES = re.compile(r"^\s*\(\s*[-=*]{4,}\s*\)\s*$|^\s*;\s*-*\s*-{4,}\s*$")
_NOT_AN_OPERATION = re.compile(
    r"^(?:T\d+\b.*D\s*=|TOOL\b|MSG|ncopt\b|Begin\b|Finish\b|Path:|Block-|Exported|Post Processor|"
    r"Output Time|End\b|Required tools|Machining time|Created by|Project\b|FILENAME|Tool\b)",
    re.I)
_WORDS_ONLY = re.compile(r"^(?:[A-Z]\s*[-+]?\d+(?:\.\d*)?\s*)+$", re.I)  # "( M6 T2 )": code
# a sentence, not a name: it ends with a stop or a comma, holds "word, word" or "key: value",
# or runs over six words (Fusion's notices: "(When using Fusion for Personal Use, the
# feedrate of rapid)", "(Aviso: uso personal...)", "(Using high feed G1 F5000. instead of G0.)")
_SENTENCE = re.compile(r"[.,;:!?]\s*$|\w,\s|\w:\s|(?:\S+\s+){6}\S|personal\s+use|uso\s+personal|"
                       r"subscription|suscripci", re.I)


def operation_comments(prog: Program) -> dict[int, str]:
    """0-based line -> operation name, for the comments that start an operation.

    A name is a comment-only line in the forms CAM systems write (FreeCAD's ``Begin
    operation:``, Estlcam's ``No. 1:``, ``OPERATION=``, keyed ``JOB:`` names), or a short
    comment that is no sentence and no tool description: the first such one of a block of
    comment lines that opens after a blank line or a tool call, or that a tool call
    follows, or that notices or a tool's description open (Fusion writes a blank line,
    its notices, the name, the tool call); one framed by dashes; the last line before a
    tool call."""
    found: dict[int, str] = {}
    block: list[tuple[int, str | None, bool]] = []  # consecutive comment-only lines
    raw = np.frombuffer(prog.text.encode("latin-1"), dtype=np.uint8)
    marks = np.flatnonzero((raw == ord("(")) | (raw == ord(";")))
    comment_only = _comment_only_lines(prog)
    for i in np.unique(np.searchsorted(prog.line_start, marks, side="right") - 1).tolist():
        if i >= prog.n_lines or not comment_only[i]:
            continue
        if block and block[-1][0] != i - 1:
            _block_names(prog, block, found)
            block = []
        line = prog.line_text(i)
        direct = _named(line)
        if direct:
            found[i] = direct
            block.append((i, None, False))
        else:
            block.append((i, *_name_or_notice(line)))
    if block:
        _block_names(prog, block, found)
    return found


def _named(line: str) -> str | None:
    """The name a comment line gives in a CAM system's own form, or None."""
    m = _FREECAD.match(line) or _ESTLCAM.match(line)
    if m:
        return m.group(1) or None
    m = _OPERATION_IS.match(line)
    if m and m.group(1):
        return " ".join(m.group(1).split())
    m = _KEYED.match(_body(line))
    return m.group(1) if m and len(m.group(1)) <= 80 else None


def _body(line: str) -> str:
    """The text of a comment-only line, without its parentheses or semicolon."""
    m = _COMMENT_ONLY.match(line)
    return ((m.group(1) if m.group(1) is not None else m.group(2)) or "").strip() if m else ""


def _name_or_notice(line: str) -> tuple[str | None, bool]:
    """(the comment's text if it may name an operation (short, no sentence, no tool),
    whether it is a notice or a tool's description, which a name may follow)."""
    name = _body(line)
    if not name or _DASHES.match(line) or _WORDS_ONLY.match(name):
        return None, False
    fact = read_comment(name)
    tool = _NOT_AN_OPERATION.match(name) is not None or (fact is not None
                                                          and fact.diameter is not None)
    if tool or _SENTENCE.search(name):  # "(1/4 BALL ENDMILL)", "(3mm Endmill001)": no name
        return None, True
    return (None if len(name) > 48 or "=" in name else name), False


def _block_names(prog: Program, block: list, found: dict) -> None:
    """Mark the names of one block of consecutive comment-only lines."""
    first, last = block[0][0], block[-1][0]
    names = [(i, name) for i, name, _ in block if name]
    if not names:
        return
    before_call = _before_tool_call(prog, last)
    after_notices = names[0][0] > first and all(
        notice for i, _, notice in block if i < names[0][0])  # Fusion's notices, then the name
    if (_after_blank(prog, first) or _after_tool_call(prog, first) or before_call
            or after_notices):
        found.setdefault(*names[0])
    for i, name in names:
        if _framed(prog, i):
            found.setdefault(i, name)
    if before_call and names[-1][0] == last:
        found.setdefault(*names[-1])  # the line before the tool call names what follows


def _comment_only_lines(prog: Program) -> np.ndarray:
    """(n_lines,) bool: the line holds a comment (or nothing) and no word but a block
    number; for every line at once (one search of the word table per comment line cost
    3 ms at 1M blocks: 14 s for a program with a comment every 200 lines)."""
    other = np.zeros(prog.n_lines, dtype=bool)
    other[prog.word_line[prog.word_letter != ord("N")]] = True
    kind = prog.line_kind
    return (kind == LineKind.BLANK) | ((kind == LineKind.WORDS) & ~other)


def _framed(prog: Program, i: int) -> bool:
    """Between dashed comment lines (CAMWorks / SolidWorks CAM)."""
    return 0 < i < prog.n_lines - 1 and bool(_DASHES.match(prog.line_text(i - 1)))


def _after_blank(prog: Program, i: int) -> bool:
    return i > 0 and not prog.line_text(i - 1).strip()


_TOOL_CALL = re.compile(r"^\s*(?:N[0-9.]+\s*)?(?:T\s*\d+\s*M0?6|M0?6\s*T\s*\d+|T\s*\d+)\b", re.I)


def _after_tool_call(prog: Program, i: int) -> bool:
    return i > 0 and bool(_TOOL_CALL.match(prog.line_text(i - 1)))


def _before_tool_call(prog: Program, i: int) -> bool:
    for j in range(i + 1, min(i + 3, prog.n_lines)):
        text = prog.line_text(j)
        if text.strip():
            return bool(_TOOL_CALL.match(text))
    return False


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


# ------------------------------------------------------------------- geometry ----
@dataclass(frozen=True)
class _Samples:
    """Points about R/2 apart along one operation's feed moves, (m,) arrays."""

    xyz: np.ndarray  # (m, 3) mm
    s_mm: np.ndarray  # path length along the operation's feed moves
    weight_mm: np.ndarray  # path length each sample stands for
    sloped: np.ndarray
    point: np.ndarray  # toolpath point whose move the sample is on


def _samples(tp: Toolpath, points: np.ndarray, spacing_mm: float) -> _Samples:
    """Samples ``spacing_mm`` apart along the moves ending at ``points`` (indices into the
    toolpath), taken one after the other; at most ``MAX_SAMPLES`` (the spacing grows for
    long operations), so a million blocks cost no more than a few thousand.

    5 axes: with one tilted tool axis over them (3+2) the moves are seen in a frame whose
    Z is that axis (levels and slopes along the tool); where the axis turns (simultaneous
    5-axis) a move with the tool tilted follows the surface, whatever its tip's Z."""
    a, b = np.take(tp.xyz_mm, points - 1, axis=0), np.take(tp.xyz_mm, points, axis=0)
    turning = np.zeros(points.shape, dtype=bool)
    frame = _tool_frame(tp, points)
    if frame is not None:
        a, b = a @ frame.T, b @ frame.T
    elif tp.tool_axis is not None and points.size:
        turning = np.any(np.abs(tp.tool_axis[points][:, :2]) > 1e-9, axis=1)
    d = b - a
    length = row_norms(d)
    cum = np.concatenate(([0.0], np.cumsum(length)))
    total = float(cum[-1])
    spacing = max(spacing_mm, total / MAX_SAMPLES, 1e-3)
    s = (np.arange(max(int(total / spacing), 1)) + 0.5) * spacing
    s = s[s < total] if total > 0 else np.zeros(0)
    seg = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, max(points.size - 1, 0))
    frac = (s - cum[seg]) / np.maximum(length[seg], 1e-12)
    xyz = a[seg] + d[seg] * frac[:, None]
    sloped = (np.abs(d[:, 2]) > SLOPE * np.maximum(length, 1e-12)) | turning
    weight = np.full(s.shape, spacing)
    return _Samples(xyz, s, weight, sloped[seg], points[seg])


def _tool_frame(tp: Toolpath, points: np.ndarray) -> np.ndarray | None:
    """The rotation into the frame whose Z is the one tool axis of the moves ending at
    ``points`` (3+2), None for +Z or a turning axis."""
    if tp.tool_axis is None or not points.size:
        return None
    e = tp.tool_axis[points]
    if not np.allclose(e, e[0], atol=1e-9) or np.allclose(e[0], (0.0, 0.0, 1.0), atol=1e-9):
        return None
    return _to_axis(e[0])


def _to_axis(e: np.ndarray) -> np.ndarray:
    """A rotation taking the unit vector ``e`` to +Z (the identity for +Z)."""
    z = np.array([0.0, 0.0, 1.0])
    v, c = np.cross(e, z), float(np.dot(e, z))
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + k + k @ k / (1.0 + c)


def _neighbour_pass(sm: _Samples, radius_mm: float) -> np.ndarray:
    """(m,) bool: another pass runs within ``radius_mm`` of the sample."""
    m = sm.xyz.shape[0]
    if m < 2:
        return np.zeros(m, dtype=bool)
    k = min(12, m)
    dist, j = cKDTree(sm.xyz).query(sm.xyz, k=k, distance_upper_bound=radius_mm, workers=-1)
    ok = np.isfinite(dist)
    j = np.where(ok, j, 0)
    other = ok & (np.abs(sm.s_mm[j] - sm.s_mm[:, None]) > OTHER_PASS_RATIO * np.maximum(dist, 1e-9))
    return other.any(axis=1)


def _retraced(tp: Toolpath, geo: np.ndarray, sm: _Samples, radius_mm: float) -> np.ndarray:
    """(m,) bool, for the constant-Z samples: the nearest point of another pass lies
    straight above or below them (the same contour retraced at another depth: a vertical
    wall).  The nearest point on the other pass's moves, not its nearest sample: a CAM
    writes each level with its own points."""
    out = np.zeros(sm.xyz.shape[0], dtype=bool)
    flat = np.flatnonzero(~sm.sloped)
    if flat.size == 0 or geo.size < 2:
        return out
    a, b = np.take(tp.xyz_mm, geo - 1, axis=0), np.take(tp.xyz_mm, geo, axis=0)
    frame = _tool_frame(tp, geo)  # 3+2: the samples are in the tool's frame, so the moves too
    if frame is not None:
        a, b = a @ frame.T, b @ frame.T
    length = row_norms(b - a)
    s_end = np.cumsum(length)
    stride = max(1, -(-flat.size // RETRACE_SAMPLES))  # every stride-th sample judged
    idx = flat[::stride]
    _, vertical = _other_pass(cKDTree(b), a, b, length, s_end, sm, idx,
                              min(24, geo.size), radius_mm)  # a dense contour: own points first
    out[flat] = vertical[np.arange(flat.size) // stride]  # its neighbours along the path alike
    return out


def _other_pass(tree, a, b, length, s_end, sm: _Samples, idx: np.ndarray, k: int,
                radius_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """For the samples ``idx``: is another pass within ``radius_mm`` among the moves at
    the ``k`` nearest points, and is the nearest such one straight above or below."""
    q = sm.xyz[idx]
    _, j = tree.query(q, k=k, workers=-1)
    j = j.reshape(idx.size, -1)
    seg = np.concatenate((j, np.minimum(j + 1, b.shape[0] - 1)), axis=1)  # both moves at a point
    sa, sb = a[seg], b[seg]
    d = sb - sa
    t = np.clip(np.einsum("mkc,mkc->mk", q[:, None, :] - sa, d) /
                np.maximum(np.einsum("mkc,mkc->mk", d, d), 1e-24), 0.0, 1.0)
    off = sa + d * t[..., None] - q[:, None, :]
    dist = np.linalg.norm(off, axis=2)
    s_c = s_end[seg] - length[seg] * (1.0 - t)
    other = (dist <= radius_mm) & (np.abs(s_c - sm.s_mm[idx][:, None]) >
                                   OTHER_PASS_RATIO * np.maximum(dist, 1e-9))
    best = np.argmin(np.where(other, dist, np.inf), axis=1)
    rows = np.arange(idx.size)
    near = off[rows, best]
    found = other[rows, best]
    return found, found & (np.abs(near[:, 2]) > VERTICAL * np.maximum(dist[rows, best], 1e-12))


@dataclass(frozen=True)
class _Levels:
    """Per sample at constant Z: is its grid cell surrounded at its level, and how far
    up is the next level over the same cell (inf: none)."""

    interior: np.ndarray
    step_mm: np.ndarray


def _levels(sm: _Samples, cell_mm: float) -> _Levels:
    flat = ~sm.sloped
    m = sm.xyz.shape[0]
    interior, step = np.zeros(m, dtype=bool), np.full(m, np.inf)
    if not flat.any():
        return _Levels(interior, step)
    z = np.round(sm.xyz[flat, 2] / 0.002).astype(np.int64)
    cx = np.floor(sm.xyz[flat, 0] / cell_mm).astype(np.int64)
    cy = np.floor(sm.xyz[flat, 1] / cell_mm).astype(np.int64)
    cx -= cx.min() - 1
    cy -= cy.min() - 1
    zl = z - z.min()
    w = int(cy.max()) + 2
    h = int(cx.max()) + 2
    cell = cx * w + cy
    key = zl * (h * w) + cell
    uniq = np.unique(key)
    near = [uniq + dk for dk in (w, -w, 1, -1)]
    inner = np.logical_and.reduce([np.isin(k, uniq) for k in near])
    interior[flat] = inner[np.searchsorted(uniq, key)]
    # the next level up over the same cell: the next (cell, level) pair in sorted order
    top = int(zl.max()) + 1
    pairs, inv = np.unique(cell * top + zl, return_inverse=True)
    p_cell, p_z = pairs // top, pairs % top
    nxt = np.full(pairs.size, np.inf)
    nxt[:-1] = np.where(p_cell[1:] == p_cell[:-1], (p_z[1:] - p_z[:-1]) * 0.002, np.inf)
    step[flat] = nxt[inv.ravel()]
    return _Levels(interior, step)


# ------------------------------------------------------------- classification ----
@dataclass(frozen=True)
class _Part:
    first_point: int  # index into the operation's points
    kind: str
    step_mm: float
    stepover_mm: float
    why: str
    length_mm: float


def _weighted_median(x: np.ndarray, w: np.ndarray) -> float:
    if x.size == 0 or w.sum() <= 0:
        return float("nan")
    order = np.argsort(x)
    cum = np.cumsum(w[order])
    return float(x[order][np.searchsorted(cum, 0.5 * cum[-1])])


def _kind_of(sm: _Samples, sel: np.ndarray, nb: tuple, lv: _Levels,
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
    step = _weighted_median(lv.step_mm[flat][finite], wf[finite])
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


def cutting_feed(tp: Toolpath, feed: np.ndarray) -> float:
    """The operation's cutting feed: the F that most of its feed-move length runs at
    (mm/min); ramps, plunges and lead-ins usually run at others."""
    f = np.round(tp.feed_mm_min[feed], 3)
    values, inv = np.unique(f, return_inverse=True)
    length = np.bincount(inv.ravel(), weights=tp.seg_len_mm[feed], minlength=values.size)
    return float(values[int(np.argmax(length))])


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
    typical = _weighted_median(f[~plunge], tp.seg_len_mm[feed][~plunge])  # plunges aside
    at_feed = f >= SLOW_FEED * typical
    geo = feed[~plunge & at_feed]
    if geo.size == 0:
        return [_Part(0, NO_CUT, np.nan, np.nan, "no cut at the cutting feed", 0.0)]
    radius = 0.5 * diameter_mm
    sm = _samples(tp, geo, 0.5 * radius)
    nb = (_neighbour_pass(sm, NEIGHBOUR_D * diameter_mm),
          functools.cache(lambda: _retraced(tp, geo, sm, NEIGHBOUR_D * diameter_mm)))
    lv = _levels(sm, max(0.5 * radius, 0.05))
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
