"""Two-way ranging: closed form, N devices, uncertainty, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rangekit.errors import DetectionError, IncompatibleInputError, InvalidParameterError
from rangekit.ranging import range_beepbeep
from rangekit.types import Arrivals

FS = 44100.0
C = 343.0


def _arr(onsets, *, fs=FS, sigma=0.1):
    n = len(onsets)
    z = np.zeros(n)
    return Arrivals(np.asarray(onsets, float), fs, z + sigma, z + 30, z + 1, np.zeros((n, 4)))


def _exchange(pos_spk, pos_mic, *, play_s, rec_start_s, fs, ppm=None):
    """Closed-form onsets: device i hears device j at play_j + |spk_j - mic_i| / c."""
    n = len(pos_spk)
    ppm = np.zeros(n) if ppm is None else np.asarray(ppm)
    out = []
    for i in range(n):
        row = []
        for j in range(n):
            t = play_s[j] + np.linalg.norm(pos_spk[j] - pos_mic[i]) / C
            row.append((t - rec_start_s[i]) * fs[i] * (1 + 1e-6 * ppm[i]))
        out.append(_arr(row, fs=fs[i]))
    return out


def test_two_devices_closed_form_with_self_distance_and_different_rates():
    spk = [np.array([0.0, 0.0, 0.0]), np.array([3.0, 0.1, 0.0])]
    mic = [np.array([0.0, 0.12, 0.0]), np.array([3.0, -0.02, 0.0])]
    arrs = _exchange(spk, mic, play_s=[0.3, 0.9], rec_start_s=[0.05, 0.11], fs=[FS, 48000.0])
    sd = [np.linalg.norm(spk[i] - mic[i]) for i in range(2)]
    res = range_beepbeep(arrs, speed_m_s=C, self_distance_m=sd)
    truth = 0.5 * (np.linalg.norm(spk[0] - mic[1]) + np.linalg.norm(spk[1] - mic[0]))
    assert res.ranges[0].distance_m == pytest.approx(truth, abs=1e-9)
    assert res.ranges[0].flags == ()


def test_n_devices_every_pair():
    rng = np.random.default_rng(0)
    n = 4
    spk = [rng.uniform(0, 5, 3) for _ in range(n)]
    mic = [s + rng.normal(0, 0.05, 3) for s in spk]
    play = np.cumsum(rng.uniform(0.4, 0.8, n))
    arrs = _exchange(spk, mic, play_s=play, rec_start_s=rng.uniform(0, 0.1, n), fs=[FS] * n)
    sd = [float(np.linalg.norm(spk[i] - mic[i])) for i in range(n)]
    res = range_beepbeep(arrs, speed_m_s=C, self_distance_m=sd)
    assert [(r.a, r.b) for r in res.ranges] == [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    d = res.distance_matrix_m()
    for a in range(n):
        for b in range(a + 1, n):
            truth = 0.5 * (np.linalg.norm(spk[a] - mic[b]) + np.linalg.norm(spk[b] - mic[a]))
            assert d[a, b] == pytest.approx(truth, abs=1e-9) and d[b, a] == d[a, b]


def test_clock_rate_error_effect_is_interval_times_ppm():
    spk = [np.zeros(3), np.array([2.0, 0, 0])]
    mic = [s + np.array([0, 0.1, 0]) for s in spk]
    play = [0.3, 0.8]
    base = _exchange(spk, mic, play_s=play, rec_start_s=[0, 0], fs=[FS, FS])
    fast = _exchange(spk, mic, play_s=play, rec_start_s=[0, 0], fs=[FS, FS], ppm=[50.0, 0.0])
    d0 = range_beepbeep(base, speed_m_s=C, self_distance_m=0.1).ranges[0].distance_m
    d1 = range_beepbeep(fast, speed_m_s=C, self_distance_m=0.1).ranges[0].distance_m
    interval = (base[0].onset[1] - base[0].onset[0]) / FS
    assert d1 - d0 == pytest.approx(0.5 * C * interval * 50e-6, rel=1e-6)


def test_sigma_combines_the_four_onsets_and_the_clock_term():
    arrs = [_arr([1000.0, 21343.0], sigma=0.5), _arr([5343.0, 25000.0], sigma=0.5)]
    r = range_beepbeep(arrs, speed_m_s=C, clock_ppm=0.0).ranges[0]
    assert r.sigma_m == pytest.approx(0.5 * C * math.sqrt(4 * 0.25) / FS)
    r2 = range_beepbeep(arrs, speed_m_s=C, clock_ppm=30.0).ranges[0]
    da, db = 20343 / FS, 19657 / FS
    extra = (0.5 * C) ** 2 * ((da * 30e-6) ** 2 + (db * 30e-6) ** 2)
    assert r2.sigma_m == pytest.approx(math.sqrt(r.sigma_m**2 + extra))


def test_flags_for_impossible_geometry():
    # Device 1's beep arrives at device 0 before device 0's own: wrong play order.
    arrs = [_arr([21343.0, 1000.0]), _arr([25000.0, 5343.0])]
    r = range_beepbeep(arrs, speed_m_s=C).ranges[0]
    assert "order" in r.flags and "negative" in r.flags


def test_errors():
    ok = [_arr([1000.0, 21343.0]), _arr([5343.0, 25000.0])]
    with pytest.raises(DetectionError, match="device 1: found 1 beep"):
        range_beepbeep([ok[0], _arr([5343.0])], speed_m_s=C)
    with pytest.raises(DetectionError, match="found no beep"):
        range_beepbeep([ok[0], Arrivals.empty(fs=FS, n_bursts=4)], speed_m_s=C)
    with pytest.raises(IncompatibleInputError, match="3 self-distances"):
        range_beepbeep(ok, speed_m_s=C, self_distance_m=[0.1, 0.1, 0.1])
    with pytest.raises(InvalidParameterError, match="self_distance_m"):
        range_beepbeep(ok, speed_m_s=C, self_distance_m=-0.1)
    with pytest.raises(InvalidParameterError, match="speed_m_s"):
        range_beepbeep(ok, speed_m_s=5.0)
    with pytest.raises(IncompatibleInputError, match="at least 2"):
        range_beepbeep(ok[:1], speed_m_s=C)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(2, 5),
    fs=st.sampled_from([44100.0, 48000.0, 96000.0]),
)
def test_property_exact_for_any_geometry_and_schedule(seed, n, fs):
    """Noiseless onsets from any positions, starts and play times give the exact truth."""
    rng = np.random.default_rng(seed)
    spk = [rng.uniform(-10, 10, 3) for _ in range(n)]
    mic = [s + rng.normal(0, 0.1, 3) for s in spk]
    play = np.cumsum(rng.uniform(0.1, 2.0, n))
    rates = [fs if i % 2 else 44100.0 for i in range(n)]
    arrs = _exchange(spk, mic, play_s=play, rec_start_s=rng.uniform(-1, 0.1, n), fs=rates)
    sd = [float(np.linalg.norm(spk[i] - mic[i])) for i in range(n)]
    d = range_beepbeep(arrs, speed_m_s=C, self_distance_m=sd).distance_matrix_m()
    for a in range(n):
        for b in range(a + 1, n):
            truth = 0.5 * (np.linalg.norm(spk[a] - mic[b]) + np.linalg.norm(spk[b] - mic[a]))
            assert abs(d[a, b] - truth) < 1e-8
