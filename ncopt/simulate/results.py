"""The records a simulation gives: its report (:class:`SimReport`, with the spindle-lag
stretches it found) and its series of samples along the path (:class:`SimSeries`).

Times in minutes or seconds, lengths in mm, speeds in RPM as each field names; the
machine model that fills them is in :mod:`ncopt.simulate.replay`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ncopt.motion.kinematics import tilt_deg

__all__ = ["LagStretch", "SimReport", "SimSeries"]

# to_dict lists this many lag stretches (in program order) and counts the rest
_LAG_LISTED = 100


@dataclass(frozen=True)
class LagStretch:
    """A stretch of cut where fz leaves its band while the spindle is not at speed.

    The program commands S faster than the spindle can follow (and F with it):
    fz is off until the spindle catches up.

    first_line, last_line : 1-based source lines of the stretch
    length_mm : cut length of the stretch
    worst_fz_pct : fz deviation from its target with the largest magnitude, %
    s_cmd_rpm, s_real_rpm : commanded and real spindle speed at that worst sample
    """

    first_line: int
    last_line: int
    length_mm: float
    worst_fz_pct: float
    s_cmd_rpm: float
    s_real_rpm: float


@dataclass(frozen=True)
class SimReport:
    """What the simulated machine did with a program.

    Times in minutes, lengths in mm, speeds in RPM, ``*_pct`` in percent of the
    target.  ``*_line`` are 1-based source lines (0 when there is no cut).
    Cut statistics cover samples where the cutter touches the part on a feed
    move; NaN when nothing cuts.

    cutting_time_min : feed blocks that cut at some sample
    feed_moves_time_min : every timed feed move (``ncopt.motion.times``): the cutting time that
        inspect, rewrite and batch give for the same program
    feed_time_min : the other feed blocks (approach, retract, air)
    rapid_time_min, total_time_min
    cut_length_mm : length of the feed blocks that cut
    fz_in_band_pct : share of the cut length with ``|fz / fz_target - 1| <= band``
    fz_max_over_pct : largest ``fz / fz_target - 1`` (may be negative)
    fz_min_under_pct : largest ``1 - fz / fz_target`` (may be negative)
    vc_max_over_pct : largest ``vc / vc_target - 1``; negative when vc stays below
    vc_mean_m_min : length-weighted mean vc over the cut
    max_rpm : highest real spindle speed anywhere
    s_words : S words in the program text
    lag : stretches where fz leaves its band because the spindle is not at speed
    """

    path: str
    vc_target_m_min: float
    fz_target_mm: float
    band_pct: float
    sample_mm: float
    samples: int
    cutting_time_min: float
    feed_time_min: float
    rapid_time_min: float
    total_time_min: float
    cut_length_mm: float
    fz_in_band_pct: float
    fz_max_over_pct: float
    fz_max_over_line: int
    fz_min_under_pct: float
    fz_min_under_line: int
    vc_max_over_pct: float
    vc_max_over_line: int
    vc_mean_m_min: float
    max_rpm: float
    max_rpm_line: int
    s_words: int
    lag: tuple[LagStretch, ...] = ()
    warnings: tuple[str, ...] = ()
    feed_moves_time_min: float = float("nan")  # every timed feed move (ncopt.motion.times)
    tool: int = -1  # the T number evaluated (-1: the program names none)
    cutter: str = ""  # the cutter evaluated, "D16 ball, 2 teeth"
    cutter_from: str = ""  # where it came from: "the options", "line 5: (...)", a stamp

    @property
    def spindle_lag_breaks_fz(self) -> bool:
        """The program commands S faster than the spindle follows, and fz suffers."""
        return len(self.lag) > 0

    def to_dict(self) -> dict:
        """Plain JSON-ready values; NaN and infinities become None."""
        out = asdict(self)
        out["lag"] = [_clean(asdict(s)) for s in self.lag[:_LAG_LISTED]]
        out["lag_count"] = len(self.lag)
        out["warnings"] = list(self.warnings)
        out["spindle_lag_breaks_fz"] = self.spindle_lag_breaks_fz
        return _clean(out)


def _clean(d: dict) -> dict:
    """``d`` with NaN and infinities as None (JSON has neither)."""
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
            for k, v in d.items()}


@dataclass(frozen=True)
class SimSeries:
    """The simulation along the path, one row per sample, (m,) arrays.

    dist_mm : path length from the program start (moves from unknown
        positions count 0)
    time_s : time from the program start
    line : 1-based source line of the block the sample belongs to
    xyz_mm : (m, 3) programmed point
    s_rpm : real spindle speed; s_cmd_rpm : speed commanded (capped to the machine)
    f_mm_min : feed (the rapid rate on rapids)
    fz_mm : ``F / (z S)`` on feed moves, NaN on rapids (inf with the spindle stopped)
    d_eff_mm : effective cutting diameter ``2 R_eff`` (NaN where not evaluated)
    vc_m_min : ``pi d_eff S / 1000``
    cutting : the cutter touches the part on a feed move
    tool_axis : (m, 3) unit tool axis from the program text (5 axes), None: +Z
    """

    dist_mm: np.ndarray
    time_s: np.ndarray
    line: np.ndarray
    xyz_mm: np.ndarray
    s_rpm: np.ndarray
    s_cmd_rpm: np.ndarray
    f_mm_min: np.ndarray
    fz_mm: np.ndarray
    d_eff_mm: np.ndarray
    vc_m_min: np.ndarray
    cutting: np.ndarray
    tool_axis: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.dist_mm.shape[0])

    def write_csv(self, path: str | Path) -> None:
        """Write the series as CSV with a header row (5 axes: and the tool's tilt from +Z)."""
        cols = np.column_stack((self.dist_mm, self.time_s, self.line, self.xyz_mm, self.s_rpm,
                                self.s_cmd_rpm, self.f_mm_min, self.fz_mm, self.d_eff_mm,
                                self.vc_m_min, self.cutting))
        header = ("dist_mm,time_s,line,x_mm,y_mm,z_mm,s_rpm,s_cmd_rpm,f_mm_min,fz_mm,"
                  "d_eff_mm,vc_m_min,cutting")
        fmt = ["%.4f", "%.5f", "%d", "%.4f", "%.4f", "%.4f", "%.2f", "%.2f", "%.3f", "%.6f",
               "%.4f", "%.3f", "%d"]
        if self.tool_axis is not None:
            cols = np.column_stack((cols, tilt_deg(self.tool_axis)))
            header, fmt = header + ",tilt_deg", fmt + ["%.3f"]
        np.savetxt(path, cols, fmt=fmt, delimiter=",", header=header, comments="")
