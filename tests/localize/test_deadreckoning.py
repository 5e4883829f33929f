"""Dead-reckoning EKF with accelerometer-bias states (Ahn & Yu §2): bias recovery, Jacobians,
NEES consistency, log reading."""

from __future__ import annotations

import io

import numpy as np
import pytest
from scipy.stats import chi2

from rangekit.errors import InvalidParameterError, LogFormatError
from rangekit.localize.deadreckoning import (
    TRACK_COLUMNS,
    dead_reckon,
    read_imu_log,
    speed2_measurement,
    track_log,
    transition,
    world_acceleration,
)
from rangekit.localize.ekf import numerical_jacobian
from rangekit.sim.ahn2007 import imu_log_text, simulate_robot


def _run(sim, **kw):
    a = sim.accel_meas_mps2
    return dead_reckon(sim.t_s, a[:, 0], a[:, 1], sim.speed_meas_mps, **kw)


@pytest.mark.parametrize(
    "x", [[0, 0, 3.0, -4.0, 0.1, 0.2], [1, 2, 0.0, 0.0, 0, 0], [0, 0, -0.3, 2.5, 1, -1]]
)
def test_measurement_jacobian_equals_numerical(x):
    _, H = speed2_measurement(x)
    J = numerical_jacobian(lambda v: speed2_measurement(v)[0], x)
    np.testing.assert_allclose(H, J, atol=1e-8)


def test_transition_is_jacobian_of_eq7_and_bias_adds_to_measurement():
    A, B = transition(0.1)
    x = np.array([1.0, 2.0, 0.5, -0.5, 0.1, -0.2])
    u = np.array([0.3, 0.4])
    J = numerical_jacobian(lambda v: A @ v + B @ u, x)
    np.testing.assert_allclose(J, A, atol=1e-10)
    # eq (4): true acceleration = measured + δa, so δa enters like the input.
    np.testing.assert_allclose(A[:, 4:], B + np.vstack([np.zeros((4, 2)), np.eye(2)]), atol=0)


def test_world_acceleration_combines_simulated_body_output_and_heading():
    sim = simulate_robot(100, velocity0_mps=(1.0, 0.0), rng=3)
    np.testing.assert_allclose(
        world_acceleration(sim.accel_body_mps2, sim.heading_rad), sim.accel_meas_mps2, atol=1e-12
    )


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_bias_ekf_recovers_constant_bias(seed):
    bias = np.array([0.15, -0.1])
    sim = simulate_robot(600, bias0_mps2=bias, bias_rw_var=0.0, rng=seed)
    res = _run(sim)
    # over the last 30 s the estimated δa has RMS error < 0.015 m/s² and max error
    # < 0.04 m/s² per axis (bias 0.1-0.15 m/s²; the filter keeps the paper's random-walk
    # tuning, so its estimate wanders by about 0.01 m/s²).
    err = res.x[300:, 4:] - bias
    assert np.all(np.sqrt(np.mean(err**2, axis=0)) < 0.015), err
    assert np.all(np.abs(err).max(axis=0) < 0.04), err
    # ... and dead reckoning with bias states beats the four-state filter by far
    no_bias = _run(sim, bias_states=False)
    e6 = np.hypot(*(res.x[-1, :2] - sim.position_m[-1]))
    e4 = np.hypot(*(no_bias.x[-1, :2] - sim.position_m[-1]))
    assert e6 < 2.0 and e4 > 3 * e6
    assert np.all(no_bias.x[:, 4:] == 0) and np.all(no_bias.P[:, 4:, :] == 0)


def test_smoothing_improves_bias_and_keeps_shapes():
    sim = simulate_robot(400, rng=5)
    f, s = _run(sim), _run(sim, smooth=True)
    assert s.smoothed and not f.smoothed and s.x.shape == f.x.shape == (400, 6)
    ef = np.sqrt(np.mean((f.x[:, 4:] - sim.bias_mps2) ** 2))
    es = np.sqrt(np.mean((s.x[:, 4:] - sim.bias_mps2) ** 2))
    assert es < ef
    np.testing.assert_allclose(s.x[-1], f.x[-1], atol=1e-12)  # last step is not smoothed


def _anees(n_runs, second_order, accel_var_filter=0.001):
    """Per-step NEES averaged over runs, in a regime where the EKF linearisation holds."""
    n, bs, qf = 200, 0.02, 1e-5
    nees = []
    for seed in range(n_runs):
        sim = simulate_robot(n, velocity0_mps=(1.0, 0.0), position_std_m=0.01,
                             velocity_std_mps=0.01, bias0_std_mps2=bs, bias_rw_var=qf,
                             rng=1000 + seed)  # fmt: skip
        P0 = np.diag([1e-4] * 4 + [bs**2] * 2)
        res = _run(sim, x0=[0, 0, 1.0, 0, 0, 0], P0=P0, bias_rw_var=qf,
                   accel_var=accel_var_filter, second_order=second_order)  # fmt: skip
        e = res.x - sim.state
        nees.append(np.einsum("ki,kij,kj->k", e, np.linalg.inv(res.P), e))
    return np.mean(nees, axis=0)


