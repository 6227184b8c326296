"""Odd but valid options, judged (issue 28): every rewrite that exits 0 is replayed by
ncopt's own simulate, on the same machine and against the original's targets, and held to
what the rewrite promises.

Random small programs (``tests/programs.py``: surfaces in mm and inch, stay-down or in
passes with plunges, CR LF or LF, N words or none; strips of the sample bowl with its mesh
or without, tip or centre programmed) are rewritten on the command line with random
option sets, every value in range, some extreme: ``--accel`` 5 to 20000, ``--max-rpm``
3000 to 40000, ``--min-rpm`` up to 95 % of it, ``--max-feed``, ``--fz-band`` 0.5 to 49,
``--min-rpm-step`` 1 to 3000, ``--vc``/``--fz``, ``--tool-point``, ``--planner``,
``--s-changes``, ``--fz-policy``, ``--operations`` (all, the program's, another).  A run
exits 0, or refuses with a located message (exit 5 nothing to plan, or options that
cannot go together, named), no file written.  An output of exit 0 (:func:`judge`):

* every byte but S and F words is the input's, and the stamp's lines are all it adds;
* no S written lies outside the machine's range (S0 stops the spindle);
* vc runs above its target (beyond ``VC_SLACK_PCT``) only where a warning says so, and by
  no more than it states;
* fz stays within its band on the moves at the cutting feed but on the lines the summary
  lists as lagging (``lag_lines``) or leaves as programmed; off that feed and on plunges
  at most the program's own feed per tooth;
* a second rewrite with the same options changes nothing.

The bugs this found (S0 written, falls that ran on into a cut, a feed cap below
--min-rpm, F words too coarse for the band, the stamp renaming an operation, a second
rewrite changing S and F, vc excess understated) are fixed; each is kept as its smallest
case, judged in full (:data:`FIXED`).
Last, G93: an inverse-time move without its own F word is refused at its line, as
LinuxCNC refuses it.
"""

from __future__ import annotations

import json
import math
import re
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from typer.testing import CliRunner

from conftest import load_module
from judge import RS274, canon
from ncopt.cli.app import Exit, app
from ncopt.contacts.geometry import MeshIndex, load_stl
from ncopt.model import CuttingData
from ncopt.motion import modal
from ncopt.planning.job import job_from_values
from ncopt.reading import refuse
from ncopt.simulate.replay import simulate_program
from ncopt.simulate.spindle import LAG_RPM
from programs import MM_PER_INCH, SURFACES, bowl_strip, dome, surface

pytestmark = pytest.mark.judge  # simulate judges every output: the judge tier

make_bowl = load_module("samples/make_bowl.py", "make_bowl_for_judged_options")
#: two passes of the bowl's finish, 8 mm apart (neighbours for the D16)
BOWL2 = bowl_strip(make_bowl.drop_ball_tip_z_mm, (44.0, 52.0), 3.0)

TEETH = 2
#: vc may run this far above its target where no warning says so (percent): S words are
#: integers written at or below the planned speed, but simulate finds the contact on its own
#: samples (every 0.1 mm), the planner on the block ends and where R_eff curves
#: (docs/method.md, "Contacts with a mesh"): between them R_eff may differ a little
VC_SLACK_PCT = 0.5
#: a hair of slack at the fz band's edge (relative, and absolute in the deviation): the
#: planner holds fz at the very edge by design (F rounded to its resolution is counted in
#: the band), and simulate reaches the same figure by another sum
FZ_SLACK = 1e-3
STAMP = re.compile(r"^\s*[(;]\s*ncopt ")
# S and F words of a block, outside its comments (what a rewrite may change); a word
# ncopt appends comes with the separator the post uses
SF_WORD = re.compile(r"\s?[SsFf]\s*[-+]?(?:\d+\.?\d*|\.\d+)")


# ------------------------------------------------------------------------ cases ----
@dataclass(frozen=True)
class Case:
    """A program and the options of one rewrite of it."""

    name: str
    text: bytes
    s_rpm: float  # the program's own S and F (mm/min) at the cutting feed
    f_mm_min: float
    diameter_mm: float
    options: dict = field(default_factory=dict)  # CLI option -> value (str)
    mesh: bool = False
    inch: bool = False

    def args(self, program: Path, mesh: Path | None) -> list[str]:
        out = ["rewrite", str(program), "--diameter", f"{self.diameter_mm:g}",
               "--teeth", str(TEETH), "--json"]
        for option, value in self.options.items():
            out += [option, value]
        if self.mesh:
            out += ["--mesh", str(mesh)]
        return out


@st.composite
def programs(draw, center: bool = False):
    """(name, bytes, S, F mm/min, diameter mm, mesh?, inch?) of a small program;
    ``center``: it moves the ball's centre (``--tool-point center``)."""
    inch = draw(st.booleans())
    crlf = draw(st.integers(0, 4)) == 0
    if draw(st.booleans()):  # a strip of the sample bowl: D16, S1393 F279
        # one pass alone has no neighbour: planned only with --operations all
        ys = draw(st.sampled_from([(44.0,), (44.0, 52.0), (44.0, 52.0), (40.0, 48.0, 56.0)]))
        text = bowl_strip(make_bowl.drop_ball_tip_z_mm, ys, 3.0, inch=inch, crlf=crlf,
                          center=center)
        f = 279.0 if not inch else round(279.0 / MM_PER_INCH, 2) * MM_PER_INCH
        mesh = draw(st.integers(0, 2)) > 0
        return f"bowl{len(ys)}", text, 1393.0, f, 16.0, mesh, inch
    shape = draw(st.sampled_from(sorted(SURFACES)))
    n = draw(st.integers(6, 9))  # passes 4 mm apart or less: neighbours for a D6
    lifts = draw(st.booleans())
    s = draw(st.sampled_from([2000, 4000, 9000]))
    f = float(draw(st.sampled_from([300, 800, 2400])))
    plunge = draw(st.sampled_from([None, f / 2])) if lifts else None
    text = surface(shape, n, inch=inch, lifts=lifts, crlf=crlf, numbered=draw(st.booleans()),
                   s_rpm=s, f_mm_min=f, plunge_mm_min=plunge)
    if inch:
        f = round(f / MM_PER_INCH, 1) * MM_PER_INCH
    return f"{shape}{n}{'-lifts' if lifts else ''}", text, float(s), f, 6.0, False, inch


