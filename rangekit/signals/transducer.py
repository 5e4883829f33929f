"""Resonant transducer model for 40 kHz piezo transmitters and receivers.

Air-coupled 40 kHz piezo transducers (Murata MA40S4R/S class, used by Kim & Kim 2013
§V; the SRF02 uses one transducer to send and receive) are narrow mechanical resonators.
rangekit models each as the second-order band-pass resonator

    H(s) = (w0 / Q) s / (s^2 + (w0 / Q) s + w0^2),

unit gain at the resonance ``w0 = 2 pi f0`` and -3 dB bandwidth ``f0 / Q``. It is
discretised with the bilinear transform with both the centre and the -3 dB bandwidth
prewarped (the second-order peaking filter of Orfanidis, *Introduction to Signal
Processing*, §11.3; ``scipy.signal.iirpeak``), so the digital resonance sits exactly at
``f0`` and the digital -3 dB band is exactly ``f0 / Q`` wide at any rate.

The filter is causal: a transducer delays what passes through it (the group delay at
resonance is ``Q / (pi f0)``, 32 us = 11 mm of sound for Q = 4 at 40 kHz). Simulated
recordings put both transducers in the path; the matched-filter template can fold the
same responses in (:func:`rangekit.detect.matched.coded_template`), which removes that
delay from the arrival times. Without folding, the delay stays in the ranges as a bias
(tested in ``tests/detect/test_matched.py``).

The default ``Q = 4`` gives the element a -3 dB bandwidth of 10 kHz, the bandwidth
Kim & Kim 2013 §II-A quote for their emitted signal. A bare MA40S4 element may be
sharper: set Q from your transducer's datasheet.

Examples
--------
>>> t = Transducer()
>>> t.f0_hz, t.q, t.bandwidth_hz
(40000.0, 4.0, 10000.0)
>>> round(t.group_delay_s(fs=192000.0) * 1e6, 1)
31.5
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rangekit import _validate as V
from rangekit.errors import InvalidParameterError

__all__ = ["Transducer"]


@dataclass(frozen=True)
class Transducer:
    """A resonant band-pass transducer (second-order, unit gain at ``f0_hz``).

    Parameters
    ----------
    f0_hz : float
        Resonance frequency in Hz (default 40 kHz).
    q : float
        Quality factor, ``f0 / (-3 dB bandwidth)``, within [0.5, 100] (default 4).
    """

    f0_hz: float = 40000.0
    q: float = 4.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "f0_hz", V.positive("f0_hz", self.f0_hz))
        object.__setattr__(self, "q", V.in_range("q", self.q, 0.5, 100.0))

    @property
    def bandwidth_hz(self) -> float:
        """-3 dB bandwidth in Hz, ``f0 / Q``."""
        return self.f0_hz / self.q

    def coefficients(self, *, fs: float) -> tuple[np.ndarray, np.ndarray]:
        """Digital biquad ``(b, a)`` at rate ``fs``: peak gain 1 at f0, -3 dB band f0 / Q wide."""
        fs = V.sample_rate(fs)
        if self.f0_hz >= fs / 2:
            raise InvalidParameterError(
                f"transducer f0_hz={self.f0_hz:g} Hz is above the Nyquist frequency of fs={fs:g} Hz"
            )
        w0 = 2.0 * math.pi * self.f0_hz / fs
        bw = min(self.bandwidth_hz, 0.99 * fs / 2)
        beta = math.tan(math.pi * bw / fs)
        g = 1.0 / (1.0 + beta)
        b = (1.0 - g) * np.array([1.0, 0.0, -1.0])
        a = np.array([1.0, -2.0 * g * math.cos(w0), 2.0 * g - 1.0])
        return b, a

    def apply(self, x: np.ndarray, *, fs: float) -> np.ndarray:
        """Filter ``x`` (1-D, or 2-D along the last axis) through the transducer, causally."""
        from scipy.signal import lfilter

        b, a = self.coefficients(fs=fs)
        return lfilter(b, a, np.asarray(x, dtype=np.float64), axis=-1)

    def group_delay_s(self, *, fs: float, f_hz: float | None = None) -> float:
        """Group delay in seconds at ``f_hz`` (default the resonance) at rate ``fs``."""
        from scipy.signal import group_delay

        b, a = self.coefficients(fs=fs)
        f = self.f0_hz if f_hz is None else V.positive("f_hz", f_hz)
        _, gd = group_delay((b, a), w=[f], fs=fs)
        return float(gd[0]) / fs


def apply_chain(x: np.ndarray, transducers, *, fs: float) -> np.ndarray:
    """Pass ``x`` through each transducer in ``transducers`` (None entries are skipped)."""
    y = np.asarray(x, dtype=np.float64)
    for t in transducers:
        if t is not None:
            y = t.apply(y, fs=fs)
    return y
