"""Where the cutter starts or stops touching the part between two mesh samples (5 axes).

A 5-axis toolpath is sampled evenly (``ncopt.contacts.locate.AXIS_SAMPLE_MM``), and each
sample stands for the stretch of its move since the sample before.  Where the tool runs
onto or off the part (a lead-in or lead-out ramp leaving the surface at a few degrees,
within the contact tolerance for a few tenths of a mm) the contact ends between two
samples, and there the contact has turned farther than at the last touching sample: on
the R60 bowl of bench/make_5axis.py R_eff grows 2 % over a 0.25 mm step of a lead-out,
and the simulator, at 0.1 mm, found vc +0.6 % beyond the last touching sample.  Where a
lead-out leaves steeply, its first sample (0.25 mm on) is already in the air: the move
touched only at its start and was planned as air, at the program's F (fz -43 %).

Here, between two samples of which one touches and the other does not, the point where
the clearance crosses the tolerance is found by linear interpolation of the clearance,
and the sample that stands for that stretch (the later one) is cutting, with the R_eff
interpolated there (entering, the larger of that and its own).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ncopt.model import Contacts


def with_touch_edges(contacts: Contacts, gap_mm: np.ndarray, tol_mm: float) -> Contacts:
    """``contacts`` (evenly spaced samples of a 5-axis toolpath, in path order, ``gap_mm``
    the cutter's clearance at each) with the stretches that start or stop touching
    between two samples counted on the later sample (module docstring)."""
    cut = contacts.cutting
    if cut.size < 2:
        return contacts
    was, now = cut[:-1], cut[1:]
    edge = np.flatnonzero(was != now) + 1  # the later sample of each such pair
    if edge.size == 0:
        return contacts
    g0, g1 = gap_mm[edge - 1], gap_mm[edge]
    span = g1 - g0
    frac = np.clip((tol_mm - g0) / np.where(np.abs(span) > 1e-15, span, 1.0), 0.0, 1.0)
    r = contacts.r_eff_mm
    at_edge = r[edge - 1] + (r[edge] - r[edge - 1]) * frac
    # entering, the stretch touches from the edge to the sample: the larger of the two;
    # leaving, from the sample before (its own R_eff) to the edge: the edge's
    at_edge = np.where(now[edge - 1], np.maximum(r[edge], at_edge), at_edge)
    ok = np.isfinite(at_edge)
    r_eff = r.copy()
    r_eff[edge[ok]] = at_edge[ok]
    cutting = cut.copy()
    cutting[edge] = True
    return replace(contacts, r_eff_mm=r_eff, cutting=cutting)
