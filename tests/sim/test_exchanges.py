"""Multi-exchange renderer: equals render_beepbeep, time model, skew, jitter, noise, errors."""

from __future__ import annotations

import numpy as np
import pytest

from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.physics import speed_of_sound_m_s
from rangekit.signals import Beep, beep_waveform
from rangekit.signals.beep import beep_continuous
from rangekit.sim import Device, ShoeboxRoom, pair_devices, render_beepbeep
from rangekit.sim._fracdelay import interp_bandlimited
from rangekit.sim.exchanges import _HW, _PHASES, _phase_table, _place_kernel, render_exchanges

FS = 44100.0
BEEP = Beep()
SRC = beep_waveform(BEEP)
ROOM = ShoeboxRoom((6.0, 5.0, 3.0), absorption=0.3, max_order=2)


def _devices(**kw):
    return pair_devices(
        2.345,
        self_distance_m=0.1,
        center_m=(3.0, 2.5, 1.2),
        azimuth_rad=0.4,
        rec_start_s=(0.0123, 0.0456),
        clock_ppm=(40.0, -25.0),
        **kw,
    )


def test_phase_table_kernel_equals_direct_interpolation():
    rng = np.random.default_rng(0)
    w = rng.standard_normal(3000)
    u = -40.0 + np.arange(3100) * (1 + 173e-6) + 0.318
    out = np.zeros(len(u) + 5)
    _place_kernel(out, 5, u, w, _phase_table(_HW, 0.95, _PHASES))
    ref = interp_bandlimited(w, u, half_width=_HW, cutoff=0.95)
    assert np.all(out[:5] == 0.0)
    assert np.max(np.abs(out[5:] - ref)) < 1e-7 * np.max(np.abs(ref))


@pytest.mark.parametrize(("room", "bound"), [(None, 1e-6), (ROOM, 3e-4)])
def test_one_exchange_equals_render_beepbeep(room, bound):
    """Free field: same evaluation (phase table, ~1e-9 measured). Room: the two-stage RIR
    path gives the interpolator's residual tone image (80 dB down) another phase (~6e-5)."""
    devs = _devices()
    ref = render_beepbeep(devs, beep=BEEP, snr_db=None, room=room, gap_s=0.3, rng=0)
    sim = render_exchanges(devs, source=SRC, source_fs=FS, snr_db=None, room=room, gap_s=0.3, rng=0)
    for a, b in zip(ref.recordings, sim.recordings, strict=True):
        assert len(a) == len(b)
        assert np.max(np.abs(a - b)) <= bound * np.max(np.abs(a))
    np.testing.assert_allclose(sim.onsets, ref.onsets, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sim.distances_m, ref.distances_m, rtol=0, atol=1e-12)
    for da, db in zip(ref.truth["devices"], sim.truth["devices"], strict=True):
        assert db["play_s"] == pytest.approx(da["play_s"], abs=1e-12)
    assert sim.truth["exchanges"][0]["onsets"] == sim.onsets.tolist()


def test_exchanges_follow_the_time_model_with_clock_skew():
    """Every exchange against the continuous-time beep delayed and skewed by the model."""
    devs = pair_devices(
        3.0, self_distance_m=0.1, rec_start_s=(0.02, 0.31), clock_ppm=(150.0, -120.0)
    )
    sim = render_exchanges(
        devs, source=SRC, source_fs=FS, n_exchanges=3, period_s=1.5, gap_s=0.2,
        snr_db=None, peak=1.0, rng=0,
    )  # fmt: skip
    c = speed_of_sound_m_s(20.0)
    t0 = 0.31 + 0.15
    d_s = BEEP.duration_s
    ex = sim.truth["exchanges"]
    assert len(ex) == 3
    for e, item in enumerate(ex):
        p0, p1 = item["play_s"]
        assert p0 == pytest.approx(t0 + 1.5 * e, abs=1e-12)
        assert p1 - p0 == pytest.approx(d_s * (1 - 150e-6) + 0.2, abs=1e-12)
    for i, dev in enumerate(devs):
        x = sim.recordings[i]
        rate = FS * (1 + dev.clock_ppm * 1e-6)
        t = dev.rec_start_s + np.arange(len(x)) / rate
        ref = np.zeros(len(x))
        for item in ex:
            for j, dj in enumerate(devs):
                r = np.linalg.norm(dj.speaker_m - dev.mic_m)
                play = item["play_s"][j]
                skewed = (t - play - r / c) * (1 + dj.clock_ppm * 1e-6)
                ref += beep_continuous(skewed, beep=BEEP) / r
                # Truth onset: where the delayed, skewed beep starts, in device i's samples.
                on = item["onsets"][i][j]
                assert on == pytest.approx((play + r / c - dev.rec_start_s) * rate, abs=1e-6)
        ref /= np.max(np.abs(ref))
        err = x - ref
        assert 10 * np.log10(np.sum(err**2) / np.sum(ref**2)) < -50
    # Skew moves device 1's onsets in its own samples by (1 + ppm) over the 1.5 s period.
    on = np.array([item["onsets"] for item in ex])
    step = np.diff(on[:, 1, 0])
    np.testing.assert_allclose(step, 1.5 * FS * (1 - 120e-6), rtol=0, atol=1e-6)
    step0 = np.diff(on[:, 0, 0])
    np.testing.assert_allclose(step0, 1.5 * FS * (1 + 150e-6), rtol=0, atol=1e-6)


