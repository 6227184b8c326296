"""Plots of simulated programs: matplotlib figures (imported lazily, no display needed)
and the HTML report's interactive figures (plotly JSON, no plotly import needed).

* :func:`plot_along_path`: spindle speed, feed, fz, vc and effective diameter along
  the cut length, several programs overlaid (the paper's Figs. 13, 15, 24, 25);
* :func:`plot_toolpath`: top and 3D views of the toolpath coloured by S, F or the
  effective diameter (the paper's Fig. 17); in 5 axes the 3D view draws the tool
  axis at a few hundred points and the title gives the range of its tilt.

In 5 axes :func:`plot_along_path` adds the tool's tilt from +Z as a sixth panel.
The fz and vc panels are scaled to their target's band (:func:`panel_range`): the
few samples beyond it (a plunge, a spindle catching up) are marked at the panel's
edge and counted in a note, so one plunge cannot squash the curve to a hairline.

PNG, SVG or PDF, chosen by the file name; :func:`along_path_figure` and
:func:`toolpath_figure` give the figures themselves (the HTML report embeds them
as images); :func:`curves_json` and :func:`path_json` the report's plotly figures.
"""

from __future__ import annotations

import base64
import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ncopt.motion.kinematics import tilt_deg
from ncopt.runtime.errors import UsageError
from ncopt.simulate.results import SimReport, SimSeries

MAX_POINTS = 20000  # per curve; min/max decimation keeps peaks visible
MAX_SCATTER = 200000  # toolpath samples drawn
# a 3D box flatter than this (height / widest side) is stretched to it, and says so
MIN_Z_ASPECT = 0.25
LABELS = {"s_rpm": "spindle speed S [RPM]", "f_mm_min": "feed F [mm/min]",
          "fz_mm": "feed per tooth fz [mm]", "d_eff_mm": "effective diameter [mm]",
          "vc_m_min": "cutting speed vc [m/min]", "tilt_deg": "tool tilt from +Z [deg]"}
ALONG = ("s_rpm", "f_mm_min", "fz_mm", "vc_m_min", "d_eff_mm")
# panels scaled to their target: the series -> the SimReport field of its target
TARGETS = {"fz_mm": "fz_target_mm", "vc_m_min": "vc_target_m_min"}
SPREAD = 3.0  # a targeted panel shows at least the target +- this many bands
BULK_SHARE = 0.005  # ... and all but this share of the samples at each end


def _pyplot():
    """matplotlib.pyplot on the Agg backend (no display needed); UsageError without it."""
    # matplotlib is optional (the "plot" extra) and slow to load: only a plot needs it
    try:
        import matplotlib
    except ImportError:  # pragma: no cover - depends on the install
        raise UsageError("plots need matplotlib: python -m pip install matplotlib (or, in "
                         "ncopt's source folder, python -m pip install \".[plot]\")") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def decimate(x: np.ndarray, *ys: np.ndarray,
             max_points: int = MAX_POINTS) -> tuple[np.ndarray, ...]:
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


def panel_range(values, target: float, band: float, spread: float = SPREAD,
                share: float = BULK_SHARE) -> tuple[float, float]:
    """The y range of a panel whose curves should sit on ``target``: at least
    ``target * (1 +- spread * band)``, widened to hold all but ``share`` of the finite
    samples at each end (a curve that leaves the band for a while stays on the panel;
    a single plunge does not set its scale).  Never below 0 (fz and vc are not negative).

    values : list of (m,) arrays, the samples of every curve of the panel
    band : relative, 0.02 for +-2 %
    """
    lo, hi = target * (1.0 - spread * band), target * (1.0 + spread * band)
    finite = [v[np.isfinite(v)] for v in values]
    finite = np.concatenate(finite) if finite else np.zeros(0)
    if finite.size:
        q_lo, q_hi = (float(q) for q in np.quantile(finite, [share, 1.0 - share]))
        pad = 0.03 * (max(hi, q_hi) - min(lo, q_lo))
        lo = q_lo - pad if q_lo < lo else lo
        hi = q_hi + pad if q_hi > hi else hi
    return max(lo, 0.0), hi


