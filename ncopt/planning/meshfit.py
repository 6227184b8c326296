"""How well the part's mesh fits the planned cut, and the refusal of a mesh that is not
this program's part (MeshError, exit 4)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncopt.contacts.locate import Sampled
from ncopt.model import Toolpath
from ncopt.motion.modal import row_norms
from ncopt.planning.medians import weighted_median
from ncopt.planning.operations import SLOW_FEED
from ncopt.runtime.errors import MeshError


@dataclass(frozen=True)
class MeshFit:
    """How well the part's mesh fits the planned cut (with a mesh only).

    touching_pct : share of the planned feed length whose cutter touches the mesh within
        the contact tolerance;  air_pct : clear of it;  gouge_pct : inside it
    deepest_gouge_mm : how far the cutter goes into the mesh at worst (0: never)
    gouge_line, air_line : 1-based first line that gouges / is in the air (0: none)
    """

    touching_pct: float
    air_pct: float
    gouge_pct: float
    deepest_gouge_mm: float
    gouge_line: int
    air_line: int


AIR_LIMIT_PCT = 50.0  # more of the planned cut in the air: the mesh is not this part
GOUGE_LIMIT_PCT = 10.0  # more of it inside the part: wrong mesh, units, offset or stock


def mesh_fit(sm: Sampled, tp: Toolpath, selected: np.ndarray, tol_mm: float) -> MeshFit | None:
    """The fit of the mesh over the samples ``sm`` of the ``selected`` points (None: no
    mesh, or no such sample)."""
    if sm.gap_mm is None:
        return None
    use = selected[sm.point] & (sm.point > 0) & _surface_moves(tp, selected)[sm.point]
    if not use.any():
        return None
    gap, line = sm.gap_mm[use], tp.line[sm.point[use]]
    air, gouge = gap > tol_mm, gap < -tol_mm
    n = float(gap.size)
    first = lambda m: int(line[np.argmax(m)]) + 1 if m.any() else 0  # noqa: E731
    return MeshFit(100.0 * float(np.sum(~air & ~gouge)) / n, 100.0 * float(air.sum()) / n,
                   100.0 * float(gouge.sum()) / n, float(max(-gap.min(), 0.0)),
                   first(gouge), first(air))


def _surface_moves(tp: Toolpath, selected: np.ndarray) -> np.ndarray:
    """(n,) bool: the selected moves that follow the surface: not plunges or retracts
    (within 25 deg of the axis), not at a reduced feed (entries, links)."""
    d = np.diff(tp.xyz_mm, axis=0, prepend=tp.xyz_mm[:1])
    length = row_norms(d)
    across = np.abs(d[:, 2]) <= 0.9 * np.maximum(length, 1e-12)
    out = selected & across
    if out.any():
        f = tp.feed_mm_min[out]
        typical = weighted_median(f, tp.seg_len_mm[out], in_order=False)
        out &= tp.feed_mm_min >= SLOW_FEED * typical
    return out


def check_fit(fit: MeshFit | None, tool: int, tol_mm: float, path: str) -> None:
    """Refuse (MeshError, exit 4) a mesh that is not the part this program cuts."""
    if fit is None or (fit.air_pct <= AIR_LIMIT_PCT and fit.gouge_pct <= GOUGE_LIMIT_PCT):
        return
    where = fit.air_line if fit.air_pct > AIR_LIMIT_PCT else fit.gouge_line
    raise MeshError(
        f"the mesh does not fit T{tool}'s cut: {fit.touching_pct:.1f} % of it touches the mesh "
        f"within {tol_mm:g} mm, {fit.air_pct:.1f} % is in the air, {fit.gouge_pct:.1f} % inside "
        f"the part (deepest {fit.deepest_gouge_mm:.3g} mm); first line that does not fit: "
        f"{where}.  Check that it is this program's part, in mm, in the program's work "
        "coordinates; for a program that leaves an allowance give --stock MM", path, where or None)
