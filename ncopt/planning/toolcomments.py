"""One comment's text -> what it says about a cutter (a :class:`Fact`), per CAM system.

Read from the CAM systems' own post-processors and real programs:

==================  ====================================================================
Fusion 360 / HSM    ``(T1 D=8 CR=4 - ZMIN=-19.999 - ball end mill)``; drills add
                    ``TAPER=118DEG``.  Type names as Fusion's ``getToolTypeName``:
                    "radius mill" is a corner-rounding cutter, not a bull-nose.
OpenBuilds (Fusion) ``(  Tool #4: Flat End Mill 3 Flutes, Diam = 3mm, Len = 15.00mm)``
BlenderCAM          ``(Tool: D = 3.0 mm type END flutes 2)``, imperial ``D = 0.125''``;
                    types END, BALLNOSE, BULLNOSE (no corner radius written), VCARVE,
                    BALLCONE, CYLCONE, LASER, PLASMA, CUSTOM
FreeCAD             ``(Tool type: endmill)`` and ``(Compensated Tool Path. Diameter:
                    3.0)`` on separate lines, tool controller labels ``(TC: 5mm
                    Endmill)``; types endmill, ballend, bullnose, chamfer, v-bit, drill...
Carbide Create      ``(TOOL/MILL,0.7937,0.39687,1.000,0.0)``: diameter, corner radius,
                    flute height, taper (half) angle, in the program's units (the
                    fields as gcodepreview's ``settoolparameters`` names them; a 1/8"
                    ball is ``TOOL/MILL,3.17, 1.58, ...``, a V-bit has a taper angle)
Estlcam             ``(HSS, 2-Flute Endmill, 2mm)`` under ``(Required tools:)``
Mastercam           ``( 1/16 FLAT ENDMILL TOOL - 1 DIA. OFF. - 1 LEN. - 1 DIA. - .0625)``,
                    ``(T15|3'' FACE MILL|H15|D15|TOOL DIA. - 3.25)``, ``(T9|5/8 BALL
                    ENDMILL|H18)``: ``D15``/``H15`` are offset registers, never sizes
hyperMILL           ``T1579871377 | FRA-SP0140-G2R1 / DM=2 CR=1 TL=145`` (tool list)
SolidCAM            ``(TOOL 1   DIA 10.0000)`` (its generic Fanuc GPP), or the tool message
Vectric             ``( T1 = Ball Nose 3 mm )``, ``( T1 = End Mill 1/4" )`` (its tool names)
free text           ``( T1 = Ball Mill 4 mm )``, ``(T4 BALL D16 R8 z2)``, ``(TOOL DIA. 4)``
==================  ====================================================================

Nothing is guessed: a shape comes from a type word (ball, bull-nose, end mill,
drill...) or from an explicit corner radius (``CR=``, Carbide Create's field,
``.03 RAD``); a bare ``R8`` only confirms a ball or gives a named bull-nose its
radius (it may be the tool's radius).  A free text's size is its diameter only
where the text says so: a diameter key (``D=``, ``DIA``), a size no length word
qualifies (``1/4 BALL ENDMILL 1" FLUTE LENGTH`` is 1/4": flute length, LOC, shank,
overall length, stickout are never diameters), a bare number leading the cutter's
type (``6 BALL ENDMILL``); sizes that disagree give none.  A fraction (``5/8``) or
``"`` is inches; ``mm`` is millimetres; otherwise a size is in the program's units.  Teeth come
only from words that say so (``3 Flutes``, ``flutes 2``, ``2-Flute``, ``z2``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, fields
from functools import lru_cache

NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)"
_UNIT = r"\s*(mm\b|\"|''|in(?:ch(?:es)?)?\b)?"
_FRACTION = r"(?:(\d+)[- ])?(\d+)\s*/\s*(\d+)"

BALL, BULL, FLAT, OTHER, UNKNOWN = "ball", "bull-nose", "flat", "other", "unknown"
BULL_NO_RADIUS = "bull-nose (corner radius not given)"


@dataclass(frozen=True)
class Fact:
    """What one comment says about a cutter; None: it does not say.

    ``diameter`` and ``corner`` are in ``unit`` ("mm", "inch", or None: the
    program's units).  ``kind_word`` is the shape its words name (one of
    BALL, BULL, FLAT, OTHER; None: they name none); ``corner_explicit`` tells a
    corner radius key (``CR=``) from a bare ``R`` that might be the tool's
    radius.
    """

    number: int | None = None
    diameter: float | None = None
    unit: str | None = None
    corner: float | None = None
    corner_explicit: bool = False
    kind_word: str | None = None
    teeth: int | None = None
    tool_word: bool = False  # says "tool", "cutter", "mill" or "bit"
    source: str = "free text"

    def merged(self, other: "Fact") -> "Fact | None":
        """Both facts as one, or None where they contradict each other."""
        values = {}
        for f in fields(self):
            a, b = getattr(self, f.name), getattr(other, f.name)
            if f.name in ("tool_word", "corner_explicit"):
                values[f.name] = a or b
            elif f.name == "source":
                values[f.name] = a if a != "free text" else b
            elif a is not None and b is not None and a != b:
                return None
            else:
                values[f.name] = a if a is not None else b
        return Fact(**values)


@lru_cache(maxsize=4096)  # programs repeat their comments ("(Begin step 0.)")
def read_comment(text: str) -> Fact | None:
    """A Fact from one comment's text (without its parentheses), or None."""
    if not may_describe_a_tool(text):
        return None
    for reader in (_fusion, _openbuilds, _blendercam, _carbide, _mastercam, _hypermill,
                   _freecad):
        fact = reader(text)
        if fact is not None:
            return fact
    return _free_text(text)


