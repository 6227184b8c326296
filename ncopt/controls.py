"""How controls treat S words during feed moves, and what to tell the user.

A rewritten program changes S while the axes move.  Some controls stop the
feed at every S change unless told not to; the summary says what the detected
(or named) control needs so the speed-up is real.
"""

from __future__ import annotations

from .dialect import FANUC, GENERIC, GRBL, HEIDENHAIN, LINUXCNC, SINUMERIK

NOTES = {
    GRBL: "grbl stops the motion at every S change unless laser mode is on ($32=1); "
          "with {s} S words this program would stall: use grbl only in laser mode or a "
          "control that changes S on the fly",
    FANUC: "Fanuc waits for the spindle to reach each S when the speed-arrival check is on "
           "(parameter 3708#0, SAR): switch it off for this program, or motion pauses at "
           "each of the {s} S words",
    LINUXCNC: "LinuxCNC pauses at S changes when motion.spindle-at-speed is wired in HAL: "
              "leave it unwired for this program, or motion waits at each of the {s} S words",
    SINUMERIK: "Sinumerik acknowledges each S word through the PLC: if the path slows, space "
               "the {s} S words with --min-s-interval-ms (e.g. 100)",
    HEIDENHAIN: "check that the control applies S changes without stopping the feed "
                "({s} S words)",
    GENERIC: "check that the control applies S changes without stopping the feed ({s} S words)",
}
CONTROLS = tuple(NOTES)


def control_note(control: str, s_words: int) -> str:
    """The one thing the user must know about this control and a rewritten program."""
    return NOTES.get(control, NOTES[GENERIC]).format(s=s_words)
