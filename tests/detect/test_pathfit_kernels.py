"""The compiled step of the transducer fit against its numpy reference."""

from __future__ import annotations

import contextlib
import math

import numpy as np
import pytest

numba = pytest.importorskip("numba")

from pathfit_signals import FS, received  # noqa: E402

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
    # a short block of a long recording (a series' blocks): the recording's length rules
    from rangekit.detect._kernels import recording_samples

    with recording_samples(P.KERNEL_MIN_SAMPLES):
        probe(np.zeros(16))
    with recording_samples(P.KERNEL_MIN_SAMPLES - 1):
        probe(np.zeros(16))
    probe(np.zeros(16))
    assert seen == [False, True, True, False, False]


# The held fit as one compiled call (shift series instead of inverse FFTs) against the
# numpy reference: seeded signals of one and two paths, through Tx and Rx resonators.
HELD_CASES = [
    # (Q of the signal, onsets, amplitudes, held Q, noise, offset of the start)
    (12.0, [80.3], [1.0], 12.0, 0.01, 0.0),
    (6.0, [77.7], [0.02], 7.0, 0.002, 1.6),  # a held Q off the truth, 2 samples off
    (18.0, [90.45, 121.2], [1.0, 0.6], 18.0, 0.01, 0.0),  # a reflection in the burst
    (9.0, [60.9, 150.1], [1.0, -0.5], 9.0, 0.02, -1.2),  # two paths apart, sign flipped
    (4.0, [-20.4, 30.0], [0.5, 1.0], 4.0, 0.01, 0.7),  # a path begun before the segment
]


def _held_signal(i):
    q, onsets, amps, q_held, noise, off = HELD_CASES[i]
    model = P.ResonatorModel.for_burst(fs=FS)
    x = received(q, onsets, amps, n=model.segment)
    x = x + noise * np.random.default_rng(40 + i).standard_normal(len(x))
    return model, x, model.theta_start(q_held), [t + off for t in onsets], noise


@contextlib.contextmanager
def _step(monkeypatch, compiled: bool):
    monkeypatch.setattr(P, "USE_KERNEL", compiled)
    with P.compiled_step(True):
        yield
    monkeypatch.setattr(P, "USE_KERNEL", True)


@pytest.mark.parametrize("i", range(len(HELD_CASES)))
def test_the_compiled_held_fit_equals_the_numpy_reference(i, monkeypatch):
    model, x, th, u0, sigma = _held_signal(i)
    used = []
    real = P._held_fit
    monkeypatch.setattr(P, "_held_fit", lambda *a: used.append(1) or real(*a))
    got = {}
    for compiled in (True, False):
        with _step(monkeypatch, compiled):
            got[compiled] = P.fit_paths(x, model, u0, theta=th, fit_theta=False,
                                        tol=1e-3 * sigma**2)  # fmt: skip
    assert used == [1]  # the compiled call ran once, the reference not at all
    a, b = got[True], got[False]
    assert not a.with_theta and np.array_equal(a.theta, b.theta)
    # measured: onsets to 9e-14 samples, amplitudes to 2e-12 and cost to 5e-15 relative
    np.testing.assert_allclose(a.u, b.u, rtol=0, atol=1e-6)
    np.testing.assert_allclose(a.a, b.a, rtol=1e-8, atol=0)
    assert a.cost == pytest.approx(b.cost, rel=1e-8)
    np.testing.assert_allclose(a.r, b.r, rtol=0, atol=1e-8 * np.max(np.abs(x)))
    np.testing.assert_allclose(P._projected(a), P._projected(b), rtol=1e-7, atol=1e-9)


def _held_fits(monkeypatch, model, x, lag, sigma, th):
    """The held ``fit_arrival`` compiled and in numpy, and the compiled summary's result."""
    ran = []
    real = P._held_result
    monkeypatch.setattr(P, "_held_result", lambda *a: ran.append(real(*a)) or ran[-1])
    fits = {}
    for compiled in (True, False):
        with _step(monkeypatch, compiled):
            fits[compiled] = P.fit_arrival(x, lag, model=model, sigma=sigma, theta=th,
                                           hold=True)  # fmt: skip
    a, b = fits[True], fits[False]
    assert len(ran) == 1 and ran[0] is a  # the compiled summary made the compiled fit
    return a, b


