"""Hash what ncopt writes for every corpus program and the sample, to compare two checkouts.

    python bench/snapshot.py OUT.json            # on one checkout, then on the other
    cmp A.json B.json                            # identical outputs, summaries and errors

Every program of ``../shared/corpus`` (read in place) is rewritten twice, as its comments give
its tools and with a D6 ball, on the project's bench spindle (227 rad/s^2, 15000 RPM), and the
sample bowl with its mesh; each row holds the output's sha256, the summary (or the error).
A restructure must leave this file byte for byte the same.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ["SOURCE_DATE_EPOCH"] = "1700000000"  # the stamp's date

from ncopt.api import rewrite_file, rewrite_text  # noqa: E402
from ncopt.model import Cutter, Job, Machine  # noqa: E402
from ncopt.runtime.errors import NcoptError  # noqa: E402

CORPUS = (ROOT / "../shared/corpus").resolve()
SUFFIXES = {".nc", ".ngc", ".tap", ".gcode", ".mpf", ".h"}
JOB = Job(machine=Machine(accel_rad_s2=227.0, max_rpm=15000.0))


def _sha(text: str) -> str:
    return hashlib.sha256(text.encode("latin-1", "replace")).hexdigest()[:16]


def main(out: str) -> int:
    rows = {}
    programs = sorted(p for p in CORPUS.rglob("*") if p.suffix.lower() in SUFFIXES and p.is_file())
    for path in programs:
        text = path.read_bytes().decode("latin-1")
        for name, job in (("job", JOB), ("d6", replace(JOB, cutter=Cutter(6.0, 2)))):
            key = f"{path.relative_to(CORPUS)}:{name}"
            try:
                r = rewrite_text(text, job, str(path))
                rows[key] = {"out": _sha(r.text), "summary": repr(r.summary)}
            except NcoptError as exc:
                rows[key] = {"err": f"{type(exc).__name__}: {exc}"}
    bowl = rewrite_file(ROOT / "samples/bowl.mpf", replace(JOB, cutter=Cutter(16.0, 2)),
                        mesh_path=ROOT / "samples/bowl.stl")
    rows["samples/bowl.mpf:mesh"] = {"out": _sha(bowl.text), "summary": repr(bowl.summary)}
    Path(out).write_text(json.dumps(rows, indent=1, sort_keys=True))
    print(f"{len(rows)} rewrites hashed into {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "snapshot.json"))
