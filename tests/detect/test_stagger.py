"""The stagger-tuned transducer model and the fit that chooses it (rangekit.detect.stagger,
rangekit.detect.fitted).

The model is checked against closed forms: its derivatives against finite differences,
its spectrum against the product of two digital peaking filters (any such product is one
of its points), a Butterworth band-pass and stagger-tuned resonators fitted exactly on
noiseless arrivals. The model choice is checked on windows through a Butterworth
band-pass (chosen, the ranges unbiased) and through rangekit's resonator (not chosen).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.detect.fitted import detect_fitted
from rangekit.detect.matched import coded_template
from rangekit.detect.pathfit import ResonatorModel, fit_arrival
from rangekit.detect.stagger import StaggerModel, group_delay_samples
from rangekit.signals.barker import CodedBurst, burst_waveform
from rangekit.signals.transducer import BandpassTransducer, CoupledTransducer, Transducer

FS = 192000.0


@pytest.fixture(scope="module")
def model():
    return StaggerModel.for_burst(CodedBurst(), fs=FS)


def test_derivatives_match_finite_differences(model):
    th = np.array([math.log(0.05), 40300.0, -0.7, 0.2])
    _, ds = model.spectrum_t(th, derivs=True)
    for i in range(4):
        e = 1e-6 * max(1.0, abs(th[i]))
        tp, tm = th.copy(), th.copy()
        tp[i] += e
        tm[i] -= e
        num = (model.spectrum_t(tp) - model.spectrum_t(tm)) / (2 * e)
        assert np.max(np.abs(ds[i] - num)) < 1e-6 * np.max(np.abs(ds[i]))


def test_two_peaking_filters_are_one_point_of_the_model(model):
    """Stagger-tuned resonators (39 and 41.5 kHz, Q 9 and 14) per element: the model's
    waveform at the theta of their poles is theirs, up to the gain."""
    ta, tb = Transducer(39000.0, 9.0), Transducer(41500.0, 14.0)
    poles = []
    for t in (ta, tb):
        _, a = t.coefficients(fs=FS)
        p = np.roots(a)
        poles.append(np.log(p[np.argmax(p.imag)]))
    mu, r = 0.5 * (poles[0] + poles[1]), 0.5 * (poles[0] - poles[1])
    a = -mu.real
    nu = r * r / (a * a)
    th = np.array([math.log(a), mu.imag * FS / (2 * math.pi), nu.real, nu.imag])
    d = np.concatenate([burst_waveform(CodedBurst(fs=FS)), np.zeros(model.n_fft)])
    ref = d
    for _ in range(2):
        ref = tb.apply(ta.apply(ref, fs=FS), fs=FS)
    s = model.spectrum_t(th)
    w = model._shifted(s[None, :], np.zeros(1), 600)[0].real
    ref = ref[:600]
    g = float(ref @ w) / float(w @ w)
    assert np.max(np.abs(g * w - ref)) < 1e-9 * np.max(np.abs(ref))


@pytest.mark.parametrize("kind", [BandpassTransducer, CoupledTransducer])
@pytest.mark.parametrize("q", [4.0, 12.0, 20.0])
def test_noiseless_fit_of_four_pole_pairs_is_exact(model, kind, q):
    """A 4th-order Butterworth band-pass or two stagger-tuned resonators per element: the
    onset to 1e-3 samples (where the resonator model is 15-65 mm late)."""
    t = kind(q=q)
    x = np.zeros(4000)
    x[1500:1601] = burst_waveform(CodedBurst(fs=FS))
    x = t.apply(t.apply(x, fs=FS), fs=FS)
    f = fit_arrival(x, 1530.0, model=model, sigma=1e-7, theta=model.theta_start(q), start=[1500])
    assert f.n_paths == 1
    assert abs(f.onset - 1500.0) < 1e-3


def test_group_delay_of_the_models_is_the_filters(model):
    r = ResonatorModel.for_burst(CodedBurst(), fs=FS)
    assert group_delay_samples(r, r.theta_start(8.0)) == pytest.approx(
        2 * Transducer(q=8.0).group_delay_s(fs=FS) * FS, rel=2e-3
    )
    assert group_delay_samples(model, model.theta_start(8.0)) == pytest.approx(
        2 * BandpassTransducer(q=8.0).group_delay_s(fs=FS) * FS, rel=2e-2
    )


def _windows(t, n_win=8, snr_amp=0.01, seed=1):
    rng = np.random.default_rng(seed)
    n = 8000
    x = np.zeros(n_win * n)
    t0 = 3000.0 + np.arange(n_win) * n
    for k in range(n_win):
        x[int(t0[k]) : int(t0[k]) + 101] = burst_waveform(CodedBurst(fs=FS))
    x = t.apply(t.apply(x, fs=FS), fs=FS) + snr_amp * rng.standard_normal(len(x))
    return x, t0, np.array([[k * n, (k + 1) * n] for k in range(n_win)])


@pytest.mark.parametrize(
    ("t", "bound_samples"),
    # Measured: bandpass Q 12 mean error +0.22 samples (the resonator fit alone: +12.9),
    # resonator Q 12 +0.02 samples (the stagger model not chosen).
    [(BandpassTransducer(q=12.0), 0.45), (Transducer(q=12.0), 0.05)],
)
def test_the_fit_chooses_the_model_the_data_favour(t, bound_samples):
    x, t0, win = _windows(t)
    models = (ResonatorModel.for_burst(fs=FS), StaggerModel.for_burst(fs=FS))
    arr = detect_fitted(x, fs=FS, template=coded_template(fs=FS), models=models, windows=win)
    err = arr.onset - t0
    assert abs(float(np.mean(err))) < bound_samples
    assert float(np.mean(np.abs(err) < 2.5 * arr.sigma)) >= 0.75
    only = detect_fitted(x, fs=FS, template=coded_template(fs=FS), models=models[:1], windows=win)
    if isinstance(t, BandpassTransducer):
        assert float(np.mean(only.onset - t0)) > 10.0  # the resonator alone is late


def test_receivers_that_disagree_on_the_shape_are_refitted():
    """A transmitter's stagger shape must agree across its receivers (multipath does
    not): shapes 0.1 apart at sigma 0.02 agree (within the slack); an odd one out of
    three is refitted at the other two's shape; two that disagree fall back to the
    resonator."""
    from rangekit.detect.fitted import ChannelFit, check_shapes

    cov = np.diag([1e-4, 1.0, 4e-4, 4e-4])

    def fit(shape):
        th = np.array([-3.0, 40000.0, *shape])
        return ChannelFit(None, np.array([], dtype=object), [], {0: (th, cov)})

    assert check_shapes([fit([-1.0, 0.0]), fit([-1.1, 0.05])]) == [{}, {}]
    out = check_shapes([fit([-1.0, 0.0]), fit([0.4, -0.3]), fit([-1.02, 0.0])])
    assert out[0] == {} and out[2] == {}
    fam, theta = out[1][0]
    assert fam == "stagger" and theta[2:] == pytest.approx([-1.01, 0.0])
    assert check_shapes([fit([-1.0, 0.0]), fit([-2.0, -0.3])]) == [
        {0: "resonator"},
        {0: "resonator"},
    ]


def test_a_receiver_that_chose_the_resonator_is_refitted_at_the_consensus_shape():
    """Two receivers of a transmitter agree on a stagger shape and a third chose the
    resonator for it (no shape): the third hears the same transducer and is refitted
    with the stagger model held at the two's shape (their information-weighted mean),
    when that shape is stagger-tuned. A receiver of another transmitter only, or with
    the resonator where no two agree, is left alone."""
    from rangekit.detect.fitted import ChannelFit, check_shapes

    cov = np.diag([1e-4, 1.0, 4e-4, 4e-4])

    def fit(shapes, groups=(0,)):
        sh = {k: (np.array([-3.0, 40000.0, *v]), cov) for k, v in shapes.items()}
        return ChannelFit(None, np.array([], dtype=object), list(groups), sh)

    res = fit({})  # chose the resonator for transmitter 0
    out = check_shapes([fit({0: [-1.0, 0.0]}), res, fit({0: [-1.04, 0.02]})])
    assert out[0] == {} and out[2] == {}
    fam, theta = out[1][0]
    assert fam == "stagger" and theta[2:] == pytest.approx([-1.02, 0.01])
    # a consensus split in damping (+0.4: two receivers' fits mimicking a room's
    # reflections) is not a transducer's shape to hold the third at (HOLD_SPLIT)
    assert check_shapes([fit({0: [0.4, 0.0]}), res, fit({0: [0.42, 0.02]})]) == [{}] * 3
    # the resonator receiver heard transmitter 1 only: nothing to hold it at
    other = fit({}, groups=(1,))
    assert check_shapes([fit({0: [-1.0, 0.0]}), other, fit({0: [-1.04, 0.02]})]) == [{}] * 3
    # one stagger receiver is no consensus
    assert check_shapes([fit({0: [-1.0, 0.0]}), res]) == [{}, {}]
    # two that disagree: both back to the resonator, the third keeps its own
    out = check_shapes([fit({0: [-1.0, 0.0]}), res, fit({0: [-2.0, -0.3]})])
    assert out == [{0: "resonator"}, {}, {0: "resonator"}]


def test_a_split_beyond_maximally_flat_adds_the_model_order_term():
    """``order_terms``: pooled over the receivers of a transmitter, a split ``Re nu / a^2``
    at the maximally flat -1 adds nothing; one 3 (scaled) sigma beyond it half the term,
    4 sigma the whole; ``with_order_terms`` adds ``r (k d)^2`` (k = 1 stagger, 2
    resonator) to sigma and to sigma_transducer."""
    from rangekit.detect.fitted import (
        SPLIT_SIGMA_SCALE,
        ChannelFit,
        order_terms,
        with_order_terms,
    )
    from rangekit.types import Arrivals

    def fit(split, var, d2=100.0, fam=("stagger", "resonator")):
        n = len(fam)
        a = Arrivals(np.arange(n) * 1.0, FS, np.ones(n), np.zeros(n), np.ones(n),
                     np.zeros((n, 1)))  # fmt: skip
        return ChannelFit(a, np.array(fam, dtype=object), [0] * n, {}, {0: (d2, split, var)})

    # Two receivers of variance v each: pooled sigma sqrt(v / 2) * SPLIT_SIGMA_SCALE.
    v = 2.0 * (0.1 / SPLIT_SIGMA_SCALE) ** 2  # pooled, scaled sigma 0.1
    assert order_terms([fit(-1.0, v), fit(-1.05, v)]) == [{}, {}]
    half = order_terms([fit(-1.3, v), fit(-1.3, v)])
    assert half[0][0] == pytest.approx((0.5, 100.0))
    full = order_terms([fit(-1.4, v), fit(-1.5, v)])
    assert full[1][0] == pytest.approx((1.0, 100.0))
    # Receivers that disagree (pooled -0.8: nothing) still count one receiver's own
    # evidence (-2.1 at its sigma 0.14: z 7.8).
    odd = order_terms([fit(-0.5, v), fit(-2.1, v), fit(0.2, v)])
    assert all(o[0][0] == 1.0 for o in odd)
    f = fit(-1.5, v)
    arr = with_order_terms(f, full[0])
    assert arr.sigma == pytest.approx([math.sqrt(1 + 100.0), math.sqrt(1 + 400.0)])
    assert arr.sigma_transducer == pytest.approx([10.0, 20.0])
    assert with_order_terms(f, {}) is f.arrivals
