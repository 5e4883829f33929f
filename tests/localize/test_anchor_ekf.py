"""The range EKF against fixed anchors (issue 18 items 2-5, 7): Jacobians, the closed-form
update, NEES, and the acceptance runs on simulated rigs whose range errors are drawn from a
skewed, biased law with outliers (not the filter's Gaussian)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from rangekit.errors import IncompatibleInputError, LogFormatError
from rangekit.io.duhllog import DistanceRows, DUHLLog, OdometryRows
from rangekit.localize.anchor_ekf import (
    multilaterate,
    multilaterate_latest,
    odometry_step,
    range_model,
    track_anchors,
)
from rangekit.localize.ekf import numerical_jacobian, update
from rangekit.rig import Odometry, Rig, read_rig
from rangekit.sim.rigs import simulate_rig_run, square_rig

RIGS = Path(__file__).resolve().parents[2] / "docs" / "rigs"


def _rmse(trk, run, smoothed=False):
    e = np.hypot(*(trk.position(smoothed=smoothed) - run.truth_xy(trk.t_s)).T)
    return float(np.sqrt(np.mean(e**2))), e


def _rmse_multilateration(run):
    tm, xm = multilaterate_latest(run.log, run.rig)
    ok = np.isfinite(xm[:, 0])
    return float(np.sqrt(np.mean(np.sum((xm[ok] - run.truth_xy(tm[ok])) ** 2, axis=1))))


# --------------------------------------------------------------------------- models
@pytest.mark.parametrize("heading", [True, False])
def test_range_jacobian_against_finite_differences(heading):
    rng = np.random.default_rng(3)
    for _ in range(20):
        d = (3 if heading else 4) + 4
        x = rng.normal(0, 1, d)
        a = rng.normal(0, 2, 3)
        lever = rng.normal(0, 0.3, 3)
        i_b = int(rng.integers(4))
        _, H = range_model(x[None], a, lever, i_b, heading=heading)
        J = numerical_jacobian(
            lambda v, a=a, lv=lever, i=i_b: range_model(v[None], a, lv, i, heading=heading)[0], x
        )
        assert np.allclose(H, J, atol=1e-8)


def test_odometry_jacobians_against_finite_differences_and_closed_form():
    x = np.array([0.3, -0.2, 0.7, 0.1])
    for vr, vl in ((0.4, 0.3), (0.2, -0.2), (0.5, 0.5)):
        xn, F, G = odometry_step(x[None], 0.1, vr, vl, 0.33)
        Jx = numerical_jacobian(
            lambda s, vr=vr, vl=vl: odometry_step(s[None], 0.1, vr, vl, 0.33)[0][0], x
        )
        Ju = numerical_jacobian(
            lambda u: odometry_step(x[None], 0.1, u[0], u[1], 0.33)[0][0], [vr, vl]
        )
        assert np.allclose(F[0], Jx, atol=1e-8) and np.allclose(G[0], Ju, atol=1e-8)
    # straight: moves v dt along the heading; spin in place: turns 2 v dt / B
    xn = odometry_step(x[None], 0.5, 0.4, 0.4, 0.33)[0][0]
    assert np.allclose(xn[:2], x[:2] + 0.2 * np.array([math.cos(0.7), math.sin(0.7)]))
    xn = odometry_step(x[None], 0.5, 0.2, -0.2, 0.33)[0][0]
    assert np.allclose(xn[:2], x[:2]) and math.isclose(xn[2], 0.7 + 0.2 / 0.33)


def test_multilateration_exact_and_with_heights():
    a = np.array([[0.0, 0, 2.5], [6, 0, 2.5], [6, 4, 2.5], [0, 4, 2.5]])
    p = np.array([2.2, 1.3])
    r = np.sqrt(np.sum((a[:, :2] - p) ** 2, axis=1) + (0.9 - 2.5) ** 2)
    xy, JtJ, rms = multilaterate(a, r, z_m=0.9)
    assert np.allclose(xy, p, atol=1e-9) and rms < 1e-9 and np.linalg.det(JtJ) > 0


def _one_range_log(r):
    odo = OdometryRows(np.array([0.0, 0.1]), np.zeros(2), np.zeros(2))
    return DUHLLog(
        odo, DistanceRows(np.array([0.1]), np.array([2]), np.array([[r, np.nan, np.nan]]))
    )


@pytest.mark.parametrize(("robust", "r"), [("none", 1.9), ("huber", 1.9), ("huber", 2.8),
                                           ("student-t", 2.8)])  # fmt: skip
def test_one_update_equals_the_validated_core(robust, r):
    """One range after a still interval: the Kalman update of ``ekf.update`` with the noise
    ``σ²/w`` (w the robust weight of the normalised innovation)."""
    rig = square_rig()
    x0 = np.array([0.5, 0.6, 0.3])
    trk = track_anchors(_one_range_log(r), rig, initial_pose=x0, robust=robust)
    off = 3
    P0 = np.zeros((7, 7))
    P0[0, 0], P0[1, 1], P0[2, 2] = 0.05**2, 0.05**2, 0.035**2
    P0[off:, off:] = 0.05**2 * np.eye(4) + 0.2**2
    Pp = P0.copy()
    Pp[0, 0] += 1e-4 * 0.1
    Pp[1, 1] += 1e-4 * 0.1
    Pp[2, 2] += 1e-4 * 0.1
    Pp[np.arange(3, 7), np.arange(3, 7)] += 1e-7 * 0.1
    xp = np.concatenate([x0, np.zeros(4)])
    h, H = range_model(xp[None], rig.anchor_xyz_m[1], rig.tag_lever_m[0], 1, heading=True)
    S = float(H[0] @ Pp @ H[0] + 0.01)
    nu = (r - h[0]) / math.sqrt(S)
    w = {"none": 1.0, "huber": min(1.0, 1.5 / abs(nu)), "student-t": 5.0 / (4.0 + nu * nu)}[robust]
    ref = update(xp, Pp, [r], lambda v: range_model(v[None], rig.anchor_xyz_m[1],
                 rig.tag_lever_m[0], 1, heading=True), [[0.01 / w]])  # fmt: skip
    assert np.allclose(trk.x[0], ref.x, atol=1e-12) and np.allclose(trk.P[0], ref.P, atol=1e-12)
    assert len(trk.downweighted) == (1 if w < 1 else 0)


# --------------------------------------------------------------------------- consistency
def test_nees_in_the_filters_own_noise_law():
    """Gaussian ranges, biases drawn from the prior, no outliers: the 7-state NEES averaged
    over 40 runs lies in the 95 % chi-square band (Bar-Shalom et al. 2001, ch. 5)."""
    from scipy.stats import chi2

    n_runs, d = 40, 7
    nees = []
    for seed in range(n_runs):
        g = np.random.default_rng(1000 + seed)
        b = g.normal(0, 0.2) + g.normal(0, 0.05, 4)
        run = simulate_rig_run(square_rig(), duration_s=20, rng=seed, bias_m=b, skew_shape=1e6,
                               outlier_prob=0, wheel_scale_sigma=0)  # fmt: skip
        p0 = run.truth_pose([0.0])[0] + g.normal(0, 1, 3) * [0.05, 0.05, 0.035]
        trk = track_anchors(run.log, run.rig, initial_pose=p0, robust="none",
                            slip_psd=(1e-9, 1e-9))  # fmt: skip
        tp = run.truth_pose(trk.t_s)
        e = np.column_stack([tp[:, :2] - trk.x[:, :2],
                             (tp[:, 2] - trk.x[:, 2] + np.pi) % (2 * np.pi) - np.pi,
                             b - trk.x[:, 3:]])  # fmt: skip
        nees.append(np.einsum("ni,nij,nj->n", e, np.linalg.inv(trk.P), e)[:140])
    avg = np.mean(nees, axis=0)
    lo, hi = chi2.ppf([0.025, 0.975], n_runs * d) / n_runs
    assert lo < avg.mean() < hi, (lo, avg.mean(), hi)
    assert np.mean((avg > lo) & (avg < hi)) > 0.85


# --------------------------------------------------------------------------- acceptance
SEEDS = (0, 1, 2)


@pytest.fixture(scope="module")
def runs():
    """Issue 18's robot: one tag, 4 anchors on a 2.4 m square, ranges one anchor at a time
    at 7.8 Hz, +10 cm bias, 10 cm skewed scatter, 5 % outliers up to +0.7 m, 20 Hz wheel
    odometry with 0.5 % scale errors, 120 s."""
    return [simulate_rig_run(square_rig(), duration_s=120.0, rng=s) for s in SEEDS]


def test_simulated_errors_follow_the_stated_law(runs):
    err = np.concatenate([r.range_error_m[:, 0] for r in runs])
    out = np.concatenate([r.outlier[:, 0] for r in runs])
    inl = err[~out]
    assert abs(inl.mean() - 0.10) < 0.01 and abs(inl.std() - 0.10) < 0.01
    skew = np.mean((inl - inl.mean()) ** 3) / inl.std() ** 3
    assert 0.6 < skew < 1.4  # gamma shape 4: skewness 1, the filter assumes 0
    assert 0.03 < out.mean() < 0.07
    assert 0.3 < err[out].mean() - inl.mean() < 0.4  # excess uniform in (0, 0.7] m


def test_acceptance_with_initial_pose(runs):
    """RMSE <= 0.10 m, >= 30 % better than multilateration, biases within 3 cm."""
    for run in runs:
        p0 = run.truth_pose([run.log.odometry.t_s[0]])[0]
        trk = track_anchors(run.log, run.rig, initial_pose=p0)
        rmse, _ = _rmse(trk, run)
        rmse_ml = _rmse_multilateration(run)
        assert rmse <= 0.08, rmse  # measured 0.043-0.059
        assert rmse <= 0.4 * rmse_ml, (rmse, rmse_ml)  # measured 0.23-0.31 (ML 0.19-0.22)
        assert np.all(np.abs(trk.bias_m - 0.10) <= 0.03), trk.bias_m
        assert len(trk.downweighted) > 0.06 * trk.t_s.size  # the outliers, and more


@pytest.mark.parametrize(
    ("rate_hz", "odometry_hz", "duration_s", "measured"),
    [
        (5.0, 20.0, 400.0, "bias error 1.0 / 1.8 cm, RMSE 0.056 / 0.061 m (ML 0.19 / 0.20)"),
        (10.0, 7.8, 200.0, "bias error 2.5 / 1.4 cm, RMSE 0.053 / 0.054 m (ML 0.18 / 0.19)"),
    ],
)
def test_acceptance_biases_at_5_and_10_hz(rate_hz, odometry_hz, duration_s, measured):
    """Sequential ranges at 5 and 10 Hz: biases within 3 cm, RMSE <= 0.10 m and >= 30 %
    better than multilateration, on seeds 16 and 17 (held out: the durations were chosen
    on seeds 0-15). The bias information is the ranges per anchor: 500 here; at 5 Hz for
    120 s (150 per anchor) the reported 1-sigma is 1.7 cm and the largest error 5.9 cm,
    4.8 cm on seed 0 also in the filter's own noise law (docs/rigs.md)."""
    for seed in (16, 17):
        run = simulate_rig_run(square_rig(), duration_s=duration_s, range_rate_hz=rate_hz,
                               odometry_rate_hz=odometry_hz, rng=seed)  # fmt: skip
        p0 = run.truth_pose([run.log.odometry.t_s[0]])[0]
        trk = track_anchors(run.log, run.rig, initial_pose=p0)
        rmse, _ = _rmse(trk, run)
        rmse_ml = _rmse_multilateration(run)
        err = np.abs(trk.bias_m - run.true_bias_m)
        assert np.all(err <= 0.03), (seed, err, measured)
        assert np.all(trk.bias_sigma_m <= 0.015), trk.bias_sigma_m  # measured 1.1 cm
        assert rmse <= 0.10 and rmse <= 0.7 * rmse_ml, (seed, rmse, rmse_ml, measured)


