"""HTML report: size and load time in headless Chromium.

    python bench/bench_report.py [--runs 3]

Writes the sample bowl's report (rewrite --report), its lite page (report --report-lite)
and a batch of three corpus programs (batch --report index.html, whose pages share one
plotly.min.js) into a temporary folder, prints each page's size (plotly.js, data, images),
the batch's total (pages, the shared plotly.min.js and the index) and how long headless
Chromium takes until every plot is drawn: the page's own figure (data-drawn-ms, from the
start of loading, median of the runs) and the wall time of the whole chromium --dump-dom
call (browser start included).  A page holding only plotly.js gives the floor.
"""

from __future__ import annotations

import argparse
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CORPUS = (ROOT / "../shared/corpus").resolve()
# three programs ncopt plans (3D_Chips.ngc, once here, is refused now: F4500000 is implausible)
BATCH = ("fusion/BowlTest.nc", "more/fusion-generic_Nozzle_OP_A.nc",
         "more/fusion-linuxcnc-inch_r8s.ngc")
SPINDLE = ["--accel", "227", "--max-rpm", "15000"]


def ncopt(*args) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "from ncopt.cli.app import main; main()",
                    *map(str, args)], check=True,
                   cwd=ROOT, capture_output=True)
    return time.perf_counter() - t0


def load(page: Path, runs: int) -> tuple[float | None, float]:
    """(median data-drawn-ms, median wall s) of headless Chromium on the page."""
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    drawn, wall = [], []
    for _ in range(runs):
        with tempfile.TemporaryDirectory() as profile:
            t0 = time.perf_counter()
            dom = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu",
                                  "--disable-background-networking", "--no-first-run",
                                  "--disable-component-update", "--disable-sync",
                                  f"--user-data-dir={profile}", "--dump-dom", page.as_uri()],
                                 capture_output=True, text=True, timeout=300).stdout
            wall.append(time.perf_counter() - t0)
        m = re.search(r'data-drawn-ms="(\d+)"', dom)
        if m:
            drawn.append(float(m.group(1)))
    return (statistics.median(drawn) if drawn else None), statistics.median(wall)


def parts(page: Path) -> str:
    text = page.read_text(encoding="utf-8")
    inline = "<script>/**" in text  # plotly.js embedded (else shared, or a lite page)
    js = len(text[text.index("<script>") + 8:text.index("</script>")]) if inline else 0
    images = sum(len(m) for m in re.findall(r"<img class=[\w-]+ alt='' src='([^']*)'", text))
    shared = re.search(r"<script src='([^']+)'>", text)
    where = (f"plotly.js {js / 1e6:.2f}" if inline else
             f"plotly.js shared: {shared.group(1)}" if shared else "no plotly.js")
    return (f"{len(text) / 1e6:.2f} MB ({where}, images {images / 1e6:.2f}, the rest "
            f"{(len(text) - js - images) / 1e6:.2f})")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    out = Path(tempfile.mkdtemp(prefix="ncopt-report-"))
    from plotly.offline import get_plotlyjs
    floor = out / "plotly-only.html"
    floor.write_text("<!DOCTYPE html><html><head><meta charset=utf-8><script>" + get_plotlyjs()
                     + "</script></head><body><script>document.body.setAttribute("
                     "'data-drawn-ms', Math.round(performance.now()));</script></body></html>",
                     encoding="utf-8")
    t = ncopt("rewrite", ROOT / "samples/bowl.mpf", "--mesh", ROOT / "samples/bowl.stl",
              "--diameter", "16", *SPINDLE, "-o", out / "bowl_opt.mpf", "--report",
              out / "bowl.html", "-q")
    print(f"bowl: rewrite + report {t:.1f} s")
    t = ncopt("report", out / "bowl_opt.mpf", "--against", ROOT / "samples/bowl.mpf", "--mesh",
              ROOT / "samples/bowl.stl", "--diameter", "16", *SPINDLE, "--report-lite", "-o",
              out / "bowl_lite.html", "-q")
    print(f"bowl: lite report {t:.1f} s")
    src = out / "batch"
    (src / "sub").mkdir(parents=True)
    for i, rel in enumerate(BATCH):
        (src / ("sub" if i else ".") / Path(rel).name).symlink_to(CORPUS / rel)
    t = ncopt("batch", src, "-o", out / "batch_out", *SPINDLE, "--report", out / "index.html",
              "--jobs", "2")
    print(f"batch of {len(BATCH)}: rewrite + reports {t:.1f} s (2 processes)")
    batch = sorted((out / "index").rglob("*")) + [out / "index.html"]
    total = sum(p.stat().st_size for p in batch if p.is_file())
    n = sum(p.suffix == ".html" for p in batch) - 1
    print(f"batch of {len(BATCH)}: {total / 1e6:.2f} MB together ({n} pages, the shared "
          "plotly.min.js and the index)")
    pages = [floor, out / "bowl.html", out / "bowl_lite.html", out / "index.html"] + sorted(
        (out / "index").rglob("*.html"))
    for page in pages:
        drawn, wall = load(page, args.runs)
        what = parts(page) if page not in (floor, out / "index.html") else \
            f"{page.stat().st_size / 1e6:.2f} MB"
        shown = "-" if drawn is None else f"{drawn:.0f} ms"
        print(f"{page.relative_to(out)}: {what}; drawn after {shown}, chromium "
              f"--dump-dom {wall:.1f} s (median of {args.runs})")
    print(f"pages in {out}")


if __name__ == "__main__":
    main()
