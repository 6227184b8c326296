"""Machine kinematics: the tool axis in the part frame from rotary axis angles.

With tool-centre-point control (TCP: Sinumerik TRAORI, Fanuc G43.4, Heidenhain
M128, LinuxCNC's trt kinematics) the programmed X Y Z are the tool tip in the
part frame and the rotary words only turn the tool, so all ncopt needs from
the machine is the direction of the tool: the unit vector ``e`` from the tip
toward the spindle, in the part frame.  It depends on which rotary axis
carries which, and on the directions the control counts them.

ISO 841 directions: a positive angle turns the tool, relative to the part,
by the right-hand rule about the axis (A about X, B about Y, C about Z); a
rotary table that carries the part therefore turns the other way.  With these
directions the orientation depends only on which axis is outer (carries the
other): table-table, head-table and head-head machines with C outer and the
tilt inner all give ``e = Rz(C) R_tilt ẑ``.

=======================  =============================  ================================
name                     machine                        e = (ex, ey, ez)
=======================  =============================  ================================
xyzac-trt                table A (X) carrying table C   (sinA sinC, -sinA cosC, cosA)
xyzac-head-table         head A (X), table C            same as xyzac-trt
xyzac-trt-linuxcnc       LinuxCNC xyzac-trt-kins with   (sinA sinC,  sinA cosC, cosA)
                         its default directions
xyzbc-trt                table B (Y) carrying table C   (sinB cosC,  sinB sinC, cosB)
xyzbc-head-table         head B (Y), table C            same as xyzbc-trt
xyzbc-head-head          head C carrying head B         same as xyzbc-trt
xyzbc-trt-linuxcnc       LinuxCNC xyzbc-trt-kins with   (-sinB cosC, sinB sinC, cosB)
                         its default directions
xyzbc-5axis-linuxcnc     LinuxCNC 5axiskins (bridge     (-sinB cosC, -sinB sinC, cosB)
                         mill: head C carrying head B)
=======================  =============================  ================================

LinuxCNC's trt kinematics count both rotations opposite to ISO 841 unless the
HAL pin ``conventional-directions`` is set (its 5-axis sim configs, whose
``M428`` switches them on, leave it at 0): the ``-linuxcnc`` variants are
those, derived from ``trtfuncs.c`` (the part-frame image of the joint +Z
direction in ``xyzacKinematicsForward``/``xyzbcKinematicsForward``).
LinuxCNC's ``5axiskins`` puts the tool tip at ``s2r(L, C, 180 - B)`` from the
pivot (its note 10: the tilt counts the other way), hence its row.

``vector`` names programs whose blocks carry the tool vector itself (Fanuc
G43.5 I J K, Sinumerik A3= B3= C3=); those need no machine data and are read
whatever ``--kinematics`` says.

Between two block ends a TCP control moves the tool axis one of two ways:
rotary angles are interpolated linearly (LinuxCNC, Fanuc G43.4, Sinumerik
ORIAXES), vectors along the great circle between them (Fanuc G43.5,
Sinumerik ORIVECT): ``ncopt.contacts.locate.axes_between`` does the same, the first
through :meth:`Kinematics.tool_axis` of the turned angles, the second with
:func:`blend`.

Tilted working planes (3+2): Fanuc ``G68.2 X Y Z I J K`` (Euler angles, Z then
the new X then the new Z) sets a frame ``p_part = o + R p`` with ``R =
Rz(I) Rx(J) Rz(K)``; after ``G53.1`` the tool points along the frame's Z,
``e = R ẑ``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ncopt.runtime.errors import UsageError

VECTOR = "vector"


def _ac_iso(a, b, c):
    return np.stack([np.sin(a) * np.sin(c), -np.sin(a) * np.cos(c), np.cos(a)], axis=-1)


def _ac_linuxcnc(a, b, c):
    return np.stack([np.sin(a) * np.sin(c), np.sin(a) * np.cos(c), np.cos(a)], axis=-1)


def _bc_iso(a, b, c):
    return np.stack([np.sin(b) * np.cos(c), np.sin(b) * np.sin(c), np.cos(b)], axis=-1)


def _bc_linuxcnc(a, b, c):
    return np.stack([-np.sin(b) * np.cos(c), np.sin(b) * np.sin(c), np.cos(b)], axis=-1)


def _bc_5axiskins(a, b, c):
    return np.stack([-np.sin(b) * np.cos(c), -np.sin(b) * np.sin(c), np.cos(b)], axis=-1)


@dataclass(frozen=True)
class Kinematics:
    """A machine's rotary axes and the tool axis they give.

    name : what ``--kinematics`` takes;  axes : the two rotary letters it reads
    machine : what the machine looks like;  formula : e in the part frame
    """

    name: str
    axes: str
    machine: str
    formula: str
    _fn: Callable = None

    def tool_axis(self, angles_deg: np.ndarray) -> np.ndarray:
        """(m, 3) unit tool axes from (m, 3) A B C angles in degrees."""
        rad = np.radians(np.asarray(angles_deg, dtype=np.float64))
        return self._fn(rad[..., 0], rad[..., 1], rad[..., 2])


KINEMATICS = {k.name: k for k in (
    Kinematics("xyzac-trt", "AC", "table A (about X) carrying table C (about Z), ISO 841",
               "(sinA sinC, -sinA cosC, cosA)", _ac_iso),
    Kinematics("xyzac-head-table", "AC", "head A (about X), table C (about Z), ISO 841",
               "(sinA sinC, -sinA cosC, cosA)", _ac_iso),
    Kinematics("xyzac-trt-linuxcnc", "AC", "LinuxCNC xyzac-trt-kins, default directions "
               "(its 5-axis sim configs, M428)", "(sinA sinC, sinA cosC, cosA)", _ac_linuxcnc),
    Kinematics("xyzbc-trt", "BC", "table B (about Y) carrying table C (about Z), ISO 841",
               "(sinB cosC, sinB sinC, cosB)", _bc_iso),
    Kinematics("xyzbc-head-table", "BC", "head B (about Y), table C (about Z), ISO 841",
               "(sinB cosC, sinB sinC, cosB)", _bc_iso),
    Kinematics("xyzbc-head-head", "BC", "head C carrying head B (about Y), ISO 841",
               "(sinB cosC, sinB sinC, cosB)", _bc_iso),
    Kinematics("xyzbc-trt-linuxcnc", "BC", "LinuxCNC xyzbc-trt-kins, default directions",
               "(-sinB cosC, sinB sinC, cosB)", _bc_linuxcnc),
    Kinematics("xyzbc-5axis-linuxcnc", "BC", "LinuxCNC 5axiskins (bridge mill, head C "
               "carrying head B)", "(-sinB cosC, -sinB sinC, cosB)", _bc_5axiskins),
)}
NAMES = tuple(KINEMATICS) + (VECTOR,)


def check_name(name: str | None) -> str | None:
    """``name`` if ncopt knows it (None passes); raises UsageError naming the choices."""
    if name is None or name in NAMES:
        return name
    raise UsageError(f"--kinematics must be one of {', '.join(NAMES)}, not {name!r}")


def fitting(rotary) -> str:
    """'xyzac-trt, xyzac-head-table or xyzac-trt-linuxcnc': the kinematics that turn all
    the rotary axes named (letters), '' where none does."""
    fits = [k.name for k in KINEMATICS.values() if set(rotary) <= set(k.axes)]
    return (", ".join(fits[:-1]) + " or " + fits[-1]) if len(fits) > 1 else "".join(fits)


def unit(v: np.ndarray) -> np.ndarray:
    """Rows scaled to unit length (zero rows stay zero)."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v, dtype=np.float64), where=n > 0)


