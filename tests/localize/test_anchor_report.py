"""``track_report`` of the range EKF against anchors: the parameters for people show the
start's heading in degrees, as ``--initial-pose`` takes it; the JSON keeps radians."""

from __future__ import annotations

import math

import pytest

from rangekit.localize.anchor_ekf import track_anchors, track_report
from rangekit.sim.rigs import simulate_rig_run, square_rig


@pytest.fixture(scope="module")
def run():
    return simulate_rig_run(square_rig(), duration_s=10, rng=3)


@pytest.mark.parametrize(("deg", "shown"), [(30.0, "1,1,30"), (-90.0, "1,1,-90"), (0.0, "1,1,0")])
def test_initial_heading_in_degrees(run, deg, shown):
    pose0 = (1.0, 1.0, math.radians(deg))
    trk = track_anchors(run.log, run.rig, initial_pose=pose0)
    rep = track_report(trk, log="robot.csv", rig="rig.json", initial_pose=pose0)
    assert rep.parameters_text() == f"rig rig.json, robust huber, initial_pose {shown}"
    assert rep.extra["initial_pose"] == [1.0, 1.0, math.radians(deg)]  # JSON: radians


def test_no_initial_pose(run):
    rep = track_report(track_anchors(run.log, run.rig), log="robot.csv", rig="rig.json")
    assert rep.parameters_text() == "rig rig.json, robust huber, initial_pose from the ranges"
    assert rep.extra["initial_pose"] is None
