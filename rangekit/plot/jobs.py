"""One call per figure of ``rangekit plot``: read the inputs, compute, draw, write.

Each function takes the paths the command takes (``-`` is standard input where a
recording or a table is read) and the library's configuration objects, writes the figure
(format by the output's suffix) and returns what it drew with the counts the command
reports. ``rangekit plot`` only parses its options into these calls, so a figure made
from Python equals the command's (tests/plot/test_jobs.py).

Examples
--------
>>> import pathlib, tempfile
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> _ = (d / "s.csv").write_text("t_s,a,b,distance_m,sigma_m\\n0,0,1,2.5,0.01\\n1,0,1,2.51,0.01\\n")
>>> fig = ranges_figure(d / "s.csv", d / "r.png", truth=2.5)
>>> fig.n_ranges, round(fig.agreement.median_abs_error_m, 3)
(2, 0.005)
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from rangekit.errors import IncompatibleInputError

__all__ = [
    "RangesFigure",
    "SpectrogramFigure",
    "cdf_figure",
    "matched_figure",
    "ranges_figure",
    "read_channel",
    "spectrogram_figure",
    "track_figure",
]


def _name(path: str | os.PathLike) -> str:
    return os.fspath(path)


def read_channel(recording: str | os.PathLike, channel: int) -> tuple[np.ndarray, float]:
    """The samples (all channels, shape (samples, channels)) and rate of ``recording``
    (``-``: standard input), refused when ``channel`` does not exist.

    Raises
    ------
    IncompatibleInputError
        The recording has no channel ``channel`` (the message gives the valid range).
    """
    from rangekit.io.audio import read_audio

    x, fs = read_audio(recording)
    if channel >= x.shape[1]:
        raise IncompatibleInputError(
            f"'{_name(recording)}' has {x.shape[1]} channel(s): --channel {channel} does not "
            f"exist (0..{x.shape[1] - 1})"
        )
    return x, fs


@dataclass(frozen=True)
class SpectrogramFigure:
    """What :func:`spectrogram_figure` drew.

    Attributes
    ----------
    source : str
        ``FILE#CHANNEL``.
    method : str
        The detector that marked the onsets (``"template"`` with a probe).
    n_onsets : int
        Onsets detected on the channel (all of them, inside the window or not).
    plot : rangekit.plot.figures.SpectrogramPlot
        The drawn spectrogram, with the onsets inside the window.
    """

    source: str
    method: str
    n_onsets: int
    plot: object


def spectrogram_figure(
    recording: str | os.PathLike,
    output: str | os.PathLike,
    *,
    channel: int = 0,
    beep=None,
    detector: str = "changepoint",
    probe=None,
    t0_s: float | None = None,
    t1_s: float | None = None,
    fmin_hz: float | None = None,
    fmax_hz: float | None = None,
) -> SpectrogramFigure:
    """STFT spectrogram of one channel with the onsets ``rangekit detect`` finds there.

    Parameters
    ----------
    recording : path-like
        The recording (``-``: standard input).
    output : path-like
        The figure (``.png``, ``.pdf``, ``.svg``).
    channel : int
        Channel to show, from 0.
    beep : rangekit.signals.Beep, optional
        The beep that was played (default ``Beep()``); unused with ``probe``.
    detector : {"changepoint", "xcorr"}
        Arrival detector for the beep.
    probe : rangekit.signals.probe.Probe, optional
        The probe that was played instead (matched filter with first-path selection).
    t0_s, t1_s, fmin_hz, fmax_hz : float, optional
        Time and frequency window (:func:`rangekit.plot.figures.plot_spectrogram`).
    """
    from rangekit.io.audio import Channel
    from rangekit.plot import check_figure_path
    from rangekit.plot.figures import plot_spectrogram
    from rangekit.ranging.pipeline import detect_channel
    from rangekit.signals import Beep

    check_figure_path(output)
    beep = Beep() if beep is None else beep
    method = "template" if probe is not None else detector
    x, fs = read_channel(recording, channel)
    src = f"{_name(recording)}#{channel}"
    ch = Channel(np.ascontiguousarray(x[:, channel]), fs, src)
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
    return SpectrogramFigure(src, method, len(arr), out)


def matched_figure(
    recording: str | os.PathLike,
    output: str | os.PathLike,
    *,
    setup,
    medium=None,
    channel: int = 0,
    window: int = 0,
):
    """Matched-filter envelope of one channel and window with the first path ranging chose.

    Parameters
    ----------
    recording : path-like
        The recording (``-``: standard input); sample 0 = the trigger (one-way) or the
        ping (echo).
    output : path-like
        The figure.
    setup : rangekit.ranging.config.OneWaySetup or EchoSetup
        The job, as for ``rangekit range --scheme oneway|echo``; its type picks the scheme.
    medium : rangekit.ranging.config.Medium, optional
        Speed of sound (default ``Medium()``).
    channel, window : int
        Receiver (sensor) and activation window (ranging cycle), from 0.

    Returns
    -------
    rangekit.ranging.ultrasonic.MatchedTrace
        The drawn trace (``trace.tof``: the path marked, with its distance).

    Raises
    ------
    IncompatibleInputError
        The recording's channel count differs from ``setup.channels``, the burst does
        not fit its rate, or ``channel`` / ``window`` does not exist.
    """
    from rangekit.plot import check_figure_path
    from rangekit.plot.figures import plot_matched
    from rangekit.ranging.config import EchoSetup, Medium
    from rangekit.ranging.ultrasonic import matched_trace
    from rangekit.signals.barker import check_burst_fits

    check_figure_path(output)
    scheme = "echo" if isinstance(setup, EchoSetup) else "oneway"
    args = setup.kwargs()
    args.update((Medium() if medium is None else medium).kwargs())
    burst = args.pop("burst")
    want = args.pop("channels")
    x, fs = read_channel(recording, channel)
    name = _name(recording)
    if want is not None and x.shape[1] != want:
        raise IncompatibleInputError(
            f"'{name}' has {x.shape[1]} channel(s) but {want} are expected "
            f"({'one per receiver' if scheme == 'oneway' else 'one per sensor'}; see --channels)"
        )
    check_burst_fits(burst, fs=fs, what=f"'{name}'")
    try:
        trace = matched_trace(
            x.T, fs=fs, scheme=scheme, channel=channel, window=window, burst=burst.with_fs(fs),
            **args,
        )  # fmt: skip
    except IncompatibleInputError as e:
        hint = " (see --period)" if "window" in str(e) else ""
        raise IncompatibleInputError(f"'{name}': {e}{hint}") from e
    plot_matched(trace, output)
    return trace


@dataclass(frozen=True)
class RangesFigure:
    """What :func:`ranges_figure` drew: the series, their finite ranges and, with a
    truth, how they agree with it (:class:`rangekit.plot.figures.TruthAgreement`)."""

    series: list
    n_ranges: int
    agreement: object | None


def ranges_figure(
    series: str | os.PathLike,
    output: str | os.PathLike,
    *,
    truth: float | str | os.PathLike | Mapping[str, float] | None = None,
) -> RangesFigure:
    """Range time series with ±1/±2 sigma bands, optionally against the truth.

    Parameters
    ----------
    series : path-like
        Output of ``rangekit range --series`` (CSV or JSON; ``-``: standard input).
    output : path-like
        The figure.
    truth : float, path or mapping, optional
        The true distance (m) of every series, a ``rangekit synth beepbeep`` sidecar
        (:func:`rangekit.plot.inputs.read_truth_pairs`), or {series key: m}.

    Raises
    ------
    IncompatibleInputError
        ``truth`` gives no series of ``series`` a true distance.
    """
    from rangekit.plot import check_figure_path
    from rangekit.plot.figures import plot_ranges, truth_agreement, truth_for
    from rangekit.plot.inputs import read_range_series, read_truth_pairs

    check_figure_path(output)
    label = str(truth)
    if truth is not None and not isinstance(truth, (int, float, Mapping)):
        label = _name(truth)
        truth = read_truth_pairs(truth)
    s = read_range_series(series)
    n = sum(int(np.isfinite(x.distance_m).sum()) for x in s)
    if truth is not None and not truth_for(s, truth):
        raise IncompatibleInputError(
            f"'{label}' has no true distance for any series of '{_name(series)}' "
            f"(series {', '.join(x.key for x in s)})"
        )
    plot_ranges(s, output, title=f"{_name(series)}: {len(s)} series, {n} ranges", truth=truth)
    return RangesFigure(s, n, None if truth is None else truth_agreement(s, truth))


def track_figure(
    track: str | os.PathLike,
    output: str | os.PathLike,
    *,
    map_path: str | os.PathLike | None = None,
    truth: str | os.PathLike | None = None,
    every: int = 10,
):
    """Trajectories of a ``rangekit track`` output (``-``: standard input) with 2-sigma
    ellipses every ``every`` rows, over the floor plan ``map_path`` and the true paths
    ``truth``; returns the :class:`rangekit.plot.figures.TrackPlot`."""
    from rangekit.plot import check_figure_path
    from rangekit.plot.figures import plot_track
    from rangekit.plot.inputs import read_track

    check_figure_path(output)
    plan = None
    if map_path is not None:
        from rangekit.floorplan import load_floorplan

        plan = load_floorplan(map_path)
    paths = read_track(track)
    true = read_track(truth) if truth is not None else ()
    return plot_track(paths, output, plan=plan, truth=true, every=every, title=_name(track))


def cdf_figure(results: str | os.PathLike, output: str | os.PathLike, *, by: str | None = None):
    """Empirical CDF of the absolute range error of batch results (``-``: standard input),
    one curve per value of column ``by``; returns the
    :class:`rangekit.plot.inputs.BatchErrors` drawn."""
    from rangekit.plot import check_figure_path
    from rangekit.plot.figures import plot_cdf
    from rangekit.plot.inputs import read_batch_errors

    check_figure_path(output)
    batch = read_batch_errors(results, by=by)
    plot_cdf(batch, output)
    return batch
