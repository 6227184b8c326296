"""Every option value checked where it is defined (issue 28): on the command line, in the
profiles and in the library's objects alike, a value out of range (NaN, inf, 0, negative,
bounds the wrong way round) is refused with exit 2 naming the option and the range, never
planned and never a traceback.  And the tracebacks the adversarial run found, each now a
located error.  Last, a property test over random option sets and output paths.
"""

from __future__ import annotations

import math
import os
import re
import tempfile
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from ncopt.cli.app import Exit, app
from ncopt.runtime.errors import NcoptError, UsageError, ValueRangeError
from ncopt.motion.interp import interpret
from ncopt.model import LIMITS, Cutter, CuttingData, Machine, PlanOptions
from ncopt.reading.parse import parse_text
from programs import dome

ROOT = Path(__file__).resolve().parents[1]
BOWL_MPF = ROOT / "samples" / "bowl.mpf"
CUTTER = ["--diameter", "6"]
SPINDLE = ["--accel", "227", "--max-rpm", "15000"]


def invoke(args, **kwargs):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100"})
    result = runner.invoke(app, [str(a) for a in args], catch_exceptions=False, **kwargs)
    assert "Traceback" not in result.stderr
    return result


@pytest.fixture
def prog(tmp_path) -> Path:
    path = tmp_path / "dome.nc"
    path.write_bytes(dome(8))
    return path


# ------------------------------------------------------------- the command line ----
@pytest.mark.parametrize("options, message", [
    (["--accel", "nan", "--max-rpm", "15000"],
     "--accel must be a finite number above 0 rad/s^2, not nan"),
    (["--accel", "inf", "--max-rpm", "15000"],
     "--accel must be a finite number above 0 rad/s^2, not inf"),
    (["--accel", "227", "--max-rpm", "inf"],
     "--max-rpm must be a finite number of at least 1 RPM, not inf"),
    ([*SPINDLE, "--min-rpm-step", "nan"],
     "--min-rpm-step must be a finite number above 0 RPM, not nan"),
    ([*SPINDLE, "--min-rpm-step", "-1"],
     "--min-rpm-step must be a finite number above 0 RPM, not -1"),
    ([*SPINDLE, "--max-feed", "0"],  # was a ZeroDivisionError
     "--max-feed must be a number above 0 mm/min (inf: no limit), not 0"),
    ([*SPINDLE, "--max-feed", "-1"],
     "--max-feed must be a number above 0 mm/min (inf: no limit), not -1"),
    ([*SPINDLE, "--max-feed", "nan"],
     "--max-feed must be a number above 0 mm/min (inf: no limit), not nan"),
    ([*SPINDLE, "--rapid", "0"], "--rapid must be a finite number above 0 mm/min, not 0"),
    ([*SPINDLE, "--rapid", "-1"], "--rapid must be a finite number above 0 mm/min, not -1"),
    ([*SPINDLE, "--rapid", "nan"], "--rapid must be a finite number above 0 mm/min, not nan"),
    ([*SPINDLE, "--vc", "nan", "--fz", "0.1"], "--vc must be a finite number above 0 m/min, not nan"),
    ([*SPINDLE, "--vc", "80", "--fz", "inf"], "--fz must be a finite number above 0 mm, not inf"),
    ([*SPINDLE, "--min-rpm", "15000"],
     "--min-rpm is equal to --max-rpm (15000 and 15000 RPM): the lowest spindle speed must "
     "be below the highest"),
    ([*SPINDLE, "--min-rpm", "16000"],
     "--min-rpm is above --max-rpm (16000 and 15000 RPM): the lowest spindle speed must be "
     "below the highest"),
    ([*SPINDLE, "--operations", ""],
     "--operations takes operation names separated by commas, or all; not ''"),
    ([*SPINDLE, "--operations", " , "],
     "--operations takes operation names separated by commas, or all; not ' , '"),
    ([*SPINDLE, "--fz-band", "nan"], "--fz-band is a percentage above 0 and below 50"),
    ([*SPINDLE, "--stock", "1" + "0" * 400], "--stock must be a finite length"),
])
def test_an_option_out_of_range_is_one_line_naming_it_and_its_range(prog, tmp_path, options,
                                                                    message):
    out = tmp_path / "out.nc"
    result = invoke(["rewrite", prog, *CUTTER, *options, "-o", out])
    assert result.exit_code == Exit.USAGE
    assert result.stderr == message + "\n"
    assert not out.exists()


