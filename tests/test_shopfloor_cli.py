"""The command line on the shop floor: ``inspect`` shows the operations as ``rewrite``
judges them, ``rewrite --check``, machine profiles (``profiles init``, misspelt keys, the
project's ``ncopt.toml`` found upward, ``NCOPT_MACHINE``), colours, closed pipes, plurals,
shell completion and a light ``COMMAND -h``.

Every test runs in an empty working folder with no user profile file.
"""

from __future__ import annotations

import io
import json
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from hypothesis import given, strategies as st
from rich.console import Console
from typer.testing import CliRunner

from ncopt.api import OpRow, Summary
from ncopt.cli.app import WOULD_CHANGE, Exit, app, print_summary
from ncopt.planning.inspection import Inspection, render_inspection
from ncopt.planning.profiles import EXAMPLES, MACHINE_KEYS, MachineProfile, load
from programs import dome

ROOT = Path(__file__).resolve().parents[1]
CORPUS = ROOT.parent / "shared" / "corpus"
BOWL_MPF = ROOT / "samples" / "bowl.mpf"
CHESS = CORPUS / "fusion" / "chess_engraved_box.nc"
SPINDLE = ["--accel", "227", "--max-rpm", "15000"]
DOME = ["--diameter", "6", *SPINDLE]


def invoke(args, stdin: bytes | None = None, env: dict | None = None, columns: int = 100,
           prog_name: str | None = None):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": str(columns),
                            **(env or {})})
    result = runner.invoke(app, [str(a) for a in args], input=stdin, catch_exceptions=False,
                           prog_name=prog_name)
    assert "Traceback" not in result.stderr
    return result


def ncopt(args, cwd: Path, **kwargs) -> subprocess.Popen:
    env = {**os.environ, "NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100",
           "XDG_CONFIG_HOME": str(cwd / "config"), "PYTHONPATH": str(ROOT)}
    env.pop("NCOPT_MACHINE", None)
    return subprocess.Popen([sys.executable, "-m", "ncopt", *[str(a) for a in args]], env=env,
                            cwd=cwd, **kwargs)


@pytest.fixture(autouse=True)
def empty_folder(tmp_path, monkeypatch) -> Path:
    monkeypatch.setattr("ncopt.planning.profiles.user_file", lambda: tmp_path / "user" / "ncopt.toml")
    monkeypatch.delenv("NCOPT_MACHINE", raising=False)
    work = tmp_path / "work"
    work.mkdir()
    (work / ".git").mkdir()  # the search for ncopt.toml stops here, never above tmp_path
    monkeypatch.chdir(work)
    return work


@pytest.fixture
def dome_nc(empty_folder) -> Path:
    path = empty_folder / "dome.nc"
    path.write_bytes(dome())
    return path


# ------------------------------------------------------ inspect: the operations ----
def rewrite_rows(program: Path, *options) -> list[dict]:
    """The operations of rewrite's own JSON summary (its OpRow per operation)."""
    result = invoke(["rewrite", program, *SPINDLE, *options, "--json", "-o",
                     Path.cwd() / "out.nc"])
    assert result.exit_code == Exit.OK, result.stderr
    return json.loads(result.stderr)["operations"]


@pytest.mark.parametrize("options", [[], ["--operations", "PENCIL2,SCALLOP1"]],
                         ids=["as-is", "operations"])
def test_inspect_judges_the_operations_as_rewrite_does(options):
    """The Fusion 360 chess box: 13 operations with flat end mills, a face mill, a pencil
    pass, drilling and one ball scallop finish. inspect (which plans nothing and needs no
    spindle) and the rewrite's summary agree on every operation: name, tool, lines,
    planned or not and why, and its time at the programmed feed."""
    inspected = json.loads(invoke(["inspect", CHESS, "--json", *options]).stdout)["operations"]
    rows = rewrite_rows(CHESS, *options)
    assert [(o["name"], o["tool"], o["lines"], o["planned"], o["reason"]) for o in inspected] \
        == [(r["name"], r["tool"], r["lines"], r["planned"], r["reason"]) for r in rows]
    assert [o["time_min"] for o in inspected] == pytest.approx(
        [r["time_before_min"] for r in rows], rel=1e-12)
    names = [o["name"] for o in inspected]
    assert names[:3] == ["FACE2", "POCKET4", "POCKET5"] and len(names) == 13
    # both with T3 "(T3 D=1.5 CR=0.75 - ZMIN=-29.522 - BALL END MILL)"; the pencil pass, one
    # Z level, only when --operations names it
    planned = [o["name"] for o in inspected if o["planned"]]
    assert planned == (["PENCIL2", "SCALLOP1"] if options else ["SCALLOP1"])