#: option -> values drawn (None: not given); all in range, some extreme
OPTIONS = {
    "--accel": ["227", "131", "751", "5", "20000"],
    "--max-rpm": ["15000", "8000", "40000", "3000"],
    "--max-feed": [None, None, "inf", "5000", "600", "50"],
    "--fz-band": [None, None, "0.5", "5", "20", "49"],
    "--min-rpm-step": [None, None, "1", "100", "2000", "3000"],
    "--tool-point": [None, "tip", "center"],
    "--planner": [None, "lookahead", "forward"],
    "--s-changes": [None, "anywhere", "between-passes"],
    "--fz-policy": [None, "centred", "below"],
    "--operations": [None, None, "all", "TOOL", "T9"],  # TOOL: the program's operation
}


@st.composite
def cases(draw):
    """A program (:func:`programs`) and an option set for it, every value in range."""
    point = draw(st.sampled_from(OPTIONS["--tool-point"]))
    name, text, s, f, d, mesh, inch = draw(programs(center=point == "center"))
    options = {} if point is None else {"--tool-point": point}
    for option, values in OPTIONS.items():
        if option == "--tool-point":
            continue
        value = draw(st.sampled_from(values))
        if value is not None:
            options[option] = value
    if options.get("--operations") == "TOOL":  # the program's one operation, by its name
        options["--operations"] = "T4" if name.startswith("bowl") else "T1"
    # the lowest speed: below the highest, sometimes above what the cut needs
    share = draw(st.sampled_from([None, None, 0.0, 0.05, 0.3, 0.6, 0.95]))
    if share is not None:
        options["--min-rpm"] = f"{share * float(options['--max-rpm']):g}"
    if draw(st.integers(0, 3)) == 0:
        options["--vc"] = draw(st.sampled_from(["30", "80", "250"]))
        options["--fz"] = draw(st.sampled_from(["0.02", "0.1", "0.3"]))
    return Case(name, text, s, f, d, options, mesh, inch)


# ------------------------------------------------------------------------ judge ----
def invoke(args: list[str]):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100"})
    result = runner.invoke(app, args, catch_exceptions=False)
    assert "Traceback" not in result.stderr
    return result


def code_part(line: str) -> tuple[str, str]:
    """A line's words and its comments: ``(G1 X1 F100, (rough) ; note)``, split at the
    first ``(`` or ``;`` (the generated programs have no parentheses in expressions)."""
    m = re.search(r"[(;]", line)
    return (line, "") if m is None else (line[:m.start()], line[m.start():])


def masked(line: str) -> str:
    code, comment = code_part(line)
    return SF_WORD.sub("", code) + comment


def stamp_block(before: bytes, after: bytes) -> tuple[int, int]:
    """Where the stamp's lines sit in ``after`` (first 0-based line, count), checking that
    every other line is the input's but for S and F words, byte for byte (line ends and
    comments included)."""
    a = before.decode("latin-1").splitlines(keepends=True)
    b = after.decode("latin-1").splitlines(keepends=True)
    k = len(b) - len(a)
    assert k >= 0, "the rewrite has fewer lines than its input"
    at = next((i for i in range(len(a)) if masked(a[i]) != masked(b[i])), len(a))
    assert all(STAMP.match(line) for line in b[at:at + k]), \
        f"line {at + 1} of the rewrite is not the input's: {b[at]!r} for {a[at:at + 1]!r}"
    for i, (x, y) in enumerate(zip(a[at:], b[at + k:]), at + 1):
        assert masked(x) == masked(y), f"input line {i} changed beyond S and F: {x!r} -> {y!r}"
    return at, k


RANGES = re.compile(r"\(lines? ([\d\-, ]+?)(?: and (\d+) more)?[;)]")


def listed(warning: str) -> tuple[set[int], int | None]:
    """The 1-based lines a warning lists (``lines 5-9, 12``), and where a list cut short
    (``and 3 more``) begins: from there on any line may be one not shown (else None)."""
    lines, open_from = set(), None
    for r in RANGES.finditer(warning):
        firsts = []
        for part in r[1].split(","):
            lo, _, hi = part.strip().partition("-")
            lines.update(range(int(lo), int(hi or lo) + 1))
            firsts.append(int(lo))
        if r[2]:
            open_from = min(firsts) if open_from is None else min(open_from, *firsts)
    return lines, open_from


def located(warning: str, path: str) -> tuple[int, int] | None:
    """The lines a warning starts with (``path:12:`` or ``path:12-40:``), or None."""
    m = re.match(re.escape(path) + r":(\d+)(?:-(\d+))?:", warning)
    return None if m is None else (int(m[1]), int(m[2] or m[1]))


