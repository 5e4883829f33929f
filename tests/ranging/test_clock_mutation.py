"""Clock-rate fit against its closed forms and limits (module Notes of rangekit.ranging.clock).

Synthetic onsets only (no audio). Written against the mutants of
``rangekit/ranging/clock.py`` that ``tests/ranging/test_clock.py`` lets through
(``benchmarks/mutation.py``, docs/evidence.md).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.errors import DetectionError, IncompatibleInputError, InvalidParameterError
from rangekit.ranging.clock import (
    MIN_EXCHANGES,
    MIN_SPAN_S,
    ClockRates,
    clock_error_m,
    correct_clock,
    correct_series_clock,
    estimate_clock_rates,
)
from rangekit.ranging.series import ExchangeRanges
from rangekit.types import Arrivals, Range

C = 343.0
FS = 44100.0


def _pair(t0, t1, sig):
    """Two recordings' arrivals: onsets (s) of device 0's and device 1's beep."""
    return tuple(
        Arrivals(
            np.asarray(t) * FS,
            FS,
            np.asarray(s, dtype=float) * FS,
            np.full(2, 30.0),
            np.ones(2),
            np.zeros((2, 4)),
            "changepoint",
        )
        for t, s in ((t0, sig[0]), (t1, sig[1]))
    )


def _exchanges(ppm=40.0, n=8, period=1.5, noise_s=(), sig_s=None, d=1.2):
    """Exchanges of two devices 1.2 m apart, device 1 ``ppm`` fast; ``noise_s[k]`` (s) is
    added to device 1's own beep in its own recording (its midpoint moves by half)."""
    e = ppm * 1e-6
    out = []
    for k in range(n):
        p0, p1 = 0.3 + k * period, 0.9 + k * period
        own = noise_s[k] if k < len(noise_s) else 0.0
        sig = sig_s[k] if sig_s is not None else ((1e-5, 1e-5), (1e-5, 1e-5))
        heard = np.array([p0 + d / C, p1 + own])  # device 1's recording, true time
        a = _pair([p0, p1 + d / C], heard * (1 + e) + 0.02, sig)
        out.append(ExchangeRanges(k, p0, (), arrivals=a))
    return out


def _wls(x, y, var):
    w = 1.0 / var
    xm = np.sum(w * x) / np.sum(w)
    b = np.sum(w * (x - xm) * (y - np.sum(w * y) / np.sum(w))) / np.sum(w * (x - xm) ** 2)
    a = np.sum(w * (y - b * (x - xm))) / np.sum(w)
    r = y - a - b * (x - xm)
    s2 = np.sum(w * r * r) / (len(x) - 2)
    return b, math.sqrt(s2 / np.sum(w * (x - xm) ** 2))


def test_rate_and_sigma_are_the_weighted_line_of_the_midpoints():
    """Slope of (Mi - M0) on M0 with weights 1 / (var Mi + var M0), var from the four
    onsets' sigmas; its sigma from the residuals (module Notes)."""
    rng = np.random.default_rng(3)
    noise = rng.normal(0, 2e-6, 8)
    sig = [((1e-5, 2e-5), (3e-5, 1e-5 * (1 + k))) for k in range(8)]
    ex = _exchanges(noise_s=noise, sig_s=sig)
    rates = estimate_clock_rates(ex)
    x = np.array([0.5 * (e.arrivals[0].onset_s[0] + e.arrivals[0].onset_s[1]) for e in ex])
    y = np.array([0.5 * (e.arrivals[1].onset_s[0] + e.arrivals[1].onset_s[1]) for e in ex])
    var = np.array([0.25 * sum(a**2 + b**2 for a, b in s) for s in sig])
    b, sb = _wls(x, y - x, var)
    assert rates.ppm[0] == 0.0 and rates.sigma_ppm[0] == 0.0
    assert rates.ppm[1] == pytest.approx(1e6 * b, rel=1e-9)
    assert rates.sigma_ppm[1] == pytest.approx(1e6 * sb, rel=1e-9)
    assert abs(rates.ppm[1] - 40.0) < 5 * rates.sigma_ppm[1]
    assert rates.n_exchanges == 8 and rates.n_rejected == 0
    assert rates.span_s == pytest.approx(7 * 1.5, rel=1e-12)


