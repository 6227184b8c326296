"""Cutting time with S changing anywhere vs between passes only, on the sample bowl and
corpus programs (estimated by the planner; 227 rad/s^2, 15000 RPM).

    python bench/s_changes.py            # a markdown table on stdout
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
CORPUS = (ROOT / "../shared/corpus").resolve()

from ncopt import passes  # noqa: E402
from ncopt.api import _separating, rewrite_file  # noqa: E402
from ncopt.cli import make_job  # noqa: E402

CASES = [(ROOT / "samples/bowl.mpf", dict(diameter=16), ROOT / "samples/bowl.stl"),
         (CORPUS / "fusion/BowlTest.nc", {}, None),
         (CORPUS / "linuxcnc/3D_Chips.ngc", {}, None),
         (CORPUS / "more/fusion-linuxcnc-inch_r8s.ngc", {}, None),
         (CORPUS / "camotics/flower_mold.nc", dict(diameter=3.175), None),
         (CORPUS / "camotics/bear.nc", dict(diameter=3.175), None),
         (CORPUS / "fusion/chess_engraved_box.nc", {}, None),
         (CORPUS / "more/fusion-generic_Nozzle_OP_A.nc", {}, None),
         (CORPUS / "camotics/wave.gcode", dict(diameter=3.175), None)]


def pass_lengths_m(result) -> np.ndarray:
    out = []
    for p in result.plans:
        sep = _separating(result.toolpath, result.block_index, p.blocks, p.sampled)
        pid = passes.pass_ids(p.blocks, sep)
        out += np.bincount(pid[pid >= 0], weights=p.blocks.length_mm[pid >= 0]).tolist()
    return np.array(out) / 1000.0


def main() -> None:
    print("| program | passes | median pass | longest pass | before (min) | anywhere | "
          "between passes | S words (between) | s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for path, options, mesh in CASES:
        t0 = time.perf_counter()
        job = make_job(accel=227, max_rpm=15000, s_changes="between-passes", **options)
        r = rewrite_file(path, job, mesh_path=mesh)
        s, length = r.summary, pass_lengths_m(r)
        pct = lambda t: 100 * (t / s.cut_time_before_min - 1) if s.cut_time_before_min else 0.0  # noqa
        print(f"| {path.name} | {s.passes} | {np.median(length):.3f} m | {length.max():.2f} m "
              f"| {s.cut_time_before_min:.1f} | {s.cut_time_other_min:.1f} "
              f"({pct(s.cut_time_other_min):+.1f} %) | {s.cut_time_after_min:.1f} "
              f"({pct(s.cut_time_after_min):+.1f} %) | {s.s_words} | "
              f"{time.perf_counter() - t0:.1f} |")


if __name__ == "__main__":
    main()
