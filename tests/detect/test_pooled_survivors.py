"""Tests written against survivors of the held-out pooled mutation samples of
``rangekit/detect`` (seeds 102 and 103, issue 21; docs/evidence.md): xcorr's detection
threshold in dB, the stagger model's clip of the split's real part, and the fitted
detector's ``low_snr`` level. Each rule is checked against the value its docstring or
``Arrivals`` states, computed here (about 3 s).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from rangekit.detect.fitted import fit_channel
from rangekit.detect.matched import DEFAULT_K_DETECT, coded_template
from rangekit.detect.pathfit import ResonatorModel
from rangekit.detect.stagger import StaggerModel
from rangekit.detect.xcorr import detect_xcorr
from rangekit.signals.barker import CodedBurst, burst_waveform
from rangekit.signals.beep import Beep, beep_continuous_analytic, beep_waveform
from rangekit.signals.transducer import Transducer
from rangekit.types import flag_bit


def _xcorr_peak_over_median_db(x: np.ndarray, beep: Beep) -> float:
    """The burst-summed correlation envelope's peak over its median, in dB (20 log10):
    what ``detect_xcorr``'s ``threshold_db`` is compared with (module doc)."""
    one = beep_continuous_analytic(
        np.arange(math.ceil(beep.burst_s * beep.fs)) / beep.fs, beep=beep
    )
    e1 = np.abs(signal.correlate(x.astype(complex), one, mode="full", method="direct"))
    e1 = e1[len(one) - 1 : len(one) - 1 + len(x)]
    env = np.zeros(len(x))
    for k in range(beep.n_bursts):
        sh = int(round(k * beep.spacing_s * beep.fs))
        env[: len(x) - sh] += e1[sh:]
    return 20.0 * math.log10(env.max() / np.median(env))


def test_xcorr_detects_a_beep_exactly_above_its_threshold_in_db():
    """A beep whose envelope peak is ``r`` dB over the envelope's median is detected with
    ``threshold_db`` 0.05 dB under ``r`` and not 0.05 dB over it (20 log10: amplitude)."""
    b = Beep()
    rng = np.random.default_rng(4)
    x = 0.2 * rng.standard_normal(40000)
    x[5000 : 5000 + b.duration_samples] += beep_waveform(b)
    r = _xcorr_peak_over_median_db(x, b)
    assert 25.0 < r < 45.0  # measured 35.8 dB: a 21-based conversion would move it 1.8 dB
    assert len(detect_xcorr(x, fs=b.fs, beep=b, threshold_db=r - 0.05).onset) == 1
    assert len(detect_xcorr(x, fs=b.fs, beep=b, threshold_db=r + 0.05).onset) == 0


def test_stagger_split_real_part_is_clipped_to_one_before_the_damping_bound():
    """``Re nu`` is kept in ``[NU_RE_MIN, 1]``, then both pole pairs scaled to keep
    ``MIN_DAMPING`` (0.1) of the centre damping: ``|Re sqrt(nu)| = 0.9``."""
    st = StaggerModel.for_burst(fs=192000.0)
    la = math.log(st._a_of_q(8.0, st.f0_hz))
    out = st.theta_clip(np.array([la, st.f0_hz, 1.5, 0.3]))
    re = abs(np.sqrt(complex(1.0, 0.3)).real)  # Re nu clipped to 1 first
    c = (0.9 / re) ** 2
    assert out[2] == pytest.approx(c, rel=1e-12) and out[3] == pytest.approx(0.3 * c, rel=1e-12)
    assert abs(np.sqrt(complex(out[2], out[3])).real) == pytest.approx(0.9, rel=1e-12)
    low = st.theta_clip(np.array([la, st.f0_hz, -9.0, 0.0]))
    assert low[2] == -4.0 and low[3] == 0.0  # NU_RE_MIN, inside the damping bound


def test_fitted_arrivals_are_low_snr_below_three_times_k_detect():
    """``low_snr`` marks each fitted arrival whose SNR is under ``LOW_SNR_FACTOR`` (3)
    times ``k_detect`` (4.5): 13.5. Five windows of falling amplitude straddle it."""
    fs, n = 192000.0, 8000
    rng = np.random.default_rng(5)
    t = Transducer(q=12.0)
    d = burst_waveform(CodedBurst(fs=fs))
    amps = [0.3, 0.15, 0.1, 0.07, 0.05]
    x = np.zeros(len(amps) * n)
    for k, a in enumerate(amps):
        x[k * n + 3000 : k * n + 3000 + len(d)] += a * d
    x = t.apply(t.apply(x, fs=fs), fs=fs) + 0.02 * rng.standard_normal(len(x))
    win = np.array([[k * n, (k + 1) * n] for k in range(len(amps))])
    res = fit_channel(x, fs=fs, template=coded_template(fs=fs),
                      models=(ResonatorModel.for_burst(fs=fs),), windows=win)  # fmt: skip
    a = res.arrivals
    snr = 10.0 ** (a.snr_db / 20.0)  # measured 38.3, 17.6, 12.7, 9.0, 7.9
    flagged = (a.flags & flag_bit("low_snr")) > 0
    assert DEFAULT_K_DETECT == 4.5
    assert len(snr) == 5
    np.testing.assert_array_equal(flagged, snr < 13.5)
    assert flagged.sum() == 3
