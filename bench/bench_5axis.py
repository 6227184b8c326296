"""The measured 5-axis cases: rewrite, simulate, and the spindle-limited optimum.

Two cases of ``bench/make_5axis.py``, each a dome and a bowl (D10 ball, lead and tilt each
5-25 deg): ``sweep``, lead and tilt sweeping slowly along the whole path (at most 0.43
deg/mm, 0.5 mm blocks), and ``flowline``, the harder one, lead and tilt functions of the
place that sweep 5-25 deg within every pass (up to 3.9 and 2.4 deg/mm, 1 mm blocks: the
axis turns 3 deg a block at the median, 5.5 at most).  Each in every style (Sinumerik
TRAORI vectors, Fanuc G43.5 vectors, xyzac-trt angles in G94 and in G93), with and
without the exact mesh, run as a user runs it::

    ncopt rewrite PROG [--mesh PART.stl] --diameter 10 --teeth 2 --vc 150 --fz 0.08 \\
        --accel 227 --max-rpm 18000 --kinematics vector|xyzac-trt -o OUT
    ncopt simulate OUT --mesh PART.stl ... (the same options)

It prints the cutting time before and after, against the optimum, the share of the cut
with fz within +-2 %, the worst fz and vc (simulate with the mesh judges both rewrites),
and the S words.

The optimum is ``bench/optimum_5axis.py``'s, computed without ncopt from the analytic
part: samples every 0.02 mm, the tool axis between block ends as the control turns it
(vectors along the great circle, angles linearly), R_eff from the exact contact, the
largest S(s) under the requirement with the spindle's acceleration everywhere (F = fz z S
on feed moves, the rapids at the machine's rapid rate).  ``after/free`` is against the
same optimum with the spindle free across rapids (a lower bound no program reaches).

``python bench/bench_5axis.py [OUT_DIR] [--small] [--sweep] [--flowline] [--step=MM]``
(``--step``: the flowline case's block length, default 1 mm)
"""

from __future__ import annotations

import importlib.util
import math
import os
import sys
import time


import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from ncopt.api import rewrite_file  # noqa: E402
from ncopt.cli.app import make_job  # noqa: E402
from ncopt.simulate.replay import simulate_file  # noqa: E402

VC, FZ, Z, ACCEL, S_MAX = 150.0, 0.08, 2, 227.0, 18000.0
TOL_MM, STEP_MM = 0.05, 0.05
RUNS = (("traori", "g94", "vector"), ("g43.5", "g94", "vector"),
        ("xyzac-trt", "g94", "xyzac-trt"), ("xyzac-trt", "g93", "xyzac-trt"))


def _generator():
    spec = importlib.util.spec_from_file_location("make_5axis", os.path.join(HERE, "make_5axis.py"))
    module = importlib.util.module_from_spec(spec)
    sys.modules["make_5axis"] = module
    spec.loader.exec_module(module)
    return module


def _optimum_module():
    spec = importlib.util.spec_from_file_location("optimum_5axis",
                                                  os.path.join(HERE, "optimum_5axis.py"))
    module = importlib.util.module_from_spec(spec)
    sys.modules["optimum_5axis"] = module
    spec.loader.exec_module(module)
    return module


def main(out_dir: str, small: bool, variations=("sweep", "flowline"),
         step_mm: float | None = None) -> None:
    gen, ref = _generator(), _optimum_module()
    print("| case | part | style | mesh | blocks | before | after | optimum | after/optimum | "
          "after/free | fz in +-2 % | fz worst | vc worst | S words | rewrite s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for variation in variations:
        step = step_mm if variation == "flowline" else None
        gen.write_cases(out_dir, small=small, variation=variation, step_mm=step)
        for kind in ("dome", "bowl"):
            _rows(gen, ref, out_dir, variation, kind, small, step)


def _rows(gen, ref, out_dir, variation, kind, small, step_mm):
    """One table row per style and mesh of one part."""
    case = gen.make_case(kind, **gen.case_args(variation, small, step_mm))
    best = {angles: ref.optimum(gen, case, angles).cutting_min for angles in (False, True)}
    free = {angles: ref.optimum(gen, case, angles, rapid_free=True).cutting_min
            for angles in (False, True)}
    stl = os.path.join(out_dir, f"{kind}.stl")
    for style, feed, kin in RUNS:
        name = f"{gen.case_name(kind, variation)}_{style}" + ("_g93" if feed == "g93" else "") \
            + ".nc"
        prog = os.path.join(out_dir, name)
        job = make_job(diameter=10, teeth=2, vc=VC, fz=FZ, accel=ACCEL, max_rpm=S_MAX,
                       kinematics=kin)
        for mesh in (stl, None):
            t0 = time.perf_counter()
            result = rewrite_file(prog, job, mesh_path=mesh)
            took = time.perf_counter() - t0
            out = prog.replace(".nc", "_out.nc" if mesh else "_out_nomesh.nc")
            with open(out, "w", encoding="latin-1", newline="") as fh:
                fh.write(result.text)
            before, _ = simulate_file(prog, job, stl)
            rep, _ = simulate_file(out, job, stl)
            opt, low = best[kin != "vector"], free[kin != "vector"]
            print(f"| {variation} | {kind} | {style} {feed.upper()} | "
                  f"{'yes' if mesh else 'no'} | "
                  f"{result.summary.blocks} | {before.cutting_time_min:.3f} | "
                  f"{rep.cutting_time_min:.3f} | {opt:.3f} | "
                  f"{rep.cutting_time_min / opt:.4f} | {rep.cutting_time_min / low:.4f} | "
                  f"{rep.fz_in_band_pct:.2f} % | "
                  f"{rep.fz_max_over_pct:+.2f} / {-rep.fz_min_under_pct:+.2f} % | "
                  f"{rep.vc_max_over_pct:+.2f} % | {rep.s_words} | {took:.1f} |")



if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    wanted = tuple(v for v in ("sweep", "flowline") if f"--{v}" in sys.argv)
    steps = [float(a.split("=", 1)[1]) for a in sys.argv[1:] if a.startswith("--step=")]
    main(args[0] if args else "/tmp/ncopt_5axis", "--small" in sys.argv,
         wanted or ("sweep", "flowline"), steps[-1] if steps else None)
