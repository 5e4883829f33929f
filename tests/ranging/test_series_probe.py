"""Series of sweep exchanges: template detection, clock-rate correction and calibration.

Issue 8 acceptance: clock skew of +-50 ppm on 40 exchanges 2 s apart. Devices with unknown
speaker-to-microphone distances play a 17-20 kHz sweep in a room at SNR 20 dB; the clock
rate is estimated from the series (within 2 ppm), the ranges corrected, and calibrated by
the offset fitted from three clock-corrected exchanges of another series at 1 m; then
median |err| <= 1 cm and p90 <= 3 cm. Measured: rate error < 0.001 ppm; corrected median
0.216 / 0.087 mm, p90 0.289 / 0.213 mm (+50 / -100 ppm relative); without the clock
correction the median error is 3.3 / 8.0 mm (c/2 x ppm x the 0.35-0.55 s gap).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from rangekit.io.audio import write_audio
from rangekit.physics import speed_of_sound_m_s
from rangekit.ranging.calibration import Measurement, fit_calibration
from rangekit.ranging.clock import correct_clock, estimate_clock_rates
from rangekit.ranging.series import range_series_beepbeep
from rangekit.signals.probe import linear_sweep
from rangekit.sim.exchanges import render_exchanges
from rangekit.sim.recording import pair_devices
from rangekit.sim.room import ShoeboxRoom

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perturb import worse  # tests/perturb.py: errors x $RANGEKIT_TEST_WORSE

C = speed_of_sound_m_s(20.0)
ROOM = ShoeboxRoom((6.0, 5.0, 3.0), absorption=0.3, max_order=2)
PROBE = linear_sweep(17000.0, 20000.0, 0.1)
SELF_M = 0.14  # unknown to the ranging: only the calibration knows it (as an offset)


def _series(tmp_path, name, distance_m, ppm, seed):
    devs = pair_devices(
        distance_m, self_distance_m=SELF_M, center_m=(3.0, 2.5, 1.2), azimuth_rad=0.2,
        rec_start_s=(0.0, 0.041), clock_ppm=ppm,
    )  # fmt: skip
    sim = render_exchanges(
        devs, source=PROBE.samples, source_fs=PROBE.fs, n_exchanges=40, period_s=2.0,
        jitter_s=0.2, room=ROOM, snr_db=20.0, rng=seed,
    )  # fmt: skip
    paths = [tmp_path / f"{name}_dev{i}.wav" for i in range(2)]
    for p, x in zip(paths, sim.recordings, strict=True):
        write_audio(p, x, fs=PROBE.fs)
    ex = list(range_series_beepbeep(paths, probe=PROBE, speed_m_s=C))
    assert len(ex) == 40 and all(e.error is None for e in ex)
    return ex, float(sim.distances_m[0, 1])


@pytest.mark.parametrize("ppm", [(0.0, 50.0), (50.0, -50.0)])
def test_skewed_sweep_series_corrected_and_calibrated(tmp_path, ppm):
    rel = ((1 + ppm[1] * 1e-6) / (1 + ppm[0] * 1e-6) - 1) * 1e6
    # Calibration: three clock-corrected exchanges of a series at 1 m.
    cal_ex, cal_d = _series(tmp_path, "cal", 1.0, ppm, 4)
    cal_fixed = correct_clock(cal_ex, estimate_clock_rates(cal_ex), speed_m_s=C)
    meas = [
        Measurement(f"ex{k}", cal_d, e.ranges[0].distance_m / C, e.ranges[0].sigma_m / C)
        for k, e in enumerate(cal_fixed[:3])
    ]
    cal = fit_calibration(meas, scheme="beepbeep", speed_m_s=C)
    # The ranged series, 3.2 m.
    ex, d = _series(tmp_path, "run", 3.2, ppm, 5)
    rates = estimate_clock_rates(ex)
    assert abs(rates.ppm[1] - rel) <= 2.0
    fixed = correct_clock(ex, rates, speed_m_s=C)
    got = np.array([r.distance_m for e in fixed for r in cal.apply_ranges(e.ranges, speed_m_s=C)])
    err = worse(np.abs(got - d))
    # Issue 8 asked for median <= 1 cm and p90 <= 3 cm; within 2x of today (issue 21):
    # measured 2026-12-02 median 0.216 / 0.087 mm, p90 0.289 / 0.213 mm (the two skews;
    # 0.26 / 0.69 and 0.44 / 0.90 before the template detector's side-lobe correction).
    # Most of it is the offset fitted from three exchanges (per-exchange sd 0.15 mm).
    assert np.median(err) <= 0.45e-3 and np.percentile(err, 90) <= 0.6e-3, err
    # Not corrected (but calibrated): the skew error c/2 e G is there, ~G = 0.35-0.55 s.
    raw = np.array([r.distance_m for e in ex for r in cal.apply_ranges(e.ranges, speed_m_s=C)])
    assert np.median(np.abs(raw - d)) > 0.5 * C / 2 * abs(rel) * 1e-6 * 0.35
