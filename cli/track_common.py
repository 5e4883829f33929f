"""Options and output shared by the ``rangekit track`` subcommands (written once here).

Every option defaults to None: the value used when it is not given is the library's
default, and the help text shows that default read from the library (:func:`default`).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable

import click
from rangekit_cli._options import (
    FiniteRange,
    debug_option,
    detail,
    emit,
    float_list,
    format_choice,
    note,
    output_option,
    shown_default,
    verbosity_options,
    warn,
)


def default(fn: Callable, name: str):
    """The default of keyword ``name`` of the library function ``fn`` (for help texts)."""
    return inspect.signature(fn).parameters[name].default


def log_argument(metavar: str = "LOG.csv", required: bool = True):
    """The subcommand's input log (a path; read and checked by the library)."""
    return click.argument("log", type=click.Path(dir_okay=True), metavar=metavar, required=required)


def smooth_option(f):
    """--smooth: the RTS-smoothed (offline) track instead of the causal filter's."""
    return click.option(
        "--smooth",
        is_flag=True,
        default=None,
        help="Output the RTS-smoothed (offline) track instead of the causal filter's.",
    )(f)


def gate_options(library_default: float | None, per: str = ""):
    """--gate P / --no-gate; ``library_default`` is the gate used without either."""
    shown = "no gate" if library_default is None else f"{library_default:g}{per}"

    def deco(f):
        f = click.option(
            "--no-gate",
            "no_gate",
            is_flag=True,
            default=None,
            help="Use every measurement (no innovation gate).",
        )(f)
        return click.option(
            "--gate",
            type=FiniteRange(0.0, 1.0, min_open=True, max_open=True),
            default=None,
            metavar="P",
            help="Innovation gate probability in (0, 1): measurements beyond this "
            f"chi-square quantile are rejected {shown_default(shown)}.",
        )(f)

    return deco


def gate_value(gate: float | None, no_gate: bool | None) -> dict:
    """Keyword ``gate`` for the library: {} (its default), None (no gate) or the value."""
    if gate is not None and no_gate:
        raise click.UsageError("--gate and --no-gate exclude each other")
    if no_gate:
        return {"gate": None}
    return {} if gate is None else {"gate": gate}


def rig_option(help: str):
    """--rig RIG.json (rigs.md of the documentation)."""
    return click.option(
        "--rig", type=click.Path(dir_okay=True), default=None, metavar="RIG.json", help=help
    )


def initial_pose_option(help: str):
    """--initial-pose X,Y,DEG."""
    return click.option(
        "--initial-pose", "initial_pose", default=None, metavar="X,Y,DEG", help=help
    )


def output_options(f):
    """--format csv|json|table, -o/--output, -q/--quiet, -v/--verbose, --debug: every
    track subcommand writes a track, a summary (dropped by --quiet) and its warnings."""
    return format_choice(("table", "json", "csv"), "csv")(
        output_option(verbosity_options(debug_option(f)))
    )


def parse_pose(text: str | None, n: int) -> list[float] | None:
    """``--initial-pose``: ``X,Y,DEG`` as ``[x_m, y_m, heading_rad]`` (n=3) or ``X,Y`` (n=2)."""
    vals = float_list(text, name="--initial-pose")
    if vals is None:
        return None
    if len(vals) != n:
        want = "X,Y,DEG (m, m, degrees)" if n == 3 else "X,Y (m)"
        raise click.BadParameter(
            f"{text!r} must be {n} numbers {want}, got {len(vals)}", param_hint="--initial-pose"
        )
    return [vals[0], vals[1], math.radians(vals[2])] if n == 3 else vals


def write_report(report, fmt: str, output: str | None) -> None:
    """Print (or write to ``-o``) the track of a :class:`rangekit.io.tracks.TrackReport`
    as CSV, a table or JSON, then its summary (a note, dropped by ``--quiet``) and its
    warnings (always); with ``--verbose`` first the parameters used (the library's
    defaults filled in)."""
    if report.parameters:
        detail(f"rangekit: track {report.filter_name}: {report.parameters_text()}")
    emit(report.format(fmt), output)
    if report.summary:
        note(report.summary)
    for msg in report.warnings:
        warn(f"warning: {msg}")
