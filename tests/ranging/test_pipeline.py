"""``rangekit.ranging.pipeline``: recordings to two-way ranges (issue 21: the mutation check
of the module). Each test pins what the entry point promises: the range of a rendered
exchange is its true distance, the self-distance and the speed of sound enter as BeepBeep's
formula says (Peng et al. 2007, eq. 4: ``d = c/2 (dt_B - dt_A) + (d_AA + d_BB)/2``), the
configuration objects replace the loose keywords, a failed detection says why (count,
spacing, probe) and every device's probe filter is weighted by one common noise spectrum.
Rendered by rangekit's simulator (the accuracy evidence is elsewhere: ``test_front.py``,
``test_template_rooms.py``, ``test_impairments.py``); about 3 s.
"""

from __future__ import annotations

import numpy as np
import pytest

from rangekit.errors import DetectionError, InvalidParameterError
from rangekit.io.audio import Channel, write_audio
from rangekit.physics import Medium, speed_of_sound_m_s
from rangekit.ranging import pipeline as P
from rangekit.ranging.calibration import Calibration
from rangekit.ranging.config import TwoWaySetup
from rangekit.signals.beep import Beep
from rangekit.signals.probe import linear_sweep
from rangekit.sim.recording import pair_devices, render_beepbeep

FS = 44100.0
D_M, SELF_M = 2.0, 0.1


def _channels(sim, name: str) -> list[Channel]:
    pairs = zip(sim.recordings, sim.fs, strict=True)
    return [Channel(x, f, name.format(i)) for i, (x, f) in enumerate(pairs)]


@pytest.fixture(scope="module")
def chans():
    sim = render_beepbeep(pair_devices(D_M, self_distance_m=SELF_M), snr_db=30.0, rng=4)
    return _channels(sim, "dev{}.wav")


@pytest.fixture(scope="module")
def base(chans):
    return P.range_channels(chans, self_distance_m=SELF_M)


def test_range_is_the_true_distance_within_sigma(base):
    (r,) = base.ranges
    assert (r.a, r.b) == (0, 1)
    assert abs(r.distance_m - D_M) < 3 * r.sigma_m and abs(r.distance_m - D_M) < 0.01
    assert 0 < r.sigma_m < 0.01  # measured ~1 mm
    assert base.speed_m_s == speed_of_sound_m_s(20.0)


def test_self_distance_enters_as_the_mean_of_both(chans, base):
    """Peng 2007 eq. 4: the range moves by the mean of the two devices' self-distances."""
    d0 = base.ranges[0].distance_m
    r = P.range_channels(chans, self_distance_m=SELF_M + 0.05).ranges[0]
    assert r.distance_m - d0 == pytest.approx(0.05, abs=1e-12)
    r = P.range_channels(chans, self_distance_m=[SELF_M, SELF_M + 0.1]).ranges[0]
    assert r.distance_m - d0 == pytest.approx(0.05, abs=1e-12)
    r = P.range_channels(chans, setup=TwoWaySetup((SELF_M + 0.1, SELF_M))).ranges[0]
    assert r.distance_m - d0 == pytest.approx(0.05, abs=1e-12)


def test_speed_of_sound_scales_the_time_term(chans, base):
    d0 = base.ranges[0].distance_m - SELF_M
    c0 = base.speed_m_s
    for kw, c in [({"speed_m_s": 350.0}, 350.0), ({"temp_c": 30.0}, speed_of_sound_m_s(30.0)),
                  ({"medium": Medium(temp_c=0.0)}, speed_of_sound_m_s(0.0)),
                  ({"medium": Medium(speed_m_s=330.0), "speed_m_s": 350.0}, 330.0)]:  # fmt: skip
        res = P.range_channels(chans, self_distance_m=SELF_M, **kw)
        assert res.speed_m_s == c
        assert res.ranges[0].distance_m - SELF_M == pytest.approx(d0 * c / c0, rel=1e-12)


def test_clock_tolerance_widens_sigma_only(chans, base):
    r0 = P.range_channels(chans, self_distance_m=SELF_M, clock_ppm=0.0).ranges[0]
    r1 = P.range_channels(chans, self_distance_m=SELF_M, clock_ppm=1000.0).ranges[0]
    r2 = P.range_channels(chans, setup=TwoWaySetup(SELF_M, clock_ppm=1000.0)).ranges[0]
    assert r0.distance_m == r1.distance_m == base.ranges[0].distance_m
    assert r1.sigma_m > r0.sigma_m and r2.sigma_m == r1.sigma_m


