"""The Jiang 2018 range tracker: noise model, engines, consistency, gating, smoothing."""

from __future__ import annotations

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError, LogFormatError
from rangekit.io.tracklog import FixRows, MeasurementLog, RangeRows, RobotRows
from rangekit.localize.ekf import numerical_jacobian
from rangekit.localize.range_ekf import (
    _epochs,
    _h_rows,
    cv_transition,
    measurement_covariance,
    track_ranges,
    track_rows,
)

SIGMA_D = 0.10
SIGMA_R = 0.06
SIGMA_F = 0.10
Q = 1e-4  # target 2's true white-acceleration density
Q1 = 0.01  # the filter's for target 1 (it walks a circle: v²/r ≈ 0.005 m/s²)


def model_log(rng, *, n_ep=40, dt=3.0, nlos=()):
    """Target 1 walks a 2 m circle (0.1 m/s) with the robot 1.2 m behind it; target 2
    moves exactly as the filter's model says (CV + white acceleration) from (3, 4);
    noisy measurements as in Jiang 2018 §5.2. Returns (log, truth (n_ep, 8))."""
    F, Qm = cv_transition(dt, 1, Q)
    L = np.linalg.cholesky(Qm)
    x2 = np.array([3.0, 4.0, 0.0, 0.0])
    t2 = []
    for _ in range(n_ep):
        t2.append(x2.copy())
        x2 = F @ x2 + L @ rng.standard_normal(4)
    w = 0.05
    t = dt * np.arange(n_ep)
    ang = w * t
    t1 = 2.0 * np.column_stack([np.cos(ang), np.sin(ang), -w * np.sin(ang), w * np.cos(ang)])
    truth = np.column_stack([t1, np.array(t2)])
    heading = np.arctan2(truth[:, 3], truth[:, 2])
    rob_true = truth[:, :2] - 1.2 * np.column_stack([np.cos(heading), np.sin(heading)])
    rob_est = rob_true + SIGMA_R * rng.standard_normal((n_ep, 2))
    c, s = np.cos(heading), np.sin(heading)
    d = truth[:, :2] - rob_true
    rel = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
    rel += SIGMA_F * rng.standard_normal((n_ep, 2))
    d_r2 = np.hypot(*(truth[:, 4:6] - rob_true).T) + SIGMA_D * rng.standard_normal(n_ep)
    d_12 = np.hypot(*(truth[:, 4:6] - truth[:, :2]).T) + SIGMA_D * rng.standard_normal(n_ep)
    for k, extra in nlos:
        d_r2[k] += extra
    eye = np.broadcast_to(np.eye(2), (n_ep, 2, 2))
    log = MeasurementLog(
        RobotRows(t, rob_est, heading, SIGMA_R**2 * eye),
        FixRows(t, np.ones(n_ep, int), rel, SIGMA_F**2 * eye),
        RangeRows(
            np.repeat(t, 2),
            np.tile([0, 1], n_ep),
            np.full(2 * n_ep, 2),
            np.column_stack([d_r2, d_12]).ravel(),
            np.full(2 * n_ep, SIGMA_D),
        ),
        2,
    )
    return log, truth


def test_cv_transition_matches_paper_structure():
    F, Qm = cv_transition(3.0, 2, 0.1)
    # eq (2a): position += dT * velocity ; (2b) velocity unchanged
    x = np.arange(8.0)
    assert np.allclose(F @ x, [6, 10, 2, 3, 22, 26, 6, 7])
    assert np.allclose(Qm, Qm.T) and np.all(np.linalg.eigvalsh(Qm) > 0)
    assert Qm[0, 4] == 0  # targets independent (§4.4.1)


