"""rangekit.signals.design: one call per ``rangekit design`` signal, the samples the old
command built itself, and the sweep's checks in the caller's names (check_sweep)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import soundfile as sf

from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.signals import Beep
from rangekit.signals.barker import CodedBurst, burst_waveform
from rangekit.signals.beep import beep_continuous, beep_waveform
from rangekit.signals.design import design_barker, design_beep, design_sweep
from rangekit.signals.probe import SweepError, check_sweep, linear_sweep

NAMES = {"f0_hz": "--f0", "f1_hz": "--f1", "duration_s": "--duration", "fs": "--fs"}
NAMES["fade_s"] = "--fade"


@pytest.mark.parametrize("fs", [None, 44100.0, 48000.0, 96000.0])
def test_beep_is_the_continuous_beep_at_the_files_rate(fs):
    beep = Beep(f_hz=17000.0, amplitude=0.5)
    d = design_beep(beep, fs=fs)
    rate = beep.fs if fs is None else fs
    n = math.ceil(beep.duration_s * rate)
    assert d.signal is beep and d.fs == rate and d.samples.shape == (n,)
    np.testing.assert_array_equal(d.samples, beep_continuous(np.arange(n) / rate, beep=beep))


def test_beep_at_its_own_rate_is_its_waveform():
    d = design_beep()
    np.testing.assert_array_equal(d.samples, beep_waveform(Beep()))


def test_beep_rate_too_low_names_the_rate_as_asked():
    with pytest.raises(IncompatibleInputError) as e:
        design_beep(fs=22050.0, what="--fs")
    assert str(e.value) == (
        "--fs sample rate 22050 Hz is too low for the 16000 Hz beep (needs more than 36009.1 Hz)"
    )


def test_barker_is_the_burst_waveform():
    burst = CodedBurst((1.0, -1.0, 1.0), 40000.0, 4, 0.7, 192000.0)
    d = design_barker(burst)
    assert d.signal is burst and d.fs == 192000.0
    np.testing.assert_array_equal(d.samples, burst_waveform(burst))
    np.testing.assert_array_equal(design_barker().samples, burst_waveform(CodedBurst()))


def test_sweep_is_linear_sweep():
    d = design_sweep(6000.0, 2000.0, 0.05, fs=16000.0, fade_s=0.01, amplitude=0.9, names=NAMES)
    want = linear_sweep(6000.0, 2000.0, 0.05, fs=16000.0, fade_s=0.01, amplitude=0.9)
    assert d.fs == 16000.0 and d.signal.name == want.name
    np.testing.assert_array_equal(d.samples, want.samples)


def test_write_is_16_bit_pcm(tmp_path):
    d = design_sweep(2000.0, 6000.0, 0.1)
    d.write(tmp_path / "s.wav")
    info = sf.info(tmp_path / "s.wav")
    assert (info.samplerate, info.channels, info.subtype, info.frames) == (44100, 1, "PCM_16", 4410)
    back, _ = sf.read(tmp_path / "s.wav")
    assert np.max(np.abs(back - d.samples)) < 1.5 / 32767  # one 16-bit step


# Library messages: those linear_sweep gave before the checks moved to check_sweep.
LIBRARY = [
    ((9000.0, 2000.0, 0.1, 16000.0, None),
     "f0_hz=9000 Hz is not below the Nyquist frequency 8000 Hz of fs=16000"),
    ((2000.0, 8000.0, 0.1, 16000.0, None),
     "f1_hz=8000 Hz is not below the Nyquist frequency 8000 Hz of fs=16000"),
    ((3000.0, 3000.0, 0.1, 44100.0, None), "f0_hz and f1_hz are both 3000 Hz; a sweep needs two"),
    ((2000.0, 6000.0, 0.1, 44100.0, 0.06), "fade_s=0.06 must be within [0.0, 0.05]"),
    ((2000.0, 6000.0, 0.0, 44100.0, None), "duration_s=0.0 must be within [0.001, 600.0]"),
]  # fmt: skip
# The same in the CLI's names: (parameter, reason) as design sweep's usage errors show them.
NAMED = [
    ("--f0", "9000 Hz is not below the Nyquist frequency 8000 Hz of --fs 16000"),
    ("--f1", "8000 Hz is not below the Nyquist frequency 8000 Hz of --fs 16000"),
    (None, "--f0 and --f1 are both 3000 Hz; a sweep needs two frequencies"),
    ("--fade", "0.06 s is longer than half of --duration 0.1 s"),
]


@pytest.mark.parametrize(("args", "msg"), LIBRARY)
def test_library_messages(args, msg):
    f0, f1, dur, fs, fade = args
    for call in (linear_sweep, check_sweep, design_sweep):
        with pytest.raises(InvalidParameterError) as e:
            call(f0, f1, dur, fs=fs, fade_s=fade)
        assert str(e.value) == msg
        assert not isinstance(e.value, SweepError)


PAIRS = list(zip([a for a, _ in LIBRARY[:4]], NAMED, strict=True))


@pytest.mark.parametrize(("args", "want"), PAIRS)
def test_messages_in_the_callers_names(args, want):
    f0, f1, dur, fs, fade = args
    for call in (check_sweep, design_sweep):
        with pytest.raises(SweepError) as e:
            call(f0, f1, dur, fs=fs, fade_s=fade, names=NAMES)
        assert (e.value.param, e.value.reason) == want
        assert e.value.exit_code == 2


def test_a_name_without_a_dash_is_shown_as_a_keyword():
    with pytest.raises(SweepError) as e:
        check_sweep(9000.0, 2000.0, 0.1, fs=16000.0, names={"f0_hz": "start", "fs": "rate"})
    assert str(e.value) == "start: 9000 Hz is not below the Nyquist frequency 8000 Hz of rate=16000"


def test_check_sweep_fills_the_default_fade():
    assert check_sweep(2000.0, 6000.0, 0.02) == (44100.0, 2000.0, 6000.0, 0.02, 0.002)
    assert check_sweep(2000.0, 6000.0, 0.1, fade_s=0.05, names=NAMES)[4] == 0.05  # half: allowed
