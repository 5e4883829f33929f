"""The recording's quiet level (``reverb_limited``) with digital silence in the recording.

``reverb_limited`` marks an arrival whose level before it is ``REVERB_FLOOR_RATIO``
times the recording's quiet level, the 10th percentile of its stretches' floors. Until
2026-12-04 stretches of digital silence counted with the whole series' level that
``local_floor`` gives them, in themselves and in their neighbours' interpolated floors:
0.2-1 s of zeros before the recording below (a recording app that starts silent) dropped
the flag of its one arrival. The quiet level now leaves silence out (``live_frames``,
``local_floor(silent="skip")``); without silence nothing changed (the realistic corpus,
seeds 1 and 2, prints the same summary before and after).
"""

from __future__ import annotations

import numpy as np
import pytest

import rangekit.detect.changepoint as cp
from rangekit.detect._kernels import recording_samples
from rangekit.detect.condition import live_frames, local_floor
from rangekit.errors import InvalidParameterError
from rangekit.signals import Beep
from rangekit.signals.beep import beep_continuous


def _recording(quiet_part: bool) -> np.ndarray:
    """A beep at 2 s of 4 s in noise of 0.01, 14 dB quieter over the first eighth (the
    arrival then rides 14 dB over the quiet level: ``reverb_limited``), or not."""
    b = Beep()
    t = np.arange(int(4.0 * b.fs)) / b.fs
    noise = 0.01 * np.random.default_rng(1).standard_normal(len(t))
    if quiet_part:
        noise[: len(t) // 8] *= 0.2
    return 0.3 * beep_continuous(t - 2.0, beep=b) + noise


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize(("pre_s", "post_s"), [(0.0, 0.0), (0.2, 0.0), (1.0, 0.0),
                                               (1.0, 1.0), (3.0, 0.0), (0.0, 2.0)])  # fmt: skip
def test_digital_silence_does_not_change_reverb_limited(pre_s, post_s, compiled):
    b = Beep()
    for quiet_part in (True, False):
        x = _recording(quiet_part)
        z = np.concatenate([np.zeros(int(pre_s * b.fs)), x, np.zeros(int(post_s * b.fs))])
        # compiled: the kernels a long recording takes (the numpy path's numbers to
        # rounding), chosen as for a block of one
        with recording_samples(10**7 if compiled else 0):
            arr = cp.detect_changepoint(z, fs=b.fs, beep=b)
        assert len(arr) == 1
        assert arr.onset[0] == pytest.approx(88200.0 + pre_s * b.fs, abs=1.0)
        assert ("reverb_limited" in arr.flag_names(0)) == quiet_part, (pre_s, post_s)


def test_silence_leaves_the_quiet_level_as_it_was():
    """The quiet level itself: with 1 s of zeros before and after, within 3.5 % of the one
    without (measured 0.000681 -> 0.000693, +1.7 %; with the silence counted it was
    0.00214, +214 %)."""
    b = Beep()
    x = _recording(True)
    n_win, hop = cp._stft_params(b.fs, cp.WIN_S, cp.HOP_S)

    def quiet(y):
        e = cp.band_energy(y, fs=b.fs, f_hz=np.array([b.f_hz]), n_win=n_win, hop=hop)
        return cp._quiet_level(e, cp._floor(e, fs=b.fs, hop=hop), fs=b.fs, hop=hop)

    pad = np.zeros(int(b.fs))
    q0, q1 = quiet(x), quiet(np.concatenate([pad, x, pad]))
    assert q1 == pytest.approx(q0, rel=0.035)


def test_live_frames_is_local_floors_own_level_rule():
    """A stretch is live with ``max(8, min_live * length)`` frames over 1e-12 of the
    largest: here stretches of 100 frames with 100, 30, 25, 24 and 0 such frames, and a
    last one of 12 with 8 and a 5-frame tail."""
    rng = np.random.default_rng(0)
    parts, want = [], []
    for n_live, n in [(100, 100), (30, 100), (25, 100), (24, 100), (0, 100), (8, 12)]:
        seg = np.zeros(n)
        seg[rng.choice(n, n_live, replace=False)] = rng.exponential(1.0, n_live)
        parts.append(seg)
        want.append(np.full(n, n_live >= max(8, 0.25 * n)))
    e = np.concatenate(parts)
    np.testing.assert_array_equal(live_frames(e[:512], block=100), np.concatenate(want))
    # a series no longer than a stretch is one stretch with the whole series' level
    assert live_frames(np.zeros(50), block=100).all()
    dead = ~live_frames(e[:512], block=100)
    assert dead[400:500].all() and not dead[200:300].any()


def test_local_floor_skip_keeps_the_neighbours_levels():
    rng = np.random.default_rng(2)
    e = np.concatenate([rng.exponential(1.0, 1000), np.zeros(1000), rng.exponential(16.0, 1000)])
    whole = local_floor(e, block=500)
    skip = local_floor(e, block=500, silent="skip")
    # "whole": the silent stretches' centres take the whole series' level; "skip": the
    # floor runs straight from the quiet stretch's last centre (749.5) to the loud one's
    # first (2249.5), past the silence
    for c in (1249, 1749):
        assert whole[c] == pytest.approx(cp.active_floor(e), rel=1e-3)  # c: 0.5 off centre
    assert 0.8 < skip[700] < 1.2 and 13.0 < skip[2400] < 20.0
    assert skip[1499] == pytest.approx(0.5 * (skip[749] + skip[2249]), rel=1e-3)
    # no silence: the two are the same
    live = rng.exponential(1.0, 3000)
    np.testing.assert_array_equal(
        local_floor(live, block=500, silent="skip"), local_floor(live, block=500)
    )
    with pytest.raises(InvalidParameterError, match="silent"):
        local_floor(e, block=500, silent="zero")


@pytest.mark.parametrize("silence_s", [2.0, 5.0, 20.0])
def test_template_noise_level_leaves_digital_silence_out(silence_s):
    """A 50 ms 2-6 kHz sweep in 4 s of noise, 20 dB over it, after ``silence_s`` of
    zeros. The matched filter's noise level is the median of the envelope: with more
    than half of the recording zeros it was 0 (the floor, 1e-6 of the peak), and the
    filter's -70 dB tails of the noise where it starts were arrivals in the silence (two
    more at 5 and 20 s, at 15-70 dB SNR, one flagged only ambiguous_first_path) and the
    SNR rose 3.7 dB at 2 s. Now: the one arrival, its SNR as without silence (43.9 dB,
    measured equal to 0.01 dB), its onset to 0.016 samples."""
    from rangekit.detect.template import detect_template
    from rangekit.signals.probe import linear_sweep

    fs = 44100.0
    p = linear_sweep(2000.0, 6000.0, 0.05, fs=fs)
    x = 0.01 * np.random.default_rng(3).standard_normal(int(4 * fs))
    x[int(2 * fs) : int(2 * fs) + len(p.samples)] += 0.1 * p.samples
    ref = detect_template(x, fs=fs, probe=p)
    z = np.concatenate([np.zeros(int(silence_s * fs)), x])
    got = detect_template(z, fs=fs, probe=p)
    assert len(ref) == len(got) == 1
    # the weighting's spectra and the filter's blocks fall elsewhere: measured 0.006-0.016
    assert got.onset[0] - silence_s * fs == pytest.approx(ref.onset[0], abs=0.035)
    assert got.snr_db[0] == pytest.approx(ref.snr_db[0], abs=0.1)
    assert got.flag_names(0) == ref.flag_names(0) == ()


def test_live_frames_counts_signal_as_local_floor_does_at_its_threshold():
    """ "Holding signal" is over 1e-12 of the largest frame in both: a stretch whose 30 of
    100 frames sit at 1.5e-12 of the peak is live (its own level in ``local_floor``), one
    whose frames sit at 0.5e-12 is not (the whole series' level)."""
    e = np.zeros(400)
    e[:100] = 1.0  # the peak, and a live stretch
    e[100:130] = 1.5e-12  # live: 30 % over the threshold
    e[200:230] = 0.5e-12  # dead: under it
    e[300:] = 1.0
    live = live_frames(e, block=100)
    assert live[100:200].all() and not live[200:300].any()
    # local_floor agrees: the live stretch's own level (~1e-12), the dead one's the whole
    # series' (4.48) near its centre (249.5)
    f, whole = local_floor(e, block=100), cp.active_floor(e)
    assert f[149] < 0.01 * whole  # measured 0.005 (the interpolation from 49.5)
    assert f[249] > 0.9 * whole
