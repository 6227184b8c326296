"""Modal interpreter: :class:`Program` -> :class:`Toolpath` (numpy arrays).

The modal tables of RS-274 are constant data (``ncopt.motion.modal``); the
interpreter is a function of the program and a start state, run as stages, each
in its module: the line table (``linetable``), the lines that run and the values
of computed words (``flow``), the checks a control makes (``checks``), the modal
state (``modalstate``), the tool axis (``orientation``), the positions
(``positions``), the points (``points``, ``arcs``) and the state per source line
the writer needs (``linestate``).  Plain blocks are interpreted with vectorised
forward fills (a 1M-block program in about a second); arcs are worked out all at
once too, bit for bit as the one-arc reference (``arcs``); expressions take a
per-line path.

Nothing is guessed: where the position cannot be known (a subprogram call, a
macro, a return to home, a parameter the program does not set, an opaque
line that may move the machine) the axes become unknown until the program
states them again absolutely, and moves in between are not planned.
"""

from __future__ import annotations

from dataclasses import replace

from ncopt.model import Job, Program, Toolpath
from ncopt.motion.checks import check_comp_corners, check_semantics
from ncopt.motion.flow import evaluate, executed_lines
from ncopt.motion.lean import lean_toward_travel
from ncopt.motion.linestate import line_state
from ncopt.motion.linetable import LineTable
from ncopt.motion.modalstate import StartState, modal_state
from ncopt.motion.orientation import read_orientation, with_tool_axis
from ncopt.motion.points import build_points
from ncopt.motion.positions import positions


def tcp_for(tcp: str | None, dialect: str) -> str | None:
    """A machine's ``tcp`` setting for a program of ``dialect``: grbl has no
    tool-centre-point control, whatever a profile says."""
    return None if dialect == "grbl" else tcp


def tcp_of(job: Job, detected: str) -> str | None:
    """The job's ``tcp`` for a program of the ``detected`` dialect (:func:`tcp_for`)."""
    return tcp_for(job.tcp, job.control or detected)


def interpret(prog: Program, start: StartState = StartState(),
              kinematics: str | None = None, tcp: str | None = None) -> Toolpath:
    """Interpret a program into cutter locations.

    ``kinematics``: the machine's kinematics (``ncopt.motion.kinematics``) for
    programs that tilt the tool with rotary axes; None: such moves are not
    planned.  ``tcp``: ``"always"`` where the machine's control runs tool-tip
    kinematics for every program (its profile says so); None: only where the
    program switches tool-centre-point control on (``ncopt.motion.orientation``).

    Returns
    -------
    Toolpath
        One row per CL point; arcs split within ``start.chord_tol_mm``.
    """
    skip = None
    if prog.line_exprs:  # subroutine bodies and lines after M2/M30 are not evaluated
        skip = ~executed_lines(prog, LineTable(prog, prog.word_value), [])
    values, poisoned, warnings = evaluate(prog, skip)
    lines = LineTable(prog, values)
    executed = executed_lines(prog, lines, warnings)
    check_semantics(prog, lines, executed)
    modal = modal_state(lines, start, executed)
    orient = read_orientation(prog, lines, modal, executed, kinematics, tcp)
    pos_mm, known, last_event = positions(prog, lines, modal, executed, poisoned, warnings)
    orient = lean_toward_travel(orient, prog, lines, modal, executed, pos_mm)  # G43.5 Q
    check_comp_corners(prog, lines, modal, pos_mm, known, executed)
    tp = build_points(prog, lines, modal, pos_mm, known, executed, start, warnings, orient,
                      last_event)
    tp = replace(tp, lines=line_state(prog, lines, modal, executed))
    return tp if orient is None else with_tool_axis(tp, orient)
