"""Acceptance: two-way ranging accuracy on seeded rendered exchanges (issue #2).

Small seeded sweeps; the full table is made by ``python benchmarks/accuracy_table.py``
(docs/accuracy.md). Distances 0.5-7 m, self-distance 0.1 m, white noise, clocks +-50 ppm.

Every bound sits within about 2x of what these seeds measure today (written beside it,
measured 2026-12-01), so a result 3x worse fails (issue 21). The uncertainty test is
two-sided: sigma too small (over-confident) and too large (over-cautious) both fail.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from rangekit.experiments.beepbeep_accuracy import run_trials, summarize
from rangekit.sim import ShoeboxRoom

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perturb import worse_rows  # tests/perturb.py: errors x $RANGEKIT_TEST_WORSE

ROOM = ShoeboxRoom((6.0, 5.0, 3.0), absorption=0.3, max_order=1)
N = 25
MM = 1e-3


@pytest.fixture(scope="module")
def free20_rows():
    return run_trials(n_trials=N, snr_db=20.0, rng=101)


@pytest.fixture
def free20(free20_rows):
    return summarize(worse_rows(free20_rows))


def _free20_accurate(s) -> bool:
    return s["failures"] == 0 and s["median_m"] <= 6.6 * MM and s["p90_m"] <= 14.0 * MM


def _free20_honest(s) -> bool:
    # Too confident: median |error| above sigma; too cautious: sigma 2x today's (already
    # about 2x the scatter). An honest Gaussian sigma gives 0.674 and coverage 0.954.
    return s["coverage_2sigma"] >= 0.85 and 0.18 <= s["median_z"] <= 1.0


def test_free_field_snr20(free20):
    # measured: median 3.30 mm, p90 7.06 mm
    assert _free20_accurate(free20), free20


def test_uncertainty_is_honest_free_field(free20):
    """|error| / sigma, two-sided; measured: median 0.367, 2-sigma coverage 1.00."""
    assert _free20_honest(free20), free20


def test_free_field_bounds_fail_a_result_3x_worse(free20_rows):
    """Perturbation: the same trials with 3x the error, or sigma 3x off either way."""
    worse = [{**r, "error_m": 3.0 * r["error_m"]} for r in free20_rows]
    assert not _free20_accurate(summarize(worse))
    for k in (3.0, 1.0 / 3.0):
        off = [{**r, "sigma_m": k * r["sigma_m"]} for r in free20_rows]
        assert not _free20_honest(summarize(off)), k


@pytest.mark.xfail(
    strict=True,
    reason="sigma_m is about twice the error scatter in the free field at 20 dB (median "
    "|error|/sigma 0.367, honest 0.674): ranging/detection uncertainty, issue 21",
)
def test_uncertainty_is_not_over_cautious_free_field(free20):
    assert free20["median_z"] >= 0.45  # two thirds of the honest 0.674


def test_room_first_order_snr20():
    s = summarize(worse_rows(run_trials(n_trials=N, snr_db=20.0, room=ROOM, rng=102)))
    assert s["failures"] == 0
    assert s["median_m"] <= 4.1 * MM  # measured 2.04 mm
    assert s["p90_m"] <= 16.0 * MM  # measured 8.06 mm


@pytest.mark.parametrize(
    ("room", "median_mm", "p90_mm"),
    [(None, 9.0, 14.0), (ROOM, 6.0, 15.0)],  # measured 4.49 / 7.02 mm, 3.00 / 7.37 mm
    ids=["free", "room"],
)
def test_snr10_no_detection_failures(room, median_mm, p90_mm):
    s = summarize(worse_rows(run_trials(n_trials=N, snr_db=10.0, room=room, rng=103)))
    assert s["failures"] == 0
    assert s["median_m"] <= median_mm * MM
    assert s["p90_m"] <= p90_mm * MM


def test_three_devices_every_pair_within_bounds():
    rows = run_trials(n_trials=12, snr_db=20.0, n_devices=3, rng=104)
    assert {(r["a"], r["b"]) for r in rows} == {(0, 1), (0, 2), (1, 2)}
    s = summarize(worse_rows(rows))
    assert s["failures"] == 0
    assert s["median_m"] <= 9.5 * MM  # measured 4.73 mm
    assert s["p90_m"] <= 21.0 * MM  # measured 10.68 mm


def test_xcorr_baseline_free_field():
    s = summarize(worse_rows(run_trials(n_trials=12, snr_db=20.0, detector="xcorr", rng=105)))
    assert s["failures"] == 0
    assert s["median_m"] <= 5.0 * MM  # measured 2.50 mm
    assert s["p90_m"] <= 10.4 * MM  # measured 5.19 mm


def test_rows_told_the_true_self_distance_are_oracle_rows():
    """Default rows range with the simulator's self-distance and say so; a user's assumed
    value moves every distance by the difference and the rows are not oracle rows."""
    truth = run_trials(n_trials=2, snr_db=20.0, rng=106)
    told = run_trials(n_trials=2, snr_db=20.0, assumed_self_distance_m=0.13, rng=106)
    assert {r["oracle"] for r in truth} == {"true self-distance"}
    assert {r["oracle"] for r in told} == {None}
    for a, b in zip(truth, told, strict=True):
        assert b["distance_m"] - a["distance_m"] == pytest.approx(0.03, abs=1e-9)
