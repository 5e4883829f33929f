"""Change-point detector, sixth mutation round: rules the other tests let through.

Written against the blind survivors of the seed-8 sample of ``benchmarks/mutation.py
rangekit/detect/changepoint.py`` (docs/evidence.md, "sixth round"): the masked-burst
ratio of ``_shift_flags``, the drift term of its one-spacing tolerance, and the anchors'
spacing test. Each test checks a rule the module documents (its docstrings and
comments), on short synthetic inputs.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rangekit.detect import _edge_kernels as K
from rangekit.detect import changepoint as cp
from rangekit.detect._kernels import band_energy
from rangekit.detect.refine import _window
from rangekit.signals import Beep
from rangekit.signals.beep import beep_continuous
from rangekit.types import Arrivals, flag_bit

FS = 44100.0


def _burst(n: int, at: float, amp: float, *, beep: Beep) -> np.ndarray:
    """``beep`` (peak ``amp``) starting at sample ``at`` of ``n`` (continuous time)."""
    return amp / 0.9 * beep_continuous((np.arange(n) - at) / FS, beep=beep)


def _masked_after(seed: int, tone: float, lone: float) -> np.ndarray:
    """The default beep (peak 0.5) at 20000.3, a lone burst (peak ``lone``) one spacing
    after its last one (40000.3), and a tone of the beep's frequency (peak ``tone``,
    Hann-shaped over samples 36500-43500, after the beep's last burst has ended) in
    antiphase with that burst, so it cancels part of it; white noise of 0.001."""
    n, at = 60000, 40000.3
    x = _burst(n, 20000.3, 0.5, beep=Beep()) + _burst(n, at, lone, beep=Beep(n_bursts=1))
    i = np.arange(36500, 43500)
    x[i] -= tone * np.sin(2 * np.pi * Beep().f_hz * (i - at) / FS) * np.hanning(len(i))
    return x + 0.001 * np.random.default_rng(seed).standard_normal(n)


@pytest.mark.parametrize("tone", [0.8, 1.5])
def test_a_burst_masked_by_a_loud_tone_one_spacing_on_is_still_tested(tone):
    """``_shift_flags``: a place one spacing beyond the beep where the band energy does
    not rise is tested all the same when the band holds ``MASK_RATIO`` (1/16) of the
    energy of the burst a shifted beep would drop (burst 0) at or just before it: a burst
    masked by a loud tone does not rise. The lone burst (0.5) under a tone of 0.8 (1.5)
    in antiphase: the place's rise is 0 dB (plateau 86 (982), level before 643 (2259),
    burst 0's plateau 256: max over it 2.5 (8.8), between 1/16 and 16; measured seed 0);
    the edge statistic finds the burst there, so the arrival is flagged
    ``ambiguous_first_path`` (every seed, measured). The tone without the burst: nothing
    to find, no flag. (A ratio of 16 would leave both places untested: no flag.)"""
    for seed in range(3):
        for lone, flagged in ((0.5, True), (0.0, False)):
            arr = cp.detect_changepoint(_masked_after(seed, tone, lone), fs=FS)
            assert len(arr) == 1 and abs(arr.onset[0] - 20000.3) < 0.1  # measured 0.01
            assert ("ambiguous_first_path" in arr.flag_names(0)) == flagged, (seed, lone)
            assert arr.flags[0] & ~flag_bit("ambiguous_first_path") == 0


def test_the_masked_place_is_read_against_the_burst_a_shifted_beep_would_drop(monkeypatch):
    """The same place and tone (0.8), with ``MASK_RATIO`` set either side of what the
    band holds there (2.5 of burst 0's plateau, measured): 2 tests it (flagged), 3 does
    not (no flag): the ratio is the level at or just before the place over burst 0's
    plateau, as the comment says."""
    x = _masked_after(0, 0.8, 0.5)
    for ratio, flagged in ((2.0, True), (3.0, False)):
        monkeypatch.setattr(cp, "MASK_RATIO", ratio)
        arr = cp.detect_changepoint(x, fs=FS)
        assert len(arr) == 1 and abs(arr.onset[0] - 20000.3) < 0.1
        assert ("ambiguous_first_path" in arr.flag_names(0)) == flagged, ratio


def _long_spacing(seed: int, off: float, *, beep: Beep) -> np.ndarray:
    """``beep`` (peak 0.5) at 10000.3 and a lone burst (peak 0.3) ``off`` samples after
    the place one spacing beyond its last burst; white noise of 0.001."""
    n = 10000 + 4 * beep.spacing + 20000
    x = _burst(n, 10000.3, 0.5, beep=beep)
    x += _burst(n, 10000.3 + 4 * beep.spacing + off, 0.3, beep=Beep(n_bursts=1))
    return x + 0.001 * np.random.default_rng(seed).standard_normal(n)


@pytest.mark.parametrize(
    ("spacing", "off", "flagged"),
    [(44100, 9.0, True), (44100, 14.0, True), (44100, 24.0, False), (5000, 9.0, False)],
)
def test_the_one_spacing_tolerance_holds_200_ppm_of_the_spacing(spacing, off, flagged):
    """``_shift_flags`` tests the place one spacing beyond the beep over "the scatter
    ``_combine`` allows a burst one spacing on": ``_allowed_scatter(scale, min(sigma, 2
    scale), 1, spacing)`` = 2 samples + 4 sigma + ``MAX_DRIFT`` (200 ppm) of the spacing.
    sigma is 1 sample here (measured: the model term), so a spacing of one second (44100
    samples, 8.8 samples of drift) gives ceil(14.8) = 15 samples: a burst 9 or 14 samples
    off the place is flagged, 24 not; at the default spacing (5000, 1 sample of drift:
    7) the same 9 samples are outside. (Without the drift term, or with it subtracted,
    9 samples would be outside at either spacing.)"""
    beep = Beep(spacing=spacing)
    for seed in range(3):
        arr = cp.detect_changepoint(_long_spacing(seed, off, beep=beep), fs=FS, beep=beep)
        assert len(arr) == 1 and abs(arr.onset[0] - 10000.3) < 0.1  # measured 0.01
        assert arr.sigma[0] == pytest.approx(1.0, abs=0.05)  # measured 1.000
        assert ("ambiguous_first_path" in arr.flag_names(0)) == flagged, seed


def test_anchors_one_hop_apart_are_the_same_edge(monkeypatch):
    """``detect_changepoint`` keeps a beep start as an anchor only when it lies more than
    a hop from each of the last 8 kept (one edge raises change points in neighbouring
    frames): starts of change-point frames 100, 101 and 103 (hop 32: samples 3200, 3232,
    3296), each with two rising places, give the anchors 3200 and 3296; 3232, exactly one
    hop on, is the same edge. The numpy loop gives the compiled ``dedupe`` kernel's
    anchors."""
    x = 1e-3 * np.random.default_rng(0).standard_normal(30000)
    assert len(x) < K.NUMBA_MIN_SAMPLES  # the numpy loop
    real = cp._candidates

    def candidates(*args, **kwargs):
        n_win, hop, e, floor, _ = real(*args, **kwargs)
        return n_win, hop, e, floor, np.array([100, 101, 103])

    seen: list[int] = []

    def row(cond, a, *args, **kwargs):
        seen.append(int(a))

    monkeypatch.setattr(cp, "_candidates", candidates)
    monkeypatch.setattr(cp, "_anchor", lambda c, *a, **k: (int(c), 2))
    monkeypatch.setattr(cp, "_beep_row", row)
    assert len(cp.detect_changepoint(x, fs=FS)) == 0
    assert seen == [3200, 3296]
    starts = np.array([3200, 3232, 3296], dtype=np.int64)
    kernel = K._dedupe_py(starts, np.full(3, 2, dtype=np.int64), 2, 32)
    assert kernel.tolist() == seen


def _shift_flag_at_start(t0: int, *, lone: bool, condition: bool) -> int:
    """``_shift_flags`` of one arrival of the default beep timed at sample ``t0`` (its
    four bursts found, sigma 0.25), with a lone burst as strong (peak 0.5) one spacing
    before it when ``lone``, on a band energy of 16-sample windows at a hop of 1 (so
    the band levels of a place 26 samples into the recording exist); noise 0.001."""
    beep, n_win, hop = Beep(), 16, 1
    s = beep.spacing
    n = t0 + 4 * s + 3000
    x = _burst(n, t0, 0.5, beep=beep) + 0.001 * np.random.default_rng(0).standard_normal(n)
    if lone:
        x += _burst(n, t0 - s, 0.5, beep=Beep(n_bursts=1))
    e = band_energy(x, fs=FS, f_hz=np.array([beep.f_hz]), n_win=n_win, hop=hop).ravel()
    cs = np.concatenate(([0.0], np.cumsum(e)))
    cond = cp._conditioner(x, fs=FS, beep=beep, condition=condition)
    arr = Arrivals(
        np.array([float(t0)]), FS, np.array([0.25]), np.array([30.0]), np.array([1.0]),
        np.array([[t0 + k * s for k in range(4)]], dtype=float), "changepoint",
    )  # fmt: skip
    out = cp._shift_flags(arr, cond, e, cs, fs=FS, beep=beep, n_win=n_win, hop=hop, bg=True)
    return int(out.flags[0])


@pytest.mark.parametrize("condition", [False, True])
def test_a_shifted_place_whose_stretch_starts_at_sample_0_is_tested(condition):
    """``_shift_flags`` tests the edge statistic over the place one spacing before the
    beep plus the allowed scatter and a taper either side, ``p - tol - sep ... p + tol +
    sep``, wherever that stretch lies in the recording: here tol = ceil(2 + 4 x 0.25 +
    200 ppm x 5000) = 4 and sep = 22 (the taper), so a beep at 5026 puts the stretch's
    first sample at 0: tested, and the lone burst there flags ``ambiguous_first_path``
    (as at 5027 and 5100); at 5025 it would start at -1: not tested, no flag. Without the
    lone burst, no flag."""
    bit = flag_bit("ambiguous_first_path")
    tol = int(np.ceil(cp._allowed_scatter(1.0, 0.25, 1, Beep().spacing)))
    assert (tol, max(2, round(Beep().taper_s * FS))) == (4, 22)
    for t0, flag in ((5025, 0), (5026, bit), (5027, bit), (5100, bit)):
        assert _shift_flag_at_start(t0, lone=True, condition=condition) == flag, t0
    assert _shift_flag_at_start(5026, lone=False, condition=condition) == 0


def test_the_raw_statistic_of_a_clipped_burst_fits_from_the_recordings_first_sample():
    """``_burst_stat`` on a clipped stretch computes the statistic on the raw samples
    (clipped ones left out) over the same stretch as the band-limited one, cut at the
    recording's start alike; ``_stat_on`` gives 0 only where the window does not fit.
    The window reads ``pre`` (24) samples before an onset, so near the start the first
    onset with a statistic is sample 24, for the raw samples as for the band-limited
    ones: a burst at 34, three times 0.5 and clipped at 0.6, onsets 22-46: 0 at 22 and
    23, nonzero from 24 on (measured 69 at 24), the largest at the burst (34)."""
    beep = Beep(n_bursts=1)
    pre, _ = _window(FS, beep, None, None)
    assert pre == 24
    n, at = 3000, pre + 10
    x = _burst(n, at, 1.5, beep=beep) + 0.001 * np.random.default_rng(0).standard_normal(n)
    x = np.clip(x, -0.6, 0.6)
    kw = {"fs": FS, "beep": beep, "background": True}
    cond = cp._conditioner(x, fs=FS, beep=beep, condition=True)
    assert cond.is_clipped(0, 100)
    _, off, f = cp._burst_stat(cond, at, -12, 25, **kw)
    plain = cp._conditioner(x, fs=FS, beep=beep, condition=True)
    plain = replace(plain, clipped=None)  # the band-limited statistic alone
    _, _, f_band = cp._burst_stat(plain, at, -12, 25, **kw)
    onsets = at - 12 + np.arange(25)
    assert off == 0
    assert (onsets[f > 0] >= pre).all() and f[onsets == pre][0] > 0
    assert ((f > 0) == (f_band > 0)).all()
    assert not np.allclose(f, f_band)  # the raw one was used
    assert onsets[np.argmax(f)] == at
