"""A richer transducer model for the arrival fit: two stagger-tuned resonators per element.

:class:`rangekit.detect.pathfit.ResonatorModel` times a coded burst exactly only through
transducers that are one second-order resonator per element. A transducer whose element
has a second mode nearby, or a tuned receiver, is a fourth-order band-pass (two pole pairs
per element): its group delay at the carrier is larger than a resonator's of the same
band (1.4x for a 4th-order Butterworth band-pass), and a resonator fit puts the arrival
late by the difference (1-6 cm at Q 4-20, ``docs/theory/ultrasonic.md``).

**Model.** Each of the ``stages`` equal elements (Tx and Rx) is

    E(z) = (1 - z^-2)^2 / (P(z) conj(P)(z)),
    P(z) = 1 - 2 e^mu cosh(sqrt(nu)) z^-1 + e^(2 mu) z^-2,

``conj(P)`` the polynomial with conjugated coefficients, so that the element's poles are
``exp(mu +- sqrt(nu))`` and their conjugates: two pole pairs centred on ``mu = -a + j w_c``
(``a`` the damping per sample, ``w_c`` the centre frequency) and split by ``sqrt(nu)``
(imaginary: stagger-tuned in frequency, real: split in damping; complex: both). Every
product of two second-order band-pass sections of the form ``(1 - z^-2) / (1 - b1 z^-1 +
b2 z^-2)`` is one ``E`` (the digital peaking filter, :class:`rangekit.signals.transducer.
Transducer`; so the bilinear transform of any analog band-pass with two pole pairs and
its zeros at 0 and infinity, e.g. a 4th-order Butterworth band-pass), and ``E`` depends
on ``nu`` analytically (``cosh(sqrt(nu))`` is entire in ``nu``), so two equal resonators
(``nu = 0``) are an ordinary point of the fit, not a singular one. The parameters are
``theta = (log a, f_c, Re nu / a^2, Im nu / a^2)`` with ``f_c = w_c fs / (2 pi)``; a
maximally flat pair (Butterworth) has ``nu / a^2 = -1``. The response is normalised to
unit gain at the nominal carrier (a constant the path amplitudes absorb).

The fit (:func:`rangekit.detect.pathfit.fit_arrival`) uses this model exactly as the
resonator: the same variable projection, Levenberg-Marquardt steps, analytic derivatives
(``d log E / d theta`` from ``dP / d theta``), paths, Cramér-Rao sigma and pooling.
Which of the two models describes a transducer pair is decided from the data
(:mod:`rangekit.detect.fitted`).

Examples
--------
>>> from rangekit.signals.barker import CodedBurst, burst_waveform
>>> from rangekit.signals.transducer import BandpassTransducer
>>> from rangekit.detect.pathfit import fit_arrival
>>> fs = 192000.0
>>> model = StaggerModel.for_burst(CodedBurst(), fs=fs)
>>> t = BandpassTransducer(q=12.0)
>>> x = np.zeros(3000)
>>> x[1000:1101] = burst_waveform(CodedBurst(fs=fs))
>>> x = t.apply(t.apply(x, fs=fs), fs=fs)
>>> f = fit_arrival(x, 1030.0, model=model, sigma=1e-5, theta=model.theta_start(12.0),
...                 start=[1000.0])
>>> round(f.onset, 3), f.n_paths, round(f.q, 1)
(1000.0, 1, 12.0)
"""

from __future__ import annotations

import cmath
import functools
import math

import numpy as np

from rangekit.detect.pathfit import F0_LIMIT, SCAN_Q, ResonatorModel
from rangekit.signals.barker import CodedBurst, burst_waveform

__all__ = ["StaggerModel", "group_delay_samples"]

#: Element quality factors (of the maximally flat pair) the fit may take.
Q_LIMITS = (1.0, 40.0)
#: The split ``nu / a^2 = (alpha + j beta)^2`` (``a alpha`` the two pole pairs' half
#: difference of damping, ``a beta`` of frequency) is kept in ``Re >= NU_RE_MIN`` (a
#: double hump of resonances 2 dampings either side of the centre) and ``|Im| = 2 |alpha
#: beta| <= NU_IM``: the two modes of an element differ in damping by at most about 30 %
#: of the centre's where they are a band apart. A prior, not a fit: a freer split also
#: mimics a room's dense early reflections (a pyroomacoustics room's fit took ``Im nu /
#: a^2`` of -1.2 to -1.3 and put the ranges 4 cm early); the 4th-order Butterworth
#: band-pass has -0.01 to -0.06, two stagger-tuned resonators of one Q -0.05 to -0.26.
NU_RE_MIN = -4.0
NU_IM = 0.6
#: Both pole pairs keep at least this fraction of the centre damping ``a`` (stable).
MIN_DAMPING = 0.1


