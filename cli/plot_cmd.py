"""``rangekit plot``: pictures of what happened (PNG, PDF or SVG by the output's suffix)."""

from __future__ import annotations

import math

import click
from rangekit_cli._options import (
    FiniteRange,
    beep_options,
    debug_option,
    detail,
    detector_option,
    load_template,
    make_beep,
    note,
    refuse_beep_options,
    speed_of_sound_option,
    temperature_option,
    template_option,
    verbosity_options,
)
from rangekit_cli.ultrasonic_options import ultrasonic_options, ultrasonic_setup


def _output(f):
    """-o/--output FILE (required): the figure; its suffix picks the format."""
    return click.option(
        "-o",
        "--output",
        type=click.Path(dir_okay=False),
        required=True,
        help="Figure to write: .png, .pdf or .svg (written atomically).",
    )(f)


def _channel_option(f):
    return click.option(
        "--channel",
        type=click.IntRange(min=0),
        default=0,
        show_default=True,
        help="Channel of the recording to show, from 0.",
    )(f)


def _start(output: str):
    """Check the output before any work; returns the path."""
    from rangekit.plot import check_figure_path

    return check_figure_path(output)


def _read_channel(recording: str, channel: int):
    """One channel of a recording, with a one-line error when it does not exist."""
    from rangekit.errors import IncompatibleInputError
    from rangekit.io.audio import read_audio

    x, fs = read_audio(recording)
    if channel >= x.shape[1]:
        raise IncompatibleInputError(
            f"'{recording}' has {x.shape[1]} channel(s): --channel {channel} does not exist "
            f"(0..{x.shape[1] - 1})"
        )
    return x, fs


def _done(output: str, what: str) -> None:
    note(f"wrote {output} ({what})")


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


def _window_option(name: str, dest: str, help: str):
    return click.option(name, dest, type=FiniteRange(min=0.0), default=None, metavar="X", help=help)


@plot.command("spectrogram")
@click.argument("recording", type=click.Path(dir_okay=True), metavar="REC.wav")
@_channel_option
@detector_option
@template_option
@beep_options
@_window_option("--t0", "t0_s", "Start of the time window to show, s [default: 0].")
@_window_option("--t1", "t1_s", "End of the time window to show, s [default: the recording's end].")
@_window_option("--fmin", "fmin_hz", "Lowest frequency to show, Hz [default: 0].")
@_window_option("--fmax", "fmax_hz", "Highest frequency to show, Hz [default: fs/2].")
@_output
@verbosity_options
@debug_option
def spectrogram_cmd(
    recording, channel, detector, template, t0_s, t1_s, fmin_hz, fmax_hz, output, **beep_kw
):
    """STFT spectrogram (dB) of one channel, with the detected onsets marked.

    The onsets are those `rangekit detect` prints for that channel (same detector, beep
    options or --template); a channel without any is drawn without marks. --t0/--t1 and
    --fmin/--fmax zoom into a long recording (the STFT is computed on the window only).

    \b
    Examples:
      rangekit plot spectrogram x.wav -o x.png
      rangekit plot spectrogram x.wav --t0 0.1 --t1 0.3 --fmin 14000 --fmax 18000 -o zoom.png
      rangekit plot spectrogram sw.wav --template sweep.wav -o sw.png
    """
    import numpy as np

    from rangekit.io.audio import Channel
    from rangekit.plot.figures import plot_spectrogram
    from rangekit.ranging.pipeline import detect_channel

    _start(output)
    probe = load_template(template)
    if probe is not None:
        refuse_beep_options(beep_kw)
        if click.get_current_context().get_parameter_source("detector") == (
            click.core.ParameterSource.COMMANDLINE
        ):
            raise click.UsageError(
                "--detector applies to the built-in beep; --template uses the matched filter"
            )
    beep = make_beep(beep_kw)
    method = "template" if probe is not None else detector
    x, fs = _read_channel(recording, channel)
    src = f"{recording}#{channel}"
    ch = Channel(np.ascontiguousarray(x[:, channel]), fs, src)
    detail(f"rangekit: plot spectrogram: {src}, onsets by {method}")
    arr = detect_channel(ch, beep=beep, detector=detector, probe=probe)
    what = "beep onset(s)" if probe is None else f"arrival(s) of '{probe.name}'"
    out = plot_spectrogram(
        ch.x,
        output,
        fs=fs,
        onsets=arr.onset,
        title=f"{src}: {len(arr)} {what}, {method} detector",
        label=f"onset ({method})",
        t0_s=t0_s,
        t1_s=t1_s,
        fmin_hz=fmin_hz,
        fmax_hz=fmax_hz,
    )
    shown = len(out.onsets_s)
    inside = f", {shown} in the window" if shown != len(arr) else ""
    _done(output, f"{len(arr)} onset(s) marked{inside}")