def blend(e0: np.ndarray, e1: np.ndarray, frac: np.ndarray) -> np.ndarray:
    """Unit axes between ``e0`` and ``e1`` (m, 3) at ``frac`` (m,): the normalised
    linear blend, which runs along their great circle as a TCP control moves a
    vector (an exact reversal has no circle: the end vector is kept)."""
    f = np.asarray(frac, dtype=np.float64)[..., None]
    mix = unit(e0 * (1.0 - f) + e1 * f)
    return np.where(np.linalg.norm(mix, axis=-1, keepdims=True) > 0.5, mix, e1)


def lean(e: np.ndarray, d: np.ndarray, angle_deg) -> np.ndarray:
    """(m, 3) the unit axes ``e`` leaned ``angle_deg`` toward the directions ``d`` (m, 3),
    in the plane of the two (Fanuc G43.5 Q: the tool inclined toward the direction of
    travel); NaN rows where ``d`` runs along ``e`` (no plane) or is zero."""
    e = np.asarray(e, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    t = d - np.einsum("ij,ij->i", d, e)[:, None] * e
    size = np.linalg.norm(t, axis=1)
    ok = size > 1e-9 * np.maximum(np.linalg.norm(d, axis=1), 1e-300)
    u = np.divide(t, size[:, None], out=np.zeros_like(t), where=ok[:, None])
    q = np.radians(np.broadcast_to(np.asarray(angle_deg, dtype=np.float64), size.shape))
    out = np.cos(q)[:, None] * e + np.sin(q)[:, None] * u
    out[~ok] = np.nan
    return out


def turn_deg(e0: np.ndarray, e1: np.ndarray, a0: np.ndarray, a1: np.ndarray,
             kinematics: str | None, at_least: float = 0.0) -> np.ndarray:
    """(m,) how far the tool axis turns over each move, degrees: the length of its path
    on the unit sphere from ``e0`` to ``e1`` (m, 3).  Where ``a0`` and ``a1`` (m, 3) give
    both ends' angles in ``kinematics`` the control turns them linearly and the path is
    followed (sampled every 1/360 of the move); elsewhere the axis moves along the great
    circle, the angle between its ends.  Rows whose rotary turns add up to no more than
    ``at_least`` degrees (which bounds the path) keep that angle, a lower bound."""
    out = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", e0, e1), -1.0, 1.0)))
    kin = KINEMATICS.get(kinematics)
    if kin is None:
        return out
    both = np.isfinite(a0).all(axis=1) & np.isfinite(a1).all(axis=1)
    bound = np.where(both, np.abs(np.nan_to_num(a1 - a0)).sum(axis=1), 0.0)
    rows = np.flatnonzero(bound > at_least)
    if rows.size:
        f = np.linspace(0.0, 1.0, 361)[None, :, None]
        ang = a0[rows, None, :] + (a1[rows] - a0[rows])[:, None, :] * f
        e = kin.tool_axis(ang)
        step = np.clip(np.einsum("ijk,ijk->ij", e[:, 1:], e[:, :-1]), -1.0, 1.0)
        out[rows] = np.degrees(np.arccos(step)).sum(axis=1)
    return out


def tilt_deg(axis: np.ndarray) -> np.ndarray:
    """(m,) angle of each unit axis from +Z, degrees."""
    return np.degrees(np.arccos(np.clip(np.asarray(axis)[..., 2], -1.0, 1.0)))


def rot_x(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_z(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def euler_zxz(i_deg: float, j_deg: float, k_deg: float) -> np.ndarray:
    """G68.2's frame rotation: Z by I, then the new X by J, then the new Z by K."""
    i, j, k = np.radians([i_deg, j_deg, k_deg])
    return rot_z(i) @ rot_x(j) @ rot_z(k)
