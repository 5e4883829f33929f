"""The one-line notes for people that ``design``, ``synth`` and ``plot`` print on stderr.

Each command writes files and then says what it wrote: ``wrote FILE (...)``, with the
numbers a person checks at a glance. The lines are built here from the library's results
(the signal designed, the :class:`~rangekit.sim.scenarios.Synthesis`, the figure drawn),
so that the command only prints them and a run from Python can say the same.

With ``--verbose``, ``range``, ``detect``, ``calibrate``, ``locate`` and ``batch`` first say
what the run uses (:func:`range_detail`, :func:`detect_detail`, :func:`calibrate_detail`,
:func:`locate_detail`, :func:`batch_details`), built here from the job's configuration objects
(:class:`~rangekit.physics.Medium`, :class:`~rangekit.ranging.config.TwoWaySetup`,
:class:`~rangekit.batch.BatchOptions`) in the same way.

The numbers, the same in every note:

* frequencies and sample rates in Hz with up to six significant digits (``16000 Hz``,
  ``44100 Hz``; :func:`rangekit.io.results.format_value`), band edges in kHz to 10 Hz;
* durations in ms to 0.1 ms (bursts, spacing, fades), us to 0.1 us (a coded burst), s
  to 1 ms (a beep) or as given (a sweep);
* true distances of a simulation in m to 0.1 mm (``2.0000 m``), the SRF02 model's range
  to 1 mm (it reports whole centimetres); a distance ranged from a recording in m to
  0.1 mm;
* agreement with the truth as a median absolute error in mm to 0.1 mm and a whole
  percentage;
* what a run uses (temperature, speed of sound, self-distances, a distance sigma) by
  :func:`~rangekit.io.results.format_value`, except the speed of sound a calibration
  fits with, to 0.01 m/s (``c = 343.29 m/s``).

Examples
--------
>>> from rangekit.signals import Beep
>>> beep_note("beep.wav", Beep(), fs=48000.0)
'wrote beep.wav: 4 x 16000 Hz bursts of 10.0 ms, 113.4 ms apart, 0.350 s at 48000 Hz'
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from rangekit.errors import InvalidParameterError
from rangekit.io.results import format_value

__all__ = [
    "batch_details",
    "beep_note",
    "burst_note",
    "calibrate_detail",
    "cdf_note",
    "detect_detail",
    "locate_detail",
    "matched_note",
    "range_detail",
    "ranges_note",
    "spectrogram_note",
    "sweep_note",
    "synthesis_note",
    "track_figure_note",
    "wrote",
]


def wrote(output: str | os.PathLike, what: str) -> str:
    """``wrote OUTPUT (WHAT)``: the note of a figure.

    >>> wrote("r.png", "1 series, 5 ranges")
    'wrote r.png (1 series, 5 ranges)'
    """
    return f"wrote {os.fspath(output)} ({what})"


# ---------------------------------------------------------------------------- design


def beep_note(output: str | os.PathLike, beep, *, fs: float) -> str:
    """The note of ``rangekit design beep``: the :class:`~rangekit.signals.Beep` written to
    ``output`` at the file's rate ``fs`` (Hz)."""
    return (
        f"wrote {os.fspath(output)}: {beep.n_bursts} x {format_value(beep.f_hz)} Hz bursts of "
        f"{beep.burst_s * 1e3:.1f} ms, {beep.spacing_s * 1e3:.1f} ms apart, "
        f"{beep.duration_s:.3f} s at {format_value(fs)} Hz"
    )


def burst_note(output: str | os.PathLike, burst) -> str:
    """The note of ``rangekit design barker``: the
    :class:`~rangekit.signals.barker.CodedBurst` written to ``output`` at its rate.

    >>> from rangekit.signals.barker import CodedBurst
    >>> burst_note("b.wav", CodedBurst())
    'wrote b.wav: code +++--+- on 40000 Hz, 3 cycles per chip, 525.0 us at 192000 Hz'
    """
    chips = "".join("+" if c > 0 else "-" for c in burst.code)
    return (
        f"wrote {os.fspath(output)}: code {chips} on {format_value(burst.carrier_hz)} Hz, "
        f"{burst.cycles_per_bit} cycles per chip, {burst.duration_s * 1e6:.1f} us at "
        f"{format_value(burst.fs)} Hz"
    )


