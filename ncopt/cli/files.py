"""The files a command reads and writes, checked before the (long) work: no output over an
input or over another output, no report that cannot be written; and the HTML report
written after it.  The modules these need are imported when a command runs, not for -h."""

from __future__ import annotations

from pathlib import Path

from ncopt.runtime.errors import FileError
from ncopt.runtime.stdio import say


def guard_outputs(inputs, outputs, in_place=()) -> None:
    """:func:`ncopt.runtime.fileio.guard_outputs`, imported when a command runs (not for -h)."""
    from ncopt.runtime import fileio

    fileio.guard_outputs(inputs, outputs, in_place)


def read_by(*programs, mesh=None, tools_file=None) -> list:
    """(what, path) of every file a command reads: its programs, the mesh, the profile
    files (--tools, and the ncopt.toml files found: the project's, the user's)."""
    from ncopt.planning.profiles import search_paths

    return [*programs, ("mesh", mesh)] + [("profile file", p)
                                          for p in search_paths(tools_file=tools_file)]


def guard_batch(files, targets, report, pages, in_place, mesh, tools_file) -> None:
    """A batch's outputs (the rewrites, the report and its pages) checked against its
    inputs, one another and, in place, the programs' backups (ncopt.runtime.fileio.guard_outputs)."""
    outputs = [] if in_place else [("-o", t) for t in targets]
    outputs += [("--report", report)] + [("--report (a program's page)", p) for p in pages]
    guard_outputs([("program", f) for f in files] + read_by(mesh=mesh, tools_file=tools_file),
                  outputs, in_place=files if in_place else ())


def check_report(report: Path | None, json_ok: bool = False,
                 made_folder: Path | None = None) -> None:
    """Refuse a report that cannot be written before the (long) work, not after it
    (``made_folder``: the output folder the command creates, a report may go there)."""
    if report is None:
        return
    if not (json_ok and report.suffix.lower() == ".json"):
        from ncopt.report.html import require_libraries
        require_libraries()
    parent = report.resolve().parent
    if made_folder is not None and parent == made_folder.resolve():
        return
    if not parent.is_dir():
        raise FileError("the folder to write into does not exist; create it first", str(report))


def write_report(path: Path, gather, mesh: Path | None, quiet: bool = False,
                 lite: bool = False) -> None:
    """Simulate what the report shows (with the mesh, if any) and write the page (``lite``:
    static images, no plotly.js)."""
    from ncopt.contacts.geometry import MeshIndex, load_stl
    from ncopt.report.html import render
    from ncopt.runtime.fileio import write_output

    page = render(gather(MeshIndex(load_stl(mesh)) if mesh else None), lite=lite)
    write_output(path, page.encode("utf-8"))
    if not quiet:
        say(f"ncopt: report written to {path}")