def test_bias_and_position_sigmas_are_honest_under_the_mismatched_law():
    """Issue 18 "covariances that mean something": under the skewed, outlier-ridden law at
    5 and 10 Hz ranging (120 s), pooled over the 4 anchors of seeds 24-31 (nothing was
    tuned: the filter is unchanged, docs/rigs.md), the bias errors lie within 2 sigma as
    often as an honest sigma says (95.4 %) and the position NEES is near 2 (Bar-Shalom et
    al. 2001, §5.4.2). A sigma 1.5x too small (RMS error/sigma 1.4) or 1.7x too large
    (0.56) fails."""
    from rangekit.localize._rig_acceptance import consistency

    z, nees = [], []
    for rate_hz in (5.0, 10.0):
        for seed in range(24, 32):
            run = simulate_rig_run(square_rig(), duration_s=120.0, range_rate_hz=rate_hz, rng=seed)
            p0 = run.truth_pose([run.log.odometry.t_s[0]])[0]
            trk = track_anchors(run.log, run.rig, initial_pose=p0)
            c = consistency(trk, run)
            z.append(c["bias_z"])
            nees.append(c["nees"])
            assert 1.0 <= trk.bias_scale <= 1.3, trk.bias_scale  # measured 1.0-1.2
    z = np.concatenate(z)
    within, rms = np.mean(np.abs(z) <= 2.0), np.sqrt(np.mean(z**2))
    assert within >= 0.85, within  # measured 0.953 (5 Hz 0.969, 10 Hz 0.938)
    assert 0.6 <= rms <= 1.4, rms  # measured 0.93 (0.95 without the sandwich factor)
    assert 1.0 <= np.mean(nees) <= 3.0, nees  # measured 1.69 (1.62, 1.76)


