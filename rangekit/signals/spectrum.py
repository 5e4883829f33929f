"""Spectral measures of probe signals: RMS bandwidth and noise-equivalent bandwidth.

Both are defined on the one-sided power spectrum ``|S(f)|^2`` of a real signal (computed
with enough zero padding that the sums approximate the integrals).

Examples
--------
>>> import numpy as np
>>> fs = 192000.0
>>> t = np.arange(960) / fs
>>> x = np.sin(2 * np.pi * 40000 * t) * np.hanning(960)
>>> round(spectral_centroid_hz(x, fs=fs))
40000
>>> 100 < rms_bandwidth_hz(x, fs=fs) < noise_bandwidth_hz(x, fs=fs) < 1000
True
"""

from __future__ import annotations

import math

import numpy as np

from rangekit import _validate as V

__all__ = ["noise_bandwidth_hz", "power_spectrum", "rms_bandwidth_hz", "spectral_centroid_hz"]


def power_spectrum(x: np.ndarray, *, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """``(f, |S(f)|^2)`` on a grid at least 8x finer than ``fs / len(x)`` (one-sided)."""
    fs = V.sample_rate(fs)
    x = V.signal_1d("x", x)
    n = 1 << int(math.ceil(math.log2(8 * len(x) + 8)))
    return np.fft.rfftfreq(n, 1.0 / fs), np.abs(np.fft.rfft(x, n)) ** 2


def spectral_centroid_hz(x: np.ndarray, *, fs: float) -> float:
    """Power-weighted mean frequency ``sum f |S|^2 / sum |S|^2`` in Hz."""
    f, p = power_spectrum(x, fs=fs)
    return float(f @ p / p.sum())


def rms_bandwidth_hz(x: np.ndarray, *, fs: float, about_centre: bool = True) -> float:
    """RMS bandwidth in Hz: ``beta^2 = sum (f - f_c)^2 |S|^2 / sum |S|^2``.

    ``about_centre=True`` takes ``f_c`` = the spectral centroid (the bandwidth of the
    complex envelope, which sets the delay bound when the carrier phase is unknown);
    ``about_centre=False`` takes ``f_c = 0`` (Gabor's bandwidth, the bound with a known
    phase).
    """
    f, p = power_spectrum(x, fs=fs)
    fc = float(f @ p / p.sum()) if about_centre else 0.0
    return math.sqrt(float(((f - fc) ** 2) @ p / p.sum()))


def noise_bandwidth_hz(x: np.ndarray, *, fs: float) -> float:
    """Noise-equivalent bandwidth in Hz: ``sum |S|^2 df / max |S|^2``.

    The width of the rectangular band, at the spectrum's peak level, that holds the same
    power. rangekit's "in-band SNR" of an ultrasonic burst counts the noise inside this
    width (see ``docs/theory/ultrasonic.md``).
    """
    f, p = power_spectrum(x, fs=fs)
    return float(p.sum() * (f[1] - f[0]) / p.max())
