"""Uncertainty of a UHL pose, and the UHL input from one-way ranging rows.

:func:`pose_covariance` propagates the distances' 1-sigma through the UHL solve
(:func:`rangekit.localize.uhl.solve_pose`, Kim & Kim 2013 §II-B) to first order:
``C = J diag(sigma^2) J^T`` with ``J`` the Jacobian of ``(x, y, phi)`` with respect to the
``3 n`` distances, by central differences (the solve is a composition of least squares
and a quartic root: smooth away from its method switch, where the hybrid rule of
Table I may jump; the difference step, 0.1 mm, is far below any distance's sigma).

:func:`uhl_inputs` turns the rows of ``rangekit range --scheme oneway`` (with
``--tx-order``: every row names its transmitter) into the UHL's ``(ids, distances,
sigmas)``: per transmitter and receiver the median distance over the windows, and the
median sigma (not divided by the square root of the count: what repeated windows share,
the transducers' and the geometry's model error, does not average out).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.localize.uhl import solve_pose

__all__ = ["UHLInputs", "pose_covariance", "uhl_inputs"]

#: Central-difference step of :func:`pose_covariance`, m.
STEP_M = 1e-4


def pose_covariance(
    tx_xyz: np.ndarray, distances: np.ndarray, sigma_m: np.ndarray | float, **solve_kw
) -> np.ndarray:
    """Covariance (3 x 3) of the UHL pose ``(x_m, y_m, phi_rad)`` from the distances' sigma.

    Parameters
    ----------
    tx_xyz, distances
        As for :func:`rangekit.localize.uhl.solve_pose` (shapes (n, 3)).
    sigma_m : float or array_like, shape (n, 3)
        1-sigma of each distance, m (independent).
    **solve_kw
        ``r_R``, ``method``, ``d_th`` of :func:`~rangekit.localize.uhl.solve_pose`.

    Examples
    --------
    Three transmitters around a robot at the origin, 1 cm on every distance:

    >>> import numpy as np
    >>> tx = np.array([[1.0, 0.0, 2.0], [-1.0, 1.0, 2.0], [0.0, -1.5, 2.0]])
    >>> a = np.radians([0.0, 120.0, 240.0])
    >>> rx = 0.19 * np.stack([np.cos(a), np.sin(a)], axis=1)  # receivers, heading 0
    >>> d = np.sqrt(np.sum((tx[:, None, :2] - rx[None]) ** 2, axis=2) + 2.0**2)
    >>> c = pose_covariance(tx, d, 0.01)
    >>> bool(0.003 < np.sqrt(c[0, 0]) < 0.03 and np.allclose(c, c.T))
    True
    """
    tx = np.asarray(tx_xyz, dtype=np.float64)
    d = np.asarray(distances, dtype=np.float64)
    sig = np.broadcast_to(np.asarray(sigma_m, dtype=np.float64), d.shape)
    if not np.all(np.isfinite(sig)) or np.any(sig < 0):
        raise InvalidParameterError("sigma_m must be finite and >= 0")
    jac = np.zeros((3, d.size))
    for k in range(d.size):
        step = np.zeros(d.size)
        step[k] = STEP_M
        hi = solve_pose(tx, d + step.reshape(d.shape), **solve_kw)
        lo = solve_pose(tx, np.maximum(d - step.reshape(d.shape), 0.0), **solve_kw)
        dphi = np.angle(np.exp(1j * (hi.phi_rad - lo.phi_rad)))
        jac[:, k] = [hi.x_m - lo.x_m, hi.y_m - lo.y_m, dphi]
        jac[:, k] /= 2.0 * STEP_M
    c = jac @ np.diag(sig.reshape(-1) ** 2) @ jac.T
    return 0.5 * (c + c.T)


@dataclass(frozen=True)
class UHLInputs:
    """What :func:`uhl_inputs` gathered: transmitter ids, (n, 3) distances and sigmas,
    and the transmitters left out (a receiver that never heard them)."""

    ids: list[int]
    distances_m: np.ndarray
    sigma_m: np.ndarray
    dropped: list[int]


def uhl_inputs(
    tx: Sequence[int], channel: Sequence[int], distance_m: Sequence[float],
    sigma_m: Sequence[float], *, what: str = "the ranges", n_receivers: int = 3,
) -> UHLInputs:  # fmt: skip
    """Per transmitter, the median distance and sigma to each receiver over the rows.

    Parameters
    ----------
    tx, channel, distance_m, sigma_m : sequences of one length
        One-way ranging rows: transmitter id (>= 0), receiver channel (0 .. n_receivers -
        1, channel k = receiver k + 1 of Kim & Kim's eq (1)), distance and its sigma
        (NaN: nothing heard).
    what : str
        The source, for messages.

    Raises
    ------
    IncompatibleInputError
        A transmitter id below 0 (the rows came without ``--tx-order``), a channel beyond
        the receivers.

    Examples
    --------
    >>> r = uhl_inputs([0, 0, 0, 1, 1, 1, 1], [0, 1, 2, 0, 1, 2, 0],
    ...                [2.0, 2.1, 2.2, 3.0, 3.1, 3.2, 3.4], [0.01] * 7)
    >>> r.ids, r.distances_m[1].tolist(), r.dropped
    ([0, 1], [3.2, 3.1, 3.2], [])
    """
    t = np.asarray(tx, dtype=np.int64)
    ch = np.asarray(channel, dtype=np.int64)
    d = np.asarray(distance_m, dtype=np.float64)
    s = np.asarray(sigma_m, dtype=np.float64)
    if not (len(t) == len(ch) == len(d) == len(s)):
        raise InvalidParameterError("tx, channel, distance_m and sigma_m must have one length")
    if np.any(t < 0):
        raise IncompatibleInputError(
            f"{what}: rows without a transmitter id (tx '-'); range with --tx-order so that "
            "every window names its transmitter"
        )
    if np.any((ch < 0) | (ch >= n_receivers)):
        bad = int(ch[(ch < 0) | (ch >= n_receivers)][0])
        raise IncompatibleInputError(
            f"{what}: channel {bad} is not one of the {n_receivers} receivers "
            f"(0..{n_receivers - 1})"
        )
    ids, dist, sig, dropped = [], [], [], []
    for i in np.unique(t).tolist():
        row_d, row_s = [], []
        for k in range(n_receivers):
            m = (t == i) & (ch == k) & np.isfinite(d)
            if not m.any():
                break
            row_d.append(float(np.median(d[m])))
            ss = s[m][np.isfinite(s[m])]
            row_s.append(float(np.median(ss)) if len(ss) else np.nan)
        if len(row_d) < n_receivers:
            dropped.append(i)
            continue
        ids.append(i)
        dist.append(row_d)
        sig.append(row_s)
    shape = (len(ids), n_receivers)
    return UHLInputs(
        ids, np.array(dist).reshape(shape), np.array(sig, dtype=np.float64).reshape(shape), dropped
    )
