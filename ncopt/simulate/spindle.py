"""The spindle of the replay: its real speed ramping toward the S in force, and the moves
where it lags so far behind that fz leaves its band.

The real speed ramps toward the commanded one (capped to the machine's range; 0 while
the spindle is off) at ``a = Machine.accel_rpm_s``, the same for deceleration,
continuously across blocks, rapids and air moves: piecewise linear in time (ramp, then
hold), so it is exact at every sample.  When the spindle starts (M3/M4 after a stop) the
control waits for speed: the real speed is the commanded one at once.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ncopt.model import Job, Machine, Program, Toolpath
from ncopt.simulate.movetable import Moves, move_table

__all__ = ["LAG_RPM", "Runs", "lagging_blocks", "spindle_ramp", "spindle_runs"]

# The spindle counts as "not at speed" when it is further than this from its command.
LAG_RPM = 0.5


@dataclass(frozen=True)
class Runs:
    """Stretches of moves with one commanded speed: (nr,) arrays plus the move -> run map."""

    first_move: np.ndarray
    w0_rpm: np.ndarray  # real speed at the start of the run
    of_move: np.ndarray  # (nm,) run of each move


def spindle_runs(moves: Moves, a: float) -> Runs:
    """Real spindle speed at the start of each run of constant command.

    The speed at the end of a run depends on the one at its start: see
    :func:`_run_start_speeds`.
    """
    target = moves.target_rpm
    brk = moves.start.copy()
    if brk.size:
        brk[0] = True
        brk[1:] |= target[1:] != target[:-1]
    first = np.flatnonzero(brk)
    end = moves.t0_s[-1] + moves.dt_s[-1] if first.size else 0.0
    dur = np.append(moves.t0_s[first[1:]], end)[:first.size] - moves.t0_s[first]
    reach = np.where(dur > 0, a * dur, 0.0)
    w0 = _run_start_speeds(target[first], moves.start[first], reach)
    return Runs(first_move=first, w0_rpm=w0, of_move=np.cumsum(brk) - 1)


# _run_start_speeds: rounds, and runs recomputed per run, before the rest goes run by run
RUN_ROUNDS, RUN_WORK = 200, 3


def _ramped(w: np.ndarray, t: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The speed after ramping from ``w`` toward ``t`` by at most ``d``, stopping at ``t``
    (``w + d`` reaching ``t`` is ``t``; NaN anywhere gives ``t``)."""
    up, down = w + d, w - d
    return np.where(w < t, np.where(up < t, up, t), np.where(down > t, down, t))


