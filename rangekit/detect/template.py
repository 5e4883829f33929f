"""Arrivals of any probe signal (a sweep, a chirp, a lab's own file) by matched filtering.

The beep detectors look for rangekit's burst train; this one finds every arrival of a
given :class:`~rangekit.signals.probe.Probe` in a channel:

1. **Template**: the probe at the recording's rate (:meth:`Probe.at_rate`: polyphase
   resampling when the rates differ, an error when its band does not fit).
2. **Analytic matched filter** (:class:`rangekit.detect.matched.MatchedFilter`,
   overlap-save): the envelope ``|c|`` of the correlation with the analytic template.
3. **Arrivals**: local maxima of the envelope above ``max(k_detect, sqrt(2 ln(n /
   FALSE_ALARM)))`` times the noise's Rayleigh scale (``n`` samples of noise alone give
   a false arrival with probability <= ``FALSE_ALARM`` = 1e-3), taken strongest first;
   a peak within ``min_separation_s`` of a stronger accepted one belongs to that arrival
   (its reverberation or side lobes). With ``expected`` only the ``expected`` strongest
   arrivals are kept.
4. **First path** (:func:`rangekit.detect.matched.first_path`): within ``lookback_s``
   before each arrival's strongest peak, the earliest peak above ``max(k_noise * noise,
   rel_threshold * strongest)`` that is not a side lobe of the strongest path. A sweep's
   correlation peak is sharp, but in a room the reflections pile up later peaks that can
   be stronger than the direct one; the first path is the direct sound.
5. **Sub-sample lag** by a Gaussian fit of the envelope (:func:`interp_peak`); 1-sigma
   from the Cramér–Rao bound ``1 / (2 pi beta snr)`` (``beta``: RMS bandwidth of the
   template about its centroid).

The onset of an arrival is the float sample index at which the probe's sample 0 arrived.

Examples
--------
>>> from rangekit.signals.probe import linear_sweep
>>> p = linear_sweep(17000.0, 20000.0, 0.1)
>>> x = np.zeros(20000)
>>> x[3000 : 3000 + 4410] += p.samples
>>> x[12000 : 12000 + 4410] += 0.01 * p.samples
>>> a = detect_template(x, fs=44100.0, probe=p)
>>> a.onset.round(3).tolist()
[3000.0, 12000.0]
"""

from __future__ import annotations

import functools
import math

import numpy as np

from rangekit import _validate as V
from rangekit.detect.matched import (
    DEFAULT_BLOCK,
    DEFAULT_K_DETECT,
    DEFAULT_K_NOISE,
    DEFAULT_REL_THRESHOLD,
    NOISE_FLOOR_REL,
    MatchedFilter,
    first_path,
    noise_level,
)
from rangekit.errors import InvalidParameterError
from rangekit.signals.probe import Probe
from rangekit.signals.spectrum import rms_bandwidth_hz
from rangekit.types import Arrivals

__all__ = ["DEFAULT_LOOKBACK_S", "FALSE_ALARM", "detect_template"]

#: Default time before an arrival's strongest peak searched for an earlier direct path, s
#: (20 ms: a reflection up to 6.9 m longer than the direct path).
DEFAULT_LOOKBACK_S = 0.020
#: Probability that a recording of noise alone yields an arrival (sets the detection
#: threshold together with the recording's length; see :func:`detect_template`).
FALSE_ALARM = 1e-3