def test_inspect_prints_the_operations_of_the_chess_box():
    out = invoke(["inspect", CHESS]).stdout.splitlines()
    i = out.index("  operations: 1 of 13 operations would be planned (times at the programmed "
                  "feed):")
    rows = out[i + 1:i + 14]
    # "(T2 D=5. CR=0. - ZMIN=-10.5 - FLAT END MILL)" on line 4 of the program
    assert rows[1].startswith("    POCKET4 (T2, lines 36-5265): left as programmed (")
    assert rows[1].endswith("min): a flat end mill (T2 D=5. CR=0. - ZMIN=-10.5 - FLAT END "
                            "MILL, line 4); ncopt plans ball and bull-nose cutters only")
    assert re.fullmatch(r"    SCALLOP1 \(T3, lines 32024-34852\): planned, 3d surface "
                        r"finishing, \d+\.\d min", rows[10])
    # "N175830 G83 ..." drilling with T11 (line 8: "(T11 D=8. ... DRILL)")
    assert rows[12].startswith("    DRILL1 (T11, lines 35186-35211): left as programmed")


def test_inspect_of_the_bowl_needs_no_spindle_and_times_at_the_programmed_feed():
    """The sample bowl: one zig-zag finish with its D16 ball (line 4 "(tool: T04 ball end
    mill D16 (R 8 mm), z 2; S1393 F279)"), 59.3 min at F279 (README's results table)."""
    result = invoke(["inspect", BOWL_MPF])
    assert result.exit_code == Exit.OK, result.stderr
    lines = result.stdout.splitlines()
    assert lines[lines.index("  operations: 1 of 1 operation would be planned (times at the "
                             "programmed feed):") + 1] == \
        "    T4 (T4, lines 1-21902): planned, 3d surface finishing, 59.3 min"


def test_inspect_takes_the_cutter_options_of_rewrite():
    """--diameter 10 on a program of several tools: rewrite asks which tool it is; so
    does inspect, with the same message and exit code."""
    a = invoke(["inspect", CHESS, "--diameter", "10"])
    b = invoke(["rewrite", CHESS, "--diameter", "10", *SPINDLE, "-o", Path.cwd() / "o.nc"])
    assert a.exit_code == b.exit_code == Exit.USAGE
    assert a.stderr == b.stderr and "--tool N" in a.stderr


def test_not_plannable_names_its_lines():
    """In the chess box, after each tool change ("N30 T1 M06") the post moves in X Y first
    ("N55 G00 X345. Y13.75", Z not known yet) and then "N60 G43 Z15. H01" (a tool length
    offset ncopt does not know): two moves not plannable after each of the 7 tool changes."""
    text = CHESS.read_bytes().decode("latin-1").splitlines()
    changes = [i for i, ln in enumerate(text, 1) if re.search(r"\bM06\b", ln)]
    runs = []
    for line in changes:
        first = next(i for i in range(line + 1, len(text) + 1)
                     if re.match(r"N\d+ G00 X\S+ Y\S+$", text[i - 1]))
        assert text[first].split()[1:3] == ["G43", "Z15."]  # the line after it
        runs.append([first, first + 1])
    info = json.loads(invoke(["inspect", CHESS, "--json"]).stdout)
    assert info["unknown_lines"] == runs and info["unknown_moves"] == 14
    shown = ", ".join(f"{a}-{b}" for a, b in runs)
    second = invoke(["inspect", CHESS]).stdout.splitlines()[1]
    assert second.endswith(f"not plannable 14 (lines {shown})")


def test_an_inspected_ncopt_output_shows_its_stamped_operations(dome_nc):
    """A rewritten program is planned again from its stamp: inspect says so, as the
    rewrite's summary does."""
    out = Path.cwd() / "opt.nc"
    assert invoke(["rewrite", dome_nc, *DOME, "-o", out, "-q"]).exit_code == Exit.OK
    inspected = json.loads(invoke(["inspect", out, "--json", "--diameter", "6"]).stdout)
    rows = json.loads(invoke(["rewrite", out, *DOME, "--check", "--json"]).stderr)["operations"]
    assert [(o["lines"], o["planned"], o["reason"]) for o in inspected["operations"]] == \
        [(r["lines"], r["planned"], r["reason"]) for r in rows]
    assert any("stamped" in o["reason"] for o in inspected["operations"])