@dataclass
class Excuses:
    """What the rewrite's summary says of the lines it could not hold to its targets, by
    the kind of each warning (a warning of a kind not known here excuses nothing):

    * ``not planned (...)``: the lines of its range keep the program's S and F;
    * ``keep their S and F`` (F words too coarse): from its line on, the lines whose S and
      F in force are the input's;
    * ``need less than the machine's lowest speed``: vc above its target on the lines it
      lists, by at most the excess it states;
    * ``still falling from an S that ncopt could not plan``: vc above its target by at
      most the excess it states (it names no lines);
    * the spindle check's ``lag_lines``: fz out of its band there.
    """

    kept: set = field(default_factory=set)  # lines left as programmed
    kept_from: int | None = None  # from here on, lines whose S and F are the input's
    vc_lines: set = field(default_factory=set)
    vc_open_from: int | None = None
    vc_anywhere: bool = False
    vc_stated_pct: list = field(default_factory=list)  # the excess each warning states
    lag: set = field(default_factory=set)
    unknown: list = field(default_factory=list)

    @classmethod
    def of(cls, summary: dict, path: str, to_input=lambda n: n) -> "Excuses":
        """The excuses of a summary whose lines ``to_input`` turns into the input's."""
        ex = cls(lag={to_input(n) for n in summary["lag_lines"]})
        for w in summary["warnings"]:
            where = located(w, path)
            where = where and (to_input(where[0]), to_input(where[1]))
            lines, open_from = listed(w)
            lines = {to_input(n) for n in lines}
            open_from = open_from and to_input(open_from)
            stated = [float(x) for x in re.findall(r"vc up to \+?([\d.]+) %", w)]
            if "not planned (" in w and where:
                ex.kept.update(range(where[0], where[1] + 1))
            elif "keep their S and F" in w and where:
                ex.kept_from = min(where[0], ex.kept_from or where[0])
            elif "need less than the machine's lowest speed" in w:
                ex.vc_lines |= lines
                if open_from is not None:
                    ex.vc_open_from = min(open_from, ex.vc_open_from or open_from)
                ex.vc_stated_pct += stated
            elif "still falling from an S that ncopt could not plan" in w:
                ex.vc_anywhere = True
                ex.vc_stated_pct += stated
            elif not any(k in w for k in QUIET_WARNINGS):
                ex.unknown.append(w)
        return ex

    def vc_excess_pct(self) -> float:
        """The most vc may run above its target where excused, percent: the largest excess
        a warning states."""
        return max(self.vc_stated_pct, default=0.0)


#: warnings that excuse nothing: they promise vc at or below its target and fz in band
#: where they speak of (the contact planned at the full diameter), or vc below it (S
#: above the machine's), or fz at the program's own feed per tooth off the cutting feed
QUIET_WARNINGS = ("runs where the toolpath cannot show the contact",
                  "runs below the top of the cut where the mesh has no part",
                  "is above the machine's", "off the cutting feed",
                  "the spindle cannot follow the S words")


def words_in_force(text: bytes, letter: str) -> np.ndarray:
    """(n_lines + 1,) the value of the S or F word in force after each 1-based line of a
    program (index 0: before any), as written (program units)."""
    word = re.compile(letter + r"\s*([-+]?(?:\d+\.?\d*|\.\d+))", re.I)
    lines = text.decode("latin-1").splitlines()
    out = np.full(len(lines) + 1, np.nan)
    value = math.nan
    for i, line in enumerate(lines, 1):
        m = word.search(code_part(line)[0])
        if m:
            value = float(m[1])
        out[i] = value
    return out


@dataclass
class Verdict:
    """What the judge found on one exit-0 rewrite (empty lists: within its promises):
    (input line, percent off the target) of the first samples outside them."""

    vc: list = field(default_factory=list)
    # (line, percent, a pass's start or a ramp, an F too coarse for the band)
    fz: list = field(default_factory=list)
    s: list = field(default_factory=list)  # (line, S) written outside the machine's range
    report: object = None

    @property
    def ok(self) -> bool:
        return not (self.vc or self.fz or self.s)


def simulation_job(case: Case):
    """The job simulate replays the rewrite with: the rewrite's machine and cutter, and the
    original's targets (``--vc``/``--fz``, else its own S and F at the nominal diameter)."""
    values = {"diameter": case.diameter_mm, "teeth": TEETH}
    names = {"--accel": "accel", "--max-rpm": "max_rpm", "--min-rpm": "min_rpm",
             "--max-feed": "max_feed", "--tool-point": "tool_point"}
    for option, key in names.items():
        if option in case.options:
            value = case.options[option]
            values[key] = value if key == "tool_point" else float(value)
    job = job_from_values(**values)
    if "--vc" in case.options:
        cut = CuttingData(float(case.options["--vc"]), float(case.options["--fz"]))
    else:
        cut = CuttingData(math.pi * case.diameter_mm * case.s_rpm / 1000.0,
                          case.f_mm_min / (TEETH * case.s_rpm))
    return replace(job, cutting=cut)


