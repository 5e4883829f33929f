"""Tests of the compiled band-energy kernel ``rangekit.detect._kernels``."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import ShortTimeFFT
from scipy.signal.windows import hann

import rangekit.detect._kernels as kernels_module
from rangekit.detect._kernels import _band_energy_reference, band_energy
from rangekit.errors import InvalidParameterError

FS = 44100.0


@pytest.fixture(autouse=True)
def _always_numba(monkeypatch):
    """Short inputs normally take the numpy path; these tests exercise the numba kernel."""
    monkeypatch.setattr(kernels_module, "NUMBA_MIN_SAMPLES", 0)


def test_short_inputs_take_the_numpy_path_with_the_same_numbers(monkeypatch):
    x = _noise_and_tone(5000, 3)
    f = np.array([15900.0, 16000.0])
    fast = band_energy(x, fs=FS, f_hz=f, n_win=128, hop=32)
    monkeypatch.setattr(kernels_module, "NUMBA_MIN_SAMPLES", 10**9)
    called = []
    monkeypatch.setattr(kernels_module, "_band_energy_kernel", lambda *a: called.append(1))
    slow = band_energy(x, fs=FS, f_hz=f, n_win=128, hop=32)
    assert not called
    _assert_rel(slow, fast, rtol=1e-12)


def _assert_rel(actual: np.ndarray, desired: np.ndarray, rtol: float = 1e-9) -> None:
    """Relative agreement, scaled by the largest value so near-zero frames are fine."""
    assert actual.shape == desired.shape
    assert actual.dtype == np.float64
    if desired.size:
        np.testing.assert_allclose(actual, desired, rtol=rtol, atol=rtol * np.max(desired))


def _noise_and_tone(n: int, seed: int, f0: float = 16000.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    return 0.1 * rng.standard_normal(n) + 0.5 * np.sin(2 * np.pi * f0 * t + 0.3)


# ---------------------------------------------------------------- kernel vs reference


@pytest.mark.parametrize(
    ("n_win", "hop", "f_hz"),
    [
        (128, 32, [15900.0, 16000.0, 16100.0]),
        (128, 128, [16000.0]),
        (128, 1, [1000.0, 21000.0]),
        (4, 1, [11025.0]),
        (4, 4, [5000.0, 17000.0]),
        (256, 64, [18000.0, 18172.3, 18344.6, 18516.9, 18689.2]),
        (100, 37, [440.0, 12345.678]),
        (1023, 500, [20.0, 22049.0]),
    ],
)
@pytest.mark.parametrize("n_extra", [-1, 0, 1, 7, 5000])
def test_kernel_matches_reference(n_win, hop, f_hz, n_extra):
    # n_extra = -1: shorter than one frame (empty); 0: exactly one frame;
    # 5000: many frames with a ragged tail (frames past the end are dropped).
    n = n_win + n_extra
    x = _noise_and_tone(n, seed=n_win * 1000 + n_extra + 1)
    f = np.array(f_hz)
    got = band_energy(x, fs=FS, f_hz=f, n_win=n_win, hop=hop)
    want = _band_energy_reference(x, fs=FS, f_hz=f, n_win=n_win, hop=hop)
    expected_frames = 0 if n < n_win else (n - n_win) // hop + 1
    assert got.shape == (expected_frames,)
    _assert_rel(got, want)


@pytest.mark.parametrize(("n_frames", "hop"), [(1, 32), (10, 32), (1000, 16), (77, 128)])
def test_exact_multiples(n_frames, hop):
    # len(x) chosen so the last frame ends exactly at the last sample.
    n_win = 128
    n = (n_frames - 1) * hop + n_win
    x = _noise_and_tone(n, seed=n_frames)
    f = np.array([15900.0, 16000.0, 16100.0])
    got = band_energy(x, fs=FS, f_hz=f, n_win=n_win, hop=hop)
    assert got.shape == (n_frames,)
    _assert_rel(got, _band_energy_reference(x, fs=FS, f_hz=f, n_win=n_win, hop=hop))
    # One more sample does not add a frame; hop more samples do.
    x1 = np.concatenate([x, _noise_and_tone(hop, seed=99)])
    assert band_energy(x1[: n + 1], fs=FS, f_hz=f, n_win=n_win, hop=hop).shape == (n_frames,)
    assert band_energy(x1, fs=FS, f_hz=f, n_win=n_win, hop=hop).shape == (n_frames + 1,)


def test_empty_when_shorter_than_window():
    f = np.array([16000.0])
    for n in (0, 1, 127):
        e = band_energy(np.ones(n), fs=FS, f_hz=f, n_win=128, hop=32)
        assert e.shape == (0,)
        assert e.dtype == np.float64
    assert band_energy(np.ones(5, np.int16), fs=FS, f_hz=f, n_win=128, hop=32).shape == (0,)


def test_float32_input_and_scalar_frequency():
    x = _noise_and_tone(20000, seed=3).astype(np.float32)
    got = band_energy(x, fs=FS, f_hz=16000.0, n_win=128, hop=32)
    want = _band_energy_reference(x.astype(np.float64), fs=FS, f_hz=[16000.0], n_win=128, hop=32)
    _assert_rel(got, want)


def test_non_contiguous_and_list_input():
    x = _noise_and_tone(20001, seed=4)
    f = np.array([16000.0, 16100.0])
    got = band_energy(x[::3], fs=FS, f_hz=f, n_win=64, hop=16)
    _assert_rel(got, _band_energy_reference(x[::3].copy(), fs=FS, f_hz=f, n_win=64, hop=16))
    got_list = band_energy(list(x[:500]), fs=FS, f_hz=f, n_win=64, hop=16)
    _assert_rel(got_list, _band_energy_reference(x[:500], fs=FS, f_hz=f, n_win=64, hop=16))


def test_non_finite_samples_propagate():
    # fastmath is limited to reassoc/contract, so NaN/inf are not assumed away.
    x = _noise_and_tone(1000, seed=5)
    x[500] = np.nan
    e = band_energy(x, fs=FS, f_hz=[16000.0], n_win=128, hop=32)
    bad = ~np.isfinite(e)
    frames_with_nan = [m for m in range(e.size) if m * 32 <= 500 < m * 32 + 128]
    assert np.flatnonzero(bad).tolist() == frames_with_nan


def test_tone_energy_value():
    # A unit-amplitude complex-free real tone exactly at f: |X|^2 = (A * sum(w) / 2)^2
    # up to the small leakage of the negative-frequency image.
    n_win = 441
    x = np.cos(2 * np.pi * 16000.0 * np.arange(4410) / FS)
    e = band_energy(x, fs=FS, f_hz=[16000.0], n_win=n_win, hop=441)
    expected = (hann(n_win, sym=False).sum() / 2) ** 2
    np.testing.assert_allclose(e, expected, rtol=1e-3)


# ---------------------------------------------------------------- vs scipy ShortTimeFFT


@pytest.mark.parametrize("hop", [32, 16, 64])
def test_matches_scipy_shorttimefft(hop):
    # n_win = 128, fs = 44100, mfft = 441: bin q is at q * 100 Hz, so 16 kHz is exactly
    # bin 160 and bins 159..161 are 15.9, 16.0, 16.1 kHz.
    #
    # Frame alignment: ShortTimeFFT centres slice p on sample p * hop; its window index
    # 0 sits at sample p * hop - m_num_mid with m_num_mid = n_win // 2 = 64.  Our frame
    # m starts at sample m * hop, so frame m is slice p = m + 64 // hop (hop must divide
    # 64 for an exact correspondence; 16, 32, 64 do).  Slices p >= 64 // hop need no
    # zero padding at the start, and stft(x, p0, p1) returns slices p0 .. p1 - 1.
    # ShortTimeFFT's default phase_shift rolls the zero-padded FFT input circularly,
    # which multiplies each bin by a unit-modulus factor and leaves |X|^2 unchanged.
    n_win, mfft = 128, 441
    win = hann(n_win, sym=False)
    x = _noise_and_tone(30000, seed=hop)
    n_frames = (x.size - n_win) // hop + 1

    sft = ShortTimeFFT(win, hop=hop, fs=FS, mfft=mfft, scale_to=None)
    assert sft.m_num_mid == n_win // 2
    p0 = sft.m_num_mid // hop
    assert p0 * hop == sft.m_num_mid
    X = sft.stft(x, p0=p0, p1=p0 + n_frames)  # shape (mfft // 2 + 1, n_frames)
    assert X.shape == (mfft // 2 + 1, n_frames)
    f_bins = sft.f
    assert f_bins[160] == pytest.approx(16000.0, abs=1e-9)

    single = band_energy(x, fs=FS, f_hz=[f_bins[160]], n_win=n_win, hop=hop)
    _assert_rel(single, np.abs(X[160]) ** 2)

    band = band_energy(x, fs=FS, f_hz=f_bins[159:162], n_win=n_win, hop=hop)
    _assert_rel(band, np.sum(np.abs(X[159:162]) ** 2, axis=0))

    # The alignment is not accidental: a one-slice offset does not match.
    assert not np.allclose(single[1:], np.abs(X[160, :-1]) ** 2, rtol=1e-3)


# ---------------------------------------------------------------- int16


@pytest.mark.parametrize(("n_win", "hop"), [(128, 32), (64, 7), (4, 4)])
def test_int16_equals_scaled_float64(n_win, hop):
    rng = np.random.default_rng(n_win + hop)
    x16 = rng.integers(-32768, 32768, size=10_000, dtype=np.int16)
    x16[:3] = [-32768, 32767, 0]
    f = np.array([15900.0, 16000.0, 16100.0])
    got = band_energy(x16, fs=FS, f_hz=f, n_win=n_win, hop=hop)
    want = band_energy(x16.astype(np.float64) / 32768.0, fs=FS, f_hz=f, n_win=n_win, hop=hop)
    _assert_rel(got, want, rtol=1e-12)
    ref = _band_energy_reference(x16, fs=FS, f_hz=f, n_win=n_win, hop=hop)
    _assert_rel(got, ref)


# ---------------------------------------------------------------- validation


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n_win": 3}, "n_win=3"),
        ({"n_win": 0}, "n_win=0"),
        ({"n_win": 128.5}, "n_win=128.5"),
        ({"hop": 0}, "hop=0"),
        ({"hop": 129}, "hop=129"),
        ({"hop": 2.5}, "hop=2.5"),
        ({"fs": 0.0}, "fs=0.0"),
        ({"fs": -44100.0}, "fs=-44100.0"),
        ({"fs": float("nan")}, "fs=nan"),
        ({"fs": "fast"}, "fs='fast'"),
        ({"f_hz": np.array([16000.0, 22050.0])}, "f_hz=22050.0"),
        ({"f_hz": np.array([0.0])}, "f_hz=0.0"),
        ({"f_hz": np.array([-5.0])}, "f_hz=-5.0"),
        ({"f_hz": np.array([16000.0, np.nan])}, "f_hz=nan"),
        ({"f_hz": np.array([30000.0]), "fs": 48000.0}, "f_hz=30000.0"),
        ({"f_hz": np.array([])}, "f_hz"),
        ({"f_hz": np.ones((2, 2)) * 1000.0}, "f_hz"),
        ({"f_hz": ["a"]}, "f_hz"),
        ({"x": np.zeros((2, 500))}, "x must be 1-D"),
        ({"x": np.zeros(500, dtype=complex)}, "x must be real"),
        ({"x": np.array(["a"] * 500)}, "x must be real"),
    ],
)
def test_invalid_inputs_raise(kwargs, match):
    args = {
        "x": np.zeros(500),
        "fs": FS,
        "f_hz": np.array([16000.0]),
        "n_win": 128,
        "hop": 32,
    }
    args.update(kwargs)
    x = args.pop("x")
    with pytest.raises(InvalidParameterError, match=match):
        band_energy(x, **args)


def test_invalid_parameter_error_is_value_error():
    with pytest.raises(ValueError):
        band_energy(np.zeros(500), fs=FS, f_hz=[16000.0], n_win=2, hop=1)


# ---------------------------------------------------------------- numba disk cache


def test_stale_cache_from_other_module_name_falls_back(tmp_path):
    # numba's disk cache records the module name and re-imports it when loading.  Write
    # the cache while the file is imported as a top-level module "_kernels" (as a
    # prepend-mode doctest run does), then load it as rangekit.detect._kernels: the
    # wrapper must fall back to an uncached compile instead of raising.
    src = Path(kernels_module.__file__).resolve()
    root = src.parents[2]
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    call = (
        "import numpy as np; m.NUMBA_MIN_SAMPLES = 0; "
        "e = m.band_energy(np.ones(300), fs=44100.0, f_hz=[1e3], n_win=128, hop=32); "
        "print(e.shape[0])"
    )
    as_toplevel = (
        "import importlib.util as u, sys; "
        f"s = u.spec_from_file_location('_kernels', {str(src)!r}); m = u.module_from_spec(s); "
        "sys.modules['_kernels'] = m; s.loader.exec_module(m); " + call
    )
    as_package = "import rangekit.detect._kernels as m; " + call
    for code in (as_toplevel, as_package):
        out = subprocess.run(
            [sys.executable, "-c", code], cwd=root, env=env, capture_output=True, text=True
        )
        assert out.returncode == 0, out.stderr
        assert out.stdout.strip() == "6"
    assert any(tmp_path.rglob("*.nbi"))
