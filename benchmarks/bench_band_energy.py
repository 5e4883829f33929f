"""Benchmark :func:`rangekit.detect._kernels.band_energy` against scipy ShortTimeFFT.

Signal: 10 minutes of 44.1 kHz white noise plus a 16 kHz tone, as float32 and as
int16.  Band: 15.9, 16.0 and 16.1 kHz, ``n_win=128``, ``hop=32``, periodic Hann window.

The scipy baseline is ``ShortTimeFFT(hann(128, sym=False), hop=32, fs=44100,
mfft=441, scale_to=None).stft(...)`` followed by ``sum(|X[159:162]|**2)``: with
``mfft=441`` the bins are exactly 100 Hz apart, so it computes the *same* quantity (the
script checks this).  A full 10-minute STFT with 221 bins would need ~2.9 GB of
complex128, so scipy is run in chunks of ~60 s of frames (frames never straddle chunk
boundaries: every chunk covers whole frames, and its sample range overlaps the next
chunk by ``n_win - hop`` samples).  For int16, the scipy timing includes the conversion
to float (``x / 32768``), which the rangekit kernel does on the fly.  A second scipy line
uses the default ``mfft=n_win=128`` (65 bins, nearest bins to the band) for reference.

Everything runs on one core (the kernel is single-threaded, scipy.fft uses one worker by
default).  Timing: ``time.perf_counter``, best of 3, after a numba warm-up.

Run: ``python benchmarks/bench_band_energy.py``
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np
from _report import row
from _stft_peer import stft_band_energy

from rangekit.detect._kernels import NUMBA_MIN_SAMPLES, band_energy

FS = 44100.0
DURATION_S = 600.0
N_WIN = 128
HOP = 32
F_HZ = np.array([15900.0, 16000.0, 16100.0])
CHUNK_S = 60.0
REPEATS = 3


def make_signals() -> tuple[np.ndarray, np.ndarray]:
    """Return (float32, int16) versions of 10 minutes of noise + 16 kHz tone."""
    rng = np.random.default_rng(12345)
    n = int(DURATION_S * FS)
    t = np.arange(n) / FS
    x = 0.05 * rng.standard_normal(n) + 0.3 * np.sin(2 * np.pi * 16000.0 * t)
    x32 = x.astype(np.float32)
    x16 = np.clip(np.round(x * 32768.0), -32768, 32767).astype(np.int16)
    return x32, x16


def scipy_band_energy(x: np.ndarray, mfft: int, bins: slice) -> np.ndarray:
    """Band energy via ShortTimeFFT in ~60 s chunks (``_stft_peer.stft_band_energy``)."""
    return stft_band_energy(x, fs=FS, n_win=N_WIN, hop=HOP, mfft=mfft, bins=bins, chunk_s=CHUNK_S)


def best_time(fn, *args) -> tuple[float, np.ndarray]:
    """Best wall time of ``REPEATS`` calls, and the last result."""
    best = np.inf
    res = None
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        res = fn(*args)
        best = min(best, time.perf_counter() - t0)
    return best, res


def main() -> None:
    x32, x16 = make_signals()
    print(
        f"signal: {DURATION_S:.0f} s at {FS:.0f} Hz ({x32.size} samples), "
        f"n_win={N_WIN}, hop={HOP}, f_hz={F_HZ.tolist()}, best of {REPEATS}"
    )

    # Warm up numba (compile or load from cache) for both dtypes; inputs shorter than
    # NUMBA_MIN_SAMPLES take the numpy path, so the warm-up must be at least that long.
    t0 = time.perf_counter()
    for x in (x32, x16):
        band_energy(x[:NUMBA_MIN_SAMPLES], fs=FS, f_hz=F_HZ, n_win=N_WIN, hop=HOP)
    print(f"numba warm-up (compile/cache load, 2 dtypes): {time.perf_counter() - t0:.2f} s")
    print(f"scipy runs in chunks of {CHUNK_S:.0f} s (full 10-min STFT is ~2.9 GB at mfft=441)")

    def rk(x: np.ndarray) -> np.ndarray:
        return band_energy(x, fs=FS, f_hz=F_HZ, n_win=N_WIN, hop=HOP)

    for name, x in (("float32", x32), ("int16", x16)):
        t_rk, e_rk = best_time(rk, x)
        t_sp, e_sp = best_time(scipy_band_energy, x, 441, slice(159, 162))
        t_sp128, _ = best_time(scipy_band_energy, x, N_WIN, slice(45, 48))
        rel = np.max(np.abs(e_rk - e_sp)) / np.max(e_sp)
        print(f"\n[{name}]")
        print(
            f"  rangekit band_energy          : {t_rk:8.4f} s  {DURATION_S / t_rk:9.0f}x realtime"
        )
        print(
            f"  scipy ShortTimeFFT mfft=441   : {t_sp:8.4f} s  {DURATION_S / t_sp:9.0f}x realtime"
        )
        print(
            f"  scipy ShortTimeFFT mfft=128   : {t_sp128:8.4f} s  "
            f"{DURATION_S / t_sp128:9.0f}x realtime"
        )
        print(f"  ratio rangekit / scipy(441)   : {t_sp / t_rk:9.1f}x")
        print(f"  ratio rangekit / scipy(128)   : {t_sp128 / t_rk:9.1f}x")
        print(f"  max |diff| / max (vs 441)     : {rel:.2e}")
        row("band_energy", f"band_energy {name}, 3 frequencies", DURATION_S / t_rk, "x-realtime",
            peer="scipy ShortTimeFFT mfft=441 + band sum", peer_value=DURATION_S / t_sp,
            note=f"{DURATION_S:.0f} s at 44.1 kHz, best of {REPEATS}; vs mfft=128: "
            f"{t_sp128 / t_rk:.0f}x; max rel. diff {rel:.1e}")  # fmt: skip


if __name__ == "__main__":
    main()