def judge(case: Case, before: bytes, after: bytes, summary: dict, path: str,
          mesh_index: MeshIndex | None) -> Verdict:
    """Replay the rewrite with simulate (same machine, the original's targets) and list
    what is outside the promises: S words outside the machine's range, vc above target,
    fz out of band (the summary numbers its lines as ``before``)."""
    at, k = stamp_block(before, after)
    job = simulation_job(case)
    cut = job.cutting
    band = float(case.options.get("--fz-band", 2.0)) / 100.0
    report, series = simulate_program(after.decode("latin-1"), job, mesh_index, path=path,
                                      band=band)
    verdict = Verdict(report=report, s=s_out_of_range(case, before, after, at, k))
    ex = Excuses.of(summary, path)
    assert not ex.unknown, f"a warning of a kind the judge does not know: {ex.unknown}"
    line = np.where(series.line > at + k, series.line - k, series.line)  # input lines
    n = len(before.decode("latin-1").splitlines()) + 1
    # lines left as programmed: S and F in force are the input's
    same = np.ones(n, dtype=bool)
    for letter in "SF":
        a = words_in_force(before, letter)
        b = np.delete(words_in_force(after, letter), np.arange(at + 1, at + k + 1))
        same &= (a == b) | (np.isnan(a) & np.isnan(b))
    kept = np.isin(np.arange(n), list(ex.kept))
    if ex.kept_from is not None:
        kept |= same & (np.arange(n) >= ex.kept_from)
    c = series.cutting & ~kept[line]
    # vc: above its target only where a warning says so, and never above what it says
    vc_dev = 100.0 * (series.vc_m_min / cut.vc_m_min - 1.0)
    vc_ok = np.isin(line, list(ex.vc_lines)) | ex.vc_anywhere
    if ex.vc_open_from is not None:
        vc_ok |= line >= ex.vc_open_from
    limit = 100.0 * ((1.0 + ex.vc_excess_pct() / 100.0) * (1.0 + VC_SLACK_PCT / 100.0) - 1.0)
    over = c & (vc_dev > VC_SLACK_PCT) & ~(vc_ok & (vc_dev <= limit))
    verdict.vc = [(int(line[i]), round(float(vc_dev[i]), 2)) for i in np.flatnonzero(over)[:5]]
    # fz: within its band on the moves at the cutting feed, but on the lines the summary
    # lists as lagging; off it, and on a plunge (whose F is never raised), at most the
    # program's own feed per tooth (docs/guide.md, "The CAM's feed intent is kept")
    unit = MM_PER_INCH if case.inch else 1.0
    f_in = words_in_force(before, "F")[line] * unit
    own = f_in / (TEETH * words_in_force(before, "S")[line])
    at_feed = np.abs(f_in / case.f_mm_min - 1.0) < 1e-3
    plunge = np.isin(line, plunges(before))
    fz_dev = series.fz_mm / cut.fz_mm - 1.0
    tol = band * (1.0 + FZ_SLACK) + FZ_SLACK
    held = (np.abs(fz_dev) <= tol) | np.isin(line, list(ex.lag))
    own_kept = series.fz_mm <= own * (1.0 + tol)
    out = c & np.where(at_feed & ~plunge, ~held, ~own_kept)
    # the first moves of a pass, and the lines along which the spindle ramps toward the S
    # commanded somewhere (simulate's own lag threshold)
    ramping = np.zeros(n, dtype=bool)
    ramping[list(pass_starts(before))] = True
    ramping[line[np.abs(series.s_rpm - series.s_cmd_rpm) > LAG_RPM]] = True
    # the lines whose F word (rounded to the resolution of the input's F words) cannot
    # hold fz within its band
    f_out = np.delete(words_in_force(after, "F"), np.arange(at + 1, at + k + 1)) * unit
    coarse = f_resolution(before) * unit / f_out > band
    verdict.fz = [(int(line[i]), round(100.0 * float(fz_dev[i]), 2), bool(ramping[line[i]]),
                   bool(coarse[line[i]])) for i in np.flatnonzero(out)[:5]]
    return verdict


def f_resolution(text: bytes) -> float:
    """The resolution of a program's F words, in its units per minute: 1 for ``F279``,
    0.01 for ``F10.98``."""
    found = re.findall(r"F\s*\d*(?:\.(\d*))?", "\n".join(
        code_part(line)[0] for line in text.decode("latin-1").splitlines()), re.I)
    return 10.0 ** -max((len(d) for d in found), default=0)


def s_out_of_range(case: Case, before: bytes, after: bytes, at: int, k: int) -> list:
    """(input line, S) of the S words the rewrite wrote outside the machine's range (never
    0: with M3 in force, S0 stops the spindle)."""
    low = max(float(case.options.get("--min-rpm", 0)), 1.0)
    high = float(case.options["--max-rpm"])
    word = re.compile(r"S\s*([-+]?\d+\.?\d*)", re.I)
    a = before.decode("latin-1").splitlines()
    b = after.decode("latin-1").splitlines()
    b = b[:at] + b[at + k:]
    own = words_in_force(before, "S")  # a stretch left as programmed gets its own S back
    out = []
    for i, (x, y) in enumerate(zip(a, b), 1):
        was = word.findall(code_part(x)[0])
        for value in word.findall(code_part(y)[0]):
            if value not in was and float(value) not in (own[i], own[i - 1]) \
                    and not low - 0.5 <= float(value) <= high + 0.5:
                out.append((i, float(value)))
    return out


def pass_starts(text: bytes) -> set[int]:
    """The first two feed moves across X or Y after each stretch off the cut (1-based)."""
    off = off_the_cut(text)
    n = len(text.splitlines())
    return {i for i in range(1, n + 1) if i not in off and (i - 1 in off or i - 2 in off)}


def plunges(text: bytes) -> list[int]:
    """The 1-based lines of a generated program that move along Z alone."""
    out, xy = [], None
    for i, line in enumerate(text.decode("latin-1").splitlines(), 1):
        words = dict(re.findall(r"([XYZ])([-+]?[\d.]+)", code_part(line)[0]))
        if not words:
            continue
        new = (words.get("X", xy[0] if xy else None), words.get("Y", xy[1] if xy else None))
        if new == xy and "Z" in words:
            out.append(i)
        xy = new
    return out


def check(case: Case, mesh_path: Path | None, mesh_index: MeshIndex | None) -> Verdict | None:
    """Rewrite ``case`` on the command line; if it exits 0, judge the output and rewrite it
    again with the same options: fail on anything outside the promises.  Returns the
    verdict (None: the run exited 5, nothing to plan)."""
    with tempfile.TemporaryDirectory(prefix="judged") as folder:
        work = Path(folder)
        program = work / ("prog.ngc" if case.inch else "prog.nc")
        program.write_bytes(case.text)
        out = work / "out.nc"
        result = invoke(case.args(program, mesh_path) + ["-o", str(out)])
        assert program.read_bytes() == case.text
        if result.exit_code in (Exit.PLANNING, Exit.USAGE):  # nothing to plan, or options
            assert not out.exists()  # in range that cannot go together, named
            assert result.stderr.startswith(f"{program}: ") and (
                "nothing to plan: " in result.stderr or " --" in result.stderr), result.stderr
            return None
        assert result.exit_code == Exit.OK, result.stderr
        after = out.read_bytes()
        summary = json.loads(result.stderr)
        verdict = held_to_promises(case, after, summary, program, mesh_index)
        again = work / "again.nc"
        second = invoke(case.args(out, mesh_path) + ["-o", str(again)])
        assert second.exit_code == Exit.OK, second.stderr
        changed = changed_lines(after, again.read_bytes())
        assert not changed, f"a second rewrite with the same options changed lines {changed}"
        return verdict


