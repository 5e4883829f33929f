"""Measurement-log and CSV-log reading: every malformed input names its row and column."""

from __future__ import annotations

import io

import numpy as np
import pytest

from rangekit.errors import InputFileError, LogFormatError
from rangekit.io.csvlog import Column, read_table, write_table
from rangekit.io.tracklog import LOG_COLUMNS, read_measurement_log

HEADER = ",".join(LOG_COLUMNS)
GOOD = [
    "0.0,robot,,,1.0,2.0,0.0,0.0036,0.0036,0,,",
    "0.0,fix,,1,1.2,0.1,,0.01,0.01,0,,",
    "0.0,range,0,2,,,,,,,3.1,0.1",
    "0.0,range,1,2,,,,,,,2.5,0.1",
    "3.0,robot,,,2.0,2.0,0.1,0.0036,0.0036,0,,",
    "3.0,range,0,2,,,,,,,,0.1",
]


def read(lines, header=HEADER):
    return read_measurement_log(io.StringIO("\n".join([header, *lines])), name="log.csv")


def test_good_log_parses():
    log = read(GOOD)
    assert log.n_targets == 2
    assert log.robot.t_s.tolist() == [0.0, 3.0]
    assert np.allclose(log.robot.cov_m2[0], 0.0036 * np.eye(2))
    assert log.fixes.rel_m.tolist() == [[1.2, 0.1]]
    assert np.isnan(log.ranges.range_m[2])  # failed ranging
    again = read_measurement_log(io.StringIO(log.to_csv()), name="again")
    assert np.array_equal(again.ranges.range_m, log.ranges.range_m, equal_nan=True)
    assert np.array_equal(again.robot.xy_m, log.robot.xy_m)


@pytest.mark.parametrize(
    "row,edit,match",
    [
        (
            4,
            lambda s: s.replace("3.1,0.1", "3.1,-0.1"),
            r"row 4, column 'sigma_m': -0.1 is negative",
        ),
        (
            4,
            lambda s: s.replace("3.1,0.1", "nan,0.1"),
            r"row 4, column 'range_m': 'nan' is not finite",
        ),
        (
            6,
            lambda s: s.replace("3.0,robot", "-1.0,robot"),
            r"row 6, column 't_s': time -1 goes back",
        ),
        (2, lambda s: s.replace("robot", "lidar"), r"row 2, column 'kind': unknown kind 'lidar'"),
        (3, lambda s: s.replace(",1,1.2", ",0,1.2"), r"row 3, column 'b': target ids start at 1"),
        (5, lambda s: s.replace("range,1,2", "range,2,2"), r"row 5, column 'a': a range from 2 to"),
        (
            2,
            lambda s: s.replace("0.0036,0.0036,0", "0.0036,0.0036,0.01"),
            r"row 2, column 'cov_xy_m2'",
        ),
        (2, lambda s: s.replace("1.0,2.0", ",2.0"), r"row 2, column 'x_m': a robot row needs"),
        (4, lambda s: s.replace(",3.1,0.1", ",3.1"), r"row 4: 11 cells, the header has 12"),
        (4, lambda s: s.replace("3.1", "abc"), r"row 4, column 'range_m': 'abc' is not a number"),
    ],
)
def test_bad_rows_name_row_and_column(row, edit, match):
    lines = list(GOOD)
    lines[row - 2] = edit(lines[row - 2])
    with pytest.raises(LogFormatError, match=match):
        read(lines)


def test_missing_column_and_empty_log():
    header = HEADER.replace(",sigma_m", "")
    with pytest.raises(LogFormatError, match=r"row 1: missing column 'sigma_m'"):
        read([g.rsplit(",", 1)[0] for g in GOOD], header=header)
    with pytest.raises(LogFormatError, match="no 'range' rows"):
        read(GOOD[:2])
    with pytest.raises(LogFormatError, match="empty file"):
        read_measurement_log(io.StringIO("# only a comment\n"), name="e.csv")


def test_missing_file(tmp_path):
    with pytest.raises(InputFileError, match="no such file"):
        read_measurement_log(tmp_path / "nope.csv")
    with pytest.raises(InputFileError, match="directory"):
        read_measurement_log(tmp_path)


def test_csv_table_round_trip_and_unknown_columns():
    spec = {"t_s": Column(kind="time"), "v": Column(empty_ok=True), "n": Column(kind="int")}
    text = write_table(["t_s", "v", "n"], [[0.0, 0.1 + 0.2, 3], [1.0, float("nan"), 4]])
    tab = read_table(io.StringIO(text), spec, name="t")
    assert tab["v"][0] == 0.1 + 0.2 and np.isnan(tab["v"][1]) and tab["n"].tolist() == [3, 4]
    with pytest.raises(LogFormatError, match="unknown column 'extra'"):
        read_table(io.StringIO("t_s,v,n,extra\n0,1,2,3\n"), spec, name="t", allow_extra=False)
    with pytest.raises(LogFormatError, match=r"row 2, column 'n': '1.5' is not an integer"):
        read_table(io.StringIO("t_s,v,n\n0,1,1.5\n"), spec, name="t")
