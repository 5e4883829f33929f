"""``rangekit.detect._coherent``'s helpers against closed forms (issue 21, the mutation
check): the side-extremum ratio of a self response (and its symmetry), the windowed-sinc
interpolation (its symmetry, tones) and the extremum search on band-limited signals (its
interval), the weight of the coherent timing, the coherent lag of a pulse whose real part
peaks at a known lag (its reach, the array's first sample, the phase of a tone), the
interpolation RMS of a symmetric response. About a second.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.detect import _coherent as C


def _centred(values):
    """A real self response ``values`` (lag 0 in the middle), as complex."""
    return np.asarray(values, dtype=float).astype(complex)


def test_real_side_ratio_is_the_second_extremum_over_the_first():
    r = np.zeros(41)
    r[20], r[19], r[21] = 1.0, 0.6, 0.6
    r[14], r[26] = -0.4, 0.3  # side extrema of |Re R| at lags -6 and +6
    assert C.real_side_ratio(_centred(r), 10) == pytest.approx(0.4)
    assert C.real_side_ratio(_centred(r), 5) == 0.0  # within 5 lags: the main one only
    r[14] = -1.0  # a side extremum as large as the main one
    assert C.real_side_ratio(_centred(r), 10) == 1.0
    assert C.real_side_ratio(_centred([1.0, 2.0]), 5) == 1.0  # too short to tell
    assert C.real_side_ratio(_centred(np.linspace(0.0, 1.0, 9)), 4) == 1.0  # no extremum
    assert C.real_side_ratio(_centred(np.zeros(9)), 4) == 1.0


def test_sinc_interpolation_reconstructs_a_band_limited_signal():
    """Tones at 0.3 and 0.6 of the Nyquist frequency read at fractional indices away from
    the ends: within 4e-4 of their peak (about the documented 1e-4; measured 1.7e-4 and
    2.2e-4 at worst over 1000 points)."""
    n = np.arange(200.0)
    for f in (0.15, 0.3):
        x = np.cos(2 * np.pi * f * n + 0.4)
        for t in np.linspace(40.0, 160.0, 97):
            want = math.cos(2 * math.pi * f * t + 0.4)
            assert C._sinc_at(x, t) == pytest.approx(want, abs=4e-4), (f, t)
    x = np.cos(2 * np.pi * 0.15 * n + 0.4)
    assert C._sinc_at(x, 60.0) == pytest.approx(x[60], abs=1e-12)  # on the grid: the sample


def test_refine_extremum_finds_a_band_limited_pulses_peak():
    """A Gaussian-windowed tone whose real part peaks at 40.37: found to 1e-3 samples from
    the nearest sample (the golden section stops at 1e-4); at the ends the index."""
    n = np.arange(80.0)
    for t0 in (40.37, 40.5, 39.8):
        r = np.exp(-0.5 * ((n - t0) / 2.5) ** 2) * np.cos(2 * np.pi * 0.1 * (n - t0))
        i = int(np.argmax(np.abs(r)))
        assert C.refine_extremum(r, i) == pytest.approx(t0, abs=1e-3), t0
    r = np.exp(-0.5 * ((n - 30.0) / 2.5) ** 2)
    assert C.refine_extremum(r, 0) == 0.0 and C.refine_extremum(r, 79) == 79.0


def test_coherent_weight_at_its_corners():
    assert C.COHERENT_FULL_COS == pytest.approx(math.cos(math.radians(30.0)))
    assert C.COHERENT_NONE_COS == pytest.approx(0.5)
    assert C.coherent_weight(1.0) == 1.0 and C.coherent_weight(0.0) == 0.0
    mid = 0.5 * (C.COHERENT_FULL_COS + C.COHERENT_NONE_COS)
    assert C.coherent_weight(mid) == pytest.approx(0.5)


def test_coherent_lag_of_a_pulse_in_phase_at_its_peak():
    """A pulse whose carrier is in phase at its envelope peak (lag 32.3): its real part
    peaks there too, and ``|cos phase|`` is 1; a quarter period away, 0."""
    n = np.arange(64.0)
    env = np.exp(-0.5 * ((n - 32.3) / 3.0) ** 2)
    c = env * np.exp(2j * np.pi * 0.15 * (n - 32.3))
    t, cp = C.coherent_lag(c, 32.3, 3)
    assert t == pytest.approx(32.3, abs=1e-3) and cp == pytest.approx(1.0, abs=1e-4)
    _, cp = C.coherent_lag(c * 1j, 32.3, 3)
    assert cp == pytest.approx(0.0, abs=1e-3)
    assert C.coherent_lag(np.ones(64, dtype=complex), 32.0, 3) is None  # no extremum


def test_coherent_interp_rms_of_a_symmetric_self_response_is_small():
    """A self response with an even real part: the coherent lag follows a fractional
    delay to within 1.2e-5 samples RMS (measured 5.6e-6)."""
    n = np.arange(-64.0, 65.0)
    r = np.exp(-0.5 * (n / 4.0) ** 2) * np.exp(2j * np.pi * 0.12 * n)
    assert C.coherent_interp_rms(r, 3) < 1.2e-5


def test_refine_extremum_next_to_the_ends():
    """Indices 1 and len - 2 are refined (with the taps the array holds: measured 0.07 and
    0.15 samples off a peak at 1.3 and 38.3); only the end samples are returned as they are."""
    n = np.arange(40.0)
    for t0, i, tol in ((1.3, 1, 0.15), (38.3, 38, 0.25)):
        r = np.exp(-0.5 * ((n - t0) / 2.5) ** 2) * np.cos(2 * np.pi * 0.1 * (n - t0))
        assert C.refine_extremum(r, i) == pytest.approx(t0, abs=tol), t0


def test_coherent_lag_searches_reach_either_side():
    """An extremum of the real part exactly ``reach`` samples before or after the given
    lag (or between) is found there."""
    n = np.arange(64.0)
    for p in (29.0, 35.0, 34.6):
        c = np.exp(-0.5 * ((n - p) / 3.0) ** 2) * np.exp(2j * np.pi * 0.15 * (n - p))
        t, _ = C.coherent_lag(c, 32.0, 3)
        assert t == pytest.approx(p, abs=1e-3), p


def test_real_side_ratio_with_one_side_extremum():
    """Exactly two extrema of ``|Re R|`` within the reach (the main one and one side
    extremum): their ratio."""
    r = np.zeros(41)
    r[20], r[19], r[21] = 1.0, 0.6, 0.6
    r[14] = -0.4
    assert C.real_side_ratio(_centred(r), 10) == pytest.approx(0.4)


def test_real_side_ratio_is_the_same_for_the_mirrored_response():
    """``Re R`` of a self response is even: the ratio must not depend on which side of lag
    0 a side extremum lies, also at the edge of the reach (an extremum exactly ``reach``
    lags out has no neighbour beyond the reach on either side: not counted)."""
    for lag in (3, 4, 5, 6):
        r = np.zeros(41)
        r[20], r[19], r[21] = 1.0, 0.6, 0.6
        r[20 + lag] = 0.4
        want = C.real_side_ratio(_centred(r), 5)
        assert C.real_side_ratio(_centred(r[::-1]), 5) == want, lag
        assert want == (pytest.approx(0.4) if lag < 5 else 0.0), lag


def test_sinc_interpolation_is_mirror_symmetric():
    """The windowed-sinc kernel is even: reading the time-reversed samples at the mirrored
    index gives the same value, for any samples (measured 1.5e-14 on white noise)."""
    rng = np.random.default_rng(1)
    x = rng.standard_normal(101)
    for t in np.linspace(20.1, 80.9, 57):
        assert C._sinc_at(x, t) == pytest.approx(C._sinc_at(x[::-1], 100.0 - t), abs=1e-12), t


def test_refine_extremum_keeps_to_its_interval_and_improves_on_the_sample():
    """On white noise band-limited to 0.8 of the Nyquist frequency, at every local maximum
    ``i`` of ``|r|``: the refined extremum lies in the documented ``[i - 1, i + 1]``
    (measured within 0.66 samples of ``i`` over 1180 maxima) and ``|r|`` there, read by
    the same interpolation, is at least the sample's."""
    rng = np.random.default_rng(5)
    n = 256
    f = np.fft.rfftfreq(n)
    count = 0
    for _ in range(6):
        spec = np.fft.rfft(rng.standard_normal(n))
        spec[f > 0.4] = 0.0
        r = np.fft.irfft(spec, n)
        a = np.abs(r)
        for i in range(40, n - 40):
            if a[i] >= a[i - 1] and a[i] > a[i + 1]:
                t = C.refine_extremum(r, i)
                assert i - 1.0 <= t <= i + 1.0, (i, t)
                assert abs(C._sinc_at(r, t)) >= a[i] - 1e-12, (i, t)
                count += 1
    assert count > 300  # measured 354 maxima


