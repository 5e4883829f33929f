"""Conditioning steps of ``rangekit.detect.condition``, each on its own (issue 21).

Each test pins the property a step exists for (a flat pass band and the attenuation asked
for, no time shift, clipped samples found and only those, a noise floor that digital
silence does not pull down, the numpy replacements equal to the library functions they
stand in for), not the constants that reach it. Runs in about a second.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import firwin, kaiser_beta, kaiserord

from rangekit import _validate as V
from rangekit.detect import condition as C

FS = 44100.0


def _response(h: np.ndarray, freqs: np.ndarray, fs: float = FS) -> np.ndarray:
    """|H(f)| of the FIR taps ``h`` at ``freqs`` (Hz), exactly (no FFT grid)."""
    k = np.arange(len(h))
    return np.abs(np.exp(-2j * np.pi * np.outer(freqs / fs, k)) @ h)


# ---------------------------------------------------------------- bandpass_taps


@pytest.mark.parametrize(
    ("lo", "hi", "tw"),
    [(14000.0, 18000.0, None), (2000.0, 6000.0, None), (16000.0, 17000.0, None),
     (3000.0, 9000.0, 1500.0)],
)  # fmt: skip
def test_band_pass_is_flat_in_band_and_attenuated_outside(lo, hi, tw):
    h = C.bandpass_taps(FS, lo, hi, transition_hz=tw)
    width = min(3000.0, max(300.0, 0.25 * (hi - lo))) if tw is None else tw
    assert len(h) % 2 == 1
    np.testing.assert_array_equal(h, h[::-1])  # linear phase: delay (len - 1) / 2 exactly
    ripple = 10 ** (-C.DEFAULT_ATTEN_DB / 20)
    band = np.linspace(lo, hi, 41)
    assert np.max(np.abs(_response(h, band) - 1.0)) < 2.0 * ripple  # measured 1.51e-3 at most
    stop = np.concatenate([np.linspace(0.0, lo - width, 60), np.linspace(hi + width, FS / 2, 60)])
    assert np.max(_response(h, stop)) < 2.0 * ripple
    # and the transition is not wider than asked: half-way through it, the gain is ~0.5
    assert 0.3 < _response(h, np.array([lo - 0.5 * width]))[0] < 0.7


def test_length_is_kaisers_estimate_for_the_narrowest_transition():
    """n from Kaiser's formula (scipy.signal.kaiserord), made odd, for the width used."""
    cases = [(14000.0, 18000.0, 1000.0), (2000.0, 8000.0, 500.0), (5000.0, 9000.0, 2000.0)]
    for lo, hi, tw in cases:
        h = C.bandpass_taps(FS, lo, hi, transition_hz=tw)
        n_ref, _ = kaiserord(C.DEFAULT_ATTEN_DB, tw / (0.5 * FS))
        assert len(h) in (n_ref, n_ref + 1) and len(h) % 2 == 1
    # default transition: a quarter of the band, clamped to [300, 3000] Hz
    assert len(C.bandpass_taps(FS, 14000.0, 18000.0)) == len(
        C.bandpass_taps(FS, 14000.0, 18000.0, transition_hz=1000.0)
    )
    assert len(C.bandpass_taps(FS, 5000.0, 18000.0)) == len(
        C.bandpass_taps(FS, 5000.0, 18000.0, transition_hz=3000.0)
    )  # a quarter of 13 kHz is 3.25 kHz: clamped to 3 kHz
    assert len(C.bandpass_taps(FS, 10000.0, 10400.0)) == len(
        C.bandpass_taps(FS, 10000.0, 10400.0, transition_hz=300.0)
    )
    # a higher attenuation needs a longer filter, and reaches it
    h80 = C.bandpass_taps(FS, 14000.0, 18000.0, atten_db=80.0)
    assert len(h80) > len(C.bandpass_taps(FS, 14000.0, 18000.0))
    assert np.max(_response(h80, np.linspace(0.0, 13000.0, 50))) < 1.5e-4


def test_shortest_filter_is_nine_taps():
    h = C.bandpass_taps(8000.0, 500.0, 1500.0, transition_hz=3000.0, atten_db=10.0)
    assert len(h) == 9


