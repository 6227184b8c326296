"""How long ``ncopt --help`` and ``ncopt version`` take to start: the median of five runs
of the installed ``ncopt`` command (target: under 0.3 s on the 2-core machine), and which
heavy modules the command line imports before a command needs them.

    python bench/bench_startup.py [--runs 5]
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import time

COMMANDS = (["--help"], ["version"], ["--version"], ["rewrite", "-h"])
HEAVY = ("numpy", "lark", "scipy", "igl", "ncopt.api", "rich", "pydantic")


def seconds(argv: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    ncopt = shutil.which("ncopt")
    if ncopt is None:
        sys.exit("ncopt is not installed in this environment (python -m pip install .)")
    base = [seconds([sys.executable, "-c", "pass"]) for _ in range(args.runs)]
    print(f"python -c pass: median {statistics.median(base):.3f} s (the interpreter alone)")
    for extra in COMMANDS:
        times = [seconds([ncopt, *extra]) for _ in range(args.runs)]
        print(f"ncopt {' '.join(extra)}: median {statistics.median(times):.3f} s of "
              f"{args.runs} (min {min(times):.3f}, max {max(times):.3f})")
    probe = ("import sys; import ncopt.cli; "
             f"print(' '.join(m for m in {HEAVY!r} if m in sys.modules) or 'none')")
    loaded = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True,
                            text=True).stdout.strip()
    print(f"heavy modules imported by 'import ncopt.cli': {loaded}")


if __name__ == "__main__":
    main()
