"""How controls treat S words during feed moves, and what to tell the user.

A rewritten program changes S while the axes move (``anywhere``) or only on
the moves between passes (``between-passes``).  Some controls stop or wait at
every S change; the summary says what the detected (or named) control does
with the program as written, so the speed-up is real.

What each control does (from its documentation and source):

* grbl 1.1 in spindle mode (laser mode ``$32=0``) empties its planner buffer
  at every S change while the spindle runs (``spindle_sync`` in
  ``spindle_control.c``): the axes stop, the new PWM is set and the motion
  goes on at once, without waiting for the spindle.  Laser mode (``$32=1``)
  changes S without stopping, but it also switches the output off on every
  G0 and turns it back on at the next G1 without waiting: grbl's laser
  documentation says it must be off for a milling spindle.
* Fanuc with the speed-arrival check (parameter 3708#0 SAR) waits for the
  SAR signal before the first feed block after an S code, and after every
  rapid-to-feed change.
* LinuxCNC pauses before the first feed move after each spindle start or
  speed change while ``spindle.0.at-speed`` (``motion.spindle-at-speed``
  before 2.8) is false.
* Sinumerik outputs S as an auxiliary function to the PLC; acknowledging
  several in consecutive blocks drops the path velocity.
"""

from __future__ import annotations

from ncopt.reading.dialect import FANUC, GENERIC, GRBL, HEIDENHAIN, LINUXCNC, SINUMERIK

ANYWHERE, BETWEEN_PASSES = "anywhere", "between-passes"
S_CHANGES = (ANYWHERE, BETWEEN_PASSES)
_LASER = ("keep laser mode off ($32=0), as grbl's documentation requires for a milling "
          "spindle: with $32=1 grbl switches the spindle off on every G0 and resumes "
          "cutting without waiting for it")

NOTES = {
    GRBL: {
        ANYWHERE: "grbl stops the axes at every S change and sets the new speed without "
                  "waiting for it: this program would stop {s} times, in the cut; rewrite "
                  "it with --s-changes between-passes (grbl's default); " + _LASER,
        BETWEEN_PASSES: "grbl stops the axes at every S change and does not wait for the "
                        "spindle; this program changes S only on moves between passes "
                        "({words}), whose time lets the spindle reach speed before the next "
                        "pass; " + _LASER,
    },
    FANUC: {
        ANYWHERE: "with the speed-arrival check on (parameter 3708#0 SAR) a Fanuc control "
                  "waits for the spindle before the first feed block after each S word: "
                  "switch it off for this program, or motion pauses at each of the "
                  "{words}, in the cut",
        BETWEEN_PASSES: "S changes only on moves between passes ({words}): with the "
                        "speed-arrival check on (parameter 3708#0 SAR) the control waits "
                        "there for the spindle, never along a pass",
    },
    LINUXCNC: {
        ANYWHERE: "LinuxCNC pauses before the first feed move after each S change while "
                  "spindle.0.at-speed (motion.spindle-at-speed before 2.8) is wired in HAL "
                  "and false: leave it unwired for this program, or motion waits at each "
                  "of the {words}",
        BETWEEN_PASSES: "S changes only on moves between passes ({words}): with "
                        "spindle.0.at-speed wired in HAL LinuxCNC waits there for the "
                        "spindle, never along a pass",
    },
    SINUMERIK: {
        ANYWHERE: "Sinumerik acknowledges each S word through the PLC: if the path slows, "
                  "space the {words} with --min-s-interval-ms (e.g. 100)",
        BETWEEN_PASSES: "S changes only on moves between passes ({words}), where the "
                        "PLC's acknowledgement does not slow a cut",
    },
    GENERIC: {
        ANYWHERE: "check that the control applies S changes without stopping the feed "
                  "({words}); if it stops or waits, use --s-changes between-passes",
        BETWEEN_PASSES: "S changes only on moves between passes ({words}): a control "
                        "that stops or waits for the spindle at an S word does so there",
    },
}
NOTES[HEIDENHAIN] = NOTES[GENERIC]
CONTROLS = (GRBL, FANUC, LINUXCNC, SINUMERIK, HEIDENHAIN, GENERIC)

# controls that stop the axes at every S word: S changes between passes by default
_DEFAULT_S_CHANGES = {GRBL: BETWEEN_PASSES}


def default_s_changes(control: str) -> str:
    """Where S may change unless the user says: between passes for grbl, else anywhere."""
    return _DEFAULT_S_CHANGES.get(control, ANYWHERE)


def control_note(control: str, s_words: int, s_changes: str = ANYWHERE) -> str:
    """The one thing the user must know about this control and a rewritten program."""
    notes = NOTES.get(control, NOTES[GENERIC])
    words = f"{s_words} S word" + ("" if s_words == 1 else "s")
    return notes.get(s_changes, notes[ANYWHERE]).format(s=s_words, words=words)