# ------------------------------------------------------------- rewrite --check ----
def test_check_writes_nothing_and_exits_1_when_the_rewrite_would_change(dome_nc):
    before = sorted(Path.cwd().iterdir())
    result = invoke(["rewrite", dome_nc, *DOME, "--check"])
    assert result.exit_code == WOULD_CHANGE == 1
    assert result.stdout == "" and sorted(Path.cwd().iterdir()) == before
    verdict = result.stderr.splitlines()[-1]
    # the counts are those ncopt diff shows between the program and its rewrite
    out = Path.cwd() / "opt.nc"
    assert invoke(["rewrite", dome_nc, *DOME, "-o", out, "-q"]).exit_code == Exit.OK
    header = invoke(["diff", dome_nc, out, "--plain"]).stdout  # unified: count it
    changed = sum(1 for ln in header.splitlines() if ln.startswith("+") and
                  not ln.startswith("+++"))
    n_out = len(out.read_bytes().splitlines())
    m = re.fullmatch(rf"ncopt: {re.escape(str(dome_nc))} would change: (\d+) of (\d+) lines "
                     r"\(S in (\d+), F in (\d+)\); nothing written \(--check\)", verdict)
    assert m, verdict
    assert (int(m[1]), int(m[2])) == (changed, n_out)


def test_check_exits_0_on_its_own_output_and_is_quiet_with_q(dome_nc):
    out = Path.cwd() / "opt.nc"
    assert invoke(["rewrite", dome_nc, *DOME, "-o", out, "-q"]).exit_code == Exit.OK
    same = invoke(["rewrite", out, *DOME, "--check"])
    assert same.exit_code == Exit.OK, same.stderr
    assert same.stderr.splitlines()[-1] == f"ncopt: {out}: nothing would change"
    quiet = invoke(["rewrite", dome_nc, *DOME, "--check", "-q"])
    assert (quiet.exit_code, quiet.stdout, quiet.stderr) == (WOULD_CHANGE, "", "")


def test_check_with_nothing_to_plan_exits_0(empty_folder):
    """Without a spindle start ("M5" instead of "S4000 M3") nothing is planned: the rewrite
    would leave the program as it is."""
    prog = empty_folder / "off.nc"
    prog.write_bytes(dome(spindle=False))
    result = invoke(["rewrite", prog, *DOME, "--check"])
    assert result.exit_code == Exit.OK
    assert result.stderr.startswith(f"ncopt: {prog}: nothing would change: nothing to plan")


@pytest.mark.parametrize("extra", [["-o", "x.nc"], ["--report", "r.html"]], ids=["-o", "report"])
def test_check_refuses_an_output(dome_nc, extra):
    result = invoke(["rewrite", dome_nc, *DOME, "--check", *extra])
    assert result.exit_code == Exit.USAGE
    assert result.stderr == "--check writes nothing: leave out -o and --report\n"
    assert not (Path.cwd() / extra[1]).exists()


# ------------------------------------------------------------------ profiles ----
def fill_required(text: str, accel: float, max_rpm: float) -> str:
    return (text.replace("# accel_rad_s2 =    # required: give your figure and remove the '#'",
                         f"accel_rad_s2 = {accel}")
            .replace("# max_rpm =    # required: give your figure and remove the '#'",
                     f"max_rpm = {max_rpm}"))


def test_profiles_init_comments_every_key_with_its_unit(empty_folder):
    result = invoke(["profiles", "init", "shop-mill"])
    assert result.exit_code == Exit.OK, result.stderr
    text = result.stdout
    lines = text.splitlines()
    fields = [f for f in MachineProfile.__dataclass_fields__ if f not in ("name", "source")]
    for key in fields + ["note"]:
        at = next(i for i, ln in enumerate(lines) if re.match(rf"#? ?{key} =", ln))
        comment = []
        for ln in reversed(lines[:at]):  # the comment block just above the key
            if not ln.startswith("# "):
                break
            comment.insert(0, ln)
        said = " ".join(comment)
        assert said, key
        unit = {"accel_rad_s2": "rad/s^2", "max_rpm": "RPM", "min_rpm": "RPM",
                "max_feed_mm_min": "mm/min", "rapid_mm_min": "mm/min", "min_s_interval_ms": "ms",
                "control": "sinumerik", "decimal_point": "is-b", "s_changes": "between-passes",
                "kinematics": "xyzac-trt", "tcp": "always", "note": "Free text"}[key]
        assert unit in said, (key, said)
    # the spindle is never guessed: until it is given, the file is refused
    path = empty_folder / "ncopt.toml"
    path.write_text(text)
    refused = invoke(["profiles"])
    assert refused.exit_code == Exit.USAGE
    assert refused.stderr == f"{path}: machine 'shop-mill' has no accel_rad_s2; add it\n"
    path.write_text(fill_required(text, 300, 12000))
    machine = load().machines["shop-mill"]
    assert (machine.accel_rad_s2, machine.max_rpm, machine.min_rpm, machine.control) == \
        (300, 12000, 0.0, None)