def test_low_pass_high_pass_and_all_pass():
    lp = C.bandpass_taps(FS, 0.0, 5000.0)  # lo 0: a low-pass, unit gain at DC
    assert _response(lp, np.array([0.0, 2500.0, 5000.0])) == pytest.approx(1.0, abs=1.5e-3)
    assert np.max(_response(lp, np.linspace(5000.0 + 1250.0, FS / 2, 50))) < 1.5e-3
    hp = C.bandpass_taps(FS, 15000.0, 21500.0)  # hi + tw beyond Nyquist: a high-pass
    assert _response(hp, np.array([15000.0, 20000.0, FS / 2])) == pytest.approx(1.0, abs=1.5e-3)
    assert np.max(_response(hp, np.linspace(0.0, 15000.0 - 3000.0, 50))) < 1.5e-3
    ap = C.bandpass_taps(FS, 0.0, 21000.0)  # both: nothing to remove, a delayed impulse
    assert np.count_nonzero(ap) == 1 and ap[len(ap) // 2] == 1.0
    # hi close to Nyquist: the upper transition is the room left, the lower one is tw
    h = C.bandpass_taps(FS, 14000.0, 21000.0, transition_hz=2000.0)
    n_ref, _ = kaiserord(C.DEFAULT_ATTEN_DB, 2000.0 / (0.5 * FS))
    assert len(h) in (n_ref, n_ref + 1)
    assert np.max(_response(h, np.linspace(0.0, 12000.0, 50))) < 1.5e-3


def test_upper_transition_reaching_nyquist_exactly_makes_a_high_pass():
    """'hi at or above Nyquist minus the transition makes a high-pass': Nyquist passes."""
    h = C.bandpass_taps(FS, 17050.0, 21050.0, transition_hz=1000.0)  # 21050 + 1000 = Nyquist
    assert _response(h, np.array([21050.0, FS / 2])) == pytest.approx(1.0, abs=2e-3)
    h = C.bandpass_taps(FS, 17050.0, 21049.0, transition_hz=1000.0)  # 1 Hz short: band-pass
    assert _response(h, np.array([FS / 2]))[0] < 2e-3


def test_lower_transition_shrinks_to_reach_zero_hz_only():
    """lo below the transition width: the lower transition becomes lo (0 Hz is stopped)."""
    h = C.bandpass_taps(FS, 400.0, 6000.0, transition_hz=1000.0)
    n_ref, _ = kaiserord(C.DEFAULT_ATTEN_DB, 400.0 / (0.5 * FS))
    assert len(h) in (n_ref, n_ref + 1)
    assert _response(h, np.array([0.0]))[0] < 2.5e-3  # DC removed (measured 1.8e-3)
    assert _response(h, np.array([400.0, 3000.0, 6000.0])) == pytest.approx(1.0, abs=1.5e-3)


def test_taps_are_read_only_and_cached():
    h = C.bandpass_taps(FS, 14000.0, 18000.0)
    assert not h.flags.writeable and h.dtype == np.float64
    assert C.bandpass_taps(FS, 14000.0, 18000.0) is h


@pytest.mark.parametrize(("lo", "hi"), [(5000.0, 5000.0), (6000.0, 5000.0), (-1.0, 5000.0)])
def test_band_must_be_ordered_and_non_negative(lo, hi):
    with pytest.raises(V.InvalidParameterError):
        C.bandpass_taps(FS, lo, hi)


@pytest.mark.parametrize("atten", [10.0, 21.0, 21.5, 30.0, 50.0, 50.5, 60.0, 80.0])
def test_kaiser_beta_equals_scipy(atten):
    assert C._kaiser_beta(atten) == pytest.approx(kaiser_beta(atten), rel=1e-12, abs=1e-15)


@pytest.mark.parametrize(
    ("n", "cut", "pz"),
    [(31, [5000.0], True), (31, [5000.0], False), (41, [3000.0, 9000.0], False),
     (41, [3000.0, 9000.0], True), (33, [2000.0, 8000.0, 12000.0], True)],
)  # fmt: skip
def test_firwin_kaiser_equals_scipy(n, cut, pz):
    beta = kaiser_beta(40.0)
    ref = firwin(n, cut, window=("kaiser", beta), fs=FS, pass_zero=pz)
    got = C._firwin_kaiser(n, cut, beta, FS, pass_zero=pz)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-14 * np.max(np.abs(ref)))


