"""Output and verbosity options of every command: ``-o`` (checked before any work, ``-`` =
standard output), ``--format``, ``-q/-v``, ``--debug``, and the stderr notes and progress."""

from __future__ import annotations

import functools
import math

import click

__all__ = [
    "FORMATS",
    "VERBOSITY_KEY",
    "check_outputs",
    "debug_option",
    "detail",
    "emit",
    "format_choice",
    "format_option",
    "guard_output",
    "input_paths",
    "is_quiet",
    "is_verbose",
    "note",
    "note_after",
    "output_option",
    "progress",
    "verbosity",
    "verbosity_options",
    "warn",
]


FORMATS = ("table", "json", "csv")


def output_option(f):
    """-o/--output FILE: results go there (atomically) instead of stdout."""
    return click.option(
        "-o",
        "--output",
        type=click.Path(dir_okay=False),
        default=None,
        help="Write here (atomically) instead of stdout; - is stdout. Refused: a link, a "
        "directory, a device or an input file.",
    )(f)


def format_choice(choices: tuple[str, ...] = FORMATS, default: str = "table"):
    """A ``--format`` option with the given choices (the command's output formats)."""

    def deco(f):
        return click.option(
            "--format",
            "fmt",
            type=click.Choice(choices),
            default=default,
            show_default=True,
            help="Output format.",
        )(f)

    return deco


format_option = format_choice()


def debug_option(f):
    """--debug on every command (also accepted before the command name)."""

    @click.option("--debug", is_flag=True, help="Show tracebacks of errors.")
    @functools.wraps(f)
    def wrapper(*args, debug: bool, **kw):
        ctx = click.get_current_context()
        if debug:
            ctx.find_root().meta["rangekit.debug"] = True
        guard_output(ctx, kw)
        return f(*args, **kw)

    return wrapper


#: ``ctx.find_root().meta`` key of the verbosity: -1 quiet, 0 normal, 1 verbose.
VERBOSITY_KEY = "rangekit.verbosity"


def verbosity_options(f):
    """``-q/--quiet`` and ``-v/--verbose`` on a command (one decorator for every verb).

    The flags are not passed to the command: it asks :func:`verbosity`, :func:`is_quiet`
    or :func:`is_verbose`, and writes to stderr through :func:`note` (dropped by
    ``--quiet``), :func:`detail` (only with ``--verbose``: what was chosen, e.g. the
    detector, the template, where the setup came from), :func:`note_after` (a note printed
    after the results) and :func:`warn` (always: a caveat about the results). Progress
    bars from :func:`progress` are off with ``--quiet``. Both flags at once are a usage
    error (exit 2). Errors are reported whatever the verbosity.
    """

    @click.option(
        "-q",
        "--quiet",
        "quiet",
        is_flag=True,
        help="No notes or progress on stderr (errors and warnings are still shown).",
    )
    @click.option(
        "-v",
        "--verbose",
        "verbose",
        is_flag=True,
        help="Also say on stderr what was chosen (detector, template, setup source, ...).",
    )
    @functools.wraps(f)
    def wrapper(*args, quiet: bool, verbose: bool, **kw):
        if quiet and verbose:
            raise click.UsageError("--quiet and --verbose exclude each other")
        ctx = click.get_current_context()
        ctx.find_root().meta[VERBOSITY_KEY] = -1 if quiet else (1 if verbose else 0)
        return f(*args, **kw)

    return wrapper


def verbosity() -> int:
    """-1 with ``--quiet``, 1 with ``--verbose``, 0 otherwise (or outside a command)."""
    ctx = click.get_current_context(silent=True)
    return 0 if ctx is None else int(ctx.find_root().meta.get(VERBOSITY_KEY, 0))


def is_quiet() -> bool:
    """Whether ``--quiet`` was given."""
    return verbosity() < 0


def is_verbose() -> bool:
    """Whether ``--verbose`` was given."""
    return verbosity() > 0


def note(msg: str) -> None:
    """A note on stderr (what was written, how long it took); dropped by ``--quiet``."""
    if not is_quiet():
        click.echo(msg, err=True)


