"""Ultrasonic time-of-flight ranging of files: one-way (RF-synchronised beacons) and echo.

The schemes are :func:`rangekit.ranging.oneway.range_oneway` (Kim & Kim 2013 §II-A: sample
0 is the RF trigger, each channel a receiver, distances ``c * (arrival - latency)``) and
:func:`rangekit.ranging.echo.range_echo` (SRF02, Girard 2011 §2.6: sample 0 is the ping,
``c * t / 2`` of the earliest echo after the ring-down), their shared core (the result
type :class:`ToF`, the activation windows, the loop from arrivals to distances)
:mod:`rangekit.ranging.tof`. This module ranges files of either scheme
(:func:`range_ultrasonic_files`, what ``rangekit range --scheme oneway|echo`` runs; the
rows are formatted by :func:`rangekit.io.results.format_tof`) and gives the matched-filter
trace of one window
(:func:`matched_trace`); it re-exports the schemes, so ``from rangekit.ranging.ultrasonic
import range_oneway`` keeps working.

Examples
--------
>>> import numpy as np
>>> from rangekit.detect.matched import coded_template
>>> fs = 192000.0
>>> x = np.zeros((1, 20000))
>>> x[0, 560 : 561 + 100] = coded_template(fs=fs)
>>> from rangekit.io.results import format_tof
>>> rows = [r.as_dict() for r in range_oneway(x, fs=fs, tx=None, rx=None, speed_m_s=343.0)]
>>> print(format_tof([{"file": "a.wav", **r, "flags": []} for r in rows], "csv",
...                  scheme="oneway").splitlines()[1])
a.wav,0,,0,1.0004...
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rangekit import _validate as V
from rangekit.detect.matched import coded_template
from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.physics import DEFAULT_TEMP_C
from rangekit.ranging.calibration import Calibration
from rangekit.ranging.echo import SRF02_CYCLE_S, SRF02_MAX_RANGE_M, SRF02_MIN_RANGE_M, range_echo
from rangekit.ranging.oneway import range_oneway
from rangekit.ranging.tof import ToF, _as_channels, _speed, window_starts
from rangekit.signals.barker import CodedBurst, check_burst_fits, srf02_ping
from rangekit.signals.probe import Probe

__all__ = [
    "SRF02_CYCLE_S",
    "SRF02_MAX_RANGE_M",
    "SRF02_MIN_RANGE_M",
    "ULTRASONIC_SCHEMES",
    "MatchedTrace",
    "ToF",
    "matched_trace",
    "range_echo",
    "range_oneway",
    "range_ultrasonic_files",
    "window_starts",
]


#: Ranging schemes of :func:`range_ultrasonic_files`.
ULTRASONIC_SCHEMES = ("oneway", "echo")


def _file_burst(
    path,
    n_channels: int,
    fs: float,
    *,
    scheme: str,
    channels: int | None,
    burst,
    probe: Probe | None = None,
) -> CodedBurst:
    """Check a file's channel count and rate; the scheme's burst at the file's rate."""
    if channels is not None and n_channels != channels:
        raise IncompatibleInputError(
            f"'{path}' has {n_channels} channel(s) but {channels} are expected "
            f"({'one per receiver' if scheme == 'oneway' else 'one per sensor'})"
        )
    b = (CodedBurst() if scheme == "oneway" else srf02_ping()) if burst is None else burst
    if probe is not None:
        probe.check_fits(fs, what=f"'{path}'")
        return b
    check_burst_fits(b, fs=fs, what=f"'{path}'")
    return b.with_fs(fs)


def _calibrated(r: ToF, cal: Calibration, c: float) -> ToF:
    """``r`` with its distance from the calibration (``arrival_s`` is the measured time)."""
    if not math.isfinite(r.arrival_s):
        return r
    d, s = cal.distance(r.arrival_s, r.sigma_m / c, speed_m_s=c)
    return ToF(r.window, r.tx, r.channel, d, s, r.snr_db, r.arrival_s, r.flags)


def _no_burst_message(path, scheme: str) -> str:
    return (
        f"'{path}': no burst found in any channel or window (is this a {scheme} recording "
        "at the right --period and --latency?)"
    )


