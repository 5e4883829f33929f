"""``rangekit track FILTER --verbose`` prints the parameters used as every line for people
writes values (``rangekit.io.results.format_value``): no Python reprs (``None``,
``False``, ``[90.0, -90.0]``, ``29.999999999999996``)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from clihelp import ok, run

from rangekit.sim import ahn2007, girard2011, jiang2018, rigs
from rangekit.sim.kim2013 import simulate

SQUARE = Path(__file__).resolve().parents[2] / "docs" / "rigs" / "one_tag_square.json"


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("logs")
    kim = simulate(1, t_max_s=5, rng=1)
    kim.to_log().to_csv(d / "run.csv")
    (d / "beacons.json").write_text(json.dumps(kim.beacons.to_json()))
    (d / "walk.csv").write_text(jiang2018.simulate(rng=1).log.to_csv())
    rigs.simulate_rig_run(rigs.square_rig(), duration_s=10, rng=3).log.to_csv(d / "robot.csv")
    (d / "steps.csv").write_text(girard2011.simulate(rng=1).steps.to_csv())
    (d / "fixes.csv").write_text(ahn2007.position_log_text(ahn2007.simulate_pedestrian(12, rng=3)))
    (d / "imu.csv").write_text(ahn2007.imu_log_text(ahn2007.simulate_robot(200, rng=2)))
    return d


CASES = [
    (["duhl", "run.csv", "--beacons", "beacons.json"],
     "wheel_base_m 0.33, sigma_d_m 0.01, k_v_m 0.0004, gate none"),
    (["duhl-ranges", "run.csv", "--beacons", "beacons.json", "--gate", "0.99"],
     "wheel_base_m 0.33, sigma_d_m 0.01, k_v_m 0.0004, gate 0.99"),
    (["range-ekf", "walk.csv", "--no-gate"],
     "accel_psd 0.05, gate none, cross_sign physical, iterations 5, engine compiled"),
    (["range-ekf", "--rig", str(SQUARE), "robot.csv"],
     f"rig {SQUARE}, robust huber, initial_pose from the ranges"),
    (["range-ekf", "--rig", str(SQUARE), "robot.csv", "--initial-pose", "1,1,30"],
     f"rig {SQUARE}, robust huber, initial_pose 1,1,30"),  # degrees, as given (not 0.523599)
    (["dead-reckoning", "imu.csv"], "gate none, smooth no"),
    (["dead-reckoning", "imu.csv", "--smooth", "--gate", "0.5"], "gate 0.5, smooth yes"),
    (["lmax", "fixes.csv", "--l-max", "0.5", "--i-star", "3"],
     "l_max_m 0.5, filter offline from 3"),
    (["particle", "steps.csv", "--start", "1.25,1", "--mounts", "10,20,30", "--seed", "1"],
     "method girard, mode imu, n_particles 150, mounts_deg 10,20,30, lever_arms_m none"),
]  # fmt: skip


@pytest.mark.parametrize(("args", "want"), CASES, ids=[" ".join(c[0][:2]) for c in CASES])
def test_verbose_parameters_line(logs, args, want):
    full = [str(logs / a) if a.endswith((".csv", ".json")) and "/" not in a else a for a in args]
    r = ok(run(["track", *full, "-v", "-o", logs / "out.csv"]))
    first = r.stderr.splitlines()[0]
    assert first == f"rangekit: track {args[0]}: {want}"
    # No Python repr in it: None/True/False, brackets, floats with more than 6 digits.
    body = first.split(": ", 2)[2].replace(str(SQUARE), "RIG")
    assert not re.search(r"\b(None|True|False)\b|[\[\]()]|\d\.\d{7,}", body), body
