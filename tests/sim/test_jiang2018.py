"""Tests of the Jiang 2018 §5 scenario simulator (rangekit.sim.jiang2018)."""

from __future__ import annotations

import io

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.io.tracklog import read_measurement_log
from rangekit.sim.jiang2018 import (
    NLOS_EXCESS_M,
    atrium_paths,
    environment,
    lab_office_paths,
    paper_settings,
    simulate,
    trail,
    walk,
)

PATHS = {"lab": lab_office_paths, "atrium": atrium_paths}
N_WAYPOINTS = {"lab": 19, "atrium": 12}


def _dist(a, b):
    return np.hypot(*(np.asarray(a) - np.asarray(b)).T)


@pytest.mark.parametrize("scenario", ["lab", "atrium"])
def test_paths_have_the_paper_waypoint_counts_and_stay_on_the_floor(scenario):
    env = environment(scenario)
    p1, p2 = PATHS[scenario]()
    assert p1.shape == p2.shape == (N_WAYPOINTS[scenario], 2)
    assert not np.array_equal(p1, p2)
    w, h = env.size_m
    for p in (p1, p2):
        assert np.all((p >= 0) & (p <= [w, h]))
        # dense samples of the walk: segments must not cut through walls
        xy = walk(p, 0.4, np.arange(0, 200, 0.05))
        assert env.contains(xy, margin_m=0.3).all()


def test_environment_sizes_match_the_paper():
    lab = environment("lab")
    assert lab.size_m == pytest.approx((69 * 0.3048, 33 * 0.3048), abs=0.05)
    corridor = {r.name: r for r in lab.rooms}["corridor"]
    assert corridor.hi_m[1] - corridor.lo_m[1] == pytest.approx(1.8)
    atrium = environment("atrium")
    assert atrium.size_m[0] * atrium.size_m[1] == pytest.approx(400.0)


def test_lab_persons_go_from_laboratory_through_corridor_to_office():
    rooms = {r.name: r for r in environment("lab").rooms}
    for p in lab_office_paths():
        assert p[0, 0] < rooms["laboratory"].hi_m[0]
        assert p[-1, 0] > rooms["office"].lo_m[0]


@pytest.mark.parametrize("speed", [0.4, 0.8])
def test_walk_respects_speed_and_stops_at_the_end(speed):
    p1, _ = lab_office_paths()
    length = np.sum(_dist(p1[1:], p1[:-1]))
    t = np.arange(0.0, length / speed, 0.01)
    xy = walk(p1, speed, t)
    travelled = np.sum(_dist(xy[1:], xy[:-1]))
    assert travelled == pytest.approx(speed * t[-1], rel=1e-3)
    assert np.allclose(walk(p1, speed, [length / speed + 5.0, 1e6]), p1[-1])
    assert np.allclose(walk(p1, speed, -1.0), p1[0])


@pytest.mark.parametrize("scenario", ["lab", "atrium"])
def test_robot_follows_target1_at_the_follow_distance_on_the_floor(scenario):
    run = simulate(scenario, rng=0)
    d = _dist(run.targets_m[:, 0], run.robot_m)
    assert np.all((d >= 1.0) & (d <= 1.5))
    assert np.allclose(d, run.params["follow_m"], atol=1e-9)
    assert environment(scenario).contains(run.robot_m, margin_m=0.3).all()
    # the robot faces Target 1
    u = np.column_stack([np.cos(run.robot_heading_rad), np.sin(run.robot_heading_rad)])
    assert np.allclose(run.robot_m + d[:, None] * u, run.targets_m[:, 0])
    # the robot moves continuously (no jumps larger than walking 10x faster)
    step = _dist(run.robot_m[1:], run.robot_m[:-1])
    assert step.max() < 10 * 0.4 / run.params["truth_rate_hz"]


def test_trail_keeps_the_gap_round_a_corner():
    wp = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]]
    t = np.linspace(0.0, 4.0, 81)
    f = trail(wp, 1.0, t, 1.2)
    assert np.allclose(_dist(f, walk(wp, 1.0, t)), 1.2)
    assert np.allclose(f[0], [-1.2, 0.0])


@pytest.mark.parametrize(("scenario", "lo", "hi"), [("lab", 3.5, 4.8), ("atrium", 6.0, 7.0)])
def test_robot_to_target2_distances_reach_the_paper_maximum(scenario, lo, hi):
    run = simulate(scenario, rng=0)
    d = _dist(run.targets_m[:, 1], run.robot_m)
    assert lo <= d.max() <= hi
    assert d.min() > 1.0  # nobody walks into the robot


