"""Cross-correlation beep detector: the BeepBeep baseline (Peng et al. 2007).

The recording is correlated with the analytic burst template ``env(t) exp(j 2 pi f t)`` by
FFT; the magnitudes at the burst places (k * spacing) are summed into the beep envelope
(coherent within a burst, non-coherent across bursts, so that a clock-rate difference
between player and recorder cannot make the bursts cancel). Beeps are
its peaks above ``threshold_db`` over the median envelope, taken greedily from the
strongest with suppression of +-(beep duration) around each (which also removes the
side lobes at +-k*spacing that a burst train's correlation has). The peak is refined by a
parabola through the three highest samples. Each beep's bursts are then checked at their
expected places (k * spacing): a beep with fewer than ``min_confidence`` of its bursts at
half the largest burst's amplitude or more is dropped (the burst-spacing check). The peak
time is the template's start, i.e. the onset of the first burst, with no offset to remove.

This is the baseline the change-point detector is compared against (``docs/accuracy.md``):
reflections that arrive during a burst move the correlation peak, where the change-point
detector's edge fit sees only the leading edge. Its arrivals carry the
``ambiguous_first_path`` flag when sound of the beep's band arrived before the chosen
peak (the strongest peak in a room is often a reflection).
"""

from __future__ import annotations

import math

import numpy as np

from rangekit import _validate as V
from rangekit.signals.beep import Beep, beep_continuous_analytic, check_beep_fits
from rangekit.types import Arrivals, flag_bit

__all__ = ["detect_xcorr"]


def detect_xcorr(
    x: np.ndarray,
    *,
    fs: float,
    beep: Beep | None = None,
    threshold_db: float = 20.0,
    max_beeps: int | None = None,
    min_confidence: float = 0.75,
) -> Arrivals:
    """Detect beep arrivals by matched filtering with the whole beep.

    Parameters
    ----------
    x : array_like, shape (n,)
        One channel of a recording.
    fs : float
        Sample rate in Hz.
    beep : Beep, optional
        The beep that was played.
    threshold_db : float
        Minimum peak height over the median of the correlation envelope, in dB.
    max_beeps : int, optional
        Keep at most this many (the strongest).
    min_confidence : float
        Drop beeps whose fraction of bursts with at least half the largest burst's matched
        amplitude (at the expected burst places) is below this: the burst-spacing check.

    Returns
    -------
    Arrivals
        One entry per beep, in time order.

    Examples
    --------
    >>> import numpy as np
    >>> from rangekit.signals import Beep, beep_waveform
    >>> b = Beep()
    >>> x = np.zeros(30000)
    >>> x[1000:1000 + b.duration_samples] = beep_waveform(b)
    >>> arr = detect_xcorr(x, fs=b.fs, beep=b)
    >>> bool(abs(arr.onset[0] - 1000) < 0.1)
    True
    """
    from scipy import fft as sfft

    beep = Beep() if beep is None else beep
    fs = V.sample_rate(fs)
    x = V.signal_1d("x", x, max_abs=V.MAX_SAMPLE_ABS)
    check_beep_fits(beep, fs=fs)
    threshold_db = V.in_range("threshold_db", threshold_db, -100.0, 200.0)
    min_confidence = V.in_range("min_confidence", min_confidence, 0.0, 1.0)
    if max_beeps is not None:
        max_beeps = V.positive_int("max_beeps", max_beeps)
    k_b = beep.n_bursts
    n_tmpl = int(math.ceil(beep.duration_s * fs))
    one = beep_continuous_analytic(np.arange(int(math.ceil(beep.burst_s * fs))) / fs, beep=beep)
    nfft = sfft.next_fast_len(len(x) + len(one))
    e1 = np.abs(sfft.ifft(sfft.fft(x, nfft) * np.conj(sfft.fft(one, nfft)))[: len(x)])
    # Bursts are summed non-coherently: a clock-rate difference of 100 ppm between player
    # and recorder turns the carrier phase by ~3 rad over three spacings, which would make
    # a coherent whole-beep correlation cancel at the true lag.
    env = np.zeros(len(x))
    for k in range(k_b):
        sh = int(round(k * beep.spacing_s * fs))
        if sh < len(x):
            env[: len(x) - sh] += e1[sh:]
    if len(x) < n_tmpl or not np.any(env > 0):
        return Arrivals.empty(fs=fs, n_bursts=k_b, detector="xcorr")
    noise = float(np.median(env))
    thr = noise * 10 ** (threshold_db / 20)
    excl = n_tmpl
    work = env.copy()
    peaks = []
    while True:
        i = int(np.argmax(work))
        if work[i] <= max(thr, 0.0) or (max_beeps is not None and len(peaks) >= max_beeps):
            break
        peaks.append(i)
        work[max(0, i - excl) : i + excl + 1] = 0.0
    peaks.sort()
    onset, sigma, snr = [], [], []
    # SNR as Arrivals documents it, a burst's power over the full-band noise power: x = A
    # Re(one) correlates to A E1 / 2 per burst (E1 the burst template's energy), white
    # noise of variance s2 to a complex Gaussian of E|z|^2 = s2 E1, whose magnitude
    # (Rayleigh) has its median at sqrt(ln 4 E|z|^2 / 2); so A^2 / 2 / s2 = 2 m^2 /
    # (E1 E|z|^2) with m the burst's peak magnitude (env / k_b; the bursts are summed)
    # and E|z|^2 = 2 median(e1)^2 / ln 4 (one burst's correlation: the beeps are sparse).
    e_one = float(np.sum(np.abs(one) ** 2))
    z2 = 2.0 * float(np.median(e1)) ** 2 / math.log(4.0)
    for i in peaks:
        if 0 < i < len(env) - 1:
            y0, y1, y2 = env[i - 1], env[i], env[i + 1]
            den = y0 - 2 * y1 + y2
            delta = 0.5 * (y0 - y2) / den if den < 0 else 0.0
            curv = -den / y1 if y1 > 0 else 0.0
        else:
            delta, curv = 0.0, 0.0
        onset.append(i + float(np.clip(delta, -0.5, 0.5)))
        # Output SNR of the matched filter; timing variance of a parabola fit ~ 1/(SNR*curv).
        snr_out = (env[i] / max(noise, 1e-300)) ** 2
        sigma.append(1.0 / math.sqrt(max(snr_out * curv, 1e-12)))
        m = env[i] / k_b
        snr.append(10 * math.log10(max(2.0 * m * m / max(e_one * z2, 1e-300), 1e-30)))
    onset = np.array(onset)
    bursts = onset[:, None] + np.arange(k_b)[None, :] * beep.spacing_s * fs
    conf = _burst_confidence(x, bursts, fs=fs, beep=beep)
    keep = conf >= min_confidence
    return Arrivals(
        onset[keep],
        fs,
        np.array(sigma)[keep],
        np.array(snr)[keep],
        conf[keep],
        bursts.reshape(len(onset), k_b)[keep],
        "xcorr",
        flags=_flags(x, onset[keep], fs=fs, beep=beep),
    )


