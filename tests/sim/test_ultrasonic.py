"""Simulated one-way ultrasonic recordings: geometry, signal chain, SNR, reflections."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import welch

from rangekit.detect.matched import MatchedFilter, coded_template, first_path, interp_peak
from rangekit.errors import InvalidParameterError
from rangekit.physics import speed_of_sound_m_s
from rangekit.signals.barker import CodedBurst, burst_waveform
from rangekit.signals.transducer import Transducer, apply_chain
from rangekit.sim._fracdelay import interp_bandlimited
from rangekit.sim.room import ShoeboxRoom, image_sources
from rangekit.sim.ultrasonic import R_RECEIVER_M, receiver_positions, render_oneway

FS = 192000.0
TXS = [[1.0, 1.0, 2.8], [3.5, 2.0, 2.8]]
POSE = (2.0, 1.5, 0.7)
TD = Transducer()


def _received_1m(n_tail: int = int(0.002 * FS)) -> np.ndarray:
    """The direct path at 1 m: the drive through Tx and Rx transducers."""
    return apply_chain(np.concatenate([burst_waveform(), np.zeros(n_tail)]), (TD, TD), fs=FS)


def _peak(env: np.ndarray, lo: int = 0, hi: int | None = None) -> float:
    i = lo + int(np.argmax(env[lo:hi]))
    return i + interp_peak(env, i)[0]


def test_receiver_positions_on_a_circle():
    p = receiver_positions((1.0, 2.0, math.pi / 2), height_m=0.3)
    assert p.shape == (3, 3)
    np.testing.assert_allclose(np.hypot(p[:, 0] - 1.0, p[:, 1] - 2.0), R_RECEIVER_M)
    np.testing.assert_allclose(p[0], [1.0, 2.0 + R_RECEIVER_M, 0.3], atol=1e-12)
    ang = np.degrees(np.arctan2(p[:, 1] - 2.0, p[:, 0] - 1.0)) % 360
    np.testing.assert_allclose(ang, [90.0, 210.0, 330.0])
    with pytest.raises(InvalidParameterError, match="pose"):
        receiver_positions((1.0, 2.0))


def test_truth_distances_match_geometry():
    sim = render_oneway(
        TXS, POSE, order=[1, 0], n_windows=3, receiver_height_m=0.25, snr_db=None, period_s=0.03
    )
    rx = receiver_positions(POSE, height_m=0.25)
    assert sim.truth["receivers_m"] == rx.tolist()
    assert sim.x.shape == (3, int(math.ceil(3 * 0.03 * FS)))
    for w, win in enumerate(sim.truth["windows"]):
        k = [1, 0][w % 2]
        assert win["tx"] == k and win["window"] == w
        assert win["start_sample"] == round(w * 0.03 * FS)
        np.testing.assert_allclose(
            win["distances_m"], np.linalg.norm(rx - np.array(TXS[k]), axis=1), rtol=1e-12
        )
    assert sim.truth["noise_sigma"] == 0.0 and sim.truth["snr_db"] is None


def test_noiseless_signal_is_delayed_scaled_received_burst():
    sim = render_oneway([TXS[0]], POSE, latency_s=1e-3, snr_db=None, period_s=0.03)
    c = speed_of_sound_m_s(20.0)
    h = _received_1m()
    for r, d in enumerate(sim.truth["windows"][0]["distances_m"]):
        start = (1e-3 + d / c) * FS
        u = np.arange(sim.x.shape[1], dtype=np.float64) - start
        ref = interp_bandlimited(np.concatenate([h, np.zeros(64)]), u, half_width=32) / d
        # 1/r spreading and a true fractional delay (interpolator good to ~80 dB).
        assert np.max(np.abs(sim.x[r] - ref)) < 1e-3 * np.max(np.abs(ref))


def test_snr_definition_noise_variance_and_in_band_snr():
    snr_db = 3.0
    kw = {"order": [0, 1], "period_s": 0.05}
    clean = render_oneway(TXS, POSE, snr_db=None, **kw)
    noisy = render_oneway(TXS, POSE, snr_db=snr_db, rng=11, **kw)
    dists = np.array([w["distances_m"] for w in clean.truth["windows"]])
    burst = CodedBurst()
    t_drive = burst.duration_s
    band = burst.band_hz[1] - burst.band_hz[0]  # 26.7 kHz
    e_1m = float(np.sum(_received_1m() ** 2)) / FS  # energy (amplitude^2 s) at 1 m
    e_weak = e_1m / dists.max() ** 2  # the weakest direct arrival over all windows
    n0 = e_weak / t_drive / (10 ** (snr_db / 10) * band)  # one-sided noise PSD
    sigma = math.sqrt(n0 * FS / 2)
    assert noisy.truth["noise_sigma"] == pytest.approx(sigma, rel=1e-6)
    noise = noisy.x - clean.x
    assert noise.var() == pytest.approx(sigma**2, rel=0.03)  # 28800 samples: ~1 % spread
    assert abs(noise.mean()) < 5 * sigma / math.sqrt(noise.size)
    # Measured in band: the noise's power in the burst's main lobe against E / T.
    f, p = welch(noise, fs=FS, nperseg=1024, axis=-1)
    in_band = (f >= burst.band_hz[0]) & (f <= burst.band_hz[1])
    p_noise = float(np.mean(p[:, in_band]) * band)
    assert 10 * math.log10(e_weak / t_drive / p_noise) == pytest.approx(snr_db, abs=0.3)
    # Consequence: the matched-filter output SNR 2 E / N0 = 2 SNR T B (14.5 dB at 0 dB).
    e_weak_samples = e_weak * FS
    assert 10 * math.log10(e_weak_samples / sigma**2) == pytest.approx(
        snr_db + 10 * math.log10(2 * t_drive * band), abs=1e-9
    )
    assert 10 * math.log10(2 * t_drive * band) == pytest.approx(14.5, abs=0.05)


def test_noise_seeded_and_independent_per_channel():
    a = render_oneway([TXS[0]], POSE, snr_db=10.0, rng=3, period_s=0.02)
    b = render_oneway([TXS[0]], POSE, snr_db=10.0, rng=3, period_s=0.02)
    c = render_oneway([TXS[0]], POSE, snr_db=10.0, rng=4, period_s=0.02)
    np.testing.assert_array_equal(a.x, b.x)
    assert not np.array_equal(a.x, c.x)
    n = a.x - render_oneway([TXS[0]], POSE, snr_db=None, period_s=0.02).x
    assert abs(np.corrcoef(n[0], n[1])[0, 1]) < 0.05


def test_extra_paths_add_delayed_scaled_copies():
    kw = {"snr_db": None, "period_s": 0.03}
    base = render_oneway([TXS[0]], POSE, **kw)
    extra = render_oneway([TXS[0]], POSE, extra_paths=[(1e-3, 2.0), (2.5e-3, -0.5)], **kw)
    assert extra.truth["extra_paths"] == [[1e-3, 2.0], [2.5e-3, -0.5]]
    c = speed_of_sound_m_s(20.0)
    mf = MatchedFilter(coded_template(fs=FS, tx=TD, rx=TD))
    for r, d in enumerate(base.truth["windows"][0]["distances_m"]):
        t0 = d / c * FS
        env_d = np.abs(mf.correlate(base.x[r]))
        env_x = np.abs(mf.correlate(extra.x[r] - base.x[r]))
        assert _peak(env_d) == pytest.approx(t0, abs=0.01)
        lag1 = t0 + 1e-3 * FS
        lag2 = t0 + 2.5e-3 * FS
        mid = int((lag1 + lag2) / 2)
        assert _peak(env_x, 0, mid) == pytest.approx(lag1, abs=0.01)
        assert _peak(env_x, mid) == pytest.approx(lag2, abs=0.01)
        assert env_x[round(lag1)] / env_d[round(t0)] == pytest.approx(2.0, rel=0.01)
        assert env_x[round(lag2)] / env_d[round(t0)] == pytest.approx(0.5, rel=0.01)


def test_room_reflections_present_at_image_source_delays():
    room = ShoeboxRoom((5.0, 4.0, 3.0), absorption=0.36, max_order=1)
    tx, pose, h_rx = [2.5, 2.0, 2.9], (2.3, 1.8, 0.0), 0.6
    kw = {"snr_db": None, "period_s": 0.04, "receiver_height_m": h_rx, "n_receivers": 1}
    free = render_oneway([tx], pose, **kw)
    roomy = render_oneway([tx], pose, room=room, **kw)
    assert roomy.truth["room"] == {"size_m": [5.0, 4.0, 3.0], "absorption": 0.36, "max_order": 1}
    refl = roomy.x[0] - free.x[0]
    assert np.sum(refl**2) > 0.05 * np.sum(free.x[0] ** 2)
    rxp = receiver_positions(pose, n=1, height_m=h_rx)[0]
    pos, gains, _ = image_sources(tx, room)
    d_img = np.linalg.norm(pos[1:] - rxp, axis=1)
    c = speed_of_sound_m_s(20.0)
    i_first = int(np.argmin(d_img))  # the ceiling 0.1 m above the Tx
    gaps = np.sort(d_img)
    assert gaps[1] - gaps[0] > 0.4  # the earliest reflection stands alone (> 1 template)
    mf = MatchedFilter(coded_template(fs=FS, tx=TD, rx=TD))
    c_refl = mf.correlate(refl)
    p = first_path(c_refl, self_response=mf.self_response)
    assert p.lag == pytest.approx(d_img[i_first] / c * FS, abs=0.01)
    d_dir = free.truth["windows"][0]["distances_m"][0]
    env_free = np.abs(mf.correlate(free.x[0]))
    ratio = p.height / env_free.max()
    assert ratio == pytest.approx(gains[1 + i_first] * d_dir / d_img[i_first], rel=0.01)
    # Every first-order image contributes at its delay.
    env = np.abs(c_refl)
    for d in d_img:
        assert env[round(d / c * FS)] > 0.3 * np.max(env) * d_img.min() / d


@pytest.mark.parametrize(
    ("args", "kw", "match"),
    [
        (([1.0, 2.0, 3.0], POSE), {}, "tx_positions_m"),
        (([[1.0, 2.0, math.nan]], POSE), {}, "tx_positions_m"),
        ((np.zeros((0, 3)), POSE), {}, "tx_positions_m"),
        ((TXS, POSE), {"order": [0, 2]}, "order"),
        ((TXS, POSE), {"order": []}, "order"),
        ((TXS, POSE), {"n_windows": 0}, "n_windows"),
        ((TXS, POSE), {"period_s": 0.0}, "period_s"),
        ((TXS, POSE), {"latency_s": -1.0}, "latency_s"),
        ((TXS, POSE), {"snr_db": 500.0}, "snr_db"),
        ((TXS, POSE), {"extra_paths": [(-1e-3, 1.0)]}, "excess_delay_s"),
        ((TXS, (1.0, 2.0)), {}, "pose"),
        ((TXS, POSE), {"fs": 96000.0}, "fs="),
        ((TXS, POSE), {"room": ShoeboxRoom((3.0, 3.0, 2.5))}, "outside the room"),
    ],
)
def test_render_validation(args, kw, match):
    with pytest.raises(InvalidParameterError, match=match):
        render_oneway(*args, **kw)
