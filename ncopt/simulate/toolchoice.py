"""Which tool a simulation evaluates, and its cutter: ``Job.tool`` or the program's only
cutting tool; its cutter from the options, an ncopt stamp, the tool profiles or the
program's tool comments, and where it came from.
"""

from __future__ import annotations

import numpy as np

from ncopt.model import MM_PER_INCH, Cutter, Job, Program, Toolpath
from ncopt.planning.tooltable import BALL, BULL, cutter_for, tool_table
from ncopt.reading.stamp import Stamp, read_stamps
from ncopt.runtime.errors import UsageError
from ncopt.simulate.movetable import feed_tools

__all__ = ["describe_cutter", "evaluated_tool", "stamp_of"]


def stamp_of(prog: Program, tool: int) -> Stamp | None:
    """The first ncopt stamp of T``tool`` (None: the program is not an ncopt output)."""
    found = sorted((st for (t, _), st in read_stamps(prog).items() if t == tool),
                   key=lambda st: st.line)
    return found[0] if found else None


def evaluated_tool(prog: Program, tp: Toolpath, job: Job,
                   path: str) -> tuple[Cutter, np.ndarray, int, str]:
    """The cutter to evaluate, (nm,) bool: the moves made with it, its T number (-1: none)
    and where the cutter came from.

    One tool per simulation: ``job.tool``, else the program's only cutting tool
    (:func:`ncopt.simulate.replay.tools_to_simulate` picks them in a program of several).
    Its cutter is ``job.cutter``, else read from the program's tool comments.
    """
    tool = tp.tool[1:]
    used = feed_tools(tp)
    if job.tool is not None:
        if job.tool not in used:
            raise UsageError(f"no feed moves with tool T{job.tool}; check --tool", path)
        used = [job.tool]
    if len(used) > 1:
        listed = ", ".join(f"T{t}" for t in used)
        raise UsageError(f"the program cuts with several tools ({listed}); simulate one at a "
                         "time with --tool N", path)
    mask = tool == used[0] if used else np.zeros(tool.shape, dtype=bool)
    number = used[0] if used else -1
    if job.cutter is not None:
        return job.cutter, mask, number, "the options"
    stamp = stamp_of(prog, number)
    if stamp is not None:  # the cutter ncopt planned with (mm, its teeth), as rewrite reads it
        return stamp.cutter, mask, number, f"the ncopt stamp on line {stamp.line + 1}"
    if number in job.tool_library:
        return job.tool_library[number], mask, number, "the tool profiles"
    info = cutter_for(tool_table(prog), number, len(used))
    if info is None or info.kind not in (BALL, BULL):
        raise UsageError("the program's comments do not describe a ball or bull-nose cutter; "
                         "give --diameter (and --corner-radius for a bull-nose)", path)
    inch = tp.line_inch is not None and bool(np.any(tp.line_inch))
    teeth = f"teeth from line {info.teeth_line}" if info.teeth else f"{job.teeth} teeth assumed"
    return (info.cutter(info.teeth or job.teeth, MM_PER_INCH if inch else 1.0), mask, number,
            f"line {info.line}: ({info.text.strip()}); {teeth}")


def describe_cutter(cutter: Cutter) -> str:
    """``D16 ball, 2 teeth``, ``D10 bull-nose r2, 4 teeth`` (mm)."""
    kind = "ball" if cutter.is_ball else f"bull-nose r{cutter.corner_radius_mm:g}"
    return f"D{cutter.diameter_mm:g} {kind}, {cutter.teeth} teeth"