@pytest.mark.parametrize("command", ["simulate", "report", "inspect"])
def test_every_command_checks_the_same_way(prog, tmp_path, command):
    args = {"simulate": [], "report": ["-o", tmp_path / "r.html"], "inspect": []}[command]
    spindle = [] if command == "inspect" else ["--accel", "227", "--max-rpm", "15000"]
    result = invoke([command, prog, *CUTTER, *spindle, "--max-feed", "0", *args])
    assert result.exit_code == Exit.USAGE
    assert result.stderr == "--max-feed must be a number above 0 mm/min (inf: no limit), not 0\n"


@pytest.mark.parametrize("options, option", [
    (["--accel", "227", "--max-rpm", "nan"], "--max-rpm"),  # was a traceback
    (["--accel", "227", "--max-rpm", "0.5"], "--max-rpm"),
    ([*SPINDLE, "--min-rpm", "nan"], "--min-rpm"),  # was a traceback
    ([*SPINDLE, "--min-rpm", "-100"], "--min-rpm"),
    ([*SPINDLE, "--teeth", "0"], "--teeth"),
    ([*SPINDLE, "--teeth", "2.5"], "--teeth"),
    ([*SPINDLE, "--tool", "-1"], "--tool"),
    ([*SPINDLE, "--min-s-interval-ms", "nan"], "--min-s-interval-ms"),
])
def test_closed_ranges_are_typers_own(prog, tmp_path, options, option):
    """A closed bound is typer's min=: refused before the command runs, with the option."""
    out = tmp_path / "out.nc"
    result = invoke(["rewrite", prog, *CUTTER, *options, "-o", out])
    assert result.exit_code == Exit.USAGE
    assert f"Invalid value for '{option}'" in result.stderr
    assert not out.exists()


def test_batch_jobs_cannot_be_negative(prog, tmp_path):
    result = invoke(["batch", prog, *CUTTER, *SPINDLE, "-o", tmp_path / "out", "--jobs", "-1"])
    assert result.exit_code == Exit.USAGE
    assert "Invalid value for '--jobs'" in result.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command, option, shown", [
    ("rewrite", "--max-rpm", "x>=1"), ("rewrite", "--teeth", "x>=1"),
    ("rewrite", "--min-rpm", "x>=0"), ("rewrite", "--tool", "x>=0"),
    ("batch", "--jobs", "x>=0"), ("simulate", "--teeth", "x>=1"),
])
def test_help_shows_the_closed_ranges(command, option, shown):
    lines = invoke([command, "-h"]).stdout.splitlines()
    at = next(i for i, ln in enumerate(lines)
              if re.match(r"\s*(?:-\w, )?" + re.escape(option) + " ", ln))
    end = next(i for i in range(at + 1, len(lines)) if lines[i].lstrip().startswith("-"))
    entry = " ".join(" ".join(lines[at:end]).split())  # the option's entry, unwrapped
    assert shown in entry, entry


def test_help_says_the_open_ranges():
    text = " ".join(invoke(["rewrite", "-h"]).stdout.split())
    for words in ("rad/s^2, finite and above 0", "mm/min, above 0 (inf: no limit)",
                  "RPM, above 0", "percent, above 0 and below 50"):
        assert words in text


