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
from pathfit_signals import fake_fit as _fake
from pathfit_signals import received

from rangekit.detect import pathfit as P
from rangekit.detect.matched import MatchedFilter, coded_template, first_path
from rangekit.detect.pathfit import (
    Q_LIMITS,
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


@pytest.mark.parametrize("stages", [1, 3])
def test_model_of_one_or_three_resonators(stages):
    """``stages`` resonators in the path: the drive through a Transducer that many times
    (to 1e-6 of the peak; measured 1.6e-15), derivatives against finite differences."""
    m = ResonatorModel(burst_waveform(CodedBurst(fs=FS)), fs=FS, stages=stages)
    t = Transducer(q=9.0)
    ref = np.concatenate([burst_waveform(CodedBurst(fs=FS)), np.zeros(m.n_fft)])
    for _ in range(stages):
        ref = t.apply(ref, fs=FS)
    w = m.waveform(9.0, 40000.0, 600)
    assert np.max(np.abs(w - ref[:600])) < 1e-6 * np.max(np.abs(ref))
    _, dq, df = m.spectrum(9.0, 40300.0, derivs=True)
    e = 1e-5
    num_q = (m.spectrum(9.0 * math.exp(e), 40300.0) - m.spectrum(9.0 * math.exp(-e), 40300.0)) / (
        2 * e
    )
    num_f = (m.spectrum(9.0, 40300.01) - m.spectrum(9.0, 40299.99)) / 0.02
    assert np.max(np.abs(dq - num_q)) < 1e-6 * np.max(np.abs(dq))
    assert np.max(np.abs(df - num_f)) < 1e-5 * np.max(np.abs(df))


def test_model_segment_and_grid(model):
    """The default segment is ``PRE_S`` + the drive + ``TAIL_S`` (77 + 101 + 154 samples
    at 192 kHz); the FFT grid the smallest power of two holding the segment, the drive
    and ten ring-down time constants of the top Q; a segment shorter than the drive is
    refused; ``for_burst`` caches one model per arguments."""
    n_d = len(model.drive)
    assert model.pre == round(P.PRE_S * FS) == 77 and n_d == 101
    assert model.segment == 77 + n_d + round(P.TAIL_S * FS)
    need = model.segment + n_d + 10.0 * Q_LIMITS[1] / (math.pi * 40000.0) * FS
    assert model.n_fft >= need > model.n_fft / 2 and model.n_fft & (model.n_fft - 1) == 0
    assert [P._next_pow2(n) for n in (1, 16, 17, 1000)] == [16, 16, 32, 1024]
    assert ResonatorModel(model.drive, fs=FS, segment=n_d).segment == n_d
    with pytest.raises(ValueError):
        ResonatorModel(model.drive, fs=FS, segment=n_d - 1)
    assert ResonatorModel.for_burst(CodedBurst(), fs=FS) is model
    assert ResonatorModel.for_burst(CodedBurst(), fs=FS, stages=1).stages == 1


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
    x = received(q, [100.3], [1.0], n=model.segment)
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
    x = received(q, [t0], [0.01], f0=f0)
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
    x = received(q, [t0, t0 + lag_s * FS], [1.0, 1.5])
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
    x = received(qt, [t0], [0.01], qr=qr)
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
    clean = received(q, [t0], [1.0])
    e = float(clean @ clean)
    noise = math.sqrt(e) / 10 ** (30 / 20)  # sqrt(2E/N0) = 31.6: E / sigma^2 = 1000
    errs, sig, given, theta, theta_sd = [], [], [], [], []
    for _ in range(40):
        x = clean + noise * rng.standard_normal(len(clean))
        f = fit_arrival(x, t0, model=model, sigma=noise, q0=4.0)
        errs.append(f.onset - t0)
        sig.append(f.sigma)
        given.append(math.sqrt(f.var_given))
        theta.append(f.theta_hat)
        theta_sd.append(np.sqrt(np.diag(np.linalg.inv(f.info))))
    sd = float(np.std(errs))
    assert 0.75 < np.mean(sig) / sd < 1.25
    assert 1.2 < np.mean(sig) / np.mean(given) < 2.5
    # The information about (log Q, f0): its sds against the estimates' scatter
    # (measured 0.050 / 0.050 in log Q, 55.3 / 53.2 Hz in f0).
    ratio = np.mean(theta_sd, axis=0) / np.std(theta, axis=0)
    assert np.all((0.75 < ratio) & (ratio < 1.25)), ratio


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


# Issue 21 (the mutation check): the fit's documented rules, one by one.


def test_q_beyond_the_limit_is_fitted_at_the_limit(model):
    """Transducers of Q 40, beyond ``Q_LIMITS``' 30: the paths are fitted at Q 30 (the
    limit), and the arrival's own estimate (one Newton step from it) lies between the
    limit and the truth (measured 38.4); within the limits (Q 29) the fit is exact."""
    t0 = 1500.3
    f = fit_arrival(received(40.0, [t0], [0.01]), t0, model=model, sigma=1e-9)
    assert math.exp(f.theta_lin[0]) == pytest.approx(Q_LIMITS[1], rel=1e-12)
    assert Q_LIMITS[1] + 4.0 < f.q < 40.0
    f = fit_arrival(received(29.0, [t0], [0.01]), t0, model=model, sigma=1e-9)
    assert f.q == pytest.approx(29.0, rel=1e-6) and abs(f.onset - t0) < 1e-3


def test_a_held_fit_holds_the_default_q_and_estimates_the_arrivals_own(model):
    """``hold=True`` without ``q0`` holds rangekit's default Q 4: an arrival through Q 4
    transducers is timed exactly. Held at Q 10 or 14 for a Q 12 arrival, the paths are
    fitted at the held Q (onset there 1.10 and -0.81 samples off, measured) and the
    arrival's own estimate of Q, one Gauss-Newton step from it, is within 0.5 of 12
    (measured 11.79, 11.74); the onset conditioned on it is within 0.16 samples (0.081,
    0.075)."""
    t0 = 1500.25
    f = fit_arrival(received(4.0, [t0], [0.01]), t0, model=model, sigma=1e-9, hold=True)
    assert f.q == pytest.approx(4.0, rel=1e-9) and abs(f.onset - t0) < 1e-6
    x = received(12.0, [t0], [0.01])
    for qh, off in ((10.0, 1.10), (14.0, -0.81)):
        f = fit_arrival(x, t0, model=model, sigma=1e-9, hold=True, q0=qh)
        assert math.exp(f.theta_lin[0]) == pytest.approx(qh, rel=1e-12)
        assert f.onsets[f.first] - t0 == pytest.approx(off, abs=0.02)
        assert abs(f.q - 12.0) < 0.5 and abs(f.onset - t0) < 0.16 and not f.pooled


def test_a_direct_path_weaker_than_a_later_reflection(model):
    """The coarse lag at a reflection 0.3 ms (57.6 samples) after a weaker direct path:
    the segment starts ``PRE_S`` (0.4 ms) before the lag, so the direct path is fitted,
    and it is the first path when it clears ``k_noise`` (6) noise scales and
    ``rel_threshold`` (0.25) of the reflection (the rule of ``matched.first_path``):
    at 0.35 of the reflection and an SNR of 9 it is; with ``k_noise`` 10 or
    ``rel_threshold`` 0.4 it is not; at 0.2 of the reflection (SNR 150) it is not."""
    t0, d = 1500.25, 0.3e-3 * FS
    e = model.energy(12.0, 40000.0)
    x = received(12.0, [t0, t0 + d], [0.35, 1.0])
    sigma = 0.35 * math.sqrt(e) / 9.0  # the direct path's SNR: 9
    f = fit_arrival(x, t0 + d, model=model, sigma=sigma)
    assert f.n_paths == 2 and abs(f.onset - t0) < 1e-3
    assert f.snr == pytest.approx(9.0, rel=1e-3)
    assert f.n0 <= t0 - model.pre + d  # read from PRE_S before the lag (or earlier)
    f = fit_arrival(x, t0 + d, model=model, sigma=sigma, k_noise=10.0)
    assert abs(f.onset - (t0 + d)) < 1e-3
    f = fit_arrival(x, t0 + d, model=model, sigma=sigma, rel_threshold=0.4)
    assert abs(f.onset - (t0 + d)) < 1e-3
    x = received(12.0, [t0, t0 + d], [0.2, 1.0])
    f = fit_arrival(x, t0 + d, model=model, sigma=0.2 * math.sqrt(e) / 30.0)
    assert f.n_paths == 2 and abs(f.onset - (t0 + d)) < 1e-3


def test_a_path_at_the_segments_start_is_read_again_from_earlier(model):
    """A coarse lag 0.45 ms late (beyond ``PRE_S``: the path begins 8.75 samples before
    the first segment read): the segment is read again from ``PRE_S`` before the path,
    and the fit is the one from the right lag (the same segment, onset and sigma)."""
    t0 = 1500.25
    x = received(12.0, [t0], [1.0])
    rng = np.random.default_rng(7)
    x = x + 1e-3 * rng.standard_normal(len(x))
    right = fit_arrival(x, t0, model=model, sigma=1e-3)
    late = fit_arrival(x, t0 + 0.45e-3 * FS, model=model, sigma=1e-3)
    assert late.n0 == right.n0 == int(t0) - model.pre
    assert late.onset == pytest.approx(right.onset, abs=1e-9)
    assert late.sigma == pytest.approx(right.sigma, rel=1e-9)


def test_the_first_path_lies_in_lo_hi_within_a_sample(model):
    """Two paths 57.6 samples apart: with ``lo`` up to a sample after the first path it
    is taken (the search's one-sample slack); with ``lo`` 1.5 samples after it, the
    second; with ``hi`` before the second, the first, and a ``[lo, hi)`` that holds neither:
    no fit."""
    t0, d = 1500.25, 0.3e-3 * FS
    x = received(12.0, [t0, t0 + d], [1.0, 0.8])
    for lo, want in ((t0 - 0.5, t0), (t0 + 0.9, t0), (t0 + 1.5, t0 + d)):
        f = fit_arrival(x, t0, model=model, sigma=1e-6, lo=lo)
        assert abs(f.onset - want) < 1e-3, lo - t0
    f = fit_arrival(x, t0, model=model, sigma=1e-6, hi=t0 + d - 0.5)
    assert abs(f.onset - t0) < 1e-3
    assert fit_arrival(x, t0, model=model, sigma=1e-6, lo=t0 + 1.5, hi=t0 + d - 0.5) is None


def test_well_posed_refuses_close_paths_and_outsized_amplitudes(model):
    """``_well_posed``: paths ``MIN_SEP`` resolutions apart or more, and no path stronger
    than ``AMP_GUARD`` (2) times the segment's single-path amplitude scale."""
    th = model.theta_start(12.0)
    res = P._resolution(model, th)
    x = received(12.0, [100.0, 100.0 + 2 * res], [1.0, 1.5], n=model.segment)
    st = _evaluate(x, model, np.array([100.0, 100.0 + 2 * res]), th, False)
    top = float(P._amps(st).max())
    assert top == pytest.approx(1.5, rel=1e-6)
    assert P._well_posed(st, model, top / 1.9)
    assert not P._well_posed(st, model, top / 2.1)
    close = _evaluate(x, model, np.array([100.0, 100.0 + 0.25 * res]), th, False)
    assert not P._well_posed(close, model, 100.0)
    apart = _evaluate(x, model, np.array([100.0, 100.0 + 0.35 * res]), th, False)
    assert P._well_posed(apart, model, 100.0)


@pytest.mark.parametrize("hold", [False, True])
def test_the_fit_does_not_depend_on_the_recordings_scale(model, hold):
    """The same noisy arrival (a reflection 1.5x the direct path 0.05 ms later, inside a
    resolution) in units 1e-4, 1 and 3e4 times apart (int16 counts), the noise sigma
    scaled alike: the same onsets, sigma, Q and misfit (relative 1e-6)."""
    t0 = 1200.25
    rng = np.random.default_rng(2)
    x = received(12.0, [t0, t0 + 0.05e-3 * FS], [1.0, 1.5])
    x = x + 1e-3 * rng.standard_normal(len(x))
    fits = [
        fit_arrival(s * x, t0, model=model, sigma=s * 1e-3, hold=hold, q0=12.0)
        for s in (1e-4, 1.0, 3e4)
    ]
    ref = fits[1]
    assert ref.n_paths == 2 and abs(ref.onset - t0) < 0.1  # measured 0.048
    for f in (fits[0], fits[2]):
        assert f.n_paths == ref.n_paths
        assert f.onsets == pytest.approx(ref.onsets, rel=1e-9, abs=1e-6)
        assert f.sigma == pytest.approx(ref.sigma, rel=1e-6)
        assert f.q == pytest.approx(ref.q, rel=1e-6)
        assert f.misfit_z == pytest.approx(ref.misfit_z, rel=1e-6, abs=1e-6)
        assert f.snr == pytest.approx(ref.snr, rel=1e-6)


def test_three_separated_paths_are_each_fitted(model):
    """A direct path and reflections 0.3 and 0.65 ms later (the second beyond the
    two-path scan's reach: added at the residual's peak): all three fitted, free or with
    Q held, at their onsets and amplitudes."""
    t0 = 1500.25
    on = [t0, t0 + 0.3e-3 * FS, t0 + 0.65e-3 * FS]
    x = received(12.0, on, [1.0, 0.7, 0.5])
    for hold in (False, True):
        f = fit_arrival(x, t0, model=model, sigma=1e-6, hold=hold, q0=12.0)
        assert f.n_paths == 3 and f.first == 0 and f.strongest == 0, hold
        assert f.onsets == pytest.approx(on, abs=1e-3)
        assert f.amplitudes == pytest.approx([1.0, 0.7, 0.5], rel=1e-4)


@pytest.mark.parametrize("q", [4.0, 12.0, 25.0])
def test_energies_resolution_and_matched_filter_in_closed_form(model, q):
    """The model's energy (and the energy of its first ``n - j`` samples) is the sum of
    the waveform's squares; its resolution the lag where the envelope of the waveform's
    analytic autocorrelation (scipy's Hilbert transform, numpy's correlation) first falls
    below one half (13, 24, 38 samples at Q 4, 12, 25); the residual matched filter the
    correlation of the residual with the analytic waveform."""
    from scipy.signal import hilbert

    th = model.theta_start(q)
    w = model.waveform(q, 40000.0)
    e = float(w @ w)
    assert model.energy(q, 40000.0) == pytest.approx(e, rel=1e-12)
    assert P._energy(model, th) == pytest.approx(e, rel=1e-12)
    n = 300
    ref = np.cumsum(w[:n] ** 2)[::-1]
    assert model.energy_inside(q, 40000.0, n) == pytest.approx(ref, rel=1e-12)
    assert P._energy_inside(model, th, n) == pytest.approx(ref, rel=1e-12)
    a = hilbert(w)
    r = np.abs(np.correlate(a, a, "full"))[len(a) - 1 :]
    assert P._resolution(model, th) == float(np.flatnonzero(r < 0.5 * r[0])[0])
    x = received(q, [100.0, 180.0], [1.0, 0.5], n=model.segment)
    spec = np.zeros(model.n_fft, complex)
    spec[: model.n_fft // 2 + 1] = model.spectrum(q, 40000.0)
    sa = np.fft.ifft(spec)  # the analytic waveform
    c = model.residual_mf(x, q, 40000.0)
    assert np.max(np.abs(c - P._residual_mf(model, x, th))) == 0.0
    for j in (0, 57, 100, 180, 250):
        want = np.sum(x * np.conj(np.roll(sa, j)[: len(x)]))
        assert c[j] == pytest.approx(want, rel=1e-9, abs=1e-12 * abs(c).max())


def test_theta_limits_variants_and_scan(model):
    """``theta_clip`` keeps Q in ``Q_LIMITS`` and f0 within ``F0_LIMIT`` (10 %) of the
    nominal; the two-path scan's broader models are Q / 2, Q / sqrt 2 and Q itself
    (clipped at the lower limit); the free fit's scan is ``SCAN_Q`` at the given f0."""
    lq, f = model.theta_clip(np.array([10.0, 50000.0]))
    assert math.exp(lq) == pytest.approx(Q_LIMITS[1]) and f == pytest.approx(44000.0)
    lq, f = model.theta_clip(np.array([-1.0, 1000.0]))
    assert math.exp(lq) == pytest.approx(Q_LIMITS[0]) and f == pytest.approx(36000.0)
    qs = [model.q_f0(t)[0] for t in model.theta_variants(model.theta_start(12.0))]
    assert qs == pytest.approx([6.0, 12.0 / math.sqrt(2.0), 12.0])
    qs = [model.q_f0(t)[0] for t in model.theta_variants(model.theta_start(1.5))]
    assert qs == pytest.approx([1.0, 1.5 / math.sqrt(2.0), 1.5])
    scan = np.array([model.q_f0(t) for t in model.scan_thetas(40500.0)])
    assert scan[:, 0] == pytest.approx(P.SCAN_Q) and np.all(scan[:, 1] == 40500.0)


def test_no_fit_without_an_arrival_or_without_room_for_the_drive(model):
    """Noise alone (free or held) and a lag too near the recording's end for the drive:
    no fit; a sigma of 0 is read as 1e-12 of the recording's peak."""
    rng = np.random.default_rng(5)
    noise = 1e-3 * rng.standard_normal(4000)
    assert fit_arrival(noise, 1500.0, model=model, sigma=1e-3) is None
    assert fit_arrival(noise, 1500.0, model=model, sigma=1e-3, hold=True) is None
    x = received(12.0, [1500.25], [1.0])
    assert fit_arrival(x[:1550], 1540.0, model=model, sigma=1e-6) is None
    f0 = fit_arrival(x, 1500.25, model=model, sigma=0.0)
    f1 = fit_arrival(x, 1500.25, model=model, sigma=1e-12 * float(np.max(np.abs(x))))
    assert f0.onset == f1.onset and f0.sigma == f1.sigma


@pytest.mark.parametrize("hold", [False, True])
def test_chi2_degrees_of_freedom_and_misfit_z(model, hold):
    """In noise: ``chi2`` is the residual's sum of squares over sigma^2, within 4 of its
    standard deviations ``sqrt(2 dof)`` of the degrees of freedom ``dof = n - 3 k - 2``
    (measured |misfit_z| 0.05-1.83); ``misfit_z`` is that z; ``n_par`` counts 3 per path
    and the 2 transducer parameters unless they were held."""
    rng = np.random.default_rng(11)
    x = received(12.0, [1500.25, 1500.25 + 0.3e-3 * FS], [1.0, 0.6])
    for _ in range(3):
        y = x + 1e-3 * rng.standard_normal(len(x))
        f = fit_arrival(y, 1500.25, model=model, sigma=1e-3, hold=hold, q0=12.0)
        k = f.n_paths
        dof = model.segment - 3 * k - 2
        assert k == 2 and f.n_par == 3 * k + (0 if hold else 2)
        assert f.misfit_z == pytest.approx((f.chi2 - dof) / math.sqrt(2.0 * dof), rel=1e-9)
        assert abs(f.misfit_z) < 4.0


def test_a_further_path_must_clear_k_add_noise_scales(model):
    """A reflection 0.55 ms after the direct path (beyond the two-path scan), 0.3 of its
    amplitude, whose matched-filter peak stands 5 or 7 noise scales up (the noise sigma
    stated, the recording noiseless): fitted at 7 (above ``K_ADD`` = 6), not at 5, free
    or held. Left unfitted, it pulls the direct path's onset by 0.64 samples (free; 0.49
    held; measured) where it overlaps its tail."""
    t0, a = 1500.3, 0.3
    e = model.energy(12.0, 40000.0)
    x = received(12.0, [t0, t0 + 0.55e-3 * FS], [1.0, a])
    for hold in (False, True):
        f = fit_arrival(x, t0, model=model, sigma=a * math.sqrt(e) / 7.0, hold=hold, q0=12.0)
        assert f.n_paths == 2 and abs(f.onset - t0) < 1e-3, hold
        f = fit_arrival(x, t0, model=model, sigma=a * math.sqrt(e) / 5.0, hold=hold, q0=12.0)
        assert f.n_paths == 1 and 0.3 < f.onset - t0 < 1.0, hold


def test_a_fit_stopped_at_once_is_completed_by_the_newton_step(model):
    """With ``tol`` 1e6 noise variances Levenberg-Marquardt stops before its first step;
    the summary's one Newton step in the onsets brings the onset from the scan's
    parabolic vertex to within 0.005 samples of the truth (measured 0.0025)."""
    t0 = 1500.3
    x = received(12.0, [t0], [0.01])
    f = fit_arrival(x, t0, model=model, sigma=1e-6, tol=1e6)
    assert abs(f.onset - t0) < 0.005


def test_misfit_z_is_the_residual_chi2_in_standard_deviations(model):
    """``_misfit_z`` (the held fit's two-path trigger): the residual's chi-square over
    its ``n - n_par`` degrees of freedom, in standard deviations ``sqrt(2 dof)``; at the
    truth in noise about 0 (within 4: measured 0.52)."""
    rng = np.random.default_rng(9)
    th = model.theta_start(12.0)
    x = received(12.0, [100.3], [1.0], n=model.segment)
    x = x + 1e-3 * rng.standard_normal(len(x))
    st = _evaluate(x, model, np.array([100.3]), th, False)
    n = len(x)
    for n_par in (3, 5):
        dof = n - n_par
        want = (float(st.r @ st.r) / 1e-6 - dof) / math.sqrt(2.0 * dof)
        assert P._misfit_z(st, 1e-3, n_par) == pytest.approx(want, rel=1e-12)
    assert abs(P._misfit_z(st, 1e-3, 3)) < 4.0


def test_interp_next_to_the_ends():
    """The path scan's parabolic vertex at the second and the second-last lag (each has a
    neighbour on either side); only the end lags are returned as they are."""
    z = -((np.arange(20.0) - 1.2) ** 2)
    assert P._interp(z, 1) == pytest.approx(1.2, abs=1e-12)
    z = -((np.arange(20.0) - 17.7) ** 2)
    assert P._interp(z, 18) == pytest.approx(17.7, abs=1e-12)


def test_two_path_scan_is_the_least_squares_pair(model):
    """``_scan_two``'s closed form (the explained energy ``2 c^H G^-1 c`` of two paths at
    integer onsets) against least squares: the pair it returns explains the energy it
    states (rel 1e-4; measured 1.1e-5, the waveform's tail at the grid's end) and no
    pair of a grid around it explains more; noiseless, it is the true pair."""
    th = model.theta_start(12.0)
    x = received(12.0, [100.0, 115.0], [1.0, 0.7], n=model.segment)
    rng = np.random.default_rng(3)

    def explained(y, u1, u2):
        st = _evaluate(y, model, np.array([float(u1), float(u2)]), th, False)
        return float(np.sum((st.basis @ st.a) ** 2))

    for noise in (0.0, 0.05):
        y = x + noise * rng.standard_normal(len(x))
        pv, u1, u2, _ = P._scan_two(y, model, [th], around=107.0)
        assert pv == pytest.approx(explained(y, u1, u2), rel=1e-4)
        if noise == 0.0:
            assert (u1, u2) == (100, 115)
        grid = max(explained(y, a, a + d) for a in range(95, 111) for d in range(7, 31))
        assert pv >= grid * (1 - 1e-4)


def test_pooling_passes_uninformative_fits_through_and_obeys_max_chi2():
    """A fit without information about ``theta`` (zero ``info``) is returned as it is
    while the others are pooled; four fits scattered by 1.5 sigma (chi2 per degree of
    freedom 1.5) are pooled at the default ``max_chi2`` 4 and not at 1."""
    info = np.diag([100.0, 1e-4])
    fits = [_fake([math.log(10.0) + 0.15 * s, 40000.0], info) for s in (-1, 1, -1, 1)]
    blind = _fake([math.log(12.0), 40000.0], np.zeros((2, 2)))
    out, pooled = pool_fits([*fits, blind])
    assert pooled and out[-1] is blind and all(f.pooled for f in out[:-1])
    assert out[0].q == pytest.approx(10.0, rel=1e-9)
    dev = np.array([[0.15 * s, 0.0] for s in (-1, 1, -1, 1)])
    chi2_dof = float(np.einsum("ni,ij,nj->", dev, info, dev)) / (2 * 3)
    assert chi2_dof == pytest.approx(1.5, rel=1e-9)
    out, pooled = pool_fits(fits, max_chi2=1.0)
    assert not pooled and out == fits


def test_gain_is_the_onsets_derivative_along_the_profile(model):
    """``gain``: the onset's derivative by ``theta`` with the paths refitted (the fits
    held at ``theta`` +- a small step, central differences: within 1e-3 relative;
    measured 1.1e-5 in log Q, 1.7e-5 in f0)."""
    t0 = 1500.3
    x = received(12.0, [t0], [0.01])

    def onset(q, f0=40000.0):
        f = fit_arrival(x, t0, model=model, sigma=1e-6, hold=True, q0=q, f0=f0)
        return f.onsets[f.first], f.gain

    _, gain = onset(12.0)
    d_q = (onset(12.0 * math.exp(0.01))[0] - onset(12.0 * math.exp(-0.01))[0]) / 0.02
    d_f = (onset(12.0, 40020.0)[0] - onset(12.0, 39980.0)[0]) / 40.0
    assert d_q == pytest.approx(gain[0], rel=1e-3)
    assert d_f == pytest.approx(gain[1], rel=1e-3)


def test_pooling_keeps_the_fits_within_4_sigma():
    """Nine fits at Q 10 and one 4.5 sigma off in log Q (Mahalanobis distance to the
    pooled value: 4.05 with it, 4.5 without): left out of the mean, which is the nine's;
    one 3 sigma off instead is kept (the mean moves to 0.3 sigma)."""
    info = np.diag([100.0, 1e-4])  # sd 0.1 in log Q
    nine = [_fake([math.log(10.0), 40000.0], info) for _ in range(9)]
    out, pooled = pool_fits([*nine, _fake([math.log(10.0) + 0.45, 40000.0], info)])
    assert pooled and out[0].q == pytest.approx(10.0, rel=1e-12)
    out, pooled = pool_fits([*nine, _fake([math.log(10.0) + 0.3, 40000.0], info)])
    assert pooled and out[0].q == pytest.approx(10.0 * math.exp(0.03), rel=1e-9)


@pytest.mark.parametrize("hold", [False, True])
def test_the_fit_does_not_depend_on_the_drives_scale(hold):
    """Models built from the drive in units 1e-4, 1 and 1e4 apart fit the same noisy
    arrival (a reflection 1.5x the direct path 0.05 ms later, resolved by the two-path
    scan) alike: the same onsets, sigma and Q, the amplitudes in inverse units."""
    t0 = 1200.25
    rng = np.random.default_rng(2)
    x = received(12.0, [t0, t0 + 0.05e-3 * FS], [1.0, 1.5])
    x = x + 1e-3 * rng.standard_normal(len(x))
    d = burst_waveform(CodedBurst(fs=FS))
    fits = {
        s: fit_arrival(x, t0, model=ResonatorModel(s * d, fs=FS), sigma=1e-3, hold=hold, q0=12.0)
        for s in (1e-4, 1.0, 1e4)
    }
    ref = fits[1.0]
    assert ref.n_paths == 2 and abs(ref.onset - t0) < 0.1  # measured 0.048
    for s, f in fits.items():
        assert f.n_paths == 2, s
        assert f.onsets == pytest.approx(ref.onsets, rel=1e-9, abs=1e-6)
        assert f.sigma == pytest.approx(ref.sigma, rel=1e-6)
        assert f.q == pytest.approx(ref.q, rel=1e-6)
        assert s * f.amplitudes == pytest.approx(ref.amplitudes, rel=1e-6)
