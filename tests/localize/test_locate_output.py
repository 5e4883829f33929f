"""``Located`` as ``rangekit locate`` prints it (row, JSON, table/CSV) and the
``--ranges`` reader's choice of JSON or CSV on standard input."""

from __future__ import annotations

import io
import json
import math
import sys

import numpy as np
import pytest

from rangekit.io.duhllog import Beacons
from rangekit.io.results import format_rows
from rangekit.localize.locate import FIELDS, SIGMA_FIELDS, locate_pose, read_range_rows
from rangekit.sim.ultrasonic import receiver_positions

B = Beacons([1, 2, 3], [[0.0, 0.0, 2.0], [3.0, 0.0, 2.0], [0.0, 3.0, 2.2]])


POSE = (1.2, 0.7, math.radians(34.0))


def _distances(pose=POSE):
    rx = receiver_positions(pose)
    return [np.linalg.norm(rx - B.position(i), axis=1).tolist() for i in (1, 2, 3)]


def test_the_located_pose_records_how_it_was_solved():
    p = locate_pose(B, [3, 1, 2], [_distances()[k] for k in (2, 0, 1)], beacon_file="b.json")
    assert (p.method, p.d_th_m, p.r_R_m, p.tx, p.beacon_file) == (
        "hybrid",
        0.2,
        0.19,
        (3, 1, 2),
        "b.json",
    )  # fmt: skip  (the defaults of rangekit.localize.uhl.solve_pose)
    q = locate_pose(B, [1, 2, 3], _distances(), method="direct", d_th=0.5, r_R=0.19)
    assert (q.method, q.method_used, q.d_th_m) == ("direct", "direct", 0.5)


def test_json_keys_and_values():
    p = locate_pose(B, [1, 2, 3], _distances(), beacon_file="b.json")
    obj = p.to_json()
    assert list(obj) == [*FIELDS, "heading_rad", "method", "d_th_m", "r_R_m", "beacons", "tx"]
    assert obj["tx"] == [1, 2, 3] and obj["beacons"] == "b.json"
    assert obj["heading_rad"] == p.heading_rad
    assert abs(obj["heading_deg"] - 34.0) < 1e-6  # exact distances: the true heading
    assert json.loads(p.format("json")) == obj
    s = locate_pose(B, [1, 2, 3], _distances(), sigma_m=0.01)
    obj = s.to_json()
    assert list(obj)[5:8] == list(SIGMA_FIELDS) and list(obj)[-1] == "covariance"
    np.testing.assert_array_equal(obj["covariance"], s.covariance)
    json.dumps(obj, allow_nan=False)


@pytest.mark.parametrize("fmt", ["table", "csv"])
def test_table_and_csv_are_the_row(fmt):
    p = locate_pose(B, [1, 2, 3], _distances())
    assert p.fields() == FIELDS
    assert p.format(fmt) == format_rows([p.row()], FIELDS, fmt)
    s = locate_pose(B, [1, 2, 3], _distances(), sigma_m=0.01)
    assert s.fields() == FIELDS + SIGMA_FIELDS
    assert s.format(fmt) == format_rows([s.row()], FIELDS + SIGMA_FIELDS, fmt)
    assert s.format("csv").splitlines()[0] == ",".join(FIELDS + SIGMA_FIELDS)


CSV = "tx,channel,distance_m,sigma_m\n" + "".join(
    f"{t},{c},{2.0 + t + c / 10},0.001\n" for t in (0, 1) for c in range(3)
)


def _stdin(monkeypatch, text: str):
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(text.encode())))


@pytest.mark.parametrize("as_json", [False, True])
def test_standard_input_is_json_when_it_starts_with_a_brace(monkeypatch, tmp_path, as_json):
    p = tmp_path / "r.csv"
    p.write_text(CSV)
    want = read_range_rows(p)
    if as_json:
        rows = [
            {"tx": t, "channel": c, "distance_m": 2.0 + t + c / 10, "sigma_m": 0.001}
            for t in (0, 1)
            for c in range(3)
        ]
        text = "\n  " + json.dumps({"ranges": rows})  # leading space: still JSON
    else:
        text = CSV
    _stdin(monkeypatch, text)
    got = read_range_rows("-", name="standard input")
    assert got.ids == want.ids
    np.testing.assert_array_equal(got.distances_m, want.distances_m)
