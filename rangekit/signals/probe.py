"""Probe signals given as samples: a lab's sweep or chirp file, or rangekit's own designs.

Users rarely record the rangekit beep: labs play linear sweeps (17-20 kHz, 20 Hz-20 kHz,
0.1-1 s), chirps or tones from their own apps. A :class:`Probe` is the emitted signal as
samples at the rate it was made for; :meth:`Probe.at_rate` gives the matched-filter
template at a recording's rate (a phone that records at 48 kHz while playing a 44.1 kHz
file) and refuses a probe whose band does not fit below the recording's Nyquist frequency.

Time origin: sample 0 of the probe is the instant the emission starts. A probe file's
leading silence is kept (it is part of what was played, and the arrival times count from
the file's first sample); trailing digital silence is dropped.

Resampling is polyphase (``scipy.signal.resample_poly``) with the exact rational rate
ratio, e.g. 48000 / 44100 = 160 / 147, and a Kaiser lowpass (100 dB) whose transition
band lies between the probe's band and its mirror about the lower Nyquist frequency, so
the band passes unchanged (error ~2e-5 for a 17-20 kHz sweep taken to 48 kHz); the
filter is zero-phase, so sample 0 stays at t = 0.

Examples
--------
>>> p = linear_sweep(17000.0, 20000.0, 0.1, fs=44100.0)
>>> p.duration_s, len(p.samples)
(0.1, 4410)
>>> lo, hi = p.band_hz()
>>> bool(16500 < lo < 17100 and 19900 < hi < 20500)
True
>>> len(p.at_rate(48000.0))
4800
"""

from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass
from fractions import Fraction
from typing import ClassVar

import numpy as np

from rangekit import _validate as V
from rangekit.errors import AudioFormatError, IncompatibleInputError, InvalidParameterError

__all__ = [
    "BAND_ENERGY",
    "Probe",
    "SweepError",
    "check_sweep",
    "linear_sweep",
    "read_probe",
    "sweep_fade_s",
]

#: Fraction of the probe's energy that :meth:`Probe.band_hz` must enclose.
BAND_ENERGY = 0.999
#: Default length of the raised-cosine fade at each end of a designed sweep, s.
DEFAULT_FADE_S = 0.005
#: Stop-band attenuation of the resampling filter of :meth:`Probe.at_rate`, dB.
RESAMPLE_ATTEN_DB = 100.0


