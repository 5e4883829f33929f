"""Recording synthesis: truth onsets, fractional delays, clocks, rooms, noise level."""

from __future__ import annotations

import numpy as np
import pytest

from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.physics import speed_of_sound_m_s
from rangekit.signals import Beep
from rangekit.signals.beep import beep_continuous
from rangekit.sim import Device, ShoeboxRoom, pair_devices, render_beepbeep


def test_pair_devices_truth_distance_is_exact():
    devs = pair_devices(3.7, self_distance_m=0.13, azimuth_rad=0.7)
    sim = render_beepbeep(devs, snr_db=None, rng=0)
    assert sim.distances_m[0, 1] == pytest.approx(3.7, abs=1e-12)
    assert devs[0].self_distance_m == pytest.approx(0.13)


def test_rendered_signal_equals_the_analytic_delayed_beep():
    """Band-limited fractional delay + clock error against the continuous-time beep."""
    beep = Beep()
    devs = pair_devices(
        2.345, self_distance_m=0.1, rec_start_s=(0.0123, 0.0456), clock_ppm=(40.0, -25.0)
    )
    sim = render_beepbeep(devs, beep=beep, snr_db=None, peak=1.0, rng=0)
    c = speed_of_sound_m_s(20.0)
    for i, dev in enumerate(devs):
        x = sim.recordings[i]
        rate = dev.fs * (1 + dev.clock_ppm * 1e-6)
        t = dev.rec_start_s + np.arange(len(x)) / rate
        ref = np.zeros(len(x))
        for j, dj in enumerate(devs):
            r = np.linalg.norm(dj.speaker_m - dev.mic_m)
            play = sim.truth["devices"][j]["play_s"]
            tj = (t - play - r / c) * (1 + dj.clock_ppm * 1e-6)
            ref += beep_continuous(tj, beep=beep) / r
        ref *= 1.0 / np.max(np.abs(ref))
        err = x - ref
        assert 10 * np.log10(np.sum(err**2) / np.sum(ref**2)) < -50
        # Truth onsets are where the analytic beep starts.
        on = np.asarray(sim.truth["devices"][i]["onsets"])
        assert np.all(on > 0) and np.all(on < len(x))


def test_truth_onsets_follow_the_time_model():
    devs = pair_devices(5.0, self_distance_m=0.0, rec_start_s=(0.0, 0.1))
    sim = render_beepbeep(devs, snr_db=None, gap_s=0.3, rng=0)
    c = speed_of_sound_m_s(20.0)
    on = sim.onsets
    fs = 44100.0
    # Device 0 hears its own beep at once (self distance 0) and device 1's after 5 m.
    p0, p1 = (d["play_s"] for d in sim.truth["devices"])
    assert on[0, 0] == pytest.approx(p0 * fs, abs=1e-6)
    assert on[0, 1] == pytest.approx((p1 + 5.0 / c) * fs, abs=1e-6)
    assert on[1, 0] == pytest.approx((p0 + 5.0 / c - 0.1) * fs, abs=1e-6)
    assert p1 - p0 == pytest.approx(Beep().duration_s + 0.3)


def test_snr_is_relative_to_the_weakest_direct_arrival():
    devs = pair_devices(4.0, self_distance_m=0.1)
    beep = Beep()
    sim = render_beepbeep(devs, beep=beep, snr_db=10.0, peak=1.0, rng=1)
    clean = render_beepbeep(devs, beep=beep, snr_db=None, peak=1.0, rng=1)
    # Same scale in both renders: the peak is the own beep in either.
    noise = sim.recordings[0] - clean.recordings[0] * (
        np.max(np.abs(sim.recordings[0])) / np.max(np.abs(clean.recordings[0]))
    )
    far_amp = clean.recordings[0].max() * 0.1 / 4.0  # 1/r: own at 0.1 m, far at 4 m
    snr = 10 * np.log10(0.5 * far_amp**2 / np.var(noise))
    assert snr == pytest.approx(10.0, abs=0.5)


def test_room_adds_reflections_after_the_direct_path():
    room = ShoeboxRoom((6.0, 5.0, 3.0), absorption=0.3, max_order=1)
    devs = pair_devices(3.0, self_distance_m=0.1, center_m=(3.0, 2.5, 1.2))
    free = render_beepbeep(devs, snr_db=None, peak=1.0, rng=0)
    refl = render_beepbeep(devs, snr_db=None, room=room, peak=1.0, rng=0)
    on = int(free.onsets[1, 0])
    n = min(len(free.recordings[1]), len(refl.recordings[1]))
    x_free, x_refl = free.recordings[1][:n], refl.recordings[1][:n]
    # Common scale from the first samples of the direct arrival (before any reflection).
    seg = slice(on + 5, on + 40)
    k = np.dot(x_refl[seg], x_free[seg]) / np.dot(x_free[seg], x_free[seg])
    diff = x_refl - k * x_free
    # The earliest first-order path (floor, 0.84 m longer) arrives ~108 samples later.
    early = slice(on - 500, on + 60)
    late = slice(on + 115, on + 600)
    assert np.sum(diff[early] ** 2) < 1e-6 * np.sum(x_free[late] ** 2)
    assert np.sum(diff[late] ** 2) > 0.05 * np.sum(x_free[late] ** 2)
    assert refl.truth["room"]["size_m"] == [6.0, 5.0, 3.0]


def test_three_devices_and_mixed_rates():
    pts = [np.array(p) for p in ((0, 0, 1.0), (3, 0, 1.0), (0, 4, 1.0))]
    up = np.array([0, 0, 0.05])
    devs = [
        Device(p - up, p + up, fs=fs)
        for p, fs in zip(pts, (44100.0, 48000.0, 44100.0), strict=True)
    ]
    sim = render_beepbeep(devs, snr_db=20, rng=2)
    assert sim.fs == [44100.0, 48000.0, 44100.0]
    assert sim.distances_m[1, 2] == pytest.approx(5.0, abs=1e-3)
    assert len(sim.truth["pairs"]) == 3


def test_reproducible_with_seed():
    devs = pair_devices(2.0)
    a = render_beepbeep(devs, snr_db=10, noise="pink", rng=7)
    b = render_beepbeep(devs, snr_db=10, noise="pink", rng=7)
    assert np.array_equal(a.recordings[0], b.recordings[0])


def test_errors():
    devs = pair_devices(2.0)
    with pytest.raises(InvalidParameterError, match="at least 2"):
        render_beepbeep(devs[:1])
    with pytest.raises(InvalidParameterError, match="outside the room"):
        render_beepbeep(devs, room=ShoeboxRoom((1.0, 1.0, 1.0)))
    with pytest.raises(IncompatibleInputError, match="too low"):
        render_beepbeep(pair_devices(2.0, fs=16000.0))
    with pytest.raises(InvalidParameterError, match="speaker_m"):
        Device([0, 0], [0, 0, 1])
    with pytest.raises(InvalidParameterError, match="gap_s"):
        render_beepbeep(devs, gap_s=-1.0)
