"""plotly.js for the report's interactive plots, so a page needs no network when it is
viewed: embedded whole in a single page, or one ``plotly.min.js`` that a batch's pages
share in their folder (written once, by the first page that needs it).
"""

from __future__ import annotations

from pathlib import Path

from ncopt.runtime.fileio import write_output

__all__ = ["PLOTLY_FILE", "plotly_js", "shared_plotly"]

PLOTLY_FILE = "plotly.min.js"  # a batch's pages share this file, in the pages' folder


def plotly_js() -> str:
    """The whole plotly.js (some megabytes of text)."""
    # plotly is optional (the "plot" extra) and slow to load: only a page with plots needs it
    from plotly.offline import get_plotlyjs

    return get_plotlyjs()


def shared_plotly(folder: Path) -> Path:
    """``folder/plotly.min.js``, written (atomically) unless it already holds this plotly.js."""
    js = plotly_js().encode("utf-8")
    target = folder / PLOTLY_FILE
    try:
        same = target.stat().st_size == len(js) and target.read_bytes() == js
    except OSError:
        same = False
    if not same:
        write_output(target, js, make_parents=True)
    return target