@dataclass(frozen=True, eq=False)
class Probe:
    """An emitted probe signal: samples at the rate they were made for.

    Parameters
    ----------
    samples : array_like, shape (n,)
        The signal as played; sample 0 is the start of the emission.
    fs : float
        Its sample rate in Hz.
    name : str
        What to call it in messages (e.g. the file it came from).
    """

    samples: np.ndarray
    fs: float
    name: str = "probe"

    #: What kind of emitted signal this is (:data:`rangekit.signals.SIGNAL_KINDS`).
    kind: ClassVar[str] = "probe"

    def __post_init__(self) -> None:
        x = V.signal_1d("probe samples", self.samples)
        if len(x) < 16:
            raise InvalidParameterError(
                f"probe '{self.name}' has {len(x)} samples; a probe needs at least 16"
            )
        if not np.any(x):
            raise InvalidParameterError(f"probe '{self.name}' is all zeros")
        object.__setattr__(self, "samples", np.ascontiguousarray(x, dtype=np.float64))
        object.__setattr__(self, "fs", V.sample_rate(self.fs))
        self.samples.flags.writeable = False

    def __repr__(self) -> str:
        """Name, rate, length and a digest of the samples (stable across processes)."""
        import hashlib

        digest = hashlib.sha1(self.samples.tobytes()).hexdigest()[:12]
        return f"Probe(name={self.name!r}, fs={self.fs:g}, n={len(self.samples)}, sha1={digest})"

    @property
    def duration_s(self) -> float:
        """Length of the probe in seconds."""
        return len(self.samples) / self.fs

    def band_hz(self, energy: float = BAND_ENERGY) -> tuple[float, float]:
        """``(lo, hi)``: the band holding ``energy`` of the probe's power, equal tails out.

        Examples
        --------
        >>> fs = 44100.0
        >>> t = np.arange(4410) / fs
        >>> lo, hi = Probe(np.sin(2 * np.pi * 1000 * t) * np.hanning(4410), fs).band_hz()
        >>> bool(900 < lo < 1000 < hi < 1100)
        True
        """
        if energy == BAND_ENERGY:
            return self._band
        return self._band_of(energy)

    @functools.cached_property
    def _band(self) -> tuple[float, float]:
        # Every at_rate / check_fits asks for it: one spectrum per probe.
        return self._band_of(BAND_ENERGY)

    def _band_of(self, energy: float) -> tuple[float, float]:
        from rangekit.signals.spectrum import power_spectrum

        V.in_range("energy", energy, 0.5, 1.0)
        f, p = power_spectrum(self.samples, fs=self.fs)
        c = np.cumsum(p)
        c /= c[-1]
        tail = 0.5 * (1.0 - energy)
        lo = f[min(len(f) - 1, int(np.searchsorted(c, tail)))]
        hi = f[min(len(f) - 1, int(np.searchsorted(c, 1.0 - tail)))]
        return float(lo), float(hi)

    def check_fits(self, fs: float, *, what: str = "the recording") -> None:
        """Raise IncompatibleInputError if the probe's band reaches ``fs / 2``.

        The band is :meth:`band_hz` (99.9 % of the energy); it must lie below the
        recording's Nyquist frequency, else the recording cannot hold the probe.
        """
        fs = V.sample_rate(fs)
        lo, hi = self.band_hz()
        if hi >= 0.5 * fs:
            raise IncompatibleInputError(
                f"probe '{self.name}' has its band at {lo / 1e3:.2f}-{hi / 1e3:.2f} kHz, "
                f"above the Nyquist frequency {0.5 * fs / 1e3:.2f} kHz of {what} "
                f"(sampled at {fs:g} Hz); record at a higher rate or use a lower-band probe"
            )

    # The emitted-signal interface shared with Beep and CodedBurst (rangekit.signals).
    def band(self) -> tuple[float, float]:
        """``(lo, hi)`` in Hz: :meth:`band_hz` (99.9 % of the energy)."""
        return self.band_hz()

    def as_probe(self) -> Probe:
        """The probe itself."""
        return self

    def samples_at(self, fs: float, *, what: str = "the recording") -> np.ndarray:
        """The probe sampled at ``fs``: :meth:`at_rate`."""
        return self.at_rate(fs, what=what)

    def at_rate(self, fs: float, *, what: str = "the recording") -> np.ndarray:
        """The probe as samples at ``fs`` (the matched-filter template of a recording).

        Parameters
        ----------
        fs : float
            The recording's sample rate in Hz.
        what : str
            The recording, for the error message.

        Raises
        ------
        IncompatibleInputError
            The probe's band does not fit below ``fs / 2``.
        """
        fs = V.sample_rate(fs)
        self.check_fits(fs, what=what)
        if fs == self.fs:
            return np.array(self.samples)
        from scipy.signal import firwin, kaiserord, resample_poly

        ratio = _rate_ratio(fs, self.fs)
        # Kaiser lowpass at the lower Nyquist frequency, flat over the probe's band and
        # RESAMPLE_ATTEN_DB down beyond its mirror image (scipy's default filter, beta 5 and
        # 10 taps per phase, has a transition ~6 kHz wide at 44.1 kHz: 14 % error at 20 kHz).
        m = max(ratio.numerator, ratio.denominator)
        half = min(0.1, max(0.02, 1.0 - self.band_hz()[1] / (0.5 * min(fs, self.fs))))
        n_taps, beta = kaiserord(RESAMPLE_ATTEN_DB, 2.0 * half / m)
        h = firwin(n_taps | 1, 1.0 / m, window=("kaiser", beta))
        y = resample_poly(self.samples, ratio.numerator, ratio.denominator, window=h)
        n = int(math.ceil(len(self.samples) * fs / self.fs))
        return np.ascontiguousarray(y[:n])


