"""Issue 16 acceptance: two-way sweeps in pyroomacoustics rooms with low-frequency noise.

Exchanges rendered independently of rangekit's simulator
(:func:`rangekit.experiments.realistic.render_exchange`: pyroomacoustics image sources of
order 6-10, absorption 0.15-0.35, air absorption, phones at hand height 0.5-7 m apart,
independent recording starts; clocks exact here), white noise 20 dB below the far
arrival, then low-frequency noise 30 dB above that floor (brown, 20-200 Hz) and a DC
offset of 0.1 % full scale (:func:`rangekit.sim.impair.impair`). Probes: linear sweeps
17-20 kHz and 20 Hz-20 kHz, 0.1 s and 1 s. Ranged by ``range_channels(probe=...)`` (the
arrivals of ``detect_template(expected=2)``), after a one-distance calibration (three
exchanges at 1 m, offset only).

Measured (seed 16, 32 exchanges, 8 per sweep; ``python tests/detect/measure_template.py
rooms`` reruns this corpus and a larger one): far arrival found in 32 / 32; calibrated
|error| median 0.02 mm (0.14 before the side-lobe pull of later paths was taken off,
0.30 before the phase-coherent timing of the 20 Hz-20 kHz sweeps), p90 1.27 mm (4.5
before), max 37.0 mm (a 17-20 kHz, 0.1 s exchange, flagged ``ambiguous_first_path``);
none above 10 cm; |err| / sigma median 0.17, p90 0.89, all within 2 sigma (0.09 and
0.44 before the shape term stopped counting the later paths' pull twice, 0.11 before the
phase-coherent shape share took the real part's curvature). The bounds sit
within about 2x of these. ``python tests/detect/measure_template.py rooms 17`` runs the
held-out seed.
"""

from __future__ import annotations

import functools
import sys
from pathlib import Path

import numpy as np
import pyroomacoustics  # noqa: F401  (a test dependency: fail, do not skip, without it)

from rangekit.errors import DetectionError
from rangekit.io.audio import Channel
from rangekit.ranging.calibration import Measurement, fit_calibration
from rangekit.ranging.pipeline import range_channels
from rangekit.signals.probe import linear_sweep

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perturb import worse  # tests/perturb.py: errors x $RANGEKIT_TEST_WORSE

SWEEPS = [
    (17000.0, 20000.0, 0.1),
    (20.0, 20000.0, 0.1),
    (17000.0, 20000.0, 1.0),
    (20.0, 20000.0, 1.0),
]
SELF_M = 0.12
N_PER_SWEEP = 8


def _exchange(rng, probe, distance_m):
    from rangekit.experiments.realistic import draw_room, render_exchange
    from rangekit.sim.impair import impair, parse_impairments

    lo_x = max(4.0, distance_m + 1.5)
    room = draw_room(rng, size_lo_m=(lo_x, 3.0, 2.5), size_hi_m=(lo_x + 6.0, 10.0, 4.0),
                     max_order=(6, 10))  # fmt: skip
    ex = render_exchange(
        rng, room=room, distance_m=distance_m, signal=probe, ppm=0.0,
        self_distance_m=(SELF_M, SELF_M), gap_s=(0.1, 0.3), tail_s=0.2,
    )  # fmt: skip
    imp = parse_impairments("lf_db=30,dc=0.001")
    chans = []
    for i, x in enumerate(ex.recordings):
        floor = 2.0 * ex.info["noise_sigma"][i] ** 2 / ex.fs
        y = impair(x, fs=ex.fs, impairments=imp, rng=rng, floor_psd=floor).x
        chans.append(Channel(y, ex.fs, f"dev{i}"))
    return chans, ex


def _flags(chans, probe):
    from rangekit.detect.template import detect_template

    names = set()
    for ch in chans:
        a = detect_template(ch.x, fs=ch.fs, probe=probe, expected=2)
        for i in range(len(a)):
            names |= set(a.flag_names(i))
    return names - {"dc_or_lowband"}


