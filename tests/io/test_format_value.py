"""``rangekit.io.results.format_value``: the one rule for a value in a line for people."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.io.results import format_value


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (0.33, "0.33"),
        (0.0004, "0.0004"),
        (1e-5, "1e-05"),
        (math.radians(30), "0.523599"),  # six significant digits
        (math.degrees(math.radians(30)), "30"),  # 29.999999999999996
        (5000.0, "5000"),
        (1234567.0, "1.23457e+06"),
        (np.float64(0.999), "0.999"),
        (np.float32(0.5), "0.5"),
        (7, "7"),
        (np.int64(150), "150"),
        (None, "none"),
        (float("nan"), "none"),
        (math.inf, "inf"),
        (True, "yes"),
        (np.bool_(False), "no"),
        ([90.0, -90.0], "90,-90"),
        ((0.5,), "0.5"),
        (np.array([1.0, 2.5]), "1,2.5"),
        (((0.0, 0.15), (0.0, -0.15)), "0,0.15;0,-0.15"),
        ([], ""),
        ("huber", "huber"),
    ],
)
def test_format_value(value, text):
    assert format_value(value) == text