def _flags(x: np.ndarray, onsets: np.ndarray, *, fs: float, beep: Beep) -> np.ndarray:
    """``ambiguous_first_path`` / ``reverb_limited`` from the band energy before each
    onset, and the tone precursor test (as for the change-point detector): the strongest
    correlation peak in a room is often a reflection, and the direct sound then shows
    before it."""
    from rangekit.detect._kernels import band_energy
    from rangekit.detect.changepoint import (
        HOP_S,
        WIN_S,
        _before_onset_flags,
        _stft_params,
        precursor_hits,
    )
    from rangekit.detect.condition import clip_mask

    n_win, hop = _stft_params(fs, WIN_S, HOP_S)
    e = band_energy(x, fs=fs, f_hz=np.array([beep.f_hz]), n_win=n_win, hop=hop)
    flags = np.array(
        [_before_onset_flags(e, t, hop=hop, n_win=n_win, fs=fs, quiet=0.0) for t in onsets],
        dtype=np.int64,
    )
    clipped = clip_mask(x)
    hit = precursor_hits(x, onsets, fs=fs, beep=beep, clipped=clipped if clipped.any() else None)
    return np.where(hit, flags | flag_bit("ambiguous_first_path"), flags)


def _burst_confidence(x: np.ndarray, bursts: np.ndarray, *, fs: float, beep: Beep) -> np.ndarray:
    """Fraction of each beep's bursts whose matched amplitude reaches half the largest.

    A beep played with another burst spacing correlates with the whole template where only
    some bursts line up; its other bursts then show little amplitude at their expected places.
    """
    n_b = int(math.ceil(beep.burst_s * fs))
    one = beep_continuous_analytic(np.arange(n_b) / fs, beep=beep)
    one_energy = float(np.sum(np.abs(one) ** 2))
    conf = np.zeros(len(bursts))
    for i, row in enumerate(bursts):
        amp = []
        for pos in np.rint(row).astype(np.int64):
            seg = x[max(pos, 0) : max(pos, 0) + n_b]
            amp.append(abs(np.dot(seg, np.conj(one[: len(seg)]))) / one_energy if len(seg) else 0.0)
        amp = np.asarray(amp)
        conf[i] = float(np.mean(amp >= 0.5 * amp.max())) if amp.max() > 0 else 0.0
    return conf
