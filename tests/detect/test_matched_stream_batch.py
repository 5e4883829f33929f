"""``MatchedFilter.stream`` batches at least ``STREAM_MIN_BLOCKS`` overlap-save blocks per
FFT call (issue 20: ~1.6x less CPU for float32 streams) and still equals ``correlate``
bit for bit: a row's FFT does not depend on how many rows the call holds."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import soundfile as sf

from rangekit.detect import matched as M
from rangekit.detect.matched import MatchedFilter, coded_template
from rangekit.signals.barker import CodedBurst
from rangekit.signals.transducer import Transducer

FS = 192000.0


@pytest.fixture(scope="module")
def h_folded():
    return coded_template(CodedBurst(), fs=FS, tx=Transducer(), rx=Transducer())


@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("seed", [0, 1])
def test_stream_equals_correlate_bit_for_bit(h_folded, dtype, seed):
    rng = np.random.default_rng(seed)
    x = (0.05 * rng.standard_normal(60_000)).astype(dtype)
    mf = MatchedFilter(h_folded, block=1024, dtype=dtype)
    sizes = rng.choice([0, 1, 7, 183, 1500, 3000, 9000], size=40)
    edges = np.minimum(np.cumsum(np.concatenate([[0], sizes])), len(x))
    chunks = [x[a:b] for a, b in itertools.pairwise(edges)] + [x[edges[-1] :]]
    outs = list(mf.stream(iter(chunks)))
    np.testing.assert_array_equal(np.concatenate(outs), mf.correlate(x))
    # every output but the last holds whole steps, at least STREAM_MIN_BLOCKS of them
    assert len(outs) > 2
    assert all(len(o) % mf.step == 0 and len(o) >= M.STREAM_MIN_BLOCKS * mf.step
               for o in outs[:-1])  # fmt: skip


def test_stream_copies_the_chunks_it_keeps(h_folded):
    """A caller that reuses its chunk buffer (as a block reader may) gets the same output."""
    x = 0.05 * np.random.default_rng(3).standard_normal(40_000)
    mf = MatchedFilter(h_folded, block=1024)
    buf = np.empty(700)

    def reused():
        for i in range(0, len(x), len(buf)):
            n = min(len(buf), len(x) - i)
            buf[:n] = x[i : i + n]
            yield buf[:n]
            buf[:] = np.nan  # overwritten before the next chunk

    np.testing.assert_array_equal(np.concatenate(list(mf.stream(reused()))), mf.correlate(x))


def test_stream_from_a_16_bit_wav_equals_the_whole_file(h_folded, tmp_path):
    x = 0.05 * np.random.default_rng(5).standard_normal(200_000)
    p = tmp_path / "x.wav"
    sf.write(p, x, int(FS), subtype="PCM_16")
    mf = MatchedFilter(h_folded, dtype="float32")
    got = np.concatenate(list(mf.stream(sf.blocks(p, blocksize=2**16, dtype="float32"))))
    np.testing.assert_array_equal(got, mf.correlate(sf.read(p, dtype="float32")[0]))
