"""``rangekit.detect._coherent`` against independent references (issue 21, the mutation
check, second round): the side-extremum ratio and the coherent lag against loops written
from their docstrings on random band-limited responses, the windowed-sinc value against
the Kaiser window computed directly, the coherent weight against its closed form, the
coherent lag's phase at any scale down to 1e-300, and the interpolation RMS's floor and
default delays. Seeded, about a second.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.detect import _coherent as C


def _band_limited(rng, n: int, top: float = 0.35, analytic: bool = True) -> np.ndarray:
    """Complex (analytic) or real noise band-limited to ``top`` cycles per sample."""
    f = np.fft.fftfreq(n)
    spec = np.fft.fft(rng.standard_normal(n))
    spec[np.abs(f) > top] = 0.0
    if analytic:
        spec[f < 0] = 0.0
        spec[f > 0] *= 2.0
    return np.fft.ifft(spec)


def _side_ratio_reference(self_resp: np.ndarray, reach: int) -> float:
    m = len(self_resp) // 2
    r = np.abs(self_resp.real[max(0, m - reach) : m + reach + 1])
    if len(r) < 3:
        return 1.0
    vals = [r[i] for i in range(1, len(r) - 1) if r[i] >= r[i - 1] and r[i] > r[i + 1]]
    if len(vals) == 0:
        return 1.0
    if len(vals) == 1:
        return 0.0
    vals.sort(reverse=True)
    return vals[1] / vals[0] if vals[0] > 0 else 1.0


def test_real_side_ratio_against_a_loop_on_random_responses():
    """The largest side extremum of ``|Re R|`` over the main one within ``+- reach`` of the
    centre, on 300 random responses of odd and even lengths and reaches 1-40 (some windows
    cut by the array's start), as a loop finds it: exactly."""
    rng = np.random.default_rng(11)
    for _ in range(300):
        n = int(rng.integers(3, 120))
        sr = rng.standard_normal(n) + 1j * rng.standard_normal(n)
        if rng.random() < 0.3:
            sr = np.round(sr)  # ties
        reach = int(rng.integers(1, 41))
        assert C.real_side_ratio(sr, reach) == _side_ratio_reference(sr, reach), (n, reach)


def test_sinc_value_against_the_kaiser_window_computed_directly():
    """``_sinc_at(r, t) = sum_k r[k] sinc(t - k) w(t - k)`` over the ``2 SINC_HALF`` taps
    ``floor(t) - SINC_HALF + 1 .. floor(t) + SINC_HALF`` (those inside ``r``), ``w`` the
    Kaiser window ``I0(beta sqrt(1 - (u / (SINC_HALF + 1))^2)) / I0(beta)``: within 5e-6 of
    the tap sum's scale (the window is read off a table; measured 2.6e-6)."""
    rng = np.random.default_rng(3)
    r = rng.standard_normal(80)
    H, beta = C.SINC_HALF, C.SINC_BETA
    worst = 0.0
    for t in rng.uniform(0.0, 79.0, 400):
        k0 = math.floor(t)
        k = np.arange(max(0, k0 - H + 1), min(len(r), k0 + H + 1))
        u = t - k
        w = np.i0(beta * np.sqrt(np.clip(1.0 - (u / (H + 1.0)) ** 2, 0.0, 1.0))) / np.i0(beta)
        want = float(np.dot(r[k], np.sinc(u) * w))
        worst = max(worst, abs(C._sinc_at(r, t) - want))
    assert worst < 5e-6


def test_coherent_weight_against_its_closed_form():
    """``min(1, max(0, (cos - cos 60) / (cos 30 - cos 60)))`` at 200 phases, and at either
    side of its two corners."""
    full, none = math.cos(math.pi / 6.0), 0.5
    for ph in np.linspace(0.0, math.pi / 2.0, 200):
        cp = math.cos(ph)
        assert C.coherent_weight(cp) == pytest.approx(
            min(1.0, max(0.0, (cp - none) / (full - none))), abs=1e-12
        )
    assert C.coherent_weight(full + 1e-9) == 1.0 and C.coherent_weight(full - 1e-6) < 1.0
    assert C.coherent_weight(none - 1e-9) == 0.0 and C.coherent_weight(none + 1e-6) > 0.0


def _coherent_lag_reference(c: np.ndarray, lag: float, reach: int):
    """The largest local maximum of ``|Re c|`` at a sample of ``[j - reach, j + reach]``
    with a neighbour on each side (first of equals), refined on the whole array; ``|cos|``
    of the phase read on the whole array."""
    j = round(lag)
    r = np.abs(c.real)
    cand = [
        i
        for i in range(max(1, j - reach), min(len(c) - 1, j + reach + 1))
        if r[i] >= r[i - 1] and r[i] > r[i + 1]
    ]
    re, im = C._sinc_at(c.real, lag), C._sinc_at(c.imag, lag)
    cos_phase = abs(re) / math.hypot(re, im)
    if not cand:
        return None, cos_phase
    p = max(cand, key=lambda i: (r[i], -i))
    return C.refine_extremum(np.ascontiguousarray(c.real), p), cos_phase


def test_coherent_lag_against_a_loop_on_random_band_limited_signals():
    """On analytic noise band-limited to 0.35 cycles per sample, 400 random lags 25
    samples or more from the ends and reaches 0-6: the extremum the loop picks, refined
    on the whole array (the segment ``coherent_lag`` refines holds every tap: the same
    value to rounding, 1e-9), and ``|cos phase|`` to 1e-12."""
    rng = np.random.default_rng(8)
    c = _band_limited(rng, 400)
    for _ in range(400):
        lag = float(rng.uniform(25.0, 375.0))
        reach = int(rng.integers(0, 7))
        got = C.coherent_lag(c, lag, reach)
        want_t, want_cos = _coherent_lag_reference(c, lag, reach)
        if want_t is None:
            assert got is None, (lag, reach)
            continue
        assert got is not None, (lag, reach)
        assert got[0] == pytest.approx(want_t, abs=1e-9), (lag, reach)
        assert got[1] == pytest.approx(want_cos, abs=1e-12), (lag, reach)


def test_coherent_lag_near_the_arrays_ends():
    """Lags within a few samples of either end (windows and taps cut by the array): the
    loop's extremum (the refinement then reads fewer taps: within 1e-9 of the whole
    array's), inside the array."""
    rng = np.random.default_rng(9)
    c = _band_limited(rng, 120)
    for lag in [0.0, 0.4, 1.0, 2.6, 4.0, 116.0, 117.4, 118.0, 119.0]:
        for reach in (1, 3, 5):
            got = C.coherent_lag(c, lag, reach)
            want_t, _ = _coherent_lag_reference(c, lag, reach)
            if want_t is None:
                assert got is None
                continue
            assert got[0] == pytest.approx(want_t, abs=1e-9), (lag, reach)
            assert 0.0 <= got[0] <= len(c) - 1.0


@pytest.mark.parametrize("scale", [1.5e-300, 1e-150, 1e150])
def test_coherent_lag_is_scale_invariant_down_to_1e_300(scale):
    """A pulse scaled by 1.5e-300 (its magnitude at the lag just above the phase's
    1e-300 floor) to 1e150: the same lag and ``|cos phase|`` as at scale 1 (to 1e-9)."""
    n = np.arange(64.0)
    c = np.exp(-0.5 * ((n - 32.3) / 3.0) ** 2) * np.exp(2j * np.pi * 0.15 * (n - 31.6))
    t1, cp1 = C.coherent_lag(c, 32.3, 3)
    t, cp = C.coherent_lag(c * scale, 32.3, 3)
    assert t == pytest.approx(t1, abs=1e-9) and cp == pytest.approx(cp1, abs=1e-9)
    assert 0.3 < cp1 < 0.95  # a phase between the corners: measured 0.79


def test_coherent_interp_rms_floor_and_default_delays():
    """One delay (0: the self response itself, whose extremum at lag 0 the search finds
    exactly) gives the floor, 1e-6 samples; the default is 16 delays ``k / 16``: the RMS of
    ``coherent_lag``'s errors on the response delayed by each (exact frequency-domain
    delay), here 5.6e-6."""
    n = np.arange(-64.0, 65.0)
    r = np.exp(-0.5 * (n / 4.0) ** 2) * np.exp(2j * np.pi * 0.12 * n)
    assert C.coherent_interp_rms(r, 3, 1) == 1e-6
    m = len(r) // 2
    f = np.fft.fftfreq(len(r))
    errs = []
    for k in range(16):
        d = k / 16
        rd = np.fft.ifft(np.fft.fft(r) * np.exp(-2j * np.pi * f * d))
        errs.append(C.coherent_lag(rd, m + d, 3)[0] - (m + d))
    want = math.sqrt(float(np.mean(np.square(errs))))
    assert want > 2e-6  # above the floor: measured 5.6e-6
    assert C.coherent_interp_rms(r, 3) == pytest.approx(want, rel=1e-12)


def test_coherent_interp_rms_counts_a_delay_without_extremum_as_half_a_sample():
    """A response whose real part has no interior extremum (all zeros): each delay's error
    is 0.5 samples, so the RMS is 0.5."""
    assert C.coherent_interp_rms(np.zeros(129, dtype=complex), 3, 4) == 0.5
