"""Two-way ranging at the edges of its rules: defaults, domain limits, flag thresholds.

Written against mutants of ``rangekit/ranging/beepbeep.py`` that the other tests let
through (``benchmarks/mutation.py``, docs/evidence.md): each test pins one documented
number or boundary.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.ranging import range_beepbeep
from rangekit.ranging.beepbeep import DEFAULT_CLOCK_PPM, withhold_doubtful
from rangekit.types import Arrivals

FS = 44100.0
C = 343.0


def _arr(onsets, sigma=0.1):
    n = len(onsets)
    z = np.zeros(n)
    return Arrivals(np.asarray(onsets, float), FS, z + sigma, z + 30, z + 1, np.zeros((n, 4)))


OK = [_arr([1000.0, 21343.0]), _arr([5343.0, 25000.0])]


def test_default_clock_tolerance_is_30_ppm_in_sigma():
    """The documented default (30 ppm, 1 sigma) is the one sigma_m uses."""
    r0 = range_beepbeep(OK, speed_m_s=C, clock_ppm=0.0).ranges[0]
    r = range_beepbeep(OK, speed_m_s=C).ranges[0]
    da, db = 20343 / FS, 19657 / FS
    clock = (0.5 * C) ** 2 * ((da * 30e-6) ** 2 + (db * 30e-6) ** 2)
    assert DEFAULT_CLOCK_PPM == 30.0
    assert r.sigma_m == pytest.approx(math.sqrt(r0.sigma_m**2 + clock), rel=1e-12)


@pytest.mark.parametrize(("speed", "ok"), [(100.0, True), (99.99, False), (2000.0, True),
                                           (2000.01, False)])  # fmt: skip
def test_speed_of_sound_domain_is_100_to_2000(speed, ok):
    if ok:
        assert range_beepbeep(OK, speed_m_s=speed).speed_m_s == speed
    else:
        with pytest.raises(InvalidParameterError, match="speed_m_s"):
            range_beepbeep(OK, speed_m_s=speed)


def test_self_distance_up_to_2_m():
    d0 = range_beepbeep(OK, speed_m_s=C).ranges[0].distance_m
    d2 = range_beepbeep(OK, speed_m_s=C, self_distance_m=2.0).ranges[0].distance_m
    assert d2 - d0 == pytest.approx(2.0)  # (s_a + s_b) / 2
    with pytest.raises(InvalidParameterError, match="implausibly large"):
        range_beepbeep(OK, speed_m_s=C, self_distance_m=2.001)


def test_negative_flag_only_below_zero():
    # delta_a == delta_b and no self-distance: D is exactly 0, which is not negative.
    zero = [_arr([1000.0, 3000.0]), _arr([1000.0, 3000.0])]
    r = range_beepbeep(zero, speed_m_s=C).ranges[0]
    assert r.distance_m == 0.0 and "negative" not in r.flags
    # A short positive distance (0.19 m) is not flagged either.
    near = [_arr([1000.0, 3050.0]), _arr([1000.0, 3000.0])]
    r = range_beepbeep(near, speed_m_s=C).ranges[0]
    assert r.distance_m == pytest.approx(0.5 * C * 50 / FS) and r.flags == ()
    neg = [_arr([1000.0, 2950.0]), _arr([1000.0, 3000.0])]
    assert "negative" in range_beepbeep(neg, speed_m_s=C).ranges[0].flags


def test_order_flag_when_both_beeps_arrive_together():
    """A device that hears the other's beep at the same instant as its own: order."""
    same = [_arr([1000.0, 1000.0]), _arr([5343.0, 25000.0])]
    assert "order" in range_beepbeep(same, speed_m_s=C).ranges[0].flags
    same_b = [_arr([1000.0, 21343.0]), _arr([5343.0, 5343.0])]
    assert "order" in range_beepbeep(same_b, speed_m_s=C).ranges[0].flags
    assert "order" not in range_beepbeep(OK, speed_m_s=C).ranges[0].flags


def test_clock_tolerance_domain_is_0_to_10000_ppm():
    assert range_beepbeep(OK, speed_m_s=C, clock_ppm=1e4).ranges[0].sigma_m > 0
    with pytest.raises(InvalidParameterError, match="clock_ppm"):
        range_beepbeep(OK, speed_m_s=C, clock_ppm=1.0001e4)


def test_withhold_leaves_rows_without_a_distance_or_already_withheld():
    none = {"distance_m": None, "sigma_m": None, "flags": ["low_snr"]}
    assert withhold_doubtful(none) is False and none["flags"] == ["low_snr"]
    nan = {"distance_m": math.nan, "sigma_m": 0.01, "flags": ["clipped"]}
    assert withhold_doubtful(nan) is False and nan["distance_m"] is not None
    row = {"distance_m": 2.0, "sigma_m": 0.01, "flags": ["clipped"]}
    assert withhold_doubtful(row) is True
    assert withhold_doubtful(row) is False and row["flags"] == ["clipped", "withheld"]
