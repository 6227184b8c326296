"""Effective cutting radius from the remaining material (the paper's second method).

The material left for this pass is approximated by the plane rho1 parallel to
the tangent plane at the contact point, offset by the allowance ap.  The
cutting edge meets it where the tool sphere, rho1 and the plane through the
sphere centre with normal m = n x d (d the motion direction) intersect: two
points, of which the one ahead in the direction of motion cuts.  R_eff is its
distance from the tool axis (+Z, or in 5 axes the axis given per contact).

With ``along="normal"`` (default) rho1 is offset along the surface normal n,
as the paper's text and figure say; with ``along="axis"`` the offset is ap
along the tool axis, as its equation (2) writes it and as finishing layers made
by shifting Z leave the material.

For a ball the tool sphere is the ball; for a bull-nose, the sphere of the
torus tube (radius r) at the core-circle point on the contact side, which is
exact in the plane of the tool axis and very close to it for ap << r.  On a
bull-nose's flat bottom (n = +Z) the side is the direction of motion.

Closed form: X = Cs + (h) n + sqrt(rho^2 - h^2) d_t, with Cs the sphere centre,
rho its radius, h = ap - rho (normal) or ap (n . e) - rho (axis), and d_t the
unit tangential component of d.  All vectorised.
"""

from __future__ import annotations

import numpy as np

from ncopt.model import Cutter


def r_eff_material_mm(cutter: Cutter, normal: np.ndarray, direction: np.ndarray,
                      ap_mm: float, along: str = "normal",
                      axis: np.ndarray | None = None) -> np.ndarray:
    """(m,) effective radius where the edge meets the remaining material, mm.

    Parameters
    ----------
    normal : (m, 3) unit surface normals at the contact, toward the tool
    direction : (m, 3) motion directions (any length; zero rows: no motion)
    ap_mm : height of the remaining material
    along : ``"normal"`` or ``"axis"``
    axis : (m, 3) unit tool axes, or None for +Z
    """
    if along not in ("normal", "axis"):
        raise ValueError(f"along must be 'normal' or 'axis', not {along!r}")
    rho = cutter.corner_radius_mm
    core = cutter.radius_mm - rho
    n = normal
    d = direction / np.maximum(np.linalg.norm(direction, axis=1), 1e-12)[:, None]
    d_t = d - np.sum(d * n, axis=1)[:, None] * n
    dn = np.linalg.norm(d_t, axis=1)
    # moving along the normal (a plunge onto the surface): no lead, fall back to the contact
    d_t = np.where(dn[:, None] > 1e-9, d_t / np.maximum(dn, 1e-12)[:, None], 0.0)
    if axis is None:
        side = _core_side(n, d)
        h = np.full(n.shape[0], ap_mm - rho) if along == "normal" else ap_mm * n[:, 2] - rho
    else:
        side = _core_side_along(n, d, axis)
        h = np.full(n.shape[0], ap_mm - rho) if along == "normal" else \
            ap_mm * np.einsum("ij,ij->i", n, axis) - rho
    lead = np.sqrt(np.clip(rho * rho - h * h, 0.0, None))
    x = core * side + h[:, None] * n + lead[:, None] * d_t
    if axis is None:
        return np.hypot(x[:, 0], x[:, 1])
    return np.linalg.norm(x - np.einsum("ij,ij->i", x, axis)[:, None] * axis, axis=1)


def _core_side(n: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Unit horizontal direction from the axis to the tube centre on the contact side."""
    side = -n[:, :2]  # the contact lies opposite the normal's horizontal part
    norm = np.linalg.norm(side, axis=1)
    flat = norm < 1e-9
    side[flat] = d[flat, :2]
    norm = np.linalg.norm(side, axis=1)
    out = np.zeros((n.shape[0], 3))
    out[:, :2] = np.where(norm[:, None] > 1e-12, side / np.maximum(norm, 1e-12)[:, None], 0.0)
    return out


def _core_side_along(n: np.ndarray, d: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """:func:`_core_side` with the tool axis ``axis`` (m, 3) instead of +Z."""
    side = -(n - np.einsum("ij,ij->i", n, axis)[:, None] * axis)
    flat = np.linalg.norm(side, axis=1) < 1e-9
    df, af = d[flat], axis[flat]
    side[flat] = df - np.einsum("ij,ij->i", df, af)[:, None] * af
    norm = np.linalg.norm(side, axis=1)
    return np.where(norm[:, None] > 1e-12, side / np.maximum(norm, 1e-12)[:, None], 0.0)
