"""Every corpus program ncopt plans, planned as its owner would run it (tools from its own
comments, or a D6 ball where it names none; the project's bench spindle): a second rewrite
changes nothing, and simulate finds no place where the spindle cannot follow that rewrite
did not name.

The corpus is read in place from ``../shared/corpus``.  Programs ncopt leaves alone (nothing
to plan, or refused with a located error) are checked elsewhere (tests/test_corpus.py).
"""

from __future__ import annotations

import re
from dataclasses import replace
from functools import lru_cache
from pathlib import Path

import pytest

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.runtime.errors import NcoptError, NothingToPlan
from ncopt.model import Cutter, Machine
from ncopt.simulate.replay import simulate_program

ROOT = Path(__file__).resolve().parents[1]
CORPUS = (ROOT / "../shared/corpus").resolve()
SUFFIXES = {".nc", ".ngc", ".tap", ".gcode", ".mpf", ".h"}
PROGRAMS = sorted(p for p in CORPUS.rglob("*") if p.suffix.lower() in SUFFIXES and p.is_file()
                  and "interp-tests" not in p.parts) if CORPUS.is_dir() else []
JOB = Job(machine=Machine(accel_rad_s2=227.0, max_rpm=15000.0))
STAMP = re.compile(r"^\s*[(;]\s*ncopt ")  # a line of the stamp


pytestmark = pytest.mark.corpus  # the corpus tier: every corpus program, planned, simulated


def _id(p: Path) -> str:
    return str(p.relative_to(CORPUS))


@lru_cache(maxsize=None)
def job_for(path: Path) -> Job:
    """The tools from the program's comments; where it names none, a D6 ball as its owner
    would give with --diameter 6."""
    text = path.read_bytes().decode("latin-1")
    try:
        rewrite_text(text, JOB, str(path))
    except NothingToPlan as exc:
        if "no diameter known" in str(exc):
            return replace(JOB, cutter=Cutter(6.0, 2))
    except NcoptError:
        pass
    return JOB


@lru_cache(maxsize=None)
def rewritten(path: Path):
    """(input text, Result) or (input text, None) where ncopt plans nothing."""
    text = path.read_bytes().decode("latin-1")
    try:
        return text, rewrite_text(text, job_for(path), str(path))
    except NothingToPlan:
        return text, None
    except NcoptError:  # refused at a located line: not planned
        return text, None


def test_the_corpus_has_programs_ncopt_plans():
    planned = [p for p in PROGRAMS if rewritten(p)[1] is not None]
    assert len(planned) >= 8, [_id(p) for p in planned]
    assert {"more2/fusion-haas-es_1001.nc", "fusion/BowlTest.nc"} <= {_id(p) for p in planned}


@pytest.mark.parametrize("path", PROGRAMS, ids=_id)
def test_a_second_rewrite_is_byte_identical(path):
    _, result = rewritten(path)
    if result is None:
        return
    try:
        again = rewrite_text(result.text, job_for(path), str(path)).text
    except NothingToPlan:  # the filter passes it through: nothing changes
        again = result.text
    assert again == result.text


def input_line(out_text: str):
    """1-based output line -> 1-based input line (the stamp lines are not the input's)."""
    table, k = {}, 0
    for n, line in enumerate(out_text.splitlines(), 1):
        if not STAMP.match(line):
            k += 1
        table[n] = k
    return table.get


@pytest.mark.parametrize("path", PROGRAMS, ids=_id)
def test_simulate_finds_no_lag_that_rewrite_did_not_name(path):
    _, result = rewritten(path)
    if result is None:
        return
    named = set(result.summary.lag_lines)
    back = input_line(result.text)
    for tool in sorted({p.tool for p in result.plans}):
        job = job_for(path)
        job = replace(job, tool=tool) if tool >= 0 else job  # the program may cut with others
        report, _ = simulate_program(result.text, job, path=str(path), sample_mm=0.5)
        missed = [(s.first_line, s.last_line) for s in report.lag
                  if not named & set(range(back(s.first_line), back(s.last_line) + 1))]
        assert not missed, (tool, missed[:5], sorted(named)[:10])
