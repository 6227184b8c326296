"""The report of a replay: times, the cut's fz and vc against their targets, where the
spindle lags so that fz leaves its band, and the warnings (a cut with the spindle
stopped, S above the machine's range, moves not timed, moves sampled coarsely).

Cut statistics cover the samples where the cutter touches the part on a feed move,
each weighted by the path length it stands for; NaN when nothing cuts.
"""

from __future__ import annotations

import math

import numpy as np

from ncopt.contacts.locate import MAX_SAMPLES_PER_MOVE
from ncopt.model import CuttingData, Machine, Toolpath
from ncopt.simulate.movetable import Moves
from ncopt.simulate.results import LagStretch, SimReport, SimSeries
from ncopt.simulate.spindle import LAG_RPM

__all__ = ["coarse_moves", "replay_warnings", "summarize"]


def summarize(path: str, moves: Moves, series: SimSeries, weight: np.ndarray, mv: np.ndarray,
              cut: CuttingData, band: float, sample_mm: float, s_words: int,
              warnings: tuple[str, ...]) -> SimReport:
    """The report of the samples ``series`` (``weight``: path length each stands for, mm;
    ``mv``: its move) against the targets ``cut``, with fz band ``band`` (relative)."""
    move_cuts = np.zeros(moves.line.shape[0], dtype=bool)
    np.logical_or.at(move_cuts, mv, series.cutting)
    cutting_time = float(moves.dt_s[move_cuts].sum()) / 60.0
    feed_time = float(moves.dt_s[moves.feed & ~move_cuts].sum()) / 60.0
    rapid_time = float(moves.dt_s[moves.rapid].sum()) / 60.0
    c = series.cutting
    fz_dev = series.fz_mm[c] / cut.fz_mm - 1.0
    vc_dev = series.vc_m_min[c] / cut.vc_m_min - 1.0
    w, lines = weight[c], series.line[c]
    cut_w = float(w.sum())
    in_band = np.abs(fz_dev) <= band
    return SimReport(
        path=path, vc_target_m_min=cut.vc_m_min, fz_target_mm=cut.fz_mm, band_pct=100 * band,
        sample_mm=sample_mm, samples=len(series), cutting_time_min=cutting_time,
        feed_moves_time_min=cutting_time + feed_time,
        feed_time_min=feed_time, rapid_time_min=rapid_time,
        total_time_min=float(moves.dt_s.sum()) / 60.0,
        cut_length_mm=float(moves.length_mm[move_cuts].sum()),
        fz_in_band_pct=100.0 * float(w[in_band].sum()) / cut_w if cut_w > 0 else math.nan,
        fz_max_over_pct=_extreme(100 * fz_dev), fz_max_over_line=_where(fz_dev, lines),
        fz_min_under_pct=_extreme(-100 * fz_dev), fz_min_under_line=_where(-fz_dev, lines),
        vc_max_over_pct=_extreme(100 * vc_dev), vc_max_over_line=_where(vc_dev, lines),
        vc_mean_m_min=float(np.sum(w * series.vc_m_min[c])) / cut_w if cut_w > 0 else math.nan,
        max_rpm=float(series.s_rpm.max()) if len(series) else 0.0,
        max_rpm_line=int(series.line[np.argmax(series.s_rpm)]) if len(series) else 0,
        s_words=s_words, lag=_lag_stretches(series, weight, cut, band), warnings=warnings)


def _extreme(x: np.ndarray) -> float:
    """Largest value ignoring NaN (inf counts); NaN for no data."""
    x = x[~np.isnan(x)]
    return float(x.max()) + 0.0 if x.size else math.nan  # + 0.0: no "-0.0" in reports


def _where(x: np.ndarray, lines: np.ndarray) -> int:
    """The line of the largest value ignoring NaN; 0 for no data."""
    ok = ~np.isnan(x)
    if not ok.any():
        return 0
    return int(lines[ok][np.argmax(x[ok])])


