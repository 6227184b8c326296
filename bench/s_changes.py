"""Cutting time with S changing anywhere vs between passes only, on the sample bowl and
corpus programs (estimated by the planner; 227 rad/s^2, 15000 RPM).

    python bench/s_changes.py            # a markdown table on stdout
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
CORPUS = (ROOT / "../shared/corpus").resolve()

from ncopt.api import rewrite_file  # noqa: E402
from ncopt.cli.app import make_job  # noqa: E402
from ncopt.runtime.errors import NothingToPlan  # noqa: E402

CASES = [(ROOT / "samples/bowl.mpf", dict(diameter=16), ROOT / "samples/bowl.stl"),
         (CORPUS / "fusion/BowlTest.nc", {}, None),
         (CORPUS / "linuxcnc/3D_Chips.ngc", {}, None),
         (CORPUS / "more/fusion-linuxcnc-inch_r8s.ngc", {}, None),
         (CORPUS / "camotics/flower_mold.nc", dict(diameter=3.175), None),
         (CORPUS / "camotics/bear.nc", dict(diameter=3.175), None),
         (CORPUS / "fusion/chess_engraved_box.nc", {}, None),
         (CORPUS / "more/fusion-generic_Nozzle_OP_A.nc", {}, None),
         (CORPUS / "camotics/wave.gcode", dict(diameter=3.175), None)]


def main() -> None:
    print("| program | passes | before (min) | anywhere | between passes | S words (between) "
          "| s |")
    print("|---|---|---|---|---|---|---|")
    for path, options, mesh in CASES:
        t0 = time.perf_counter()
        job = make_job(accel=227, max_rpm=15000, s_changes="between-passes", **options)
        try:
            s = rewrite_file(path, job, mesh_path=mesh).summary
        except NothingToPlan as exc:
            print(f"| {path.name} | nothing planned: {exc.message[:60]} | | | | | |")
            continue
        pct = lambda t: 100 * (t / s.cut_time_before_min - 1) if s.cut_time_before_min else 0.0  # noqa
        print(f"| {path.name} | {s.passes} | {s.cut_time_before_min:.1f} | {s.cut_time_other_min:.1f} "
              f"({pct(s.cut_time_other_min):+.1f} %) | {s.cut_time_after_min:.1f} "
              f"({pct(s.cut_time_after_min):+.1f} %) | {s.s_words} | "
              f"{time.perf_counter() - t0:.1f} |")


if __name__ == "__main__":
    main()
