"""The transducer fit of coded ultrasonic arrivals (rangekit.detect.pathfit).

The model (the drive through two equal second-order resonators of unknown Q and f0, with
overlapping paths) is checked against rangekit's transducer filters, its derivatives
against finite differences, its fits on noiseless arrivals of every Q, f0 and fractional
onset, on a reflection stronger than the direct path inside the burst, and its sigma
against the scatter of noisy fits. Whether it holds on transducers it does not describe
exactly, on pyroomacoustics rooms and in the ranging rows is tested in
``tests/ranging/test_oneway_unknown_q.py`` and ``tests/experiments/test_oneway_rooms.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.detect.matched import MatchedFilter, coded_template, first_path
from rangekit.detect.pathfit import (
    PathFit,
    ResonatorModel,
    _evaluate,
    fit_arrival,
    pool_fits,
)
from rangekit.signals.barker import CodedBurst, burst_waveform
from rangekit.signals.transducer import Transducer

FS = 192000.0


@pytest.fixture(scope="module")
def model():
    return ResonatorModel.for_burst(CodedBurst(), fs=FS)


def _received(q: float, onsets, amps, n: int = 4000, f0: float = 40000.0, qr=None):
    """The drive at fractional ``onsets`` (band-limited shift), through Tx and Rx."""
    d = burst_waveform(CodedBurst(fs=FS))
    f = np.fft.rfftfreq(n)
    spec = np.fft.rfft(d, n)
    x = np.zeros(n)
    for t0, a in zip(onsets, amps, strict=True):
        x += a * np.fft.irfft(spec * np.exp(-2j * np.pi * f * t0), n)
    t, r = Transducer(f0, q), Transducer(f0, q if qr is None else qr)
    return r.apply(t.apply(x, fs=FS), fs=FS)


@pytest.mark.parametrize("q", [4.0, 12.0, 25.0])
def test_model_waveform_is_the_drive_through_rangekits_transducers(model, q):
    t = Transducer(q=q)
    d = np.concatenate([burst_waveform(CodedBurst(fs=FS)), np.zeros(model.n_fft)])
    ref = t.apply(t.apply(d, fs=FS), fs=FS)[:600]
    w = model.waveform(q, 40000.0, 600)
    assert np.max(np.abs(w - ref)) < 1e-6 * np.max(np.abs(ref))
    # The same waveform as the matched-filter template of those transducers.
    h = coded_template(fs=FS, tx=t, rx=t)
    assert np.max(np.abs(w[: len(h)] - h)) < 1e-6 * np.max(np.abs(h))


def test_model_derivatives_match_finite_differences(model):
    q, f0 = 9.0, 40300.0
    _, dq, df = model.spectrum(q, f0, derivs=True)
    e = 1e-5
    num_q = (model.spectrum(q * math.exp(e), f0) - model.spectrum(q * math.exp(-e), f0)) / (2 * e)
    num_f = (model.spectrum(q, f0 + 0.01) - model.spectrum(q, f0 - 0.01)) / 0.02
    assert np.max(np.abs(dq - num_q)) < 1e-6 * np.max(np.abs(dq))
    assert np.max(np.abs(df - num_f)) < 1e-6 * np.max(np.abs(df))
    # Onset derivative: the model's d/du column against a finite difference of the fit.
    x = _received(q, [100.3], [1.0], n=model.segment)
    st = _evaluate(x, model, np.array([100.3]), np.array([math.log(q), f0]), True)
    st2 = _evaluate(x, model, np.array([100.3 + 1e-4]), np.array([math.log(q), f0]), True)
    st1 = _evaluate(x, model, np.array([100.3 - 1e-4]), np.array([math.log(q), f0]), True)
    fd = (st2.basis - st1.basis) / 2e-4 @ st.a
    assert np.max(np.abs(st.jac[:, 0] - fd)) < 1e-5 * np.max(np.abs(fd))


@pytest.mark.parametrize("q", [4.0, 8.0, 15.0, 20.0, 25.0])
@pytest.mark.parametrize("f0", [39200.0, 40000.0, 40800.0])
@pytest.mark.parametrize("frac", [0.0, 0.37, 0.81])
def test_noiseless_arrival_onset_q_and_f0_recovered(model, q, f0, frac):
    """Whatever the transducers' Q and tuning (MA40S4: 40.0 +- 1.0 kHz), the fit times
    the drive's start: 1e-3 samples (5 nm of sound) and Q, f0 to 1e-4."""
    t0 = 1500.0 + frac
    x = _received(q, [t0], [0.01], f0=f0)
    fit = fit_arrival(x, t0 + 7.0, model=model, sigma=1e-9, q0=4.0)
    assert fit.n_paths == 1
    assert abs(fit.onset - t0) < 1e-3
    assert fit.q == pytest.approx(q, rel=1e-4)
    assert fit.f0_hz == pytest.approx(f0, rel=1e-6)