def held_to_promises(case: Case, after: bytes, summary: dict, path: Path,
                     mesh_index: MeshIndex | None) -> Verdict:
    """Judge one output (:func:`judge`) and fail on what it finds."""
    verdict = judge(case, case.text, after, summary, str(path),
                    mesh_index if case.mesh else None)
    assert not verdict.s, f"S words outside the machine's range: {verdict.s}"
    assert not verdict.vc, f"vc above its target beyond what the warnings say: {verdict.vc}"
    assert not verdict.fz, f"fz out of its band, not named: {verdict.fz}"
    return verdict


def changed_lines(a: bytes, b: bytes) -> list[int]:
    """The 1-based lines that differ between two programs of as many lines (all of them
    where their numbers of lines differ)."""
    x, y = a.splitlines(), b.splitlines()
    if len(x) != len(y):
        return list(range(1, max(len(x), len(y)) + 1))
    return [i for i, (p, q) in enumerate(zip(x, y), 1) if p != q]


def off_the_cut(text: bytes) -> set[int]:
    """The 1-based lines of a generated program (or its rewrite) that are no feed move
    across X or Y: set-up, spindle start, rapids, approaches and plunges along Z."""
    out, xy, feed = set(), None, False
    for i, line in enumerate(text.decode("latin-1").splitlines(), 1):
        code = code_part(line)[0]
        g = re.findall(r"G0*([01])(?!\d)", code)
        feed = g[-1] == "1" if g else feed
        words = dict(re.findall(r"([XYZ])([-+]?[\d.]+)", code))
        new = (words.get("X", xy[0] if xy else None), words.get("Y", xy[1] if xy else None))
        if not (feed and xy is not None and new != xy):
            out.add(i)
        xy = new if words else xy
    return out


@pytest.fixture(scope="session")
def coarse_bowl(tmp_path_factory):
    """A 2 mm grid of the bowl (quick to load for each run), and its index."""
    V, F = make_bowl.bowl_mesh(2.0)
    path = tmp_path_factory.mktemp("mesh") / "bowl_2mm.stl"
    make_bowl.write_stl(path, V, F)
    return path, MeshIndex(load_stl(path))


# --------------------------------------------------------------- the property ----
@given(case=cases())  # the "ncopt" profile of conftest.py: derandomized, 40 examples
@example(case=Case("bowl2", BOWL2, 1393.0, 279.0, 16.0, {"--accel": "227",
                                                        "--max-rpm": "15000"}, mesh=True))
@example(case=Case("bowl3", bowl_strip(make_bowl.drop_ball_tip_z_mm, (40.0, 48.0, 56.0), 3.0,
                                       inch=True, center=True), 1393.0,
                   round(279.0 / MM_PER_INCH, 2) * MM_PER_INCH, 16.0,
                   {"--accel": "131", "--max-rpm": "8000", "--tool-point": "center",
                    "--s-changes": "between-passes", "--fz-band": "5"}, mesh=True, inch=True))
@example(case=Case("bowl2", BOWL2, 1393.0, 279.0, 16.0,
                   {"--accel": "751", "--max-rpm": "40000", "--planner": "forward",
                    "--min-rpm": "1000", "--max-feed": "600"}, mesh=True))
def test_every_rewrite_that_exits_0_is_within_its_promises(coarse_bowl, case):
    """Odd but valid options on small programs: exit 0 only with an output simulate finds
    within what the rewrite promised (vc, fz, bytes, a second rewrite changing nothing);
    else exit 5, nothing to plan, and no file."""
    check(case, *coarse_bowl)


def test_the_judge_sees_a_rewrite_break_its_promises(coarse_bowl):
    """The judge is no rubber stamp: a rewrite whose S words were raised by 10 % after the
    fact runs vc 10 % above its target where no warning says so."""
    case = Case("dome6", surface("dome", 6), 4000.0, 800.0, 6.0,
                {"--accel": "227", "--max-rpm": "15000"})
    with tempfile.TemporaryDirectory(prefix="judged") as folder:
        program = Path(folder) / "prog.nc"
        program.write_bytes(case.text)
        result = invoke(case.args(program, None))
        assert result.exit_code == Exit.OK
        raised = re.sub(rb"S(\d+)", lambda m: b"S%d" % round(int(m[1]) * 1.1),
                        result.stdout_bytes)
        verdict = judge(case, case.text, raised, json.loads(result.stderr), str(program),
                        None)
    assert verdict.vc and max(dev for _, dev in verdict.vc) > 5.0
    assert verdict.fz  # F no longer follows S: fz 9 % low


