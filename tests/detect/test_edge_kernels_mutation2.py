"""The edge fit's compiled kernels and helpers, one by one, against independent references.

``test_edge_kernels.py`` compares whole detections and stage outputs of
``rangekit.detect._edge_kernels`` with the numpy path; a changed rule inside a helper
(a pivot test, a regularisation constant, a boundary comparison) rarely shows there. Here
each kernel and helper meets a reference written apart from it: ``numpy.linalg`` for the
Cholesky factor and solves, ``numpy.linspace``, ``numpy.convolve``, ``numpy.median``,
``numpy.triu_indices``, ``scipy.ndimage.maximum_filter1d``, least-squares projections
for the F statistics and the stage-2 fit, changepoint's numpy code for the change points
and first edge, and plain-python restatements of the documented rules (burst envelope,
drift half-width, line ranking, de-duplication), on many seeded random inputs and at both
sides of each boundary. Written for the mutation round of issue 21 (docs/evidence.md).

Helpers that are not kernels are called as python functions (or, once another test has
compiled them, as their compiled versions: the same source either way); kernels through
``call``, as the detector calls them.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from detections import assert_same_detections
from scipy.ndimage import maximum_filter1d

import rangekit.detect._edge_kernels as K
import rangekit.detect.changepoint as cp

RNG_SEED = 20261203


@pytest.fixture(autouse=True, scope="module")
def _compiled_helpers():
    """The helpers as numba compiles them (as the detector runs them, and whatever ran
    before in the session), so the measured rounding is the compiled one."""
    K._compiled("all_finite")


def _spd(rng, p, cond=1e3):
    q, _ = np.linalg.qr(rng.standard_normal((p, p)))
    ev = np.geomspace(1.0, 1.0 / cond, p) * rng.uniform(0.5, 2.0)
    return (q * ev) @ q.T


# ---------------------------------------------------------------- linear algebra


def test_cholesky_and_its_solve_equal_numpy_linalg():
    rng = np.random.default_rng(RNG_SEED)
    worst_l = worst_x = 0.0
    for _ in range(200):
        p = int(rng.integers(1, 7))
        g = _spd(rng, p)
        lo = np.full((p, p), 7.0)  # the upper triangle is not written
        assert K._cholesky(g, p, lo)
        ref = np.linalg.cholesky(g)
        worst_l = max(worst_l, np.max(np.abs(np.tril(lo) - ref)) / np.max(np.abs(ref)))
        rhs = rng.standard_normal(p)
        out = np.zeros(p)
        K._chol_solve(lo, p, rhs, out)
        x = np.linalg.solve(g, rhs)
        worst_x = max(worst_x, np.max(np.abs(out - x)) / np.max(np.abs(x)))
    assert worst_l < 1e-14  # measured 2.9e-15
    assert worst_x < 3e-13  # measured 8.6e-14 (condition numbers up to 1e3)


def test_cholesky_uses_the_leading_block_only():
    rng = np.random.default_rng(1)
    g = np.full((5, 5), np.nan)
    g[:3, :3] = _spd(rng, 3)
    lo = np.zeros((5, 5))
    assert K._cholesky(g, 3, lo)
    np.testing.assert_allclose(lo[:3, :3], np.linalg.cholesky(g[:3, :3]), rtol=1e-13, atol=0)


@pytest.mark.parametrize(
    "g",
    [
        [[1.0, 1.0], [1.0, 1.0]],  # singular: the second pivot exactly 0
        [[1.0, 2.0], [2.0, 1.0]],  # indefinite
        [[0.0]],  # a zero pivot first
        [[-1.0]],
        [[np.nan]],
        [[4.0, 0.0, 0.0], [0.0, 1.0, 1.0], [0.0, 1.0, 1.0]],  # the last pivot exactly 0
    ],
)
def test_cholesky_refuses_a_matrix_not_positive_definite(g):
    g = np.array(g)
    p = g.shape[0]
    assert not K._cholesky(g, p, np.zeros((p, p)))


def test_regularised_solve_of_a_singular_gram_matrix():
    """(G + r I) c = g with r = 1e-12 tr(G) / p + 1e-300: on a singular G the
    regularisation is the answer (explained energy 1/(1 + r) + 1/r for diag(1, 0))."""
    for p, diag in ((2, [1.0, 0.0]), (3, [2.0, 0.0, 1.0]), (4, [3.0, 1.0, 0.0, 0.0])):
        gram = np.diag(np.array(diag))
        g = np.ones(p)
        lo = np.zeros((p, p))
        coef = np.zeros(p)
        r = 1e-12 * sum(diag) / p + 1e-300
        e, ok = K._reg_solve(gram.copy(), g, p, lo, coef)
        assert ok
        ref_coef = 1.0 / (np.array(diag) + r)
        np.testing.assert_allclose(coef, ref_coef, rtol=1e-9, atol=0)
        assert math.isclose(e, float(np.sum(ref_coef)), rel_tol=1e-9)
        gm = gram.copy()
        K._reg_solve(gm, g, p, lo, coef)
        np.testing.assert_allclose(np.diag(gm), np.array(diag) + r, rtol=1e-15, atol=0)
    # an all-zero Gram matrix: only the 1e-300 floor
    e, ok = K._reg_solve(np.zeros((1, 1)), np.ones(1), 1, np.zeros((1, 1)), np.zeros(1))
    assert ok and math.isclose(e, 1e300, rel_tol=1e-12)
    e, ok = K._reg_solve(np.full((1, 1), -1.0), np.ones(1), 1, np.zeros((1, 1)), np.zeros(1))
    assert not ok and e == 0.0


def test_regularised_solve_and_explained_energy_equal_numpy():
    rng = np.random.default_rng(RNG_SEED + 1)
    worst = 0.0
    for _ in range(200):
        p = int(rng.integers(2, 7))
        a = rng.standard_normal((30, p))
        gram = a.T @ a
        g = rng.standard_normal(p)
        r = 1e-12 * np.trace(gram) / p + 1e-300
        ref = g @ np.linalg.solve(gram + r * np.eye(p), g)
        e, ok = K._reg_solve(gram.copy(), g, p, np.zeros((p, p)), np.zeros(p))
        assert ok
        worst = max(worst, abs(e - ref) / ref)
        j0 = int(rng.integers(0, p))
        sub = gram[j0:, j0:]
        rs = 1e-12 * np.trace(sub) / (p - j0) + 1e-300
        ref2 = g[j0:] @ np.linalg.solve(sub + rs * np.eye(p - j0), g[j0:])
        e2, ok = K._explained(gram, g, j0, p, np.zeros((p, p)), np.zeros(p))
        assert ok
        worst = max(worst, abs(e2 - ref2) / ref2)
    assert worst < 2e-15  # measured 5.2e-16


# ---------------------------------------------------------------- small helpers


def test_linspace_equals_numpy_bit_for_bit():
    rng = np.random.default_rng(RNG_SEED + 2)
    cases = [(0.0, 1.0, 2), (5.0, 5.0, 7), (-3.0, 2.0, 11), (0.0, 1.5e-323, 11), (1.0, -1.0, 3)]
    for _ in range(200):
        a, b = rng.uniform(-1e4, 1e4, 2)
        cases.append((float(a), float(b), int(rng.integers(2, 40))))
    for a, b, num in cases:
        out = np.full(num, np.nan)
        K._linspace(a, b, num, out)
        np.testing.assert_array_equal(out, np.linspace(a, b, num))


def _env_ref(t, taper_s, burst_s):
    """rangekit.signals.beep.burst_envelope's rule at one time, restated."""
    env = 1.0 if 0.0 <= t <= burst_s else 0.0
    if taper_s > 0:
        if 0.0 <= t < taper_s:
            env = 0.5 - 0.5 * math.cos(math.pi * t / taper_s)
        if burst_s - taper_s < t <= burst_s:
            env = 0.5 - 0.5 * math.cos(math.pi * (burst_s - t) / taper_s)
    return env


