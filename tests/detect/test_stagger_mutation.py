"""``rangekit.detect.stagger.StaggerModel``'s rules that its fit tests reach only through a
whole fit (issue 21, the mutation check): the element Q round trip over the documented
limits, the stability clip, the broader variants, the small-split series, the scalar and
vector element, the unit gain at the nominal carrier. About a second.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
import pytest

from rangekit.detect.stagger import MIN_DAMPING, StaggerModel
from rangekit.signals.barker import CodedBurst

FS = 192000.0


@pytest.fixture(scope="module")
def model():
    return StaggerModel.for_burst(CodedBurst(), fs=FS)


def test_theta_start_round_trips_the_element_q_over_its_limits(model):
    """Element Q 1-40 (the documented limits) and a centre within the f0 range: q_f0 of
    theta_start is the Q and centre given; outside them the clip holds the limit."""
    for q in (1.0, 1.5, 4.0, 12.0, 39.0, 40.0):
        got = model.q_f0(model.theta_start(q))
        assert got == pytest.approx((q, 40000.0), rel=1e-12), q
    for q in (1.5, 4.0, 12.0, 39.0):  # the limits are dampings at the nominal f0
        for f0 in (39000.0, 41000.0):
            got = model.q_f0(model.theta_start(q, f0))
            assert got == pytest.approx((q, f0), rel=1e-12), (q, f0)
    assert model.q_f0(model.theta_start(0.5))[0] == pytest.approx(1.0, rel=1e-12)
    assert model.q_f0(model.theta_start(80.0))[0] == pytest.approx(40.0, rel=1e-12)


def test_theta_clip_keeps_both_pole_pairs_damped(model):
    """Poles ``exp(mu +- a sqrt(nu / a^2))``: each pair's damping ``a (1 -+ Re sqrt)`` stays
    at least MIN_DAMPING of ``a``; a split already inside is kept as it is."""
    la = math.log(0.05)
    for nr, ni in ((0.95, 0.0), (0.85, 0.5), (1.0, -0.6), (0.5, 0.0), (-1.0, 0.3)):
        th = model.theta_clip(np.array([la, 40000.0, nr, ni]))
        re = abs(cmath.sqrt(complex(th[2], th[3])).real)
        assert re <= 1.0 - MIN_DAMPING + 1e-12, (nr, ni, re)
        if abs(cmath.sqrt(complex(nr, ni)).real) <= 1.0 - MIN_DAMPING:
            assert (th[2], th[3]) == (nr, ni)


def test_theta_variants_are_the_model_and_broader_ones(model):
    """The two-path scan's variants: the same damping, sqrt 2 and 2x it (element Q /
    sqrt 2, / 2): broader models, never narrower."""
    th = model.theta_start(12.0)
    q = [model.q_f0(v)[0] for v in model.theta_variants(th)]
    assert sorted(q) == pytest.approx([6.0, 12.0 / math.sqrt(2.0), 12.0], rel=1e-12)


def test_the_small_split_series_joins_sinh(model):
    """Below |r| = 1e-3 ``sinh(r) / (2 r)`` is its series: the coefficients' derivatives
    are continuous across the switch (relative jump below 1e-8; measured ~1e-10)."""
    th = model.theta_start(4.0)
    a = math.exp(th[0])
    out = []
    for r in (1e-3 * (1 - 1e-6), 1e-3 * (1 + 1e-6)):
        nr = (r / a) ** 2  # nu = a^2 nr, |sqrt(nu)| = r
        _, _, dq = model._poly(np.array([th[0], th[1], nr, 0.0]))
        out.append(np.array([d for pair in dq for d in pair]))
    jump = np.abs(out[0] - out[1]) / np.maximum(np.abs(out[0]), 1e-300)
    assert np.max(jump[np.abs(out[0]) > 0]) < 1e-8


def test_element_at_one_point_is_the_element(model):
    """The scalar path (the carrier's normalisation) equals the vector one at that point:
    ``E(z)`` and ``Re d log E / d theta``."""
    th = np.array([math.log(0.05), 40300.0, -0.7, 0.2])
    for f in (38000.0, 40000.0, 42500.0):
        z = cmath.exp(-2j * math.pi * f / FS)
        e, de = model._element(np.array([z]), th, True)
        e1, de1 = model._element_at(z, th)
        assert e1 == pytest.approx(complex(e[0]), rel=1e-12)
        np.testing.assert_allclose(de1, de[:, 0].real, rtol=1e-9, atol=1e-12)


def test_gain_at_the_nominal_carrier_is_one(model):
    """The received spectrum over the drive's has unit magnitude at the nominal 40 kHz
    carrier (between the grid's bins at 39937.5 and 40125 Hz, linearly: measured 1 -
    1.1e-5 for element Q 4, centred there or 300 Hz off)."""
    f = model.w / (2 * math.pi) * FS
    k = int(np.searchsorted(f, 40000.0)) - 1
    u = (40000.0 - f[k]) / (f[k + 1] - f[k])
    for f0 in (40000.0, 40300.0):
        g = np.abs(model.spectrum_t(model.theta_start(4.0, f0)) / model._d)
        assert (1 - u) * g[k] + u * g[k + 1] == pytest.approx(1.0, abs=1e-4), f0