@plot.command("matched")
@click.argument("recording", type=click.Path(dir_okay=True), metavar="REC.wav")
@click.option(
    "--scheme",
    type=click.Choice(["oneway", "echo"]),
    required=True,
    help="oneway = RF-synchronised beacons (sample 0 = trigger); echo = SRF02 pulse-echo.",
)
@_channel_option
@click.option(
    "--window",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="Activation window (oneway) or ranging cycle (echo) to show, from 0 (see --period).",
)
@temperature_option
@speed_of_sound_option()
@ultrasonic_options
@_output
@verbosity_options
@debug_option
def matched_cmd(recording, scheme, channel, window, temp_c, speed, output, **kw):
    """Matched-filter envelope of one channel and window, with the chosen first path.

    The options are those of `rangekit range --scheme oneway|echo`; the marked path is
    the one that command reports for this channel and window (its distance in the title).
    """
    from rangekit.errors import IncompatibleInputError
    from rangekit.plot.figures import plot_matched
    from rangekit.ranging.config import Medium
    from rangekit.ranging.ultrasonic import matched_trace
    from rangekit.signals.barker import check_burst_fits

    _start(output)
    args = ultrasonic_setup(kw, scheme=scheme).kwargs()
    args.update(Medium(temp_c=temp_c, speed_m_s=speed).kwargs())
    burst = args.pop("burst")
    want = args.pop("channels")
    x, fs = _read_channel(recording, channel)
    if want is not None and x.shape[1] != want:
        raise IncompatibleInputError(
            f"'{recording}' has {x.shape[1]} channel(s) but {want} are expected "
            f"({'one per receiver' if scheme == 'oneway' else 'one per sensor'}; see --channels)"
        )
    check_burst_fits(burst, fs=fs, what=f"'{recording}'")
    try:
        trace = matched_trace(
            x.T,
            fs=fs,
            scheme=scheme,
            channel=channel,
            window=window,
            burst=burst.with_fs(fs),
            **args,
        )
    except IncompatibleInputError as e:
        hint = " (see --period)" if "window" in str(e) else ""
        raise IncompatibleInputError(f"'{recording}': {e}{hint}") from e
    plot_matched(trace, output)
    tof = trace.tof
    found = f"{tof.distance_m:.4f} m" if math.isfinite(tof.distance_m) else "nothing detected"
    _done(output, f"channel {channel}, window {window}: {found}")


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
@_output
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
    import numpy as np

    from rangekit.plot.figures import plot_ranges, truth_for
    from rangekit.plot.inputs import read_range_series

    _start(output)
    true = _read_truth(truth)
    s = read_range_series(series)
    n = sum(int(np.isfinite(x.distance_m).sum()) for x in s)
    by_key = truth_for(s, true)
    if truth is not None and not by_key:
        from rangekit.errors import IncompatibleInputError

        raise IncompatibleInputError(
            f"'{truth}' has no true distance for any series of '{series}' "
            f"(series {', '.join(x.key for x in s)})"
        )
    plot_ranges(s, output, title=f"{series}: {len(s)} series, {n} ranges", truth=true)
    what = f"{len(s)} series, {n} ranges"
    if truth is not None:
        err = np.concatenate([np.abs(x.distance_m - by_key[x.key]) for x in s if x.key in by_key])
        sig = np.concatenate([x.sigma_m for x in s if x.key in by_key])
        ok = np.isfinite(err)
        if ok.any():
            within = float(np.mean(err[ok] <= 2 * sig[ok]))
            what += (
                f"; against the truth: median |error| {1e3 * np.median(err[ok]):.1f} mm, "
                f"{100 * within:.0f} % within 2 sigma"
            )
    _done(output, what)


