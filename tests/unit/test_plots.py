"""ncopt.report.plots: the decimation keeps every bucket's extremes; labels and legends stay
off each other and off the data; the original's curve stays visible."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from ncopt.report import plots  # noqa: E402
from ncopt.simulate.results import SimReport, SimSeries  # noqa: E402


def _loop_decimate(x, y, max_points):
    """The definition: per bucket, the first sample of its minimum and of its maximum."""
    edges = np.linspace(0, x.shape[0], max_points // 2 + 1).astype(int)
    keep = []
    for a, b in zip(edges[:-1], edges[1:]):
        seg = y[a:b]
        if np.all(np.isnan(seg)):
            keep.append(a)
            continue
        keep += sorted({a + int(np.nanargmin(seg)), a + int(np.nanargmax(seg))})
    return x[keep], y[keep]


def test_decimation_keeps_each_buckets_extremes(rng):
    y = rng.normal(size=50_001)
    y[1000:1400] = np.nan  # a stretch with nothing evaluated
    y[30_000] = 40.0  # a spike
    x = np.arange(y.size, dtype=float)
    xd, yd = plots.decimate(x, y, max_points=2000)
    xe, ye = _loop_decimate(x, y, 2000)
    assert np.array_equal(xd, xe)
    assert np.array_equal(yd, ye, equal_nan=True)
    assert 40.0 in yd and xd.size <= 2000
    short = x[:100]
    assert plots.decimate(short, y[:100], max_points=2000)[0] is short  # short: as is


def _series(n=4000, seed=1):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, n)
    xyz = np.column_stack((100 * np.cos(40 * t) * t, 100 * np.sin(40 * t) * t, -8 * t))
    s = 2000 + 8000 * t
    d = 2 + 10 * t
    return SimSeries(dist_mm=t * 5000, time_s=t * 60, line=np.arange(n) + 1, xyz_mm=xyz,
                     s_rpm=s, s_cmd_rpm=s, f_mm_min=0.2 * s, fz_mm=0.1 + 0.001 * rng.normal(
                         size=n), d_eff_mm=d, vc_m_min=np.pi * d * s / 1000,
                     cutting=np.ones(n, bool))


def _report(path):
    nan = float("nan")
    return SimReport(path, 70.0, 0.1, 2.0, 0.1, 4000, 1.0, 0.0, 0.0, 1.0, 5000.0, 100.0, 0.0,
                     1, 0.0, 1, 0.0, 1, 70.0, 10000.0, 1, 1, warnings=(), lag=()) if path else nan


def _overlap(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def test_along_path_draws_the_original_on_top_and_the_legend_off_the_data():
    runs = [("orig.nc", _series(), _report("orig.nc")), ("opt.nc", _series(seed=2),
                                                          _report("opt.nc"))]
    fig = plots.along_path_figure(runs)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        assert ax.get_legend() is None  # no legend inside a panel
        lines = [ln for ln in ax.get_lines() if len(ln.get_xdata()) > 2]
        assert len(lines) == 2
        original, rewrite = lines
        assert original.get_zorder() > rewrite.get_zorder()
        assert original.get_linestyle() == "--"  # dashed: what lies under it shows
    (legend,) = fig.legends
    box = legend.get_window_extent(renderer)
    assert not any(_overlap(box, ax.get_window_extent(renderer)) for ax in fig.axes)
    labels = [t.get_text() for t in legend.get_texts()]
    assert labels[:2] == ["orig.nc (1.0 min)", "opt.nc (1.0 min)"] and "fz target" in labels
    plots._pyplot().close(fig)


def _tick_gaps_px(ax, axis: str) -> list[float]:
    """Screen distance between consecutive ticks of a 3D axis that lie within its limits."""
    from mpl_toolkits.mplot3d import proj3d

    lims = {"x": ax.get_xlim(), "y": ax.get_ylim(), "z": ax.get_zlim()}
    ticks = [t for t in getattr(ax, f"get_{axis}ticks")() if min(lims[axis]) <= t <= max(lims[axis])]
    points = []
    for t in ticks:
        p = {k: v[0] for k, v in lims.items()}
        p[axis] = t
        x, y, _ = proj3d.proj_transform(p["x"], p["y"], p["z"], ax.get_proj())
        points.append(ax.transData.transform((x, y)))
    return [float(np.hypot(*(b - a))) for a, b in zip(points, points[1:])]


def test_toolpath_tick_labels_do_not_overlap():
    fig = plots.toolpath_figure(_series(), "s_rpm")
    fig.canvas.draw()
    ax3d = fig.axes[1]
    label_px = ax3d.zaxis.get_ticklabels()[0].get_fontsize() * fig.dpi / 72.0
    for axis in "xyz":
        gaps = _tick_gaps_px(ax3d, axis)
        assert len(gaps) >= 1
        assert min(gaps) > 1.3 * label_px, axis  # a label's height and some air between
    assert "heights x" in ax3d.get_title()  # the flat part is drawn stretched, and says so
    plots._pyplot().close(fig)
