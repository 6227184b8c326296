"""The replay's samples along the path: where they fall, the real spindle speed, F, fz,
the effective diameter and vc at each, and whether the cutter touches the part there.

Every move is sampled at most ``sample_mm`` apart (a move longer than
``ncopt.contacts.locate.MAX_SAMPLES_PER_MOVE`` times that, every length / that many),
both ends included: the start of block ``b`` is sampled with block ``b``'s F (and again,
at the same place, as the end of block ``b-1``), so the jump of fz where F changes is
seen exactly.  Each sample weighs the path length it stands for (trapezoid rule).
"""

from __future__ import annotations

import numpy as np

from ncopt.contacts.geometry import MeshIndex, contacts_from_mesh
from ncopt.contacts.locate import centre_offsets, sample_axes, sample_points, samples_per_move
from ncopt.model import Contacts, Job, Program, Toolpath
from ncopt.planning.operations import spans
from ncopt.reading.stamp import read_stamps, stamped_line
from ncopt.runtime.errors import UsageError
from ncopt.simulate.movetable import Moves
from ncopt.simulate.results import SimSeries
from ncopt.simulate.spindle import Runs, spindle_ramp

__all__ = ["MAX_SAMPLES", "check_sample_count", "normal_groups", "sample_series"]

# The most samples a simulation takes: each costs about 300 bytes of memory at its peak,
# so this is about 3 GB (the 110 m of moves of a 3.4 MB Fusion program take 1.4 million
# at the default 0.1 mm).
MAX_SAMPLES = 10_000_000


def check_sample_count(tp: Toolpath, sample_mm: float, path: str) -> None:
    """Refuse (UsageError) a sample spacing that would take more than MAX_SAMPLES samples
    along the program's moves, naming the spacing that fits: --sample 1e-9 once grew to
    24 GB before the kernel ended it."""
    n = int(samples_per_move(tp, sample_mm).sum()) if tp.n > 1 else 0
    if n <= MAX_SAMPLES:
        return
    length = float(np.sum(np.linalg.norm(np.diff(tp.xyz_mm, axis=0), axis=1)))
    fits = length / max(MAX_SAMPLES - (tp.n - 1), 1)
    least = float(f"{fits * 1.05:.2g}")
    raise UsageError(f"sample spacing {sample_mm:g} mm would take {n:,} samples along the "
                     f"program's {length / 1000:.3g} m of moves; at most {MAX_SAMPLES:,} fit in "
                     f"memory: give a spacing of {least:g} mm or more (--sample)", path)


def normal_groups(prog: Program, tp: Toolpath) -> np.ndarray:
    """(n,) int per toolpath point: whose moves its normal is estimated from without a
    mesh, as the planner does: each operation of the program on its own, and the
    operations an ncopt stamp says were planned together (one group per tool)."""
    line_group = np.zeros(prog.n_lines + 1, dtype=np.int64)
    for k, sp in enumerate(spans(prog, tp)):
        line_group[sp.first_line:sp.last_line + 1] = k + 1
    stamps = read_stamps(prog)
    for st in stamps.values():
        if st.lines is None:  # an ncopt 0.1 stamp: every operation of its tool
            line_group[np.flatnonzero(tp.lines.tool == st.tool)] = -1 - st.tool
            continue
        first, last = (stamped_line(stamps, n) for n in st.lines)
        line_group[first:last + 1] = -1 - st.tool
    return line_group[np.clip(tp.line, 0, prog.n_lines)]


def sample_series(tp: Toolpath, moves: Moves, runs: Runs, job: Job, sample_mm: float,
                  mesh_index: MeshIndex | None, contacts: Contacts | None,
                  path: str) -> tuple[SimSeries, np.ndarray, np.ndarray]:
    """The series along the path, each sample's share of path length (mm) and its move.

    The contacts come from ``contacts`` (one row per point of
    ``ncopt.contacts.locate.sample_points(tp, sample_mm)``), else from ``mesh_index``."""
    xyz_u, point_u = sample_points(tp, sample_mm)
    nm = moves.line.shape[0]
    counts = np.bincount(point_u, minlength=tp.n)[1:]
    first_u = np.cumsum(counts) - counts  # unique sample at the start of each move
    reps = counts + 1
    mv = np.repeat(np.arange(nm), reps)
    k = np.arange(int(reps.sum())) - np.repeat(np.cumsum(reps) - reps, reps)
    frac = k / counts[mv]
    uidx = first_u[mv] + k
    weight = (moves.length_mm / counts)[mv] * np.where((k == 0) | (k == counts[mv]), 0.5, 1.0)
    time_s = moves.t0_s[mv] + frac * moves.dt_s[mv]
    run = runs.of_move[mv]
    s_cmd = moves.target_rpm[mv]
    s_real = spindle_ramp(runs.w0_rpm[run], s_cmd, time_s - moves.t0_s[runs.first_move[run]],
                          job.machine.accel_rpm_s)
    cand = moves.candidate[mv]
    r_eff, touch = _contact_radius(tp, job, xyz_u, uidx, cand, sample_mm, mesh_index,
                                   contacts, path)
    f = moves.speed_mm_min[mv]
    with np.errstate(divide="ignore", invalid="ignore"):
        fz = np.where(moves.feed[mv], f / (job.cutter.teeth * s_real), np.nan)
    d_eff = 2.0 * r_eff
    axis = sample_axes(tp, sample_mm)
    series = SimSeries(dist_mm=moves.d0_mm[mv] + frac * moves.length_mm[mv], time_s=time_s,
                       line=moves.line[mv], xyz_mm=xyz_u[uidx], s_rpm=s_real, s_cmd_rpm=s_cmd,
                       f_mm_min=f, fz_mm=fz, d_eff_mm=d_eff,
                       vc_m_min=np.pi * d_eff * s_real / 1000.0, cutting=cand & touch,
                       tool_axis=None if axis is None else axis[uidx])
    return series, weight, mv


def _contact_radius(tp, job, xyz_u, uidx, cand, sample_mm, mesh_index, contacts, path):
    """R_eff (mm, NaN where not evaluated) and touching flag per series sample."""
    need = np.zeros(xyz_u.shape[0], dtype=bool)
    need[uidx[cand]] = True
    rows = np.flatnonzero(need)
    if contacts is not None:
        if contacts.r_eff_mm.shape[0] != xyz_u.shape[0]:
            raise UsageError(f"the contacts have {contacts.r_eff_mm.shape[0]} rows but the "
                             f"program has {xyz_u.shape[0]} sample points at {sample_mm} mm; "
                             "compute them on ncopt.contacts.locate.sample_points with the same spacing",
                             path)
        r_u, cut_u = contacts.r_eff_mm[rows], contacts.cutting[rows]
    else:  # the tool axis from the program text (5 axes), the centre along it
        axis = sample_axes(tp, sample_mm)
        axis = None if axis is None else axis[rows]
        centers = xyz_u[rows] + centre_offsets(tp, job.cutter, axis)
        got = contacts_from_mesh(centers, mesh_index, job.cutter, tol_mm=job.contact_tol_mm,
                                 axis=axis)
        r_u, cut_u = got.r_eff_mm, got.cutting
    r_all = np.full(xyz_u.shape[0], np.nan)
    touch_all = np.zeros(xyz_u.shape[0], dtype=bool)
    r_all[rows], touch_all[rows] = r_u, cut_u
    return np.where(cand, r_all[uidx], np.nan), touch_all[uidx]
