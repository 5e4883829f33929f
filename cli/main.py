"""The ``rangekit`` command group; maps library errors to exit codes in one place.

Every error is one line on stderr, ``rangekit: error: ...`` (``--debug`` shows the
traceback of library errors). The exit codes are the table
:data:`rangekit.errors.EXIT_CODES`, which ``rangekit --help`` prints.
"""

from __future__ import annotations

import sys
from typing import ClassVar

import click

from rangekit.errors import DOCS_URL, exit_codes_text

EXIT_INTERNAL = 70
EXIT_INTERRUPTED = 130


class RangekitGroup(click.Group):
    """A click group whose commands are imported only when used (fast start-up)."""

    _commands: ClassVar[dict[str, tuple[str, str]]] = {
        "range": ("rangekit_cli.range_cmd", "range_cmd"),
        "detect": ("rangekit_cli.detect_cmd", "detect_cmd"),
        "design": ("rangekit_cli.design_cmd", "design"),
        "synth": ("rangekit_cli.synth_cmd", "synth"),
        "track": ("rangekit_cli.track_cmd", "track_cmd"),
        "locate": ("rangekit_cli.locate_cmd", "locate_cmd"),
        "experiment": ("rangekit_cli.experiment_cmd", "experiment_cmd"),
        "plot": ("rangekit_cli.plot_cmd", "plot"),
        "batch": ("rangekit_cli.batch_cmd", "batch_cmd"),
        "calibrate": ("rangekit_cli.calibrate_cmd", "calibrate_cmd"),
    }

    #: Each command's short help (what ``get_short_help_str`` gives, untruncated), so that
    #: ``rangekit --help`` lists the commands without importing them (``range`` imports
    #: numpy: 0.28 -> 0.1 s CPU). ``tests/cli/test_main_startup.py`` checks it against
    #: the commands themselves.
    _short_help: ClassVar[dict[str, str]] = {
        "batch": "Range every session found in files, folders and globs; one results file.",
        "calibrate": "Fit a device pair's (or link's) offset, and speed of sound, from known "
        "distances.",
        "design": "Write probe signals as playable WAV files.",
        "detect": "Beep onsets (or --template probe onsets) in every channel of every FILE.",
        "experiment": "Reproduce a paper's experiment by simulation: its numbers beside "
        "rangekit's.",
        "locate": "One robot pose from the distances of ceiling transmitters to its three "
        "receivers.",
        "plot": "Pictures: spectrogram with onsets, matched-filter output, ranges, tracks, "
        "error CDFs.",
        "range": "Distances from recordings: two-way beeps, one-way beacons or pulse-echo.",
        "synth": "Render simulated recordings plus a JSON sidecar with the ground truth.",
        "track": "Track from a log: people from ranges, a robot from its IMU or beacons, a "
        "walker's fixes or steps.",
    }

    def list_commands(self, ctx):
        return sorted(self._commands)

    def format_commands(self, ctx, formatter):
        """The command list of ``--help``, as click writes it, from :attr:`_short_help`."""
        names = self.list_commands(ctx)
        if not names:
            return
        limit = formatter.width - 6 - max(len(n) for n in names)
        short = {n: click.Command(n, help=self._short_help[n]) for n in names}
        rows = [(n, short[n].get_short_help_str(limit)) for n in names]
        with formatter.section("Commands"):
            formatter.write_dl(rows)

    def get_command(self, ctx, name):
        if name not in self._commands:
            return None
        import importlib

        mod, attr = self._commands[name]
        return getattr(importlib.import_module(mod), attr)

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        """Like click's, but every usage error is one line on stderr: ``rangekit: error: ...``."""
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        try:
            rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except click.exceptions.NoArgsIsHelpError as e:
            # A bare group (`rangekit`, `rangekit synth`): its help, as asked for, exit 0.
            click.echo(e.ctx.get_help())
            sys.exit(0)
        except click.ClickException as e:
            _drop_hidden_suggestions(e)
            msg = " ".join(e.format_message().split())
            ctx = getattr(e, "ctx", None)
            hint = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
            click.echo(f"rangekit: error: {msg}{hint}", err=True)
            sys.exit(e.exit_code)
        except click.Abort:
            click.echo("rangekit: interrupted", err=True)
            sys.exit(EXIT_INTERRUPTED)
        sys.exit(rv if isinstance(rv, int) else 0)

    def invoke(self, ctx):
        from rangekit.errors import RangekitError

        try:
            rv = super().invoke(ctx)
        except RangekitError as e:
            if ctx.meta.get("rangekit.debug"):
                raise
            click.echo(f"rangekit: error: {e}", err=True)
            ctx.exit(e.exit_code)
        except (click.exceptions.Exit, click.ClickException, click.Abort):
            raise
        except KeyboardInterrupt:
            click.echo("rangekit: interrupted", err=True)
            ctx.exit(EXIT_INTERRUPTED)
        except Exception as e:
            if ctx.meta.get("rangekit.debug"):
                raise
            click.echo(
                f"rangekit: internal error: {type(e).__name__}: {e} (rerun with --debug for the "
                "traceback, and please report it)",
                err=True,
            )
            ctx.exit(EXIT_INTERNAL)
        # Notes a command left for after its results (e.g. the setup range read).
        for note in ctx.meta.pop("rangekit.notes", []):
            click.echo(note, err=True)
        return rv


