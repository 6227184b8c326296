"""Golden cases, one parametrised test per stage: tests/golden/<stage>/<case>/.

* ``writing``: ``input.*``, ``args`` (the options of ``ncopt rewrite``) and ``expected.*``,
  the rewritten program byte for byte.  Each case is also checked for equivalence (only
  S/F words and the stamp's comment lines differ; same toolpath) and stability (rewriting
  the expected output gives it back).
* ``reading``, ``motion``, ``planning``, ``simulate``: ``case.json`` (the program and the
  job) and ``expected.json``, a summary of what the stage made of the program:

  - reading: the dialect, line kinds, words per letter, opaque lines, every ``STEP``-th
    word with its span, and a digest of the whole word table;
  - motion: points per motion, lengths, bounding box, feed time, tools, warnings, every
    ``STEP``-th toolpath point, and a digest of all of them;
  - planning: the rewrite's summary and the S and F to be in force per moving block
    (every ``STEP``-th block listed, a digest of all);
  - simulate: the figures of the simulation report.

  A stage that refuses the program has ``{"error": class name, "message": ...}`` as its
  expected summary.

``case.json`` keys: the program is one of ``"program"`` (a path from the project root),
``"corpus"`` (a path inside ../shared/corpus, read in place: only the expected summary is
stored here) or ``"generated"`` (``{"name": "dome", "args": {...}}``, a function of
tests/programs.py); ``"job"`` holds :class:`ncopt.model.Job` fields (``machine``,
``cutter``, ``cutting``, ``options``, ``method`` as dicts of their fields; without
``machine``, a 227 rad/s^2, 15000 RPM spindle); ``"mesh"`` a path from the project root;
``"sample_mm"`` and ``"band"`` the simulation's.

Floats in the summaries are rounded to ``SIG`` significant digits (NaN and infinities
become null, "inf", "-inf"); digests are the first 16 hex digits of the sha256 of the full
rounded table, so a change anywhere in it shows, and the listed rows show where.

Expected files are ncopt's own output, inspected when written: a regression guard, not a
proof of correctness.  After a change meant to alter them, rewrite them with
``python -m pytest tests/test_golden.py --update-golden`` and read the diff.
"""

from __future__ import annotations

import hashlib
import json
import math
import shlex
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from ncopt.api import rewrite_text
from ncopt.cli.app import Exit, app
from ncopt.contacts.geometry import MeshIndex, load_stl
from ncopt.model import (VECTOR_WORD_CODES, Cutter, CuttingData, Job, LineKind, Machine, Method,
                         Motion, PlanOptions)
from ncopt.motion.interp import interpret, tcp_of
from ncopt.motion.kinematics import tilt_deg
from ncopt.motion.times import feed_minutes, untimed_moves
from ncopt.reading.dialect import detect
from ncopt.reading.parse import parse_text
from ncopt.reading.read import read_text
from ncopt.runtime.errors import NcoptError
from ncopt.simulate.replay import simulate_program
from ncopt.writing.edits import masked

import programs

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = ROOT / "tests" / "golden"
CORPUS = (ROOT / "../shared/corpus").resolve()
SIG = 7  # significant digits of the floats in the summaries
LISTED = 40  # about this many rows of a table are listed; the rest are in its digest
MACHINE = {"accel_rad_s2": 227.0, "max_rpm": 15000.0}
STAGES = ("reading", "motion", "planning", "simulate")

# the stamp's date, as the expected outputs of the writing stage were written
GOLDEN_ENV = {"SOURCE_DATE_EPOCH": "1767225600"}


def _cases(stage: str, marker: str) -> list[Path]:
    folder = GOLDEN / stage
    return sorted(p for p in folder.iterdir() if (p / marker).is_file()) \
        if folder.is_dir() else []


WRITING = _cases("writing", "args")
READING, MOTION, PLANNING, SIMULATE = (_cases(stage, "case.json") for stage in STAGES)