@pytest.mark.parametrize(("taper_s", "burst_s"), [(0.25, 1.0), (0.0, 1.0), (0.75, 1.0), (0.5, 1.0)])
def test_envelope_equals_the_raised_cosine_rule_at_and_between_its_knots(taper_s, burst_s):
    ts = [-1e-9, 0.0, 1e-12, taper_s, burst_s - taper_s, burst_s, burst_s + 1e-12, 2.0]
    ts += list(np.linspace(-0.1, 1.1, 97))
    for t in ts:
        assert K._env(float(t), taper_s, burst_s) == _env_ref(float(t), taper_s, burst_s), t
    # overlapping tapers (0.75 of a 1.0 s burst): at t = burst - taper the rise, not the fall
    if taper_s == 0.75:
        assert math.isclose(K._env(0.25, 0.75, 1.0), 0.25, rel_tol=1e-12)
        assert K._env(0.75, 0.75, 1.0) == 0.5 - 0.5 * math.cos(math.pi * 0.25 / 0.75)
    if taper_s == 0.0:
        assert K._env(0.0, 0.0, 1.0) == 1.0 and K._env(1.0, 0.0, 1.0) == 1.0
        assert K._env(-1e-12, 0.0, 1.0) == 0.0 and K._env(1.0 + 1e-12, 0.0, 1.0) == 0.0


def test_fir_equals_numpy_convolve_at_any_output_range():
    rng = np.random.default_rng(RNG_SEED + 3)
    worst = 0.0
    for _ in range(150):
        n = int(rng.integers(1, 300))
        n_h = int(rng.integers(0, 40))
        x = rng.standard_normal(n)
        h = rng.standard_normal(n_h)
        half = int(rng.integers(0, max(n_h, 1)))
        start = int(rng.integers(-60, n + 20))
        count = int(rng.integers(0, 120))
        got = K.call("fir", x, np.ascontiguousarray(h[::-1]), half, start, count)
        assert got.shape == (count,) and got.dtype == np.float64
        if n_h == 0:  # no conditioning: the raw samples, zero outside x
            ref = np.array([x[start + j] if 0 <= start + j < n else 0.0 for j in range(count)])
            np.testing.assert_array_equal(got, ref)
            continue
        full = np.convolve(x, h)
        idx = start + np.arange(count) + half
        inside = (idx >= 0) & (idx < len(full))
        ref = np.where(inside, full[np.clip(idx, 0, len(full) - 1)], 0.0)
        worst = max(worst, float(np.max(np.abs(got - ref), initial=0.0)))
    assert worst < 2e-14  # measured 7.1e-15 (sums of 40 products of unit normals)


def test_widen_equals_scipy_maximum_filter():
    rng = np.random.default_rng(RNG_SEED + 4)
    for _ in range(200):
        n = int(rng.integers(1, 60))
        f = rng.integers(0, 5, n).astype(float) * rng.uniform(0.1, 3.0)  # ties, zeros
        half = int(rng.integers(0, 70))
        out = np.full(n, np.nan)
        K._widen_py(f, half, out)
        ref = maximum_filter1d(f, 2 * half + 1, mode="constant", cval=0.0)
        np.testing.assert_array_equal(out, ref)


def test_first_edge_equals_changepoint_numpy():
    rng = np.random.default_rng(RNG_SEED + 5)
    hits = {"earlier": 0, "top": 0}
    for _ in range(600):
        n = int(rng.integers(3, 40))
        stat = rng.integers(0, 6, n).astype(float)  # plateaus and ties
        frac = float(rng.choice([0.0, 0.1, 0.5, 1.0]))
        floor = float(rng.choice([0.0, 2.0, 4.0, 5.0]))
        sep = int(rng.integers(0, 8))
        got = K._first_edge_py(stat, frac, floor, sep)
        ref = cp._first_edge(stat, frac, floor, sep=sep)
        assert got == ref, (stat, frac, floor, sep)
        hits["top" if got == int(np.argmax(stat)) else "earlier"] += 1
    assert min(hits.values()) > 38  # measured: earlier 76, top 524


