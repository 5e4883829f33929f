"""Change-point detector, fifth mutation round: rules the other tests let through.

Written against the survivors of the seed-6 sample of ``benchmarks/mutation.py
rangekit/detect/changepoint.py`` (docs/evidence.md, "Fifth round"). Each test checks a
rule the module documents (its docstrings), on short synthetic inputs.
"""

from __future__ import annotations

import numpy as np

from rangekit.detect import changepoint as cp
from rangekit.detect.refine import EdgeFit
from rangekit.signals import Beep
from rangekit.signals.beep import beep_continuous

FS = 44100.0


def _fit(onset: float, sigma: float) -> EdgeFit:
    return EdgeFit(onset=onset, sigma=sigma, snr_db=20.0, amplitude=1.0, f_stat=100.0)


def test_the_recent_level_ends_a_window_before_the_frame_and_lookback_moves_it():
    """``_change_points``: a frame rises over the mean of the 8 frames ending
    ``ceil(n_win / hop)`` frames before it (4 at 128 / 32), ``lookback`` frames earlier
    still. A loud frame 5 frames before frame 40 lies in the default window (its mean
    13.4: frame 40's 20 is under 10 dB over it) and just outside it with ``lookback=1``
    (the 8 frames ending 5 before: mean 1, frame 40 rises)."""
    kw = {"n_win": 128, "hop": 32, "threshold_db": 0.0, "rise_db": 10.0}
    e = np.ones(60)
    e[40 - 5] = 100.0
    e[40] = 20.0
    floor = np.full(len(e), 0.5)
    assert cp._change_points(e, floor=floor, **kw).tolist() == [35]
    assert cp._change_points(e, floor=floor, lookback=0, **kw).tolist() == [35]
    assert cp._change_points(e, floor=floor, lookback=1, **kw).tolist() == [35, 40]


def test_allowed_scatter_scales_its_timing_term_with_the_rate():
    """``_allowed_scatter``: 2 samples of timing noise at 44.1 kHz are ``2 fs / 44100`` at
    another rate. At scale 2.5 (110.25 kHz) a burst 4 samples off the other three (1.6
    samples at 44.1 kHz) is kept; at scale 1 it is rejected (4 > 2 + 4 sigma)."""
    fits = [_fit(0.0, 0.01), _fit(100.0, 0.01), _fit(200.0, 0.01), _fit(304.0, 0.01)]
    got = cp._combine(fits, [False] * 4, spacing=100.0, scale=2.5, min_bursts=2)
    assert got is not None and got[3] == 1.0 and got[5] == 0
    one = cp._combine(fits, [False] * 4, spacing=100.0, scale=1.0, min_bursts=2)
    assert one is not None and one[3] == 0.75
    assert np.isnan(one[4][3]) and one[5] & cp.flag_bit("inconsistent_bursts")


def test_allowed_scatter_holds_200_ppm_of_clock_rate_per_spacing():
    """A receiver clock 150 ppm fast over a spacing of 22050 samples (0.5 s): burst k lies
    3.3 k samples late. The first two bursts precise (sigma 0.01), the last two not (0.3):
    the centre sits near the first two and every burst lies within its allowed scatter
    (2 + 4 sigma + 200 ppm x k spacings: 13.2 samples for burst 3, 8.2 off). Without the
    clock term the bursts would agree with none of the others."""
    spacing, d = 22050.0, 150e-6 * 22050.0
    sg = [0.01, 0.01, 0.3, 0.3]
    fits = [_fit(k * (spacing + d), sg[k]) for k in range(4)]
    got = cp._combine(fits, [False] * 4, spacing=spacing, scale=1.0, min_bursts=3)
    assert got is not None and got[3] == 1.0 and got[5] == 0
    # the inverse-variance centre: about d / 2 (measured 1.66 samples)
    assert 0.0 < got[0] < d
    # 400 ppm (8.8 samples a spacing): burst 3 lies 2 x its clock term off; not all kept
    fits = [_fit(k * (spacing * (1 + 400e-6)), sg[k]) for k in range(4)]
    far = cp._combine(fits, [False] * 4, spacing=spacing, scale=1.0, min_bursts=2)
    assert far is None or far[3] < 1.0


def _nlos3(noise: float, seed: int) -> tuple[Beep, np.ndarray]:
    """A three-burst beep: a direct path 20 dB under a reflection 80 samples later."""
    b = Beep(n_bursts=3)
    t = np.arange(50000) / FS
    x = sum(a * beep_continuous(t - t0 / FS, beep=b) for t0, a in ((20000.0, 0.05 / 0.9),
            (20080.0, 0.5 / 0.9)))  # fmt: skip
    return b, x + noise * np.random.default_rng(seed).standard_normal(len(t))