@dataclass(frozen=True)
class Outliers:
    """The samples of one curve beyond its panel's range, (k,) arrays.

    x : cut length, m;  y : the value;  line : 1-based source line
    """

    x: np.ndarray
    y: np.ndarray
    line: np.ndarray

    def note(self, target: float, name: str) -> str:
        """``b.mpf: 1 sample beyond the scale: lowest -90.7 % (line 14)``."""
        if not self.y.size:
            return ""
        with np.errstate(divide="ignore", invalid="ignore"):
            pct = 100.0 * (self.y / target - 1.0)
        parts = []
        for side, pick, word in ((pct < 0, np.argmin, "lowest"), (pct >= 0, np.argmax,
                                                                   "highest")):
            if side.any():
                k = np.flatnonzero(side)[pick(pct[side])]
                value = "spindle stopped" if np.isinf(pct[k]) else f"{pct[k]:+.1f} %"
                parts.append(f"{word} {value} (line {int(self.line[k])})")
        n = self.y.size
        return f"{name}: {n} sample{'s' if n > 1 else ''} beyond the scale: " + ", ".join(parts)


def outliers(x: np.ndarray, y: np.ndarray, line: np.ndarray, lo: float, hi: float) -> Outliers:
    """The samples of a curve outside ``[lo, hi]`` (inf included: a stopped spindle)."""
    out = ~np.isnan(y) & ((y < lo) | (y > hi))
    return Outliers(x[out], y[out], line[out])


def _targeted(runs, name: str) -> tuple[float, float, float]:
    """(target, lo, hi) of a targeted panel over every run's cutting samples."""
    first = runs[0][2]
    target = getattr(first, TARGETS[name])
    values = [getattr(s, name)[s.cutting] for _, s, _ in runs]
    return (target, *panel_range(values, target, first.band_pct / 100.0))