# --------------------------------------------------- the bugs it found, fixed ----
SPINDLE = {"--accel": "227", "--max-rpm": "15000"}
#: cases it found that hold now, judged in full: id -> (what was wrong, the case)
FIXED = {
    "feed cap below min-rpm": (
        "--max-feed / (fz z) below --min-rpm: S planned at --min-rpm and F at --max-feed, fz "
        "-37.5 % on the whole cut, exit 0, no warning (now the operation is left, naming "
        "both; alone in its program: exit 5)",
        Case("dome6", surface("dome", 6), 4000.0, 800.0, 6.0,
             {**SPINDLE, "--max-feed": "600", "--min-rpm": "4800"})),
    "S fall misjudged": (
        "--min-rpm-step 2000: S3651 -> S1651 on the plunge, a fall the spindle could not "
        "end in it, ran on into the first cut: fz -14 % to +15 % in a +-2 % band",
        Case("bowl2", BOWL2, 1393.0, 279.0, 16.0, {**SPINDLE, "--min-rpm-step": "2000"})),
    "S0 written": (
        "--min-rpm-step 3000: a full step down from S2405 wrote S0 on the plunge (the "
        "spindle stopped while the tool fed into the part)",
        Case("bowl2", BOWL2, 1393.0, 279.0, 16.0,
             {"--accel": "227", "--max-rpm": "8000", "--min-rpm-step": "3000"})),
    "F too coarse for the band": (
        "--fz-band 0.5 and fz 0.02: cuts the plan slowed below the F words' resolution "
        "(F111 at 1 mm/min a word) were planned anyway, fz -0.64 % (now kept as programmed "
        "with the warning)",
        Case("bowl2", BOWL2, 1393.0, 279.0, 16.0,
             {**SPINDLE, "--fz-band": "0.5", "--vc": "70", "--fz": "0.02"})),
    "not idempotent, a large fall": (
        "--min-rpm-step 2000 --vc 30 --fz 0.1: a second rewrite changed 23 lines",
        Case("bowl2", BOWL2, 1393.0, 279.0, 16.0,
             {"--accel": "227", "--max-rpm": "8000", "--min-rpm-step": "2000", "--vc": "30",
              "--fz": "0.1"})),
    "not idempotent": (
        "--vc 30 --fz 0.1: a second rewrite changed the spindle start and the approach "
        "(S7801 M3 -> S8637 M3): the plan took the air moves' times at the F words it had "
        "lowered there (F in the air is now the program's)",
        Case("bowl2", BOWL2, 1393.0, 279.0, 16.0, {**SPINDLE, "--vc": "30", "--fz": "0.1"})),
    "not idempotent, along the cut": (
        "inch, --min-rpm-step 100 --vc 30 --fz 0.02: a second rewrite changed 23 lines, a "
        "third 2",
        Case("bowl2", bowl_strip(make_bowl.drop_ball_tip_z_mm, (44.0, 52.0), 3.0, inch=True),
             1393.0, round(279.0 / MM_PER_INCH, 2) * MM_PER_INCH, 16.0,
             {**SPINDLE, "--min-rpm-step": "100", "--vc": "30", "--fz": "0.02"}, inch=True)),
    "not idempotent, passes": (
        "plunges at half the feed, --min-rpm-step 1000: a second rewrite changed the retract "
        "and traverse (S7690 -> S7738)",
        Case("saddle6-lifts", surface("saddle", 6, lifts=True, plunge_mm_min=400.0), 4000.0,
             800.0, 6.0, {"--accel": "227", "--max-rpm": "40000", "--min-rpm-step": "1000"})),
    "S fall misjudged, along a pass": (
        "--min-rpm-step 2000 --min-rpm 4800: the spindle still rising from S6803 on the "
        "entry into a pass, a full step down to S4803 made it fall by more than the band "
        "over the next blocks, fz -2.1 % in a +-2 % band on a block nothing named",
        Case("saddle8-lifts", surface("saddle", 8, lifts=True), 4000.0, 800.0, 6.0,
             {"--tool-point": "center", "--accel": "131", "--max-rpm": "8000",
              "--min-rpm-step": "2000", "--min-rpm": "4800"})),
    "stamp names the operation": (
        "the stamp's comment lines, taken for CAM notices, made the comment after them the "
        "operation's name: '--operations T1' planned the original's T1, and the same "
        "rewrite of the output exited 5, 'not named in --operations'",
        Case("dome6", surface("dome", 6), 4000.0, 800.0, 6.0,
             {**SPINDLE, "--operations": "T1"})),
    "vc excess understated": (
        "the forward planner: 'vc up to 32.7 % above its target ... still falling from an S "
        "that ncopt could not plan', simulate found +35.6 % on the plunge after a retract "
        "(S17990 while the spindle still fell from S18954)",
        Case("saddle6-lifts", surface("saddle", 6, lifts=True), 4000.0, 800.0, 6.0,
             {"--accel": "131", "--max-rpm": "40000", "--planner": "forward", "--vc": "250",
              "--fz": "0.1"})),
    "vc excess understated, min-rpm": (
        "the forward planner with --min-rpm 2000 on the bowl: +43.6 % and +622.6 % stated, "
        "+742.2 % found on a line the --min-rpm warning names",
        Case("bowl2", BOWL2, 1393.0, 279.0, 16.0,
             {**SPINDLE, "--planner": "forward", "--min-rpm": "2000"})),
    "a contact's onset between samples, with a mesh": (
        "--min-rpm 14250 and a spindle that follows at once (--accel 20000): where the tool "
        "rolls onto the bowl's rim the contact began between a sample that did not cut "
        "yet (R_eff 0.83 mm) and one that did (0.73 mm), vc +1.89 % on a line the "
        "--min-rpm warning did not list (the onset's requirement counts now)",
        Case("bowl2", BOWL2, 1393.0, 279.0, 16.0,
             {"--accel": "20000", "--max-rpm": "15000", "--min-rpm": "14250"}, mesh=True)),
    "F for a spindle start that is not written": (
        "--fz-band 0.3 --min-rpm-step 4000 --planner forward, the dome at S2000 F300: the "
        "spindle start planned at S5402, the links before the blocks kept as programmed "
        "written back to S2000, and the cuts after them given F for 3800 RPM: fz +97 %",
        Case("dome6", surface("dome", 6, s_rpm=2000, f_mm_min=300.0), 2000.0, 300.0, 6.0,
             {"--accel": "50", "--max-rpm": "15000", "--fz-band": "0.3",
              "--min-rpm-step": "4000", "--planner": "forward"})),
    "a program's S above the machine's": (
        "the dome at S9000 F300 on an 8000 RPM machine, --vc 30 --fz 0.02 --fz-band 1: "
        "between blocks kept as programmed (S9000), F planned for a spindle at 8450 RPM "
        "the machine cannot reach, fz +5.6 %",
        Case("dome6", surface("dome", 6, s_rpm=9000, f_mm_min=300.0), 9000.0, 300.0, 6.0,
             {"--accel": "227", "--max-rpm": "8000", "--vc": "30", "--fz": "0.02",
              "--fz-band": "1"})),
    "a program's S above the machine's, CR LF": (
        "the same with --vc 10 --fz 0.1 --fz-band 0.3: S8000 F1770, fz +10.6 %",
        Case("dome6", surface("dome", 6, s_rpm=9000, f_mm_min=300.0, crlf=True), 9000.0,
             300.0, 6.0, {"--accel": "227", "--max-rpm": "8000", "--vc": "10", "--fz": "0.1",
                          "--fz-band": "0.3"})),
    "plunges at the program's own S, read again": (
        "the dome with lifts, plunges at F150 under a cut at F300, S2000, --planner forward "
        "--vc 80 --fz 0.02: a second rewrite read the plunges' feed per revolution at the "
        "speed replayed (ncopt's) and changed 24 lines; with one S over the operation "
        "(the stamp's S0=) it is read over S0 (the same at acae37c)",
        Case("dome6-lifts", surface("dome", 6, lifts=True, crlf=True, s_rpm=2000,
                                    f_mm_min=300.0, plunge_mm_min=150.0), 2000.0, 300.0, 6.0,
             {**SPINDLE, "--planner": "forward", "--vc": "80", "--fz": "0.02"})),
    "a full step down across the band": (
        "one pass of the bowl with its mesh, --accel 751 --fz-band 20 --min-rpm-step 2000: "
        "a forced fall of one step S4703 -> S2703 inside one block, below the band's floor "
        "for the spindle there (fz 21.9 % off in a 20 % band, no warning)",
        Case("bowl1", bowl_strip(make_bowl.drop_ball_tip_z_mm, (44.0,), 3.0, crlf=True), 1393.0,
             279.0, 16.0, {"--accel": "751", "--max-rpm": "15000", "--fz-band": "20",
                           "--min-rpm-step": "2000", "--operations": "all"}, mesh=True)),
}


