"""``rangekit.ranging.tof``, the time-of-flight core, on what ``test_ultrasonic.py`` does not
reach (issue 21, the mutation check): the result type, the window layout's edges, explicit
windows, the search range's edges, the sigma's scale against the scatter it claims, the
transducer term, and the pooling groups of a firing order. A few seconds.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from rangekit.detect.matched import coded_template
from rangekit.errors import InvalidParameterError
from rangekit.ranging.tof import ToF, _as_channels, _windows, window_starts
from rangekit.ranging.ultrasonic import range_oneway
from rangekit.signals.transducer import Transducer
from rangekit.sim._fracdelay import interp_bandlimited
from rangekit.sim.ultrasonic import render_oneway

FS = 192000.0
C = 343.0


def test_tof_is_frozen_and_its_transducer_term_defaults_to_zero():
    r = ToF(0, None, 0, 1.0, 0.001, 30.0, 0.003)
    assert r.flags == () and r.sigma_transducer_m == 0.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.distance_m = 2.0


def test_nothing_detected_rows_carry_no_transducer_term():
    rows = range_oneway(np.zeros((2, 4000)), fs=FS)
    assert len(rows) == 2
    for r in rows:
        assert math.isnan(r.distance_m) and r.flags == () and r.sigma_transducer_m == 0.0


def test_window_starts_at_a_period_of_two_samples():
    """Two samples is the shortest period (documented: shorter raises); the last window, of
    one sample, is half a period and kept."""
    w = window_starts(7, fs=1000.0, period_s=0.002).tolist()
    assert w == [[0, 2], [2, 4], [4, 6], [6, 7]]
    with pytest.raises(InvalidParameterError, match="shorter than two samples"):
        window_starts(7, fs=1000.0, period_s=0.0019)


def test_as_channels_takes_two_samples_not_one():
    assert _as_channels(np.zeros(2)).shape == (1, 2)
    assert _as_channels(np.zeros((3, 2))).shape == (3, 2)
    with pytest.raises(InvalidParameterError, match="x must be"):
        _as_channels(np.zeros((3, 1)))


def test_explicit_windows_are_checked_and_used():
    ok = _windows(100, fs=FS, period_s=None, windows=np.array([[0, 2], [10, 100]]), first_window=0)
    assert ok.tolist() == [[0, 2], [10, 100]] and ok.dtype == np.int64
    bad = [
        np.array([0, 100]),  # 1-D
        np.zeros((2, 2, 2), dtype=int),  # 3-D
        np.array([[0, 10, 20]]),  # three columns
        np.zeros((0, 2), dtype=int),  # none
        np.array([[0.0, 10.0]]),  # not integer
        np.array([[-1, 10]]),  # before the start
        np.array([[0, 101]]),  # past the end
        np.array([[5, 6]]),  # one sample
        np.array([[6, 5]]),  # reversed
    ]
    for w in bad:
        with pytest.raises(InvalidParameterError, match="windows must be"):
            _windows(100, fs=FS, period_s=None, windows=w, first_window=0)
    with pytest.raises(InvalidParameterError, match="not both"):
        _windows(100, fs=FS, period_s=0.0001, windows=np.array([[0, 10]]), first_window=0)
    # through range_oneway: each window's time origin is its start
    h = coded_template(fs=FS)
    x = np.zeros((1, 20000))
    x[0, 560 : 560 + len(h)] = h
    x[0, 10000 + 700 : 10000 + 700 + len(h)] = h
    rows = range_oneway(x, fs=FS, tx=None, rx=None, speed_m_s=C,
                        windows=np.array([[0, 10000], [10000, 20000]]), first_window=4)  # fmt: skip
    assert [r.window for r in rows] == [4, 5]
    np.testing.assert_allclose([r.arrival_s for r in rows], [560 / FS, 700 / FS], atol=1e-9)


def _bare_path(lag: float, n: int = 12000) -> np.ndarray:
    """The bare Barker drive at a sub-sample ``lag``, noiseless (one channel)."""
    h = coded_template(fs=FS)
    u = np.arange(n, dtype=np.float64) - lag
    return interp_bandlimited(np.concatenate([h, np.zeros(64)]), u, half_width=32)[None, :]


def test_a_path_at_exactly_the_search_ranges_edges_is_ranged():
    """A path at exactly min_range_m or max_range_m (here 0.3 and 0.7 of a sample past an
    integer lag) is found at its distance: the search reaches a sample beyond either."""
    for lag in (2000.3, 2000.7):
        d = lag / FS * C
        x = _bare_path(lag)
        kw = {"fs": FS, "tx": None, "rx": None, "speed_m_s": C}
        for edge in (
            {"min_range_m": d},
            {"max_range_m": d},
            {"min_range_m": d, "max_range_m": d * 1.0001},
        ):
            (r,) = range_oneway(x, **kw, **edge)
            assert r.distance_m == pytest.approx(d, abs=2e-5), (lag, edge)  # 0.1 sample


def test_sigma_is_the_scatter_of_the_ranges():
    """40 windows at 15 dB through one Q 4 Tx to three receivers: the ranges' errors over
    their sigma have mean square 1 (measured 0.95, the fit and the fixed template alike),
    and the transducer term is 0 in-model."""
    sim = render_oneway([[1.0, 0.3, 2.5]], (0.0, 0.0, 0.0), snr_db=15.0, period_s=0.03,
                        order=[0], n_windows=40, rng=3)  # fmt: skip
    for fit in (True, False):
        rows = range_oneway(sim.x, fs=sim.fs, period_s=0.03, fit_transducers=fit)
        d = np.array([r.distance_m for r in rows])
        s = np.array([r.sigma_m for r in rows])
        truth = np.array([sim.truth["windows"][r.window]["distances_m"][r.channel] for r in rows])
        z2 = np.mean(((d - truth) / s) ** 2)
        assert 0.5 < z2 < 2.0, (fit, z2)
        assert all(r.sigma_transducer_m == 0.0 for r in rows)


def test_the_transducer_term_is_part_of_sigma():
    """A 6th-order Butterworth transducer (outside both fitted models) carries the
    model-order term: measured 40.4 mm of the 40.45 mm sigma through one receiver."""
    from rangekit.experiments.oneway_accuracy import make_transducer

    t = make_transducer("bandpass6", 12.0)
    sim = render_oneway([[1.0, 0.3, 2.5]], (0.0, 0.0, 0.0), tx=t, rx=t, snr_db=20.0,
                        period_s=0.03, order=[0], n_windows=6, rng=4)  # fmt: skip
    rows = range_oneway(sim.x[:1], fs=sim.fs, period_s=0.03)
    for r in rows:
        assert 20e-3 < r.sigma_transducer_m <= r.sigma_m < 80e-3


def test_a_transmitters_windows_are_pooled_among_themselves():
    """Firing order [0, 0, 1] (a Tx fired twice in a row; Q 4 and Q 20): the transducer
    fit pools each Tx's windows, so ranging each Tx's windows alone gives the same rows."""
    period, order, n_w = 0.03, [0, 0, 1], 9
    sims = [
        render_oneway([[1.0 + i, 0.3, 2.5]], (0.0, 0.0, 0.0), tx=Transducer(q=q),
                      rx=Transducer(q=q), snr_db=20.0, period_s=period, order=[0],
                      n_windows=n_w, rng=10 + i)
        for i, q in enumerate((4.0, 20.0))
    ]  # fmt: skip
    n = int(round(period * FS))
    x = np.concatenate([sims[order[w % 3]].x[:, w * n : (w + 1) * n] for w in range(n_w)], axis=1)
    rows = range_oneway(x, fs=FS, period_s=period, tx_ids=order)
    assert [r.tx for r in rows[::3]] == [order[w % 3] for w in range(n_w)]
    win = np.array([[w * n, (w + 1) * n] for w in range(n_w)])
    for tx in (0, 1):
        ws = [w for w in range(n_w) if order[w % 3] == tx]
        alone = range_oneway(x, fs=FS, windows=win[ws])
        full = [r for r in rows if r.window in ws]
        assert [r.distance_m for r in alone] == [r.distance_m for r in full]
        assert [r.sigma_m for r in alone] == [r.sigma_m for r in full]