def test_zero_onset_sigmas_are_floored():
    """Exact onsets with sigma 0: the weights use a 1 ns floor (finite, equal weights)."""
    zero = [((0.0, 0.0), (0.0, 0.0))] * 6
    ex = _exchanges(noise_s=[0.0, 1e-7, 0.0, -1e-7, 0.0, 2e-7], sig_s=zero, n=6)
    rates = estimate_clock_rates(ex)
    assert np.isfinite(rates.sigma_ppm[1]) and rates.sigma_ppm[1] > 0
    x = np.array([0.5 * sum(e.arrivals[0].onset_s) for e in ex])
    y = np.array([0.5 * sum(e.arrivals[1].onset_s) for e in ex])
    b, sb = _wls(x, y - x, np.full(6, 1e-18))
    assert rates.ppm[1] == pytest.approx(1e6 * b, rel=1e-9)
    assert rates.sigma_ppm[1] == pytest.approx(1e6 * sb, rel=1e-9)


def test_outlier_rejection_threshold():
    """Dropped beyond max(5 x 1.4826 MAD, 3) nominal sigmas; a point at 2.5 sigma stays.

    The onsets' sigma is 10 us, so a midpoint's nominal sigma is 10 us and moving one of
    device 1's onsets by 2 s moves its midpoint by s; the others lie exactly on the line
    (MAD 0): the floor of 3 sigma decides."""
    s = 1e-5
    kept = estimate_clock_rates(_exchanges(noise_s=[0, 0, 0, 2 * 2.5 * s]))
    assert kept.n_rejected == 0 and kept.n_exchanges == 8
    dropped = estimate_clock_rates(_exchanges(noise_s=[0, 0, 0, 2 * 3.5 * s]))
    assert dropped.n_rejected == 1 and dropped.n_exchanges == 7
    assert dropped.ppm[1] == pytest.approx(40.0, abs=1e-6)
    # the span is that of the kept exchanges: drop the last one
    last = estimate_clock_rates(_exchanges(n=20, noise_s=[0] * 19 + [2 * 10 * s]))
    assert last.n_rejected == 1 and last.span_s == pytest.approx(18 * 1.5, rel=1e-12)


def test_minimum_exchanges_and_span_are_inclusive():
    assert MIN_EXCHANGES == 3 and MIN_SPAN_S == 1.0
    three = _exchanges(n=3, period=0.5)  # span exactly 1.0 s
    assert estimate_clock_rates(three).n_exchanges == 3
    with pytest.raises(IncompatibleInputError, match="at least 3 exchanges, got 2"):
        estimate_clock_rates(three[:2])
    with pytest.raises(IncompatibleInputError, match=r"span 1\.000 s; .* at least 1\.5 s"):
        estimate_clock_rates(three, min_span_s=1.5)
    with pytest.raises(IncompatibleInputError, match="at least 4 exchanges, got 3"):
        estimate_clock_rates(three, min_exchanges=4)
    with pytest.raises(InvalidParameterError, match="min_exchanges"):
        estimate_clock_rates(three, min_exchanges=2)
    failed = ExchangeRanges(3, 2.0, (Range(0, 1, math.nan, math.nan),), "exchange 3: no beep")
    with pytest.raises(DetectionError, match="only 3 of 4 have them"):
        estimate_clock_rates([*three, failed], min_exchanges=4)
    bare = ExchangeRanges(9, 5.0, ())
    with pytest.raises(IncompatibleInputError, match=r"exchange 9 at 5\.000 s carries no arrivals"):
        estimate_clock_rates([*three, bare])


def test_known_rates():
    assert ClockRates.known([49.8], 2).ppm.tolist() == [0.0, 49.8]
    three = ClockRates.known([1.0, 2.0, 3.0], 3)
    assert three.ppm.tolist() == [1.0, 2.0, 3.0] and three.sigma_ppm.tolist() == [0.0] * 3
    assert (three.n_exchanges, three.span_s, three.n_rejected) == (0, 0.0, 0)
    assert ClockRates.known([1e4, -1e4], 3).ppm.tolist() == [0.0, 1e4, -1e4]
    with pytest.raises(InvalidParameterError, match="clock rate"):
        ClockRates.known([1.0001e4], 2)
    with pytest.raises(IncompatibleInputError, match="3 clock rate\\(s\\) given for 2 devices"):
        ClockRates.known([1.0, 2.0, 3.0], 2)
    d = ClockRates(np.array([0.0, 5.0]), np.array([0.0, 0.5]), 7, 12.0, 2).as_dict()
    assert d == {"ppm": [0.0, 5.0], "sigma_ppm": [0.0, 0.5], "n_exchanges": 7, "span_s": 12.0,
                 "n_rejected": 2}  # fmt: skip