def corpus(seed: int = 16, sigmas: list | None = None):
    """Calibrated two-way errors (m), whether each has a (non-informational) flag, and
    the number of exchanges whose far arrival was not found; each range's reported
    sigma (m) is appended to ``sigmas`` when given."""
    rng = np.random.default_rng(seed)
    errs, flagged, failed = [], [], 0
    for f0, f1, dur in SWEEPS:
        probe = linear_sweep(f0, f1, dur)
        meas = []
        for k in range(3):
            chans, ex = _exchange(rng, probe, 1.0)
            r = range_channels(chans, probe=probe, speed_m_s=ex.speed_m_s, clock_ppm=0.0)
            d = r.ranges[0].distance_m
            meas.append(Measurement(f"cal{k}", ex.distance_m, d / ex.speed_m_s, 1e-5))
        cal = fit_calibration(meas, scheme="beepbeep", speed_m_s=ex.speed_m_s, fit_speed=False)
        for _ in range(N_PER_SWEEP):
            chans, ex = _exchange(rng, probe, float(rng.uniform(0.5, 7.0)))
            try:
                r = range_channels(chans, probe=probe, speed_m_s=ex.speed_m_s, clock_ppm=0.0)
            except DetectionError:  # a failure is counted, not raised
                failed += 1
                continue
            d = r.ranges[0].distance_m
            got, _ = cal.distance(d / ex.speed_m_s, 1e-5, speed_m_s=ex.speed_m_s)
            errs.append(got - ex.distance_m)
            if sigmas is not None:
                sigmas.append(r.ranges[0].sigma_m)
            flagged.append(bool(_flags(chans, probe)))
    return np.abs(errs), np.array(flagged), failed


@functools.lru_cache(maxsize=2)
def _measured(seed: int = 16):
    """``corpus(seed)`` once per session, with each range's sigma (m)."""
    sig: list = []
    err, flagged, failed = corpus(seed, sigmas=sig)
    return err, flagged, failed, np.array(sig)


def test_sweeps_with_lf_noise_in_rooms_after_one_distance_calibration():
    err, flagged, failed, _ = _measured()
    err = worse(err)
    n = len(SWEEPS) * N_PER_SWEEP
    assert failed == 0 and len(err) == n  # far arrival found: 32 / 32 measured
    assert np.median(err) <= 0.00005, err  # measured 0.02 mm (issue bound 1 cm)
    assert np.percentile(err, 90) <= 0.0025, err  # measured 1.27 mm (issue bound 5 cm)
    assert not np.any((err > 0.10) & ~flagged), err  # none above 10 cm unflagged
    assert not np.any((err > 0.02) & ~flagged), err  # measured: the one > 2 cm is flagged
    assert err.max() <= 0.07, err  # measured 37.0 mm


def test_two_way_sigma_is_neither_too_confident_nor_too_cautious():
    """Issue 16 item 6: 90-97 % of the errors within 2 sigma, neither too confident nor too
    cautious. Two-way ranges leave the transducer term out (``Arrivals.sigma_relative``).
    Measured on this corpus (seed 16, the one the change was examined on): |err| / sigma
    median 0.37 over the 17-20 kHz ranges (0.22 before the shape term stopped counting
    the later paths' pull, which s_leak holds), 0.232 over the 20 Hz-20 kHz ones (0.127
    with the whole residual in their coherent shape share rather than its reflection-odd
    part, 0.068 before that share took the real part's curvature F_w;
    docs/theory/probes.md), every range within 2 sigma.
    Held out (seed 17, ``measure_template.py rooms 17``): 94 % within 2 sigma over 32, 98 %
    over 100; the two beyond (both in 32 and 100) are unflagged 17-20 kHz, 0.1 s ranges at
    2.1-2.2 sigma, errors 2.9 and 3.2 mm."""
    err, flagged, failed, sig = _measured()
    assert failed == 0
    z = worse(err) / sig
    n = N_PER_SWEEP
    narrow = np.concatenate([z[0:n], z[2 * n : 3 * n]])  # 17-20 kHz, 0.1 and 1 s
    wide = np.concatenate([z[n : 2 * n], z[3 * n :]])  # 20 Hz-20 kHz
    # Too confident: measured 100 % within 2 sigma, none unflagged beyond.
    assert np.mean(z <= 2.0) >= 0.9
    assert not np.any((z > 2.0) & (err > 0.02) & ~flagged)
    assert np.median(narrow) <= 0.75  # measured 0.37
    assert np.median(wide) <= 0.5  # measured 0.232
    # Too cautious: measured medians 0.37 (narrow; 0.22 before) and 0.232 (wide; 0.127
    # with the whole residual in the coherent shape share, 0.068 before F_w).
    assert np.median(narrow) >= 0.25
    assert np.median(wide) >= 0.15
    assert np.max(narrow) >= 0.9  # measured 1.77 (1.75 before)