def range_ultrasonic_files(
    paths: Sequence[str],
    *,
    scheme: str,
    channels: int | None = None,
    burst: CodedBurst | None = None,
    probe: Probe | None = None,
    calibration: Calibration | None = None,
    **kw,
) -> list[dict]:
    """Ranges of every file, channel and window; rows for :func:`rangekit.io.results.format_tof`.

    Each file is ranged on its own (one-way: channel = receiver; echo: channel = sensor).

    Parameters
    ----------
    paths : sequence of str
        Audio files.
    scheme : {"oneway", "echo"}
        :func:`range_oneway` or :func:`range_echo`.
    channels : int, optional
        Channel count every file must have (e.g. 3 receivers); None accepts any.
    burst : CodedBurst, optional
        The emitted code (default per scheme: Barker-7 for oneway, the SRF02 ping for echo).
    probe : Probe, optional
        Any other emitted signal instead of the burst (see :func:`range_oneway`).
    calibration : Calibration, optional
        A one-way calibration (:mod:`rangekit.ranging.calibration`): its latency (and
        fitted speed) turn the arrival times into distances; ``latency_s`` must then be
        left at 0.
    **kw
        Passed to the scheme's function.

    Raises
    ------
    IncompatibleInputError
        A file's sample rate cannot carry the burst, or its channel count is wrong.
    DetectionError
        A file holds no burst at all (no channel, no window; one-way), or every sample
        of it is 0 (either scheme).
    """
    from rangekit.errors import DetectionError
    from rangekit.io.audio import read_audio

    if scheme not in ULTRASONIC_SCHEMES:
        raise InvalidParameterError(
            f"scheme={scheme!r} must be one of {', '.join(ULTRASONIC_SCHEMES)}"
        )
    if channels is not None:
        channels = V.positive_int("channels", channels)
    func = range_oneway if scheme == "oneway" else range_echo
    if probe is not None:
        kw["probe"] = probe
    c = _speed(kw.get("temp_c", DEFAULT_TEMP_C), kw.get("speed_m_s"))
    if calibration is not None:
        calibration.check_scheme(scheme)
        if kw.get("latency_s", 0.0) != 0.0:
            raise InvalidParameterError(
                "give latency_s or a calibration, not both: the calibration's latency replaces it"
            )
        # Search from the calibrated latency; distances are recomputed below.
        kw["latency_s"] = max(0.0, calibration.latency_s)
    rows: list[dict] = []
    for p in paths:
        x, fs = read_audio(p)
        b = _file_burst(
            p, x.shape[1], fs, scheme=scheme, channels=channels, burst=burst, probe=probe
        )
        if not (x[:4096].any() or x.any()):  # the first samples settle most files
            # windows of zeros hold no arrival, and an echo log without one is not an
            # error (nothing in range): a file of zeros would be a table of dashes
            raise DetectionError(
                f"'{p}': every sample is 0 (digital silence): nothing was recorded"
            )
        res = func(x.T, fs=fs, burst=b, **kw)
        if calibration is not None:
            res = [_calibrated(r, calibration, c) for r in res]
        if scheme == "oneway" and not any(math.isfinite(r.distance_m) for r in res):
            raise DetectionError(_no_burst_message(p, scheme))
        for r in res:
            d = r.as_dict()
            if scheme == "echo":
                d.pop("tx")
            rows.append({"file": str(p), **d, "flags": list(r.flags)})
    return rows


@dataclass(frozen=True)
class MatchedTrace:
    """The matched-filter output of one channel in one window, and the range taken from it.

    Attributes
    ----------
    fs : float
        Sample rate, Hz.
    start : int
        The window's first sample in the recording (its time origin).
    envelope : ndarray
        Envelope ``|c|`` of the analytic matched-filter output over the window: index ``k``
        is lag ``k`` samples from ``start`` (what :func:`rangekit.detect.matched.detect_matched`
        searches).
    noise : float
        Rayleigh scale of the envelope's noise in the window
        (:func:`rangekit.detect.matched.noise_level`), the unit of the detection thresholds.
    search_s : tuple of float
        Arrival times the search considers, s from the window start (``[lo, hi)``; one-way:
        latency plus ``min_range_m / c`` to ``max_range_m / c``; echo: ``2 min_range_m / c``
        to ``2 max_range_m / c``).
    tof : ToF
        The range of this channel and window, as :func:`range_oneway` or :func:`range_echo`
        returns it (``arrival_s`` NaN when nothing was detected).
    """

    fs: float
    start: int
    envelope: np.ndarray
    noise: float
    search_s: tuple[float, float]
    tof: ToF

    @property
    def peak_lag(self) -> float:
        """Lag of the chosen first path in samples from ``start`` (NaN if none)."""
        return self.tof.arrival_s * self.fs


