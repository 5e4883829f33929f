"""``rangekit plot``: pictures of what happened (PNG, PDF or SVG by the output's suffix).

The figures of a recording (``spectrogram``, ``matched``) live in
:mod:`rangekit_cli.plot_signal_cmd`; the figures of tables (``ranges``, ``track``,
``cdf``) here. Every command parses its options and calls :mod:`rangekit.plot.jobs`.
"""

from __future__ import annotations

import math

import click
from rangekit_cli._options import debug_option, note, verbosity_options
from rangekit_cli._plot_options import check_figure, figure_output
from rangekit_cli.plot_signal_cmd import matched_cmd, spectrogram_cmd


@click.group("plot")
def plot():
    """Pictures: spectrogram with onsets, matched-filter output, ranges, tracks, error CDFs.

    Every figure goes to -o FILE; the suffix picks the format (.png, .pdf, .svg).

    \b
    Examples:
      rangekit plot spectrogram rec.wav --channel 1 -o rec.png
      rangekit plot matched ow.wav --scheme oneway --period 0.2 --window 3 -o mf.svg
      rangekit plot ranges series.csv -o ranges.pdf
      rangekit plot track track.csv --map plan.json --truth truth.csv -o track.png
      rangekit plot cdf results.jsonl --by scheme -o cdf.png
    """


plot.add_command(spectrogram_cmd)
plot.add_command(matched_cmd)


@plot.command("ranges")
@click.argument("series", type=click.Path(dir_okay=True), metavar="SERIES.csv|json")
@click.option(
    "--truth",
    default=None,
    metavar="M|FILE.json",
    help="The true distance: metres (every series), or the JSON sidecar `rangekit synth "
    "beepbeep` wrote (its pairs' distances, by pair). Drawn as a dashed line; the summary "
    "line counts the ranges within 2 sigma of it.",
)
@figure_output
@verbosity_options
@debug_option
def ranges_cmd(series, truth, output):
    """Range time series with ±1 sigma and ±2 sigma bands, one line per series.

    SERIES is the output of `rangekit range --series` (CSV, or JSON with a "ranges" list):
    columns t_s, distance_m, sigma_m and the key a,b (pairs), tx,channel (oneway) or
    channel (echo). An empty distance is a gap.

    \b
    Examples:
      rangekit plot ranges series.csv -o ranges.png
      rangekit plot ranges series.csv --truth 2.0 -o ranges.png
      rangekit plot ranges series.csv --truth s.json -o ranges.png
    """
    from rangekit.io.notes import ranges_note
    from rangekit.plot.jobs import ranges_figure

    check_figure(output)
    fig = ranges_figure(series, output, truth=_parse_truth(truth))
    note(ranges_note(output, fig))


def _parse_truth(text: str | None) -> float | str | None:
    """--truth: a distance in metres, or the path of a synth sidecar (read by the library)."""
    if text is None:
        return None
    try:
        v = float(text)
    except ValueError:
        return text
    if not (math.isfinite(v) and v >= 0):
        raise click.BadParameter(
            f"{text!r} must be a distance >= 0 in metres or a JSON file", param_hint="--truth"
        )
    return v


@plot.command("track")
@click.argument("track", type=click.Path(dir_okay=True), metavar="TRACK.csv|json")
@click.option(
    "--map",
    "map_path",
    type=click.Path(dir_okay=True),
    default=None,
    metavar="PLAN.json",
    help="Floor plan whose walls are drawn (floorplan.md of the documentation).",
)
@click.option(
    "--truth",
    type=click.Path(dir_okay=True),
    default=None,
    metavar="TRUTH.csv",
    help="True path(s): columns x_m, y_m (and target), drawn dashed.",
)
@click.option(
    "--ellipses",
    type=click.IntRange(min=0),
    default=10,
    show_default=True,
    metavar="N",
    help="A 2-sigma covariance ellipse every N rows of each target (0: none).",
)
@figure_output
@verbosity_options
@debug_option
def track_cmd(track, map_path, truth, ellipses, output):
    """Trajectories with 2-sigma covariance ellipses over the floor plan.

    TRACK is the output of `rangekit track` (CSV or its JSON): x_m, y_m, optional
    target; ellipses from var_x_m2, var_y_m2 (cov_xy_m2) or sigma_x_m, sigma_y_m; circles
    of radius spread_m when only that is given (particle filter).
    """
    from rangekit.io.notes import track_figure_note
    from rangekit.plot.jobs import track_figure

    check_figure(output)
    out = track_figure(track, output, map_path=map_path, truth=truth, every=ellipses)
    note(track_figure_note(output, out))


@plot.command("cdf")
@click.argument("results", type=click.Path(dir_okay=True), metavar="RESULTS.csv|jsonl")
@click.option(
    "--by",
    default=None,
    metavar="COLUMN",
    help="One curve per value of this column (e.g. scheme) [default: one curve].",
)
@figure_output
@verbosity_options
@debug_option
def cdf_cmd(results, by, output):
    """Empirical CDF of the absolute range error across a batch, median and p90 in the legend.

    RESULTS rows need distance_m and true_distance_m; rows where either is empty (null),
    or whose status is not "ok", are skipped and counted in the title.
    """
    from rangekit.io.notes import cdf_note
    from rangekit.plot.jobs import cdf_figure

    check_figure(output)
    batch = cdf_figure(results, output, by=by)
    note(cdf_note(output, batch))