@pytest.mark.parametrize(("second_order", "min_in_band"), [(False, 0.8), (True, 0.9)])
def test_nees_in_chi2_band(second_order, min_in_band):
    runs, d = 30, 6
    m = _anees(runs, second_order)
    lo, hi = chi2.ppf([0.025, 0.975], runs * d) / runs
    # 95 % band per step; the first-order EKF is slightly optimistic (the squared
    # cross-track velocity error is read as along-track speed), hence 0.8.
    assert np.mean((m > lo) & (m < hi)) >= min_in_band
    assert 5.5 < m.mean() < 7.0


def test_nees_detects_a_mis_tuned_filter():
    m = _anees(10, False, accel_var_filter=1e-5)  # filter believes a 100x better accelerometer
    assert m.mean() > 12.0


def test_predict_only_rows_and_empty_log():
    t = np.arange(3) * 0.1
    r = dead_reckon(t, [1.0, 1.0, 1.0], [0.0] * 3, [np.nan, 0.1, np.nan])
    assert (
        np.isnan(r.nis[0])
        and not np.isnan(r.nis[1])
        and r.accepted.tolist() == [False, True, False]
    )
    e = dead_reckon([], [], [], [])
    assert e.x.shape == (0, 6) and e.P.shape == (0, 6, 6)


def test_invalid_parameters_name_the_parameter():
    t = np.arange(3) * 0.1
    z = np.zeros(3)
    with pytest.raises(InvalidParameterError, match="ax_mps2"):
        dead_reckon(t, [0, np.nan, 0], z, z)
    with pytest.raises(InvalidParameterError, match="speed_mps"):
        dead_reckon(t, z, z, [0, -1.0, 0])
    with pytest.raises(InvalidParameterError, match="t_s"):
        dead_reckon([0, 0.2, 0.1], z, z, z)
    with pytest.raises(InvalidParameterError, match="ay_mps2"):
        dead_reckon(t, z, [0, 0], z)
    with pytest.raises(InvalidParameterError, match="meas_var"):
        dead_reckon(t, z, z, z, meas_var=0)
    with pytest.raises(InvalidParameterError, match="P0"):
        dead_reckon(t, z, z, z, P0=np.eye(4))


# --------------------------------------------------------------------------- logs
GOOD = "t_s,ax_mps2,ay_mps2,speed_mps\n0.0,0.1,0.0,0.0\n0.1,0.1,0.0,\n0.2,0.0,0.1,0.02\n"


def test_read_imu_log_and_track_log_round_trip_of_simulated_log():
    sim = simulate_robot(50, odometry_every=5, rng=2)
    log = read_imu_log(io.StringIO(imu_log_text(sim)))
    np.testing.assert_array_equal(log.ax_mps2, sim.accel_meas_mps2[:, 0])
    np.testing.assert_array_equal(log.speed_mps, sim.speed_meas_mps)
    cols, rows = track_log(io.StringIO(imu_log_text(sim)), smooth=True)
    assert cols == list(TRACK_COLUMNS) and rows.shape == (50, 9)
    ref = _run(sim, smooth=True)
    np.testing.assert_allclose(rows[:, 1:7], ref.x, atol=1e-12)
    np.testing.assert_allclose(rows[:, 7], np.sqrt(ref.P[:, 0, 0]), atol=1e-12)


@pytest.mark.parametrize(
    ("text", "where"),
    [
        ("t_s,ax_mps2,speed_mps\n0,0,0\n", "row 1: missing column 'ay_mps2'"),
        (GOOD.replace("0.1,0.1,0.0,", "0.1,nan,0.0,"), "row 3, column 'ax_mps2'"),
        (GOOD.replace("0.2,0.0", "0.05,0.0"), "row 4, column 't_s'"),
        (GOOD.replace("0.1,0.02", "0.1,-0.02"), "row 4, column 'speed_mps'"),
        (GOOD.replace("0.1,0.1,0.0,", "0.1,,0.0,"), "row 3, column 'ax_mps2'"),
    ],
    ids=["missing-column", "nan", "time-backwards", "negative-speed", "empty-accel"],
)
def test_imu_log_errors_name_row_and_column(text, where):
    with pytest.raises(LogFormatError, match=where):
        read_imu_log(io.StringIO(text), name="imu.csv")


def test_track_log_rejects_unknown_parameter():
    with pytest.raises(InvalidParameterError, match="l_max_m"):
        track_log(io.StringIO(GOOD), l_max_m=1.0)