def test_detectors_and_bad_detector(chans):
    r = P.range_channels(chans, self_distance_m=SELF_M, detector="xcorr").ranges[0]
    assert abs(r.distance_m - D_M) < 0.02
    with pytest.raises(InvalidParameterError, match="detector='nope' must be one of"):
        P.range_channels(chans, detector="nope")


def _cal(scheme="beepbeep", offset=0.1):
    return Calibration(scheme, "offset", offset_m=offset, sigma_offset_m=0.001,
                       latency_s=offset / 343.0, sigma_latency_s=0.001 / 343.0,
                       speed_m_s=343.0, sigma_speed_m_s=0.0, cov_speed_offset=0.0,
                       n_recordings=3, distances_m=(1.0, 2.0), rms_residual_m=0.001)  # fmt: skip


def test_calibration_replaces_the_self_distance(chans, base):
    r = P.range_channels(chans, calibration=_cal(offset=SELF_M)).ranges[0]
    assert r.distance_m == pytest.approx(base.ranges[0].distance_m, abs=1e-9)
    with pytest.raises(InvalidParameterError, match="not both"):
        P.range_channels(chans, calibration=_cal(), self_distance_m=SELF_M)
    with pytest.raises(InvalidParameterError, match="not both"):
        P.range_channels(chans, calibration=_cal(), self_distance_m=[0.0, 0.1])
    with pytest.raises(InvalidParameterError, match="for --scheme oneway"):
        P.range_channels(chans, calibration=_cal("oneway"))


def test_count_mismatch_says_what_was_found(chans):
    noise = Channel(np.random.default_rng(0).normal(0, 0.01, len(chans[0].x)), FS, "n.wav")
    with pytest.raises(DetectionError) as e:
        P.range_channels([noise, Channel(noise.x.copy(), FS, "m.wav")])
    msg = str(e.value)
    assert "'n.wav': found no beep but expected 2 (one per device)" in msg
    assert "; 'm.wav': found no beep" in msg  # every device's failure, joined
    with pytest.raises(DetectionError, match=r"found 2 beeps but expected 1 \(one per device\); "
                       "is this one exchange"):  # fmt: skip
        P.detect_channel(chans[0], expected=1)
    with pytest.raises(DetectionError, match=r"'dev0.wav': found 2 beep\(s\) but expected 3"):
        P.detect_channel(chans[0], expected=3)
    assert len(P.detect_channel(chans[0], expected=2)) == 2
    assert len(P.detect_channel(chans[0])) == 2


def test_spacing_hint_explains_a_wrong_spacing():
    b = Beep()
    want = b.spacing  # samples
    assert P._spacing_hint(np.array([100.0]), beep=b, fs=FS) == ""
    ok = np.array([0.0, 1.0, 2.0, 3.0]) * want + 1000.0
    assert P._spacing_hint(ok, beep=b, fs=FS) == ""
    # within a quarter burst of the spacing is a fit
    assert P._spacing_hint(ok * 1.0 + np.array([0, 1, 2, 3]) * 0.2 * b.burst_len, beep=b,
                           fs=FS) == ""  # fmt: skip
    far = np.array([0.0, 1.0, 2.0, 3.0]) * 1.6 * want
    hint = P._spacing_hint(far[::-1], beep=b, fs=FS)  # order does not matter
    assert hint == (
        f"; burst spacing does not fit: bursts are {1.6 * want:.0f} samples apart but the "
        f"beep's spacing is {want:.0f} samples ({b.spacing_s * 1e3:.1f} ms); check --spacing"
    )
    # the rule's edges: a gap of exactly 0.3 spacings is an echo, not a spacing; a spacing
    # off by exactly a quarter burst still fits
    assert P._spacing_hint(np.array([0.0, 0.3 * b.spacing_s * FS]), beep=b, fs=FS) == ""
    # half a spacing is a (wrong) spacing, not an echo
    assert f"bursts are {0.5 * want:.0f} samples apart" in P._spacing_hint(
        np.array([0.0, 0.5 * want]), beep=b, fs=FS
    )
    quarter = 0.25 * b.burst_s * FS
    assert P._spacing_hint(np.array([0.0, want + quarter]), beep=b, fs=FS) == ""
    assert P._spacing_hint(np.array([0.0, want + quarter + 0.01]), beep=b, fs=FS) != ""
    # two bursts are enough to see a spacing
    assert "bursts are 8000 samples apart" in P._spacing_hint(
        np.array([0.0, 8000.0]), beep=b, fs=FS
    )
    # gaps under 0.3 spacings (a burst's own echo) are not spacings; none left: no hint
    assert P._spacing_hint(np.array([0.0, 0.2]) * want, beep=b, fs=FS) == ""
    mixed = np.array([0.0, 0.1, 1.6, 1.7, 3.2]) * want  # spacings 1.5, echoes 0.1
    assert f"bursts are {1.5 * want:.0f} samples apart" in P._spacing_hint(mixed, beep=b, fs=FS)


