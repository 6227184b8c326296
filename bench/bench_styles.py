"""Speed whatever the program looks like: one finishing program in several posts' styles.

The same ~N-block bowl finishing program (``samples/make_bowl.py``'s generator, the spacing
``bench/make_case.py`` picks for N blocks) is written in these styles:

* ``plain``: the generator's own word lines (``N114 X-9.471``);
* ``semicolon``: a ``; pt`` comment after every motion block (Sinumerik, LinuxCNC, grbl posts);
* ``paren``: a ``(pt)`` comment after every motion block (Fanuc, Mach posts);
* ``arcs``: every move an arc (``G2``/``G3`` with ``I`` and ``K`` in ``G18``), the same points;
* ``heidenhain``: Heidenhain ISO, ``N`` numbers and ``*`` on every block;
* ``fusion``: a real Fusion 360 program (``../shared/corpus/fusion/BowlTest.nc``, 151k lines)
  with its cutting body repeated up to N blocks.

Each is rewritten without a mesh, or with ``--mesh`` with the sample bowl's mesh
(``samples/bowl.stl``, loaded inside the timing; the fusion style, another part, is then
left out) (D16 ball, 2 teeth, 227 rad/s^2, 15000 RPM: the project's bench spindle) in its
own process, one after the other in one run, and the bench prints its
wall time, its peak memory (ru_maxrss), its ratio to ``plain``, and the ratio of ``plain`` to
a floor measured in the same run: read the plain file and split every line into address words
with one regex, in pure Python. Machines differ by 2x from day to day: read the ratios.

Run ``python bench/bench_styles.py [--blocks N] [--styles plain,semicolon,...] [--mesh] [--out DIR]``
(defaults: 1,000,000 blocks, every style, ``$TMPDIR/ncopt_styles``).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FUSION = (ROOT / "../shared/corpus/fusion/BowlTest.nc").resolve()
STYLES = ("plain", "semicolon", "paren", "arcs", "heidenhain", "fusion")
WORD = re.compile(r"([A-Z])\s*([-+]?[0-9]*\.?[0-9]+)")
ARC_BULGE = 20.0  # arc centre this many chord lengths off the chord: nearly straight arcs


def _load(rel: str, name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / rel)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _spacing(blocks: int) -> tuple[float, float]:
    """(stepover_mm, step_mm) that give a bowl program of about ``blocks`` blocks."""
    return _load("bench/make_case.py", "ncopt_bench_make_case").choose_spacing_mm(blocks)


def plain(blocks: int) -> str:
    bowl = _load("samples/make_bowl.py", "ncopt_samples_make_bowl")
    stepover_mm, step_mm = _spacing(blocks)
    return bowl.make_program(stepover_mm=stepover_mm, step_mm=step_mm)


_MOTION = re.compile(r"^N\d+ (?:G[0-3] )?[XYZ]")


def commented(text: str, comment: str) -> str:
    """``comment`` after every motion block."""
    return "".join(line + comment + "\n" if _MOTION.match(line) else line + "\n"
                   for line in text.splitlines())


def heidenhain(text: str) -> str:
    """The plain program as Heidenhain ISO: ``%NAME G71 *`` around it, ``*`` on every block,
    the tool call ``T4 G17 S...``, no ``;`` comment lines and no G55 (ISO's datum shift
    takes parameters)."""
    out = ["%BOWL G71 *"]
    for line in text.splitlines():
        if not line or line.startswith(";") or line.endswith(" G55"):
            continue
        line = line.replace(" T04 D01", " T4 G17").replace(" M03", " M3").replace(" M08", " M8")
        out.append(line + " *")
    out.append("N99999999 %BOWL G71 *")
    return "\n".join(out) + "\n"


def arcs(blocks: int) -> str:
    """The bowl's points joined by G18 arcs (centre ``ARC_BULGE`` chords off each chord,
    alternately left and right), links between passes in G1."""
    bowl = _load("samples/make_bowl.py", "ncopt_samples_make_bowl")
    stepover_mm, step_mm = _spacing(blocks)
    xyz, pid = bowl.toolpath_points(stepover_mm=stepover_mm, step_mm=step_mm)
    lines = ["(bowl finishing, every move an arc)", "G21 G90 G94 G18", "T4 M6", "S1393 M3",
             f"G0 X{xyz[0, 0]:.4f} Y{xyz[0, 1]:.4f} Z15.", f"G1 Z{xyz[0, 2]:.4f} F279"]
    d = np.diff(xyz, axis=0)
    same_pass = pid[1:] == pid[:-1]
    chord = np.hypot(d[:, 0], d[:, 2])
    side = np.where(np.arange(d.shape[0]) % 2 == 0, 1.0, -1.0)
    # centre = midpoint + side * ARC_BULGE * chord * unit normal of the chord in X-Z
    nx, nz = -d[:, 2], d[:, 0]
    i_mm = d[:, 0] / 2 + side * ARC_BULGE * nx
    k_mm = d[:, 2] / 2 + side * ARC_BULGE * nz
    # G18 arcs turn in the Z-X plane (Z first): counter-clockwise (G3) where the start and
    # end radius vectors (s - c, e - c) have a positive cross product in (z, x)
    cz, cx = xyz[:-1, 2] + k_mm, xyz[:-1, 0] + i_mm
    cross = (xyz[:-1, 2] - cz) * (xyz[1:, 0] - cx) - (xyz[:-1, 0] - cx) * (xyz[1:, 2] - cz)
    for j in range(d.shape[0]):
        p = xyz[j + 1]
        if not same_pass[j] or chord[j] < 1e-6:
            lines.append(f"G1 X{p[0]:.4f} Y{p[1]:.4f} Z{p[2]:.4f}")
            continue
        g = "G3" if cross[j] > 0 else "G2"
        lines.append(f"{g} X{p[0]:.4f} Z{p[2]:.4f} I{i_mm[j]:.4f} K{k_mm[j]:.4f}")
    lines += ["G0 Z15.", "M5", "M30"]
    return "\n".join(lines) + "\n"


def fusion(blocks: int) -> str:
    """The Fusion program's cutting body (first tool's first G1 to the line before the
    closing M9) repeated until about ``blocks`` lines."""
    lines = FUSION.read_text(encoding="latin-1").splitlines()
    first = next(i for i, ln in enumerate(lines) if ln.startswith("G1"))
    last = max(i for i, ln in enumerate(lines) if ln.strip() == "M9")
    head, body, tail = lines[:first], lines[first:last], lines[last:]
    reps = max(1, round((blocks - len(head) - len(tail)) / len(body)))
    return "\n".join(head + body * reps + tail) + "\n"


def write_case(style: str, blocks: int, out: Path) -> Path:
    path = out / f"{style}_{blocks}.nc"
    if path.is_file():
        return path
    if style == "plain":
        text = plain(blocks)
    elif style == "semicolon":
        text = commented(plain(blocks), " ; pt")
    elif style == "paren":
        text = commented(plain(blocks), " (pt)")
    elif style == "heidenhain":
        text = heidenhain(plain(blocks))
    elif style == "arcs":
        text = arcs(blocks)
    else:
        text = fusion(blocks)
    path.write_text(text, encoding="latin-1")
    return path


def floor_s(path: Path) -> float:
    """Read the file and split every line into address words with one regex."""
    t0 = time.perf_counter()
    text = path.read_text(encoding="latin-1")
    n = 0
    for line in text.splitlines():
        n += len(WORD.findall(line))
    assert n > 0
    return time.perf_counter() - t0


def one(path: Path, mesh: Path | None = None) -> dict:
    """Rewrite ``path`` once (in this process), with the bowl's mesh when given (loaded
    inside the timing, as the command line loads it): seconds, peak MB, blocks."""
    from ncopt.api import rewrite_text
    from ncopt.contacts.geometry import MeshIndex, load_stl
    from ncopt.model import Cutter, Job, Machine

    job = Job(cutter=Cutter(16.0, 2), machine=Machine(accel_rad_s2=227.0, max_rpm=15000.0))
    t0 = time.perf_counter()
    text = path.read_text(encoding="latin-1")
    index = MeshIndex(load_stl(mesh)) if mesh is not None else None
    result = rewrite_text(text, job, str(path), index)
    seconds = time.perf_counter() - t0
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"seconds": seconds, "peak_mb": peak_mb, "lines": text.count("\n"),
            "s_words": result.summary.s_words, "f_words": result.summary.f_words}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=1_000_000)
    ap.add_argument("--styles", default=",".join(STYLES))
    ap.add_argument("--out", type=Path, default=Path(tempfile.gettempdir()) / "ncopt_styles")
    ap.add_argument("--mesh", action="store_true",
                    help="with the sample bowl's mesh (samples/bowl.stl); the fusion style, "
                         "another part, is left out")
    ap.add_argument("--one", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--mesh-file", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(one(args.one, args.mesh_file)))
        return 0
    styles = [s for s in args.styles.split(",") if s and not (args.mesh and s == "fusion")]
    unknown = sorted(set(styles) - set(STYLES))
    if unknown:
        ap.error(f"unknown style {', '.join(unknown)}; choose from {', '.join(STYLES)}")
    if "plain" not in styles:
        styles.insert(0, "plain")
    args.out.mkdir(parents=True, exist_ok=True)
    paths = {s: write_case(s, args.blocks, args.out) for s in styles}
    floor = floor_s(paths["plain"])
    rows = {}
    print(f"{'style':<11} {'lines':>9} {'S words':>9} {'seconds':>9} {'x plain':>8} {'peak MB':>8}")
    for s in styles:
        mesh = ["--mesh-file", str(ROOT / "samples/bowl.stl")] if args.mesh else []
        run = subprocess.run([sys.executable, __file__, "--one", str(paths[s]), *mesh],
                             check=True, capture_output=True, text=True, cwd=ROOT)
        rows[s] = json.loads(run.stdout.strip().splitlines()[-1])
        r = rows[s]
        print(f"{s:<11} {r['lines']:>9} {r['s_words']:>9} {r['seconds']:>9.2f} "
              f"{r['seconds'] / rows['plain']['seconds']:>8.2f} {r['peak_mb']:>8.0f}", flush=True)
    print(f"floor (read + one regex per line, plain): {floor:.2f} s; "
          f"plain / floor = {rows['plain']['seconds'] / floor:.2f}")
    print(f"worst style / plain = {max(r['seconds'] for r in rows.values()) / rows['plain']['seconds']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
