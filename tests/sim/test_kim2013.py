"""Kim & Kim 2013 §V simulator: eq (14) kinematics, noise models, firing schedule, the log."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.io.duhllog import parse_beacons, read_duhl_log
from rangekit.sim.kim2013 import (
    ACCEL_MPS2,
    TRAJECTORIES,
    TURN_RATE_RADPS,
    drive,
    follow_path,
    layout,
    simulate,
)

B_W = 0.33
DT = 0.01


def eq14(pose0, v_r, v_l, dt=DT, b_w=B_W):
    """Kim & Kim 2013 eq (14), written out independently of the module."""
    x, y, phi = pose0
    out = [(x, y, phi)]
    for r, lft in zip(v_r[1:], v_l[1:], strict=True):
        d_d = dt * (r + lft) / 2.0
        d_phi = dt * (r - lft) / b_w
        x += d_d * math.cos(phi + d_phi / 2.0)
        y += d_d * math.sin(phi + d_phi / 2.0)
        phi += d_phi
        out.append((x, y, phi))
    return np.array(out)


def test_straight_drive_is_exact():
    n, v = 501, 0.37
    pose0 = (1.0, -2.0, math.pi / 6)
    poses = drive(np.full(n, v), np.full(n, v), pose0=pose0, dt_s=DT, wheel_base_m=B_W)
    t = np.arange(n) * DT
    np.testing.assert_allclose(poses[:, 0], 1.0 + v * t * math.cos(math.pi / 6), atol=1e-12)
    np.testing.assert_allclose(poses[:, 1], -2.0 + v * t * math.sin(math.pi / 6), atol=1e-12)
    assert np.all(poses[:, 2] == math.pi / 6)


def test_pure_rotation_is_exact():
    n, v = 301, 0.2
    poses = drive(np.full(n, v), np.full(n, -v), pose0=(0.5, 0.25, -1.0), dt_s=DT)
    assert np.all(poses[:, 0] == 0.5) and np.all(poses[:, 1] == 0.25)
    t = np.arange(n) * DT
    np.testing.assert_allclose(poses[:, 2], -1.0 + 2 * v * t / B_W, atol=1e-12)


def test_drive_rejects_bad_input():
    with pytest.raises(InvalidParameterError, match="differ in length"):
        drive([0.0, 1.0], [0.0])
    with pytest.raises(InvalidParameterError, match="wheel_base_m=0"):
        drive([0.0, 1.0], [0.0, 1.0], wheel_base_m=0)
    with pytest.raises(InvalidParameterError, match="pose0"):
        drive([0.0, 1.0], [0.0, 1.0], pose0=(0, 0))


@pytest.mark.parametrize("trajectory", [1, 2, 3, 4])
def test_truth_is_eq14_of_the_true_speeds_and_clean_odometry_reproduces_it(trajectory):
    run = simulate(trajectory, k_v_m=0.0, rng=0)
    ref = eq14(run.true_pose[0], run.v_right_true, run.v_left_true)
    np.testing.assert_allclose(run.true_pose, ref, rtol=0, atol=1e-12)
    assert np.array_equal(run.v_right, run.v_right_true)
    assert np.array_equal(run.v_left, run.v_left_true)
    again = drive(run.v_right, run.v_left, pose0=run.true_pose[0], dt_s=DT, wheel_base_m=B_W)
    np.testing.assert_allclose(again, run.true_pose, rtol=0, atol=1e-12)
    np.testing.assert_allclose(run.t_s, np.arange(run.t_s.size) * DT, atol=1e-12)


@pytest.mark.parametrize("trajectory", [1, 2, 3, 4])
def test_path_following_reaches_the_nominal_speed_within_the_limits(trajectory):
    tr = TRAJECTORIES[trajectory]
    run = simulate(trajectory, rng=0)
    v = (run.v_right_true + run.v_left_true) / 2
    w = (run.v_right_true - run.v_left_true) / B_W
    assert run.nominal_speed_mps == tr.speed_mps
    assert abs(v.max() - tr.speed_mps) < 1e-9
    assert np.mean(v > 0.99 * tr.speed_mps) > 0.3  # cruising at the nominal speed
    assert v[0] == v[-1] == 0.0 and w[-1] == 0.0  # from rest to rest
    assert np.all(v >= 0.0)
    assert np.max(np.abs(np.diff(v))) <= ACCEL_MPS2 * DT + 1e-12  # ramps
    assert np.max(np.abs(w)) <= TURN_RATE_RADPS + 1e-12
    assert np.max(np.abs(np.diff(run.v_right_true))) < 0.01  # smooth wheel speeds
    wp = tr.waypoints_m
    assert np.hypot(*(run.true_pose[-1, :2] - wp[-1])) < 0.01
    np.testing.assert_allclose(run.true_pose[0, :2], wp[0])
    # Stays on the path (corners are cut by at most ~0.2 m).
    seg_a, seg_d = wp[:-1], np.diff(wp, axis=0)
    p = run.true_pose[::10, None, :2]
    u = np.clip(np.sum((p - seg_a) * seg_d, axis=2) / np.sum(seg_d**2, axis=1), 0, 1)
    off = np.min(np.hypot(*(seg_a + u[..., None] * seg_d - p).transpose(2, 0, 1)), axis=1)
    assert off.max() < 0.2
    length = np.sum(np.hypot(*seg_d.T))
    assert 10.0 <= length <= 25.0


def test_odometry_noise_variance_is_k_v_v_over_dt():
    """Monte-Carlo over the four runs (about 17,700 samples per wheel): per wheel and per
    speed band, (v_meas - v_true) / sqrt(k_v |v| / dT) has mean 0 and variance 1."""
    k_v = 4e-4
    z = {"right": [], "left": []}
    speed = {"right": [], "left": []}
    zero = []
    for trajectory in (1, 2, 3, 4):
        run = simulate(trajectory, k_v_m=k_v, rng=10 + trajectory)
        for wheel, meas, true in [
            ("right", run.v_right, run.v_right_true),
            ("left", run.v_left, run.v_left_true),
        ]:
            moving = np.abs(true) > 0
            z[wheel].append((meas - true)[moving] / np.sqrt(k_v * np.abs(true[moving]) / DT))
            speed[wheel].append(np.abs(true[moving]))
            zero.append((meas - true)[~moving])
    for wheel in ("right", "left"):
        zw, sw = np.concatenate(z[wheel]), np.concatenate(speed[wheel])
        assert zw.size > 15000
        for band in (sw < 0.3, (sw >= 0.3) & (sw < 0.5), sw >= 0.5):
            zb = zw[band]
            assert zb.size > 1000
            assert abs(np.mean(zb)) < 4 / math.sqrt(zb.size)
            assert abs(np.var(zb) - 1.0) < 4 * math.sqrt(2 / zb.size)
        assert abs(np.var(zw) - 1.0) < 4 * math.sqrt(2 / zw.size)  # about 4 %
    assert np.all(np.concatenate(zero) == 0.0)  # a wheel at rest reads 0


def test_noise_scales_with_k_v():
    a = simulate(2, k_v_m=4e-4, rng=7)
    b = simulate(2, k_v_m=1.6e-3, rng=7)  # 4x the variance, same draws: 2x the error
    np.testing.assert_allclose(b.v_right - b.v_right_true, 2 * (a.v_right - a.v_right_true))


@pytest.mark.parametrize("trajectory", [2, 3])
def test_distances_equal_geometry_at_zero_sigma(trajectory):
    run = simulate(trajectory, sigma_dd_m=0.0, rng=1)
    assert np.array_equal(run.distance_m, run.distance_true_m)
    pose = run.true_pose[run.distance_k]
    txyz = run.beacons.position(run.distance_tx)
    for ell in range(3):  # eqs (1)-(3): receivers at 0, 120, 240 degrees, r_R = 0.19 m
        g = pose[:, 2] + 2 * math.pi * ell / 3
        dx = txyz[:, 0] - (pose[:, 0] + 0.19 * np.cos(g))
        dy = txyz[:, 1] - (pose[:, 1] + 0.19 * np.sin(g))
        np.testing.assert_allclose(
            run.distance_m[:, ell], np.sqrt(dx**2 + dy**2 + txyz[:, 2] ** 2), atol=1e-12
        )


def test_distance_noise_is_sigma_dd():
    run = simulate(1, sigma_dd_m=0.01, rng=2)
    e = (run.distance_m - run.distance_true_m).ravel()
    assert e.size > 700
    assert abs(np.std(e) - 0.01) < 0.001 and abs(np.mean(e)) < 0.0015


def _audible(run, k, radius):
    d = np.hypot(*(run.beacons.xyz_m[:, :2] - run.true_pose[k, :2]).T)
    return np.sort(run.beacons.ids[d <= radius])


@pytest.mark.parametrize("fire_rate_hz,every", [(5.0, 20), (10.0, 10)])
def test_firing_rate_and_round_robin_order(fire_rate_hz, every):
    run = simulate(1, fire_rate_hz=fire_rate_hz, rng=3)
    assert np.all(run.distance_k % every == 0)
    assert run.distance_k[0] == 0
    # Every slot fires (3-6 Txs are always audible on trajectory 1 at 4 m).
    assert np.array_equal(run.distance_k, np.arange(0, run.t_s.size, every))
    np.testing.assert_allclose(np.diff(run.distance_t_s), 1 / fire_rate_hz, atol=1e-9)
    last = None
    for k, tx in zip(run.distance_k, run.distance_tx, strict=True):
        aud = _audible(run, k, 4.0)
        later = aud[aud > last] if last is not None else aud
        assert tx == (later[0] if later.size else aud[0])
        last = tx
    assert set(run.distance_tx.tolist()) == set(range(1, 7))


def test_audible_radius_is_respected_and_empty_slots_are_skipped():
    radius = 1.2
    run = simulate(3, audible_radius_m=radius, rng=4)
    slots = np.arange(0, run.t_s.size, 20)
    heard = [k for k in slots if _audible(run, k, radius).size]
    assert 0 < len(heard) < slots.size  # some slots have no Tx within 1.2 m
    assert np.array_equal(run.distance_k, heard)
    for k, tx in zip(run.distance_k, run.distance_tx, strict=True):
        assert tx in _audible(run, k, radius)


@pytest.mark.parametrize("trajectory", [1, 2, 3, 4])
def test_two_or_more_txs_are_always_audible(trajectory):
    run = simulate(trajectory, rng=0)
    counts = [_audible(run, k, 4.0).size for k in range(0, run.t_s.size, 20)]
    assert min(counts) >= 2


def test_layouts():
    six, ten = layout("six"), layout("ten")
    assert six.ids.tolist() == list(range(1, 7)) and ten.ids.tolist() == list(range(1, 11))
    assert np.all(six.xyz_m[:, 2] == 2.011) and np.all(ten.xyz_m[:, 2] == 1.887)
    assert {t.layout for n, t in TRAJECTORIES.items() if n != 3} == {"six"}
    assert TRAJECTORIES[3].layout == "ten"
    assert [TRAJECTORIES[n].speed_mps for n in (1, 2, 3, 4)] == [0.37, 0.37, 0.37, 1.02]
    with pytest.raises(InvalidParameterError, match="layout='eight'"):
        layout("eight")


def test_seeds_are_reproducible():
    a, b, c = simulate(2, rng=5), simulate(2, rng=5), simulate(2, rng=np.random.default_rng(6))
    for f in ("v_right", "v_left", "distance_m", "distance_tx", "true_pose"):
        assert np.array_equal(getattr(a, f), getattr(b, f))
    assert not np.array_equal(a.v_right, c.v_right)
    assert not np.array_equal(a.distance_m, c.distance_m)


def test_t_max_slices_the_same_run():
    full, part = simulate(4, rng=8), simulate(4, t_max_s=3.0, rng=8)
    assert part.t_s[-1] == pytest.approx(3.0) and part.t_s.size == 301
    assert np.array_equal(part.true_pose, full.true_pose[:301])
    assert np.array_equal(part.v_right, full.v_right[:301])  # same odometry draws
    assert np.array_equal(part.distance_tx, full.distance_tx[: part.distance_tx.size])


def test_log_round_trip():
    run = simulate(4, rng=9)
    log = read_duhl_log(io.StringIO(run.to_log().to_csv()), name="kim.csv")
    assert np.array_equal(log.odometry.t_s, run.t_s)
    assert np.array_equal(log.odometry.v_right_mps, run.v_right)
    assert np.array_equal(log.odometry.v_left_mps, run.v_left)
    assert np.array_equal(log.distances.t_s, run.distance_t_s)
    assert np.array_equal(log.distances.tx, run.distance_tx)
    assert np.array_equal(log.distances.d_m, run.distance_m)
    b = parse_beacons(run.beacons.to_json())
    assert np.array_equal(b.xyz_m, run.beacons.xyz_m)


def test_audio_distances_are_within_a_centimetre():
    run = simulate(4, distance_source="audio", snr_db=20.0, t_max_s=0.8, rng=10)
    assert run.distance_m.shape == (5, 3)
    assert not np.any(np.isnan(run.distance_m))
    assert np.max(np.abs(run.distance_m - run.distance_true_m)) < 0.01
    assert not np.array_equal(run.distance_m, run.distance_true_m)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"trajectory": 5}, r"trajectory=5 must be one of \[1, 2, 3, 4\]"),
        ({"trajectory": True}, r"trajectory=True"),
        ({"sigma_dd_m": -0.1}, r"sigma_dd_m=-0.1 must be finite and >= 0"),
        ({"k_v_m": float("nan")}, r"k_v_m=nan"),
        ({"wheel_base_m": 0.0}, r"wheel_base_m=0.0 must be finite and > 0"),
        ({"r_R_m": -1}, r"r_R_m=-1"),
        ({"odo_rate_hz": 0}, r"odo_rate_hz=0"),
        ({"fire_rate_hz": 3.0}, r"odo_rate_hz / fire_rate_hz = 33.3333 must be an integer"),
        ({"fire_rate_hz": 200.0}, r"= 0.5 must be an integer >= 1"),
        ({"audible_radius_m": 0}, r"audible_radius_m=0"),
        ({"distance_source": "lidar"}, r"distance_source='lidar' must be 'model' or 'audio'"),
        ({"snr_db": 1e9}, r"snr_db=1000000000.0 must be within"),
        ({"t_max_s": -1.0}, r"t_max_s=-1.0"),
    ],
)
def test_parameter_errors(kwargs, match):
    kwargs = {"trajectory": 1, **kwargs}
    with pytest.raises(InvalidParameterError, match=match):
        simulate(**kwargs)


def test_follow_path_rejects_bad_waypoints():
    with pytest.raises(InvalidParameterError, match=r"\(k, 2\) array with k >= 2"):
        follow_path([[0.0, 0.0]], 0.3)
    with pytest.raises(InvalidParameterError, match="zero-length segment"):
        follow_path([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0]], 0.3)
    with pytest.raises(InvalidParameterError, match="not finished within"):
        follow_path([[0.0, 0.0], [10.0, 0.0]], 0.3, max_time_s=5.0)
