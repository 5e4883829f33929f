"""The matched filter's fast paths: float32 FFTs, the decimated (complex baseband)
envelope, strided blocks, streamed remainders, float32 recordings without a float64 copy.

Each is checked against the float64 whole-signal reference; tolerances are stated in
``rangekit.detect.matched`` (``FLOAT32_RTOL``, ``DECIMATE_TAIL``) with the measured values
beside the bounds.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from rangekit.detect import matched as M
from rangekit.detect.matched import MatchedFilter, coded_template, detect_matched
from rangekit.errors import InvalidParameterError
from rangekit.signals.barker import CodedBurst
from rangekit.signals.transducer import Transducer

FS = 192000.0


@pytest.fixture(scope="module")
def h_folded():
    return coded_template(CodedBurst(), fs=FS, tx=Transducer(), rx=Transducer())


@pytest.fixture(scope="module")
def bursts(h_folded):
    """0.5 s of noise (sigma 0.05) with a burst (0.3) every 9600 samples."""
    x = 0.05 * np.random.default_rng(4).standard_normal(int(0.5 * FS))
    for k in range(0, len(x) - 400, 9600):
        x[k + 100 : k + 100 + len(h_folded)] += 0.3 * h_folded
    return x


def test_float32_correlation_within_round_off(h_folded, bursts):
    ref = MatchedFilter(h_folded).correlate(bursts)
    c32 = MatchedFilter(h_folded, dtype="float32").correlate(bursts)
    assert c32.dtype == np.complex64
    err = np.max(np.abs(c32 - ref)) / np.max(np.abs(ref))
    assert err < M.FLOAT32_RTOL  # measured 2.0e-7
    # A float32 input is not copied to float64 on the way: same result from float32 x.
    c32b = MatchedFilter(h_folded, dtype="float32").correlate(bursts.astype(np.float32))
    assert np.max(np.abs(c32b - ref)) / np.max(np.abs(ref)) < M.FLOAT32_RTOL


def test_decimation_and_band_of_the_barker_template(h_folded):
    mf = MatchedFilter(h_folded)
    assert mf.decimation == 4  # Barker band 26.7-53.3 kHz: a quarter of 192 kHz holds it
    lo, hi = (v * FS for v in mf.band)
    assert 15e3 < lo < 27e3 and 53e3 < hi < 66e3 and hi - lo == pytest.approx(FS / 4)
    # The bare drive reaches DC and Nyquist: only the analytic half (D = 2).
    assert MatchedFilter(coded_template(CodedBurst(), fs=FS)).decimation == 2


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_decimated_envelope_equals_full_rate_envelope(h_folded, bursts, dtype):
    mf = MatchedFilter(h_folded, dtype=dtype)
    ref = np.abs(MatchedFilter(h_folded).correlate(bursts))
    d = mf.decimation
    env = mf.envelope(bursts)
    assert env.shape == ref[::d].shape
    rms = math.sqrt(float(np.mean(ref**2)))
    # The FIR's energy outside the band (5.6e-6) bounds the error: measured 0.55 % of the
    # output's RMS at most (float64 and float32 alike).
    assert np.max(np.abs(env - ref[::d])) < 0.011 * rms
    spans = np.array([[0, 5000], [7, 9000], [50001, 70002], [len(bursts) - 3000, len(bursts)]])
    for (a, b), e in zip(spans, mf.envelope_spans(bursts, spans), strict=True):
        assert e.shape == ref[a:b:d].shape
        assert np.max(np.abs(e - ref[a:b:d])) < 0.011 * rms  # measured 0.50 %


def test_span_envelope_depends_on_the_span_only(h_folded, bursts):
    """A span's decimated envelope is computed on its own grid: the same samples give the
    same values wherever the span lies (block-wise series equal whole-file ranging)."""
    mf = MatchedFilter(h_folded, dtype="float32")
    a, b = 20000, 31000
    one = mf.envelope_spans(bursts, np.array([[a, b]]))[0]
    sub = bursts[a - 5000 : b + 5000]
    other = mf.envelope_spans(sub, np.array([[5000, 5000 + b - a], [0, 100]]))[0]
    np.testing.assert_array_equal(one, other)


def test_blocks_inside_the_signal_are_views():
    x = np.arange(100000, dtype=np.float64)
    got = list(M._block_batches(x, 300, 1000, 4096, 101, 8))
    firsts = [b0 for b0, _ in got]
    assert firsts == sorted(firsts) and sum(len(w) for _, w in got) == 101
    inner = [w for b0, w in got if 0 < b0 and b0 + len(w) < 97]
    assert inner and all(np.shares_memory(w, x) for w in inner)
    for b0, w in got:  # every block is v[b * step : b * step + n] of the padded signal
        v = np.concatenate([np.zeros(300), x, np.zeros(200000)])
        for i, row in enumerate(w):
            s = (b0 + i) * 1000
            np.testing.assert_array_equal(row, v[s : s + 4096])


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_stream_carries_remainders(h_folded, bursts, dtype):
    mf = MatchedFilter(h_folded, block=1024, dtype=dtype)
    ref = mf.correlate(bursts[:20000])
    rng = np.random.default_rng(2)
    sizes = rng.choice([0, 1, 7, 183, 1500, 3000], size=30)
    edges = np.minimum(np.cumsum(np.concatenate([[0], sizes])), 20000)
    chunks = [bursts[a:b] for a, b in itertools.pairwise(edges)] + [bursts[edges[-1] : 20000]]
    outs = list(mf.stream(iter(chunks)))
    # Whole overlap-save steps per chunk; only the last output holds a partial step.
    assert all(len(o) % mf.step == 0 for o in outs[:-1])
    got = np.concatenate(outs)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-6 * np.max(np.abs(ref)))


def test_detection_of_a_float32_recording_equals_float64(h_folded, bursts):
    win = np.array([[k, k + 9600] for k in range(0, len(bursts) - 9600, 9600)])
    a64 = detect_matched(bursts, fs=FS, template=h_folded, windows=win)
    a32 = detect_matched(bursts.astype(np.float32).astype(np.float64), fs=FS,
                         template=h_folded, windows=win)  # fmt: skip
    b32 = detect_matched(bursts.astype(np.float32), fs=FS, template=h_folded, windows=win)
    assert len(a64) == len(win) == len(b32)
    np.testing.assert_array_equal(b32.onset, a32.onset)
    np.testing.assert_array_equal(b32.sigma, a32.sigma)
    np.testing.assert_allclose(a64.onset, 100 + win[:, 0], atol=1.6)  # measured 0.78


def test_fast_path_validation(h_folded):
    with pytest.raises(InvalidParameterError, match="dtype"):
        MatchedFilter(h_folded, dtype="float16")
    mf = MatchedFilter(h_folded, dtype="float32")
    x = np.zeros(5000, dtype=np.float32)
    x[7] = np.nan
    with pytest.raises(InvalidParameterError, match="NaN"):
        mf.envelope(x)
    with pytest.raises(InvalidParameterError, match="1-D"):
        mf.correlate(np.zeros((2, 100), dtype=np.float32))
    with pytest.raises(InvalidParameterError, match="span"):
        mf.envelope_spans(np.zeros(100), np.array([[50, 200]]))


@pytest.mark.parametrize("chunk", [1, 5000, 40000, M.WINDOW_CHUNK])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_window_correlations_in_chunks_equal_all_spans_at_once(
    h_folded, bursts, chunk, dtype, monkeypatch
):
    """The per-window correlations, computed a chunk of windows at a time, are bit for bit
    the correlation of all spans laid end to end (the same blocks), at any chunk size
    (one span per chunk, chunks ending inside an FFT block, the default), with spans at
    both ends of the signal, empty and overlapping ones, read in order and out of order."""
    monkeypatch.setattr(M, "WINDOW_CHUNK", chunk)
    x = bursts.astype(dtype)
    n = len(x)
    rng = np.random.default_rng(7)
    a = np.sort(rng.integers(0, n - 9000, 40))
    spans = np.column_stack([a, a + rng.integers(0, 9000, 40)])
    spans = np.vstack([[[0, 5000], [n - 3000, n], [100, 100], [n, n]], spans])
    mf = M.matched_filter(h_folded)
    want = mf._correlate_spans(x, spans)
    corr = M._window_correlations(x, h_folded, spans)
    assert len(corr) == len(spans)
    order = [*range(len(spans)), 3, 0, len(spans) - 1, 10]
    for i in order:
        c, noise, env = corr[i]
        assert c.dtype == np.complex128 and np.array_equal(c, want[i])
        assert np.array_equal(env, np.abs(want[i]))
        assert noise == M.noise_level(np.abs(want[i]))
    with pytest.raises(IndexError):
        corr[len(spans)]
    with pytest.raises(InvalidParameterError, match="not within"):
        M._window_correlations(x, h_folded, np.array([[10, n + 1]]))


def test_median_by_one_partition_equals_numpy():
    """``_median`` (one partition; the lower middle value the largest below it) is
    ``np.median`` exactly: even and odd sizes, ties, float32 and float64."""
    rng = np.random.default_rng(11)
    for n in (2, 3, 4, 8700, 8701):
        for v in (rng.normal(size=n), rng.integers(0, 3, n).astype(float),
                  rng.normal(size=n).astype(np.float32)):  # fmt: skip
            assert M._median(v) == float(np.median(v))


def test_biquad_equals_lfilter_bit_for_bit():
    """``_biquad`` is ``scipy.signal.lfilter`` of the resonator's biquad exactly (random
    resonators, rates, lengths, amplitudes, and ``a[0] != 1``); the template through
    rangekit's resonators equals the one through ``apply_chain`` (lfilter); another
    transducer class still filters by its own ``apply``."""
    from scipy.signal import lfilter

    from rangekit.signals.transducer import BandpassTransducer, apply_chain

    rng = np.random.default_rng(3)
    for _ in range(100):
        fs = float(rng.choice([44100.0, 96000.0, 192000.0, 500000.0]))
        t = Transducer(f0_hz=float(rng.uniform(0.05, 0.45) * fs), q=float(rng.uniform(0.5, 100)))
        x = rng.standard_normal(int(rng.integers(1, 600))) * 10.0 ** rng.uniform(-5, 3)
        b, a = t.coefficients(fs=fs)
        assert np.array_equal(M._biquad(b, a, x), lfilter(b, a, x))
        a2 = a * rng.uniform(0.5, 2.0)
        assert np.array_equal(M._biquad(b, a2, x), lfilter(b, a2, x))
    x = rng.standard_normal(500)
    for chain in ((Transducer(), Transducer(q=12.0, f0_hz=39000.0)), (None, Transducer()),
                  (BandpassTransducer(q=12.0), Transducer())):  # fmt: skip
        assert np.array_equal(M._through(chain, x, FS), apply_chain(x, chain, fs=FS))


def test_coded_template_imports_no_scipy_signal():
    """The one-way template (rangekit's resonators) is built without ``scipy.signal``
    (its import, with ``scipy.stats``, cost 0.4-1.3 s of the one-way command)."""
    import subprocess
    import sys

    code = (
        "import sys; from rangekit.detect.matched import coded_template; "
        "from rangekit.signals.transducer import Transducer; "
        "coded_template(fs=192000.0, tx=Transducer(), rx=Transducer()); "
        "print('scipy.signal' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
