"""The library builds and checks a Job from plain values (ncopt.planning.job), as the
command line does: every value out of its range and every unknown choice is refused with a
UsageError (a ValueRangeError for a number out of range) naming the option; every valid
combination makes a Job.  And the choices the command line shows are the model's."""

from __future__ import annotations

import math
from typing import get_args

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ncopt.model import FZ_POLICIES, PLANNERS, S_CHANGES, TOOL_POINTS, Job
from ncopt.motion.kinematics import NAMES
from ncopt.planning import job as jobs
from ncopt.planning.job import (ControlOptions, CutterOptions, MachineOptions, PartOptions,
                                PlanningOptions, TargetOptions, build_job, job_from_values,
                                length_mm)
from ncopt.reading import controls
from ncopt.reading.dialect import DECIMAL_POINT_CONVENTIONS
from ncopt.runtime.errors import UsageError, ValueRangeError

SPINDLE = {"accel": 227, "max_rpm": 15000}


@pytest.fixture(scope="module", autouse=True)
def no_profiles_of_this_machine(tmp_path_factory):
    """Only the examples ncopt ships: no user's or project's ncopt.toml."""
    home = tmp_path_factory.mktemp("home")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("ncopt.planning.profiles.user_file", lambda: home / "ncopt.toml")
        patch.chdir(home)
        patch.delenv("NCOPT_MACHINE", raising=False)
        yield


# ------------------------------------------------------------------- the choices ----
@pytest.mark.parametrize("literal, source", [
    (jobs.ToolPoint, TOOL_POINTS), (jobs.Planner, PLANNERS), (jobs.FzPolicy, FZ_POLICIES),
    (jobs.SChanges, S_CHANGES), (jobs.SChanges, controls.S_CHANGES),
    (jobs.Control, controls.CONTROLS), (jobs.DecimalPoint, DECIMAL_POINT_CONVENTIONS),
    (jobs.Kinematics, NAMES),
], ids=lambda x: getattr(x, "__name__", None) or str(x)[:20])
def test_the_choices_are_the_models(literal, source):
    """Spelt twice (the command line shows them without loading numpy): held equal here."""
    assert get_args(literal) == tuple(source)


def test_the_records_hold_every_value_once():
    names = [f for record in jobs.RECORDS.values() for f in record.__dataclass_fields__]
    assert len(names) == len(set(names))
    assert jobs.VALUE_NAMES == set(names) | {"tools_file"}


def test_an_unknown_value_name_is_a_type_error():
    with pytest.raises(TypeError, match="diamter"):
        job_from_values(diamter=6, **SPINDLE)


# ------------------------------------------------------------- the property ----
# each value's option (vc: the pair of --vc and --fz), the values in range (GOOD: any
# combination of them makes a Job) and out of range or unknown (BAD: each refused alone)
FLAGS = {"diameter": "--diameter", "corner_radius": "--corner-radius", "shape": "--shape",
         "teeth": "--teeth", "tool_point": "--tool-point", "vc": ("--vc", "--fz"),
         "fz_band": "--fz-band",
         "fz_policy": "--fz-policy", "accel": "--accel", "max_rpm": "--max-rpm",
         "min_rpm": "--min-rpm", "max_feed": "--max-feed", "rapid": "--rapid",
         "kinematics": "--kinematics", "control": "--dialect",
         "decimal_point": "--decimal-point", "s_changes": "--s-changes",
         "min_s_interval_ms": "--min-s-interval-ms", "stock": "--stock", "method": "--method",
         "ap": "--ap", "allowance_along": "--allowance-along", "tool": "--tool",
         "operations": "--operations", "planner": "--planner", "min_rpm_step": "--min-rpm-step"}