def _rate_ratio(new: float, old: float) -> Fraction:
    """``new / old`` as a fraction: exact for integer rates, else within 1e-9."""
    if float(new).is_integer() and float(old).is_integer():
        return Fraction(int(new), int(old))
    return Fraction(new / old).limit_denominator(1 << 20)


def linear_sweep(
    f0_hz: float,
    f1_hz: float,
    duration_s: float,
    *,
    fs: float = 44100.0,
    fade_s: float | None = None,
    amplitude: float = 0.5,
) -> Probe:
    """A linear sweep (chirp) from ``f0_hz`` to ``f1_hz`` with raised-cosine fades.

    ``x(t) = amplitude * w(t) * sin(2 pi (f0 t + (f1 - f0) t^2 / (2 T)))`` for ``0 <= t <
    T``, with ``w`` rising and falling over ``fade_s`` as a half cosine (the fades lower
    the matched filter's range side lobes and keep the ends click-free).

    Parameters
    ----------
    f0_hz, f1_hz : float
        Start and end frequency in Hz (a down-sweep has ``f1 < f0``); both below ``fs / 2``.
    duration_s : float
        Length T in seconds (at least 1 ms).
    fs : float
        Sample rate in Hz (default 44.1 kHz).
    fade_s : float, optional
        Length of each fade in seconds; default ``min(5 ms, T / 10)``.
    amplitude : float
        Peak amplitude, in (0, 1].

    Examples
    --------
    >>> p = linear_sweep(20.0, 20000.0, 0.5)
    >>> p.name, len(p.samples), float(np.max(np.abs(p.samples))) <= 0.5
    ('sweep 20-20000 Hz, 0.5 s', 22050, True)
    """
    fs, f0, f1, T, fade = check_sweep(f0_hz, f1_hz, duration_s, fs=fs, fade_s=fade_s)
    amplitude = V.in_range("amplitude", amplitude, 1e-6, 1.0)
    n = int(round(T * fs))
    t = np.arange(n) / fs
    x = np.sin(2.0 * np.pi * (f0 * t + 0.5 * (f1 - f0) / T * t * t))
    m = int(round(fade * fs))
    if m > 0:
        ramp = 0.5 - 0.5 * np.cos(np.pi * (np.arange(m) + 0.5) / m)
        x[:m] *= ramp
        x[n - m :] *= ramp[::-1]
    x *= amplitude / max(float(np.max(np.abs(x))), 1e-300)
    return Probe(x, fs, f"sweep {f0:g}-{f1:g} Hz, {T:g} s")


class SweepError(InvalidParameterError):
    """Sweep arguments that do not fit together, named as the caller names them
    (:func:`check_sweep` with ``names``).

    Attributes
    ----------
    param : str or None
        The caller's name of the argument at fault; None when two are at fault together
        (the message names both) (:class:`~rangekit.errors.InvalidParameterError`'s).
    reason : str
        Why, without the name of ``parameter`` (the whole message when it is None).
    """

    def __init__(self, message: str, *, param: str | None = None, reason: str | None = None):
        super().__init__(message, param=param)
        self.reason = message if reason is None else reason


