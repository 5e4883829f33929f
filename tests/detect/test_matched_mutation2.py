"""``rangekit.detect.matched``: documented rules pinned against independent references.

Issue 21's mutation round (helper P2; seeds 101 and 330 of the mutation check). The
expectations are closed forms (overlap-save block arithmetic, the CRB's sigma), numpy or
scipy references, or the documented defaults, never a value read from the module under
test. A few seconds.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from rangekit.detect import matched as M
from rangekit.detect.matched import MatchedFilter, coded_template
from rangekit.signals.barker import CodedBurst
from rangekit.signals.transducer import Transducer

FS = 192000.0


@pytest.fixture(scope="module")
def h_folded():
    return coded_template(CodedBurst(), fs=FS, tx=Transducer(q=4.0), rx=Transducer(q=4.0))


def test_overlap_save_blocks_default_size_and_growth(h_folded):
    """The FFT size is the block (default 2^15, as documented), doubled until it holds
    four template lengths; each block then gives ``n_fft - n_taps + 1`` new outputs (an
    ``N``-point circular correlation with an ``L``-tap FIR has ``N - L + 1`` valid lags:
    Oppenheim & Schafer, Discrete-Time Signal Processing, 3rd ed., §8.7.3)."""
    mf = MatchedFilter(h_folded)
    assert mf.block == 1 << 15 and mf.n_fft == 1 << 15  # the FIR is far shorter
    assert mf.step == mf.n_fft - mf.n_taps + 1
    for block in (16, 100, 1000, 4096):
        mf = MatchedFilter(h_folded, block=block)
        n = block
        while n < 4 * mf.n_taps:
            n *= 2
        assert mf.n_fft == n
        assert mf.step == n - mf.n_taps + 1


@pytest.mark.parametrize("block", [256, 1024])
def test_stream_yields_whole_overlap_save_steps(h_folded, block):
    """``stream`` computes whole steps only, at least ``STREAM_MIN_BLOCKS`` (8) per call:
    every output chunk but the last is a multiple of ``n_fft - n_taps + 1`` outputs and at
    least eight of them; the outputs concatenated are ``correlate``'s."""
    mf = MatchedFilter(h_folded, block=block)
    step = mf.n_fft - len(mf._g) + 1
    rng = np.random.default_rng(330)
    x = rng.standard_normal(40000)
    sizes = rng.choice([0, 1, 7, 183, 1500, 3000], size=60)
    edges = np.minimum(np.cumsum(np.concatenate([[0], sizes])), len(x))
    chunks = [x[a:b] for a, b in itertools.pairwise(edges)] + [x[edges[-1] :]]
    outs = list(mf.stream(iter(chunks)))
    assert len(outs) >= 3
    for o in outs[:-1]:
        assert len(o) % step == 0 and len(o) >= 8 * step
    got = np.concatenate(outs)
    ref = mf.correlate(x)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9 * np.abs(ref).max())


def _analytic_correlation(x, h, n_grid=1 << 17):
    """``c[tau] = sum_k x[tau + k] conj(h_a[k])``, ``h_a`` the analytic template (its
    spectrum doubled at positive frequencies, zeroed at negative ones), by one long FFT
    (the template's Hilbert tails have room before they wrap)."""
    f = np.fft.fftfreq(n_grid)
    H = np.fft.fft(h, n_grid)
    Ha = np.where(f > 0, 2.0 * H, np.where(f == 0, H, 0.0))
    return np.fft.ifft(np.fft.fft(x, n_grid) * np.conj(Ha))[: len(x)]


def _peak(env, i):
    la, lb, lc = np.log(env[i - 1 : i + 2])
    d = float(np.clip(0.5 * (la - lc) / (la - 2 * lb + lc), -0.5, 0.5))
    return d, math.exp(lb - 0.25 * (la - lc) * d)


