"""Clock-rate estimation and correction: closed form, motion, failures, and the acceptance."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from rangekit.errors import DetectionError, IncompatibleInputError
from rangekit.io.audio import write_audio
from rangekit.physics import speed_of_sound_m_s
from rangekit.ranging.beepbeep import range_beepbeep
from rangekit.ranging.clock import (
    ClockRates,
    clock_error_m,
    correct_clock,
    correct_series_clock,
    estimate_clock_rates,
)
from rangekit.ranging.series import ExchangeRanges, range_series_beepbeep
from rangekit.signals import Beep, beep_waveform
from rangekit.sim import ShoeboxRoom, pair_devices
from rangekit.sim.exchanges import render_exchanges
from rangekit.types import Arrivals, Range

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perturb import worse  # tests/perturb.py: errors x $RANGEKIT_TEST_WORSE

C = 343.0
FS = 44100.0


def _arrivals(t_s, fs=FS, sigma=0.05):
    n = len(t_s)
    z = np.zeros(n)
    return Arrivals(np.asarray(t_s, dtype=float) * fs, fs, z + sigma, z + 30, z + 1,
                    np.zeros((n, 4)), "changepoint")  # fmt: skip


def _series(
    ppm,
    *,
    n=12,
    period=2.0,
    gaps=None,
    dist=lambda t: 1.5,
    self_m=(0.1, 0.12, 0.08),
    rec_start=(0.0, 0.37, -0.21),
    fs=(FS, 48000.0, FS),
):
    """Exact arrivals of the time model (module Notes of rangekit.ranging.clock).

    Device 0 plays at ``0.5 + k period``, device j ``gaps[k]`` after device j - 1; the
    flight of a beep emitted at P is ``dist(P) / C`` (``dist``: distance between every
    two devices at that time). Returns the exchanges and the true play times.
    """
    nd = len(ppm)
    e = np.asarray(ppm) * 1e-6
    gaps = np.full(n, 0.6) if gaps is None else np.asarray(gaps)
    out, plays = [], []
    for k in range(n):
        p = 0.5 + k * period + np.arange(nd) * gaps[k]
        arr = []
        for i in range(nd):
            t = np.array(
                [p[j] + (self_m[i] if i == j else dist(p[j])) / C - rec_start[i] for j in range(nd)]
            )
            arr.append(_arrivals(t * (1 + e[i]), fs=fs[i]))
        res = range_beepbeep(arr, speed_m_s=C, self_distance_m=list(self_m[:nd]))
        out.append(ExchangeRanges(k, float(arr[0].onset_s[0]), res.ranges, arrivals=tuple(arr)))
        plays.append(p)
    return out, np.array(plays)


def _failed(k, t_s, n_pairs=1):
    nan = (Range(0, 1, math.nan, math.nan, ("detection",)),) * n_pairs
    return ExchangeRanges(k, t_s, nan, f"exchange {k}: '1.wav' has 1 beep(s)")


def test_exact_skew_gives_the_exact_ppm_and_exact_ranges():
    ppm = (30.0, 80.0, -45.0)
    ex, _ = _series(ppm, self_m=(0.1, 0.12, 0.08))
    rates = estimate_clock_rates(ex)
    rel = [((1 + p * 1e-6) / (1 + ppm[0] * 1e-6) - 1) * 1e6 for p in ppm]
    np.testing.assert_allclose(rates.ppm, rel, rtol=0, atol=1e-6)
    assert rates.ppm[0] == 0.0 and rates.sigma_ppm[0] == 0.0
    assert np.all(rates.sigma_ppm < 1e-6)
    assert rates.n_exchanges == 12 and rates.n_rejected == 0
    assert rates.span_s == pytest.approx(22.0 * (1 + 30e-6), abs=1e-9)
    # Uncorrected ranges are off; corrected ones are the true 1.5 m up to the common
    # clock error of device 0: e_0 (d - (s_a + s_b)/2).
    before = np.array([[r.distance_m for r in e.ranges] for e in ex])
    assert np.max(np.abs(before - 1.5)) > 5e-3
    fixed = correct_clock(ex, rates, speed_m_s=C, self_distance_m=[0.1, 0.12, 0.08])
    after = np.array([[r.distance_m for r in e.ranges] for e in fixed])
    s = np.array([0.1, 0.12, 0.08])
    pair_s = np.array([(s[a] + s[b]) / 2 for a, b in ((0, 1), (0, 2), (1, 2))])
    want = np.broadcast_to(1.5 + 30e-6 * (1.5 - pair_s), after.shape)
    np.testing.assert_allclose(after, want, rtol=0, atol=1e-9)
    # Same exchanges otherwise; the arrivals are the recordings' (not rescaled).
    assert [e.t_s for e in fixed] == [e.t_s for e in ex]
    assert fixed[3].arrivals is ex[3].arrivals
    # Known absolute rates correct exactly, device 0 included.
    exact = correct_clock(ex, ClockRates.known(ppm, 3), speed_m_s=C, self_distance_m=list(s))
    after = np.array([[r.distance_m for r in e.ranges] for e in exact])
    np.testing.assert_allclose(after, 1.5, rtol=0, atol=1e-9)


def test_uncorrected_error_is_c_over_2_ppm_times_the_gap():
    """D - d = c/2 (e_a T_a - e_b T_b) ~= -c/2 (e_b - e_a) G (+ (e_a + e_b)/2 d)."""
    for gap in (0.4, 1.1):
        ex, _ = _series((0.0, 60.0), n=3, gaps=np.full(3, gap), dist=lambda t: 0.5)
        err = ex[0].ranges[0].distance_m - 0.5
        pred = clock_error_m(60.0, gap, speed_m_s=C)
        assert pred == pytest.approx(-0.5 * C * 60e-6 * gap)
        assert err == pytest.approx(pred + 30e-6 * 0.5, rel=1e-3)


def test_moving_device_still_gives_the_right_ppm():
    """Distance 1 m -> 4.9 m over the series: midpoints cancel the flight time."""
    v = 0.05
    ex, _ = _series((0.0, 50.0), n=40, dist=lambda t: 1.0 + v * t)
    rates = estimate_clock_rates(ex)
    assert rates.ppm[1] == pytest.approx(50.0, abs=1e-6)
    # Without midpoints (device 0's beep only: C_k against A_k) the motion reads as
    # v / c ~ 146 ppm of clock error.
    a = np.array([e.arrivals[0].onset_s[0] for e in ex])
    c = np.array([e.arrivals[1].onset_s[0] for e in ex])
    naive = (np.polyfit(a, c, 1)[0] - 1) * 1e6
    assert abs(naive - 50.0) > 100
    # Motion within an exchange with jittered gaps: -v G_k / 2c varies, still << 2 ppm.
    gaps = np.random.default_rng(0).uniform(0.6, 0.8, 40)
    ex, _ = _series((0.0, 50.0), n=40, gaps=gaps, dist=lambda t: 1.0 + v * t)
    assert estimate_clock_rates(ex).ppm[1] == pytest.approx(50.0, abs=0.05)


def test_failed_exchanges_are_skipped_and_kept():
    ex, _ = _series((0.0, 70.0), n=8, rec_start=(0.0, 0.2), self_m=(0.1, 0.1))
    mixed = list(ex)
    for k in (0, 3, 7):
        mixed[k] = _failed(k, ex[k].t_s)
    rates = estimate_clock_rates(mixed)
    assert rates.ppm[1] == pytest.approx(70.0, abs=1e-6)
    assert rates.n_exchanges == 5
    assert rates.span_s == pytest.approx(ex[6].t_s - ex[1].t_s)
    fixed = correct_clock(mixed, rates, speed_m_s=C, self_distance_m=0.1)
    assert fixed[3] is mixed[3]
    assert fixed[4].ranges[0].distance_m == pytest.approx(1.5, abs=1e-6)


def test_a_wrong_detection_is_rejected():
    ex, _ = _series((0.0, -40.0), n=10, rec_start=(0.0, 0.2), self_m=(0.1, 0.1))
    bad = ex[4].arrivals[1]
    on = bad.onset.copy()
    on[1] += 0.004 * bad.fs  # an echo 4 ms late taken for device 1's own beep
    ex[4] = ExchangeRanges(4, ex[4].t_s, ex[4].ranges, arrivals=(ex[4].arrivals[0],
                           Arrivals(on, bad.fs, bad.sigma, bad.snr_db, bad.confidence,
                                    bad.burst_onsets)))  # fmt: skip
    rates = estimate_clock_rates(ex)
    assert rates.n_rejected == 1 and rates.n_exchanges == 9
    assert rates.ppm[1] == pytest.approx(-40.0, abs=1e-6)


def test_too_few_exchanges_and_other_errors():
    ex, _ = _series((0.0, 50.0), n=6, rec_start=(0.0, 0.2), self_m=(0.1, 0.1))
    with pytest.raises(IncompatibleInputError, match="at least 3 exchanges, got 2"):
        estimate_clock_rates(ex[:2])
    few = [ex[0], _failed(1, 2.5), ex[2], _failed(3, 6.5), _failed(4, 8.5)]
    with pytest.raises(DetectionError, match="only 2 of 5 have them"):
        estimate_clock_rates(few)
    with pytest.raises(IncompatibleInputError, match=r"span 4\.000 s"):
        estimate_clock_rates(ex[:3], min_span_s=10.0)
    bare = [ExchangeRanges(e.exchange, e.t_s, e.ranges) for e in ex]
    with pytest.raises(IncompatibleInputError, match="carries no arrivals"):
        estimate_clock_rates(bare)
    with pytest.raises(IncompatibleInputError, match="carries no arrivals"):
        correct_clock(bare, ClockRates.known([0.0, 1.0], 2), speed_m_s=C)
    with pytest.raises(IncompatibleInputError, match="clock rates for 3 devices"):
        correct_clock(ex, ClockRates.known([1.0, 2.0, 3.0], 3), speed_m_s=C)
    with pytest.raises(IncompatibleInputError, match="3 clock rate"):
        ClockRates.known([1.0, 2.0, 3.0], 2)
    assert ClockRates.known([7.0], 2).ppm.tolist() == [0.0, 7.0]
    assert ClockRates.known([3.0, 7.0], 2).ppm.tolist() == [3.0, 7.0]
    fixed, rates = correct_series_clock(iter(ex), speed_m_s=C, self_distance_m=0.1, ppm=[50.0])
    assert rates.ppm.tolist() == [0.0, 50.0]
    assert fixed[2].ranges[0].distance_m == pytest.approx(1.5, abs=1e-9)


@pytest.mark.parametrize(
    ("distance_m", "ppm", "seed"),
    [(0.3, (0.0, 50.0), 1), (2.0, (50.0, -50.0), 2), (4.5, (0.0, -50.0), 3)],
)
def test_acceptance_40_exchanges_in_a_room(tmp_path, distance_m, ppm, seed):
    """Issue 8: +-50 ppm on 40 exchanges 2 s apart (room, SNR 20 dB, jittered gaps,
    mono files, built-in beep and detector): estimate within 2 ppm, corrected ranges
    median |err| <= 1 cm and p90 <= 3 cm, uncorrected error the predicted c/2 e G."""
    room = ShoeboxRoom((6.0, 5.0, 3.0), absorption=0.3, max_order=3)
    devs = pair_devices(
        distance_m, self_distance_m=0.1, center_m=(3.0, 2.5, 1.2), azimuth_rad=0.3,
        rec_start_s=(0.0, 0.037), clock_ppm=ppm,
    )  # fmt: skip
    sim = render_exchanges(
        devs, source=beep_waveform(Beep()), source_fs=FS, n_exchanges=40, period_s=2.0,
        jitter_s=0.2, room=room, snr_db=20.0, rng=seed,
    )  # fmt: skip
    paths = [tmp_path / f"dev{i}.wav" for i in range(2)]
    for p, x in zip(paths, sim.recordings, strict=True):
        write_audio(p, x, fs=FS)
    ex = list(range_series_beepbeep(paths, self_distance_m=0.1))
    assert len(ex) == 40 and all(e.error is None for e in ex)
    rates = estimate_clock_rates(ex)
    rel = ((1 + ppm[1] * 1e-6) / (1 + ppm[0] * 1e-6) - 1) * 1e6
    assert abs(rates.ppm[1] - rel) <= 2.0
    assert rates.sigma_ppm[1] < 0.5
    c = speed_of_sound_m_s(20.0)
    fixed = correct_clock(ex, rates, speed_m_s=c, self_distance_m=0.1)
    d = sim.distances_m[0, 1]
    err = worse(np.abs([e.ranges[0].distance_m - d for e in fixed]))
    # Issue 8 asked for median <= 1 cm and p90 <= 3 cm; within 2x of today (issue 21):
    # measured median 1.05 / 1.01 / 0.75 mm, p90 2.11 / 2.62 / 2.48 mm (the three cases).
    assert np.median(err) <= 2.1e-3 and np.percentile(err, 90) <= 5.3e-3, err
    # Without the correction: -c/2 e G_k, G_k the true start-to-start gap of exchange k.
    unc = np.array([e.ranges[0].distance_m - d for e in ex])
    g = np.array([x["play_s"][1] - x["play_s"][0] for x in sim.truth["exchanges"]])
    pred = np.array([clock_error_m(rel, gk, speed_m_s=c) for gk in g])
    assert np.median(unc) == pytest.approx(np.median(pred), rel=0.2)
