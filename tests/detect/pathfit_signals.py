"""The coded drive through transducers at fractional onsets, for the pathfit tests
(importable through ``tests/detect/conftest.py``)."""

from __future__ import annotations

import numpy as np

from rangekit.signals.barker import CodedBurst, burst_waveform
from rangekit.signals.transducer import Transducer

FS = 192000.0


def received(q: float, onsets, amps, n: int = 4000, f0: float = 40000.0, qr=None):
    """The drive at fractional ``onsets`` (band-limited shift), through Tx and Rx."""
    d = burst_waveform(CodedBurst(fs=FS))
    f = np.fft.rfftfreq(n)
    spec = np.fft.rfft(d, n)
    x = np.zeros(n)
    for t0, a in zip(onsets, amps, strict=True):
        x += a * np.fft.irfft(spec * np.exp(-2j * np.pi * f * t0), n)
    t, r = Transducer(f0, q), Transducer(f0, q if qr is None else qr)
    return r.apply(t.apply(x, fs=FS), fs=FS)
