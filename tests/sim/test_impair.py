"""Tests for rangekit.sim.impair: levels against the reference floor, laws, order, parser.

Bounds sit within about 2x of what was measured on seeds 0-5 when they were written (the
measured spread is in each test's comment).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import butter, sosfreqz, welch

from rangekit.errors import InvalidParameterError
from rangekit.sim import pair_devices, render_beepbeep
from rangekit.sim.impair import (
    KEYS,
    Impairments,
    estimate_floor_psd,
    impair,
    interference_band_hz,
    noise_floor_psd,
    parse_impairments,
    shift_truth,
)
from rangekit.sim.noise import pink_noise
from rangekit.sim.ultrasonic import render_oneway

FS = 44100.0
SIGMA = 0.01
FLOOR = 2 * SIGMA**2 / FS  # one-sided PSD of white noise of std SIGMA


def _db(v):
    return 10.0 * np.log10(v)


def _noise(seed: int, seconds: float = 10.0, channels: int | None = None) -> np.ndarray:
    shape = int(seconds * FS) if channels is None else (int(seconds * FS), channels)
    return SIGMA * np.random.default_rng(seed).standard_normal(shape)


def _beep_band_excess_db(added: np.ndarray) -> float:
    """PSD of an added component in 12-20 kHz (the beep's band), dB re the floor."""
    f, p = welch(added, fs=FS, nperseg=4096)
    band = (f >= 12000) & (f <= 20000)
    return float(_db(p[band].mean() / FLOOR))


def _beep_band_change_db(x: np.ndarray, y: np.ndarray) -> float:
    """How much the 12-20 kHz PSD of ``y`` exceeds that of ``x``, dB."""
    f, px = welch(x, fs=FS, nperseg=4096)
    _, py = welch(y, fs=FS, nperseg=4096)
    band = (f >= 12000) & (f <= 20000)
    return float(_db(py[band].mean() / px[band].mean()))


# --- reference floor ----------------------------------------------------------------


@pytest.mark.parametrize("seed", range(3))
def test_floor_estimate_ignores_bursts_bumps_and_tones(seed):
    x = _noise(seed, seconds=3.0)
    t = np.arange(len(x)) / FS
    # Four 10 ms 16 kHz bursts (Hann-tapered, as the beep's are) 40 dB above the noise,
    # and a 3 kHz tone 20 dB above it.
    burst = 100 * SIGMA * np.hanning(441) * np.sin(2 * np.pi * 16000 * t[:441])
    for k in range(4):
        i0 = int((0.5 + 0.6 * k) * FS)
        x[i0 : i0 + 441] += burst
    x += 10 * SIGMA * np.sin(2 * np.pi * 3000 * t)
    # And a 50 ms broadband bump 30 dB above the noise (a mean over segments: +12 dB).
    i0 = int(1.2 * FS)
    x[i0 : i0 + 2205] += 30 * SIGMA * np.random.default_rng(100 + seed).standard_normal(2205)
    est = estimate_floor_psd(x, fs=FS)
    assert est.shape == (1,)
    # Measured on seeds 0-5: +0.12 ... +0.18 dB (the bump's segments move the median up).
    assert abs(_db(est[0] / FLOOR)) < 0.35


@pytest.mark.parametrize("seed", range(4))
def test_pink_floor_formula_matches_the_estimate(seed):
    n = int(3 * FS)
    y = 0.02 * pink_noise(n, rng=seed)
    known = noise_floor_psd(0.02, fs=FS, kind="pink", n_samples=n)
    # Measured on seeds 0-3: -0.17 ... +0.22 dB (0-9: up to +0.76 dB: pink_noise's exact
    # variance normalisation lets its strongest low bins move the level of the rest).
    assert abs(_db(estimate_floor_psd(y, fs=FS)[0] / known)) < 0.5


@pytest.mark.parametrize("distance_m", [0.5, 2.0, 5.0])
def test_render_truth_noise_sigma_gives_the_floor(distance_m):
    """The floor the CLI takes from the simulator is the one the estimator finds, although
    the own beep, 66 dB above the floor in its band, is in a third of the recording."""
    for seed in range(3):
        sim = render_beepbeep(pair_devices(distance_m), snr_db=20.0, rng=seed)
        for x, dev in zip(sim.recordings, sim.truth["devices"], strict=True):
            known = noise_floor_psd(dev["noise_sigma"], fs=FS)
            # Measured: +0.14 ... +0.30 dB (the beeps' spectral skirts).
            assert 0.05 < _db(estimate_floor_psd(x, fs=FS)[0] / known) < 0.5


# --- additive noises: levels in their bands, nothing in the beep's band -------------


@pytest.mark.parametrize("seed", range(3))
def test_lf_noise_level_and_band(seed):
    x = _noise(seed)
    r = impair(x, fs=FS, impairments=Impairments(lf_db=30.0), rng=seed, floor_psd=FLOOR)
    f, p = welch(r.x, fs=FS, nperseg=2**15)
    band = (f >= 20) & (f <= 200)
    # Measured on seeds 0-5: 29.91 ... 30.37 dB.
    assert abs(_db((p[band] - FLOOR).mean() / FLOOR) - 30.0) < 0.75
    # Brown below 200 Hz: 1/f^2 from 40 to 120 Hz is -9.5 dB.
    lo, hi = (f >= 35) & (f <= 45), (f >= 115) & (f <= 125)
    assert abs(_db(p[hi].mean() / p[lo].mean()) + 9.5) < 1.5
    assert abs(_beep_band_change_db(x, r.x)) < 0.5
    assert _beep_band_excess_db(r.x - x) < -140  # measured -148 dB


@pytest.mark.parametrize("seed", range(3))
def test_hum_power_harmonics_and_band(seed):
    x = _noise(seed)
    imp = Impairments(hum_db=30.0, hum_hz=60.0)
    r = impair(x, fs=FS, impairments=imp, rng=seed, floor_psd=FLOOR)
    hum = r.x - x
    assert _db(np.mean(hum**2) / (FLOOR * 200)) == pytest.approx(30.0, abs=1e-9)
    f, p = welch(r.x, fs=FS, nperseg=2**15)
    df = f[1] - f[0]
    band = (f >= 20) & (f <= 1100)
    # The PSD's view of the same power; measured 29.96 ... 30.03 dB.
    assert abs(_db((p[band] - FLOOR).sum() * df / (FLOOR * 200)) - 30.0) < 0.1
    # Harmonics fall 6 dB each (60 Hz vs 120 Hz vs 180 Hz); nothing above 1 kHz.
    spec = np.abs(np.fft.rfft(hum * np.hanning(len(hum))))
    fk = np.fft.rfftfreq(len(hum), 1 / FS)
    peak = [spec[np.abs(fk - k * 60.0) < 3].max() for k in (1, 2, 3, 16, 17)]
    assert 20 * np.log10(peak[1] / peak[0]) == pytest.approx(-6.0, abs=0.3)
    assert 20 * np.log10(peak[2] / peak[1]) == pytest.approx(-6.0, abs=0.3)
    assert peak[3] > 1e3 * peak[4]  # 960 Hz is a harmonic, 1020 Hz is not
    assert abs(_beep_band_change_db(x, r.x)) < 0.5
    assert _beep_band_excess_db(hum) < -150  # measured -157 dB


def test_hum_wanders_by_ten_percent():
    x = _noise(1, seconds=20.0)
    r = impair(x, fs=FS, impairments=Impairments(hum_db=40.0), rng=2, floor_psd=FLOOR)
    hum = r.x - x
    # RMS over whole mains cycles (20 ms): the envelope 1 + 0.1 sin(2 pi f_w t).
    rms = np.sqrt(np.mean(hum[: len(hum) // 882 * 882].reshape(-1, 882) ** 2, axis=1))
    swing = rms.max() / rms.min()
    assert swing == pytest.approx(1.1 / 0.9, rel=0.01)


@pytest.mark.parametrize("seed", range(3))
def test_pink_noise_level_follows_one_over_f(seed):
    x = _noise(seed)
    r = impair(x, fs=FS, impairments=Impairments(pink_db=20.0), rng=seed, floor_psd=FLOOR)
    f, p = welch(r.x, fs=FS, nperseg=2**14)
    for lo, hi in ((500, 2000), (4000, 16000)):
        band = (f >= lo) & (f <= hi)
        # PSD x f / 1 kHz is flat for 1/f; measured 19.31 ... 20.55 dB in both bands.
        level = _db(((p[band] - FLOOR) * f[band] / 1000).mean() / FLOOR)
        assert abs(level - 20.0) < 1.2, (lo, hi, level)


@pytest.mark.parametrize("kind", ["speech", "music"])
@pytest.mark.parametrize("seed", range(3))
def test_interference_level_and_band(kind, seed):
    x = _noise(seed)
    imp = Impairments(interference=kind, interference_db=10.0)
    r = impair(x, fs=FS, impairments=imp, rng=seed, floor_psd=FLOOR)
    lo, hi = interference_band_hz(imp, fs=FS)
    assert (lo, hi) == ((100.0, 4000.0) if kind == "speech" else (100.0, 8000.0))
    added = r.x - x
    assert _db(np.mean(added**2) / (FLOOR * (hi - lo))) == pytest.approx(10.0, abs=1e-9)
    f, p = welch(r.x, fs=FS, nperseg=2**14)
    band = (f >= lo) & (f <= hi)
    # In-band power seen by the PSD; measured 9.63 ... 10.30 dB.
    level = _db((p[band] - FLOOR).sum() * (f[1] - f[0]) / (FLOOR * (hi - lo)))
    assert abs(level - 10.0) < 0.75
    assert abs(_beep_band_change_db(x, r.x)) < 0.5
    # Measured: speech -55.5 ... -55.8 dB, music -112 ... -117 dB.
    assert _beep_band_excess_db(added) < (-52.0 if kind == "speech" else -105.0)


def test_speech_has_syllables_and_pauses():
    x = _noise(3, seconds=20.0)
    imp = Impairments(interference="speech", interference_db=20.0)
    added = impair(x, fs=FS, impairments=imp, rng=4, floor_psd=FLOOR).x - x
    frame = 441  # 10 ms
    env = np.sqrt(np.mean(added[: len(added) // frame * frame].reshape(-1, frame) ** 2, axis=1))
    silent = env < 1e-12
    assert 0.15 < silent.mean() < 0.6  # pauses of 0.2-1 s between phrases
    spec = np.abs(np.fft.rfft(env - env.mean()))
    fm = np.fft.rfftfreq(len(env), frame / FS)
    assert 2.0 < fm[np.argmax(spec * (fm > 1.0))] < 7.0  # syllable rate 3-6 Hz


# --- gain, DC, clipping, silence, band response --------------------------------------


@pytest.mark.parametrize("seed", range(3))
def test_agc_steps(seed):
    x = _noise(seed)
    imp = Impairments(agc_db=6.0, agc_steps=4)
    r = impair(x, fs=FS, impairments=imp, rng=seed)
    g_db = 20 * np.log10(r.x / x)
    on_level = np.abs(g_db / 6.0 - np.round(g_db / 6.0)) < 1e-9
    assert g_db[0] == pytest.approx(0.0, abs=1e-9)
    levels = np.round(g_db[on_level] / 6.0).astype(int)
    steps = np.diff(levels)[np.diff(levels) != 0]
    assert len(steps) == 4
    assert set(np.abs(steps)) == {1}
    # Each step is a 20 ms linear-in-dB ramp: 881 samples strictly between two levels.
    assert (~on_level).sum() == pytest.approx(4 * (0.02 * FS - 1), abs=4)
    ramp = g_db[~on_level][:881]
    assert np.allclose(np.diff(ramp), np.diff(ramp)[0], atol=1e-9)


def test_dc_and_clipping_levels():
    x = _noise(1, seconds=2.0)
    imp = Impairments(dc=0.02, clip_db=10.0)
    r = impair(x, fs=FS, impairments=imp, rng=0)
    shifted = x + 0.02
    level = np.max(np.abs(shifted)) * 10 ** (-10 / 20)
    assert np.max(r.x) == pytest.approx(level, rel=1e-12)
    assert np.min(r.x) == pytest.approx(-level, rel=1e-12)
    assert r.clipped_fraction.tolist() == [np.mean(np.abs(shifted) > level)]
    # Unclipped samples carry the offset exactly.
    keep = np.abs(shifted) < level
    np.testing.assert_allclose(r.x[keep] - x[keep], 0.02, atol=1e-15)
    assert 0.3 < r.clipped_fraction[0] < 0.5  # level ~1.7 sigma above the offset

    r_dc = impair(x, fs=FS, impairments=Impairments(dc=-0.01), rng=0)
    assert np.mean(r_dc.x) - np.mean(x) == pytest.approx(-0.01, abs=1e-15)


def test_silence_padding_is_exact_and_reported():
    x = _noise(2, seconds=1.0, channels=2)
    imp = Impairments(silence_s=0.25, dc=0.1)
    r = impair(x, fs=FS, impairments=imp, rng=0)
    shift = round(0.25 * FS)
    assert r.shift_samples == shift == 11025
    assert r.x.shape == (len(x) + 2 * shift, 2)
    assert np.all(r.x[:shift] == 0.0) and np.all(r.x[-shift:] == 0.0)  # after the DC
    np.testing.assert_array_equal(r.x[shift:-shift], x + 0.1)


def test_order_band_response_first_dc_and_clip_after_gain():
    x = _noise(3, seconds=2.0)
    # DC after the high-pass (which would remove it); clipping after the gain steps.
    imp = Impairments(hp_hz=100.0, dc=0.05, agc_db=12.0, clip_db=3.0)
    r = impair(x, fs=FS, impairments=imp, rng=1)
    level = np.max(np.abs(r.x))
    assert np.mean(r.x) > 0.04
    assert np.mean(np.isclose(np.abs(r.x), level, rtol=1e-12)) == pytest.approx(
        r.clipped_fraction[0], abs=1e-9
    )


@pytest.mark.parametrize(("key", "btype"), [("lp_hz", "lowpass"), ("hp_hz", "highpass")])
def test_band_response_is_the_causal_butterworth(key, btype):
    n, k0 = 8192, 100
    x = np.zeros(n)
    x[k0] = 1.0
    corner = 4000.0 if btype == "lowpass" else 300.0
    r = impair(x, fs=FS, impairments=Impairments(**{key: corner}), rng=0)
    assert np.all(r.x[:k0] == 0.0)  # causal: nothing before the impulse
    f_test = np.array([100.0, 300.0, 1000.0, 4000.0, 8000.0, 16000.0])
    _, h = sosfreqz(butter(2, corner, btype=btype, fs=FS, output="sos"), worN=f_test, fs=FS)
    got = np.fft.rfft(r.x[k0:])
    fk = np.fft.rfftfreq(n - k0, 1 / FS)
    got_at = np.interp(f_test, fk, np.abs(got))
    np.testing.assert_allclose(20 * np.log10(got_at), 20 * np.log10(np.abs(h)), atol=0.05)
    # At the corner: -3 dB.
    assert 20 * np.log10(np.abs(h[f_test == corner][0])) == pytest.approx(-3.01, abs=0.05)


def test_lowpass_delays_like_a_device():
    """The group delay at low frequency is sqrt(2) / (2 pi f_c), as documented."""
    t = np.arange(int(FS)) / FS
    x = np.sin(2 * np.pi * 200.0 * t)
    r = impair(x, fs=FS, impairments=Impairments(lp_hz=4000.0), rng=0)
    lag = np.angle(np.sum(x[4410:] * np.exp(-2j * np.pi * 200 * t[4410:])))
    lag -= np.angle(np.sum(r.x[4410:] * np.exp(-2j * np.pi * 200 * t[4410:])))
    delay_s = lag / (2 * np.pi * 200.0)
    # The analog prototype's value; the bilinear transform's is 2.6 % shorter at 4 kHz.
    assert delay_s == pytest.approx(math.sqrt(2) / (2 * np.pi * 4000.0), rel=0.04)


# --- randomness and channels --------------------------------------------------------


def test_determinism_with_a_seed():
    x = _noise(0, seconds=2.0)
    imp = parse_impairments("lf_db=20,hum_db=20,pink_db=10,interference=music,agc_db=3")
    a = impair(x, fs=FS, impairments=imp, rng=7, floor_psd=FLOOR).x
    b = impair(x, fs=FS, impairments=imp, rng=np.random.default_rng(7), floor_psd=FLOOR).x
    c = impair(x, fs=FS, impairments=imp, rng=8, floor_psd=FLOOR).x
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)


def test_impairments_draw_from_their_own_streams():
    x = _noise(0, seconds=2.0)
    kw = {"fs": FS, "rng": 3, "floor_psd": FLOOR}
    hum = impair(x, impairments=Impairments(hum_db=20.0), **kw).x - x
    both = impair(x, impairments=Impairments(hum_db=20.0, lf_db=20.0), **kw).x
    lf = impair(x, impairments=Impairments(lf_db=20.0), **kw).x - x
    np.testing.assert_allclose(both - x, hum + lf, atol=1e-15)


def test_channels_are_independent():
    x = _noise(4, seconds=5.0, channels=1)
    x2 = np.hstack([x, x, 0.5 * x])
    imp = Impairments(pink_db=20.0, hum_db=20.0, interference="speech", interference_db=10.0)
    r = impair(x2, fs=FS, impairments=imp, rng=5)
    assert r.x.shape == x2.shape and r.floor_psd.shape == (3,)
    assert r.floor_psd[2] == pytest.approx(0.25 * r.floor_psd[0], rel=1e-12)
    added = impair(x2, fs=FS, impairments=Impairments(pink_db=20.0), rng=5).x - x2
    # First differences: pink noise's few strong low bins make a raw correlation noisy.
    d = np.diff(added, axis=0)
    corr = np.corrcoef(d[:, 0], d[:, 1])[0, 1]
    assert abs(corr) < 0.01  # measured -0.0002 (chance level 1 / sqrt(n) = 0.002)
    # A channel's result does not depend on the others' content.
    other = np.hstack([x, _noise(9, seconds=5.0, channels=1), 0.5 * x])
    np.testing.assert_array_equal(impair(other, fs=FS, impairments=imp, rng=5).x[:, 0], r.x[:, 0])
    # 1-D in, 1-D out; the same as a one-channel 2-D input.
    one = impair(x[:, 0], fs=FS, impairments=imp, rng=5)
    assert one.x.shape == (len(x),) and one.clipped_fraction.shape == (1,)
    np.testing.assert_array_equal(one.x, impair(x, fs=FS, impairments=imp, rng=5).x[:, 0])


def test_input_is_not_modified_and_all_off_is_identity():
    x = _noise(5, seconds=0.5)
    keep = x.copy()
    r = impair(x, fs=FS, impairments=Impairments(), rng=0)
    np.testing.assert_array_equal(x, keep)
    np.testing.assert_array_equal(r.x, x)
    assert r.shift_samples == 0 and r.clipped_fraction.tolist() == [0.0]
    assert r.x.dtype == np.float64


# --- errors of impair ---------------------------------------------------------------


def test_impair_errors():
    x = _noise(0, seconds=0.5)
    hum = Impairments(hum_db=30.0)
    with pytest.raises(InvalidParameterError, match=r"hum_db are set relative.*--snr-db"):
        impair(np.zeros(4410), fs=FS, impairments=hum)
    with pytest.raises(InvalidParameterError, match="channel 1's floor is zero"):
        impair(np.stack([x, np.zeros_like(x)], axis=1), fs=FS, impairments=hum)
    with pytest.raises(InvalidParameterError, match="floor is zero"):
        impair(x, fs=FS, impairments=hum, floor_psd=0.0)
    # Without a relative level a silent input is fine.
    assert impair(np.zeros(100), fs=FS, impairments=Impairments(dc=0.1)).x[0] == 0.1
    with pytest.raises(InvalidParameterError, match="floor_psd"):
        impair(x, fs=FS, impairments=hum, floor_psd=[1.0, 2.0])
    with pytest.raises(InvalidParameterError, match="floor_psd"):
        impair(x, fs=FS, impairments=hum, floor_psd=-1.0)
    with pytest.raises(InvalidParameterError, match=r"lp_hz=30000\.0 must be below fs/2"):
        impair(x, fs=FS, impairments=Impairments(lp_hz=30000.0))
    with pytest.raises(InvalidParameterError, match="interference_max_hz"):
        imp = Impairments(interference="music", interference_max_hz=12000.0)
        impair(x, fs=16000.0, impairments=imp, floor_psd=1.0)
    with pytest.raises(InvalidParameterError, match="must be an Impairments"):
        impair(x, fs=FS, impairments="dc=0.1")
    with pytest.raises(InvalidParameterError, match="1-D or 2-D"):
        impair(np.zeros((4, 4, 4)), fs=FS, impairments=hum)
    with pytest.raises(InvalidParameterError, match="NaN"):
        impair(np.array([0.0, np.nan, 1.0]), fs=FS, impairments=hum)
    with pytest.raises(InvalidParameterError, match=">= 2 samples"):
        impair(np.zeros(1), fs=FS, impairments=hum)
    with pytest.raises(InvalidParameterError, match="fs"):
        impair(x, fs=-1.0, impairments=hum)
    with pytest.raises(InvalidParameterError, match="no frequency in 1000-900 Hz"):
        estimate_floor_psd(np.ones(1000), fs=2000.0)
    with pytest.raises(InvalidParameterError, match="n_samples is needed"):
        noise_floor_psd(0.1, fs=FS, kind="pink")


# --- parser --------------------------------------------------------------------------


ROUND_TRIP = [
    Impairments(),
    Impairments(dc=0.02, clip_db=10.0, hum_db=30.0, hum_hz=60.0),
    Impairments(interference="speech", interference_db=10.0, silence_s=1.0),
    Impairments(interference="music", interference_max_hz=6000.0, interference_db=-3.5),
    Impairments(agc_db=6.0, agc_steps=5, lf_db=31.25, pink_db=0.1, lp_hz=7000.0, hp_hz=80.0),
    Impairments(dc=-1 / 3),
]


@pytest.mark.parametrize("imp", ROUND_TRIP, ids=lambda i: i.spec() or "off")
def test_spec_round_trip(imp):
    assert parse_impairments(imp.spec()) == imp
    d = imp.as_dict()
    assert list(d) == list(KEYS)
    assert Impairments(**d) == imp


def test_parse_the_documented_example():
    spec = (
        "dc=0.02,clip_db=10,hum_db=30,hum_hz=60,interference=speech,interference_db=10,silence_s=1"
    )
    imp = parse_impairments(spec)
    assert imp.spec() == spec
    assert imp.relative_keys == ("hum_db", "interference")
    assert parse_impairments(" dc = 0.02 , clip_db=10 ") == Impairments(dc=0.02, clip_db=10.0)
    assert parse_impairments("  ") == Impairments()


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("dc", "impairment 'dc' must be KEY=VALUE"),
        ("dc=0.1,,clip_db=3", "impairment '' must be KEY=VALUE"),
        ("clip=10", "unknown impairment key 'clip' (valid keys: dc, clip_db, lf_db, hum_db,"),
        ("dc=0.1,dc=0.2", "impairment key 'dc' is given twice"),
        ("hum_db=loud", "hum_db='loud' must be a number"),
        ("dc=", "dc='' must be a number"),
        ("dc=0.6", "dc=0.6 must be within [-0.5, 0.5]"),
        ("clip_db=0", "clip_db=0.0 must be within (0.0, 40.0]"),
        ("clip_db=nan", "clip_db=nan must be within"),
        ("hum_db=30,hum_hz=5", "hum_hz=5.0 must be within [10.0, 1000.0]"),
        ("lf_db=120", "lf_db=120.0 must be within [-40.0, 80.0]"),
        ("silence_s=-1", "silence_s=-1.0 must be within [0.0, 60.0]"),
        ("agc_db=3,agc_steps=2.5", "agc_steps=2.5 must be an integer"),
        ("agc_db=3,agc_steps=0", "agc_steps=0 must be >= 1"),
        ("agc_db=3,agc_steps=2000", "agc_steps=2000 must be <= 1000"),
        ("interference=noise", "interference='noise' must be one of 'speech', 'music'"),
        ("hum_hz=60", "hum_hz=60.0 has no effect without hum_db"),
        ("interference_db=10", "interference_db=10.0 has no effect without interference"),
        ("agc_steps=4", "agc_steps=4 has no effect without agc_db"),
        ("interference=speech,interference_max_hz=5000", "applies to music only"),
        ("hp_hz=5000,lp_hz=4000", "hp_hz=5000.0 must be below lp_hz=4000.0"),
    ],
)
def test_parse_errors(spec, message):
    with pytest.raises(InvalidParameterError) as e:
        parse_impairments(spec)
    assert message in str(e.value)
    assert "\n" not in str(e.value)
    with pytest.raises(InvalidParameterError, match="must be a string"):
        parse_impairments(None)


# --- truth moved by the shift ------------------------------------------------------


def test_shift_truth_keeps_the_time_model():
    sim = render_beepbeep(pair_devices(1.5, clock_ppm=(40.0, -30.0)), snr_db=None, rng=1)
    moved = shift_truth(sim.truth, 1000)
    for old, new in zip(sim.truth["devices"], moved["devices"], strict=True):
        rate = old["fs"] * (1 + old["clock_ppm"] * 1e-6)
        for o_old, o_new in zip(old["onsets"], new["onsets"], strict=True):
            assert o_new == o_old + 1000
            # The arrival's absolute time is unchanged.
            t_old = old["rec_start_s"] + o_old / rate
            assert new["rec_start_s"] + o_new / rate == pytest.approx(t_old, abs=1e-12)
        assert new["play_s"] == old["play_s"]
    assert moved["pairs"] == sim.truth["pairs"]
    assert sim.truth["devices"][0]["onsets"] != moved["devices"][0]["onsets"]  # a copy

    ow = render_oneway([[1.0, 0.0, 2.0]], (0.0, 0.0, 0.0), snr_db=None, period_s=0.05)
    w = shift_truth(ow.truth, 7)["windows"]
    assert [v["start_sample"] for v in w] == [v["start_sample"] + 7 for v in ow.truth["windows"]]
    ex = {"exchanges": [{"play_s": [1.0], "onsets": [[1.5, 2.5], [3.0, 4.0]]}]}
    assert shift_truth(ex, 2)["exchanges"][0]["onsets"] == [[3.5, 4.5], [5.0, 6.0]]
    with pytest.raises(InvalidParameterError, match="shift_samples"):
        shift_truth(ex, -1)