_SIZE_HINTS = ("d", "mm", '"', "''", "/", "in", "\xd8", "tool type", "ball", "bull")


def may_describe_a_tool(text: str) -> bool:
    """A quick test every description passes (it names a size or a ball, or FreeCAD's
    tool type): most comments of a long program ("(pass 12)") go no further."""
    low = text.lower()
    return any(hint in low for hint in _SIZE_HINTS) and (any(c.isdigit() for c in low)
                                                         or "tool type" in low)


def _num(text: str | None) -> float | None:
    return None if text is None else float(text)


def _unit(mark: str | None) -> str | None:
    if not mark:
        return None
    return "mm" if mark.lower() == "mm" else "inch"


# ------------------------------------------------------------- CAM formats ----
_FUSION = re.compile(rf"^\s*T(\d+)\s+D=({NUM})\s+CR=({NUM})(?:\s+TAPER=({NUM})\s*DEG)?"
                     rf"[^)]*?-\s*([^-)]*?)\s*$", re.I)


def _fusion(text: str) -> Fact | None:
    m = _FUSION.match(text)
    if not m:
        return None
    kind = kind_of_words(m.group(5))
    if m.group(4) and float(m.group(4)) != 0 and kind in (BALL, BULL, FLAT):
        kind = OTHER  # a taper angle on a mill: a tapered cutter
    return Fact(int(m.group(1)), float(m.group(2)), None, float(m.group(3)), True, kind,
                source="Fusion 360")


_OPENBUILDS = re.compile(rf"Tool\s*(?:#\s*(\d+)|\(\s*(\d+)\s*\))?\s*:\s*(.*?)\s+(\d+)\s+Flutes,"
                         rf"\s*Diam\s*=\s*({NUM}){_UNIT}", re.I)


def _openbuilds(text: str) -> Fact | None:
    m = _OPENBUILDS.search(text)
    if not m:
        return None
    number = m.group(1) or m.group(2)
    return Fact(int(number) if number else None, float(m.group(5)), _unit(m.group(6)), None,
                False, kind_of_words(m.group(3)), int(m.group(4)), True,
                "OpenBuilds (Fusion 360)")


_BLENDERCAM = re.compile(rf"Tool(?:\s+change\s*-|\s*:)\s*D\s*=\s*({NUM}){_UNIT}\s*type\s+(\w+)"
                         rf"\s+flutes\s+(\d+)", re.I)
_BLENDERCAM_TYPES = {"END": FLAT, "BALLNOSE": BALL, "BULLNOSE": BULL}


def _blendercam(text: str) -> Fact | None:
    m = _BLENDERCAM.search(text)
    if not m:
        return None
    kind = _BLENDERCAM_TYPES.get(m.group(3).upper(), OTHER)
    return Fact(None, float(m.group(1)), _unit(m.group(2)), None, False, kind,
                int(m.group(4)), True, "BlenderCAM")


_CARBIDE = re.compile(rf"TOOL/MILL\s*,\s*({NUM})\s*,\s*({NUM})\s*,\s*({NUM})\s*,\s*({NUM})", re.I)


def _carbide(text: str) -> Fact | None:
    m = _CARBIDE.search(text)
    if not m:
        return None
    taper = float(m.group(4))
    return Fact(None, float(m.group(1)), None, float(m.group(2)), True,
                OTHER if taper != 0 else None, None, True, "Carbide Create")