def test_detect_matched_rows_and_low_snr_flag_from_first_principles(h_folded):
    """One burst per 3000-sample window (each window its own noise span, shorter than
    ``NOISE_MIN_SPAN``), at SNRs from 6.6 to 90 noise scales: ``onset`` the window's start
    plus the envelope peak's log-parabola vertex, ``snr_db`` 20 log10 of its height over
    the envelope's Rayleigh scale (median / sqrt(2 ln 2)), ``sigma`` the CRB
    ``fs / (2 pi beta snr)`` with ``beta`` the template's RMS bandwidth about its
    centroid, ``confidence`` 1 (the strongest is the first path), ``low_snr`` exactly
    below ``3 k_detect`` = 13.5 noise scales; all against an envelope computed here from
    the FFT's analytic signal (the bounds twice the differences measured, which are
    the module's FIR cut at 1e-9 of the energy: onsets 7.6e-4 samples at SNR 6.6, SNR
    and sigma 3.3e-5 relative)."""
    from rangekit.signals.spectrum import rms_bandwidth_hz
    from rangekit.types import flag_bit

    rng = np.random.default_rng(330)
    amps = [0.016, 0.025, 0.04, 0.05, 0.07, 0.1, 0.13, 0.2]
    win = 3000
    x = 0.01 * rng.standard_normal(win * len(amps))
    t0 = []
    for k, a in enumerate(amps):
        t = k * win + 700 + rng.uniform(0, 1500)
        n = np.arange(len(h_folded) + 8)
        # the template at a fractional onset (band-limited shift)
        spec = np.fft.rfft(h_folded, 4096) * np.exp(-2j * np.pi * np.fft.rfftfreq(4096) * (t % 1))
        x[int(t) : int(t) + len(n)] += a * np.fft.irfft(spec, 4096)[: len(n)]
        t0.append(t)
    windows = np.array([[k * win, (k + 1) * win] for k in range(len(amps))])
    arr = M.detect_matched(x, fs=FS, template=h_folded, windows=windows)
    beta = rms_bandwidth_hz(h_folded, fs=FS)
    assert len(arr) == len(amps)
    np.testing.assert_array_equal(arr.window, np.arange(len(amps)))
    env_all = np.abs(_analytic_correlation(x, h_folded))
    snrs = []
    for k in range(len(amps)):
        env = env_all[k * win : (k + 1) * win]
        noise = float(np.median(env)) / math.sqrt(2.0 * math.log(2.0))
        i = int(np.argmax(env))
        d, h = _peak(env, i)
        snr = h / noise
        snrs.append(snr)
        assert arr.onset[k] == pytest.approx(k * win + i + d, abs=1.5e-3)
        assert abs(arr.onset[k] - t0[k]) < 3.7 * arr.sigma[k]  # the truth: measured 1.85 sigma
        assert 10 ** (arr.snr_db[k] / 20) == pytest.approx(snr, rel=7e-5)
        assert arr.sigma[k] == pytest.approx(FS / (2 * math.pi * beta * snr), rel=7e-5)
        assert arr.confidence[k] == 1.0
        low = bool(arr.flags[k] & flag_bit("low_snr"))
        assert low == (snr < 3 * 4.5), (k, snr)
    snrs = np.array(snrs)
    assert (snrs < 13.5).sum() >= 2 and (snrs > 13.5).sum() >= 2
    assert np.min(np.abs(snrs - 13.5)) > 0.3  # no case at the boundary by rounding


def test_sample_noise_leaves_out_samples_beyond_five_mad_deviations():
    """``_sample_noise``: the standard deviation of the samples within 5 MAD-based
    deviations (1.4826 MAD) of the median, so a few clicks do not count; against numpy's
    median and std, at noise levels from 1e-3 to 10 (the rule is scale-free), with 1 %
    of the samples clicks of 50 noise sigmas (with them the plain std is 5x larger)."""
    rng = np.random.default_rng(330_1)
    for scale in (1e-3, 0.01, 1.0, 10.0):
        x = scale * rng.standard_normal(2000) + 0.3 * scale
        x[rng.permutation(2000)[:20]] += 50.0 * scale * rng.choice([-1.0, 1.0], 20)
        d = x - np.median(x)
        s = 1.4826 * np.median(np.abs(d))
        want = float(np.std(d[np.abs(d) < 5.0 * s]))
        assert M._sample_noise(x) == pytest.approx(want, rel=1e-12)
        assert M._sample_noise(x) == pytest.approx(scale, rel=0.028)  # measured within 1.4 %
        assert np.std(x) > 4.0 * scale


