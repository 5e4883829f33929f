"""``rangekit.ranging.ultrasonic``'s file layer on what its tests do not reach (issue 21,
the mutation check): a one-way calibration's latency (searched from, and not with a
latency of its own), a file whose rate cannot carry the burst named in the error, and the
trace's type. A few seconds.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import soundfile as sf

from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.physics import speed_of_sound_m_s
from rangekit.ranging.calibration import Calibration
from rangekit.ranging.ultrasonic import matched_trace, range_ultrasonic_files
from rangekit.signals.transducer import Transducer
from rangekit.sim.ultrasonic import render_oneway

LATENCY_S = 2e-3


@pytest.fixture(scope="module")
def oneway_file(tmp_path_factory):
    """Two windows of one Tx at three receivers, 2 ms latency, 30 dB: the file and truth."""
    sim = render_oneway([[1.0, 0.3, 2.5]], (0.0, 0.0, 0.0), snr_db=30.0, period_s=0.03,
                        order=[0], n_windows=2, latency_s=LATENCY_S, rng=2)  # fmt: skip
    path = tmp_path_factory.mktemp("us") / "ow.wav"
    sf.write(path, (sim.x / np.abs(sim.x).max() * 0.9).T, int(sim.fs), subtype="FLOAT")
    truth = [w["distances_m"] for w in sim.truth["windows"]]
    return str(path), truth


def _cal(latency_s: float) -> Calibration:
    c = speed_of_sound_m_s(20.0)
    return Calibration("oneway", "offset", -latency_s * c, 1e-4, latency_s, 1e-4 / c, c,
                       0.0, 0.0, 4, (1.0, 2.0), 1e-4)  # fmt: skip


def test_a_calibrations_latency_gives_the_distances(oneway_file):
    """Offset-only one-way calibration: distance ``c (arrival - latency)`` with the
    calibration's latency (within 1 mm of the truth at 30 dB); a latency_s of 0 may be
    passed beside it, any other not."""
    path, truth = oneway_file
    c = speed_of_sound_m_s(20.0)
    for kw in ({}, {"latency_s": 0.0}):
        rows = range_ultrasonic_files([path], scheme="oneway", period_s=0.03,
                                      calibration=_cal(LATENCY_S), **kw)  # fmt: skip
        assert len(rows) == 6
        for r in rows:
            assert r["distance_m"] == pytest.approx(c * (r["arrival_s"] - LATENCY_S), rel=1e-9)
            assert abs(r["distance_m"] - truth[r["window"]][r["channel"]]) < 1e-3
    with pytest.raises(InvalidParameterError, match="not both"):
        range_ultrasonic_files([path], scheme="oneway", period_s=0.03, latency_s=1e-3,
                               calibration=_cal(LATENCY_S))  # fmt: skip


def test_a_negative_calibrated_latency_searches_from_the_trigger(oneway_file):
    """A calibration whose latency came out negative (-1 ms): the search starts at the
    trigger (latency 0), and the distances still take the calibration's latency."""
    path, truth = oneway_file
    c = speed_of_sound_m_s(20.0)
    rows = range_ultrasonic_files([path], scheme="oneway", period_s=0.03,
                                  calibration=_cal(-1e-3))  # fmt: skip
    for r in rows:
        assert r["distance_m"] == pytest.approx(c * (r["arrival_s"] + 1e-3), rel=1e-9)
        want = truth[r["window"]][r["channel"]] + c * (LATENCY_S + 1e-3)
        assert abs(r["distance_m"] - want) < 1e-3


def test_a_file_whose_rate_cannot_carry_the_burst_is_named(tmp_path):
    path = tmp_path / "low.wav"
    sf.write(path, np.zeros((4000, 1)), 96000)
    with pytest.raises(IncompatibleInputError, match=r"low\.wav"):
        range_ultrasonic_files([str(path)], scheme="oneway")


def test_matched_trace_is_frozen():
    from rangekit.detect.matched import coded_template

    x = np.zeros((1, 20000))
    h = coded_template(fs=192000.0)
    x[0, 560 : 560 + len(h)] = h
    tr = matched_trace(x, fs=192000.0, scheme="oneway", tx=None, rx=None, speed_m_s=343.0)
    assert math.isfinite(tr.peak_lag)
    with pytest.raises(dataclasses.FrozenInstanceError):
        tr.noise = 0.0


