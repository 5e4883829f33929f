"""The series' block reader: integer PCM decoded straight into float32, one contiguous row
per channel; values and series results identical to the float64 reader it replaced."""

from __future__ import annotations

import numpy as np
import pytest
import soundfile as sf

from rangekit.errors import AudioFormatError
from rangekit.io.audio import open_audio, read_frames
from rangekit.ranging import series
from rangekit.ranging.series import _read_block, range_series_beepbeep
from rangekit.sim.recording import pair_devices, render_beepbeep

FS = 44100


@pytest.mark.parametrize(("subtype", "channels"), [("PCM_16", 2), ("PCM_24", 1), ("FLOAT", 3)])
def test_block_values_equal_the_float64_reader(tmp_path, subtype, channels):
    x = 0.5 * np.random.default_rng(0).standard_normal((5000, channels)).clip(-1.9, 1.9)
    path = tmp_path / "x.wav"
    sf.write(path, x, FS, subtype)
    with open_audio(path) as f:
        got = _read_block(f, 100, 4000)
        ref = read_frames(f, 100, 4000).T
        empty = _read_block(f, 4000, 4000)
    assert got.shape == ref.shape == (channels, 3900)
    assert all(row.flags.c_contiguous for row in got.reshape(channels, -1))
    # float32 for integer PCM (exact), float64 (checked by read_frames) for the rest
    assert got.dtype == (np.float64 if subtype == "FLOAT" else np.float32)
    np.testing.assert_array_equal(got.astype(np.float64), ref)
    assert empty.size == 0


def test_float_blocks_keep_the_checks(tmp_path):
    path = tmp_path / "nan.wav"
    x = np.zeros((1000, 2), dtype=np.float32)
    x[500, 1] = np.nan
    sf.write(path, x, FS, "FLOAT")
    with open_audio(path) as f, pytest.raises(AudioFormatError, match="NaN"):
        _read_block(f, 0, 1000)


def test_series_equal_to_the_float64_reader_on_compiled_blocks(tmp_path):
    """A 25 s stereo file: its first default block (2^20 frames per channel) is detected by
    the compiled path, which reads float32 as it is: the exchanges must not change."""
    one = np.stack(render_beepbeep(pair_devices(2.0, self_distance_m=0.1)).recordings, 1)
    rng = np.random.default_rng(3)
    period = int(2.5 * FS)
    tile = np.zeros((period, 2))
    tile[: len(one)] = one
    x = np.concatenate([tile] * 10) + 2e-3 * rng.standard_normal((10 * period, 2))
    path = tmp_path / "s.wav"
    sf.write(path, x, FS, "PCM_16")
    new = list(range_series_beepbeep([path], self_distance_m=0.1))
    try:
        series._BLOCK_DTYPE = "float64"
        old = list(range_series_beepbeep([path], self_distance_m=0.1))
    finally:
        series._BLOCK_DTYPE = "auto"
    assert len(new) == 10
    assert [(e.t_s, e.ranges, e.error) for e in new] == [(e.t_s, e.ranges, e.error) for e in old]
    assert all(abs(e.ranges[0].distance_m - 2.0) < 0.01 for e in new)
