"""``rangekit.physics`` (issue 21: the mutation check; ``Medium`` and ``check_speed`` moved
here from ``rangekit.ranging.config``): the speed of sound of Kim & Kim 2013 §II-A,
``c = 20.05 sqrt(T + 273.16)``, its domain, the delay/distance conversions and the one
place the speed of a job is derived. Runs in well under a second.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from rangekit import physics as PH
from rangekit.errors import InvalidParameterError


def test_speed_of_sound_follows_the_square_root_of_absolute_temperature():
    c0 = PH.speed_of_sound_m_s(0.0)
    assert c0 == pytest.approx(20.05 * math.sqrt(273.16), rel=1e-15)  # 331.4 m/s
    for t in (-60.0, -10.0, 20.0, 35.5, 60.0):
        ratio = (PH.speed_of_sound_m_s(t) / c0) ** 2
        assert ratio == pytest.approx((t + 273.16) / 273.16, rel=1e-13)
    assert PH.speed_of_sound_m_s() == PH.speed_of_sound_m_s(PH.DEFAULT_TEMP_C)
    assert PH.DEFAULT_TEMP_C == 20.0 and round(PH.speed_of_sound_m_s(), 2) == 343.29
    assert PH.speed_of_sound_m_s(np.float32(20.0)) == PH.speed_of_sound_m_s(20)


@pytest.mark.parametrize("t", [-60.001, 60.001, math.nan, math.inf, True, "20", None, [20.0]])
def test_speed_of_sound_domain(t):
    with pytest.raises(InvalidParameterError):
        PH.speed_of_sound_m_s(t)


def test_delay_and_distance_are_inverse_scalar_and_array():
    assert PH.delay_to_distance_m(0.01, speed_m_s=343.0) == pytest.approx(3.43)
    assert PH.distance_to_delay_s(3.43, speed_m_s=343.0) == pytest.approx(0.01)
    d = PH.delay_to_distance_m([0.001, 0.002], speed_m_s=340.0)
    assert isinstance(d, np.ndarray) and d.tolist() == pytest.approx([0.34, 0.68])
    t = PH.distance_to_delay_s(np.array([0.34, 0.68]), speed_m_s=340.0)
    assert t.tolist() == pytest.approx([0.001, 0.002])
    assert isinstance(PH.delay_to_distance_m(0.5, speed_m_s=2.0), float)


@pytest.mark.parametrize("v", [100.0, 2000.0, 343.0])
def test_check_speed_edges(v):
    assert PH.check_speed(v) == v


@pytest.mark.parametrize("v", [99.99, 2000.01, math.nan, -343.0])
def test_check_speed_rejects(v):
    with pytest.raises(InvalidParameterError, match="speed_m_s"):
        PH.check_speed(v)


def test_medium_derives_c_once():
    assert PH.Medium().c == PH.speed_of_sound_m_s(20.0)
    assert PH.Medium(temp_c=-5.0).c == PH.speed_of_sound_m_s(-5.0)
    m = PH.Medium(temp_c=-5.0, speed_m_s=350)
    assert m.c == 350.0 and type(m.c) is float
    assert m.kwargs() == {"temp_c": -5.0, "speed_m_s": 350}
    assert PH.Medium().kwargs() == {"temp_c": 20.0, "speed_m_s": None}
    with pytest.raises(InvalidParameterError):
        PH.Medium(speed_m_s=50.0)
    with pytest.raises(InvalidParameterError):
        PH.Medium(temp_c=80.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        PH.Medium().temp_c = 30.0
    assert repr(m) == "Medium(temp_c=-5.0, speed_m_s=350)" and PH.Medium(
        speed_m_s=350.0
    ) == PH.Medium(speed_m_s=350.0)
    with pytest.raises(TypeError):
        PH.Medium(c=340.0)  # derived, not given