def detect_template(
    x: np.ndarray,
    *,
    fs: float,
    probe: Probe,
    expected: int | None = None,
    min_separation_s: float | None = None,
    lookback_s: float = DEFAULT_LOOKBACK_S,
    k_noise: float = DEFAULT_K_NOISE,
    rel_threshold: float = DEFAULT_REL_THRESHOLD,
    k_detect: float = DEFAULT_K_DETECT,
    block: int = DEFAULT_BLOCK,
    what: str = "the recording",
) -> Arrivals:
    """Every arrival of ``probe`` in one channel, first path each, in time order.

    Parameters
    ----------
    x : ndarray
        One channel of the recording.
    fs : float
        Its sample rate in Hz (the probe is resampled to it).
    probe : Probe
        The emitted signal.
    expected : int, optional
        Keep only this many arrivals, the strongest (e.g. one per device of an exchange).
    min_separation_s : float, optional
        Shortest time between the starts of two arrivals, s; peaks closer to a stronger
        arrival belong to it. Default: the probe's duration (plays do not overlap).
    lookback_s : float
        How far before an arrival's strongest peak its direct path may lie (default
        20 ms); capped at half of ``min_separation_s``.
    k_noise, rel_threshold, k_detect : float
        Thresholds of :func:`rangekit.detect.matched.first_path`.
    block : int
        Overlap-save FFT size.
    what : str
        The recording, for error messages.

    Returns
    -------
    Arrivals
        ``detector="template"``; ``confidence`` is the first path's height over the
        arrival's strongest peak; ``burst_onsets[:, 0]`` repeats the onset.
    """
    fs = V.sample_rate(fs)
    x = V.signal_1d("x", x)
    if not isinstance(probe, Probe):
        raise InvalidParameterError(f"probe must be a Probe, got {type(probe).__name__}")
    if expected is not None:
        expected = V.positive_int("expected", expected)
    sep_s = probe.duration_s if min_separation_s is None else min_separation_s
    sep = max(1, int(round(V.positive("min_separation_s", sep_s) * fs)))
    look = int(round(V.positive("lookback_s", lookback_s, allow_zero=True) * fs))
    look = min(look, sep // 2)
    probe.check_fits(fs, what=what)
    if len(x) < 3:
        return _empty(fs)
    mf, self_resp, beta = _filter(probe, fs, block, look)
    c = mf.correlate(x)
    env = np.abs(c)
    noise = max(noise_level(env), NOISE_FLOOR_REL * float(env.max()))
    peaks = _local_maxima(env)
    # The noise envelope is Rayleigh: P(|c| > k noise) = exp(-k^2 / 2) per sample, so over
    # n samples a peak beyond sqrt(2 ln(n / FALSE_ALARM)) noise levels is a false alarm
    # with probability <= FALSE_ALARM (k_detect = 4.5 alone gives several per second).
    k_rec = max(k_detect, math.sqrt(2.0 * math.log(len(x) / FALSE_ALARM)))
    peaks = peaks[env[peaks] > k_rec * noise]
    if len(peaks) == 0:
        return _empty(fs)
    order = peaks[np.argsort(-env[peaks], kind="stable")]
    taken: list[int] = []
    for p in order.tolist():
        if all(abs(p - q) >= sep for q in taken):
            taken.append(p)
            if expected is not None and len(taken) == expected:
                break
    taken.sort()
    rows = []
    for q in taken:
        pk = first_path(
            c,
            lo=q - max(look, 1),  # first_path needs 3 lags; lookback_s=0 is legal
            hi=q + 2,
            noise=noise,
            k_noise=k_noise,
            rel_threshold=rel_threshold,
            k_detect=k_detect,
            self_response=self_resp,
        )
        if pk is None:  # cannot happen for a peak above k_detect * noise; kept for safety
            continue
        sigma = fs / (2.0 * math.pi * beta * pk.snr) if pk.snr > 0 else math.inf
        rows.append((pk.lag, sigma, 20.0 * math.log10(max(pk.snr, 1e-300)), pk.height / env[q]))
    if not rows:
        return _empty(fs)
    a = np.array(rows, dtype=np.float64)
    onset = a[:, 0]
    return Arrivals(
        onset, fs, a[:, 1], a[:, 2], np.minimum(a[:, 3], 1.0), onset[:, None].copy(), "template"
    )


@functools.lru_cache(maxsize=8)
def _filter(
    probe: Probe, fs: float, block: int, look: int
) -> tuple[MatchedFilter, np.ndarray, float]:
    """The probe's matched filter at ``fs``, its self response cut to the search's reach,
    and the template's RMS bandwidth (Hz, for the Cramér–Rao 1-sigma).

    Cached per probe (by identity) and rate: the channels of a recording share one filter.
    Only lags within ``look`` (plus a margin) of a path are ever compared with its side
    lobes, so the self response is cut there (a 1 s sweep's is two seconds long).
    """
    mf = MatchedFilter(probe.at_rate(fs), block=block)
    sr = mf.self_response
    mid = len(sr) // 2
    w = min(mid, look + 256)
    beta = rms_bandwidth_hz(mf.template, fs=fs)
    return mf, np.ascontiguousarray(sr[mid - w : mid + w + 1]), beta


def _local_maxima(env: np.ndarray) -> np.ndarray:
    """Indices of local maxima (``>=`` the left neighbour, ``>`` the right one)."""
    if len(env) < 3:
        return np.zeros(0, dtype=np.int64)
    mid = env[1:-1]
    return np.flatnonzero((mid >= env[:-2]) & (mid > env[2:])) + 1


def _empty(fs: float) -> Arrivals:
    return Arrivals.empty(fs=fs, n_bursts=1, detector="template")
