"""``rangekit.detect.pathfit``'s rules that its fit tests do not pin (issue 21, the mutation
check): the parabolic vertex of the path scan, and the misfit of an in-model arrival
(noise-corrected: about 0, not the noise's own energy). About a second.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from pathfit_signals import received

from rangekit.detect import pathfit as P
from rangekit.detect.fitted import transducer_models
from rangekit.detect.matched import coded_template, detect_matched
from rangekit.signals.barker import CodedBurst
from rangekit.signals.transducer import Transducer

FS = 192000.0


def test_interp_is_the_parabolas_vertex_clipped_to_half_a_sample():
    z = -((np.arange(20.0) - 10.3) ** 2)
    assert P._interp(z, 10) == pytest.approx(10.3, abs=1e-12)
    z = -((np.arange(20.0) - 9.8) ** 2)
    assert P._interp(z, 10) == pytest.approx(9.8, abs=1e-12)
    assert P._interp(-((np.arange(20.0) - 12.0) ** 2), 10) == 10.5  # not the top: clipped
    assert P._interp(-((np.arange(20.0) - 8.0) ** 2), 10) == 9.5
    assert P._interp(np.arange(20.0), 10) == 10.0  # no curvature
    assert P._interp(z, 0) == 0.0 and P._interp(z, 19) == 19.0


def test_misfit_of_an_in_model_arrival_is_noise_corrected():
    """Six Q 4 arrivals in white noise of 2 % of the peak, fitted with the resonator
    model they come from: the misfit (the energy the model leaves unexplained beyond the
    noise, over the fitted signal's) is within 2.5e-3 of 0 (measured |misfit| <= 1.1e-3 at
    |misfit_z| <= 2.5; the noise's own energy would be ~1e-2)."""
    t = Transducer()
    h = coded_template(fs=FS, tx=t, rx=t)
    models, _ = transducer_models(CodedBurst(), fs=FS, transducers=(t, t))
    rng = np.random.default_rng(3)
    sigma = 0.02 * np.abs(h).max()
    for w in range(6):
        x = sigma * rng.standard_normal(12000)
        x[6000 : 6000 + len(h)] += h
        (on,) = detect_matched(x, fs=FS, template=h).onset
        f = P.fit_arrival(x, on, model=models[0], sigma=sigma, q0=4.0, lo=0, hi=12000)
        assert abs(f.misfit) < 2.5e-3 and abs(f.misfit_z) < 4.0, (w, f.misfit, f.misfit_z)


def test_numpy_lm_step_is_marquardts_damped_step():
    """``_lm_step_np`` (used when the compiled step is not available) solves Marquardt's
    (1963) damped normal equations ``(J^T J + lam diag(J^T J)) s = g``: for every damping
    the step is a descent direction (``g . s > 0``), its scaled length falls as ``lam``
    grows, and at large ``lam`` it tends to the scaled gradient ``g / (lam d)`` (at
    ``lam = 1e4`` within 2.5e-4; measured 1.2e-4). ``lim`` scales the whole step (one
    factor, the direction kept) so that no parameter exceeds its limit."""
    rng = np.random.default_rng(0)
    jac = rng.standard_normal((200, 5)) * np.array([1.0, 10.0, 0.1, 3.0, 0.5])
    r = rng.standard_normal(200)
    g = jac.T @ r
    d = np.diag(jac.T @ jac)
    no_lim = np.full(5, np.inf)
    lengths = []
    for lam in (1e-3, 0.1, 0.5, 1.0, 2.0, 10.0, 100.0):
        gn, lam_out, s = P._lm_step_np(jac, r, 5, lam, no_lim)
        assert lam_out == lam  # solvable: no extra damping
        assert g @ s > 0, lam
        lengths.append(float(np.linalg.norm(s * np.sqrt(d))))
        assert gn == pytest.approx(g @ np.linalg.solve(jac.T @ jac, g), rel=1e-9)
    assert all(b < a for a, b in itertools.pairwise(lengths)), lengths
    _, _, s = P._lm_step_np(jac, r, 5, 1e4, no_lim)
    assert np.max(np.abs(s * 1e4 * d / g - 1.0)) < 2.5e-4
    _, _, free = P._lm_step_np(jac, r, 5, 0.1, no_lim)
    lim = 0.25 * np.abs(free)
    _, _, capped = P._lm_step_np(jac, r, 5, 0.1, lim)
    assert np.max(np.abs(capped) / lim) == pytest.approx(1.0, abs=1e-12)
    assert capped == pytest.approx(0.25 * free, rel=1e-12)


@pytest.mark.parametrize(("late_s", "read_again"), [(0.3e-3, False), (0.33e-3, True),
                                                    (0.35e-3, True)])  # fmt: skip
def test_a_path_in_the_first_quarter_of_pre_s_is_read_again(late_s, read_again):
    """A coarse lag ``late_s`` after the path (``PRE_S`` 0.4 ms, 77 samples): at 0.33
    and 0.35 ms the path lies 13.9 and 10.1 samples into the segment, inside its first
    quarter (19.25 samples), and the segment is read again from ``PRE_S`` before it (the
    same segment as from the right lag); at 0.3 ms it lies 20.2 samples in and the
    segment is kept. Either way the onset is the right lag's (measured 3.5e-5 samples
    apart at 0.3 ms)."""
    model = P.ResonatorModel.for_burst(CodedBurst(), fs=FS)
    t0 = 1500.25
    x = received(12.0, [t0], [1.0]) + 1e-3 * np.random.default_rng(7).standard_normal(4000)
    right = P.fit_arrival(x, t0, model=model, sigma=1e-3)
    late = P.fit_arrival(x, t0 + late_s * FS, model=model, sigma=1e-3)
    assert right.n0 == int(t0) - model.pre
    if read_again:
        assert late.n0 == right.n0
    else:
        assert late.n0 == int(t0 + late_s * FS) - model.pre
        assert late.onset - late.n0 > 0.25 * model.pre
    assert late.onset == pytest.approx(right.onset, abs=1e-3)


class _Fit:
    """What :func:`pool_fits` reads of a PathFit: ``theta_hat``, ``info`` and ``at``."""

    def __init__(self, theta, info):
        self.theta_hat, self.info = np.asarray(theta, float), np.asarray(info, float)

    def at(self, mean, cov):
        return ("at", tuple(np.round(mean, 12)))


@pytest.mark.parametrize(("scale", "pooled"), [(3.0, False), (1.5, True), (2.4, True)])
def test_pooling_stops_beyond_max_chi2_per_degree_of_freedom(scale, pooled):
    """``pool_fits``' rule: the kept fits' spread ``sum d2`` over ``p (n - 1)`` degrees
    of freedom above ``max_chi2`` (4) means they did not go through one pair of
    transducers: unchanged. Four unit-information fits on a cross of radius ``scale``
    about 0: each d2 = scale^2 (kept: <= 8 p = 16), sum 4 scale^2 over dof 6, i.e. 6.0,
    1.5 and 3.84 per degree of freedom."""
    from rangekit.detect.pathfit import pool_fits

    pts = [(scale, 0.0), (-scale, 0.0), (0.0, scale), (0.0, -scale)]
    fits = [_Fit(t, np.eye(2)) for t in pts]
    out, ok = pool_fits(fits)
    assert ok is pooled
    if pooled:
        assert out == [("at", (0.0, 0.0))] * 4
    else:
        assert out == fits
    # the limit is the argument: 6.0 per degree of freedom pools under max_chi2 = 6.5
    assert pool_fits([_Fit(t, np.eye(2)) for t in [(3.0, 0), (-3.0, 0), (0, 3.0), (0, -3.0)]],
                     max_chi2=6.5)[1]  # fmt: skip
