"""Matched filter for coded bursts: overlap-save, streaming, first path, sub-sample, CRB."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.signal import correlate, freqz, group_delay, hilbert

from rangekit.detect.matched import (
    MatchedFilter,
    _analytic_fir,
    coded_template,
    crb_delay_s,
    detect_matched,
    first_path,
    interp_peak,
    noise_level,
)
from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.signals.barker import CodedBurst, burst_waveform
from rangekit.signals.spectrum import rms_bandwidth_hz
from rangekit.signals.transducer import Transducer, apply_chain
from rangekit.sim._fracdelay import interp_bandlimited

FS = 192000.0
TD = Transducer()


@pytest.fixture(scope="module")
def h_folded():
    return coded_template(CodedBurst(), fs=FS, tx=TD, rx=TD)


@pytest.fixture(scope="module")
def h_drive():
    return coded_template(CodedBurst(), fs=FS)


def _delayed(src: np.ndarray, start: float, n: int) -> np.ndarray:
    """``src`` delayed to the fractional sample ``start`` (band-limited), ``n`` samples."""
    u = np.arange(n, dtype=np.float64) - start
    return interp_bandlimited(np.concatenate([src, np.zeros(64)]), u, half_width=32)


def _peak(env: np.ndarray) -> float:
    i = int(np.argmax(env))
    return i + interp_peak(env, i)[0]


# --- template ---------------------------------------------------------------------------


def test_template_is_drive_through_transducers(h_folded, h_drive):
    d = burst_waveform(CodedBurst())
    np.testing.assert_array_equal(h_drive, d)
    full = apply_chain(np.concatenate([d, np.zeros(2000)]), (TD, TD), fs=FS)
    np.testing.assert_allclose(h_folded, full[: len(h_folded)], rtol=0, atol=1e-15)
    # The cut tail holds less than 60 dB of the energy.
    assert np.sum(full[len(h_folded) :] ** 2) <= 1e-6 * np.sum(full**2) * (1 + 1e-9)


def test_template_refuses_low_rate():
    with pytest.raises(IncompatibleInputError, match="96000 Hz"):
        coded_template(CodedBurst(), fs=96000.0)


# --- overlap-save correlation -----------------------------------------------------------


def _direct(x: np.ndarray, h: np.ndarray) -> np.ndarray:
    """``r[tau] = sum_k x[tau + k] conj(h_a[k])`` by a direct (non-FFT) correlation."""
    g, pre = _analytic_fir(h)
    full = correlate(x.astype(complex), g, mode="full", method="direct")
    return full[len(g) - 1 - pre : len(g) - 1 - pre + len(x)]


@pytest.mark.parametrize("block", [16, 64, 512, 1024, 4096, 1 << 15])
def test_overlap_save_equals_direct_correlation(h_folded, block):
    x = np.random.default_rng(1).standard_normal(5000)
    mf = MatchedFilter(h_folded, block=block)
    assert mf.n_fft >= 4 * mf.n_taps  # blocks smaller than the template are raised
    ref = _direct(x, h_folded)
    got = mf.correlate(x)
    assert got.shape == x.shape and got.dtype == np.complex128
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9 * np.max(np.abs(ref)))


def test_analytic_fir_real_part_is_the_template(h_folded):
    g, pre = _analytic_fir(h_folded)
    np.testing.assert_allclose(g.real[pre : pre + len(h_folded)], h_folded, atol=1e-12)
    assert (
        np.max(np.abs(g.real[:pre])) < 1e-9 and np.max(np.abs(g.real[pre + len(h_folded) :])) < 1e-9
    )
    # Imaginary part = Hilbert transform of the template (long zero padding: negligible wrap).
    n = 1 << 14
    ha = hilbert(np.concatenate([np.zeros(n // 2), h_folded, np.zeros(n // 2 - len(h_folded))]))
    ref = ha[n // 2 - pre : n // 2 - pre + len(g)]
    np.testing.assert_allclose(g, ref, atol=1e-6 * np.max(np.abs(g)))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_stream_equals_correlate(h_folded, seed):
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(7000)
    mf = MatchedFilter(h_folded, block=1024)
    ref = mf.correlate(x)
    sizes = rng.choice([0, 1, 7, 50, 183, 400, 1500, 3000], size=60)
    edges = np.minimum(np.cumsum(np.concatenate([[0], sizes])), len(x))
    chunks = [x[a:b] for a, b in itertools.pairwise(edges)] + [x[edges[-1] :]]
    assert sum(len(c) for c in chunks) == len(x)
    got = np.concatenate(list(mf.stream(iter(chunks))))
    assert got.shape == ref.shape
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9 * np.max(np.abs(ref)))


def test_envelope_matches_hilbert_of_real_correlation(h_folded):
    x = np.random.default_rng(3).standard_normal(6000)
    x[2000 : 2000 + len(h_folded)] += 3 * h_folded
    c = MatchedFilter(h_folded).correlate(x)
    real = correlate(x, h_folded, mode="full", method="direct")[len(h_folded) - 1 :]
    np.testing.assert_allclose(c.real, real, atol=1e-9 * np.max(np.abs(real)))
    env = np.abs(hilbert(real))
    mid = slice(500, 5000)  # away from the edges, where the circular Hilbert wraps
    err = np.max(np.abs(np.abs(c[mid]) - env[mid])) / np.max(env[mid])
    assert err < 1e-3


def test_self_response_centred_on_lag_zero(h_folded):
    mf = MatchedFilter(h_folded)
    r = mf.self_response
    assert len(r) % 2 == 1 and int(np.argmax(np.abs(r))) == len(r) // 2
    assert abs(r[len(r) // 2]) == pytest.approx(mf.energy, rel=1e-9)
    # Barker-7 through two Q = 4 transducers: side lobes about 0.2 of the peak.
    env = np.abs(r) / abs(r[len(r) // 2])
    i = np.flatnonzero((env[1:-1] > env[:-2]) & (env[1:-1] >= env[2:])) + 1
    side = np.sort(env[i])[:-1]
    assert 0.15 < side[-1] < 0.25


def test_matched_filter_validation():
    with pytest.raises(InvalidParameterError, match="template"):
        MatchedFilter(np.zeros(10))
    with pytest.raises(InvalidParameterError, match="template"):
        MatchedFilter(np.ones(1))
    with pytest.raises(InvalidParameterError, match="block"):
        MatchedFilter(np.ones(10), block=8)


# --- sub-sample accuracy and time origin --------------------------------------------------


@pytest.mark.parametrize("folded", [False, True], ids=["bare", "transducers"])
def test_subsample_accuracy_noiseless(folded, h_folded, h_drive):
    # The signal went through what the template holds (both transducers or neither).
    h = h_folded if folded else h_drive
    mf = MatchedFilter(h)
    errs = []
    for frac in np.linspace(0.0, 1.0, 20, endpoint=False):
        start = 1000.0 + frac
        errs.append(_peak(np.abs(mf.correlate(_delayed(h, start, 4000)))) - start)
    assert np.max(np.abs(errs)) < 0.01


def test_time_origin_folded_exact_unfolded_biased_by_group_delay(h_folded, h_drive):
    # Received: the drive through Tx and Rx transducers, drive starting at sample 1000.25.
    start = 1000.25
    rec = _delayed(h_folded, start, 4000)
    t_fold = _peak(np.abs(MatchedFilter(h_folded).correlate(rec)))
    t_bare = _peak(np.abs(MatchedFilter(h_drive).correlate(rec)))
    assert abs(t_fold - start) < 0.01
    bias = t_bare - start
    gd_f0 = 2 * TD.group_delay_s(fs=FS) * FS  # two transducers, at resonance: 16.6 samples
    # The envelope peak moves by the group delay averaged over the band the burst fills
    # (the resonator's delay is largest at f0): the cross spectrum |S|^2 |H| weights it.
    f = np.linspace(1.0, FS / 2 - 1.0, 8000)
    b, a = TD.coefficients(fs=FS)
    _, hf = freqz(b, a, worN=f, fs=FS)
    _, sf = freqz(h_drive, 1, worN=f, fs=FS)
    _, gd = group_delay((b, a), w=f, fs=FS)
    w = np.abs(sf) ** 2 * np.abs(hf) ** 2
    gd_mean = float(2 * gd @ w / w.sum())
    assert 0.6 * gd_f0 < bias < gd_f0
    assert bias == pytest.approx(gd_mean, rel=0.1)
    # As a range: about 2 cm of bias at 343 m/s.
    assert 0.015 < bias / FS * 343.0 < 0.03


# --- first path ---------------------------------------------------------------------------


def _two_paths(h, *, d0, gain, lag, snr_amp, seed, n=6000):
    """Direct path at ``d0`` plus a ``gain`` times stronger one ``lag`` samples later."""
    x = _delayed(h, d0, n) + gain * _delayed(h, d0 + lag, n)
    sigma = math.sqrt(h @ h) / snr_amp  # direct path's matched-filter output SNR
    return x + sigma * np.random.default_rng(seed).standard_normal(n)


@pytest.mark.parametrize(("seed", "snr_amp"), [(0, 30.0), (1, 30.0), (2, 100.0), (3, 100.0)])
def test_first_path_beats_6db_stronger_reflection_1ms_later(h_folded, seed, snr_amp):
    d0, lag = 1200.4, 1e-3 * FS
    x = _two_paths(h_folded, d0=d0, gain=2.0, lag=lag, snr_amp=snr_amp, seed=seed)
    # The envelope is broad (about 4 kHz wide): the delay bound is ~0.4 samples at 30.
    tol = 4 * crb_delay_s(h_folded, fs=FS, noise_sigma=math.sqrt(h_folded @ h_folded) / snr_amp)
    tol *= FS
    a = detect_matched(x, fs=FS, template=h_folded)
    assert len(a) == 1
    assert abs(a.onset[0] - d0) < tol < 2.0
    # The strongest peak alone would have taken the reflection.
    mf = MatchedFilter(h_folded)
    env = np.abs(mf.correlate(x))
    assert abs(np.argmax(env) - (d0 + lag)) <= 2
    p = first_path(mf.correlate(x), self_response=mf.self_response)
    assert abs(p.strongest_lag - (d0 + lag)) < tol / 2 and abs(p.lag - d0) < tol
    assert a.confidence[0] == pytest.approx(0.5, abs=0.1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_first_path_ignores_side_lobes_of_strong_single_path(h_folded, seed):
    d0 = 2000.7
    x = _two_paths(h_folded, d0=d0, gain=0.0, lag=0.0, snr_amp=1000.0, seed=seed)
    mf = MatchedFilter(h_folded)
    c = mf.correlate(x)
    # Default thresholds: the ~0.2 side lobes stay below 0.25 of the peak.
    assert abs(first_path(c, self_response=mf.self_response).lag - d0) < 0.05
    assert abs(detect_matched(x, fs=FS, template=h_folded).onset[0] - d0) < 0.05
    # A permissive relative threshold puts the side lobes above it; the side-lobe
    # cancellation (self response) still rejects them ...
    p = first_path(c, rel_threshold=0.1, self_response=mf.self_response)
    assert abs(p.lag - d0) < 0.05
    # ... and without it the earliest side lobe is (wrongly) taken.
    q = first_path(c, rel_threshold=0.1)
    assert q.lag < d0 - 10


@pytest.mark.parametrize("seed", range(6))
def test_nothing_detected_in_pure_noise(h_folded, seed):
    x = np.random.default_rng(seed).standard_normal(int(0.03 * FS))
    a = detect_matched(x, fs=FS, template=h_folded)
    assert len(a) == 0 and a.onset.shape == (0,)
    assert first_path(MatchedFilter(h_folded).correlate(x)) is None


def test_noise_level_is_rayleigh_scale(h_folded):
    sigma = 0.3
    x = sigma * np.random.default_rng(9).standard_normal(200000)
    mf = MatchedFilter(h_folded)
    # Real and imaginary parts each have variance sigma^2 E: Rayleigh scale sigma sqrt(E).
    assert noise_level(np.abs(mf.correlate(x))) == pytest.approx(
        sigma * math.sqrt(mf.energy), rel=0.03
    )


def test_windows_and_search(h_folded):
    x = np.zeros(9000)
    for s in (500.0, 3500.3, 6100.6):
        x += _delayed(h_folded, s, len(x))
    x += 1e-3 * np.random.default_rng(0).standard_normal(len(x))
    win = np.array([[0, 3000], [3000, 6000], [6000, 9000]])
    a = detect_matched(x, fs=FS, template=h_folded, windows=win)
    np.testing.assert_allclose(a.onset, [500.0, 3500.3, 6100.6], atol=0.01)
    assert a.window.tolist() == [0, 1, 2]
    b = detect_matched(x, fs=FS, template=h_folded, windows=win, search=(400, 600))
    assert b.window.tolist() == [0, 1]  # window 2's path is at lag 100.6, outside
    np.testing.assert_allclose(b.onset, [500.0, 3500.3], atol=0.01)
    # No path in [200, 400): not even the tail of window 2's (local maxima only).
    b = detect_matched(x, fs=FS, template=h_folded, windows=win, search=(200, 400))
    assert len(b) == 0


# --- Cramér–Rao bound -------------------------------------------------------------------------


def _gaussian_tone(fc=40000.0, width_s=60e-6, n=400, phase=0.3):
    t = (np.arange(n) - n / 2) / FS
    return np.exp(-0.5 * (t / width_s) ** 2) * np.cos(2 * math.pi * fc * t + phase)


@pytest.mark.parametrize("phase", [0.0, 0.3, 1.2])
def test_crb_closed_forms_for_symmetric_envelope(phase):
    s = 0.7 * _gaussian_tone(phase=phase)
    sigma = 0.05
    snr = math.sqrt(s @ s) / sigma  # sqrt(2 E / N0), N0 = 2 sigma^2 per sample
    beta = rms_bandwidth_hz(s, fs=FS)
    beta0 = rms_bandwidth_hz(s, fs=FS, about_centre=False)
    nc = crb_delay_s(s, fs=FS, noise_sigma=sigma)
    co = crb_delay_s(s, fs=FS, noise_sigma=sigma, coherent=True)
    assert nc == pytest.approx(1 / (2 * math.pi * beta * snr), rel=1e-3)
    assert co == pytest.approx(1 / (2 * math.pi * beta0 * snr), rel=1e-3)
    # Unknown carrier phase costs a factor of about f_c / beta.
    assert nc / co == pytest.approx(beta0 / beta, rel=1e-3) and nc / co > 10


def test_crb_scaling_and_barker(h_folded):
    a = crb_delay_s(h_folded, fs=FS, noise_sigma=0.1)
    assert crb_delay_s(2 * h_folded, fs=FS, noise_sigma=0.2) == pytest.approx(a, rel=1e-9)
    assert crb_delay_s(h_folded, fs=FS, noise_sigma=0.3) == pytest.approx(3 * a, rel=1e-9)
    snr = math.sqrt(h_folded @ h_folded) / 0.1
    closed = 1 / (2 * math.pi * rms_bandwidth_hz(h_folded, fs=FS) * snr)
    # The asymmetric envelope couples delay and amplitude: the bound can only grow.
    assert closed * (1 - 1e-6) <= a < 1.1 * closed
    with pytest.raises(InvalidParameterError, match="noise_sigma"):
        crb_delay_s(h_folded, fs=FS, noise_sigma=0.0)


def test_monte_carlo_rms_error_near_crb_at_20db(h_folded):
    # 200 windows, a random fractional delay each, matched-filter output SNR 20 dB.
    rng = np.random.default_rng(2024)
    n_trials, per = 200, 1200
    snr_amp = 10.0
    sigma = math.sqrt(h_folded @ h_folded) / snr_amp
    starts = np.arange(n_trials) * per + rng.uniform(300.0, 800.0, n_trials)
    x = np.zeros(n_trials * per)
    for s in starts:
        i0 = int(s) - 40
        x[i0 : i0 + 300] += _delayed(h_folded, s - i0, 300)
    x += sigma * rng.standard_normal(len(x))
    win = np.stack([np.arange(n_trials) * per, np.arange(1, n_trials + 1) * per], axis=1)
    a = detect_matched(x, fs=FS, template=h_folded, windows=win)
    assert len(a) == n_trials
    err = a.onset - starts
    rms = math.sqrt(np.mean(err**2))
    crb = crb_delay_s(h_folded, fs=FS, noise_sigma=sigma) * FS
    assert 0.7 * crb < rms < 1.5 * crb  # ~0.16 samples; the estimator is near-efficient
    # The reported sigma is the same bound from the measured SNR.
    assert np.median(a.sigma) == pytest.approx(crb, rel=0.15)
    assert np.median(a.snr_db) == pytest.approx(20.0, abs=1.0)
