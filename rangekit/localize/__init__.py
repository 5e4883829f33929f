"""State estimation: the extended Kalman filter core and the RTS smoother.

Examples
--------
>>> from rangekit.localize import ExtendedKalmanFilter
>>> ExtendedKalmanFilter([0.0, 0.0], [[1.0, 0.0], [0.0, 1.0]]).x.tolist()
[0.0, 0.0]
"""

from __future__ import annotations

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

__all__ = [
    "ExtendedKalmanFilter",
    "Rejection",
    "UpdateResult",
    "chi2_gate",
    "numerical_jacobian",
    "predict",
    "rts_smooth",
    "update",
]