NAN, INF = math.nan, math.inf
GOOD = {
    "diameter": [6, 6.0, "6.35mm", "0.25in", "10", 16.0],
    "corner_radius": [None, 1, "0.5mm", 2.5, "0.02in"],
    "teeth": [1, 2, 4],
    "tool_point": list(TOOL_POINTS),
    "vc": [(None, None), (80, 0.05), (300.0, 0.2)],
    "fz_band": [2.0, 0.5, 49.9],
    "fz_policy": list(FZ_POLICIES),
    "accel": [227, 131.5, 1e-9],
    "max_rpm": [15000, 8000.0, 1000],
    "min_rpm": [None, 0, 100.0],
    "max_feed": [None, INF, 5000.0],
    "rapid": [None, 1000, 30000.0],
    "kinematics": [None, "xyzac-trt", "vector"],
    "control": [None, *controls.CONTROLS],
    "decimal_point": [None, *DECIMAL_POINT_CONVENTIONS],
    "s_changes": [None, *S_CHANGES],
    "min_s_interval_ms": [None, 0, 100.0],
    "stock": [0.0, "0", "0.1", "0.004in", 0.5],
    "method": ["contact", "material"],
    "ap": [0.2, "0.1mm", "0.008in"],
    "allowance_along": ["normal", "axis"],
    "tool": [None, 0, 3],
    "operations": [None, "all", "Finish, Contour", ("Finish",)],
    "planner": list(PLANNERS),
    "min_rpm_step": [10.0, 1, 0.5],
}
BAD = {
    "diameter": [0, -1, NAN, INF, "abc", "6 cm"],
    "corner_radius": [0, -1, 100, NAN, "1 cm"],
    "shape": ["flat", "Ball"],
    "teeth": [0, -1, 2.5, True],
    "tool_point": ["centre", "TIP", ""],
    "vc": [(0, 0.05), (NAN, 0.05), (-3, 0.05), (80, None), (80, 0), (80, INF), (None, 0.05)],
    "fz_band": [0, 50, NAN, -1, INF],
    "fz_policy": ["centered", "above"],
    "accel": [0, -1, NAN, INF],
    "max_rpm": [0.5, NAN, INF, -5],
    "min_rpm": [20000, NAN, -100],
    "max_feed": [0, -1, NAN],
    "rapid": [0, NAN, INF],
    "kinematics": ["xyzac", "table-table"],
    "control": ["haas", "Fanuc"],
    "decimal_point": ["is-a"],
    "s_changes": ["between", "passes"],
    "min_s_interval_ms": [NAN, -1, INF],
    "stock": [-1, "-0.1", "abc", INF, NAN],
    "method": ["edge"],
    "ap": [0, -1, "x", INF, NAN],
    "allowance_along": ["z"],
    "tool": [-1, 2.5],
    "operations": ["", " , ", ()],
    "planner": ["backward"],
    "min_rpm_step": [0, -1, NAN, INF],
}


@st.composite
def option_sets(draw, spoil: bool = True):
    """(values, the option spoilt or None): every value in range but at most one."""
    spoilt = draw(st.sampled_from([None, *BAD])) if spoil else None
    values = {name: draw(st.sampled_from(good)) for name, good in GOOD.items()}
    # the shapes that fit the corner radius drawn
    values["shape"] = draw(st.sampled_from([None, "ball"] + (
        ["bull-nose"] if values["corner_radius"] is not None else [])))
    if spoilt is not None:
        values[spoilt] = draw(st.sampled_from(BAD[spoilt]))
    if spoilt == "corner_radius" or spoilt == "diameter":
        values["shape"] = None  # a shape needs both: its message would come first
    values["vc"], values["fz"] = values["vc"]
    return values, spoilt


def _refused(values: dict) -> UsageError | None:
    try:
        made = job_from_values(**values)
    except UsageError as exc:
        return exc
    assert isinstance(made, Job)
    return None


@settings(max_examples=200)  # every option spoilt several ways
@given(option_sets())
def test_a_job_is_made_exactly_when_every_value_is_in_range(drawn):
    values, spoilt = drawn
    refused = _refused(values)
    if spoilt is None:
        assert refused is None, (values, str(refused))
    else:
        assert refused is not None, (spoilt, values[spoilt])
        flags = FLAGS[spoilt] if isinstance(FLAGS[spoilt], tuple) else (FLAGS[spoilt],)
        assert any(flag in str(refused) for flag in flags), (spoilt, values, str(refused))
        bad = (values["vc"], values["fz"]) if spoilt == "vc" else (values[spoilt],)
        if all(isinstance(v, (int, float)) for v in bad):  # a number out of its range
            assert isinstance(refused, ValueRangeError), (spoilt, bad, str(refused))