def _read_truth(text: str | None):
    """--truth: a distance in metres, or {pair key: distance} from a synth sidecar."""
    if text is None:
        return None
    try:
        v = float(text)
    except ValueError:
        pass
    else:
        if not (math.isfinite(v) and v >= 0):
            raise click.BadParameter(
                f"{text!r} must be a distance >= 0 in metres or a JSON file", param_hint="--truth"
            )
        return v
    from rangekit.errors import InputFileError, InvalidParameterError
    from rangekit.io.sidecar import read_json

    try:
        obj = read_json(text)  # guarded: regular file, size, nesting, finite numbers
    except InputFileError as e:
        if "JSON" in str(e) or "not UTF-8" in str(e):
            raise InvalidParameterError(f"--truth '{text}' is not JSON: {e}") from None
        raise
    pairs = obj.get("pairs") if isinstance(obj, dict) else None
    try:
        return {f"{int(p['a'])}-{int(p['b'])}": float(p["distance_m"]) for p in pairs}
    except (TypeError, KeyError, ValueError):
        raise InvalidParameterError(
            f"--truth '{text}' has no \"pairs\" list of {{a, b, distance_m}} (a sidecar "
            "of `rangekit synth beepbeep`)"
        ) from None


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
@_output
@verbosity_options
@debug_option
def track_cmd(track, map_path, truth, ellipses, output):
    """Trajectories with 2-sigma covariance ellipses over the floor plan.

    TRACK is the output of `rangekit track` (CSV or its JSON): x_m, y_m, optional
    target; ellipses from var_x_m2, var_y_m2 (cov_xy_m2) or sigma_x_m, sigma_y_m; circles
    of radius spread_m when only that is given (particle filter).
    """
    from rangekit.plot.figures import plot_track
    from rangekit.plot.inputs import read_track

    _start(output)
    plan = None
    if map_path is not None:
        from rangekit.floorplan import load_floorplan

        plan = load_floorplan(map_path)
    paths = read_track(track)
    true = read_track(truth) if truth is not None else ()
    out = plot_track(paths, output, plan=plan, truth=true, every=ellipses, title=str(track))
    n_pts = sum(len(v) for v in out.xy_m.values())
    n_ell = sum(len(v) for v in out.ellipse_rows.values())
    _done(output, f"{len(paths)} track(s), {n_pts} points, {n_ell} ellipses/circles")


@plot.command("cdf")
@click.argument("results", type=click.Path(dir_okay=True), metavar="RESULTS.csv|jsonl")
@click.option(
    "--by",
    default=None,
    metavar="COLUMN",
    help="One curve per value of this column (e.g. scheme) [default: one curve].",
)
@_output
@verbosity_options
@debug_option
def cdf_cmd(results, by, output):
    """Empirical CDF of the absolute range error across a batch, median and p90 in the legend.

    RESULTS rows need distance_m and true_distance_m; rows where either is empty (null),
    or whose status is not "ok", are skipped and counted in the title.
    """
    from rangekit.plot.figures import plot_cdf
    from rangekit.plot.inputs import read_batch_errors

    _start(output)
    batch = read_batch_errors(results, by=by)
    plot_cdf(batch, output)
    used = batch.n_rows - batch.n_skipped
    _done(output, f"{len(batch.errors_m)} curve(s), {used} rows, {batch.n_skipped} skipped")