@pytest.mark.parametrize("sign,ok", [("physical", True), ("paper", False)])
def test_measurement_covariance_against_monte_carlo(sign, ok):
    """R(k) of eqs (7), (9), (11)–(13) against the sample covariance of the actual
    measurement errors when the robot's position estimate is off by e_r ~ N(0, P_r)."""
    rng = np.random.default_rng(3)
    Pr = np.array([[0.02, 0.008], [0.008, 0.01]])
    Rf = np.array([[0.01, 0.002], [0.002, 0.02]])
    robot = np.array([0.5, -0.2])
    t1, t2 = np.array([1.7, 0.3]), np.array([2.0, 3.5])
    n = 200_000
    e_r = rng.multivariate_normal([0, 0], Pr, n)
    r_hat = robot + e_r
    z1 = np.hypot(*(t2 - robot)) + SIGMA_D * rng.standard_normal(n)
    z2 = np.hypot(*(t2 - t1)) + SIGMA_D * rng.standard_normal(n)
    z3 = r_hat + (t1 - robot) + rng.multivariate_normal([0, 0], Rf, n)
    # errors relative to the filter's prediction made with the robot estimate
    err = np.column_stack([z1 - np.hypot(*(t2 - r_hat).T), z2 - np.hypot(*(t2 - t1)), z3 - t1])
    emp = np.cov(err.T)
    # linearised at the robot estimate's mean (r_hat ~ robot)
    x = np.concatenate([t1, [0, 0], t2, [0, 0]])
    R = measurement_covariance(
        [0, 1, 2, 3], [1, 1, 0, 0], robot, Pr, x,
        [SIGMA_D**2, SIGMA_D**2, Rf[0, 0], Rf[1, 1]], [0, 0, Rf[0, 1], 0], cross_sign=sign,
    )  # fmt: skip
    assert np.allclose(np.diag(emp), np.diag(R), rtol=0.03)
    assert np.allclose(emp[2:, 2:], R[2:, 2:], atol=2e-3 * 0.05)
    assert abs(emp[0, 1]) < 1e-3 and R[0, 1] == 0
    cross_ok = np.allclose(emp[0, 2:], R[0, 2:], atol=1e-3)
    assert cross_ok is ok


def test_measurement_jacobian_matches_finite_differences():
    rng = np.random.default_rng(1)
    log, truth = model_log(rng, n_ep=3)
    ep = _epochs(log, "t")
    rows = np.arange(ep.start[1], ep.start[2])
    h = _h_rows(ep, rows, ep.robot_xy[1])
    x = truth[1] + 0.3 * rng.standard_normal(8)
    _, H = h(x)
    assert np.allclose(H, numerical_jacobian(lambda v: h(v)[0], x), atol=1e-7)


def test_compiled_engine_equals_numpy_reference():
    rng = np.random.default_rng(7)
    log, _ = model_log(rng, n_ep=25, nlos=[(22, 3.0)])
    a = track_ranges(log, smooth=True, engine="compiled")
    b = track_ranges(log, smooth=True, engine="numpy")
    assert a.n_hypotheses == b.n_hypotheses == 8
    assert np.allclose(a.x, b.x, atol=1e-9) and np.allclose(a.P, b.P, atol=1e-9)
    assert np.allclose(a.loglik, b.loglik, atol=1e-7)
    assert np.allclose(a.x_smooth, b.x_smooth, atol=1e-9)
    assert [(r.t_s, r.a, r.b) for r in a.rejected] == [(r.t_s, r.a, r.b) for r in b.rejected]


def test_single_hypothesis_fast_path_equals_the_bank():
    """With one start hypothesis and no mirrors, the whole-log compiled loop runs; it must
    equal the per-epoch bank path and the numpy reference."""
    log, _ = model_log(np.random.default_rng(8), n_ep=25, nlos=[(15, 3.0)])
    kw = dict(accel_psd=[Q1, Q], n_ring=2, max_hypotheses=1, smooth=True, mirror=False)
    with pytest.raises(LogFormatError, match="2 initial hypotheses"):
        track_ranges(log, **kw)
    fix2 = MeasurementLog(
        log.robot,
        FixRows(np.concatenate([log.fixes.t_s, [0.0]]), np.concatenate([log.fixes.target, [2]]),
                np.vstack([log.fixes.rel_m, [[3.0, 0.0]]]),
                np.concatenate([log.fixes.cov_m2, [np.eye(2)]])),
        log.ranges, 2,
    )  # fmt: skip
    fast = track_ranges(fix2, **kw)
    ref = track_ranges(fix2, **kw, engine="numpy")
    assert fast.n_hypotheses == 1
    assert np.allclose(fast.x, ref.x, atol=1e-9) and np.allclose(fast.P, ref.P, atol=1e-9)
    assert np.allclose(fast.x_smooth, ref.x_smooth, atol=1e-9)
    assert [r.t_s for r in fast.rejected] == [r.t_s for r in ref.rejected]


