"""``rangekit.ranging.oneway.range_oneway``'s documented defaults and edges that
``test_ultrasonic.py`` does not reach (issue 21, the mutation check): the default search
range (0-15 m), the transducer fit and its pooling on by default, equal range limits.
A few seconds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.detect.matched import coded_template
from rangekit.errors import InvalidParameterError
from rangekit.ranging.oneway import range_oneway
from rangekit.signals.transducer import Transducer
from rangekit.sim.ultrasonic import render_oneway

FS = 192000.0
C = 343.0


def _bare(lag: int, n: int) -> np.ndarray:
    h = coded_template(fs=FS)
    x = np.zeros((1, n))
    x[0, lag : lag + len(h)] = h
    return x


def test_the_default_search_is_0_to_15_m():
    kw = {"fs": FS, "tx": None, "rx": None, "speed_m_s": C}
    (r,) = range_oneway(_bare(28, 20000), **kw)  # 5 cm: inside the default 0 m
    assert r.distance_m == pytest.approx(28 / FS * C, abs=1e-9)
    lag = int(16.0 / C * FS)  # 16 m: beyond the default 15 m
    (r,) = range_oneway(_bare(lag, 20000), **kw)
    assert math.isnan(r.distance_m)
    (r,) = range_oneway(_bare(lag, 20000), **kw, max_range_m=17.0)
    assert r.distance_m == pytest.approx(lag / FS * C, abs=1e-9)
    lag = int(14.9 / C * FS)
    (r,) = range_oneway(_bare(lag, 20000), **kw)
    assert r.distance_m == pytest.approx(lag / FS * C, abs=1e-9)
    # a minimum range below the path keeps it, one beyond it does not
    (r,) = range_oneway(_bare(280, 20000), **kw, min_range_m=0.4)
    assert r.distance_m == pytest.approx(280 / FS * C, abs=1e-9)  # 0.5 m
    (r,) = range_oneway(_bare(280, 20000), **kw, min_range_m=0.6)
    assert math.isnan(r.distance_m)


def test_equal_range_limits_are_refused():
    with pytest.raises(InvalidParameterError, match="must exceed min_range_m"):
        range_oneway(np.zeros((1, 4000)), fs=FS, min_range_m=2.0, max_range_m=2.0)


@pytest.fixture(scope="module")
def q12():
    """Eight windows through Q 12 transducers (the default assumes Q 4) at 20 dB."""
    t = Transducer(q=12.0)
    sim = render_oneway([[1.0, 0.3, 2.5]], (0.0, 0.0, 0.0), tx=t, rx=t, snr_db=20.0,
                        period_s=0.03, order=[0], n_windows=8, rng=5)  # fmt: skip
    return sim


def _errors(sim, rows):
    d = np.array([r.distance_m for r in rows])
    truth = np.array([sim.truth["windows"][r.window]["distances_m"][r.channel] for r in rows])
    return d - truth, np.array([r.sigma_m for r in rows])


def test_by_default_the_transducers_are_fitted_and_pooled(q12):
    """The default fits the transducers (Q unknown) and pools their estimate: within 3.5
    sigma (measured |z| <= 2.5) where the fixed Q 4 template is 20 mm long (54 sigma), at
    0.70x the sigma of unpooled fits (measured 0.70 / 1.00 mm)."""
    e, s = _errors(q12, range_oneway(q12.x, fs=q12.fs, period_s=0.03))
    assert np.all(np.abs(e / s) < 3.5)
    e_fixed, _ = _errors(q12, range_oneway(q12.x, fs=q12.fs, period_s=0.03, fit_transducers=False))
    assert np.mean(e_fixed) > 10e-3  # measured 20.0 mm
    _, s_free = _errors(q12, range_oneway(q12.x, fs=q12.fs, period_s=0.03, pool=False))
    assert 0.55 < np.mean(s) / np.mean(s_free) < 0.85


def test_a_stagger_tuned_transducer_is_fitted_by_its_own_model():
    """Two resonators stagger-tuned half a band apart (Q 12; outside the resonator model):
    the default fit compares both models, within 3.5 sigma (measured |z| <= 2.5; the
    resonator model alone is 21.7 mm long, 36 sigma)."""
    from rangekit.experiments.oneway_accuracy import make_transducer

    t = make_transducer("coupled", 12.0)
    sim = render_oneway([[1.0, 0.3, 2.5]], (0.0, 0.0, 0.0), tx=t, rx=t, snr_db=20.0,
                        period_s=0.03, order=[0], n_windows=8, rng=6)  # fmt: skip
    rows = range_oneway(sim.x, fs=sim.fs, period_s=0.03)
    e, s = _errors(sim, rows)
    assert np.all(np.abs(e / s) < 3.5) and not any(r.flags for r in rows)
