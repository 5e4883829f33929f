"""``rangekit.detect.condition`` against independent references on seeded random inputs.

Issue 21's mutation round (helper P2): each function of the module is compared with a
reference written here from its documented rule, with scipy/numpy doing the arithmetic
(``scipy.signal.firwin`` and ``kaiser_beta`` for the taps, ``scipy.ndimage`` for the
dilation, ``numpy.percentile`` for the floors), on many seeded draws that include each
rule's boundary. Runs in about two seconds.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.ndimage import binary_dilation
from scipy.signal import firwin, kaiser_beta

from rangekit.detect import condition as C


def _design(fs, lo, hi, tw=None, atten=60.0):
    """The band-pass design ``bandpass_taps`` documents, with scipy's firwin.

    Transition: a quarter of the band within [300 Hz, 3 kHz] unless given; a low-pass
    for ``lo`` 0; a lower transition that would pass 0 Hz shrinks to ``lo``; ``hi``
    at or above Nyquist minus the transition makes a high-pass whose upper transition is
    the room left; Kaiser's length ``(A - 7.95) / (14.36 df / fs) + 1`` (Kaiser 1974, as
    in Oppenheim & Schafer, Discrete-Time Signal Processing, eq. 7.63), odd, >= 9.
    """
    nyq = fs / 2
    if tw is None:
        tw = min(3000.0, max(300.0, (hi - lo) / 4))
    hp = hi + tw >= nyq
    lp = lo - tw <= 0.0
    if lp and lo > 0.0:
        tw, lp = lo, False
    tw_hi = nyq - hi if (hp and hi < nyq) else tw
    width = tw if (hp or lp) else min(tw, tw_hi)
    n = math.ceil((atten - 7.95) / (14.36 * width / fs)) + 1
    n = max(n if n % 2 else n + 1, 9)
    beta = kaiser_beta(atten)
    if lo <= 0.0 and hp:
        h = np.zeros(n)
        h[n // 2] = 1.0
        return h
    if lo <= 0.0:
        return firwin(n, hi + tw / 2, window=("kaiser", beta), fs=fs, pass_zero=True)
    if hp:
        return firwin(n, lo - tw / 2, window=("kaiser", beta), fs=fs, pass_zero=False)
    edges = [lo - tw / 2, hi + tw_hi / 2]
    return firwin(n, edges, window=("kaiser", beta), fs=fs, pass_zero=False)


def _cases():
    rng = np.random.default_rng(330_2)
    out = []
    for fs in (8000.0, 16000.0, 44100.0, 48000.0):
        nyq = fs / 2
        for _ in range(10):
            lo = float(rng.choice([0.0, rng.uniform(50.0, 0.6 * nyq)]))
            hi = float(rng.uniform(lo + 100.0, nyq))
            tw = None if rng.random() < 0.5 else float(rng.uniform(200.0, 0.3 * nyq))
            atten = float(rng.choice([60.0, rng.uniform(25.0, 90.0)]))
            out.append((fs, lo, hi, tw, atten))
    # each branch at its boundary: lower transition reaching 0 Hz exactly and 1 Hz short,
    # a pass band from 1 Hz (not a low-pass), the upper one reaching Nyquist exactly
    out += [
        (8000.0, 1000.0, 2000.0, 1000.0, 60.0),
        (8000.0, 1001.0, 2000.0, 1000.0, 60.0),
        (8000.0, 1000.5, 2000.0, 1000.0, 60.0),
        (1000.0, 1.0, 100.0, None, 40.0),
        (1000.0, 0.5, 100.0, None, 40.0),
        (8000.0, 1000.0, 3000.0, 1000.0, 60.0),
        (8000.0, 1000.0, 2999.0, 1000.0, 60.0),
        (8000.0, 0.0, 3000.0, 1000.0, 50.0),
        (8000.0, 0.0, 2500.0, 1000.0, 21.0),
    ]
    return out


@pytest.mark.parametrize(("fs", "lo", "hi", "tw", "atten"), _cases())
def test_bandpass_taps_are_the_documented_kaiser_design(fs, lo, hi, tw, atten):
    got = C.bandpass_taps(fs, lo, hi, transition_hz=tw, atten_db=atten)
    want = _design(fs, lo, hi, tw, atten)
    assert len(got) == len(want)
    # firwin's window is scipy.special.i0's, the module's numpy.i0's: 2.3e-16 apart
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-14 * np.max(np.abs(want)))


def test_a_band_from_one_hertz_stops_dc():
    """``lo`` of 0 makes a low-pass; any ``lo`` above it (1 Hz too) removes DC."""
    h = C.bandpass_taps(1000.0, 1.0, 100.0, atten_db=40.0)
    assert abs(float(np.sum(h))) < 0.04  # the DC gain, at the stop band's edge: measured 0.0204
    h0 = C.bandpass_taps(1000.0, 0.0, 100.0, atten_db=40.0)
    assert float(np.sum(h0)) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("atten", [*np.linspace(5.0, 120.0, 47).tolist(), 21.0, 50.0])
def test_kaiser_beta_equals_scipy_everywhere(atten):
    assert C._kaiser_beta(atten) == pytest.approx(kaiser_beta(atten), rel=1e-13, abs=1e-15)


def test_firwin_kaiser_equals_scipy_on_random_bands():
    rng = np.random.default_rng(330_3)
    for _ in range(40):
        n = int(rng.integers(5, 80)) | 1
        k = int(rng.integers(1, 5))
        fs = float(rng.choice([8000.0, 44100.0]))
        cut = np.sort(rng.uniform(0.02, 0.98, k)) * fs / 2
        pz = bool(rng.random() < 0.5)
        beta = float(rng.uniform(0.0, 10.0))
        want = firwin(n, cut, window=("kaiser", beta), fs=fs, pass_zero=pz)
        got = C._firwin_kaiser(n, cut.tolist(), beta, fs, pass_zero=pz)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-14 * np.max(np.abs(want)))


def test_bandlimit_is_the_centred_full_convolution():
    rng = np.random.default_rng(330_4)
    for _ in range(30):
        m = int(rng.integers(0, 20))
        taps = rng.normal(size=2 * m + 1)
        x = rng.normal(size=int(rng.integers(1, 300)))
        half = m
        want = np.convolve(x, taps)[half : half + len(x)]
        got = C.bandlimit(x, taps)
        assert got.shape == x.shape
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def _runs_ref(m, k):
    out = np.zeros(len(m), bool)
    i = 0
    while i < len(m):
        if m[i]:
            j = i
            while j < len(m) and m[j]:
                j += 1
            if j - i >= k:
                out[i:j] = True
            i = j
        else:
            i += 1
    return out


def test_runs_at_least_equals_a_loop():
    rng = np.random.default_rng(330_5)
    for _ in range(200):
        m = rng.random(int(rng.integers(0, 40))) < rng.uniform(0.2, 0.9)
        k = int(rng.integers(0, 6))
        np.testing.assert_array_equal(C._runs_at_least(m, k), _runs_ref(m, max(k, 1)))


def test_dilate_equals_scipy_binary_dilation():
    rng = np.random.default_rng(330_6)
    for _ in range(200):
        m = rng.random(int(rng.integers(1, 60))) < rng.uniform(0.0, 0.2)
        half = int(rng.integers(0, 8))
        want = binary_dilation(m, np.ones(2 * half + 1, bool)) if half else m
        np.testing.assert_array_equal(C.dilate(m, half), want)


def _touches_ref(at, min_count, max_gap):
    if len(at) < min_count:
        return False
    if min_count <= 1:
        return True
    run = 1
    for a, b in itertools.pairwise(at):
        run = run + 1 if b - a < max_gap else 1
        if run >= min_count:
            return True
    return False


def _clip_ref(x, rel_tol=1e-4, min_run=2, min_count=8, max_gap=64):
    """The rule of clip_mask's docstring, per rail, in float64."""
    x = np.asarray(x, dtype=np.float64)
    mask = np.zeros(len(x), bool)
    if len(x) < min_run:
        return mask
    hi, lo = x.max(), x.min()
    span = hi - lo
    if span <= 0:
        return mask
    for rail, near in ((hi, x >= hi - rel_tol * span), (lo, x <= lo + rel_tol * span)):
        idx = np.flatnonzero(near)
        if rail == 0.0 or len(idx) < min_run:
            continue
        run = min_run <= 1 or _runs_ref(near, min_run).any()
        if run or _touches_ref(np.flatnonzero(x == rail), min_count, max_gap):
            mask[idx] = True
    return mask


