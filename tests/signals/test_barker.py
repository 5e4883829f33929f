"""Barker-coded bursts, the SRF02 ping and the resonant transducer model."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import freqz

from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.signals.barker import (
    BARKER_CODES,
    CodedBurst,
    burst_continuous,
    burst_waveform,
    check_burst_fits,
    srf02_ping,
)
from rangekit.signals.transducer import Transducer, apply_chain

FS = 192000.0


# --- Barker codes ---------------------------------------------------------------------


@pytest.mark.parametrize("n", sorted(BARKER_CODES))
def test_barker_autocorrelation_side_lobes_at_most_one(n):
    code = np.array(BARKER_CODES[n])
    assert len(code) == n and set(code.tolist()) <= {-1, 1}
    r = np.correlate(code, code, mode="full")
    assert r[n - 1] == n
    side = np.delete(r, n - 1)
    assert np.max(np.abs(side)) <= 1


def test_default_burst_is_kim_and_kim_barker7():
    b = CodedBurst()
    assert b.code == BARKER_CODES[7]
    assert (b.carrier_hz, b.cycles_per_bit, b.fs) == (40000.0, 3, FS)
    assert b.duration_s == pytest.approx(21 / 40000.0)
    assert len(burst_waveform(b)) == b.duration_samples == 101


# --- validation -----------------------------------------------------------------------


@pytest.mark.parametrize(
    "code",
    [(), (1, 0, -1), (1, 2), (1, -1, 0.5), ("a", 1), None],
    ids=["empty", "zero", "two", "half", "text", "none"],
)
def test_bad_chips_refused(code):
    with pytest.raises(InvalidParameterError, match="code="):
        CodedBurst(code=code)


def test_chips_normalised_to_int_tuple():
    b = CodedBurst(code=[1.0, -1.0, np.int64(1)])
    assert b.code == (1, -1, 1) and all(type(c) is int for c in b.code)


@pytest.mark.parametrize("fs", [96000.0, 44100.0, 106000.0])
def test_fs_too_low_refused_naming_fs(fs):
    with pytest.raises(InvalidParameterError, match=rf"fs={fs:g} Hz") as e:
        CodedBurst(fs=fs)
    assert "Nyquist" in str(e.value) and "needs fs > 106667 Hz" in str(e.value)
    with pytest.raises(InvalidParameterError, match="fs="):
        CodedBurst().with_fs(fs)


def test_fs_just_above_the_band_accepted():
    assert CodedBurst(fs=107000.0).fs == 107000.0


def test_check_burst_fits_names_the_input():
    with pytest.raises(IncompatibleInputError, match=r"'rec\.wav' sample rate 96000 Hz"):
        check_burst_fits(CodedBurst(), fs=96000.0, what="'rec.wav'")
    check_burst_fits(CodedBurst(), fs=FS)  # no error


@pytest.mark.parametrize(
    ("kw", "name"),
    [
        ({"carrier_hz": 0.0}, "carrier_hz"),
        ({"carrier_hz": math.nan}, "carrier_hz"),
        ({"cycles_per_bit": 0}, "cycles_per_bit"),
        ({"cycles_per_bit": 2.5}, "cycles_per_bit"),
        ({"amplitude": 1.5}, "amplitude"),
        ({"amplitude": 0.0}, "amplitude"),
        ({"fs": -1.0}, "fs"),
    ],
)
def test_numeric_fields_validated(kw, name):
    with pytest.raises(InvalidParameterError, match=name):
        CodedBurst(**kw)


# --- waveform ---------------------------------------------------------------------------


@pytest.mark.parametrize("n", [7, 13, 2])
def test_waveform_continuous_at_chip_boundaries(n):
    b = CodedBurst(code=BARKER_CODES[n])
    tc = 1.0 / b.chip_rate_hz
    eps = 1e-9 * tc
    for k in range(n + 1):
        t = np.array([k * tc - eps, k * tc + eps])
        # sin is zero on every chip boundary (and at the start and end): no step.
        assert np.max(np.abs(burst_continuous(t, burst=b))) < 1e-6
    # Sampled: no step larger than the carrier's steepest slope allows.
    x = burst_waveform(b)
    max_step = b.amplitude * 2 * math.pi * b.carrier_hz / b.fs
    assert np.max(np.abs(np.diff(x))) <= max_step * (1 + 1e-9)


def test_chip_signs_follow_the_code():
    b = CodedBurst()
    tc = 1.0 / b.chip_rate_hz
    # A quarter carrier cycle into each chip sin() = +1: the sample is amplitude * chip.
    t = np.arange(7) * tc + 0.25 / b.carrier_hz
    np.testing.assert_allclose(burst_continuous(t, burst=b), b.amplitude * np.array(b.code))
    outside = burst_continuous(np.array([-1e-6, b.duration_s, b.duration_s + 1e-5]), burst=b)
    assert not np.any(outside)


def test_srf02_ping_is_eight_cycles_of_40khz():
    p = srf02_ping()
    assert p.code == (1,) and p.cycles_per_bit == 8 and p.carrier_hz == 40000.0
    assert p.duration_s == pytest.approx(8 / 40000.0)
    t = np.linspace(0.0, 2 * p.duration_s, 200001)
    x = burst_continuous(t, burst=p)
    positive_lobes = np.count_nonzero(np.diff((x > 1e-9).astype(int)) == 1)
    assert positive_lobes == 8
    assert np.max(x) == pytest.approx(p.amplitude, rel=1e-6)


# --- transducer -------------------------------------------------------------------------


def _gain_db(t: Transducer, f_hz, fs=FS):
    b, a = t.coefficients(fs=fs)
    _, h = freqz(b, a, worN=np.atleast_1d(np.asarray(f_hz, dtype=float)), fs=fs)
    return 20 * np.log10(np.abs(h))


@pytest.mark.parametrize("q", [2.0, 4.0, 10.0])
def test_transducer_unit_gain_at_resonance(q):
    t = Transducer(q=q)
    assert abs(_gain_db(t, t.f0_hz)[0]) < 1e-9
    f = np.linspace(20000.0, 60000.0, 2001)
    assert np.max(_gain_db(t, f)) <= 1e-9  # the peak is the resonance


@pytest.mark.parametrize("q", [2.0, 4.0, 10.0])
@pytest.mark.parametrize("fs", [FS, 500e3])
def test_transducer_minus_3db_band_is_f0_over_q(q, fs):
    # Centre and bandwidth are both prewarped: the digital -3 dB band is exactly f0 / Q
    # wide at any rate, with edges geometrically symmetric in the warped frequency.
    t = Transducer(q=q)
    f = np.linspace(t.f0_hz - 2 * t.bandwidth_hz, t.f0_hz + 2 * t.bandwidth_hz, 400001)
    f = f[f > 0]
    inside = f[_gain_db(t, f, fs=fs) >= -10 * math.log10(2)]
    step = f[1] - f[0]
    assert inside[-1] - inside[0] == pytest.approx(t.bandwidth_hz, abs=2 * step)
    w = np.tan(np.pi * np.array([inside[0], inside[-1]]) / fs)
    assert math.sqrt(w[0] * w[1]) == pytest.approx(math.tan(math.pi * t.f0_hz / fs), rel=1e-4)


def test_transducer_is_causal_and_delays():
    t = Transducer()
    x = np.zeros(600)
    x[200] = 1.0
    y = t.apply(x, fs=FS)
    assert not np.any(y[:200])
    assert y[200] != 0.0
    # Filtering a 40 kHz tone burst delays its envelope by about the group delay.
    # The analogue resonator's group delay at resonance is Q / (pi f0) = 31.8 us.
    assert t.group_delay_s(fs=FS) == pytest.approx(t.q / (math.pi * t.f0_hz), rel=0.02)
    assert 0 < t.group_delay_s(fs=FS, f_hz=30000.0) < t.group_delay_s(fs=FS)


def test_transducer_2d_and_chain():
    t = Transducer()
    x = np.random.default_rng(0).standard_normal((2, 300))
    y = t.apply(x, fs=FS)
    np.testing.assert_allclose(y[1], t.apply(x[1], fs=FS))
    np.testing.assert_allclose(apply_chain(x[0], (t, None, t), fs=FS), t.apply(y[0], fs=FS))


@pytest.mark.parametrize(
    ("kw", "fs", "name"),
    [({"q": 0.1}, FS, "q="), ({"f0_hz": -4.0}, FS, "f0_hz"), ({"f0_hz": 100e3}, FS, "f0_hz")],
)
def test_transducer_validation(kw, fs, name):
    with pytest.raises(InvalidParameterError, match=name):
        Transducer(**kw).coefficients(fs=fs)