def test_wrong_spacing_reaches_the_error(chans):
    with pytest.raises(DetectionError, match="burst spacing does not fit"):
        P.detect_channel(chans[0], beep=Beep(spacing=7000), expected=2)
    with pytest.raises(DetectionError, match="burst spacing does not fit"):  # the beep given
        P.range_channels(chans, beep=Beep(spacing=7000))


@pytest.fixture(scope="module")
def sweep_chans():
    probe = linear_sweep(17000.0, 20000.0, 0.05)
    sim = render_beepbeep(pair_devices(1.5, self_distance_m=0.05), beep=probe, snr_db=25.0,
                          lead_s=0.05, gap_s=0.1, tail_s=0.05, rng=2)  # fmt: skip
    return probe, _channels(sim, "s{}")


def test_probe_ranges_with_one_common_spectrum(sweep_chans, monkeypatch):
    from rangekit.detect.matched import common_spectra
    from rangekit.detect.template import noise_spectra

    probe, ch = sweep_chans
    seen = []
    real = P.detect

    def spy(x, **kw):
        seen.append(kw)
        return real(x, **kw)

    monkeypatch.setattr(P, "detect", spy)
    r = P.range_channels(ch, probe=probe, self_distance_m=0.05).ranges[0]
    assert abs(r.distance_m - 1.5) < 0.01
    assert [k["method"] for k in seen] == ["template", "template"]
    assert seen[0]["spectra"] is seen[1]["spectra"]
    want = common_spectra([noise_spectra(c.x, fs=c.fs, probe=probe) for c in ch])
    np.testing.assert_array_equal(seen[0]["spectra"].noise, want.noise)
    # a beep is detected by the detector asked for, without spectra
    seen.clear()
    P.detect_channel(ch[0], beep=Beep(), detector="xcorr")
    assert seen[0]["method"] == "xcorr" and "spectra" not in seen[0]


def test_common_spectra_none_when_rates_or_grids_differ(sweep_chans):
    probe, ch = sweep_chans
    assert P._common_spectra(ch, probe) is not None
    other = Channel(ch[1].x, 48000.0, "r")
    assert P._common_spectra([ch[0], other], probe) is None
    short = Channel(ch[1].x[:3000], ch[1].fs, "short")
    assert P._common_spectra([ch[0], short], probe) is None


def test_probe_count_mismatch_names_the_probe(sweep_chans):
    probe, ch = sweep_chans
    with pytest.raises(DetectionError, match=r"found 2 arrival\(s\) of probe .* but expected 3"):
        P.detect_channel(ch[0], probe=probe, expected=3)
    quiet = Channel(np.random.default_rng(1).normal(0, 0.01, len(ch[0].x)), ch[0].fs, "q")
    with pytest.raises(DetectionError, match="found no arrival of probe"):
        P.detect_channel(quiet, probe=probe, expected=2)


def test_range_files(tmp_path, chans, base):
    path = tmp_path / "ex.wav"
    write_audio(path, np.stack([c.x for c in chans], axis=1), fs=FS)
    r = P.range_files([path], self_distance_m=SELF_M).ranges[0]
    assert r.distance_m == pytest.approx(base.ranges[0].distance_m, abs=1e-3)  # 16-bit file
    with pytest.raises(InvalidParameterError, match="scheme='oneway' must be 'beepbeep'"):
        P.range_files([path], scheme="oneway")