def test_median_equals_numpy():
    rng = np.random.default_rng(RNG_SEED + 6)
    for _ in range(300):
        n = int(rng.integers(1, 12))
        v = rng.integers(-3, 4, n + 3).astype(float) * rng.uniform(0.5, 2.0)
        m = int(rng.integers(1, n + 1))
        assert K._median_py(v, m) == np.median(v[:m])


def test_any_in_equals_brute_force():
    rng = np.random.default_rng(RNG_SEED + 7)
    for _ in range(500):
        idx = np.unique(rng.integers(0, 50, int(rng.integers(0, 8)))).astype(np.int64)
        a, b = (int(v) for v in rng.integers(-10, 60, 2))
        ref = any(max(a, 0) <= int(i) < b for i in idx)
        assert K._any_in(idx, a, b) == ref, (idx, a, b)
    idx = np.array([5, 9], dtype=np.int64)
    assert K._any_in(idx, 5, 6) and not K._any_in(idx, 6, 9) and K._any_in(idx, 6, 10)
    assert not K._any_in(idx, -3, 5) and K._any_in(idx, -3, 6)


def test_all_finite():
    assert K.call("all_finite", np.zeros(0))
    assert K.call("all_finite", np.array([1.0, -2.0, 1e308]))
    for bad in (np.nan, np.inf, -np.inf):
        x = np.ones(5)
        x[3] = bad
        assert not K.call("all_finite", x)
        with np.errstate(invalid="ignore"):
            assert not K._all_finite_py(x)
    assert K._all_finite_py(np.array([1.0, -1e300]))


def test_pair_of_follows_triu_indices():
    for m in range(2, 9):
        ii, jj = np.triu_indices(m, 1)
        for c in range(len(ii)):
            assert K._pair_of(c, m) == (ii[c], jj[c])


def test_drift_half_width():
    """max(2, ceil(MAX_DRIFT spacing |k - (k_b - 1) / 2|)); MAX_DRIFT is 200 ppm."""
    assert K.MAX_DRIFT == 2e-4
    for k_b in range(1, 9):
        for k in range(k_b):
            for spacing in (0.0, 5000.0, 20000.0, 44100.0, 100000.0, 1e6):
                d = 2e-4 * spacing * abs(k - (k_b - 1) / 2.0)
                assert K._drift_half_py(k, k_b, spacing) == max(2, math.ceil(d))
    # 200 ppm of 12500 samples is 2.5 a burst: burst 0 of 4 is 1.5 bursts from the middle
    assert K._drift_half_py(0, 4, 12500.0) == 4  # ceil(3.75)
    assert K._drift_half_py(0, 4, 10000.0) == 3  # exactly 3.0: not rounded up
    assert K._drift_half_py(0, 4, 10001.0) == 4


def _better_ref(n, cost, mean, n_best, cost_best, mean_best):
    if n > n_best:
        return True
    if n < n_best:
        return False
    if cost < cost_best - 1e-9:
        return True
    if cost > cost_best + 1e-9:
        return False
    return mean < mean_best


def test_better_line_ranks_bursts_then_cost_then_the_earlier_mean():
    rng = np.random.default_rng(RNG_SEED + 8)
    for _ in range(2000):
        n, nb = (int(v) for v in rng.integers(2, 5, 2))
        cb = float(rng.uniform(0, 2))
        c = float(cb + rng.choice([0.0, 2e-9, -2e-9, 5e-10, -5e-10, 0.3, -0.3]))
        mb = float(rng.integers(0, 3))
        mn = float(rng.integers(0, 3))
        assert K._better_line(n, c, mn, nb, cb, mb) == _better_ref(n, c, mn, nb, cb, mb)


def test_drift_line_equals_weighted_least_squares():
    rng = np.random.default_rng(RNG_SEED + 9)
    clamped = 0
    for _ in range(300):
        m = int(rng.integers(1, 9))
        ks = np.sort(rng.choice(12, m, replace=False)).astype(np.int64)
        est = rng.normal(100.0, 2.0, m) + ks * rng.normal(0, 1.0)
        w = rng.uniform(0.1, 10.0, m)
        members = rng.random(m) < 0.7
        lim = float(rng.choice([0.5, 1.0, 100.0]))
        mean, slope, kbar = K._drift_line_py(ks, est, w, members, m, lim)
        sel = members
        if not sel.any():
            assert (mean, slope, kbar) == (math.inf, 0.0, 0.0)
            continue
        ww, kk, ee = w[sel], ks[sel].astype(float), est[sel]
        kb = np.sum(ww * kk) / np.sum(ww)
        mu = np.sum(ww * ee) / np.sum(ww)
        if sel.sum() > 1:
            # weighted least squares through (kk, ee): the slope of numpy's lstsq
            a = np.stack([np.ones_like(kk), kk - kb], axis=1) * np.sqrt(ww)[:, None]
            sl = np.linalg.lstsq(a, ee * np.sqrt(ww), rcond=None)[0][1]
        else:
            sl = 0.0
        clamped += abs(sl) > lim
        assert math.isclose(kbar, kb, rel_tol=1e-12, abs_tol=1e-12)
        assert math.isclose(mean, mu, rel_tol=1e-12)
        assert math.isclose(slope, float(np.clip(sl, -lim, lim)), rel_tol=1e-9, abs_tol=1e-11)
    assert 42 < clamped < 170  # measured 85


def test_fit_summary_closed_form():
    rng = np.random.default_rng(RNG_SEED + 10)
    for _ in range(200):
        m = int(rng.integers(1, 60))
        n_cols = int(rng.integers(0, 5))
        r = np.array([1.0, rng.uniform(-5, 5), rng.uniform(0, 10), *rng.normal(0, 1, 2), 0.0])
        r[5] = float(rng.choice([0.0, rng.uniform(0.1, 100.0)]))
        tau, sigma, snr = K._fit_summary(r, m, n_cols)
        nv = max(r[2] / max(m - n_cols - 1, 1), 1e-30)
        amp2 = r[3] ** 2 + r[4] ** 2
        assert tau == r[1]
        if r[5] == 0.0:
            assert sigma == math.inf
        else:
            assert math.isclose(sigma, math.sqrt(nv / r[5]), rel_tol=1e-12)
        assert math.isclose(snr, 10 * math.log10(max(amp2 / 2 / nv, 1e-30)), abs_tol=1e-9)
    # no residual: the noise floor 1e-30; no amplitude: the SNR floor -300 dB
    _, s, snr = K._fit_summary(np.array([1.0, 0.0, 0.0, 1.0, 0.0, 4.0]), 10, 2)
    assert math.isclose(s, math.sqrt(1e-30 / 4.0), rel_tol=1e-12)
    assert math.isclose(snr, 10 * math.log10(0.5e30), rel_tol=1e-12)
    _, _, snr = K._fit_summary(np.array([1.0, 0.0, 7.0, 0.0, 0.0, 4.0]), 10, 2)
    assert snr == -300.0


