"""Verbosity options of every command (``-q/--quiet``, ``-v/--verbose``) and what they
govern: the notes, details and warnings on stderr, and the progress bars."""

from __future__ import annotations

import functools
import math

import click

__all__ = [
    "VERBOSITY_KEY",
    "detail",
    "is_quiet",
    "is_verbose",
    "note",
    "note_after",
    "progress",
    "verbosity",
    "verbosity_options",
    "warn",
]


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