def test_profiles_init_of_a_known_machine_starts_from_its_values(empty_folder):
    out = empty_folder / "m.toml"
    result = invoke(["profiles", "init", "paper-direct-15000", "-o", out])
    assert result.exit_code == Exit.OK, result.stderr
    written = load(tools_file=out).machines["paper-direct-15000"]
    shipped = [m for m in load().machines.values() if m.source == str(EXAMPLES)]
    want = next(m for m in shipped if m.name == "paper-direct-15000")
    # examples.toml: accel_rad_s2 = 227, max_rpm = 15000, control = "sinumerik"
    assert (written.accel_rad_s2, written.max_rpm, written.control) == (227, 15000, "sinumerik")
    assert written.__dict__ | {"source": ""} == want.__dict__ | {"source": ""}
    assert tomllib.loads(out.read_text())["machines"]["paper-direct-15000"] == {
        "accel_rad_s2": 227, "max_rpm": 15000, "control": "sinumerik"}


def test_profiles_init_never_replaces_a_file(empty_folder):
    out = empty_folder / "ncopt.toml"
    out.write_text("# mine\n")
    result = invoke(["profiles", "init", "shop", "-o", out])
    assert result.exit_code == Exit.IO
    assert result.stderr == (f"{out}: exists; profiles init never replaces a file: name "
                             "another, or add the machine to it by hand\n")
    assert out.read_text() == "# mine\n"


@pytest.mark.parametrize("command", [["profiles"], ["inspect", BOWL_MPF],
                                     ["rewrite", BOWL_MPF, "--machine", "shop"]])
def test_a_misspelt_key_is_refused_with_file_line_and_the_key_meant(empty_folder, command):
    path = empty_folder / "ncopt.toml"
    path.write_text('[machines.shop]\naccel_rad_s2 = 227\nmax_rmp = 15000\n')
    result = invoke(command)
    assert result.exit_code == Exit.USAGE
    assert result.stderr == (f"{path}:3: unknown key max_rmp in machine 'shop'; did you mean "
                             "max_rpm?\n")


@pytest.mark.parametrize("toml, message", [
    ('machine = "shop"\n', ":1: unknown key machine; did you mean machines?"),
    ('[tools.ball6]\ndiameter_mm = 6\nteth = 2\n',
     ":3: unknown key teth in tool 'ball6'; did you mean teeth?"),
    ('[cutting.steel]\nvc_m_min = 70\nfz = 0.1\n',
     ":3: unknown key fz in cutting data 'steel'; did you mean fz_mm?"),
    ('[machines.shop]\naccel_rad_s2 = 227\nmax_rpm = 1\ncolour = "red"\n',
     ":4: unknown key colour in machine 'shop'; the keys are accel_rad_s2, max_rpm, min_rpm, "
     "max_feed_mm_min, rapid_mm_min, control, min_s_interval_ms, decimal_point, s_changes, "
     "kinematics, tcp, note"),
    ('[machines.shop]\naccel_rad_s2 = 227\nmax_rpm = 1\ncontrol = "sinumeric"\n',
     ": machine 'shop': control must be one of grbl, fanuc, linuxcnc, sinumerik, "
     "heidenhain-iso, generic, not 'sinumeric'; did you mean sinumerik?"),
], ids=["top", "tool", "cutting", "no-close-key", "value"])
def test_every_table_refuses_unknown_keys(empty_folder, toml, message):
    path = empty_folder / "p.toml"
    path.write_text(toml)
    result = invoke(["profiles", "--tools", path])
    assert result.exit_code == Exit.USAGE
    assert result.stderr == f"{path}{message}\n"


def test_the_shipped_examples_pass_the_key_check():
    """examples.toml holds 'note' keys: a key for people, known to the check."""
    assert "note" in EXAMPLES.read_text() and "note" in MACHINE_KEYS
    assert invoke(["profiles"]).exit_code == Exit.OK


