"""Timing coded ultrasonic bursts through transducers of unknown Q: a multipath model fit.

A 40 kHz air transducer is a resonator whose Q is rarely known (MA40S4-class elements
are of the order of 10-20; rangekit's default model is 4). The resonator delays the
burst by its group delay ``Q / (pi f0)`` per element and smears its envelope, so a
matched filter whose template assumes the wrong Q puts the arrival tens of millimetres
off (``docs/theory/ultrasonic.md``). This module estimates the transducers with the
arrival instead of assuming them.

**Model.** The received stretch around an arrival is

    x[n] = sum_k Re{ alpha_k s_a(n - u_k; Q, f0) } + w[n],

``s_a`` the analytic signal of the known drive passed through ``stages`` identical
second-order resonators (:class:`rangekit.signals.transducer.Transducer`: the Tx and the
Rx element, or the one element of a pulse-echo sensor twice) with a common quality
factor ``Q`` and resonance ``f0``; ``u_k`` the onsets of the paths (the first is the
direct path, later ones reflections that may overlap it), ``alpha_k`` their complex
amplitudes (carrier phase unknown), ``w`` white noise. Index 0 of ``s_a`` is the drive's
first sample, so ``u_0`` is the time of flight with every transducer delay removed,
whatever ``Q`` is.

**Fit.** Maximum likelihood in white noise is least squares. The amplitudes enter
linearly and are solved for at every step (variable projection, Golub & Pereyra 1973,
"The differentiation of pseudo-inverses and nonlinear least squares problems whose
variables separate", SIAM J. Numer. Anal. 10(2); Kaufman's 1975 simplified Jacobian);
the onsets, ``log Q`` and ``f0`` by Levenberg-Marquardt with analytic derivatives. The
waveforms and their derivatives are evaluated in the frequency domain (a phase ramp for
a sub-sample onset, the resonators' exact digital response for ``Q`` and ``f0``). Paths
are added one at a time from the residual's matched-filter peak (CLEAN-like, Högbom
1974) while it stands ``k_add`` noise scales up and ``rel_add`` of the strongest path.

**Uncertainty.** The covariance of the nonlinear parameters is ``sigma^2 (J^T J)^-1``
with ``J`` the projected Jacobian (the Cramér-Rao bound evaluated at the fit, amplitudes
profiled out), so the onset's sigma includes what not knowing ``Q`` and ``f0`` costs
(and what an overlapping reflection costs). :func:`pool_fits` combines the ``(log Q,
f0)`` estimates of arrivals through the same transducers (one Tx and one Rx over many
activation windows) and conditions each onset on the pooled value, which brings the
onset's sigma down to the known-transducer bound.

Examples
--------
>>> from rangekit.signals.barker import CodedBurst, burst_waveform
>>> from rangekit.signals.transducer import Transducer
>>> fs = 192000.0
>>> model = ResonatorModel.for_burst(CodedBurst(), fs=fs)
>>> t = Transducer(q=15.0)
>>> x = np.zeros(3000)
>>> x[1000:1101] = burst_waveform(CodedBurst(fs=fs))
>>> x = t.apply(t.apply(x, fs=fs), fs=fs)
>>> f = fit_arrival(x, 1000.0, model=model, sigma=1e-4, q0=4.0)
>>> round(f.onset, 3), round(f.q, 2), f.n_paths
(1000.0, 15.0, 1)
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from rangekit import _validate as V
from rangekit.detect._fft import pocketfft
from rangekit.detect._kernel_choice import (  # noqa: F401  (re-exported)
    _KERNEL,
    KERNEL_MIN_SAMPLES,
    compiled_step,
    kernel_by_length,
)
from rangekit.signals.barker import CodedBurst, burst_waveform

__all__ = [
    "PathFit",
    "ResonatorModel",
    "fit_arrival",
    "fit_paths",
    "pool_fits",
]

#: Range of Q the fit may take (a -3 dB band of 40 kHz to 1.3 kHz at 40 kHz).
Q_LIMITS = (1.0, 30.0)
#: f0 may move this fraction off the nominal resonance (MA40S4: 40.0 +- 1.0 kHz).
F0_LIMIT = 0.1
#: Segment read before the coarse first path, s (a direct path hidden by a stronger
#: reflection up to this much later is still inside the fit).
PRE_S = 0.4e-3
#: Segment kept after the drive's end, s: 5 ring-down time constants Q / (pi f0) of a
#: Q = 20 element at 40 kHz (the tail carries most of what tells Q from the onset).
TAIL_S = 0.8e-3
#: Default noise multiple a residual peak must clear to become a further path.
K_ADD = 6.0
#: Default fraction of the strongest path's amplitude a further path must reach: smaller
#: residual structure is model error (a transducer not quite two equal resonators), and
#: paths fitted to it would bend the first path.
REL_ADD = 0.1
#: Skip the two-path scan of fits started from given paths.
SKIP_SCAN = True
#: Most paths fitted in one segment.
MAX_PATHS = 4
#: Levenberg-Marquardt iterations per fit.
MAX_ITER = 30


def _ifft(a, n, axis=-1):
    """``scipy.fft.ifft(a, n, axis)``; a 1-d or last-axis input shorter than ``n`` is
    zero-padded here and transformed by pocketfft directly (the same call scipy makes:
    the same numbers, without its per-call argument handling)."""
    a = np.asarray(a)
    if a.ndim and axis in (-1, a.ndim - 1) and a.shape[-1] <= n and _POCKET is not None:
        buf = np.zeros((*a.shape[:-1], n), dtype=np.complex128)
        buf[..., : a.shape[-1]] = a
        return _POCKET.c2c(buf, (a.ndim - 1,), False, 2, buf, 1)
    from scipy import fft

    return fft.ifft(a, n=n, axis=axis)


def _rfft(a, n):
    """``scipy.fft.rfft(a, n)`` of a real 1-d ``a`` (pocketfft directly, as :func:`_ifft`)."""
    a = np.asarray(a)
    if a.ndim == 1 and len(a) <= n and a.dtype == np.float64 and _POCKET is not None:
        buf = np.zeros(n)
        buf[: len(a)] = a
        return _POCKET.r2c(buf, (0,), True, 0, None, 1)
    from scipy import fft

    return fft.rfft(a, n=n)


#: scipy's pocketfft (None: another scipy layout, the public calls): the fit runs only
#: where its transforms are needed, so it is looked up when this module is imported.
_POCKET = pocketfft()


def _next_pow2(n: int) -> int:
    return 1 << max(4, int(math.ceil(math.log2(max(n, 1)))))


class ResonatorModel:
    """The drive's spectrum and the resonators' response on one FFT grid.

    Parameters
    ----------
    drive : ndarray
        The emitted drive at ``fs`` (index 0 = drive start).
    fs : float
        Sample rate in Hz.
    f0_hz : float
        Nominal resonance (the fit's starting point and the centre of its f0 range).
    stages : int
        Identical second-order resonators in the path (2: a Tx and an Rx element).
    segment : int, optional
        Length of the fitted stretch in samples; default ``PRE_S + drive + TAIL_S``.
    """

    def __init__(
        self,
        drive: np.ndarray,
        *,
        fs: float,
        f0_hz: float = 40000.0,
        stages: int = 2,
        segment: int | None = None,
    ) -> None:
        self.fs = V.sample_rate(fs)
        self.drive = V.signal_1d("drive", drive)
        self.f0_hz = V.positive("f0_hz", f0_hz)
        self.stages = V.positive_int("stages", stages)
        self.pre = int(round(PRE_S * self.fs))
        n_d = len(self.drive)
        self.segment = (
            self.pre + n_d + int(round(TAIL_S * self.fs))
            if segment is None
            else V.positive_int("segment", segment, minimum=n_d)
        )
        # The grid must hold the segment plus the slowest response's ring-down (10 time
        # constants Q / (pi f0) at the top Q: -70 dB) so that little wraps around into it.
        ring = 10.0 * Q_LIMITS[1] / (math.pi * self.f0_hz) * self.fs
        self.n_fft = _next_pow2(int(self.segment + n_d + ring))
        m = self.n_fft
        k = np.arange(m // 2 + 1)
        self.w = 2.0 * math.pi * k / m  # rad / sample
        self._z = np.exp(-1j * self.w)
        self._mjw = -1j * self.w
        d = np.fft.rfft(self.drive, m)
        d[1 : m // 2] *= 2.0  # one-sided: the analytic signal's spectrum
        self._d = d
        self._cache: dict = {}

    @classmethod
    def for_burst(
        cls, burst: CodedBurst | None = None, *, fs: float, f0_hz: float | None = None,
        stages: int = 2,
    ) -> ResonatorModel:  # fmt: skip
        """The model of ``burst`` (default Barker-7) at ``fs``, cached per arguments."""
        burst = CodedBurst() if burst is None else burst
        f0 = burst.carrier_hz if f0_hz is None else float(f0_hz)
        return _model(burst.with_fs(float(fs)), float(fs), f0, int(stages))

    def _resonator(self, q: float, f0: float, derivs: bool):
        """One resonator's response on the grid (and d/dlogQ, d/df0)."""
        fs = self.fs
        bw = min(f0 / q, 0.99 * fs / 2)
        beta = math.tan(math.pi * bw / fs)
        g = 1.0 / (1.0 + beta)
        w0 = 2.0 * math.pi * f0 / fs
        c = math.cos(w0)
        z = self._z
        z2 = z * z
        num = 1.0 - z2
        den = 1.0 - 2.0 * g * c * z + (2.0 * g - 1.0) * z2
        h = (1.0 - g) * num / den
        if not derivs:
            return h, None, None
        dh_dg = -num / den - h * (2.0 * z2 - 2.0 * c * z) / den
        dh_dc = h * 2.0 * g * z / den
        dg_dbw = -g * g * (math.pi / fs) * (1.0 + beta * beta)
        dh_dlogq = dh_dg * dg_dbw * (-bw)
        dh_df0 = dh_dg * dg_dbw / q + dh_dc * (-(2.0 * math.pi / fs) * math.sin(w0))
        return h, dh_dlogq, dh_df0

    def spectrum(self, q: float, f0: float, derivs: bool = False):
        """One-sided spectrum of ``s_a`` (and its derivatives by log Q and f0)."""
        key = (float(q), float(f0), bool(derivs))
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        h, hq, hf = self._resonator(q, f0, derivs)
        m = self.stages
        hm1 = h ** (m - 1)
        s = self._d * hm1 * h
        if derivs:
            base = m * self._d * hm1
            out = (s, base * hq, base * hf)
        else:
            out = s
        if len(self._cache) > 64:
            self._cache.clear()
        self._cache[key] = out
        return out

    #: Number of transducer parameters ``theta = (log Q, f0)``.
    n_theta = 2
    #: Name of the transducer family (:attr:`PathFit.family`).
    family = "resonator"

    def theta_start(self, q: float, f0: float | None = None) -> np.ndarray:
        """``theta = (log Q, f0)`` for a quality factor and resonance (clipped to the limits)."""
        f0 = self.f0_hz if f0 is None else float(f0)
        return self.theta_clip(np.array([math.log(q), f0]))

    def theta_clip(self, theta: np.ndarray) -> np.ndarray:
        """``theta`` inside the fit's limits (``Q_LIMITS``, f0 within ``F0_LIMIT``)."""
        lq = min(max(float(theta[0]), math.log(Q_LIMITS[0])), math.log(Q_LIMITS[1]))
        f = min(max(float(theta[1]), self.f0_hz * (1 - F0_LIMIT)), self.f0_hz * (1 + F0_LIMIT))
        return np.array([lq, f])

    def theta_step(self) -> np.ndarray:
        """Largest Levenberg-Marquardt step of each parameter."""
        return np.array([0.35, 0.01 * self.f0_hz])

    def theta_variants(self, theta: np.ndarray) -> list[np.ndarray]:
        """Broader models a merged pair of paths may hide behind (the two-path scan)."""
        ds = (math.log(2.0), 0.5 * math.log(2.0), 0.0)
        return [self.theta_clip(theta - np.array([d, 0.0])) for d in ds]

    def scan_thetas(self, f0: float) -> list[np.ndarray]:
        """The starting scan of a free fit (``SCAN_Q`` at ``f0``)."""
        return [self.theta_start(q, f0) for q in SCAN_Q]

    @staticmethod
    def q_f0(theta: np.ndarray) -> tuple[float, float]:
        """``(Q, f0)`` of ``theta``."""
        return math.exp(float(theta[0])), float(theta[1])

    def spectrum_t(self, theta: np.ndarray, derivs: bool = False):
        """:meth:`spectrum` at ``theta``; with ``derivs`` ``(s, [ds/dtheta_i])``."""
        out = self.spectrum(math.exp(float(theta[0])), float(theta[1]), derivs)
        return (out[0], list(out[1:])) if derivs else out

    def energy(self, q: float, f0: float) -> float:
        """Energy ``sum s[n]^2`` of the real received waveform of unit amplitude."""
        s = self.spectrum(q, f0)
        return float(np.sum(np.abs(s) ** 2) / (2.0 * self.n_fft))

    def waveform(self, q: float, f0: float, n: int | None = None) -> np.ndarray:
        """The real received waveform (drive through the resonators), ``n`` samples."""
        n = self.n_fft if n is None else int(n)
        return self._shifted(self.spectrum(q, f0)[None, :], np.zeros(1), n)[0].real

    def _shifted(self, specs: np.ndarray, u: np.ndarray, n: int) -> np.ndarray:
        """Rows ``IFFT(spec_i exp(-j w u_i))[:n]``: the waveforms with onsets ``u_i``."""
        ph = np.exp(np.multiply.outer(u, self._mjw))
        return _ifft(specs * ph, n=self.n_fft, axis=1)[:, :n]

    def energy_inside(self, q: float, f0: float, n: int) -> np.ndarray:
        """``E[j]``: energy of the unit waveform's first ``n - j`` samples (a path at lag
        ``j`` of an ``n``-sample segment, cut by the segment's end), ``j = 0 .. n - 1``."""
        key = ("cum", float(q), float(f0), int(n))
        hit = self._cache.get(key)
        if hit is None:
            w = self.waveform(q, f0, n)
            hit = np.cumsum(w * w)[::-1].copy()
            self._cache[key] = hit
        return hit

    def residual_mf(self, r: np.ndarray, q: float, f0: float) -> np.ndarray:
        """Analytic matched filter of ``r`` with the model's waveform, lags ``[0, len(r))``."""
        m = self.n_fft
        spec = np.conj(self.spectrum(q, f0))
        return _ifft(_rfft(r, n=m) * spec, n=m)[: len(r)]


@functools.lru_cache(maxsize=16)
def _model(burst: CodedBurst, fs: float, f0: float, stages: int) -> ResonatorModel:
    return ResonatorModel(burst_waveform(burst), fs=fs, f0_hz=f0, stages=stages)


def _key(tag: str, theta: np.ndarray, *extra) -> tuple:
    # (the Python floats of theta's values: tolist() is float(v) of each, in one call)
    return (tag, *np.asarray(theta, dtype=np.float64).tolist(), *extra)


def _energy(model, theta: np.ndarray) -> float:
    """Energy ``sum s[n]^2`` of the real received waveform of unit amplitude at ``theta``
    (cached on the model)."""
    cache = _held_cache(model)
    key = _key("energy", theta)
    hit = cache.get(key)
    if hit is None:
        s = model.spectrum_t(theta)
        hit = float(np.sum(np.abs(s) ** 2) / (2.0 * model.n_fft))
        _held_put(cache, key, hit)
    return hit


#: Entries of a model's cache of held-``theta`` quantities (:func:`_held_cache`).
HELD_CACHE = 16


def _held_cache(model) -> dict:
    """The model's cache of quantities at the ``theta`` a group's fits hold (energy,
    shift tables): apart from ``model._cache``, which the free fits' many spectra clear,
    so that the groups' few held values (one per group, alternating) stay."""
    cache = model.__dict__.get("_held")
    if cache is None:
        cache = model.__dict__["_held"] = {}
    return cache


def _held_put(cache: dict, key, value) -> None:
    if len(cache) >= HELD_CACHE:
        cache.pop(next(iter(cache)))  # the oldest entry
    cache[key] = value


def _energy_inside(model, theta: np.ndarray, n: int) -> np.ndarray:
    """``E[j]``: energy of the unit waveform's first ``n - j`` samples (a path at lag ``j``
    of an ``n``-sample segment, cut by the segment's end)."""
    key = _key("cum", theta, int(n))
    hit = model._cache.get(key)
    if hit is None:
        s = model.spectrum_t(theta)
        w = model._shifted(s[None, :], np.zeros(1), n)[0].real
        hit = np.cumsum(w * w)[::-1].copy()
        model._cache[key] = hit
    return hit


def _residual_mf(model, r: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Analytic matched filter of ``r`` with the model's waveform at ``theta``."""
    m = model.n_fft
    return _ifft(_rfft(r, n=m) * np.conj(model.spectrum_t(theta)), n=m)[: len(r)]


def _resolution(model, theta: np.ndarray) -> float:
    """Lag (samples) where the waveform's autocorrelation envelope falls to one half."""
    key = _key("res", theta)
    hit = model._cache.get(key)
    if hit is not None:
        return hit
    s = model.spectrum_t(theta)
    r = np.abs(np.fft.ifft(np.abs(s) ** 2, n=model.n_fft))
    half = np.flatnonzero(r[: model.n_fft // 2] < 0.5 * r[0])
    out = float(half[0]) if len(half) else float(model.n_fft // 2)
    model._cache[key] = out
    return out


def _q_f0_resonator(theta: np.ndarray) -> tuple[float, float]:
    return math.exp(float(theta[0])), float(theta[1])


@dataclass(frozen=True)
class PathFit:
    """The fitted paths of one arrival, and what its onset knows about the transducers.

    The onset depends on the transducers' parameters ``theta`` (``(log Q, f0)`` for
    :class:`ResonatorModel`, four for :class:`rangekit.detect.stagger.StaggerModel`):
    along the fit's profile ``onset(theta) = onset + gain . (theta - theta_lin)``. The
    arrival's own estimate of ``theta`` is ``theta_hat`` with information matrix ``info``
    (inverse covariance); with it the onset is :attr:`onset` and its 1-sigma
    :attr:`sigma`. :func:`pool_fits` replaces ``theta_hat`` by a pooled value.

    Attributes
    ----------
    onset : float
        Onset of the first path (the direct path), sub-sample index into the recording,
        at ``theta_hat``.
    sigma : float
        Its 1-sigma in samples: the Cramér-Rao bound at the fit with ``theta`` known to
        ``info`` (the transducers, the other paths and every amplitude estimated).
    snr : float
        The first path's ``|alpha| sqrt(E) / sigma_noise`` (its matched-filter peak over
        the noise's Rayleigh scale, ``sqrt(2 E / N0)``).
    q, f0_hz : float
        ``theta_hat`` as a quality factor and a resonance in Hz (for the stagger model
        the element's Q if its two resonances were maximally flat, and their centre).
    onsets, amplitudes : ndarray
        Every fitted path (sorted by onset, at ``theta_lin``) and its ``|alpha|``.
    first : int
        Index of the first path in ``onsets``.
    misfit : float
        Fraction of the fitted signal's energy the model leaves unexplained beyond the
        noise (0 for a perfect model; noise-corrected, may be slightly negative).
    misfit_z : float
        The residual's excess over the noise in standard deviations of its chi-square.
    resolution : float
        Half width (samples) at which the model waveform's autocorrelation envelope falls
        to one half: paths closer than this are not resolved by a matched filter.
    theta_lin : ndarray, shape (p,)
        The ``theta`` the paths were fitted at (``theta_hat`` for a free fit, the
        group's estimate for a fit that held it).
    gain : ndarray, shape (p,)
        ``d onset / d theta`` along the profile (samples per unit of each parameter).
    var_given : float
        Variance of the onset with ``theta`` known (samples^2).
    theta_hat : ndarray, shape (p,)
        The arrival's own estimate of ``theta`` (or the pooled one).
    info : ndarray, shape (p, p)
        Information (inverse covariance) of ``theta_hat`` from this arrival alone.
    pooled : bool
        Whether ``theta_hat`` is a pooled value (:func:`pool_fits`).
    family : str
        The transducer model (``"resonator"`` or ``"stagger"``).
    chi2 : float
        The fit's residual sum of squares over the noise variance.
    n_par : int
        Parameters the fit estimated (3 per path, ``theta`` unless held).
    q_of : callable, optional
        Map from ``theta`` to ``(Q, f0)`` (default the resonator's ``(exp, id)``).
    n0 : int
        First sample of the fitted segment in the recording (-1 if unknown).
    """

    onset: float
    sigma: float
    snr: float
    q: float
    f0_hz: float
    onsets: np.ndarray
    amplitudes: np.ndarray
    first: int
    misfit: float
    misfit_z: float
    resolution: float
    theta_lin: np.ndarray
    gain: np.ndarray
    var_given: float
    theta_hat: np.ndarray
    info: np.ndarray
    pooled: bool = False
    family: str = "resonator"
    chi2: float = math.nan
    n_par: int = 0
    q_of: object = None
    n0: int = -1

    @property
    def n_paths(self) -> int:
        """Number of fitted paths."""
        return len(self.onsets)

    @property
    def strongest(self) -> int:
        """Index of the strongest fitted path."""
        return int(np.argmax(self.amplitudes))

    def at(self, theta: np.ndarray, cov: np.ndarray, *, pooled: bool = True) -> PathFit:
        """This fit with ``theta`` known to covariance ``cov``."""
        from dataclasses import replace

        theta = np.asarray(theta, dtype=np.float64)
        cov = np.asarray(cov, dtype=np.float64)
        onset = self.onsets[self.first] + float(self.gain @ (theta - self.theta_lin))
        var = self.var_given + float(self.gain @ cov @ self.gain)
        q, f0 = (self.q_of or _q_f0_resonator)(theta)
        return replace(
            self,
            onset=float(onset),
            sigma=math.sqrt(max(var, 0.0)),
            q=q,
            f0_hz=f0,
            theta_hat=theta,
            pooled=pooled,
        )


@dataclass
class _State:
    u: np.ndarray
    theta: np.ndarray
    cost: float
    a: np.ndarray
    r: np.ndarray
    basis: np.ndarray
    gram_inv: np.ndarray  # (basis^T basis)^-1
    jac: np.ndarray  # d model / d (u_1..u_K, [theta]), unprojected
    with_theta: bool
    jp: np.ndarray | None = None  # the projected Jacobian, when computed with the state
    rows: np.ndarray | None = None  # (2, k, n) waveform and onset rows (the held kernel's)


def _evaluate(x: np.ndarray, model, u: np.ndarray, theta: np.ndarray, with_theta: bool) -> _State:
    """Least-squares amplitudes, residual and model Jacobian at ``(u, theta)``."""
    n, k = len(x), len(u)
    theta = np.asarray(theta, dtype=np.float64)
    if with_theta:
        s, ds = model.spectrum_t(theta, derivs=True)
        base = np.array([s, s * model._mjw, *ds])
    else:
        s = model.spectrum_t(theta)
        base = np.array([s, s * model._mjw])
    nb, nl = base.shape
    ph = np.exp(np.multiply.outer(u, model._mjw))  # (k, L)
    # Rows IFFT(base_b exp(-j w u_i))[:n]: the one-sided products written into a
    # zero-padded grid and transformed in place (pocketfft, as scipy.fft.ifft(n=n_fft)
    # calls it: the same numbers without its per-call argument handling).
    buf = np.zeros((nb, k, model.n_fft), dtype=np.complex128)
    np.multiply(base[:, None, :], ph[None, :, :], out=buf[:, :, :nl])
    rows = _c2c_inverse(buf)
    if _use_kernel(x):
        from rangekit.detect._pathfit_kernels import call

        ok, basis, gi, a, r, cost, jac, jp = call("vp", rows, x, n)
        if ok:
            return _State(u, theta, cost, a, r, basis, gi, jac, with_theta, jp)
    return _evaluate_np(x, rows[:, :, :n], u, theta, with_theta)


def _use_kernel(x: np.ndarray) -> bool:
    """Whether :func:`_evaluate` runs the compiled step: asked for by the caller
    (:func:`compiled_step`, which the channel fits set from the recording's length),
    ``x`` contiguous float64, and not disabled (``USE_KERNEL``)."""
    return USE_KERNEL and _KERNEL.get() and x.dtype == np.float64 and x.flags.c_contiguous


#: Run the compiled step (:mod:`rangekit.detect._pathfit_kernels`) where it is asked for.
USE_KERNEL = True


def _evaluate_np(x: np.ndarray, rows: np.ndarray, u, theta, with_theta: bool) -> _State:
    """The numpy reference of :func:`_evaluate` after its inverse FFTs (``rows``:
    ``(nb, k, n)`` waveforms and derivatives) and of the compiled step."""
    n, k = rows.shape[2], rows.shape[1]
    nb = rows.shape[0]
    wa = rows[0]
    basis = np.empty((n, 2 * k))
    basis[:, 0::2] = wa.real.T
    basis[:, 1::2] = wa.imag.T
    # Normal equations: the paths are kept MIN_SEP resolutions apart, so the Gram matrix
    # of their (in-phase, quadrature) columns is well conditioned.
    gram = basis.T @ basis
    try:
        gi = np.linalg.inv(gram)
    except np.linalg.LinAlgError:
        gi = np.linalg.pinv(gram)
    a = gi @ (basis.T @ x)
    r = x - basis @ a
    ar, ai = a[0::2, None], a[1::2, None]
    jac = np.empty((n, k + nb - 2))
    # d/du_k: the path's own derivative only; d/dtheta: the sum over the paths.
    jac[:, :k] = (ar * rows[1].real + ai * rows[1].imag).T
    if nb > 2:
        jac[:, k:] = (ar * rows[2:].real + ai * rows[2:].imag).sum(axis=1).T
    cost = float(r @ r) if np.all(np.isfinite(r)) else math.inf
    return _State(u, theta, cost, a, r, basis, gi, jac, with_theta)


def _c2c_inverse(buf: np.ndarray) -> np.ndarray:
    """In-place inverse FFT (1/n normalised) of ``buf``'s last axis."""
    if _POCKET is None:  # pragma: no cover - another scipy layout: the public call
        return _ifft(buf, n=buf.shape[-1], axis=-1)
    return _POCKET.c2c(buf, (buf.ndim - 1,), False, 2, buf, 1)


def _projected(st: _State) -> np.ndarray:
    """Kaufman's variable-projection Jacobian: the model Jacobian off the amplitudes."""
    if st.jp is not None:
        return st.jp
    return st.jac - st.basis @ (st.gram_inv @ (st.basis.T @ st.jac))


def _lm_step_np(jp: np.ndarray, r: np.ndarray, p: int, lam: float, lim: np.ndarray):
    """One Levenberg-Marquardt proposal (the numpy reference of the compiled
    ``lm_step``): ``(g^T (J^T J)^-1 g`` or nan if singular, the damping the step was
    solved at (raised tenfold, from 1e-9 where ``lam`` is 0; ``>= 1e8``: none), the step
    scaled so no parameter exceeds ``lim``)."""
    jp = jp[:, :p]
    jtj = jp.T @ jp
    g = jp.T @ r
    d = np.diag(jtj).copy()
    d[d <= 0] = 1.0
    try:
        gn = float(g @ np.linalg.solve(jtj, g))
    except np.linalg.LinAlgError:
        gn = math.nan
    step = np.zeros(p)
    while lam < 1e8:
        try:
            step = np.linalg.solve(jtj + lam * np.diag(d), g)
        except np.linalg.LinAlgError:
            lam = lam * 10.0 if lam > 0.0 else 1e-9  # from 0 (undamped): the smallest
            continue
        # One scale for the whole step keeps its direction (onset and Q are coupled).
        step = step * min(1.0, float(np.min(lim / np.maximum(np.abs(step), 1e-300))))
        break
    return gn, lam, step


#: Run a held fit (``fit_theta=False``) as one compiled call
#: (:func:`rangekit.detect._pathfit_kernels._held_fit_py`) where the compiled step runs.
HELD_KERNEL = True
#: The held fit's shift series stops where its next term is below this fraction of the
#: largest value a waveform sample can take (``sum |s| / n_fft``).
SHIFT_TOL = 1e-14


def _shift_tables(model, theta: np.ndarray, derivs: bool = False):
    """``(tab, nt, wc)`` (``derivs``: ``(tabd, nt, wc)``): the tables of the held fit's
    shift series at ``theta``.

    ``tab[q] = IFFT(s (w - wc)^q)``, ``q = 0 .. nt``, repeated once along the grid
    (:func:`rangekit.detect._pathfit_kernels._shift_rows_py`), ``wc`` the spectrum's
    peak bin; ``tabd[j, q]`` the same of ``ds / dtheta_j``, ``q < nt``. ``nt`` is the
    first ``q`` at which the series' term bound ``sum_l |s_l| (|w_l - wc| / 2)^q / q!``
    (a shift's fraction is at most 1/2; also with a factor ``|w_l - wc|`` for the onset
    derivative, and for each ``ds_j``) drops below ``SHIFT_TOL sum_l |s_l|``, so the
    rows equal the inverse FFT's to ~2e-14 of their peak. Cached on the model
    (:func:`_held_cache`).
    """
    cache = _held_cache(model)
    key = _key("shiftd" if derivs else "shift", theta)
    hit = cache.get(key)
    if hit is not None:
        return hit
    if derivs:
        s, ds = model.spectrum_t(theta, derivs=True)
    else:
        s, ds = model.spectrum_t(theta), []
    w = -model._mjw.imag
    mag = np.abs(s)
    wc = float(w[int(np.argmax(mag))])
    dw = w - wc
    half = np.abs(dw) / 2.0
    terms = [mag, mag * np.abs(dw), *(np.abs(d) for d in ds)]
    refs = [SHIFT_TOL * float(t.sum()) for t in terms]
    nt = 1
    while nt < 60:
        terms = [t * half / nt for t in terms]
        if all(float(t.sum()) < r for t, r in zip(terms, refs, strict=True)):
            break
        nt += 1
    m, nl = model.n_fft, len(s)
    specs = ds if derivs else [s]
    n_q = nt if derivs else nt + 1  # the onset row reads D_{q + 1}
    buf = np.zeros((len(specs), n_q, m), dtype=np.complex128)
    for j, spec in enumerate(specs):
        buf[j, 0, :nl] = spec
        for q in range(1, n_q):
            buf[j, q, :nl] = buf[j, q - 1, :nl] * dw
    d = _c2c_inverse(buf)
    d = np.concatenate([d, d[:, :, : model.segment]], axis=2)  # a shift of n <= segment
    hit = (d, nt, wc) if derivs else (d[0], nt, wc)
    _held_put(cache, key, hit)
    return hit


def _held_fit(x, model, u, theta, tol, max_iter, u_lo, u_hi) -> _State | None:
    """:func:`fit_paths` with ``theta`` held, as one compiled call (None: the kernel
    met a Gram matrix that is not positive definite; the caller runs the reference)."""
    from rangekit.detect._pathfit_kernels import call

    tab, nt, wc = _shift_tables(model, theta)
    ok, u, cost, a, r, basis, gi, jac, jp, rows = call(
        "held_fit",
        x,
        tab,
        nt,
        wc,
        model.n_fft,
        u,
        float(u_lo),
        float(u_hi),
        float(tol),
        int(max_iter),
    )
    if not ok:
        return None
    return _State(u, theta, cost, a, r, basis, gi, jac, False, jp, rows)


def _lm_step(jp, r, p, lam, lim, kernel: bool):
    if kernel:
        from rangekit.detect._pathfit_kernels import call

        return call("lm_step", np.ascontiguousarray(jp), r, p, float(lam), lim)
    return _lm_step_np(jp, r, p, lam, lim)


def fit_paths(
    x: np.ndarray,
    model,
    u0,
    *,
    q0: float | None = None,
    f0: float | None = None,
    theta: np.ndarray | None = None,
    fit_theta: bool = True,
    tol: float = 0.0,
    max_iter: int = MAX_ITER,
) -> _State:
    """Levenberg-Marquardt fit of ``len(u0)`` paths (and ``theta``) to ``x``.

    ``theta`` is the transducer model's starting point (default
    ``model.theta_start(q0, f0)``). Stops when the Gauss-Newton step would lower the cost
    by less than ``tol`` (e.g. ``1e-3 sigma^2``: the parameters are then within a small
    fraction of their sigma of the optimum). The returned state carries the Jacobian
    columns of ``theta`` (for the information about them) only when ``fit_theta``.
    """
    x = np.asarray(x, dtype=np.float64)
    u = np.asarray(u0, dtype=np.float64).copy()
    k = len(u)
    th = model.theta_start(q0, f0) if theta is None else model.theta_clip(theta)
    u_lo, u_hi = -0.5 * len(model.drive), len(x) - 4.0
    if not fit_theta and HELD_KERNEL and _use_kernel(x) and len(x) <= model.segment:
        st = _held_fit(x, model, u, th, tol, max_iter, u_lo, u_hi)
        if st is not None:
            return st
    p = k + model.n_theta if fit_theta else k
    st = _evaluate(x, model, u, th, fit_theta)
    jp = _projected(st)[:, :p]
    lam = 1e-3
    lim = np.concatenate([np.full(k, 4.0), model.theta_step() if fit_theta else []])
    kernel = _use_kernel(x)
    for _ in range(max_iter):
        gn, lam, step = _lm_step(jp, st.r, p, lam, lim, kernel)
        if gn < tol:
            break  # the Gauss-Newton step would gain less than tol: converged
        accepted = None
        while lam < 1e8:
            nu = np.clip(st.u + step[:k], u_lo, u_hi)
            nth = model.theta_clip(st.theta + step[k:]) if fit_theta else st.theta
            cand = _evaluate(x, model, nu, nth, fit_theta)
            if cand.cost <= st.cost:
                accepted = cand
                lam = max(lam / 3.0, 1e-9)
                break
            lam *= 10.0
            if lam < 1e8:
                _, lam, step = _lm_step(jp, st.r, p, lam, lim, kernel)
        if accepted is None:
            break
        small = np.all(np.abs(accepted.u - st.u) < 1e-4) and np.all(
            np.abs(accepted.theta - st.theta) < 1e-6 * np.maximum(1.0, np.abs(st.theta))
        )
        gain = st.cost - accepted.cost
        st = accepted
        jp = _projected(st)[:, :p]
        if gain < tol or (small and (lam < 1.0 or gain <= 1e-12 * st.cost)):
            break
    return st


def fit_arrival(
    x: np.ndarray,
    lag: float,
    *,
    model,
    sigma: float,
    q0: float = 4.0,
    f0: float | None = None,
    hold: bool = False,
    theta: np.ndarray | None = None,
    start: np.ndarray | None = None,
    k_add: float = K_ADD,
    rel_add: float = REL_ADD,
    max_paths: int = MAX_PATHS,
    k_noise: float = 6.0,
    rel_threshold: float = 0.25,
    lo: float = -math.inf,
    hi: float = math.inf,
    tol: float = 1e-3,
    max_iter: int = MAX_ITER,
) -> PathFit | None:
    """Fit the paths of the arrival near ``lag`` in ``x``; the first path's onset.

    Parameters
    ----------
    x : ndarray
        The recording's channel (the segment around ``lag`` is read from it).
    lag : float
        Coarse first-path lag (e.g. from :func:`rangekit.detect.matched.first_path`);
        the segment starts ``PRE_S`` before it.
    model : ResonatorModel or rangekit.detect.stagger.StaggerModel
        Drive and transducer model.
    sigma : float
        Standard deviation of the white noise per sample (> 0).
    q0, f0 : float
        Starting quality factor and resonance (default the model's nominal f0), for a
        :class:`ResonatorModel`.
    hold : bool
        Hold the transducers (``theta``, or ``(q0, f0)``) during the fit (e.g. a group's
        estimate from earlier arrivals through the same transducers: faster, and
        :func:`pool_fits` still learns from this arrival through its ``info``); default
        False: a scan over Q (or the start ``theta``) starts a fit of everything.
    theta : ndarray, optional
        The model's parameters to start from or hold (instead of ``q0, f0``).
    start : ndarray, optional
        Absolute onsets of the paths to start a free fit from (with ``theta``; e.g. a
        resonator fit's paths when the stagger model is tried), instead of the scan.
    k_add, rel_add, max_paths : float, float, int
        A further path is fitted at the residual's matched-filter peak while that peak
        clears ``k_add`` noise scales and its amplitude ``rel_add`` times the strongest
        path's, up to ``max_paths`` paths.
    k_noise, rel_threshold : float
        A path earlier than the strongest one is the first path only if it clears
        ``k_noise`` noise scales and ``rel_threshold`` times the strongest amplitude
        (the rule of :func:`rangekit.detect.matched.first_path`).
    lo, hi : float
        The first path must lie in ``[lo, hi)`` (absolute samples; e.g. the search range,
        so that an echo sensor's ring-down before it is fitted but never taken).
    tol, max_iter : float, int
        Levenberg-Marquardt stops when a step would gain less than ``tol`` noise
        variances, or after ``max_iter`` steps (per fit of a path set).

    Returns
    -------
    PathFit or None
        None when the segment holds no path above ``k_add`` noise scales.
    """
    sigma = float(sigma)
    if not sigma > 0:
        sigma = 1e-12 * max(float(np.max(np.abs(x))), 1e-300)
    th0 = model.theta_start(q0, f0) if theta is None else model.theta_clip(theta)
    res = n0 = None
    for attempt in range(2):
        n0 = max(0, int(math.floor(lag)) - model.pre)
        n1 = min(len(x), n0 + model.segment)
        seg = np.asarray(x[n0:n1], dtype=np.float64)
        if len(seg) < len(model.drive):
            return None
        u_start = None if start is None else np.asarray(start, dtype=np.float64) - n0
        res = _paths(
            seg, model, sigma, th0, hold, k_add, rel_add, max_paths, u_start, tol, max_iter
        )
        if res is None:
            return None
        u_min = float(np.min(res.u))
        # A path at the very start may have begun before the segment: look earlier once.
        if u_min < 0.25 * model.pre and n0 > 0 and attempt == 0 and start is None:
            lag = n0 + u_min
            continue
        break
    return _summarize(res, seg, n0, model, sigma, k_noise, rel_threshold, lo, hi, not hold)


#: Quality factors of the scans that start a fit (log-spaced over the Q range).
SCAN_Q = (3.0, 5.0, 8.0, 12.0, 18.0, 27.0)
#: A one-path fit whose residual exceeds the noise by this many standard deviations of
#: its chi-square is tried as two overlapping paths (a reflection within the burst).
Z_TWO_PATHS = 3.0
#: The two-path scan tries separations up to this many resolutions of the model (paths
#: further apart stand out in the residual and are added one at a time).
SCAN_SEPS = 4.0
#: Fitted paths closer than this many resolutions of the model are not resolved: their
#: amplitudes trade off against each other (two large paths cancelling), so a fit with
#: such a pair is not accepted.
MIN_SEP = 0.3
#: No fitted path may be stronger than this many times the segment's strongest
#: single-path amplitude (the matched-filter peak over the waveform's energy): a larger
#: one is the signature of paths cancelling each other.
AMP_GUARD = 2.0


def _misfit_z(st: _State, sigma: float, n_par: int) -> float:
    dof = max(1, len(st.r) - n_par)
    return (st.cost / sigma**2 - dof) / math.sqrt(2.0 * dof)


def _scan_one(seg, model, thetas):
    """Best single path over a list of ``theta``: the normalised matched-filter peak."""
    best = (-1.0, 0, thetas[0])
    j_max = max(1, len(seg) - len(model.drive) // 2)
    for th in thetas:
        c = _residual_mf(model, seg, th)[:j_max]
        p = np.abs(c) ** 2 / _energy(model, th)
        j = int(np.argmax(p))
        if p[j] > best[0]:
            best = (float(p[j]), j, th)
    return best


def _well_posed(st: _State, model, amp_scale: float) -> bool:
    """No two paths within ``MIN_SEP`` resolutions, no path above ``AMP_GUARD`` x scale."""
    if len(st.u) > 1:
        res = _resolution(model, st.theta)
        if float(np.min(np.diff(np.sort(st.u)))) < MIN_SEP * res:
            return False
    return float(_amps(st).max()) <= AMP_GUARD * amp_scale


def _scan_two(seg, model, thetas, around: float, step: int = 1):
    """Best pair of overlapping paths over ``theta``, onset and separation (closed form).

    For paths at integer onsets ``u1 < u2`` of one waveform the least-squares explained
    energy is ``2 c^H G^-1 c`` with ``c`` the analytic matched-filter outputs at the two
    onsets and ``G`` the waveform's analytic autocorrelation at 0 and ``u2 - u1`` (exact
    when both waveforms lie inside the segment). Separations from ``MIN_SEP`` to
    ``SCAN_SEPS`` resolutions of each model are tried, the first onset from ``SCAN_SEPS``
    resolutions before ``around`` (a one-path fit's onset, which a merged pair puts
    between its paths) to one after.
    """
    n = len(seg)
    j_max = max(2, n - len(model.drive) // 2)
    best = None
    for th in thetas:
        res = _resolution(model, th)
        d_lo = max(2, int(MIN_SEP * res))
        d_hi = min(int(SCAN_SEPS * res) + 1, j_max - 1)
        if d_hi <= d_lo:
            continue
        d = np.arange(d_lo, d_hi, step)
        u1 = np.arange(max(0, int(around - SCAN_SEPS * res)), min(j_max, int(around + res) + 1))
        if len(u1) == 0:
            continue
        s = model.spectrum_t(th)
        rho = np.fft.ifft(np.abs(s) ** 2, n=model.n_fft)
        r0 = rho[0].real
        c = _residual_mf(model, seg, th)
        i2 = u1[None, :] + d[:, None]
        valid = i2 < j_max
        c1 = c[u1][None, :]
        c2 = c[np.minimum(i2, j_max - 1)]
        g12 = np.conj(rho[d])[:, None]
        den = r0 * r0 - np.abs(rho[d]) ** 2
        num = r0 * (np.abs(c1) ** 2 + np.abs(c2) ** 2) - 2.0 * np.real(np.conj(c1) * g12 * c2)
        ok = valid & (den[:, None] > 1e-6 * r0 * r0)
        pv = np.where(ok, 2.0 * num / np.maximum(den, 1e-300)[:, None], -1.0)
        k = int(np.argmax(pv))
        a, b = divmod(k, len(u1))
        if best is None or pv[a, b] > best[0]:
            best = (float(pv[a, b]), int(u1[b]), int(u1[b] + d[a]), th)
    return best


def _interp(z: np.ndarray, j: int) -> float:
    if 0 < j < len(z) - 1:
        a_, b_, c_ = z[j - 1], z[j], z[j + 1]
        den = a_ - 2 * b_ + c_
        if den < 0:
            return j + max(-0.5, min(0.5, 0.5 * (a_ - c_) / den))
    return float(j)


def _amps(st: _State) -> np.ndarray:
    return np.hypot(st.a[0::2], st.a[1::2])


def _paths(
    seg, model, sigma, th0, hold, k_add, rel_add, max_paths, u_start=None, tol_var=1e-3,
    max_iter=MAX_ITER,
):  # fmt: skip
    """Paths of one segment: a first fit, a two-path scan where one path does not
    explain it, then further paths at the residual's matched-filter peak, all refitted
    jointly (``theta`` too unless ``hold``)."""
    fit = not hold
    tol = tol_var * sigma**2
    j_max = max(1, len(seg) - len(model.drive) // 2)
    # First path: from the held model's matched filter, given onsets, or a scan over Q.
    if hold or u_start is not None:
        e = _energy(model, th0)
        c = np.abs(_residual_mf(model, seg, th0)[:j_max])
        j = int(np.argmax(c))
        if c[j] / (sigma * math.sqrt(e)) < k_add:
            return None
        u_init, thi = [_interp(c, j)], th0
        amp_scale = float(c[j]) / e
        if u_start is not None and len(u_start):
            u_init = [float(v) for v in u_start]
    else:
        p, j, thi = _scan_one(seg, model, model.scan_thetas(float(th0[1])))
        if math.sqrt(max(p, 0.0)) / sigma < k_add:
            return None
        u_init = [float(j)]
        amp_scale = math.sqrt(max(p, 0.0) / _energy(model, thi))
    st = fit_paths(seg, model, u_init, theta=thi, fit_theta=fit, tol=tol, max_iter=max_iter)
    amp_scale = max(amp_scale, float(_amps(st).max()))
    n_theta = model.n_theta if fit else 0
    # A reflection within about a resolution merges with the direct path into one wider
    # path (of higher Q): try two paths wherever Q is free (the few fits that set a
    # group's Q), and where a held Q leaves the one-path fit short.
    # (Not when the paths were given: they come from a fit that scanned already.)
    if (
        max_paths >= 2
        and (u_start is None or not SKIP_SCAN)
        and len(st.u) == 1
        and (fit or _misfit_z(st, sigma, 3 + n_theta) > Z_TWO_PATHS)
    ):
        ths = model.theta_variants(st.theta) if fit else [st.theta]
        sc = _scan_two(seg, model, ths, around=float(st.u[0]))
        if sc is not None:
            two = fit_paths(seg, model, [sc[1], sc[2]], theta=sc[3], fit_theta=fit, tol=tol)
            amp2 = _amps(two)
            if (
                st.cost - two.cost > k_add**2 * sigma**2
                and amp2.min() >= rel_add * amp2.max()
                and _well_posed(two, model, amp_scale)
            ):
                st = two
    n = len(seg)
    while len(st.u) < max_paths:
        th = st.theta
        e = _energy_inside(model, th, n)[: n - 4]
        c = np.abs(_residual_mf(model, st.r, th)[: n - 4])
        z = c / (sigma * np.sqrt(e))
        j = int(np.argmax(z))
        if z[j] < k_add or float(c[j]) / e[j] < rel_add * float(_amps(st).max()):
            break
        new = fit_paths(seg, model, [*st.u.tolist(), _interp(z, j)], theta=th,
                        fit_theta=fit, tol=tol)  # fmt: skip
        # A path must pay for its three parameters (Schwarz's 3 ln n noise variances),
        # or it is model error fitted as a path (a transducer not quite the model's).
        if st.cost - new.cost < 3.0 * math.log(n) * sigma**2 or not _well_posed(
            new, model, amp_scale
        ):
            break
        st = new
    return st


def _summarize(st, seg, n0, model, sigma, k_noise, rel_threshold, lo, hi, free=True):
    """First path, information about ``theta`` and flags' inputs of a fitted segment."""
    if not (st.with_theta or free) and st.rows is not None and _use_kernel(seg):
        out = _held_result(seg, n0, model, sigma, k_noise, rel_threshold, lo, hi, st)
        if out is not _REFERENCE:
            return out
    if not st.with_theta:
        st = _evaluate(seg, model, st.u, st.theta, True)
    k = len(st.u)
    amp = _amps(st)
    e = _energy(model, st.theta)
    snr = amp * math.sqrt(e) / sigma
    u_abs = n0 + st.u
    inside = (u_abs >= lo - 1.0) & (u_abs < hi)
    if not inside.any():
        return None
    top = float(amp[inside].max())
    strongest = int(np.argmax(np.where(inside, amp, -1.0)))
    first = strongest
    for i in np.argsort(st.u, kind="stable"):
        if inside[i] and u_abs[i] < u_abs[strongest] and snr[i] >= k_noise:
            if amp[i] >= rel_threshold * top:
                first = int(i)
                break
    # Gauss-Newton blocks of the projected Jacobian: onsets (A), theta (C), cross (B).
    jp = _projected(st)
    ju, jt = jp[:, :k], jp[:, k:]
    A, B, C = ju.T @ ju, ju.T @ jt, jt.T @ jt
    gu, gt = ju.T @ st.r, jt.T @ st.r
    try:
        ai = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return None
    S = C - B.T @ ai @ B
    p = model.n_theta
    theta_lin = st.theta.copy()
    # One Newton step to the optimum in the onsets (~0 after a converged fit).
    newton = float((ai @ gu)[first])
    onset_lin = float(u_abs[first] + (newton if abs(newton) < 1.0 else 0.0))
    gain = -(ai @ B)[first]
    var_given = sigma**2 * float(ai[first, first])
    try:
        theta_hat = theta_lin + np.linalg.solve(S, gt - B.T @ ai @ gu)
        info = S / sigma**2
        cov_t = np.linalg.inv(info)
    except np.linalg.LinAlgError:
        theta_hat, info, cov_t = theta_lin, np.zeros((p, p)), np.zeros((p, p))
    if not np.all(np.isfinite(theta_hat)) or np.any(
        np.abs(theta_hat - theta_lin) > 3.0 * model.theta_step()
    ):
        theta_hat = theta_lin  # a Newton step beyond the fit's reach: keep the fit's value
    n = len(st.r)
    n_par = 3 * k + (p if free else 0)
    dof = max(1, n - 2 * k - k - 2)
    sig_energy = float(np.sum((st.basis @ st.a) ** 2))
    misfit = (st.cost - dof * sigma**2) / sig_energy if sig_energy > 0 else 0.0
    order = np.argsort(u_abs, kind="stable")
    onsets = u_abs[order].copy()
    first_s = int(np.flatnonzero(order == first)[0])
    onsets[first_s] = onset_lin
    q, f0 = model.q_f0(theta_lin)
    fit = PathFit(
        onset=onset_lin,
        sigma=math.sqrt(var_given),
        snr=float(snr[first]),
        q=q,
        f0_hz=f0,
        onsets=onsets,
        amplitudes=amp[order],
        first=first_s,
        misfit=float(misfit),
        misfit_z=float((st.cost / sigma**2 - dof) / math.sqrt(2.0 * dof)),
        resolution=_resolution(model, st.theta),
        theta_lin=theta_lin,
        gain=gain,
        var_given=var_given,
        theta_hat=theta_lin,
        info=info,
        family=model.family,
        chi2=float(st.cost / sigma**2),
        n_par=n_par,
        q_of=model.q_f0,
        n0=int(n0),
    )
    return fit.at(theta_hat, cov_t, pooled=False)


#: :func:`_held_result`'s answer where the reference must run.
_REFERENCE = object()


def _held_result(seg, n0, model, sigma, k_noise, rel_threshold, lo, hi, st: _State):
    """:func:`_summarize` of a state of the held kernel as one compiled call
    (:func:`rangekit.detect._pathfit_kernels._held_result_py`); ``_REFERENCE`` where a
    matrix is not positive definite (the reference then runs, with its own fallbacks)."""
    from rangekit.detect._pathfit_kernels import call

    tabd, nt, wc = _shift_tables(model, st.theta, derivs=True)
    out = call(
        "held_result", seg, st.rows, tabd, nt, wc, model.n_fft, st.u, st.theta, float(n0),
        float(lo), float(hi), float(sigma), _energy(model, st.theta), float(k_noise),
        float(rel_threshold), model.theta_step(),
    )  # fmt: skip
    status, first_s, onsets, amps, onset, sig, snr, misfit, misfit_z, chi2 = out[:10]
    if status != 1:
        return None if status == 2 else _REFERENCE
    theta_hat, info, gain, var_given = out[10:]
    theta_lin = st.theta.copy()
    q, f0 = model.q_f0(theta_hat)
    return PathFit(
        onset=onset,
        sigma=sig,
        snr=snr,
        q=q,
        f0_hz=f0,
        onsets=onsets,
        amplitudes=amps,
        first=first_s,
        misfit=misfit,
        misfit_z=misfit_z,
        resolution=_resolution(model, st.theta),
        theta_lin=theta_lin,
        gain=gain,
        var_given=var_given,
        theta_hat=theta_hat,
        info=info,
        family=model.family,
        chi2=chi2,
        n_par=3 * len(st.u),
        q_of=model.q_f0,
        n0=int(n0),
    )


def pool_fits(fits, *, max_chi2: float = 4.0):
    """Pool ``theta`` over arrivals through the same transducers; condition the onsets.

    ``fits`` are :class:`PathFit` (None entries are passed through) of one transducer
    pair and one model, e.g. one Tx and one receiver over many activation windows. Each
    contributes its own estimate ``theta_hat`` with information ``info``; the pooled value
    is their information-weighted mean over the fits whose squared Mahalanobis distance
    from it is at most ``8 p`` (``p`` parameters: 4 sigma for the resonator's two, about
    5.7 for the stagger model's four; others, e.g. a low-SNR fit stuck at a bound, are
    left out of the mean but conditioned on it), iterated up to 5 times. If the
    remaining spread exceeds ``max_chi2`` per degree of freedom, the arrivals did not go
    through one pair of transducers (or the model does not describe them well) and the
    fits are returned unchanged.

    Each onset is moved along its profile to the pooled value, and its variance becomes
    ``var_given + gain C gain^T`` with ``C`` the pooled value's covariance.

    Returns
    -------
    (list of PathFit, bool)
        The fits (conditioned, or unchanged) and whether they were pooled.
    """
    fits = list(fits)
    ok = [
        i
        for i, f in enumerate(fits)
        if f is not None and np.all(np.isfinite(f.info)) and np.linalg.det(f.info) > 0
    ]
    if len(ok) < 2:
        return fits, False
    theta = np.array([fits[i].theta_hat for i in ok])
    w = np.array([fits[i].info for i in ok])
    p = theta.shape[1]
    keep = np.ones(len(ok), bool)
    mean = theta[0]
    cov = np.zeros((p, p))
    d2 = np.zeros(len(ok))
    for _ in range(5):
        try:
            cov = np.linalg.inv(w[keep].sum(axis=0))
        except np.linalg.LinAlgError:
            return fits, False
        mean = cov @ np.einsum("nij,nj->i", w[keep], theta[keep])
        dev = theta - mean
        d2 = np.einsum("ni,nij,nj->n", dev, w, dev)
        new_keep = d2 <= 8.0 * p
        if new_keep.sum() < 2:
            return fits, False
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
    dof = p * (int(keep.sum()) - 1)
    if float(d2[keep].sum()) > max_chi2 * dof:
        return fits, False
    out = list(fits)
    for i in ok:
        out[i] = fits[i].at(mean, cov)
    return out, True