def test_clock_error_closed_form():
    assert clock_error_m(50.0, 0.6, speed_m_s=343.0) == pytest.approx(-0.5 * 343 * 50e-6 * 0.6)
    assert clock_error_m(-20.0, 1.0, speed_m_s=340.0) == pytest.approx(0.5 * 340 * 20e-6)


def test_correction_gives_the_true_distance_and_the_tolerance_default():
    ex = _exchanges()
    rates = estimate_clock_rates(ex)
    fixed = correct_clock(ex, rates, speed_m_s=C)
    for f in fixed:
        assert f.ranges[0].distance_m == pytest.approx(1.2, abs=2e-9)
    # the remaining tolerance defaults to the largest sigma_ppm: here tiny, so sigma_m is
    # that of the onsets alone; a 100 ppm tolerance (0.6 s gap) adds c/2 * 1e-4 * 0.6
    loose = correct_clock(ex, rates, speed_m_s=C, clock_ppm=100.0)[0].ranges[0].sigma_m
    tight = fixed[0].ranges[0].sigma_m
    assert loose > tight + 0.5 * C * 100e-6 * 0.6 * 0.9
    same = correct_clock(ex, rates, speed_m_s=C, clock_ppm=float(np.max(rates.sigma_ppm)))
    assert same[0].ranges[0].sigma_m == tight
    with pytest.raises(InvalidParameterError, match="clock_ppm=nan"):
        correct_clock(ex, rates, speed_m_s=C, clock_ppm=math.nan)
    with pytest.raises(IncompatibleInputError, match="clock rates for 3 devices"):
        correct_clock(ex, ClockRates.known([1.0, 2.0], 3), speed_m_s=C)
    failed = ExchangeRanges(8, 9.0, (Range(0, 1, math.nan, math.nan),), "no beep")
    assert correct_clock([failed], rates, speed_m_s=C) == [failed]
    with pytest.raises(IncompatibleInputError, match="carries no arrivals to correct"):
        correct_clock([ExchangeRanges(1, 1.0, ())], rates, speed_m_s=C)


@pytest.mark.parametrize("n_devices", [2, 3, 4])
def test_series_with_known_rates_counts_devices_from_the_pairs(n_devices):
    """Without arrivals (a failed exchange) the device count comes from N (N - 1) / 2."""
    pairs = n_devices * (n_devices - 1) // 2
    failed = ExchangeRanges(0, 0.0, (Range(0, 1, math.nan, math.nan),) * pairs, "no beep")
    fixed, rates = correct_series_clock([failed], speed_m_s=C, ppm=[7.0] * (n_devices - 1))
    assert fixed == [failed] and rates.ppm.tolist() == [0.0] + [7.0] * (n_devices - 1)
    with pytest.raises(IncompatibleInputError, match=f"given for {n_devices} devices"):
        correct_series_clock([failed], speed_m_s=C, ppm=[7.0] * (n_devices + 1))
    empty, r = correct_series_clock([], speed_m_s=C, ppm=[1.0, 2.0])
    assert empty == [] and r.ppm.tolist() == [1.0, 2.0]


def test_rejection_may_leave_exactly_three_exchanges():
    """Outliers are dropped as long as MIN_EXCHANGES (3) remain: 5 exchanges, 2 off."""
    rates = estimate_clock_rates(_exchanges(n=5, noise_s=[2e-4, -3e-4]))
    assert (rates.n_rejected, rates.n_exchanges) == (2, 3)
    assert rates.ppm[1] == pytest.approx(40.0, abs=1e-6)


def test_exchanges_with_other_device_counts_are_refused():
    ex = _exchanges(n=4)
    three = ExchangeRanges(9, 7.0, (), arrivals=(*ex[0].arrivals, ex[0].arrivals[0]))
    with pytest.raises(IncompatibleInputError, match="exchange 9 has 3 recordings where the ot"):
        estimate_clock_rates([*ex, three])


def test_span_is_that_of_device_0s_own_beeps():
    """span_s: first to last own beep of device 0 in its recording, whatever the gaps."""
    ex = _exchanges(n=4)
    last = ex[-1]
    t0, t1 = last.arrivals[0].onset_s, last.arrivals[1].onset_s
    late = _pair(
        [t0[0], t0[1] + 0.25], [t1[0], t1[1] + 0.25 * (1 + 40e-6)], ((1e-5, 1e-5), (1e-5, 1e-5))
    )  # fmt: skip  (device 1 plays 0.25 s later)
    ex[-1] = ExchangeRanges(3, last.t_s, (), arrivals=late)
    assert estimate_clock_rates(ex).span_s == pytest.approx(t0[0] - ex[0].arrivals[0].onset_s[0])