class StaggerModel(ResonatorModel):
    """The drive through ``stages`` equal elements of two pole pairs each (module doc).

    Parameters as :class:`rangekit.detect.pathfit.ResonatorModel`; ``theta = (log a,
    f_c, Re nu / a^2, Im nu / a^2)``.
    """

    n_theta = 4
    family = "stagger"

    @classmethod
    def for_burst(
        cls, burst: CodedBurst | None = None, *, fs: float, f0_hz: float | None = None,
        stages: int = 2,
    ) -> StaggerModel:  # fmt: skip
        """The model of ``burst`` (default Barker-7) at ``fs``, cached per arguments."""
        burst = CodedBurst() if burst is None else burst
        f0 = burst.carrier_hz if f0_hz is None else float(f0_hz)
        return _stagger(burst.with_fs(float(fs)), float(fs), f0, int(stages))

    def _a_of_q(self, q: float, f: float) -> float:
        # A maximally flat pair of element band f / q: poles damped by pi f / (q fs) / sqrt 2.
        return math.pi * f / (q * self.fs) / math.sqrt(2.0)

    def theta_start(self, q: float, f0: float | None = None) -> np.ndarray:
        """A maximally flat pair (``nu / a^2 = -1``) of element Q ``q`` centred at ``f0``."""
        f0 = self.f0_hz if f0 is None else float(f0)
        return self.theta_clip(np.array([math.log(self._a_of_q(q, f0)), f0, -1.0, 0.0]))

    def theta_clip(self, theta: np.ndarray) -> np.ndarray:
        """``theta`` inside the limits, both pole pairs stable (``MIN_DAMPING``)."""
        f = min(max(float(theta[1]), self.f0_hz * (1 - F0_LIMIT)), self.f0_hz * (1 + F0_LIMIT))
        la_lo = math.log(self._a_of_q(Q_LIMITS[1], self.f0_hz))
        la_hi = math.log(self._a_of_q(Q_LIMITS[0], self.f0_hz))
        la = min(max(float(theta[0]), la_lo), la_hi)
        nr = min(max(float(theta[2]), NU_RE_MIN), 1.0)
        ni = min(max(float(theta[3]), -NU_IM), NU_IM)
        # Poles exp(mu +- a sqrt(nu~)): both damped while |Re sqrt(nu~)| < 1.
        re = abs(cmath.sqrt(complex(nr, ni)).real)
        if re > 1.0 - MIN_DAMPING:
            c = ((1.0 - MIN_DAMPING) / re) ** 2
            nr, ni = nr * c, ni * c
        return np.array([la, f, nr, ni])

    def theta_step(self) -> np.ndarray:
        """Largest Levenberg-Marquardt step of each parameter."""
        return np.array([0.35, 0.01 * self.f0_hz, 0.5, 0.5])

    def theta_variants(self, theta: np.ndarray) -> list[np.ndarray]:
        """Broader models a merged pair of paths may hide behind (the two-path scan)."""
        ds = (math.log(2.0), 0.5 * math.log(2.0), 0.0)
        return [self.theta_clip(theta + np.array([d, 0.0, 0.0, 0.0])) for d in ds]

    def scan_thetas(self, f0: float) -> list[np.ndarray]:
        """Maximally flat pairs of the element Qs of ``SCAN_Q`` (a free fit's scan)."""
        return [self.theta_start(q, f0) for q in SCAN_Q]

    def q_f0(self, theta: np.ndarray) -> tuple[float, float]:
        """The element Q of a maximally flat pair with this damping, and the centre (Hz)."""
        a = math.exp(float(theta[0]))
        f = float(theta[1])
        return math.pi * f / (a * self.fs) / math.sqrt(2.0), f

    def _poly(self, theta: np.ndarray) -> tuple[complex, complex, list[tuple[complex, complex]]]:
        """``P``'s coefficients ``q1, q2`` at ``theta`` and their derivatives
        ``(dq1, dq2)`` by each ``theta_i``."""
        a = math.exp(float(theta[0]))
        wc = 2.0 * math.pi * float(theta[1]) / self.fs
        mu = complex(-a, wc)
        nu = a * a * complex(float(theta[2]), float(theta[3]))
        r = cmath.sqrt(nu)
        ch = cmath.cosh(r)
        sh = 0.5 + nu / 12.0 + nu * nu / 240.0 if abs(r) < 1e-3 else cmath.sinh(r) / (2.0 * r)
        em = cmath.exp(mu)
        steps = ((-a, 2.0 * nu), (2j * math.pi / self.fs, 0.0), (0.0, a * a), (0.0, 1j * a * a))
        dq = [(-2.0 * em * (ch * dmu + sh * dnu), 2.0 * em * em * dmu) for dmu, dnu in steps]
        return -2.0 * em * ch, em * em, dq

    def _element(self, z: np.ndarray, theta: np.ndarray, derivs: bool):
        """``E(z)`` on ``z`` (= e^{-jw}) and ``d log E / d theta_i`` (rows of an array).

        ``d log E / d theta_i = -(dq1 z / p + dq2 z^2 / p + conj(dq1) z / pb + conj(dq2)
        z^2 / pb)``: one (4, 4) by (4, n) product of the coefficients and the four ratios.
        """
        q1, q2, dq = self._poly(theta)
        z2, num = _powers(z)
        p = 1.0 + q1 * z + q2 * z2
        pb = 1.0 + q1.conjugate() * z + q2.conjugate() * z2
        e = num / (p * pb)
        if not derivs:
            return e, None
        ratios = np.empty((4, len(z)), dtype=np.complex128)
        np.divide(z, p, out=ratios[0])
        np.multiply(ratios[0], z, out=ratios[1])
        np.divide(z, pb, out=ratios[2])
        np.multiply(ratios[2], z, out=ratios[3])
        coef = np.array([(-d1, -d2, -d1.conjugate(), -d2.conjugate()) for d1, d2 in dq])
        return e, coef @ ratios

    def _element_at(self, z: complex, theta: np.ndarray) -> tuple[complex, list[float]]:
        """``E(z)`` at one point and ``Re d log E / d theta_i`` there (scalar arithmetic)."""
        q1, q2, dq = self._poly(theta)
        z2 = z * z
        p = 1.0 + q1 * z + q2 * z2
        pb = 1.0 + q1.conjugate() * z + q2.conjugate() * z2
        e = (1.0 - z2) ** 2 / (p * pb)
        out = [
            -((d1 * z + d2 * z2) / p + (d1.conjugate() * z + d2.conjugate() * z2) / pb).real
            for d1, d2 in dq
        ]
        return e, out

    def spectrum_t(self, theta: np.ndarray, derivs: bool = False):
        """One-sided spectrum of ``s_a`` at ``theta``; with ``derivs`` ``(s, [ds/dtheta_i])``."""
        key = ("st", *(float(v) for v in theta), bool(derivs))
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        e, de = self._element(self._z, theta, derivs)
        en, den = self._element_at(cmath.exp(-2j * math.pi * self.f0_hz / self.fs), theta)
        m = self.stages
        s = self._d * (e / abs(en)) ** m
        if derivs:
            ds = (m * s) * (de - np.array(den)[:, None])
            out = (s, list(ds))
        else:
            out = s
        if len(self._cache) > 64:
            self._cache.clear()
        self._cache[key] = out
        return out


