"""The probe detector on measured room impulse responses (dEchorate, ``tests/data``).

Each of the 12 measured responses (48 kHz, a real loudspeaker and microphones, room
setting 011111) is convolved with a probe inside its valid band (100 Hz-14 kHz), placed
0.1 s into a recording (sample 0 of the response = emission), with white noise 30 dB
below the probe's received power (and, where named, a low-frequency shelf 35 dB above the
white level, 50 Hz hum and a 0.1 % DC offset). The first path is compared with the
authors' hand-annotated direct path (good to about one sample).

Measured (seed 5; ``python tests/detect/measure_template.py dechorate``):

==========================  ========  ========  ===========  ==============
probe, noise                |e| <= 1  |e| <= 3  |e| <= 2 sig  max |e|
==========================  ========  ========  ===========  ==============
200 Hz-13 kHz, 30 dB         6 / 12   12 / 12    12 / 12     2.2 samples
200 Hz-13 kHz, 30 dB + LF    2 / 12   12 / 12    12 / 12     3.0 samples
8-12 kHz, 30 dB              2 / 12    2 / 12     4 / 12    12.0 samples
==========================  ========  ========  ===========  ==============

The issue's targets (>= 11 / 12 within one sample wide, 12 / 12 within 3 samples at 8-12
kHz) are not met; the limit is the responses, not the search (``docs/theory/probes.md``):
the direct pulse of the band-limited response itself peaks 1.2-2.2 samples from the
annotation on channels 0, 1, 4, 7 (envelope) whatever the noise, and at 8-12 kHz the
loudspeaker's group delay puts the direct pulse ~4 samples late, split in two humps by
a path 5-8 samples behind it on half the channels.
"""

from __future__ import annotations

import numpy as np
import pytest
from probecorpus import dechorate, lf_noise
from scipy.signal import fftconvolve

from rangekit.detect.template import detect_template
from rangekit.signals.probe import linear_sweep

LEAD_S = 0.1


@pytest.fixture(scope="module")
def rirs():
    return dechorate()


def _recordings(rirs, probe, *, snr_db=30.0, lf=False, seed=5):
    h, fs, direct = rirs
    rng = np.random.default_rng(seed)
    off = int(LEAD_S * fs)
    out = []
    for ch in range(h.shape[1]):
        y = fftconvolve(probe.samples, h[:, ch])
        y = np.concatenate([np.zeros(off), y, np.zeros(off)])
        s = np.sqrt(np.mean(y[off : off + len(probe.samples)] ** 2) / 10 ** (snr_db / 10))
        x = y + s * rng.standard_normal(len(y))
        if lf:
            x += lf_noise(len(y), fs=fs, inband_sigma=s, above_db=35, dc=1e-3, hum_db=40, rng=rng)
        out.append((x, off + direct[ch]))
    return out


def _errors(rirs, probe, *, check=True, **kw):
    fs = rirs[1]
    rows = []
    for x, truth in _recordings(rirs, probe, **kw):
        one = detect_template(x, fs=fs, probe=probe, expected=1)
        assert len(one) == 1
        if check:
            # Without --expected the reverberation is still one arrival, the same one.
            every = detect_template(x, fs=fs, probe=probe)
            assert len(every) == 1 and every.onset[0] == one.onset[0]
        rows.append((one.onset[0] - truth, one.sigma[0], one.flag_names(0)))
    return rows


def test_wide_sweep_first_path_against_the_annotation(rirs):
    p = linear_sweep(200.0, 13000.0, 0.2, fs=rirs[1])
    rows = _errors(rirs, p)
    e = np.array([r[0] for r in rows])
    sig = np.array([r[1] for r in rows])
    assert np.sum(np.abs(e) <= 1.0) >= 5  # measured 6 / 12
    assert np.all(np.abs(e) <= 3.0)  # measured max 2.2 samples
    assert np.sum(np.abs(e) <= 2 * sig) >= 11  # measured 12 / 12
    assert np.all(sig > 0.5)  # the model error: measured 1.0-2.1 samples, never 0
    assert not any("poor_match" in r[2] for r in rows)


def test_wide_sweep_with_low_frequency_noise(rirs):
    p = linear_sweep(200.0, 13000.0, 0.2, fs=rirs[1])
    rows = _errors(rirs, p, lf=True)
    e = np.array([r[0] for r in rows])
    sig = np.array([r[1] for r in rows])
    assert np.all(np.abs(e) <= 3.5)  # measured max 3.0 samples
    assert np.sum(np.abs(e) <= 2 * sig) >= 11  # measured 12 / 12
    assert all("dc_or_lowband" in r[2] for r in rows)
    assert not any("poor_match" in r[2] for r in rows)


def test_4khz_sweep_is_one_arrival_per_channel_and_flags_its_doubts(rirs):
    p = linear_sweep(8000.0, 12000.0, 0.2, fs=rirs[1])
    rows = _errors(rirs, p)
    e = np.array([r[0] for r in rows])
    assert np.all(np.abs(e) <= 13.0)  # measured max 12.0 samples (8.6 cm of path)
    assert np.sum(np.abs(e) <= 3.0) >= 2  # measured 2 / 12 (channels 2 and 8)
    # The channels where a second path splits the direct pulse are flagged.
    amb = np.array(["ambiguous_first_path" in r[2] for r in rows])
    assert amb.sum() >= 5  # measured 6 / 12
    assert np.all(np.abs(e[amb]) >= 6.0)  # measured 7.2-12.0 samples


def test_sigma_is_never_zero_at_very_high_snr(rirs):
    """The issue reported sigma = 0.00000 m at 120 dB SNR; the model-error terms keep it
    at the size of the actual error (measured sigma 0.93-1.72 samples, |e| <= 2 sigma on
    12 / 12 channels, max |e| 2.1 samples)."""
    p = linear_sweep(200.0, 13000.0, 0.2, fs=rirs[1])
    rows = _errors(rirs, p, snr_db=120.0)
    e = np.array([r[0] for r in rows])
    sig = np.array([r[1] for r in rows])
    assert np.all(sig > 0.5)
    assert np.sum(np.abs(e) <= 2 * sig) >= 11
    assert np.all(np.abs(e) <= 3.0)


def test_a_common_noise_spectrum_keeps_the_dispersion_bias_common(rirs):
    """The weighting shifts the onset through the loudspeaker's dispersion: the same
    arrival with and without a low-frequency shelf differs by 0.15-1.1 samples when each
    is weighted by its own noise spectrum (measured), by <= 0.05 samples with one
    spectrum for both (``common_spectra``), as two devices of an exchange should be."""
    from rangekit.detect.matched import common_spectra, welch_spectra

    fs = rirs[1]
    p = linear_sweep(200.0, 13000.0, 0.2, fs=fs)
    own, common = [], []
    for (xc, _), (xl, _) in zip(_recordings(rirs, p), _recordings(rirs, p, lf=True), strict=True):
        a = detect_template(xc, fs=fs, probe=p, expected=1).onset[0]
        b = detect_template(xl, fs=fs, probe=p, expected=1).onset[0]
        n = 1 << 10
        sp = common_spectra([welch_spectra(v, fs=fs, nperseg=n) for v in (xc, xl)])
        a2 = detect_template(xc, fs=fs, probe=p, expected=1, spectra=sp).onset[0]
        b2 = detect_template(xl, fs=fs, probe=p, expected=1, spectra=sp).onset[0]
        own.append(b - a)
        common.append(b2 - a2)
    assert np.max(np.abs(own)) > 0.5  # measured 1.1 samples
    assert np.max(np.abs(common)) < 0.1  # measured 0.05 samples