_MC_PIPES = re.compile(r"^\s*T(\d+)\s*\|([^|]*)\|.*\bH\d+", re.I)
_MC_DASHES = re.compile(r"^(.*?)\bTOOL\s*-\s*(\d+)\b(.*)\bDIA\.\s*OFF\.", re.I)
_MC_DIAMETER = re.compile(rf"\bDIA\.\s*-\s*({NUM})")
_MC_CORNER = re.compile(rf"(?:CORNER\s+RAD\.?\s*-\s*|\bRAD(?:IUS)?\.?\s*-\s*)({NUM})|"
                        rf"({NUM})\s*(?:CORNER\s+)?RAD\b", re.I)


def _mastercam(text: str) -> Fact | None:
    m = _MC_PIPES.match(text)
    if m:
        number, name = int(m.group(1)), m.group(2)
    else:
        m = _MC_DASHES.search(text)
        if not m:
            return None
        number, name = int(m.group(2)), m.group(1) + m.group(3)
    size = _MC_DIAMETER.findall(text.upper())
    diameter, unit = (float(size[-1]), None) if size else _leading_size(name)
    corner = _MC_CORNER.search(name)
    cr = _num(corner.group(1) or corner.group(2)) if corner else None
    return Fact(number, diameter, unit, cr, cr is not None, kind_of_words(name),
                teeth_of(name), True, "Mastercam")


def _leading_size(name: str) -> tuple[float | None, str | None]:
    """A Mastercam tool name's size: ``5/8 BALL ENDMILL`` (inch), ``.25 SPOT``."""
    m = re.match(rf"\s*(?:{_FRACTION}|({NUM}))(\s*(?:\"|''|mm\b))?", name, re.I)
    if not m:
        return None, None
    if m.group(3):
        whole = float(m.group(1) or 0)
        return whole + float(m.group(2)) / float(m.group(3)), "inch"
    mark = (m.group(5) or "").strip()
    return float(m.group(4)), _unit(mark) if mark else None


_HYPERMILL = re.compile(rf"^\s*T(\d+)\s*\|.*?/\s*DM\s*=\s*({NUM})\s+CR\s*=\s*({NUM})", re.I)


def _hypermill(text: str) -> Fact | None:
    m = _HYPERMILL.match(text)
    if not m:
        return None
    return Fact(int(m.group(1)), float(m.group(2)), None, float(m.group(3)), True,
                kind_of_words(text), teeth_of(text), True, "hyperMILL")


_FREECAD_TYPE = re.compile(r"^\s*Tool\s+type\s*:\s*([\w -]+?)\s*$", re.I)
_FREECAD_DIAMETER = re.compile(rf"^\s*Compensated\s+Tool\s+Path\.\s*Diameter\s*:\s*({NUM})",
                               re.I)
# FreeCAD's ToolBit shape names and legacy tool types (Path.Tool.ToolType)
_FREECAD_TYPES = {"endmill": FLAT, "ballend": BALL, "ballendmill": BALL, "bullnose": BULL,
                  "torus": BULL, "cornerround": OTHER}


def _freecad(text: str) -> Fact | None:
    m = _FREECAD_TYPE.match(text)
    if m:
        name = re.sub(r"[\s_-]", "", m.group(1)).lower()
        kind = _FREECAD_TYPES.get(name) or kind_of_words(m.group(1)) or OTHER
        return Fact(kind_word=kind, tool_word=True, source="FreeCAD")
    m = _FREECAD_DIAMETER.match(text)
    if m:
        return Fact(diameter=float(m.group(1)), tool_word=True, source="FreeCAD")
    return None


# --------------------------------------------------------------- free text ----
_T_NUMBER = re.compile(r"\bT\s*=?\s*(\d+)\b|\bTOOL\s*(?:-|#|NO\.?|NR\.?|:|\()?\s*(\d+)\b(?!\s*mm)",
                       re.I)
_DIAMETER_KEYED = re.compile(rf"(?:\bD|\bDM|\bDIA(?:M(?:ETER)?)?\.?|\u00d8|\bDURCHMESSER)"
                             rf"\s*(?:=|:|-)?\s*({NUM}){_UNIT}", re.I)
_DIAMETER_BARE_D = re.compile(rf"\bD({NUM}){_UNIT}", re.I)
_DIAMETER_AFTER = re.compile(rf"(?<![\w./])({NUM}){_UNIT}\s*(?:dia(?:m(?:eter)?)?\b|\u00d8)", re.I)
# a size with its unit (``6mm``, ``1/4"``, ``0.5 in``) or a bare fraction (inch)
_SIZE = re.compile(rf"(?<![\w./])(?:{_FRACTION}(?![\w/])\s*(\"|''|in(?:ch(?:es)?)?\b)?|"
                   rf"({NUM})\s*(mm\b|\"|''|in(?:ch(?:es)?)?\b))", re.I)