def _lag_stretches(series: SimSeries, weight: np.ndarray, cut: CuttingData,
                   band: float) -> tuple[LagStretch, ...]:
    """Consecutive cut samples with fz out of band while the spindle is not at speed, on
    moves whose F means the target fz at the commanded S (a move the program runs at
    another feed per tooth, a ramp or a plunge at its own feed, is off target by design,
    not because the spindle lags)."""
    dev = series.fz_mm / cut.fz_mm - 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        meant = series.fz_mm * series.s_rpm / series.s_cmd_rpm / cut.fz_mm - 1.0
    at_target = np.abs(meant) <= 2.0 * band
    lagging = np.abs(series.s_rpm - series.s_cmd_rpm) > LAG_RPM
    idx = np.flatnonzero(series.cutting & ~(np.abs(dev) <= band) & lagging & at_target)
    if idx.size == 0:
        return ()
    new = np.concatenate(([True], np.diff(idx) > 1))
    group = np.cumsum(new) - 1
    first, last = idx[new], idx[np.concatenate((new[1:], [True]))]
    length = np.bincount(group, weights=weight[idx])
    mag = np.nan_to_num(np.abs(dev[idx]), nan=np.inf)
    order = np.lexsort((-mag, group))  # by stretch, worst first
    worst = idx[order[np.concatenate(([True], np.diff(group[order]) > 0))]]
    return tuple(LagStretch(int(series.line[a]), int(series.line[b]), float(n),
                            float(100 * dev[w]), float(series.s_cmd_rpm[w]), float(series.s_rpm[w]))
                 for a, b, n, w in zip(first, last, length, worst))


def coarse_moves(path: str, tp: Toolpath, moves: Moves, sample_mm: float) -> tuple[str, ...]:
    """Moves too long to sample every ``sample_mm``: where, and how coarsely."""
    chord = np.linalg.norm(np.diff(tp.xyz_mm, axis=0), axis=1)
    long = np.flatnonzero(chord > MAX_SAMPLES_PER_MOVE * sample_mm)
    if long.size == 0:
        return ()
    i = long[np.argmax(chord[long])]
    return (f"{path}:{moves.line[i]}: a move of {chord[i]:.6g} mm is sampled every "
            f"{chord[i] / MAX_SAMPLES_PER_MOVE:.6g} mm, not {sample_mm:g} "
            f"({long.size} move{'s' if long.size > 1 else ''} longer than "
            f"{MAX_SAMPLES_PER_MOVE * sample_mm:g} mm; at most {MAX_SAMPLES_PER_MOVE} samples "
            "a move)",)


def replay_warnings(path: str, tp: Toolpath, moves: Moves, machine: Machine,
                    series: SimSeries) -> tuple[str, ...]:
    """The interpreter's warnings, then a cut with the spindle stopped, S words above the
    machine's range and the moves not timed (each named by its first line)."""
    out = list(tp.warnings)
    stopped = np.flatnonzero(series.cutting & (series.s_rpm <= 0))
    if stopped.size:
        out.append(f"{path}:{series.line[stopped[0]]}: the cutter touches the part with the "
                   "spindle stopped; check M3/M5 and S")
    s = tp.spindle_rpm[1:]
    over = np.flatnonzero((s > machine.max_rpm) & (moves.target_rpm > 0))
    if over.size:
        out.append(f"{path}:{moves.line[over[0]]}: S{s[over[0]]:g} is above the machine's "
                   f"{machine.max_rpm:g} RPM ({over.size} moves); the control clamps it")
    # the first move always starts from an unknown position
    unknown = np.flatnonzero(~moves.known & (moves.rapid | moves.feed))[1:]
    if unknown.size:
        out.append(f"{path}:{moves.line[unknown[0]]}: {unknown.size} moves from an unknown "
                   "position, in G95 or G41/G42 mode or with a tool axis ncopt cannot read are "
                   "not timed nor evaluated")
    return tuple(out)
