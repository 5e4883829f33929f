"""Probe signals: the designed sweep, probe files, resampling to a recording's rate."""

from __future__ import annotations

import numpy as np
import pytest
import soundfile as sf
from scipy.signal import hilbert

from rangekit.errors import (
    AudioFormatError,
    IncompatibleInputError,
    InputFileError,
    InvalidParameterError,
)
from rangekit.signals.probe import Probe, linear_sweep, read_probe

FS = 44100.0


def _phase(f0: float, f1: float, T: float, t: np.ndarray) -> np.ndarray:
    """The sweep's phase 2 pi (f0 t + (f1 - f0) t^2 / (2 T)) (the docstring's formula)."""
    return 2.0 * np.pi * (f0 * t + 0.5 * (f1 - f0) / T * t * t)


# --- linear_sweep ------------------------------------------------------------------------


@pytest.mark.parametrize(("f0", "f1"), [(17000.0, 20000.0), (20.0, 20000.0), (19000.0, 2000.0)])
def test_sweep_instantaneous_frequency_follows_the_line(f0, f1):
    T = 0.1
    p = linear_sweep(f0, f1, T, fs=FS)
    assert len(p.samples) == 4410 and p.fs == FS and p.duration_s == pytest.approx(T)
    phi = np.unwrap(np.angle(hilbert(p.samples)))
    f_inst = np.diff(phi) * FS / (2.0 * np.pi)
    t_mid = (np.arange(len(f_inst)) + 0.5) / FS
    want = f0 + (f1 - f0) * t_mid / T
    inner = slice(int(0.01 * FS), int(0.09 * FS))  # past the fades and Hilbert edge effects
    # The slowest sweep (20 Hz - 20 kHz over 0.1 s) starts at 20 Hz: allow a few cycles' jitter.
    assert np.max(np.abs(f_inst[inner] - want[inner])) < 0.01 * abs(f1 - f0)
    # Down-sweep: frequency falls.
    assert np.sign(np.median(np.diff(f_inst[inner]))) == np.sign(f1 - f0)


