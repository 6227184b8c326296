"""What the planner works on, and the spindle's limits over it.

Works on *blocks* (source lines that move), because a control applies S and F per
block.  Units: S in RPM, lengths in mm, F in mm/min, accelerations in RPM/s.  The
spindle's limit of docs/method.md, |d(S^2)/ds| <= K = 2*60*a/(fz*z), is applied per block
as |S_b^2 - S_(b-1)^2| <= K*L_b (:func:`increments`); the fz band bounds the ratio of
the real speeds within one block (:func:`max_speed_ratio`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncopt.model import CuttingData, Machine, PlanOptions
from ncopt.runtime.errors import PlanningError



@dataclass(frozen=True)
class Blocks:
    """The program's moving blocks in order, (nb,) arrays.

    length_mm : path length of the block
    req_rpm : lowest required spindle speed along the block (inf: no requirement)
    cutting : the block cuts (has a requirement and is planned)
    planned : ncopt may set the block's S/F
    time_s : duration of non-cutting blocks at their own feed or the rapid rate
    fixed_rpm : programmed S in force (used for blocks that are not planned)
    spindle_start : the spindle (re)starts at this block (M3/M4 after a stop or a tool
        change): the control brings it to speed, nothing carries over from before
    running : the spindle turns during the block
    k_limited : the spindle's change over the block is bounded by the feed it would have
        at the target fz (S^2 by K*L, as in a cut) rather than by its own duration: the
        feed moves of a planned operation, whose F ncopt sets from S (default: cutting)
    k_scale : per block, the share of K*L that applies (default 1): a block whose F
        follows S at a higher feed per revolution than the target's is faster, so the
        spindle changes less over it
    """

    length_mm: np.ndarray
    req_rpm: np.ndarray
    cutting: np.ndarray
    planned: np.ndarray
    time_s: np.ndarray
    fixed_rpm: np.ndarray
    spindle_start: np.ndarray | None = None
    running: np.ndarray | None = None
    k_limited: np.ndarray | None = None
    k_scale: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = self.length_mm.shape[0]
        if self.spindle_start is None:
            object.__setattr__(self, "spindle_start", np.zeros(n, dtype=bool))
        if self.running is None:
            object.__setattr__(self, "running", np.ones(n, dtype=bool))



@dataclass(frozen=True)
class Profile:
    """Planned spindle speed per block (real-valued, before emission), RPM."""

    s_rpm: np.ndarray
    cap_rpm: np.ndarray
    k_rpm2_per_mm: float


def max_speed_ratio(opts: PlanOptions, cut: CuttingData, teeth: int, s_low_rpm: float) -> float:
    """Largest ratio of the highest to the lowest real spindle speed within one block.

    F is constant in a block while the spindle ramps, so fz spans
    [F/(z S_hi), F/(z S_lo)]; F is also rounded down to ``opts.f_quantum_mm_min``,
    which at the plan's lowest feed (fz z S_low) takes up to q = quantum / F_low
    off fz.  Keeping fz within +-tol gives, with r = S_hi/S_lo:

    * ``below`` (F = fz z S_lo):  r <= (1 - q) / (1 - tol)
    * ``centred`` (F = fz z 2 S_lo S_hi / (S_lo + S_hi)):  r <= (1 + tol - 2q) / (1 - tol)
    """
    tol = opts.fz_tolerance
    if s_low_rpm is None:  # nothing cuts: no fz to hold
        s_low_rpm = float("inf")
    q = opts.f_quantum_mm_min / (cut.fz_mm * teeth * max(s_low_rpm, 1.0))
    if opts.fz_policy not in ("centred", "below"):
        raise PlanningError(f"unknown fz policy {opts.fz_policy!r}; use centred or below")
    r = (1.0 + tol - 2.0 * q) / (1.0 - tol) if opts.fz_policy == "centred" else (1.0 - q) / (1.0 - tol)
    if r <= 1.0:
        raise PlanningError(f"F words of {opts.f_quantum_mm_min:g} mm/min resolution cannot hold "
                            f"fz within {100 * tol:g} % at F {cut.fz_mm * teeth * s_low_rpm:.0f} "
                            "mm/min; write F with more decimals or widen the band")
    return r


def k_rpm2_per_mm(machine: Machine, cut: CuttingData, teeth: int) -> float:
    """K = 2 * 60 * a / (fz z): the largest change of S^2 per mm of cut."""
    return 2.0 * 60.0 * machine.accel_rpm_s / (cut.fz_mm * teeth)


def speed_limits(machine: Machine, cut: CuttingData, teeth: int) -> tuple[float, float]:
    """Lowest and highest S the plan may use: machine range and the F_max cap."""
    s_hi = machine.max_rpm
    if np.isfinite(machine.max_feed_mm_min):
        s_hi = min(s_hi, machine.max_feed_mm_min / (cut.fz_mm * teeth))
    return machine.min_rpm, s_hi


def increments(blocks: Blocks, machine: Machine, k: float) -> tuple[np.ndarray, np.ndarray]:
    """How far the spindle may change during each block.

    Returns
    -------
    inc_s2 : (nb,) RPM^2, cutting blocks: K*L (inf elsewhere)
    inc_s : (nb,) RPM, other blocks: a*T over their whole duration T (inf for cutting)
    """
    ramp = machine.accel_rpm_s * blocks.time_s
    limited = blocks.cutting if blocks.k_limited is None else blocks.k_limited
    k_len = k * blocks.length_mm if blocks.k_scale is None else k * blocks.length_mm * blocks.k_scale
    inc_s2 = np.where(limited & ~blocks.spindle_start, k_len, np.inf)
    inc_s = np.where(limited | blocks.spindle_start, np.inf, ramp)
    return inc_s2, inc_s