def sweep_note(
    output: str | os.PathLike,
    probe,
    *,
    f0_hz: float,
    f1_hz: float,
    duration_s: float,
    fade_s: float | None = None,
) -> str:
    """The note of ``rangekit design sweep``: the
    :class:`~rangekit.signals.probe.Probe` that :func:`~rangekit.signals.probe.linear_sweep`
    made of these arguments (``fade_s`` None: its default fade), and the band holding
    99.9 % of its energy.

    >>> from rangekit.signals.probe import linear_sweep
    >>> sweep_note("s.wav", linear_sweep(17000.0, 20000.0, 0.1), f0_hz=17000.0,
    ...            f1_hz=20000.0, duration_s=0.1)  # doctest: +NORMALIZE_WHITESPACE
    'wrote s.wav: linear sweep 17000-20000 Hz, 0.1 s (4410 samples at 44100 Hz), fades
    5.0 ms, 99.9 % of the energy in 16.98-20.02 kHz'
    """
    from rangekit.signals.probe import sweep_fade_s

    lo, hi = probe.band_hz()
    fade = sweep_fade_s(duration_s) if fade_s is None else fade_s
    return (
        f"wrote {os.fspath(output)}: linear sweep {format_value(f0_hz)}-{format_value(f1_hz)} "
        f"Hz, {format_value(duration_s)} s ({len(probe.samples)} samples at "
        f"{format_value(probe.fs)} Hz), fades {fade * 1e3:.1f} ms, 99.9 % of the energy in "
        f"{lo / 1e3:.2f}-{hi / 1e3:.2f} kHz"
    )


# ----------------------------------------------------------------------------- synth


def synthesis_note(syn, output: str | os.PathLike) -> str:
    """The note of ``rangekit synth beepbeep|oneway|echo``: the files a
    :class:`~rangekit.sim.scenarios.Synthesis` wrote for ``output`` and the truth a
    person checks first: each pair's distance (beepbeep), the windows, receivers and
    the ``--tx-order`` to range with (oneway), the SRF02 model's range per cycle (echo,
    ``-`` out of range).
    """
    out = Path(output)
    truth = syn.sidecar(out)
    sidecar = out.with_suffix(".json").name
    scheme = truth.get("scheme")
    if scheme == "beepbeep":
        pairs = ", ".join(f"{p['a']}-{p['b']}: {p['distance_m']:.4f} m" for p in truth["pairs"])
        return f"wrote {', '.join(truth['files'])} and {sidecar} ({pairs})"
    if scheme == "oneway":
        n_tx = len(truth["setup"]["tx_order"])  # the transmitters fired, ids 0..n_tx - 1
        return (
            f"wrote {out.name} ({len(truth['windows'])} windows x {syn.recordings[0].shape[1]} "
            f"receivers), {sidecar} and {truth['beacons']} (Tx ids 0-{n_tx - 1} in firing "
            f"order: range with --tx-order {','.join(str(i) for i in range(n_tx))})"
        )
    if scheme == "echo":
        ranges = ", ".join(
            "-" if w["distance_m"] is None else f"{w['distance_m']:.3f} m" for w in truth["windows"]
        )
        return f"wrote {out.name} and {sidecar} (model: {ranges})"
    raise InvalidParameterError(
        f"scheme={scheme!r} of the synthesis must be beepbeep, oneway or echo"
    )


# ------------------------------------------------------------------------------ plot


def spectrogram_note(output: str | os.PathLike, fig) -> str:
    """The note of ``rangekit plot spectrogram``: the onsets marked
    (a :class:`~rangekit.plot.jobs.SpectrogramFigure`), and how many of them the time
    window shows when it does not show all."""
    shown = len(fig.plot.onsets_s)
    inside = f", {shown} in the window" if shown != fig.n_onsets else ""
    return wrote(output, f"{fig.n_onsets} onset(s) marked{inside}")


def matched_note(output: str | os.PathLike, trace, *, channel: int, window: int) -> str:
    """The note of ``rangekit plot matched``: the distance of the path marked in the
    :class:`~rangekit.ranging.ultrasonic.MatchedTrace` of ``channel`` and ``window``."""
    d = trace.tof.distance_m
    found = f"{d:.4f} m" if math.isfinite(d) else "nothing detected"
    return wrote(output, f"channel {channel}, window {window}: {found}")