def _dedupe_ref(starts, rising, min_rise, hop):
    kept = []
    for a, r in zip(starts.tolist(), rising.tolist(), strict=True):
        if r < min_rise:
            continue
        if all(abs(a - b) > hop for b in kept[-8:]):
            kept.append(a)
    return kept


def test_dedupe_keeps_rising_starts_apart_from_the_last_eight_kept():
    rng = np.random.default_rng(RNG_SEED + 11)
    for _ in range(300):
        n = int(rng.integers(0, 30))
        starts = np.sort(rng.integers(0, 200, n)).astype(np.int64)
        if rng.random() < 0.3:  # far apart but unsorted: beyond the last 8 kept
            starts = rng.permutation(np.arange(n, dtype=np.int64) * 40)
        rising = rng.integers(0, 5, n).astype(np.int64)
        min_rise, hop = int(rng.integers(0, 4)), int(rng.integers(0, 12))
        got = K.call("dedupe", starts, rising, min_rise, hop)
        assert got.tolist() == _dedupe_ref(starts, rising, min_rise, hop)
    # the window is the last 8 kept: a ninth-back duplicate is kept again
    starts = np.array([0, 100, 200, 300, 400, 500, 600, 700, 800, 5, 700], dtype=np.int64)
    got = K.call("dedupe", starts, np.ones(11, dtype=np.int64), 1, 10)
    assert got.tolist() == [0, 100, 200, 300, 400, 500, 600, 700, 800, 5]
    got = K.call("dedupe", np.array([0, 10, 11], dtype=np.int64), np.ones(3, dtype=np.int64), 1, 10)
    assert got.tolist() == [0, 11]  # 10 apart is a duplicate at hop 10, 11 is not


def test_change_points_equal_changepoint_numpy():
    rng = np.random.default_rng(RNG_SEED + 12)
    n_cp = 0
    for _ in range(60):
        n = int(rng.integers(1, 900))
        e = rng.exponential(1.0, n) * 10.0 ** rng.uniform(-3, 3)
        for _ in range(int(rng.integers(0, 5))):  # steps, some in two stages
            a = int(rng.integers(0, n))
            e[a : a + int(rng.integers(1, 80))] *= float(rng.choice([3.0, 30.0, 300.0]))
        floor = rng.uniform(0.1, 2.0, n) * np.median(e)
        if rng.random() < 0.2:
            floor[:] = 0.0
        n_win, hop = int(rng.choice([128, 256, 64])), int(rng.choice([32, 64]))
        thr_db, rise_db, lb = (
            float(rng.uniform(3, 12)),
            float(rng.uniform(3, 12)),
            int(rng.integers(0, 3)),
        )
        ref = cp._change_points(
            e, n_win=n_win, hop=hop, threshold_db=thr_db, rise_db=rise_db, floor=floor, lookback=lb
        )
        w = int(math.ceil(n_win / hop))
        got = K.call(
            "change_points", e, floor, w + lb, 8, 10 ** (thr_db / 10), 10 ** (rise_db / 10), w
        )
        np.testing.assert_array_equal(got, ref)
        n_cp += len(ref)
    assert n_cp > 325  # measured 650


# ---------------------------------------------------------------- F statistics


def _bases(rng, length, n_par):
    cols = rng.standard_normal((length, n_par))
    qf, _ = np.linalg.qr(cols)
    n_base = n_par - 2
    qb = np.linalg.qr(cols[:, 2:])[0] if n_base > 0 else np.zeros((length, 0))
    return cols, np.ascontiguousarray(np.vstack([qf.T, qb.T])), n_base


def _f_ref(win, cols):
    length, p = cols.shape
    total = win @ win
    full = total - np.sum((win - cols @ np.linalg.lstsq(cols, win, rcond=None)[0]) ** 2)
    base = 0.0
    if p > 2:
        nb = cols[:, 2:]
        base = total - np.sum((win - nb @ np.linalg.lstsq(nb, win, rcond=None)[0]) ** 2)
    resid = max(total - full, 1e-12 * total + 1e-300) / (length - p)
    return max(full - base, 0.0) / 2.0 / resid


def test_edge_statistic_equals_least_squares_projections():
    rng = np.random.default_rng(RNG_SEED + 13)
    worst = 0.0
    for _ in range(40):
        length, n_par = int(rng.integers(8, 40)), int(rng.choice([2, 4, 6]))
        cols, qt, n_base = _bases(rng, length, n_par)
        n_out = int(rng.integers(0, 30))
        seg = rng.standard_normal(n_out + length - 1)
        for i in range(0, n_out, 3):  # an edge in some windows
            seg[i : i + length] += cols[:, :2] @ rng.normal(0, 3, 2)
        got = K.call("edge_stat", seg, qt, n_base, n_par)
        assert got.shape == (n_out,)
        ref = np.array([_f_ref(seg[i : i + length], cols) for i in range(n_out)])
        if n_out:
            worst = max(worst, float(np.max(np.abs(got - ref) / np.maximum(ref, 1.0))))
    assert worst < 8e-14  # measured 2.6e-14
    # a window shorter than the basis: no output
    cols, qt, n_base = _bases(rng, 20, 4)
    assert K.call("edge_stat", np.ones(19), qt, n_base, 4).shape == (0,)


