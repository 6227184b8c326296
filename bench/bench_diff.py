"""``ncopt diff`` against ``diff -u`` / ``diff -ru``, CPU time of the whole process (user +
system, from ``os.wait4``: other work on the machine changes the wall time more than this).

    python bench/bench_diff.py [--repeat N] [--out DIR]

Three cases, each the median of ``--repeat`` runs, measured in one run:

* the sample bowl (22k lines) and its rewrite: a small program, where starting Python is
  most of it (printed beside it: ``python -S -c pass``, the floor of any Python program);
* the corpus's largest program (``fusion/BowlTest.nc``, 151k lines) and its rewrite;
* the corpus as a batch leaves it: a copy of ``../shared/corpus`` and the same copy with
  every program ncopt plans (D6 ball, the README's machine) replaced by its rewrite, as
  ``ncopt diff IN OUT`` and ``diff -ru IN OUT`` compare them.

The rewrites are made once into ``--out`` (a temporary folder by default).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CORPUS = (ROOT / "../shared/corpus").resolve()
NCOPT = [sys.executable, "-m", "ncopt"]
JOB = ["--accel", "227", "--max-rpm", "15000"]


def cpu_s(cmd: list[str]) -> float:
    """User + system CPU seconds of one run of ``cmd`` (its output to /dev/null)."""
    with open(os.devnull, "wb") as null:
        proc = subprocess.Popen(cmd, stdout=null, stderr=null)
        _, _, usage = os.wait4(proc.pid, 0)
    return usage.ru_utime + usage.ru_stime


def median_cpu_s(cmd: list[str], repeat: int) -> float:
    return statistics.median(cpu_s(cmd) for _ in range(repeat))


def prepare(out: Path) -> dict[str, tuple[str, str]]:
    """The pairs compared: name -> (original, rewritten), files or folders."""
    out.mkdir(parents=True, exist_ok=True)
    bowl = out / "bowl_opt.mpf"
    if not bowl.exists():
        subprocess.run([*NCOPT, "rewrite", str(ROOT / "samples/bowl.mpf"), *JOB, "-q",
                        "-o", str(bowl)], check=True)
    big = out / "BowlTest_opt.nc"
    if not big.exists():
        subprocess.run([*NCOPT, "rewrite", str(CORPUS / "fusion/BowlTest.nc"), "--diameter",
                        "6", *JOB, "-q", "-o", str(big)], check=True)
    a, b = out / "corpus_in", out / "corpus_out"
    if not b.exists():
        shutil.copytree(CORPUS, a, dirs_exist_ok=True)
        rewritten = out / "batch"
        subprocess.run([*NCOPT, "batch", str(a), "-o", str(rewritten), "--diameter", "6",
                        *JOB, "-q"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        shutil.copytree(a, b)
        shutil.copytree(rewritten, b, dirs_exist_ok=True)
    return {"sample bowl (22k lines)": (str(ROOT / "samples/bowl.mpf"), str(bowl)),
            "fusion/BowlTest.nc (151k lines)": (str(CORPUS / "fusion/BowlTest.nc"), str(big)),
            "the corpus, as folders": (str(a), str(b))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--out", type=Path, default=Path(tempfile.gettempdir()) / "ncopt_diff_bench")
    args = ap.parse_args()
    pairs = prepare(args.out)
    floor = median_cpu_s([sys.executable, "-S", "-c", "pass"], args.repeat)
    print(f"python -S -c pass: {floor:.3f} s CPU (the start of any Python program)")
    print(f"{'case':34} {'diff':>8} {'ncopt diff':>11} {'ratio':>6}")
    for name, (a, b) in pairs.items():
        flag = "-ru" if os.path.isdir(a) else "-u"
        plain = median_cpu_s(["diff", flag, a, b], args.repeat)
        ours = median_cpu_s([*NCOPT, "diff", a, b], args.repeat)
        print(f"{name:34} {plain:7.3f}s {ours:10.3f}s {ours / max(plain, 1e-9):5.1f}x")


if __name__ == "__main__":
    main()
