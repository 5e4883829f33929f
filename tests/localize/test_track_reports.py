"""The range trackers' diagnostics and reports (what ``rangekit track range-ekf`` prints)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.localize import anchor_ekf, range_ekf
from rangekit.rig import read_rig
from rangekit.sim.jiang2018 import simulate
from rangekit.sim.rigs import simulate_rig_run, square_rig

SQUARE = Path(__file__).resolve().parents[2] / "docs" / "rigs" / "one_tag_square.json"


@pytest.fixture(scope="module")
def walk():
    return simulate(rng=1).log


def test_range_diagnostics_list_the_rejected_ranges(walk):
    trk = range_ekf.track_ranges(walk, gate=0.3)
    d = trk.diagnostics()
    assert len(d["rejected"]) == len(trk.rejected) == 17  # measured 17 at gate 0.3
    for got, r in zip(d["rejected"], trk.rejected, strict=True):
        assert got == {"t_s": r.t_s, "a": r.a, "b": r.b, "range_m": r.range_m, "nis": r.nis}
    assert d["n_targets"] == 2 and d["n_skipped"] == trk.n_skipped
    assert d["n_reinit"] == int(trk.n_reinit.sum())
    _cols, rows = range_ekf.track_rows(trk)
    assert len(d["p_branch"]) == rows.shape[0]  # one per epoch and target
    assert all(0.0 <= p <= 1.0 + 1e-12 for p in d["p_branch"])  # 1 + 2e-16 occurs
    assert "n_epochs_other_branch" not in d
    with pytest.raises(InvalidParameterError, match="not smoothed"):
        trk.diagnostics(smoothed=True)
    json.dumps(d, allow_nan=False)  # plain JSON values


def test_range_report_summary_and_parameters(walk):
    trk = range_ekf.track_ranges(walk, smooth=True)
    rep = range_ekf.track_report(trk, log="walk.csv", smoothed=True)
    # the line docs/cli.md shows for this walk
    assert rep.summary == (
        "range-ekf: 18 epochs, 2 targets, 0 ranges rejected by the gate, 0 targets "
        "re-opened, 0 epochs skipped before the start; smoothed along the final best "
        "branch (0 epochs where the causal filter reported another)"
    )
    assert rep.parameters == {"accel_psd": 0.05, "gate": 0.999, "cross_sign": "physical",
                              "iterations": 5, "engine": "compiled"}  # fmt: skip
    assert rep.smoothed and rep.extra["n_epochs_other_branch"] == 0
    np.testing.assert_array_equal(rep.rows, range_ekf.track_rows(trk, smoothed=True)[1])
    plain = range_ekf.track_report(trk, log="walk.csv", options={"gate": None, "iterations": 1})
    assert plain.parameters["gate"] is None and plain.parameters["iterations"] == 1
    assert "smoothed" not in plain.summary and "n_epochs_other_branch" not in plain.extra


@pytest.fixture(scope="module")
def robot():
    return simulate_rig_run(square_rig(), duration_s=60, rng=3).log


def test_anchor_report_biases_and_downweighted(robot):
    rig = read_rig(SQUARE)
    trk = anchor_ekf.track_anchors(robot, rig)
    rep = anchor_ekf.track_report(trk, log="robot.csv", rig="docs/rigs/one_tag_square.json")
    # the line docs/cli.md shows for this run
    assert rep.summary == (
        "range-ekf (rig docs/rigs/one_tag_square.json): 464 distance rows from t_s=0.574313 "
        "(start: multilateration), 68 ranges down-weighted (huber); range bias m per anchor "
        "1: +0.122±0.023, 2: +0.130±0.023, 3: +0.076±0.023, 4: +0.101±0.023"
    )
    d = trk.diagnostics()
    assert [b["anchor"] for b in d["biases"]] == trk.anchor_ids.tolist()
    assert [b["bias_m"] for b in d["biases"]] == trk.bias_m.tolist()
    assert len(d["downweighted"]) == len(trk.downweighted) == 68
    assert all(0.0 < w["weight"] < 1.0 for w in d["downweighted"])
    assert list(rep.extra) == ["rig", "robust", "start", "start_t_s", "initial_pose",
                               "biases", "downweighted"]  # fmt: skip
    assert rep.parameters == {"rig": "docs/rigs/one_tag_square.json", "robust": "huber",
                              "initial_pose": "from the ranges"}  # fmt: skip
    pose0 = [1.0, 1.0, math.radians(30)]
    given = anchor_ekf.track_anchors(robot, rig, initial_pose=pose0, robust="none")
    rep = anchor_ekf.track_report(given, log="r.csv", rig="s.json", robust="none",
                                  initial_pose=pose0)  # fmt: skip
    assert "(start: given), 0 ranges down-weighted (none)" in rep.summary
    assert rep.extra["initial_pose"] == pose0  # JSON: radians; for people: degrees
    assert rep.parameters["initial_pose"] == [1.0, 1.0, math.degrees(pose0[2])]
