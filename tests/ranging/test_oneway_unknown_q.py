"""Acceptance of issue 16 item 4: one-way Barker ranging through transducers of unknown Q.

``range_oneway`` is not told the transducers: its default starting point is rangekit's
Q = 4 model; the recordings come through Tx and Rx resonators of Q 4-20, with a ceiling
or floor bounce 1.5x the direct path 0.2-2 ms after it (inside the burst at the short
end), at the in-band SNR of rangekit's one-way definition (``render_oneway``: the weakest
receiver's direct path). Ten activation windows of the one Tx per trial (a robot at
rest, 2 s of 5 Hz beacons), so the per-receiver pooling of the (Q, f0) estimate works
as in use. Harness: :func:`rangekit.experiments.oneway_accuracy.run_q_trials` (the table
in ``docs/accuracy.md`` is ``python -m rangekit.experiments.oneway_accuracy``, 60 trials
per row; these tests run 10-20 with their own seeds).

Acceptance: RMS <= 3 mm at 10 dB for every Q; after a one-point calibration at one Q the
bias at every other Q within 2 mm; at 0 dB the numbers reported and every arrival
flagged ``low_snr``. Each bound below is within about 2x of the value measured with the
test's seed (in the comments), so a regression fails.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from rangekit.experiments.oneway_accuracy import calibrated_spread, run_q_trials, summarize_q
from rangekit.ranging.ultrasonic import range_oneway
from rangekit.signals.transducer import Transducer
from rangekit.sim.ultrasonic import render_oneway

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perturb import worse, worse_rows  # tests/perturb.py: errors x $RANGEKIT_TEST_WORSE

QS = (4.0, 8.0, 12.0, 16.0, 20.0)
#: RMS bounds at 10 dB, mm (measured 1.14, 1.59, 2.07, 2.54, 2.88; the issue's 3 mm).
RMS_10DB_MM = {4.0: 2.0, 8.0: 2.6, 12.0: 3.0, 16.0: 3.0, 20.0: 3.0}
#: RMS bounds at 20 dB, mm (measured 0.36, 0.53, 0.67, 0.79, 0.92).
RMS_20DB_MM = {4.0: 0.7, 8.0: 1.0, 12.0: 1.3, 16.0: 1.5, 20.0: 1.8}


def _rows(snr: float, n: int) -> dict:
    return {q: run_q_trials(n, snr_db=snr, q=q, rng=[16, int(snr), int(q)]) for q in QS}


@pytest.fixture(scope="module")
def rows_10db():
    return _rows(10.0, 20)  # 600 ranges per Q


@pytest.fixture(scope="module")
def rows_20db():
    return _rows(20.0, 10)  # 300 ranges per Q


# The summaries are made in each test (not cached) so that the rows' errors pass
# through worse() before they are read.
@pytest.fixture
def at_10db(rows_10db):
    return {q: summarize_q(worse_rows(r)) for q, r in rows_10db.items()}


@pytest.fixture
def at_20db(rows_20db):
    return {q: summarize_q(worse_rows(r)) for q, r in rows_20db.items()}


@pytest.mark.parametrize("q", QS)
def test_rms_at_10db_within_3mm_for_every_q(at_10db, q):
    s = at_10db[q]
    assert s["misses"] == 0 and s["gross"] == 0
    assert s["rms_m"] <= RMS_10DB_MM[q] * 1e-3
    # Close to the known-transducer Cramér-Rao bound (measured 1.02-1.09x).
    assert s["rms_m"] <= 1.25 * s["crb_rms_m"]


@pytest.mark.parametrize("q", QS)
def test_rms_at_20db(at_20db, q):
    s = at_20db[q]
    assert s["gross_unflagged"] == 0  # measured: 1 gross range in 1500 (Q 8), flagged
    assert s["rms_m"] <= RMS_20DB_MM[q] * 1e-3


# snr -> (spread, max |bias|) bounds, m. Measured 2026-12-02: spread 0.130 / 0.105 mm,
# max |bias| 0.071 / 0.100 mm at 10 / 20 dB; the biases' standard errors are 0.05-0.12 /
# 0.02-0.05 mm, so the 10 dB |bias| bound is the scatter's (3 se), not 2x the value.
CAL_BOUNDS_M = {10.0: (0.26e-3, 0.35e-3), 20.0: (0.21e-3, 0.20e-3)}


@pytest.mark.parametrize("snr", [10.0, 20.0])
def test_one_point_calibration_leaves_no_bias_across_q(at_10db, at_20db, snr):
    """Calibrated at Q 12, the bias at Q 4-20 stays within 0.26 / 0.21 mm at 10 / 20 dB
    (measured spread 0.130 / 0.105 mm; the acceptance asks 2 mm)."""
    table = at_10db if snr == 10.0 else at_20db
    sp = calibrated_spread(table, at_q=12.0)
    spread, bias = CAL_BOUNDS_M[snr]
    assert sp["spread_m"] <= spread
    assert max(abs(s["bias_m"]) for s in table.values()) <= bias  # uncalibrated too


@pytest.mark.parametrize("snr", [10.0, 20.0])
def test_sigma_covers_the_error(at_10db, at_20db, snr):
    """95 % within 2 sigma for an honest sigma: measured 94.5-96.7 % (10 dB), 94.7-98.0 %
    (20 dB), the sigma including what not knowing Q and the reflection cost."""
    for s in (at_10db if snr == 10.0 else at_20db).values():
        assert 0.90 <= s["coverage_2sigma"] <= 0.99


@pytest.mark.parametrize("q", [4.0, 20.0])
def test_0db_is_flagged_low_snr_and_no_gross_error_goes_unflagged(q):
    """At 0 dB the direct path is at the detection threshold and the 1.5x reflection is
    taken for it in most windows (measured: 65 % of the ranges at Q 4, 88 % at Q 20 more
    than 2 cm off; RMS of the others 4.3 / 7.9 mm): every range is flagged ``low_snr``."""
    rows = worse_rows(run_q_trials(10, snr_db=0.0, q=q, rng=[16, 0, int(q)]))
    s = summarize_q(rows)
    found = [r for r in rows if not r["missed"]]
    assert len(found) >= 0.9 * len(rows)
    assert all("low_snr" in r["flags"] for r in found)
    assert s["gross_unflagged"] == 0
    # RMS over the ranges within 2 cm (measured 4.34 / 7.88 mm): at Q 20 a 3x error moves
    # most of them beyond 2 cm, so the median over every found range (the reflection's,
    # untrimmed: measured 0.217 / 0.430 m) is what sees it.
    assert s["rms_m"] <= {4.0: 8e-3, 20.0: 16e-3}[q]
    e = np.abs([r["error_m"] for r in found])
    assert np.median(e) <= {4.0: 0.45, 20.0: 0.9}[q]


@pytest.mark.parametrize(("q", "old_bias_mm"), [(8.0, 11.0), (15.0, 24.0)])
def test_the_q4_template_was_biased_and_the_fit_is_not(q, old_bias_mm):
    """The issue's measurement: with the Q 4 template assumed (``fit_transducers=False``,
    the old behaviour) ranges through Q 8 / Q 15 transducers are biased +11 / +24 mm at
    20 dB; the default fit leaves < 0.5 mm (measured +0.01 / -0.02 mm)."""
    t = Transducer(q=q)
    sim = render_oneway(
        [[1.0, 0.3, 2.5]], (0.0, 0.0, 0.0), tx=t, rx=t, snr_db=20.0, period_s=0.03,
        order=[0], n_windows=10, rng=3,
    )  # fmt: skip
    truth = np.array([w["distances_m"] for w in sim.truth["windows"]])

    def bias(**kw) -> float:
        rows = range_oneway(sim.x, fs=sim.fs, period_s=0.03, **kw)
        return float(worse(np.mean([r.distance_m - truth[r.window, r.channel] for r in rows])))

    assert bias(fit_transducers=False) == pytest.approx(old_bias_mm * 1e-3, abs=3e-3)
    assert abs(bias()) < 0.5e-3


def test_flags_reach_the_ranging_rows():
    """``ToF.flags`` carries the arrival's flags (here a 0 dB window: low_snr)."""
    sim = render_oneway(
        [[1.0, 0.3, 2.5]], (0.0, 0.0, 0.0), tx=Transducer(q=12.0), rx=Transducer(q=12.0),
        snr_db=0.0, period_s=0.03, rng=5,
    )  # fmt: skip
    found = [r for r in range_oneway(sim.x, fs=sim.fs) if math.isfinite(r.distance_m)]
    assert found and all("low_snr" in r.flags for r in found)
    clean = render_oneway([[1.0, 0.3, 2.5]], (0.0, 0.0, 0.0), snr_db=30.0, period_s=0.03, rng=5)
    assert all(r.flags == () for r in range_oneway(clean.x, fs=clean.fs))


