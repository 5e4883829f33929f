"""SRF02 echo recordings: renderer + pulse-echo ranging against the SRF02 model's truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.floorplan import FloorPlan
from rangekit.ranging.ultrasonic import range_echo
from rangekit.sensors.srf02 import SRF02, model_range
from rangekit.sim.ultrasonic import render_echo, specular_echoes

WALL = FloorPlan.from_walls([((0.0, -50.0), (0.0, 50.0))])


def _poses(d, rng, tilt_deg=5.0):
    """Facing the wall x = 0 from x = d, heading pi (towards -x), tilted a little."""
    d = np.asarray(d, dtype=float)
    tilt = np.radians(rng.uniform(-tilt_deg, tilt_deg, d.shape))
    return np.stack([d, rng.uniform(-2, 2, d.shape), math.pi + tilt], axis=1)


def test_echo_rms_within_1cm_between_15cm_and_6m():
    rng = np.random.default_rng(11)
    d = rng.uniform(0.16, 5.95, 60)
    poses = _poses(d, rng)
    sim = render_echo(WALL, poses, snr_db=20.0, rng=rng)
    truth = np.array([w["distance_m"] for w in sim.truth["windows"]], dtype=float)
    # A few tilted poses near 6 m are beyond the off-axis maximum range (6 m x D(psi)^2).
    ok = np.isfinite(truth)
    assert ok.sum() >= 55
    rows = range_echo(sim.x, fs=sim.fs, period_s=SRF02().cycle_s)
    got = np.array([r.distance_m for r in rows])[ok]
    err = got - truth[ok]
    assert np.all(np.isfinite(got))
    assert math.sqrt(np.mean(err**2)) <= 0.01
    # The reported sigma is honest: |error| within 4 sigma for every cycle.
    sig = np.array([r.sigma_m for r in rows])[ok]
    assert np.all(np.abs(err) <= 4 * sig + 1e-4)


def test_out_of_range_inside_15cm_and_beyond_6m():
    rng = np.random.default_rng(2)
    d = np.array([0.08, 0.12, 6.3, 7.5, 12.0])
    poses = _poses(d, rng, tilt_deg=0.0)
    sim = render_echo(WALL, poses, snr_db=30.0, rng=rng)
    assert all(w["distance_m"] is None for w in sim.truth["windows"])
    rows = range_echo(sim.x, fs=sim.fs, period_s=SRF02().cycle_s)
    assert all(math.isnan(r.distance_m) and math.isnan(r.sigma_m) for r in rows)
    # ... while the echoes are in the recording (beyond 6 m the wall still answers).
    assert all(w["echoes"] for w in sim.truth["windows"][2:4])


def test_truth_is_the_specular_model():
    poses = np.array([[1.0, 0.0, math.pi], [2.5, 1.0, math.pi + 0.1]])
    sim = render_echo(WALL, poses, snr_db=None)
    want = model_range(WALL, poses, SRF02(), method="specular")
    got = [w["distance_m"] for w in sim.truth["windows"]]
    np.testing.assert_allclose(got, want)
    np.testing.assert_allclose(got, [1.0, 2.5])


def test_specular_echoes_skip_hidden_walls_and_walls_behind():
    plan = FloorPlan.from_walls(
        [((2, -5), (2, 5)), ((4, -5), (4, 5)), ((-3, -5), (-3, 5)), ((1, -0.2), (1, 0.2))]
    )
    d, psi, amp = specular_echoes(plan, (0.0, 0.0, 0.0))
    # x = 1 (short piece) hides the x = 2 and x = 4 perpendicular feet; x = -3 is behind.
    assert d.tolist() == [1.0]
    assert psi.tolist() == [0.0]
    assert amp[0] == pytest.approx(0.5)


def test_render_echo_validation():
    from rangekit.errors import InvalidParameterError

    with pytest.raises(InvalidParameterError, match="poses"):
        render_echo(WALL, [[1.0, 2.0]])
    with pytest.raises(InvalidParameterError, match="snr_db"):
        render_echo(WALL, [1.0, 0.0, 0.0], snr_db=1000.0)