def test_update_times_start_at_zero_every_interval_and_truth_is_consistent():
    run = simulate("lab", update_interval_s=3.0, rng=0)
    assert run.update_t_s[0] == 0.0
    assert np.allclose(np.diff(run.update_t_s), 3.0)
    assert run.update_t_s[-1] <= run.t_s[-1]
    k = np.searchsorted(run.t_s, run.update_t_s)  # 3 s is on the 10 Hz grid
    assert np.allclose(run.t_s[k], run.update_t_s)
    assert np.allclose(run.targets_m[k], run.update_targets_m)
    assert np.allclose(run.robot_m[k], run.update_robot_m)
    log = run.log
    assert np.array_equal(log.robot.t_s, run.update_t_s)
    assert np.array_equal(log.fixes.t_s, run.update_t_s)
    assert np.array_equal(log.ranges.t_s, np.repeat(run.update_t_s, 2))
    assert log.ranges.a.tolist()[:4] == [0, 1, 0, 1]
    assert set(log.ranges.b.tolist()) == {2}
    assert log.n_targets == 2


def test_range_errors_have_the_configured_std_and_zero_mean():
    sigma = 0.15
    run = simulate("atrium", sigma_d_m=sigma, update_interval_s=0.1, truth_rate_hz=1.0, rng=7)
    err = run.log.ranges.range_m - run.range_truth_m
    n = err.size
    assert n > 2000
    # truth itself: recompute d_r2 and d_12 from the true positions
    g = run.log.ranges
    ui = np.repeat(np.arange(run.update_t_s.size), 2)
    src = np.where((g.a == 0)[:, None], run.update_robot_m[ui], run.update_targets_m[ui, 0])
    assert np.allclose(run.range_truth_m, _dist(run.update_targets_m[ui, 1], src))
    # sample std within a chi-square bound (about 5 sigma of its sampling spread)
    s = err.std(ddof=1)
    assert abs(s / sigma - 1.0) < 5.0 / np.sqrt(2 * n)
    assert abs(err.mean()) < 5.0 * sigma / np.sqrt(n)
    assert np.all(g.sigma_m == sigma)
    assert not run.nlos.any()


def test_robot_rows_are_truth_plus_independent_noise_with_the_stated_covariance():
    rs = 0.1
    run = simulate("atrium", robot_sigma_m=rs, update_interval_s=0.1, truth_rate_hz=1.0, rng=3)
    e = run.log.robot.xy_m - run.update_robot_m
    n = e.shape[0]
    assert np.allclose(e.std(axis=0, ddof=1) / rs, 1.0, atol=5.0 / np.sqrt(2 * n))
    lag1 = np.corrcoef(e[1:, 0], e[:-1, 0])[0, 1]
    assert abs(lag1) < 5.0 / np.sqrt(n)  # uncorrelated in time (Fig. 8)
    assert np.allclose(run.log.robot.cov_m2, rs * rs * np.eye(2))
    assert np.array_equal(run.log.robot.heading_rad, run.update_heading_rad)


def test_fix_rows_rotate_back_to_the_true_target1_position():
    run = simulate("lab", fix_sigma_m=1e-9, rng=0)
    f = run.log.fixes
    assert np.all(f.target == 1)
    th = run.update_heading_rad
    c, s = np.cos(th), np.sin(th)
    world = run.update_robot_m + np.column_stack(
        [c * f.rel_m[:, 0] - s * f.rel_m[:, 1], s * f.rel_m[:, 0] + c * f.rel_m[:, 1]]
    )
    assert np.allclose(world, run.update_targets_m[:, 0], atol=1e-6)
    assert np.allclose(f.cov_m2, 1e-18 * np.eye(2))


def test_fix_noise_has_the_configured_std():
    run = simulate("atrium", fix_sigma_m=0.2, update_interval_s=0.1, truth_rate_hz=1.0, rng=5)
    f = run.log.fixes
    e = f.rel_m - np.array([run.params["follow_m"], 0.0])  # the robot faces Target 1
    n = e.shape[0]
    assert np.allclose(e.std(axis=0, ddof=1) / 0.2, 1.0, atol=5.0 / np.sqrt(2 * n))


