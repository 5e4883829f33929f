"""Output options of every command: ``-o`` (checked before any work, ``-`` = standard
output), ``--format`` and ``--debug``, and :func:`emit`, which writes the results. The
verbosity options and the stderr notes are :mod:`rangekit_cli._options_verbosity`."""

from __future__ import annotations

import functools

import click

__all__ = [
    "FORMATS",
    "check_outputs",
    "debug_option",
    "emit",
    "format_choice",
    "format_option",
    "guard_output",
    "input_paths",
    "output_option",
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


def input_paths(ctx: click.Context, kw: dict) -> list[str]:
    """Every path the command reads: its arguments and its ``click.Path`` options other
    than ``-o`` (``a.wav+b.wav@0.5`` counts as ``a.wav`` and ``b.wav``: the files of a
    recording spec, :func:`rangekit.ranging.calibration.recording_paths`)."""
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
                if "+" in item or "@" in item:  # a plain path needs no parser (nor numpy)
                    from rangekit.ranging.calibration import recording_paths

                    out.extend(t for t in recording_paths(item) if t and t != item)
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