@pytest.mark.parametrize(("q", "late_mm", "st_mm"), [(4.0, 12.4, 13.9), (12.0, 33.5, 35.6)])
def test_a_transducer_outside_both_models_is_not_confidently_wrong(q, late_mm, st_mm):
    """A 6th-order Butterworth element (three pole pairs: outside both models) is fitted
    to within the noise but late (measured median +12.4 / +33.5 mm at Q 4 / 12, 20 dB);
    its split beyond maximally flat brings in the model-order term (``fitted.
    order_terms``), so sigma covers the error (measured: 100 % within 2 sigma, the term
    on every range, its median 13.9 / 35.6 mm) and nothing is confidently wrong. Before
    it: 0.8 / 3.3 % within 2 sigma at sigma 0.8 mm, unflagged."""
    rows = run_q_trials(3, snr_db=20.0, q=q, model="bandpass6", rng=[16, 20, int(q)])
    s = summarize_q(worse_rows(rows))
    assert s["median_m"] == pytest.approx(late_mm * 1e-3, rel=0.3)  # still late
    assert s["order_rate"] >= 0.9
    assert s["coverage_2sigma"] >= 0.9
    assert s["wrong_unflagged"] == 0


@pytest.mark.parametrize("model", ["bandpass", "coupled"])
def test_transducers_inside_the_second_model_keep_their_sigma(model):
    """In-model elements (4th-order Butterworth, stagger-tuned pair; Q 12, 20 dB) fit a
    split near maximally flat: no order term (measured 0 % of the ranges)."""
    s = summarize_q(run_q_trials(3, snr_db=20.0, q=12.0, model=model, rng=[16, 20, 12]))
    assert s["order_rate"] <= 0.05
    assert s["sigma_rms_m"] <= 5e-3