@pytest.mark.parametrize("kwargs", [{}, {"n_targets": 3, "nlos": 0.3, "fail_prob": 0.2}])
def test_log_round_trips_through_csv(kwargs):
    run = simulate("lab", rng=11, **kwargs)
    text = run.log.to_csv()
    back = read_measurement_log(io.StringIO(text))
    assert back.n_targets == run.log.n_targets
    for kind in ("robot", "fixes", "ranges"):
        a, b = getattr(run.log, kind), getattr(back, kind)
        for name in a.__dataclass_fields__:
            x, y = getattr(a, name), getattr(b, name)
            assert x.shape == y.shape, (kind, name)
            assert np.array_equal(x, y, equal_nan=True), (kind, name)


def test_nlos_ranges_are_too_long_by_half_a_metre_to_five():
    clean = simulate("lab", sigma_d_m=1e-6, rng=2)
    run = simulate("lab", sigma_d_m=1e-6, nlos=0.5, rng=2)
    err = run.log.ranges.range_m - run.range_truth_m
    assert 0 < run.nlos.sum() < run.nlos.size
    lo, hi = NLOS_EXCESS_M
    assert np.all((err[run.nlos] > lo - 1e-4) & (err[run.nlos] < hi + 1e-4))
    assert np.all(np.abs(err[~run.nlos]) < 1e-4)
    assert np.allclose(clean.range_truth_m, run.range_truth_m)
    all_nlos = simulate("lab", sigma_d_m=1e-6, nlos=1.0, rng=2)
    assert all_nlos.nlos.all()


def test_failed_rangings_are_nan():
    run = simulate("lab", fail_prob=1.0, rng=0)
    assert np.all(np.isnan(run.log.ranges.range_m))
    assert not np.isnan(simulate("lab", rng=0).log.ranges.range_m).any()


def test_extra_targets_get_ranges_from_robot_and_target1():
    run = simulate("atrium", n_targets=4, rng=0)
    assert run.targets_m.shape[1] == 4
    assert run.log.n_targets == 4
    pairs = list(zip(run.log.ranges.a[:6].tolist(), run.log.ranges.b[:6].tolist(), strict=True))
    assert pairs == [(0, 2), (1, 2), (0, 3), (1, 3), (0, 4), (1, 4)]
    gap = _dist(run.targets_m[:, 2], run.targets_m[:, 1])
    assert np.allclose(gap, 0.8)
    # the two-target part is unchanged by the extra persons' presence
    base = simulate("atrium", rng=0)
    assert np.array_equal(base.targets_m, run.targets_m[:, :2])


def test_same_seed_same_run_and_paper_settings():
    a = simulate(**paper_settings("lab_heavy"), rng=4)
    b = simulate(**paper_settings("lab_heavy"), rng=np.random.default_rng(4))
    assert a.log.to_csv() == b.log.to_csv()
    assert a.params["sigma_d_m"] == 0.15 and a.params["robot_sigma_m"] == 0.06


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"scenario": "hall"}, "scenario"),
        ({"speed_mps": 0.0}, "speed_mps"),
        ({"speed_mps": -0.4}, "speed_mps"),
        ({"sigma_d_m": 0.0}, "sigma_d_m"),
        ({"robot_sigma_m": -0.06}, "robot_sigma_m"),
        ({"fix_sigma_m": float("nan")}, "fix_sigma_m"),
        ({"heading_sigma_rad": -0.1}, "heading_sigma_rad"),
        ({"update_interval_s": 0.0}, "update_interval_s"),
        ({"truth_rate_hz": -1.0}, "truth_rate_hz"),
        ({"follow_m": 0.0}, "follow_m"),
        ({"nlos": 1.5}, "nlos"),
        ({"fail_prob": -0.1}, "fail_prob"),
        ({"n_targets": 1}, "n_targets"),
        ({"n_targets": 2.5}, "n_targets"),
    ],
)
def test_invalid_parameters_raise_naming_the_parameter(kwargs, name):
    with pytest.raises(InvalidParameterError, match=name):
        simulate(**kwargs)


def test_invalid_inputs_of_helpers_raise():
    with pytest.raises(InvalidParameterError, match="speed_mps"):
        walk([[0, 0], [1, 0]], 0.0, 1.0)
    with pytest.raises(InvalidParameterError, match="waypoints"):
        walk([0.0, 1.0], 1.0, 1.0)
    with pytest.raises(InvalidParameterError, match="gap_m"):
        trail([[0, 0], [1, 0]], 1.0, 1.0, -1.0)
    with pytest.raises(InvalidParameterError, match="case"):
        paper_settings("office")
