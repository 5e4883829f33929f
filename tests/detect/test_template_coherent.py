"""Phase-coherent timing of wideband probes (``rangekit.detect._coherent``).

A wideband probe's arrival is timed at the extremum of the real correlation (the peak of
the received pulse, band-limited by the probe), not at the envelope's peak; the two part
where a transducer's response is not symmetric. Each test checks the detector against
an independent computation (scipy correlation, FFT interpolation), on recordings that
rangekit's simulator did not make. ``docs/theory/probes.md`` (phase-coherent timing).
"""

from __future__ import annotations

import numpy as np
import pytest
from probecorpus import place
from scipy.signal import butter, correlate, hilbert, lfilter, resample

from rangekit.detect._coherent import coherent_lag, coherent_weight, real_side_ratio
from rangekit.detect.template import _unweighted, detect_template
from rangekit.signals.probe import linear_sweep

FS = 48000.0


@pytest.mark.parametrize(
    ("f0", "f1", "fs", "coherent"),
    [
        (200.0, 13000.0, 48000.0, True),
        (20.0, 20000.0, 44100.0, True),
        (2000.0, 12000.0, 48000.0, True),
        (17000.0, 20000.0, 44100.0, False),
        (8000.0, 12000.0, 48000.0, False),
        (2000.0, 6000.0, 48000.0, False),
    ],
)
def test_coherent_timing_only_where_no_cycle_can_slip(f0, f1, fs, coherent):
    """The real self response's largest side extremum: 0.10-0.46 of the main one for
    the wide probes (coherent), 0.66-0.83 for the narrow ones (envelope only)."""
    p = linear_sweep(f0, f1, 0.2 if fs == 48000.0 else 0.1, fs=fs)
    wf = _unweighted(p, fs, 1 << 15, 882)
    assert (wf.coherent_reach > 0) == coherent
    ratio = real_side_ratio(wf.self_resp, max(2 * wf.half_lobe, 8))
    assert (ratio <= 0.5) == coherent


def _fine_peak(r: np.ndarray, i: int, up: int = 64) -> float:
    """Location of the extremum of ``r`` near ``i`` by FFT (band-limited) upsampling."""
    seg = r[i - 64 : i + 64]
    fine = resample(seg, len(seg) * up)
    k = int(np.argmax(np.abs(fine[(64 - 2) * up : (64 + 2) * up]))) + (64 - 2) * up
    return i - 64 + k / up


def test_the_onset_of_a_minimum_phase_transducer_is_its_pulse_peak():
    """A 200 Hz-13 kHz sweep through a causal band-pass (a 2nd-order Butterworth 300 Hz-
    9 kHz, minimum phase): the onset is the peak of the real correlation (scipy, 64x FFT
    interpolation) within 0.05 samples (measured 0.01); the envelope's peak lies 0.7
    samples later (measured), so the two timings are told apart."""
    p = linear_sweep(200.0, 13000.0, 0.2, fs=FS)
    b, a = butter(2, [300.0, 9000.0], btype="bandpass", fs=FS)
    played = lfilter(b, a, np.concatenate([p.samples, np.zeros(400)]))
    start = 3000.3
    n = int(start) + len(played) + 3000
    x = place(played, [start], [1.0], n)
    x += 1e-5 * np.random.default_rng(3).standard_normal(n)
    r = correlate(x, p.samples, mode="full", method="fft")[len(p.samples) - 1 :]
    i = int(round(start)) + int(np.argmax(np.abs(r[int(start) : int(start) + 40])))
    truth = _fine_peak(r, i)
    env = _fine_peak(np.abs(hilbert(r)), i)
    a = detect_template(x, fs=FS, probe=p)
    assert len(a) == 1
    assert abs(a.onset[0] - truth) < 0.05
    assert abs(env - truth) > 0.4  # measured 0.7 samples
    assert abs(a.onset[0] - truth) <= 2 * a.sigma[0]