def shop(max_rpm: int) -> str:
    return f'default_machine = "shop"\n[machines.shop]\naccel_rad_s2 = 227\nmax_rpm = {max_rpm}\n'


def test_the_project_file_is_found_upward_up_to_the_git_folder(empty_folder):
    deep = empty_folder / "jobs" / "2024" / "bowl"
    deep.mkdir(parents=True)
    (empty_folder / "ncopt.toml").write_text(shop(9000))
    (empty_folder.parent / "ncopt.toml").write_text(shop(1000))  # above .git: not read
    os.chdir(deep)
    listing = invoke(["profiles"], columns=300)
    sources = [ln.strip() for ln in listing.stdout.splitlines() if ln.startswith("  /")]
    assert sources == [str(EXAMPLES), str(empty_folder / "ncopt.toml")]
    assert load().chosen_machine(None).max_rpm == 9000
    # without a .git folder the search goes on up to the nearest file
    (empty_folder / ".git").rmdir()
    (empty_folder / "ncopt.toml").unlink()
    assert load().chosen_machine(None).max_rpm == 1000


def test_ncopt_machine_names_the_default_and_machine_wins(empty_folder, monkeypatch, dome_nc):
    (empty_folder / "ncopt.toml").write_text(
        shop(9000) + '[machines.small]\naccel_rad_s2 = 227\nmax_rpm = 5000\n')
    highest = lambda args: max(  # noqa: E731
        float(w[1:]) for w in re.findall(r"S\d+", invoke(["rewrite", dome_nc, "--diameter",
                                                          "6", "-q", *args]).stdout))
    assert highest([]) == 9000  # default_machine of the file
    monkeypatch.setenv("NCOPT_MACHINE", "small")
    assert highest([]) == 5000
    assert highest(["--machine", "shop"]) == 9000
    listing = invoke(["profiles"], env={"NCOPT_MACHINE": "small"})
    assert listing.stdout.splitlines()[-1] == \
        "default machine: small (the NCOPT_MACHINE environment variable)"
    monkeypatch.setenv("NCOPT_MACHINE", "nope")
    bad = invoke(["rewrite", dome_nc, "--diameter", "6"])
    assert bad.exit_code == Exit.USAGE
    assert bad.stderr == ("no machine profile 'nope', which the NCOPT_MACHINE environment "
                          "variable names as the default machine (known: paper-direct-15000, "
                          "paper-direct-40000, paper-geared-4000, shop, small); see ncopt "
                          "profiles\n")


def test_the_profiles_table_shows_names_whole(empty_folder):
    name = "tajmac-zps-mcfv-5050-ln-sinumerik-840d-sl-spindle-2"
    (empty_folder / "ncopt.toml").write_text(
        f'[machines.{name}]\naccel_rad_s2 = 227\nmax_rpm = 15000\n')
    out = invoke(["profiles"], columns=80).stdout
    assert "…" not in out
    assert any(f"│ {name} │" in ln for ln in out.splitlines())
    # the long paths are folded over lines, whole: every character is there
    assert str(EXAMPLES) in re.sub(r"[│ \n]", "", out.split("tools")[0])


# ------------------------------------------------------------- the terminal ----
def test_color_always_colours_the_warning_prefix_and_never_does_not():
    coloured = invoke(["inspect", BOWL_MPF, "--color", "always"]).stdout
    warning = next(ln for ln in coloured.splitlines() if "warning:" in ln)
    assert re.search(r"\x1b\[[0-9;]*m\s*warning:\x1b\[0m", warning), repr(warning)
    plain = invoke(["inspect", BOWL_MPF, "--color", "never"], env={"NO_COLOR": ""}).stdout
    assert "\x1b[" not in plain and "  warning: " in plain
    assert re.sub(r"\x1b\[[0-9;]*m", "", coloured) == plain


def test_an_error_line_is_red_only_when_asked(empty_folder):
    missing = empty_folder / "none.nc"
    red = invoke(["inspect", missing, "--color", "always"])
    assert red.exit_code == Exit.IO
    assert red.stderr.startswith("\x1b[") and f"{missing}: cannot read the file" in red.stderr
    assert invoke(["inspect", missing]).stderr.startswith(f"{missing}: ")  # NO_COLOR=1
    bad = invoke(["inspect", BOWL_MPF, "--color", "blue"])
    assert bad.exit_code == Exit.USAGE
    assert bad.stderr == "--color must be one of auto, always, never, not 'blue'\n"


