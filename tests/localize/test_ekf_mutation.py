"""EKF core: documented limits pinned one by one.

Written against the mutants of ``rangekit/localize/ekf.py`` that ``tests/localize/
test_ekf.py`` lets through (``benchmarks/mutation.py``, docs/evidence.md): the gate at its
threshold, the probability domain of ``chi2_gate``, the smoother's shape check of ``Fs``
and its projection of a non-PSD process noise, frozen results, the empty Jacobian, the
covariance checks' relative tolerance.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.localize.ekf import (
    COV_RTOL,
    ExtendedKalmanFilter,
    _psd_part,
    chi2_gate,
    numerical_jacobian,
    predict,
    rts_smooth,
    update,
)


def test_a_measurement_exactly_at_the_gate_is_accepted():
    """Rejected when NIS *exceeds* the threshold: NIS = 4 with gate_nis = 4 passes."""
    # x = 0, P = 1, H = 1, R = 3: S = 4, z = 4 gives NIS = 16 / 4 = 4 exactly
    at = update([0.0], [[1.0]], [4.0], np.eye(1), [[3.0]], gate_nis=4.0)
    assert at.nis == 4.0 and at.accepted
    above = update([0.0], [[1.0]], [4.0], np.eye(1), [[3.0]], gate_nis=np.nextafter(4.0, 0.0))
    assert not above.accepted
    kf = ExtendedKalmanFilter([0.0], [[1.0]])
    kf.update([4.0], np.eye(1), [[3.0]], gate_nis=4.0)
    assert kf.rejections == [] and kf.x.tolist() == [1.0]


def test_gate_probability_is_strictly_between_0_and_1():
    assert chi2_gate(0.5, 1) == pytest.approx(0.454936, rel=1e-5)
    assert chi2_gate(1e-9, 3) > 0.0 and chi2_gate(1 - 1e-9, 3) < 100.0
    for p in (0.0, 1.0, 1.5, -0.1):
        with pytest.raises(InvalidParameterError, match="gate="):
            chi2_gate(p, 2)
    with pytest.raises(InvalidParameterError, match="dim=0 must be >= 1"):
        chi2_gate(0.9, 0)
    assert chi2_gate(0.9, 1) < chi2_gate(0.9, 2)  # the dimension is used
    with pytest.raises(InvalidParameterError, match="at most one of gate"):
        update([0.0], [[1.0]], [1.0], np.eye(1), [[1.0]], gate=0.9, gate_nis=3.0)


def test_results_are_frozen():
    res = update([0.0], [[1.0]], [1.0], np.eye(1), [[1.0]])
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.accepted = False


def _run(n=4, d=2):
    """A consistent constant-velocity run: filtered and predicted moments, Fs."""
    F = np.array([[1.0, 1.0], [0.0, 1.0]])[:d, :d]
    Q = 0.1 * np.eye(d)
    x, P = np.zeros(d), np.eye(d)
    xf, Pf, xp, Pp = [x], [P], [x], [P]
    rng = np.random.default_rng(0)
    for _ in range(n - 1):
        x, P = predict(x, P, F, Q)
        xp.append(x)
        Pp.append(P)
        res = update(x, P, [rng.normal()], np.eye(1, d), [[0.5]])
        x, P = res.x, res.P
        xf.append(x)
        Pf.append(P)
    return np.array(xf), np.array(Pf), np.array(xp), np.array(Pp), np.array([F] * (n - 1))


def test_rts_fs_has_n_minus_1_or_n_rows_only():
    xf, Pf, xp, Pp, Fs = _run()
    a = rts_smooth(xf, Pf, xp, Pp, Fs)
    b = rts_smooth(xf, Pf, xp, Pp, np.concatenate([Fs, np.full((1, 2, 2), 7.0)]))
    np.testing.assert_array_equal(a[0], b[0])  # a last row is not used
    for bad in (Fs[:-1], np.concatenate([Fs, Fs[:2]])):
        with pytest.raises(InvalidParameterError, match=r"Fs must have shape \(3, 2, 2\)"):
            rts_smooth(xf, Pf, xp, Pp, bad)
    Fs_nan = Fs.copy()
    Fs_nan[-1, 0, 0] = np.nan
    with pytest.raises(InvalidParameterError, match="Fs contains NaN"):
        rts_smooth(xf, Pf, xp, Pp, Fs_nan)
    extra = np.concatenate([Fs, np.full((1, 2, 2), np.nan)])
    rts_smooth(xf, Pf, xp, Pp, extra)  # NaN in the unused last row is fine


def test_psd_part_projects_only_indefinite_matrices():
    M = np.array([[2.0, 0.0], [0.0, -1.0]])
    np.testing.assert_allclose(_psd_part(M), [[2.0, 0.0], [0.0, 0.0]], atol=1e-15)
    R = np.array([[np.cos(0.3), -np.sin(0.3)], [np.sin(0.3), np.cos(0.3)]])
    got = _psd_part(R @ M @ R.T)
    np.testing.assert_allclose(got, R @ np.diag([2.0, 0.0]) @ R.T, atol=1e-14)
    assert np.linalg.eigvalsh(got)[0] > -1e-14
    psd = np.array([[2.0, 1.0], [1.0, 1.0]])
    assert _psd_part(psd) is psd  # already PSD: returned as is
    zero = np.diag([0.0, 1.0])
    assert _psd_part(zero) is zero  # a zero eigenvalue is PSD
    empty = np.zeros((0, 0))
    assert _psd_part(empty) is empty


def test_rts_clips_a_process_noise_that_rounding_made_indefinite():
    """Q_k = P⁻_{k+1} - F P_k F^T slightly indefinite: the smoothed P stays PSD and
    below the filter's."""
    xf, Pf, xp, Pp, Fs = _run(n=3)
    Pp = Pp.copy()
    Pp[1] = Fs[0] @ Pf[0] @ Fs[0].T + np.diag([1e-3, -1e-9])  # Q_0 indefinite by a hair
    _, Ps = rts_smooth(xf, Pf, xp, Pp, Fs)
    for k in range(3):
        assert np.linalg.eigvalsh(Ps[k])[0] >= -1e-12
        assert np.linalg.eigvalsh(Pf[k] - Ps[k])[0] >= -1e-9