def along_path_figure(runs: list[tuple[str, SimSeries, SimReport]], title: str = "",
                      max_points: int = MAX_POINTS, size: tuple[float, float] | None = None):
    """The figure of :func:`plot_along_path`, at most ``max_points`` per curve.

    The first program (the original, with ``--against``) is drawn dashed on top of
    the others, so where the curves agree (the effective diameter of an unchanged
    toolpath) both stay visible; one legend sits above the panels, off the data.
    ``size``: (width, height) in inches (default 11 wide, 2.3 a panel).
    """
    plt = _pyplot()
    rows = ALONG + (("tilt_deg",) if any(s.tool_axis is not None for _, s, _ in runs) else ())
    fig, axes = plt.subplots(len(rows), 1, figsize=size or (11, 2.3 * len(rows)), sharex=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    scales = {name: _targeted(runs, name) for name in TARGETS}
    notes = {}
    for i, (label, series, report) in enumerate(runs):
        first = i == 0 and len(runs) > 1
        style = dict(lw=1.1, ls=(0, (5, 3)), zorder=4, color="#1a1a1a") if first else dict(
            lw=0.7, zorder=2, color=colours[i % len(colours)])
        x = cut_length_m(series)
        line = series.line[series.cutting]
        for ax, name in zip(axes, rows):
            y = (_tilt(series) if name == "tilt_deg" else getattr(series, name))[series.cutting]
            xd, yd = decimate(x, y, max_points=max_points)
            ax.plot(xd, yd, label=f"{Path(label).name} ({report.cutting_time_min:.1f} min)"
                    if ax is axes[0] else None, **style)
            if name in TARGETS:
                out = outliers(x, y, line, *scales[name][1:])
                _mark_outliers(ax, out, scales[name][1:], style["color"])
                notes.setdefault(name, []).append(out.note(scales[name][0], Path(label).name))
    target = runs[0][2]
    band = target.band_pct / 100.0
    fz_ax, vc_ax = axes[rows.index("fz_mm")], axes[rows.index("vc_m_min")]
    # under the first program's line: a program at its target shows both
    fz_ax.axhline(target.fz_target_mm, color="tab:red", lw=1.4, zorder=3, label="fz target")
    for k in (1 - band, 1 + band):
        fz_ax.axhline(target.fz_target_mm * k, color="tab:red", lw=0.8, ls=":", zorder=3,
                      label=f"band +-{target.band_pct:g} %" if k > 1 else None)
    vc_ax.axhline(target.vc_target_m_min, color="tab:red", lw=1.4, zorder=3)  # as fz's
    for ax, name in zip(axes, rows):
        ax.set_ylabel(LABELS[name], fontsize=9)
        ax.grid(True, lw=0.3)
        if name in scales:
            ax.set_ylim(*scales[name][1:])
            ax.set_title("; ".join(n for n in notes[name] if n), fontsize=7, loc="right")
    axes[-1].set_xlabel("cut length [m]")
    handles, labels = [], []
    for ax in (axes[0], fz_ax):
        h, lab = ax.get_legend_handles_labels()
        handles += h
        labels += lab
    fig.legend(handles, labels, loc="upper center", ncol=min(len(labels), 4), fontsize=8,
               frameon=False, bbox_to_anchor=(0.5, 0.96))
    fig.suptitle(title or f"vc target {target.vc_target_m_min:.1f} m/min, "
                 f"fz target {target.fz_target_mm:.4f} mm", y=0.99)
    fig.tight_layout(rect=(0, 0, 1, 0.945))
    return fig


def _mark_outliers(ax, out: Outliers, scale: tuple[float, float], colour: str) -> None:
    """Samples beyond the panel's range: a triangle at its edge, pointing their way."""
    lo, hi = scale
    for beyond, edge, marker in ((out.y < lo, lo, "v"), (out.y > hi, hi, "^")):
        if beyond.any():
            ax.scatter(out.x[beyond], np.full(int(beyond.sum()), edge), marker=marker, s=22,
                       color=colour, edgecolors="tab:red", linewidths=0.8, zorder=6,
                       clip_on=False)


def plot_along_path(runs: list[tuple[str, SimSeries, SimReport]], path: str | Path,
                    title: str = "") -> Path:
    """S, F, fz and effective diameter along the cut length, one curve per program."""
    return _save(along_path_figure(runs, title), path)


def toolpath_figure(series: SimSeries, color_by: str = "s_rpm", title: str = "",
                    max_points: int = MAX_SCATTER):
    """The figure of :func:`plot_toolpath`, with at most ``max_points`` samples drawn."""
    plt = _pyplot()
    from matplotlib.ticker import MaxNLocator  # loaded with pyplot, only for a plot

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


def png_bytes(fig, dpi: int = 110, palette: bool = True) -> bytes:
    """A figure as PNG bytes (closed afterwards); ``palette``: 256 colours (a third of the
    size for these plots, no visible change)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    _pyplot().close(fig)
    if not palette:
        return buffer.getvalue()
    from PIL import Image  # matplotlib's own dependency, loaded with it: only for a plot

    buffer.seek(0)
    image = Image.open(buffer).convert("RGB").quantize(256, method=Image.Quantize.FASTOCTREE)
    out = io.BytesIO()
    image.save(out, format="png", optimize=True)
    return out.getvalue()


def _save(fig, path: str | Path) -> Path:
    out = Path(path)
    fig.savefig(out, dpi=120)
    _pyplot().close(fig)
    return out


# ------------------------------------------------------------ plotly figures (the HTML report)

COLOR_BY = (("s_rpm", "S [RPM]"), ("f_mm_min", "F [mm/min]"), ("d_eff_mm", "D_eff [mm]"),
            ("vc_m_min", "vc [m/min]"))
PANEL_TITLES = {"s_rpm": "S [RPM]", "f_mm_min": "F [mm/min]", "fz_mm": "fz [mm]",
                "vc_m_min": "vc [m/min]", "d_eff_mm": "D_eff [mm]"}
MARKED = 300  # outliers marked per curve in the report (the extremes always)
COLOURS = ("#ff7f0e", "#1f77b4", "#2ca02c", "#9467bd", "#8c564b")
CONFIG = {"displaylogo": False, "responsive": True}


def typed_array(values) -> dict:
    """A plotly typed array: float32, base64 (a third of the JSON's digits)."""
    a = np.ascontiguousarray(np.asarray(values, dtype="<f4"))
    return {"dtype": "f4", "bdata": base64.b64encode(a.tobytes()).decode("ascii")}


def colour_array(values: np.ndarray) -> dict:
    """Colour values as a plotly typed array: whole numbers 0-65535 (S in RPM, F in mm/min)
    as uint16, rounded (half the bytes; NaN, where the path breaks, as 0), else float32."""
    finite = values[np.isfinite(values)]
    if finite.size and finite.min() >= 0 and finite.max() <= 65535 and finite.max() >= 100:
        a = np.ascontiguousarray(np.rint(np.nan_to_num(values, nan=0.0)).astype("<u2"))
        return {"dtype": "u2", "bdata": base64.b64encode(a.tobytes()).decode("ascii")}
    return typed_array(values)


def curves_json(runs: list[tuple[str, SimSeries, SimReport]], max_points: int) -> str:
    """S, F, fz, vc and D_eff along the cut: stacked panels sharing the cut length; fz and
    vc scaled to their band, the samples beyond it marked at the panel's edge."""
    scales = {name: _targeted(runs, name) for name in TARGETS}
    for name in ALONG:  # a constant S or F: a plain scale around it, not 8999-9001 RPM
        values = np.concatenate([getattr(s, name)[s.cutting] for _, s, _ in runs])
        finite = values[np.isfinite(values)]
        if name not in TARGETS and finite.size and np.ptp(finite) < 0.02 * np.abs(finite).max():
            lo, hi = colour_range(finite)
            scales[name] = (None, lo - 0.5 * (hi - lo), hi + 0.5 * (hi - lo))
    traces, notes = [], {name: [] for name in TARGETS}
    for i, (label, series, _) in reversed(list(enumerate(runs))):
        first = i == 0 and len(runs) > 1
        colour = "#1a1a1a" if first else COLOURS[max(i - 1, 0) % len(COLOURS)]
        x, line = cut_length_m(series), series.line[series.cutting]
        for p, name in enumerate(ALONG):
            y = getattr(series, name)[series.cutting]
            xd, yd = decimate(x, y, max_points=max_points)
            axis = f"y{p + 1 if p else ''}"
            traces.append({"type": "scatter", "mode": "lines", "x": typed_array(xd),
                           "y": typed_array(yd), "xaxis": "x", "yaxis": axis,
                           "name": Path(label).name, "legendgroup": str(i),
                           "showlegend": p == 0, "legendrank": i,
                           "line": {"width": 1.6 if first else 1.0,
                                    "dash": "dash" if first else "solid", "color": colour}})
            if name in TARGETS:
                out = outliers(x, y, line, *scales[name][1:])
                notes[name].append(out.note(scales[name][0], Path(label).name))
                if out.y.size:
                    traces.append(_outlier_trace(out, scales[name], axis, colour, name))
    layout = _curves_layout(runs[0][2], scales, notes)
    ends = [cut_length_m(s) for _, s, _ in runs]
    layout["xaxis"]["range"] = [0.0, max(float(e[-1]) if e.size else 0.0 for e in ends) or 1.0]
    return json.dumps({"data": traces, "layout": layout, "config": CONFIG})


def _outlier_trace(out: Outliers, scale: tuple[float, float, float], axis: str, colour: str,
                   name: str) -> dict:
    """Triangles at the panel's edge where a curve leaves it; the value on hover."""
    target, lo, hi = scale
    keep = np.unique(np.concatenate((np.linspace(0, out.y.size - 1, min(MARKED, out.y.size))
                                     .astype(int), [np.argmin(out.y), np.argmax(out.y)])))
    y, x, line = out.y[keep], out.x[keep], out.line[keep]
    unit = "mm" if name == "fz_mm" else "m/min"
    with np.errstate(divide="ignore", invalid="ignore"):
        pct = 100.0 * (y / target - 1.0)
    text = [f"line {int(n)}: {name.split('_')[0]} {v:.4g} {unit} ({p:+.1f} %)"
            for n, v, p in zip(line, y, pct)]
    # plain numbers: a float32 edge lies just outside the range, and plotly drops it
    return {"type": "scatter", "mode": "markers", "x": [round(float(v), 6) for v in x],
            "y": [lo if v < lo else hi for v in y], "yaxis": axis, "xaxis": "x",
            "showlegend": False, "hoverinfo": "text", "hovertext": text, "cliponaxis": False,
            "marker": {"symbol": ["triangle-down" if v < lo else "triangle-up" for v in y],
                       "size": 9, "color": colour, "line": {"color": "#d62728", "width": 1}}}


def _curves_layout(target: SimReport, scales: dict, notes: dict) -> dict:
    """Five panels, the targets drawn as lines, each targeted panel's note above it."""
    band = target.band_pct / 100.0
    axis_of = {name: f"y{p + 1 if p else ''}" for p, name in enumerate(ALONG)}
    ref = lambda name: "y" + axis_of[name][1:]  # noqa: E731 - "y3" for layout's "yaxis3"
    shapes = [{"type": "line", "xref": "paper", "x0": 0, "x1": 1, "yref": ref("fz_mm"),
               "y0": target.fz_target_mm * k, "y1": target.fz_target_mm * k, "layer": "between",
               "line": {"color": "#d62728", "width": 1.2 if k == 1 else 0.8,
                        "dash": "solid" if k == 1 else "dot"}} for k in (1 - band, 1.0, 1 + band)]
    shapes.append({"type": "line", "xref": "paper", "x0": 0, "x1": 1, "yref": ref("vc_m_min"),
                   "y0": target.vc_target_m_min, "y1": target.vc_target_m_min, "layer": "between",
                   "line": {"color": "#d62728", "width": 1.2}})
    layout = {"height": 940, "margin": {"l": 70, "r": 20, "t": 40, "b": 50},
              "legend": {"orientation": "h", "y": 1.05, "x": 0}, "shapes": shapes,
              "xaxis": {"title": {"text": "cut length [m]"}, "anchor": axis_of[ALONG[-1]]},
              "hovermode": "x unified", "annotations": []}
    step = 1.0 / len(ALONG)
    for p, name in enumerate(ALONG):
        top = 1.0 - p * step
        axis = {"domain": [top - step + 0.035, top], "title": {"text": PANEL_TITLES[name]}}
        if name in scales:
            axis["range"] = list(scales[name][1:])
        if name in TARGETS:
            note = "; ".join(n for n in notes[name] if n)
            if note:
                layout["annotations"].append(
                    {"text": note, "xref": "paper", "x": 1, "xanchor": "right",
                     "yref": "paper", "y": top, "yanchor": "bottom", "showarrow": False,
                     "font": {"size": 11, "color": "#a00"}})
        layout[f"yaxis{p + 1 if p else ''}"] = axis
    return layout


def colour_range(values: np.ndarray) -> tuple[float, float]:
    """The colour scale's ends: the values' range, widened to at least 2 % of their size so
    a constant S (one S per pass) reads as one colour on a plain scale, not as
    1687.6-1688.4 RPM."""
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return 0.0, 1.0
    lo, hi = float(finite.min()), float(finite.max())
    least = 0.02 * max(abs(lo), abs(hi), 1e-9)
    if hi - lo < least:
        mid = 0.5 * (lo + hi)
        lo, hi = mid - 0.5 * least, mid + 0.5 * least
    return lo, hi


def path_json(series: SimSeries, max_points: int) -> str:
    """The cutting samples in 3D, evenly thinned, broken where the cut is interrupted;
    a menu recolours them by S, F, D_eff or vc."""
    idx = np.flatnonzero(series.cutting)
    step = max(1, -(-idx.size // max(max_points, 1)))
    keep = idx[::step]
    brk = np.concatenate(([False], np.diff(keep) > step))  # not consecutive cut samples
    pos = np.arange(keep.size) + np.cumsum(brk)
    n = keep.size + int(brk.sum())

    def gapped(values):
        out = np.full(n, np.nan)
        out[pos] = values[keep]
        return out

    xyz = [gapped(series.xyz_mm[:, j]) for j in range(3)]
    colours = {key: gapped(getattr(series, key)) for key, _ in COLOR_BY}
    first, label = COLOR_BY[0]
    ranges = {key: colour_range(colours[key]) for key, _ in COLOR_BY}
    lo, hi = ranges[first]
    trace = {"type": "scatter3d", "mode": "lines", "x": typed_array(xyz[0]),
             "y": typed_array(xyz[1]), "z": typed_array(xyz[2]), "connectgaps": False,
             "hoverinfo": "x+y+z",
             "line": {"width": 4, "color": colour_array(colours[first]), "colorscale": "Viridis",
                      "cmin": lo, "cmax": hi,
                      "showscale": True, "colorbar": {"title": {"text": label}}}}
    buttons = [{"label": lab, "method": "restyle",
                "args": [{"line.color": [colour_array(colours[key])],
                          "line.cmin": [ranges[key][0]], "line.cmax": [ranges[key][1]],
                          "line.colorbar.title.text": lab}]} for key, lab in COLOR_BY]
    return json.dumps({"data": [trace], "layout": _path_layout(xyz, buttons), "config": CONFIG})


def _path_layout(xyz: list, buttons: list) -> dict:
    span = np.nanmax(np.vstack(xyz), axis=1) - np.nanmin(np.vstack(xyz), axis=1)
    span = np.maximum(np.nan_to_num(span, nan=1.0), 1e-3)
    ratio = span / span.max()
    ratio[2] = max(ratio[2], MIN_Z_ASPECT)  # as the printed view: a flat part stretched
    return {"height": 640, "margin": {"l": 0, "r": 0, "t": 30, "b": 0},
            "updatemenus": [{"buttons": buttons, "x": 0, "y": 1.08, "xanchor": "left",
                             "direction": "right", "type": "buttons"}],
            "scene": {"aspectmode": "manual",
                      "aspectratio": dict(zip("xyz", map(float, ratio))),
                      "xaxis": {"title": {"text": "X [mm]"}},
                      "yaxis": {"title": {"text": "Y [mm]"}},
                      "zaxis": {"title": {"text": "Z [mm]"}, "nticks": 4},
                      "camera": {"eye": {"x": 0.95, "y": -1.2, "z": 0.75}}}}