def test_nees_of_target_2_and_the_sign_of_eq_12():
    """Range-only tracking is mildly overconfident (the EKF linearises a banana-shaped
    posterior), so the check is on the median NEES of target 2's 4-state block over
    40 runs (epochs 15..39): below twice the chi-square(4) median (3.36) with the derived
    sign of the cross-covariance, and lower than with the sign printed in eq (12)."""
    med = {}
    for sign in ("physical", "paper"):
        rng = np.random.default_rng(2026)
        nees = []
        for _ in range(40):
            log, truth = model_log(rng)
            trk = track_ranges(log, accel_psd=[Q1, Q], cross_sign=sign)
            err = trk.x - truth
            for k in range(15, truth.shape[0]):
                nees.append(err[k, 4:] @ np.linalg.solve(trk.P[k][4:, 4:], err[k, 4:]))
        med[sign] = np.median(nees)
    assert med["physical"] < 2 * 3.36, med
    assert med["physical"] < med["paper"], med


def test_starts_without_prior_and_converges_within_six_updates():
    rng = np.random.default_rng(5)
    errs = []
    for _ in range(30):
        log, truth = model_log(rng, n_ep=12)
        trk = track_ranges(log, accel_psd=[Q1, Q])
        errs.append(np.hypot(*(trk.position(2)[5:] - truth[5:, 4:6]).T))
    # after 5-6 updates (15-18 s, Jiang 2018 §5.3.1): median error below 0.5 m and 80 %
    # within 1 m (the rest are runs still on the mirror branch, see the module docstring)
    e = np.concatenate(errs)
    assert np.median(e) < 0.5 and np.mean(e < 1.0) > 0.8, (np.median(e), np.mean(e < 1.0))


def test_nlos_range_is_gated_and_logged():
    rng = np.random.default_rng(11)
    log, truth = model_log(rng, n_ep=30, nlos=[(22, 2.5)])
    trk = track_ranges(log, accel_psd=[Q1, Q])
    assert [(r.t_s, r.a, r.b) for r in trk.rejected] == [(66.0, 0, 2)]
    assert trk.rejected[0].nis > 10.8
    ungated = track_ranges(log, accel_psd=[Q1, Q], gate=None)
    e_g = np.hypot(*(trk.position(2)[22] - truth[22, 4:6]))
    e_u = np.hypot(*(ungated.position(2)[22] - truth[22, 4:6]))
    assert e_u > e_g + 0.5, (e_g, e_u)


def test_smoothing_beats_filtering():
    rng = np.random.default_rng(9)
    f, s = [], []
    for _ in range(20):
        log, truth = model_log(rng, n_ep=30)
        trk = track_ranges(log, accel_psd=[Q1, Q], smooth=True)
        f.append(np.hypot(*(trk.position(2)[5:] - truth[5:, 4:6]).T))
        s.append(np.hypot(*(trk.position(2, smoothed=True)[5:] - truth[5:, 4:6]).T))
    rf, rs = np.sqrt(np.mean(np.concatenate(f) ** 2)), np.sqrt(np.mean(np.concatenate(s) ** 2))
    assert rs < 0.85 * rf


def test_track_rows_and_accessors():
    rng = np.random.default_rng(4)
    log, _ = model_log(rng, n_ep=5)
    trk = track_ranges(log, smooth=True)
    cols, rows = track_rows(trk, smoothed=True)
    assert cols[:4] == ["t_s", "target", "x_m", "y_m"] and rows.shape == (10, 9)
    assert np.allclose(rows[1::2, 2:4], trk.position(2, smoothed=True))
    assert np.allclose(trk.sqrt_det_p(2), np.sqrt(np.linalg.det(trk.position_cov(2))))
    with pytest.raises(InvalidParameterError, match="target=3"):
        trk.position(3)
    with pytest.raises(InvalidParameterError, match="not smoothed"):
        track_ranges(log).position(1, smoothed=True)


