"""Phase-coherent timing of a wideband arrival: the extremum of the real correlation.

The envelope ``|c|`` of the analytic matched-filter output times an arrival by its
group delay and ignores its carrier phase. For a probe whose band is wide compared with
its centre frequency, the real part ``Re c`` (the recording correlated with the real
template, i.e. the received response band-limited by the probe's autocorrelation)
has one dominant extremum, and that extremum is the peak of the received pressure
pulse: the convention by which measured impulse responses are annotated (dEchorate's
direct paths are picked peaks of ``|h|``). For a pure delay both estimates agree (the
real part of the self response is even, peaked at lag 0); through a transducer whose
response is not symmetric (causal, minimum-phase-like pulses) the envelope peak and the
pulse peak part by up to a quarter of the carrier period. Theory and measurements:
``docs/theory/probes.md`` (first path, phase-coherent timing).

The coherent estimate is used only where it cannot slip a cycle: when the real self
response's largest side extremum is at most :data:`COHERENT_SIDE` of its main one (a
fractional bandwidth of about 0.4 or more: 200 Hz-13 kHz, 20 Hz-20 kHz; not 17-20 kHz
or 8-12 kHz, whose carrier cycles under the envelope are nearly equal), and as far as
the arrival's phase at its envelope peak is near the template's (0 or pi): alone
within 30 degrees, not at all beyond 60 (an arrival in quadrature has two equal
extrema), blended linearly in ``|cos phase|`` between (:func:`coherent_weight`).
Otherwise the envelope timing stands.
"""

from __future__ import annotations

import math

import numpy as np

#: The real self response's largest side extremum must be at most this fraction of its
#: main extremum for the phase-coherent timing to be used (no cycle to slip to).
COHERENT_SIDE = 0.5
#: The arrival's ``|cos phase|`` at its envelope peak from which the coherent timing is
#: used alone (phase within 30 degrees of 0 or pi) ...
COHERENT_FULL_COS = math.cos(math.pi / 6.0)
#: ... and up to which the envelope timing is used alone (phase 60-90 degrees: the real
#: part's extremum is no longer the pulse's own); in between the two are blended
#: linearly in ``|cos phase|``, so that the onset does not jump between definitions when
#: two recordings of one arrival differ only by noise.
COHERENT_NONE_COS = math.cos(math.pi / 3.0)


def real_side_ratio(self_resp: np.ndarray, reach: int) -> float:
    """Largest side extremum of ``|Re R|`` over its main one, within ``+- reach`` lags.

    ``self_resp``: the filter's complex self response, centred (index ``len // 2`` =
    lag 0). 1.0 when no side extremum can be told apart (treat as ambiguous).
    """
    m = len(self_resp) // 2
    r = np.abs(self_resp.real[max(0, m - reach) : m + reach + 1])
    if len(r) < 3:
        return 1.0
    mid = r[1:-1]
    pk = np.flatnonzero((mid >= r[:-2]) & (mid > r[2:])) + 1
    if len(pk) < 2:
        return 0.0 if len(pk) == 1 else 1.0
    v = np.sort(r[pk])[::-1]
    return float(v[1] / v[0]) if v[0] > 0 else 1.0


#: Half width (samples) of the windowed-sinc interpolation of the real part.
SINC_HALF = 16
#: Kaiser window parameter of that interpolation (a tone below 0.84 of the Nyquist
#: frequency is reconstructed to 1e-4 of its peak; 0.9 of it to 5e-2: docs/evidence.md).
SINC_BETA = 8.0


#: The Kaiser window over offsets ``[-SINC_HALF - 1, SINC_HALF + 1]`` on a fine grid (its
#: values at fractional offsets are read from it by linear interpolation).
_WIN_U = np.linspace(-SINC_HALF - 1.0, SINC_HALF + 1.0, 64 * (2 * SINC_HALF + 2) + 1)
_WIN = np.i0(SINC_BETA * np.sqrt(np.clip(1.0 - (_WIN_U / (SINC_HALF + 1.0)) ** 2, 0, 1)))
_WIN = _WIN / _WIN.max()


def _sinc_at(r: np.ndarray, t: float) -> float:
    """Band-limited value of ``r`` at fractional index ``t`` (Kaiser-windowed sinc)."""
    k0 = int(math.floor(t))
    k = np.arange(max(0, k0 - SINC_HALF + 1), min(len(r), k0 + SINC_HALF + 1))
    u = t - k
    return float(np.dot(r[k], np.sinc(u) * np.interp(u, _WIN_U, _WIN)))