def test_edge_statistic_of_an_exact_fit_uses_the_residual_floor():
    """A window in the model's span: residual 1e-12 of the energy (not 0) sets F."""
    rng = np.random.default_rng(3)
    length = 24
    cols, qt, n_base = _bases(rng, length, 4)
    win = cols @ np.array([2.0, -1.0, 0.0, 0.0])  # edge columns only: base ~ small
    got = K.call("edge_stat", win, qt, n_base, 4)[0]
    total = win @ win
    base = total - np.sum(
        (win - cols[:, 2:] @ np.linalg.lstsq(cols[:, 2:], win, rcond=None)[0]) ** 2
    )
    ref = (total - base) / 2.0 / (1e-12 * total / (length - 4))
    assert math.isclose(got, ref, rel_tol=3e-15)  # measured 8e-16 (F 9.7e12)
    assert K.call("edge_stat", np.zeros(length + 2), qt, n_base, 4).tolist() == [0.0] * 3


def _masked_ref(seg, keep, cols):
    length, p = cols.shape
    out = []
    for i in range(len(seg) - length + 1):
        k = keep[i : i + length] > 0
        y, a = seg[i : i + length][k], cols[k]
        total = y @ y

        def explained(b, y=y):
            gram = b.T @ b
            r = 1e-12 * np.trace(gram) / b.shape[1] + 1e-300
            g = b.T @ y
            return g @ np.linalg.solve(gram + r * np.eye(b.shape[1]), g)

        full = explained(a)
        base = explained(a[:, 2:]) if p > 2 else 0.0
        dof = k.sum() - p
        resid = max(total - full, 1e-12 * total + 1e-300) / max(dof, 1.0)
        f = max(full - base, 0.0) / 2.0 / resid
        out.append(f if dof >= 8 else 0.0)
    return np.array(out)


@pytest.mark.parametrize("p", [2, 4, 6])
def test_masked_statistic_equals_least_squares_and_needs_eight_degrees_of_freedom(p):
    rng = np.random.default_rng(RNG_SEED + 14 + p)
    length = 10 + p
    sides = {"below": 0, "above": 0}
    worst = 0.0
    for _ in range(25):
        cols = rng.standard_normal((length, p))
        seg = rng.standard_normal(length + 20)
        seg[5 : 5 + length] += cols[:, :2] @ np.array([3.0, 1.0])
        keep = (rng.random(len(seg)) > rng.uniform(0.0, 0.3)).astype(float)
        got, ok = K.call("masked_stat", seg, keep, np.ascontiguousarray(cols))
        assert ok
        ref = _masked_ref(seg, keep, cols)
        worst = max(worst, float(np.max(np.abs(got - ref) / np.maximum(ref, 1.0))))
        for i in range(len(ref)):
            dof = keep[i : i + length].sum() - p
            sides["below" if dof < 8 else "above"] += 1
            if dof == 7:
                assert got[i] == 0.0
    assert worst < 1e-13  # measured 3.6e-14 (p = 4; 1.9e-14, 1.5e-14 at p = 2, 6)
    assert (
        min(sides.values()) > 80
    )  # both sides of 8 degrees of freedom: measured 161 below (p = 2)
    cols = rng.standard_normal((length, p))
    cols[3, 0] = np.nan  # the normal equations are not positive definite
    _, ok = K.call("masked_stat", rng.standard_normal(length + 4), np.ones(length + 4), cols)
    assert not ok


# ---------------------------------------------------------------- stage 2 (refine)

FS = 44100.0
TAPER_S, BURST_S = 22 / FS, 441 / FS
W = 2 * math.pi * 16000.0 / FS


def _env_vec(t):
    return np.array([_env_ref(float(v), TAPER_S, BURST_S) for v in t])


def _fit_ref(tau, seg, n, nuis):
    e = _env_vec((n - tau) / FS)
    b = np.column_stack([e * np.sin(W * n), e * np.cos(W * n), nuis])
    gram = b.T @ b
    p = b.shape[1]
    r = 1e-12 * np.trace(gram) / p + 1e-300
    g = b.T @ seg
    coef = np.linalg.solve(gram + r * np.eye(p), g)
    return seg @ seg - g @ coef, coef, b


def _refine_ref(seg, n, nuis, a, h, n_coarse, n_fine):
    """refine_onset's stage 2 restated: coarse grid, fine grid between the coarse
    minimum's neighbours, parabola through the fine minimum and its neighbours (vertex
    held within one fine step), rss and amplitudes there, and the Fisher information of
    the onset (the derivative's part orthogonal to the model's columns)."""
    grid = np.linspace(a - h, a + h, n_coarse)
    j = int(np.argmin([_fit_ref(t, seg, n, nuis)[0] for t in grid]))
    fine = np.linspace(grid[max(j - 1, 0)], grid[min(j + 1, n_coarse - 1)], n_fine)
    rf = np.array([_fit_ref(t, seg, n, nuis)[0] for t in fine])
    m = min(max(int(np.argmin(rf)), 1), n_fine - 2)
    y0, y1, y2 = rf[m - 1 : m + 2]
    den = y0 - 2 * y1 + y2
    vertex = float(np.clip(0.5 * (y0 - y2) / den, -1.0, 1.0)) if den > 0 else 0.0
    tau = fine[m] + vertex * (fine[1] - fine[0])
    rss, coef, b = _fit_ref(tau, seg, n, nuis)
    eps = 1e-3
    de = (_env_vec((n - tau - eps) / FS) - _env_vec((n - tau + eps) / FS)) / (2 * eps)
    dm = de * (np.sin(W * n) * coef[0] + np.cos(W * n) * coef[1])
    perp = dm - b @ np.linalg.lstsq(b, dm, rcond=None)[0]
    return tau, max(rss, 0.0), coef[0], coef[1], perp @ perp


