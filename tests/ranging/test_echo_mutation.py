"""``rangekit.ranging.echo.range_echo``'s defaults and edges that ``test_ultrasonic.py``
does not reach (issue 21, the mutation check): the transducer fit and its pooling on by
default, a zero minimum range, the ring-down length check, equal range limits, and an
echo beyond the maximum range masking none within it. A few seconds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.detect.matched import coded_template
from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.floorplan import FloorPlan
from rangekit.ranging.echo import range_echo
from rangekit.sensors.srf02 import SRF02
from rangekit.signals.barker import srf02_ping
from rangekit.signals.transducer import Transducer
from rangekit.sim._fracdelay import interp_bandlimited
from rangekit.sim.ultrasonic import render_echo

FS = 192000.0
C = 343.0


def _echoes(n: int, *paths: tuple[float, float], ring: float = 0.0, seed: int = 0):
    """A hand-built log: echoes ``(distance m, amplitude)`` of the Q 4 ping, a ring-down of
    ``ring`` at lag 0, white noise 2e-3."""
    td = Transducer()
    h = coded_template(srf02_ping(), fs=FS, tx=td, rx=td)
    x = np.zeros(n)
    for d, a in paths:
        u = np.arange(n, dtype=np.float64) - 2.0 * d / C * FS
        x += a * interp_bandlimited(np.concatenate([h, np.zeros(64)]), u, half_width=32)
    x[: len(h)] += ring * h
    return x + 2e-3 * np.random.default_rng(seed).standard_normal(n)


@pytest.fixture(scope="module")
def q12():
    """Eight SRF02 cycles facing a wall at 0.3-5.5 m through a Q 12 transducer (the
    default assumes Q 4), 20 dB: recording, truth, cycle."""
    wall = FloorPlan.from_walls([((0.0, -50.0), (0.0, 50.0))])
    rng = np.random.default_rng([3, 12])
    d = rng.uniform(0.3, 5.5, 8)
    tilt = np.radians(rng.uniform(-3.0, 3.0, 8))
    poses = np.stack([d, rng.uniform(-2.0, 2.0, 8), math.pi + tilt], axis=1)
    sim = render_echo(wall, poses, snr_db=20.0, rng=rng, transducer=Transducer(q=12.0))
    truth = np.array([w["distance_m"] for w in sim.truth["windows"]], dtype=float)
    return sim.x, truth, SRF02().cycle_s


def test_by_default_the_transducer_is_fitted_and_pooled(q12):
    """Within 3 sigma (measured |z| <= 2.1) where the fixed Q 4 template is 12-15 mm long
    (67 sigma), at 0.63x the sigma of unpooled fits (measured 0.84 / 1.33 mm)."""
    x, truth, cycle = q12

    def errors(**kw):
        rows = range_echo(x, fs=FS, period_s=cycle, **kw)
        return np.array([r.distance_m for r in rows]) - truth, np.array([r.sigma_m for r in rows])

    e, s = errors()
    assert np.all(np.abs(e / s) < 3.0)
    e_fixed, _ = errors(fit_transducer=False)
    assert np.all(e_fixed > 6e-3)  # measured 12.4-15.4 mm
    _, s_free = errors(pool=False)
    assert 0.5 < np.mean(s) / np.mean(s_free) < 0.8


def test_a_zero_minimum_range_searches_from_the_ping():
    """Without a ring-down (a separate receiver), ``min_range_m=0`` searches from lag 0:
    an echo at 10 cm, inside the SRF02's default 15 cm blanking, is ranged."""
    x = _echoes(4000, (0.10, 0.3))
    (r,) = range_echo(x, fs=FS, speed_m_s=C, min_range_m=0.0, fit_transducer=False)
    assert r.distance_m == pytest.approx(0.10, abs=5e-4)
    (r,) = range_echo(x, fs=FS, speed_m_s=C, fit_transducer=False)
    assert math.isnan(r.distance_m)


def test_equal_range_limits_are_refused():
    with pytest.raises(InvalidParameterError, match="must exceed min_range_m"):
        range_echo(np.zeros(4000), fs=FS, min_range_m=2.0, max_range_m=2.0)


def test_a_recording_as_long_as_the_blanking_is_ranged():
    """The blanking of 17.15 cm at 343 m/s is 1 ms, 192 samples: a first window of 192
    samples is accepted (nothing found in it), one of 191 is refused, also when the
    window does not start at sample 0."""
    kw = {"fs": FS, "speed_m_s": C, "min_range_m": 0.1715}
    (r,) = range_echo(np.zeros(192), **kw)
    assert math.isnan(r.distance_m)
    with pytest.raises(IncompatibleInputError, match="ring-down"):
        range_echo(np.zeros(191), **kw)
    with pytest.raises(IncompatibleInputError, match="ring-down"):
        range_echo(np.zeros(2000), **kw, windows=np.array([[1000, 1191], [1191, 2000]]))
    rows = range_echo(np.zeros(2000), **kw, windows=np.array([[1000, 1192], [1192, 2000]]))
    assert [r.window for r in rows] == [0, 1]


def test_an_echo_beyond_the_maximum_range_masks_none_within_it():
    """A strong echo at 8 m (beyond the default 6 m) and a weak one at 5 m (a fifth of
    it, below the first-path rule's quarter of the strongest): the search ends at 6 m, so
    the 5 m echo is the first path; searching to 9 m, the 8 m echo is the strongest and the
    result out of range."""
    x = _echoes(int(0.07 * FS), (5.0, 0.06), (8.0, 0.3), ring=50.0)
    (r,) = range_echo(x, fs=FS, speed_m_s=C, fit_transducer=False)
    assert r.distance_m == pytest.approx(5.0, abs=1e-3)
    (r,) = range_echo(x, fs=FS, speed_m_s=C, fit_transducer=False, max_range_m=9.0)
    assert r.distance_m == pytest.approx(8.0, abs=1e-3)


def test_the_srf02_figures_are_the_sensor_models():
    # one datasheet (Girard 2011 sec. 2.6): the echo scheme's exported SRF02 figures are
    # those of the sensor model the simulators render, and one cycle holds the round
    # trip to the maximum range
    from rangekit.ranging import echo
    from rangekit.sensors import srf02

    assert (echo.SRF02_CYCLE_S, echo.SRF02_MIN_RANGE_M, echo.SRF02_MAX_RANGE_M) == (
        srf02.CYCLE_S,
        srf02.MIN_RANGE_M,
        srf02.MAX_RANGE_M,
    )
    assert 2 * echo.SRF02_MAX_RANGE_M / srf02.DATASHEET_SPEED_M_S < echo.SRF02_CYCLE_S