def _assert_held_equal(a, b):
    assert a.n_paths == b.n_paths and a.first == b.first
    # measured: onsets to 2e-13 samples, the rest to 1e-13 relative (gain 1e-13 absolute)
    np.testing.assert_allclose(a.onsets, b.onsets, rtol=0, atol=1e-6)
    assert a.onset == pytest.approx(b.onset, abs=1e-6)
    np.testing.assert_allclose(a.amplitudes, b.amplitudes, rtol=1e-8, atol=0)
    for name in ("sigma", "chi2", "misfit_z", "var_given", "snr"):
        assert getattr(a, name) == pytest.approx(getattr(b, name), rel=1e-8), name
    np.testing.assert_allclose(a.info, b.info, rtol=1e-8, atol=1e-12 * np.max(np.abs(b.info)))
    np.testing.assert_allclose(a.gain, b.gain, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(a.theta_hat, b.theta_hat, rtol=1e-10, atol=0)


@pytest.mark.parametrize("i", range(len(HELD_CASES)))
def test_a_held_fit_arrival_compiled_equals_the_numpy_reference(i, monkeypatch):
    """The whole held fit of an arrival: its LM loop and its summary (the ``theta``
    columns, the Gauss-Newton blocks and their Cholesky inverses) compiled."""
    model, x, th, u0, sigma = _held_signal(i)
    x = np.concatenate([np.zeros(200), x])  # room before the segment
    a, b = _held_fits(monkeypatch, model, x, 200.0 + min(u0), sigma, th)
    _assert_held_equal(a, b)


@pytest.mark.parametrize("u", [0.0, 0.5, -0.5, 37.25, -41.7, 300.49])
def test_the_shift_series_gives_the_inverse_fft_rows(u):
    """Rows of the held spectrum at a fractional onset (either side of a rounding, before
    the grid's start: a circular shift) from the tables, equal to the inverse FFTs."""
    model = P.ResonatorModel.for_burst(fs=FS)
    th = model.theta_start(8.0)
    n = model.segment
    tab, nt, wc = P._shift_tables(model, th)
    rows = np.empty((2, 2, n), dtype=np.complex128)
    uu = np.array([u, u + 13.3])
    K.call("shift_rows", tab, nt, wc, model.n_fft, uu, n, rows)
    s = model.spectrum_t(th)
    ph = np.exp(np.multiply.outer(uu, model._mjw))
    want = np.fft.ifft(np.array([s * ph, s * model._mjw * ph]), n=model.n_fft, axis=2)[..., :n]
    for j in range(2):
        scale = np.max(np.abs(want[j]))
        # measured 1.5e-14 of the row's peak (the series stops at SHIFT_TOL = 1e-14)
        np.testing.assert_allclose(rows[j], want[j], rtol=0, atol=4e-14 * scale)


def test_a_singular_held_fit_falls_back_to_the_reference(monkeypatch):
    """A Gram matrix that is not positive definite (here: a zero spectrum, no waveform):
    the compiled call says so, and fit_paths then runs the per-evaluation path, as it
    does with the held kernel switched off."""
    model, x, th, u0, _ = _held_signal(2)
    tab, nt, wc = P._shift_tables(model, th)
    ok = K.call("held_fit", x, np.zeros_like(tab), nt, wc, model.n_fft, np.array(u0),
                -50.0, 300.0, 0.0, 30)[0]  # fmt: skip
    assert not ok
    got = {}
    for refuse in (True, False):
        if refuse:
            monkeypatch.setattr(P, "_held_fit", lambda *a: None)
        else:
            monkeypatch.setattr(P, "HELD_KERNEL", False)
        with P.compiled_step(True):
            got[refuse] = P.fit_paths(x, model, u0, theta=th, fit_theta=False)
    assert np.array_equal(got[True].u, got[False].u) and got[True].cost == got[False].cost


@pytest.mark.parametrize("compiled", [True, False])
def test_a_held_fit_with_no_path_in_the_search_range_is_none(compiled, monkeypatch):
    model, x, th, u0, sigma = _held_signal(0)
    x = np.concatenate([np.zeros(200), x])
    with _step(monkeypatch, compiled):
        kw = {"model": model, "sigma": sigma, "theta": th, "hold": True}
        assert P.fit_arrival(x, 200.0 + u0[0], lo=600.0, hi=700.0, **kw) is None
        assert P.fit_arrival(x, 200.0 + u0[0], lo=200.0, hi=400.0, **kw) is not None


@pytest.mark.parametrize("i", [0, 2])
def test_a_held_stagger_fit_compiled_equals_the_numpy_reference(i, monkeypatch):
    """The stagger model (four ``theta`` columns) through the same compiled calls."""
    from rangekit.detect.stagger import StaggerModel

    _, x, _, u0, sigma = _held_signal(i)
    model = StaggerModel.for_burst(fs=FS)
    th = model.theta_start(HELD_CASES[i][3])
    x = np.concatenate([np.zeros(200), x])
    a, b = _held_fits(monkeypatch, model, x, 200.0 + min(u0), sigma, th)
    assert a.info.shape == (4, 4)
    _assert_held_equal(a, b)


@pytest.mark.parametrize("which", ["kernel", "numpy"])
def test_lm_step_from_zero_damping_on_a_singular_system_returns(which):
    """An undamped request (``lam = 0``) on a singular ``J^T J`` used to loop forever
    (``0 * 10 = 0``); the damping now rises from 1e-9, the fit's smallest."""
    import threading

    rng = np.random.default_rng(11)
    jp = rng.standard_normal((30, 3))
    jp[:, 2] = 0.0
    r = rng.standard_normal(30)
    lim = np.full(3, 1e6)
    step_fn = (
        (lambda: K.call("lm_step", jp, r, 3, 0.0, lim))
        if which == "kernel"
        else (lambda: P._lm_step_np(jp, r, 3, 0.0, lim))
    )
    out: list = []
    t = threading.Thread(target=lambda: out.append(step_fn()), daemon=True)
    t.start()
    t.join(timeout=60.0)  # measured: well under a second, compile included
    assert out, "lm_step did not return from lam = 0 on a singular system"
    gn, lam, step = out[0]
    assert math.isnan(gn)  # J^T J singular: no Gauss-Newton gain
    assert lam == 1e-9  # solved at the smallest damping, not raised further
    # the damped step solves (J^T J + 1e-9 diag') step = g, diag' = 1 where J^T J's is 0
    jtj, g = jp.T @ jp, jp.T @ r
    d = np.where(np.diag(jtj) > 0, np.diag(jtj), 1.0)
    np.testing.assert_allclose((jtj + lam * np.diag(d)) @ step, g, rtol=1e-9, atol=1e-9)
    assert step[2] == 0.0  # nothing in g moves the dead column
