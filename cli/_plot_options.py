"""Options and helpers shared by the ``rangekit plot`` commands."""

from __future__ import annotations

import click


def figure_output(f):
    """-o/--output FILE (required): the figure; its suffix picks the format."""
    return click.option(
        "-o",
        "--output",
        type=click.Path(dir_okay=False),
        required=True,
        help="Figure to write: .png, .pdf or .svg (written atomically).",
    )(f)


def channel_option(f):
    return click.option(
        "--channel",
        type=click.IntRange(min=0),
        default=0,
        show_default=True,
        help="Channel of the recording to show, from 0.",
    )(f)


def check_figure(output: str):
    """Check the output before any work; returns the path."""
    from rangekit.plot import check_figure_path

    return check_figure_path(output)