# --------------------------------------------------------------------- profiles ----
@pytest.mark.parametrize("toml, line, message", [
    ("[machines.m]\naccel_rad_s2 = nan\nmax_rpm = 15000\n", 2,  # was a traceback
     "machine 'm': accel_rad_s2 must be a finite number above 0 rad/s^2, not nan"),
    ("[machines.m]\naccel_rad_s2 = 227\nmax_rpm = inf\n", 3,
     "machine 'm': max_rpm must be a finite number of at least 1 RPM, not inf"),
    ("[machines.m]\naccel_rad_s2 = 227\nmax_rpm = 8000\nmin_rpm = 9000\n", 4,
     "machine 'm': min_rpm: the lowest spindle speed (9000 RPM) must be below the highest "
     "(8000 RPM)"),
    ("[machines.m]\naccel_rad_s2 = 227\nmax_rpm = 8000\nrapid_mm_min = -1\n", 4,
     "machine 'm': rapid_mm_min must be a finite number above 0 mm/min, not -1"),
    ("[machines.m]\naccel_rad_s2 = 227\nmax_rpm = 8000\nmax_feed_mm_min = 0\n", 4,
     "machine 'm': max_feed_mm_min must be a number above 0 mm/min (inf: no limit), not 0"),
    ("[tools.4]\ndiameter_mm = 16\nteeth = 2.5\n", 3,
     "tool '4': teeth must be an integer of at least 1, not 2.5"),
    ("[tools.4]\ndiameter_mm = 16\nteeth = 0\n", 3,
     "tool '4': teeth must be an integer of at least 1, not 0"),
    ('[tools.b]\ntype = "bull-nose"\ndiameter_mm = 6\ncorner_radius_mm = 4\n', 4,
     "tool 'b': corner_radius_mm must be at most half of diameter_mm (3 mm), not 4.0"),
    ('[cutting."1.4462"]\nvc_m_min = 70\nfz_mm = 0\n', 3,
     "cutting data '1.4462': fz_mm must be a finite number above 0 mm, not 0"),
])
def test_a_profile_value_out_of_range_names_the_file_line_and_range(tmp_path, toml, line,
                                                                    message):
    path = tmp_path / "mine.toml"
    path.write_text(toml)
    result = invoke(["profiles", "--tools", path])
    assert result.exit_code == Exit.USAGE
    assert result.stderr == f"{path}:{line}: {message}\n"


@pytest.mark.parametrize("text", ["a = " + "[" * 1000 + "]" * 1000,
                                  "a = " + "{b=" * 1000 + "}" * 1000],
                         ids=["1000-deep array", "1000 nested tables"])
def test_a_profile_nested_too_deep_is_a_located_error(tmp_path, text):
    """tomllib recurses once per level: a RecursionError traceback before."""
    path = tmp_path / "deep.toml"
    path.write_text(text + "\n")
    result = invoke(["rewrite", BOWL_MPF, *SPINDLE, "--tools", path])
    assert result.exit_code == Exit.USAGE
    assert result.stderr == (f"{path}: cannot read the profile: its arrays or tables are "
                             "nested too deep to read (hundreds of levels); a profile needs "
                             "two: fix the TOML\n")


# ---------------------------------------------------------------------- library ----
def test_a_value_out_of_range_is_a_value_error_and_a_usage_error():
    with pytest.raises(ValueError) as exc:
        Machine(accel_rad_s2=math.nan, max_rpm=15000)
    assert isinstance(exc.value, UsageError)
    assert str(exc.value) == ("machine: accel_rad_s2 must be a finite number above 0 "
                              "rad/s^2, not nan")