def test_coherent_lag_at_the_first_interior_sample_and_with_no_reach():
    """An extremum of the real part at sample 1 (the first with a neighbour on each side)
    is found there (measured 0.0063 samples off with the taps the array holds); with
    ``reach`` 0 the search is the lag's own sample (an extremum: refined, measured 1.3e-4
    off)."""
    n = np.arange(64.0)
    c = np.exp(-0.5 * ((n - 1.0) / 3.0) ** 2) * np.exp(2j * np.pi * 0.15 * (n - 1.0))
    t, cp = C.coherent_lag(c, 1.0, 3)
    assert t == pytest.approx(1.0, abs=0.013) and cp == pytest.approx(1.0, abs=1e-4)
    t, _ = C.coherent_lag(c, 2.0, 1)
    assert t == pytest.approx(1.0, abs=0.013)
    c = np.exp(-0.5 * ((n - 32.3) / 3.0) ** 2) * np.exp(2j * np.pi * 0.15 * (n - 32.3))
    t, cp = C.coherent_lag(c, 32.3, 0)
    assert t == pytest.approx(32.3, abs=3e-4) and cp == pytest.approx(1.0, abs=1e-4)


def test_coherent_lag_phase_of_an_analytic_tone():
    """``|cos phase|`` at a fractional lag of a constant-envelope analytic tone (every tap
    of the interpolation carries signal): within 8e-5 of the exact ``|cos|`` (measured
    9.4e-6 at 0.1 and 4.0e-5 at 0.2 cycles per sample)."""
    n = np.arange(200.0)
    for f in (0.1, 0.2):
        for lag in np.linspace(80.05, 120.95, 41):
            for ph in (0.3, 0.8, 1.2):
                c = np.exp(1j * (2 * np.pi * f * (n - lag) + ph))
                _, cp = C.coherent_lag(c, lag, 3)
                assert cp == pytest.approx(abs(math.cos(ph)), abs=8e-5), (f, lag, ph)


