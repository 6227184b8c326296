"""The modal state in force on every line, as (n_lines,) arrays: motion mode, units,
distance modes, plane, feed mode, cutter compensation, F, S, the spindle and the tool;
and the modes ncopt does not read (scaling, computed F and S, the modes of
:data:`ncopt.motion.modal.G_MODES_NOT_READ`), whose moves are not planned."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ncopt.motion.linetable import LineTable
from ncopt.motion.modal import (G_ARC_DISTANCE, G_COMP, G_DISTANCE, G_FEED_MODE, G_MODES_NOT_READ,
                                G_MOTION, G_PLANE, G_SCALE_OFF, G_SCALE_ON, G_UNITS, INCH_HEADER,
                                KW_FRAME_RESET, KW_SCALE, ffill)
from ncopt.motion.planes import after_keyword


@dataclass(frozen=True)
class StartState:
    """Modal state before the first line (a control's usual power-on state)."""

    inch: bool = False
    absolute: bool = True
    arc_absolute: bool = False
    plane: int = 170
    chord_tol_mm: float = 0.005


@dataclass(frozen=True)
class Modal:
    """Modal state in force at each line, (n_lines,) arrays."""

    motion: np.ndarray  # G code x10, NaN if never set
    inch: np.ndarray  # bool
    absolute: np.ndarray  # bool
    arc_absolute: np.ndarray
    plane: np.ndarray  # 170 / 180 / 190
    feed_mode: np.ndarray  # 930 / 940 / 950
    comp: np.ndarray  # 400 / 410 / 420
    feed: np.ndarray  # programmed F in program units (NaN before any)
    spindle_rpm: np.ndarray
    spindle_on: np.ndarray
    tool: np.ndarray


def modal_state(lines: LineTable, start: StartState, executed: np.ndarray) -> Modal:
    """The modal state in force at each line from ``start``; lines not executed change
    nothing."""
    def group(codes, initial):
        arr = lines.g_group(codes)
        arr[~executed] = np.nan
        return ffill(arr, initial)

    units = group(G_UNITS, 200.0 if start.inch else 210.0)
    spindle_on = np.full(lines.n, np.nan)
    for codes, state in (({3, 4}, 1.0), ({5}, 0.0), ({2, 30}, 0.0)):
        spindle_on[lines.has_m(codes) & executed] = state
    limit = lines.has_g({250, 260})  # Sinumerik G26 S8000: a spindle limit, not a speed
    s_words = np.where(executed & ~limit, lines.value("S"), np.nan)
    speed = ffill(s_words, 0.0)
    running = ffill(spindle_on, 0.0) > 0
    t_words = np.where(executed, lines.value("T"), np.nan)
    t_ffill = ffill(t_words, -1.0)
    changes = lines.has_m({6}) & executed
    tool = ffill(np.where(changes, t_ffill, np.nan), -1.0) if changes.any() else t_ffill
    feed = ffill(np.where(executed, lines.value("F"), np.nan))
    return Modal(
        motion=group(G_MOTION, np.nan), inch=units == 200.0,
        absolute=group(G_DISTANCE, 900.0 if start.absolute else 910.0) == 900.0,
        arc_absolute=group(G_ARC_DISTANCE, 901.0 if start.arc_absolute else 911.0) == 901.0,
        plane=group(G_PLANE, float(start.plane)), feed_mode=group(G_FEED_MODE, 940.0),
        comp=group(G_COMP, 400.0), feed=feed, spindle_rpm=speed, spindle_on=running, tool=tool)


def _switched(on: np.ndarray, off: np.ndarray, executed: np.ndarray) -> np.ndarray:
    """(n,) bool: a mode switched on on the lines ``on`` and off on ``off`` (``on`` wins on
    a line with both) is in force; lines not executed switch nothing."""
    on, off = on & executed, off & executed
    if not on.any():  # the usual program: no ffill over its lines
        return np.zeros(on.shape[0], dtype=bool)
    state = np.full(on.shape[0], np.nan)
    state[off] = 0.0
    state[on] = 1.0
    return ffill(state, 0.0) > 0


def _modes_not_read(prog, lines, executed) -> np.ndarray:
    """(n,) int: 1 + the index in :data:`G_MODES_NOT_READ` of a mode in force on the line
    (the first listed wins), 0 where none is; M2/M30 end them all."""
    out = np.zeros(lines.n, dtype=np.int64)
    first = next((i for i in range(min(prog.n_lines, 5)) if prog.line_text(i).strip()), None)
    ends = lines.has_m({2, 30})
    for k, (codes_on, codes_off, _) in reversed(list(enumerate(G_MODES_NOT_READ))):
        on, off = lines.has_g(codes_on), lines.has_g(codes_off) | ends
        if 700 in codes_on and first is not None and INCH_HEADER.match(prog.line_text(first)):
            on[first] = True
        if 71 in codes_on:  # G07.1 C0 (a zero radius) switches cylindrical interpolation off
            zero = on & (np.nan_to_num(lines.value("C"), nan=1.0) == 0.0)
            on, off = on & ~zero, off | zero
        out[_switched(on & ~ends, off, executed)] = k + 1
    return out


def _scaled(prog, lines, executed) -> np.ndarray:
    """(n,) bool: a scaling or mirror image is in force on the line (Fanuc G51/G51.1 until
    G50/G50.1, Sinumerik SCALE/ASCALE/MIRROR/AMIRROR until the frame is reset; M2/M30 end
    both).  The moves under it are not where the program says, nor the surface as long."""
    on, off = lines.has_g(G_SCALE_ON), lines.has_g(G_SCALE_OFF)
    for i, head in prog.opaque_reason.items():
        up = head.upper()
        if up in KW_SCALE or up in KW_FRAME_RESET:
            args = bool(after_keyword(prog.line_text(i), up))
            on[i] |= up in KW_SCALE and args
            off[i] |= up in KW_FRAME_RESET and not args
    ends = lines.has_m({2, 30})
    return _switched(on & ~ends, off | ends, executed)


def _computed(prog, lines, executed, letter: str) -> np.ndarray:
    """(n,) bool: the feed (``letter`` F) or spindle speed (S) in force is a Sinumerik
    assignment ncopt does not evaluate (``F=R1``, ``S=R2*2``), from that line to the next
    such word with a number."""
    on = np.zeros(lines.n, dtype=bool)
    on[[i for i, head in prog.opaque_reason.items() if head.upper() == letter]] = True
    return _switched(on, lines.present(letter), executed)


class NotRead(NamedTuple):
    """What is in force on each line that ncopt does not read: no move under it is
    planned.  (n_lines,) arrays."""

    mode: np.ndarray  # int64: 1 + the index in G_MODES_NOT_READ of the mode in force, 0 none
    scaled: np.ndarray  # bool: a scaling or mirror image
    computed_s: np.ndarray  # bool: S is an assignment ncopt does not evaluate (S=R2*2)
    computed_f: np.ndarray  # bool: F is one (F=R1)

    def any_line(self) -> np.ndarray:
        """(n_lines,) bool: any of them is in force."""
        return self.scaled | self.computed_f | self.computed_s | (self.mode > 0)


def not_read_in_force(prog, lines: LineTable, executed: np.ndarray) -> NotRead:
    """The modes ncopt does not read, in force on each line (:class:`NotRead`)."""
    computed_f = _computed(prog, lines, executed, "F")
    computed_s = _computed(prog, lines, executed, "S")
    return NotRead(mode=_modes_not_read(prog, lines, executed),
                   scaled=_scaled(prog, lines, executed), computed_s=computed_s,
                   computed_f=computed_f)