@pytest.mark.parametrize("make, message", [
    (lambda: Cutter(16, 2.5), "cutter: teeth must be an integer of at least 1, not 2.5"),
    (lambda: Cutter(16, True), "cutter: teeth must be an integer of at least 1, not True"),
    (lambda: Cutter(0, 2), "cutter: diameter_mm must be a finite number above 0 mm, not 0"),
    (lambda: Cutter(6, 2, 3.5), "cutter: corner_radius_mm must be at most half the "
                                "diameter (3 mm), not 3.5"),
    (lambda: Cutter(6, 2, tool_point="centre"),
     "cutter: tool_point must be one of tip, center, not 'centre'"),
    (lambda: CuttingData(70, 0.0), "cutting data: fz_mm must be a finite number above 0 mm, "
                                   "not 0.0"),
    (lambda: PlanOptions(min_rpm_step=math.nan),
     "plan options: min_rpm_step must be a finite number above 0 RPM, not nan"),
    (lambda: PlanOptions(sample_mm=0.0),
     "plan options: sample_mm must be a finite number above 0 mm, not 0.0"),
    (lambda: PlanOptions(planner="backward"),
     "plan options: planner must be one of lookahead, forward, not 'backward'"),
    (lambda: Machine(227, 15000, max_feed_mm_min=math.nan),
     "machine: max_feed_mm_min must be a number above 0 mm/min (inf: no limit), not nan"),
])
def test_the_library_objects_refuse_what_the_options_refuse(make, message):
    with pytest.raises(ValueRangeError) as exc:
        make()
    assert str(exc.value) == message


def test_no_spindle_is_two_nans():
    """``ncopt inspect`` plans nothing and needs no spindle: NaN for both says so."""
    assert Machine(math.nan, math.nan).spindle_unknown
    with pytest.raises(ValueRangeError):
        Machine(math.nan, 15000)


numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                    st.sampled_from([0.0, -0.0, 1.0, -1.0, 0.5, 1e-300, 1e300]))


@given(accel=numbers, max_rpm=numbers, min_rpm=numbers, max_feed=numbers, rapid=numbers)
def test_a_machine_is_made_exactly_when_its_values_are_in_range(accel, max_rpm, min_rpm,
                                                                max_feed, rapid):
    """The ranges written out by hand (README, Commands): a machine is made iff they hold."""
    ok = ((math.isnan(accel) and math.isnan(max_rpm))
          or (math.isfinite(accel) and accel > 0 and math.isfinite(max_rpm) and max_rpm >= 1
              and min_rpm < max_rpm))
    ok = ok and math.isfinite(min_rpm) and min_rpm >= 0 and max_feed > 0 \
        and math.isfinite(rapid) and rapid > 0
    try:
        Machine(accel, max_rpm, min_rpm, max_feed, rapid)
        made = True
    except ValueRangeError:
        made = False
    assert made == ok


def test_the_limits_the_options_name_are_the_models():
    assert LIMITS["accel_rad_s2"].describe() == "a finite number above 0 rad/s^2"
    assert LIMITS["teeth"].describe() == "an integer of at least 1"


# ------------------------------------------------------ tracebacks made located ----
@pytest.mark.slow
def test_simulate_with_a_sample_spacing_that_would_exhaust_memory(tmp_path):
    """--sample 1e-9 grew to 24 GB before the kernel ended it: refused with the spacing
    that fits (a 12 x 12 dome's 146 moves at the cap of 100,000 samples each: 14.5
    million)."""
    prog = tmp_path / "dome.nc"
    prog.write_bytes(dome(12))
    result = invoke(["simulate", prog, *CUTTER, *SPINDLE, "--sample", "1e-9"])
    assert result.exit_code == Exit.USAGE
    line = result.stderr.strip()
    assert line.startswith(f"{prog}: sample spacing 1e-09 mm would take ")
    assert "at most 10,000,000 fit in memory: give a spacing of" in line
    fits = float(line.split("give a spacing of ")[1].split(" mm")[0])
    again = invoke(["simulate", prog, *CUTTER, *SPINDLE, "--sample", str(fits), "--json"])
    assert again.exit_code == Exit.OK  # the spacing named is one that fits


def test_simulate_with_an_infinite_sample_spacing(prog):
    result = invoke(["simulate", prog, *CUTTER, *SPINDLE, "--sample", "inf"])
    assert result.exit_code == Exit.USAGE
    assert result.stderr == f"{prog}: sample spacing must be a finite length, got inf\n"


