"""How long ``ncopt --help`` and ``ncopt version`` take to start: the median of five runs
of the installed ``ncopt`` command (target: under 0.3 s on the 2-core machine), and which
heavy modules the command line imports before a command needs them.

Wall-clock time depends on what else the machine runs; the CPU time (user + system) of
the child much less, so both are printed.

    python bench/bench_startup.py [--runs 5]
"""

from __future__ import annotations

import argparse
import resource
import shutil
import statistics
import subprocess
import sys
import time

COMMANDS = (["--help"], ["version"], ["--version"], ["rewrite", "-h"])
HEAVY = ("numpy", "lark", "scipy", "igl", "ncopt.api", "rich", "pydantic")


def seconds(argv: list[str]) -> tuple[float, float]:
    """Wall-clock and CPU seconds of one run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime


def report(what: str, runs: list[tuple[float, float]]) -> None:
    wall, cpu = [w for w, _ in runs], [c for _, c in runs]
    print(f"{what}: wall median {statistics.median(wall):.3f} s (min {min(wall):.3f}, max "
          f"{max(wall):.3f}), CPU median {statistics.median(cpu):.3f} s, {len(runs)} runs")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    ncopt = shutil.which("ncopt")
    if ncopt is None:
        sys.exit("ncopt is not installed in this environment (python -m pip install .)")
    report("python -c pass", [seconds([sys.executable, "-c", "pass"]) for _ in range(args.runs)])
    for extra in COMMANDS:
        report(f"ncopt {' '.join(extra)}", [seconds([ncopt, *extra]) for _ in range(args.runs)])
    probe = ("import sys; import ncopt.cli.app; "
             f"print(' '.join(m for m in {HEAVY!r} if m in sys.modules) or 'none')")
    loaded = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True,
                            text=True).stdout.strip()
    print(f"heavy modules imported by 'import ncopt.cli.app': {loaded}")


if __name__ == "__main__":
    main()
