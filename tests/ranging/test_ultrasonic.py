"""One-way (RF-synchronised) and pulse-echo ultrasonic ranging."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.detect.matched import coded_template
from rangekit.errors import IncompatibleInputError, InvalidParameterError, RangekitError
from rangekit.physics import speed_of_sound_m_s
from rangekit.ranging.ultrasonic import ToF, range_echo, range_oneway, window_starts
from rangekit.signals.barker import srf02_ping
from rangekit.signals.transducer import Transducer
from rangekit.sim._fracdelay import interp_bandlimited
from rangekit.sim.ultrasonic import render_oneway

FS = 192000.0
TXS = [[0.5, 0.3, 2.6], [3.0, 0.5, 2.6], [1.5, 3.5, 2.6]]
POSE = (1.4, 1.1, 0.4)


@pytest.fixture(scope="module")
def sim_multi():
    """Three Txs fired as 2, 0, 1, 2, 0 (five windows), 1.7 ms latency, noiseless."""
    return render_oneway(
        TXS, POSE, order=[2, 0, 1], n_windows=5, period_s=0.04, latency_s=1.7e-3, snr_db=None
    )


def _truth(sim, w, ch):
    return sim.truth["windows"][w]["distances_m"][ch]


# --- one-way ------------------------------------------------------------------------------


def test_oneway_noiseless_recovers_distances_windows_and_tx_ids(sim_multi):
    rows = range_oneway(sim_multi.x, fs=FS, latency_s=1.7e-3, period_s=0.04, tx_ids=[2, 0, 1])
    assert len(rows) == 5 * 3
    assert [(r.window, r.channel) for r in rows] == [(w, c) for w in range(5) for c in range(3)]
    for r in rows:
        assert r.tx == sim_multi.truth["windows"][r.window]["tx"] == [2, 0, 1][r.window % 3]
        assert abs(r.distance_m - _truth(sim_multi, r.window, r.channel)) < 1e-5
        # Arrival from the window's start includes the latency.
        c = sim_multi.truth["speed_of_sound_m_s"]
        assert r.arrival_s == pytest.approx(1.7e-3 + r.distance_m / c, rel=1e-12)
    # The distances differ between Txs: a wrong window/Tx mapping could not pass.
    assert len({round(_truth(sim_multi, w, 0), 3) for w in range(3)}) == 3


def test_oneway_latency_not_subtracted_adds_its_distance(sim_multi):
    rows = range_oneway(sim_multi.x, fs=FS, period_s=0.04)
    c = speed_of_sound_m_s(20.0)
    for r in rows:
        assert r.tx is None
        assert r.distance_m - _truth(sim_multi, r.window, r.channel) == pytest.approx(
            1.7e-3 * c, abs=1e-5
        )


def test_oneway_single_window_without_period(sim_multi):
    # Without period_s the whole file is one window: the earliest path of all.
    rows = range_oneway(sim_multi.x, fs=FS, latency_s=1.7e-3)
    assert [r.window for r in rows] == [0, 0, 0]
    for r in rows:
        assert abs(r.distance_m - _truth(sim_multi, 0, r.channel)) < 1e-5


def test_temperature_sets_the_speed_of_sound():
    sim = render_oneway([[0.0, 0.0, 3.0]], (0.5, 0.2, 0.0), temp_c=0.0, snr_db=None, period_s=0.03)
    c0, c30 = speed_of_sound_m_s(0.0), speed_of_sound_m_s(30.0)
    assert sim.truth["speed_of_sound_m_s"] == c0
    true = np.array(sim.truth["windows"][0]["distances_m"])
    right = np.array([r.distance_m for r in range_oneway(sim.x, fs=FS, temp_c=0.0)])
    np.testing.assert_allclose(right, true, atol=1e-5)
    wrong = np.array([r.distance_m for r in range_oneway(sim.x, fs=FS, temp_c=30.0)])
    np.testing.assert_allclose(wrong, true * c30 / c0, atol=1e-5)  # 5 % too long
    forced = np.array([r.distance_m for r in range_oneway(sim.x, fs=FS, speed_m_s=c0)])
    np.testing.assert_allclose(forced, true, atol=1e-5)


def test_out_of_search_arrivals_give_nan_rows():
    sim = render_oneway([[0.0, 0.0, 5.0]], (0.0, 0.0, 0.0), snr_db=40.0, period_s=0.04, rng=1)
    true = np.array(sim.truth["windows"][0]["distances_m"])  # about 5 m
    ok = range_oneway(sim.x, fs=FS)
    np.testing.assert_allclose([r.distance_m for r in ok], true, atol=2e-3)
    for kw in ({"max_range_m": 3.0}, {"min_range_m": 5.5}, {"min_range_m": 5.5, "max_range_m": 8}):
        rows = range_oneway(sim.x, fs=FS, **kw)
        assert len(rows) == 3
        for r in rows:
            assert math.isnan(r.distance_m) and math.isnan(r.sigma_m)
            assert math.isnan(r.snr_db) and math.isnan(r.arrival_s)
            assert r.as_dict()["distance_m"] is None


def test_oneway_noisy_sigma_and_snr_are_sane():
    sim = render_oneway([[0.0, 0.0, 2.0]], (0.3, 0.0, 0.0), snr_db=10.0, period_s=0.03, rng=5)
    true = np.array(sim.truth["windows"][0]["distances_m"])
    rows = range_oneway(sim.x, fs=FS, max_range_m=7.0)
    for r, d in zip(rows, true, strict=True):
        assert 0.0002 < r.sigma_m < 0.005
        assert abs(r.distance_m - d) < 5 * r.sigma_m
        assert 20.0 < r.snr_db < 30.0  # 24.5 dB matched-filter output for the weakest


def test_range_oneway_on_one_dimensional_input():
    h = coded_template(fs=FS)
    x = np.zeros(20000)
    x[560 : 560 + len(h)] = h
    (r,) = range_oneway(x, fs=FS, tx=None, rx=None, speed_m_s=343.0)
    assert isinstance(r, ToF) and r.channel == 0
    assert r.distance_m == pytest.approx(560 / FS * 343.0, abs=1e-9)


@pytest.mark.parametrize("fs", [96000.0, 44100.0])
def test_low_rates_incompatible_oneway(fs):
    # Barker-7's main lobe reaches 53.3 kHz: 96 kHz and 44.1 kHz recordings cannot carry it.
    with pytest.raises(IncompatibleInputError, match=f"sample rate {fs:g} Hz"):
        range_oneway(np.zeros((1, 4000)), fs=fs)


def test_echo_at_96khz_is_fine_but_not_44khz():
    # The SRF02 ping's main lobe (35-45 kHz) fits 96 kHz.
    (r,) = range_echo(np.zeros((1, 4000)), fs=96000.0)
    assert math.isnan(r.distance_m)
    with pytest.raises(RangekitError, match="44100 Hz"):
        range_echo(np.zeros((1, 4000)), fs=44100.0)


def test_echo_low_rate_is_incompatible_input():
    with pytest.raises(IncompatibleInputError):
        range_echo(np.zeros((1, 4000)), fs=44100.0)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"latency_s": -1e-3}, "latency_s"),
        ({"min_range_m": 3.0, "max_range_m": 2.0}, "max_range_m"),
        ({"max_range_m": 0.0}, "max_range_m"),
        ({"min_range_m": -1.0}, "min_range_m"),
        ({"tx_ids": []}, "tx_ids"),
        ({"period_s": 1e-6}, "period_s"),
        ({"period_s": -0.2}, "period_s"),
        ({"temp_c": 90.0}, "temperature"),
        ({"speed_m_s": 5.0}, "speed_m_s"),
        ({"fs": 0.0}, "fs"),
        ({"block": 4}, "block"),
    ],
)
def test_oneway_parameter_validation(kw, match):
    kw = {"fs": FS, **kw}
    with pytest.raises(InvalidParameterError, match=match):
        range_oneway(np.zeros((2, 4000)), **kw)


@pytest.mark.parametrize("shape", [(2, 3, 100), (1, 1), (0,)])
def test_oneway_bad_shapes(shape):
    with pytest.raises(InvalidParameterError, match="x must be"):
        range_oneway(np.zeros(shape), fs=FS)


def test_window_starts_cover_and_drop_short_tail():
    w = window_starts(10500, fs=FS, period_s=0.02)  # 3840 per window: last is 2820 long
    assert w.tolist() == [[0, 3840], [3840, 7680], [7680, 10500]]
    w = window_starts(9000, fs=FS, period_s=0.02)  # last is 1320 < 1920: dropped
    assert w.tolist() == [[0, 3840], [3840, 7680]]


# --- pulse-echo ---------------------------------------------------------------------------

C = 343.0


def _echo_recording(
    d_m: float, *, ring: float = 50.0, noise: float = 2e-3, seed: int = 0, length_s: float = 0.04
):
    """An SRF02-style log by hand: a strong ring-down at lag 0 plus the echo at 2 d / c."""
    td = Transducer()
    h = coded_template(srf02_ping(), fs=FS, tx=td, rx=td)
    n = int(length_s * FS)
    u = np.arange(n, dtype=np.float64) - 2.0 * d_m / C * FS
    x = 0.3 * interp_bandlimited(np.concatenate([h, np.zeros(64)]), u, half_width=32)
    x[: len(h)] += ring * h  # the transducer ringing after the ping
    return x + noise * np.random.default_rng(seed).standard_normal(n)


@pytest.mark.parametrize("d", [0.2, 0.5, 1.0, 2.345, 5.9])
def test_range_echo_recovers_hand_built_echo(d):
    (r,) = range_echo(_echo_recording(d), fs=FS, speed_m_s=C)
    assert r.window == 0 and r.tx is None
    assert abs(r.distance_m - d) < 5e-4
    assert r.arrival_s == pytest.approx(2 * r.distance_m / C, rel=1e-12)


@pytest.mark.parametrize("d", [0.05, 0.1, 0.14, 6.1, 6.5, 8.0])
def test_range_echo_outside_blanking_or_max_range_is_nan(d):
    (r,) = range_echo(_echo_recording(d), fs=FS, speed_m_s=C)
    assert math.isnan(r.distance_m) and r.as_dict()["distance_m"] is None


def test_range_echo_cycles_by_period():
    parts = [_echo_recording(d, seed=i, length_s=0.07) for i, d in enumerate([1.0, 7.0, 3.0])]
    rows = range_echo(np.concatenate(parts), fs=FS, speed_m_s=C, period_s=0.07)
    assert [r.window for r in rows] == [0, 1, 2]
    assert abs(rows[0].distance_m - 1.0) < 5e-4
    assert math.isnan(rows[1].distance_m)
    assert abs(rows[2].distance_m - 3.0) < 5e-4


def test_range_echo_validation():
    with pytest.raises(IncompatibleInputError, match="ring-down"):
        range_echo(np.zeros(100), fs=FS)
    with pytest.raises(InvalidParameterError, match="max_range_m"):
        range_echo(np.zeros(4000), fs=FS, min_range_m=2.0, max_range_m=1.0)
    with pytest.raises(InvalidParameterError, match="x must be"):
        range_echo(np.zeros((1, 1)), fs=FS)


def test_a_float32_recording_ranges_as_its_float64_copy():
    """16-bit files are decoded to float32 and ranged without a float64 copy: the same
    rows as the float64 copy of the same samples (the fits read float64 segments)."""
    sim = render_oneway(
        [[0.0, 0.0, 2.5], [2.0, 0.0, 2.5]], (0.6, 0.4, 0.2), snr_db=20.0, period_s=0.05,
        n_windows=4, rng=3,
    )  # fmt: skip
    x32 = sim.x.astype(np.float32)
    kw = {"fs": 192000.0, "period_s": 0.05, "tx_ids": [0, 1]}
    a = range_oneway(x32, **kw)
    b = range_oneway(x32.astype(np.float64), **kw)
    assert len(a) == 12 and all(math.isfinite(r.distance_m) for r in a)
    assert a == b