def test_a_feed_so_low_its_fz_rounds_to_zero_is_a_located_planning_error(tmp_path):
    """The sample bowl's ``N110 G1 Z3.000 F279`` as ``F0.0001``: fz 0.0001 / (2 x 1393)
    mm is 0 in the stamp's 6 decimals (a ZeroDivisionError before)."""
    lines = BOWL_MPF.read_text().splitlines()[:400]
    assert lines[11] == "N110 G1 Z3.000 F279"
    path = tmp_path / "bowl.mpf"
    path.write_text("\n".join(ln.replace("F279", "F0.0001") for ln in lines) + "\nM30\n")
    result = invoke(["rewrite", path, *SPINDLE, "--diameter", "16", "-o", tmp_path / "o.mpf"])
    assert result.exit_code == Exit.PLANNING
    assert result.stderr == (f"{path}: cutting data: fz_mm must be a finite number above 0 "
                             "mm, not 0.0, from the program's own S and F words or its ncopt "
                             "stamp: check them, or give --vc and --fz\n")
    assert not (tmp_path / "o.mpf").exists()


@pytest.mark.slow
def test_an_expression_of_50000_terms_is_evaluated():
    """LinuxCNC's cam-nisley demo computes its feed so: ``#1122 = [#1121 * #1111 * #1112]``;
    50,000 terms made a tree deeper than Python's recursion limit (RecursionError)."""
    text = ("#1111 = [" + " + ".join(["0.0005"] * 50_000) + "]\n"
            "G21 G90 G94\nG0 X0 Y0 Z0\nG1 X#1111 F100\n")
    tp = interpret(parse_text(text, "t.ngc", dialect="linuxcnc"))
    assert tp.xyz_mm[-1, 0] == pytest.approx(25.0)  # 50,000 x 0.0005 mm


@pytest.mark.parametrize("expression", ["[10 ** 308 * 10]", "[10 ** 400]"])
def test_an_expression_beyond_any_number_is_a_located_error(expression):
    text = f"G21 G90 G94\nG0 X0 Y0 Z0\n#1 = {expression}\nG1 X#1 F100\n"
    with pytest.raises(NcoptError) as exc:
        interpret(parse_text(text, "t.ngc", dialect="linuxcnc"))
    assert str(exc.value).startswith("t.ngc:3:1: cannot evaluate expression: ")


def test_a_word_beyond_any_number_is_a_located_error(tmp_path):
    path = tmp_path / "big.nc"
    path.write_bytes(dome(8).replace(b"G1 X-10.000 Y-10.000", b"G1 X1" + b"0" * 309 + b" Y-10.000", 1))
    result = invoke(["rewrite", path, *CUTTER, *SPINDLE, "-o", tmp_path / "o.nc"])
    assert result.exit_code == Exit.PROGRAM
    assert f"{path}:6:4: 'X1000" in result.stderr
    assert "beyond any control's range" in result.stderr


def test_inverse_time_with_f0_is_refused(tmp_path):
    """G93 with F0 was planned (F0 became F841); LinuxCNC refuses it, and so does ncopt."""
    lines = dome(8).decode().splitlines()
    lines[6] = "G93 " + lines[6] + " F0"
    lines[7] = "G94 " + lines[7] + " F800"
    path = tmp_path / "g93.nc"
    path.write_text("\n".join(lines) + "\n")
    result = invoke(["rewrite", path, *CUTTER, *SPINDLE, "-o", tmp_path / "o.nc"])
    assert result.exit_code == Exit.PROGRAM
    assert f"{path}:7:" in result.stderr and "inverse-time (G93) move with F0" in result.stderr
    assert not (tmp_path / "o.nc").exists()


