"""``rangekit track range-ekf --rig``: fixed anchors from a rig file (issue 18)."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest
from clihelp import assert_error, ok, run

from rangekit.sim.rigs import simulate_rig_run, square_rig

RIGS = Path(__file__).resolve().parents[2] / "docs" / "rigs"
SQUARE = RIGS / "one_tag_square.json"


@pytest.fixture(scope="module")
def sim():
    return simulate_rig_run(square_rig(), duration_s=40.0, rng=3)


@pytest.fixture
def log(tmp_path, sim):
    p = tmp_path / "robot.csv"
    sim.log.to_csv(p)
    return p


def _table(text):
    rows = list(csv.reader(io.StringIO(text)))
    return rows[0], np.array([[float(c) if c else np.nan for c in r] for r in rows[1:]])


def test_csv_follows_the_truth_and_reports(log, sim):
    r = ok(run(["track", "range-ekf", "--rig", SQUARE, log]))
    cols, rows = _table(r.stdout)
    assert cols[:4] == ["t_s", "x_m", "y_m", "heading_rad"] and cols[-1] == "n_hypotheses"
    err = np.hypot(*(rows[:, 1:3] - sim.truth_xy(rows[:, 0])).T)
    assert np.sqrt(np.mean(err**2)) < 0.12  # measured 0.06
    assert "start: multilateration" in r.stderr and "down-weighted (huber)" in r.stderr
    assert "Traceback" not in r.stderr


def test_json_biases_downweighted_smooth_and_plot(tmp_path, log, sim):
    out = tmp_path / "t.json"
    p0 = sim.truth_pose([0.0])[0]
    pose = f"{p0[0]},{p0[1]},{np.degrees(p0[2])}"
    ok(run(["track", "range-ekf", "--rig", SQUARE, log, "--initial-pose", pose,
            "--smooth", "--robust", "student-t", "--format", "json", "-o", out]))  # fmt: skip
    js = json.loads(out.read_text())
    assert js["start"] == "given" and js["robust"] == "student-t" and js["smoothed"]
    assert [b["anchor"] for b in js["biases"]] == [1, 2, 3, 4]
    assert all(abs(b["bias_m"] - 0.10) < 3 * b["sigma_m"] + 0.01 for b in js["biases"])
    dw = js["downweighted"]
    assert dw and all(0 < d["weight"] < 1 and d["tag"] == 1 for d in dw)
    rows = np.array(js["rows"], dtype=float)
    assert np.all(rows[:, 4] > 0) and np.all(rows[:, 5] > 0)
    png = tmp_path / "t.png"
    ok(run(["plot", "track", out, "-o", png]))
    assert png.stat().st_size > 5000


def test_kim_rig_on_a_kim_log(tmp_path):
    from rangekit.sim.kim2013 import simulate

    r = simulate(1, t_max_s=8.0, rng=1)
    p = tmp_path / "run.csv"
    r.to_log().to_csv(p)
    res = ok(run(["track", "range-ekf", "--rig", RIGS / "kim2013.json", p]))
    _, rows = _table(res.stdout)
    truth = np.column_stack([np.interp(rows[:, 0], r.t_s, r.true_pose[:, c]) for c in (0, 1)])
    assert np.max(np.hypot(*(rows[-10:, 1:3] - truth[-10:]).T)) < 0.05


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        (["--gate", "0.9"], "--gate does not apply with --rig"),
        (["--cross-sign", "paper"], "--cross-sign does not apply with --rig"),
        (["--initial-pose", "1,1"], "--initial-pose"),
        (["--robust", "cauchy"], "--robust"),
    ],
)
def test_usage_errors(log, extra, named):
    assert_error(run(["track", "range-ekf", "--rig", SQUARE, log, *extra]), 2, named)


def test_rig_options_need_a_rig(log):
    assert_error(run(["track", "range-ekf", log, "--robust", "huber"]), 2, "--rig")
    assert_error(run(["track", "lmax", log, "--rig", SQUARE]), 2, "--rig")


def test_bad_rig_file(tmp_path, log):
    doc = json.loads(SQUARE.read_text())
    del doc["anchors"][2]["y_m"]
    bad = tmp_path / "rig.json"
    bad.write_text(json.dumps(doc))
    assert_error(run(["track", "range-ekf", "--rig", bad, log]), 3, "rig.json",
                 "anchors[2]: missing key 'y_m'")  # fmt: skip
    assert_error(run(["track", "range-ekf", "--rig", tmp_path / "no.json", log]), 3,
                 "no.json")  # fmt: skip


def test_log_that_does_not_fit_the_rig(tmp_path, log):
    doc = json.loads(SQUARE.read_text())
    doc["anchors"] = doc["anchors"][:3]
    three = tmp_path / "three.json"
    three.write_text(json.dumps(doc))
    assert_error(run(["track", "range-ekf", "--rig", three, log]), 5, "robot.csv",
                 "names anchor 4")  # fmt: skip
    doc = json.loads(SQUARE.read_text())
    doc["odometry"] = {"type": "steps"}
    steps = tmp_path / "steps.json"
    steps.write_text(json.dumps(doc))
    assert_error(run(["track", "range-ekf", "--rig", steps, log]), 2, "--steps")
    doc["odometry"] = {"type": "none"}
    steps.write_text(json.dumps(doc))
    assert_error(run(["track", "range-ekf", "--rig", steps, log]), 4,
                 "odometry rows in the log")  # fmt: skip
    lines = log.read_text().splitlines()
    keep = [ln for ln in lines if ",distance," not in ln]
    (tmp_path / "noranges.csv").write_text("\n".join(keep) + "\n")
    assert_error(run(["track", "range-ekf", "--rig", SQUARE,
                      tmp_path / "noranges.csv"]), 4, "noranges.csv")  # fmt: skip


def test_duhl_reads_kims_rig_like_its_beacon_file(tmp_path):
    """The shipped Kim & Kim rig gives DUHL the same transmitters, wheel base, k_v,
    sigma and receiver circle as the beacon file and defaults: the same track."""
    from rangekit.sim.kim2013 import simulate

    r = simulate(1, t_max_s=6.0, rng=2)
    p = tmp_path / "run.csv"
    r.to_log().to_csv(p)
    bcn = tmp_path / "beacons.json"
    bcn.write_text(json.dumps(r.beacons.to_json()))
    for filt in ("duhl", "duhl-ranges"):
        a = _table(ok(run(["track", filt, p, "--beacons", bcn])).stdout)[1]
        b = _table(ok(run(["track", filt, p, "--rig", RIGS / "kim2013.json"])).stdout)[1]
        assert a.shape == b.shape and np.allclose(a, b, rtol=0, atol=1e-9, equal_nan=True)
    assert_error(run(["track", "duhl", p, "--rig", SQUARE]), 5, "one_tag_square.json",
                 "three receivers")  # fmt: skip
    assert_error(run(["track", "duhl", p, "--rig", SQUARE, "--beacons", bcn]), 2,
                 "--beacons or --rig")  # fmt: skip


def test_walker_with_step_events(tmp_path):
    """A steps rig (docs/rigs/walker_steps.json): the range log has no odometry rows, the
    step log comes with --steps."""
    from rangekit.rig import read_rig
    from rangekit.sim.rigs import simulate_walker_run

    rig = read_rig(RIGS / "walker_steps.json")
    w = simulate_walker_run(rig, duration_s=30.0, rng=2)
    log, steps = tmp_path / "ranges.csv", tmp_path / "steps.csv"
    w.log.to_csv(log)
    steps.write_text(w.steps.to_csv())
    r = ok(run(["track", "range-ekf", "--rig", RIGS / "walker_steps.json", log,
                "--steps", steps]))  # fmt: skip
    _, rows = _table(r.stdout)
    err = np.hypot(*(rows[:, 1:3] - w.truth_xy(rows[:, 0])).T)
    assert np.sqrt(np.mean(err**2)) < 0.2  # measured 0.10
    assert np.all(np.isnan(rows[:, 3]))  # no heading state
    assert_error(run(["track", "range-ekf", "--rig", RIGS / "walker_steps.json",
                      log]), 2, "--steps")  # fmt: skip
    assert_error(run(["track", "range-ekf", "--rig", SQUARE, log, "--steps", steps]),
                 2, "--steps")  # fmt: skip
    assert_error(run(["track", "range-ekf", log, "--steps", steps]), 2, "--rig")


def test_a_rig_without_anchors(tmp_path, log):
    """The particle filter takes one (same track as without --rig); the anchor trackers
    refuse it, exit 5, naming the rig file."""
    from rangekit.sim import girard2011

    walk = girard2011.simulate(rng=1)
    (tmp_path / "plan.json").write_text(json.dumps(walk.plan.to_json()))
    (tmp_path / "steps.csv").write_text(walk.steps.to_csv())
    (tmp_path / "ranges.csv").write_text(walk.ranges.to_csv())
    base = ["track", "particle", tmp_path / "steps.csv", "--map", tmp_path / "plan.json",
            "--ranges", tmp_path / "ranges.csv", "--start", "1.25,1", "--particles", "300",
            "--seed", "2"]  # fmt: skip
    with_rig = ok(run([*base, "--rig", RIGS / "girard2011_walker.json"])).stdout
    assert with_rig == ok(run(base)).stdout and with_rig.count("\n") > 40
    bare = RIGS / "girard2011_walker.json"
    assert_error(run(["track", "range-ekf", "--rig", bare, log]), 5, "girard2011_walker.json")


def test_five_tags_through_the_log_file(tmp_path):
    """More than three tags (issue 18): the log carries d4_m, d5_m; the rig's five tags
    track the robot, and DUHL (three receivers) refuses that log, exit 5."""
    from rangekit.io.duhllog import read_duhl_log

    rig = square_rig(n_tags=5)
    s = simulate_rig_run(rig, duration_s=30.0, rng=4)
    (tmp_path / "rig.json").write_text(json.dumps(rig.to_json()))
    p = tmp_path / "five.csv"
    s.log.to_csv(p)
    assert p.read_text().splitlines()[0].endswith("d3_m,d4_m,d5_m")
    back = read_duhl_log(p).distances.d_m
    np.testing.assert_array_equal(back, s.log.distances.d_m)  # floats round-trip exactly
    assert back.shape[1] == 5 and np.isfinite(back[:, 4]).mean() > 0.9
    _, rows = _table(ok(run(["track", "range-ekf", "--rig", tmp_path / "rig.json", p])).stdout)
    err = np.hypot(*(rows[:, 1:3] - s.truth_xy(rows[:, 0])).T)
    assert np.median(err[rows[:, 0] > 5.0]) < 0.055  # measured 0.027 m (RMS 0.032 m)
    kim = RIGS / "kim2013.json"
    assert_error(run(["track", "duhl", "--rig", kim, p]), 5, "d4_m")
