"""``rangekit.detect._coherent``'s helpers against closed forms (issue 21, the mutation
check): the side-extremum ratio of a self response, the windowed-sinc interpolation and
the extremum search on band-limited signals, the weight of the coherent timing, the
coherent lag of a pulse whose real part peaks at a known lag. About a second.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.detect import _coherent as C


def _centred(values):
    """A real self response ``values`` (lag 0 in the middle), as complex."""
    return np.asarray(values, dtype=float).astype(complex)


def test_real_side_ratio_is_the_second_extremum_over_the_first():
    r = np.zeros(41)
    r[20], r[19], r[21] = 1.0, 0.6, 0.6
    r[14], r[26] = -0.4, 0.3  # side extrema of |Re R| at lags -6 and +6
    assert C.real_side_ratio(_centred(r), 10) == pytest.approx(0.4)
    assert C.real_side_ratio(_centred(r), 5) == 0.0  # within 5 lags: the main one only
    r[14] = -1.0  # a side extremum as large as the main one
    assert C.real_side_ratio(_centred(r), 10) == 1.0
    assert C.real_side_ratio(_centred([1.0, 2.0]), 5) == 1.0  # too short to tell
    assert C.real_side_ratio(_centred(np.linspace(0.0, 1.0, 9)), 4) == 1.0  # no extremum
    assert C.real_side_ratio(_centred(np.zeros(9)), 4) == 1.0


def test_sinc_interpolation_reconstructs_a_band_limited_signal():
    """Tones at 0.3 and 0.6 of the Nyquist frequency read at fractional indices away from
    the ends: within 4e-4 of their peak (about the documented 1e-4; measured 1.7e-4 and
    2.2e-4 at worst over 1000 points)."""
    n = np.arange(200.0)
    for f in (0.15, 0.3):
        x = np.cos(2 * np.pi * f * n + 0.4)
        for t in np.linspace(40.0, 160.0, 97):
            want = math.cos(2 * math.pi * f * t + 0.4)
            assert C._sinc_at(x, t) == pytest.approx(want, abs=4e-4), (f, t)
    x = np.cos(2 * np.pi * 0.15 * n + 0.4)
    assert C._sinc_at(x, 60.0) == pytest.approx(x[60], abs=1e-12)  # on the grid: the sample


def test_refine_extremum_finds_a_band_limited_pulses_peak():
    """A Gaussian-windowed tone whose real part peaks at 40.37: found to 1e-3 samples from
    the nearest sample (the golden section stops at 1e-4); at the ends the index."""
    n = np.arange(80.0)
    for t0 in (40.37, 40.5, 39.8):
        r = np.exp(-0.5 * ((n - t0) / 2.5) ** 2) * np.cos(2 * np.pi * 0.1 * (n - t0))
        i = int(np.argmax(np.abs(r)))
        assert C.refine_extremum(r, i) == pytest.approx(t0, abs=1e-3), t0
    r = np.exp(-0.5 * ((n - 30.0) / 2.5) ** 2)
    assert C.refine_extremum(r, 0) == 0.0 and C.refine_extremum(r, 79) == 79.0


def test_coherent_weight_at_its_corners():
    assert C.COHERENT_FULL_COS == pytest.approx(math.cos(math.radians(30.0)))
    assert C.COHERENT_NONE_COS == pytest.approx(0.5)
    assert C.coherent_weight(1.0) == 1.0 and C.coherent_weight(0.0) == 0.0
    mid = 0.5 * (C.COHERENT_FULL_COS + C.COHERENT_NONE_COS)
    assert C.coherent_weight(mid) == pytest.approx(0.5)


def test_coherent_lag_of_a_pulse_in_phase_at_its_peak():
    """A pulse whose carrier is in phase at its envelope peak (lag 32.3): its real part
    peaks there too, and ``|cos phase|`` is 1; a quarter period away, 0."""
    n = np.arange(64.0)
    env = np.exp(-0.5 * ((n - 32.3) / 3.0) ** 2)
    c = env * np.exp(2j * np.pi * 0.15 * (n - 32.3))
    t, cp = C.coherent_lag(c, 32.3, 3)
    assert t == pytest.approx(32.3, abs=1e-3) and cp == pytest.approx(1.0, abs=1e-4)
    _, cp = C.coherent_lag(c * 1j, 32.3, 3)
    assert cp == pytest.approx(0.0, abs=1e-3)
    assert C.coherent_lag(np.ones(64, dtype=complex), 32.0, 3) is None  # no extremum


def test_coherent_interp_rms_of_a_symmetric_self_response_is_small():
    """A self response with an even real part: the coherent lag follows a fractional
    delay to within 0.01 samples RMS (measured below 1e-3)."""
    n = np.arange(-64.0, 65.0)
    r = np.exp(-0.5 * (n / 4.0) ** 2) * np.exp(2j * np.pi * 0.12 * n)
    assert C.coherent_interp_rms(r, 3) < 0.01


def test_refine_extremum_next_to_the_ends():
    """Indices 1 and len - 2 are refined (with the taps the array holds: measured 0.07 and
    0.15 samples off a peak at 1.3 and 38.3); only the end samples are returned as they are."""
    n = np.arange(40.0)
    for t0, i, tol in ((1.3, 1, 0.15), (38.3, 38, 0.25)):
        r = np.exp(-0.5 * ((n - t0) / 2.5) ** 2) * np.cos(2 * np.pi * 0.1 * (n - t0))
        assert C.refine_extremum(r, i) == pytest.approx(t0, abs=tol), t0


def test_coherent_lag_searches_reach_either_side():
    """An extremum of the real part exactly ``reach`` samples before or after the given
    lag (or between) is found there."""
    n = np.arange(64.0)
    for p in (29.0, 35.0, 34.6):
        c = np.exp(-0.5 * ((n - p) / 3.0) ** 2) * np.exp(2j * np.pi * 0.15 * (n - p))
        t, _ = C.coherent_lag(c, 32.0, 3)
        assert t == pytest.approx(p, abs=1e-3), p
