"""Phase-coded ultrasonic bursts: Barker-coded BPSK (Kim & Kim 2013) and the SRF02 ping.

Kim & Kim 2013 §II-A drive their ceiling beacons with a 7-bit Barker code, biphase
modulated onto a 40 kHz carrier, three carrier cycles per bit, for a signal of "approximately
10 kHz" bandwidth. The Devantech SRF02 fires 8 cycles of 40 kHz (datasheet; Girard 2011
§2.6). Both are a :class:`CodedBurst`: a code of +-1 chips, each chip a whole number of
carrier cycles of ``sin(2 pi f_c t)`` multiplied by the chip sign. The SRF02 ping is the
one-chip code ``(1,)`` with 8 cycles per chip.

Every chip boundary falls on a whole carrier cycle, where ``sin`` is zero, so the drive
waveform is continuous (its spectrum falls as ``1/f^2``) and samples well at any rate
whose Nyquist frequency is above the signal's main lobe (:attr:`CodedBurst.band_hz`).

Examples
--------
>>> b = CodedBurst()
>>> b.code, b.carrier_hz, b.cycles_per_bit, b.fs
((1, 1, 1, -1, -1, 1, -1), 40000.0, 3, 192000.0)
>>> round(b.duration_s * 1e6, 1), b.duration_samples
(525.0, 101)
>>> [round(f) for f in b.band_hz]
[26667, 53333]
>>> srf02_ping().code, srf02_ping().cycles_per_bit
((1,), 8)
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
    "BARKER_CODES",
    "CodedBurst",
    "burst_continuous",
    "burst_waveform",
    "check_burst_fits",
    "srf02_ping",
]

#: The Barker codes (all known binary codes with autocorrelation side lobes <= 1/N).
BARKER_CODES: dict[int, tuple[int, ...]] = {
    2: (1, -1),
    3: (1, 1, -1),
    4: (1, 1, -1, 1),
    5: (1, 1, 1, -1, 1),
    7: (1, 1, 1, -1, -1, 1, -1),
    11: (1, 1, 1, -1, -1, -1, 1, -1, -1, 1, -1),
    13: (1, 1, 1, 1, 1, -1, -1, 1, 1, -1, 1, -1, 1),
}

#: Default ultrasonic sample rate in Hz (a common rate of ultrasonic sound cards).
DEFAULT_FS = 192000.0


@dataclass(frozen=True)
class CodedBurst:
    """A biphase (BPSK) coded burst on a sinusoidal carrier.

    Parameters
    ----------
    code : tuple of int
        Chip signs, each +1 or -1 (default the 7-bit Barker code, Kim & Kim 2013 §II-A).
    carrier_hz : float
        Carrier frequency in Hz (default 40 kHz).
    cycles_per_bit : int
        Whole carrier cycles per chip (default 3, Kim & Kim 2013 §II-A).
    amplitude : float
        Peak drive amplitude in (0, 1].
    fs : float
        Sample rate in Hz of the sampled waveform (default 192 kHz). It must carry the
        signal's main lobe: ``fs / 2 > band_hz[1]``.

    Raises
    ------
    InvalidParameterError
        If a chip is not +-1, a number is out of its domain, or ``fs`` cannot carry
        the band.
    """

    code: tuple[int, ...] = BARKER_CODES[7]
    carrier_hz: float = 40000.0
    cycles_per_bit: int = 3
    amplitude: float = 0.9
    fs: float = DEFAULT_FS

    #: What kind of emitted signal this is (:data:`rangekit.signals.SIGNAL_KINDS`).
    kind: ClassVar[str] = "coded"

    def __post_init__(self) -> None:
        try:
            chips = [float(c) for c in self.code]
        except (TypeError, ValueError):
            raise InvalidParameterError(f"code={self.code!r} must be a sequence of +1/-1") from None
        code = tuple(int(c) for c in chips if c in (1.0, -1.0))
        if not code or len(code) != len(chips):
            raise InvalidParameterError(f"code={self.code!r} must be a non-empty sequence of +1/-1")
        object.__setattr__(self, "code", code)
        object.__setattr__(self, "carrier_hz", V.positive("carrier_hz", self.carrier_hz))
        object.__setattr__(
            self, "cycles_per_bit", V.positive_int("cycles_per_bit", self.cycles_per_bit)
        )
        amp = V.positive("amplitude", self.amplitude)
        if amp > 1.0:
            raise InvalidParameterError(f"amplitude={amp!r} must be <= 1 (full scale)")
        object.__setattr__(self, "amplitude", amp)
        fs = V.sample_rate(self.fs)
        object.__setattr__(self, "fs", fs)
        top = self.band_hz[1]
        if top >= fs / 2:
            raise InvalidParameterError(
                f"fs={fs:g} Hz cannot carry the {self.carrier_hz:g} Hz burst: its main lobe "
                f"reaches {top:.0f} Hz, above the Nyquist frequency {fs / 2:g} Hz "
                f"(needs fs > {2 * top:.0f} Hz)"
            )

    @property
    def chip_rate_hz(self) -> float:
        """Chips per second, ``carrier_hz / cycles_per_bit``."""
        return self.carrier_hz / self.cycles_per_bit

    @property
    def band_hz(self) -> tuple[float, float]:
        """The main lobe of the burst's spectrum, ``carrier -+ chip rate``, in Hz.

        This is the band rangekit calls "in band" (e.g. for the SNR of simulated noise)
        and the band a recording's Nyquist frequency must exceed. For the default
        Barker-7 it is 26.7-53.3 kHz; Kim & Kim quote "approximately 10 kHz" of
        bandwidth, which is about the -3 dB width once the transducers filter it.
        """
        return (self.carrier_hz - self.chip_rate_hz, self.carrier_hz + self.chip_rate_hz)

    @property
    def duration_s(self) -> float:
        """Duration of the drive in seconds: chips x cycles per chip / carrier."""
        return len(self.code) * self.cycles_per_bit / self.carrier_hz

    @property
    def duration_samples(self) -> int:
        """Samples of the sampled drive at ``fs`` (the duration rounded up)."""
        return int(math.ceil(self.duration_s * self.fs - 1e-9))

    def with_fs(self, fs: float) -> CodedBurst:
        """The same burst sampled at another rate (validated)."""
        return CodedBurst(self.code, self.carrier_hz, self.cycles_per_bit, self.amplitude, fs)

    # The emitted-signal interface shared with Beep and Probe (rangekit.signals).
    def band(self) -> tuple[float, float]:
        """``(lo, hi)`` in Hz: the main lobe, :attr:`band_hz`."""
        return self.band_hz

    def check_fits(self, fs: float, *, what: str = "recording") -> None:
        """Raise IncompatibleInputError if a ``fs`` Hz recording cannot carry the burst."""
        check_burst_fits(self, fs=fs, what=what)

    def as_probe(self) -> Probe:
        """The drive as a :class:`~rangekit.signals.probe.Probe` (its samples at ``fs``).

        This is the drive, not what a microphone receives: the transducers' responses
        (:mod:`rangekit.signals.transducer`) are not in it.
        """
        from rangekit.signals.probe import Probe

        return Probe(burst_waveform(self), self.fs, name="coded burst")

    def samples_at(self, fs: float, *, what: str = "recording") -> np.ndarray:
        """The drive sampled at ``fs`` (sampled anew from the continuous waveform).

        Examples
        --------
        >>> len(CodedBurst().samples_at(192000.0)), len(CodedBurst().samples_at(384000.0))
        (101, 202)
        """
        self.check_fits(fs, what=what)
        return burst_waveform(self.with_fs(fs))


def srf02_ping(*, fs: float = DEFAULT_FS, amplitude: float = 0.9) -> CodedBurst:
    """The Devantech SRF02 ping: 8 cycles of 40 kHz (datasheet; see REFERENCES.md)."""
    return CodedBurst((1,), 40000.0, 8, amplitude, fs)


def burst_continuous(t_s: np.ndarray, *, burst: CodedBurst) -> np.ndarray:
    """The drive waveform at times ``t_s`` seconds from its start (continuous time).

    ``amplitude * code[k] * sin(2 pi f_c t)`` for ``t`` in chip ``k``; zero outside
    ``[0, duration_s)``.

    Examples
    --------
    >>> b = CodedBurst(code=(1, -1), cycles_per_bit=1)
    >>> t = np.array([-1.0, 0.25, 1.25, 2.5]) / b.carrier_hz
    >>> (burst_continuous(t, burst=b) / b.amplitude).round(12).tolist()
    [0.0, 1.0, -1.0, 0.0]
    """
    t = np.asarray(t_s, dtype=np.float64)
    chip = np.floor(t * burst.chip_rate_hz).astype(np.int64)
    inside = (t >= 0.0) & (chip < len(burst.code))
    signs = np.zeros(t.shape)
    signs[inside] = np.asarray(burst.code, dtype=np.float64)[chip[inside]]
    out = burst.amplitude * signs * np.sin(2.0 * math.pi * burst.carrier_hz * t)
    out[~inside] = 0.0
    return out


def burst_waveform(burst: CodedBurst | None = None) -> np.ndarray:
    """The drive sampled at ``burst.fs``: ``duration_samples`` float64 samples from t = 0."""
    burst = CodedBurst() if burst is None else burst
    n = np.arange(burst.duration_samples, dtype=np.float64)
    return burst_continuous(n / burst.fs, burst=burst)


def check_burst_fits(burst: CodedBurst, *, fs: float, what: str = "recording") -> None:
    """Raise IncompatibleInputError if a ``fs`` Hz recording cannot carry ``burst``.

    Examples
    --------
    >>> check_burst_fits(CodedBurst(), fs=44100.0, what="'x.wav'")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    rangekit.errors.IncompatibleInputError: 'x.wav' sample rate 44100 Hz ... fs > 106667 Hz)
    """
    top = burst.band_hz[1]
    if top >= fs / 2:
        raise IncompatibleInputError(
            f"{what} sample rate {fs:g} Hz is too low for the {burst.carrier_hz:g} Hz burst "
            f"(its band reaches {top:.0f} Hz; needs fs > {2 * top:.0f} Hz)"
        )