# ---------------------------------------------------------------- bandlimit


def test_bandlimit_keeps_the_time_origin():
    h = C.bandpass_taps(FS, 14000.0, 18000.0)
    x = np.zeros(2000)
    x[900] = 1.0
    y = C.bandlimit(x, h)
    half = (len(h) - 1) // 2
    assert len(y) == len(x)
    np.testing.assert_allclose(y[900 - half : 900 + half + 1], h, atol=1e-15)
    assert int(np.argmax(np.abs(y))) == 900
    # sum_k taps[k] x[n + half - k], samples outside x as zero, at the edges too
    x = np.random.default_rng(0).normal(size=50)
    taps = np.array([0.1, -0.2, 0.7, 0.3, -0.05])
    want = [sum(taps[k] * (x[n + 2 - k] if 0 <= n + 2 - k < 50 else 0.0) for k in range(5))
            for n in range(50)]  # fmt: skip
    np.testing.assert_allclose(C.bandlimit(x, taps), want, atol=1e-14)


def test_bandlimit_long_input_equals_direct_convolution():
    """Above 2^20 products the overlap-add path runs: same output as the direct one."""
    h = C.bandpass_taps(FS, 14000.0, 18000.0)
    x = np.random.default_rng(1).normal(size=(1 << 20) // len(h) + 500)
    half = (len(h) - 1) // 2
    want = np.convolve(x, h)[half : half + len(x)]
    got = C.bandlimit(x, h)
    np.testing.assert_allclose(got, want, atol=1e-9)
    assert got.flags.c_contiguous


def test_bandlimit_edge_cases():
    x = np.arange(5.0)
    assert C.bandlimit(np.zeros(0), np.ones(3)).shape == (0,)
    np.testing.assert_array_equal(C.bandlimit(x, np.array([2.0])), 2.0 * x)
    for bad in (np.ones(4), np.ones((3, 3))):
        with pytest.raises(V.InvalidParameterError):
            C.bandlimit(x, bad)


# ---------------------------------------------------------------- clip_mask


def _tone(n=2000, f=1000.0, amp=1.0, fs=FS):
    return amp * np.sin(2 * np.pi * f * np.arange(n) / fs + 0.3)


def test_clip_mask_finds_clipped_samples_and_only_those():
    x = _tone()
    assert not C.clip_mask(x).any()
    y = np.clip(x, -0.6, 0.6)
    np.testing.assert_array_equal(C.clip_mask(y), np.abs(y) >= 0.6)
    # one rail only (a limiter clipping asymmetrically): the other rail is left alone
    z = np.minimum(x, 0.6)
    np.testing.assert_array_equal(C.clip_mask(z), z >= 0.6)
    z = np.maximum(x, -0.6)
    np.testing.assert_array_equal(C.clip_mask(z), z <= -0.6)


def test_clip_mask_run_length_and_tolerance():
    x = np.zeros(100)
    x[::7] = 0.5
    x[1::7] = -0.5
    x[40] = x[41] = 1.0  # a run of two at the maximum: clipped
    m = C.clip_mask(x, min_count=99)
    assert m[40] and m[41] and m.sum() == 2 + 0  # the lower rail has no run
    x[41] = 0.0  # a single sample at the maximum: not clipped
    assert not C.clip_mask(x, min_count=99)[40]
    x[60] = 1.0  # two samples at the maximum, apart: no run, not clipped
    assert not C.clip_mask(x, min_count=99)[[40, 60]].any()
    x[60] = 0.0
    # within rel_tol of the peak-to-peak range counts as at the rail
    x[41] = 1.0 - 0.5e-4 * 1.5
    assert C.clip_mask(x, min_count=99)[[40, 41]].all()
    x[41] = 1.0 - 2e-4 * 1.5
    assert not C.clip_mask(x, min_count=99)[40]
    # min_run 3: a run of two does not count, a run of three does
    x[41] = 1.0
    assert not C.clip_mask(x, min_run=3, min_count=99).any()
    x[60] = 1.0  # three samples at the rail, two of them adjacent: still no run of three
    assert not C.clip_mask(x, min_run=3, min_count=99).any()
    x[60] = 0.0
    x[42] = 1.0
    assert C.clip_mask(x, min_run=3, min_count=99)[40:43].all()
    # min_run 1: any sample at the rail
    y = np.zeros(10)
    y[3], y[7] = 1.0, -1.0
    np.testing.assert_array_equal(np.flatnonzero(C.clip_mask(y, min_run=1)), [3, 7])


def test_clip_mask_counts_exact_rail_touches_without_runs():
    """A clipped sweep may touch the rail one sample at a time: min_count touches clip it."""
    x = np.zeros(200)
    x[1::2] = -np.linspace(0.2, 0.3, 100)  # the lower rail touched once
    idx = np.arange(10, 10 + 2 * 8, 2)  # 8 isolated samples exactly at the maximum
    x[idx] = 1.0
    assert C.clip_mask(x)[idx].all()
    assert not C.clip_mask(x, min_count=9).any()
    x[idx[-1]] = 0.9  # 7 touches: not clipped
    assert not C.clip_mask(x).any()


def test_clip_mask_touches_must_be_sustained():
    """Touches spread out (each copy of a digitally mixed signal reaching the same exact
    peak) are not clipping; the same touches less than max_gap apart are."""
    for gap, clipped in ((63, True), (64, False)):
        x = np.zeros(1000)
        x[1::2] = -np.linspace(0.2, 0.3, 500)
        idx = 5 + gap * np.arange(8)
        x[idx] = 1.0
        assert C.clip_mask(x).any() == clipped, gap
        assert C.clip_mask(x, max_gap=gap + 1)[idx].all()
    # 8 touches, only 7 of them in one sustained stretch
    x[idx] = 0.0
    idx = np.r_[5 + 10 * np.arange(7), 900]
    x[idx] = 1.0
    assert not C.clip_mask(x).any()
    x[80] = 1.0  # the eighth joins the stretch
    assert C.clip_mask(x)[idx].all()


def test_clip_mask_lightly_clipped_sweep_and_mixed_copies():
    fs = 44100.0
    t = np.arange(4410) / fs
    sweep = np.sin(2 * np.pi * (17000 * t + 0.5 * 3e4 * t * t))  # 17-20 kHz in 0.1 s
    assert not C.clip_mask(sweep).any()
    for db in (0.1, 1.0, 6.0):
        c = 10 ** (-db / 20)
        y = np.clip(sweep, -c, c)
        m = C.clip_mask(y)
        # every clipped sample is found (0.1 dB: 413 of them, 85 samples apart at the 99th
        # percentile); at most a few more lie within rel_tol of the rail
        assert m[np.abs(y) >= c].all(), db
        assert m.sum() <= (np.abs(y) >= c).sum() + 4, db
    # twenty identical peak-normalised bursts, 0.5 s apart: 40 exact touches of each rail
    # (two per burst), not one sustained stretch
    burst = np.sin(2 * np.pi * 16000 * np.arange(441) / fs) * np.hanning(441)
    burst /= np.max(np.abs(burst))
    x = np.zeros(int(10.5 * fs))
    for k in range(20):
        x[int(k * 0.5 * fs) : int(k * 0.5 * fs) + 441] += burst
    assert np.count_nonzero(x == x.max()) >= 8
    assert not C.clip_mask(x).any()
    assert C.clip_mask(x, max_gap=10**9).any()  # what the rule without max_gap said


def test_clip_mask_digital_silence_and_degenerate_input():
    # zeros at the lower rail are digital silence, not clipping (a rectified signal)
    x = np.concatenate([np.zeros(100), np.abs(_tone(400))])
    m = C.clip_mask(x)
    assert not m[:100].any()
    assert not C.clip_mask(np.full(50, 0.7)).any()  # no span
    assert not C.clip_mask(np.array([1.0])).any()  # shorter than a run
    assert C.clip_mask(np.array([1.0, 1.0, 0.0])).tolist() == [True, True, False]
    assert C.clip_mask(np.array([-1.0, -1.0, 0.0])).tolist() == [True, True, False]


def test_clip_mask_float32_and_int_same_as_float64():
    x = np.clip(_tone(3000, 777.0), -0.55, 0.7)
    want = C.clip_mask(x)
    assert want.any()
    np.testing.assert_array_equal(C.clip_mask(x.astype(np.float32)), C.clip_mask(
        x.astype(np.float32).astype(np.float64)))  # fmt: skip
    q = np.round(x * 32767).astype(np.int16)
    np.testing.assert_array_equal(C.clip_mask(q), C.clip_mask(q.astype(np.float64)))
    np.testing.assert_array_equal(C.clip_mask(q), want)


def test_threshold_float32_rounds_outward():
    for t in (0.1, 0.7, 1.0 / 3.0, -0.2):
        up = C._threshold(t, np.dtype(np.float32), up=True)
        dn = C._threshold(t, np.dtype(np.float32), up=False)
        assert isinstance(up, np.float32) and isinstance(dn, np.float32)
        assert float(up) >= t and float(dn) <= t
        assert float(np.nextafter(up, np.float32(-np.inf))) < t  # the nearest such
        assert float(np.nextafter(dn, np.float32(np.inf))) > t
    assert C._threshold(0.1, np.dtype(np.float64), up=True) == 0.1
    # a threshold a float32 holds exactly is itself (not one step further out)
    for t in (0.5, -0.25, 0.75):
        assert C._threshold(t, np.dtype(np.float32), up=True) == np.float32(t)
        assert C._threshold(t, np.dtype(np.float32), up=False) == np.float32(t)


def test_runs_at_least():
    m = np.array([1, 1, 0, 1, 1, 1, 0, 1], bool)
    assert C._runs_at_least(m, 3).tolist() == [0, 0, 0, 1, 1, 1, 0, 0]
    assert C._runs_at_least(m, 2).tolist() == [1, 1, 0, 1, 1, 1, 0, 0]
    assert C._runs_at_least(m, 1).tolist() == m.tolist()
    assert C._runs_at_least(m, 4).sum() == 0


# ---------------------------------------------------------------- dilate


def test_dilate_widens_by_half_each_side_and_stops_at_the_ends():
    m = np.zeros(12, bool)
    m[[0, 6]] = True
    assert C.dilate(m, 2).astype(int).tolist() == [1, 1, 1, 0, 1, 1, 1, 1, 1, 0, 0, 0]
    m = np.zeros(6, bool)
    m[5] = True
    assert C.dilate(m, 1).astype(int).tolist() == [0, 0, 0, 0, 1, 1]
    assert C.dilate(m, 0).tolist() == m.tolist()
    assert not C.dilate(np.zeros(5, bool), 3).any()
    assert C.dilate(m, 0) is not m


# ---------------------------------------------------------------- percentile


def test_percentile_equals_numpy():
    rng = np.random.default_rng(2)
    for n in (1, 2, 3, 10, 101):
        a = rng.normal(size=n)
        for q in (0.0, 1.0, 20.0, 49.9, 50.0, 50.1, 75.0, 99.0, 100.0):
            assert C.percentile(a, q) == np.percentile(a, q)
    b = rng.normal(size=(4, 9))
    for q in (0.0, 20.0, 60.0, 100.0):
        np.testing.assert_array_equal(C.percentile(b, q, axis=-1), np.percentile(b, q, axis=-1))
        np.testing.assert_array_equal(C.percentile(b, q, axis=1), np.percentile(b, q, axis=1))
    assert C.percentile(b, 30.0) == np.percentile(b, 30.0)  # flattened
    # half-way between two order statistics numpy interpolates from the upper one; the
    # two forms differ in the last bit for these values
    a = np.array([0.1257302210933933, -0.1321048632913019, 0.6404226504432821])
    assert C.percentile(a, 25.0) == np.percentile(a, 25.0)
    lo, hi = np.sort(a)[:2]
    assert lo + (hi - lo) * 0.5 != np.percentile(a, 25.0)  # the case is a real one


def test_percentile_rejects_other_axes_and_empty():
    with pytest.raises(V.InvalidParameterError):
        C.percentile(np.ones((3, 4)), 20.0, axis=0)
    with pytest.raises(V.InvalidParameterError):
        C.percentile(np.zeros(0), 20.0)


# ---------------------------------------------------------------- active_floor / local_floor


def test_active_floor_is_the_exponential_mean_and_ignores_silence():
    e = np.random.default_rng(3).exponential(3.0, 20000)
    for q in (10.0, 20.0, 50.0):
        assert C.active_floor(e, q=q) == pytest.approx(3.0, rel=0.05)  # measured within 2 %
    assert C.active_floor(e) == pytest.approx(np.percentile(e, 20.0) / -math.log(0.8), rel=1e-12)
    # digital silence (and rounding residue of it) left out while most frames are live
    z = np.concatenate([np.zeros(9000), np.full(1000, 1e-14), e])
    assert C.active_floor(z) == pytest.approx(C.active_floor(e), rel=1e-12)
    # mostly silence: the signal is what is rare, every frame counts (floor near zero)
    rare = np.concatenate([np.zeros(19000), e[:1000]])
    assert C.active_floor(rare) == 0.0
    assert C.active_floor(rare, min_live=0.01) == pytest.approx(C.active_floor(e[:1000]), rel=1e-12)
    # a level, not a scale: energies far below 1 (a quiet 16-bit file) are not silence
    for k in (1e-12, 1e-6, 1e6):
        assert C.active_floor(k * e) == pytest.approx(k * C.active_floor(e), rel=1e-12)
        assert C.active_floor(k * z) == pytest.approx(k * C.active_floor(e), rel=1e-12)
    # "at least min_live": exactly half the frames live is enough to leave the zeros out
    half = np.concatenate([np.zeros(1000), e[:1000]])
    assert C.active_floor(half) == pytest.approx(C.active_floor(e[:1000]), rel=1e-12)
    assert C.active_floor(np.zeros(10)) == 0.0
    assert C.active_floor(np.zeros(0)) == 0.0


def test_local_floor_follows_level_steps():
    rng = np.random.default_rng(4)
    e = np.concatenate([rng.exponential(1.0, 4000), rng.exponential(16.0, 4000)])
    f = C.local_floor(e, block=1000)
    assert f.shape == e.shape
    assert f[:1500] == pytest.approx(1.0, rel=0.15)
    assert f[-1500:] == pytest.approx(16.0, rel=0.15)
    # block centres hold the block's own active_floor, linear in between
    b0, b1 = C.active_floor(e[:1000]), C.active_floor(e[1000:2000])
    assert f[999] == pytest.approx(b0 + (b1 - b0) * (999 - 499.5) / 1000.0, rel=1e-12)
    assert C.local_floor(e[:900], block=1000) == pytest.approx(C.active_floor(e[:900]))


def test_local_floor_vectorised_blocks_equal_one_at_a_time():
    """Whole live blocks in one percentile call, the rest one by one: same levels."""
    rng = np.random.default_rng(5)
    e = rng.exponential(2.0, 5300)  # 5 whole blocks and a partial one
    e[2000:3000] = 0.0  # a silent block: the whole series' level
    e[3000:3100] = 0.0  # a mostly live block that is not all live: its own live frames
    f = C.local_floor(e, block=1000)
    whole = C.active_floor(e)
    top = float(np.max(e))
    levels = []
    for b in range(6):
        seg = e[b * 1000 : (b + 1) * 1000]
        live = seg[seg > 1e-12 * top]
        ok = len(live) >= max(8, 0.25 * len(seg))
        levels.append(np.percentile(live, 20.0) / -math.log(0.8) if ok else whole)
    centres = np.arange(6) * 1000 + 0.5 * (np.array([1000] * 5 + [300]) - 1)
    np.testing.assert_allclose(f, np.interp(np.arange(5300), centres, levels), rtol=1e-12)
    assert levels[2] == whole


def test_local_floor_small_blocks_and_sparse_blocks():
    rng = np.random.default_rng(6)
    e = rng.exponential(1.0, 64)
    f = C.local_floor(e, block=4)  # blocks under 8 frames: the whole series' level
    assert f == pytest.approx(np.full(64, C.active_floor(e)))
    e2 = rng.exponential(1.0, 404)  # 4 blocks of 101 frames, centres 50, 151, 252, 353
    e2[101:202] = 0.0
    e2[150:160] = 5.0  # 10 live frames of 101: below min_live 0.25, the whole level
    f2 = C.local_floor(e2, block=101)
    assert f2[151] == pytest.approx(C.active_floor(e2), rel=1e-12)
    assert C.local_floor(e2, block=101, min_live=0.05)[151] == pytest.approx(
        C.active_floor(e2[150:160], min_live=0.0)
    )


def test_local_floor_default_min_live_is_a_quarter():
    """A block with 30 % of its frames live (a microphone opening late) has its own level."""
    rng = np.random.default_rng(7)
    e = rng.exponential(1.0, 4000)
    e[1000:1700] = 0.0  # block 1: 30 % live, at 9x the level
    e[1700:2000] *= 9.0
    f = C.local_floor(e, block=1000)
    own = C.active_floor(e[1700:2000], min_live=0.0)
    assert f[1499] == pytest.approx(own, rel=0.02)  # interpolated 1 frame from the centre
    assert C.local_floor(e, block=1000, min_live=0.35)[1499] == pytest.approx(
        C.active_floor(e), rel=0.02
    )


def test_local_floor_block_with_exactly_min_live_has_its_own_level():
    """'Fewer than min_live' takes the whole level: exactly a quarter live does not."""
    rng = np.random.default_rng(9)
    e = rng.exponential(1.0, 404)  # 4 blocks of 101, centres 50, 151, 252, 353
    e[101:202] = 0.0
    e[101:126] = 9.0 * rng.exponential(1.0, 25)  # 25 live frames of 101: exactly min_live
    f = C.local_floor(e, block=101, min_live=25 / 101)
    assert f[151] == pytest.approx(C.active_floor(e[101:126], min_live=0.0), rel=1e-12)
    e[125] = 0.0  # 24 live: fewer, the whole series' level
    f = C.local_floor(e, block=101, min_live=25 / 101)
    assert f[151] == pytest.approx(C.active_floor(e), rel=1e-12)


def test_local_floor_is_scale_invariant_with_silence_residue():
    """Frames under 1e-12 of the largest are silence at any scale (the whole-block path and
    the one-at-a-time path alike)."""
    rng = np.random.default_rng(8)
    e = rng.exponential(1.0, 3000)
    e[1000:1500] = 1e-14  # rounding residue of digital silence in block 1
    f = C.local_floor(e, block=1000)
    for s in (1e-9, 1e9):
        np.testing.assert_allclose(C.local_floor(e * s, block=1000), s * f, rtol=1e-12)
    # block 1's level is that of its live frames
    assert f[1499] == pytest.approx(C.active_floor(e[1500:2000]), rel=0.02)


def test_local_floor_rejects_bad_block():
    with pytest.raises(V.InvalidParameterError):
        C.local_floor(np.ones(10), block=0)


# ---------------------------------------------------------------- out_of_band_ratio


def test_out_of_band_ratio():
    t = np.arange(8820) / FS
    taps = C.bandpass_taps(FS, 14000.0, 18000.0)
    tone = np.sin(2 * np.pi * 16000 * t)
    hum = np.sin(2 * np.pi * 100 * t)
    assert C.out_of_band_ratio(tone, taps) < 1e-3  # in band: almost nothing removed
    assert C.out_of_band_ratio(tone + 10 * hum, taps) == pytest.approx(100.0, rel=0.02)
    x = tone + 3 * hum
    y = C.bandlimit(x, taps)
    assert C.out_of_band_ratio(x, taps, y) == C.out_of_band_ratio(x, taps)
    assert C.out_of_band_ratio(x, taps, np.zeros_like(x)) == math.inf
    assert C.out_of_band_ratio(np.zeros(100), taps) == 0.0