def test_coherent_interp_rms_with_a_reach_of_one_sample():
    """The symmetric self response of the test above, searched one sample either side of
    each fractional delay: the same RMS as with reach 3 (measured 5.6e-6 at both)."""
    n = np.arange(-64.0, 65.0)
    r = np.exp(-0.5 * (n / 4.0) ** 2) * np.exp(2j * np.pi * 0.12 * n)
    assert C.coherent_interp_rms(r, 1) < 1.2e-5


def test_coherent_lag_takes_no_extremum_beyond_its_reach():
    """Extrema of the real part every 2 samples (0.25 cycles per sample), the largest one
    ``reach + 1`` samples from the lag: the largest within ``+- reach`` is taken, on
    either side (refined 0.049 samples off its sample, towards the envelope's peak)."""
    n = np.arange(64.0)
    for peak, want in ((36.0, 34.0), (28.0, 30.0)):
        c = np.exp(-0.5 * ((n - peak) / 4.0) ** 2) * np.exp(2j * np.pi * 0.25 * (n - peak))
        t, _ = C.coherent_lag(c, 32.0, 3)
        assert t == pytest.approx(want, abs=0.1), peak


def test_real_side_ratio_of_a_side_extremum_between_two_samples():
    """A side extremum that falls between two samples (two equal samples) counts once."""
    r = np.zeros(41)
    r[20], r[19], r[21] = 1.0, 0.6, 0.6
    r[14] = r[15] = -0.4
    assert C.real_side_ratio(_centred(r), 10) == pytest.approx(0.4)


def test_coherent_lag_at_the_last_interior_sample():
    """An extremum of the real part at sample ``len - 2`` (the last with a neighbour on
    each side) is found there (measured 0.0063 samples off, as at sample 1)."""
    n = np.arange(64.0)
    c = np.exp(-0.5 * ((n - 62.0) / 3.0) ** 2) * np.exp(2j * np.pi * 0.15 * (n - 62.0))
    t, _ = C.coherent_lag(c, 62.0, 3)
    assert t == pytest.approx(62.0, abs=0.013)


def test_sinc_interpolation_accuracy_near_the_top_of_the_band():
    """The accuracy ``SINC_BETA``'s comment states: a tone at 0.8 of the Nyquist
    frequency within 1.2e-4 of its peak (measured 5.8e-5; at 0.9 of it 4.7e-2)."""
    n = np.arange(200.0)
    x = np.cos(2 * np.pi * 0.4 * n + 0.4)
    for t in np.linspace(40.0, 160.0, 197):
        assert C._sinc_at(x, t) == pytest.approx(math.cos(2 * math.pi * 0.4 * t + 0.4), abs=1.2e-4)


def test_refine_extremum_on_a_20_hz_20_khz_probes_correlation():
    """The real autocorrelation of a 20 Hz-20 kHz sweep at 44.1 kHz (content up to 0.91
    of the Nyquist frequency, where the interpolation is least accurate), delayed by
    sixteenths of a sample: its extremum within 1e-4 samples (measured 4.4e-5)."""
    from rangekit.signals.probe import linear_sweep

    p = linear_sweep(20.0, 20000.0, 0.1, fs=44100.0).samples
    n = 1 << 14
    spec = np.abs(np.fft.rfft(p, n)) ** 2
    f = np.fft.rfftfreq(n)
    for d in np.arange(16) / 16.0:
        r = np.fft.irfft(spec * np.exp(-2j * np.pi * f * (n // 2 + d)), n)
        i = int(np.argmax(np.abs(r)))
        assert C.refine_extremum(r, i) == pytest.approx(n // 2 + d, abs=1e-4), d
