"""The coded drive through transducers at fractional onsets, for the pathfit tests
(importable through ``tests/detect/conftest.py``)."""

from __future__ import annotations

import math

import numpy as np

from rangekit.detect.pathfit import PathFit
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


def fake_fit(theta, info, *, onset=100.0, sigma=1.0, gain=None, var=0.01) -> PathFit:
    """A one-path :class:`PathFit` with estimate ``theta`` (``theta_lin`` and
    ``theta_hat``; ``q``, ``f0`` from its first two entries) and information ``info``, for
    the pooling tests. ``gain``: the onset's profile gain, ``linspace(-10, 1e-3, p)`` by
    default; a ``theta`` of other than two parameters gets a ``q_of`` reading the same two."""
    theta = np.asarray(theta, float)
    p = len(theta)
    return PathFit(
        onset=onset,
        sigma=sigma,
        snr=30.0,
        q=math.exp(theta[0]),
        f0_hz=float(theta[1]),
        onsets=np.array([onset]),
        amplitudes=np.array([1.0]),
        first=0,
        misfit=0.0,
        misfit_z=0.0,
        resolution=20.0,
        theta_lin=theta,
        gain=np.linspace(-10.0, 1e-3, p) if gain is None else np.asarray(gain, float),
        var_given=var,
        theta_hat=theta,
        info=np.asarray(info, float),
        q_of=(lambda t: (math.exp(float(t[0])), float(t[1]))) if p != 2 else None,
    )
