"""Plots of simulated programs (matplotlib, imported lazily, no display needed).

* :func:`plot_along_path`: spindle speed, feed, fz and effective diameter along
  the cut length, several programs overlaid (the paper's Figs. 13, 15, 24, 25);
* :func:`plot_toolpath`: top and 3D views of the toolpath coloured by S, F or the
  effective diameter (the paper's Fig. 17); in 5 axes the 3D view draws the tool
  axis at a few hundred points and the title gives the range of its tilt.

In 5 axes :func:`plot_along_path` adds the tool's tilt from +Z as a fifth panel.

PNG or SVG, chosen by the file name.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .kinematics import tilt_deg
from .simulate import SimReport, SimSeries

MAX_POINTS = 20000  # per curve; min/max decimation keeps peaks visible


def _pyplot():
    try:
        import matplotlib
    except ImportError:  # pragma: no cover - depends on the install
        from .errors import UsageError
        raise UsageError("plots need matplotlib: pip install 'ncopt[plot]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _decimate(x: np.ndarray, *ys: np.ndarray) -> tuple:
    """Keep the min and max of each bucket so spikes survive thinning."""
    n = x.shape[0]
    if n <= MAX_POINTS:
        return (x, *ys)
    buckets = MAX_POINTS // 2
    edges = np.linspace(0, n, buckets + 1).astype(int)
    keep = []
    ref = ys[0]
    for a, b in zip(edges[:-1], edges[1:]):
        seg = ref[a:b]
        if seg.size == 0 or np.all(np.isnan(seg)):
            keep.append(a)
            continue
        keep += sorted({a + int(np.nanargmin(seg)), a + int(np.nanargmax(seg))})
    keep = np.array(keep)
    return (x[keep], *(y[keep] for y in ys))


def plot_along_path(runs: list[tuple[str, SimSeries, SimReport]], path: str | Path,
                    title: str = "") -> Path:
    """S, F, fz and effective diameter along the cut length, one curve per program."""
    plt = _pyplot()
    rows = (("s_rpm", "spindle speed S [RPM]"), ("f_mm_min", "feed F [mm/min]"),
            ("fz_mm", "feed per tooth fz [mm]"), ("d_eff_mm", "effective diameter [mm]"))
    if any(series.tool_axis is not None for _, series, _ in runs):
        rows += (("tilt_deg", "tool tilt from +Z [deg]"),)
    fig, axes = plt.subplots(len(rows), 1, figsize=(11, 2.5 * len(rows)), sharex=True)
    for label, series, report in runs:
        cut = series.cutting
        x = np.cumsum(np.where(cut, np.diff(series.dist_mm, prepend=series.dist_mm[:1]), 0.0))[cut]
        for ax, (name, ylabel) in zip(axes, rows):
            y = _tilt(series)[cut] if name == "tilt_deg" else getattr(series, name)[cut]
            xd, yd = _decimate(x / 1000.0, y)
            ax.plot(xd, yd, lw=0.7, label=f"{Path(label).name} ({report.cutting_time_min:.1f} min)")
            ax.set_ylabel(ylabel)
    target = runs[0][2]
    band = target.band_pct / 100.0 if target.band_pct > 1 else target.band_pct
    axes[2].axhline(target.fz_target_mm, color="k", lw=0.6, ls="--", label="fz target")
    for k in (1 - band, 1 + band):
        axes[2].axhline(target.fz_target_mm * k, color="grey", lw=0.5, ls=":")
    axes[-1].set_xlabel("cut length [m]")
    axes[0].legend(loc="upper right", fontsize=8)
    axes[2].legend(loc="upper right", fontsize=8)
    for ax in axes:
        ax.grid(True, lw=0.3)
    fig.suptitle(title or f"vc target {target.vc_target_m_min:.1f} m/min, "
                 f"fz target {target.fz_target_mm:.4f} mm")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


AXES_DRAWN = 300  # tool axes drawn in the 3D view of a 5-axis toolpath


def _tilt(series: SimSeries) -> np.ndarray:
    """(m,) the tool's tilt from +Z, deg (0 for a 3-axis program)."""
    if series.tool_axis is None:
        return np.zeros(len(series))
    return tilt_deg(series.tool_axis)


def _draw_axes(ax, series: SimSeries, cut: np.ndarray) -> str:
    """Short tool-axis segments at up to AXES_DRAWN cutting samples; the tilt range."""
    if series.tool_axis is None or not cut.any():
        return ""
    rows = np.flatnonzero(cut)
    rows = rows[np.linspace(0, rows.size - 1, min(AXES_DRAWN, rows.size)).astype(int)]
    p, e = series.xyz_mm[rows], series.tool_axis[rows]
    size = 0.06 * float(np.max(np.ptp(series.xyz_mm[cut], axis=0))) or 1.0
    ax.quiver(p[:, 0], p[:, 1], p[:, 2], e[:, 0], e[:, 1], e[:, 2], length=size,
              color="k", linewidth=0.4, arrow_length_ratio=0.0)
    tilt = tilt_deg(series.tool_axis[cut])
    return f"; tool axis tilted {tilt.min():.1f}..{tilt.max():.1f} deg from +Z"


def plot_toolpath(series: SimSeries, path: str | Path, color_by: str = "s_rpm",
                  title: str = "") -> Path:
    """Top and 3D views of the cutting samples coloured by S, F or effective diameter."""
    plt = _pyplot()
    labels = {"s_rpm": "spindle speed S [RPM]", "f_mm_min": "feed F [mm/min]",
              "d_eff_mm": "effective diameter [mm]", "vc_m_min": "cutting speed vc [m/min]"}
    cut = series.cutting
    xyz, value = series.xyz_mm[cut], getattr(series, color_by)[cut]
    step = max(1, xyz.shape[0] // 200000)
    xyz, value = xyz[::step], value[::step]
    fig = plt.figure(figsize=(13, 6))
    ax1 = fig.add_subplot(1, 2, 1)
    sc = ax1.scatter(xyz[:, 0], xyz[:, 1], c=value, s=0.5, cmap="viridis")
    ax1.set_aspect("equal")
    ax1.set_xlabel("X [mm]")
    ax1.set_ylabel("Y [mm]")
    ax1.set_title("top view")
    ax2 = fig.add_subplot(1, 2, 2, projection="3d")
    ax2.scatter(xyz[:, 0], xyz[:, 1], xyz[:, 2], c=value, s=0.3, cmap="viridis")
    ax2.set_xlabel("X [mm]")
    ax2.set_ylabel("Y [mm]")
    ax2.set_zlabel("Z [mm]")
    ax2.set_title("3D view")
    ax2.set_box_aspect(tuple(np.maximum(np.ptp(xyz, axis=0), 1e-3)) if xyz.size else None)
    fig.colorbar(sc, ax=[ax1, ax2], label=labels.get(color_by, color_by), shrink=0.8)
    tilt = _draw_axes(ax2, series, cut)
    fig.suptitle(title or f"toolpath coloured by {labels.get(color_by, color_by)}" + tilt)
    out = Path(path)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out