def test_matched_trace_of_a_channel_and_window():
    """The trace of channel 1, window 1 of a three-receiver, two-window recording: that
    row of ``range_oneway``, the envelope of that channel over that window, the search
    ``latency + [min, max] / c``; a window or channel beyond the recording is refused."""
    from rangekit.detect.matched import MatchedFilter, coded_template
    from rangekit.ranging.ultrasonic import range_oneway
    from rangekit.signals.barker import CodedBurst

    sim = render_oneway([[1.0, 0.3, 2.5]], (0.0, 0.0, 0.0), snr_db=30.0, period_s=0.03,
                        order=[0], n_windows=2, latency_s=LATENCY_S, rng=2)  # fmt: skip
    kw = {"period_s": 0.03, "latency_s": LATENCY_S, "min_range_m": 0.5, "max_range_m": 7.0}
    tr = matched_trace(sim.x, fs=sim.fs, scheme="oneway", channel=1, window=1, **kw)
    rows = range_oneway(sim.x, fs=sim.fs, **kw)
    assert tr.tof == next(r for r in rows if (r.window, r.channel) == (1, 1))
    n = int(round(0.03 * sim.fs))
    assert tr.start == n
    h = coded_template(fs=sim.fs, tx=Transducer(), rx=Transducer())
    env = np.abs(MatchedFilter(h).correlate(sim.x[1]))[n : 2 * n]
    np.testing.assert_allclose(tr.envelope, env, rtol=0, atol=1e-12 * env.max())
    c = speed_of_sound_m_s(20.0)
    assert tr.search_s == pytest.approx((LATENCY_S + 0.5 / c, LATENCY_S + 7.0 / c), rel=1e-12)
    b = CodedBurst(cycles_per_bit=2)  # a burst given: its template, not the default's
    tb = matched_trace(sim.x, fs=sim.fs, scheme="oneway", channel=1, window=1, burst=b, **kw)
    hb = coded_template(b, fs=sim.fs, tx=Transducer(), rx=Transducer())
    env = np.abs(MatchedFilter(hb).correlate(sim.x[1]))[n : 2 * n]
    np.testing.assert_allclose(tb.envelope, env, rtol=0, atol=1e-12 * env.max())
    for bad in ({"window": 2}, {"channel": 3}, {"channel": -1}):
        with pytest.raises(IncompatibleInputError, match="does not exist"):
            matched_trace(sim.x, fs=sim.fs, scheme="oneway", **{**kw, **bad})
    with pytest.raises(IncompatibleInputError, match="channel 1 does not exist"):
        matched_trace(sim.x[:1], fs=sim.fs, scheme="oneway", channel=1, **kw)


def test_matched_trace_of_an_echo_uses_the_ping_and_the_round_trip():
    """Echo: the template is the SRF02 ping through the transducer twice (or the burst
    given), the search ``2 [min, max] / c``."""
    from rangekit.detect.matched import MatchedFilter, coded_template
    from rangekit.signals.barker import CodedBurst, srf02_ping

    td = Transducer()
    h = coded_template(srf02_ping(), fs=192000.0, tx=td, rx=td)
    x = np.zeros((1, 8000))
    x[0, 3000 : 3000 + len(h)] = 0.3 * h
    x[0, : len(h)] += 20.0 * h
    tr = matched_trace(x, fs=192000.0, scheme="echo", speed_m_s=343.0, max_range_m=5.0)
    assert tr.search_s == pytest.approx((2 * 0.15 / 343.0, 2 * 5.0 / 343.0), rel=1e-12)
    assert tr.tof.distance_m == pytest.approx(3000 / 192000.0 * 343.0 / 2, abs=1e-4)
    env = np.abs(MatchedFilter(h).correlate(x[0]))
    np.testing.assert_allclose(tr.envelope, env, rtol=0, atol=1e-12 * env.max())
    b = CodedBurst(code=(1, 1, 1, -1, -1, 1, -1), cycles_per_bit=2)
    tr = matched_trace(x, fs=192000.0, scheme="echo", burst=b, speed_m_s=343.0)
    env = np.abs(MatchedFilter(coded_template(b, fs=192000.0, tx=td, rx=td)).correlate(x[0]))
    np.testing.assert_allclose(tr.envelope, env, rtol=0, atol=1e-12 * env.max())
