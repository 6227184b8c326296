"""Where the tool points in every block: rotary axes, tool vectors, tilted planes.

ncopt plans a move only when it knows the tool axis ``e`` (unit, from the tip
toward the spindle, in the part frame) at both its ends.  A 3-axis program
never mentions anything below, its tool axis is +Z and the reader returns
``None`` (no cost).  Everything that can turn the tool away from +Z is read
here, per source line; a move whose axis ncopt cannot know is left as
programmed with a located reason.

* Rotary axis words ``A B C`` (degrees; G90/G91 as the linear axes).  An axis
  is not known until the program states it (ncopt takes none at 0), and is lost
  after a move that can turn it without saying where to (G28/G30, offsets set
  with rotary words, a call, a swivel, G53.1, a construct ncopt does not
  interpret) until stated again.  Where one is not 0 the machine's kinematics
  gives ``e`` (``ncopt.motion.kinematics``, ``--kinematics``); a spin axis (C) not known
  matters only where the tool tilts.  A feed block whose axis turns more than
  :data:`~ncopt.motion.toolaxis.MAX_TURN_DEG` along the way (a full turn A360 -> A0 ends upright) is a
  reorientation, not planned.
* Tool-centre-point control (TCP): with it the programmed X Y Z are the tool
  tip in the part frame.  Switched on by Sinumerik ``TRAORI``, Fanuc
  ``G43.4``/``G43.5``, Haas ``G234``, Heidenhain ``M128``/``FUNCTION TCPM``, the
  LinuxCNC 5-axis configurations' ``M428``; off by ``TRAFOOF``, ``G49`` (or
  ``G43``/``G44``), ``M129``, ``FUNCTION RESET TCPM``, ``M429``, M2/M30.  Without
  it X Y Z are machine positions: a move with a rotary axis turned is not
  planned, unless the machine profile says its control always runs tool-tip
  kinematics (``tcp = "always"``).  The block that switches TCP on does not move
  under it (Fanuc): not planned when the tool is tilted.
* Tool vectors, which need no machine data: Fanuc ``G43.5`` ``I J K`` (a
  component left out of a block is 0; none given, the last vector holds) and
  Sinumerik ``A3= B3= C3=`` under ``TRAORI`` (same rule; orientation in the
  workpiece frame, ORIWKS, the default; ``ORIMKS`` is not read).  Other
  Sinumerik orientation addresses (``A2=``, ``A4=``, ``LEAD=``...) are not read.
* Tilted working planes (3+2): ``ncopt.motion.planes``.
* Fanuc ``G43.5 ... Q``: the tool leans Q degrees toward the direction of
  travel (:func:`ncopt.motion.lean.lean_toward_travel`, once the positions are known).
* Arcs keep the tool axis: an arc that turns it is not planned, nor any arc
  under G43.5 (its I J K would be both centre and vector).

This module decides which moves are blocked and why, and carries the points into the
part frame; the pieces are read in their own modules: rotary axes
(``ncopt.motion.rotary``), TCP (``ncopt.motion.tcp``), tool vectors
(``ncopt.motion.toolvectors``), planes (``ncopt.motion.planes``), the lean
(``ncopt.motion.lean``), on the codes and the record of ``ncopt.motion.toolaxis``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ncopt.motion.kinematics import VECTOR, turn_deg, unit
from ncopt.motion.modal import ffill
from ncopt.motion.planes import (G_ALIGN, G_FRAME_OFF, G_FRAME_ON, G_ROTATION, KW_FRAME_OFF,
                                 KW_ROTATIONS, KW_SWIVEL, frames)
from ncopt.motion.rotary import axes_from_angles, positions_of, rotary_positions
from ncopt.motion.tcp import tcp_changed, tcp_state
from ncopt.motion.toolaxis import (G_LENGTH_GROUP, G_TCP_ON, G_VECTOR_TCP, KW_TCP, M_TCP_ON,
                                   MAX_TURN_DEG, ORIENTATION_ADDRESS, ROTARY, TCP_ALWAYS,
                                   VECTOR_LETTERS, Z, Orientation, Reasons, before)
from ncopt.motion.toolvectors import tool_vectors


def read_orientation(prog, lines, modal, executed: np.ndarray,
                     kinematics: str | None = None,
                     tcp: str | None = None) -> Orientation | None:
    """The tool axis per line, or None when nothing in the program tilts the tool.

    ``lines`` and ``modal`` are the interpreter's line table and modal state
    (``ncopt.motion.linetable``, ``ncopt.motion.modalstate``); ``executed`` (n,) the
    lines the control runs;
    ``kinematics`` a name of :data:`ncopt.motion.kinematics.NAMES` or None; ``tcp``
    ``"always"`` where the machine's control runs tool-tip kinematics for every
    program (the machine profile says so), None: as the program switches it.
    """
    keywords = _keywords(prog, executed)
    rotary = [c for c in ROTARY if positions_of(lines, c).any()]
    # the codes alone, not per-line arrays: a 3-axis program pays a few milliseconds here
    flagged = np.isin(lines.g_code, list(G_FRAME_ON | G_FRAME_OFF | G_TCP_ON
                                          | {G_ROTATION, G_ALIGN})).any() \
        or np.isin(lines.m_code, list(M_TCP_ON)).any() \
        or any(c in lines.letters for c in VECTOR_LETTERS)
    if not rotary and not keywords and not flagged:
        return None
    r = Reasons()
    angle, move, unknown = rotary_positions(prog, lines, modal, executed, r)
    tcp_on, tcp_explicit, switch = tcp_state(prog, lines, executed, keywords, tcp == TCP_ALWAYS)
    why = np.zeros(lines.n, dtype=np.int16)
    axis, angles, spin_why = axes_from_angles(angle, unknown, rotary, kinematics,
                                              (tcp_on, tcp_explicit), why, r)
    vec, vec_why = tool_vectors(prog, lines, executed, keywords, tcp_on, r)
    has_vec = ~np.isnan(vec).any(axis=1)
    axis[has_vec], angles[has_vec] = unit(vec[has_vec]), np.nan
    why = np.where(vec_why > 0, vec_why, np.where(has_vec, 0, why))
    frame, planes, frame_why = frames(prog, lines, modal, executed, keywords, rotary, r)
    in_frame = frame >= 0
    for k, (_, rot) in enumerate(planes):
        axis[frame == k] = rot @ Z
    angles[in_frame] = np.nan
    why = np.where(in_frame, 0, why)
    why = np.where(frame_why > 0, frame_why, why).astype(np.int16)
    blocked = _moves(lines, modal, executed, axis, angles, why, switch, frame, r, tcp_on,
                     np.where(has_vec | in_frame, 0, spin_why), kinematics)
    blocked[~executed] = 0
    used = (kinematics if np.isfinite(angles).any() and kinematics != VECTOR else
            VECTOR if has_vec.any() else None)
    return Orientation(blocked=blocked, reasons=tuple(r.texts), rotary_move=move, axis=axis,
                       angles_deg=angles, kinematics=used, frame=frame, frames=tuple(planes))


def _moves(lines, modal, executed, axis, angles, why, switch, frame, r, tcp_on, spin_why,
           kinematics) -> np.ndarray:
    """(n,) reason a move on each line is not planned: its start or end axis is not
    known, it tilts the tool from a vertical stand whose spin axis is not known, it is
    an arc that turns the tool (or any arc under G43.5), a block whose tool axis turns
    more than :data:`MAX_TURN_DEG`, it switches TCP on with the tool tilted, or it
    starts in another frame."""
    blocked = np.where(why > 0, why, before(why, 0)).astype(np.int16)
    start = before(axis, Z)
    start_angles = before(angles, np.full(3, np.nan))
    tilted = np.abs(axis[:, :2]).sum(1) > 1e-12
    turns = (np.abs(axis - start).sum(1) > 1e-12) | np.any(
        (angles != start_angles) & np.isfinite(angles) & np.isfinite(start_angles), axis=1)
    spin = np.where(turns, np.maximum(before(spin_why, 0), spin_why), 0)
    blocked = np.where((blocked == 0) & executed, spin, blocked).astype(np.int16)
    arc = np.isin(modal.motion, [20, 30])
    feed = np.isin(modal.motion, [10, 20, 30]) & turns & executed & (blocked == 0)
    turn = np.zeros(lines.n)
    turn[feed] = turn_deg(start[feed], axis[feed], start_angles[feed], angles[feed],
                          kinematics, MAX_TURN_DEG)
    for i in np.flatnonzero(turn > MAX_TURN_DEG).tolist():
        blocked[i] = r.code(f"the tool axis turns {turn[i]:.0f} deg within this block: a "
                            f"reorientation, not a cut ncopt plans (at most {MAX_TURN_DEG:g} "
                            "deg a block)")
    length = ffill(np.where(executed, lines.g_group(G_LENGTH_GROUP), np.nan), 490.0)
    rules = (
        (arc & turns, "an arc that turns the tool: ncopt keeps the tool axis fixed on arcs"),
        (arc & (length == G_VECTOR_TCP), "an arc under G43.5, where I J K give the tool "
         "vector"),
        (switch & (tilted | before(tilted, False)), "the block that switches tool-centre-"
         "point control on does not move under it"),
        (tcp_changed(lines, executed, tcp_on) & before(tilted, False),
         "the first move after tool-centre-point control was switched with the tool tilted "
         "starts from a machine position"),
        (frame != before(frame, -1), "the first move in a new tilted working plane"),
    )
    for mask, text in rules:
        hit = mask & executed & (blocked == 0)
        if hit.any():
            blocked[hit] = r.code(text)
    return blocked


def _keywords(prog, executed) -> dict:
    """{0-based line: keyword} of the executed opaque lines that concern the tool axis."""
    wanted = KW_SWIVEL | KW_ROTATIONS | KW_FRAME_OFF | KW_TCP | {"TRANS"}
    return {i: why.upper() for i, why in prog.opaque_reason.items()
            if (why.upper() in wanted or ORIENTATION_ADDRESS.match(why)) and executed[i]}


def with_tool_axis(tp, o: Orientation):
    """``tp`` (a :class:`~ncopt.model.Toolpath` in programmed coordinates) in the part
    frame with its tool axis per point (and the rotary angles where a kinematics gave
    it: between two such points the angles turn linearly); points in a tilted working
    plane are carried into the part frame.  ``tool_axis`` stays None where every axis
    is +Z."""
    if tp.n < 2:
        return tp
    line = np.maximum(tp.line, 0)
    start = tp.line < 0
    axis = np.where(start[:, None], Z, o.axis[line])
    angles = np.where(start[:, None], np.nan, o.angles_deg[line])
    xyz = tp.xyz_mm
    if o.frames:
        xyz = xyz.copy()
        frame_of = np.where(start, -1, o.frame[line])
        for k, (org, rot) in enumerate(o.frames):
            sel = frame_of == k
            xyz[sel] = org + xyz[sel] @ rot.T
    if np.all(axis == Z):
        return replace(tp, xyz_mm=xyz, kinematics=o.kinematics)
    turned = np.isfinite(angles).all(axis=1)
    return replace(tp, xyz_mm=xyz, tool_axis=axis, kinematics=o.kinematics,
                   tool_angles_deg=angles if turned.any() else None)
