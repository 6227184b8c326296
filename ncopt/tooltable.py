"""Cutters read from the tool header comments that CAM posts write.

Recognised (case-insensitive), in a comment anywhere in the program:

* Fusion 360 / Autodesk posts: ``(T1 D=8 CR=4 - ZMIN=-19.999 - ball end mill)``
* Mastercam-style: ``(TOOL - 3 DIA. OFF. - 3 LEN. - 3 DIA. - 10.)`` plus a type word
* free text naming a T number, a diameter and a type: ``( T1 = Ball Mill 4 mm )``,
  ``(T4 BALL D16 R8)``, ``M6 T7 (TOOL DIA. 4)``

A tool is usable by ncopt when it is a ball or a bull-nose (corner radius
between 0 and D/2).  Flat end mills, drills, chamfer and engraving tools are
reported and their sections left untouched.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .model import Cutter, Program

BALL, BULL, FLAT, OTHER = "ball", "bull-nose", "flat", "other"
UNNUMBERED = -1  # "( Cutter is assumed to be a 10mm ball nose )": no T number given

_FUSION = re.compile(r"T(\d+)\s+D=([\d.]+)\s+CR=([\d.]+)[^)]*?-\s*([^-)]*?)\s*\)?$", re.I)
_T_NUMBER = re.compile(r"\bT\s*=?\s*(\d+)\b|\bTOOL\s*(?:-|#|NO\.?|:)?\s*(\d+)\b", re.I)
_DIAMETER = re.compile(r"(?:\bD\s*=?\s*|DIA(?:METER)?\.?\s*(?:-|=|:)?\s*)([\d]*\.?\d+)", re.I)
_DIAMETER_MM = re.compile(r"\b([\d]*\.?\d+)\s*mm\b", re.I)
_CORNER = re.compile(r"\b(?:CR|R|CORNER\s*RAD(?:IUS)?)\s*=?\s*([\d]*\.?\d+)", re.I)


@dataclass(frozen=True)
class ToolInfo:
    """One tool as the program's header describes it (lengths in program units)."""

    number: int
    kind: str
    diameter: float
    corner_radius: float
    line: int  # 1-based line of the comment
    text: str

    def cutter(self, teeth: int, scale_to_mm: float = 1.0, tool_point: str = "tip") -> Cutter:
        return Cutter(self.diameter * scale_to_mm, teeth, self.corner_radius * scale_to_mm,
                      tool_point)


def _kind(text: str, diameter: float, corner: float | None) -> str:
    low = text.lower()
    if any(w in low for w in ("drill", "chamfer", "engrav", "v-bit", "vee", "spot", "tap",
                               "thread", "face mill", "slot")):
        return OTHER
    if "ball" in low or "sphere" in low or (corner is not None and abs(2 * corner - diameter) < 1e-9):
        return BALL
    if any(w in low for w in ("bull", "toroid", "torus", "radius mill")) or (
            corner is not None and 0 < corner < diameter / 2):
        return BULL
    if corner == 0 or "flat" in low or "end mill" in low or "endmill" in low:
        return FLAT
    return OTHER


def parse_tool_comment(text: str, line: int) -> ToolInfo | None:
    """A ToolInfo from one comment's text, or None if it does not describe a tool."""
    m = _FUSION.search(text)
    if m:
        d, cr = float(m.group(2)), float(m.group(3))
        return ToolInfo(int(m.group(1)), _kind(m.group(4), d, cr), d, cr, line, text)
    t = _T_NUMBER.search(text)
    dm = _DIAMETER.search(text) or _DIAMETER_MM.search(text)
    if not dm:
        return None
    number = int(t.group(1) or t.group(2)) if t else UNNUMBERED
    d = float(dm.group(1))
    cm = _CORNER.search(text[dm.end():]) or _CORNER.search(text[:dm.start()])
    cr = float(cm.group(1)) if cm else None
    kind = _kind(text, d, cr)
    if cr is None:
        cr = d / 2 if kind == BALL else 0.0
    return ToolInfo(number, kind, d, cr, line, text)


_COMMENT = re.compile(r"\(([^()]*)\)|;(.*)$")


def tool_table(prog: Program) -> dict[int, ToolInfo]:
    """Tools described in the program's comments, by T number (first description wins)."""
    raw = np.frombuffer(prog.text.encode("latin-1"), dtype=np.uint8)
    marks = np.flatnonzero((raw == ord("(")) | (raw == ord(";")))
    lines = np.unique(np.searchsorted(prog.line_start, marks, side="right") - 1)
    table: dict[int, ToolInfo] = {}
    for line in lines.tolist():
        for c in _COMMENT.finditer(prog.line_text(line)):
            body = c.group(1) if c.group(1) is not None else c.group(2)
            if (body or "").lstrip().startswith("ncopt "):
                continue  # ncopt's own stamp: nominal data in mm, not a tool description
            info = parse_tool_comment(body or "", line + 1)
            if info is None or info.number in table:
                continue
            if info.number == UNNUMBERED and info.kind not in (BALL, BULL):
                continue  # "(Xcen=0 Ycen=0 Dia=10)" is not a tool
            table[info.number] = info
    return table


def cutter_for(table: dict[int, ToolInfo], tool: int, n_tools: int) -> ToolInfo | None:
    """The description of T``tool``; an unnumbered one serves a single-tool program."""
    if tool in table:
        return table[tool]
    if n_tools <= 1 and UNNUMBERED in table:
        return table[UNNUMBERED]
    return None
