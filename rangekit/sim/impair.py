"""Recording impairments: what real recordings carry and rangekit's renderers do not.

:func:`impair` applies them to an already rendered (or recorded) array; the levels of the
additive ones are set relative to the recording's own background noise, its *reference
floor*. ``docs/impairments.md`` gives each law with its reasoning; the measured facts
behind the defaults are in ``shared/REFERENCES.md`` ("What real recordings look like").

Order of application (per channel)
----------------------------------
1. Band response of the device: causal 2nd-order Butterworth high-pass ``hp_hz``, then
   low-pass ``lp_hz`` (``scipy.signal.sosfilt``, not zero-phase). Like a real loudspeaker
   or microphone it *delays* the signal: the low-pass's group delay is near the analog
   ``sqrt(2) / (2 pi lp_hz)`` at low frequency (25 us for ``lp_hz=8000`` at 44.1 kHz;
   13 us at the beep's 16 kHz), so arrivals are timed later, as in a recording.
2. Additive noises, each drawn independently: low-frequency noise ``lf_db``, mains hum
   ``hum_db``, pink noise ``pink_db``, interference ``interference`` at
   ``interference_db``.
3. Automatic gain steps ``agc_db`` (multiplies everything above).
4. DC offset ``dc``.
5. Symmetric clipping at ``clip_db`` below the channel's peak (after 1-4).
6. Silence padding: ``round(silence_s * fs)`` exact zeros before and after. Every sample
   index moves by this shift (:attr:`ImpairResult.shift_samples`); :func:`shift_truth`
   moves a simulator's truth by it.

Reference floor
---------------
``F`` (units^2/Hz, one-sided) is the recording's background-noise PSD: given by the caller
(``floor_psd``; a simulator knows its own noise, :func:`noise_floor_psd`) or estimated by
:func:`estimate_floor_psd`, the median over frequency, in 1 kHz ... min(20 kHz, 0.45 fs),
of a Welch PSD of ~20 ms segments averaged with the median across segments (bursts and
beeps do not count).
It is always taken from the input, before any impairment.

Levels (``L`` = 10^(level_db / 10))
----------------------------------
- ``lf_db``: brown noise, PSD proportional to ``1 / ((f^2 + 2^2) (1 + (f / 200)^8))``
  (1/f^2 between a 2 Hz knee and 200 Hz), whose expected mean PSD over 20-200 Hz is ``L F``.
- ``hum_db``: power ``L F 200 Hz`` (a 200 Hz-wide band at ``L F``) in ``hum_hz`` and its
  harmonics up to 1 kHz, amplitudes -6 dB per harmonic, random phases, times
  ``1 + 0.1 sin(2 pi f_w t + phi)`` with ``f_w`` uniform in 0.1-1 Hz. Exact sample power.
- ``pink_db``: :func:`rangekit.sim.noise.pink_noise` (1/f over the whole band) scaled so that
  its PSD at 1 kHz is ``L F``.
- ``interference``, ``interference_db``: mean power (over the whole recording, pauses
  included; exact sample power) ``L F B``, with ``B`` the interference's band: speech
  100 Hz ... min(4 kHz, fs / 2), music 100 Hz ... ``interference_max_hz``.
- ``agc_db``: the gain steps by +-``agc_db`` (random sign) at ``agc_steps`` random times,
  each step a 20 ms ramp linear in dB; the gain starts at 0 dB.
- ``dc``: added, as a fraction of full scale (1.0).
- ``clip_db``: every sample is clipped to +-``max|x| 10^(-clip_db / 20)`` of its channel.

Examples
--------
>>> x = 0.01 * np.random.default_rng(0).standard_normal(44100)
>>> imp = parse_impairments("dc=0.02,clip_db=6,silence_s=0.1")
>>> r = impair(x, fs=44100.0, impairments=imp, rng=1)
>>> r.shift_samples, r.x.shape
(4410, (52920,))
>>> bool(np.all(r.x[:4410] == 0.0) and np.all(r.x[-4410:] == 0.0))
True
>>> round(float(r.x[4410:-4410].mean()), 3), imp.spec()
(0.02, 'dc=0.02,clip_db=6,silence_s=0.1')
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike

from rangekit import _validate as V
from rangekit.errors import InvalidParameterError
from rangekit.sim.noise import pink_noise
from rangekit.types import RngLike

__all__ = [
    "FLOOR_BAND_HZ",
    "INTERFERENCE_KINDS",
    "KEYS",
    "ImpairResult",
    "Impairments",
    "estimate_floor_psd",
    "impair",
    "interference_band_hz",
    "noise_floor_psd",
    "parse_impairments",
    "shift_truth",
]

#: Band of the reference floor, Hz (the upper edge is also at most 0.45 fs).
FLOOR_BAND_HZ = (1000.0, 20000.0)
#: Interference kinds understood by :class:`Impairments`.
INTERFERENCE_KINDS = ("speech", "music")

_FLOOR_SEGMENT_S = 0.02
_LF_BAND_HZ = (20.0, 200.0)
_LF_KNEE_HZ = 2.0
_HUM_MAX_HZ = 1000.0
_HUM_BAND_HZ = 200.0
_PINK_REF_HZ = 1000.0
_SPEECH_BAND_HZ = (100.0, 4000.0)
_SPEECH_TILT_HZ = 500.0
_MUSIC_LOW_HZ = 100.0
_AGC_RAMP_S = 0.02
_DB = (-40.0, 80.0)
# key: (lo, hi, lo excluded); the numeric fields of Impairments.
_LIMITS = {
    "dc": (-0.5, 0.5, False),
    "clip_db": (0.0, 40.0, True),
    "lf_db": (*_DB, False),
    "hum_db": (*_DB, False),
    "hum_hz": (10.0, 1000.0, False),
    "pink_db": (*_DB, False),
    "interference_db": (*_DB, False),
    "interference_max_hz": (1000.0, 20000.0, True),
    "agc_db": (0.0, 40.0, True),
    "silence_s": (0.0, 60.0, False),
    "lp_hz": (0.0, 1e6, True),
    "hp_hz": (0.0, 1e6, True),
}
# Settings that mean nothing unless another key switches their impairment on.
_NEEDS = {
    "hum_hz": "hum_db",
    "interference_db": "interference",
    "interference_max_hz": "interference",
    "agc_steps": "agc_db",
}


@dataclass(frozen=True)
class Impairments:
    """Which impairments :func:`impair` applies, and how strongly (all off by default).

    Levels in dB are relative to the reference floor (module notes).

    Parameters
    ----------
    dc : float
        DC offset, fraction of full scale, ``|dc| <= 0.5``.
    clip_db : float, optional
        Clip at the channel's peak ``|x|`` times ``10^(-clip_db / 20)``, in (0, 40] dB.
    lf_db : float, optional
        Low-frequency (brown, < 200 Hz) noise: mean PSD over 20-200 Hz, dB above the floor.
    hum_db : float, optional
        Mains hum power as that of a 200 Hz band at ``hum_db`` above the floor PSD.
    hum_hz : float
        Mains frequency, 10-1000 Hz (default 50).
    pink_db : float, optional
        Pink noise: PSD at 1 kHz, dB above the floor.
    interference : {"speech", "music"}, optional
        Interference outside the beep's band.
    interference_db : float
        Its mean power over the floor's power in its band, dB (default 0).
    interference_max_hz : float
        Highest harmonic of the music, Hz, in (1000, 20000] (default 8000).
    agc_db : float, optional
        Size of each automatic-gain step, dB, in (0, 40].
    agc_steps : int
        Number of gain steps, 1-1000 (default 3).
    silence_s : float
        Exact zeros before and after the recording, s, 0-60 (default 0).
    lp_hz, hp_hz : float, optional
        Corner frequencies of the device's 2nd-order Butterworth low-pass / high-pass, Hz.

    Raises
    ------
    InvalidParameterError
        A value out of its range (the message names the key and value), ``hp_hz >= lp_hz``,
        or a setting whose impairment is off (``hum_hz`` without ``hum_db``, ...;
        ``interference_max_hz`` with speech).

    Examples
    --------
    >>> Impairments(hum_db=30.0, hum_hz=60).spec()
    'hum_db=30,hum_hz=60'
    >>> Impairments(clip_db=0)
    Traceback (most recent call last):
    ...
    rangekit.errors.InvalidParameterError: clip_db=0 must be within (0.0, 40.0]
    """

    dc: float = 0.0
    clip_db: float | None = None
    lf_db: float | None = None
    hum_db: float | None = None
    hum_hz: float = 50.0
    pink_db: float | None = None
    interference: str | None = None
    interference_db: float = 0.0
    interference_max_hz: float = 8000.0
    agc_db: float | None = None
    agc_steps: int = 3
    silence_s: float = 0.0
    lp_hz: float | None = None
    hp_hz: float | None = None

    def __post_init__(self) -> None:
        for key, (lo, hi, open_lo) in _LIMITS.items():
            value = getattr(self, key)
            if value is None:
                continue
            v = V.in_range(key, value, lo, hi)
            if open_lo and v == lo:
                raise InvalidParameterError(f"{key}={value!r} must be within ({lo}, {hi}]")
            object.__setattr__(self, key, v)
        steps = V.positive_int("agc_steps", self.agc_steps)
        if steps > 1000:
            raise InvalidParameterError(f"agc_steps={steps!r} must be <= 1000")
        object.__setattr__(self, "agc_steps", steps)
        if self.interference is not None and self.interference not in INTERFERENCE_KINDS:
            choices = ", ".join(repr(k) for k in INTERFERENCE_KINDS)
            raise InvalidParameterError(
                f"interference={self.interference!r} must be one of {choices}"
            )
        defaults = {f.name: f.default for f in fields(self)}
        for key, owner in _NEEDS.items():
            if getattr(self, owner) is None and getattr(self, key) != defaults[key]:
                raise InvalidParameterError(
                    f"{key}={getattr(self, key)!r} has no effect without {owner}"
                )
        if self.interference == "speech" and self.interference_max_hz != 8000.0:
            raise InvalidParameterError(
                f"interference_max_hz={self.interference_max_hz!r} applies to music only"
            )
        if self.hp_hz is not None and self.lp_hz is not None and self.hp_hz >= self.lp_hz:
            raise InvalidParameterError(f"hp_hz={self.hp_hz!r} must be below lp_hz={self.lp_hz!r}")

    @property
    def relative_keys(self) -> tuple[str, ...]:
        """The keys set whose level is relative to the reference floor."""
        keys = ("lf_db", "hum_db", "pink_db", "interference")
        return tuple(k for k in keys if getattr(self, k) is not None)

    def as_dict(self) -> dict:
        """Every field and its value (None = off), JSON-ready (the sidecar's record)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def spec(self) -> str:
        """The canonical spec string: the keys not at their default, in field order.

        ``parse_impairments(imp.spec()) == imp``; all off gives ``""``.
        """
        items = []
        for f in fields(self):
            v = getattr(self, f.name)
            if v != f.default:
                items.append(f"{f.name}={_format_value(v)}")
        return ",".join(items)


def _format_value(v) -> str:
    if isinstance(v, float):
        text = repr(v)
        return text[:-2] if text.endswith(".0") else text
    return str(v)


#: The keys of a spec string: the fields of :class:`Impairments`.
KEYS = tuple(f.name for f in fields(Impairments))


def parse_impairments(spec: str) -> Impairments:
    """Parse ``"key=value,key=value,..."`` (keys: the fields of :class:`Impairments`).

    Parameters
    ----------
    spec : str
        Comma-separated ``key=value`` items; numbers as Python reads them; ``interference``
        takes ``speech`` or ``music``. Blank: every impairment off.

    Returns
    -------
    Impairments

    Raises
    ------
    InvalidParameterError
        An item without ``=``, an unknown key (the message lists the valid ones), a key
        given twice, a value that is not a number, or a value out of range.

    Examples
    --------
    >>> imp = parse_impairments("dc=0.02, clip_db=10, hum_db=30, hum_hz=60")
    >>> imp.dc, imp.clip_db, imp.hum_hz
    (0.02, 10.0, 60.0)
    >>> parse_impairments(imp.spec()) == imp
    True
    >>> parse_impairments("clip=10")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    rangekit.errors.InvalidParameterError: unknown impairment key 'clip' (valid keys: dc, ...)
    """
    if not isinstance(spec, str):
        raise InvalidParameterError(f"impairment spec {spec!r} must be a string")
    kw: dict = {}
    for item in spec.split(",") if spec.strip() else ():
        key, sep, value = (s.strip() for s in item.partition("="))
        if not sep:
            raise InvalidParameterError(f"impairment {item.strip()!r} must be KEY=VALUE")
        if key not in KEYS:
            raise InvalidParameterError(
                f"unknown impairment key {key!r} (valid keys: {', '.join(KEYS)})"
            )
        if key in kw:
            raise InvalidParameterError(f"impairment key {key!r} is given twice")
        if key == "interference":
            kw[key] = value
            continue
        try:
            kw[key] = float(value)
        except ValueError:
            raise InvalidParameterError(f"{key}={value!r} must be a number") from None
    return Impairments(**kw)


@dataclass(frozen=True)
class ImpairResult:
    """An impaired recording.

    Attributes
    ----------
    x : ndarray, float64
        The impaired samples, in the input's layout ((n,) or (n, n_channels)), longer by
        ``2 * shift_samples``.
    shift_samples : int
        Zeros prepended (and appended): input sample ``k`` is output sample
        ``k + shift_samples``.
    clipped_fraction : ndarray, shape (n_channels,)
        Fraction of each channel's (unpadded) samples changed by the clipping.
    floor_psd : ndarray, shape (n_channels,)
        Reference floor used per channel, units^2/Hz (one-sided).
    """

    x: np.ndarray
    shift_samples: int
    clipped_fraction: np.ndarray
    floor_psd: np.ndarray


def noise_floor_psd(
    sigma: float, *, fs: float, kind: str = "white", n_samples: int | None = None
) -> float:
    """Reference floor of noise a simulator drew: ``sigma`` times unit-variance noise.

    Parameters
    ----------
    sigma : float
        Standard deviation of the noise in the recording (after any scaling), >= 0.
    fs : float
        Sample rate, Hz.
    kind : {"white", "pink"}
        The generator of :mod:`rangekit.sim.noise`.
    n_samples : int, optional
        Length of the pink noise drawn (its 1/f level depends on it); needed for pink.

    Returns
    -------
    float
        One-sided PSD, units^2/Hz: ``2 sigma^2 / fs`` for white noise; for pink, its PSD
        ``sigma^2 / (f Z / 2)`` (``Z`` the sum of the generator's bin weights, about
        ``2 ln(n / 2) + 1.15``) at the middle of the floor band, where the median over a
        linear frequency grid of a 1/f spectrum lies.

    Examples
    --------
    >>> noise_floor_psd(0.01, fs=44100.0) == 2 * 0.01**2 / 44100.0
    True
    """
    sigma = V.positive("sigma", sigma, allow_zero=True)
    fs = V.sample_rate(fs)
    if kind == "white":
        return 2.0 * sigma**2 / fs
    if kind != "pink":
        raise InvalidParameterError(f"kind={kind!r} must be 'white' or 'pink'")
    if n_samples is None:
        raise InvalidParameterError("n_samples is needed for kind='pink'")
    n = V.positive_int("n_samples", n_samples, minimum=2)
    lo, hi = _floor_band(fs)
    return sigma**2 / (0.5 * (lo + hi) * 0.5 * _pink_weight_sum(n))


def _pink_weight_sum(n: int) -> float:
    """``Z``: the variance of pink_noise's bins before normalisation, in units of bin 1's.

    Bin k (1 <= k < n/2) carries power 2/k of the variance; an even n's Nyquist bin 1/k.
    """
    k = np.arange(1, (n - 1) // 2 + 1, dtype=np.float64)
    z = float(np.sum(2.0 / k))
    return z + (2.0 / n if n % 2 == 0 else 0.0)


def _floor_nperseg(fs: float) -> int:
    """Welch segment of the floor estimate: the power of two at or above 20 ms of samples."""
    return 2 ** math.ceil(math.log2(_FLOOR_SEGMENT_S * fs))


def _floor_band(fs: float) -> tuple[float, float]:
    return FLOOR_BAND_HZ[0], min(FLOOR_BAND_HZ[1], 0.45 * fs)


def estimate_floor_psd(x: ArrayLike, *, fs: float) -> np.ndarray:
    """The recording's background-noise PSD per channel (the reference floor).

    Parameters
    ----------
    x : array_like, shape (n,) or (n, n_channels)
        The recording.
    fs : float
        Sample rate, Hz.

    Returns
    -------
    ndarray, shape (n_channels,)
        One-sided PSD, units^2/Hz: the median over the frequencies in 1 kHz ...
        min(20 kHz, 0.45 fs) of ``scipy.signal.welch(x, nperseg=min(N, n),
        average="median")``, ``N`` the power of two at or above 20 ms of samples (1024 at
        44.1 or 48 kHz, 4096 at 192 kHz). The median across segments ignores beeps and
        bursts in fewer than half the segments (short segments: a 10 ms burst fills few);
        the median over frequency ignores tones.

    Raises
    ------
    InvalidParameterError
        ``fs`` too low for the band to hold a frequency of the Welch grid.

    Examples
    --------
    >>> x = 0.01 * np.random.default_rng(0).standard_normal(10 * 44100)
    >>> f = estimate_floor_psd(x, fs=44100.0)
    >>> bool(abs(10 * np.log10(f[0] / (2 * 0.01**2 / 44100))) < 0.1)
    True
    """
    from scipy.signal import welch

    x2 = _as_channels(x)
    fs = V.sample_rate(fs)
    nper = min(_floor_nperseg(fs), x2.shape[0])
    f, p = welch(x2, fs=fs, nperseg=nper, axis=0, average="median")
    lo, hi = _floor_band(fs)
    band = (f >= lo) & (f <= hi)
    if not np.any(band):
        raise InvalidParameterError(
            f"fs={fs!r} Hz and {x2.shape[0]} samples leave no frequency in {lo:g}-{hi:g} Hz "
            "to estimate the noise floor from; give floor_psd"
        )
    return np.median(p[band], axis=0)


def _as_channels(x: ArrayLike) -> np.ndarray:
    """``x`` as a finite float64 (n, n_channels) array (a 1-D input is one channel)."""
    a = np.array(x, dtype=np.float64)
    if a.ndim not in (1, 2):
        raise InvalidParameterError(f"x must be 1-D or 2-D (samples, channels), got {a.shape}")
    if a.shape[0] < 2 or (a.ndim == 2 and a.shape[1] < 1):
        raise InvalidParameterError(f"x must hold >= 2 samples of >= 1 channel, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InvalidParameterError("x contains NaN or infinite values")
    return a.reshape(a.shape[0], -1)


def impair(
    x: ArrayLike,
    *,
    fs: float,
    impairments: Impairments,
    rng: RngLike = None,
    floor_psd: ArrayLike | None = None,
) -> ImpairResult:
    """Apply ``impairments`` to a recording (order and levels in the module notes).

    Parameters
    ----------
    x : array_like, shape (n,) or (n, n_channels)
        The recording, float, finite (not modified).
    fs : float
        Sample rate, Hz.
    impairments : Impairments
        What to apply.
    rng : RngLike, optional
        Random source, anything :func:`numpy.random.default_rng` accepts. Each channel,
        and within it each impairment, gets its own stream: channels are independent, and
        switching one impairment on does not change the draws of another.
    floor_psd : float or array_like of shape (n_channels,), optional
        Reference floor, units^2/Hz (one-sided), e.g. :func:`noise_floor_psd` of the
        simulator's noise; default :func:`estimate_floor_psd` of ``x``.

    Returns
    -------
    ImpairResult

    Raises
    ------
    InvalidParameterError
        Bad ``x`` or ``fs``; a frequency of ``impairments`` at or above fs / 2; a level
        relative to the floor asked for where the floor is zero (a noiseless render:
        below 1e-14 of the channel's mean PSD ``2 mean(x^2) / fs``, or 0).

    Examples
    --------
    >>> x = 0.01 * np.random.default_rng(0).standard_normal((44100, 2))
    >>> r = impair(x, fs=44100.0, impairments=Impairments(hum_db=30.0), rng=3)
    >>> r.x.shape, r.shift_samples
    ((44100, 2), 0)
    >>> hum = r.x - x
    >>> ratio_db = 10 * np.log10(np.mean(hum**2, axis=0) / (r.floor_psd * 200.0))
    >>> np.round(ratio_db, 6).tolist()
    [30.0, 30.0]
    """
    if not isinstance(impairments, Impairments):
        raise InvalidParameterError(
            f"impairments must be an Impairments, got {type(impairments).__name__}"
        )
    imp = impairments
    fs = V.sample_rate(fs)
    x2 = _as_channels(x)
    n_ch = x2.shape[1]
    _check_frequencies(imp, fs)
    if floor_psd is None:
        floor = estimate_floor_psd(x2, fs=fs)
    else:
        try:
            floor = np.broadcast_to(np.asarray(floor_psd, dtype=np.float64), (n_ch,)).copy()
        except (TypeError, ValueError):
            raise InvalidParameterError(
                f"floor_psd={floor_psd!r} must be one value or one per channel ({n_ch})"
            ) from None
        if not np.all(np.isfinite(floor) & (floor >= 0.0)):
            raise InvalidParameterError(f"floor_psd={floor_psd!r} must be finite and >= 0")
    if imp.relative_keys:
        mean_psd = 2.0 * np.mean(x2**2, axis=0) / fs
        for c in range(n_ch):
            if not (floor[c] > 0.0 and floor[c] >= 1e-14 * mean_psd[c]):
                raise InvalidParameterError(
                    f"{', '.join(imp.relative_keys)} are set relative to the recording's noise "
                    f"floor, but channel {c}'s floor is zero (a noiseless render?): render "
                    "with noise (e.g. --snr-db) or give the floor (floor_psd)"
                )
    sos = _band_sos(imp, fs)
    out = np.empty_like(x2)
    clipped = np.zeros(n_ch)
    for c, ch_rng in enumerate(_streams(np.random.default_rng(rng), n_ch)):
        out[:, c], clipped[c] = _impair_channel(
            x2[:, c], fs=fs, imp=imp, sos=sos, rng=ch_rng, floor=float(floor[c])
        )
    shift = round(imp.silence_s * fs)
    if shift:
        out = np.pad(out, ((shift, shift), (0, 0)))
    out = out[:, 0] if np.ndim(x) == 1 else out
    return ImpairResult(out, int(shift), clipped, floor)


def _check_frequencies(imp: Impairments, fs: float) -> None:
    nyq = 0.5 * fs
    for key in ("lp_hz", "hp_hz", "hum_hz"):
        v = getattr(imp, key)
        if v is not None and (key != "hum_hz" or imp.hum_db is not None) and v >= nyq:
            raise InvalidParameterError(f"{key}={v!r} must be below fs/2 = {nyq!r} Hz")
    if imp.interference == "music" and imp.interference_max_hz >= nyq:
        raise InvalidParameterError(
            f"interference_max_hz={imp.interference_max_hz!r} must be below fs/2 = {nyq!r} Hz"
        )


def _band_sos(imp: Impairments, fs: float) -> list[np.ndarray]:
    """Second-order sections of the band response: high-pass, then low-pass."""
    from scipy.signal import butter

    sos = []
    if imp.hp_hz is not None:
        sos.append(butter(2, imp.hp_hz, btype="highpass", fs=fs, output="sos"))
    if imp.lp_hz is not None:
        sos.append(butter(2, imp.lp_hz, btype="lowpass", fs=fs, output="sos"))
    return sos


def _streams(rng: np.random.Generator, k: int) -> list[np.random.Generator]:
    """``k`` independent generators seeded from ``rng``."""
    return [np.random.default_rng(s) for s in rng.integers(0, 2**62, size=k)]


def _impair_channel(
    x: np.ndarray, *, fs: float, imp: Impairments, sos, rng, floor: float
) -> tuple[np.ndarray, float]:
    """Steps 1-5 of the module notes on one channel; returns it and its clipped fraction."""
    from scipy.signal import sosfilt

    lf_rng, hum_rng, pink_rng, int_rng, agc_rng = _streams(rng, 5)
    n = len(x)
    for s in sos:
        x = sosfilt(s, x)
    x = x.copy()
    if imp.lf_db is not None:
        x += _lf_noise(n, fs=fs, psd=_power_ratio(imp.lf_db) * floor, rng=lf_rng)
    if imp.hum_db is not None:
        power = _power_ratio(imp.hum_db) * floor * _HUM_BAND_HZ
        x += _hum(n, fs=fs, f_hz=imp.hum_hz, power=power, rng=hum_rng)
    if imp.pink_db is not None:
        scale = math.sqrt(_power_ratio(imp.pink_db) * floor * _PINK_REF_HZ * 0.5)
        x += scale * math.sqrt(_pink_weight_sum(n)) * pink_noise(n, rng=pink_rng)
    if imp.interference is not None:
        lo, hi = interference_band_hz(imp, fs=fs)
        power = _power_ratio(imp.interference_db) * floor * (hi - lo)
        if imp.interference == "speech":
            y = _speech(n, fs=fs, rng=int_rng)
        else:
            y = _music(n, fs=fs, max_hz=imp.interference_max_hz, rng=int_rng)
        x += _with_power(y, power)
    if imp.agc_db is not None:
        x *= 10.0 ** (
            _agc_gain_db(n, fs=fs, step_db=imp.agc_db, n_steps=imp.agc_steps, rng=agc_rng) / 20
        )
    x += imp.dc
    frac = 0.0
    if imp.clip_db is not None:
        level = float(np.max(np.abs(x))) * 10.0 ** (-imp.clip_db / 20.0)
        frac = float(np.mean(np.abs(x) > level))
        x = np.clip(x, -level, level)
    return x, frac


def interference_band_hz(imp: Impairments, *, fs: float) -> tuple[float, float]:
    """The band ``B`` of the interference's level: speech 100 Hz-min(4 kHz, fs/2), music
    100 Hz-``interference_max_hz``."""
    if imp.interference == "music":
        return _MUSIC_LOW_HZ, imp.interference_max_hz
    return _SPEECH_BAND_HZ[0], min(_SPEECH_BAND_HZ[1], 0.5 * fs)


def _power_ratio(db: float) -> float:
    return 10.0 ** (db / 10.0)


def _with_power(y: np.ndarray, power: float) -> np.ndarray:
    """``y`` scaled to mean power ``power`` (all zeros stay zeros)."""
    p = float(np.mean(y**2))
    return y * math.sqrt(power / p) if p > 0.0 else y


def _shaped_noise(n: int, shape: np.ndarray, rng) -> np.ndarray:
    """Gaussian noise whose one-sided PSD is ``2 / fs * shape`` on the rfft grid."""
    return np.fft.irfft(np.fft.rfft(rng.standard_normal(n)) * np.sqrt(shape), n)


def _lf_shape(f: np.ndarray) -> np.ndarray:
    return 1.0 / ((f**2 + _LF_KNEE_HZ**2) * (1.0 + (f / _LF_BAND_HZ[1]) ** 8))


def _lf_noise(n: int, *, fs: float, psd: float, rng) -> np.ndarray:
    """Brown noise below 200 Hz whose expected mean PSD over 20-200 Hz is ``psd``."""
    shape = _lf_shape(np.fft.rfftfreq(n, 1.0 / fs))
    shape[0] = 0.0
    ref = 2.0 / fs * float(np.mean(_lf_shape(np.linspace(*_LF_BAND_HZ, 1801))))
    return _shaped_noise(n, shape, rng) * math.sqrt(psd / ref)


def _hum(n: int, *, fs: float, f_hz: float, power: float, rng) -> np.ndarray:
    """Mains hum of mean power ``power`` (module notes)."""
    top = min(_HUM_MAX_HZ, 0.5 * fs * (1.0 - 1e-9))
    k_max = max(1, int(math.floor(top / f_hz + 1e-9)))
    phases = rng.uniform(0.0, 2.0 * math.pi, k_max)
    f_w, phi_w = rng.uniform(0.1, 1.0), rng.uniform(0.0, 2.0 * math.pi)
    t = np.arange(n) / fs
    h = np.zeros(n)
    for k in range(1, k_max + 1):
        h += 10.0 ** (-6.0 * (k - 1) / 20.0) * np.cos(2.0 * math.pi * k * f_hz * t + phases[k - 1])
    h *= 1.0 + 0.1 * np.sin(2.0 * math.pi * f_w * t + phi_w)
    return _with_power(h, power)


def _speech_shape(f: np.ndarray) -> np.ndarray:
    lo, hi = _SPEECH_BAND_HZ
    return f**8 / (f**8 + lo**8) / (1.0 + (f / hi) ** 8) / (1.0 + (f / _SPEECH_TILT_HZ) ** 2)


def _speech(n: int, *, fs: float, rng) -> np.ndarray:
    """Speech-band noise (100 Hz-4 kHz, -6 dB/octave above 500 Hz) under syllables."""
    y = _shaped_noise(n, _speech_shape(np.fft.rfftfreq(n, 1.0 / fs)), rng)
    return y * _syllable_envelope(n, fs=fs, rng=rng)


def _syllable_envelope(n: int, *, fs: float, rng) -> np.ndarray:
    """Phrases of 2-8 syllables at 3-6 Hz (sin^2 bumps, peaks 0.3-1) and 0.2-1 s pauses."""
    env = np.zeros(n)
    dur = n / fs
    t = rng.uniform(0.0, min(0.3, 0.5 * dur))
    while t < dur:
        for _ in range(int(rng.integers(2, 9))):
            d = 1.0 / rng.uniform(3.0, 6.0)
            a = rng.uniform(0.3, 1.0)
            i0, i1 = round(t * fs), min(n, round((t + d) * fs))
            if i1 > i0:
                env[i0:i1] = a * np.sin(math.pi * (np.arange(i0, i1) / fs - t) / d) ** 2
            t += d
        t += rng.uniform(0.2, 1.0)
    return env


def _music(n: int, *, fs: float, max_hz: float, rng) -> np.ndarray:
    """Notes of 0.1-0.5 s one after the other: fundamentals 100-1000 Hz (log-uniform), up
    to 4 harmonics below ``max_hz`` at amplitudes 1/k, raised-cosine attack of 5-20 ms,
    exponential decay, 10 ms release."""
    y = np.zeros(n)
    dur, t = n / fs, 0.0
    while t < dur:
        d = rng.uniform(0.1, 0.5)
        f0 = math.exp(rng.uniform(math.log(100.0), math.log(1000.0)))
        k = np.arange(1, 5)
        k = k[k * f0 < max_hz]
        phases = rng.uniform(0.0, 2.0 * math.pi, k.size)
        attack, tau = rng.uniform(0.005, 0.02), d / rng.uniform(1.5, 4.0)
        i0, i1 = round(t * fs), min(n, round((t + d) * fs))
        u = np.arange(i1 - i0) / fs
        env = np.where(
            u < attack, np.sin(0.5 * math.pi * u / attack) ** 2, np.exp(-(u - attack) / tau)
        )
        env *= np.sin(0.5 * math.pi * np.clip((d - u) / 0.01, 0.0, 1.0)) ** 2
        for kk, ph in zip(k, phases, strict=True):
            y[i0:i1] += env * np.cos(2.0 * math.pi * kk * f0 * u + ph) / kk
        t += d
    return y


def _agc_gain_db(n: int, *, fs: float, step_db: float, n_steps: int, rng) -> np.ndarray:
    """Gain in dB per sample: ``n_steps`` steps of +-``step_db`` at random times."""
    ramp = _AGC_RAMP_S * fs
    starts = np.sort(rng.uniform(0.0, max(n - 1 - ramp, 0.0), n_steps))
    signs = rng.choice([-1.0, 1.0], n_steps)
    i = np.arange(n, dtype=np.float64)
    g = np.zeros(n)
    for s0, sign in zip(starts, signs, strict=True):
        g += sign * step_db * np.clip((i - s0) / ramp, 0.0, 1.0)
    return g


def shift_truth(truth: dict, shift_samples: int) -> dict:
    """A simulator's truth with every sample index and time moved for ``shift_samples``
    zeros prepended to every recording (a copy; ``truth`` is not modified).

    Moves the layouts of :mod:`rangekit.sim`: ``devices[i].onsets`` (+shift) and
    ``devices[i].rec_start_s`` (-shift / (fs (1 + clock_ppm 1e-6)), so that sample n is still
    taken at ``rec_start_s + n / rate``) of ``render_beepbeep`` and ``render_exchanges``,
    ``exchanges[e].onsets`` (+shift) of ``render_exchanges``, ``windows[k].start_sample``
    (+shift) of ``render_oneway`` and ``render_echo``. Absolute times (``play_s``) and
    distances do not change.

    Examples
    --------
    >>> t = {"devices": [{"onsets": [10.5, 99.0], "rec_start_s": 1.0, "fs": 100.0}]}
    >>> shift_truth(t, 50)["devices"][0]
    {'onsets': [60.5, 149.0], 'rec_start_s': 0.5, 'fs': 100.0}
    """
    shift = V.positive_int("shift_samples", shift_samples, minimum=0)
    out = copy.deepcopy(truth)
    for d in out.get("devices") or ():
        d["onsets"] = [o + shift for o in d["onsets"]]
        rate = d["fs"] * (1.0 + d.get("clock_ppm", 0.0) * 1e-6)
        d["rec_start_s"] = d["rec_start_s"] - shift / rate
    for e in out.get("exchanges") or ():
        e["onsets"] = [[o + shift for o in row] for row in e["onsets"]]
    for w in out.get("windows") or ():
        w["start_sample"] = w["start_sample"] + shift
    return out
