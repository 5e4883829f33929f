"""``rangekit locate`` prints the library's result: the same options through
:func:`rangekit.localize.locate.locate_pose` and the CLI give the same output."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from clihelp import ok, run

from rangekit.io.duhllog import Beacons, read_beacons
from rangekit.localize.locate import locate_pose, read_distance_table
from rangekit.sim.ultrasonic import receiver_positions


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("locate")
    b = Beacons([1, 2, 3], [[0.0, 0.0, 2.0], [3.0, 0.0, 2.0], [0.0, 3.0, 2.2]])
    (d / "b.json").write_text(json.dumps(b.to_json()))
    rx = receiver_positions((1.2, 0.7, math.radians(34.0)))
    rows = [f"{i}," + ",".join(f"{v:.4f}" for v in np.linalg.norm(rx - b.position(i), axis=1))
            for i in (1, 2, 3)]  # fmt: skip
    (d / "d.csv").write_text("tx,d1_m,d2_m,d3_m\n" + "\n".join(rows) + "\n")
    return d / "b.json", d / "d.csv"


@pytest.mark.parametrize(
    ("extra", "kw"),
    [
        ([], {}),
        (["--sigma", "0.01"], {"sigma_m": 0.01}),
        (["--method", "direct", "--d-th", "0.5", "--r-r", "0.2"],
         {"method": "direct", "d_th": 0.5, "r_R": 0.2}),
    ],
)  # fmt: skip
@pytest.mark.parametrize("fmt", ["table", "csv", "json"])
def test_locate_prints_the_located_pose(files, extra, kw, fmt):
    bcn, dist = files
    r = ok(run(["locate", "--beacons", bcn, "--distances", dist, "--format", fmt, *extra]))
    ids, d = read_distance_table(dist)
    pose = locate_pose(read_beacons(bcn), ids, d, source=str(dist), beacon_file=str(bcn), **kw)
    assert r.stdout == pose.format(fmt)
    assert r.stderr == ""


def test_tx_options_are_the_library_call(files):
    bcn, _ = files
    r = ok(run(["locate", "--beacons", bcn, "--tx", "2:2.7114,2.9151,2.7292", "--tx",
                "1:2.5481,2.3812,2.3949", "--format", "json"]))  # fmt: skip
    d = [[2.7114, 2.9151, 2.7292], [2.5481, 2.3812, 2.3949]]
    pose = locate_pose(read_beacons(bcn), [2, 1], d, beacon_file=str(bcn))
    assert r.stdout == pose.format("json")
    assert json.loads(r.stdout)["tx"] == [2, 1]
