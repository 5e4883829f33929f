"""Tests for rangekit.sensors.srf02 (beam, range model, errors, firing, crosstalk)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.special import j1

from rangekit import _raycast
from rangekit.errors import InvalidParameterError
from rangekit.floorplan import FloorPlan, load_floorplan
from rangekit.physics import speed_of_sound_m_s
from rangekit.sensors.srf02 import (
    BEAM_WIDTH_RAD,
    CYCLE_S,
    SOURCE_CROSS_WALL,
    SOURCE_LEAK,
    SOURCE_NONE,
    SOURCE_OWN,
    SRF02,
    WAVELENGTH_M,
    beam_pattern,
    model_range,
    piston_ka,
    read_ranges,
    schedule_firings,
    simulate_readings,
)

CORRIDOR = Path(__file__).resolve().parents[2] / "fixtures_audio" / "corridor_plan.json"
C_24 = speed_of_sound_m_s(24.0)


def _wall_at(d: float, half_length: float = 20.0) -> FloorPlan:
    """A wall along x = d (the sensor sits at the origin facing +x)."""
    return FloorPlan.from_walls([((d, -half_length), (d, half_length))])


@pytest.fixture(params=["numpy", "numba"])
def path_kind(request, monkeypatch):
    monkeypatch.setattr(_raycast, "NUMBA_MIN_PAIRS", 10**12 if request.param == "numpy" else 0)
    return request.param


# ----------------------------------------------------------------------- parameters


def test_datasheet_constants_and_defaults():
    assert WAVELENGTH_M == pytest.approx(0.00865)
    assert math.degrees(BEAM_WIDTH_RAD) == pytest.approx(55.0)
    assert CYCLE_S == 0.070
    s = SRF02()
    assert (s.n_rays, s.min_range_m, s.max_range_m, s.cycle_s) == (7, 0.15, 6.0, 0.070)
    assert s.resolution_m == 0.01 and s.slip_step_m == pytest.approx(0.00865)
    assert s.incidence_window_rad == pytest.approx(math.radians(55) / 14)
    # Ray centres of lambda equal sub-sectors: the windows tile the aperture exactly.
    psi = s.ray_offsets_rad
    assert psi[0] - s.incidence_window_rad == pytest.approx(-s.aperture_rad / 2)
    assert psi[-1] + s.incidence_window_rad == pytest.approx(s.aperture_rad / 2)
    np.testing.assert_allclose(np.diff(psi), 2 * s.incidence_window_rad)
    hash(s)


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"aperture_rad": 0.0}, r"aperture_rad=0\.0 must be in \(0, pi\)"),
        ({"aperture_rad": 4.0}, r"aperture_rad=4\.0 must be within"),
        ({"n_rays": 0}, r"n_rays=0 must be >= 1"),
        ({"n_rays": 2.5}, r"n_rays=2\.5 must be an integer"),
        ({"min_range_m": -1}, r"min_range_m=-1 must be finite and > 0"),
        ({"max_range_m": 0.1}, r"max_range_m=0\.1 must be > min_range_m=0\.15"),
        ({"cycle_s": 0}, r"cycle_s=0 must be finite and > 0"),
        ({"noise_sigma_m": -0.01}, r"noise_sigma_m=-0\.01 must be finite and >= 0"),
        ({"slip_probs": (0.5, 0.5)}, r"slip_probs=\(0\.5, 0\.5\) must be 3 probabilities"),
        ({"slip_probs": 0.5}, r"slip_probs=0\.5 must be 3 probabilities"),
        ({"slip_probs": (0.5, 1.5, 0)}, r"slip_probs\[1\]=1\.5 must be within \[0\.0, 1\.0\]"),
        ({"slip_probs": (0.5, 0.4, 0.2)}, r"must sum to <= 1"),
        ({"slip_step_m": math.nan}, r"slip_step_m=nan must be finite"),
        ({"resolution_m": -0.01}, r"resolution_m=-0\.01 must be finite and >= 0"),
    ],
)
def test_sensor_validation(kw, message):
    with pytest.raises(InvalidParameterError, match=message):
        SRF02(**kw)


def test_beam_pattern_is_a_piston_with_55_degree_width():
    ka = piston_ka()
    x = 2.0 * j1(ka * math.sin(math.radians(27.5))) / (ka * math.sin(math.radians(27.5)))
    assert x == pytest.approx(0.5, abs=1e-12)
    psi = np.linspace(-1.5, 1.5, 301)
    psi = psi[psi != 0.0]
    u = ka * np.sin(psi)
    np.testing.assert_allclose(beam_pattern(psi), 2 * j1(u) / u, atol=1e-12)
    assert 20 * math.log10(beam_pattern(math.radians(27.5))) == pytest.approx(-6.02, abs=0.01)
    assert beam_pattern(0.0) == 1.0 and beam_pattern(math.pi) == 0.0
    # A narrow beam needs |ka sin psi| > 10: the scipy branch.
    narrow = math.radians(8.0)
    big = np.array([0.05, 0.6, 1.2])
    u = piston_ka(narrow) * np.sin(big)
    np.testing.assert_allclose(beam_pattern(big, beam_width_rad=narrow), 2 * j1(u) / u, atol=1e-12)
    with pytest.raises(InvalidParameterError, match="beam_width_rad"):
        piston_ka(0.0)


def test_max_range_follows_two_way_pattern():
    s = SRF02()
    psi = np.radians([0.0, 10.0, 27.5])
    np.testing.assert_allclose(s.max_range_at(psi), 6.0 * beam_pattern(psi) ** 2)
    assert s.max_range_at(math.radians(27.5)) == pytest.approx(1.5)


# ----------------------------------------------------------------------- range model


@pytest.mark.parametrize("d", [0.5, 1.0, 2.7, 5.9])
@pytest.mark.parametrize("n_rays", [7, 6, 1])
def test_facing_a_wall(d, n_rays, path_kind):
    s = SRF02(n_rays=n_rays)
    plan = _wall_at(d)
    assert float(model_range(plan, (0.0, 0.0, 0.0), s, method="specular")) == pytest.approx(d)
    r = float(model_range(plan, (0.0, 0.0, 0.0), s))
    if n_rays % 2:
        assert r == pytest.approx(d, rel=1e-14)  # the central ray is perpendicular
        return
    # Even lambda: the rays nearest the axis meet the wall at the edge of the window.
    w = s.incidence_window_rad
    if d / math.cos(w) <= s.max_range_at(w):
        assert d <= r <= d / math.cos(w) + 1e-12
        assert r == pytest.approx(d / math.cos(w))
    else:  # 5.9 m at 4.6 deg off axis is beyond that ray's 5.86 m maximum range
        assert math.isnan(r)


def test_out_of_range_far_near_and_behind(path_kind):
    s = SRF02()
    pose = (0.0, 0.0, 0.0)
    for method in ("rays", "specular"):
        assert math.isnan(model_range(_wall_at(6.01), pose, s, method=method))
        assert math.isnan(model_range(_wall_at(0.14), pose, s, method=method))
        assert model_range(_wall_at(0.16), pose, s, method=method) == pytest.approx(0.16)
        assert math.isnan(model_range(_wall_at(2.0), (0.0, 0.0, math.pi), s, method=method))
        assert math.isnan(model_range(FloorPlan.from_walls([]), pose, s, method=method))


def test_tilting_the_sensor(path_kind):
    s = SRF02()
    plan = _wall_at(2.0)
    half = s.aperture_rad / 2
    # Beyond the half aperture: no ray meets the wall within the window, no foot in the beam.
    for tilt in (half + s.incidence_window_rad + 0.01, -(half + 0.05), 1.2):
        assert math.isnan(model_range(plan, (0, 0, tilt), s))
        assert math.isnan(model_range(plan, (0, 0, tilt), s, method="specular"))
    # Inside the beam the specular echo is the perpendicular distance, limited by
    # max_range(psi); the rays method needs a ray within +-alpha/(2 lambda) of the normal.
    tilt = math.radians(10.0)
    assert model_range(plan, (0, 0, tilt), s, method="specular") == pytest.approx(2.0)
    ray = s.ray_offsets_rad[2]  # -7.86 deg: 2.14 deg off the wall normal
    assert model_range(plan, (0, 0, tilt), s) == pytest.approx(2.0 / math.cos(tilt + ray))
    tilt = math.radians(5.0)  # between rays: 5 deg and 2.86 deg off -> the second one
    assert model_range(plan, (0, 0, tilt), s) == pytest.approx(
        2.0 / math.cos(tilt - 2 * s.incidence_window_rad)
    )
    # Off axis the maximum range shrinks: at 25 deg it is 6 D(25 deg)^2 = 1.93 m.
    tilt = math.radians(25.0)
    limit = float(s.max_range_at(tilt))
    assert 1.8 < limit < 1.95
    assert model_range(_wall_at(limit - 0.01), (0, 0, tilt), s, method="specular") == (
        pytest.approx(limit - 0.01)
    )
    assert math.isnan(model_range(_wall_at(limit + 0.01), (0, 0, tilt), s, method="specular"))


def test_mount_angle_and_corridor_with_door(path_kind):
    plan = load_floorplan(CORRIDOR)
    s = SRF02()
    # Walking east along the corridor centre line, left sensor (+90 deg), right sensor (-90).
    xs = np.array([1.0, 2.45, 4.0, 7.0])
    poses = np.c_[xs, np.ones_like(xs), np.zeros_like(xs)]
    for method in ("rays", "specular"):
        left = model_range(plan, poses, s, mount_angle_rad=math.pi / 2, method=method)
        right = model_range(plan, poses, s, mount_angle_rad=-math.pi / 2, method=method)
        np.testing.assert_allclose(left, [1.0, 5.0, 1.0, 1.0])  # 5 m: through the door
        np.testing.assert_allclose(right, [1.0, 1.0, 1.0, 1.0])


def test_occluded_perpendicular_is_not_heard(path_kind):
    # The far wall's perpendicular foot lies behind a short near wall whose own foot is
    # outside the beam; the near wall is oblique to all rays: nothing is heard.
    far = ((3.0, -5.0), (3.0, 5.0))
    near = ((1.0, -0.3), (1.6, 0.3))  # 45 deg, covers the axis
    plan = FloorPlan.from_walls([far, near])
    s = SRF02()
    assert math.isnan(model_range(plan, (0, 0, 0), s, method="specular"))
    assert math.isnan(model_range(plan, (0, 0, 0), s))
    assert model_range(FloorPlan.from_walls([far]), (0, 0, 0), s, method="specular") == 3.0


def _parallel_walls_plan() -> tuple[FloorPlan, float]:
    """Two parallel walls y = 0 and y = 1 and a short wall C across the twice-bounced ray.

    From (0, 0.5) heading -45 deg, the axis ray meets y = 0 at 45 deg incidence (outside
    the window), then y = 1, then C perpendicularly 1 m after the second bounce.
    """
    q = np.array([1.5, 1.0]) + np.array([1.0, -1.0]) / math.sqrt(2.0)
    t = np.array([1.0, 1.0]) / math.sqrt(2.0)
    walls = [((-1, 0), (6, 0)), ((-1, 1), (6, 1)), (tuple(q - 0.2 * t), tuple(q + 0.2 * t))]
    path = 0.5 * math.sqrt(2.0) + math.sqrt(2.0) + 1.0
    return FloorPlan.from_walls(walls), path


def test_secondary_reflections_give_the_long_path(path_kind):
    plan, path = _parallel_walls_plan()
    s = SRF02()
    pose = (0.0, 0.5, -math.pi / 4)
    assert math.isnan(model_range(plan, pose, s))
    assert math.isnan(model_range(plan, pose, s, secondary=True, max_bounces=1))
    assert model_range(plan, pose, s, secondary=True) == pytest.approx(path, rel=1e-12)
    assert model_range(plan, pose, s, secondary=True, max_bounces=4) == pytest.approx(path)
    # The path must fit in the maximum range.
    short = SRF02(max_range_m=path - 0.01)
    assert math.isnan(model_range(plan, pose, short, secondary=True))
    # One bounce off a wall at 45 deg onto a perpendicular wall (Girard Fig. 3b).
    b = np.array([1.0, 0.0]) + 1.5 * np.array([1.0, 1.0]) / math.sqrt(2.0)
    t = np.array([-1.0, 1.0]) / math.sqrt(2.0)
    fig3b = FloorPlan.from_walls([((-1, 0), (6, 0)), (tuple(b - t), tuple(b + t))])
    pose = (0.0, 1.0, -math.pi / 4)
    assert math.isnan(model_range(fig3b, pose, s))
    got = model_range(fig3b, pose, s, secondary=True, max_bounces=1)
    assert got == pytest.approx(math.sqrt(2.0) + 1.5, rel=1e-12)


def test_secondary_keeps_direct_echoes():
    plan = _wall_at(2.0)
    s = SRF02()
    assert model_range(plan, (0, 0, 0), s, secondary=True) == pytest.approx(2.0)


def test_vectorised_poses_equal_one_by_one(monkeypatch):
    plan = load_floorplan(CORRIDOR)
    rng = np.random.default_rng(3)
    poses = np.c_[rng.uniform(0.2, 9.8, 60), rng.uniform(0.2, 5.8, 60), rng.uniform(-4, 4, 60)]
    s = SRF02()
    for kw in ({}, {"method": "specular"}, {"secondary": True}):
        batch = model_range(plan, poses.reshape(3, 20, 3), s, mount_angle_rad=0.3, **kw)
        assert batch.shape == (3, 20)
        single = [float(model_range(plan, p, s, mount_angle_rad=0.3, **kw)) for p in poses]
        np.testing.assert_array_equal(batch.reshape(-1), single)
        assert np.isfinite(batch).mean() > 0.2
        monkeypatch.setattr(_raycast, "NUMBA_MIN_PAIRS", 0)
        fast = model_range(plan, poses.reshape(3, 20, 3), s, mount_angle_rad=0.3, **kw)
        np.testing.assert_allclose(fast, batch, rtol=1e-12, equal_nan=True)
        monkeypatch.setattr(_raycast, "NUMBA_MIN_PAIRS", 10**12)


def test_model_range_errors():
    plan = _wall_at(2.0)
    with pytest.raises(InvalidParameterError, match="plan must be a FloorPlan"):
        model_range([], (0, 0, 0))
    with pytest.raises(InvalidParameterError, match="sensor must be an SRF02"):
        model_range(plan, (0, 0, 0), "srf02")
    with pytest.raises(InvalidParameterError, match=r"pose must have shape \(3,\)"):
        model_range(plan, (0, 0))
    with pytest.raises(InvalidParameterError, match="pose contains NaN"):
        model_range(plan, (0, np.nan, 0))
    with pytest.raises(InvalidParameterError, match="method='cone' must be"):
        model_range(plan, (0, 0, 0), method="cone")
    with pytest.raises(InvalidParameterError, match="secondary=True needs method='rays'"):
        model_range(plan, (0, 0, 0), method="specular", secondary=True)
    with pytest.raises(InvalidParameterError, match="max_bounces=0 must be >= 1"):
        model_range(plan, (0, 0, 0), secondary=True, max_bounces=0)
    with pytest.raises(InvalidParameterError, match="mount_angle_rad=inf must be finite"):
        model_range(plan, (0, 0, 0), mount_angle_rad=math.inf)


# ----------------------------------------------------------------------- error model


def test_read_ranges_typical_error_is_3_to_4_cm():
    rng = np.random.default_rng(11)
    true = rng.uniform(0.3, 5.5, 200_000)
    r = read_ranges(true, rng=12)
    mae = np.mean(np.abs(r - true))
    assert 0.03 <= mae <= 0.04
    assert mae == pytest.approx(0.035, abs=0.002)
    assert np.mean(r - true) == pytest.approx(0.0052, abs=0.001)  # slips only lengthen
    np.testing.assert_allclose(r * 100, np.round(r * 100), atol=1e-9)  # whole centimetres


def test_read_ranges_parts_of_the_model():
    true = np.array([np.nan, 1.0, 2.004, np.nan, 0.15])
    exact = SRF02(noise_sigma_m=0.0, slip_probs=(0.0, 0.0, 0.0))
    np.testing.assert_array_equal(read_ranges(true, exact, rng=0), [np.nan, 1.0, 2.0, np.nan, 0.15])
    # Slips only: whole wavelengths, one to three of them.
    slips = SRF02(noise_sigma_m=0.0, slip_probs=(0.2, 0.2, 0.2), resolution_m=0.0)
    r = read_ranges(np.full(20_000, 2.0), slips, rng=1)
    k = (r - 2.0) / WAVELENGTH_M
    np.testing.assert_allclose(k, np.round(k), atol=1e-9)
    counts = np.bincount(np.round(k).astype(int), minlength=4) / k.size
    np.testing.assert_allclose(counts, [0.4, 0.2, 0.2, 0.2], atol=0.015)
    # Noise never reports below the ring-down minimum; seeded and shape-preserving.
    noisy = read_ranges(np.full((50, 40), 0.16), rng=2)
    assert noisy.shape == (50, 40) and noisy.min() >= 0.15
    np.testing.assert_array_equal(read_ranges(true, rng=3), read_ranges(true, rng=3))
    with pytest.raises(InvalidParameterError, match="true_ranges_m must be >= 0"):
        read_ranges([-1.0])
    with pytest.raises(InvalidParameterError, match="true_ranges_m must be >= 0"):
        read_ranges([np.inf])
    with pytest.raises(InvalidParameterError, match="sensor must be an SRF02"):
        read_ranges([1.0], sensor=3)


# ------------------------------------------------------------------ firing, crosstalk


def test_sequential_schedule():
    t = schedule_firings(2, 100, rng=4)
    assert t.shape == (100, 2)
    flat = t.reshape(-1)
    assert 0.001 <= flat[0] <= 0.004
    gaps = np.diff(flat)
    assert gaps.min() >= CYCLE_S + 0.001 and gaps.max() <= CYCLE_S + 0.004
    np.testing.assert_array_equal(t, schedule_firings(2, 100, rng=4))


def test_simultaneous_schedule():
    t = schedule_firings(3, 100, mode="simultaneous", rng=5)
    assert t.shape == (100, 3)
    spread = np.ptp(t, axis=1)
    assert spread.max() <= 0.003 and spread.mean() > 0.001
    # The next cycle's commands leave only after every result came back.
    assert np.all(t[1:].min(axis=1) - t[:-1].max(axis=1) >= CYCLE_S + 0.002)
    assert t[0].min() >= 0.001


def test_schedule_errors():
    with pytest.raises(InvalidParameterError, match="mode='both' must be"):
        schedule_firings(2, 3, mode="both")
    with pytest.raises(InvalidParameterError, match="n_sensors=0 must be >= 1"):
        schedule_firings(0, 3)
    with pytest.raises(InvalidParameterError, match=r"usb_latency_s=\(0\.004, 0\.001\) must have"):
        schedule_firings(2, 3, usb_latency_s=(0.004, 0.001))
    with pytest.raises(InvalidParameterError, match="must be a pair"):
        schedule_firings(2, 3, usb_latency_s=0.001)
    with pytest.raises(InvalidParameterError, match="cycle_s=-1 must be finite and > 0"):
        schedule_firings(2, 3, cycle_s=-1)


def test_back_to_back_crosstalk_sequential_vs_simultaneous():
    d = np.array([1.5, 2.0])  # left and right walls of a corridor
    seq = simulate_readings(schedule_firings(2, 200, rng=6), d)
    assert np.all(seq.source == SOURCE_OWN)
    np.testing.assert_allclose(seq.range_m, np.broadcast_to(d, (200, 2)), rtol=1e-12)

    fire = schedule_firings(2, 200, mode="simultaneous", rng=7)
    sim = simulate_readings(fire, d)
    false_short = sim.range_m < d - 0.5
    assert false_short.sum() >= 60  # about 58 % of the cycles for U(1, 4) ms latencies
    assert np.all(sim.source[false_short] == SOURCE_LEAK)
    assert np.all(sim.source[~false_short] == SOURCE_OWN)
    # The false reading is the delay between the pings, plus half the leak path.
    rows, cols = np.nonzero(false_short)
    other = 1 - cols
    expected = 0.5 * C_24 * (fire[rows, other] - fire[rows, cols]) + 0.025
    np.testing.assert_allclose(sim.range_m[rows, cols], expected, rtol=1e-12)
    assert np.all((sim.range_m[false_short] > 0.15) & (sim.range_m[false_short] < 0.6))
    # At most one sensor of a pair is fooled: the one that fired first.
    assert not np.any(false_short.all(axis=1))
    assert np.all(fire[rows, cols] < fire[rows, other])


def test_crosstalk_via_walls_blanking_and_timeout():
    # Sensor 1 fires 10 ms after sensor 0; sensor 0's echo off its near wall (0.3 m) comes
    # back across to sensor 1's far wall (3 m) before sensor 1's own echo.
    out = simulate_readings([[0.0, 0.010]], [0.3, 3.0])
    assert out.source.tolist() == [[SOURCE_OWN, SOURCE_CROSS_WALL]]
    expected = 0.5 * C_24 * (2 * (0.3 + 3.0) / C_24 - 0.010)
    assert out.range_m[0, 1] == pytest.approx(expected, rel=1e-12)
    # A leak that arrives inside the ring-down blanking is not heard: 0.5 ms apart.
    out = simulate_readings([[0.0, 0.0005]], [1.0, 1.0])
    assert out.source.tolist() == [[SOURCE_OWN, SOURCE_OWN]]
    # Nothing within the cycle: out of range; NaN own ranges have no cross-wall path.
    out = simulate_readings([[0.0, 0.2]], [np.nan, 2.0])
    assert out.source.tolist() == [[SOURCE_NONE, SOURCE_OWN]]
    assert math.isnan(out.range_m[0, 0])
    out = simulate_readings([[0.0, 0.005]], [np.nan, 2.0])
    assert out.source[0, 0] == SOURCE_LEAK and out.source[0, 1] == SOURCE_OWN
    # An own echo beyond the 70 ms timer (12.1 m) is out of range.
    out = simulate_readings([[0.0]], [12.2])
    assert out.source[0, 0] == SOURCE_NONE


def test_simulate_readings_errors():
    with pytest.raises(InvalidParameterError, match=r"fire_times_s must have shape"):
        simulate_readings([0.0, 1.0], [1.0, 1.0])
    with pytest.raises(InvalidParameterError, match="fire_times_s contains NaN"):
        simulate_readings([[0.0, np.nan]], [1.0, 1.0])
    with pytest.raises(InvalidParameterError, match="does not fit fire_times_s"):
        simulate_readings([[0.0, 1.0]], [1.0, 1.0, 1.0])
    with pytest.raises(InvalidParameterError, match="ranges_m must be >= 0"):
        simulate_readings([[0.0, 1.0]], [1.0, -1.0])
    with pytest.raises(InvalidParameterError, match="leak_path_m=0 must be finite and > 0"):
        simulate_readings([[0.0, 1.0]], [1.0, 1.0], leak_path_m=0)
