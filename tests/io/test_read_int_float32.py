"""``read_audio`` decodes 16- and 24-bit PCM as integers and scales them to float32 itself
(issue 20: half the decoding CPU): the values are libsndfile's own float conversion, and
the float64 ones, exactly."""

from __future__ import annotations

import numpy as np
import pytest
import soundfile as sf

from rangekit.io import audio as A
from rangekit.io.audio import read_audio

FULL = {"PCM_16": 2**15, "PCM_24": 2**23}


def _write(path, subtype: str, frames: int, channels: int, seed: int = 0):
    full = FULL[subtype]
    v = np.random.default_rng(seed).integers(-full, full, size=(frames, channels))
    v[:4, 0] = [-full, full - 1, 0, -1]  # both extremes, zero, the smallest negative
    sf.write(path, v / float(full), 48000, subtype=subtype)
    return v


@pytest.mark.parametrize("subtype", ["PCM_16", "PCM_24"])
@pytest.mark.parametrize("channels", [1, 3])
def test_equals_libsndfiles_float32_and_the_float64_values(tmp_path, subtype, channels):
    p = tmp_path / "x.wav"
    frames = 2 * A._INT_BLOCK_FRAMES + 12345  # three blocks, the last one partial
    v = _write(p, subtype, frames, channels)
    x, fs = read_audio(p)
    assert fs == 48000.0 and x.dtype == np.float32 and x.shape == (frames, channels)
    # each channel one contiguous run (the detectors read it without a copy)
    assert all(x[:, c].flags["C_CONTIGUOUS"] for c in range(channels))
    np.testing.assert_array_equal(x, sf.read(p, dtype="float32", always_2d=True)[0])
    np.testing.assert_array_equal(x.astype(np.float64), sf.read(p, always_2d=True)[0])
    np.testing.assert_array_equal(x.astype(np.float64) * FULL[subtype], v)
    np.testing.assert_array_equal(read_audio(p, dtype="float32")[0], x)
    x64 = read_audio(p, dtype="float64")[0]
    assert x64.dtype == np.float64
    np.testing.assert_array_equal(x64, x.astype(np.float64))


def test_the_integer_path_is_taken_and_other_subtypes_keep_libsndfile(tmp_path, monkeypatch):
    calls = []
    real = A._read_int_float32
    monkeypatch.setattr(A, "_read_int_float32", lambda f, st: calls.append(st) or real(f, st))
    _write(tmp_path / "a.wav", "PCM_16", 1000, 2)
    read_audio(tmp_path / "a.wav")
    sf.write(tmp_path / "b.wav", np.zeros((1000, 1)), 48000, subtype="FLOAT")
    assert read_audio(tmp_path / "b.wav")[0].dtype == np.float32
    sf.write(tmp_path / "c.wav", np.full((1000, 1), 0.25), 48000, subtype="PCM_U8")
    np.testing.assert_array_equal(read_audio(tmp_path / "c.wav")[0], 0.25)
    assert calls == ["PCM_16"]


@pytest.mark.parametrize("subtype", ["PCM_16", "PCM_24", "PCM_U8"])
@pytest.mark.parametrize("channels", [1, 2])
def test_series_blocks_equal_libsndfiles_float32(tmp_path, subtype, channels, monkeypatch):
    """``range --series`` reads its blocks through the same integer path (PCM 16/24)."""
    from rangekit.ranging import series

    p = tmp_path / "x.wav"
    frames = A._INT_BLOCK_FRAMES + 777  # a block crosses the integer buffer's size
    if subtype == "PCM_U8":  # libsndfile's own path
        sf.write(
            p, np.linspace(-0.5, 0.5, frames * channels).reshape(frames, -1), 48000, subtype=subtype
        )
    else:
        _write(p, subtype, frames, channels)
    calls = []
    real = A._read_int_float32
    monkeypatch.setattr(
        A, "_read_int_float32", lambda f, st, n=None: calls.append(n) or real(f, st, n)
    )
    with sf.SoundFile(p) as f:
        for start, stop in [(0, 1000), (123, frames - 5), (frames - 100, frames + 400)]:
            x = series._read_block(f, start, stop)
            f.seek(start)
            want = f.read(min(stop, frames) - start, dtype="float32", always_2d=True).T
            assert x.dtype == np.float32 and x.flags["C_CONTIGUOUS"]
            np.testing.assert_array_equal(x, want)
    assert calls == (
        [] if subtype == "PCM_U8" else [1000, frames - 128, 100]
    )  # the last clipped to the end