# --------------------------------------------------------- the property: nothing lost ----
# option: (values in range, None for "not given"; values out of range or inconsistent)
VALUES = {
    "--accel": (["227", "131", "1e-9"], ["0", "-1", "nan", "inf"]),
    "--max-rpm": (["15000", "8000", "1"], ["0.5", "nan", "inf", "-5"]),
    "--min-rpm": ([None, "0", "100"], ["20000", "nan", "-100"]),  # 20000: above --max-rpm
    "--max-feed": ([None, "inf", "5000"], ["0", "-1", "nan"]),
    "--rapid": ([None, "1000", "30000"], ["0", "nan", "inf"]),
    "--min-rpm-step": ([None, "10", "1"], ["0", "-1", "nan"]),
    "--teeth": ([None, "1", "2"], ["0", "2.5"]),
    "--fz-band": ([None, "2", "5"], ["0", "50", "nan"]),
}
NOT_IN = {"simulate": {"--min-rpm-step"}}  # simulate plans nothing: it has no such option
# where an output may go: new files, the program, links to it, and to each other
PLACES = ["out.nc", "other.nc", "report.html", "data.csv", "dome.nc", "link.nc", "hard.nc",
          "to-out.nc"]
FRESH = ["out.nc", "other.nc", "report.html", "data.csv"]  # drawn as often: runs that write


@st.composite
def runs(draw):
    command = draw(st.sampled_from(["rewrite", "rewrite", "simulate"]))
    names = [o for o in VALUES if o not in NOT_IN.get(command, ())]
    spoilt = set(draw(st.lists(st.sampled_from(names), max_size=2, unique=True)))
    options = []
    for option in names:
        good, bad = VALUES[option]
        value = draw(st.sampled_from(bad if option in spoilt else good))
        if value is not None:
            options += [option, value]
    if draw(st.booleans()):  # cutting data, in range or not
        options += ["--vc", draw(st.sampled_from(["80", "80", "0", "nan", "-3"])),
                    "--fz", draw(st.sampled_from(["0.05", "0.05", "0", "inf"]))]
    if command == "rewrite":
        outputs = {"-o": draw(st.sampled_from(PLACES + FRESH + [None]))}
        if draw(st.integers(0, 4)) == 0:  # a report costs a second simulation: seldom
            outputs["--report"] = draw(st.sampled_from(PLACES + FRESH))
    else:
        outputs = {"--csv": draw(st.sampled_from(PLACES + FRESH))}
    return command, options, outputs


@pytest.mark.slow
@settings(max_examples=100, deadline=None)
@given(runs())
def test_no_option_set_or_output_path_loses_an_input_or_ends_in_a_traceback(run):
    """Random option sets (NaN, inf, 0, negative, bounds swapped) and output paths (the
    program, links to it, one another): the program is never changed, no run ends in a
    traceback, and exit 0 comes only with every output written."""
    command, options, outputs = run
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        program = work / "dome.nc"
        program.write_bytes(dome(6))
        (work / "link.nc").symlink_to("dome.nc")
        os.link(program, work / "hard.nc")
        (work / "to-out.nc").symlink_to("out.nc")
        before = program.read_bytes()
        args = [command, program, *CUTTER, *options]
        for option, place in outputs.items():
            if place is not None:
                args += [option, work / place]
        result = CliRunner(env={"NO_COLOR": "1"}).invoke(app, [str(a) for a in args])
        assert result.exception is None or isinstance(result.exception, SystemExit), \
            repr(result.exception)
        assert "Traceback" not in result.stderr
        assert result.exit_code in {int(e) for e in Exit}, result.exit_code
        assert program.read_bytes() == before, (args, result.stderr)
        if result.exit_code == Exit.OK:
            for option, place in outputs.items():
                target = work / place if place is not None else None
                assert target is None or (target.is_file() and target.stat().st_size > 0), \
                    (option, place, result.stderr)
                if place in ("out.nc", "other.nc", "to-out.nc") and option == "-o":
                    assert target.read_bytes().startswith(b"(ncopt ")  # the rewrite itself
