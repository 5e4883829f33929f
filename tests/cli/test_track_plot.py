"""``rangekit plot track`` reads every track ``rangekit track`` writes (issue 18 item 5):
each filter, CSV and JSON, causal and smoothed, on seeded simulated logs."""

from __future__ import annotations

import json

import numpy as np
import pytest
from clihelp import ok, run

from rangekit.sim import ahn2007, girard2011, jiang2018, kim2013


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("inputs")
    out = {}
    for seed in (1, 2, 4):  # the seeds whose smoothed tracks had negative variances
        p = d / f"walk{seed}.csv"
        p.write_text(jiang2018.simulate(rng=seed).log.to_csv())
        out[f"walk{seed}"] = p
    (d / "imu.csv").write_text(ahn2007.imu_log_text(ahn2007.simulate_robot(120, rng=2)))
    (d / "fixes.csv").write_text(ahn2007.position_log_text(ahn2007.simulate_pedestrian(30, rng=3)))
    r = kim2013.simulate(1, t_max_s=6.0, rng=1)
    r.to_log().to_csv(d / "run.csv")
    (d / "beacons.json").write_text(json.dumps(r.beacons.to_json()))
    w = girard2011.simulate(rng=3)
    (d / "steps.csv").write_text(w.steps.to_csv())
    out["start"] = f"{w.start_m[0]},{w.start_m[1]}"
    out["dir"] = d
    return out


def _cases(inp):
    d = inp["dir"]
    cases = []
    cases.append(["range-ekf", inp["walk1"]])
    for seed in (1, 2, 4):
        cases.append(["range-ekf", inp[f"walk{seed}"], "--smooth"])
    cases += [
        ["dead-reckoning", d / "imu.csv"],
        ["dead-reckoning", d / "imu.csv", "--smooth"],
        ["lmax", d / "fixes.csv", "--l-max", 0.5],
        ["duhl", d / "run.csv", "--beacons", d / "beacons.json"],
        ["duhl-ranges", d / "run.csv", "--beacons", d / "beacons.json"],
        ["particle", "--steps", d / "steps.csv", "--start", inp["start"], "--seed", 1],
    ]
    return cases


def test_plot_track_reads_every_track_output(inputs, tmp_path):
    n = 0
    for i, (filt, *args) in enumerate(_cases(inputs)):
        for fmt in ("csv", "json"):
            trk = tmp_path / f"t{i}.{fmt}"
            ok(run(["track", filt, *args, "--format", fmt, "-o", trk]))
            png = tmp_path / f"t{i}_{fmt}.png"
            ok(run(["plot", "track", trk, "--ellipses", 3, "-o", png]))
            assert png.stat().st_size > 5000
            n += 1
    assert n == 20


def test_smoothed_variances_are_positive_and_below_the_same_branch(inputs, tmp_path):
    """The issue's recipe: ``--smooth`` wrote var_x_m2 = -7.56 (seed 1)."""
    for seed in (1, 2, 4):
        out = tmp_path / f"s{seed}.json"
        r = ok(run(["track", "range-ekf", inputs[f"walk{seed}"], "--smooth",
                    "--format", "json", "-o", out]))  # fmt: skip
        js = json.loads(out.read_text())
        rows = np.array(js["rows"], dtype=float)
        cols = js["columns"]
        vx, vy, cxy = (rows[:, cols.index(c)] for c in ("var_x_m2", "var_y_m2", "cov_xy_m2"))
        assert np.all(vx > 0) and np.all(vy > 0) and np.all(cxy**2 < vx * vy)
        assert js["n_epochs_other_branch"] >= 0
        assert "smoothed along the final best branch" in r.stderr


def test_range_ekf_json_reports_branch_probabilities(inputs, tmp_path):
    out = tmp_path / "b.json"
    ok(run(["track", "range-ekf", inputs["walk1"], "--format", "json", "-o", out]))
    js = json.loads(out.read_text())
    p = np.array(js["p_branch"])
    assert p.size == len(js["rows"]) and np.all((p >= 0) & (p <= 1 + 1e-12))
    assert np.all(p[0::2] > 0.999)  # target 1 has a fix: one branch