def test_numerical_jacobian_of_no_variables_is_empty_with_m_rows():
    J = numerical_jacobian(lambda p: np.array([1.0, 2.0, 3.0]), np.zeros(0))
    assert J.shape == (3, 0)


def test_numerical_jacobian_step_is_relative_above_1():
    """Step eps * max(1, |x|): exact for a quadratic whatever the scale."""
    for x0 in (0.5, 3.0, 1e6):
        J = numerical_jacobian(lambda p: p**2, [x0], eps=1e-4)
        assert J[0, 0] == pytest.approx(2 * x0, rel=1e-9)
    # a step of eps * 2 would change a cubic's central difference by 4 eps^2 x^2 more
    J = numerical_jacobian(lambda p: p**3, [0.5], eps=1e-2)
    assert J[0, 0] == pytest.approx(3 * 0.25 + 1e-4, rel=1e-9)  # f' + eps^2 (step = eps)


def test_covariance_checks_use_a_relative_tolerance():
    """Asymmetry or a negative eigenvalue up to COV_RTOL x the largest entry is rounding."""
    assert COV_RTOL == 1e-9
    P = np.array([[1e6, 0.0], [0.5e-3, 1e6]])  # 5e-4 < 1e-9 * 1e6 = 1e-3
    predict([0.0, 0.0], P, np.eye(2), np.zeros((2, 2)))
    with pytest.raises(InvalidParameterError, match="P must be symmetric"):
        predict([0.0, 0.0], np.array([[1e6, 0.0], [2e-3, 1e6]]), np.eye(2), np.zeros((2, 2)))
    Pn = np.diag([1e6, -0.5e-3])
    predict([0.0, 0.0], Pn, np.eye(2), np.zeros((2, 2)))
    with pytest.raises(InvalidParameterError, match="positive semidefinite"):
        predict([0.0, 0.0], np.diag([1e6, -2e-3]), np.eye(2), np.zeros((2, 2)))
    predict(np.zeros(0), np.zeros((0, 0)), np.zeros((0, 0)), np.zeros((0, 0)))  # empty state


def test_rejections_are_frozen():
    kf = ExtendedKalmanFilter([0.0], [[1.0]])
    kf.update([50.0], np.eye(1), [[1.0]], gate=0.99)
    with pytest.raises(dataclasses.FrozenInstanceError):
        kf.rejections[0].nis = 0.0


def test_rts_checks_every_used_prediction_row_and_not_row_0():
    """Row 0 of xs_pred / Ps_pred is unused (NaN allowed); rows 1.. must be finite."""
    xf, Pf, xp, Pp, Fs = _run()
    xp0, Pp0 = xp.copy(), Pp.copy()
    xp0[0], Pp0[0] = np.nan, np.nan
    ref = rts_smooth(xf, Pf, xp, Pp, Fs)
    got = rts_smooth(xf, Pf, xp0, Pp0, Fs)
    np.testing.assert_array_equal(got[0], ref[0])
    for name, k in (("xs_pred", 1), ("Ps_pred", 1)):
        a, b = xp.copy(), Pp.copy()
        (a if name == "xs_pred" else b)[k] = np.nan
        with pytest.raises(InvalidParameterError, match=f"{name} contains NaN"):
            rts_smooth(xf, Pf, a, b, Fs)


def test_numerical_jacobian_default_step_is_1e_6():
    def cube(p):
        return p**3

    default = numerical_jacobian(cube, [0.5])
    assert np.array_equal(default, numerical_jacobian(cube, [0.5], eps=1e-6))
    assert not np.array_equal(default, numerical_jacobian(cube, [0.5], eps=2e-6))
