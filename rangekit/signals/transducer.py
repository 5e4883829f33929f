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
Kim & Kim 2013 §II-A quote for their emitted signal. Real MA40S4-class elements are
sharper (Q of the order of 10-20; ``../shared/REFERENCES.md``), and no datasheet gives Q
to the precision a millimetre needs: one-way ranging therefore estimates Q and f0 from
each recording (:mod:`rangekit.detect.pathfit`) rather than trusting this model's Q.

Two further models, **not** rangekit's resonator, exist to test that estimate on
transducers it does not describe exactly (``docs/theory/ultrasonic.md``):
:class:`BandpassTransducer` (a Butterworth band-pass of any order with the same -3 dB
band) and :class:`CoupledTransducer` (two stagger-tuned resonators in series: a flat or
double-humped pass band, like an element with a second mode nearby or a tuned
receiver). Both have ``apply``, ``f0_hz`` and ``q`` like :class:`Transducer`, so the
simulators accept them.

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

__all__ = ["BandpassTransducer", "CoupledTransducer", "Transducer"]


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

    def response(self, f_hz, *, fs: float) -> np.ndarray:
        """Complex frequency response of the digital filter at ``f_hz`` (array)."""
        from scipy.signal import freqz

        b, a = self.coefficients(fs=fs)
        return freqz(b, a, worN=np.atleast_1d(np.asarray(f_hz, dtype=np.float64)), fs=fs)[1]


def _sos_group_delay(sos: np.ndarray, f_hz: float, fs: float) -> float:
    """Group delay (s) of a second-order-sections filter at ``f_hz`` (numerical phase slope)."""
    from scipy.signal import sosfreqz

    df = 1e-3 * f_hz
    _, h = sosfreqz(sos, worN=np.array([f_hz - df, f_hz + df]), fs=fs)
    dphi = np.angle(h[1] / h[0])
    return float(-dphi / (2.0 * math.pi * 2.0 * df))


@dataclass(frozen=True)
class BandpassTransducer:
    """A Butterworth band-pass of order ``2 * order``: -3 dB band ``f0 / q``, centre ``f0``.

    Not rangekit's resonator (for ``order >= 2``): its pass band is flatter, its skirts
    steeper and its group delay at the centre larger (about 1.4x a resonator of the same
    band for ``order = 2``). Used to test timing on a transducer model the estimator does
    not share. The band edges are placed about ``f0`` geometrically (``f_lo f_hi =
    f0^2``, ``f_hi - f_lo = f0 / q``); unit gain at ``f0``.

    Parameters
    ----------
    f0_hz : float
        Centre frequency in Hz (default 40 kHz).
    q : float
        ``f0`` over the -3 dB bandwidth, within [0.5, 100] (default 4).
    order : int
        Butterworth prototype order (the filter has ``2 * order`` poles; default 2).

    Examples
    --------
    >>> t = BandpassTransducer(q=10.0)
    >>> round(float(abs(t.response([40000.0], fs=192000.0)[0])), 6)
    1.0
    >>> round(t.group_delay_s(fs=192000.0) / Transducer(q=10.0).group_delay_s(fs=192000.0), 2)
    1.42
    """

    f0_hz: float = 40000.0
    q: float = 4.0
    order: int = 2

    def __post_init__(self) -> None:
        object.__setattr__(self, "f0_hz", V.positive("f0_hz", self.f0_hz))
        object.__setattr__(self, "q", V.in_range("q", self.q, 0.5, 100.0))
        object.__setattr__(self, "order", V.positive_int("order", self.order))

    @property
    def bandwidth_hz(self) -> float:
        """-3 dB bandwidth in Hz, ``f0 / q``."""
        return self.f0_hz / self.q

    def sos(self, *, fs: float) -> np.ndarray:
        """Second-order sections at rate ``fs`` (``scipy.signal.butter``)."""
        from scipy.signal import butter

        fs = V.sample_rate(fs)
        bw = self.bandwidth_hz
        lo = 0.5 * (-bw + math.sqrt(bw * bw + 4.0 * self.f0_hz**2))
        if lo + bw >= fs / 2:
            raise InvalidParameterError(
                f"transducer band up to {lo + bw:g} Hz is above the Nyquist frequency "
                f"of fs={fs:g} Hz"
            )
        return butter(self.order, [lo, lo + bw], btype="bandpass", fs=fs, output="sos")

    def apply(self, x: np.ndarray, *, fs: float) -> np.ndarray:
        """Filter ``x`` (1-D, or 2-D along the last axis) through the transducer, causally."""
        from scipy.signal import sosfilt

        return sosfilt(self.sos(fs=fs), np.asarray(x, dtype=np.float64), axis=-1)

    def response(self, f_hz, *, fs: float) -> np.ndarray:
        """Complex frequency response at ``f_hz`` (array)."""
        from scipy.signal import sosfreqz

        f = np.atleast_1d(np.asarray(f_hz, dtype=np.float64))
        return sosfreqz(self.sos(fs=fs), worN=f, fs=fs)[1]

    def group_delay_s(self, *, fs: float, f_hz: float | None = None) -> float:
        """Group delay in seconds at ``f_hz`` (default the centre) at rate ``fs``."""
        f = self.f0_hz if f_hz is None else V.positive("f_hz", f_hz)
        return _sos_group_delay(self.sos(fs=fs), f, fs)