@given(option_sets(spoil=False))
def test_a_job_made_holds_the_values_given(drawn):
    values, _ = drawn
    job = job_from_values(**values)
    assert job.cutter.diameter_mm == pytest.approx(length_mm(values["diameter"], "--diameter"))
    assert job.cutter.teeth == job.teeth == values["teeth"]
    assert job.cutter.tool_point == values["tool_point"]
    if values["shape"] == "ball" or values["corner_radius"] is None:
        assert job.cutter.is_ball
    assert (job.machine.accel_rad_s2, job.machine.max_rpm) == (values["accel"], values["max_rpm"])
    assert job.options.planner == values["planner"]
    assert job.options.fz_tolerance == pytest.approx(values["fz_band"] / 100)
    assert job.options.s_changes == values["s_changes"]
    assert (job.control, job.decimal_point, job.kinematics) == (
        values["control"], values["decimal_point"], values["kinematics"])
    assert job.method.name == values["method"] and job.method.along == values["allowance_along"]
    assert job.cutting is None if values["vc"] is None else (
        job.cutting.vc_m_min, job.cutting.fz_mm) == (values["vc"], values["fz"])
    assert job.tool == values["tool"]


@pytest.mark.parametrize("spindle", [{}, {"accel": 227}, {"max_rpm": 15000}])
def test_planning_needs_the_spindle_and_inspecting_does_not(spindle):
    with pytest.raises(UsageError, match="give the spindle: --accel RAD_S2 and --max-rpm RPM"):
        build_job(machine=MachineOptions(**spindle))
    job = build_job(machine=MachineOptions(**spindle), spindle_needed=False)
    assert job.machine.spindle_unknown


@pytest.mark.parametrize("make, message", [
    (lambda: build_job(CutterOptions(cutter="nope"), machine=MachineOptions(**SPINDLE)),
     "no tool 'nope' in the profiles"),
    (lambda: build_job(CutterOptions(cutter="nope", diameter=6), machine=MachineOptions(**SPINDLE)),
     "give --cutter or --diameter, not both"),
    (lambda: build_job(targets=TargetOptions(material="unobtainium"),
                       machine=MachineOptions(**SPINDLE)), "no cutting data for 'unobtainium'"),
    (lambda: build_job(targets=TargetOptions(material="x", vc=80, fz=0.1),
                       machine=MachineOptions(**SPINDLE)), "give --material or --vc/--fz"),
    (lambda: build_job(machine=MachineOptions(machine="nope")), "no machine profile 'nope'"),
    (lambda: build_job(CutterOptions(shape="ball"), machine=MachineOptions(**SPINDLE)),
     "--shape needs --diameter"),
    (lambda: build_job(CutterOptions(corner_radius=1), machine=MachineOptions(**SPINDLE)),
     "--corner-radius needs --diameter"),
])
def test_names_not_in_the_profiles_and_contradictions_are_refused(make, message):
    with pytest.raises(UsageError, match=message):
        make()


def test_the_records_and_the_flat_values_make_the_same_job():
    records = build_job(CutterOptions(diameter="0.25in", teeth=4), TargetOptions(vc=80, fz=0.05),
                        MachineOptions(**SPINDLE, min_rpm=100), ControlOptions(control="fanuc"),
                        PartOptions(stock="0.1"), PlanningOptions(planner="forward"))
    flat = job_from_values(diameter="0.25in", teeth=4, vc=80, fz=0.05, **SPINDLE, min_rpm=100,
                           control="fanuc", stock="0.1", planner="forward")
    assert records == flat
    assert records.cutter.diameter_mm == pytest.approx(6.35)


def test_a_range_error_is_a_value_range_error():
    with pytest.raises(ValueRangeError, match="--max-feed must be a number above 0 mm/min"):
        build_job(machine=MachineOptions(**SPINDLE, max_feed=0))
