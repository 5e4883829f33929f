"""EKF core and RTS smoother: closed forms, numerical stability, consistency, gating."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy.stats import chi2

from rangekit.errors import InvalidParameterError
from rangekit.localize.ekf import (
    ExtendedKalmanFilter,
    chi2_gate,
    numerical_jacobian,
    predict,
    rts_smooth,
    update,
)

# --------------------------------------------------------------------------- models


def cv_model(dt: float, q: float, dim: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Constant velocity driven by white acceleration of PSD q; state [p..., v...]."""
    F1 = np.array([[1.0, dt], [0.0, 1.0]])
    Q1 = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    if dim == 1:
        return F1, Q1
    eye = np.eye(dim)
    return np.kron(F1, eye), np.kron(Q1, eye)


def h_range(x):
    r = np.hypot(x[0], x[1])
    return np.array([r]), np.array([[x[0] / r, x[1] / r, 0.0, 0.0]])


def h_bearing(x):
    r2 = x[0] ** 2 + x[1] ** 2
    return np.array([np.arctan2(x[1], x[0])]), np.array([[-x[1] / r2, x[0] / r2, 0.0, 0.0]])


def h_range_bearing(x):
    zr, Hr = h_range(x)
    zb, Hb = h_bearing(x)
    return np.concatenate([zr, zb]), np.vstack([Hr, Hb])


def wrap_residual(z, z_pred):
    y = z - z_pred
    y[1] = (y[1] + np.pi) % (2 * np.pi) - np.pi
    return y


# --------------------------------------------------------------------------- linear KF


def test_scalar_constant_matches_closed_form():
    P0, R, x0 = 4.0, 0.5, 1.0
    rng = np.random.default_rng(1)
    zs = 3.0 + np.sqrt(R) * rng.standard_normal(40)
    x, P = np.array([x0]), np.array([[P0]])
    for k, zk in enumerate(zs, start=1):
        x, P = predict(x, P, np.eye(1), np.zeros((1, 1)))
        res = update(x, P, [zk], np.eye(1), [[R]])
        x, P = res.x, res.P
        P_closed = P0 * R / (R + k * P0)
        x_closed = (x0 / P0 + zs[:k].sum() / R) / (1 / P0 + k / R)
        assert P[0, 0] == pytest.approx(P_closed, rel=1e-12)
        assert x[0] == pytest.approx(x_closed, rel=1e-12)