def ranges_note(output: str | os.PathLike, fig) -> str:
    """The note of ``rangekit plot ranges``: series and ranges drawn (a
    :class:`~rangekit.plot.jobs.RangesFigure`) and, with a truth, the median absolute
    error and the share of ranges within 2 sigma of it."""
    what = f"{len(fig.series)} series, {fig.n_ranges} ranges"
    agree = fig.agreement
    if agree is not None and agree.n:
        what += (
            f"; against the truth: median |error| {1e3 * agree.median_abs_error_m:.1f} mm, "
            f"{100 * agree.within_2sigma:.0f} % within 2 sigma"
        )
    return wrote(output, what)


def track_figure_note(output: str | os.PathLike, fig) -> str:
    """The note of ``rangekit plot track``: tracks, points and ellipses drawn (a
    :class:`~rangekit.plot.figures.TrackPlot`)."""
    n_pts = sum(len(v) for v in fig.xy_m.values())
    n_ell = sum(len(v) for v in fig.ellipse_rows.values())
    return wrote(output, f"{len(fig.xy_m)} track(s), {n_pts} points, {n_ell} ellipses/circles")


def cdf_note(output: str | os.PathLike, batch) -> str:
    """The note of ``rangekit plot cdf``: curves, rows used and rows skipped (a
    :class:`~rangekit.plot.inputs.BatchErrors`)."""
    used = batch.n_rows - batch.n_skipped
    return wrote(output, f"{len(batch.errors_m)} curve(s), {used} rows, {batch.n_skipped} skipped")


# ------------------------------------------------------------------- what a run uses


def _signal_text(scheme: str, detector: str | None, template: str | None) -> str:
    """What is detected: the template named, the ultrasonic schemes' coded burst, or the
    beep's detector."""
    if template is not None:
        return f"template '{template}'"
    if scheme != "beepbeep":
        return "coded burst (--code)"
    return f"detector {detector}"


def _air_text(medium) -> str:
    """The :class:`~rangekit.physics.Medium` as given: its speed of sound, or its
    temperature."""
    if medium.speed_m_s is not None:
        return f"speed of sound {format_value(medium.speed_m_s)} m/s"
    return f"temperature {format_value(medium.temp_c)} C"


def range_detail(
    scheme: str,
    *,
    medium,
    detector: str | None = None,
    template: str | None = None,
    calibration: str | None = None,
    setup=None,
) -> str:
    """What ``rangekit range --verbose`` says the run uses, after ``rangekit: range: ``.

    Parameters
    ----------
    scheme : {"beepbeep", "oneway", "echo"}
    medium : rangekit.physics.Medium
        The air of the job.
    detector : str, optional
        The beep's detector (two-way without a template).
    template, calibration : str, optional
        The names of the template and calibration files given.
    setup : rangekit.ranging.config.TwoWaySetup, optional
        The two-way devices (None: ``TwoWaySetup()``, the library's default); its
        self-distances are shown for ``beepbeep`` only.

    Examples
    --------
    >>> from rangekit.physics import Medium
    >>> from rangekit.ranging.config import TwoWaySetup
    >>> range_detail("beepbeep", medium=Medium(), detector="changepoint",
    ...              setup=TwoWaySetup(self_distance_m=(0.1, 0.12)))
    'scheme beepbeep, detector changepoint, temperature 20 C, self-distance 0.1,0.12'
    >>> range_detail("oneway", medium=Medium(speed_m_s=343.5), calibration="ow.json")
    "scheme oneway, coded burst (--code), speed of sound 343.5 m/s, calibration 'ow.json'"
    """
    text = f"scheme {scheme}, {_signal_text(scheme, detector, template)}, {_air_text(medium)}"
    if scheme == "beepbeep":
        if setup is None:
            from rangekit.ranging.config import TwoWaySetup

            setup = TwoWaySetup()
        text += f", self-distance {format_value(setup.self_distance_m)}"
    if calibration is not None:
        text += f", calibration '{os.fspath(calibration)}'"
    return text


