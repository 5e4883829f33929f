"""Step and range logs: round trips, and one clear error naming file, row and column."""

from __future__ import annotations

import io

import numpy as np
import pytest

from rangekit.errors import InputFileError, InvalidParameterError, LogFormatError
from rangekit.io.steplog import (
    RANGE_COLUMNS,
    STEP_COLUMNS,
    RangeLog,
    StepLog,
    read_range_log,
    read_step_log,
)

STEP_HEADER = ",".join(STEP_COLUMNS)
RANGE_HEADER = ",".join(RANGE_COLUMNS)


def steps(*lines, header=STEP_HEADER):
    return read_step_log(io.StringIO("\n".join([header, *lines])), name="steps.csv")


def ranges(*lines, header=RANGE_HEADER):
    return read_range_log(io.StringIO("\n".join([header, *lines])), name="ranges.csv")


def test_step_log_parses_and_round_trips():
    log = steps("# IMU steps", "1.0,1.25,0.5,0.03", "2.0,1.25,-3.0,")
    assert len(log) == 2 and log.t_s.tolist() == [1.0, 2.0]
    assert np.isnan(log.heading_sigma_rad[1])
    np.testing.assert_allclose(log.vectors_m[0], 1.25 * np.array([np.cos(0.5), np.sin(0.5)]))
    again = read_step_log(io.StringIO(log.to_csv(comment="again")), name="again")
    for k in STEP_COLUMNS:
        assert np.array_equal(getattr(again, k), getattr(log, k), equal_nan=True)


def test_range_log_parses_and_round_trips():
    log = ranges("0.07,0,1.02", "0.14,1,", "0.21,0,0.98")
    assert log.sensor.tolist() == [0, 1, 0] and log.n_sensors == 2
    assert np.isnan(log.range_m[1])  # out of range
    again = read_range_log(io.StringIO(log.to_csv()), name="again")
    assert np.array_equal(again.range_m, log.range_m, equal_nan=True)
    assert again.sensor.dtype == np.int64


def test_empty_logs_are_legal():
    assert len(steps()) == 0
    assert len(ranges()) == 0 and ranges().n_sensors == 0


@pytest.mark.parametrize(
    ("lines", "header", "message"),
    [
        ((), "t_s,length_m,heading_rad", "steps.csv row 1: missing column 'heading_sigma_rad'"),
        (("1.0,abc,0.0,0.0",), STEP_HEADER, "steps.csv row 2, column 'length_m': 'abc' is not"),
        (("1.0,-1.25,0.0,0.0",), STEP_HEADER, "row 2, column 'length_m': -1.25 is negative"),
        (("1.0,1.25,nan,0.0",), STEP_HEADER, "row 2, column 'heading_rad': 'nan' is not finite"),
        (("1.0,1.25,,0.0",), STEP_HEADER, "row 2, column 'heading_rad': empty cell"),
        (("1.0,1.25,0,-0.1",), STEP_HEADER, "column 'heading_sigma_rad': -0.1 is negative"),
        (("2.0,1.25,0,0", "1.0,1.25,0,0"), STEP_HEADER, "row 3, column 't_s': time 1 goes back"),
        (("1.0,1.25,0",), STEP_HEADER, "steps.csv row 2: 3 cells, the header has 4"),
    ],
)
def test_malformed_step_log_names_the_problem(lines, header, message):
    with pytest.raises(LogFormatError) as e:
        steps(*lines, header=header)
    assert message in str(e.value)
    assert "\n" not in str(e.value)  # one line


@pytest.mark.parametrize(
    ("lines", "header", "message"),
    [
        ((), "t_s,range_m", "ranges.csv row 1: missing column 'sensor'"),
        (("0.1,-1,1.0",), RANGE_HEADER, "ranges.csv row 2, column 'sensor': -1 is negative"),
        (("0.1,0.5,1.0",), RANGE_HEADER, "row 2, column 'sensor': '0.5' is not an integer"),
        (("0.1,0,-1.0",), RANGE_HEADER, "row 2, column 'range_m': -1.0 is negative"),
        (("0.1,0,inf",), RANGE_HEADER, "column 'range_m': 'inf' is not finite (leave the cell"),
        (("0.2,0,1", "0.1,1,1"), RANGE_HEADER, "row 3, column 't_s': time 0.1 goes backwards"),
        (("0.1,,1.0",), RANGE_HEADER, "row 2, column 'sensor': empty cell"),
    ],
)
def test_malformed_range_log_names_the_problem(lines, header, message):
    with pytest.raises(LogFormatError) as e:
        ranges(*lines, header=header)
    assert message in str(e.value)


def test_files_on_disk(tmp_path):
    p = tmp_path / "steps.csv"
    p.write_text(STEP_HEADER + "\n1.0,1.25,0.0,0.03\n")
    assert read_step_log(p).length_m.tolist() == [1.25]
    with pytest.raises(InputFileError, match="no such file"):
        read_step_log(tmp_path / "missing.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("")
    with pytest.raises(LogFormatError, match=r"bad\.csv: empty file"):
        read_range_log(bad)


def test_log_objects_validate():
    with pytest.raises(InvalidParameterError, match="length_m has 1 values, t_s has 2"):
        StepLog([1.0, 2.0], [1.0], [0.0, 0.0], [0.0, 0.0])
    with pytest.raises(InvalidParameterError, match="t_s must not decrease"):
        StepLog([2.0, 1.0], [1.0, 1.0], [0.0, 0.0], [0.0, 0.0])
    with pytest.raises(InvalidParameterError, match="heading_rad contains NaN"):
        StepLog([1.0], [1.0], [np.nan], [0.0])
    with pytest.raises(InvalidParameterError, match="sensor indices"):
        RangeLog([0.0], [-1], [1.0])
    with pytest.raises(InvalidParameterError, match="range_m must be >= 0"):
        RangeLog([0.0], [0], [np.inf])
    log = StepLog([1.0], [1.0], [0.0], [0.0])
    with pytest.raises(ValueError, match="read-only"):
        log.t_s[0] = 5.0