@dataclass(frozen=True)
class CoupledTransducer:
    """Two resonators of quality factor ``q`` at ``f0 (1 -+ split / 2)``, in series.

    Stagger tuning flattens the pass band (``split = 1 / q``, the default, puts the two
    resonances half a band either side of ``f0``: nearly maximally flat) or splits it into
    two humps (larger ``split``), like a piezo element with a second mode close to its
    first or a receiver tuned off the element's resonance. Not rangekit's resonator: the
    one-way estimator models every element as one resonator. Unit gain at ``f0``.

    Parameters
    ----------
    f0_hz : float
        Centre frequency in Hz (default 40 kHz).
    q : float
        Quality factor of each resonator, within [0.5, 100] (default 4).
    split : float, optional
        Separation of the two resonances as a fraction of ``f0`` (default ``1 / q``).

    Examples
    --------
    >>> t = CoupledTransducer(q=10.0)
    >>> round(float(abs(t.response([40000.0], fs=192000.0)[0])), 6)
    1.0
    """

    f0_hz: float = 40000.0
    q: float = 4.0
    split: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "f0_hz", V.positive("f0_hz", self.f0_hz))
        object.__setattr__(self, "q", V.in_range("q", self.q, 0.5, 100.0))
        split = 1.0 / self.q if self.split is None else self.split
        object.__setattr__(self, "split", V.in_range("split", split, 0.0, 0.5))

    def _parts(self) -> tuple[Transducer, Transducer]:
        s = float(self.split)
        return (
            Transducer(self.f0_hz * (1.0 - 0.5 * s), self.q),
            Transducer(self.f0_hz * (1.0 + 0.5 * s), self.q),
        )

    def _gain(self, fs: float) -> float:
        a, b = self._parts()
        return float(abs(a.response([self.f0_hz], fs=fs)[0] * b.response([self.f0_hz], fs=fs)[0]))

    def apply(self, x: np.ndarray, *, fs: float) -> np.ndarray:
        """Filter ``x`` (1-D, or 2-D along the last axis) through the transducer, causally."""
        a, b = self._parts()
        return b.apply(a.apply(x, fs=fs), fs=fs) / self._gain(fs)

    def response(self, f_hz, *, fs: float) -> np.ndarray:
        """Complex frequency response at ``f_hz`` (array)."""
        a, b = self._parts()
        return a.response(f_hz, fs=fs) * b.response(f_hz, fs=fs) / self._gain(fs)

    def group_delay_s(self, *, fs: float, f_hz: float | None = None) -> float:
        """Group delay in seconds at ``f_hz`` (default the centre) at rate ``fs``."""
        a, b = self._parts()
        f = self.f0_hz if f_hz is None else V.positive("f_hz", f_hz)
        return a.group_delay_s(fs=fs, f_hz=f) + b.group_delay_s(fs=fs, f_hz=f)


def apply_chain(x: np.ndarray, transducers, *, fs: float) -> np.ndarray:
    """Pass ``x`` through each transducer in ``transducers`` (None entries are skipped)."""
    y = np.asarray(x, dtype=np.float64)
    for t in transducers:
        if t is not None:
            y = t.apply(y, fs=fs)
    return y
