"""Conditioning of a recording before arrival timing: the steps real recordings need.

Recordings that rangekit did not make carry what its simulator never renders: DC offsets,
hum, handling noise and microphone drift far below the signal's band, speech or music
outside it, clipped own arrivals, digital silence where a microphone opened late. Each
step here removes or marks one of them, and each is tested on its own
(``tests/detect/test_condition.py``).

1. **Band-limiting** (:func:`bandpass_taps`, :func:`bandlimit`): a linear-phase FIR
   band-pass (Kaiser window, odd length ``2 h + 1``) applied causally, then shifted by its
   exact group delay of ``h`` samples, so the time origin does not move. It removes DC,
   hum, low-frequency noise and out-of-band interference in one step. The pass band is
   the signal's band plus a margin, flat to within the Kaiser ripple
   (``10^(-atten_db/20)``), so the filtered arrival equals the arrival: the filter adds
   energy before an onset only from the part of the signal's own spectrum that lies in
   the transition bands (for the tapered beep, below -60 dB; see the onset-timing traps
   in ``../shared/REFERENCES.md``: the danger is a filter *narrower* than the signal).
2. **Clipped samples** (:func:`clip_mask`): runs of two or more samples at the
   recording's extreme values (within ``rel_tol`` of the peak-to-peak range). Fits leave
   them out (and, after band-limiting, every output sample whose filter support touches
   one: :func:`dilate`), and the arrival is flagged ``clipped``.
3. **Robust noise floor** (:func:`active_floor`): a percentile of a band-energy series
   over the frames that hold signal at all, so digital silence (exact zeros) does not pull
   the floor to zero, and per stretch of about a quarter second (:func:`local_floor`), so
   automatic-gain steps and non-stationary noise set their own floor.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from rangekit import _validate as V

__all__ = [
    "DEFAULT_ATTEN_DB",
    "active_floor",
    "bandlimit",
    "bandpass_taps",
    "clip_mask",
    "dilate",
    "live_frames",
    "local_floor",
    "out_of_band_ratio",
    "percentile",
]

#: Stop-band attenuation of the band-limiting FIR, dB (pass-band ripple 1e-3).
DEFAULT_ATTEN_DB = 60.0


@functools.lru_cache(maxsize=32)
def bandpass_taps(
    fs: float,
    lo_hz: float,
    hi_hz: float,
    *,
    transition_hz: float | None = None,
    atten_db: float = DEFAULT_ATTEN_DB,
) -> np.ndarray:
    """Linear-phase band-pass FIR taps (odd length), flat over ``[lo_hz, hi_hz]``.

    Parameters
    ----------
    fs : float
        Sample rate in Hz.
    lo_hz, hi_hz : float
        Edges of the pass band (where the response is still 1 within the ripple). ``lo_hz``
        of 0 makes a low-pass; ``hi_hz`` at or above Nyquist minus the transition makes a
        high-pass.
    transition_hz : float, optional
        Width of each transition band (default: a quarter of the pass band, within
        [300 Hz, 3 kHz] and at most the room the band leaves to 0 and Nyquist).
    atten_db : float
        Stop-band attenuation (default 60 dB).

    Returns
    -------
    numpy.ndarray
        Read-only taps; their group delay is ``(len - 1) // 2`` samples exactly.

    Examples
    --------
    >>> h = bandpass_taps(44100.0, 14000.0, 18000.0)
    >>> len(h) % 2, bool(abs(np.abs(np.fft.rfft(h, 8192))[int(16000 / 44100 * 8192)] - 1) < 1e-3)
    (1, True)
    """
    fs = V.sample_rate(fs)
    nyq = 0.5 * fs
    lo = V.positive("lo_hz", lo_hz, allow_zero=True)
    hi = V.positive("hi_hz", hi_hz)
    if not lo < hi:
        raise V.InvalidParameterError(f"lo_hz={lo_hz!r} must be below hi_hz={hi_hz!r}")
    if transition_hz is None:
        tw = min(3000.0, max(300.0, 0.25 * (hi - lo)))
    else:
        tw = V.positive("transition_hz", transition_hz)
    high_pass_only = hi + tw >= nyq
    low_pass_only = lo - tw <= 0.0
    if low_pass_only and lo > 0.0:
        tw = lo  # the lower transition may reach 0 Hz but not beyond
        low_pass_only = False
    if high_pass_only and hi < nyq:
        tw_hi = nyq - hi
    else:
        tw_hi = tw
    width = min(tw, tw_hi) if not (high_pass_only or low_pass_only) else tw
    # Kaiser design: length from the attenuation and the narrowest transition.
    n = int(math.ceil((atten_db - 7.95) / (14.36 * width / fs))) + 1
    n = max(n | 1, 9)
    beta = _kaiser_beta(atten_db)
    if lo <= 0.0 and high_pass_only:
        h = np.zeros(n)
        h[n // 2] = 1.0
    elif lo <= 0.0:
        h = _firwin_kaiser(n, [hi + 0.5 * tw], beta, fs, pass_zero=True)
    elif high_pass_only:
        h = _firwin_kaiser(n, [lo - 0.5 * tw], beta, fs, pass_zero=False)
    else:
        edges = [lo - 0.5 * tw, hi + 0.5 * tw_hi]
        h = _firwin_kaiser(n, edges, beta, fs, pass_zero=False)
    h = np.ascontiguousarray(h, dtype=np.float64)
    h.flags.writeable = False
    return h


def _kaiser_beta(atten_db: float) -> float:
    """Kaiser window parameter for a stop-band attenuation in dB (``scipy.signal.kaiser_beta``)."""
    if atten_db > 50:
        return 0.1102 * (atten_db - 8.7)
    if atten_db > 21:
        return 0.5842 * (atten_db - 21) ** 0.4 + 0.07886 * (atten_db - 21)
    return 0.0


def _firwin_kaiser(
    n: int, cutoff_hz: list[float], beta: float, fs: float, *, pass_zero: bool
) -> np.ndarray:
    """``scipy.signal.firwin(n, cutoff_hz, window=("kaiser", beta), fs=fs, pass_zero=...)``.

    The same window method (ideal band responses as sums of sincs, times the symmetric
    Kaiser window, scaled to unit gain at the centre of the first pass band), written out
    so that the detector does not import ``scipy.signal`` (~0.7-1 s with ``scipy.stats``,
    which it pulls in). Equal to scipy's taps within 2.3e-16 of the largest tap (the
    window's Bessel function: ``numpy.i0`` against ``scipy.special.i0``; tested).
    """
    cutoff = np.asarray(cutoff_hz, dtype=np.float64) / (0.5 * fs)
    pass_nyquist = (cutoff.size % 2 == 0) == pass_zero
    cutoff = np.concatenate((np.zeros(int(pass_zero)), cutoff, np.ones(int(pass_nyquist))))
    bands = cutoff.reshape(-1, 2)
    m = np.arange(0, n, dtype=np.float64) - 0.5 * (n - 1)
    h = np.zeros(n)
    for left, right in bands:
        h += right * np.sinc(right * m)
        h -= left * np.sinc(left * m)
    h *= np.kaiser(n, beta)
    left, right = bands[0]
    f_scale = 0.0 if left == 0 else (1.0 if right == 1 else 0.5 * (left + right))
    return h / np.sum(h * np.cos(np.pi * m * f_scale))


def bandlimit(x: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """``x`` through the linear-phase FIR ``taps`` with its group delay removed.

    Output sample ``n`` is ``sum_k taps[k] x[n + h - k]`` with ``h = (len(taps) - 1) //
    2`` (samples outside ``x`` count as zero): the causal filter's output ``h`` samples
    later, so a symmetric filter leaves every arrival at its place.

    Examples
    --------
    >>> x = np.zeros(64); x[20] = 1.0
    >>> y = bandlimit(x, np.array([0.25, 0.5, 0.25]))
    >>> y[19:22].tolist()
    [0.25, 0.5, 0.25]
    """
    h = np.asarray(taps, dtype=np.float64)
    if h.ndim != 1 or len(h) % 2 != 1:
        raise V.InvalidParameterError(f"taps must be 1-D of odd length, got shape {h.shape}")
    x = np.asarray(x, dtype=np.float64)
    if len(x) == 0:
        return x.copy()
    if len(h) == 1:
        return h[0] * x
    half = (len(h) - 1) // 2
    # Direct convolution for short stretches (the edge fits' few hundred samples): the
    # FFT's set-up costs more than the products there.
    if len(x) * len(h) > 1 << 20:
        from scipy.signal import oaconvolve  # deferred: scipy.signal costs ~0.7-1 s to import

        y = oaconvolve(x, h, mode="full")
    else:
        y = np.convolve(x, h)
    return np.ascontiguousarray(y[half : half + len(x)])


def clip_mask(
    x: np.ndarray,
    *,
    rel_tol: float = 1e-4,
    min_run: int = 2,
    min_count: int = 8,
    max_gap: int = 64,
) -> np.ndarray:
    """Boolean mask of clipped samples: runs at the recording's extreme values.

    A rail (the maximum, or the minimum) is clipped when at least one run of ``min_run``
    consecutive samples lies within ``rel_tol`` of the peak-to-peak range of it (an
    unclipped tone or sweep, sampled above twice its frequency, does not stay at its crest
    for two samples, a clipped one does somewhere), or when ``min_count`` samples or more
    are exactly at it (a clipped 17-20 kHz sweep at 44.1 kHz touches the rail one sample
    per half cycle and may never show a run; a sampled unclipped signal reaches its exact
    extreme once). Then every sample at that rail is clipped. Each rail is tested on its
    own (converters and limiters clip asymmetrically, DC shifts the rails).

    Examples
    --------
    >>> t = np.arange(400) / 44100.0
    >>> x = np.sin(2 * np.pi * 1000 * t)
    >>> int(clip_mask(x).sum()), int(clip_mask(np.clip(x, -0.5, 0.5)).sum()) > 100
    (0, True)
    """
    x = np.asarray(x)
    if x.dtype not in (np.float32, np.float64):
        x = x.astype(np.float64)
    mask = np.zeros(len(x), dtype=bool)
    if len(x) < min_run:
        return mask
    hi, lo = float(np.max(x)), float(np.min(x))
    span = hi - lo
    if span <= 0.0:
        return mask
    tol = rel_tol * span
    # float32 samples compared in float32 with thresholds that compare as the float64
    # ones do (no float64 copy of a long recording)
    near_hi = np.flatnonzero(x >= _threshold(hi - tol, x.dtype, up=True))
    near_lo = np.flatnonzero(x <= _threshold(lo + tol, x.dtype, up=False))
    for idx, rail in ((near_hi, hi), (near_lo, lo)):
        if rail == 0.0 or len(idx) < min_run:
            continue  # digital silence at a rail is not clipping
        # a run of min_run consecutive indices among the (few) samples at the rail
        step = np.diff(idx) == 1
        if (
            min_run <= 1
            or _runs_at_least(step, min_run - 1).any()
            or _touches(idx[x[idx] == rail], min_count, max_gap)
        ):
            mask[idx] = True
    return mask


def _touches(at: np.ndarray, min_count: int, max_gap: int) -> bool:
    """Whether ``min_count`` of the sorted indices ``at`` follow one another, each less
    than ``max_gap`` after the one before (a sustained stretch of rail touches)."""
    if len(at) < min_count:
        return False
    if min_count <= 1:
        return True
    return bool(_runs_at_least(np.diff(at) < max_gap, min_count - 1).any())


def _threshold(t: float, dtype: np.dtype, *, up: bool):
    """A threshold of ``dtype`` that compares with samples of that dtype as ``t`` (float64)
    does: for float32, the nearest float32 at or above ``t`` (``up``) or at or below it
    (a float32 array compared with a Python float compares in float32, NEP 50)."""
    if dtype != np.float32:
        return t
    t32 = np.float32(t)
    if up and float(t32) < t:
        t32 = np.nextafter(t32, np.float32(np.inf))
    elif not up and float(t32) > t:
        t32 = np.nextafter(t32, np.float32(-np.inf))
    return t32


def _runs_at_least(m: np.ndarray, k: int) -> np.ndarray:
    """Samples of ``m`` that lie in runs of ``True`` at least ``k`` long."""
    if k <= 1:
        return m.copy()
    d = np.diff(np.concatenate(([0], m.astype(np.int8), [0])))
    starts = np.flatnonzero(d == 1)
    stops = np.flatnonzero(d == -1)
    out = np.zeros(len(m), dtype=bool)
    for s, e in zip(starts, stops, strict=True):
        if e - s >= k:
            out[s:e] = True
    return out


def dilate(mask: np.ndarray, half: int) -> np.ndarray:
    """``mask`` widened by ``half`` samples on each side (a filter's reach).

    Examples
    --------
    >>> dilate(np.array([0, 0, 0, 1, 0, 0, 0], bool), 1).astype(int).tolist()
    [0, 0, 1, 1, 1, 0, 0]
    """
    m = np.asarray(mask, dtype=bool)
    if half <= 0 or not m.any():
        return m.copy()
    c = np.concatenate(([0], np.cumsum(m, dtype=np.int64)))
    n = len(m)
    i = np.arange(n)
    return (c[np.minimum(i + half + 1, n)] - c[np.maximum(i - half, 0)]) > 0


def percentile(a: np.ndarray, q: float, *, axis: int | None = None) -> np.ndarray | float:
    """``numpy.percentile(a, q, axis=axis)`` (method ``linear``) of finite values.

    The same order statistics (by ``numpy.partition``) and the same interpolation
    arithmetic, so the same numbers (tested); written out because ``numpy.percentile``
    calls ``numpy.unique``, which imports ``numpy.ma`` on first use (~20-60 ms of a
    short command's start-up). ``axis`` is None (the whole array, flattened) or the last
    axis of a 2-D array.

    Examples
    --------
    >>> percentile(np.array([4.0, 1.0, 3.0, 2.0]), 20.0)
    1.6
    """
    a = np.asarray(a, dtype=np.float64)
    if axis is None:
        a = a.ravel()
    elif axis not in (-1, a.ndim - 1):
        raise V.InvalidParameterError(f"axis={axis!r} must be None or the last axis")
    n = a.shape[-1]
    if n == 0:
        raise V.InvalidParameterError("percentile of an empty array")
    virtual = (n - 1) * (float(q) / 100.0)
    if virtual >= n - 1:
        lo_i = hi_i = n - 1
    else:
        lo_i = max(int(math.floor(virtual)), 0)
        hi_i = lo_i + 1
    gamma = virtual - math.floor(virtual) if virtual < n - 1 else 0.0
    part = np.partition(a, sorted({0, n - 1, lo_i, hi_i}), axis=-1)
    lo_v, hi_v = part[..., lo_i], part[..., hi_i]
    diff = hi_v - lo_v
    out = hi_v - diff * (1.0 - gamma) if gamma >= 0.5 else lo_v + diff * gamma
    return float(out) if axis is None else np.asarray(out, dtype=np.float64)


def active_floor(
    e: np.ndarray, *, q: float = 20.0, rel_zero: float = 1e-12, min_live: float = 0.5
) -> float:
    """Mean noise level of a band-energy series, from frames that hold any signal.

    The ``q``-th percentile of the frames above ``rel_zero`` times the largest, divided
    by ``-ln(1 - q/100)``: the mean of an exponential variable (the law of one noise-only
    DFT bin's energy) whose ``q``-th percentile that is. Frames of digital silence (exact
    zeros, or rounding residue of them) are left out when at least ``min_live`` of the
    frames hold signal; otherwise the signal is what is rare (a noiseless render: zeros
    with a beep in them) and every frame counts. With no silent frames it equals the
    plain estimate. Returns 0 for a silent series.

    Examples
    --------
    >>> e = np.random.default_rng(0).exponential(2.0, 10000)
    >>> round(active_floor(e), 1), round(active_floor(np.concatenate([np.zeros(9000), e])), 1)
    (2.0, 2.0)
    """
    e = np.asarray(e, dtype=np.float64)
    if len(e) == 0:
        return 0.0
    top = float(np.max(e))
    if top <= 0.0:
        return 0.0
    live = e[e > rel_zero * top]
    if len(live) < min_live * len(e):
        live = e
    return float(percentile(live, q)) / -math.log(1.0 - q / 100.0)


def local_floor(
    e: np.ndarray,
    *,
    block: int,
    q: float = 20.0,
    min_live: float = 0.25,
    silent: str = "whole",
) -> np.ndarray:
    """Per-frame noise level: :func:`active_floor` of blocks of ``block`` frames.

    Each block's level is assigned to its centre and linearly interpolated between
    centres; a block with fewer than ``min_live`` of its frames holding signal (mostly
    digital silence; :func:`live_frames`) takes the level of the whole series
    (``silent="whole"``), or is left out of the interpolation (``"skip"``: the live
    blocks' levels, held flat beyond the first and the last; the whole series' level
    where no block is live), so that its neighbours keep their own level.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> e = np.concatenate([rng.exponential(1.0, 4000), rng.exponential(16.0, 4000)])
    >>> f = local_floor(e, block=1000)
    >>> bool(0.8 < f[500] < 1.2), bool(13 < f[7500] < 20)
    (True, True)
    """
    if silent not in ("whole", "skip"):
        raise V.InvalidParameterError(f"silent must be 'whole' or 'skip', got {silent!r}")
    e = np.asarray(e, dtype=np.float64)
    n = len(e)
    whole = active_floor(e, q=q)
    block = V.positive_int("block", block)
    if n <= block:
        return np.full(n, whole)
    n_b = -(-n // block)
    top = float(np.max(e)) if n else 0.0
    lengths = np.minimum(n - np.arange(n_b) * block, block)
    centres = np.arange(n_b) * block + 0.5 * (lengths - 1)
    levels = np.full(n_b, whole)
    own = _live_blocks(e, block=block, min_live=min_live, top=top)  # a level of their own
    # Whole blocks with every frame live (the usual case) in one call: the same
    # percentile along an axis as one block at a time, so the same numbers (tested).
    n_full = n // block
    full = e[: n_full * block].reshape(n_full, block)
    all_live = np.all(full > 1e-12 * top, axis=1)
    if block >= 8 and all_live.any():
        pct = percentile(full[all_live], q, axis=1)
        levels[:n_full][all_live] = pct / -math.log(1.0 - q / 100.0)
    for b in np.flatnonzero(own).tolist():
        if b < n_full and all_live[b] and block >= 8:
            continue
        seg = e[b * block : min(n, (b + 1) * block)]
        levels[b] = float(percentile(seg[seg > 1e-12 * top], q)) / -math.log(1.0 - q / 100.0)
    if silent == "skip" and own.any() and not own.all():
        return np.interp(np.arange(n), centres[own], levels[own])
    return np.interp(np.arange(n), centres, levels)


def live_frames(e: np.ndarray, *, block: int, min_live: float = 0.25) -> np.ndarray:
    """Frames of ``e`` in the stretches :func:`local_floor` gives a level of their own.

    A stretch of ``block`` frames is live when at least ``max(8, min_live * its
    length)`` of its frames hold signal (over ``1e-12`` of the largest); the others
    (mostly digital silence) take the whole series' level there, which is no level of
    the recording's own. A series no longer than ``block`` is one stretch with the whole
    series' level: every frame counts.

    Examples
    --------
    >>> e = np.concatenate([np.zeros(3000), np.ones(5000)])
    >>> m = live_frames(e, block=1000)
    >>> int(m.sum()), bool(m[:3000].any())
    (5000, False)
    """
    e = np.asarray(e, dtype=np.float64)
    n = len(e)
    block = V.positive_int("block", block)
    if n <= block:
        return np.ones(n, dtype=bool)
    live = _live_blocks(e, block=block, min_live=min_live, top=float(np.max(e)))
    return np.repeat(live, np.minimum(n - np.arange(0, n, block), block))


def _live_blocks(e: np.ndarray, *, block: int, min_live: float, top: float) -> np.ndarray:
    """Per stretch of ``block`` frames of ``e`` (the last one shorter): whether at least
    ``max(8, min_live * its length)`` of them lie over ``1e-12 * top`` (the one rule of
    :func:`local_floor` and :func:`live_frames`)."""
    starts = np.arange(0, len(e), block)
    lengths = np.minimum(len(e) - starts, block)
    counts = np.add.reduceat((e > 1e-12 * top).astype(np.int64), starts)
    return counts >= np.maximum(8, min_live * lengths)


def out_of_band_ratio(x: np.ndarray, taps: np.ndarray, y: np.ndarray | None = None) -> float:
    """Energy of ``x`` removed by band-limiting over the energy kept (linear).

    ``y`` is ``bandlimit(x, taps)`` when already computed. A ratio far above 1 means the
    recording is dominated by DC, hum, low-frequency or out-of-band sound.

    Examples
    --------
    >>> t = np.arange(4410) / 44100.0
    >>> x = np.sin(2 * np.pi * 16000 * t) + 10 * np.sin(2 * np.pi * 100 * t)
    >>> round(out_of_band_ratio(x, bandpass_taps(44100.0, 14000.0, 18000.0)))
    100
    """
    x = np.asarray(x, dtype=np.float64)
    y = bandlimit(x, taps) if y is None else y
    # einsum, not BLAS: a multithreaded BLAS dot of 64k samples can wait milliseconds
    # for its threads on a busy machine.
    d = x - y
    kept = float(np.einsum("i,i->", y, y))
    removed = float(np.einsum("i,i->", d, d))
    return removed / kept if kept > 0 else (math.inf if removed > 0 else 0.0)
