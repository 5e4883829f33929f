"""Change-point detector, eighth mutation round: rules no earlier test pinned.

Written by reading ``rangekit/detect/changepoint.py`` top to bottom (not against one
sample's survivors): each documented constant is tested where it changes a result,
including the sample-rate rounding of the constants given in samples at 44.1 kHz
(``HOP_S = 32 / 44100`` and its kin: at a rate where ``n fs / 44100`` lies just above a
half, ``/ 44101`` rounds the other way), and the numpy paths are compared with their
independent references: the python forms of the compiled kernels
(``_edge_kernels._change_points_py``, ``_anchors_py``), ``numpy.median``,
``scipy.ndimage.maximum_filter1d``, a weighted ``numpy.polyfit``, a loop over the
precursor windows, and ``condition.bandlimit`` of the whole recording. Short seeded
inputs only.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.ndimage

from rangekit.detect import _edge_kernels as K
from rangekit.detect import changepoint as cp
from rangekit.detect._kernels import band_energy
from rangekit.detect.condition import bandlimit
from rangekit.signals import Beep
from rangekit.signals.beep import beep_continuous
from rangekit.types import Arrivals

FS = 44100.0


def _burst(n: int, at: float, amp: float, beep: Beep) -> np.ndarray:
    """``beep`` (peak ``amp``) starting at sample ``at`` of ``n`` (continuous time)."""
    return amp / 0.9 * beep_continuous((np.arange(n) - at) / FS, beep=beep)


def _rate(n: int, k: int, delta: float) -> float:
    """A sample rate at which ``n`` samples at 44.1 kHz are ``k + 0.5 + delta`` samples:
    ``round`` gives ``k + 1``, while the same with ``/ 44101`` gives ``k`` (delta below
    ``(k + 0.5) / 44101``)."""
    return (k + 0.5 + delta) * 44100.0 / n


# n samples at 44.1 kHz -> a rate where they round up (k + 1) and 44101 would round down.
FS_32 = _rate(32, 37, 4e-4)  # 37.5004 samples (/44101: 37.4996)
FS_64 = _rate(64, 75, 8e-4)  # 75.5008 (/44101: 75.4991)
FS_128 = _rate(128, 150, 1e-3)  # 150.501 (/44101: 150.4976)
FS_8 = _rate(8, 9, 1e-4)  # 9.5001 (/44101: 9.4999)
FS_256 = _rate(256, 300, 2e-3)  # 300.502 (/44101: 300.4952)


def test_the_rates_round_as_designed():
    """The tuned rates: ``n fs / 44100`` rounds up, ``n fs / 44101`` down."""
    for n, fs, k in ((32, FS_32, 37), (64, FS_64, 75), (128, FS_128, 150), (8, FS_8, 9),
                     (256, FS_256, 300)):  # fmt: skip
        assert round(n * fs / 44100) == k + 1 and round(n * fs / 44101) == k


@pytest.mark.parametrize(
    ("fs", "n_win", "hop"), [(FS, 128, 32), (FS_128, 151, 38), (FS_32, 150, 38)]
)
def test_the_stft_window_and_hop_are_128_and_32_samples_at_44100_hz(fs, n_win, hop):
    """``WIN_S = 128 / 44100`` and ``HOP_S = 32 / 44100`` s, rounded to samples at each
    rate (``find_bursts``' defaults): at 51855 Hz 150.501 -> 151 samples, at 51681 Hz a
    hop of 37.5004 -> 38."""
    x = 1e-3 * np.random.default_rng(0).standard_normal(4000)
    got = cp.find_bursts(x, fs=fs, beep=Beep())
    assert (got.n_win, got.hop) == (n_win, hop)
    assert (n_win, hop) == (round(128 * fs / 44100), round(32 * fs / 44100))


def test_stft_params_floors_and_caps():
    """The window is 16 samples at least, the hop 1 at least and a window at most."""
    assert cp._stft_params(FS, 1e-4, 1e-6) == (16, 1)  # 4.41 and 0.04 samples
    assert cp._stft_params(FS, 128 / FS, 1.0) == (128, 128)
    assert cp._stft_params(FS, 100 / FS, 7 / FS) == (100, 7)


@pytest.mark.parametrize("fs", [FS, FS_8, FS_256])
def test_last_frames_guard_is_8_and_the_count_256_samples_at_44100_hz(fs):
    """``_last_frames``: the last frame ending ``PRE_GUARD_S`` (8 samples at 44.1 kHz)
    or more before the onset, ``floor((t0 - guard - n_win) / hop)``, and
    ``round(PRE_LAST_S fs / hop)`` frames (256 samples at 44.1 kHz), at least 1."""
    guard, count = round(8 * fs / 44100), round(256 * fs / 44100)
    assert cp._last_frames(1000.0, hop=1, n_win=100, fs=fs) == (1000 - guard - 100, count)
    # hop 32 at 44.1 kHz: (1000.5 - 8 - 128) / 32 = 27.02 -> 27 (a guard of 9: 26.98)
    assert cp._last_frames(1000.5, hop=32, n_win=128, fs=FS) == (27, 8)
    assert cp._last_frames(1000.0, hop=1000, n_win=16, fs=8000.0)[1] == 1  # 0.046 -> 1


@pytest.mark.parametrize(
    ("fs", "lengths", "guard"),
    [(FS, (32, 64, 128), 8), (FS_32, (38, 75, 150), 9), (FS_64, (38, 76, 151), 9),
     (FS_128, (38, 75, 151), 9), (4000.0, (5, 6, 12), 1)],
)  # fmt: skip
def test_precursor_windows_are_32_64_and_128_samples_at_44100_hz(fs, lengths, guard, monkeypatch):
    """``precursor_hits`` reads windows of ``PRE_TONE_S`` (32, 64 and 128 samples at 44.1
    kHz, rounded at each rate, the guard plus 4 samples at least: at 4 kHz a guard of 1
    and 2.9 samples give 5) ending ``PRE_GUARD_S`` (8 samples) before each onset."""
    seen = []

    def spy(x, onsets, **kw):
        seen.append((kw["lengths"], kw["guard"]))
        return np.zeros((len(onsets), len(kw["lengths"])))

    monkeypatch.setattr(cp, "precursor_ratio", spy)
    cp.precursor_hits(np.zeros(40000), np.array([10000.0]), fs=fs, beep=Beep())
    assert seen == [(lengths, guard)]
    assert lengths == tuple(max(guard + 4, round(n * fs / 44100)) for n in (32, 64, 128))


def _runs(n: int, runs: list[tuple[int, int]]) -> np.ndarray:
    m = np.zeros(n, dtype=bool)
    for a, length in runs:
        m[a : a + length] = True
    return m


@pytest.mark.parametrize(
    ("fs", "max_len", "gap"), [(FS, 8, 32), (FS_8, 10, 38), (FS_32, 9, 38), (2000.0, 1, 2)]
)
def test_a_click_is_8_samples_at_most_and_32_from_any_other_at_44100_hz(fs, max_len, gap):
    """``click_mask``: a run of at most ``CLICK_MAX_S`` (8 samples at 44.1 kHz, 1 at
    least) with no other clipped sample within ``CLICK_GAP_S`` (32 samples, 2 at least)
    is a click; a run one sample longer, or a neighbour ``gap`` samples away, is not."""
    assert (max_len, gap) == (max(1, round(8 * fs / 44100)), max(2, round(32 * fs / 44100)))
    n = 1000
    assert cp.click_mask(_runs(n, [(100, max_len)]), fs=fs).any()
    assert not cp.click_mask(_runs(n, [(100, max_len + 1)]), fs=fs).any()
    # two single clipped samples: apart by more than gap both are clicks, at gap neither
    far = cp.click_mask(_runs(n, [(300, 1), (301 + gap, 1)]), fs=fs)
    assert np.flatnonzero(far).tolist() == sorted({*range(298, 303), *range(299 + gap, 304 + gap)})
    assert not cp.click_mask(_runs(n, [(300, 1), (300 + gap, 1)]), fs=fs).any()


def _random_series(rng: np.random.Generator, n: int) -> np.ndarray:
    """Exponential noise (mean 1) with a few bursts, steps within them, silences."""
    e = rng.exponential(1.0, n)
    for _ in range(rng.integers(1, 5)):
        a = int(rng.integers(0, n - 10))
        b = min(n, a + int(rng.integers(3, 40)))
        e[a:b] *= 10 ** rng.uniform(0.3, 4.0)
        if b - a > 10 and rng.random() < 0.5:
            s = a + int(rng.integers(4, b - a))
            e[s:b] *= 10 ** rng.uniform(0.5, 2.5)
    if rng.random() < 0.3:
        a = int(rng.integers(0, n - 20))
        e[a : a + int(rng.integers(5, 20))] = 0.0
    return e


def test_numpy_change_points_equal_the_kernels_on_random_series():
    """``_change_points`` (numpy path, series shorter than ``NUMBA_MIN_SAMPLES // hop``
    frames) gives the frames of ``_edge_kernels._change_points_py`` (its independent loop
    form) with the documented parameters: the recent level is the mean of the 8 frames
    ending ``ceil(n_win / hop) + lookback`` frames before the frame, the thresholds
    ``10^(dB / 10)``, a second step ``ceil(n_win / hop)`` frames or more into a run. 400
    seeded series, with the series' start (fewer than 8 frames of recent level) and
    floors per frame."""
    rng = np.random.default_rng(5)
    n_steps = 0
    for _ in range(400):
        n = int(rng.integers(20, 160))
        e = _random_series(rng, n)
        floor = rng.uniform(0.5, 2.0) * np.ones(n) if rng.random() < 0.5 else None
        n_win, hop = int(rng.choice([16, 64, 128, 100])), int(rng.choice([8, 16, 32]))
        thr_db, rise_db = float(rng.uniform(3, 15)), float(rng.uniform(3, 15))
        lookback = int(rng.integers(0, 4))
        got = cp._change_points(
            e, n_win=n_win, hop=hop, threshold_db=thr_db, rise_db=rise_db, floor=floor,
            lookback=lookback,
        )  # fmt: skip
        fl = np.full(n, cp.active_floor(e)) if floor is None else floor
        w = math.ceil(n_win / hop)
        ref = K._change_points_py(
            e, fl, w + lookback, 8, 10 ** (thr_db / 10), 10 ** (rise_db / 10), w
        )
        assert got.dtype == np.int64 and got.tolist() == ref.tolist()
        n_steps += len(ref)
    assert n_steps > 400  # measured 1100-odd change points in all


def test_change_points_at_the_series_start_read_the_frames_there_are():
    """At frame ``gap + 1`` the recent level is frame 0 alone (one frame, its mean: 100
    here, so a frame of 50 does not rise 10 dB over it); before that there is none and
    the floor stands in (a frame of 5 is not 10 dB over a floor of 1, one of 11 is)."""
    kw = {"n_win": 128, "hop": 32, "threshold_db": 6.0, "rise_db": 10.0}
    gap = 4
    e = np.ones(40)
    e[0] = 100.0
    e[gap + 1] = 50.0
    assert cp._change_points(e, floor=np.ones(40), **kw).tolist() == [0]
    e[gap + 1] = 1001.0  # over 10 x 100
    assert cp._change_points(e, floor=np.ones(40), **kw).tolist() == [0, gap + 1]
    for v, found in ((5.0, False), (11.0, True)):
        e = np.ones(40)
        e[2] = v
        assert (2 in cp._change_points(e, floor=np.ones(40), **kw).tolist()) == found
    assert cp._change_points(np.zeros(0), **kw).tolist() == []
    # one frame over a given floor is a change point (the empty series alone has none)
    assert cp._change_points(np.array([100.0]), floor=np.ones(1), **kw).tolist() == [0]


def test_long_series_go_to_the_kernel_with_the_same_parameters():
    """A series of ``NUMBA_MIN_SAMPLES // hop`` frames or more is done by the compiled
    kernel, with the parameters the numpy path uses (compared with the python form)."""
    rng = np.random.default_rng(1)
    hop = 32
    n = K.NUMBA_MIN_SAMPLES // hop
    e = _random_series(rng, n)
    for _ in range(40):
        a = int(rng.integers(0, n - 50))
        e[a : a + 30] *= 10 ** rng.uniform(0.5, 3.0)
        e[a + 4 : a + 30] *= 10 ** rng.uniform(1.8, 2.5)  # a second step in the run
    fl = rng.uniform(0.5, 2.0) * np.ones(n)
    got = cp._change_points(
        e, n_win=128, hop=hop, threshold_db=7.0, rise_db=9.0, floor=fl, lookback=2
    )
    ref = K._change_points_py(e, fl, 4 + 2, 8, 10**0.7, 10**0.9, 4)
    assert len(ref) > 40 and got.tolist() == ref.tolist()
    # the steps count: a run's first window as long as the series finds 66, not 87 (measured)
    assert len(K._change_points_py(e, fl, 4 + 2, 8, 10**0.7, 10**0.9, n)) < len(ref) - 10
    short = cp._change_points(
        e[: n - 1], n_win=128, hop=hop, threshold_db=7.0, rise_db=9.0, floor=fl[: n - 1],
        lookback=2,
    )  # fmt: skip
    assert short.tolist() == [v for v in ref.tolist() if v < n - 1]


def _anchor_kernel(c, e, *, hop, n_win, beep, fs):
    """``_edge_kernels._anchors_py`` with the documented arguments: the plateau from a
    window (``n_win // hop`` frames) after each place over the burst less two windows,
    the level before over the 8 frames ending a window before, ``MIN_RISE_DB`` = 1.5."""
    cs = np.concatenate(([0.0], np.cumsum(e)))
    w = max(1, n_win // hop)
    n_plat = max(1, int((beep.burst_s * fs - 2 * n_win) / hop))
    return K._anchors_py(
        np.asarray(c, dtype=np.int64), cs, len(e), hop, w, n_plat, beep.spacing_s * fs,
        beep.n_bursts, 1.5,
    )  # fmt: skip


@pytest.mark.parametrize("n_bursts", [2, 3, 4])
def test_anchor_equals_the_kernels_on_random_band_energies(n_bursts):
    """``_anchor`` (numpy) and ``_anchors_compiled`` give the beep start and rising
    places of ``_edge_kernels._anchors_py`` on random band energies: bursts of random
    rises (falls, 0-40 dB, silences, so the [0, 30] dB clip, the empty plateau and the
    1.5 dB count all decide somewhere) at random places, change points anywhere,
    including the series' ends (places whose frames leave the series are skipped)."""
    rng = np.random.default_rng(n_bursts)
    beep = Beep(n_bursts=n_bursts, spacing=1500)
    hop, n_win = 32, 128
    for _ in range(30):
        n = int(rng.integers(200, 600))
        e = rng.exponential(1.0, n)
        for _ in range(int(rng.integers(2, 9))):
            a = int(rng.integers(0, n - 14))
            e[a : a + 14] *= 10 ** rng.uniform(-1.0, 4.0)
        if rng.random() < 0.5:
            a = int(rng.integers(0, n - 30))
            e[a : a + int(rng.integers(10, 30))] = 0.0
        c = rng.integers(0, n * hop, 40)
        ref = _anchor_kernel(c, e, hop=hop, n_win=n_win, beep=beep, fs=FS)
        got = [cp._anchor(int(v), e, hop=hop, n_win=n_win, spacing=beep.spacing_s * FS,
                          beep=beep, fs=FS) for v in c]  # fmt: skip
        assert got == [tuple(r) for r in ref.tolist()]
        cs = np.concatenate(([0.0], np.cumsum(e)))
        comp = cp._anchors_compiled(c, cs, n, hop=hop, n_win=n_win, beep=beep, fs=FS)
        assert comp == got
    # a one-burst beep: its change point is its start, one rising place
    one = Beep(n_bursts=1)
    c = rng.integers(0, 200 * hop, 10)
    cs = np.concatenate(([0.0], np.cumsum(e)))
    want = [(int(v), 1) for v in c]
    kw = {"hop": hop, "n_win": n_win, "beep": one, "fs": FS}
    assert [cp._anchor(int(v), e, spacing=one.spacing_s * FS, **kw) for v in c] == want
    assert cp._anchors_compiled(c, cs, len(e), **kw) == want


def test_levels_and_rise_of_a_burst_place():
    """``_levels``: the mean band energy over the ``n_plat`` frames from a window (``w``
    frames) after the place's frame ``round(place / hop)`` and over the 8 frames ending a
    window before it; None where those leave the series. ``_rise_of``: 10 log10 of their
    ratio clipped to [0, 30] dB, None for an empty plateau."""
    e = np.arange(1.0, 101.0) ** 2
    cs = np.concatenate(([0.0], np.cumsum(e)))
    kw = {"hop": 10, "w": 4, "n_plat": 5}
    f = 30  # place 303.0 -> frame 30
    got = cp._levels(303.0, cs, 100, **kw)
    assert got == (float(np.mean(e[34:39])), float(np.mean(e[18:26])))
    assert cp._levels(298.0, cs, 100, **kw) == got  # 29.8 -> frame 30
    # the first place whose 8 frames before exist: f - 4 - 8 = 0; the last: f + 4 + 5 = 100
    assert cp._levels(120.0, cs, 100, **kw) is not None
    assert cp._levels(110.0, cs, 100, **kw) is None
    assert cp._levels(910.0, cs, 100, **kw) is not None
    assert cp._levels(920.0, cs, 100, **kw) is None
    assert f == 30
    assert cp._rise_of((10.0, 1.0)) == pytest.approx(10.0, abs=1e-12)
    assert cp._rise_of((0.5, 0.01)) == pytest.approx(10 * math.log10(50.0), abs=1e-12)
    assert cp._rise_of((1e4, 1.0)) == 30.0  # 40 dB, clipped
    assert cp._rise_of((1.0, 0.0)) == 30.0
    assert cp._rise_of((1.0, 2.0)) == 0.0  # a fall
    assert cp._rise_of((0.0, 1.0)) is None and cp._rise_of(None) is None
    assert cp._rise_db(303.0, cs, 100, **kw) == cp._rise_of(got)


def _precursor_reference(x, onsets, *, fs, f_hz, lengths, guard):
    """The docstring of ``precursor_ratio`` as a loop: per burst, |sum w x e^(-i w0 n)|^2
    over the ``length - guard`` samples ending ``guard`` before ``floor(onset)`` (w the
    Hann window of that many nonzero samples), over its mean over windows of that length
    every half window (``max(1, n // 2)``) in the ``round(PRE_NEAR_S fs)`` samples just
    before that window; the smallest over the bursts."""
    far = round(0.025 * fs)
    w0 = 2 * math.pi * f_hz / fs
    out = np.full((len(onsets), len(lengths)), np.nan)
    span = far + max(lengths) - guard
    for r, row in enumerate(np.atleast_2d(onsets)):
        ends = [math.floor(t) - guard for t in row]
        if any(e - span < 0 or e > len(x) for e in ends):
            continue
        for c, length in enumerate(lengths):
            n = length - guard
            win = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(1, n + 1) / (n + 1))
            h = win * np.exp(-1j * w0 * np.arange(n))
            ratios = []
            for e in ends:
                last = abs(np.dot(h, x[e - n : e])) ** 2
                s0 = e - n - far
                lv = [
                    abs(np.dot(h, x[s : s + n])) ** 2
                    for s in range(s0, e - 2 * n + 1, max(1, n // 2))
                ]
                ratios.append(last / np.mean(lv))
            out[r, c] = min(ratios)
    return out


def test_precursor_ratio_equals_its_definition_on_random_recordings():
    """``precursor_ratio`` against a loop over its windows (the docstring's definition) on
    white noise with a tone here and there, for several window lengths and guards, a beep
    whose first burst's stretch starts at sample 0 exactly (tested) and one a sample
    earlier (NaN)."""
    rng = np.random.default_rng(3)
    beep = Beep()
    for trial in range(6):
        x = rng.standard_normal(30000)
        t = np.arange(len(x))
        x += (trial % 3) * np.sin(2 * np.pi * beep.f_hz / FS * t) * (t % 3000 < 400)
        guard = int(rng.integers(1, 12))
        lengths = (int(rng.integers(guard + 4, 40)), 64, int(rng.integers(65, 200)))
        span = round(0.025 * FS) + max(lengths) - guard
        first = np.array([span + guard, span + guard - 1, 8000.7, 15000.2, 29000.0])
        on = first[:, None] + 3000.0 * np.arange(3)[None, :]
        on[4] = [29000.0, 29500.0, 30001.0 + guard]  # the last window past the end: NaN
        kw = {"fs": FS, "f_hz": beep.f_hz, "lengths": lengths, "guard": guard}
        got = cp.precursor_ratio(x, on, **kw)
        ref = _precursor_reference(x, on, **kw)
        assert np.array_equal(np.isnan(got), np.isnan(ref))
        assert np.isnan(got[1]).all() and np.isnan(got[4]).all() and not np.isnan(got[0]).any()
        np.testing.assert_allclose(got, ref, rtol=1e-9)
        one = cp.precursor_ratio(x, on[2], **kw)
        np.testing.assert_allclose(one, ref[2:3], rtol=1e-9)


def test_median_of_a_few_floats_is_numpys():
    rng = np.random.default_rng(0)
    for n in range(1, 9):
        for _ in range(20):
            v = rng.normal(size=n).tolist()
            assert cp._median(v) == pytest.approx(float(np.median(v)), abs=1e-15)


def test_widen_is_scipys_maximum_filter():
    rng = np.random.default_rng(0)
    for half in range(0, 6):
        for n in (1, 5, 40):
            f = rng.exponential(1.0, n)
            ref = scipy.ndimage.maximum_filter1d(f, 2 * half + 1, mode="constant")
            assert cp._widen(f, half).tolist() == ref.tolist()


def test_drift_line_is_the_weighted_least_squares_line_of_each_row():
    """``_drift_line``: per row of ``members``, the weighted mean index ``kbar`` and
    estimate (the line's value there) and the weighted least-squares slope (``numpy
    .polyfit`` with weights sqrt(w)), held within +-200 ppm of the spacing; a row of
    one burst has slope 0, a row of none an infinite mean."""
    rng = np.random.default_rng(2)
    spacing = 5000.0
    lim = 200e-6 * spacing
    for _ in range(50):
        k_b = int(rng.integers(2, 7))
        ks = np.sort(rng.choice(8, k_b, replace=False)).astype(float)
        est = 1000.0 + rng.normal(0, 1.5, k_b)
        w = rng.uniform(0.2, 5.0, k_b)
        members = rng.random((6, k_b)) < 0.6
        members[0] = False
        members[1] = True
        mean, slope, kbar = cp._drift_line(ks, est, w, members, spacing)
        assert mean[0] == np.inf and slope[0] == 0.0
        for r in range(1, 6):
            m = members[r]
            if not m.any():
                assert mean[r] == np.inf
                continue
            kb = np.sum(w[m] * ks[m]) / np.sum(w[m])
            assert kbar[r] == pytest.approx(kb, rel=1e-12)
            assert mean[r] == pytest.approx(np.sum(w[m] * est[m]) / np.sum(w[m]), rel=1e-12)
            if m.sum() == 1:
                assert slope[r] == 0.0
                continue
            s = np.polyfit(ks[m], est[m], 1, w=np.sqrt(w[m]))[0]
            assert slope[r] == pytest.approx(float(np.clip(s, -lim, lim)), abs=1e-9)


def test_found_onsets_within_a_closed_interval():
    found = cp._Found()
    assert not found.within(-1e9, 1e9)
    for t in (300.0, 100.0, 200.0):
        found.add(t)
    assert found.t == [100.0, 200.0, 300.0]
    assert found.within(100.0, 100.0) and found.within(50.0, 100.0) and found.within(300.0, 400.0)
    assert not found.within(100.5, 199.5) and not found.within(300.5, 1e9)
    assert not found.within(0.0, 99.5)


def _arrivals(onsets, confidence):
    n = len(onsets)
    return Arrivals(
        np.asarray(onsets, dtype=float), FS, np.ones(n), np.full(n, 30.0),
        np.asarray(confidence, dtype=float), np.zeros((n, 4)), "changepoint",
    )  # fmt: skip


def test_drop_echoes_keeps_an_arrival_starting_exactly_at_the_earlier_ones_end():
    """An arrival starting at the earlier one's end (onset + duration) is not inside it:
    kept; one a sample earlier is dropped (same confidence); a later one replacing an
    earlier one starts the next span from its own onset."""
    d = 1000.0
    assert cp.drop_echoes(_arrivals([0.0, 1000.0], [1, 1]), duration=d).onset.tolist() == [
        0.0,
        1000.0,
    ]
    assert cp.drop_echoes(_arrivals([0.0, 999.0], [1, 1]), duration=d).onset.tolist() == [0.0]
    got = cp.drop_echoes(_arrivals([0.0, 500.0, 1200.0, 1500.0], [0.75, 1, 1, 1]), duration=d)
    assert got.onset.tolist() == [500.0, 1500.0]
    got = cp.drop_echoes(_arrivals([0.0, 500.0], [0.75, 0.75 + 0.5e-9]), duration=d)
    assert got.onset.tolist() == [0.0]


@pytest.mark.parametrize("compiled", [False, True])
def test_a_conditioned_segment_is_the_band_limited_recording_cut(compiled):
    """``_Conditioner.segment(a, b)``: samples ``[a, b)`` of the whole recording through
    ``bandlimit`` (the filter reads the samples around the stretch), cut to the recording
    at both ends; its offset is the first sample's index."""
    rng = np.random.default_rng(4)
    x = rng.standard_normal(6000)
    beep = Beep()
    cond = cp._conditioner(x, fs=FS, beep=beep, condition=True, compiled=compiled)
    cond = cp._Conditioner(x, cond.taps, None, compiled)
    full = bandlimit(x, cond.taps)
    for a, b in ((0, 500), (-40, 300), (2000, 2600), (5700, 6000), (5800, 6300), (10, 11)):
        y, off = cond.segment(a, b)
        assert off == max(0, a)
        np.testing.assert_allclose(y, full[max(0, a) : min(6000, b)], rtol=0, atol=1e-12)
    raw = cp._conditioner(x, fs=FS, beep=beep, condition=False)
    y, off = raw.segment(-5, 20)
    assert off == 0 and y.tolist() == x[:20].tolist()


def test_is_clipped_reads_the_stretch_from_the_recordings_start():
    m = np.zeros(100, dtype=bool)
    m[0] = True
    cond = cp._Conditioner(np.zeros(100), None, m)
    assert cond.is_clipped(0, 5) and cond.is_clipped(-3, 1) and not cond.is_clipped(1, 100)
    assert not cp._Conditioner(np.zeros(100), None, None).is_clipped(0, 100)


@pytest.mark.parametrize("compiled", [False, True])
def test_out_of_band_reads_the_middle_65536_samples(compiled):
    """``_out_of_band`` reads ``1 << 16`` samples from the middle of the recording: a
    recording of 4 x 65536 samples whose middle quarter holds the beep's tone and its
    rest 50 Hz hum 20 times as strong is not flagged (the hum is not read), the same with
    the hum in the middle is; a recording of 65536 samples or fewer is read whole."""
    beep = Beep()
    n, q = 4 * 65536, 65536
    t = np.arange(n) / FS
    tone = 0.05 * np.sin(2 * np.pi * beep.f_hz * t)
    hum = np.sin(2 * np.pi * 50.0 * t)
    mid = (np.arange(n) >= (n - q) // 2) & (np.arange(n) < (n + q) // 2)
    for x, flagged in ((np.where(mid, tone, hum), False), (np.where(mid, hum, tone), True)):
        cond = cp._conditioner(x, fs=FS, beep=beep, condition=True)
        cond = cp._Conditioner(x, cond.taps, None, compiled)
        assert cp._out_of_band(x, cond) == flagged
    short = np.where(np.arange(30000) < 29000, tone[:30000], 50 * hum[:30000])
    cond = cp._Conditioner(short, cp.beep_taps(beep, FS), None, compiled)
    assert cp._out_of_band(short, cond)


def _shift_flag(amps, lone_at, lone_amp, row, sigma, seed=0, fs=FS):
    """``_shift_flags`` (its ``ambiguous_first_path`` bit, 4, or 0) of one arrival of
    the default beep (at rate ``fs``) with burst onsets ``row`` (as the arrival reports
    them) and sigma ``sigma``, on a recording of the beep's bursts at 20000 + k 5000 with
    peaks ``amps`` and a lone burst of peak ``lone_amp`` at ``lone_at`` (none: None),
    noise 0.001."""
    beep, one = Beep(fs=fs), Beep(n_bursts=1, fs=fs)
    t0, s = 20000, beep.spacing
    n = t0 + 5 * s + 3000
    x = 0.001 * np.random.default_rng(seed).standard_normal(n)

    def burst(at, amp, b):
        return amp / 0.9 * beep_continuous((np.arange(n) - at) / fs, beep=b)

    for k, a in enumerate(amps):
        x += burst(t0 + k * s, a, one)
    if lone_at is not None:
        x += burst(lone_at, lone_amp, one)
    n_win, hop = cp._stft_params(fs, 128 / 44100, 32 / 44100)
    e = band_energy(x, fs=fs, f_hz=np.array([beep.f_hz]), n_win=n_win, hop=hop).ravel()
    cs = np.concatenate(([0.0], np.cumsum(e)))
    cond = cp._conditioner(x, fs=fs, beep=beep, condition=True)
    arr = Arrivals(
        np.array([float(row[0])]), fs, np.array([sigma]), np.array([30.0]), np.array([1.0]),
        np.array([row], dtype=float), "changepoint",
    )  # fmt: skip
    out = cp._shift_flags(arr, cond, e, cs, fs=fs, beep=beep, n_win=n_win, hop=hop, bg=True)
    return int(out.flags[0])


T0, S = 20000, 5000
ROW = [T0, T0 + S, T0 + 2 * S, T0 + 3 * S]


def test_the_places_beyond_are_one_spacing_from_the_outermost_bursts_found():
    """The place before the beep is one spacing before its first burst's onset, the place
    after one spacing after its last (each from that burst's own onset): with burst 1
    reported 10 samples late, a lone burst at 15000 or 40000 still flags, and none
    does not (the places from burst 1 would be 10 samples off, beyond the tolerance 4)."""
    row = [T0, T0 + S + 10, T0 + 2 * S, T0 + 3 * S]
    assert _shift_flag([0.5] * 4, T0 - S, 0.5, row, 0.25) == 4
    assert _shift_flag([0.5] * 4, T0 + 4 * S, 0.5, row, 0.25) == 4
    assert _shift_flag([0.5] * 4, None, 0.0, row, 0.25) == 0
    # burst 2 reported 10 late instead: the place after is still from burst 3
    row = [T0, T0 + S, T0 + 2 * S + 10, T0 + 3 * S]
    assert _shift_flag([0.5] * 4, T0 + 4 * S, 0.5, row, 0.25) == 4
    assert _shift_flag([0.5] * 4, T0 - S, 0.5, row, 0.25) == 4


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_shifted_beep_is_weighed_against_the_burst_at_the_other_end(seed):
    """The lone burst one spacing before the beep is weighed against the beep's last
    burst (the one a beep shifted earlier would drop), the one after against its first:
    a lone burst of 0.2 does not flag against a last (first) burst of 1.0 while the
    burst next to it is 0.15, and flags when the two are swapped (measured, 5 seeds)."""
    assert _shift_flag([0.5, 0.5, 0.15, 1.0], T0 - S, 0.2, ROW, 0.25, seed) == 0
    assert _shift_flag([0.5, 0.5, 1.0, 0.15], T0 - S, 0.2, ROW, 0.25, seed) == 4
    assert _shift_flag([1.0, 0.15, 0.5, 0.5], T0 + 4 * S, 0.2, ROW, 0.25, seed) == 0
    assert _shift_flag([0.15, 1.0, 0.5, 0.5], T0 + 4 * S, 0.2, ROW, 0.25, seed) == 4


@pytest.mark.parametrize("seed", [0, 1])
def test_the_shift_tolerance_caps_sigma_at_2_samples(seed):
    """The tolerance about a place is ``_allowed_scatter`` one spacing on with the
    arrival's sigma capped at 2 samples (44.1 kHz): sigma 3 gives ceil(2 + 8 + 1) = 11,
    so a lone burst 11 samples after the place flags and one 12 samples after does not
    (measured: the statistic peaks at the lone burst's integer onset)."""
    assert math.ceil(cp._allowed_scatter(1.0, 2.0, 1, 5000.0)) == 11
    assert _shift_flag([0.5] * 4, T0 - S + 11, 0.5, ROW, 3.0, seed) == 4
    assert _shift_flag([0.5] * 4, T0 - S + 12, 0.5, ROW, 3.0, seed) == 0
    assert _shift_flag([0.5] * 4, T0 + 4 * S + 11, 0.5, ROW, 3.0, seed) == 4
    assert _shift_flag([0.5] * 4, T0 + 4 * S + 12, 0.5, ROW, 3.0, seed) == 0


def test_the_shift_tolerance_caps_sigma_at_2_samples_at_44100_hz_scaled_with_the_rate():
    """At 96 kHz the cap is 2 x 96000 / 44100 = 4.35 samples: sigma 6 gives a tolerance
    of ceil(4.35 + 17.4 + 1) = 23, so a lone burst 14 or 22 samples after the place
    before the beep flags and one 24 samples after does not (measured, 2 seeds)."""
    fs = 96000.0
    assert math.ceil(cp._allowed_scatter(fs / 44100, 2 * fs / 44100, 1, 5000.0)) == 23
    for seed in (0, 1):
        for off, flag in ((14, 4), (22, 4), (24, 0)):
            assert _shift_flag([0.5] * 4, T0 - S + off, 0.5, ROW, 6.0, seed, fs=fs) == flag


def _retry_case():
    beep = Beep()
    n = 60000
    x = 0.001 * np.random.default_rng(0).standard_normal(n) + _burst(n, 20000, 0.5, beep)
    n_win, hop, e, _, _ = cp._candidates(
        x, fs=FS, beep=beep, win_s=cp.WIN_S, hop_s=cp.HOP_S, threshold_db=6.0, rise_db=10.0
    )
    cond = cp._conditioner(x, fs=FS, beep=beep, condition=True)
    kw = {"fs": FS, "beep": beep, "n_win": n_win, "hop": hop, "background": True,
          "min_bursts": 3, "quiet": 0.0, "oob": False}  # fmt: skip
    return cond, e, kw


def test_a_re_anchored_edge_where_a_found_beeps_later_burst_lies_is_not_retried():
    """``_beep_row`` of an anchor 150 samples before the beep's burst 1 (25000): the
    joint edge lies at its window's late end, so it is re-anchored on it (24998). With
    nothing found that retry finds bursts 1-3 as a beep at 25000 (3 of 4 bursts); with
    the beep's onset 20000 found (one spacing before the edge) or 10000 (three), the
    edge is that beep's later burst: no row; 5000 (four spacings) is no burst of a beep
    of four: the retry runs. The later-burst window is the retry's search window less a
    taper (22 samples) at both ends, one spacing back: [19780, 20136]; 19790 and 20130
    lie in it, 19760 and 20160 do not."""
    cond, e, kw = _retry_case()
    assert cp._fit_beep(cond, 24850, **{k: kw[k] for k in ("fs", "beep", "n_win", "hop",
                        "background", "min_bursts")})[2] == 24998  # fmt: skip
    for found_at, row in ((None, True), (20000.0, False), (10000.0, False), (5000.0, True),
                          (20130.0, False), (19790.0, False), (19760.0, True),
                          (20160.0, True)):  # fmt: skip
        found = cp._Found()
        if found_at is not None:
            found.add(found_at)
        r = cp._beep_row(cond, 24850, e, found, **kw)
        assert (r is not None) == row, found_at
        if row:
            assert abs(r[0] - 25000) < 0.1 and r[3] == 0.75  # measured 0.007
    found = cp._Found()
    assert cp._beep_row(cond, 24850, e, found, retry=False, **kw) is None


def test_the_raw_statistic_of_a_clipped_stretch_ignores_a_constant_and_a_slope():
    """On a stretch with clipped samples ``_burst_stat`` uses the raw samples' statistic
    with a constant and a slope fitted (clipped samples left out): adding DC of 0.3 and a
    ramp to the recording (same clip mask) leaves it unchanged (measured 3e-10 of its
    peak; without the constant and slope it moves by its whole size)."""
    beep = Beep()
    n = 30000
    t = np.arange(n)
    x = _burst(n, 20000.3, 1.0, Beep(n_bursts=1))
    x = np.clip(x + 0.01 * np.random.default_rng(0).standard_normal(n), -0.8, 0.8)
    mask = cp.clip_mask(x)
    assert mask.sum() > 100
    taps = cp.beep_taps(beep, FS)
    for bg in (True, False):
        args = (20000, -240, 401)
        f0 = cp._burst_stat(cp._Conditioner(x, taps, mask), *args, fs=FS, beep=beep, background=bg)
        y = x + 0.3 + 0.5 * (t - 20000) / n
        f1 = cp._burst_stat(cp._Conditioner(y, taps, mask), *args, fs=FS, beep=beep, background=bg)
        assert int(np.argmax(f0[2])) == 240 and f0[2].max() > 1e4
        assert np.max(np.abs(f1[2] - f0[2])) < 1e-9 * f0[2].max()


def test_before_onset_flags_equal_the_kernels_on_random_band_energies():
    """``_before_onset_flags`` gives the flags of ``_edge_kernels._onset_flags_py`` (its
    independent loop form) with the documented constants: ``PRE_NEAR_S`` (25 ms),
    ``PRE_RUN`` 8 frames, ``PRE_RISE_DB`` 10, ``REVERB_FLOOR_RATIO`` 4, ``PRE_LAST_S`` and
    ``PRE_GUARD_S`` (256 and 8 samples at 44.1 kHz), ``PRE_LAST_DB`` 8, on random band
    energies with rises before the onset, single loud frames just before each burst and
    quiet levels near a quarter of the level before, at 44.1 and 48 kHz; each flag fires
    in a share of the cases and not in another."""
    rng = np.random.default_rng(7)
    fired = np.zeros(3, dtype=int)
    for _ in range(600):
        fs = float(rng.choice([44100.0, 48000.0]))
        hop, n_win = int(rng.choice([16, 32])), int(rng.choice([64, 128]))
        n = int(rng.integers(150, 500))
        e = rng.exponential(1.0, n) * 10 ** rng.uniform(-2, 2)
        t0 = float(rng.uniform(0, n * hop))
        k_b = int(rng.integers(1, 5))
        spacing = float(rng.uniform(500, 3000))
        near = round(0.025 * fs / hop)
        end = int(t0 - n_win) // hop
        if rng.random() < 0.5 and 0 <= end - near < end <= n:
            a = int(rng.integers(end - near, end))
            e[a : a + int(rng.integers(4, 16))] *= 10 ** rng.uniform(0.5, 1.6)
        if rng.random() < 0.5:
            for k in range(k_b):
                last = math.floor((t0 + k * spacing - round(8 * fs / 44100) - n_win) / hop)
                if 0 <= last < n:
                    e[last - int(rng.integers(0, 4))] *= 10 ** rng.uniform(0.4, 1.4)
        if rng.random() < 0.3 and end > 2 * near:
            e[: end - 2 * near] = 0.0 if rng.random() < 0.5 else e[: end - 2 * near]
        quiet = float(np.mean(e[max(0, end - 2 * near) : max(1, end - near)])) * rng.uniform(
            0.1, 0.5
        )
        quiet = 0.0 if rng.random() < 0.1 else quiet
        got = cp._before_onset_flags(
            e, t0, hop=hop, n_win=n_win, fs=fs, quiet=quiet, spacing=spacing, n_bursts=k_b
        )
        ref = K._onset_flags_py(
            e, t0, hop, n_win, near, 8, 10.0, quiet, 4.0,
            max(1, round(256 * fs / 44100 / hop)), float(round(8 * fs / 44100)), 10**0.8,
            spacing, k_b,
        )  # fmt: skip
        want = (cp.flag_bit("ambiguous_first_path") if ref & 1 else 0) | (
            cp.flag_bit("reverb_limited") if ref & 2 else 0
        )
        assert got == want
        fired += [bool(ref & 1), bool(ref & 2), ref == 0]
    assert (fired > 60).all(), fired  # measured: each outcome in 100 or more of 600


def _aliases_reference(rows, tol, max_set=12):
    """``_resolve_aliases`` by its docstring: groups sharing two or more burst onsets
    (within tol) whose onsets lie more than tol apart are aliases; in each set linked so,
    of ``max_set`` groups or fewer, the selection sharing no burst with the largest
    summed strength stays; a larger set is resolved pair by pair in order (the weaker
    of two aliases dropped)."""
    n = len(rows)
    ons = [r[4][np.isfinite(r[4])] for r in rows]
    shared = np.zeros((n, n), dtype=int)
    for i in range(n):
        for j in range(i + 1, n):
            k = sum(any(abs(a - b) <= tol for b in ons[j]) for a in ons[i])
            shared[i, j] = shared[j, i] = k
    t = np.array([r[0] for r in rows])
    alias = (shared >= 2) & (np.abs(t[:, None] - t[None, :]) > tol)
    keep = [True] * n
    seen = set()
    for s in range(n):
        if s in seen or not alias[s].any():
            continue
        comp, todo = set(), [s]
        while todo:
            i = todo.pop()
            if i not in comp:
                comp.add(i)
                todo += [j for j in range(n) if alias[i, j]]
        seen |= comp
        comp = sorted(comp)
        if len(comp) <= max_set:
            best, best_s = [], -math.inf
            for m in range(1, 1 << len(comp)):
                sel = [c for t, c in enumerate(comp) if m >> t & 1]
                if any(shared[a, b] for a in sel for b in sel if a < b):
                    continue
                tot = sum(rows[i][6] for i in sel)
                if tot > best_s:
                    best, best_s = sel, tot
            for i in comp:
                keep[i] = i in best
        else:
            for i in comp:
                for j in comp:
                    if i < j and keep[i] and keep[j] and alias[i, j]:
                        keep[i if rows[i][6] < rows[j][6] else j] = False
    return [i for i in range(n) if keep[i]]


def _group(t0, strength, *, s=5000.0, missing=(), jitter=None, rng=None):
    row = t0 + s * np.arange(4)
    if jitter is not None:
        row = row + rng.uniform(-jitter, jitter, 4)
    row[list(missing)] = np.nan
    return (float(t0), 1.0, 30.0, 1.0, row, 0, float(strength))


def test_resolve_aliases_keeps_the_strongest_selection_sharing_no_burst():
    """``_resolve_aliases`` against its docstring's rule on random sets of groups on a
    spacing grid (aliases of one beep indexed differently, chains, groups with missing
    bursts, onsets jittered across the tolerance), including a set of exactly 12 linked
    groups (searched whole) and one of 13 (pair by pair), where the two rules differ."""
    rng = np.random.default_rng(11)
    tol = 4.0
    n_dropped = 0
    for _ in range(150):
        n = int(rng.integers(2, 7))
        rows = []
        for _ in range(n):
            t0 = 5000.0 * int(rng.integers(0, 6)) + rng.uniform(-6, 6)
            miss = tuple(rng.choice(4, int(rng.integers(0, 2)), replace=False))
            rows.append(_group(t0, rng.uniform(1, 10), missing=miss, jitter=5.0, rng=rng))
        rows.sort(key=lambda r: r[0])
        got = cp._resolve_aliases(rows, tol=tol)
        ref = _aliases_reference(rows, tol)
        assert [r[0] for r in got] == [rows[i][0] for i in ref]
        n_dropped += len(got) < n
    assert 40 < n_dropped < 150  # measured 81 of 150 sets lose a group
    # two groups whose onsets lie exactly tol apart are one indexing, not aliases
    pair = [_group(1000.0, 2.0), _group(1000.0 + tol, 3.0)]
    assert [r[0] for r in cp._resolve_aliases(pair, tol=tol)] == [1000.0, 1000.0 + tol]
    pair = [_group(1000.0, 2.0), _group(1000.0 + 5000.0, 3.0)]
    assert [r[0] for r in cp._resolve_aliases(pair, tol=tol)] == [6000.0]
    # bursts exactly tol apart are shared: three of them, aliases, the stronger stays
    pair = [_group(1000.0, 2.0), _group(6000.0 + tol, 3.0)]
    assert [r[0] for r in cp._resolve_aliases(pair, tol=tol)] == [6000.0 + tol]
    pair = [_group(1000.0, 2.0), _group(6000.0 + tol + 0.5, 3.0)]
    assert len(cp._resolve_aliases(pair, tol=tol)) == 2
    # a chain of 12 (13) linked groups one spacing apart, strengths 2, 3, 2, 2, 3, 2, ...:
    # searched whole (pair by pair); the two rules keep different groups there
    for size, whole in ((12, True), (13, False)):
        rows = [_group(5000.0 * i, 3.0 if i % 3 == 1 else 2.0) for i in range(size)]
        got = [rows.index(r) for r in cp._resolve_aliases(rows, tol=tol)]
        exhaustive = _aliases_reference(rows, tol, max_set=13)
        pairwise = _aliases_reference(rows, tol, max_set=0)
        assert exhaustive != pairwise
        assert got == (exhaustive if whole else pairwise), size


def test_combine_equals_the_kernels_loop_in_every_output():
    """``_combine`` against ``_edge_kernels._combine_py`` (its loop form) in every output:
    onset, sigma (model term ``MODEL_SIGMA`` x fs / 44100 at 44.1 and 96 kHz), the median
    SNR of the kept bursts, confidence, kept bursts and summed strength, on 300 seeded sets
    with failed fits (infinite and NaN sigma), sigmas below the 1e-3 clip, drift,
    outliers and missing bursts; the flags are those of the kept bursts:
    ``inconsistent_bursts`` when fewer than all are kept, ``clipped`` when a kept one
    was, ``low_snr`` below a median of 10 dB."""
    from rangekit.detect.refine import EdgeFit

    K._compiled("beeps")
    rng = np.random.default_rng(21)
    seen = {"none": 0, "partial": 0, "low": 0, "clip": 0}
    for _ in range(300):
        k_b = int(rng.integers(2, 7))
        spacing = float(rng.choice([5000.0, 22050.0]))
        scale = float(rng.choice([1.0, 96000.0 / 44100.0]))
        drift = rng.uniform(-250e-6, 250e-6) * spacing
        sg = np.exp(rng.uniform(np.log(1e-4), np.log(3.0), k_b))
        sg[rng.random(k_b) < 0.1] = np.inf
        sg[rng.random(k_b) < 0.05] = np.nan
        on = (
            1000.0
            + np.arange(k_b) * (spacing + drift)
            + np.nan_to_num(sg, nan=1, posinf=1) * rng.standard_normal(k_b)
        )
        on[rng.random(k_b) < 0.2] += rng.choice([-1, 1]) * rng.uniform(2, 30)
        snr = rng.uniform(3, 30, k_b)
        fst = rng.uniform(20, 500, k_b)
        have = rng.random(k_b) > 0.15
        fits = [EdgeFit(onset=float(on[k]), sigma=float(sg[k]), snr_db=float(snr[k]),
                        amplitude=1.0, f_stat=float(fst[k])) if have[k] else None
                for k in range(k_b)]  # fmt: skip
        clipped = list(rng.random(k_b) < 0.2)
        mb = int(rng.integers(1, k_b + 1))
        got = cp._combine(fits, clipped, spacing=spacing, scale=scale, min_bursts=mb)
        res, row = np.zeros(6), np.zeros(k_b)
        sg_in = np.where(have, sg, np.inf)
        ok = K._combine_py(np.where(have, on, np.nan), sg_in, snr, fst, have, spacing, scale,
                           mb, 1.0, res, row)  # fmt: skip
        assert (got is None) == (not ok)
        if got is None:
            seen["none"] += 1
            continue
        t0, s0, med, conf, burst_row, flags, strength = got
        assert t0 == pytest.approx(res[0], abs=1e-9) and s0 == pytest.approx(res[1], rel=1e-9)
        assert med == pytest.approx(res[2], abs=1e-12) and conf == res[3]
        assert strength == pytest.approx(res[5], rel=1e-12)
        np.testing.assert_array_equal(burst_row, row)
        kept = np.isfinite(row)
        want = 0
        if kept.sum() < k_b:
            want |= cp.flag_bit("inconsistent_bursts")
            seen["partial"] += 1
        if any(c for c, k in zip(clipped, kept, strict=True) if k):
            want |= cp.flag_bit("clipped")
            seen["clip"] += 1
        if float(np.median(snr[kept])) < 10.0:
            want |= cp.flag_bit("low_snr")
            seen["low"] += 1
        assert flags == want
    assert min(seen.values()) > 15, seen  # measured: each case 30 times or more


@pytest.mark.parametrize("dc", [0.3, 0.5])
def test_a_clipped_beep_on_dc_is_timed_with_a_constant_fitted(dc):
    """A clipped burst's onset is refined on the raw samples with the clipped ones left
    out and a constant and slope fitted: a beep (peak 1.1) clipped at +-0.8 about DC of
    0.3 or 0.5, noise 0.01, is timed within 0.05 samples (measured 0.021 at most, as
    without DC) and flagged ``clipped`` only (without the constant: 0.4-0.57 samples
    early and ``low_snr``)."""
    beep = Beep()
    n = 50000
    for seed in range(3):
        x = _burst(n, 20000.3, 1.0, beep) + dc
        x += 0.01 * np.random.default_rng(seed).standard_normal(n)
        arr = cp.detect_changepoint(np.clip(x, dc - 0.8, dc + 0.8), fs=FS, beep=beep)
        assert len(arr) == 1 and abs(arr.onset[0] - 20000.3) < 0.05, seed
        assert arr.flag_names(0) == ("clipped",)


def test_the_noise_floor_is_local_to_quarter_second_stretches_of_16_frames_or_more():
    """``_floor``: ``condition.local_floor`` over stretches of ``round(FLOOR_BLOCK_S fs /
    hop)`` frames (0.25 s: 345 frames of 32 samples at 44.1 kHz), 16 at least."""
    e = np.random.default_rng(0).exponential(1.0, 3000) * np.repeat([1.0, 30.0, 3.0], 1000)
    assert np.array_equal(cp._floor(e, fs=FS, hop=32), cp.local_floor(e, block=345))
    assert not np.array_equal(cp.local_floor(e, block=345), cp.local_floor(e, block=344))
    assert np.array_equal(cp._floor(e, fs=FS, hop=2000), cp.local_floor(e, block=16))
    assert not np.array_equal(cp.local_floor(e, block=16), cp.local_floor(e, block=17))


def test_signal_keeps_long_float32_recordings_and_bounds_samples_at_1e100():
    """``_signal``: a float32 recording of ``NUMBA_MIN_SAMPLES`` samples or more stays
    float32 (no copy), a shorter one becomes float64; samples of exactly +-1e100 pass,
    the next float beyond is refused; a 2-D array is refused."""
    long = np.zeros(K.NUMBA_MIN_SAMPLES, dtype=np.float32)
    assert cp._signal(long).dtype == np.float32 and np.shares_memory(cp._signal(long), long)
    assert cp._signal(np.zeros(100, dtype=np.float32)).dtype == np.float64
    assert cp._signal(np.array([1e100, -1e100, 0.0])).tolist() == [1e100, -1e100, 0.0]
    with pytest.raises(cp.V.InvalidParameterError):
        cp._signal(np.array([np.nextafter(1e100, np.inf), 0.0]))
    with pytest.raises(cp.V.InvalidParameterError):
        cp._signal(np.zeros((2, 5)))


@pytest.mark.parametrize(
    ("beep", "fs", "lo", "hi", "tw"),
    [
        # the default beep: f +- 2 edge bandwidths (4009 Hz), a 1500 Hz transition
        (Beep(), FS, 16000 - 4009.09, 16000 + 4009.09, 1500.0),
        # a low beep: the lower edge at 0.1 f, the transition half of it
        (Beep(f_hz=2000.0), FS, 200.0, 2000 + 4009.09, 100.0),
        # a beep near Nyquist: the upper edge at 0.98 Nyquist, the transition what is left
        (Beep(f_hz=19000.0, fs=44100.0), FS, 19000 - 4009.09, 0.98 * 22050, 441.0),
        (Beep(f_hz=19000.0, fs=44100.0), 40000.0, 19000 - 4009.09, 0.98 * 20000, 400.0),
    ],
)
def test_beep_taps_band_edges_and_transition(beep, fs, lo, hi, tw):
    """``beep_taps``: ``bandpass_taps`` flat over ``f +- 2`` edge bandwidths, the lower
    edge at least 0.1 f, the upper at most 0.98 of Nyquist, with a transition of 1500 Hz,
    at most half the lower edge and at most what lies above the upper (at least 0.01
    Nyquist)."""
    want = cp.bandpass_taps(fs, lo, hi, transition_hz=tw)
    got = cp.beep_taps(beep, fs)
    assert len(got) == len(want)
    np.testing.assert_allclose(got, want, rtol=0, atol=2e-6)  # edges rounded to 0.01 Hz


def test_the_change_points_look_back_4_ms_in_frames_rounded_up(monkeypatch):
    """``_candidates`` separates each frame from the recent level it must rise over by
    ``ceil(LOOKBACK_S fs / hop)`` frames more (4 ms: 5.5 -> 6 frames of 32 samples, 11.03
    -> 12 of 16 at 44.1 kHz)."""
    seen = []
    real = cp._change_points

    def spy(e, **kw):
        seen.append(kw["lookback"])
        return real(e, **kw)

    monkeypatch.setattr(cp, "_change_points", spy)
    x = 1e-3 * np.random.default_rng(0).standard_normal(5000)
    for hop_s in (32 / FS, 16 / FS):
        cp._candidates(x, fs=FS, beep=Beep(), win_s=cp.WIN_S, hop_s=hop_s, threshold_db=6.0,
                       rise_db=10.0)  # fmt: skip
    assert seen == [6, 12]


@pytest.mark.parametrize(("fs", "tol"), [(FS, 4.0), (96000.0, 2 * 96000 / 44100 + 2)])
def test_groups_share_a_burst_within_2_samples_at_44100_hz_plus_2(fs, tol, monkeypatch):
    """``detect_changepoint`` resolves aliases with a burst-sharing tolerance of ``2 fs /
    44100 + 2`` samples (4 at 44.1 kHz)."""
    seen = []
    real = cp._resolve_aliases

    def spy(rows, *, tol):
        seen.append(tol)
        return real(rows, tol=tol)

    monkeypatch.setattr(cp, "_resolve_aliases", spy)
    beep = Beep(fs=fs)
    n = 3 * beep.duration_samples
    x = 1e-3 * np.random.default_rng(0).standard_normal(n)  # called with no group too
    cp.detect_changepoint(x, fs=fs, beep=beep)
    assert seen == [pytest.approx(tol, abs=1e-12)]


def _over_a_tone(seed: int, rise_db: float) -> np.ndarray:
    """The default beep (peak 0.5) at 20000.3 over a steady tone 200 Hz above its
    frequency ``rise_db`` under it (random phase), white noise of 0.001 (as in
    ``test_changepoint_mutation4``)."""
    b, n = Beep(), 40000
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    tone = np.sin(2 * np.pi * (b.f_hz + 200.0) * t / FS + rng.uniform(0.0, 2 * np.pi))
    x = _burst(n, 20000.3, 0.5, b) + 0.5 / 10 ** (rise_db / 20) * tone
    return x + 0.001 * rng.standard_normal(n)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_find_bursts_defaults_find_a_beep_16_db_over_a_steady_tone(seed):
    """``find_bursts``' defaults, 12 dB over the floor and a 10 dB rise: over a steady
    tone of the band (the floor and the level before are the tone's) every burst of a beep
    16 dB over it is found, each within 3.5 samples (measured 1.74 at most: the tone biases
    the edge); asking a 20 dB rise, or 24 dB over the floor, finds none."""
    x = _over_a_tone(seed, 16.0)
    got = cp.find_bursts(x, fs=FS, beep=Beep())
    assert len(got.onset) == 4
    assert np.max(np.abs(got.onset - (20000.3 + 5000.0 * np.arange(4)))) < 3.5
    assert len(cp.find_bursts(x, fs=FS, beep=Beep(), rise_db=20.0).onset) == 0
    assert len(cp.find_bursts(x, fs=FS, beep=Beep(), threshold_db=24.0).onset) == 0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_an_onset_a_sample_or_two_before_the_found_window_does_not_skip_the_anchor(seed):
    """The found-onset window of an anchor ``a`` starts a taper into its search window,
    at ``a - 218`` (44.1 kHz), on both paths: with the beep found at 5000.3 (from anchor
    5000) and a reflection 300 samples later (peak 0.6), a second anchor 219 or 220
    samples after the onset is not skipped, and finds the beep's onset again from the
    reflection's edge (measured, seeds 0-2): two rows, the compiled loop's equal to the
    reference's. (A window starting a taper before the search window would skip it.)"""
    b, n = Beep(), 30000
    x = _burst(n, 5000.3, 0.5, b) + _burst(n, 5300.3, 0.6, b)
    x += 0.001 * np.random.default_rng(seed).standard_normal(n)
    n_win, hop, e, _, _ = cp._candidates(
        x, fs=FS, beep=b, win_s=cp.WIN_S, hop_s=cp.HOP_S, threshold_db=6.0, rise_db=10.0
    )
    kw = {"fs": FS, "beep": b, "n_win": n_win, "hop": hop, "background": True,
          "min_bursts": 3, "quiet": 0.0, "oob": False}  # fmt: skip
    ref_cond = cp._conditioner(x, fs=FS, beep=b, condition=True)
    fast_cond = cp._conditioner(x, fs=FS, beep=b, condition=True, compiled=True)
    for d in (1, 2):
        anchors = np.array([5000, 5000 + 218 + d], dtype=np.int64)
        found = cp._Found()
        ref = [r for a in anchors if (r := cp._beep_row(ref_cond, int(a), e, found, **kw))]
        fast = cp._rows_compiled(fast_cond, anchors, e, **kw)
        assert len(ref) == 2 and abs(ref[1][0] - 5000.3) < 0.05, d  # measured 0.02
        assert [r[0] for r in fast] == pytest.approx([r[0] for r in ref], abs=1e-6), d


@pytest.mark.parametrize("seed", [0, 1])
def test_a_burst_is_refined_as_clipped_when_clipped_samples_lie_2_pre_before_to_2_post_after(
    seed,
):
    """``_fit_beep`` refines a burst on the raw samples (flagged ``clipped``) when clipped
    samples lie in ``[a - 2 pre, a + 2 post)`` about its integer onset ``a`` (pre 24 and
    post 30 samples at 44.1 kHz: ``[a - 48, a + 60)``): a two-sample click at the rail
    starting 46 samples before or 58 after each burst's onset flags the beep, one starting
    50 before or 62 after does not (measured at the beep at 10000.3; the onset within 0.2
    samples either way, measured 0.14)."""
    b, n = Beep(), 40000
    for off, flagged in ((-50, False), (-46, True), (58, True), (62, False)):
        x = _burst(n, 10000.3, 0.5, b) + 0.01 * np.random.default_rng(seed).standard_normal(n)
        for k in range(4):
            x[10000 + k * 5000 + off : 10000 + k * 5000 + off + 2] = 0.9
        arr = cp.detect_changepoint(x, fs=FS, beep=b)
        assert len(arr) == 1 and abs(arr.onset[0] - 10000.3) < 0.2, off
        assert arr.flag_names(0) == (("clipped",) if flagged else ()), off


def _masked_before(tone: float, lone: float, seed: int) -> tuple[float, int]:
    """The default beep (peak 0.5) at 20000, a lone burst (peak ``lone``) one spacing
    before it (15000) under a tone of the beep's frequency in antiphase with it (peak
    ``tone``, Hann-shaped over 11000-18500), noise 0.001: the place's larger band level
    over the last burst's plateau, and ``_shift_flags``' bit for the arrival."""
    beep, one = Beep(), Beep(n_bursts=1)
    n = 45000
    x = 0.001 * np.random.default_rng(seed).standard_normal(n)
    x += _burst(n, 20000, 0.5, beep) + _burst(n, 15000, lone, one)
    i = np.arange(11000, 18500)
    x[i] -= tone * np.sin(2 * np.pi * beep.f_hz * (i - 15000) / FS) * np.hanning(len(i))
    e = band_energy(x, fs=FS, f_hz=np.array([beep.f_hz]), n_win=128, hop=32).ravel()
    cs = np.concatenate(([0.0], np.cumsum(e)))
    kw = {"hop": 32, "w": 4, "n_plat": 5}
    lv, ref = cp._levels(15000.0, cs, len(e), **kw), cp._levels(35000.0, cs, len(e), **kw)
    assert cp._rise_of(lv) < 1.5  # no rise: tested only as masked
    cond = cp._conditioner(x, fs=FS, beep=beep, condition=True)
    row = [20000.0 + k * 5000 for k in range(4)]
    arr = Arrivals(
        np.array([20000.0]), FS, np.array([0.25]), np.array([30.0]), np.array([1.0]),
        np.array([row]), "changepoint",
    )  # fmt: skip
    out = cp._shift_flags(arr, cond, e, cs, fs=FS, beep=beep, n_win=128, hop=32, bg=True)
    return max(lv) / ref[0], int(out.flags[0])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_masked_place_holding_a_tenth_of_a_bursts_energy_is_tested(seed):
    """``MASK_RATIO`` = 1/16: a place one spacing before the beep where the band does not
    rise (a lone burst of 0.3 or 0.28 under a tone of half its peak in antiphase: rise
    0.4 dB) but holds 0.099 (0.086) of the last burst's plateau, between 1/16 and 1/8,
    is tested, and the lone burst there flags the arrival (measured, 3 seeds; a ratio of
    1/8 would leave it untested). The tone alone: no flag."""
    for tone, lone, ratio in ((0.15, 0.3, 0.0986), (0.14, 0.28, 0.0859)):
        got, flag = _masked_before(tone, lone, seed)
        assert got == pytest.approx(ratio, abs=0.002) and flag == 4, (tone, seed)
    assert _masked_before(0.15, 0.0, seed)[1] == 0


@pytest.mark.parametrize("condition", [False, True])
def test_a_short_recording_is_fitted_without_the_compiled_kernels(condition, monkeypatch):
    """A recording shorter than ``NUMBA_MIN_SAMPLES`` is fitted on the numpy path, with
    and without conditioning (``_Conditioner``'s ``compiled`` defaults to False): no
    compiled edge kernel is called, and the beep is found (onset within 0.05 samples,
    measured 0.01)."""

    def refuse(name, *args):
        raise AssertionError(f"compiled kernel {name} called")

    monkeypatch.setattr(K, "call", refuse)
    b, n = Beep(), 30000
    x = _burst(n, 5000.3, 0.5, b) + 0.001 * np.random.default_rng(0).standard_normal(n)
    arr = cp.detect_changepoint(x, fs=FS, beep=b, condition=condition)
    assert len(arr) == 1 and abs(arr.onset[0] - 5000.3) < 0.05
    assert cp._Conditioner(x, None, None).compiled is False