@pytest.mark.parametrize("q", [8.0, 16.0, 20.0])
@pytest.mark.parametrize("lag_s", [0.2e-3, 0.5e-3, 1.0e-3])
def test_reflection_stronger_than_direct_inside_the_burst_is_resolved(model, q, lag_s):
    """A ceiling bounce 1.5x the direct path 0.2-1 ms later (the burst lasts 0.525 ms):
    both paths fitted, the direct one timed to 0.01 samples."""
    t0 = 1200.25
    x = _received(q, [t0, t0 + lag_s * FS], [1.0, 1.5])
    # The coarse first path of the default (Q 4) template: the direct path where the
    # two are apart, the merged pair where they overlap.
    mf = MatchedFilter(coded_template(fs=FS, tx=Transducer(), rx=Transducer()))
    coarse = first_path(mf.correlate(x), self_response=mf.self_response).lag
    fit = fit_arrival(x, coarse, model=model, sigma=1e-6, q0=4.0)
    assert abs(fit.onset - t0) < 0.01
    assert fit.q == pytest.approx(q, rel=1e-3)
    if lag_s < 0.6e-3:  # a later reflection is cut by the fitted segment's end
        assert abs(fit.onsets[fit.first + 1] - (t0 + lag_s * FS)) < 0.05
        assert fit.amplitudes[fit.first + 1] / fit.amplitudes[fit.first] == pytest.approx(1.5)


@pytest.mark.parametrize(
    ("qt", "qr", "bound_mm"),
    # Measured onset errors (noiseless): -0.24 mm (8, 12), -0.82 mm (10, 20), -0.74 mm
    # (16, 8), -3.5 mm (4, 20): the error grows with the Q ratio (docs/theory/ultrasonic.md).
    [(8.0, 12.0, 0.5), (10.0, 20.0, 1.6), (16.0, 8.0, 1.5), (4.0, 20.0, 7.0)],
)
def test_unequal_transducers_fitted_as_one_equal_pair(model, qt, qr, bound_mm):
    """A Tx and an Rx of different Q (not the model's equal pair): the pair is fitted
    with one Q between the two; the onset moves by well under a millimetre for Q ratios
    up to 2."""
    t0 = 1500.4
    x = _received(qt, [t0], [0.01], qr=qr)
    fit = fit_arrival(x, t0, model=model, sigma=1e-7, q0=4.0)
    assert abs(fit.onset - t0) / FS * 343.0 < bound_mm * 1e-3
    assert min(qt, qr) < fit.q < max(qt, qr)


@pytest.mark.parametrize(("q", "bound_mm"), [(4.0, 0.1), (12.0, 1.0), (20.0, 3.0)])
def test_tx_and_rx_tuned_apart(model, q, bound_mm):
    """A Tx at 39.5 kHz and an Rx at 40.5 kHz (the model has one f0): measured +0.04,
    +0.53, +1.7 mm at Q 4, 12, 20. Both tuned off the carrier alike: exact."""
    t0 = 1500.0
    d = burst_waveform(CodedBurst(fs=FS))
    x = np.zeros(4000)
    x[1500 : 1500 + len(d)] = d
    skew = Transducer(40500.0, q).apply(Transducer(39500.0, q).apply(x, fs=FS), fs=FS)
    fit = fit_arrival(skew, t0, model=model, sigma=1e-7, q0=4.0)
    assert abs(fit.onset - t0) / FS * 343.0 < bound_mm * 1e-3
    same = Transducer(41000.0, q).apply(Transducer(41000.0, q).apply(x, fs=FS), fs=FS)
    fit = fit_arrival(same, t0, model=model, sigma=1e-7, q0=4.0)
    assert abs(fit.onset - t0) < 1e-3 and fit.f0_hz == pytest.approx(41000.0, rel=1e-6)


