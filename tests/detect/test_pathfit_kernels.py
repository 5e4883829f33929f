"""The compiled step of the transducer fit against its numpy reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

numba = pytest.importorskip("numba")

from rangekit.detect import _pathfit_kernels as K  # noqa: E402
from rangekit.detect import pathfit as P  # noqa: E402
from rangekit.signals.barker import CodedBurst, burst_waveform  # noqa: E402
from rangekit.signals.transducer import Transducer  # noqa: E402


def _rows(rng, nb, k, m=64):
    return rng.standard_normal((nb, k, m)) + 1j * rng.standard_normal((nb, k, m))


@pytest.mark.parametrize(("nb", "k"), [(2, 1), (2, 3), (4, 2), (6, 1)])
def test_vp_kernel_equals_the_numpy_reference(nb, k):
    rng = np.random.default_rng(nb * 10 + k)
    rows = _rows(rng, nb, k)
    n = 50
    x = rng.standard_normal(n)
    ok, basis, gi, a, r, cost, jac, jp = K.call("vp", rows, x, n)
    ref = P._evaluate_np(x, rows[:, :, :n], np.zeros(k), np.zeros(2), nb > 2)
    assert ok
    for got, want in [(basis, ref.basis), (gi, ref.gram_inv), (a, ref.a), (r, ref.r),
                      (jac, ref.jac), (jp, P._projected(ref))]:  # fmt: skip
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)  # measured ~1e-15
    assert cost == pytest.approx(ref.cost, rel=1e-12)


def test_vp_kernel_refuses_a_singular_gram_matrix():
    rows = np.zeros((2, 2, 16), dtype=np.complex128)
    ok = K.call("vp", rows, np.ones(16), 16)[0]
    assert not ok  # the caller falls back to the reference (pseudo-inverse)


def test_vp_kernel_flags_a_non_finite_residual():
    rng = np.random.default_rng(3)
    x = rng.standard_normal(20)
    x[5] = math.nan
    assert K.call("vp", _rows(rng, 2, 1, 32), x, 20)[5] == math.inf


@pytest.mark.parametrize("singular", [False, True])
def test_lm_step_kernel_equals_the_numpy_reference(singular):
    rng = np.random.default_rng(7)
    jp = rng.standard_normal((40, 4))
    if singular:
        jp[:, 3] = 0.0  # J^T J singular: no Gauss-Newton gain, the damped step still solves
    r = rng.standard_normal(40)
    lim = np.array([4.0, 4.0, 0.35, 400.0])
    gn, lam, step = K.call("lm_step", jp, r, 4, 1e-3, lim)
    gn_r, lam_r, step_r = P._lm_step_np(jp, r, 4, 1e-3, lim)
    assert lam == lam_r
    np.testing.assert_allclose(step, step_r, rtol=1e-9, atol=1e-14)
    if singular:
        assert math.isnan(gn) and (math.isnan(gn_r) or abs(gn_r) > 1e6)
    else:
        assert gn == pytest.approx(gn_r, rel=1e-10)


def test_lm_step_scales_the_whole_step_to_its_limits():
    jp = np.eye(3)
    gn, lam, step = K.call("lm_step", jp, np.array([10.0, 1.0, 0.0]), 3, 0.0, np.full(3, 2.0))
    assert lam == 0.0
    assert gn == pytest.approx(101.0)
    np.testing.assert_allclose(step, [2.0, 0.2, 0.0])  # direction kept, largest at its limit


@pytest.mark.parametrize("hold", [True, False])
def test_fit_with_and_without_the_kernels_agrees_to_rounding(hold, monkeypatch):
    fs = 192000.0
    model = P.ResonatorModel.for_burst(fs=fs)
    t = Transducer(q=12.0)
    x = np.zeros(1600)
    x[600:701] = burst_waveform(CodedBurst(fs=fs))
    x = t.apply(t.apply(x, fs=fs), fs=fs)
    x[630:] += 0.5 * x[600:-30]  # a reflection within the burst: two paths
    x += 0.01 * np.random.default_rng(0).standard_normal(len(x))
    th = model.theta_start(12.0)
    fits = []
    for use in (True, False):
        monkeypatch.setattr(P, "USE_KERNEL", use)
        with P.compiled_step(True):
            fits.append(P.fit_arrival(x, 600.0, model=model, sigma=0.01, theta=th, hold=hold))
    a, b = fits
    assert a.n_paths == b.n_paths == 2
    # measured: onsets equal to 3e-12 samples, sigma to 1e-15 relative
    np.testing.assert_allclose(a.onsets, b.onsets, rtol=0, atol=1e-8)
    assert a.sigma == pytest.approx(b.sigma, rel=1e-8)
    assert a.q == pytest.approx(b.q, rel=1e-8)


def test_the_compiled_step_runs_by_the_recording_length_not_the_imports():
    """Which step a fit runs is the caller's (``compiled_step``, set by the channel fits
    from the recording's length), never whether numba happens to be imported: the same
    recording gives the same bits in any process."""
    import numba  # noqa: F401  (imported: it must not matter)

    x = np.zeros(64)
    assert not P._use_kernel(x)
    with P.compiled_step(True):
        assert P._use_kernel(x)
        with P.compiled_step(False):
            assert not P._use_kernel(x)
        assert P._use_kernel(x)
    assert not P._use_kernel(x)

    seen = []

    @P.kernel_by_length
    def probe(y):
        seen.append(P._use_kernel(np.zeros(4)))

    probe(np.zeros(P.KERNEL_MIN_SAMPLES - 1))
    probe(np.zeros(P.KERNEL_MIN_SAMPLES))
    assert seen == [False, True]
