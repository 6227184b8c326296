"""Plots of simulated programs (matplotlib, imported lazily, no display needed).

* :func:`plot_along_path`: spindle speed, feed, fz and effective diameter along
  the cut length, several programs overlaid (the paper's Figs. 13, 15, 24, 25);
* :func:`plot_toolpath`: top and 3D views of the toolpath coloured by S, F or the
  effective diameter (the paper's Fig. 17); in 5 axes the 3D view draws the tool
  axis at a few hundred points and the title gives the range of its tilt.

In 5 axes :func:`plot_along_path` adds the tool's tilt from +Z as a fifth panel.

PNG, SVG or PDF, chosen by the file name; :func:`along_path_figure` and
:func:`toolpath_figure` give the figures themselves (the HTML report embeds them
as print images).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from .kinematics import tilt_deg
from .simulate import SimReport, SimSeries

MAX_POINTS = 20000  # per curve; min/max decimation keeps peaks visible
MAX_SCATTER = 200000  # toolpath samples drawn
# a 3D box flatter than this (height / widest side) is stretched to it, and says so
MIN_Z_ASPECT = 0.25
LABELS = {"s_rpm": "spindle speed S [RPM]", "f_mm_min": "feed F [mm/min]",
          "fz_mm": "feed per tooth fz [mm]", "d_eff_mm": "effective diameter [mm]",
          "vc_m_min": "cutting speed vc [m/min]", "tilt_deg": "tool tilt from +Z [deg]"}
ALONG = ("s_rpm", "f_mm_min", "fz_mm", "d_eff_mm")


def _pyplot():
    try:
        import matplotlib
    except ImportError:  # pragma: no cover - depends on the install
        from .errors import UsageError
        raise UsageError("plots need matplotlib: python -m pip install matplotlib (or, in "
                         "ncopt's source folder, python -m pip install \".[plot]\")") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def decimate(x: np.ndarray, *ys: np.ndarray, max_points: int = MAX_POINTS) -> tuple:
    """Keep the min and max of each bucket (of the first y) so spikes survive thinning."""
    n = x.shape[0]
    if n <= max_points:
        return (x, *ys)
    buckets = max_points // 2
    edges = np.linspace(0, n, buckets + 1).astype(np.int64)
    ref = np.where(np.isnan(ys[0]), np.inf, ys[0])
    lo = np.minimum.reduceat(ref, edges[:-1])
    hi = np.maximum.reduceat(np.where(np.isinf(ref), -np.inf, ref), edges[:-1])
    keep = np.zeros(n, dtype=bool)
    bucket = np.repeat(np.arange(buckets), np.diff(edges))
    keep[_first_where(ref == lo[bucket], bucket, buckets)] = True
    keep[_first_where(ref == hi[bucket], bucket, buckets)] = True
    keep[edges[:-1]] = keep[edges[:-1]] | np.isinf(lo)  # all-NaN bucket: its first sample
    return (x[keep], *(y[keep] for y in ys))


def _first_where(mask: np.ndarray, bucket: np.ndarray, n: int) -> np.ndarray:
    """Index of the first True of ``mask`` in each bucket that has one."""
    idx = np.flatnonzero(mask)
    first = np.full(n, -1)
    first[bucket[idx][::-1]] = idx[::-1]
    return first[first >= 0]


def cut_length_m(series: SimSeries) -> np.ndarray:
    """Length of cut up to each cutting sample, m (rapids and air moves do not count)."""
    cut = series.cutting
    step = np.diff(series.dist_mm, prepend=series.dist_mm[:1])
    return np.cumsum(np.where(cut, step, 0.0))[cut] / 1000.0


def along_path_figure(runs: list[tuple[str, SimSeries, SimReport]], title: str = "",
                      max_points: int = MAX_POINTS):
    """The figure of :func:`plot_along_path`, at most ``max_points`` per curve.

    The first program (the original, with ``--against``) is drawn dashed on top of
    the others, so where the curves agree (the effective diameter of an unchanged
    toolpath) both stay visible; one legend sits above the panels, off the data.
    """
    plt = _pyplot()
    rows = ALONG + (("tilt_deg",) if any(s.tool_axis is not None for _, s, _ in runs) else ())
    fig, axes = plt.subplots(len(rows), 1, figsize=(11, 2.5 * len(rows)), sharex=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (label, series, report) in enumerate(runs):
        first = i == 0 and len(runs) > 1
        style = dict(lw=1.1, ls=(0, (5, 3)), zorder=4, color="#1a1a1a") if first else dict(
            lw=0.7, zorder=2, color=colours[i % len(colours)])
        x = cut_length_m(series)
        for ax, name in zip(axes, rows):
            y = _tilt(series) if name == "tilt_deg" else getattr(series, name)
            xd, yd = decimate(x, y[series.cutting], max_points=max_points)
            ax.plot(xd, yd, label=f"{Path(label).name} ({report.cutting_time_min:.1f} min)"
                    if ax is axes[0] else None, **style)
    target = runs[0][2]
    band = target.band_pct / 100.0
    # under the first program's line: a program at its target shows both
    axes[2].axhline(target.fz_target_mm, color="tab:red", lw=1.4, zorder=3, label="fz target")
    for k in (1 - band, 1 + band):
        axes[2].axhline(target.fz_target_mm * k, color="tab:red", lw=0.8, ls=":", zorder=3,
                        label=f"band +-{target.band_pct:g} %" if k > 1 else None)
    for ax, name in zip(axes, rows):
        ax.set_ylabel(LABELS[name])
        ax.grid(True, lw=0.3)
    axes[-1].set_xlabel("cut length [m]")
    handles, labels = [], []
    for ax in (axes[0], axes[2]):
        h, lab = ax.get_legend_handles_labels()
        handles += h
        labels += lab
    fig.legend(handles, labels, loc="upper center", ncol=min(len(labels), 4), fontsize=8,
               frameon=False, bbox_to_anchor=(0.5, 0.955))
    fig.suptitle(title or f"vc target {target.vc_target_m_min:.1f} m/min, "
                 f"fz target {target.fz_target_mm:.4f} mm", y=0.99)
    fig.tight_layout(rect=(0, 0, 1, 0.945))
    return fig


def plot_along_path(runs: list[tuple[str, SimSeries, SimReport]], path: str | Path,
                    title: str = "") -> Path:
    """S, F, fz and effective diameter along the cut length, one curve per program."""
    return _save(along_path_figure(runs, title), path)


def toolpath_figure(series: SimSeries, color_by: str = "s_rpm", title: str = "",
                    max_points: int = MAX_SCATTER):
    """The figure of :func:`plot_toolpath`, with at most ``max_points`` samples drawn."""
    plt = _pyplot()
    from matplotlib.ticker import MaxNLocator

    cut = series.cutting
    xyz, value = series.xyz_mm[cut], getattr(series, color_by)[cut]
    step = max(1, -(-xyz.shape[0] // max_points))
    xyz, value = xyz[::step], value[::step]
    fig = plt.figure(figsize=(13, 6))
    grid = fig.add_gridspec(1, 2, width_ratios=(1.0, 1.4))
    ax1 = fig.add_subplot(grid[0])
    sc = ax1.scatter(xyz[:, 0], xyz[:, 1], c=value, s=0.5, cmap="viridis")
    ax1.set_aspect("equal")
    ax1.set_xlabel("X [mm]")
    ax1.set_ylabel("Y [mm]")
    ax1.set_title("top view")
    ax2 = fig.add_subplot(grid[1], projection="3d")
    ax2.scatter(xyz[:, 0], xyz[:, 1], xyz[:, 2], c=value, s=0.3, cmap="viridis")
    span = np.maximum(np.ptp(xyz, axis=0), 1e-3) if xyz.size else np.ones(3)
    stretch = max(1.0, MIN_Z_ASPECT * max(span[0], span[1]) / span[2])
    ax2.set_box_aspect((span[0], span[1], span[2] * stretch), zoom=1.2)
    for axis in (ax2.xaxis, ax2.yaxis):
        axis.set_major_locator(MaxNLocator(nbins=5))
    ax2.zaxis.set_major_locator(MaxNLocator(nbins=3))
    ax2.set_xlabel("X [mm]")
    ax2.set_ylabel("Y [mm]")
    ax2.set_zlabel("Z [mm]", labelpad=6)
    ax2.set_title("3D view" + (f" (heights x{stretch:.1f})" if stretch > 1.0 else ""))
    fig.colorbar(sc, ax=[ax1, ax2], label=LABELS.get(color_by, color_by), shrink=0.5,
                 orientation="horizontal", pad=0.12, aspect=40)
    tilt = _draw_axes(ax2, series, cut)
    fig.suptitle(title or f"toolpath coloured by {LABELS.get(color_by, color_by)}" + tilt)
    return fig


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
    return _save(toolpath_figure(series, color_by, title), path)


def png_bytes(fig, dpi: int = 110) -> bytes:
    """A figure as PNG bytes (closed afterwards)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    _pyplot().close(fig)
    return buffer.getvalue()


def _save(fig, path: str | Path) -> Path:
    out = Path(path)
    fig.savefig(out, dpi=120)
    _pyplot().close(fig)
    return out