def test_bias_sigma_widened_by_the_huber_sandwich_under_15_percent_outliers():
    """Three times the outliers (15 %, one-sided): the weighted updates report more
    information than the Huber M-estimate has; the sandwich factor E[w] E[psi^2] /
    E[psi']^2 widens the bias sigma (Huber 1964). 5 Hz, 120 s, seeds 12-17 (held out:
    measured first on 0-11). Still short of 95 %: the clipped outliers also shift Huber's
    location, common to the anchors (docs/rigs.md)."""
    from rangekit.localize._rig_acceptance import consistency

    z, scales = [], []
    for seed in range(12, 18):
        run = simulate_rig_run(square_rig(), duration_s=120.0, range_rate_hz=5.0, rng=seed,
                               outlier_prob=0.15)  # fmt: skip
        p0 = run.truth_pose([run.log.odometry.t_s[0]])[0]
        trk = track_anchors(run.log, run.rig, initial_pose=p0)
        z.append(consistency(trk, run)["bias_z"])
        scales.append(trk.bias_scale)
    z = np.concatenate(z)
    assert np.all((np.array(scales) >= 1.3) & (np.array(scales) <= 2.5)), scales  # 1.45-1.78
    within, rms = np.mean(np.abs(z) <= 2.0), np.sqrt(np.mean(z**2))
    assert within >= 0.70, within  # measured 0.79 (0.625 without the factor)
    assert rms <= 1.7, rms  # measured 1.46 (1.86 without the factor)


