"""The probe detector on measured room impulse responses (dEchorate, ``tests/data``).

Each of the 12 measured responses (48 kHz, a real loudspeaker and microphones, room
setting 011111) is convolved with a probe inside its valid band (100 Hz-14 kHz), placed
0.1 s into a recording (sample 0 of the response = emission), with white noise 30 dB
below the probe's received power (and, where named, a low-frequency shelf 35 dB above the
white level, 50 Hz hum and a 0.1 % DC offset). The first path is compared with the
authors' hand-annotated direct path (good to about one sample) and with the response's
own peak (the peak of ``|h|``, FFT-interpolated: the convention the authors' annotation
tool picks, ``dechorate_post2_rir_annotation.py`` of their repository).

Measured (seed 5; ``python tests/detect/measure_template.py dechorate``):

==========================  ========  ========  ===========  ==============
probe, noise                |e| <= 1  |e| <= 3  |e| <= 2 sig  max |e|
==========================  ========  ========  ===========  ==============
200 Hz-13 kHz, 30 dB         9 / 12   12 / 12    12 / 12     1.7 samples
200 Hz-13 kHz, 30 dB + LF    5 / 12   12 / 12    12 / 12     2.6 samples
200 Hz-13 kHz, 120 dB        8 / 12   12 / 12    12 / 12     1.7 samples
8-12 kHz, 30 dB              2 / 12    2 / 12    11 / 12    11.9 samples
==========================  ========  ========  ===========  ==============

(8-12 kHz: 7 / 12 within 2 sigma before sigma held the transducers' in-band group
delay; now the one beyond, channel 4, is flagged ``ambiguous_first_path``.)

(Envelope timing, before the phase-coherent timing of wide probes: 6 / 12, 2 / 12 and
7 / 12 within a sample, max 2.2, 3.0, 2.1.) The issue's targets (>= 11 / 12 within one
sample wide, 12 / 12 within 3 samples at 8-12 kHz) are not met, and no timing rule on
this data can meet the first: the response's own peak is itself 1.2-1.8 samples from the
annotation on channels 0, 4 and 7 (8 / 12 within a sample), and the wide sweep's onset
is that peak within 0.13 samples on 11 channels (0.38 on one). At 8-12 kHz the transducers' group
delay in that band puts the direct pulse 3.8-5.2 samples after the broadband peak
(channels 1, 3, 7, 9), and a path 5-8 samples behind it splits it into two humps on half
the channels (``docs/theory/probes.md``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from probecorpus import dechorate, lf_noise
from scipy.signal import fftconvolve

from rangekit.detect.template import detect_template
from rangekit.signals.probe import linear_sweep

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perturb import worse  # tests/perturb.py: errors x $RANGEKIT_TEST_WORSE

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
        rows.append(
            (one.onset[0] - truth, one.sigma[0], one.flag_names(0), one.sigma_transducer[0])
        )
    return rows


def own_peaks(rirs, up: int = 16) -> np.ndarray:
    """The peak of each response's ``|h|`` within 3 samples of the annotation, relative to
    it (FFT interpolation by ``up``): what the annotation marks, measured on this data."""
    from scipy.signal import resample

    h, _, direct = rirs
    out = []
    for ch in range(h.shape[1]):
        i = int(round(direct[ch]))
        fine = np.abs(resample(h[i - 64 : i + 64, ch], 128 * up))
        k = (64 - 3) * up + int(np.argmax(fine[(64 - 3) * up : (64 + 3) * up]))
        out.append(i - 64 + k / up - direct[ch])
    return np.array(out)


def test_wide_sweep_first_path_against_the_annotation(rirs):
    p = linear_sweep(200.0, 13000.0, 0.2, fs=rirs[1])
    rows = _errors(rirs, p)
    e = worse(np.array([r[0] for r in rows]))
    sig = np.array([r[1] for r in rows])
    assert np.sum(np.abs(e) <= 1.0) >= 8  # measured 9 / 12 (envelope timing: 6 / 12)
    assert np.all(np.abs(e) <= 2.5)  # measured max 1.7 samples (envelope: 2.2)
    assert np.sum(np.abs(e) <= 2 * sig) >= 11  # measured 11 / 12 (channel 7 at 2.38, flagged)
    assert np.all(sig > 0.5)  # the model error: measured 0.69-1.88 samples, never 0
    assert not any("poor_match" in r[2] for r in rows)


def test_wide_sweep_onset_is_the_responses_own_peak(rirs):
    """The phase-coherent onset is the measured response's own peak (measured within 0.13
    samples on 11 channels; 0.38 on channel 10, whose arrival is 37 degrees off the
    template's phase, so its onset is weighted 0.83 / 0.17 between the pulse's peak and
    the envelope's; the envelope's peak alone was up to 1.7 samples from it); the
    annotation is not that peak on channels 0, 4 and 7 (1.2-1.8 samples off it), so no
    timing of this data is within a sample of the annotation there."""
    p = linear_sweep(200.0, 13000.0, 0.2, fs=rirs[1])
    e = np.array([r[0] for r in _errors(rirs, p, check=False)])
    own = own_peaks(rirs)
    d = np.abs(worse(e - own))  # the onset against the response's own peak
    assert np.sum(d <= 0.25) >= 11  # measured 11 / 12 within 0.13 samples
    assert np.all(d <= 0.6)  # measured max 0.38 samples (channel 10)
    assert np.sum(np.abs(own) <= 1.0) == 8  # the data: channels 0, 1, 4, 7 beyond
    assert np.all(np.abs(own[[0, 4, 7]]) > 1.1)  # measured 1.22, 1.35, 1.76


def test_wide_sweep_with_low_frequency_noise(rirs):
    p = linear_sweep(200.0, 13000.0, 0.2, fs=rirs[1])
    rows = _errors(rirs, p, lf=True)
    e = worse(np.array([r[0] for r in rows]))
    sig = np.array([r[1] for r in rows])
    assert np.all(np.abs(e) <= 3.5)  # measured max 2.6 samples (2026-12-03; was 3.0)
    assert np.sum(np.abs(e) <= 1.0) >= 3  # measured 5 / 12 (envelope timing: 2 / 12)
    assert np.sum(np.abs(e) <= 2 * sig) >= 11  # measured 12 / 12
    assert all("dc_or_lowband" in r[2] for r in rows)
    assert not any("poor_match" in r[2] for r in rows)


def test_4khz_sweep_is_one_arrival_per_channel_and_flags_its_doubts(rirs):
    p = linear_sweep(8000.0, 12000.0, 0.2, fs=rirs[1])
    rows = _errors(rirs, p)
    e = worse(np.array([r[0] for r in rows]))
    assert np.all(np.abs(e) <= 13.0)  # measured max 12.0 samples (8.6 cm of path)
    assert np.sum(np.abs(e) <= 3.0) >= 2  # measured 2 / 12 (channels 2 and 8)
    # The channels where a second path splits the direct pulse are flagged.
    amb = np.array(["ambiguous_first_path" in r[2] for r in rows])
    assert amb.sum() >= 5  # measured 6 / 12
    assert np.all(np.abs(e[amb]) >= 5.0)  # measured 5.6-11.9 samples (7.2-12.0 before the
    # side-lobe pull of later paths was taken off)


def test_4khz_sweep_is_within_2_sigma_or_flagged(rirs):
    """The transducers' group delay at 8-12 kHz puts the unflagged channels 1, 3, 7, 9
    3.8-5.2 samples late (measured), which sigma must cover: the transducer term
    (transducer_sigma, +-6 dB of ripple) is 4.9-5.2 samples (measured), |e| / sigma of the
    unflagged channels 0.00-0.99 (measured; before the term 3.0-4.2 on four of them)."""
    from rangekit.types import INFO_FLAGS

    p = linear_sweep(8000.0, 12000.0, 0.2, fs=rirs[1])
    rows = _errors(rirs, p, check=False)
    e = worse(np.array([r[0] for r in rows]))
    sig = np.array([r[1] for r in rows])
    td = np.array([r[3] for r in rows])
    doubt = np.array([bool(set(r[2]) - INFO_FLAGS) for r in rows])
    assert not np.any((np.abs(e) > 2 * sig) & ~doubt)  # every channel: within 2 sigma or flagged
    assert np.all((td > 4.0) & (td < 6.5))  # measured 4.88-5.22 samples
    z = np.abs(e[~doubt]) / sig[~doubt]
    assert np.max(z) > 0.5  # not 10x cautious: measured max 0.99 (channel 1)
    assert np.sum(np.abs(e) <= 2 * sig) >= 10  # measured 11 / 12 (channel 4 flagged)


def test_wide_sweep_sigma_holds_the_pulse_peaks_transducer_term(rirs):
    """The phase-coherent onset of a wide sweep is the pulse's peak, whose delay behind the
    propagation onset is unknown within the transducer term ``A / (2 pi F_w)`` (measured
    0.67-0.84 samples; 0.84 on channel 10, phase weight 0.83, which blends in the
    envelope's 1.58). That term and the shape term read with the real part's curvature
    ``F_w`` on the residual's reflection-odd part (the even part moves neither peak) give
    sigma 0.69-1.88 samples (0.83-2.10 with the whole residual, 1.04-2.67 with ``beta_w``
    and no term), every channel within 2 sigma or flagged, 11 / 12 within 2 sigma
    (channel 7 at 2.38, flagged: its response's own peak is 1.76 samples off the
    annotation, 2.4x the term) and |e| / sigma a median of 0.62 (0.45 with the whole
    residual, 0.35 before the term)."""
    from rangekit.types import INFO_FLAGS

    p = linear_sweep(200.0, 13000.0, 0.2, fs=rirs[1])
    rows = _errors(rirs, p, check=False)
    e = worse(np.array([r[0] for r in rows]))
    sig = np.array([r[1] for r in rows])
    td = np.array([r[3] for r in rows])
    doubt = np.array([bool(set(r[2]) - INFO_FLAGS) for r in rows])
    assert np.all((td > 0.5) & (td < 1.0))  # measured 0.67-0.84 samples
    assert not np.any((np.abs(e) > 2 * sig) & ~doubt)  # every channel: within 2 sigma or flagged
    assert np.sum(np.abs(e) <= 2 * sig) >= 11  # measured 11 / 12 (channel 7, flagged, 2.38)
    assert 0.31 < np.median(np.abs(e) / sig) < 1.25  # measured 0.62


def test_sigma_is_never_zero_at_very_high_snr(rirs):
    """The issue reported sigma = 0.00000 m at 120 dB SNR; the model-error terms keep it
    at the size of the actual error (measured sigma 0.78-2.15 samples, the transducer term
    of the pulse peak 0.75-1.52 of it; |e| <= 2 sigma on 11 / 12 channels, channel 7 at
    2.06, flagged (12 / 12, max 1.67, before the coherent shape share took the residual's
    odd part); max |e| 1.7 samples)."""
    p = linear_sweep(200.0, 13000.0, 0.2, fs=rirs[1])
    rows = _errors(rirs, p, snr_db=120.0)
    e = worse(np.array([r[0] for r in rows]))
    sig = np.array([r[1] for r in rows])
    assert np.all(sig > 0.5)
    assert np.sum(np.abs(e) <= 2 * sig) >= 11
    assert np.all(np.abs(e) <= 3.0)


def test_a_common_noise_spectrum_keeps_the_dispersion_bias_common(rirs):
    """The weighting shifts the onset through the loudspeaker's dispersion: the same
    arrival with and without a low-frequency shelf differs by up to 2.4 samples when each
    is weighted by its own noise spectrum (measured), by <= 0.084 samples with one
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
    assert np.max(np.abs(own)) > 0.5  # measured 2.4 samples (envelope timing: 1.1)
    common = worse(np.array(common))  # two devices' onsets should differ by 0
    assert np.max(np.abs(common)) < 0.15  # measured 0.084 samples (envelope: 0.053)
