"""Seeded test material for the probe detector: placement, real-world noise, rooms.

Shared by ``test_template_*.py`` (and the measurement commands quoted in
``docs/theory/probes.md``). Nothing here uses rangekit's simulator: noise shapes follow
what other labs' phone recordings show (``../shared/REFERENCES.md``), rooms come from
pyroomacoustics, measured responses from dEchorate (``tests/data/dechorate``).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from rangekit.sim._fracdelay import interp_bandlimited

DATA = Path(__file__).resolve().parents[1] / "data" / "dechorate"


def place(src: np.ndarray, starts, amps, n: int) -> np.ndarray:
    """``src`` at the fractional sample positions ``starts`` (band-limited), ``n`` samples."""
    u = np.arange(n, dtype=np.float64)
    x = np.zeros(n)
    for s, a in zip(starts, amps, strict=True):
        lo = max(0, int(s) - 40)
        hi = min(n, int(s) + len(src) + 40)
        x[lo:hi] += a * interp_bandlimited(src, u[lo:hi] - s, half_width=32)
    return x


def lf_noise(
    n: int,
    *,
    fs: float,
    inband_sigma: float,
    above_db: float = 30.0,
    f_hi: float = 200.0,
    dc: float = 0.0,
    hum_db: float | None = None,
    rng: np.random.Generator,
) -> np.ndarray:
    """Phone-like low-frequency noise: a shelf ``above_db`` over the white PSD below ``f_hi``.

    The white noise of standard deviation ``inband_sigma`` has the one-sided PSD
    ``N0 = 2 sigma^2 / fs``; this noise's PSD is ``N0 10^(above_db / 10)`` at ``f_hi``,
    rising as ``1 / f`` below it (handling noise and drift: another +20 dB at 2 Hz,
    capped there) and falling as ``f^-4`` above it, plus a DC offset ``dc`` and, with
    ``hum_db``, mains hum at 50 Hz and its first four harmonics, each ``hum_db`` over the
    white noise's power in a 1 Hz band. Not the white noise itself (add it).
    """
    f = np.fft.rfftfreq(n, 1.0 / fs)
    n0 = 2.0 * inband_sigma**2 / fs
    fc = np.maximum(f, 2.0)
    psd = n0 * 10 ** (above_db / 10.0) * np.where(fc < f_hi, f_hi / fc, (f_hi / fc) ** 4)
    spec = (rng.standard_normal(len(f)) + 1j * rng.standard_normal(len(f))) / np.sqrt(2)
    spec *= np.sqrt(psd * fs * n / 2.0)
    spec[0] = 0.0
    x = np.fft.irfft(spec, n)
    t = np.arange(n) / fs
    if hum_db is not None:
        a = np.sqrt(2.0 * n0 * 10 ** (hum_db / 10.0))
        for k in range(1, 6):
            x += a / k * np.sin(2 * np.pi * 50.0 * k * t + rng.uniform(0, 2 * np.pi))
    return x + dc


def dechorate():
    """The 12 measured responses (48 kHz, sample 0 = emission) and the annotated direct
    path of each channel in samples."""
    import soundfile as sf

    parts = [sf.read(DATA / f"rirs_ch{a:02d}-{a + 5:02d}.flac", dtype="float64") for a in (0, 6)]
    h = np.concatenate([p[0] for p in parts], axis=1)
    fs = parts[0][1]
    with open(DATA / "geometry.csv") as fh:
        rows = list(csv.DictReader(fh))
    direct = np.array([float(r["annotated_direct_s"]) for r in rows]) * fs
    return h, float(fs), direct