#: the cases of FIXED that now leave their one operation as programmed (said, exit 5)
LEFT_WHOLE = {"feed cap below min-rpm", "F too coarse for the band",
              "F for a spindle start that is not written"}


@pytest.mark.parametrize("fixed", list(FIXED))
def test_the_cases_it_found_and_that_hold_now(coarse_bowl, fixed):
    """Judged in full, a second rewrite included; the feed cap below --min-rpm is refused
    naming both options."""
    case = FIXED[fixed][1]
    verdict = check(case, *(coarse_bowl if case.mesh else (None, None)))
    if fixed in LEFT_WHOLE:  # every cut keeps its S and F: nothing planned, exit 5, no file
        assert verdict is None
    if fixed == "feed cap below min-rpm":
        assert verdict is None
        with tempfile.TemporaryDirectory(prefix="judged") as folder:
            program = Path(folder) / "prog.nc"
            program.write_bytes(case.text)
            result = invoke(case.args(program, None) + ["-o", str(Path(folder) / "o.nc")])
        assert result.exit_code == Exit.PLANNING
        assert result.stderr.startswith(f"{program}: nothing to plan: T1 (lines 1-44): "
                                        "--max-feed 600 mm/min over fz 0.1 mm x 2 teeth is "
                                        "3000 RPM, below --min-rpm 4800: "), result.stderr
        assert "raise --max-feed to at least 960 mm/min" in result.stderr
    elif fixed not in LEFT_WHOLE:
        assert verdict is not None and verdict.ok


# ------------------------------------------------------- G93 without its F ----
# (lines after the dome's 5 set-up lines and its first cut; ``at``: the line refused)
G93_CASES = {
    "g1 without F": (["G93 G1 X-7.143 Y-10.000 Z6.224 F20", "G1 X-4.286 Y-10.000 Z7.041",
                      "G94 G1 X-1.429 Y-10.000 Z7.449 F800"], 8, "g1"),
    "F on the G93 line only": (["G93 F20", "G1 X-7.143 Y-10.000 Z6.224",
                                "G94 G1 X-1.429 Y-10.000 Z7.449 F800"], 8, "g1"),
    "modal move, axis words only": (["G93 G1 X-7.143 Y-10.000 Z6.224 F20",
                                     "X-4.286 Y-10.000 Z7.041",
                                     "G94 G1 X-1.429 Y-10.000 Z7.449 F800"], 8, "g1"),
    "arc without F": (["G93 G1 X-7.143 Y-10.000 Z6.224 F20", "G2 X-4.286 Y-10.000 R3",
                       "G94 G1 X-1.429 Y-10.000 Z7.449 F800"], 8, "arc"),
}
G93_ACCEPTED = {  # every feed move with its F; rapids and offsets need none
    "every move with F": ["G93 G1 X-7.143 Y-10.000 Z6.224 F20",
                          "G1 X-4.286 Y-10.000 Z7.041 F25", "G94 G1 X-1.429 F800"],
    "rapid and offset without F": ["G93 G1 X-7.143 Y-10.000 Z6.224 F20", "G0 Z15",
                                   "G92 X0", "G92.1", "G1 X-4.286 Y-10.000 Z7.041 F2",
                                   "G94 G1 X-1.429 F800"],
    "F in G94 carries on": ["G93 G1 X-7.143 Y-10.000 Z6.224 F20", "G94 F800",
                            "G1 X-4.286 Y-10.000 Z7.041"],
}


def with_g93(lines: list[str]) -> str:
    text = dome(8).decode().splitlines()
    return "\n".join(text[:6] + lines + text[6 + len(lines):]) + "\n"