@pytest.mark.parametrize(
    ("T", "fade_s", "m_want"),
    [(0.1, None, 220), (0.02, None, 88), (0.1, 0.01, 441), (0.1, 0.0, 0)],
)
def test_sweep_fades_are_half_cosines_of_the_stated_length(T, fade_s, m_want):
    """x / sin(phase) is the window: half-cosine ramps of m samples, 1 between them."""
    f0, f1, A = 1000.0, 8000.0, 0.7
    p = linear_sweep(f0, f1, T, fs=FS, fade_s=fade_s, amplitude=A)
    x = p.samples
    n = len(x)
    assert float(np.max(np.abs(x))) == pytest.approx(A, rel=1e-12)
    s = np.sin(_phase(f0, f1, T, np.arange(n) / FS))
    ok = np.abs(s) > 0.3
    w = np.where(ok, x / np.where(ok, s, 1.0), np.nan)
    w /= np.nanmedian(w[n // 3 : 2 * n // 3])  # the plateau (peak normalisation aside)
    ramp = 0.5 - 0.5 * np.cos(np.pi * (np.arange(m_want) + 0.5) / max(m_want, 1))
    want = np.ones(n)
    if m_want:
        want[:m_want] = ramp
        want[n - m_want :] = ramp[::-1]
    assert np.nanmax(np.abs(w - want)) < 1e-9
    if m_want == 0:  # no fade: full level from the first samples
        assert abs(x[5]) > 0.5 * A * abs(s[5])


def test_sweep_band():
    lo, hi = linear_sweep(17000.0, 20000.0, 0.1, fs=FS).band_hz()
    assert 16700.0 < lo < 17100.0 and 19900.0 < hi < 20300.0
    lo, hi = linear_sweep(20.0, 20000.0, 0.5, fs=FS).band_hz()
    assert lo < 200.0 and 19500.0 < hi < 20300.0
    # A narrower energy fraction gives a narrower band.
    p = linear_sweep(5000.0, 9000.0, 0.05, fs=FS)
    lo9, hi9 = p.band_hz(0.9)
    lo, hi = p.band_hz()
    assert lo < lo9 < hi9 < hi
    with pytest.raises(InvalidParameterError, match="energy"):
        p.band_hz(1.5)


@pytest.mark.parametrize(
    ("args", "kw", "names"),
    [
        ((17000.0, 22050.0, 0.1), {}, ("f1_hz", "22050", "Nyquist")),
        ((30000.0, 1000.0, 0.1), {}, ("f0_hz", "30000", "Nyquist")),
        ((17000.0, 20000.0, 0.1), {"fs": 32000.0}, ("f0_hz", "16000")),
        ((5000.0, 5000.0, 0.1), {}, ("f0_hz", "f1_hz", "5000")),
        ((1000.0, 2000.0, 0.0), {}, ("duration_s",)),
        ((1000.0, 2000.0, 1000.0), {}, ("duration_s",)),
        ((1000.0, 2000.0, 0.1), {"fade_s": 0.06}, ("fade_s",)),
        ((1000.0, 2000.0, 0.1), {"amplitude": 0.0}, ("amplitude",)),
        ((1000.0, 2000.0, 0.1), {"amplitude": 1.5}, ("amplitude",)),
        ((-1.0, 2000.0, 0.1), {}, ("f0_hz",)),
        ((1000.0, 2000.0, 0.1), {"fs": 10.0}, ("fs",)),
    ],
)
def test_sweep_errors_name_the_parameter(args, kw, names):
    with pytest.raises(InvalidParameterError) as e:
        linear_sweep(*args, **kw)
    for name in names:
        assert name in str(e.value)


def test_probe_refuses_degenerate_samples():
    with pytest.raises(InvalidParameterError, match="all zeros"):
        Probe(np.zeros(100), FS, "z")
    with pytest.raises(InvalidParameterError, match="at least 16"):
        Probe(np.ones(8), FS, "short")
    with pytest.raises(InvalidParameterError):
        Probe(np.full(100, np.nan), FS)
    p = Probe(np.arange(1.0, 101.0), FS)
    assert not p.samples.flags.writeable


# --- read_probe ----------------------------------------------------------------------------


def _sweep() -> Probe:
    return linear_sweep(3000.0, 9000.0, 0.02, fs=FS)


def test_read_probe_mono_round_trip(tmp_path):
    p = _sweep()
    f = tmp_path / "probe.wav"
    sf.write(f, p.samples, int(FS), subtype="FLOAT")
    q = read_probe(f)
    assert q.fs == FS and q.name == str(f)
    assert len(q.samples) == len(p.samples)
    assert np.max(np.abs(q.samples - p.samples)) < 1e-7  # float32 in the file


def test_read_probe_channel_selection_and_errors(tmp_path):
    p = _sweep()
    f = tmp_path / "stereo.wav"
    sf.write(f, np.stack([0.5 * p.samples, p.samples], axis=1), int(FS), subtype="FLOAT")
    q = read_probe(f, channel=1)
    assert np.max(np.abs(q.samples - p.samples)) < 1e-7
    assert np.max(np.abs(read_probe(f, channel=0).samples - 0.5 * p.samples)) < 1e-7
    with pytest.raises(AudioFormatError, match="2 channels") as e:
        read_probe(f)
    assert "stereo.wav" in str(e.value)
    with pytest.raises(AudioFormatError, match="no channel 2"):
        read_probe(f, channel=2)
    with pytest.raises(InputFileError, match="no such file"):
        read_probe(tmp_path / "missing.wav")


def test_read_probe_silent_file_is_refused(tmp_path):
    f = tmp_path / "silent.wav"
    sf.write(f, np.zeros(1000), int(FS), subtype="PCM_16")
    with pytest.raises(AudioFormatError, match="silent") as e:
        read_probe(f)
    assert "silent.wav" in str(e.value)


def test_read_probe_drops_trailing_silence_keeps_leading(tmp_path):
    """Sample 0 of the file is the emission's start: leading zeros are part of the probe."""
    p = _sweep()
    lead, tail = 300, 2000
    f = tmp_path / "padded.wav"
    x = np.concatenate([np.zeros(lead), p.samples, np.zeros(tail)])
    sf.write(f, x, int(FS), subtype="FLOAT")
    q = read_probe(f)
    last = int(np.flatnonzero(p.samples)[-1])
    assert len(q.samples) == lead + last + 1
    assert np.all(q.samples[:lead] == 0.0)
    assert np.max(np.abs(q.samples[lead:] - p.samples[: last + 1])) < 1e-7


# --- at_rate -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("f0", "f1", "fs_from", "fs_to"),
    [
        (17000.0, 20000.0, 44100.0, 48000.0),
        (20.0, 20000.0, 44100.0, 48000.0),
        (20000.0, 17000.0, 44100.0, 96000.0),
        (17000.0, 20000.0, 48000.0, 44100.0),
    ],
)
def test_at_rate_equals_the_sweep_sampled_at_the_new_rate(f0, f1, fs_from, fs_to):
    """Resampled = the analytic sweep at fs_to (same t = 0), away from the fades.

    The fades differ at the two rates (the ramp is defined per sample), so the check
    starts and ends 6 ms in. A relative error of 1e-3 at 20 kHz would also be a time
    shift of 8 ns: sample 0 stays at t = 0.
    """
    T = 0.1
    p = linear_sweep(f0, f1, T, fs=fs_from)
    y = p.at_rate(fs_to)
    want = linear_sweep(f0, f1, T, fs=fs_to).samples
    assert len(y) == len(want) == int(round(T * fs_to))
    edge = int(0.006 * fs_to)
    err = np.max(np.abs(y - want)[edge:-edge]) / 0.5
    assert err < 1e-3, err
    # The time origin directly: the lag that best aligns y with the analytic sweep is 0.
    lags = np.arange(-3, 4)
    mid = slice(edge, len(y) - edge)
    fit = [np.sum((np.roll(y, k)[mid] - want[mid]) ** 2) for k in lags]
    assert lags[int(np.argmin(fit))] == 0


def test_at_rate_same_rate_is_a_copy():
    p = _sweep()
    y = p.at_rate(FS)
    assert np.array_equal(y, p.samples) and y.flags.writeable


def test_at_rate_refuses_a_band_above_nyquist_naming_probe_and_rate():
    p = linear_sweep(17000.0, 20000.0, 0.1, fs=FS, fade_s=0.0)
    with pytest.raises(IncompatibleInputError) as e:
        p.at_rate(32000.0, what="'rec32.wav'")
    msg = str(e.value)
    for part in ("sweep 17000-20000 Hz", "rec32.wav", "32000 Hz", "16.00 kHz"):
        assert part in msg, (part, msg)
    with pytest.raises(IncompatibleInputError):
        p.check_fits(40000.0)  # Nyquist 20 kHz: the band's top sits on it
    p.check_fits(44100.0)