@pytest.mark.parametrize("model", ["resonator", "bandpass6"])
def test_the_front_end_times_a_coded_burst_as_range_oneway_does(model):
    """``detect(x, signal=CodedBurst(), method="fitted", windows=...)`` returns, per
    window, the first path ``range_oneway`` ranges (same onset and sigma, its transducer
    term included) on a one-receiver recording through Q 12 transducers."""
    from rangekit.detect import detect
    from rangekit.experiments.oneway_accuracy import make_transducer
    from rangekit.signals.barker import CodedBurst

    t = make_transducer(model, 12.0)
    sim = render_oneway(
        [[1.0, 0.3, 2.5]], (0.0, 0.0, 0.0), tx=t, rx=t, snr_db=20.0, period_s=0.03,
        order=[0], n_windows=6, rng=4,
    )  # fmt: skip
    x = sim.x[:1]
    n = int(round(0.03 * sim.fs))
    rows = range_oneway(x, fs=sim.fs, period_s=0.03, max_range_m=15.0)
    c = sim.truth["speed_of_sound_m_s"]
    lo, hi = 0, int(math.ceil(15.0 / c * sim.fs)) + 2
    win = np.array([[k * n, (k + 1) * n] for k in range(len(rows))])
    arr = detect(x[0], fs=sim.fs, signal=CodedBurst(), method="fitted", windows=win,
                 search=(lo, hi))  # fmt: skip
    assert len(arr) == len(rows) == 6
    got = (arr.onset - win[:, 0]) / sim.fs
    assert got == pytest.approx([r.arrival_s for r in rows], abs=1e-12)
    assert c * arr.sigma / sim.fs == pytest.approx([r.sigma_m for r in rows], rel=1e-9)
    st = c * arr.sigma_transducer / sim.fs
    assert st == pytest.approx([r.sigma_transducer_m for r in rows], rel=1e-9, abs=1e-12)
    # One receiver alone also carries the order term (measured 40.4 mm; errors +34 mm).
    assert (st.min() > 20e-3) if model == "bandpass6" else (st.max() == 0.0)