def detect_detail(method: str, *, template: str | None = None, expected: int | None = None) -> str:
    """What ``rangekit detect --verbose`` says the run uses, after ``rangekit: detect: ``:
    the signal (the template named, or the beep), the method of
    :func:`rangekit.detect.files.detect_files` and the most arrivals kept per channel.

    Examples
    --------
    >>> detect_detail("changepoint")
    'the beep by changepoint'
    >>> detect_detail("template", template="sweep.wav", expected=3)
    "template 'sweep.wav' by template, at most 3 per channel"
    """
    sig = f"template '{template}'" if template is not None else "the beep"
    exp = f", at most {expected} per channel" if expected is not None else ""
    return f"{sig} by {method}{exp}"


def calibrate_detail(
    scheme: str,
    *,
    n_recordings: int,
    medium,
    detector: str | None = None,
    template: str | None = None,
) -> str:
    """What ``rangekit calibrate --verbose`` says the fit uses, after
    ``rangekit: calibrate: ``: the scheme, the signal (as :func:`range_detail` names it),
    how many recordings and the speed of sound the offset is fitted with
    (:attr:`Medium.c <rangekit.physics.Medium>`, to 0.01 m/s).

    Examples
    --------
    >>> from rangekit.physics import Medium
    >>> calibrate_detail("beepbeep", n_recordings=4, medium=Medium(), template="sweep.wav")
    "beepbeep, template 'sweep.wav', 4 recordings, c = 343.29 m/s"
    >>> calibrate_detail("oneway", n_recordings=1, medium=Medium(), detector="changepoint")
    'oneway, coded burst (--code), 1 recording, c = 343.29 m/s'
    """
    sig = _signal_text(scheme, detector, template)
    what = f"{n_recordings} recording{'' if n_recordings == 1 else 's'}"
    return f"{scheme}, {sig}, {what}, c = {medium.c:.2f} m/s"


def locate_detail(ids, *, source: str, method: str, sigma_m=None) -> str:
    """What ``rangekit locate --verbose`` says the solve uses, after ``rangekit: locate: ``:
    the transmitters and where their distances came from, the method and the distances'
    sigma (one number in m, ``per range`` for an array of them, ``none``).

    Examples
    --------
    >>> locate_detail([0, 2], source="--tx", method="hybrid", sigma_m=0.002)
    '2 transmitters (0, 2) from --tx, method hybrid, distance sigma 0.002 m'
    >>> locate_detail([1, 2, 3], source="d.csv", method="direct")
    '3 transmitters (1, 2, 3) from d.csv, method direct, distance sigma none'
    """
    if sigma_m is None:
        sigma = "none"
    elif np.ndim(sigma_m) == 0:
        sigma = f"{format_value(float(sigma_m))} m"
    else:
        sigma = "per range"
    return (
        f"{len(ids)} transmitters ({', '.join(map(str, ids))}) from {source}, method "
        f"{method}, distance sigma {sigma}"
    )


def batch_details(options, sessions, output: str | os.PathLike) -> list[str]:
    """What ``rangekit batch --verbose`` says the run uses, each line after ``batch: ``:
    the scheme and the two-way signal of the :class:`~rangekit.batch.BatchOptions`
    (``detector`` None: :func:`~rangekit.ranging.pipeline.range_channels`' default), how
    many of the ``sessions`` take their scheme or setup from a sidecar, whether they were
    paired by name, and where the options are recorded (:func:`rangekit.batch.meta_path`
    of ``output``).

    Examples
    --------
    >>> from rangekit.batch import BatchOptions
    >>> batch_details(BatchOptions(), [], "r.jsonl")  # doctest: +NORMALIZE_WHITESPACE
    ['scheme beepbeep, detector changepoint; 0 of 0 sessions take their scheme or setup
    from a sidecar', 'options recorded in r.jsonl.meta.json']
    """
    import inspect

    from rangekit.batch import meta_path
    from rangekit.ranging.pipeline import range_channels

    two_way = options.beepbeep
    if two_way.probe is not None:
        given = "probe (--template)"
    else:
        d = two_way.detector
        d = inspect.signature(range_channels).parameters["detector"].default if d is None else d
        given = f"detector {d}"
    by_sidecar = sum(bool(s.scheme or s.params) for s in sessions)
    lines = [
        f"scheme {options.scheme}, {given}; {by_sidecar} of {len(sessions)} sessions take "
        "their scheme or setup from a sidecar"
    ]
    if options.pair_by_name:
        lines.append("sessions paired by name across the device folders")
    return [*lines, f"options recorded in {meta_path(output)}"]