def matched_trace(
    x: np.ndarray, *, fs: float, scheme: str, channel: int = 0, window: int = 0, **kw
) -> MatchedTrace:
    """The matched-filter envelope of one channel and window, with the first path ranging chose.

    The range comes from :func:`range_oneway` or :func:`range_echo` run on that channel
    (so it is the one ``rangekit range`` reports); the envelope is the same analytic
    matched filter (:class:`rangekit.detect.matched.MatchedFilter`, template from
    :func:`rangekit.detect.matched.coded_template` with the scheme's transducers) over the
    whole channel, cut to the window.

    Parameters
    ----------
    x : ndarray, shape (channels, samples) or (samples,)
        The recording, as for :func:`range_oneway`.
    fs : float
        Sample rate in Hz.
    scheme : {"oneway", "echo"}
        Which ranging function (and defaults) to use.
    channel, window : int
        The receiver (sensor) and the activation window (ranging cycle), from 0.
    **kw
        Keyword arguments of the scheme's function (``burst``, ``period_s``, ...).

    Returns
    -------
    MatchedTrace

    Raises
    ------
    IncompatibleInputError
        ``channel`` or ``window`` does not exist in the recording.

    Examples
    --------
    >>> from rangekit.detect.matched import coded_template
    >>> fs = 192000.0
    >>> h = coded_template(fs=fs)
    >>> x = np.zeros((1, 20000))
    >>> x[0, 560 : 560 + len(h)] = h
    >>> tr = matched_trace(x, fs=fs, scheme="oneway", tx=None, rx=None, speed_m_s=343.0)
    >>> round(tr.peak_lag, 3), int(np.argmax(tr.envelope))
    (560.0, 560)
    """
    import inspect
    from dataclasses import replace

    from rangekit.detect.matched import MatchedFilter, noise_level

    if scheme not in ULTRASONIC_SCHEMES:
        raise InvalidParameterError(
            f"scheme={scheme!r} must be one of {', '.join(ULTRASONIC_SCHEMES)}"
        )
    x = _as_channels(x)
    n_ch = x.shape[0]
    if not 0 <= channel < n_ch:
        raise IncompatibleInputError(
            f"channel {channel} does not exist: the recording has {n_ch} channel(s) (0..{n_ch - 1})"
        )
    func = range_oneway if scheme == "oneway" else range_echo
    rows = func(x[channel : channel + 1], fs=fs, **kw)  # checks every parameter
    if not 0 <= window < len(rows):
        raise IncompatibleInputError(
            f"window {window} does not exist: the recording holds {len(rows)} window(s) "
            f"(0..{len(rows) - 1})"
        )
    tof = replace(rows[window], channel=channel)
    p = {k: v.default for k, v in inspect.signature(func).parameters.items()} | kw
    if scheme == "oneway":
        burst = CodedBurst() if p["burst"] is None else p["burst"]
        tx, rx = p["tx"], p["rx"]
    else:
        burst = srf02_ping() if p["burst"] is None else p["burst"]
        tx = rx = p["transducer"]
    template = coded_template(burst, fs=fs, tx=tx, rx=rx)
    s0, s1 = (int(v) for v in window_starts(x.shape[1], fs=fs, period_s=p["period_s"])[window])
    env = np.abs(MatchedFilter(template, block=p["block"]).correlate(x[channel]))[s0:s1]
    c = _speed(p["temp_c"], p["speed_m_s"])
    if scheme == "oneway":
        lat = p["latency_s"]
        search = (lat + p["min_range_m"] / c, lat + p["max_range_m"] / c)
    else:
        search = (2.0 * p["min_range_m"] / c, 2.0 * p["max_range_m"] / c)
    return MatchedTrace(float(fs), s0, env, noise_level(env), search, tof)