def test_a_peak_just_beyond_the_reach_of_a_stronger_path_before_the_range_is_kept(h_folded):
    """``first_path`` with the self response drops in-range peaks that are side lobes of a
    stronger path just before ``lo``; a peak one lag beyond that path's reach (its self
    response's half length ``m`` + 1) has nothing subtracted (the model is zero there)
    and stays: the weaker path at exactly ``j + m + 1`` is the one found, its side lobes'
    rivals (the strong path's own lobes inside the range) dropped."""
    mf = MatchedFilter(h_folded)
    sr = mf.self_response
    m = len(sr) // 2
    j = 3000
    x = np.zeros(j + 2 * m + 6000)
    x[j : j + len(h_folded)] += 10.0 * h_folded
    p = j + m + 1
    x[p : p + len(h_folded)] += h_folded
    c = mf.correlate(x)
    env = np.abs(c)
    assert int(np.argmax(env[j + 1 :])) + j + 1 != p  # a side lobe of j is the top in range
    got = M.first_path(c, lo=j + 1, noise=1e-6 * env.max(), self_response=sr)
    assert got is not None and got.lag == pytest.approx(p, abs=1e-9)


def _templates():
    rng = np.random.default_rng(330_5)
    return [
        coded_template(CodedBurst(), fs=FS, tx=Transducer(q=4.0), rx=Transducer(q=4.0)),
        coded_template(CodedBurst(), fs=384000.0, tx=Transducer(q=12.0)),
        coded_template(CodedBurst(), fs=FS),
        rng.standard_normal(37),  # broadband
    ]


