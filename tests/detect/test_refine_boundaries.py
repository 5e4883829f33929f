"""Edge fit: documented defaults and thresholds, pinned one by one.

Written against mutants of ``rangekit/detect/refine.py`` that the other tests let through
(``benchmarks/mutation.py``, docs/evidence.md).
"""

from __future__ import annotations

import math

import numpy as np

from rangekit.detect.refine import _window, edge_statistic, first_peak, fit_edge, refine_onset
from rangekit.signals import Beep
from rangekit.signals.beep import beep_continuous

FS = 44100.0
BEEP = Beep(n_bursts=1)


def _ringing(onset=700.4):
    """A burst over a 16 kHz tone still ringing (the case ``background`` is for)."""
    n = np.arange(2000)
    x = beep_continuous((n - onset) / FS, beep=BEEP) + 0.6 * np.sin(2 * np.pi * 16000 * n / FS)
    return x + 1e-3 * np.random.default_rng(1).standard_normal(len(x))


def test_background_is_off_by_default():
    x = _ringing()
    kw = {"fs": FS, "beep": BEEP, "lo": 640, "hi": 760}
    off, on = fit_edge(x, **kw, background=False), fit_edge(x, **kw, background=True)
    assert abs(off.onset - on.onset) > 1.0  # the two fits differ here ...
    assert fit_edge(x, **kw) == off  # ... and the default is the one without the tone
    a = int(round(on.onset))
    r_off = refine_onset(x, fs=FS, beep=BEEP, a=a, background=False)
    assert refine_onset(x, fs=FS, beep=BEEP, a=a) == r_off
    assert refine_onset(x, fs=FS, beep=BEEP, a=a, background=True) != r_off


def test_first_peak_threshold_is_frac_of_the_top_and_f_min():
    f = np.array([0.0, 30.0, 0.0, 1000.0, 0.0])
    assert first_peak(f, 0.1, 15.0) == 3  # 30 < 0.1 * 1000: not an edge
    assert first_peak(f, 0.02, 15.0) == 1  # 30 >= 20 and >= 15: the first path
    assert first_peak(f, 0.02, 40.0) == 3  # below f_min
    # every value below f_min: the threshold drops to the top, the largest wins
    assert first_peak(np.array([1.0, 3.0, 2.0, 5.0, 1.0]), 0.1, 15.0) == 3


def test_default_window_is_24_samples_and_the_taper_plus_8():
    for fs in (44100.0, 48000.0, 96000.0):
        scale = fs / 44100.0
        pre, post = _window(fs, BEEP, None, None)
        assert pre == round(24 * scale)
        assert post == math.ceil(BEEP.taper_s * fs + 8 * scale)
        assert post > BEEP.taper_s * fs  # the whole rise is in the window
    assert _window(FS, BEEP, 5, 7) == (5, 7)


def test_masked_window_needs_8_plus_2_samples_per_column():
    """Stage 2 with the window masked down to 8 + 2 * 2 = 12 samples still fits; 11 do not."""
    rng = np.random.default_rng(3)
    onset = 500.3
    x = beep_continuous((np.arange(2000) - onset) / FS, beep=BEEP)
    x = x + 0.01 * rng.standard_normal(len(x))
    for keep, fits in ((12, True), (13, True), (11, False)):
        mask = np.ones(len(x), dtype=bool)
        mask[500 : 500 + keep] = False
        fit = refine_onset(x, fs=FS, beep=BEEP, a=500, mask=mask)
        assert (fit is not None) == fits, keep
        if fits:
            assert fit.n_masked > 0


def _offset_burst(dc=0.3, noise=0.01, seed=4):
    x = beep_continuous((np.arange(2000) - 500.3) / FS, beep=BEEP)
    return x + dc + noise * np.random.default_rng(seed).standard_normal(len(x))


def test_edge_statistic_fits_no_dc_by_default():
    x = _offset_burst()
    kw = {"fs": FS, "beep": BEEP, "lo": 450, "hi": 550}
    plain = edge_statistic(x, **kw, dc=False)
    assert np.array_equal(edge_statistic(x, **kw), plain)
    assert np.max(np.abs(edge_statistic(x, **kw, dc=True) - plain)) > 1.0


def test_one_candidate_onset_is_a_search_interval():
    """lo == hi is a legal interval: the fit is made there, not refused."""
    fit = fit_edge(_offset_burst(dc=0.0), fs=FS, beep=BEEP, lo=500, hi=500)
    assert fit is not None and abs(fit.onset - 500.3) < 0.5


def test_a_mask_at_the_end_of_the_last_window_is_used():
    x = _offset_burst()
    post = _window(FS, BEEP, None, None)[1]
    mask = np.zeros(len(x), dtype=bool)
    mask[550 + post - 1] = True  # the last sample of the last offset's window only
    kw = {"fs": FS, "beep": BEEP, "lo": 450, "hi": 550}
    plain, masked = edge_statistic(x, **kw), edge_statistic(x, **kw, mask=mask)
    assert masked[-1] != plain[-1]
    assert np.allclose(masked[: 100 - post], plain[: 100 - post], rtol=1e-9)


def test_sigma_above_one_sample_is_finite():
    """A faint edge: the Fisher information is below 1 / sample^2, sigma stays finite."""
    x = beep_continuous((np.arange(2000) - 500.3) / FS, beep=BEEP)
    x = x + 0.3 * np.random.default_rng(4).standard_normal(len(x))
    fit = refine_onset(x, fs=FS, beep=BEEP, a=500)
    assert 1.0 < fit.sigma < 4.0  # measured 1.88 samples


def test_defaults_are_the_numpy_path_without_background():
    """``compiled=False`` and ``background=False`` by default (the compiled kernels give the
    same numbers only to rounding, so the default's result is the numpy one exactly)."""
    x = _offset_burst(dc=0.0)
    kw = {"fs": FS, "beep": BEEP, "lo": 450, "hi": 550}
    numpy_fit = fit_edge(x, **kw, compiled=False)
    assert fit_edge(x, **kw) == numpy_fit
    compiled_fit = fit_edge(x, **kw, compiled=True)
    assert abs(compiled_fit.onset - numpy_fit.onset) < 1e-9  # same fit, other rounding
    assert np.array_equal(edge_statistic(x, **kw), edge_statistic(x, **kw, compiled=False))
    ring = _ringing()
    kw = {"fs": FS, "beep": BEEP, "lo": 640, "hi": 760}
    off = edge_statistic(ring, **kw, background=False)
    assert np.array_equal(edge_statistic(ring, **kw), off)
    assert not np.allclose(edge_statistic(ring, **kw, background=True), off)


def test_n_masked_counts_the_masked_samples_of_the_window():
    x = _offset_burst(dc=0.0)
    assert refine_onset(x, fs=FS, beep=BEEP, a=500).n_masked == 0
    mask = np.zeros(len(x), dtype=bool)
    mask[495:499] = True  # 4 samples inside the stage-2 window
    mask[1500:1510] = True  # 10 outside it
    assert refine_onset(x, fs=FS, beep=BEEP, a=500, mask=mask).n_masked == 4
