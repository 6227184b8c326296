"""What a command line is expected to do: -h everywhere, --version, -q, - for stdin, a
diff that pages and exits like diff(1), a light start, and an install name of our own."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from typer.testing import CliRunner

import ncopt
from ncopt.cli.app import DIFFERENT, Exit, app
from programs import dome

ROOT = Path(__file__).resolve().parents[1]
SPINDLE = ["--diameter", "6", "--accel", "227", "--max-rpm", "15000"]
COMMANDS = ["rewrite", "batch", "simulate", "inspect", "diff", "profiles", "version"]


def invoke(args, stdin: bytes | None = None, env: dict | None = None):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100", **(env or {})})
    result = runner.invoke(app, [str(a) for a in args], input=stdin, catch_exceptions=False)
    assert "Traceback" not in result.stderr
    return result


@pytest.fixture
def pair(tmp_path, monkeypatch):
    """A program and its rewrite, in an empty working folder with no user profiles."""
    monkeypatch.setattr("ncopt.planning.profiles.user_file", lambda: tmp_path / "user" / "ncopt.toml")
    monkeypatch.chdir(tmp_path)
    prog, opt = tmp_path / "p.nc", tmp_path / "opt.nc"
    prog.write_bytes(dome())
    assert invoke(["rewrite", prog, *SPINDLE, "-o", opt, "-q"]).exit_code == 0
    return prog, opt


# ------------------------------------------------------------- help, version ----
@pytest.mark.parametrize("command", [[], *([c] for c in COMMANDS)], ids=["app", *COMMANDS])
def test_h_is_help_everywhere(command):
    short, long = invoke([*command, "-h"]), invoke([*command, "--help"])
    assert short.exit_code == long.exit_code == 0
    assert short.stdout == long.stdout
    usage = short.stdout.splitlines()[0]  # CliRunner names the program "root"
    assert re.match(r"Usage: \S+" + "".join(f" {c}" for c in command) + r" \[OPTIONS\]", usage)
    assert "-h, --help" in short.stdout


def test_help_lists_the_options_by_panel_with_their_choices():
    out = invoke(["rewrite", "-h"]).stdout
    heads = [ln[:-1] for ln in out.splitlines() if re.fullmatch(r"[A-Z]\w*:", ln)]
    assert heads == ["Arguments", "Cutter", "Targets", "Machine", "Control", "Part",
                     "Planning", "Output", "Options"]
    for entry in ("--planner <lookahead|forward>", "--tool-point <tip|center>",
                  "--s-changes <anywhere|between-passes>", "--color <auto|always|never>"):
        assert entry in out
    simulate = invoke(["simulate", "-h"]).stdout
    assert "--color-by <s_rpm|f_mm_min|d_eff_mm|vc_m_min>" in simulate


def test_the_color_by_choices_are_the_plots():
    """Spelt for -h (the plots load numpy), checked against ncopt.report.plots itself."""
    from typing import get_args

    from ncopt.cli.replay import ColorBy
    from ncopt.report.plots import COLOR_BY

    assert get_args(ColorBy) == tuple(key for key, _ in COLOR_BY)


@pytest.mark.parametrize("words, offered", [
    ("ncopt rewrite p.nc --planner ", ["lookahead", "forward"]),
    ("ncopt simulate p.nc --color-by d", ["d_eff_mm"]),
    ("ncopt inspect p.nc --dialect s", ["sinumerik"]),
])
def test_the_shell_completes_a_choice(words, offered):
    done = CliRunner().invoke(app, [], prog_name="ncopt", env={
        "_NCOPT_COMPLETE": "complete_bash", "COMP_WORDS": words,
        "COMP_CWORD": str(len(words.split()) - (0 if words.endswith(" ") else 1))})
    assert done.stdout.split() == offered


def test_version_both_ways():
    for args in (["--version"], ["version"]):
        result = invoke(args)
        assert (result.exit_code, result.stdout, result.stderr) == (0, f"{ncopt.__version__}\n", "")


def test_the_command_line_starts_without_the_heavy_modules():
    """ncopt --help and ncopt version import neither numpy nor lark nor rich nor the api
    (bench/bench_startup.py measures the time)."""
    probe = ("import sys\nsys.argv = ['ncopt'] + sys.argv[1:]\nfrom ncopt.cli.app import main\n"
             "try:\n    main()\nexcept SystemExit:\n    pass\n"
             "heavy = ('numpy', 'lark', 'scipy', 'rich', 'ncopt.api', 'ncopt.reading.parse')\n"
             "print(sorted(m for m in heavy if m in sys.modules), file=sys.stderr)\n")
    for args in (["--help"], ["version"], ["--version"]):
        done = subprocess.run([sys.executable, "-c", probe, *args], capture_output=True,
                              text=True, timeout=60)
        assert done.returncode == 0 and done.stderr == "[]\n", (args, done.stderr)


# ---------------------------------------------------------------------- quiet ----
def test_quiet_silences_the_summaries(pair, tmp_path):
    prog, opt = pair
    for args in (["rewrite", prog, *SPINDLE, "-o", tmp_path / "q.nc"],
                 ["simulate", prog, *SPINDLE, "--sample", "1"],
                 ["batch", tmp_path, *SPINDLE, "-o", tmp_path.parent / f"{tmp_path.name}-out"],
                 ["diff", prog, opt]):
        loud, quiet = invoke(args), invoke([*args, "-q"])
        assert loud.stderr + loud.stdout != "", args
        assert (quiet.stdout, quiet.stderr) == ("", ""), args
        assert quiet.exit_code == loud.exit_code, args
    data = invoke(["simulate", prog, *SPINDLE, "--sample", "1", "--json", "-q"])
    assert data.stdout.startswith("{") and data.stderr == ""  # -q keeps the data output


# ---------------------------------------------------------------------- stdin ----
def test_dash_reads_the_program_from_stdin(pair):
    prog, opt = pair
    data = prog.read_bytes()
    a = invoke(["inspect", "-", "--json"], stdin=data)
    b = invoke(["inspect", prog, "--json"])
    assert a.exit_code == b.exit_code == 0
    assert a.stdout.replace('"-"', "P") == b.stdout.replace(f'"{prog}"', "P")
    a = invoke(["simulate", "-", *SPINDLE, "--sample", "1", "--json"], stdin=data)
    b = invoke(["simulate", prog, *SPINDLE, "--sample", "1", "--json"])
    assert a.stdout.replace('"-"', "P") == b.stdout.replace(f'"{prog}"', "P")
    a = invoke(["diff", "-", opt], stdin=data)
    b = invoke(["diff", prog, opt])
    assert a.exit_code == b.exit_code == DIFFERENT
    assert a.stdout.splitlines()[2:] == b.stdout.splitlines()[2:]
    assert a.stdout.splitlines()[0] == "--- -"
    two = invoke(["diff", "-", "-"], stdin=data)
    assert two.exit_code == Exit.USAGE
    assert two.stderr == "only one program can come from stdin (-)\n"


# ----------------------------------------------------------------------- diff ----
def test_diff_exits_like_diff(pair, tmp_path):
    prog, opt = pair
    copy = tmp_path / "copy.nc"
    copy.write_bytes(prog.read_bytes())
    same, differ = invoke(["diff", prog, copy]), invoke(["diff", prog, opt])
    assert (same.exit_code, same.stdout) == (0, "")
    assert differ.exit_code == DIFFERENT == 1 and differ.stdout.startswith(f"--- {prog}\n")
    crlf = tmp_path / "crlf.nc"
    crlf.write_bytes(prog.read_bytes().replace(b"\n", b"\r\n"))
    assert invoke(["diff", prog, crlf, "-q"]).exit_code == DIFFERENT  # bytes differ
    missing = invoke(["diff", prog, tmp_path / "none.nc"])
    assert missing.exit_code == Exit.IO


def test_diff_pages_on_a_terminal_with_colour(pair, tmp_path):
    prog, opt = pair
    paged = tmp_path / "paged.txt"
    terminal = {"FORCE_COLOR": "1", "NO_COLOR": None, "TERM": "xterm-256color", "LESS": None,
                "PAGER": f'printf "LESS=%s\\n" "$LESS" > {paged}; cat >> {paged}',
                "NCOPT_PAGER": None}
    result = invoke(["diff", prog, opt], env=terminal)
    assert result.exit_code == DIFFERENT and result.stdout == ""
    text = paged.read_text()
    assert text.startswith("LESS=FRX\n")  # colours pass, a short diff stays on the screen
    assert "\x1b[" in text and "lines changed" in text and "┃" in text
    # no pager: straight to the terminal, coloured
    paged.unlink()
    direct = invoke(["diff", prog, opt, "--no-pager"], env=terminal)
    assert direct.exit_code == DIFFERENT and "\x1b[" in direct.stdout and not paged.exists()
    for pager in ("", "cat"):  # an empty pager or cat: none
        result = invoke(["diff", prog, opt], env={**terminal, "NCOPT_PAGER": pager})
        assert "lines changed" in result.stdout and not paged.exists()
    # not a terminal: a plain unified diff, never paged
    plain = invoke(["diff", prog, opt], env={**terminal, "FORCE_COLOR": None, "TERM": "dumb"})
    assert plain.stdout.startswith("--- ") and not paged.exists()


# -------------------------------------------------------------- -o as a folder ----
def test_output_into_a_folder_and_a_path_ending_in_slash(pair, tmp_path):
    prog, _ = pair
    (tmp_path / "out").mkdir()
    for out in (f"{tmp_path}/out/", f"{tmp_path}/out"):
        result = invoke(["rewrite", prog, *SPINDLE, "-o", out, "-q"])
        assert result.exit_code == 0 and (tmp_path / "out" / "p.nc").is_file()
    result = invoke(["rewrite", prog, *SPINDLE, "-o", f"{tmp_path}/newdir/"])
    assert result.exit_code == Exit.IO
    assert result.stderr == (f"{tmp_path}/newdir/: no such folder; create it first, or name a "
                             "file (without the trailing /)\n")
    assert not (tmp_path / "newdir").exists()


# ------------------------------------------------------------------ the name ----
def test_the_distribution_name_is_ours_and_the_hints_install_this_project(monkeypatch, pair):
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["name"] == ncopt.DISTRIBUTION != "ncopt"  # 'ncopt' is another project
    assert project["scripts"] == {"ncopt": "ncopt.cli.entry:main"}  # diff answers before typer loads
    readme = (ROOT / "README.md").read_text()
    hints = re.findall(r"pip install ([^`\n]+)", readme)
    assert hints and all(re.match(r"""(?:-e )?["']?\.(?:\[\w+\])?["']?(?: |$)|ncopt-cnc|matplotlib""",
                                  h) for h in hints), hints
    prog, _ = pair
    monkeypatch.setattr("ncopt.cli.replay._has_matplotlib", lambda: False)
    result = invoke(["simulate", prog, *SPINDLE, "--plot", "p.png"])
    assert result.exit_code == Exit.USAGE
    assert result.stderr == ("plots need matplotlib: python -m pip install matplotlib (or, in "
                             "ncopt's source folder, python -m pip install \".[plot]\")\n")


def test_diff_pairs_a_stamped_rewrite_line_by_line(pair, monkeypatch):
    """The stamp lines of any ncopt version are shown apart and the rest paired line by
    line (difflib on a 1M-line program would take minutes)."""
    from ncopt.report import diffview
    from ncopt.report.diffview import _rows

    def no_difflib(*args):
        raise AssertionError("the rewrite went through difflib")

    monkeypatch.setattr(diffview, "_rows_difflib", no_difflib)
    prog, opt = pair
    a = prog.read_text().splitlines()
    b = opt.read_text().splitlines()
    stamps = [i for i, line in enumerate(b[:10]) if line.startswith("(ncopt ")]
    assert stamps and len(b) == len(a) + len(stamps)
    rows = list(_rows(a, b))
    assert [r[:2] for r in rows[:len(stamps)]] == [("change", None)] * len(stamps)
    paired = [r for r in rows[len(stamps):] if r[0] != "fold"]
    assert paired and all(r[1] is not None and r[3] is not None for r in paired)
    assert all(a[r[1] - 1] == r[2] and b[r[3] - 1] == r[4] for r in paired)