def _stage2_case(rng, pn, true, offset):
    length = int(rng.integers(60, 120))
    n = np.arange(length, dtype=float) + float(rng.integers(0, 1000))
    t0 = n[0] + true
    amp = float(rng.choice([1.0, 0.1]))
    seg = amp * _env_vec((n - t0) / FS) * np.sin(W * n + rng.uniform(0, 6.28))
    ramp = (n - n[0]) / (n[-1] - n[0]) - 0.5
    background, dc = [np.sin(W * n), np.cos(W * n)], [np.ones(length), ramp]
    if pn == 4:
        cols = background + dc
    elif pn == 2:  # the background tone or a constant and slope
        cols = dc if rng.random() < 0.5 else background
    else:
        cols = []
    nuis = np.column_stack(cols) if cols else np.zeros((length, 0))
    seg = seg + 0.01 * rng.standard_normal(length)
    if pn:
        seg = seg + nuis @ rng.normal(0, 0.05, pn)
    return seg, n, np.ascontiguousarray(nuis), t0 + offset


@pytest.mark.parametrize("pn", [0, 2, 4])
def test_refine_kernel_equals_a_least_squares_restatement(pn):
    rng = np.random.default_rng(RNG_SEED + 20 + pn)
    worst = {"tau": 0.0, "rss": 0.0, "coef": 0.0, "perp2": 0.0}
    for i in range(6):
        # the start near the onset, or beyond the coarse grid's end (its minimum at an end)
        offset = [0.4, -1.3, 2.2, 6.0, -6.0, 0.0][i]
        seg, n, nuis, a = _stage2_case(rng, pn, float(rng.uniform(15, 30)), offset)
        h, n_c, n_f = 3.0, int(rng.choice([5, 13])), int(rng.choice([5, 13]))
        res = K.call(
            "refine", seg, n, nuis, np.sin(W * n), np.cos(W * n), float(seg @ seg), a, h,
            n_c, n_f, FS, TAPER_S, BURST_S,
        )  # fmt: skip
        assert res[0] == 1.0
        tau, rss, c0, c1, perp2 = _refine_ref(seg, n, nuis, a, h, n_c, n_f)
        worst["tau"] = max(worst["tau"], abs(res[1] - tau))
        worst["rss"] = max(worst["rss"], abs(res[2] - rss) / rss)
        worst["coef"] = max(worst["coef"], abs(res[3] - c0) + abs(res[4] - c1))
        worst["perp2"] = max(worst["perp2"], abs(res[5] - perp2) / perp2)
    assert worst["tau"] < 3e-11  # measured 1.0e-11 samples (pn = 4; 1.3e-12, 4.5e-13)
    assert worst["rss"] < 1e-11  # measured 3.6e-12
    assert worst["coef"] < 4e-14  # measured 1.5e-14
    assert worst["perp2"] < 1.5e-10  # measured 4.8e-11 (central differences summed apart)


def test_refine_kernel_reports_a_system_not_positive_definite():
    n = np.arange(80, dtype=float)
    z = np.zeros(80)
    args = (z, n, np.zeros((80, 0)), np.sin(W * n), np.cos(W * n), 0.0, 40.0, 3.0, 13, 13)
    res = K.call("refine", *args, FS, TAPER_S, BURST_S)
    assert res[0] == 1.0  # all zero: the regularised fits are fine (rss 0) ...
    nan_nuis = np.full((80, 2), np.nan)
    res = K.call("refine", z, n, nan_nuis, *args[3:], FS, TAPER_S, BURST_S)
    assert res.tolist() == [0.0] * 6  # ... a NaN column is not


def test_fit_tau_residual_equals_least_squares():
    rng = np.random.default_rng(RNG_SEED + 30)
    worst = 0.0
    for pn in (0, 2, 4):
        for _ in range(8):
            seg, n, nuis, a = _stage2_case(rng, pn, float(rng.uniform(15, 30)), 0.0)
            p = 2 + pn
            nb, ng = nuis.T @ nuis, nuis.T @ seg
            coef = np.zeros(p)
            for tau in (a, a + 0.37, n[0] - 5.0, n[-1] - 3.0):
                r, ok = K._fit_tau(
                    tau, seg, n, nuis, np.sin(W * n), np.cos(W * n), float(seg @ seg), FS,
                    TAPER_S, BURST_S, np.tril(nb), ng, np.zeros((p, p)), np.zeros(p),
                    np.zeros((p, p)), coef,
                )  # fmt: skip
                ref, ref_coef, _ = _fit_ref(tau, seg, n, nuis)
                assert ok
                worst = max(worst, abs(r - ref) / (seg @ seg))
                np.testing.assert_allclose(coef, ref_coef, rtol=1e-6, atol=1e-9)
    assert worst < 4e-15  # measured 1.3e-15


# ---------------------------------------------------------------- anchors, combine


def test_anchor_kernel_equals_changepoint_on_random_beeps():
    from rangekit.signals import Beep

    rng = np.random.default_rng(RNG_SEED + 40)
    n_rising = np.zeros(8, dtype=int)
    for _ in range(12):
        k_b = int(rng.integers(2, 6))
        beep = Beep(n_bursts=k_b, spacing=int(rng.choice([2205, 5000, 3001])))
        hop, n_win = int(rng.choice([32, 64])), 128
        n_e = 6000
        e = rng.exponential(1.0, n_e) * 10.0 ** rng.uniform(-6, 2)
        sp = beep.spacing_s * FS / hop
        starts = []
        for _ in range(3):
            f0 = int(rng.integers(50, n_e - 400))
            starts.append(f0)
            for k in range(k_b):
                if rng.random() < 0.8:  # some bursts missing
                    a = int(f0 + k * sp)
                    e[a : a + 13] *= float(rng.choice([1.5, 3.0, 10.0, 1000.0]))
        e[rng.integers(0, n_e, 20)] = 0.0  # empty frames: a plateau of no energy
        cs = np.concatenate(([0.0], np.cumsum(e)))
        c = np.concatenate(
            [
                rng.integers(-200, n_e * hop + 200, 40),
                np.array([(s + int(k * sp)) * hop for s in starts for k in range(k_b)]),
            ]
        ).astype(np.int64)
        kw = dict(hop=hop, n_win=n_win, beep=beep, fs=FS)
        got = cp._anchors_compiled(c, cs, n_e, **kw)
        ref = [cp._anchor(int(v), e, spacing=beep.spacing_s * FS, cs=cs, **kw) for v in c]
        assert got == ref
        for _, r in ref:
            n_rising[r] += 1
    # from no rising burst place to all five: measured [75, 180, 176, 108, 75, 10]
    assert (n_rising[:5] > 37).all() and n_rising[5] > 4