def refine_extremum(r: np.ndarray, i: int) -> float:
    """Sub-sample location of the extremum of band-limited ``r`` near index ``i``.

    Golden-section search of ``|r(t)|`` (windowed-sinc interpolation, exact for a signal
    band-limited below the Nyquist frequency up to the window's error) on ``[i - 1, i +
    1]``, to 1e-4 samples: a parabola through three samples is biased by up to 0.2
    samples on a pulse as sharp as a 20 Hz-20 kHz sweep's at 44.1 kHz.
    """
    if i < 1 or i > len(r) - 2:
        return float(i)
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = i - 1.0, i + 1.0
    x1, x2 = b - g * (b - a), a + g * (b - a)
    f1, f2 = abs(_sinc_at(r, x1)), abs(_sinc_at(r, x2))
    while b - a > 1e-4:
        if f1 >= f2:
            b, x2, f2 = x2, x1, f1
            x1 = b - g * (b - a)
            f1 = abs(_sinc_at(r, x1))
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + g * (b - a)
            f2 = abs(_sinc_at(r, x2))
    return 0.5 * (a + b)


def coherent_weight(cos_phase: float) -> float:
    """Weight of the coherent timing for an arrival whose phase at its envelope peak has
    ``|cos| = cos_phase``: 1 within 30 degrees of 0 or pi, 0 beyond 60, linear between.

    Examples
    --------
    >>> [round(coherent_weight(math.cos(math.radians(a))), 3) for a in (0, 30, 45, 60, 90)]
    [1.0, 1.0, 0.566, 0.0, 0.0]
    """
    w = (cos_phase - COHERENT_NONE_COS) / (COHERENT_FULL_COS - COHERENT_NONE_COS)
    return min(1.0, max(0.0, w))


def coherent_lag(c: np.ndarray, lag: float, reach: int) -> tuple[float, float] | None:
    """The lag of the largest extremum of ``|Re c|`` within ``+- reach`` of ``lag``.

    Parameters
    ----------
    c : ndarray
        Analytic matched-filter output (complex).
    lag : float
        The envelope's (sub-sample) lag of the path.
    reach : int
        Half width of the search, samples (a quarter carrier period and a sample).

    Returns
    -------
    (float, float) or None
        The sub-sample lag (:func:`refine_extremum` of ``Re c``) and ``|cos|`` of the
        arrival's phase at ``lag`` (``|Re c| / |c|`` there, interpolated; weigh the two
        timings by :func:`coherent_weight` of it), or None when the window holds no
        interior extremum.

    Examples
    --------
    A pulse whose carrier is in phase one sample before its envelope's peak: its real
    part peaks 0.9 samples early (the envelope pulls it back by 0.1):

    >>> n = np.arange(64.0)
    >>> env = np.exp(-0.5 * ((n - 32.0) / 3.0) ** 2)
    >>> c = env * np.exp(2j * np.pi * 0.15 * (n - 31.0))
    >>> [round(v, 2) for v in coherent_lag(c, 32.0, 3)]
    [31.11, 0.59]
    """
    j = int(round(lag))
    lo, hi = max(1, j - reach), min(len(c) - 1, j + reach + 1)
    if hi - lo < 1:
        return None
    # The arrival's phase at its envelope peak (band-limited interpolation).
    a = max(0, j - SINC_HALF - 2)
    b = min(len(c), j + SINC_HALF + 3)
    re = _sinc_at(np.ascontiguousarray(c.real[a:b]), lag - a)
    im = _sinc_at(np.ascontiguousarray(c.imag[a:b]), lag - a)
    cos_phase = abs(re) / max(math.hypot(re, im), 1e-300)
    r = np.abs(c.real[lo - 1 : hi + 1])
    mid = r[1:-1]
    pk = np.flatnonzero((mid >= r[:-2]) & (mid > r[2:]))
    if len(pk) == 0:
        return None
    i = int(pk[np.argmax(mid[pk])]) + 1
    p = lo - 1 + i
    a = max(0, p - SINC_HALF - 2)
    t = a + refine_extremum(np.ascontiguousarray(c.real[a : p + SINC_HALF + 3]), p - a)
    return t, cos_phase


def coherent_interp_rms(self_resp: np.ndarray, reach: int, n: int = 16) -> float:
    """RMS error (samples) of :func:`coherent_lag` on ``self_resp`` delayed by ``k / n``."""
    m = len(self_resp) // 2
    f = np.fft.fftfreq(len(self_resp))
    spec = np.fft.fft(self_resp)
    errs = []
    for k in range(n):
        d = k / n
        r = np.fft.ifft(spec * np.exp(-2j * math.pi * f * d))
        t = coherent_lag(r, m + d, reach)
        errs.append(0.5 if t is None else t[0] - (m + d))
    return max(float(np.sqrt(np.mean(np.square(errs)))), 1e-6)