def check_sweep(
    f0_hz: float,
    f1_hz: float,
    duration_s: float,
    *,
    fs: float = 44100.0,
    fade_s: float | None = None,
    names: dict[str, str] | None = None,
) -> tuple[float, float, float, float, float]:
    """The checks of :func:`linear_sweep`'s arguments (amplitude apart), in one place:
    ``(fs, f0_hz, f1_hz, duration_s, fade_s)`` as floats, the default fade filled in.

    Parameters
    ----------
    f0_hz, f1_hz, duration_s, fs, fade_s
        As :func:`linear_sweep` takes them.
    names : dict, optional
        The caller's names of the arguments (``{"f0_hz": "--f0", "fs": "--fs", ...}``):
        the frequencies at or above Nyquist, equal frequencies and a fade longer than half
        the sweep then raise :class:`SweepError` naming the arguments so (a name that
        starts with ``-`` is shown as an option: ``--fs 16000``, not ``fs=16000``).
        Without it the messages are :func:`linear_sweep`'s.

    Raises
    ------
    InvalidParameterError
        An argument out of its domain (:class:`SweepError` for those above, with ``names``).

    Examples
    --------
    >>> check_sweep(2000.0, 6000.0, 0.1)
    (44100.0, 2000.0, 6000.0, 0.1, 0.005)
    >>> try:
    ...     check_sweep(9000.0, 2000.0, 0.1, fs=16000.0, names={"f0_hz": "--f0", "fs": "--fs"})
    ... except SweepError as e:
    ...     print(e.param, "|", e.reason)
    --f0 | 9000 Hz is not below the Nyquist frequency 8000 Hz of --fs 16000
    """
    n = {k: k for k in ("f0_hz", "f1_hz", "duration_s", "fs", "fade_s")}
    n.update(names or {})

    def ref(key: str, value: str) -> str:  # an argument and its value, as the caller writes it
        return f"{n[key]} {value}" if n[key].startswith("-") else f"{n[key]}={value}"

    def fail(key: str, value: str, why: str):
        if names is None:
            return InvalidParameterError(f"{ref(key, value)} {why}")
        return SweepError(f"{n[key]}: {value} {why}", param=n[key], reason=f"{value} {why}")

    fs = V.sample_rate(fs)
    f0 = V.positive("f0_hz", f0_hz, allow_zero=True)
    f1 = V.positive("f1_hz", f1_hz, allow_zero=True)
    for key, f in (("f0_hz", f0), ("f1_hz", f1)):
        if f >= 0.5 * fs:
            why = f"Hz is not below the Nyquist frequency {0.5 * fs:g} Hz of {ref('fs', f'{fs:g}')}"
            raise fail(key, f"{f:g}", why)
    if f0 == f1:
        both = f"{n['f0_hz']} and {n['f1_hz']} are both {f0:g} Hz; a sweep needs two"
        if names is None:
            raise InvalidParameterError(both)
        raise SweepError(both + " frequencies")
    T = V.in_range("duration_s", duration_s, 1e-3, 600.0)
    if names is not None and fade_s is not None and fade_s > T / 2:
        why = f"s is longer than half of {ref('duration_s', f'{T:g}')} s"
        raise fail("fade_s", f"{fade_s:g}", why)
    fade = sweep_fade_s(T) if fade_s is None else V.in_range("fade_s", fade_s, 0.0, T / 2)
    return fs, f0, f1, T, fade


def sweep_fade_s(duration_s: float) -> float:
    """The fade :func:`linear_sweep` gives a sweep of ``duration_s`` by default, s:
    ``min(DEFAULT_FADE_S, duration_s / 10)``.

    Examples
    --------
    >>> sweep_fade_s(0.1), sweep_fade_s(0.02)
    (0.005, 0.002)
    """
    return min(DEFAULT_FADE_S, duration_s / 10.0)


def read_probe(path: str | os.PathLike, *, channel: int | None = None) -> Probe:
    """Read a probe (the signal that was played) from an audio file.

    Parameters
    ----------
    path : path-like
        WAV, FLAC, ... file holding the probe; sample 0 is the emission's start.
    channel : int, optional
        Which channel of a multichannel file; a mono file needs none.

    Raises
    ------
    InputFileError, AudioFormatError
        The file cannot be read, is multichannel without ``channel``, or is silent.
    """
    from rangekit.io.audio import read_audio

    x, fs = read_audio(path)
    if channel is None:
        if x.shape[1] != 1:
            raise AudioFormatError(
                f"probe '{path}' has {x.shape[1]} channels; give a mono file (the signal one "
                "speaker played)"
            )
        channel = 0
    elif not 0 <= int(channel) < x.shape[1]:
        raise AudioFormatError(f"probe '{path}' has no channel {channel} (it has {x.shape[1]})")
    y = x[:, int(channel)]
    nz = np.flatnonzero(y)
    if len(nz) == 0:
        raise AudioFormatError(f"probe '{path}' is silent (all samples are zero)")
    y = y[: int(nz[-1]) + 1]
    if len(y) < 16:
        raise AudioFormatError(f"probe '{path}' has {len(y)} non-silent samples; need 16")
    return Probe(y, fs, os.fspath(path))
