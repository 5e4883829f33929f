"""Beep design: parameters, validation, waveform and envelope."""

from __future__ import annotations

import numpy as np
import pytest

from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.signals import Beep, beep_waveform, burst_envelope, check_beep_fits
from rangekit.signals.beep import beep_continuous, beep_continuous_analytic


def test_seed_beep_parameters():
    b = Beep()
    assert (b.f_hz, b.n_bursts, b.spacing, b.fs) == (16000.0, 4, 5000, 44100.0)
    assert b.duration_samples == 3 * 5000 + b.burst_len


def test_waveform_is_tone_bursts_at_the_right_places():
    b = Beep(burst_len=441, taper=22, amplitude=0.5)
    x = beep_waveform(b)
    assert len(x) == b.duration_samples
    assert np.max(np.abs(x)) <= 0.5 + 1e-12
    for k in range(4):
        start = k * b.spacing
        assert np.all(x[start + b.burst_len + 1 : start + b.spacing] == 0.0) or k == 3
        seg = x[start + 22 : start + 441 - 22]
        assert np.isclose(np.sqrt(np.mean(seg**2)), 0.5 / np.sqrt(2), rtol=0.02)
    # Dominant frequency is 16 kHz.
    spec = np.abs(np.fft.rfft(x[:441], 1 << 15))
    f = np.fft.rfftfreq(1 << 15, 1 / 44100)
    assert abs(f[np.argmax(spec)] - 16000) < 50


def test_burst_starts_at_phase_zero_and_envelope_is_raised_cosine():
    b = Beep(taper=20)
    t = np.arange(0, 20) / b.fs
    env = burst_envelope(t, beep=b)
    np.testing.assert_allclose(env, 0.5 - 0.5 * np.cos(np.pi * np.arange(20) / 20), atol=1e-12)
    assert burst_envelope(np.array([-1e-9, b.burst_s + 1e-9]), beep=b).tolist() == [0.0, 0.0]
    x = beep_continuous(np.array([0.0]), beep=b)
    assert x[0] == 0.0


def test_analytic_template_matches_real_beep():
    b = Beep()
    t = np.arange(b.duration_samples) / b.fs
    z = beep_continuous_analytic(t, beep=b)
    np.testing.assert_allclose(b.amplitude * z.imag, beep_continuous(t, beep=b), atol=1e-12)


@pytest.mark.parametrize(
    ("kw", "needle"),
    [
        ({"f_hz": 21000.0}, "Nyquist"),
        ({"f_hz": -1.0}, "f_hz"),
        ({"n_bursts": 0}, "n_bursts"),
        ({"spacing": 400, "burst_len": 441}, "spacing"),
        ({"taper": 300, "burst_len": 441}, "taper"),
        ({"amplitude": 1.5}, "amplitude"),
        ({"fs": 100.0}, "fs"),
        ({"burst_len": 2.5}, "burst_len"),
    ],
)
def test_invalid_parameters_raise_with_the_name(kw, needle):
    with pytest.raises(InvalidParameterError, match=needle):
        Beep(**kw)


def test_check_beep_fits_rejects_low_sample_rates():
    check_beep_fits(Beep(), fs=44100.0)
    check_beep_fits(Beep(), fs=48000.0)
    with pytest.raises(IncompatibleInputError, match="too low"):
        check_beep_fits(Beep(), fs=32000.0)
