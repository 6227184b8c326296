"""Generate a large benchmark case: a ~1M-block finishing program and a ~1M-triangle STL.

Same part and generator as the committed sample (``samples/make_bowl.py``: analytic bowl,
D16 ball, exact drop-cutter, zig-zag X-Z passes), and a finer grid for the mesh.  Two
spacings reach about ``n_blocks`` blocks:

* ``dense`` (default): the stepover and the point spacing scaled down together (ratio
  1.6 : 0.75 as in the sample): 1M blocks of <= 0.11 mm, about 110 m of path;
* ``paper``: the paper's and the sample's 0.75 mm between points kept, only the stepover
  shrunk (0.035 mm for 1M blocks: the same points as 46 sample layers each shifted by
  1/46 of its 1.6 mm stepover): 1M blocks of 0.73-0.75 mm, about 750 m of path.

Run ``python bench/make_case.py [OUT_DIR] [N_BLOCKS] [N_TRIANGLES] [dense|paper]``
(default ``/tmp/ncopt_bench``, 1,000,000, 1,000,000, dense).
"""

from __future__ import annotations

import importlib.util
import math
import os
import sys
import time

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_SAMPLES = os.path.join(_ROOT, "samples", "make_bowl.py")


def _load_make_bowl():
    """Load ``samples/make_bowl.py`` by file path (``samples`` is not a package)."""
    spec = importlib.util.spec_from_file_location("ncopt_samples_make_bowl", _SAMPLES)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


SPACINGS = ("dense", "paper")
PAPER_STEP_MM = 0.75
"""Largest distance between points of the ``paper`` case (the sample's, within the paper's
0.5-1 mm)."""


def choose_spacing_mm(n_blocks, radius_mm=8.0, ratio=1.6 / 0.75, step_mm=None):
    """Stepover and point spacing that give a program of about ``n_blocks`` blocks.

    Parameters
    ----------
    n_blocks : int
        Target number of NC blocks.
    radius_mm : float, optional
        Ball radius (mm).
    ratio : float, optional
        Stepover divided by point spacing (the sample's 1.6 / 0.75).
    step_mm : float or None, optional
        Keep this point spacing and shrink only the stepover (``ratio`` unused).

    Returns
    -------
    stepover_mm, step_mm : float
        Rounded to 1e-4 mm. The block count scales like ``1 / (stepover * step)``; two
        corrections on the real layout land within a fraction of a percent.
    """
    mb = _load_make_bowl()
    if step_mm is not None:
        stepover = 1.6
        for _ in range(3):
            n = mb.count_blocks(mb.toolpath_layout(radius_mm, stepover, step_mm))
            stepover = round(stepover * n / n_blocks, 4)
        return stepover, step_mm
    step = 0.75
    for _ in range(3):
        stepover = round(ratio * step, 4)
        n = mb.count_blocks(mb.toolpath_layout(radius_mm, stepover, step))
        step = round(step * math.sqrt(n / n_blocks), 4)
    return round(ratio * step, 4), step


def make_case(out_dir, n_blocks=1_000_000, n_triangles=1_000_000, radius_mm=8.0,
              spacing="dense"):
    """Write ``bowl_bench.mpf`` (about ``n_blocks`` blocks) and ``bowl_bench.stl``.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Output folder (created if missing).
    n_blocks : int, optional
        Approximate number of NC blocks of the program.
    n_triangles : int, optional
        Approximate number of triangles of the binary STL (a square grid of
        ``n = round(sqrt(n_triangles / 2))`` cells per side over the +-95 mm land).
    radius_mm : float, optional
        Ball radius (mm), the paper's D16 by default.
    spacing : {"dense", "paper"}, optional
        How the blocks are spaced (module docstring).

    Returns
    -------
    dict
        ``mpf``, ``stl`` (paths), ``blocks``, ``triangles``, ``mpf_bytes``, ``stl_bytes``,
        ``stepover_mm``, ``step_mm``, ``mesh_step_mm`` and ``seconds``.
    """
    t0 = time.perf_counter()
    mb = _load_make_bowl()
    os.makedirs(out_dir, exist_ok=True)

    if spacing not in SPACINGS:
        raise ValueError(f"spacing must be one of {SPACINGS}, got {spacing!r}")
    stepover, step = choose_spacing_mm(n_blocks, radius_mm,
                                       step_mm=PAPER_STEP_MM if spacing == "paper" else None)
    text = mb.make_program(radius_mm=radius_mm, stepover_mm=stepover, step_mm=step,
                           title=f"ncopt benchmark: bowl mould finishing, about {n_blocks} blocks, "
                                 f"{spacing} spacing")
    mpf = os.path.join(out_dir, "bowl_bench.mpf")
    mpf_bytes = mb.write_text(mpf, text)
    blocks = text.count("\nN") + (1 if text.startswith("N") else 0)
    del text
    t1 = time.perf_counter()

    cells = max(1, int(round(math.sqrt(n_triangles / 2.0))))
    mesh_step = 2.0 * mb.HALF_WIDTH_MM / cells
    V, F = mb.bowl_mesh(mesh_step)
    stl = os.path.join(out_dir, "bowl_bench.stl")
    stl_bytes = mb.write_stl(stl, V, F, name="ncopt bowl mould, benchmark mesh")
    n_tri = len(F)
    del V, F
    t2 = time.perf_counter()

    info = dict(mpf=mpf, stl=stl, blocks=blocks, triangles=n_tri, mpf_bytes=mpf_bytes,
                stl_bytes=stl_bytes, stepover_mm=stepover, step_mm=step, mesh_step_mm=mesh_step,
                seconds=t2 - t0)
    print(f"wrote {mpf}: {blocks} blocks, {mpf_bytes / 1e6:.1f} MB "
          f"(stepover {stepover} mm, point spacing <= {step} mm, {t1 - t0:.1f} s)")
    print(f"wrote {stl}: {n_tri} triangles, grid step {mesh_step:.4f} mm, "
          f"{stl_bytes / 1e6:.1f} MB ({t2 - t1:.1f} s)")
    print(f"total {t2 - t0:.1f} s")
    return info


def main(argv=None):
    """Command line: ``make_case.py [OUT_DIR] [N_BLOCKS] [N_TRIANGLES] [dense|paper]``."""
    argv = sys.argv[1:] if argv is None else argv
    out_dir = argv[0] if len(argv) > 0 else "/tmp/ncopt_bench"
    n_blocks = int(float(argv[1])) if len(argv) > 1 else 1_000_000
    n_tri = int(float(argv[2])) if len(argv) > 2 else 1_000_000
    spacing = argv[3] if len(argv) > 3 else "dense"
    return make_case(out_dir, n_blocks, n_tri, spacing=spacing)


if __name__ == "__main__":
    main()