def detail(msg: str) -> None:
    """What was chosen, on stderr, only with ``--verbose``."""
    if is_verbose():
        click.echo(msg, err=True)


def warn(msg: str) -> None:
    """A caveat about the results, on stderr, shown even with ``--quiet``."""
    click.echo(msg, err=True)


def note_after(msg: str) -> None:
    """A note printed on stderr after the command's results (dropped by ``--quiet``)."""
    if is_quiet():
        return
    ctx = click.get_current_context(silent=True)
    if ctx is None:
        click.echo(msg, err=True)
    else:
        ctx.find_root().meta.setdefault("rangekit.notes", []).append(msg)


def progress(total: float, label: str, *, unit: str = ""):
    """A :class:`~rangekit_cli._progress.Progress` on stderr, or a silent one.

    Shown on a terminal; off with ``--quiet`` and when stderr is not a terminal (a log,
    a pipe), except with ``--verbose``, which writes a plain line every 30 s there.
    """
    import sys

    from rangekit_cli._progress import Progress

    tty = bool(getattr(sys.stderr, "isatty", lambda: False)())
    on = not is_quiet() and (tty or is_verbose())
    return Progress(total, label, unit=unit, tty=tty, interval_s=None if on else math.inf)


def input_paths(ctx: click.Context, kw: dict) -> list[str]:
    """Every path the command reads: its arguments and its ``click.Path`` options other
    than ``-o`` (``a.wav+b.wav@0.5`` counts as ``a.wav`` and ``b.wav``)."""
    import re

    out: list[str] = []
    for p in ctx.command.params:
        if p.name == "output" or p.name not in kw:
            continue
        if not (isinstance(p, click.Argument) or isinstance(p.type, click.Path)):
            continue
        v = kw[p.name]
        for item in v if isinstance(v, (list, tuple)) else (v,):
            if isinstance(item, str):
                out.append(item)
                out.extend(t for t in re.split(r"[+@]", item) if t and t != item)
    return out


def check_outputs(paths) -> None:
    """:func:`rangekit.io.guard.check_output` for every file a command derives from
    ``-o`` (``synth``: ``NAME.json``, ``NAME_devI.wav``) against the command's inputs."""
    from rangekit.io.guard import check_output

    ctx = click.get_current_context()
    inputs = input_paths(ctx, ctx.params)
    for p in paths:
        check_output(p, inputs)


def _one_stdin(ctx: click.Context, kw: dict) -> None:
    """Usage error when ``-`` (standard input) is given for more than one input."""
    dashes = [p for p in input_paths(ctx, kw) if p == "-"]
    if len(dashes) > 1:
        raise click.UsageError(
            "- (standard input) is given for more than one input: a command reads standard "
            "input once; give the other inputs as files"
        )


def guard_output(ctx: click.Context, kw: dict) -> None:
    """Check ``-o`` before any work (every command, through :func:`debug_option`).

    At most one input may be ``-`` (standard input is read once; a usage error else).

    ``-o -`` is standard output (``kw["output"]`` becomes None) where ``-o`` is
    optional, a usage error where the command must write a file. Otherwise the output
    must not be a symbolic link, a directory, a device or a FIFO, nor the same file as
    any input (:func:`rangekit.io.guard.check_output`; exit 2), and its folder must exist
    (exit 3).
    """
    _one_stdin(ctx, kw)
    out = kw.get("output")
    if out is None:
        return
    param = next((p for p in ctx.command.params if p.name == "output"), None)
    if out == "-":
        if param is not None and not param.required:
            kw["output"] = None
            return
        raise click.UsageError(
            "-o - (standard output) is not possible here: this command writes a file"
        )
    from rangekit.io.guard import check_output

    check_output(out, input_paths(ctx, kw))


def emit(text: str, output: str | None) -> None:
    """Write results to ``output`` atomically, or to stdout (None or ``-``)."""
    from rangekit.io.guard import printable

    text = printable(text)  # a non-UTF-8 file name must not break the output
    if output is None or output == "-":
        click.echo(text, nl=not text.endswith("\n"))
    else:
        from rangekit.io.sidecar import write_text_atomic

        write_text_atomic(output, text)