@pytest.mark.parametrize("name", list(G93_CASES))
def test_an_inverse_time_move_without_its_f_is_refused_at_its_line(tmp_path, name):
    """G93: F is 1 / minutes of each move, and LinuxCNC refuses a G1/G2/G3 without its
    own F ("F word missing with inverse time g1 move"); it was planned around with a
    warning.  Now refused at the move's line, as F0 is (exit 3), and nothing written."""
    lines, at, kind = G93_CASES[name]
    path = tmp_path / "g93.nc"
    path.write_text(with_g93(lines))
    result = invoke(["rewrite", str(path), "--diameter", "6", "--accel", "227",
                     "--max-rpm", "15000", "-o", str(tmp_path / "o.nc")])
    assert result.exit_code == Exit.PROGRAM, result.stderr
    assert result.stderr.startswith(
        f"{path}:{at}:1: inverse-time (G93) move without its own F word (F is 1/minutes "
        "there, of each move alone): give the move's F (LinuxCNC refuses it: \"F word "
        f"missing with inverse time {kind} move\")\n")
    assert not (tmp_path / "o.nc").exists()


@pytest.mark.parametrize("name", list(G93_ACCEPTED))
def test_inverse_time_moves_with_their_f_are_planned(tmp_path, name):
    path = tmp_path / "g93.nc"
    path.write_text(with_g93(G93_ACCEPTED[name]))
    result = invoke(["rewrite", str(path), "--diameter", "6", "--accel", "227",
                     "--max-rpm", "15000", "-o", str(tmp_path / "o.nc")])
    assert result.exit_code == Exit.OK, result.stderr


@pytest.mark.skipif(RS274 is None, reason="rs274 not installed (linuxcnc-uspace)")
@pytest.mark.parametrize("name", list(G93_CASES) + list(G93_ACCEPTED))
def test_ncopt_refuses_the_inverse_time_moves_linuxcnc_refuses(name):
    """LinuxCNC's interpreter, the judge: it rejects the G93 cases ncopt refuses, and
    accepts the others."""
    refused = name in G93_CASES
    text = with_g93(G93_CASES[name][0] if refused else G93_ACCEPTED[name])
    if refused:
        with pytest.raises(RuntimeError, match="F word missing with inverse time"):
            canon(text)
    else:
        canon(text)


def test_the_codes_the_refusal_reads_are_the_interpreters():
    """ncopt.reading may not import ncopt.motion: its copies of the motion group and of the
    codes whose axis words are no target stay equal to the interpreter's."""
    assert refuse.MOTION_GROUP == modal.G_MOTION
    assert refuse.NOT_A_MOVE == modal.G_NOT_A_TARGET - {530}


def test_an_operation_no_spindle_speed_can_hold_is_left_and_the_others_planned(tmp_path):
    """Two tools whose own S and F give fz 0.1 and 0.02: with --max-feed 600 and
    --min-rpm 4800 the first would need at most 3000 RPM: it is left as programmed, with
    the reason, and the second is planned."""
    moves = lambda f: [ln for ln in surface("dome", 6, f_mm_min=f).decode().splitlines()  # noqa: E731
                       if ln.startswith(("G0", "G1"))]
    text = "\n".join(["(T1 D=6. CR=3. - ball end mill)", "(T2 D=6. CR=3. - ball end mill)",
                      "G21 G90 G94 G17", "T1 M6", "S4000 M3", *moves(800.0), "G0 Z30",
                      "T2 M6", "S4000 M3", *moves(160.0), "G0 Z30", "M5", "M30"]) + "\n"
    program = tmp_path / "two.nc"
    program.write_text(text)
    out = tmp_path / "out.nc"
    result = invoke(["rewrite", str(program), "--json", *[a for kv in SPINDLE.items() for a in kv],
                     "--max-feed", "600", "--min-rpm", "4800", "-o", str(out)])
    assert result.exit_code == Exit.OK, result.stderr
    summary = json.loads(result.stderr)
    ops = {op["tool"]: op for op in summary["operations"]}
    assert ops[2]["planned"] and not ops[1]["planned"], ops
    assert "below --min-rpm 4800" in ops[1]["reason"]
    lines = text.splitlines()
    first = out.read_text().splitlines()
    at = first.index("T1 M6")
    assert first[at:at + lines.index("T2 M6") - 3] == lines[3:lines.index("T2 M6")]


def test_an_operation_whose_every_cut_is_kept_is_not_called_planned(tmp_path):
    """--fz-band 0.1 and fz 0.02 on the bowl strip: every cut's F is too low for F words
    of 1 mm/min to hold the band, so every cut keeps its S and F.  The operation was
    reported planned (0 blocks, a stamp claiming the new vc); it is left, with why, and a
    program of it alone has nothing to plan (exit 5, no file)."""
    case = Case("bowl2", BOWL2, 1393.0, 279.0, 16.0,
                {**SPINDLE, "--fz-band": "0.1", "--vc": "70", "--fz": "0.02"})
    program = tmp_path / "prog.nc"
    program.write_bytes(case.text)
    out = tmp_path / "out.nc"
    result = invoke(case.args(program, None) + ["-o", str(out)])
    assert result.exit_code == Exit.PLANNING and not out.exists()
    assert result.stderr.startswith(
        f"{program}: nothing to plan: T4 (lines 1-131): every cut's feed is too low for the "
        "resolution of the program's F words to hold fz within its band"), result.stderr


def test_the_links_before_a_kept_block_keep_its_s_for_the_plan_too():
    """Links (planned, not the operation's own cuts) right before a block kept as
    programmed keep the program's S, for the plan too, so the spindle it tracks is the one
    the output runs."""
    from ncopt.planning.opplan import _tie_links

    planned = np.array([True, True, True, False, True, True])
    mine = np.array([True, False, False, False, True, False])
    running = np.ones(6, dtype=bool)
    assert _tie_links(planned, mine, running).tolist() == [True, False, False, False, True,
                                                           True]