@pytest.mark.parametrize(
    "kw,match",
    [
        ({"accel_psd": -1}, "accel_psd"),
        ({"gate": 1.5}, "gate"),
        ({"cross_sign": "plus"}, "cross_sign"),
        ({"engine": "gpu"}, "engine"),
    ],
)
def test_bad_parameters(kw, match):
    log, _ = model_log(np.random.default_rng(0), n_ep=3)
    with pytest.raises(InvalidParameterError, match=match):
        track_ranges(log, **kw)


def test_log_that_cannot_start_is_refused():
    log, _ = model_log(np.random.default_rng(0), n_ep=3)
    # only target-target ranges, no fixes: no target has a known anchor
    only_pairs = MeasurementLog(
        log.robot,
        FixRows(np.zeros(0), np.zeros(0, int), np.zeros((0, 2)), np.zeros((0, 2, 2))),
        RangeRows(np.array([0.0]), np.array([1]), np.array([2]), np.array([2.0]),
                  np.array([0.1])),
        2,
    )  # fmt: skip
    with pytest.raises(LogFormatError, match="cannot start"):
        track_ranges(only_pairs, name="x.csv")


def test_bank_mixture_and_branch_probability():
    """The bank as a Gaussian mixture (issue 18 item 6): with one hypothesis it is the
    filter itself; with the mirror bank on the Jiang walks its covariance spans the live
    branches, so target 2's NEES drops from hundreds to tens (measured 11-21 against
    350-2200 in the experiment), and the branch probability is a probability."""
    from rangekit.sim.jiang2018 import paper_settings, simulate

    log, _ = model_log(np.random.default_rng(8), n_ep=10)
    fix2 = MeasurementLog(
        log.robot,
        FixRows(np.concatenate([log.fixes.t_s, [0.0]]), np.concatenate([log.fixes.target, [2]]),
                np.vstack([log.fixes.rel_m, [[3.0, 0.0]]]),
                np.concatenate([log.fixes.cov_m2, [np.eye(2)]])),
        log.ranges, 2,
    )  # fmt: skip
    one = track_ranges(fix2, mirror=False)
    assert np.array_equal(one.x_mix, one.x) and np.all(one.p_branch == 1.0)
    g = np.random.default_rng(5)
    nees_rep, nees_mix = [], []
    for _ in range(6):
        run = simulate(**paper_settings("lab_moderate"), speed_mps=0.4, rng=g)
        trk = track_ranges(run.log, accel_psd=0.05)
        assert np.all((trk.p_branch >= 0) & (trk.p_branch <= 1 + 1e-12))
        assert np.all(np.linalg.eigvalsh(trk.P_mix) > 0)
        truth = run.update_targets_m[trk.n_skipped :, 1]
        for pos, cov, out in (
            (trk.position(2), trk.position_cov(2), nees_rep),
            (trk.position_mixture(2), trk.position_cov_mixture(2), nees_mix),
        ):
            e = pos - truth
            out.append(np.mean(np.einsum("ni,nij,nj->n", e, np.linalg.inv(cov), e)))  # fmt: skip
    assert np.mean(nees_mix) < 0.2 * np.mean(nees_rep), (nees_mix, nees_rep)


def _jiang_runs(case: str, speed: float, n: int = 10):
    from rangekit.sim.jiang2018 import paper_settings, simulate

    g = np.random.default_rng(18)
    for _ in range(n):
        run = simulate(**paper_settings(case), speed_mps=speed, rng=g)
        yield run, track_ranges(run.log, accel_psd=0.05)


