"""Issue 8 acceptance: sweeps in reverberant rooms, unknown offsets, one-distance calibration.

Synthetic linear sweeps (17-20 kHz and 20 Hz-20 kHz, 0.1 s and 1 s) in a shoebox room
(absorption 0.4, image sources to order 2) at SNR 20 dB:

* two-way, each device with an unknown speaker-to-microphone distance in 0-20 cm;
* one-way, with an unknown latency in 1-20 ms from the trigger to the emission.

Each is calibrated from three recordings at 1 m (offset only, speed of sound from the
temperature) and then ranges placements over 0.1-5 m. Issue 8 asked for a median absolute
error <= 1 cm and a 90th percentile <= 3 cm over all sweeps; the bounds below sit within
about 2x of what is measured (issue 21), so a 3x regression fails. Measured 2026-12-01
(seed 8, 24 ranges each): two-way median 0.119 mm, p90 0.748 mm, worst 2.27 mm; one-way
median 0.108 mm, p90 1.46 mm, worst 3.29 mm.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from rangekit.io.audio import Channel
from rangekit.physics import speed_of_sound_m_s
from rangekit.ranging.calibration import Measurement, fit_calibration
from rangekit.ranging.pipeline import range_channels
from rangekit.ranging.ultrasonic import range_oneway
from rangekit.signals.probe import linear_sweep
from rangekit.sim.exchanges import render_exchanges
from rangekit.sim.recording import Device
from rangekit.sim.room import ShoeboxRoom

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perturb import worse  # tests/perturb.py: errors x $RANGEKIT_TEST_WORSE

SWEEPS = [
    (17000.0, 20000.0, 0.1),
    (17000.0, 20000.0, 1.0),
    (20.0, 20000.0, 0.1),
    (20.0, 20000.0, 1.0),
]
ROOM = ShoeboxRoom((7.0, 5.0, 3.0), absorption=0.4, max_order=2)
TEMP_C = 20.0
C = speed_of_sound_m_s(TEMP_C)
CAL_DISTANCE_M = 1.0
TEST_DISTANCES_M = (0.1, 0.5, 1.5, 2.5, 3.5, 5.0)


def _unit(rng, horizontal=False):
    v = rng.normal(size=3)
    if horizontal:
        v[2] = 0.0
    return v / np.linalg.norm(v)


def _pair(rng, d, self_m, fs=44100.0):
    """Two devices whose speakers are ``d`` apart, mics ``self_m[i]`` from their speakers."""
    centre = np.array([3.5, 2.5, 1.3]) + rng.uniform(-0.3, 0.3, 3)
    a = rng.uniform(-0.3, 0.3)
    u = np.array([np.cos(a), np.sin(a), 0.0])
    spk = [centre - u * d / 2, centre + u * d / 2]
    return [
        Device(speaker_m=s, mic_m=s + m * _unit(rng), fs=fs)
        for s, m in zip(spk, self_m, strict=True)
    ]


def _two_way(probe, devices, rng):
    sim = render_exchanges(
        devices, source=probe.samples, source_fs=probe.fs, room=ROOM, snr_db=20.0, rng=rng
    )
    chans = [
        Channel(x, f, f"dev{i}")
        for i, (x, f) in enumerate(zip(sim.recordings, sim.fs, strict=True))
    ]
    r = range_channels(chans, probe=probe, speed_m_s=C, clock_ppm=0.0).ranges[0]
    return r, sim.truth["pairs"][0]["distance_m"]


def _one_way(probe, devices, latency_s, rng):
    # Both record from the trigger (t = 0); device 0 emits after the latency; device 1's
    # microphone is the receiver (its own later play lies outside the search).
    sim = render_exchanges(
        devices,
        source=probe.samples,
        source_fs=probe.fs,
        room=ROOM,
        snr_db=20.0,
        lead_s=latency_s,
        gap_s=0.3,
        rng=rng,
    )
    row = range_oneway(sim.recordings[1], fs=sim.fs[1], probe=probe, speed_m_s=C)[0]
    true = float(np.linalg.norm(devices[0].speaker_m - devices[1].mic_m))
    return row, true


def _errors(scheme, rng):
    errs = []
    for f0, f1, dur in SWEEPS:
        probe = linear_sweep(f0, f1, dur)
        self_m = rng.uniform(0.0, 0.2, 2)
        latency = rng.uniform(0.001, 0.020)
        meas = []
        for k in range(3):
            devs = _pair(rng, CAL_DISTANCE_M, self_m)
            if scheme == "beepbeep":
                r, true = _two_way(probe, devs, rng)
                meas.append(Measurement(f"cal{k}", true, r.distance_m / C, r.sigma_m / C))
            else:
                # One-way: the receiver's mic at the known distance from the emitter.
                row, true = _one_way(probe, devs, latency, rng)
                meas.append(Measurement(f"cal{k}", true, row.arrival_s, row.sigma_m / C))
        # The known distances differ by the mics' placement: an offset fit, not a speed fit.
        cal = fit_calibration(meas, scheme=scheme, speed_m_s=C, fit_speed=False)
        assert cal.model == "offset"
        for d in TEST_DISTANCES_M:
            devs = _pair(rng, d, self_m)
            if scheme == "beepbeep":
                r, true = _two_way(probe, devs, rng)
                got, _ = cal.distance(r.distance_m / C, r.sigma_m / C, speed_m_s=C)
            else:
                row, true = _one_way(probe, devs, latency, rng)
                got, _ = cal.distance(row.arrival_s, row.sigma_m / C, speed_m_s=C)
            errs.append(got - true)
    return np.abs(np.array(errs))


MM = 1e-3
#: scheme -> bounds (median, p90, worst) in mm; measured: two-way 0.031, 0.434, 0.582
#: (0.119, 0.748, 2.27 before the template detector's side-lobe pull correction);
#: one-way 0.108, 1.46, 3.29.
BOUNDS_MM = {"beepbeep": (0.062, 0.87, 1.2), "oneway": (0.22, 2.9, 6.6)}


def _within(scheme, err) -> bool:
    median, p90, worst = BOUNDS_MM[scheme]
    return bool(
        np.median(err) <= median * MM
        and np.percentile(err, 90) <= p90 * MM
        and np.max(err) <= worst * MM
    )


@pytest.mark.parametrize("scheme", ["beepbeep", "oneway"])
def test_sweeps_in_rooms_after_one_distance_calibration(scheme):
    err = worse(_errors(scheme, np.random.default_rng(8)))
    assert len(err) == len(SWEEPS) * len(TEST_DISTANCES_M)
    assert _within(scheme, err), err
    # Perturbation: the same ranges with 3x the error fail the bounds.
    assert not _within(scheme, 3.0 * err)


def test_without_calibration_the_offset_is_there():
    """The same two-way scene without calibration is off by the mean self-distance."""
    rng = np.random.default_rng(3)
    probe = linear_sweep(17000.0, 20000.0, 0.1)
    self_m = np.array([0.15, 0.19])
    r, true = _two_way(probe, _pair(rng, 2.0, self_m), rng)
    # measured: off by the mean self-distance of 0.17 m to 0.036 mm (the bound is the
    # scatter of one exchange: two-way p90 0.43 mm above); worse() scales the whole error
    assert abs(worse(true - r.distance_m) - self_m.mean()) < 0.6 * MM