def test_the_precursor_test_covers_beeps_of_exactly_three_bursts(monkeypatch):
    """Beeps of three bursts or more are tested (the docstring's rule): a three-burst
    beep whose direct path is 20 dB under a reflection 80 samples later is timed on the
    reflection and flagged
    (the tone's ratio over its level before in 56 samples, the smallest of the 3 bursts:
    measured 46-56 at noise 0.02, over ``PRE_TONE_RATIO`` = 4); without the precursor
    test the frame tests leave it unflagged (4 of 4 seeds)."""
    for seed in range(2):
        b, x = _nlos3(0.02, seed)
        arr = cp.detect_changepoint(x, fs=FS, beep=b)
        assert len(arr) == 1 and abs(arr.onset[0] - 20080.0) < 3.0  # measured within 0.15
        assert "ambiguous_first_path" in arr.flag_names(0), seed
    monkeypatch.setattr(cp, "_precursor_flags", lambda arr, cond, *, fs, beep: arr)
    arr = cp.detect_changepoint(x, fs=FS, beep=b)
    assert len(arr) == 1 and "ambiguous_first_path" not in arr.flag_names(0)


def test_last_frames_level_is_read_before_the_near_stretch():
    """``_last_frames_ratio``: each burst's level before is the mean over the
    ``PRE_NEAR_S`` stretch (34 frames) ending ``PRE_NEAR_S`` before its last whole frame,
    so sound inside the near stretch (8 loud frames at its start) does not raise it: the
    last frames at 10 over a level of 1 give 10."""
    hop, n_win = 32, 128
    near = int(round(cp.PRE_NEAR_S * FS / hop))
    assert near == 34
    t0 = 200 * hop + n_win + 8  # its last whole frame ends at t0: frame 200
    last, n_last = cp._last_frames(t0, hop=hop, n_win=n_win, fs=FS)
    end = int(t0 - n_win) // hop
    assert (last, end, n_last) == (200, 200, 8)
    e = np.ones(260)
    e[end - near : end - near + 8] = 100.0  # the near stretch's first frames
    e[last - n_last + 1 : last + 1] = 10.0
    got = cp._last_frames_ratio(e, t0, hop=hop, n_win=n_win, fs=FS, spacing=5000.0, n=1)
    np.testing.assert_allclose(got, np.full(n_last, 10.0))


def _uneven_beep(amps: list[float], seed: int) -> np.ndarray:
    """Bursts of the default beep at 5000.3 + k spacing with amplitudes ``amps`` (a fifth
    amplitude: a burst-like sound one spacing after the last burst), noise 0.01."""
    b1 = Beep(n_bursts=1)
    t = np.arange(40000) / FS
    x = sum(
        a / 0.9 * beep_continuous(t - (5000.3 + k * Beep().spacing) / FS, beep=b1)
        for k, a in enumerate(amps)
        if a
    )
    return x + 0.01 * np.random.default_rng(seed).standard_normal(len(t))


def test_a_shifted_beep_is_weighed_against_the_burst_it_would_drop():
    """``_shift_flags``: a sound one spacing after the last burst makes the start
    ambiguous when its edge statistic reaches ``SHIFT_RATIO`` (1/4) of the burst a beep
    shifted one spacing later would drop, the one at the other end: burst 0. Burst 0 at
    amplitude 0.3, bursts 1-3 at 1, the sound at 0.2: its statistic is (0.2 / 0.3)^2 =
    0.44 of burst 0's (flagged), 0.04 of burst 1's. At 0.1 (0.11 of burst 0's), and with
    no sound, unflagged. Seeds where the beep is timed at its true start (measured
    within 0.3 samples)."""
    for seed in (0, 2):
        for ax, flagged in ((0.2, True), (0.1, False), (0.0, False)):
            arr = cp.detect_changepoint(_uneven_beep([0.3, 1, 1, 1, ax], seed), fs=FS, beep=Beep())
            assert len(arr) == 1 and abs(arr.onset[0] - 5000.3) < 1.0
            assert ("ambiguous_first_path" in arr.flag_names(0)) == flagged, (seed, ax)


def test_precursor_ratio_tests_every_beep_whose_stretches_lie_in_the_recording():
    """``precursor_ratio`` is NaN only where a window or level stretch leaves the
    recording: the 25 ms level stretch (1102 samples) plus a 56-sample window ending 8
    before the onset start at sample 0 for an onset at 1166 (tested), at -1 for 1165
    (NaN); a window ending at the last sample is tested, one past it is NaN."""
    x = 0.01 * np.random.default_rng(7).standard_normal(3000)

    def ratio(on: float) -> float:
        r = cp.precursor_ratio(x, [on], fs=FS, f_hz=16000.0, lengths=(64,), guard=8)
        return float(r[0, 0])

    assert np.isfinite(ratio(1166.0)) and np.isnan(ratio(1165.0))
    assert np.isfinite(ratio(3008.0)) and np.isnan(ratio(3009.0))