def _combine_case(rng):
    from rangekit.detect.refine import EdgeFit

    k_b = int(rng.integers(2, 8))
    spacing = float(rng.choice([5000.0, 22050.0, 44100.0]))
    ppm = rng.uniform(-300, 300)
    sg = np.exp(rng.uniform(np.log(1e-4), np.log(3.0), k_b))
    on = 1000.0 + np.arange(k_b) * spacing * (1 + ppm * 1e-6) + sg * rng.standard_normal(k_b)
    for k in rng.choice(k_b, size=int(rng.integers(0, 3)), replace=False):
        on[k] += float(rng.choice([-1, 1]) * rng.uniform(1, 20))
    for k in rng.choice(k_b, size=int(rng.integers(0, 2)), replace=False):
        sg[k] = float(rng.choice([np.nan, np.inf, 2e6, 1e-5]))  # failed or clamped sigmas
    snr = rng.integers(0, 40, k_b).astype(float)
    fst = rng.uniform(10, 1000, k_b)
    fits = [
        EdgeFit(onset=float(on[k]), sigma=float(sg[k]), snr_db=float(snr[k]), amplitude=1.0,
                f_stat=float(fst[k]))
        for k in range(k_b)
    ]  # fmt: skip
    for k in rng.choice(k_b, size=int(rng.integers(0, 2)), replace=False):
        fits[k] = None
    return fits, spacing, float(rng.choice([0.5, 1.0, 2.0])), int(rng.integers(1, 4))


def test_combine_kernel_equals_changepoint_in_every_output():
    """Onset, sigma, median SNR, confidence, burst count, strength and the kept bursts'
    onsets, with failed (NaN, infinite), huge and tiny sigmas, scales 0.5-2."""
    rng = np.random.default_rng(RNG_SEED + 41)
    counts = {"none": 0, "partial": 0, "full": 0}
    for _ in range(300):
        fits, spacing, scale, mb = _combine_case(rng)
        k_b = len(fits)
        ref = cp._combine(fits, [False] * k_b, spacing=spacing, scale=scale, min_bursts=mb)
        have = np.array([f is not None for f in fits])
        on = np.array([f.onset if f else np.nan for f in fits])
        sg = np.array([f.sigma if f else np.inf for f in fits])
        snr = np.array([f.snr_db if f else 0.0 for f in fits])
        fst = np.array([f.f_stat if f else 0.0 for f in fits])
        res, row = np.zeros(6), np.zeros(k_b)
        ok = K._combine_py(on, sg, snr, fst, have, spacing, scale, mb, cp.MODEL_SIGMA, res, row)
        assert ok == (ref is not None)
        if ref is None:
            counts["none"] += 1
            continue
        t0, s0, snr_db, conf, burst_on, _, strength = ref
        # the same operations; compiled, sigma's last bit differs (measured 1.1e-16)
        assert (res[0], res[2], res[3], res[5]) == (t0, snr_db, conf, strength)
        assert abs(res[1] - s0) <= 3e-16 * s0
        assert res[4] == int(np.sum(np.isfinite(burst_on)))
        np.testing.assert_array_equal(row, burst_on)
        counts["full" if conf == 1.0 else "partial"] += 1
    assert min(counts.values()) > 29, counts  # measured: none 58, partial 176, full 66


def _flags(e, *, rise=1.0, rise_last=1.0, reverb=2.0, quiet=0.5, guard=0.0):
    # onset frame 100 (t0 - n_win = 100 hops), near 20: far frames 60-79, near 80-99
    return K._onset_flags_py(
        e, 100 * 32 + 128.0, 32, 128, 20, 4, rise, quiet, reverb, 3, guard, rise_last, 0.0, 1
    )


def test_onset_flags_at_their_exact_ties_and_guards():
    """changepoint._before_onset_flags' rules, each strict: the near run's mean over the
    far level (``> rise``), the last frames over the level (``> rise_last``), the far
    level over the quiet level (``> reverb_ratio``); none where the far level or the
    quiet level is 0. Powers of two, so each tie is exact."""
    e = np.ones(200)
    assert _flags(e) == 0  # all three exactly at their thresholds
    assert _flags(e, rise=0.5, rise_last=2.0) == 1
    assert _flags(e, rise=2.0, rise_last=0.5) == 1
    assert _flags(e, reverb=1.0) == 2
    assert _flags(e, reverb=0.5, quiet=0.0) == 0  # no quiet level: no reverberation flag
    z = e.copy()
    z[60:80] = 0.0  # no far level (and no level before the last frames)
    assert _flags(z, rise=1.0, rise_last=0.5) == 0
    z[60] = 1.0  # a far level of 1/20: the near run's 1 is 20 times it
    assert _flags(z, rise=16.0, rise_last=64.0) == 1
    assert _flags(z, rise=32.0, rise_last=64.0) == 0
    # the last frames: frames 98-100 (n_last 3) over the level; guard 32 moves them to 97-99
    w = e.copy()
    w[100] = 4.0
    assert _flags(w, rise=64.0, rise_last=2.0) == 1
    assert _flags(w, rise=64.0, rise_last=2.0, guard=32.0) == 0
    w[97] = 4.0
    assert _flags(w, rise=64.0, rise_last=2.0, guard=32.0) == 1  # any of the frames
    # too early for the far frames (they would start before frame 0): nothing
    for frame, want in ((39, 0), (40, 3)):
        t0 = frame * 32 + 128.0
        got = K._onset_flags_py(e, t0, 32, 128, 20, 4, 0.5, 0.5, 1.0, 3, 0.0, 0.5, 0.0, 1)
        assert got == want


# ---------------------------------------------------------------- the whole loop (_beeps_py)