def test_acceptance_without_initial_pose(runs):
    """Start from multilateration and a heading bank: converged (< 0.3 m from then on)
    within 5 s; whole-run RMSE still <= 0.10 m."""
    for run in runs:
        trk = track_anchors(run.log, run.rig)
        assert trk.start == "multilateration" and trk.n_hypotheses[0] == 12
        rmse, e = _rmse(trk, run)
        bad = np.flatnonzero(e >= 0.3)
        t_conv = trk.t_s[bad[-1] + 1] if bad.size else trk.t_s[0]
        assert t_conv < 3.2, t_conv  # measured 0.6-1.6 s
        assert rmse <= 0.10, rmse  # measured 0.05-0.08


def test_smoother_spd_below_filter_and_better(runs):
    run = runs[0]
    trk = track_anchors(run.log, run.rig, smooth=True)
    assert np.all(np.linalg.eigvalsh(trk.P_smooth) > 0)
    scale = np.abs(trk.P_line).max(axis=(1, 2))[:, None]
    assert np.all(np.linalg.eigvalsh(trk.P_line - trk.P_smooth) >= -1e-9 * scale)
    r_f, _ = _rmse(trk, run)
    r_s, _ = _rmse(trk, run, smoothed=True)
    assert r_s < 0.8 * r_f, (r_f, r_s)  # measured 0.033 vs 0.080


