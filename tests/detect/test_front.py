"""The one detection front end: every signal and method through rangekit.detect.detect."""

from __future__ import annotations

import numpy as np
import pytest

from rangekit.detect import DETECTORS, METHODS, detect, detect_changepoint, detect_xcorr
from rangekit.detect.matched import coded_template
from rangekit.detect.template import detect_template
from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.io.audio import Channel, write_audio
from rangekit.ranging.pipeline import detect_channel, range_files
from rangekit.ranging.series import range_series_beepbeep
from rangekit.signals import SIGNAL_KINDS, Beep, CodedBurst, Probe, linear_sweep, signal_kind
from rangekit.signals.transducer import Transducer
from rangekit.sim.recording import pair_devices, render_beepbeep

FS = 44100.0


@pytest.fixture(scope="module")
def exchange():
    """A 3 m two-way exchange at 20 dB SNR: (stacked recordings, fs)."""
    sim = render_beepbeep(
        pair_devices(3.0, self_distance_m=0.1), snr_db=20.0, rng=np.random.default_rng(4)
    )
    return np.stack(sim.recordings, axis=1), FS


def _same(a, b):
    assert len(a) == len(b) > 0
    np.testing.assert_array_equal(a.onset, b.onset)
    np.testing.assert_array_equal(a.sigma, b.sigma)
    np.testing.assert_array_equal(a.flags, b.flags)


def test_every_signal_has_the_interface():
    """band / check_fits / samples_at / as_probe / kind on each kind, consistent."""
    sigs = [Beep(), CodedBurst(), linear_sweep(500.0, 5000.0, 0.1)]
    assert [signal_kind(s) for s in sigs] == list(SIGNAL_KINDS) == list(METHODS)
    for s in sigs:
        lo, hi = s.band()
        assert 0 < lo < hi < s.fs / 2
        p = s.as_probe()
        assert isinstance(p, Probe) and p.fs == s.fs
        np.testing.assert_array_equal(s.samples_at(s.fs), p.samples)
        assert abs(len(p.samples) / p.fs - s.duration_s) < 1.0 / s.fs
        with pytest.raises(IncompatibleInputError):
            s.check_fits(2.0 * lo, what="'x.wav'")
    # The beep resampled keeps its band: energy above the band's top is tiny.
    y = Beep().samples_at(48000.0)
    spec = np.abs(np.fft.rfft(y)) ** 2
    f = np.fft.rfftfreq(len(y), 1 / 48000.0)
    assert spec[f > Beep().band()[1] + 2000].sum() < 1e-6 * spec.sum()


@pytest.mark.parametrize("method", DETECTORS)
def test_beep_methods_are_the_detectors(exchange, method):
    """detect(signal=beep, method=m) is exactly that detector's answer."""
    x, fs = exchange
    got = detect(x[:, 0], fs=fs, signal=Beep(), method=method, expected=2)
    if method == "changepoint":
        want = detect_changepoint(x[:, 0], fs=fs, beep=Beep(), expected=2)
    else:
        want = detect_xcorr(x[:, 0], fs=fs, beep=Beep(), max_beeps=2)
    _same(got, want)
    # The older spelling gives the same.
    _same(detect(x[:, 0], fs=fs, beep=Beep(), detector=method, expected=2), got)


def test_methods_agree_on_the_onsets(exchange):
    """The beep methods find the same two onsets within a sample (20 dB, free field)."""
    x, fs = exchange
    ons = [detect(x[:, 1], fs=fs, method=m, expected=2).onset for m in DETECTORS]
    assert all(len(o) == 2 for o in ons)
    spread = np.ptp(np.array(ons), axis=0)
    assert np.all(spread < 1.0), spread


def test_probe_and_coded_burst_go_through_the_template():
    rng = np.random.default_rng(2)
    p = linear_sweep(2000.0, 6000.0, 0.05, fs=FS)
    x = np.zeros(20000)
    x[5000 : 5000 + len(p.samples)] += 0.5 * p.samples
    x += 1e-3 * rng.standard_normal(len(x))
    _same(detect(x, fs=FS, signal=p), detect_template(x, fs=FS, probe=p))
    a = detect(x, fs=FS, signal=p, expected=1)
    assert len(a) == 1 and abs(a.onset[0] - 5000.0) < 0.2
    # A coded burst: the drive through rangekit's transducers at both ends, 700.3 samples in.
    fs = 192000.0
    h = coded_template(CodedBurst(), fs=fs, tx=Transducer(), rx=Transducer())
    n = np.arange(len(h))
    y = np.zeros(6000)
    k = np.arange(len(y))
    # A fractional delay by a windowed-sinc interpolator of the template.
    for i, v in zip(n, h, strict=True):
        y += v * np.sinc(k - 700.3 - i) * (np.abs(k - 700.3 - i) < 64)
    y += 1e-3 * rng.standard_normal(len(y))
    b = detect(y, fs=fs, signal=CodedBurst(), expected=1)
    assert len(b) == 1 and abs(b.onset[0] - 700.3) < 0.1, b.onset


def test_front_end_errors():
    x = np.zeros(20000)
    p = linear_sweep(2000.0, 6000.0, 0.05, fs=FS)
    with pytest.raises(InvalidParameterError, match="does not apply to a probe"):
        detect(x, fs=FS, signal=p, method="changepoint")
    # The beep's matched-filter lobe is 20 ms wide: the template method is not offered.
    with pytest.raises(InvalidParameterError, match="does not apply to a beep"):
        detect(x, fs=FS, method="template")
    with pytest.raises(InvalidParameterError, match="method='nope' must be one of"):
        detect(x, fs=FS, method="nope")
    with pytest.raises(InvalidParameterError, match="min_separation_s applies to the template"):
        detect(x, fs=FS, method="xcorr", min_separation_s=0.1)
    with pytest.raises(InvalidParameterError, match="signal or beep"):
        detect(x, fs=FS, signal=p, beep=Beep())
    with pytest.raises(InvalidParameterError, match="tx and rx apply to a coded burst"):
        detect(x, fs=FS, signal=p, tx=Transducer())
    with pytest.raises(InvalidParameterError, match="must be a Beep, CodedBurst or Probe"):
        detect(x, fs=FS, signal=np.ones(100))
    with pytest.raises(IncompatibleInputError, match=r"'a\.wav'"):
        detect(x, fs=FS, signal=CodedBurst(), what="'a.wav'")


def test_cli_detector_choices_are_the_detectors():
    """The CLI's --detector (hard-coded so --help does not import numba) is DETECTORS."""
    from rangekit_cli.detect_cmd import detect_cmd

    opt = next(p for p in detect_cmd.params if p.name == "detector")
    assert tuple(opt.type.choices) == DETECTORS


@pytest.mark.parametrize("method", DETECTORS)
def test_range_series_and_detect_agree(tmp_path, exchange, method):
    """Whole-file ranging, --series and detect see the same first paths."""
    x, fs = exchange
    path = tmp_path / "ex.wav"
    write_audio(path, x, fs=fs)
    whole = range_files([path], detector=method, self_distance_m=0.1).ranges[0]
    series = list(range_series_beepbeep([path], detector=method, self_distance_m=0.1))
    assert len(series) == 1
    s = series[0].ranges[0]
    assert abs(s.distance_m - whole.distance_m) <= 1e-12
    assert abs(whole.distance_m - 3.0) < 2 * whole.sigma_m
    for dev in range(2):
        ch = Channel(x=x[:, dev], fs=fs, source="ex.wav")
        a = detect_channel(ch, detector=method, expected=2)
        _same(a, detect(x[:, dev], fs=fs, method=method, expected=2))