@pytest.mark.parametrize(
    "case, speed, bound",
    [
        ("lab_moderate", 0.4, 0.85),  # measured 0.45 m (paper 0.85 m)
        ("lab_moderate", 0.8, 0.65),  # measured 0.32 m (paper 0.98 m)
        ("lab_heavy", 0.8, 0.90),  # measured 0.46 m (paper 1.12 m)
        ("lab_mismatch", 0.4, 1.00),  # skewed, +0.1 m biased ranges, 5 % outliers: 0.53 m
    ],
)
def test_target_2_filtered_on_the_jiang_lab_walks(case, speed, bound):
    """Issue 18 item 6: the filtered (causal) target-2 error of the Jiang lab walks, the
    median over 10 seeded walks of each walk's steady-state mean error, within 1.2x of
    the paper's Table 1 (and at the paper's level when the ranges come from another
    law than the filter's). Was 1.5-4.3 m with the mirror jump."""
    err = []
    for run, trk in _jiang_runs(case, speed):
        steady = trk.t_s >= 18.0
        e = np.hypot(*(trk.position(2) - run.update_targets_m[trk.n_skipped :, 1]).T)
        err.append(np.mean(e[steady]))
    assert np.median(err) < bound, err


def _sure_and_right(case: str, speed: float, *, last: bool = True) -> tuple[int, int]:
    sure = right = 0
    for run, trk in _jiang_runs(case, speed):
        e = np.hypot(*(trk.position(2) - run.update_targets_m[trk.n_skipped :, 1]).T)
        s = (trk.t_s >= 18.0) & (trk.p_branch[:, 1] >= 0.95)
        if not last:
            s[-1] = False
        sure += int(s.sum())
        right += int(np.sum(e[s] < 1.5))
    return sure, right


def test_branch_probability_is_informative():
    """When the bank is sure of target 2's branch it is more often right than when it is
    not (moderate noise, 0.8 m/s: 16 of 16 sure epochs right, measured)."""
    sure, right = _sure_and_right("lab_moderate", 0.8)
    assert sure >= 8 and right >= 0.85 * sure, (sure, right)


def test_branch_probability_is_calibrated_before_the_final_turn():
    """At p_branch >= 0.95 the target is within 1.5 m >= 90 % of the time at every
    epoch but the walk's last one (measured: 6 of 6 and 11 of 11 at 0.4 m/s, moderate
    and skewed ranges; 42 of 44 over the six lab conditions; 44 of 44 on walks of seed
    99). The branch probability is the mass on the reported side of the mirror line
    (``range_ekf._branch_probability``); counting each hypothesis's weight whole, it was
    >= 0.95 at 40 steady epochs of these two conditions (the last included) and right
    at 26 (65 %)."""
    sure = right = 0
    for case in ("lab_moderate", "lab_mismatch"):
        s, r = _sure_and_right(case, 0.4, last=False)
        sure, right = sure + s, right + r
    assert sure >= 10 and right >= 0.9 * sure, (sure, right)


@pytest.mark.xfail(strict=True, reason="the walks' final sharp turn (issue 18)")
def test_branch_probability_is_calibrated_at_095():
    """The acceptance: at p_branch >= 0.95 the target is within 1.5 m >= 90 % of the
    time, every steady epoch. Measured 6 of 8 (moderate, 0.4 m/s) and 11 of 12 (skewed
    ranges): not met. Every miss is the walk's last epoch, a sharp turn at the office's
    far wall where the constant-velocity prediction is 3-5 m (5-7 sigma) off and the
    ranges put the target on the mirror side; the 20,000-particle reference misses there
    too (docs/theory/jiang2018.md)."""
    for case in ("lab_moderate", "lab_mismatch"):
        sure, right = _sure_and_right(case, 0.4)
        assert right >= 0.9 * sure, (case, sure, right)