def test_smoother_on_many_tiny_runs():
    """1,000 seeded 1.2 s runs (some starting from the heading bank): smoothed
    covariances SPD and below the filtered ones of the same hypothesis."""
    bad = 0
    for seed in range(1000):
        run = simulate_rig_run(square_rig(), duration_s=1.2, odometry_rate_hz=8.0, rng=seed)
        p0 = None if seed % 4 == 0 else run.truth_pose([0.0])[0]
        trk = track_anchors(run.log, run.rig, initial_pose=p0, smooth=True, n_heading=4)
        Ps, Pl = trk.P_smooth, trk.P_line
        scale = np.abs(Pl).max(axis=(1, 2))[:, None]
        ok = np.all(np.linalg.eigvalsh(Ps) > 0) and np.all(
            np.linalg.eigvalsh(Pl - Ps) >= -1e-9 * scale
        )
        bad += not ok
    assert bad == 0


# --------------------------------------------------------------------------- other rigs
def test_kim_rig_three_receivers_simultaneous_sets():
    """Kim & Kim 2013's robot (three receivers on a 0.19 m circle, six ceiling Txs, one Tx
    to all receivers at once) from its own simulated log, through the shipped rig file."""
    from rangekit.sim.kim2013 import simulate

    sim = simulate(1, t_max_s=20.0, rng=1)
    rig = read_rig(RIGS / "kim2013.json")
    trk = track_anchors(sim.to_log(), rig, initial_pose=sim.true_pose[0])
    truth = np.column_stack([np.interp(trk.t_s, sim.t_s, sim.true_pose[:, c]) for c in (0, 1)])
    rmse = float(np.sqrt(np.mean(np.sum((trk.x[:, :2] - truth) ** 2, axis=1))))
    assert rmse < 0.022, rmse  # measured 0.011 (DUHL's tightly coupled filter: 0.009)
    trk0 = track_anchors(sim.to_log(), rig)  # no pose: multilateration + heading bank
    truth0 = np.column_stack([np.interp(trk0.t_s, sim.t_s, sim.true_pose[:, c]) for c in (0, 1)])
    assert np.all(np.hypot(*(trk0.x[-50:, :2] - truth0[-50:]).T) < 0.03)  # measured 0.014


def test_rig_without_odometry_constant_velocity():
    """The same robot tracked as a point without odometry (rig odometry 'none')."""
    run = simulate_rig_run(square_rig(), duration_s=60.0, rng=5)
    r = run.rig
    rig = Rig(r.anchor_ids, r.anchor_xyz_m, r.anchor_bias_m, r.anchor_sigma_m,
              r.anchor_bias_sigma_m, r.tag_ids, r.tag_lever_m, Odometry("none", accel_psd=0.05),
              "none", r.common_bias_sigma_m)  # fmt: skip
    log = DUHLLog(distances=run.log.distances)
    trk = track_anchors(log, rig)
    rmse, _ = _rmse(trk, run)
    tm, xm = multilaterate_latest(log, rig)
    ok = np.isfinite(xm[:, 0])
    rmse_ml = float(np.sqrt(np.mean(np.sum((xm[ok] - run.truth_xy(tm[ok])) ** 2, axis=1))))
    assert rmse < 0.85 * rmse_ml, (rmse, rmse_ml)  # measured 0.126 vs 0.180