def test_sigma_matches_the_scatter_of_noisy_fits(model):
    """40 noisy arrivals (Q 12, matched-filter SNR 30 dB): the fit's sigma (Q and f0
    unknown) is within 25 % of the onsets' scatter (measured 0.96), and above the
    known-Q sigma (what not knowing Q costs: measured 1.5x)."""
    rng = np.random.default_rng(4)
    q, t0 = 12.0, 1500.3
    clean = _received(q, [t0], [1.0])
    e = float(clean @ clean)
    noise = math.sqrt(e) / 10 ** (30 / 20)  # sqrt(2E/N0) = 31.6: E / sigma^2 = 1000
    errs, sig, given = [], [], []
    for _ in range(40):
        x = clean + noise * rng.standard_normal(len(clean))
        f = fit_arrival(x, t0, model=model, sigma=noise, q0=4.0)
        errs.append(f.onset - t0)
        sig.append(f.sigma)
        given.append(math.sqrt(f.var_given))
    sd = float(np.std(errs))
    assert 0.75 < np.mean(sig) / sd < 1.25
    assert 1.2 < np.mean(sig) / np.mean(given) < 2.5


def _fake(theta, info, onset=100.0, gain=(-10.0, 0.001), var=0.01) -> PathFit:
    theta = np.asarray(theta, float)
    return PathFit(
        onset=onset,
        sigma=1.0,
        snr=30.0,
        q=math.exp(theta[0]),
        f0_hz=float(theta[1]),
        onsets=np.array([onset]),
        amplitudes=np.array([1.0]),
        first=0,
        misfit=0.0,
        misfit_z=0.0,
        resolution=20.0,
        theta_lin=theta,
        gain=np.asarray(gain, float),
        var_given=var,
        theta_hat=theta,
        info=np.asarray(info, float),
    )


def test_pooling_conditions_each_onset_on_the_pooled_estimate():
    info = np.diag([100.0, 1e-4])  # sd 0.1 in log Q, 100 Hz in f0
    a = _fake([math.log(10.0), 40000.0], info)
    b = _fake([math.log(10.0) + 0.1, 40100.0], info, onset=200.0)
    (pa, pb), pooled = pool_fits([a, b])
    assert pooled
    mean = np.array([math.log(10.0) + 0.05, 40050.0])
    assert pa.theta_hat == pytest.approx(mean)
    assert pa.onset == pytest.approx(100.0 + a.gain @ (mean - a.theta_lin))
    assert pb.onset == pytest.approx(200.0 + b.gain @ (mean - b.theta_lin))
    cov = np.linalg.inv(2 * info)
    assert pa.sigma == pytest.approx(math.sqrt(0.01 + a.gain @ cov @ a.gain))
    assert pa.pooled and pb.pooled


def test_pooling_refuses_transducers_that_disagree_and_drops_outliers():
    info = np.diag([100.0, 1e-4])
    same = [_fake([math.log(10.0) + 0.02 * k, 40000.0], info) for k in range(4)]
    far = _fake([math.log(20.0), 40000.0], info)  # 7 sigma off: left out, conditioned
    out, pooled = pool_fits([*same, far, None])
    assert pooled and out[-1] is None
    assert out[-2].q == pytest.approx(out[0].q)
    assert out[0].q == pytest.approx(10.0 * math.exp(0.03), rel=1e-9)
    two = [_fake([math.log(10.0), 40000.0], info), _fake([math.log(20.0), 40000.0], info)]
    out, pooled = pool_fits(two)  # only two, 7 sigma apart: not one pair of transducers
    assert not pooled and out == two
