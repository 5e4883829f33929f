"""Result types: frozen dataclasses of arrays, with units in field names.

Examples
--------
>>> import numpy as np
>>> a = Arrivals.empty(fs=44100.0, n_bursts=4)
>>> len(a), a.onset_s.shape
(0, (0,))
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "ARRIVAL_FLAGS",
    "INFO_FLAGS",
    "Arrivals",
    "Range",
    "RangeResult",
    "RngLike",
    "flag_bit",
    "flag_names",
]

#: Names of the per-arrival flag bits, lowest bit first (``Arrivals.flags``). A flag says
#: why an arrival's onset may be worse than its ``sigma``:
#:
#: - ``clipped``: clipped samples lie in the stretch the onset was timed on (they are kept
#:   out of the fit; the onset rests on fewer samples).
#: - ``low_snr``: the arrival is close to the detection threshold.
#: - ``ambiguous_first_path``: another path of comparable strength lies close before or
#:   after the chosen one; the first path may have been missed or a reflection taken.
#: - ``inconsistent_bursts``: the bursts of a multi-burst signal disagree beyond their
#:   timing noise, or some are missing.
#: - ``poor_match``: the received signal fits the expected one badly (wrong template,
#:   wrong detector, distorted transducer).
#: - ``reverb_limited``: the noise floor near the arrival is set by reverberation of an
#:   earlier arrival, not by the background noise.
#: - ``dc_or_lowband``: strong energy outside the signal's band (DC, hum, handling
#:   noise) was removed before timing; harmless unless combined with other flags.
ARRIVAL_FLAGS = (
    "clipped",
    "low_snr",
    "ambiguous_first_path",
    "inconsistent_bursts",
    "poor_match",
    "reverb_limited",
    "dc_or_lowband",
)

#: Flags that are informational only: they never make a result doubtful on their own.
INFO_FLAGS = frozenset({"dc_or_lowband"})


def flag_bit(name: str) -> int:
    """The bit of one arrival flag name (see :data:`ARRIVAL_FLAGS`).

    Examples
    --------
    >>> flag_bit("clipped"), flag_bit("low_snr")
    (1, 2)
    """
    try:
        return 1 << ARRIVAL_FLAGS.index(name)
    except ValueError:
        raise ValueError(f"unknown arrival flag {name!r}") from None


def flag_names(bits: int) -> tuple[str, ...]:
    """The flag names set in ``bits``, in :data:`ARRIVAL_FLAGS` order.

    Examples
    --------
    >>> flag_names(flag_bit("clipped") | flag_bit("poor_match"))
    ('clipped', 'poor_match')
    """
    b = int(bits)
    return tuple(n for i, n in enumerate(ARRIVAL_FLAGS) if b >> i & 1)


#: What ``rng`` parameters accept (everything :func:`numpy.random.default_rng` does).
RngLike = (
    int
    | Sequence[int]
    | np.random.SeedSequence
    | np.random.BitGenerator
    | np.random.Generator
    | None
)


@dataclass(frozen=True)
class Arrivals:
    """Beep arrivals detected in one recording channel.

    Attributes
    ----------
    onset : ndarray, shape (n,)
        Arrival of each beep's first burst start, as a float sample index from x[0]
        (t = 0 at sample 0). Sub-sample.
    fs : float
        Sample rate of the recording in Hz.
    sigma : ndarray, shape (n,)
        1-sigma uncertainty of each onset, in samples.
    snr_db : ndarray, shape (n,)
        Estimated signal-to-noise ratio of each arrival, in dB. Its reference is the
        detector's: ``changepoint``, a burst's power over the noise power in the beep's
        band (the edge fit's residual; white noise through the band filter is 1/sum(h^2)
        = 2.4, 3.8 dB, weaker than in the full band); ``xcorr``, a burst's power over the
        full-band noise power (white noise assumed); ``matched`` / ``template``, the
        matched filter's first-path height over its noise floor. Compare values of one
        detector only.
    confidence : ndarray, shape (n,)
        Fraction of the beep's bursts whose timing fits the known burst spacing (0..1).
    burst_onsets : ndarray, shape (n, n_bursts)
        Onset of each burst in samples; NaN where a burst was missing or rejected.
    detector : str
        Name of the detector that produced the arrivals.
    window : ndarray of int, shape (n,), optional
        Index of the activation window each arrival was found in (matched-filter
        detection of windowed one-way recordings); None when the channel is one window.
    flags : ndarray of int, shape (n,), optional
        Bit set of :data:`ARRIVAL_FLAGS` per arrival (default all zero);
        :meth:`flag_names` gives the names.
    sigma_transducer : ndarray, shape (n,), optional
        The part of ``sigma`` (samples, included in it) that is the transducers' unknown
        group delay in the signal's band: the same for every arrival through the same
        loudspeaker and microphone, so it cancels in two-way ranging and a calibration
        absorbs it (:attr:`sigma_relative` leaves it out). Default all zero.
    """

    onset: np.ndarray
    fs: float
    sigma: np.ndarray
    snr_db: np.ndarray
    confidence: np.ndarray
    burst_onsets: np.ndarray
    detector: str = ""
    window: np.ndarray | None = None
    flags: np.ndarray | None = None
    sigma_transducer: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.flags is None:
            object.__setattr__(self, "flags", np.zeros(len(self.onset), dtype=np.int64))
        elif len(self.flags) != len(self.onset):
            raise ValueError("Arrivals.flags must have one entry per onset")
        if self.sigma_transducer is None:
            object.__setattr__(self, "sigma_transducer", np.zeros(len(self.onset)))
        elif len(self.sigma_transducer) != len(self.onset):
            raise ValueError("Arrivals.sigma_transducer must have one entry per onset")
        n = len(self.onset)
        for name in ("sigma", "snr_db", "confidence"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"Arrivals.{name} has {len(getattr(self, name))} entries, not {n}")
        if self.burst_onsets.shape[0] != n:
            raise ValueError("Arrivals.burst_onsets must have one row per onset")
        if self.window is not None and len(self.window) != n:
            raise ValueError("Arrivals.window must have one entry per onset")

    @classmethod
    def empty(cls, *, fs: float, n_bursts: int, detector: str = "") -> Arrivals:
        """An Arrivals with no entries."""
        z = np.zeros(0)
        return cls(z, float(fs), z, z, z, np.zeros((0, n_bursts)), detector)

    def __len__(self) -> int:
        return len(self.onset)

    @property
    def onset_s(self) -> np.ndarray:
        """Onsets in seconds from sample 0."""
        return self.onset / self.fs

    @property
    def sigma_s(self) -> np.ndarray:
        """Onset uncertainties in seconds."""
        return self.sigma / self.fs

    @property
    def sigma_relative(self) -> np.ndarray:
        """``sigma`` without the transducer term (samples): the uncertainty of a difference
        of arrivals through the same loudspeaker and microphone (two-way ranging)."""
        return np.sqrt(np.maximum(self.sigma**2 - self.sigma_transducer**2, 0.0))

    def take(self, index) -> Arrivals:
        """A new Arrivals with the entries selected by ``index``."""
        idx = np.asarray(index)
        return Arrivals(
            self.onset[idx],
            self.fs,
            self.sigma[idx],
            self.snr_db[idx],
            self.confidence[idx],
            self.burst_onsets[idx],
            self.detector,
            None if self.window is None else self.window[idx],
            self.flags[idx],
            self.sigma_transducer[idx],
        )

    def flag_names(self, i: int) -> tuple[str, ...]:
        """Names of the flags of arrival ``i``."""
        return flag_names(int(self.flags[i]))

    def with_flags(self, flags: np.ndarray) -> Arrivals:
        """A copy whose flags are ``flags`` (OR them with :attr:`flags` to add)."""
        from dataclasses import replace

        f = np.asarray(flags, dtype=np.int64)
        if f.shape != (len(self),):
            raise ValueError("flags must have one entry per onset")
        return replace(self, flags=f)


@dataclass(frozen=True)
class Range:
    """One distance between devices ``a`` and ``b``.

    Attributes
    ----------
    a, b : int
        Device indices (a < b).
    distance_m : float
        Estimated distance in metres.
    sigma_m : float
        1-sigma uncertainty in metres, from the detection quality.
    flags : tuple of str
        Warnings, e.g. ``"negative"`` for a physically impossible distance.
    """

    a: int
    b: int
    distance_m: float
    sigma_m: float
    flags: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        """Plain-JSON form of the range."""
        return {
            "a": self.a,
            "b": self.b,
            "distance_m": self.distance_m,
            "sigma_m": self.sigma_m,
            "flags": list(self.flags),
        }


@dataclass(frozen=True)
class RangeResult:
    """All pairwise ranges of one exchange, with the arrivals they came from."""

    ranges: tuple[Range, ...]
    speed_m_s: float
    arrivals: tuple[Arrivals, ...] = field(default_factory=tuple)

    def distance_matrix_m(self) -> np.ndarray:
        """Symmetric (N, N) matrix of distances; NaN where no range, 0 on the diagonal."""
        n = len(self.arrivals) if self.arrivals else 1 + max((r.b for r in self.ranges), default=0)
        d = np.full((n, n), np.nan)
        np.fill_diagonal(d, 0.0)
        for r in self.ranges:
            d[r.a, r.b] = d[r.b, r.a] = r.distance_m
        return d
