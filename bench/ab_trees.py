"""Two (or more) checkouts of ncopt rewriting one program, interleaved, against the floor.

    python bench/ab_trees.py PROGRAM ROUNDS TREE [TREE ...]

Each round measures the floor (read the file and split every line into address words with
one regex, in pure Python: ``bench_styles.py``'s) in this process, then runs each TREE's
mesh-free rewrite of PROGRAM (D16 ball, 2 teeth, 227 rad/s^2, 15000 RPM: the project's bench
spindle) in a fresh process with ``PYTHONPATH=TREE``: the whole process's wall time (import,
read, ``rewrite_text``, write), its CPU time (user + system, every thread), its peak RSS
(ru_maxrss) and the sha256 of the output, which must be the same for every tree.  The
medians are printed as ratios to the median floor.  On a machine that other work shares,
wall times swing by 30 % from run to run: the CPU times and the peaks are the steadier
figures, and only figures of one run are compared (a checkout of the commit before a change,
``git worktree add`` or ``git archive | tar -x``, beside the one after it).
"""

from __future__ import annotations

import os
import re
import resource
import statistics
import subprocess
import sys
import time

WORD = re.compile(r"([A-Z])\s*([-+]?[0-9]*\.?[0-9]+)")

ONE = """
import hashlib, resource, sys
from ncopt.api import rewrite_text
from ncopt.model import Cutter, Job, Machine
job = Job(cutter=Cutter(16.0, 2), machine=Machine(accel_rad_s2=227.0, max_rpm=15000.0))
text = open(sys.argv[1], encoding="latin-1").read()
out = rewrite_text(text, job, sys.argv[1]).text
with open(sys.argv[2], "w", encoding="latin-1", newline="") as f:
    f.write(out)
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
      hashlib.sha256(out.encode("latin-1")).hexdigest()[:16])
"""


def floor_s(path: str) -> float:
    """Read the file and split every line into address words with one regex."""
    t0 = time.perf_counter()
    with open(path, encoding="latin-1") as f:
        text = f.read()
    n = 0
    for line in text.splitlines():
        n += len(WORD.findall(line))
    assert n > 0
    return time.perf_counter() - t0


def run(tree: str, path: str, out: str) -> tuple[float, float, float, str]:
    """(wall s, CPU s, peak MB, output sha) of one rewrite in a fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", ONE, path, out], cwd=tree, text=True,
                          capture_output=True, env=dict(os.environ, PYTHONPATH=tree))
    wall = time.perf_counter() - t0
    if done.returncode:
        sys.exit(f"{tree}: exit {done.returncode}\n{done.stderr}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    peak, sha = done.stdout.split()[-2:]
    return wall, cpu, float(peak), sha


def main(argv: list[str]) -> int:
    if len(argv) < 3:
        sys.exit(__doc__)
    path, rounds, trees = argv[0], int(argv[1]), [os.path.abspath(t) for t in argv[2:]]
    out = os.path.join(os.environ.get("TMPDIR", "/tmp"), "ncopt_ab_out.nc")
    floors, rows = [], {t: [] for t in trees}
    for r in range(rounds):
        floors.append(floor_s(path))
        for t in trees:
            rows[t].append(run(t, path, out))
            wall, cpu, peak, sha = rows[t][-1]
            print(f"round {r + 1}: {t}: wall {wall:.2f} s, CPU {cpu:.2f} s, peak {peak:.0f} MB, "
                  f"sha {sha}, floor {floors[-1]:.2f} s", flush=True)
    floor = statistics.median(floors)
    print(f"floor: median {floor:.2f} s ({min(floors):.2f}-{max(floors):.2f})")
    for t in trees:
        wall = statistics.median(x[0] for x in rows[t])
        cpu = statistics.median(x[1] for x in rows[t])
        peaks = [x[2] for x in rows[t]]
        print(f"{t}: wall {wall:.2f} s = {wall / floor:.1f}x floor, CPU {cpu:.2f} s = "
              f"{cpu / floor:.1f}x floor, peak {min(peaks):.0f}-{max(peaks):.0f} MB (medians)")
    shas = {x[3] for t in trees for x in rows[t]}
    if len(shas) != 1:
        print(f"DIFFERENT OUTPUTS: {sorted(shas)}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
