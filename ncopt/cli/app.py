"""``ncopt`` command line: a thin typer layer over :mod:`ncopt.api`, assembled here.

The commands live by family (:mod:`ncopt.cli.rewrite`: rewrite, batch;
:mod:`ncopt.cli.replay`: simulate, report; :mod:`ncopt.cli.review`: inspect, diff,
profiles, version), the options they share in :mod:`ncopt.cli.options`, the Job those
options make in :mod:`ncopt.planning.job`, and what every command shares (exit codes,
faults, help panels) in :mod:`ncopt.cli.core`.  Startup stays light: ``ncopt --help``,
``ncopt COMMAND -h`` and ``ncopt version`` import neither numpy nor lark nor the api, nor
pydantic; each command imports what it needs in its body.  A command added with
``@app.command()`` runs inside :func:`ncopt.runtime.stdio.command_faults` as the others do.
"""

# No `from __future__ import annotations` here: typer evaluates every string annotation when
# it builds the commands, a third of the time `ncopt --help` took.
import signal
import sys

from ncopt.cli import replay, review, rewrite
from ncopt.cli.core import (DIFFERENT, WOULD_CHANGE, App, Exit, Group, HelpFlag,  # noqa: F401
                            InstallCompletion, ShowCompletion, VersionFlag, exit_code, guarded,
                            say_version)
from ncopt.cli.rewrite import print_summary  # noqa: F401  (the summary, for callers and tests)
from ncopt.planning.job import job_from_values as make_job  # noqa: F401  (its old name here)
from ncopt.runtime.errors import NcoptError
from ncopt.runtime.stdio import interrupt, say

app = App(cls=Group, add_completion=False, pretty_exceptions_show_locals=False,
          no_args_is_help=True, rich_markup_mode=None,
          context_settings={"help_option_names": ["-h", "--help"]},
          help="Rewrite S and F words of finishing programs for constant vc and fz.")


@app.callback()
def _root(version: VersionFlag = False, show_help: HelpFlag = False,
          install_completion: InstallCompletion = False,
          show_completion: ShowCompletion = False) -> None:
    """Rewrite S and F words of finishing programs for constant vc and fz."""


app.command()(rewrite.rewrite)
app.command()(rewrite.batch)
app.command()(replay.report)
app.command()(replay.simulate)
app.command()(review.inspect)
app.command()(review.diff)

profiles_app = App(no_args_is_help=False, rich_markup_mode=None,
                   context_settings={"help_option_names": ["-h", "--help"]})
app.add_typer(profiles_app, name="profiles")
profiles_app.callback(invoke_without_command=True)(guarded(review.profiles))
profiles_app.command("init")(review.profiles_init)
app.command()(review.version)


def main() -> None:
    """Console entry point: ncopt errors become one located line and an exit code."""
    signal.signal(signal.SIGTERM, interrupt)  # from the start: SIGTERM is an interrupt
    if sys.argv[1:] in (["version"], ["--version"]):  # before typer builds its commands
        sys.exit(say_version())
    try:
        app()
    except NcoptError as exc:  # raised outside a command body
        say(str(exc), error=True)
        sys.exit(int(exit_code(exc)))
    except KeyboardInterrupt:  # before a command started
        say("ncopt: interrupted")
        sys.exit(int(Exit.INTERRUPTED))