def _run_start_speeds(t: np.ndarray, s: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """(nr,) speed at the start of each run: 0 at first, the run's command ``t`` where it
    starts the spindle (``s``), else where the run before left it, ramping toward its
    command by at most its ``reach`` (RPM).

    A recurrence, solved without a loop over the runs: first guess that every run
    reached its command (most do), then recompute the runs after those whose guess was
    wrong, as often as a wrong guess still changes the next one (the longest chain of
    runs that end short of their command: ~70 rounds on the 700k runs of a 1M-block
    rewrite).  Every run before the first one still to be recomputed is then right;
    after ``RUN_ROUNDS`` rounds, or once ``RUN_WORK`` times as many runs as there are
    were recomputed (a spindle that lags behind its S words over thousands of runs),
    the rest is finished run by run.  Each run's value is the same float
    operations on the same values as the run-by-run loop, so the result is that
    loop's, bit for bit."""
    n = t.shape[0]
    w0 = np.empty(n)
    if n == 0:
        return w0
    w0[0] = 0.0
    w0[1:] = t[:-1]
    w0[s] = t[s]
    k = None  # runs whose next one is to be (re)computed; None: all of them
    budget = RUN_WORK * n  # runs recomputed in all rounds: past that a loop is cheaper
    for _ in range(RUN_ROUNDS):
        if k is not None and not k.size:
            return w0
        budget -= n if k is None else k.size
        if budget < 0:
            break
        if k is None:
            j = slice(1, n)
            nxt = np.where(s[j], t[j], _ramped(w0[:-1], t[:-1], reach[:-1]))
        else:
            j = k + 1
            nxt = np.where(s[j], t[j], _ramped(w0[k], t[k], reach[k]))
        old = w0[j]
        changed = (nxt != old) & ~(np.isnan(nxt) & np.isnan(old))
        j = np.flatnonzero(changed) + 1 if k is None else j[changed]
        w0[j] = nxt[changed]
        k = j[j < n - 1]
    if k is None or k.size:
        _runs_one_by_one(w0, t, s, reach, 0 if k is None else int(k[0]))
    return w0


def _runs_one_by_one(w0: np.ndarray, t: np.ndarray, s: np.ndarray, reach: np.ndarray,
                     first: int) -> None:
    """:func:`_run_start_speeds` from run ``first`` on (right up to it), run by run."""
    w = float(w0[first])
    target, starts, ramp = t.tolist(), s.tolist(), reach.tolist()
    out = memoryview(w0)
    for i in range(first, w0.shape[0] - 1):
        if w < target[i]:
            w += ramp[i]
            if not w < target[i]:
                w = target[i]
        else:
            w -= ramp[i]
            if not w > target[i]:
                w = target[i]
        if starts[i + 1]:
            w = target[i + 1]
        out[i + 1] = w


def lagging_blocks(prog: Program, tp: Toolpath, s_rpm: np.ndarray, f_mm_min: np.ndarray,
                   machine: Machine, rev_mm: np.ndarray, band: float) -> np.ndarray:
    """Toolpath points (the moves ending there) where the real spindle, ramping toward the
    commanded S at its acceleration, leaves fz out of its band at the move's start or end
    while it is not at the commanded speed (as
    :func:`ncopt.simulate.replay.simulate_program` flags a lag).

    ``s_rpm``, ``f_mm_min``: (n,) S and F in force per point; ``rev_mm``: (n,) the target
    feed per revolution fz z of each move to check (NaN: not checked).  The same machine
    model as the simulation, at the ends of the moves only (fz is monotone inside a move:
    F is constant and the spindle ramps one way), so it is cheap enough to run after
    every rewrite.
    """
    job = Job(machine=machine)
    moves = move_table(prog, replace(tp, spindle_rpm=s_rpm, feed_mm_min=f_mm_min), job,
                       np.ones(tp.n - 1, dtype=bool))
    runs = spindle_runs(moves, machine.accel_rpm_s)
    run = runs.of_move
    t0 = moves.t0_s - moves.t0_s[runs.first_move[run]]
    a = machine.accel_rpm_s
    start = spindle_ramp(runs.w0_rpm[run], moves.target_rpm, t0, a)
    end = spindle_ramp(runs.w0_rpm[run], moves.target_rpm, t0 + moves.dt_s, a)
    rev = rev_mm[1:]
    check = np.isfinite(rev) & moves.feed & moves.known & (moves.target_rpm > 0)
    speed = moves.speed_mm_min

    def out_of_band(real: np.ndarray) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            dev = speed / real / rev - 1.0
        return (dev > band * (1 + 1e-6) + 1e-9) | (dev < -band * (1 + 1e-6) - 1e-9)

    # fz is monotone along a move; while the spindle lags it runs from its value at the
    # start to its value where the spindle comes within LAG_RPM of the command (or, if it
    # never does, to its value at the end)
    target = moves.target_rpm
    lags_start = np.abs(start - target) > LAG_RPM
    lags_end = np.abs(end - target) > LAG_RPM
    near = target + np.sign(start - target) * LAG_RPM
    bad = check & lags_start & (out_of_band(start) | np.where(lags_end, out_of_band(end),
                                                               out_of_band(near)))
    return np.flatnonzero(bad) + 1


def spindle_ramp(w0_rpm: np.ndarray, target_rpm: np.ndarray, tau_s: np.ndarray,
                 a_rpm_s: float) -> np.ndarray:
    """Speed ``tau_s`` after a ramp from ``w0_rpm`` toward ``target_rpm`` began, RPM.

    Linear at ``a_rpm_s`` until the target is reached, then constant.
    """
    step = np.where(tau_s > 0, a_rpm_s * tau_s, 0.0)
    return np.where(w0_rpm < target_rpm, np.minimum(w0_rpm + step, target_rpm),
                    np.maximum(w0_rpm - step, target_rpm))