def _both(x, monkeypatch, **det):
    """The numpy detector's arrivals, the compiled loop's (forced on a short recording),
    and how many anchors the loop left to the reference (``changepoint._beep_row``)."""
    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 10**12)
    ref = cp.detect_changepoint(x, **det)
    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 0)
    left = []
    real = cp._beep_row
    monkeypatch.setattr(cp, "_beep_row", lambda *a, **k: left.append(1) or real(*a, **k))
    fast = cp.detect_changepoint(x, **det)
    monkeypatch.setattr(cp, "_beep_row", real)
    return ref, fast, len(left)


BEEP_CASES = [
    # (beep keywords, snr_db, noise, min_bursts, background, seed)
    (dict(), 3.0, "white", None, True, 0),  # low SNR: flags, missing bursts
    (dict(n_bursts=3, spacing=3001), 15.0, "pink", None, True, 1),
    (dict(n_bursts=2, spacing=2205, taper=60), 25.0, "white", 1, False, 2),
    (dict(n_bursts=5, spacing=4000, burst_len=300, taper=10), 10.0, "pink", 3, True, 3),
    (dict(fs=48000.0, spacing=5443), 20.0, "white", None, True, 4),  # scale 48/44.1
    (dict(f_hz=12000.0, n_bursts=4, spacing=2600), 0.0, "white", 2, False, 5),
]


@pytest.mark.parametrize("case", range(len(BEEP_CASES)))
def test_the_compiled_beep_loop_equals_the_numpy_detector(case, monkeypatch):
    """Other beeps (2-5 bursts, other spacings, tapers and lengths, 48 kHz, 12 kHz), pink
    noise, low SNR, min_bursts 1-3, no background tone: the compiled loop (forced on
    short recordings) gives the numpy detector's arrivals, flags and burst onsets."""
    from rangekit.signals import Beep
    from rangekit.sim import pair_devices, render_beepbeep

    kw, snr_db, noise, min_bursts, background, seed = BEEP_CASES[case]
    beep = Beep(**kw)
    sim = render_beepbeep(
        pair_devices(2.5, self_distance_m=0.1, fs=beep.fs), beep=beep, snr_db=snr_db,
        noise=noise, rng=seed,
    )  # fmt: skip
    n_found = 0
    for x in sim.recordings:
        det = dict(fs=beep.fs, beep=beep, min_bursts=min_bursts, background=background)
        ref, fast, left = _both(x, monkeypatch, **det)
        assert left == 0  # every anchor done by the compiled loop (measured 0)
        assert_same_detections(ref, fast, min_len=0)
        n_found += len(ref)
    assert n_found >= 2


@pytest.mark.parametrize("cut", [0, 30, 45, 70, 200])
def test_the_compiled_beep_loop_at_the_recordings_ends(cut, monkeypatch):
    """A beep whose last burst starts ``cut`` samples before the recording's end (its
    stretch cut short, the statistic's windows bounded by the end) and one starting at
    the recording's first samples: the compiled loop gives the numpy detector's
    arrivals."""
    from rangekit.signals import Beep, beep_waveform

    beep = Beep()
    rng = np.random.default_rng(RNG_SEED + 50 + cut)
    wave = beep_waveform(beep)
    last = (beep.n_bursts - 1) * beep.spacing
    at = [int(rng.integers(300, 900)), 25000]
    n = at[1] + last + cut
    x = 0.003 * rng.standard_normal(n)
    for a in at:
        seg = wave[: n - a]
        x[a : a + len(seg)] += 0.3 * seg
    x = x[int(rng.integers(0, 200)) :]  # the first beep near the very start
    ref, fast, left = _both(x, monkeypatch, fs=FS)
    assert left == 0  # measured 0
    assert_same_detections(ref, fast)


@pytest.mark.parametrize("shift", [-4, -3, 3, 4])
@pytest.mark.parametrize("which", [0, 3])
def test_the_compiled_beep_loop_with_a_burst_just_outside_its_search_window(
    shift, which, monkeypatch
):
    """One burst played ``shift`` samples off its place (just beyond the +-2 samples
    within which each burst is sought about the joint edge): its statistic's peak lies
    outside that window; the compiled loop picks within the window as the numpy code."""
    from rangekit.signals import Beep, beep_waveform

    beep = Beep()
    rng = np.random.default_rng(RNG_SEED + 60 + 10 * which + shift)
    one = beep_waveform(Beep(n_bursts=1))
    x = 0.002 * rng.standard_normal(30000)
    at = 4000
    for k in range(beep.n_bursts):
        a = at + k * beep.spacing + (shift if k == which else 0)
        x[a : a + len(one)] += 0.3 * one
    ref, fast, left = _both(x, monkeypatch, fs=FS, beep=beep)
    assert left == 0  # measured 0
    assert len(ref) == 1
    assert_same_detections(ref, fast)


@pytest.mark.parametrize("sigma", [0.5, 1.0, 2.0, 5.0])
def test_combine_of_two_disagreeing_bursts_keeps_the_earlier(sigma):
    """Two bursts 50 samples apart in their onset estimates (far beyond their timing
    noise), one burst enough: each alone is a line of one burst at cost 0, so the tie
    goes to the earlier mean (a burst timed on a reflection is late), whatever the
    bursts' weights 1/sigma^2 (below 1 for sigma > 1)."""
    from rangekit.detect.refine import EdgeFit

    sp = 5000.0
    for order in ([1100.0, sp + 1050.0], [1050.0, sp + 1100.0]):  # estimates 1100, 1050
        fits = [EdgeFit(onset=o, sigma=sigma, snr_db=20.0, amplitude=1.0, f_stat=50.0)
                for o in order]  # fmt: skip
        ref = cp._combine(fits, [False, False], spacing=sp, scale=1.0, min_bursts=1)
        res, row = np.zeros(6), np.zeros(2)
        ok = K._combine_py(
            np.array(order), np.full(2, sigma), np.full(2, 20.0), np.full(2, 50.0),
            np.ones(2, dtype=bool), sp, 1.0, 1, cp.MODEL_SIGMA, res, row,
        )  # fmt: skip
        assert ok and ref is not None
        assert res[0] == ref[0] == 1050.0 and res[4] == 1
        np.testing.assert_array_equal(row, ref[4])
