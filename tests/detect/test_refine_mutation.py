"""Edge fit: properties that ``benchmarks/mutation.py`` found untested (seed 4's sample).

Each test states the documented behaviour it pins; the equivalent mutants of the same
sample are listed in docs/evidence.md.
"""

from __future__ import annotations

import numpy as np

from rangekit.detect.refine import _window, edge_statistic, fit_edge, refine_onset
from rangekit.signals import Beep
from rangekit.signals.beep import beep_continuous

FS = 44100.0
BEEP = Beep(n_bursts=1)


def _burst(onset: float, n: int, amp: float = 1.0) -> np.ndarray:
    return amp * beep_continuous((np.arange(n) - onset) / FS, beep=BEEP)


def test_an_edge_at_15_percent_of_the_strongest_is_the_first_path_by_default():
    """``first_path`` = 0.1: a direct path whose statistic is 15 % of a later, stronger
    burst's (measured 0.151) is the onset; at 0.2 the later burst would be."""
    x = _burst(1000.3, 2400, 0.3) + _burst(1600.7, 2400)
    x = x + 0.01 * np.random.default_rng(5).standard_normal(len(x))
    kw = {"fs": FS, "beep": BEEP, "lo": 950, "hi": 1650}
    f = edge_statistic(x, **kw)
    assert 0.12 < f[:300].max() / f.max() < 0.18  # the case is what it says
    default = fit_edge(x, **kw)
    assert abs(default.onset - 1000.3) < 0.5
    assert default == fit_edge(x, **kw, first_path=0.1)
    assert abs(fit_edge(x, **kw, first_path=0.2).onset - 1600.7) < 0.5


def test_a_masked_window_with_8_residual_dof_keeps_its_statistic():
    """Windows of the masked statistic need 8 residual degrees of freedom (n_keep minus
    the 2 edge columns); with 7 the statistic is 0."""
    x = _burst(500.3, 1200) + 0.01 * np.random.default_rng(2).standard_normal(1200)
    _pre, post = _window(FS, BEEP, None, None)
    for keep, nonzero in ((10, True), (9, False)):
        mask = np.ones(len(x), dtype=bool)
        mask[500 : 500 + keep] = False
        lo = 500 + keep - post  # this offset's window [lo - pre, lo + post) holds them all
        f = edge_statistic(x, fs=FS, beep=BEEP, lo=lo, hi=lo, mask=mask)
        assert (f[0] > 0.0) == nonzero, keep


def test_stage_two_uses_the_recording_from_its_first_sample():
    """An onset near the start: the window is clipped to sample 0, not beyond it. Padding
    the recording in front with masked samples gives the same fit (shifted)."""
    pad = 50
    rng = np.random.default_rng(6)
    full = _burst(26.3 + pad, 600 + pad) + 0.02 * rng.standard_normal(600 + pad)
    x = full[pad:]
    mask = np.zeros(len(full), dtype=bool)
    mask[:pad] = True
    fit = refine_onset(x, fs=FS, beep=BEEP, a=26)
    padded = refine_onset(full, fs=FS, beep=BEEP, a=26 + pad, mask=mask)
    assert abs(fit.onset - 26.3) < 0.5
    assert abs((padded.onset - pad) - fit.onset) < 1e-9
    assert abs(padded.sigma - fit.sigma) < 1e-9 * fit.sigma


def test_an_edge_with_statistic_20_is_an_edge_by_default():
    """``f_min`` = 15: a faint first path (statistic 20.5, measured, of a top 38) counts;
    with 30 the later burst would be taken. Noisy: the onset itself is 8 samples off."""
    x = _burst(1000.3, 2400, 0.5) + _burst(1600.7, 2400)
    x = x + 0.3 * np.random.default_rng(5).standard_normal(len(x))
    kw = {"fs": FS, "beep": BEEP, "lo": 950, "hi": 1650}
    f = edge_statistic(x, **kw)
    assert 15.0 < f[:300].max() < 30.0 and f.max() < 150.0  # frac * top is below f_min
    default = fit_edge(x, **kw)
    assert default == fit_edge(x, **kw, f_min=15.0) and abs(default.onset - 1000.3) < 12
    assert abs(fit_edge(x, **kw, f_min=30.0).onset - 1600.7) < 12


def test_refine_onset_defaults_are_the_numpy_path_without_dc():
    """``dc=False`` and ``compiled=False`` by default (the compiled stage 2 equals the numpy
    one only to rounding, so the default's result is the numpy one exactly)."""
    x = _burst(500.3, 2000) + 0.3 + 0.01 * np.random.default_rng(4).standard_normal(2000)
    plain = refine_onset(x, fs=FS, beep=BEEP, a=500, dc=False, compiled=False)
    assert refine_onset(x, fs=FS, beep=BEEP, a=500) == plain
    assert refine_onset(x, fs=FS, beep=BEEP, a=500, dc=True) != plain
    fast = refine_onset(x, fs=FS, beep=BEEP, a=500, compiled=True)
    assert abs(fast.onset - plain.onset) < 1e-9  # (differs in the last bits here)
