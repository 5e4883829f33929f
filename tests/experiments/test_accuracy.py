"""Acceptance: two-way ranging accuracy on seeded rendered exchanges (issue #2).

Small seeded sweeps; the full table is made by ``python benchmarks/accuracy_table.py``
(docs/accuracy.md). Distances 0.5-7 m, self-distance 0.1 m, white noise, clocks +-50 ppm.
"""

from __future__ import annotations

import pytest

from rangekit.experiments.beepbeep_accuracy import run_trials, summarize
from rangekit.sim import ShoeboxRoom

ROOM = ShoeboxRoom((6.0, 5.0, 3.0), absorption=0.3, max_order=1)
N = 25


@pytest.fixture(scope="module")
def free20():
    return summarize(run_trials(n_trials=N, snr_db=20.0, rng=101))


def test_free_field_snr20_median_1cm_p90_3cm(free20):
    assert free20["failures"] == 0
    assert free20["median_m"] <= 0.01
    assert free20["p90_m"] <= 0.03


def test_uncertainty_is_honest_free_field(free20):
    # |error| <= 2 sigma for ~95 % of trials if sigma is right; allow sampling noise.
    assert free20["coverage_2sigma"] >= 0.8


def test_room_first_order_snr20_p90_10cm():
    s = summarize(run_trials(n_trials=N, snr_db=20.0, room=ROOM, rng=102))
    assert s["failures"] == 0
    assert s["p90_m"] <= 0.10


@pytest.mark.parametrize("room", [None, ROOM], ids=["free", "room"])
def test_snr10_no_detection_failures(room):
    s = summarize(run_trials(n_trials=N, snr_db=10.0, room=room, rng=103))
    assert s["failures"] == 0
    assert s["p90_m"] <= 0.10


def test_three_devices_every_pair_within_bounds():
    rows = run_trials(n_trials=12, snr_db=20.0, n_devices=3, rng=104)
    assert {(r["a"], r["b"]) for r in rows} == {(0, 1), (0, 2), (1, 2)}
    s = summarize(rows)
    assert s["failures"] == 0
    assert s["median_m"] <= 0.01 and s["p90_m"] <= 0.03


def test_xcorr_baseline_free_field():
    s = summarize(run_trials(n_trials=12, snr_db=20.0, detector="xcorr", rng=105))
    assert s["failures"] == 0
    assert s["median_m"] <= 0.01 and s["p90_m"] <= 0.03
