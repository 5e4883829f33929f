"""Kim & Kim 2013 Tables II and III reproduced (one seeded run per trajectory)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rangekit.experiments import kim2013
from rangekit.experiments.kim2013 import PAPER_TABLE_II, pose_errors


@pytest.fixture(scope="module")
def report():
    return kim2013.run(trials=1, seed=5)


@pytest.mark.parametrize("traj", sorted(PAPER_TABLE_II))
def test_table_ii_acceptance(report, traj):
    """DUHL E_p RMS at or below the paper's and >= 3x lower than UHL using the last 2."""
    rows = [r for r in report.rows if r.condition.startswith(f"trajectory {traj} ")]
    by = {r.metric: r for r in rows}
    duhl = by["E_p RMS, DUHL"]
    assert duhl.paper == PAPER_TABLE_II[traj]["duhl"][0]
    assert duhl.measured <= duhl.paper
    assert by["E_p RMS ratio, UHL-last-2 / DUHL"].measured >= 3.0
    assert by["E_phi RMS, DUHL"].measured < 5.0
    assert by["E_p RMS, tightly coupled EKF"].measured < duhl.measured
    assert 1.5 < by["NEES mean, tightly coupled EKF"].measured < 6.0
    t = by["time per step, DUHL (one distance row + its odometry steps)"]
    assert t.paper > 500 and t.measured > 0.0


def test_report_json_round_trip(report):
    doc = json.loads(report.to_json_text())
    assert doc["experiment"] == "kim2013"
    assert len(doc["rows"]) == len(report.rows) == 4 * 15


def test_pose_errors_closed_form():
    truth = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, np.pi - 0.05]])
    est = np.array([[0.3, 0.4, 0.0], [1.0, 1.0, -np.pi + 0.05]])
    ep, ephi, es = pose_errors(est, truth)
    np.testing.assert_allclose(ep, [0.5, 0.0])
    np.testing.assert_allclose(ephi, [0.0, 0.1], atol=1e-12)  # wrapped across +-pi
    assert es[0] == pytest.approx(0.5)  # a pure translation moves every point by 0.5 m
    # a pure rotation by 0.1 rad moves point (lx, ly) by 2 |l| sin(0.05)
    pts = kim2013.SIGNIFICANT_POINTS
    want = np.sqrt(np.mean(np.sum(pts**2, axis=1))) * 2 * np.sin(0.05)
    assert es[1] == pytest.approx(want)