# ------------------------------------------------------------------ formatting ----
def rounded(x):
    """A JSON value: floats to SIG significant digits, NaN -> None, inf -> "inf"."""
    if isinstance(x, dict):
        return {str(k): rounded(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [rounded(v) for v in x]
    if isinstance(x, np.ndarray):
        return rounded(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        x = float(x)
        if math.isnan(x):
            return None
        if math.isinf(x):
            return "inf" if x > 0 else "-inf"
        return float(f"{x:.{SIG}g}") + 0.0  # + 0.0: no -0.0
    return x


def dumps(obj, indent: str = "") -> str:
    """JSON with short lists of scalars (a table's row) on one line, everything else one
    item per line, for readable diffs."""
    inner = indent + " "
    if isinstance(obj, dict) and obj:
        items = [f"{inner}{json.dumps(k)}: {dumps(v, inner)}" for k, v in obj.items()]
        return "{\n" + ",\n".join(items) + "\n" + indent + "}"
    flat = json.dumps(obj, ensure_ascii=False)
    if isinstance(obj, list) and obj and (any(isinstance(v, (list, dict)) for v in obj)
                                          or len(flat) > 100):
        return "[\n" + ",\n".join(inner + dumps(v, inner) for v in obj) + "\n" + indent + "]"
    return flat


def _column_text(col: np.ndarray) -> bytes:
    """A table column as text for the digest: floats to SIG significant digits."""
    if col.dtype.kind == "f":
        return "\n".join([f"%.{SIG}g" % x for x in col.tolist()]).encode()
    if col.dtype.kind in "iub":
        return col.astype("<i8").tobytes()
    return "\n".join(map(str, col.tolist())).encode("utf-8")


def table(*columns) -> dict:
    """Columns of equal length: the row count, every ``step``-th row (and the last) as
    ``[index, *row]`` rounded, and a digest of every row."""
    n = len(columns[0]) if columns else 0
    step = max(1, math.ceil(n / LISTED))
    keep = list(range(0, n, step))
    if n and keep[-1] != n - 1:
        keep.append(n - 1)
    cols = [np.asarray(col) for col in columns]
    digest = hashlib.sha256()
    for col in cols:
        assert col.shape == (n,)
        digest.update(_column_text(col) + b"\0")
    listed = [[i, *(rounded(col[i].item()) for col in cols)] for i in keep]
    return {"rows": n, "step": step, "sha256_16": digest.hexdigest()[:16], "listed": listed}


# ------------------------------------------------------------------ the case ----
def _job(spec: dict) -> Job:
    spec = dict(spec)
    kw = {"machine": Machine(**{**MACHINE, **spec.pop("machine", {})})}
    for key, cls in (("cutter", Cutter), ("cutting", CuttingData), ("options", PlanOptions),
                     ("method", Method)):
        if key in spec:
            kw[key] = cls(**spec.pop(key))
    if "operations" in spec:
        kw["operations"] = tuple(spec.pop("operations"))
    return Job(**kw, **spec)


def _source(spec: dict) -> tuple[str, str]:
    """(text, name in messages) of the case's program."""
    if "corpus" in spec:
        path = CORPUS / spec["corpus"]
        if not path.is_file():
            pytest.fail(f"the shared corpus has no {spec['corpus']} (at {CORPUS})")
        return path.read_bytes().decode("latin-1"), spec["corpus"]
    if "generated" in spec:
        gen = spec["generated"]
        data = getattr(programs, gen["name"])(**gen.get("args", {}))
        return data.decode("latin-1"), f"programs.{gen['name']}"
    return (ROOT / spec["program"]).read_bytes().decode("latin-1"), spec["program"]


@lru_cache(maxsize=4)
def _mesh(rel: str) -> MeshIndex:
    return MeshIndex(load_stl(ROOT / rel))


# the name of each word_letter code: the letter, or A3= B3= C3= (VECTOR_WORD_CODES)
LETTERS = np.array([chr(c) for c in range(128)]
                   + [f"{k}3=" if c in VECTOR_WORD_CODES.values() else f"#{c}"
                      for c in range(128, 256) for k in
                      [next((k for k, v in VECTOR_WORD_CODES.items() if v == c), "")]])


def _error(exc: NcoptError) -> dict:
    return {"error": type(exc).__name__, "message": str(exc)}


# ------------------------------------------------------------------ summaries ----
def reading_summary(text: str, name: str, job: Job, spec: dict) -> dict:
    detected = detect(text).name
    try:
        prog = read_text(text, name, job, detected)
    except NcoptError as exc:
        return {"dialect": detected, **_error(exc)}
    kinds = {k.name: int(np.count_nonzero(prog.line_kind == k)) for k in LineKind}
    letters = LETTERS[prog.word_letter]
    per_letter = dict(zip(*(a.tolist() for a in np.unique(letters, return_counts=True))))
    opaque = sorted(prog.opaque_reason.items())
    return {
        "dialect": detected,
        "bytes": len(text.encode("latin-1")),
        "lines": prog.n_lines,
        "line_kinds": kinds,
        "lines_with_expressions": int(np.count_nonzero(prog.line_has_expr)),
        "words": prog.n_words,
        "words_per_letter": per_letter,
        "expression_words": int(np.count_nonzero(np.isnan(prog.word_value))),
        "opaque_lines": len(opaque),
        "opaque_first": [[line + 1, why] for line, why in opaque[:10]],
        "words [index, line, letter, start, end, value]": table(
            prog.word_line + 1, letters, prog.word_start, prog.word_end,
            prog.word_value),
    }


def _read_and_interpret(text: str, name: str, job: Job):
    detected = detect(text).name
    prog = read_text(text, name, job, detected)
    return prog, interpret(prog, kinematics=job.kinematics, tcp=tcp_of(job, detected))


def motion_summary(text: str, name: str, job: Job, spec: dict) -> dict:
    try:
        _, tp = _read_and_interpret(text, name, job)
    except NcoptError as exc:
        return _error(exc)
    motion = tp.motion[1:]
    seg = tp.seg_len_mm[1:]
    kinds = {m.name.lower(): m.value for m in Motion if m != Motion.NONE}
    known = tp.known
    xyz = tp.xyz_mm[known] if known.any() else tp.xyz_mm[:0]
    out = {
        "points": tp.n,
        "unknown_points": int(np.count_nonzero(~known)),
        "moves": {k: int(np.count_nonzero(motion == v)) for k, v in kinds.items()},
        "arc_lines": int(np.unique(tp.line[np.isin(tp.motion, [2, 3])]).size),
        "length_mm": {k: rounded(float(seg[(motion == v) & known[1:]].sum()))
                      for k, v in kinds.items()},
        "bbox_min_mm": rounded(xyz.min(axis=0)) if len(xyz) else None,
        "bbox_max_mm": rounded(xyz.max(axis=0)) if len(xyz) else None,
        "feed_time_min": rounded(float(feed_minutes(tp).sum())),
        "untimed_moves": untimed_moves(tp),
        "tools": {str(t): int(n) for t, n in zip(*np.unique(tp.tool, return_counts=True))},
        "inch_lines": None if tp.line_inch is None else int(np.count_nonzero(tp.line_inch)),
        "spindle_on_points": None if tp.spindle_on is None
        else int(np.count_nonzero(tp.spindle_on)),
        "kinematics": tp.kinematics,
        "inverse_time_points": None if tp.inverse_time is None
        else int(np.count_nonzero(tp.inverse_time)),
        "tilt_max_deg": None if tp.tool_axis is None
        else rounded(float(tilt_deg(tp.tool_axis).max())),
        "warnings": len(tp.warnings),
        "warnings_first": list(tp.warnings[:5]),
    }
    columns = [tp.line + 1, tp.motion, tp.xyz_mm[:, 0], tp.xyz_mm[:, 1], tp.xyz_mm[:, 2],
               tp.feed_mm_min, tp.spindle_rpm]
    if tp.tool_axis is None:
        out["points [index, line, motion, x, y, z, F mm/min, S]"] = table(*columns)
    else:
        out["points [index, line, motion, x, y, z, F mm/min, S, axis i, j, k]"] = table(
            *columns, *tp.tool_axis.T)
    return out


def _rewrite(text: str, name: str, job: Job, spec: dict):
    mesh = _mesh(spec["mesh"]) if "mesh" in spec else None
    return rewrite_text(text, job, name, mesh)


def planning_summary(text: str, name: str, job: Job, spec: dict) -> dict:
    try:
        result = _rewrite(text, name, job, spec)
    except NcoptError as exc:
        return _error(exc)
    t = result.targets
    return {"summary": rounded(result.summary.to_dict()),
            "blocks [index, line, S in force, F in force (program units)]": table(
                t.line + 1, t.s_value, t.f_value)}


def simulate_summary(text: str, name: str, job: Job, spec: dict) -> dict:
    mesh = _mesh(spec["mesh"]) if "mesh" in spec else None
    try:
        report, series = simulate_program(text, job, mesh, path=name,
                                          sample_mm=spec.get("sample_mm", 0.5),
                                          band=spec.get("band"))
    except NcoptError as exc:
        return _error(exc)
    out = report.to_dict()
    del out["path"]
    out["series_samples"] = len(series)
    out["series_time_s"] = float(series.time_s[-1]) if len(series) else 0.0
    return rounded(out)


SUMMARIES = {"reading": reading_summary, "motion": motion_summary,
             "planning": planning_summary, "simulate": simulate_summary}


def _compare_or_update(path: Path, got: str, update: bool) -> None:
    if update:
        if not path.is_file() or path.read_text() != got:
            path.write_text(got)
        return
    assert path.is_file(), f"{path} is missing: write it with --update-golden"
    expected = path.read_text()
    if got != expected:  # the first lines that differ, then the whole assertion diff
        a, b = expected.splitlines(), got.splitlines()
        diff = [f"line {i + 1}: expected {x!r}\n         got      {y!r}"
                for i, (x, y) in enumerate(zip(a, b)) if x != y][:8]
        if len(a) != len(b):
            diff.append(f"{len(a)} lines expected, {len(b)} got")
        pytest.fail(f"{path.relative_to(ROOT)} differs (rewrite it with --update-golden "
                    "if the change is meant):\n" + "\n".join(diff))


def _check_summary(stage: str, case: Path, update: bool) -> None:
    spec = json.loads((case / "case.json").read_text())
    text, name = _source(spec)
    job = _job(spec.get("job", {}))
    got = dumps(SUMMARIES[stage](text, name, job, spec)) + "\n"
    _compare_or_update(case / "expected.json", got, update)


def _name(case: Path) -> str:
    return case.name


@pytest.mark.parametrize("case", READING, ids=_name)
def test_golden_reading(case, update_golden):
    _check_summary("reading", case, update_golden)


@pytest.mark.parametrize("case", MOTION, ids=_name)
def test_golden_motion(case, update_golden):
    _check_summary("motion", case, update_golden)


@pytest.mark.parametrize("case", PLANNING, ids=_name)
def test_golden_planning(case, update_golden):
    _check_summary("planning", case, update_golden)


@pytest.mark.parametrize("case", SIMULATE, ids=_name)
def test_golden_simulate(case, update_golden):
    _check_summary("simulate", case, update_golden)


def test_golden_cases_exist():
    for stage in STAGES:
        assert len(_cases(stage, "case.json")) >= 3, stage
        for case in _cases(stage, "case.json"):
            spec = json.loads((case / "case.json").read_text())
            assert sum(k in spec for k in ("program", "corpus", "generated")) == 1, case
            assert set(spec) <= {"program", "corpus", "generated", "job", "mesh",
                                 "sample_mm", "band", "note"}, case
    corpus = {json.loads((c / "case.json").read_text()).get("corpus")
              for s in STAGES for c in _cases(s, "case.json")} - {None}
    assert len(corpus) >= 3
    assert len(WRITING) >= 3
    for case in WRITING:
        assert len(list(case.glob("input.*"))) == 1 and len(list(case.glob("expected.*"))) == 1


# ------------------------------------------------------------------ writing ----
def _args(case: Path) -> list[str]:
    args = shlex.split((case / "args").read_text())
    return [str((case / a).resolve()) if i and args[i - 1] == "--mesh" else a
            for i, a in enumerate(args)]


def _cli_rewrite(src: Path, case: Path, out: Path) -> bytes:
    result = CliRunner(env=GOLDEN_ENV).invoke(app, ["rewrite", str(src), *_args(case), "-o",
                                                    str(out), "-q"])
    assert result.exit_code == Exit.OK, result.stderr
    assert "\x1b[" not in result.stderr
    return out.read_bytes()


def _drop_stamp(base: str, longer: str) -> tuple[str, str]:
    """``longer`` without the block of comment lines it has in addition to ``base``, and
    that block."""
    a, b = base.splitlines(keepends=True), longer.splitlines(keepends=True)
    n = len(b) - len(a)
    assert n >= 6
    i = next((k for k, (x, y) in enumerate(zip(a, b)) if x != y), len(a))
    return "".join(b[:i] + b[i + n:]), "".join(b[i:i + n])


@pytest.mark.parametrize("case", WRITING, ids=_name)
def test_golden_writing(case, tmp_path, update_golden):
    src = next(case.glob("input.*"))
    expected_path = case / f"expected{src.suffix}"
    got = _cli_rewrite(src, case, tmp_path / f"out{src.suffix}")
    if update_golden and not (expected_path.is_file() and got == expected_path.read_bytes()):
        expected_path.write_bytes(got)
    expected = expected_path.read_bytes()
    assert got == expected, (f"{case.name}: output differs from {expected_path.name} "
                             "(rewrite it with --update-golden if the change is meant)")

    # equivalence: one stamp comment line, S/F words; the same toolpath
    text_in, text_out = src.read_bytes().decode("latin-1"), expected.decode("latin-1")
    plain, stamp = _drop_stamp(text_in, text_out)
    assert "ncopt" in stamp
    assert set(parse_text(stamp).line_kind.tolist()) == {LineKind.BLANK}
    a, b = parse_text(text_in, str(src)), parse_text(plain, str(src))
    assert masked(a) == masked(b)
    tp_a, tp_b = interpret(a), interpret(b)
    assert np.array_equal(tp_a.xyz_mm, tp_b.xyz_mm)
    assert np.array_equal(interpret(parse_text(text_out)).xyz_mm, tp_a.xyz_mm)
    n_stamp = stamp.count("\n")
    assert text_out.count("\r\n") == text_in.count("\r\n") + (n_stamp if "\r\n" in text_in else 0)

    # stability: the expected output rewritten with the same flags is itself
    again = _cli_rewrite(expected_path, case, tmp_path / f"again{src.suffix}")
    assert again == expected


def test_golden_meshes_are_small():
    for stl in (GOLDEN / "meshes").glob("*.stl"):
        assert stl.stat().st_size < 200_000


def test_rounding_and_tables():
    assert rounded([1 / 3, float("nan"), float("inf"), -0.0, 2, True]) == \
        [0.3333333, None, "inf", 0.0, 2, True]
    t = table(np.arange(100), np.arange(100) / 3)
    assert t["rows"] == 100 and t["step"] == 3 and t["listed"][-1] == [99, 99, 33.0]
    assert t["listed"][1] == [3, 3, 1.0] and len(t["sha256_16"]) == 16
    assert table(np.arange(100), np.arange(100) / 3 * (1 + 1e-10))["sha256_16"] == t["sha256_16"]
    assert table(np.arange(100), np.arange(100) / 3 * (1 + 1e-5))["sha256_16"] != t["sha256_16"]
    assert dumps({"a": [[1, 2], [3]], "b": [1, 2]}) == \
        '{\n "a": [\n  [1, 2],\n  [3]\n ],\n "b": [1, 2]\n}'