def test_constant_velocity_2d_matches_textbook_kf():
    rng = np.random.default_rng(2)
    F, Q = cv_model(0.1, 0.5, dim=2)
    H = np.hstack([np.eye(2), np.zeros((2, 2))])
    R = np.array([[0.04, 0.01], [0.01, 0.09]])
    x_ref = x = np.array([0.0, 0.0, 1.0, -1.0])
    P_ref = P = np.diag([1.0, 1.0, 4.0, 4.0])
    kf = ExtendedKalmanFilter(x, P)
    for _ in range(100):
        z = rng.normal(size=2)
        # textbook form with an explicit inverse
        x_ref = F @ x_ref
        P_ref = F @ P_ref @ F.T + Q
        K = P_ref @ H.T @ np.linalg.inv(H @ P_ref @ H.T + R)
        x_ref = x_ref + K @ (z - H @ x_ref)
        P_ref = (np.eye(4) - K @ H) @ P_ref
        kf.predict(F, Q)
        kf.update(z, H, R)
        np.testing.assert_allclose(kf.x, x_ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(kf.P, P_ref, rtol=1e-12, atol=1e-12)


def test_callable_models_equal_matrix_models():
    F, Q = cv_model(0.5, 0.1)
    H = np.array([[1.0, 0.0]])
    x, P = np.array([1.0, 2.0]), np.diag([2.0, 3.0])
    xa, Pa = predict(x, P, F, Q)
    xb, Pb = predict(x, P, lambda s: (F @ s, F), Q)
    np.testing.assert_array_equal(xa, xb)
    np.testing.assert_array_equal(Pa, Pb)
    ra = update(xa, Pa, [2.5], H, [[0.3]])
    rb = update(xa, Pa, [2.5], lambda s: (H @ s, H), [[0.3]])
    np.testing.assert_array_equal(ra.x, rb.x)
    np.testing.assert_array_equal(ra.P, rb.P)


def test_inputs_are_not_modified():
    x, P = np.array([1.0, 2.0]), np.eye(2)
    x0, P0 = x.copy(), P.copy()
    predict(x, P, np.eye(2), np.eye(2))
    update(x, P, [0.0], np.array([[1.0, 0.0]]), [[1.0]])
    np.testing.assert_array_equal(x, x0)
    np.testing.assert_array_equal(P, P0)


# --------------------------------------------------------------------------- Joseph form


def _is_spd(P: np.ndarray) -> bool:
    if not np.array_equal(P, P.T):
        return False
    try:
        np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        return False
    return True


def test_joseph_form_keeps_p_positive_definite_where_naive_form_fails():
    F, Q = cv_model(1.0, 1e-6)
    H = np.array([[1.0, 0.0]])
    R = np.array([[1e-12]])
    rng = np.random.default_rng(3)
    zs = rng.normal(size=10_000)

    # naive covariance update P = (I - K H) P loses symmetry / definiteness
    P = np.diag([1e6, 1e6])
    naive_ok = True
    for _ in range(200):
        P = F @ P @ F.T + Q
        K = P @ H.T / (H @ P @ H.T + R)
        P = (np.eye(2) - K @ H) @ P
        naive_ok &= _is_spd(P)
    assert not naive_ok, "the naive form was expected to lose positive definiteness"

    x, P = np.zeros(2), np.diag([1e6, 1e6])
    for z in zs:
        x, P = predict(x, P, F, Q)
        res = update(x, P, [z], H, R)
        x, P = res.x, res.P
        assert _is_spd(P)
    assert np.all(np.linalg.eigvalsh(P) > 0)


# --------------------------------------------------------------------------- consistency


def _monte_carlo_nees(r_scale: float, n_runs: int = 200, n_steps: int = 50, seed: int = 4):
    """Average NEES and NIS per step of a CV target seen by a range-bearing sensor.

    The filter assumes R * r_scale while the truth uses R.
    """
    rng = np.random.default_rng(seed)
    F, Q = cv_model(1.0, 0.01, dim=2)
    R = np.diag([0.2**2, 0.01**2])
    m0 = np.array([30.0, 20.0, 1.0, -0.5])
    P0 = np.diag([1.0, 1.0, 0.25, 0.25])
    Lq, Lr, L0 = (np.linalg.cholesky(M) for M in (Q, R, P0))
    nees = np.empty((n_runs, n_steps))
    nis = np.empty((n_runs, n_steps))
    for i in range(n_runs):
        truth = m0 + L0 @ rng.standard_normal(4)
        x, P = m0, P0
        for k in range(n_steps):
            truth = F @ truth + Lq @ rng.standard_normal(4)
            z = h_range_bearing(truth)[0] + Lr @ rng.standard_normal(2)
            x, P = predict(x, P, F, Q)
            res = update(x, P, z, h_range_bearing, R * r_scale, residual=wrap_residual)
            x, P = res.x, res.P
            e = truth - x
            nees[i, k] = e @ np.linalg.solve(P, e)
            nis[i, k] = res.nis
    return nees.mean(axis=0), nis.mean(axis=0)


def _band(dof: int, n_runs: int) -> tuple[float, float]:
    lo, hi = chi2.ppf([0.025, 0.975], dof * n_runs) / n_runs
    return float(lo), float(hi)


def test_nees_and_nis_consistent_over_monte_carlo():
    n_runs = 200
    anees, anis = _monte_carlo_nees(1.0, n_runs=n_runs)
    lo, hi = _band(4, n_runs)
    inside = np.mean((anees >= lo) & (anees <= hi))
    assert inside >= 0.9, (inside, anees)
    assert lo <= anees.mean() <= hi
    lo2, hi2 = _band(2, n_runs)
    assert np.mean((anis >= lo2) & (anis <= hi2)) >= 0.9
    assert lo2 <= anis.mean() <= hi2


def test_nees_detects_an_overconfident_filter():
    """The consistency check can fail: a filter that believes R is 10x smaller does."""
    n_runs = 50
    anees, _ = _monte_carlo_nees(0.1, n_runs=n_runs, n_steps=20, seed=5)
    _lo, hi = _band(4, n_runs)
    assert anees.mean() > hi


# --------------------------------------------------------------------------- Jacobians


@pytest.mark.parametrize("h", [h_range, h_bearing, h_range_bearing])
def test_analytic_jacobians_match_finite_differences(h):
    rng = np.random.default_rng(6)
    for _ in range(20):
        x = np.concatenate([rng.uniform(-20, 20, 2), rng.normal(size=2)])
        J = numerical_jacobian(lambda s, h=h: h(s)[0], x)
        np.testing.assert_allclose(h(x)[1], J, rtol=1e-6, atol=1e-9)


def test_numerical_jacobian_detects_a_wrong_jacobian():
    x = np.array([3.0, 4.0, 0.0, 0.0])
    wrong = -h_bearing(x)[1]
    J = numerical_jacobian(lambda s: h_bearing(s)[0], x)
    assert not np.allclose(wrong, J, rtol=1e-6, atol=1e-9)


# --------------------------------------------------------------------------- gating


def test_outlier_rejected_and_logged_normal_accepted():
    x0 = np.array([10.0, 5.0, 0.0, 0.0])
    P0 = np.diag([0.1, 0.1, 1.0, 1.0])
    R = np.diag([0.1**2, 0.02**2])
    kf = ExtendedKalmanFilter(x0, P0)
    z_good = h_range_bearing(x0)[0] + np.array([0.05, 0.0])
    res = kf.update(z_good, h_range_bearing, R, gate=0.999, residual=wrap_residual, t=0.5)
    assert res.accepted and not kf.rejections
    x1, P1 = kf.x.copy(), kf.P.copy()
    S = update(x1, P1, z_good, h_range_bearing, R).S
    z_bad = h_range_bearing(x1)[0] + np.array([20 * np.sqrt(S[0, 0]), 0.0])
    res = kf.update(z_bad, h_range_bearing, R, gate=0.999, residual=wrap_residual, t=1.5)
    assert not res.accepted
    assert res.nis == pytest.approx(400.0, rel=0.05)
    np.testing.assert_array_equal(kf.x, x1)
    np.testing.assert_array_equal(kf.P, P1)
    (rej,) = kf.rejections
    assert (rej.index, rej.t) == (1, 1.5)
    assert rej.nis == res.nis
    assert rej.threshold == pytest.approx(chi2.ppf(0.999, 2))
    assert kf.n_updates == 2


def test_rejection_rate_matches_gate_probability():
    rng = np.random.default_rng(7)
    x, P = np.array([1.0, -1.0]), np.array([[2.0, 0.3], [0.3, 1.0]])
    H, R = np.eye(2), np.diag([0.5, 0.2])
    L = np.linalg.cholesky(P + R)
    n = 10_000
    zs = H @ x + (L @ rng.standard_normal((2, n))).T
    accepted = np.array([update(x, P, z, H, R, gate=0.99).accepted for z in zs])
    rate = 1.0 - accepted.mean()
    assert abs(rate - 0.01) < 4 * np.sqrt(0.01 * 0.99 / n)
    # the raw-threshold form gives the same decisions
    thr = chi2_gate(0.99, 2)
    same = [update(x, P, z, H, R, gate_nis=thr).accepted for z in zs[:500]]
    assert same == accepted[:500].tolist()


def test_residual_wraps_bearing_innovation():
    x = np.array([-10.0, 1e-3, 0.0, 0.0])  # bearing just below +pi
    P = np.diag([0.01, 0.01, 1.0, 1.0])
    R = np.diag([0.1**2, 0.01**2])
    z = np.array([10.0, -np.pi + 0.001])  # same direction, written just above -pi
    assert update(x, P, z, h_range_bearing, R, residual=wrap_residual, gate=0.999).accepted
    assert not update(x, P, z, h_range_bearing, R, gate=0.999).accepted


# --------------------------------------------------------------------------- RTS


def test_rts_equals_batch_information_solution():
    rng = np.random.default_rng(8)
    n, d = 30, 2
    F, Q = cv_model(0.5, 0.3)
    H = np.array([[1.0, 0.0]])
    R = np.array([[0.2]])
    m0, P0 = np.array([0.0, 1.0]), np.diag([1.0, 0.5])
    zs = rng.normal(size=(n, 1)) + 0.5 * np.arange(n)[:, None]

    xs_f = np.empty((n, d))
    Ps_f = np.empty((n, d, d))
    xs_p = np.empty((n, d))
    Ps_p = np.empty((n, d, d))
    x, P = m0, P0
    for k in range(n):
        if k:
            x, P = predict(x, P, F, Q)
        xs_p[k], Ps_p[k] = x, P
        res = update(x, P, zs[k], H, R)
        x, P = xs_f[k], Ps_f[k] = res.x, res.P
    xs_s, Ps_s = rts_smooth(xs_f, Ps_f, xs_p, Ps_p, np.broadcast_to(F, (n - 1, d, d)))

    # joint Gaussian over (x_0, ..., x_{n-1}) in information form
    Lam = np.zeros((n * d, n * d))
    eta = np.zeros(n * d)
    P0i, Qi, Ri = (np.linalg.inv(M) for M in (P0, Q, R))
    Lam[:d, :d] += P0i
    eta[:d] += P0i @ m0
    for k in range(n):
        s = slice(k * d, (k + 1) * d)
        Lam[s, s] += H.T @ Ri @ H
        eta[s] += H.T @ Ri @ zs[k]
        if k + 1 < n:
            t = slice((k + 1) * d, (k + 2) * d)
            Lam[s, s] += F.T @ Qi @ F
            Lam[t, t] += Qi
            Lam[s, t] -= F.T @ Qi
            Lam[t, s] -= Qi @ F
    mean = np.linalg.solve(Lam, eta).reshape(n, d)
    cov = np.linalg.inv(Lam)
    np.testing.assert_allclose(xs_s, mean, rtol=0, atol=1e-8)
    for k in range(n):
        s = slice(k * d, (k + 1) * d)
        np.testing.assert_allclose(Ps_s[k], cov[s, s], rtol=0, atol=1e-8)
    # smoothing never loses information; the last step is the filtered one
    assert np.all(np.trace(Ps_s, axis1=1, axis2=2) <= np.trace(Ps_f, axis1=1, axis2=2) + 1e-12)
    np.testing.assert_array_equal(xs_s[-1], xs_f[-1])
    assert np.trace(Ps_s[0]) < np.trace(Ps_f[0])
    # Fs with n rows (last unused) gives the same answer
    xs2, _ = rts_smooth(xs_f, Ps_f, xs_p, Ps_p, np.broadcast_to(F, (n, d, d)))
    np.testing.assert_array_equal(xs2, xs_s)


def test_rts_single_step_is_filtered():
    xs, Ps = rts_smooth([[1.0]], [[[2.0]]], [[0.0]], [[[0.0]]], np.zeros((0, 1, 1)))
    assert xs.tolist() == [[1.0]] and Ps.tolist() == [[[2.0]]]


# --------------------------------------------------------------------------- errors


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: predict([0.0, np.nan], np.eye(2), np.eye(2), np.eye(2)), "x contains NaN"),
        (lambda: predict([0.0, 0.0], np.eye(3), np.eye(2), np.eye(2)), r"P must have shape"),
        (lambda: predict([0.0], [[1.0]], [[1.0]], [[-1.0]]), "Q must be positive semi"),
        (
            lambda: predict([0.0, 0.0], [[1.0, 0.5], [0.0, 1.0]], np.eye(2), np.eye(2)),
            "P must be symmetric",
        ),
        (lambda: predict([0.0], [[1.0]], lambda x: x, [[0.0]]), "must return a tuple"),
        (lambda: update([0.0], [[1.0]], [1.0], [[1.0, 2.0]], [[1.0]]), "H must have shape"),
        (lambda: update([0.0], [[1.0]], [np.inf], [[1.0]], [[1.0]]), "z contains NaN"),
        (lambda: update([0.0], [[0.0]], [1.0], [[1.0]], [[0.0]]), "not positive definite"),
        (lambda: update([0.0], [[1.0]], [1.0], [[1.0]], 1.0, gate=1.0), "gate=1.0"),
        (lambda: update([0.0], [[1.0]], [1.0], [[1.0]], 1.0, gate_nis=-1), "gate_nis=-1"),
        (
            lambda: update([0.0], [[1.0]], [1.0], [[1.0]], 1.0, gate=0.9, gate_nis=3.0),
            "at most one",
        ),
        (lambda: ExtendedKalmanFilter([0.0], [[-1.0]]), "P must be positive semi"),
        (lambda: numerical_jacobian(np.sin, [0.0], eps=0.0), "eps=0.0"),
        (
            lambda: rts_smooth(
                np.zeros((3, 1)),
                np.ones((3, 1, 1)),
                np.zeros((3, 1)),
                np.ones((3, 1, 1)),
                np.ones((1, 1, 1)),
            ),
            "Fs must have shape",
        ),
        (
            lambda: rts_smooth(
                np.zeros((2, 1)),
                np.ones((2, 1, 1)),
                np.zeros((2, 1)),
                np.zeros((2, 1, 1)),
                np.ones((1, 1, 1)),
            ),
            r"Ps_pred\[1\] is not positive definite",
        ),
        (
            lambda: rts_smooth(
                np.zeros((2, 1)),
                np.ones((2, 1, 1)),
                np.zeros((1, 1)),
                np.ones((2, 1, 1)),
                np.ones((1, 1, 1)),
            ),
            "xs_pred must have shape",
        ),
    ],
)
def test_invalid_input_raises(call, match):
    with pytest.raises(InvalidParameterError, match=match):
        call()


def test_import_does_not_load_scipy_or_numba():
    code = (
        "import sys, rangekit.localize.ekf; "
        "print(sorted(m for m in ('scipy', 'numba') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr
