"""Tests of the Girard et al. 2011 test-walk simulator (rangekit.sim.girard2011)."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.floorplan import segment_crosses_wall
from rangekit.io.steplog import read_range_log, read_step_log
from rangekit.sensors.srf02 import CYCLE_S
from rangekit.sim import girard2011 as G


@pytest.fixture(scope="module")
def run():
    return G.simulate(rng=0)


def test_test_area_matches_the_paper():
    """§3.4: a 2 m corridor connected with three rooms of about 3 m x 5 m."""
    plan = G.test_area()
    assert plan.bounds == (0.0, 0.0, 9.0, 7.0)
    seg = plan.segments
    corridor_walls = seg[(seg[:, 1] == seg[:, 3]) & np.isin(seg[:, 1], [0.0, 2.0])]
    assert {0.0, 2.0} <= set(corridor_walls[:, 1])  # 2 m wide
    dividers = sorted({s[0] for s in seg if s[0] == s[2] and max(s[1], s[3]) == 7.0})
    assert dividers == [0.0, 3.0, 6.0, 9.0]  # three rooms 3 m wide, 5 m deep (y 2..7)
    assert len(plan.walls[1].doors) == 3  # one door per room
    # each room is reachable: a move through its door's centre crosses nothing
    for x in (1.25, 5.0, 7.5):
        assert not segment_crosses_wall(plan, [x, 1.0], [x, 4.0])[0]
        assert segment_crosses_wall(plan, [x + 0.6, 1.0], [x + 0.6, 4.0])[0]


def test_path_is_walked_twice_in_52_steps(run):
    assert len(run.steps) == 52 and run.truth_m.shape == (52, 2)
    assert sum(G.LEG_STEPS) == 26 and len(G.WAYPOINTS_M) == 10
    np.testing.assert_array_equal(run.truth_m[25], run.start_m)  # back at 1 after a lap
    np.testing.assert_array_equal(run.truth_m[:26], run.truth_m[26:])  # same markers
    path = np.vstack([run.start_m, run.truth_m])
    assert not np.any(segment_crosses_wall(run.plan, path[:-1], path[1:]))
    true_len = np.hypot(*np.diff(path, axis=0).T)
    assert np.all(np.abs(true_len - 1.25) <= 0.25 + 1e-9)  # "up to 25 cm" step error
    assert np.max(np.abs(true_len - 1.25)) > 0.1


def test_step_log_is_what_the_imu_reports(run):
    s = run.steps
    np.testing.assert_array_equal(s.length_m, 1.25)  # fixed step length (§3.3)
    np.testing.assert_allclose(s.t_s, np.arange(1, 53) * 1.0)
    err = (s.heading_rad - run.true_heading_rad + np.pi) % (2 * np.pi) - np.pi
    # drift 0.2 deg/step: the error at the end is about 10 deg on average
    assert np.degrees(np.mean(err[-10:])) > np.degrees(np.mean(err[:10])) + 4
    dr_err = np.hypot(*(run.dead_reckoning_m - run.truth_m).T)
    assert dr_err[-1] > 0.1 and np.all(np.isfinite(dr_err))


def test_readings_are_sequential_and_follow_the_srf02_model(run):
    r = run.ranges
    assert r.n_sensors == 2 and np.all(r.sensor[::2] == 0) and np.all(r.sensor[1::2] == 1)
    assert np.all(np.diff(r.t_s) >= CYCLE_S + 0.001 - 1e-12)  # fired one after the other
    assert r.t_s[-1] <= 52.0 and r.t_s.size > 600
    both = np.isfinite(r.range_m) & np.isfinite(run.range_truth_m)
    assert both.mean() > 0.6
    mae = np.mean(np.abs(r.range_m[both] - run.range_truth_m[both]))
    assert 0.02 < mae < 0.06  # the datasheet's 3-4 cm
    # in the corridor, walking east, the right sensor (south) reads about 1 m
    east = (np.abs(run.reading_pose[:, 2]) < 0.1) & (run.reading_pose[:, 1] < 1.2)
    right = east & (r.sensor == 1) & np.isfinite(r.range_m)
    assert abs(np.median(r.range_m[right]) - np.median(run.reading_pose[right, 1])) < 0.05


def test_logs_round_trip_through_csv(run):
    s = read_step_log(io.StringIO(run.steps.to_csv()), name="steps.csv")
    g = read_range_log(io.StringIO(run.ranges.to_csv()), name="ranges.csv")
    np.testing.assert_array_equal(s.heading_rad, run.steps.heading_rad)
    np.testing.assert_array_equal(g.range_m, run.ranges.range_m)


def test_seeded_and_parametrised():
    a, b = G.simulate(rng=3), G.simulate(rng=3)
    np.testing.assert_array_equal(a.ranges.range_m, b.ranges.range_m)
    one = G.simulate(n_laps=1, marker_jitter_m=0.0, heading_noise_rad=0.0,
                     heading_drift_rad_per_step=0.0, heading_walk_rad=0.0, rng=1)  # fmt: skip
    assert len(one.steps) == 26
    np.testing.assert_allclose(one.dead_reckoning_m, one.truth_m, atol=1e-9)
    rays = G.simulate(range_method="rays", n_laps=1, rng=1)
    assert rays.params["range_method"] == "rays"


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"n_laps": 0}, "n_laps"),
        ({"step_duration_s": 0.0}, "step_duration_s"),
        ({"marker_jitter_m": -1.0}, "marker_jitter_m"),
        ({"heading_drift_rad_per_step": math.inf}, "heading_drift_rad_per_step"),
        ({"range_method": "beam"}, "range_method"),
    ],
)
def test_bad_parameters_raise(kw, match):
    with pytest.raises(InvalidParameterError, match=match):
        G.simulate(**kw)
