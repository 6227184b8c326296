"""5-axis through the command line: --kinematics, the machine profile's kinematics, and
what a user sees when ncopt cannot plan a tilted tool."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from ncopt.cli.app import Exit, app

SPINDLE = ["--diameter", "10", "--teeth", "2", "--accel", "227", "--max-rpm", "18000",
           "--vc", "150", "--fz", "0.08"]
ROTARY = ("G21 G90 G94 M428\nS4000 M3\nG0 X0 Y0 Z5 A15 C30\nG1 Z0 F500\nG1 X10\n"
          "G1 X20 C40\nG1 X30 C50\n")


def invoke(args):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100"})
    result = runner.invoke(app, [str(a) for a in args], catch_exceptions=False)
    assert "Traceback" not in result.stdout + result.stderr
    return result


def test_an_unknown_kinematics_is_a_usage_error(tmp_path: Path):
    prog = tmp_path / "p.nc"
    prog.write_text(ROTARY)
    for cmd in (["rewrite", prog, *SPINDLE], ["inspect", prog],
                ["simulate", prog, *SPINDLE]):
        result = invoke([*cmd, "--kinematics", "xyzac"])
        assert result.exit_code == Exit.USAGE
        assert result.stderr.strip() == (
            "--kinematics must be one of xyzac-trt, xyzac-head-table, xyzac-trt-linuxcnc, "
            "xyzbc-trt, xyzbc-head-table, xyzbc-head-head, xyzbc-trt-linuxcnc, "
            "xyzbc-5axis-linuxcnc, vector, not 'xyzac'")


def test_a_profile_with_an_unknown_kinematics(tmp_path: Path):
    prog = tmp_path / "p.nc"
    prog.write_text(ROTARY)
    profiles = tmp_path / "p.toml"
    profiles.write_text('[machines.m]\naccel_rad_s2 = 227\nmax_rpm = 18000\n'
                        'kinematics = "table-table"\n')
    result = invoke(["rewrite", prog, "--diameter", "10", "--machine", "m", "--tools",
                     profiles])
    assert result.exit_code == Exit.USAGE
    assert result.stderr.strip() == (
        f"{profiles}: machine 'm': kinematics must be one of xyzac-trt, xyzac-head-table, "
        "xyzac-trt-linuxcnc, xyzbc-trt, xyzbc-head-table, xyzbc-head-head, "
        "xyzbc-trt-linuxcnc, xyzbc-5axis-linuxcnc, vector, not 'table-table'")


def test_a_rotary_program_without_kinematics_plans_nothing_and_says_why(tmp_path: Path):
    prog = tmp_path / "p.nc"
    prog.write_text(ROTARY)
    out = tmp_path / "o.nc"
    result = invoke(["rewrite", prog, *SPINDLE, "-o", out])
    assert result.exit_code == Exit.PLANNING
    assert not out.exists()
    assert result.stderr.strip() == (
        f"{prog}: nothing to plan: the program (lines 1-7): line 4-7: the rotary axes (A, C) "
        "tilt the tool and no kinematics is given; pass --kinematics xyzac-trt, "
        "xyzac-head-table or xyzac-trt-linuxcnc as the machine is built")


def test_the_machine_profile_gives_the_kinematics(tmp_path: Path):
    prog = tmp_path / "p.nc"
    prog.write_text(ROTARY)
    profiles = tmp_path / "p.toml"
    profiles.write_text('[machines.m]\naccel_rad_s2 = 227\nmax_rpm = 18000\n'
                        'kinematics = "xyzac-trt"\n')
    out = tmp_path / "o.nc"
    result = invoke(["rewrite", prog, "--diameter", "10", "--vc", "150", "--fz", "0.08",
                     "--machine", "m", "--tools", profiles, "--operations", "all", "-o", out])
    assert result.exit_code == Exit.OK, result.stderr
    assert "ncopt: 7 blocks, 3 cutting blocks planned" in result.stderr
    assert out.read_text().count("S") > ROTARY.count("S")
    shown = "5-axis: tool axes from the rotary axes through the xyzac-trt kinematics, " \
        "tilted 15.0..15.0 deg from +Z"
    for how in (["--kinematics", "xyzac-trt"], ["--machine", "m", "--tools", profiles]):
        info = invoke(["inspect", prog, *how])
        assert info.exit_code == Exit.OK
        assert shown in info.stdout