@pytest.mark.parametrize("command", [["inspect", BOWL_MPF], ["inspect", BOWL_MPF, "--json"],
                                     ["profiles"]], ids=["inspect", "json", "profiles"])
def test_a_listing_into_a_closed_pipe_ends_quietly(empty_folder, command):
    """`ncopt inspect x | head -1`: the reader has gone before the listing is written."""
    proc = ncopt(command, empty_folder, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert (proc.wait(120), err) == (0, "")


def test_a_program_into_a_closed_pipe_still_fails(empty_folder):
    """A program cut short is incomplete: exit 7 and the README's message."""
    prog = empty_folder / "big.nc"
    prog.write_bytes(dome(60))  # its rewrite is larger than a pipe holds
    proc = ncopt(["rewrite", prog, *DOME], empty_folder, stdout=subprocess.PIPE,
                 stderr=subprocess.PIPE)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(120) == Exit.IO
    assert err == ("<stdout>: cannot write the output: Broken pipe; the reading end of the "
                   "pipe was closed before the output was complete\n")


SINGULAR = re.compile(r"(?<![\d.])1 (?:[a-zA-Z]+ )?(?:blocks|points|words|operations|warnings|"
                      r"lines|places|teeth|marks|runs|passes)\b")


def summary(n: int) -> Summary:
    row = OpRow("T1", 1, "1-9", "3D surface finishing", True, "", 1.0, 0.5, 4000.0, 8000.0)
    return Summary(blocks=n, moving_blocks=n, cutting_blocks=n, planned_blocks=n, s_words=n,
                   f_words=n, edits=n, cut_time_before_min=1.0, cut_time_after_min=0.5,
                   vc_m_min=70.0, fz_mm=0.1, max_s_rpm=8000.0, warnings=("x",) * (10 + n),
                   normals_from="toolpath", stepover_mm=0.5, one_sided_points=n,
                   no_cross_points=n, close_s_words=n, operations=(row,) * n, untimed_moves=n,
                   passes=n, control="fanuc", control_source="given")


@given(st.integers(0, 3))
def test_the_summary_counts_in_the_right_number(n):
    """Every count of the rewrite summary agrees with its noun: '1 block', '2 blocks'."""
    buf = io.StringIO()
    print_summary(summary(n), Console(file=buf, width=300, color_system=None))
    text = buf.getvalue()
    assert not SINGULAR.search(text), text
    noun = lambda word: f"{n} {word}" + ("" if n == 1 else "s")  # noqa: E731
    said = [noun("block") + ", ", noun("cutting block") + " planned",
            f"{n} S and {noun('F word')} written", f"of {noun('operation')} planned",
            noun("point") + " at the edge"]
    if n:  # lines printed only when there is something to count
        said += [noun("feed block") + (" is" if n == 1 else " are") + " not timed",
                 noun("S word") + " had to come", "warning: " + noun("more warning")]
    for words in said:
        assert words in text, (words, text)


def test_simulate_and_inspect_count_one_in_the_singular():
    """The bowl's simulation: "S1393 M3" once, so 1 S word (it said '1 S words')."""
    result = invoke(["simulate", BOWL_MPF, "--sample", "1.0", *SPINDLE, "--diameter", "16"])
    assert result.exit_code == Exit.OK, result.stderr
    assert result.stderr.splitlines()[2].endswith("; 1 S word")
    info = Inspection(path="p", dialect="generic", dialect_marks=("G21",), units="mm", lines=1,
                      blocks=1, moves=1, feed_moves=1, rapids=0, arcs=0, unknown_moves=1,
                      tools=((1, "ball", 6.0, 3.0, 1, 1, 1, None, "free text"),),
                      tools_used=(1,), opaque=(), warnings=(), s_range_rpm=(1.0, 1.0),
                      f_range_mm_min=(1.0, 1.0), cut_length_mm=1.0, cut_time_min=1.0,
                      unknown_lines=((1, 1),))
    buf = io.StringIO()
    render_inspection(info, Console(file=buf, width=200, color_system=None))
    text = buf.getvalue()
    assert not SINGULAR.search(text), text
    assert "(1 mark), mm, 1 line\n" in text and "1 tooth (line 1" in text
    assert "not plannable 1 (line 1)" in text


def test_shell_completion_is_available():
    assert "--install-completion" in invoke(["--help"]).stdout
    done = invoke([], prog_name="ncopt", env={"_NCOPT_COMPLETE": "complete_bash",
                                              "COMP_WORDS": "ncopt rew", "COMP_CWORD": "1"})
    assert done.stdout.split() == ["rewrite"]


def test_command_help_loads_no_heavy_module():
    """`ncopt rewrite -h` (and every COMMAND -h) imports neither numpy, rich nor pydantic
    (which typer loads to convert option values: 90 ms of the 0.3 s budget)."""
    probe = ("import sys\nsys.argv = ['ncopt'] + sys.argv[1:]\nfrom ncopt.cli.app import main\n"
             "try:\n    main()\nexcept SystemExit:\n    pass\n"
             "heavy = ('numpy', 'lark', 'rich', 'pydantic', 'ncopt.api')\n"
             "print(sorted(m for m in heavy if m in sys.modules), file=sys.stderr)\n")
    for args in (["rewrite", "-h"], ["inspect", "-h"], ["profiles", "-h"], ["--help"]):
        done = subprocess.run([sys.executable, "-c", probe, *args], capture_output=True,
                              text=True, timeout=60, env={**os.environ, "PYTHONPATH": str(ROOT)})
        assert done.returncode == 0 and done.stderr == "[]\n", (args, done.stderr)


def test_batch_names_keep_their_first_folder_and_file_name():
    """'…ng/finishing/part_07.nc' lost which mould the file is of; the middle goes instead."""
    from ncopt.cli.batchview import _shorten

    assert _shorten("mould_A/roughing/finishing/part_07.nc", 30) == "mould_A/roughing/f…/part_07.nc"
    assert _shorten("mould_B/2025/november/week3/finish.nc", 24) == "mould_B/2025/…/finish.nc"
    assert _shorten("sub/b.nc", 30) == "sub/b.nc"
    long_name = "x" * 50 + ".nc"
    assert _shorten(long_name, 30) == "…" + long_name[-29:]
    for name in ("mould_A/roughing/finishing/part_07.nc", "a/" + "b" * 40 + ".nc"):
        for width in range(8, 45):
            assert len(_shorten(name, width)) <= width


def test_diff_into_a_pipe_answers_before_the_command_line_and_says_the_same(tmp_path):
    """``ncopt diff A B`` into a pipe is written by the light entry point (no typer: about
    0.1 s less, what a diff of a small program costs); it prints what the command line
    prints (``--plain`` takes that path) and exits as diff(1) does."""
    import subprocess
    import sys

    src = tmp_path / "bowl.mpf"
    src.write_bytes(BOWL_MPF.read_bytes())
    out = tmp_path / "bowl_opt.mpf"
    assert invoke(["rewrite", src, "--diameter", "16", *SPINDLE, "-q", "-o", out]).exit_code == 0
    run = lambda *args: subprocess.run([sys.executable, "-m", "ncopt", "diff", *map(str, args)],  # noqa: E731
                                       capture_output=True)
    quick, full = run(src, out), run("--plain", src, out)
    assert quick.returncode == full.returncode == 1
    assert quick.stdout == full.stdout and quick.stdout.startswith(f"--- {src}\n".encode())
    assert quick.stderr == b""
    same = run(src, src)
    assert same.returncode == 0 and same.stdout == b""
    missing = run(src, tmp_path / "nope.nc")  # the command line names the file
    assert missing.returncode == 7 and b"nope.nc" in missing.stderr
    import ncopt.cli.entry
    assert "typer" not in subprocess.run(
        [sys.executable, "-c", "import sys, ncopt.cli.entry, ncopt.report.diffview; "
         "print(' '.join(sorted(m for m in sys.modules if m.split('.')[0] in "
         "('typer', 'rich', 'numpy'))))"], capture_output=True, text=True).stdout
    assert ncopt.cli.entry.DIFFERENT == 1


def test_diff_of_two_folders_is_diff_ru_of_their_programs(tmp_path):
    """``ncopt diff IN OUT`` of a batch's input and output folders: a unified diff of every
    pair of files that differ (found below each folder by the same path), ``Only in``
    for a file of one alone, nothing for the same files; the same from the light entry
    point and the command line (``--plain``), and the files diff -rq names."""
    import shutil
    import subprocess
    import sys

    a, b = tmp_path / "in", tmp_path / "out"
    (a / "sub").mkdir(parents=True)
    (b / "sub").mkdir(parents=True)
    (a / "bowl.mpf").write_bytes(BOWL_MPF.read_bytes())
    assert invoke(["rewrite", a / "bowl.mpf", "--diameter", "16", *SPINDLE, "-q",
                   "-o", b / "bowl.mpf"]).exit_code == 0
    (a / "sub" / "same.nc").write_bytes(b"G0 X1\n")
    (b / "sub" / "same.nc").write_bytes(b"G0 X1\n")
    (a / "sub" / "left.nc").write_bytes(b"G0 X2\n")
    (b / "report.html").write_bytes(b"<html></html>\n")
    run = lambda *args: subprocess.run([sys.executable, "-m", "ncopt", "diff", *map(str, args)],  # noqa: E731
                                       capture_output=True)
    quick, full = run(a, b), run("--plain", a, b)
    assert quick.returncode == full.returncode == 1, full.stderr
    assert quick.stdout == full.stdout and quick.stderr == b""
    text = quick.stdout.decode()
    assert text.startswith(f"--- {a / 'bowl.mpf'}\n+++ {b / 'bowl.mpf'}\n")
    assert f"Only in {a / 'sub'}: left.nc\n" in text and f"Only in {b}: report.html\n" in text
    assert "same.nc" not in text
    if shutil.which("diff"):  # the files diff -rq names differ or stand alone here too
        rq = subprocess.run(["diff", "-rq", str(a), str(b)], capture_output=True, text=True)
        assert rq.returncode == 1
        named = {w for line in rq.stdout.splitlines() for w in line.split()
                 if w.endswith((".mpf", ".nc", ".html")) or w.endswith(":")}
        assert str(a / "bowl.mpf") in named and f"{a / 'sub'}:" in named
    quiet = run("-q", a, b)
    assert quiet.returncode == 1 and quiet.stdout == b""
    (a / "sub" / "left.nc").unlink()
    (b / "report.html").unlink()
    (b / "bowl.mpf").write_bytes((a / "bowl.mpf").read_bytes())
    same = run(a, b)
    assert same.returncode == 0 and same.stdout == b""


def test_diff_of_folders_says_what_diff_ru_says_of_other_entries(tmp_path):
    """Folders linked in are followed (each once), a folder of one side alone is one
    ``Only in`` line, a fifo is never opened (it would wait for a writer), binary files
    and entries of different kinds are named as diff -ru names them, and files whose
    lines differ only in their ends say so: each from the light entry point and the
    command line alike, exit 1."""
    import subprocess
    import sys

    a, b = tmp_path / "A", tmp_path / "B"
    for side in (a, b):
        (side / "real").mkdir(parents=True)
        os.mkfifo(side / "pipe")
    (a / "real" / "p.nc").write_text("G1 X1\n")
    (b / "real" / "p.nc").write_text("G1 X2\n")
    (a / "linked").symlink_to(a / "real")  # followed: compared as a folder of its own
    (b / "linked").symlink_to(b / "real")
    (a / "real" / "loop").symlink_to(a)  # a loop ends
    (b / "real" / "loop").symlink_to(b)
    (a / "empty").mkdir()
    (a / "f").write_text("x\n")
    (b / "f").mkdir()
    (a / "bin").write_bytes(b"a\0b")
    (b / "bin").write_bytes(b"a\0c")
    (a / "crlf.nc").write_bytes(b"G1 X1\r\n")
    (b / "crlf.nc").write_bytes(b"G1 X1\n")
    run = lambda *args: subprocess.run([sys.executable, "-m", "ncopt", "diff", *map(str, args)],  # noqa: E731
                                       capture_output=True, timeout=60)
    quick, full = run(a, b), run("--plain", a, b)
    assert quick.returncode == full.returncode == 1, full.stderr
    assert quick.stdout == full.stdout
    text = quick.stdout.decode()
    assert f"--- {a / 'linked' / 'p.nc'}\n+++ {b / 'linked' / 'p.nc'}\n" in text
    assert f"--- {a / 'real' / 'p.nc'}\n" in text
    assert f"Only in {a}: empty\n" in text
    assert f"File {a / 'f'} is a regular file while file {b / 'f'} is a directory\n" in text
    assert f"File {a / 'pipe'} is a fifo while file {b / 'pipe'} is a fifo\n" in text
    assert f"Binary files {a / 'bin'} and {b / 'bin'} differ\n" in text
    assert f"Files {a / 'crlf.nc'} and {b / 'crlf.nc'} differ only in their line ends\n" in text
    (b / "empty").mkdir()
    only_empty = run(a / "empty", b / "empty")
    assert only_empty.returncode == 0 and only_empty.stdout == b""
