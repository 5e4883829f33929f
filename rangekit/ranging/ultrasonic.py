"""Ultrasonic time-of-flight ranging: one-way (RF-synchronised beacons) and pulse-echo.

**One-way** (Kim & Kim 2013 §II-A): the robot's RF message triggers a ceiling Tx, which
fires its Barker-coded burst; each of the robot's receivers times the burst's arrival from
the trigger. In a recording, sample 0 is the trigger (the emission instant); each channel is
a receiver; a known system latency (trigger to drive start) is subtracted; distances are
``c * (arrival - latency)`` with ``c = 20.05 sqrt(T + 273.16)`` m/s. A file may hold many
consecutive activation windows at a known period (Kim & Kim fire the Txs in turn at
5 Hz): window ``k`` starts at sample ``round(k * period * fs)``, and its time origin is
there.

**Pulse-echo** (SRF02, Girard 2011 §2.6): sample 0 is the ping; the earliest echo after
the ring-down blanking (the minimum range, 15 cm) gives ``c * t / 2``; nothing within the
maximum range (6 m) is "out of range" (distance None). A recording may hold many ranging
cycles at a known period (70 ms for the SRF02).

Both use the matched filter of :mod:`rangekit.detect.matched` with first-path selection.

Examples
--------
>>> import numpy as np
>>> from rangekit.detect.matched import coded_template
>>> fs = 192000.0
>>> h = coded_template(fs=fs)
>>> x = np.zeros((1, 20000))
>>> x[0, 560 : 560 + len(h)] = h
>>> rows = range_oneway(x, fs=fs, tx=None, rx=None, speed_m_s=343.0)
>>> rows[0].channel, round(rows[0].distance_m, 4)
(0, 1.0004)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rangekit import _validate as V
from rangekit.detect.matched import (
    DEFAULT_BLOCK,
    DEFAULT_K_DETECT,
    DEFAULT_K_NOISE,
    DEFAULT_REL_THRESHOLD,
    coded_template,
    detect_matched,
)
from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.physics import DEFAULT_TEMP_C, speed_of_sound_m_s
from rangekit.ranging.calibration import Calibration
from rangekit.signals.barker import CodedBurst, check_burst_fits, srf02_ping
from rangekit.signals.probe import Probe
from rangekit.signals.transducer import Transducer

__all__ = [
    "SRF02_CYCLE_S",
    "SRF02_MAX_RANGE_M",
    "SRF02_MIN_RANGE_M",
    "ULTRASONIC_SCHEMES",
    "MatchedTrace",
    "ToF",
    "format_tof",
    "matched_trace",
    "range_echo",
    "range_oneway",
    "range_ultrasonic_files",
    "window_starts",
]

#: SRF02 ranging cycle (datasheet; Girard 2011 §2.6.5), s.
SRF02_CYCLE_S = 0.070
#: SRF02 minimum range (ring-down), m (Girard 2011 §2.6).
SRF02_MIN_RANGE_M = 0.15
#: SRF02 maximum range, m (Girard 2011 §2.6).
SRF02_MAX_RANGE_M = 6.0

_DEFAULT_TX = Transducer()


@dataclass(frozen=True)
class ToF:
    """One time-of-flight range.

    Attributes
    ----------
    window : int
        Activation window (one-way) or ranging cycle (echo), from 0.
    tx : int or None
        Transmitter id of the window (one-way with a firing order), else None.
    channel : int
        Receiver (channel of the recording), from 0.
    distance_m : float
        Distance in metres; NaN when nothing was detected (out of range).
    sigma_m : float
        1-sigma of the distance from the detection SNR (Cramér–Rao), metres; NaN if none.
    snr_db : float
        Matched-filter output SNR ``10 log10(2 E / N0)``; NaN if none.
    arrival_s : float
        Arrival time from the window's start (latency included), seconds; NaN if none.
    flags : tuple of str
        The arrival's flags (:data:`rangekit.types.ARRIVAL_FLAGS`: ``low_snr``,
        ``poor_match``, ``ambiguous_first_path``); empty when none or nothing detected.
    """

    window: int
    tx: int | None
    channel: int
    distance_m: float
    sigma_m: float
    snr_db: float
    arrival_s: float
    flags: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        """Plain-JSON form; NaN becomes None (null)."""

        def f(v: float) -> float | None:
            return None if not math.isfinite(v) else float(v)

        return {
            "window": self.window,
            "tx": self.tx,
            "channel": self.channel,
            "distance_m": f(self.distance_m),
            "sigma_m": f(self.sigma_m),
            "snr_db": f(self.snr_db),
            "arrival_s": f(self.arrival_s),
        }


def window_starts(n_samples: int, *, fs: float, period_s: float | None) -> np.ndarray:
    """``[start, stop)`` sample ranges of consecutive windows of ``period_s`` (one if None).

    A last window shorter than half a period is dropped (an activation cut off by the end
    of the recording).

    Examples
    --------
    >>> window_starts(1000, fs=100.0, period_s=2.5).tolist()
    [[0, 250], [250, 500], [500, 750], [750, 1000]]
    >>> window_starts(1000, fs=100.0, period_s=None).tolist()
    [[0, 1000]]
    """
    if period_s is None:
        return np.array([[0, n_samples]], dtype=np.int64)
    period_s = V.positive("period_s", period_s)
    per = period_s * fs
    if per < 2:
        raise InvalidParameterError(f"period_s={period_s!r} is shorter than two samples")
    k = np.arange(int(math.floor(n_samples / per + 0.5)) + 1)
    starts = np.round(k * per).astype(np.int64)
    starts = starts[starts < n_samples]
    stops = np.minimum(np.append(starts[1:], n_samples), n_samples)
    keep = (stops - starts) >= 0.5 * per
    if not keep.any():
        raise IncompatibleInputError(
            f"the recording ({n_samples / fs:g} s) is shorter than half a period "
            f"({period_s:g} s): no window to range"
        )
    return np.stack([starts[keep], stops[keep]], axis=1)


def _as_channels(x: np.ndarray) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] < 2:
        raise InvalidParameterError(f"x must be (channels, samples), got shape {a.shape}")
    return a


def _ranges(
    x: np.ndarray,
    *,
    fs: float,
    template: np.ndarray,
    windows: np.ndarray,
    lo_s: float,
    hi_s: float,
    offset_s: float,
    scale: float,
    c: float,
    tx_ids: Sequence[int] | None,
    thresholds: dict,
    block: int,
    first_window: int = 0,
    model=None,
    q0: float = 4.0,
    pool: bool = True,
) -> list[ToF]:
    """Shared core: per channel, per window first paths -> distances ``scale*c*(t - off)``.

    Window ``w`` of ``windows`` is numbered ``first_window + w`` (its transmitter too).
    With ``model`` the arrivals are timed by the transducer fit, whose ``(Q, f0)``
    estimates are pooled per channel and transmitter (``tx_ids``; all windows of a channel
    when None).
    """
    lo = max(0, int(math.floor(lo_s * fs)) - 1)
    hi = int(math.ceil(hi_s * fs)) + 2
    rows: list[ToF] = []
    groups = None
    if tx_ids is not None:
        k = first_window + np.arange(len(windows))
        groups = np.asarray(tx_ids, dtype=np.int64)[k % len(tx_ids)]
    per_channel = []
    if model is None:
        for ch in range(x.shape[0]):
            per_channel.append(
                detect_matched(
                    x[ch],
                    fs=fs,
                    template=template,
                    windows=windows,
                    search=(lo, hi),
                    block=block,
                    **thresholds,
                )
            )
    else:
        from rangekit.detect.fitted import check_shapes, fit_channel

        cf = [
            fit_channel(
                x[ch],
                fs=fs,
                template=template,
                models=model,
                windows=windows,
                search=(lo, hi),
                block=block,
                q0=q0,
                groups=groups,
                pool=pool,
                **thresholds,
            )
            for ch in range(x.shape[0])
        ]
        # A transducer's shape is the same through every receiver (multipath is not):
        # a receiver that disagrees with the others is refitted at their shape, and
        # without a consensus the resonator times that transmitter's arrivals.
        forces = check_shapes(cf) if pool else [{} for _ in cf]
        cf = [
            fit_channel(
                x[ch], fs=fs, template=template, models=model, windows=windows,
                search=(lo, hi), block=block, q0=q0, groups=groups, pool=pool,
                force=forces[ch], **thresholds,
            )
            if forces[ch]
            else f
            for ch, f in enumerate(cf)
        ]  # fmt: skip
        per_channel = [f.arrivals for f in cf]
    for ch, arr in enumerate(per_channel):
        found = dict(zip(arr.window.tolist(), range(len(arr)), strict=True))
        for w, (s0, _) in enumerate(windows):
            k = first_window + w
            tx = None if tx_ids is None else int(tx_ids[k % len(tx_ids)])
            i = found.get(w)
            if i is None:
                rows.append(ToF(k, tx, ch, math.nan, math.nan, math.nan, math.nan))
                continue
            t = (arr.onset[i] - s0) / fs
            d = scale * c * (t - offset_s)
            sig = scale * c * arr.sigma[i] / fs
            fl = arr.flag_names(i)
            rows.append(ToF(k, tx, ch, float(d), float(sig), float(arr.snr_db[i]), float(t), fl))
    rows.sort(key=lambda r: (r.window, r.channel))
    return rows


def _windows(
    n_samples: int,
    *,
    fs: float,
    period_s: float | None,
    windows: np.ndarray | None,
    first_window: int,
) -> np.ndarray:
    """The windows to range: ``window_starts`` of ``period_s``, or checked explicit ones."""
    V.positive_int("first_window", first_window, minimum=0)
    if windows is None:
        return window_starts(n_samples, fs=fs, period_s=period_s)
    if period_s is not None:
        raise InvalidParameterError("give period_s or windows, not both")
    w = np.asarray(windows)
    if (
        w.ndim != 2
        or w.shape[1] != 2
        or len(w) == 0
        or not np.issubdtype(w.dtype, np.integer)
        or np.any(w[:, 0] < 0)
        or np.any(w[:, 1] > n_samples)
        or np.any(w[:, 1] - w[:, 0] < 2)
    ):
        raise InvalidParameterError(
            f"windows must be integer [start, stop) rows of >= 2 samples within the "
            f"{n_samples} samples, got shape {w.shape}"
        )
    return w.astype(np.int64)


def _speed(temp_c: float, speed_m_s: float | None) -> float:
    if speed_m_s is None:
        return speed_of_sound_m_s(temp_c)
    return V.in_range("speed_m_s", speed_m_s, 100.0, 2000.0)


def range_oneway(
    x: np.ndarray,
    *,
    fs: float,
    burst: CodedBurst | None = None,
    tx: Transducer | None = _DEFAULT_TX,
    rx: Transducer | None = _DEFAULT_TX,
    latency_s: float = 0.0,
    temp_c: float = DEFAULT_TEMP_C,
    speed_m_s: float | None = None,
    period_s: float | None = None,
    tx_ids: Sequence[int] | None = None,
    min_range_m: float = 0.0,
    max_range_m: float = 15.0,
    k_noise: float = DEFAULT_K_NOISE,
    k_detect: float = DEFAULT_K_DETECT,
    rel_threshold: float = DEFAULT_REL_THRESHOLD,
    block: int = DEFAULT_BLOCK,
    windows: np.ndarray | None = None,
    first_window: int = 0,
    probe: Probe | None = None,
    fit_transducers: bool = True,
    pool: bool = True,
) -> list[ToF]:
    """One-way (RF-synchronised) ranges from a recording whose sample 0 is the trigger.

    Parameters
    ----------
    x : ndarray, shape (channels, samples) or (samples,)
        The recording; each channel is one receiver.
    fs : float
        Sample rate in Hz; must carry the burst's band (``CodedBurst.band_hz``).
    burst : CodedBurst, optional
        The emitted code (default Barker-7, 40 kHz, 3 cycles per bit; Kim & Kim 2013).
    tx, rx : Transducer or None
        The transducers in the path (default Q = 4 each, as the simulator uses). With
        ``fit_transducers`` they are only the starting point (their f0 centres the fit's
        f0 range, the coarse detection template folds them in); otherwise their responses
        are folded into the template as they are. None leaves one out; both None = the
        bare drive (nothing fitted, the transducers' delay stays in the ranges).
    latency_s : float
        Known system latency from the trigger to the drive's start, subtracted (>= 0).
    temp_c, speed_m_s : float
        Air temperature (sets ``c = 20.05 sqrt(T + 273.16)``), or the speed of sound.
    period_s : float, optional
        Activation period: the file holds consecutive windows of this length (e.g. 0.2 s
        for Kim & Kim's 5 Hz). Default: the whole file is one window.
    tx_ids : sequence of int, optional
        Firing order of the transmitters; window ``k`` is ``tx_ids[k % len(tx_ids)]``.
    min_range_m, max_range_m : float
        Distances the search considers (default 0-15 m).
    k_noise, k_detect, rel_threshold : float
        Detection thresholds (:func:`rangekit.detect.matched.first_path`).
    block : int
        Overlap-save FFT size.
    windows : ndarray of int, shape (n, 2), optional
        Explicit ``[start, stop)`` sample ranges of the windows, instead of ``period_s``
        (each window's time origin is its start). Used to range a long recording a block
        at a time (:mod:`rangekit.ranging.series`): ``x`` then holds the block with the
        matched filter's reach of context on both sides.
    first_window : int
        Number of the first window (window ``k`` of ``windows`` is ``first_window + k``,
        also for ``tx_ids``).
    probe : Probe, optional
        Any other emitted signal (a sweep, a lab's own file): the template is the probe at
        ``fs`` (:meth:`rangekit.signals.probe.Probe.at_rate`); ``burst``, ``tx`` and ``rx``
        are then unused (the recording's own responses stay in the arrival time, which a
        calibration's latency absorbs).
    fit_transducers : bool
        Time each arrival by fitting the drive through two resonators of unknown Q and f0,
        with overlapping reflections (:mod:`rangekit.detect.pathfit`), or through two
        elements of two stagger-tuned resonators each (:mod:`rangekit.detect.stagger`),
        whichever the recording favours per transmitter and receiver
        (:mod:`rangekit.detect.fitted`), so that the range does not depend on knowing the
        transducers (default True; ``docs/theory/ultrasonic.md``). False: the template of
        ``tx`` and ``rx`` is assumed right.
    pool : bool
        With ``fit_transducers``: pool the ``(Q, f0)`` estimates of every window of one
        receiver and transmitter (``tx_ids``; all windows of the receiver without them)
        when they agree, which brings each range's sigma down to the known-transducer
        bound (default True).

    Returns
    -------
    list of ToF
        One entry per (window, channel), sorted; ``distance_m`` NaN where nothing was found.
    """
    fs = V.sample_rate(fs)
    burst = CodedBurst() if burst is None else burst
    if probe is None:
        check_burst_fits(burst, fs=fs)
    else:
        probe.check_fits(fs)
    x = _as_channels(x)
    latency_s = V.positive("latency_s", latency_s, allow_zero=True)
    c = _speed(temp_c, speed_m_s)
    min_range_m = V.positive("min_range_m", min_range_m, allow_zero=True)
    max_range_m = V.positive("max_range_m", max_range_m)
    if max_range_m <= min_range_m:
        raise InvalidParameterError(
            f"max_range_m={max_range_m!r} must exceed min_range_m={min_range_m!r}"
        )
    if tx_ids is not None and len(tx_ids) == 0:
        raise InvalidParameterError("tx_ids must not be empty")
    windows = _windows(
        x.shape[1], fs=fs, period_s=period_s, windows=windows, first_window=first_window
    )
    template = coded_template(burst, fs=fs, tx=tx, rx=rx) if probe is None else probe.at_rate(fs)
    model, q0 = (
        (None, 4.0) if probe is not None else _fit_model(burst, fs, (tx, rx), fit_transducers)
    )
    return _ranges(
        x,
        fs=fs,
        template=template,
        windows=windows,
        lo_s=latency_s + min_range_m / c,
        hi_s=latency_s + max_range_m / c,
        offset_s=latency_s,
        scale=1.0,
        c=c,
        tx_ids=tx_ids,
        thresholds={"k_noise": k_noise, "k_detect": k_detect, "rel_threshold": rel_threshold},
        block=block,
        first_window=first_window,
        model=model,
        q0=q0,
        pool=pool,
    )


def _fit_model(burst: CodedBurst, fs: float, transducers, fit: bool, stagger: bool = True):
    """The transducer fit's models and starting Q for ``transducers``, or ``(None, 4)``."""
    ts = [t for t in transducers if t is not None]
    if not fit or not ts:
        return None, 4.0
    from rangekit.detect.pathfit import ResonatorModel
    from rangekit.detect.stagger import StaggerModel

    f0 = sum(t.f0_hz for t in ts) / len(ts)
    q0 = math.exp(sum(math.log(t.q) for t in ts) / len(ts))
    kw = {"fs": fs, "f0_hz": f0, "stages": len(ts)}
    models = (ResonatorModel.for_burst(burst, **kw), StaggerModel.for_burst(burst, **kw))
    return (models if stagger else models[:1]), q0


def range_echo(
    x: np.ndarray,
    *,
    fs: float,
    burst: CodedBurst | None = None,
    transducer: Transducer | None = _DEFAULT_TX,
    temp_c: float = DEFAULT_TEMP_C,
    speed_m_s: float | None = None,
    period_s: float | None = None,
    min_range_m: float = SRF02_MIN_RANGE_M,
    max_range_m: float = SRF02_MAX_RANGE_M,
    k_noise: float = DEFAULT_K_NOISE,
    k_detect: float = DEFAULT_K_DETECT,
    rel_threshold: float = DEFAULT_REL_THRESHOLD,
    block: int = DEFAULT_BLOCK,
    windows: np.ndarray | None = None,
    first_window: int = 0,
    probe: Probe | None = None,
) -> list[ToF]:
    """Pulse-echo ranges (SRF02 style) from a recording whose sample 0 is the ping.

    The template is the ping through the transducer twice (it sends and receives). Echoes
    earlier than ``2 min_range_m / c`` fall in the ring-down and are not searched; nothing
    before ``2 max_range_m / c`` means out of range (distance NaN, ``None`` in JSON).
    ``period_s`` splits a log of many ranging cycles (0.07 s for the SRF02), or
    ``windows`` gives them explicitly. Other parameters as :func:`range_oneway` (with
    ``probe`` the template is the probe and ``burst``, ``transducer`` are unused).
    """
    fs = V.sample_rate(fs)
    burst = srf02_ping() if burst is None else burst
    if probe is None:
        check_burst_fits(burst, fs=fs)
    else:
        probe.check_fits(fs)
    x = _as_channels(x)
    c = _speed(temp_c, speed_m_s)
    min_range_m = V.positive("min_range_m", min_range_m, allow_zero=True)
    max_range_m = V.positive("max_range_m", max_range_m)
    if max_range_m <= min_range_m:
        raise InvalidParameterError(
            f"max_range_m={max_range_m!r} must exceed min_range_m={min_range_m!r}"
        )
    windows = _windows(
        x.shape[1], fs=fs, period_s=period_s, windows=windows, first_window=first_window
    )
    if (windows[0, 1] - windows[0, 0]) / fs < 2.0 * min_range_m / c:
        raise IncompatibleInputError(
            f"recording of {x.shape[1]} samples is shorter than the ring-down blanking"
        )
    template = (
        coded_template(burst, fs=fs, tx=transducer, rx=transducer)
        if probe is None
        else probe.at_rate(fs)
    )
    rows = _ranges(
        x,
        fs=fs,
        template=template,
        windows=windows,
        lo_s=2.0 * min_range_m / c,
        hi_s=2.0 * max_range_m / c,
        offset_s=0.0,
        scale=0.5,
        c=c,
        tx_ids=None,
        thresholds={"k_noise": k_noise, "k_detect": k_detect, "rel_threshold": rel_threshold},
        block=block,
        first_window=first_window,
    )
    # Paths found at the very edges of the search are the blanking's or timeout's edge.
    out = []
    for r in rows:
        if math.isfinite(r.distance_m) and not (min_range_m <= r.distance_m <= max_range_m):
            r = ToF(r.window, r.tx, r.channel, math.nan, math.nan, math.nan, math.nan)
        out.append(r)
    return out


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
    """Ranges of every file, channel and window; rows for :func:`format_tof`.

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
        A file holds no burst at all (no channel, no window).
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


def format_tof(rows: list[dict], fmt: str, *, scheme: str, meta: dict | None = None) -> str:
    """Rows of :func:`range_ultrasonic_files` as a table, CSV or JSON (key ``ranges``)."""
    from rangekit.io.results import format_rows

    fields = ["file", "window"] + (["tx"] if scheme == "oneway" else [])
    fields += ["channel", "distance_m", "sigma_m", "snr_db", "arrival_s", "flags"]
    if fmt == "table":
        out = []
        for r in rows:
            t = dict(r)
            for k, nd in (("distance_m", 4), ("sigma_m", 5), ("snr_db", 1), ("arrival_s", 7)):
                t[k] = "-" if r[k] is None else f"{r[k]:.{nd}f}"
            if "tx" in t and t["tx"] is None:
                t["tx"] = "-"
            t["flags"] = ",".join(r.get("flags") or ()) or "-"
            out.append(t)
        return format_rows(out, fields, fmt, meta=meta, key="ranges")
    if fmt == "csv":
        rows = [{k: ("" if v is None else v) for k, v in r.items()} for r in rows]
    return format_rows(rows, fields, fmt, meta=meta, key="ranges")


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
