"""The measured 5-axis cases: rewrite, simulate, and the spindle-limited optimum.

For the dome and the bowl of ``bench/make_5axis.py`` (D10 ball, lead and tilt
each 5-25 deg) in every style (Sinumerik TRAORI vectors, Fanuc G43.5 vectors,
xyzac-trt angles in G94 and in G93), with and without the exact mesh, this
runs what a user runs::

    ncopt rewrite PROG [--mesh PART.stl] --diameter 10 --teeth 2 --vc 150 --fz 0.08 \\
        --accel 227 --max-rpm 18000 --kinematics vector|xyzac-trt -o OUT
    ncopt simulate OUT --mesh PART.stl ... (the same options)

and prints the cutting time before and after, against the optimum, the share
of the cut with fz within +-2 %, the worst fz and vc, and the S words.

The spindle-limited optimum is computed here from the analytic part, not from
ncopt: every feed move of the generated toolpath is sampled every 0.05 mm, the
tool axis between its ends moved as the control moves it (vectors blended,
angles interpolated), the contact on the sphere found exactly, R_eff = R
sqrt(1 - (n.e)^2) where the ball is within the simulator's 0.05 mm of the
part.  Over each run of moves that touch the part (simulate's cutting blocks)
the optimum spindle speed is the largest S(s) <= min(S_max, 1000 vc / (2 pi
R_eff)) with |d(S^2)/ds| <= 2 * 60 * a / (fz z) (a in RPM/s), F = fz z S
exactly; across rapids the spindle is taken as free (so the optimum is a lower
bound).  Its time is the integral of ds / (fz z S).

``python bench/bench_5axis.py [OUT_DIR] [--small]``
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
from ncopt.motion.kinematics import KINEMATICS, blend  # noqa: E402
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


def _contact(gen, kind, centre):
    """Gap to the sphere (mm) and the unit normal at the contact, for ball centres."""
    if kind == "dome":
        o = np.array([0.0, 0.0, -gen.SPHERE_MM])
        d = centre - o
        r = np.linalg.norm(d, axis=1)
        return r - gen.SPHERE_MM - gen.BALL_MM, d / r[:, None]
    o = np.array([0.0, 0.0, gen.SPHERE_MM])
    d = o - centre
    r = np.linalg.norm(d, axis=1)
    return gen.SPHERE_MM - gen.BALL_MM - r, d / r[:, None]


def optimum_min(gen, case, angles: bool) -> float:
    """The spindle-limited optimum cutting time (module docstring), minutes."""
    mv = gen.moves(case)
    kin = KINEMATICS["xyzac-trt"]
    k_limit = 2.0 * 60.0 * ACCEL * 60.0 / (2.0 * math.pi) / (FZ * Z)
    total, run_s, run_req = 0.0, [], []

    def close_run():
        nonlocal total
        if run_s:
            total += _profile_time(np.concatenate(run_s), np.concatenate(run_req), k_limit)
        run_s.clear()
        run_req.clear()

    for i in range(1, mv.tip_mm.shape[0]):
        if mv.rapid[i]:
            close_run()
            continue
        p0, p1 = mv.tip_mm[i - 1], mv.tip_mm[i]
        length = float(np.linalg.norm(p1 - p0))
        n = max(int(math.ceil(length / STEP_MM)), 1)
        f = np.linspace(0.0, 1.0, n + 1)
        tip = p0 + (p1 - p0) * f[:, None]
        if angles:
            a = mv.angles_deg[i - 1] + (mv.angles_deg[i] - mv.angles_deg[i - 1]) * f[:, None]
            e = kin.tool_axis(a)
        else:
            e = blend(np.tile(mv.axis[i - 1], (n + 1, 1)), np.tile(mv.axis[i], (n + 1, 1)), f)
        gap, normal = _contact(gen, case.kind, tip + gen.BALL_MM * e)
        touch = gap <= TOL_MM
        if not touch.any():
            close_run()
            continue
        c = np.clip(np.sum(normal * e, axis=1), -1.0, 1.0)
        r_eff = gen.BALL_MM * np.sqrt(1.0 - c * c)
        with np.errstate(divide="ignore"):
            req = np.where(touch, np.minimum(S_MAX, 1000.0 * VC / (2 * math.pi * r_eff)), S_MAX)
        s = length * f
        start = run_s[-1][-1] if run_s else 0.0
        run_s.append(start + s[1:] if run_s else s)
        run_req.append(req[1:] if run_s[:-1] else req)
    close_run()
    return total


def _profile_time(s: np.ndarray, req: np.ndarray, k_limit: float) -> float:
    """Time (min) of the largest S <= req with |d(S^2)/ds| <= k_limit along s."""
    s2 = (req * req).tolist()
    ds = np.diff(s).tolist()
    for i in range(1, len(s2)):  # forward: rises limited
        s2[i] = min(s2[i], s2[i - 1] + k_limit * ds[i - 1])
    for i in range(len(s2) - 2, -1, -1):  # backward: falls limited
        s2[i] = min(s2[i], s2[i + 1] + k_limit * ds[i])
    speed = np.sqrt(np.array(s2))
    inv = 1.0 / (FZ * Z * speed)
    return float(np.sum(np.diff(s) * 0.5 * (inv[1:] + inv[:-1])))


def main(out_dir: str, small: bool) -> None:
    gen = _generator()
    gen.write_cases(out_dir, small=small)
    size = dict(half_mm=8.0, step_mm=1.0, stepover_mm=1.5) if small else {}
    print("| part | style | mesh | blocks | before | after | optimum | after/optimum | "
          "fz in +-2 % | fz worst | vc worst | S words | rewrite s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for kind in ("dome", "bowl"):
        case = gen.make_case(kind, **size)
        best = {angles: optimum_min(gen, case, angles) for angles in (False, True)}
        stl = os.path.join(out_dir, f"{kind}.stl")
        for style, feed, kin in RUNS:
            name = f"{kind}_{style}" + ("_g93" if feed == "g93" else "") + ".nc"
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
                opt = best[kin != "vector"]
                print(f"| {kind} | {style} {feed.upper()} | {'yes' if mesh else 'no'} | "
                      f"{result.summary.blocks} | {before.cutting_time_min:.3f} | "
                      f"{rep.cutting_time_min:.3f} | {opt:.3f} | "
                      f"{rep.cutting_time_min / opt:.4f} | {rep.fz_in_band_pct:.2f} % | "
                      f"{rep.fz_max_over_pct:+.2f} / {-rep.fz_min_under_pct:+.2f} % | "
                      f"{rep.vc_max_over_pct:+.2f} % | {rep.s_words} | {took:.1f} |")



if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    main(args[0] if args else "/tmp/ncopt_5axis", "--small" in sys.argv)
