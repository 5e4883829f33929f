"""``rangekit.detect.pathfit``: rules of the fit pinned at both sides of their boundaries.

Issue 21's mutation round (helper P2, seeds 101 and 331 of the mutation check). Each test
states the rule it pins; the expectations are closed forms, numpy/scipy references or
the truth of a noiseless synthetic arrival, never a value read from the module. About
three seconds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pathfit_signals import fake_fit, received

from rangekit.detect import pathfit as P
from rangekit.signals.barker import CodedBurst

FS = 192000.0


@pytest.fixture(scope="module")
def model():
    return P.ResonatorModel.for_burst(CodedBurst(), fs=FS)


@pytest.mark.parametrize(
    ("offset", "applied"),
    [(0.6, True), (0.95, True), (-0.6, True), (1.05, False), (1.4, False), (-1.4, False)],
)
def test_the_summarys_newton_step_in_the_onset_is_taken_only_below_one_sample(
    model, offset, applied
):
    """``_summarize`` moves the first path by one Newton step in the onsets when that
    step is under one sample (a converged fit's is ~0) and keeps the fitted onset
    otherwise. A noiseless Q 12 arrival at 100.3 samples, summarized from onsets
    ``offset`` samples off: under 1 the step lands within 1e-3 samples of the truth
    (measured 5.2e-4 at 0.95), beyond it the onset stays where the state put it."""
    t0 = 100.3
    x = received(12.0, [t0], [1.0], n=model.segment)
    th = model.theta_start(12.0)
    st = P._evaluate(x, model, np.array([t0 + offset]), th, True)
    f = P._summarize(st, x, 0, model, 1e-4, 6.0, 0.25, -math.inf, math.inf, True)
    lin = float(f.onsets[f.first])
    if applied:
        assert abs(lin - t0) < 1e-3
    else:
        assert lin == t0 + offset


def test_resolution_is_the_half_width_of_the_analytic_autocorrelation(model):
    """``_resolution``: the first lag at which the model waveform's analytic
    autocorrelation envelope falls below one half of its value at lag 0, against the
    waveform's analytic signal by ``scipy.signal.hilbert`` and its circular
    autocorrelation by numpy, on 120 (Q, f0) pairs (Q 1-30 log-spaced, f0 40 kHz +-10 %;
    9 of them lie within 0.3 % of one half at the crossing, where a threshold taken from
    lag 1 instead would move it by one lag)."""
    from scipy.signal import hilbert

    for q in np.geomspace(1.0, 30.0, 40):
        for f0 in (36000.0, 40000.0, 44000.0):
            an = hilbert(model.waveform(q, f0))
            r = np.abs(np.fft.ifft(np.abs(np.fft.fft(an)) ** 2))
            want = float(np.flatnonzero(r[: len(r) // 2] < 0.5 * r[0])[0])
            assert P._resolution(model, model.theta_start(q, f0)) == want, (q, f0)


def _series(tab, nt, wc, m, u, first=0):
    """``exp(-j wc f) sum_{q < nt} (-j f)^q / q! D_{q + first}[t - i]`` with ``u = i + f``
    (``i = round(u)``), on the ``m``-point grid (numpy; the held fit's shift series)."""
    i = int(np.rint(u))
    f = u - i
    out = np.zeros(m, dtype=np.complex128)
    for q in range(nt):
        out += (-1j * f) ** q / math.factorial(q) * tab[q + first, :m]
    return np.exp(-1j * wc * f) * np.roll(out, i)


@pytest.mark.parametrize("q", [3.0, 12.0, 27.0])
def test_the_shift_tables_series_is_the_inverse_fft_of_the_shifted_spectrum(model, q):
    """``_shift_tables``: ``tab[q] = IFFT(s (w - wc)^q)`` (``wc`` the spectrum's peak bin),
    repeated once for ``segment`` samples along the grid; ``nt`` the first order at which
    the series' term bound ``sum |s| (|w - wc| / 2)^q / q!`` (also times ``|w - wc|`` for
    the onset row, and of each ``|ds_j|``) is below ``SHIFT_TOL`` of its order-0 sum
    (computed here); so the series at any fractional onset gives the inverse FFT of the
    shifted spectrum, waveform and onset derivative rows (and the derivative spectra's),
    to 6e-15 of each row's peak (measured up to 2.8e-15; the tables themselves to 7e-16 of
    theirs, measured 3.5e-16)."""
    th = model.theta_start(q, 40400.0)
    m, seg = model.n_fft, model.segment
    s, ds = model.spectrum_t(th, derivs=True)
    w = 2.0 * np.pi * np.arange(len(s)) / m
    wc = float(w[int(np.argmax(np.abs(s)))])
    dw = w - wc
    bounds = [np.abs(s), np.abs(s) * np.abs(dw), *(np.abs(d) for d in ds)]
    want_nt = next(
        k
        for k in range(1, 61)
        if all(
            (b * (np.abs(dw) / 2) ** k / math.factorial(k)).sum() < 1e-14 * b.sum() for b in bounds
        )
    )
    tab, nt, wc_got = P._shift_tables(model, th)
    tabd, ntd, _ = P._shift_tables(model, th, derivs=True)
    assert (nt, ntd, wc_got) == (want_nt, want_nt, wc)
    assert tab.shape == (nt + 1, m + seg) and tabd.shape == (2, nt, m + seg)
    for k in range(nt + 1):
        want = np.fft.ifft(np.concatenate([s * dw**k, np.zeros(m - len(s))]))
        np.testing.assert_allclose(tab[k, :m], want, rtol=0, atol=7e-16 * np.abs(want).max())
    np.testing.assert_array_equal(tab[:, m:], tab[:, :seg])
    np.testing.assert_array_equal(tabd[:, :, m:], tabd[:, :, :seg])
    pad = np.zeros(m - len(s))
    for u in (0.0, 0.5, -0.5, 0.37, 41.7, -12.49):
        ph = np.exp(-1j * w * u)
        row0 = _series(tab, nt, wc, m, u)
        row1 = -1j * wc * row0 - 1j * _series(tab, nt, wc, m, u, first=1)
        wants = [
            (row0, np.fft.ifft(np.concatenate([s * ph, pad]))),
            (row1, np.fft.ifft(np.concatenate([-1j * w * s * ph, pad]))),
        ]
        for j in range(2):
            wants.append(
                (_series(tabd[j], nt, wc, m, u), np.fft.ifft(np.concatenate([ds[j] * ph, pad])))
            )
        for got, want in wants:
            np.testing.assert_allclose(got, want, rtol=0, atol=6e-15 * np.abs(want).max())


def test_lm_step_is_not_solved_at_the_damping_limit():
    """``_lm_step_np`` solves the damped system while ``lam < 1e8``: at exactly 1e8 the
    step is zero (no step: the caller stops), just below it the damped step
    ``(J^T J + lam diag(J^T J))^-1 g`` (numpy's solve). A Jacobian with a zero column has
    no Gauss-Newton gain (nan: singular) and a zero step in that parameter (its damping
    weight set to 1)."""
    rng = np.random.default_rng(331)
    jac = rng.standard_normal((60, 3))
    r = rng.standard_normal(60)
    lim = np.full(3, np.inf)
    gn, lam, step = P._lm_step_np(jac, r, 3, 1e8, lim)
    assert lam == 1e8 and np.array_equal(step, np.zeros(3))
    assert gn == pytest.approx(float(jac.T @ r @ np.linalg.solve(jac.T @ jac, jac.T @ r)))
    lam0 = 0.99e8
    jtj = jac.T @ jac
    want = np.linalg.solve(jtj + lam0 * np.diag(np.diag(jtj)), jac.T @ r)
    _, lam, step = P._lm_step_np(jac, r, 3, lam0, lim)
    assert lam == lam0 and np.any(step != 0.0)
    np.testing.assert_allclose(step, want, rtol=1e-12)
    jac[:, 1] = 0.0
    gn, lam, step = P._lm_step_np(jac, r, 3, 0.5, lim)
    jtj = jac.T @ jac
    d = np.diag(jtj).copy()
    d[1] = 1.0
    assert math.isnan(gn) and lam == 0.5 and step[1] == 0.0
    np.testing.assert_allclose(step, np.linalg.solve(jtj + 0.5 * np.diag(d), jac.T @ r), rtol=1e-12)


@pytest.mark.parametrize(
    ("q", "onsets", "amps", "q_held", "lohi", "n_paths", "off"),
    [  # off: the first path's distance from the truth, twice what is measured
        (12.0, [280.3], [1.0], 12.0, (-math.inf, math.inf), 1, 0.065),  # measured 0.032
        (7.0, [277.7], [0.5], 6.0, (-math.inf, math.inf), 2, 1.2),  # Q held off: 0.61
        (18.0, [290.45, 321.2], [1.0, 0.6], 18.0, (200.0, 400.0), 2, 0.57),  # 0.28
        (9.0, [260.9, 350.1], [0.4, 1.0], 9.0, (255.0, 300.0), 2, 0.22),  # 0.11
    ],
)
def test_a_held_fit_compiled_equals_the_numpy_one_in_every_field(
    model, monkeypatch, q, onsets, amps, q_held, lohi, n_paths, off
):
    """``fit_arrival(hold=True)`` where the compiled step runs (the held fit as one call,
    its summary as another: ``_held_fit``, ``_held_result``) against the per-evaluation
    numpy path (``USE_KERNEL`` off): every field of the result, including those only the
    summary's wrapper sets (``n_par`` 3 per path, ``n0``, ``resolution``, ``family``, Q
    and f0 of ``theta_hat``), to rounding (bounds twice the largest difference measured on these
    four: onsets 5.7e-14 samples, the scalars 9.9e-14 relative, amplitudes 1.2e-14,
    ``theta_hat`` 4e-16, ``info`` 4.9e-15 of its largest, ``gain`` 4.1e-14)."""
    pytest.importorskip("numba")
    rng = np.random.default_rng(331)
    x = received(q, onsets, amps, n=model.segment + 200)
    x = x + 0.01 * rng.standard_normal(len(x))
    th = model.theta_start(q_held)
    lo, hi = lohi
    got = {}
    for compiled in (True, False):
        monkeypatch.setattr(P, "USE_KERNEL", compiled)
        with P.compiled_step(True):
            got[compiled] = P.fit_arrival(
                x, min(onsets), model=model, sigma=0.01, theta=th, hold=True, lo=lo, hi=hi
            )
    a, b = got[True], got[False]
    assert a.n_paths == b.n_paths == n_paths and a.first == b.first
    assert a.n_par == b.n_par == 3 * a.n_paths
    assert (a.n0, a.family, a.pooled, a.resolution) == (b.n0, b.family, b.pooled, b.resolution)
    assert a.n0 == max(0, int(math.floor(min(onsets))) - model.pre)
    np.testing.assert_allclose(a.onsets, b.onsets, rtol=0, atol=1.2e-13)
    assert abs(a.onsets[a.first] - min(t for t in onsets if lo - 1 <= t < hi)) < off
    for name in ("onset", "sigma", "snr", "q", "f0_hz", "misfit", "misfit_z", "chi2", "var_given"):
        assert getattr(a, name) == pytest.approx(getattr(b, name), rel=2e-13, abs=0.0), name
    np.testing.assert_allclose(a.amplitudes, b.amplitudes, rtol=2.5e-14)
    np.testing.assert_allclose(a.theta_hat, b.theta_hat, rtol=1e-15)
    np.testing.assert_array_equal(a.theta_lin, th)
    np.testing.assert_allclose(a.info, b.info, rtol=0, atol=1e-14 * np.abs(b.info).max())
    np.testing.assert_allclose(a.gain, b.gain, rtol=0, atol=1e-13)


@pytest.fixture(scope="module")
def two_paths(model):
    """A noiseless direct path at 100.25 samples (amplitude 0.5) and a reflection at 160.5
    (1.0), Q 12, evaluated at the truth with ``theta`` free (the summary's input)."""
    th = model.theta_start(12.0)
    x = received(12.0, [100.25, 160.5], [0.5, 1.0], n=model.segment)
    st = P._evaluate(x, model, np.array([100.25, 160.5]), th, True)
    return x, st


def _first(model, x, st, *, sigma=1e-3, k_noise=6.0, rel=0.25, lo=-math.inf, hi=math.inf):
    f = P._summarize(st, x, 0, model, sigma, k_noise, rel, lo, hi, True)
    return None if f is None else math.floor(float(f.onsets[f.first]))


def test_the_first_path_rule_at_its_thresholds(model, two_paths):
    """``_summarize``'s first path: an earlier path replaces the strongest when its
    amplitude is at least ``rel_threshold`` times the strongest's and its SNR
    (``|alpha| sqrt(E) / sigma``) at least ``k_noise``; each at exactly the threshold
    and one float above it."""
    x, st = two_paths
    amp = np.hypot(st.a[0::2], st.a[1::2])
    assert amp[0] / amp[1] == pytest.approx(0.5, rel=1e-6)
    rel = float(amp[0] / amp[1])
    while rel * amp[1] > amp[0]:
        rel = math.nextafter(rel, 0.0)
    above = rel
    while above * amp[1] <= amp[0]:
        above = math.nextafter(above, math.inf)
    assert _first(model, x, st, rel=rel) == 100
    assert _first(model, x, st, rel=above) == 160
    snr0 = float(amp[0] * math.sqrt(model.energy(12.0, model.f0_hz)) / 1e-3)
    assert _first(model, x, st, k_noise=snr0) == 100
    assert _first(model, x, st, k_noise=math.nextafter(snr0, math.inf)) == 160


def test_the_first_path_lies_in_lo_minus_one_to_hi(model, two_paths):
    """Paths count from ``lo - 1`` (inclusive) to ``hi`` (exclusive): the direct path at
    100.25 is in for ``lo`` 101.25 and out one float above; ``hi`` at 100.25 leaves no
    path (None), one float above it only the direct path."""
    x, st = two_paths
    assert _first(model, x, st, lo=101.25) == 100
    assert _first(model, x, st, lo=math.nextafter(101.25, math.inf)) == 160
    assert _first(model, x, st, hi=100.25) is None
    assert _first(model, x, st, hi=math.nextafter(100.25, math.inf)) == 100
    assert _first(model, x, st, lo=160.5, hi=161.0) == 160


def _fake(theta, info, onset=100.0, gain=None) -> P.PathFit:
    return fake_fit(theta, info, onset=onset, sigma=0.1, gain=gain)


def _pool_ref(fits, max_chi2=4.0):
    """``pool_fits`` as its docstring states it: the fits with finite, positive-definite
    information; their information-weighted mean over those within a Mahalanobis
    distance squared of ``8 p`` (4 sigma for p = 2), iterated (at most 5 times) until the
    kept set is stable, refused with fewer than 2 kept or a chi-square above
    ``max_chi2`` per degree of freedom ``p (n_kept - 1)``; each usable fit conditioned."""
    ok = [
        i
        for i, f in enumerate(fits)
        if f is not None and np.all(np.isfinite(f.info)) and np.linalg.det(f.info) > 0
    ]
    if len(ok) < 2:
        return None
    th = [fits[i].theta_hat for i in ok]
    w = [fits[i].info for i in ok]
    p = len(th[0])
    keep = [True] * len(ok)
    for _ in range(5):
        wk = sum(wi for wi, k in zip(w, keep, strict=True) if k)
        cov = np.linalg.inv(wk)
        mean = cov @ sum(wi @ ti for wi, ti, k in zip(w, th, keep, strict=True) if k)
        d2 = [float((ti - mean) @ wi @ (ti - mean)) for wi, ti in zip(w, th, strict=True)]
        new = [d <= 8.0 * p for d in d2]
        if sum(new) < 2:
            return None
        if new == keep:
            break
        keep = new
    chi2 = sum(d for d, k in zip(d2, keep, strict=True) if k)
    if chi2 > max_chi2 * p * (sum(keep) - 1):
        return None
    return ok, mean, cov


def test_pool_fits_equals_its_documented_rule_on_random_groups():
    """Random groups of 2-9 fits (``p`` 2 and 4), scattered by 0.5-3 sigma with up to
    two outliers, a None, a fit without information or with non-finite information, and
    ``max_chi2`` drawn around the groups' chi-square: ``pool_fits`` pools exactly when
    the reference does, to the reference's mean and covariance, each onset moved along
    its gain and its variance ``var_given + gain C gain``; both outcomes occur (measured:
    pooled in 185 of 300 groups)."""
    rng = np.random.default_rng(331_2)
    pooled_n = 0
    for _ in range(300):
        p = int(rng.choice([2, 4]))
        n = int(rng.integers(2, 10))
        centre = np.concatenate([[math.log(10.0), 40000.0], rng.normal(size=p - 2)])
        fits = []
        for _ in range(n):
            a = rng.normal(size=(p, p))
            info = a @ a.T + 0.1 * np.eye(p)
            dev = np.linalg.cholesky(np.linalg.inv(info)) @ rng.normal(size=p)
            fits.append(_fake(centre + rng.uniform(0.5, 3.0) * dev, info))
        for _ in range(int(rng.integers(0, 3))):
            fits.append(_fake(centre + rng.uniform(1.0, 20.0) * rng.normal(size=p), np.eye(p)))
        extra = rng.random()
        if extra < 0.2:
            fits.append(None)
        elif extra < 0.3:
            fits.append(_fake(centre, np.zeros((p, p))))
        elif extra < 0.4:
            fits.append(_fake(centre, np.full((p, p), np.nan)))
        max_chi2 = float(rng.uniform(0.5, 6.0))
        want = _pool_ref(fits, max_chi2)
        out, pooled = P.pool_fits(fits, max_chi2=max_chi2)
        assert pooled == (want is not None)
        if want is None:
            assert out == fits
            continue
        pooled_n += 1
        ok, mean, cov = want
        for i, (f, g) in enumerate(zip(fits, out, strict=True)):
            if i not in ok:
                assert g is f
                continue
            assert g.pooled
            np.testing.assert_allclose(g.theta_hat, mean, rtol=1e-9, atol=1e-12)
            assert g.onset == pytest.approx(f.onset + f.gain @ (mean - f.theta_lin), abs=1e-9)
            assert g.sigma**2 == pytest.approx(f.var_given + f.gain @ cov @ f.gain, rel=1e-9)
    assert 93 <= pooled_n <= 280, pooled_n  # measured 185


def _model_signal(model, u, theta, a):
    """``sum_k Re{(a_re,k - j a_im,k) s_a(n - u_k)}``: the modelled segment at fixed
    amplitudes (the basis columns are the real and imaginary parts of each waveform)."""
    s = model.spectrum_t(theta)
    ph = np.exp(np.multiply.outer(np.asarray(u, float), model._mjw))
    rows = np.fft.ifft(np.concatenate([s * ph, np.zeros((len(u), model.n_fft - len(s)))], 1))
    return (a[0::2, None] * rows.real + a[1::2, None] * rows.imag).sum(axis=0)


@pytest.mark.parametrize("with_theta", [True, False])
def test_evaluate_is_least_squares_with_the_models_jacobian(model, with_theta):
    """``_evaluate`` (numpy path): the amplitudes are the least-squares solution
    (``numpy.linalg.lstsq``) of the segment on the paths' in-phase and quadrature
    columns, the residual and cost follow, and the Jacobian's columns are the modelled
    segment's derivatives at those amplitudes, by each onset and (summed over the paths)
    by each ``theta`` (central differences, within 6e-9 of the column's largest value;
    measured 2.9e-9); two coincident paths (a singular Gram matrix) give lstsq's
    minimum-norm amplitudes (``pinv``)."""
    rng = np.random.default_rng(331_3)
    th = model.theta_start(9.0, 40300.0)
    n = model.segment
    x = received(9.0, [90.3, 170.8], [1.0, 0.4], n=n) + 0.01 * rng.standard_normal(n)
    u = np.array([90.1, 171.2])
    st = P._evaluate(x, model, u, th, with_theta)
    a_ref, *_ = np.linalg.lstsq(st.basis, x, rcond=None)
    np.testing.assert_allclose(st.a, a_ref, rtol=1e-9)
    full = _model_signal(model, u, th, st.a)[:n]
    np.testing.assert_allclose(st.basis @ st.a, full, atol=1e-12)
    np.testing.assert_allclose(st.r, x - full, atol=1e-12)
    assert st.cost == pytest.approx(float(np.sum((x - full) ** 2)), rel=1e-12)
    cols = []
    for i in range(2):
        h = 1e-4
        du = np.zeros(2)
        du[i] = h
        cols.append(
            (_model_signal(model, u + du, th, st.a) - _model_signal(model, u - du, th, st.a))[:n]
            / (2 * h)
        )
    if with_theta:
        for i, h in enumerate((1e-5, 1e-2)):
            dt = np.zeros(2)
            dt[i] = h
            cols.append(
                (_model_signal(model, u, th + dt, st.a) - _model_signal(model, u, th - dt, st.a))[
                    :n
                ]
                / (2 * h)
            )
    assert st.jac.shape == (n, len(cols))
    for j, col in enumerate(cols):
        assert np.abs(st.jac[:, j] - col).max() < 6e-9 * np.abs(col).max(), j
    two = P._evaluate(x, model, np.array([90.3, 90.3]), th, with_theta)
    basis = two.basis
    a_min, *_ = np.linalg.lstsq(basis, x, rcond=None)
    np.testing.assert_allclose(basis @ two.a, basis @ a_min, atol=1e-9)
    assert two.cost == pytest.approx(float(np.sum((x - basis @ a_min) ** 2)), rel=1e-9)


@pytest.mark.parametrize(
    ("a2", "rel_add", "n_paths"), [(0.08, 0.1, 1), (0.12, 0.1, 2), (0.08, 0.05, 2)]
)
def test_a_further_path_must_reach_rel_add_of_the_strongest(model, a2, rel_add, n_paths):
    """A noiseless reflection 120 samples after the direct path (beyond the two-path
    scan's reach; the noise sigma 1e-5 puts it hundreds of noise scales up) is fitted as
    a further path only at ``rel_add`` of the strongest path's amplitude or more: 0.08 of
    it not at the default 0.1, at 0.05 yes; 0.12 at the default."""
    x = received(12.0, [1000.3, 1120.6], [1.0, a2])
    f = P.fit_arrival(x, 1000.3, model=model, sigma=1e-5, q0=12.0, hold=True, rel_add=rel_add)
    assert f.n_paths == n_paths
    if n_paths == 2:
        np.testing.assert_allclose(f.onsets, [1000.3, 1120.6], atol=1e-3)


@pytest.mark.parametrize(("z", "n_paths"), [(4.1, 1), (4.4, 2)])
def test_a_further_path_must_pay_schwarzs_three_ln_n(model, z, n_paths):
    """With ``k_add`` 3, a further path ``z`` noise scales up is kept only if it lowers
    the cost by ``3 ln n`` noise variances (Schwarz 1978, "Estimating the dimension of a
    model", Ann. Statist. 6(2): ``ln n`` per parameter, three per path): ``n`` = 332
    samples of segment, 17.4 variances, so a noiseless path at ``z`` = 4.1 (gain about
    ``z^2`` = 16.8; the one-path fit's chi-square, which the path removes, measured 16.2)
    is not kept and one at 4.4 (``z^2`` = 19.4) is."""
    assert model.segment == 332 and 3 * math.log(332) == pytest.approx(17.4154, abs=1e-4)
    a2 = 0.3
    x = received(12.0, [1000.3, 1120.6], [1.0, a2])
    sigma = a2 * math.sqrt(model.energy(12.0, model.f0_hz)) / z
    f = P.fit_arrival(x, 1000.3, model=model, sigma=sigma, q0=12.0, hold=True, k_add=3.0)
    assert f.n_paths == n_paths


@pytest.mark.parametrize(("z", "n_paths"), [(2.9, 1), (3.1, 2)])
def test_a_held_one_path_fit_is_tried_as_two_beyond_z_two_paths(model, z, n_paths):
    """A held fit tries two overlapping paths when the one-path residual exceeds the noise
    by ``Z_TWO_PATHS`` = 3 deviations of its chi-square (``(chi2 - dof) / sqrt(2 dof)``,
    ``dof`` = 332 - 3). A noiseless direct path and a half-as-strong reflection 9 samples
    later (0.4 resolutions: one merged peak, which the further-path loop does not split),
    with the noise sigma set so that the one-path misfit is ``z``: at 2.9 the merged
    path (its onset 2.6 samples late), at 3.1 both paths at their onsets (within 1e-3)."""
    x = received(12.0, [1000.3, 1009.3], [1.0, 0.5])
    one = P.fit_arrival(x, 1000.3, model=model, sigma=1e-6, q0=12.0, hold=True, max_paths=1)
    resid = one.chi2 * 1e-12
    dof = model.segment - 3
    sigma = math.sqrt(resid / (dof + z * math.sqrt(2.0 * dof)))
    f = P.fit_arrival(x, 1000.3, model=model, sigma=sigma, q0=12.0, hold=True)
    assert f.n_paths == n_paths
    if n_paths == 1:
        assert 2.0 < f.onset - 1000.3 < 3.2  # measured 2.65
    else:
        np.testing.assert_allclose(f.onsets, [1000.3, 1009.3], atol=1e-3)


@pytest.mark.parametrize("hold", [True, False])
@pytest.mark.parametrize(
    ("a2", "rel_add", "n_paths"), [(0.09, 0.1, 1), (0.11, 0.1, 2), (0.06, 0.05, 2)]
)
def test_an_overlapping_pair_needs_rel_add_between_its_amplitudes(
    model, hold, a2, rel_add, n_paths
):
    """The two-path scan's pair replaces one path only if its weaker amplitude is at
    least ``rel_add`` of its stronger: a noiseless reflection 9 samples after the direct
    path (merged with it) at 0.09 of its amplitude stays merged at the default 0.1 (the
    onset pulled 0.6-0.8 samples late), at 0.11 (or 0.06 with ``rel_add`` 0.05) both
    paths are fitted at their onsets and amplitudes; held or free."""
    x = received(12.0, [1000.3, 1009.3], [1.0, a2])
    f = P.fit_arrival(x, 1000.3, model=model, sigma=1e-6, q0=12.0, hold=hold, rel_add=rel_add)
    assert f.n_paths == n_paths
    if n_paths == 2:
        np.testing.assert_allclose(f.onsets, [1000.3, 1009.3], atol=1e-3)
        np.testing.assert_allclose(f.amplitudes, [1.0, a2], rtol=1e-3)
    else:
        assert 0.3 < f.onsets[0] - 1000.3 < 1.6  # measured 0.80 held, 0.63 free