#: ``z -> (z^2, (1 - z^2)^2)`` of the last grids seen (the model's own and the carrier's).
_POWERS: dict = {}


def _powers(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``z^2`` and the element's numerator ``(1 - z^2)^2`` on ``z``, kept per grid."""
    key = (id(z), len(z)) if len(z) > 1 else None
    hit = _POWERS.get(key) if key is not None else None
    if hit is not None and hit[0] is z:
        return hit[1], hit[2]
    z2 = z * z
    num = (1.0 - z2) ** 2
    if key is not None:
        if len(_POWERS) > 16:
            _POWERS.clear()
        _POWERS[key] = (z, z2, num)
    return z2, num


@functools.lru_cache(maxsize=8)
def _stagger(burst: CodedBurst, fs: float, f0: float, stages: int) -> StaggerModel:
    return StaggerModel(burst_waveform(burst), fs=fs, f0_hz=f0, stages=stages)


def group_delay_samples(model, theta: np.ndarray) -> float:
    """Group delay (samples) of the model's transducers at its nominal carrier.

    The phase slope of the received spectrum over the drive's between the two FFT bins
    around the carrier (the drive's spectrum cancels).
    """
    s = model.spectrum_t(np.asarray(theta, dtype=np.float64))
    k = int(math.floor(model.f0_hz / model.fs * model.n_fft))
    h0, h1 = s[k] / model._d[k], s[k + 1] / model._d[k + 1]
    return float(-cmath.phase(h1 / h0) / (2.0 * math.pi / model.n_fft))