# --------------------------------------------------------------------------- errors
def test_log_and_rig_that_do_not_fit():
    rig = square_rig()
    run = simulate_rig_run(rig, duration_s=3.0, rng=1)
    d = run.log.distances
    bad = DUHLLog(run.log.odometry, DistanceRows(d.t_s, np.where(d.tx == 2, 9, d.tx), d.d_m))
    with pytest.raises(IncompatibleInputError, match=r"run.csv: .* names anchor 9"):
        track_anchors(bad, rig, name="run.csv")
    two = d.d_m.copy()
    two[3, 1] = 1.0
    with pytest.raises(IncompatibleInputError, match="d2_m but the rig has 1 tag"):
        track_anchors(DUHLLog(run.log.odometry, DistanceRows(d.t_s, d.tx, two)), rig)
    steps = Rig(rig.anchor_ids, rig.anchor_xyz_m, rig.anchor_bias_m, rig.anchor_sigma_m,
                rig.anchor_bias_sigma_m, rig.tag_ids, rig.tag_lever_m,
                Odometry("steps"))  # fmt: skip
    with pytest.raises(IncompatibleInputError, match="step events"):
        track_anchors(run.log, steps)
    with pytest.raises(LogFormatError, match="odometry row"):
        track_anchors(DUHLLog(distances=d), rig)
    one = DUHLLog(run.log.odometry, DistanceRows(d.t_s[:1], d.tx[:1], d.d_m[:1]))
    with pytest.raises(LogFormatError, match="no start pose"):
        track_anchors(one, rig, name="run.csv")


def test_walker_with_step_events_beats_constant_velocity_and_multilateration():
    """A walker (1 m/s on an ellipse, phone 0.15 m off the centre, ceiling anchors 1.6 m
    above it) with foot-IMU step events whose heading drifts: step odometry against the
    same walker tracked without odometry and against multilateration."""
    from rangekit.sim.rigs import simulate_walker_run

    rig = read_rig(RIGS / "walker_steps.json")
    rig_none = read_rig(RIGS / "walker_phone.json")
    for seed in (0, 1):
        w = simulate_walker_run(rig, duration_s=60.0, rng=seed, bias_m=[0.1, 0.1, 0.13, 0.1])
        trk = track_anchors(w.log, rig, steps=w.steps)
        e = np.hypot(*(trk.position() - w.truth_xy(trk.t_s)).T)
        cv = track_anchors(w.log, rig_none)
        ecv = np.hypot(*(cv.position() - w.truth_xy(cv.t_s)).T)
        tm, xm = multilaterate_latest(w.log, rig)
        ok = np.isfinite(xm[:, 0])
        em = np.hypot(*(xm[ok] - w.truth_xy(tm[ok])).T)
        r, rcv, rml = (float(np.sqrt(np.mean(x**2))) for x in (e, ecv, em))
        assert r < 0.16, r  # measured 0.095-0.100
        assert r < 0.6 * rcv and r < 0.4 * rml, (r, rcv, rml)  # measured 0.25-0.27, 0.43-0.45
        assert np.all(np.abs(trk.bias_m - w.true_bias_m) < 0.05)  # measured <= 0.024


def test_two_anchors_start_from_both_intersections_and_keep_the_right_one():
    """Two anchors fix a tag only up to its mirror image in the line through them: the
    start bank holds both circle intersections (x 12 headings) and odometry resolves it."""
    sq = square_rig()
    i = [0, 1]
    rig = Rig(sq.anchor_ids[i], sq.anchor_xyz_m[i], sq.anchor_bias_m[i], sq.anchor_sigma_m[i],
              sq.anchor_bias_sigma_m[i], sq.tag_ids, sq.tag_lever_m, sq.odometry, "two",
              sq.common_bias_sigma_m)  # fmt: skip
    for seed in (0, 1):
        run = simulate_rig_run(rig, duration_s=60.0, rng=seed)
        trk = track_anchors(run.log, rig)
        assert trk.n_hypotheses[0] == 24
        e = np.hypot(*(trk.position() - run.truth_xy(trk.t_s)).T)
        # the mirror image is 2 x (0.36 .. 2.0) m away; measured RMS 0.10-0.19 m
        assert np.sqrt(np.mean(e[-78:] ** 2)) < 0.4