def test_mirror_branch_is_an_update_of_the_same_prediction():
    """The mirror child is not a jump: it shares its parent's prediction (x⁻, P⁻), its
    posterior covariance is below that prediction like the direct child's, the engines
    agree on it, and from some start the two children reach the two sides of the line
    robot -> target 1 (the two modes of the same posterior)."""
    from rangekit.localize.range_ekf import (
        NO_MIRROR,
        _Ctx,
        _hypotheses,
        _mirror_lines,
        _step_compiled,
        _step_numpy,
    )

    log, _ = model_log(np.random.default_rng(3), n_ep=6)
    ep = _epochs(log, "t")
    ctx = _Ctx(ep, np.array([Q1, Q]), 1.0, np.inf, 3, 1.0, 5)
    (line,) = _mirror_lines(ep, 1, 2)
    u, p0 = line[3:5], line[1:3]
    n_split = 0
    for x0, P0 in _hypotheses(ep, 0, 2, 8, 1.0):
        sides = []
        for m in (NO_MIRROR, line):
            a = _step_compiled(ctx, x0, P0, np.zeros(2, np.int64), 3.0, 1, m)
            b = _step_numpy(ctx, x0, P0, np.zeros(2, np.int64), 3.0, 1, m)
            assert np.allclose(a[0], b[0], atol=1e-9) and np.allclose(a[1], b[1], atol=1e-9)
            assert np.isclose(a[4], b[4], atol=1e-7)
            x, P, xp, Pp = a[:4]
            if m is NO_MIRROR:
                prior = (xp, Pp)
            assert np.array_equal(xp, prior[0]) and np.array_equal(Pp, prior[1])
            assert np.all(np.linalg.eigvalsh(Pp - P) >= -1e-12)
            v = x[4:6] - p0
            sides.append(np.sign(u[0] * v[1] - u[1] * v[0]))
        n_split += sides[0] != sides[1]
    assert n_split >= 2, n_split  # measured 3 of the 8 starts


def test_mismatch_walks_draw_ranges_from_another_law():
    """``paper_settings("lab_mismatch")``: +0.10 m bias, skewed scatter (standardised
    gamma, shape 4: skewness 1), 5 % outliers up to +0.7 m; the paper settings keep
    their Gaussian ranges and their random stream."""
    from scipy.stats import skew

    from rangekit.sim.jiang2018 import paper_settings, simulate

    runs = [simulate(**paper_settings("lab_mismatch"), rng=s) for s in range(30)]
    err = np.concatenate([r.log.ranges.range_m - r.range_truth_m for r in runs])
    assert abs(np.median(err) - 0.09) < 0.02  # bias + gamma median below its mean
    assert 0.9 < skew(err) < 3.0 and np.max(err) > 0.5
    a, b = simulate(rng=4), simulate(rng=4, range_bias_m=0.0, outlier_prob=0.0)
    assert np.array_equal(a.log.ranges.range_m, b.log.ranges.range_m)


def test_compiled_bank_equals_the_python_bank_and_the_numpy_reference():
    """Issue 20 item 5: the whole bank in one numba call (``engine="compiled"``) gives
    the track of the Python-driven bank (``"python"``) and of the numpy reference to
    rounding: hypotheses, weights after merging, lineage, mixture, branch probability."""
    from rangekit.sim.jiang2018 import paper_settings, simulate

    run = simulate(**paper_settings("lab_mismatch"), speed_mps=0.8, rng=7)
    trk = {e: track_ranges(run.log, smooth=True, engine=e) for e in ("compiled", "python", "numpy")}
    a = trk["compiled"]
    assert a.n_line_mirrors > 0  # the lineage went through a mirror branch
    for e in ("python", "numpy"):
        b = trk[e]
        for f in ("x", "P", "x_smooth", "P_smooth", "x_mix", "P_mix", "p_branch", "loglik"):
            assert np.allclose(getattr(a, f), getattr(b, f), rtol=0, atol=1e-8), (e, f)
        assert np.array_equal(a.n_reinit, b.n_reinit) and a.n_line_mirrors == b.n_line_mirrors
        assert [r.t_s for r in a.rejected] == [r.t_s for r in b.rejected]


def test_branch_probability_never_exceeds_one():
    """The weights sum to 1 only up to rounding: these five summed to 1.0000000000000002,
    which reached ``p_branch`` in the JSON; a probability stays in [0, 1]."""
    from rangekit.localize.range_ekf import _branch_probability

    w = np.array([0.33447075301917856, 0.001122687042822074, 0.35150506188686553,
                  0.013768883651057343, 0.2991326144000766])  # fmt: skip
    assert w.sum() > 1.0
    X = np.zeros((5, 8))
    P = np.tile(np.eye(8) * 0.01, (5, 1, 1))
    far_line = [np.array([4.0, 0.0, 100.0, 1.0, 0.0])]  # every hypothesis far on one side
    for lines in ([], far_line):
        p = _branch_probability(X, P, w, 0, 1, lines)
        assert 0.0 <= p <= 1.0 and p == 1.0