def test_an_arrival_in_quadrature_keeps_the_envelope_timing():
    """The probe's Hilbert transform (phase -90 degrees: the real part has two equal
    extrema) is timed by the envelope (within 0.05 samples), not at either extremum."""
    p = linear_sweep(20.0, 20000.0, 0.1)
    q = np.imag(hilbert(np.concatenate([np.zeros(2000), p.samples, np.zeros(2000)])))
    x = place(q, [1000.4], [1.0], 12000) + 1e-5 * np.random.default_rng(1).standard_normal(12000)
    a = detect_template(x, fs=44100.0, probe=p)
    assert len(a) == 1
    np.testing.assert_allclose(a.onset, [3000.4], atol=0.05)


def test_coherent_lag_without_an_interior_extremum_or_in_quadrature():
    n = np.arange(64.0)
    env = np.exp(-0.5 * ((n - 32.0) / 3.0) ** 2)
    q = coherent_lag(env * np.exp(0.5j * np.pi), 32.0, 3)  # phase 90 degrees
    assert q is not None and coherent_weight(q[1]) == 0.0
    assert coherent_lag(np.linspace(0.0, 1.0, 64).astype(complex), 32.0, 3) is None
    for sign in (1.0, -1.0):  # either polarity
        t, cos_phase = coherent_lag(sign * env.astype(complex), 32.4, 3)
        assert t == pytest.approx(32.0, abs=1e-3) and cos_phase == pytest.approx(1.0)
        assert coherent_weight(cos_phase) == 1.0


def test_coherent_sigma_matches_the_scatter_in_white_noise():
    """20 Hz-20 kHz at 22 dB: the coherent bound (RMS frequency about 0, Kay 1993 §3.11)
    gives sigma 0.056 samples for a scatter of 0.067 (measured; the envelope's bound was
    0.12). The transducer term (0.45-0.48 samples, the pulse peak's unknown delay behind
    the propagation onset) is a bias common to every play, not scatter: ``sigma_relative``."""
    p = linear_sweep(20.0, 20000.0, 0.1)
    rng = np.random.default_rng(8)
    clean = place(p.samples, [1500.4], [1.0], 1500 + 2 * len(p.samples))
    errs, sig = [], []
    for _ in range(30):
        a = detect_template(clean + 2.0 * rng.standard_normal(len(clean)), fs=44100.0, probe=p)
        errs.append(a.onset[0] - 1500.4)
        sig.append(a.sigma_relative[0])
    ratio = np.std(errs) / np.median(sig)
    assert 0.6 < ratio < 2.0, (np.std(errs), np.median(sig))  # measured 1.2
    assert np.std(errs) < 0.13  # measured 0.067 samples (envelope timing: ~0.11)


@pytest.mark.parametrize("d", [0.0, 0.3, -0.45])
def test_only_the_residuals_odd_part_counts_for_the_pulse_peak(d):
    """A zero-phase (magnitude-only, as air absorption) change of the self response leaves
    a residual that is even about the path and moves neither peak: ``_odd_eps`` is ~0
    (measured <= 9.4e-5, 1e-24 at d = 0) where ``_shape``'s ``eps`` is 0.30; an echo 3
    samples late (0.3x) is partly odd (measured 0.53-0.64 of its ``eps``)."""
    from rangekit.detect.template import _odd_eps, _shape, _shifted

    wf = _unweighted(linear_sweep(200.0, 13000.0, 0.2, fs=FS), FS, 1 << 15, 882)
    R = wf.self_resp
    m = len(R) // 2
    f = np.fft.fftfreq(len(R))
    lowpass = np.fft.ifft(np.fft.fft(R) * np.exp(-((f / 0.15) ** 2)))  # real response
    echo = R + 0.3 * _shifted(R, 3.0)
    alpha = 0.7 * np.exp(1.1j)
    out = {}
    for name, r in (("lowpass", lowpass), ("echo", echo)):
        c = np.zeros(4 * len(R), complex)
        j = 2 * len(R)
        c[j - m : j + m + 1] = alpha * _shifted(r, d)
        out[name] = (_shape(c, j, d, wf, 0.0)[0], _odd_eps(c, j, d, wf, 0.0))
    eps, odd = out["lowpass"]
    assert eps > 0.2  # measured 0.30
    assert odd < 2e-4  # measured <= 9.4e-5 (the reflection's interpolation)
    eps, odd = out["echo"]
    assert 0.3 * eps < odd < 0.9 * eps  # measured 0.53-0.64 of eps
