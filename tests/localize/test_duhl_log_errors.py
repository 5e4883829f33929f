"""``rangekit.localize.duhl.track_log``: a log the filter cannot run on is the log's error
(LogFormatError, the log named, a message that says what to give), while a bad setting
stays an InvalidParameterError; ``track_duhl`` on arrays keeps InvalidParameterError."""

from __future__ import annotations

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError, LogFormatError
from rangekit.io.duhllog import Beacons, DistanceRows, DUHLLog, OdometryRows
from rangekit.localize.duhl import track_duhl, track_log

BCN = Beacons(np.array([0, 1]), np.array([[0.0, 0.0, 2.5], [1.0, 0.0, 2.5]]))
ODO = OdometryRows(np.array([0.0, 0.1, 0.2]), np.zeros(3), np.zeros(3))
ONE_TX = DistanceRows(np.array([0.05, 0.15]), np.array([0, 0]), np.full((2, 3), 2.5))
NO_START = (
    "no start pose: no two distinct transmitters were heard on all three receivers "
    "(give the initial pose)"
)


def test_no_start_pose_is_the_logs_error():
    with pytest.raises(LogFormatError) as e:
        track_log(DUHLLog(ODO, ONE_TX), BCN, name="run.csv")
    assert str(e.value) == f"run.csv: the filter cannot run on this log: {NO_START}"
    assert e.value.exit_code == 4
    with pytest.raises(LogFormatError, match=r"^the log: the filter cannot run"):
        track_log(DUHLLog(ODO, ONE_TX), BCN)  # no name given
    # with the initial pose the same log runs
    trk = track_log(DUHLLog(ODO, ONE_TX), BCN, initial_pose=(0.5, 0.5, 0.0))
    assert trk.start_index == 0


def test_no_odometry_and_overflow_are_the_logs():
    with pytest.raises(LogFormatError, match=r"^run.csv: .*no odometry rows"):
        track_log(DUHLLog(distances=ONE_TX), BCN, name="run.csv")
    fast = OdometryRows(ODO.t_s, np.array([0.0, 1e9, 0.0]), np.zeros(3))
    with pytest.raises(LogFormatError, match=r"v_right has a value of 1e\+09"):
        track_log(DUHLLog(fast, ONE_TX), BCN, name="run.csv")


def test_settings_stay_invalid_parameters():
    """A bad initial pose or covariance is the caller's, not the log's (exit 2)."""
    log = DUHLLog(ODO, ONE_TX)
    for kw in ({"initial_pose": (0.0, np.nan, 0.0)}, {"initial_cov": np.eye(3)}):
        with pytest.raises(InvalidParameterError) as e:
            track_log(log, BCN, name="run.csv", **kw)
        assert not isinstance(e.value, LogFormatError) and e.value.exit_code == 2
        assert "run.csv" not in str(e.value)


def test_arrays_keep_invalid_parameter_error():
    with pytest.raises(InvalidParameterError, match=r"^no start pose: .*initial pose\)$") as e:
        track_duhl(ODO.t_s, ODO.v_right_mps, ODO.v_left_mps, ONE_TX.t_s, ONE_TX.tx,
                   ONE_TX.d_m, BCN.xyz_m)  # fmt: skip
    assert e.value.exit_code == 2
