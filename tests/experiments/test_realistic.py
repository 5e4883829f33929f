"""Two-way beep ranging on recordings rangekit's simulator did not make (issue 16).

pyroomacoustics rooms (image order 6-10, RT60 up to ~1.6 s, up to 20 x 18 x 6 m, devices
against walls) with the impairments real recordings carry, and impairments added to
rangekit's own renders. Bounds sit within about 2x of what was measured on these seeds
(stated next to each), so a regression fails.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pyroomacoustics  # noqa: F401  (a test dependency: fail, do not skip, without it)
import pytest

from rangekit.detect.changepoint import detect_changepoint
from rangekit.experiments.realistic import run_corpus, summarize
from rangekit.io.audio import Channel
from rangekit.ranging.pipeline import range_channels
from rangekit.sim.impair import Impairments, impair
from rangekit.sim.recording import pair_devices, render_beepbeep

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perturb import worse, worse_rows  # tests/perturb.py: errors x $RANGEKIT_TEST_WORSE


@pytest.fixture(scope="module")
def impaired_rows():
    return run_corpus(60, rng=11)


def test_impaired_room_corpus(impaired_rows):
    s = summarize(worse_rows(impaired_rows))
    # Measured (seed 11, 60 exchanges): no failures, median 3.5 mm, p90 1.8 cm, 5 errors
    # above 10 cm all flagged, 90 % within 2 sigma (docs/accuracy.md: 200 exchanges). A
    # beep timed one burst spacing late (fixed since) made the p90 9.4 cm.
    assert s["failure_rate"] <= 0.07
    assert s["median_m"] <= 0.007
    assert s["p90_m"] <= 0.036
    assert s["gross_unflagged"] <= 1
    assert s["within_2sigma"] >= 0.80


def test_clean_room_corpus():
    s = summarize(worse_rows(run_corpus(40, rng=5, impaired=False)))
    # Measured: 2 failures of 40, median 4.3 mm, p90 1.08 cm, one error above 10 cm (flagged).
    assert s["failures"] <= 4
    assert s["median_m"] <= 0.009
    assert s["p90_m"] <= 0.022
    assert s["gross_unflagged"] == 0


def _exchange(seed: int, distance: float = 2.0):
    rng = np.random.default_rng(seed)
    devs = pair_devices(distance, self_distance_m=0.1, rec_start_s=0.0)
    return render_beepbeep(devs, snr_db=20.0, rng=rng)


def _range(recs, fs, **kw):
    chans = [Channel(x, fs, f"dev{i}") for i, x in enumerate(recs)]
    return range_channels(chans, **kw).ranges[0]


@pytest.mark.parametrize(
    "spec",
    [
        Impairments(dc=0.05),
        Impairments(clip_db=12.0),
        Impairments(silence_s=1.0),
        Impairments(lf_db=30.0, hum_db=30.0),
        Impairments(interference="speech", interference_db=40.0),
    ],
    ids=["dc5%", "clip12dB", "silence1s", "lf+hum", "speech"],
)
def test_impairments_on_own_renders(spec):
    """Each impairment alone on rangekit's renders: within 2.5 mm, flagged or not (was 4-31
    cm before the impairments were handled; the issue asked 1 cm)."""
    for seed in (1, 2, 3):
        sim = _exchange(seed)
        rng = np.random.default_rng(100 + seed)
        recs = [
            impair(
                x,
                fs=sim.fs[i],
                impairments=spec,
                rng=rng,
                floor_psd=2.0 * sim.truth["devices"][i]["noise_sigma"] ** 2 / sim.fs[i],
            ).x
            for i, x in enumerate(sim.recordings)
        ]
        r = _range(recs, sim.fs[0], self_distance_m=0.1)
        err = abs(worse(r.distance_m - sim.distances_m[0, 1]))
        # Measured (seeds 1-3): 0.92 / 0.14 / 0.08 mm for dc, silence and lf+hum (as the
        # unimpaired exchanges), 1.01 / 0.01 / 0.17 mm clipped (flagged), 1.00 / 0.24 /
        # 0.06 mm with speech. The unimpaired exchange's own scatter (seeds 1-30 at 2 m):
        # median 0.91, p90 2.2, max 3.7 mm, so 2.5 mm holds these seeds, not any three.
        assert err <= 2.5e-3, (spec, seed, err, r.flags)


def test_clipped_own_beep_is_flagged_and_unbiased():
    sim = _exchange(4)
    recs = [
        impair(x, fs=sim.fs[i], impairments=Impairments(clip_db=15.0), rng=i).x
        for i, x in enumerate(sim.recordings)
    ]
    arr = detect_changepoint(recs[0], fs=sim.fs[0])
    assert "clipped" in arr.flag_names(0)
    on = sim.onsets[0]
    # measured 0.073 samples off (seeds 4-15: |error| <= 0.073; 1.85 samples before the
    # template fit; the band-limited fit was 5-6 samples early: +4-5 cm)
    assert abs(worse(arr.onset[0] - on[0])) < 0.15
