"""The scipy peer of the band-energy benchmarks: ShortTimeFFT + band sum, in chunks.

Shared by ``bench_band_energy.py`` and ``bench_detect.py`` so both measure the same peer.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import ShortTimeFFT
from scipy.signal.windows import hann


def stft_band_energy(
    x: np.ndarray,
    *,
    fs: float,
    n_win: int,
    hop: int,
    mfft: int,
    bins: slice,
    chunk_s: float = 60.0,
) -> np.ndarray:
    """Band energy (sum of |X|^2 over ``bins``) per frame via ShortTimeFFT, in chunks.

    ShortTimeFFT centres slice ``p`` on sample ``p * hop``, i.e. its window starts at
    ``p * hop - n_win // 2``; rangekit's frame ``m`` (window start ``m * hop``) is slice
    ``p = m + (n_win // 2) // hop``. Chunks of ~``chunk_s`` seconds of whole frames keep
    the memory bounded (a full 10-minute STFT at mfft=441 would need ~2.9 GB).
    """
    if x.dtype == np.int16:
        x = x / 32768.0
    sft = ShortTimeFFT(hann(n_win, sym=False), hop=hop, fs=fs, mfft=mfft, scale_to=None)
    p_off = sft.m_num_mid // hop
    if p_off * hop != sft.m_num_mid:
        raise ValueError(f"n_win // 2 = {sft.m_num_mid} must be a multiple of hop = {hop}")
    n_frames = (x.size - n_win) // hop + 1
    chunk_frames = int(chunk_s * fs) // hop
    out = np.empty(n_frames)
    for m0 in range(0, n_frames, chunk_frames):
        nf = min(chunk_frames, n_frames - m0)
        seg = x[m0 * hop : (m0 + nf - 1) * hop + n_win]
        xs = sft.stft(seg, p0=p_off, p1=p_off + nf)[bins]
        out[m0 : m0 + nf] = np.sum(xs.real**2 + xs.imag**2, axis=0)
    return out