# what makes a size a length, a radius or another value, not the diameter: the words
# after it (``3" flute length``, ``1" LOC``, ``8mm shank``) or before it (``shank 8mm``,
# ``Len = 15mm``, ``R 8 mm``, ``Z=6 mm``)
_NOT_DIAMETER_AFTER = re.compile(
    r"\s*(?:-\s*)?(?:flutes?\b|fl\b|flt\b|cut(?:ting)?\s*-?\s*(?:length|len|lg)\b|"
    r"length|len\b|lg\b|long\b|loc\b|l\.o\.c\b|shank|shk\b|overall|oal\b|o\.a\.l\b|"
    r"reach|stick\s*-?\s*out|neck|deep\b|depth|doc\b)", re.I)
_NOT_DIAMETER_BEFORE = re.compile(
    r"\b(?:length|len|lg|loc|l|shank|shk|overall|oal|reach|stick\s*-?\s*out|"
    r"neck|depth|doc|r|rad|radius|cr|corner|stepover|step|stepdown|stock|tol(?:erance)?|"
    r"[xyzijk]|zmin|zmax)\s*[.=:-]?\s*$", re.I)
# a bare number before the cutter's type names its diameter in the program's units:
# ``6 BALL ENDMILL``, ``T3 .5 carbide end mill`` (one word between, not a flute count)
_LEADING_SIZE = re.compile(
    rf"^\s*(?:T\s*\d+\b\s*[=:|-]?\s*)?({NUM})\s+"
    rf"(?:(?!(?:flutes?|fl|flt|teeth|z|x)\b)[a-z]+\s+)?(?:ball|bull|flat|square|end\s*-?\s*mill)",
    re.I)
_CORNER_KEYED = re.compile(rf"\b(?:CR|CORNER\s*RAD(?:IUS)?\.?)\s*(?:=|:|-)?\s*({NUM})|"
                           rf"({NUM})\s*RAD\b", re.I)
_CORNER_BARE = re.compile(rf"\bR\s*=?\s*({NUM})(?![\w.])", re.I)
_TOOL_WORD = re.compile(r"\b(?:tool|cutter|mill|bit|fr[a\xe4]ser|werkzeug)", re.I)


def _free_text(text: str) -> Fact | None:
    kind = kind_of_words(text)
    diameter, unit = _free_diameter(text, kind)
    teeth = teeth_of(text)
    t = _T_NUMBER.search(text)
    number = int(t.group(1) or t.group(2)) if t else None
    if diameter is None and kind is None:
        return None
    cr, explicit = None, False
    m = _CORNER_KEYED.search(text)
    if m:
        cr, explicit = float(m.group(1) or m.group(2)), True
    else:
        m = _CORNER_BARE.search(text)
        cr = float(m.group(1)) if m else None
    return Fact(number, diameter, unit, cr, explicit, kind, teeth,
                _TOOL_WORD.search(text) is not None)


def _free_diameter(text: str, kind: str | None) -> tuple[float | None, str | None]:
    """The diameter a free text gives, and its unit (None: the program's).

    Only where the text says so: a diameter key (``D=``, ``DIA``, ``Ø``...), or a
    size with its unit that is no length, radius or other keyed value (``1/4 BALL
    ENDMILL 1" FLUTE LENGTH``: 1/4", never 1"), or a bare number leading the
    cutter's type (``6 BALL ENDMILL``).  Sizes that disagree give none (``6mm BALL
    50mm``: which one?), except for a cutter ncopt does not plan, whose first size is
    only reported."""
    for rx in (_DIAMETER_KEYED, _DIAMETER_BARE_D, _DIAMETER_AFTER):
        m = rx.search(text)
        if m:
            return float(m.group(1)), _unit(m.group(2))
    sizes = [size for size in _sizes(text) if size is not None]
    m = _LEADING_SIZE.match(text)
    if m:
        sizes.insert(0, (float(m.group(1)), None))
    if not sizes:
        return None, None
    first = sizes[0]
    if kind == OTHER or all(_same_size(first, other) for other in sizes[1:]):
        return next((size for size in sizes if size[1] is not None), first)  # its unit
    return None, None


def _sizes(text: str):
    """(value, unit) of every size in the text that may be its diameter (None for one
    that is a length, a radius or another keyed value)."""
    for m in _SIZE.finditer(text):
        if (_NOT_DIAMETER_AFTER.match(text, m.end())
                or _NOT_DIAMETER_BEFORE.search(text, 0, m.start())):
            yield None
        elif m.group(2):
            den = float(m.group(3))
            yield (float(m.group(1) or 0) + float(m.group(2)) / den, "inch") if den else None
        elif m.group(2) is None and m.group(5):
            yield float(m.group(5)), _unit(m.group(6))


