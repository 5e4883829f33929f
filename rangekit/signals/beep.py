"""Tone-burst beeps for two-way acoustic ranging (Jiang et al. 2018, §4.3.1).

The seed beep is a train of identical tone bursts: 16 kHz, 4 bursts whose starts are
5000 samples apart at 44.1 kHz. Each burst is a sinusoid that starts at phase 0 at the
burst start, shaped by a raised-cosine (Tukey) taper at both ends.

The default burst length and taper were chosen with the accuracy harness
(``benchmarks/design_sweep.py``; numbers in ``docs/accuracy.md``).

Examples
--------
>>> from rangekit.signals import Beep, beep_waveform
>>> b = Beep()
>>> b.n_bursts, b.spacing, b.fs
(4, 5000, 44100.0)
>>> x = beep_waveform(b)
>>> len(x) == b.duration_samples
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from rangekit import _validate as V
from rangekit.errors import IncompatibleInputError, InvalidParameterError

if TYPE_CHECKING:
    from rangekit.signals.probe import Probe

__all__ = [
    "Beep",
    "beep_continuous",
    "beep_continuous_analytic",
    "beep_waveform",
    "burst_envelope",
    "check_beep_fits",
]

#: Default burst length in samples at the beep's sample rate (see docs/accuracy.md).
DEFAULT_BURST_LEN = 441
#: Default raised-cosine taper length in samples at each burst end (see docs/accuracy.md).
DEFAULT_TAPER = 22
#: Most bursts in a beep (``--bursts``): the detectors' work per beep grows with it, and
#: a real beep has a handful.
MAX_BURSTS = 64
#: Longest beep, s (``(n_bursts - 1) x spacing + burst_len`` at ``fs``): bounds the work
#: and memory spent per beep.
MAX_BEEP_S = 10.0


@dataclass(frozen=True)
class Beep:
    """Parameters of a tone-burst beep.

    Parameters
    ----------
    f_hz : float
        Tone frequency in Hz (default 16 kHz, Jiang 2018 §4.3.1).
    n_bursts : int
        Number of bursts (default 4).
    spacing : int
        Samples between the starts of consecutive bursts at ``fs`` (default 5000).
    burst_len : int
        Samples in one burst, tapers included.
    taper : int
        Samples of raised-cosine taper at each end of a burst (0 = rectangular).
    amplitude : float
        Peak amplitude in (0, 1].
    fs : float
        Sample rate in Hz at which the beep is defined and played (default 44.1 kHz).
    """

    f_hz: float = 16000.0
    n_bursts: int = 4
    spacing: int = 5000
    burst_len: int = DEFAULT_BURST_LEN
    taper: int = DEFAULT_TAPER
    amplitude: float = 0.9
    fs: float = 44100.0

    #: What kind of emitted signal this is (:data:`rangekit.signals.SIGNAL_KINDS`).
    kind: ClassVar[str] = "beep"

    def __post_init__(self) -> None:
        fs = V.sample_rate(self.fs)
        object.__setattr__(self, "fs", fs)
        object.__setattr__(self, "f_hz", V.positive("f_hz", self.f_hz))
        object.__setattr__(self, "n_bursts", V.positive_int("n_bursts", self.n_bursts))
        object.__setattr__(self, "spacing", V.positive_int("spacing", self.spacing))
        object.__setattr__(
            self, "burst_len", V.positive_int("burst_len", self.burst_len, minimum=8)
        )
        object.__setattr__(self, "taper", V.positive_int("taper", self.taper, minimum=0))
        if self.n_bursts > MAX_BURSTS:
            raise InvalidParameterError(f"n_bursts={self.n_bursts} must be <= {MAX_BURSTS}")
        span = (self.n_bursts - 1) * self.spacing + self.burst_len
        if span > MAX_BEEP_S * fs:
            raise InvalidParameterError(
                f"the beep lasts {span} samples at fs={fs:g} Hz, more than {MAX_BEEP_S:g} s "
                "(n_bursts, spacing or burst_len too large)"
            )
        amp = V.positive("amplitude", self.amplitude)
        if amp > 1.0:
            raise InvalidParameterError(f"amplitude={amp!r} must be <= 1 (full scale)")
        object.__setattr__(self, "amplitude", amp)
        if 2 * self.taper > self.burst_len:
            raise InvalidParameterError(
                f"taper={self.taper} must be at most half of burst_len={self.burst_len}"
            )
        if self.n_bursts > 1 and self.spacing <= self.burst_len:
            raise InvalidParameterError(
                f"spacing={self.spacing} must exceed burst_len={self.burst_len} "
                "(bursts must not overlap)"
            )
        if self.f_hz + self.edge_bandwidth_hz >= fs / 2:
            raise InvalidParameterError(
                f"f_hz={self.f_hz:g} Hz plus the taper's bandwidth "
                f"{self.edge_bandwidth_hz:.0f} Hz exceeds the Nyquist frequency {fs / 2:g} Hz "
                f"of fs={fs:g} Hz; lower f_hz or lengthen the taper"
            )

    # Derived quantities, all in seconds or Hz so that recordings at other rates can use them.
    @property
    def edge_bandwidth_hz(self) -> float:
        """Half-width of the band the burst edges occupy around ``f_hz`` (1 / taper duration).

        A rectangular burst (taper 0) is charged 1 / (burst duration) only, but its
        spectral splatter is wide; prefer a taper.
        """
        t = self.taper if self.taper > 0 else self.burst_len
        return self.fs / t

    @property
    def duration_samples(self) -> int:
        """Samples from the first burst start to the last burst end."""
        return (self.n_bursts - 1) * self.spacing + self.burst_len

    @property
    def spacing_s(self) -> float:
        """Burst start spacing in seconds."""
        return self.spacing / self.fs

    @property
    def burst_s(self) -> float:
        """Burst duration in seconds."""
        return self.burst_len / self.fs

    @property
    def taper_s(self) -> float:
        """Taper duration in seconds."""
        return self.taper / self.fs

    @property
    def duration_s(self) -> float:
        """Beep duration in seconds."""
        return self.duration_samples / self.fs

    # The emitted-signal interface shared with CodedBurst and Probe (rangekit.signals).
    def band(self) -> tuple[float, float]:
        """``(lo, hi)`` in Hz: the tone -+ the tapered edges' bandwidth.

        Examples
        --------
        >>> [round(f) for f in Beep().band()]
        [13995, 18005]
        """
        return (self.f_hz - self.edge_bandwidth_hz, self.f_hz + self.edge_bandwidth_hz)

    def check_fits(self, fs: float, *, what: str = "recording") -> None:
        """Raise IncompatibleInputError if a ``fs`` Hz recording cannot carry the beep."""
        check_beep_fits(self, fs=fs, what=what)

    def as_probe(self) -> Probe:
        """The beep as a :class:`~rangekit.signals.probe.Probe` (its samples at ``fs``)."""
        from rangekit.signals.probe import Probe

        return Probe(beep_waveform(self), self.fs, name="beep")

    def samples_at(self, fs: float, *, what: str = "the recording") -> np.ndarray:
        """The beep as played, sampled at ``fs`` (resampled when ``fs != self.fs``).

        Examples
        --------
        >>> len(Beep().samples_at(44100.0)), len(Beep().samples_at(48000.0))
        (15441, 16807)
        """
        if float(fs) == self.fs:
            self.check_fits(fs, what=what)
            return beep_waveform(self)
        return self.as_probe().at_rate(fs, what=what)


def burst_envelope(t_s: np.ndarray, *, beep: Beep) -> np.ndarray:
    """Envelope of one burst at times ``t_s`` seconds from the burst start.

    Zero outside [0, burst duration]; raised cosine rising over the first ``taper``
    samples and falling over the last ``taper`` samples; one in between. Evaluated in
    continuous time, so it can be sampled at any rate or fractional delay.

    Examples
    --------
    >>> b = Beep(taper=20)
    >>> burst_envelope(np.array([-1e-3, 10 / b.fs, 100 / b.fs]), beep=b).round(3)
    array([0. , 0.5, 1. ])
    """
    t = np.asarray(t_s, dtype=np.float64)
    dur = beep.burst_s
    env = ((t >= 0.0) & (t <= dur)).astype(np.float64)
    if beep.taper > 0:
        tp = beep.taper_s
        rise = (t >= 0.0) & (t < tp)
        env[rise] = 0.5 - 0.5 * np.cos(np.pi * t[rise] / tp)
        fall = (t > dur - tp) & (t <= dur)
        env[fall] = 0.5 - 0.5 * np.cos(np.pi * (dur - t[fall]) / tp)
    return env


def beep_continuous(t_s: np.ndarray, *, beep: Beep) -> np.ndarray:
    """The beep as a continuous-time signal at times ``t_s`` seconds from its start.

    ``amplitude * env(t) * sin(2 pi f t)`` per burst: the scaled imaginary part of
    :func:`beep_continuous_analytic`.
    """
    return beep.amplitude * beep_continuous_analytic(t_s, beep=beep).imag


def beep_continuous_analytic(t_s: np.ndarray, *, beep: Beep) -> np.ndarray:
    """Analytic (complex) beep ``env(t) exp(j 2 pi f t)`` per burst, at times ``t_s``.

    Its real part is ``beep_continuous / amplitude`` shifted by a quarter period; its
    magnitude is the envelope. Used as the matched-filter template.
    """
    t = np.asarray(t_s, dtype=np.float64)
    out = np.zeros(t.shape, dtype=np.complex128)
    w = 2.0 * math.pi * beep.f_hz
    for k in range(beep.n_bursts):
        tk = t - k * beep.spacing_s
        m = (tk >= 0.0) & (tk <= beep.burst_s)
        if np.any(m):
            out[m] += burst_envelope(tk[m], beep=beep) * np.exp(1j * w * tk[m])
    return out


def beep_waveform(beep: Beep | None = None) -> np.ndarray:
    """The beep sampled at ``beep.fs``: float64 array of ``beep.duration_samples`` samples."""
    beep = Beep() if beep is None else beep
    n = np.arange(beep.duration_samples, dtype=np.float64)
    return beep_continuous(n / beep.fs, beep=beep)


def check_beep_fits(beep: Beep, *, fs: float, what: str = "recording") -> None:
    """Raise IncompatibleInputError if a ``fs`` Hz recording cannot carry ``beep``."""
    top = beep.f_hz + beep.edge_bandwidth_hz
    if top >= fs / 2:
        raise IncompatibleInputError(
            f"{what} sample rate {fs:g} Hz is too low for the {beep.f_hz:g} Hz beep "
            f"(needs more than {2 * top:g} Hz)"
        )