def _drop_hidden_suggestions(e: click.ClickException) -> None:
    """ "Did you mean" never suggests a hidden option (an old spelling such as ``--q``)."""
    ctx = getattr(e, "ctx", None)
    if not isinstance(e, click.exceptions.NoSuchOption) or ctx is None or not e.possibilities:
        return
    hidden = {o for p in ctx.command.params if getattr(p, "hidden", False) for o in p.opts}
    e.possibilities = [p for p in e.possibilities if p not in hidden]


def _version() -> str:
    from rangekit import __version__

    return __version__


EPILOG = f"""\b
Exit codes:
{exit_codes_text()}

\b
Documentation: {DOCS_URL}
"""


@click.group(
    cls=RangekitGroup,
    context_settings={"help_option_names": ["-h", "--help"]},
    epilog=EPILOG,
)
@click.option("--debug", is_flag=True, help="Show tracebacks of errors.")
@click.option(
    "--memory-budget",
    "memory_budget",
    default=None,
    metavar="SIZE|off",
    help="Most memory a whole-file command may plan to use (512M, 4G, off); a recording "
    "needing more is refused with a hint to --series [default: half the available memory; "
    "$RANGEKIT_MEMORY_BUDGET].",
)
@click.version_option(version=None, package_name="rangekit", prog_name="rangekit")
@click.pass_context
def cli(ctx: click.Context, debug: bool, memory_budget: str | None) -> None:
    """rangekit: acoustic and ultrasonic ranging from WAV files.

    \b
    Typical use:
      rangekit design beep -o beep.wav        # the file to play on every phone
      rangekit range recording.wav            # distances between the devices
      rangekit detect recording.wav           # what was detected, per channel
      rangekit synth beepbeep --distance 2 -o x.wav   # a simulated exchange + truth
      rangekit plot spectrogram x.wav -o x.png        # the onsets found, as a picture

    Every command: -q/--quiet, -v/--verbose; - for standard input or (-o -) output.
    """
    ctx.meta["rangekit.debug"] = debug
    if memory_budget is not None:
        import os

        from rangekit.io.audio import BUDGET_ENV, parse_size

        try:
            parse_size(memory_budget)
        except ValueError as e:
            raise click.BadParameter(str(e), param_hint="--memory-budget") from None
        os.environ[BUDGET_ENV] = memory_budget  # inherited by batch workers


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point."""
    cli.main(args=argv, prog_name="rangekit")


if __name__ == "__main__":  # pragma: no cover
    main(sys.argv[1:])
