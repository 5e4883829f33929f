"""Tests for rangekit.sim._fracdelay (band-limited fractional-position interpolation)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import i0

from rangekit.errors import InvalidParameterError
from rangekit.sim._fracdelay import (
    KAISER_BETA,
    _i0_series,
    _interp_kernel,
    _interp_reference,
    interp_bandlimited,
)

FS_HZ = 44_100.0
TONE_HZ = 16_000.0
START = 200.0  # first sample of the burst envelope, in samples
LENGTH = 2000.0  # envelope length in samples
TAPER = 20.0  # raised-cosine taper length in samples
N_TOTAL = 2400


def _envelope(t: np.ndarray) -> np.ndarray:
    """Raised-cosine-tapered rectangle on [START, START + LENGTH] at real times t (samples)."""
    u = np.asarray(t, dtype=np.float64) - START
    env = np.where((u >= 0.0) & (u <= LENGTH), 1.0, 0.0)
    rise = np.clip(u / TAPER, 0.0, 1.0)
    fall = np.clip((LENGTH - u) / TAPER, 0.0, 1.0)
    shape = 0.5 * (1.0 - np.cos(np.pi * np.minimum(rise, fall)))
    return env * shape


def _burst(t: np.ndarray) -> np.ndarray:
    """The analytic test signal evaluated at real sample times t."""
    return _envelope(t) * np.sin(2.0 * np.pi * TONE_HZ / FS_HZ * t)


def _rel_error_db(y: np.ndarray, ref: np.ndarray) -> float:
    return 10.0 * math.log10(np.sum((y - ref) ** 2) / np.sum(ref**2))


def test_kaiser_beta_is_kaiser_formula_for_80_db():
    assert KAISER_BETA == pytest.approx(0.1102 * (80.0 - 8.7))


def test_i0_series_matches_scipy():
    z = np.linspace(0.0, KAISER_BETA, 50)
    got = np.array([_i0_series(0.25 * v * v) for v in z])
    np.testing.assert_allclose(got, i0(z), rtol=1e-14)


@pytest.mark.parametrize(
    ("half_width", "cutoff"), [(32, 0.95), (1, 1.0), (4, 0.5), (7, 0.2), (64, 1.0)]
)
def test_kernel_matches_reference(half_width, cutoff):
    rng = np.random.default_rng(1234 + half_width)
    x = rng.standard_normal(300)
    positions = np.concatenate(
        [
            rng.uniform(-80.0, 380.0, 400),  # includes positions with no or partial support
            np.arange(-40.0, 340.0),  # exact integers
            np.arange(-40.0, 340.0) + 1e-13,  # just off integers (tiny t)
            np.arange(-40.0, 340.0) + 0.5,  # half-way points
        ]
    )
    got = _interp_kernel(x, positions, half_width, cutoff)
    ref = _interp_reference(x, positions, half_width=half_width, cutoff=cutoff)
    scale = np.max(np.abs(ref))
    assert np.max(np.abs(got - ref)) <= 1e-12 * scale


def test_public_wrapper_matches_kernel_and_coerces():
    rng = np.random.default_rng(5)
    x = rng.standard_normal(100)
    positions = rng.uniform(0.0, 99.0, 50)
    expected = _interp_kernel(x, positions, 32, 0.95)
    got = interp_bandlimited(x.tolist(), positions.tolist())
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
    # Non-contiguous and integer inputs are coerced.
    x2 = np.repeat(x, 2)[::2]
    np.testing.assert_allclose(interp_bandlimited(x2, positions), expected, rtol=0, atol=1e-12)
    y = interp_bandlimited(np.arange(10), np.array([3, 4]), cutoff=1.0)
    assert y.dtype == np.float64
    np.testing.assert_allclose(y, [3.0, 4.0], atol=1e-12)


def test_integer_positions_reproduce_bandlimited_signal():
    n = np.arange(1000.0)
    # A tone well below the cutoff, under a long smooth envelope.
    x = np.sin(2.0 * np.pi * 0.1 * n) * np.sin(np.pi * n / n.size) ** 2
    y = interp_bandlimited(x, n)
    interior = slice(64, n.size - 64)
    err = np.max(np.abs(y[interior] - x[interior]))
    assert err < 1e-3 * np.max(np.abs(x))


def test_integer_positions_exact_with_full_band_cutoff():
    x = np.random.default_rng(3).standard_normal(200)
    y = interp_bandlimited(x, np.arange(200.0), cutoff=1.0)
    np.testing.assert_allclose(y, x, rtol=0, atol=1e-14)


def test_fractional_delay_matches_analytic_signal():
    n = np.arange(float(N_TOTAL))
    x = _burst(n)
    positions = n - 37.3
    y = interp_bandlimited(x, positions)
    interior = slice(64, N_TOTAL - 64)
    assert _rel_error_db(y[interior], _burst(positions)[interior]) < -60.0


def test_clock_rate_error_matches_analytic_signal():
    n = np.arange(float(N_TOTAL))
    x = _burst(n)
    positions = n * (1.0 + 50e-6) + 10.5
    y = interp_bandlimited(x, positions)
    interior = slice(64, N_TOTAL - 64)
    assert _rel_error_db(y[interior], _burst(positions)[interior]) < -60.0


def test_delay_is_not_rounded_to_whole_samples():
    n = np.arange(float(N_TOTAL))
    x = _burst(n)
    y_frac = interp_bandlimited(x, n - 37.3)
    y_int = interp_bandlimited(x, n - 37.0)
    assert _rel_error_db(y_frac, y_int) > -20.0


def test_positions_outside_signal_give_zero():
    x = np.ones(50)
    positions = np.array([-1e12, -32.0, 50.0 + 31.0 + 1.0, 1e300, -1e300])
    np.testing.assert_array_equal(interp_bandlimited(x, positions), np.zeros(5))
    # Just inside the support a contribution appears.
    assert interp_bandlimited(x, np.array([-31.5]))[0] != 0.0


def test_empty_inputs():
    assert interp_bandlimited(np.ones(5), np.array([])).shape == (0,)
    np.testing.assert_array_equal(interp_bandlimited(np.array([]), np.arange(3.0)), np.zeros(3))


def test_large_input_runs():
    # 2e5 output positions with half_width 32 (speed is checked by hand, not asserted).
    rng = np.random.default_rng(0)
    x = rng.standard_normal(200_000)
    positions = np.arange(200_000) * (1.0 + 50e-6) + 10.5
    y = interp_bandlimited(x, positions)
    assert y.shape == (200_000,)
    assert np.all(np.isfinite(y))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"half_width": 0}, "half_width"),
        ({"half_width": 2.5}, "half_width"),
        ({"cutoff": 0.0}, "cutoff"),
        ({"cutoff": 1.5}, "cutoff"),
        ({"cutoff": float("nan")}, "cutoff"),
    ],
)
def test_invalid_parameters_raise(kwargs, match):
    with pytest.raises(InvalidParameterError, match=match):
        interp_bandlimited(np.ones(10), np.arange(10.0), **kwargs)


@pytest.mark.parametrize(
    ("x", "positions", "match"),
    [
        (np.ones((2, 5)), np.arange(3.0), "x"),
        (np.array([1.0, np.nan]), np.arange(3.0), "x"),
        (np.ones(5), np.array([0.0, np.inf]), "positions"),
        (np.ones(5), np.ones((2, 2)), "positions"),
    ],
)
def test_invalid_arrays_raise(x, positions, match):
    with pytest.raises(InvalidParameterError, match=match):
        interp_bandlimited(x, positions)
