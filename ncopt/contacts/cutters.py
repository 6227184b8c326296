"""Cutter shapes: effective cutting radius from a contact normal.

The tool axis ``e`` is a unit vector from the tip toward the spindle: +Z in
3-axis milling (``axis=None``), any direction in 5-axis.  A ball-end mill of
radius ``R`` and a bull-nose (toroidal) mill of radius ``R`` with corner
radius ``r`` are the same family: the ball is the case ``r == R``.

Geometry (docs/method.md, "The effective cutting radius", the
paper's eq. (1)), with ``c = n . e`` (``nz`` in 3 axes):

* ball: the CC point is ``SC - R n`` and its distance from the tool axis is
  ``R_eff = R sqrt(1 - c^2)``, i.e. ``R sin(angle(n, e))``;
* bull-nose, contact on the torus: ``R_eff = (R - r) + r sqrt(1 - c^2)``.
  As ``c -> 1`` the contact leaves the torus for the flat bottom (the inner
  edge of the torus, then the whole flat disc).  ``R - r`` is the right limit:
  it is the radius of the torus' inner edge, where the cutting edge meets the
  flat, and it is what the formula gives at ``nz = 1``.  The flat disc itself
  does not cut at a defined radius; the planner must not divide by anything
  smaller than ``R - r``.
"""

from __future__ import annotations

import numpy as np

from ncopt.model import Cutter

__all__ = ["r_eff_mm", "center_offset_mm", "required_rpm"]


def r_eff_mm(cutter: Cutter, normal: np.ndarray, axis: np.ndarray | None = None) -> np.ndarray:
    """Effective cutting radius at a contact, from the surface normal there.

    Parameters
    ----------
    cutter : Cutter
        Ball (``corner_radius_mm == radius_mm``) or bull-nose.
    normal : (m, 3) float64
        Unit outward surface normal at the CC point (oriented toward the tool).
        Only ``n . e`` is used; it is clipped to ``[-1, 1]`` against round-off.
    axis : (m, 3) float64 or None
        Unit tool axis at each contact; None: +Z (``n . e = nz``).

    Returns
    -------
    (m,) float64
        Distance of the CC point from the tool axis, mm:
        ``(R - r) + r sqrt(1 - nz^2)`` (``R - r == 0`` for a ball).  On a
        bull-nose with ``nz -> 1`` this tends to ``R - r``, the inner edge of
        the torus where the flat bottom begins.
    """
    n = np.asarray(normal, dtype=np.float64)
    if n.ndim != 2 or n.shape[1] != 3:
        raise ValueError(f"normal must be (m, 3), got {n.shape}")
    c = n[:, 2] if axis is None else np.einsum("ij,ij->i", n, axis)
    nz = np.clip(c, -1.0, 1.0)
    flat_mm = cutter.radius_mm - cutter.corner_radius_mm
    return flat_mm + cutter.corner_radius_mm * np.sqrt(1.0 - nz * nz)


def center_offset_mm(cutter: Cutter) -> float:
    """Height of the ball centre / torus core circle above the programmed point.

    Parameters
    ----------
    cutter : Cutter
        ``tool_point`` is ``"tip"`` (programmed point at the tool tip) or
        ``"center"`` (programmed point at the ball centre, or for a bull-nose
        at the centre of the torus core circle).

    Returns
    -------
    float
        mm to go from the programmed point along the tool axis (+Z in 3 axes)
        to the centre used by :func:`ncopt.contacts.geometry.contacts_from_mesh`: ``r``
        (the corner radius, ``R`` for a ball) for tip-programmed tools, ``0``
        for centre-programmed.
    """
    if cutter.tool_point == "center":
        return 0.0
    if cutter.tool_point == "tip":
        return float(cutter.corner_radius_mm)
    raise ValueError(f"tool_point must be 'tip' or 'center', got {cutter.tool_point!r}")


def required_rpm(r_eff_mm: np.ndarray, vc_m_min: float) -> np.ndarray:
    """Spindle speed that gives the cutting speed ``vc`` at radius ``R_eff``.

    Parameters
    ----------
    r_eff_mm : (m,) float64
        Effective cutting radius, mm (>= 0).
    vc_m_min : float
        Target cutting speed, m/min.

    Returns
    -------
    (m,) float64
        ``S = 1000 vc / (2 pi R_eff)`` in RPM; ``inf`` where ``R_eff == 0``
        (capping S is the planner's job).
    """
    r = np.asarray(r_eff_mm, dtype=np.float64)
    with np.errstate(divide="ignore"):
        return 1000.0 * vc_m_min / (2.0 * np.pi * r)
