"""State estimation: the EKF core and RTS smoother, the Jiang 2018 range tracker, the
range EKF against a rig's fixed anchors, and Ahn & Yu's dead-reckoning EKF and l_max filter.

Examples
--------
>>> from rangekit.localize import ExtendedKalmanFilter
>>> ExtendedKalmanFilter([0.0, 0.0], [[1.0, 0.0], [0.0, 1.0]]).x.tolist()
[0.0, 0.0]
"""

from __future__ import annotations

from rangekit.localize.anchor_ekf import AnchorTrack, track_anchors
from rangekit.localize.deadreckoning import DeadReckoningResult, dead_reckon
from rangekit.localize.ekf import (
    ExtendedKalmanFilter,
    Rejection,
    UpdateResult,
    chi2_gate,
    numerical_jacobian,
    predict,
    rts_smooth,
    update,
)
from rangekit.localize.lmax import lmax_offline, lmax_online
from rangekit.localize.range_ekf import RangeTrack, track_ranges

__all__ = [
    "AnchorTrack",
    "DeadReckoningResult",
    "ExtendedKalmanFilter",
    "RangeTrack",
    "Rejection",
    "UpdateResult",
    "chi2_gate",
    "dead_reckon",
    "lmax_offline",
    "lmax_online",
    "numerical_jacobian",
    "predict",
    "rts_smooth",
    "track_anchors",
    "track_ranges",
    "update",
]