def _same_size(a: tuple, b: tuple) -> bool:
    """Two (value, unit) sizes name the same length (a unit-less one: the same number)."""
    if None in (a[1], b[1]):
        return abs(a[0] - b[0]) <= 1e-6 * max(abs(a[0]), 1.0)
    mm = [v * (25.4 if u == "inch" else 1.0) for v, u in (a, b)]
    return abs(mm[0] - mm[1]) <= 1e-3 * max(mm[0], 1e-9)


# ------------------------------------------------------------ shape, teeth ----
_OTHER_WORDS = re.compile(
    r"drill|chamfer|engrav|v-?\s?bit|\bvee\b|v-?\s?carve|\bspot|\btap\b|thread|face\s*mill|"
    r"shell\s*mill|slot\s*mill|slitting|dovetail|lollipop|taper|radius\s+mill|corner\s*round|"
    r"reamer|\bbor(?:e|ing)\b|counter\s*(?:sink|bore)|\bform\b|probe|laser|plasma|\bsaw\b|"
    r"keyseat|t-slot|cone|center\s*drill|centre\s*drill|deburr|knife|\bengraver\b|gravier",
    re.I)
_BALL_WORDS = re.compile(r"ball|spheric|sphere|kugel", re.I)
_BULL_WORDS = re.compile(r"bull|toroid|torus|corner\s*rad|radiused|eckenradius", re.I)
_FLAT_WORDS = re.compile(r"flat|end\s*-?\s*mill|square|upcut|downcut|compression|fishtail|"
                         r"schaftfr[a\xe4]ser|\bem(?=\d|\b)", re.I)


def kind_of_words(text: str) -> str | None:
    """The shape a tool's name says (BALL, BULL, FLAT, OTHER), or None."""
    for rx, kind in ((_OTHER_WORDS, OTHER), (_BALL_WORDS, BALL), (_BULL_WORDS, BULL),
                     (_FLAT_WORDS, FLAT)):
        if rx.search(text):
            return kind
    return None


_NUMBER_WORDS = {"one": 1, "single": 1, "two": 2, "double": 2, "three": 3, "four": 4,
                 "five": 5, "six": 6}
_TEETH_BEFORE = re.compile(r"\b(\d{1,2}|one|single|two|double|three|four|five|six)\s*-?\s*"
                           r"(?:flutes?|flt|fl|teeth|tooth|z[a\xe4]hne|schneiden)\b", re.I)
_TEETH_AFTER = re.compile(r"\b(?:flutes?|teeth|tooth|z)\s*[=:]?\s*(\d{1,2})\b"
                          r"(?![.\d]|\s*(?:mm|in|\"))", re.I)


def teeth_of(text: str) -> int | None:
    """The number of teeth a text states (``3 Flutes``, ``flutes 2``, ``z2``), or None."""
    m = _TEETH_BEFORE.search(text)
    word = m.group(1) if m else None
    if word is None:
        m = _TEETH_AFTER.search(text)
        word = m.group(1) if m else None
    if word is None:
        return None
    n = _NUMBER_WORDS.get(word.lower()) or int(word)
    return n if 1 <= n <= 24 else None


def shape(fact: Fact) -> tuple[str, float | None]:
    """(kind, corner radius in the fact's unit) of a fact with a diameter.

    See the module docstring: a type word names the shape; an explicit corner
    radius turns an end mill into a bull-nose or ball and gives an unnamed
    shape; where they contradict, or nothing says, the kind is UNKNOWN.
    """
    d, cr, kind = fact.diameter, fact.corner, fact.kind_word
    tol = max(1e-3 * d, 1e-9)
    if kind == OTHER:
        return OTHER, cr
    if cr is not None and (cr < 0 or cr > d / 2 + tol):
        return UNKNOWN, cr
    half = cr is not None and abs(2 * cr - d) <= 2 * tol
    if kind == BALL:
        return (BALL, d / 2) if cr is None or half else (UNKNOWN, cr)
    if kind == BULL:
        if cr is None:
            return BULL_NO_RADIUS, None
        return (BALL, d / 2) if half else ((BULL, cr) if cr > 0 else (UNKNOWN, cr))
    if fact.corner_explicit and cr is not None and kind in (FLAT, None):
        return (BALL, d / 2) if half else ((BULL, cr) if cr > 0 else (FLAT, 0.0))
    if kind == FLAT:
        return FLAT, 0.0
    return UNKNOWN, cr
