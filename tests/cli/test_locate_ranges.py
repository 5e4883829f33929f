"""``synth oneway`` → ``range --scheme oneway --tx-order`` → ``locate --ranges``: the
one-way workflow from the CLI alone, with the pose's uncertainty."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from clihelp import assert_error, ok, run

from rangekit.io.duhllog import read_beacons
from rangekit.localize.uhl import solve_pose
from rangekit.localize.uhl_cov import pose_covariance, uhl_inputs


@pytest.fixture(scope="module")
def oneway(tmp_path_factory):
    d = tmp_path_factory.mktemp("ow")
    wav = d / "ow.wav"
    ok(run(["synth", "oneway", "--pose", "0.3,-0.2,40", "--windows", 12, "--seed", 4,
            "-o", wav]))  # fmt: skip
    return d, wav


def test_synth_writes_the_beacon_file(oneway):
    d, _ = oneway
    b = read_beacons(d / "ow.beacons.json")
    truth = json.loads((d / "ow.json").read_text())
    assert b.ids.tolist() == list(range(6)) and truth["beacons"] == "ow.beacons.json"
    np.testing.assert_allclose(b.xyz_m, truth["tx_positions_m"])
    assert [w["tx"] for w in truth["windows"][:6]] == list(range(6))  # firing order = ids


@pytest.mark.parametrize("fmt", ["csv", "json"])
def test_locate_reads_range_output_and_gives_sigma(oneway, fmt):
    d, wav = oneway
    r = d / f"r.{fmt}"
    ok(run(["range", "--scheme", "oneway", wav, "--period", 0.2, "--tx-order", "0,1,2,3,4,5",
            "--format", fmt, "-o", r]))  # fmt: skip
    res = ok(run(["locate", "--beacons", d / "ow.beacons.json", "--ranges", r,
                  "--format", "json"]))  # fmt: skip
    obj = json.loads(res.stdout)
    sx, sy, sh = obj["sigma_x_m"], obj["sigma_y_m"], obj["sigma_heading_deg"]
    assert 1e-4 < sx < 3e-3 and 1e-4 < sy < 3e-3 and 0.01 < sh < 1.0  # measured ~0.4 mm, 0.14 deg
    assert abs(obj["x_m"] - 0.3) < 4 * sx and abs(obj["y_m"] + 0.2) < 4 * sy
    assert abs(obj["heading_deg"] - 40.0) < 4 * sh
    assert np.allclose(obj["covariance"], np.array(obj["covariance"]).T)
    table = ok(run(["locate", "--beacons", d / "ow.beacons.json", "--ranges", r])).stdout
    assert table.splitlines()[0].split()[-3:] == ["sigma_x_m", "sigma_y_m", "sigma_heading_deg"]


def test_locate_ranges_errors(oneway):
    d, wav = oneway
    r = d / "no_ids.csv"
    ok(
        run(
            [
                "range",
                "--scheme",
                "oneway",
                wav,
                "--period",
                0.2,
                "--format",
                "csv",
                "-o",
                r,
                "--no-setup",
            ]
        )
    )  # fmt: skip  (the setup would name the transmitters)
    bcn = d / "ow.beacons.json"
    assert_error(run(["locate", "--beacons", bcn, "--ranges", r]), 5, "no_ids.csv", "--tx-order")
    res = run(["locate", "--beacons", bcn, "--ranges", r, "--tx", "1:2,2,2"])
    assert_error(res, 2, "--tx", "--ranges")
    assert_error(run(["locate", "--beacons", bcn, "--ranges", r, "--sigma", 0.01]), 2, "--sigma")
    bad = d / "bad.json"
    bad.write_text('{"ranges": [{"tx": true, "channel": 0, "distance_m": 1, "sigma_m": 0.1}]}')
    assert_error(run(["locate", "--beacons", bcn, "--ranges", bad]), 4, "bad.json")


def test_sigma_option_adds_the_pose_sigma(oneway):
    d, _ = oneway
    b = read_beacons(d / "ow.beacons.json")
    pose = (0.5, 0.1, math.radians(20.0))
    a = pose[2] + np.radians([0.0, 120.0, 240.0])
    rx = np.array(pose[:2]) + 0.19 * np.stack([np.cos(a), np.sin(a)], axis=1)
    tx = b.xyz_m[:3]
    dist = np.sqrt(np.sum((tx[:, None, :2] - rx[None]) ** 2, axis=2) + tx[:, None, 2] ** 2)
    args = [a for i in range(3) for a in ("--tx", f"{i}:" + ",".join(f"{v:.6f}" for v in dist[i]))]
    res = json.loads(ok(run(["locate", "--beacons", d / "ow.beacons.json", *args, "--sigma",
                             0.01, "--format", "json"])).stdout)  # fmt: skip
    want = np.sqrt(np.diag(pose_covariance(tx, dist, 0.01)))
    assert res["sigma_x_m"] == pytest.approx(want[0], rel=1e-3)
    assert res["sigma_heading_deg"] == pytest.approx(math.degrees(want[2]), rel=1e-3)


def test_pose_covariance_matches_monte_carlo():
    """First-order covariance against 1,000 noisy solves (1 cm distances): within 10 %."""
    tx = np.array([[1.0, 0.0, 2.0], [-1.0, 1.0, 2.0], [0.0, -1.5, 2.0]])
    a = np.radians([0.0, 120.0, 240.0]) + 0.5
    rx = 0.19 * np.stack([np.cos(a), np.sin(a)], axis=1) + [0.3, 0.2]
    dist = np.sqrt(np.sum((tx[:, None, :2] - rx[None]) ** 2, axis=2) + 4.0)
    c = pose_covariance(tx, dist, 0.01)
    rng = np.random.default_rng(0)
    s = np.array([
        [p.x_m, p.y_m, p.phi_rad]
        for p in (solve_pose(tx, dist + 0.01 * rng.standard_normal(dist.shape))
                  for _ in range(1000))
    ])  # fmt: skip
    np.testing.assert_allclose(s.std(axis=0), np.sqrt(np.diag(c)), rtol=0.1)  # measured 2 %


def test_uhl_inputs_medians_and_dropped():
    r = uhl_inputs([3, 3, 3, 3, 5, 5], [0, 1, 2, 0, 0, 1], [2.0, 2.1, 2.2, 2.4, 3.0, 3.1],
                   [0.01, 0.02, 0.01, 0.03, 0.01, 0.01])  # fmt: skip
    assert r.ids == [3] and r.dropped == [5]
    assert r.distances_m.tolist() == [[2.2, 2.1, 2.2]]
    assert r.sigma_m.tolist() == [[0.02, 0.02, 0.01]]


def test_locate_is_the_library_call(tmp_path):
    """`rangekit locate` prints what rangekit.localize.locate.locate_pose returns."""
    from rangekit.io.duhllog import Beacons
    from rangekit.localize.locate import locate_pose
    from rangekit.sim.ultrasonic import receiver_positions

    b = Beacons([1, 2, 3], [[0.0, 0.0, 2.0], [3.0, 0.0, 2.0], [0.0, 3.0, 2.0]])
    (tmp_path / "b.json").write_text(json.dumps(b.to_json()))
    rx = receiver_positions((1.1, 0.9, np.radians(-40.0)))
    d = [np.linalg.norm(rx - b.position(i), axis=1) + 0.003 * k for k, i in enumerate((1, 2, 3))]
    tx = [f"{i}:{','.join(f'{v:.9f}' for v in row)}" for i, row in zip((1, 2, 3), d, strict=True)]
    args = ["locate", "--beacons", tmp_path / "b.json", "--sigma", "0.01", "--format", "json"]
    got = json.loads(ok(run([*args, *(a for t in tx for a in ("--tx", t))])).stdout)
    want = locate_pose(b, [1, 2, 3], [[float(f"{v:.9f}") for v in r] for r in d], sigma_m=0.01)
    for k, v in want.row().items():
        assert got[k] == (v if isinstance(v, str) else pytest.approx(v, rel=1e-12, abs=1e-15)), k
    np.testing.assert_allclose(got["covariance"], want.covariance, rtol=1e-12)