def test_jitter_varies_the_gaps_reproducibly():
    devs = pair_devices(1.0, self_distance_m=0.1)
    kw = dict(source=SRC, source_fs=FS, n_exchanges=6, period_s=1.5, gap_s=0.2, jitter_s=0.3)
    a = render_exchanges(devs, snr_db=None, rng=5, **kw)
    b = render_exchanges(devs, snr_db=None, rng=5, **kw)
    gaps = np.array([e["play_s"][1] - e["play_s"][0] for e in a.truth["exchanges"]])
    extra = gaps - (BEEP.duration_s + 0.2)
    assert np.all(extra >= 0) and np.all(extra <= 0.3)
    assert np.ptp(extra) > 0.05
    assert a.truth["exchanges"] == b.truth["exchanges"]
    assert np.array_equal(a.recordings[0], b.recordings[0])


def test_snr_uses_the_sources_mean_power_over_its_non_zero_samples():
    n = int(0.2 * FS)
    tone = 0.9 * np.sin(2 * np.pi * 6000.0 * np.arange(n) / FS)
    tone[:64] *= np.hanning(128)[:64]
    tone[-64:] *= np.hanning(128)[64:]
    devs = pair_devices(3.0, self_distance_m=0.1)
    kw = dict(source=tone, source_fs=FS, peak=1.0, gap_s=0.2)
    noisy = render_exchanges(devs, snr_db=10.0, rng=3, **kw)
    clean = render_exchanges(devs, snr_db=None, rng=3, **kw)
    x, y = noisy.recordings[0], clean.recordings[0]
    k = np.dot(x, y) / np.dot(y, y)  # the two channels' peak scalings differ
    noise = x - k * y
    on = int(clean.onsets[0, 1]) + 100
    far = k * y[on : on + n - 300]
    snr = 10 * np.log10(np.mean(far**2) / np.var(noise))
    assert snr == pytest.approx(10.0, abs=0.5)
    assert noisy.truth["source"]["power"] == pytest.approx(np.mean(tone[tone != 0] ** 2))


def test_forty_exchanges_in_a_room_render_with_their_truth():
    devs = pair_devices(2.0, self_distance_m=0.1, center_m=(3.0, 2.5, 1.2), clock_ppm=(0, 50))
    sim = render_exchanges(
        devs, source=SRC, source_fs=FS, n_exchanges=40, period_s=2.0, jitter_s=0.2,
        room=ShoeboxRoom((6.0, 5.0, 3.0), max_order=3), rng=1,
    )  # fmt: skip
    ex = sim.truth["exchanges"]
    assert len(ex) == 40 == sim.truth["n_exchanges"]
    last = max(max(row) for row in ex[-1]["onsets"])
    assert all(len(x) > last + len(SRC) for x in sim.recordings)
    assert all(np.max(np.abs(x)) == pytest.approx(0.5) for x in sim.recordings)


def test_errors():
    devs = pair_devices(1.0)
    kw = dict(source=SRC, source_fs=FS)
    with pytest.raises(InvalidParameterError, match="at least 2 devices"):
        render_exchanges(devs[:1], **kw)
    with pytest.raises(InvalidParameterError, match="period_s"):
        render_exchanges(devs, n_exchanges=2, period_s=0.8, **kw)
    with pytest.raises(InvalidParameterError, match="gap_s"):
        render_exchanges(devs, gap_s=-0.1, **kw)
    with pytest.raises(InvalidParameterError, match="non-zero"):
        render_exchanges(devs, source=np.zeros(100), source_fs=FS)
    with pytest.raises(InvalidParameterError, match="n_exchanges"):
        render_exchanges(devs, n_exchanges=0, **kw)
    with pytest.raises(InvalidParameterError, match="outside the room"):
        render_exchanges(devs, room=ROOM, **kw)
    # A 20 kHz tone at 48 kHz cannot be carried by a 32 kHz recording.
    tone = np.sin(2 * np.pi * 20000.0 * np.arange(4800) / 48000.0)
    slow = [Device(d.speaker_m, d.mic_m, fs=32000.0) for d in devs]
    with pytest.raises(IncompatibleInputError, match="device 0"):
        render_exchanges(slow, source=tone, source_fs=48000.0)