@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("block", [64, 1000, 4096])
def test_every_output_path_equals_the_direct_correlation(block, dtype):
    """Four templates (folded Q 4 pair, Q 12 at 384 kHz, the bare drive, 37 random taps),
    three block sizes (raised to four FIR lengths; a non-power-of-2 one), both precisions,
    seeded noise of random length: ``correlate`` equals scipy's correlation with the
    analytic FIR (to 2e-15 of the peak in float64, 5e-7 in float32: measured 1.0e-15 and
    2.6e-7); ``correlate_spans`` of random spans (empty, single-sample, longer than an FFT
    block, at both ends) equals ``correlate``'s lags (1.4e-15 / 7e-7; measured 6.7e-16,
    3.3e-7); ``envelope`` (decimated by ``D``) and ``envelope_spans`` have
    ``ceil(len / D)`` samples, and ``envelope`` is ``|correlate|[::D]`` within the
    documented ``sqrt(DECIMATE_TAIL)`` = 0.32 % of its RMS (measured 0.20 % at most), the
    spans of 300 samples or more within 1.3 % (measured 0.65 %: short spans' RMS)."""
    from scipy.signal import correlate

    rng = np.random.default_rng(block + (dtype == "float32"))
    tol = {"float64": (2e-15, 1.4e-15), "float32": (5e-7, 7e-7)}[dtype]
    for h in _templates():
        mf = MatchedFilter(h, block=block, dtype=dtype)
        n = int(rng.integers(2000, 30000))
        x = rng.standard_normal(n)
        g, pre = mf._g, mf.pre
        ref = correlate(x.astype(complex), g, mode="full", method="fft")[len(g) - 1 - pre :][:n]
        top = np.abs(ref).max()
        c = mf.correlate(x)
        assert c.shape == (n,)
        assert np.abs(c - ref).max() < tol[0] * top
        d = mf.decimation
        env = mf.envelope(x)
        assert len(env) == -(-n // d)
        rms = np.sqrt(np.mean(np.abs(ref) ** 2))
        assert np.sqrt(np.mean((env - np.abs(ref)[::d]) ** 2)) < math.sqrt(M.DECIMATE_TAIL) * rms
        spans = [(int(a), min(n, int(a) + int(rng.choice([0, 1, 5, 300, 3 * mf.n_fft]))))
                 for a in rng.integers(0, n, 8)]  # fmt: skip
        spans = np.array([*spans, (0, min(n, 700)), (n - 5, n), (n, n)])
        cs = mf.correlate_spans(x, spans)
        es = mf.envelope_spans(x, spans)
        for (a, b), ci, ei in zip(spans.tolist(), cs, es, strict=True):
            assert len(ci) == b - a and len(ei) == -(-(b - a) // d)
            if b > a:
                assert np.abs(ci - c[a:b]).max() < tol[1] * top
            if b - a >= 300:
                r = np.abs(ref[a:b])[::d]
                assert np.sqrt(np.mean((ei - r) ** 2)) < 0.013 * np.sqrt(np.mean(r**2))


def test_groups_pool_each_transducer_pair_apart():
    """``detect_matched(model=..., groups=...)``: windows with equal labels are pooled,
    each label apart. Eight arrivals alternating between transducer pairs of Q 8 and Q 16
    (noise 2e-3): labelled by pair, every onset's sigma falls to 0.73-0.78 of its own
    fit's (``pool=False``; bound 0.85), the labels' values do not matter, the onsets stay
    within 3.6 sigma of the truth (measured 1.77); unlabelled (one group of both pairs)
    the pooling refuses them and the result is ``pool=False``'s; a label per window is
    required."""
    from pathfit_signals import received

    from rangekit.detect.pathfit import ResonatorModel
    from rangekit.errors import InvalidParameterError

    h = coded_template(CodedBurst(), fs=FS, tx=Transducer(q=4.0), rx=Transducer(q=4.0))
    model = ResonatorModel.for_burst(CodedBurst(), fs=FS)
    rng = np.random.default_rng(330)
    win, qs = 4000, [8.0, 16.0] * 4
    parts, t0 = [], []
    for k, q in enumerate(qs):
        t = 1500.0 + rng.uniform(0.0, 1.0)
        t0.append(k * win + t)
        parts.append(received(q, [t], [1.0], n=win))
    x = np.concatenate(parts) + 2e-3 * rng.standard_normal(win * len(qs))
    windows = np.array([[k * win, (k + 1) * win] for k in range(len(qs))])

    def run(**kw):
        return M.detect_matched(x, fs=FS, template=h, windows=windows, model=model, **kw)

    by_pair, own = run(groups=[0, 1] * 4), run(pool=False)
    assert len(by_pair) == len(own) == len(qs)
    ratio = by_pair.sigma / own.sigma
    assert np.all((0.6 < ratio) & (ratio < 0.85)), ratio
    assert np.all(np.abs(by_pair.onset - np.array(t0)) < 3.6 * by_pair.sigma)
    other = run(groups=[7, 3] * 4)
    np.testing.assert_array_equal(other.onset, by_pair.onset)
    np.testing.assert_array_equal(other.sigma, by_pair.sigma)
    mixed = run()
    np.testing.assert_array_equal(mixed.onset, own.onset)
    np.testing.assert_array_equal(mixed.sigma, own.sigma)
    with pytest.raises(InvalidParameterError, match="groups has 7 labels for 8 windows"):
        run(groups=[0] * 7)


def test_coded_template_through_either_order_either_side_or_a_subclass():
    """The template is the drive through ``tx`` then ``rx``: two LTI resonators commute,
    so swapping them gives the same template (to 1e-12 of its peak, the same length: the
    rendered tail uses the larger Q and the lower f0 of the two); one transducer as
    ``tx`` or as ``rx`` is the same template; a ``Transducer`` subclass (filtered by its
    own ``apply``, scipy's ``lfilter``) gives the biquad loop's template bit for bit; the
    drive through scipy's lfilter of each element's coefficients, cut where the rest of
    the energy is ``tail_db`` below the whole, is the template (to 1e-12, the cut within
    one sample)."""
    from scipy.signal import lfilter

    from rangekit.signals.barker import burst_waveform

    class Sub(Transducer):
        pass

    a, b = Transducer(q=4.0, f0_hz=39000.0), Transducer(q=12.0, f0_hz=41000.0)
    ab = coded_template(CodedBurst(), fs=FS, tx=a, rx=b)
    ba = coded_template(CodedBurst(), fs=FS, tx=b, rx=a)
    assert len(ab) == len(ba)
    np.testing.assert_allclose(ab, ba, rtol=0, atol=1e-12 * np.abs(ab).max())
    np.testing.assert_array_equal(
        coded_template(CodedBurst(), fs=FS, tx=b), coded_template(CodedBurst(), fs=FS, rx=b)
    )
    sub = coded_template(
        CodedBurst(), fs=FS, tx=Sub(q=4.0, f0_hz=39000.0), rx=Sub(q=12.0, f0_hz=41000.0)
    )
    np.testing.assert_array_equal(sub, ab)
    drive = burst_waveform(CodedBurst(fs=FS))
    for tail_db in (40.0, 60.0):
        y = np.concatenate([drive, np.zeros(20000)])
        for t in (a, b):
            y = lfilter(*t.coefficients(fs=FS), y)
        rest = np.cumsum(y[::-1] ** 2)[::-1]
        keep = int(np.argmax(rest <= rest[0] * 10 ** (-tail_db / 10)))
        got = coded_template(CodedBurst(), fs=FS, tx=a, rx=b, tail_db=tail_db)
        assert abs(len(got) - keep) <= 1, (len(got), keep)
        m = min(len(got), keep)
        np.testing.assert_allclose(got[:m], y[:m], rtol=0, atol=1e-12 * np.abs(y).max())


def _spikes(n=200, floor=0.01, **peaks):
    e = np.full(n, floor)
    for k, v in peaks.items():
        e[int(k[1:])] = v
    return e


def test_first_path_detection_threshold_and_noise_floor_at_their_boundaries():
    """Nothing is detected unless the strongest peak clears ``k_detect`` noise scales:
    a single peak at exactly 4.5 noise scales is not, one float above is; the same with
    ``k_detect`` 2. A noise of 0 (a noiseless render) is floored at ``NOISE_FLOOR_REL``
    = 1e-6 of the envelope's peak: the SNR is then 1e6, and a side peak under 6e-6 of the
    strongest cannot be taken as the first path while one above it (and above 0.25 of the
    strongest) can."""
    at = 4.5
    assert M.first_path(_spikes(p100=at), noise=1.0) is None
    p = M.first_path(_spikes(p100=math.nextafter(at, math.inf)), noise=1.0)
    assert p is not None and p.lag == 100.0 and p.snr == pytest.approx(4.5, rel=1e-12)
    assert M.first_path(_spikes(p100=2.0), noise=1.0, k_detect=2.0) is None
    assert M.first_path(_spikes(p100=2.01), noise=1.0, k_detect=2.0) is not None
    p = M.first_path(_spikes(floor=0.0, p100=3.0), noise=0.0)
    assert p.snr == pytest.approx(1e6, rel=1e-12) and p.height == 3.0
    env = _spikes(floor=0.0, p50=3.0 * 5e-6, p100=3.0)
    p = M.first_path(env, noise=0.0, rel_threshold=1e-6)
    assert p.lag == 100.0  # 5e-6 of the peak is under 6 floored noise scales
    env[50] = 3.0 * 7e-6
    assert M.first_path(env, noise=0.0, rel_threshold=1e-6).lag == 50.0
