"""The track output of every tracker (``rangekit.io.tracks``): the text ``rangekit track``
prints is :func:`format_track` of the library's table."""

from __future__ import annotations

import csv
import io
import json
import math

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.io.tracks import INT_COLUMNS, format_track, track_table

COLS = ("t_s", "target", "x_m", "y_m", "status")
ROWS = np.array([[0.0, 0.0, 1.5, -0.25, 3.0], [0.5, 1.0, math.nan, 2.0, 0.0]])


def test_table_values_ints_and_nulls():
    assert {"target", "status"} <= INT_COLUMNS
    t = track_table(COLS, ROWS)
    assert t == [[0.0, 0, 1.5, -0.25, 3], [0.5, 1, None, 2.0, 0]]
    assert [type(v) for v in t[0]] == [float, int, float, float, int]
    assert track_table(("x_m",), [[math.inf]]) == [[None]]
    with pytest.raises(ValueError):  # a row of the wrong width
        track_table(COLS, [[0.0, 1.0]])


def test_csv_round_trips_with_empty_cells():
    text = format_track(COLS, ROWS, "csv", filter_name="f", log="l.csv")
    rows = list(csv.DictReader(io.StringIO(text)))
    assert list(rows[0]) == list(COLS)
    assert rows[1] == {"t_s": "0.5", "target": "1", "x_m": "", "y_m": "2.0", "status": "0"}
    assert float(rows[0]["y_m"]) == -0.25


def test_json_object_and_extra_keys():
    extra = {"n_targets": 2, "filter": "not overridden first"}
    obj = json.loads(
        format_track(
            COLS, ROWS, "json", filter_name="range-ekf", log="w.csv", smoothed=True, extra=extra
        )
    )
    assert list(obj)[:5] == ["filter", "log", "smoothed", "columns", "rows"]
    assert obj["smoothed"] is True and obj["log"] == "w.csv" and obj["n_targets"] == 2
    assert obj["rows"][1] == [0.5, 1, None, 2.0, 0]
    assert obj["filter"] == "not overridden first"  # extra keys come last and win


def test_aligned_table():
    lines = format_track(COLS, ROWS, "table", filter_name="f", log="l").splitlines()
    assert lines[0].split() == list(COLS) and len(lines) == 3
    assert len({len(ln) for ln in lines[:2]}) == 1  # right-aligned columns
    with pytest.raises(InvalidParameterError, match="fmt='xml'"):
        format_track(COLS, ROWS, "xml", filter_name="f", log="l")