def test_clip_mask_equals_its_rule_on_random_clipped_signals():
    rng = np.random.default_rng(330_7)
    fired = 0
    for _ in range(150):
        n = int(rng.integers(1, 400))
        f = rng.uniform(0.01, 0.45)
        x = rng.uniform(0.2, 2.0) * np.sin(2 * np.pi * f * np.arange(n) + rng.uniform(0, 6))
        x += rng.normal(0.0, 0.01, n) + rng.uniform(-0.3, 0.3)
        if rng.random() < 0.6:
            x = np.clip(
                x, np.quantile(x, rng.uniform(0, 0.05)), np.quantile(x, rng.uniform(0.9, 1))
            )
        if rng.random() < 0.2:
            x[: n // 3] = 0.0
        kw = {
            "rel_tol": float(rng.choice([1e-4, 1e-2])),
            "min_run": int(rng.integers(1, 4)),
            "min_count": int(rng.integers(1, 10)),
            "max_gap": int(rng.integers(2, 80)),
        }
        want = _clip_ref(x, **kw)
        np.testing.assert_array_equal(C.clip_mask(x, **kw), want)
        fired += bool(want.any())
    assert 43 <= fired <= 140  # measured 86 of 150 draws with clipping found


def test_percentile_equals_numpy_on_random_arrays():
    rng = np.random.default_rng(330_8)
    for _ in range(300):
        n = int(rng.integers(1, 50))
        a = rng.normal(size=n) if rng.random() < 0.7 else rng.integers(0, 4, n).astype(float)
        q = float(rng.choice([0.0, 100.0, 50.0, rng.uniform(0, 100)]))
        assert C.percentile(a, q) == np.percentile(a, q)
    b = rng.normal(size=(7, 13))
    for q in rng.uniform(0, 100, 20):
        np.testing.assert_array_equal(C.percentile(b, q, axis=1), np.percentile(b, q, axis=1))


def _floor_ref(e, q=20.0, rel_zero=1e-12, min_live=0.5):
    e = np.asarray(e, dtype=np.float64)
    if len(e) == 0 or e.max() <= 0:
        return 0.0
    live = e[e > rel_zero * e.max()]
    if len(live) < min_live * len(e):
        live = e
    return float(np.percentile(live, q)) / -math.log(1 - q / 100)


def test_active_floor_equals_its_rule_on_random_series():
    rng = np.random.default_rng(330_9)
    for _ in range(200):
        n = int(rng.integers(1, 300))
        e = rng.exponential(rng.uniform(1e-6, 1e3), n)
        k = int(rng.integers(0, n + 1))
        e[rng.permutation(n)[:k]] = float(rng.choice([0.0, 1e-14 * e.max()]))
        q = float(rng.choice([20.0, rng.uniform(1.0, 90.0)]))
        ml = float(rng.choice([0.5, rng.uniform(0.0, 1.0)]))
        assert C.active_floor(e, q=q, min_live=ml) == pytest.approx(
            _floor_ref(e, q, 1e-12, ml), rel=1e-12, abs=0.0
        )


def _local_ref(e, block, q=20.0, min_live=0.25):
    n = len(e)
    whole = _floor_ref(e, q)
    if n <= block:
        return np.full(n, whole)
    top = e.max()
    centres, levels = [], []
    for s in range(0, n, block):
        seg = e[s : s + block]
        centres.append(s + (len(seg) - 1) / 2)
        live = seg[seg > 1e-12 * top]
        ok = len(live) >= max(8, min_live * len(seg))
        levels.append(np.percentile(live, q) / -math.log(1 - q / 100) if ok else whole)
    return np.interp(np.arange(n), centres, levels)


def test_local_floor_equals_its_rule_on_random_series():
    rng = np.random.default_rng(331_0)
    for _ in range(80):
        n = int(rng.integers(1, 900))
        block = int(rng.integers(1, 200))
        e = rng.exponential(1.0, n) * np.repeat(rng.uniform(0.1, 20.0, n // 50 + 1), 50)[:n]
        for _ in range(int(rng.integers(0, 3))):  # stretches of silence
            a = int(rng.integers(0, n))
            e[a : a + int(rng.integers(1, 300))] = 0.0
        q = float(rng.choice([20.0, rng.uniform(5.0, 80.0)]))
        ml = float(rng.choice([0.25, rng.uniform(0.0, 1.0)]))
        if not e.any():
            continue
        np.testing.assert_allclose(
            C.local_floor(e, block=block, q=q, min_live=ml),
            _local_ref(e, block, q, ml),
            rtol=1e-12,
            atol=0.0,
        )


def test_out_of_band_ratio_equals_its_definition():
    rng = np.random.default_rng(331_1)
    for _ in range(20):
        taps = rng.normal(size=2 * int(rng.integers(0, 10)) + 1)
        x = rng.normal(size=int(rng.integers(1, 200)))
        y = np.convolve(x, taps)[(len(taps) - 1) // 2 :][: len(x)]
        want = float(np.sum((x - y) ** 2) / np.sum(y**2))
        assert C.out_of_band_ratio(x, taps) == pytest.approx(want, rel=1e-10)
