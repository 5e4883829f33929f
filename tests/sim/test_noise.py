"""Tests for rangekit.sim.noise."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import welch

from rangekit.errors import InvalidParameterError
from rangekit.sim.noise import make_noise, pink_noise, white_noise


def test_white_noise_unit_variance():
    x = white_noise(200_000, rng=1)
    assert x.shape == (200_000,)
    assert x.dtype == np.float64
    assert abs(x.mean()) < 0.01
    assert abs(x.var() - 1.0) < 0.02


def test_pink_noise_zero_mean_unit_variance():
    x = pink_noise(100_001, rng=2)
    assert x.shape == (100_001,)
    assert abs(x.mean()) < 1e-12
    assert x.var() == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("kind", ["white", "pink"])
def test_seeded_reproducibility(kind):
    a = make_noise(1000, kind=kind, rng=42)
    b = make_noise(1000, kind=kind, rng=42)
    c = make_noise(1000, kind=kind, rng=43)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    g = np.random.default_rng(42)
    np.testing.assert_array_equal(make_noise(1000, kind=kind, rng=g), a)
    np.testing.assert_array_equal(
        make_noise(1000, kind=kind, rng=np.random.SeedSequence(42)),
        make_noise(1000, kind=kind, rng=np.random.default_rng(np.random.SeedSequence(42))),
    )


def test_generator_state_advances():
    g = np.random.default_rng(0)
    assert not np.array_equal(white_noise(100, rng=g), white_noise(100, rng=g))


def test_make_noise_dispatches():
    np.testing.assert_array_equal(make_noise(64, rng=3), white_noise(64, rng=3))
    np.testing.assert_array_equal(make_noise(64, kind="pink", rng=3), pink_noise(64, rng=3))


def _octave_levels_db(x: np.ndarray, edges: np.ndarray) -> np.ndarray:
    f, pxx = welch(x, fs=1.0, nperseg=8192)
    return np.array(
        [10 * np.log10(pxx[(f >= lo) & (f < 2 * lo)].mean()) for lo in edges],
    )


def test_pink_noise_slope_is_minus_3_db_per_octave():
    x = pink_noise(2**21, rng=4)
    edges = 0.002 * 2.0 ** np.arange(7)  # octave bands from 0.002 to 0.256 cycles/sample
    steps = np.diff(_octave_levels_db(x, edges))
    np.testing.assert_allclose(steps, -3.01, atol=1.0)


def test_white_noise_is_flat():
    x = white_noise(2**21, rng=5)
    edges = 0.002 * 2.0 ** np.arange(7)
    steps = np.diff(_octave_levels_db(x, edges))
    np.testing.assert_allclose(steps, 0.0, atol=0.5)


@pytest.mark.parametrize("kind", ["brown", "White", "", None, 3])
def test_bad_kind_raises(kind):
    with pytest.raises(InvalidParameterError, match="kind"):
        make_noise(10, kind=kind)


@pytest.mark.parametrize("n", [0, -5, 2.5, "10", None])
def test_bad_length_raises(n):
    with pytest.raises(InvalidParameterError, match="n="):
        white_noise(n)
    with pytest.raises(InvalidParameterError, match="n="):
        pink_noise(n)


def test_pink_needs_two_samples():
    with pytest.raises(InvalidParameterError, match="n=1"):
        pink_noise(1)
    assert pink_noise(2, rng=0).shape == (2,)
    assert white_noise(1, rng=0).shape == (1,)
