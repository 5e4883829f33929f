"""Static UHL pose solver: robot pose from ceiling transmitters (Kim & Kim 2013 §II-B).

Three receivers sit on the robot at radius ``r_R`` and angles 0°, 120°, 240° from its
heading (the convention of :func:`rangekit.sim.ultrasonic.receiver_positions`), in the
plane ``z = 0``; transmitter ``i`` is at ``tx_xyz[i]`` on the ceiling. From the distances
``distances[i, l]`` (Tx ``i`` to receiver ``l``) :func:`solve_pose` recovers the pose
``(x, y, phi)`` with the direct method (DM), the indirect method using ranges (IMR), or
the hybrid rule of Kim & Kim 2013 Table I.

Examples
--------
>>> import numpy as np
>>> from rangekit.sim.ultrasonic import receiver_positions
>>> tx = np.array([[0.0, 0.0, 2.0], [2.0, 0.0, 2.0], [1.0, 1.7, 2.0]])
>>> rx = receiver_positions((0.7, 0.4, 0.5))
>>> d = np.linalg.norm(tx[:, None, :] - rx[None, :, :], axis=2)
>>> p = solve_pose(tx, d)
>>> round(p.x_m, 9), round(p.y_m, 9), round(p.phi_rad, 9), p.method_used
(0.7, 0.4, 0.5, 'indirect')
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rangekit import _validate as V
from rangekit.errors import InvalidParameterError
from rangekit.localize import _uhl_kernels as K

__all__ = ["DEFAULT_D_TH_M", "R_R_M", "UHLPose", "solve_pose"]

#: Receiver radius on the robot (m), Kim & Kim 2013 §II-A (equal to
#: ``rangekit.sim.ultrasonic.R_RECEIVER_M``; processing does not import the simulator).
R_R_M = 0.19
#: Default hybrid threshold ``d_th`` (m) of Table I (see :func:`solve_pose`, Notes).
DEFAULT_D_TH_M = 0.2
_METHODS = {"hybrid": K.HYBRID, "direct": K.DIRECT, "indirect": K.INDIRECT}


@dataclass(frozen=True)
class UHLPose:
    """A robot pose from :func:`solve_pose`.

    Attributes
    ----------
    x_m, y_m : float
        Position of the robot centre (m).
    phi_rad : float
        Heading (rad), in ``(-pi, pi]``.
    method_used : str
        ``"direct"`` or ``"indirect"``: the method that gave the position (the heading
        always comes from the direct method).
    residual_m : float
        RMS over all ``3 N`` distances of (predicted - measured) at this pose (m).
    """

    x_m: float
    y_m: float
    phi_rad: float
    method_used: str
    residual_m: float


def _check_inputs(tx_xyz, distances) -> tuple[np.ndarray, np.ndarray]:
    tx = np.asarray(tx_xyz, dtype=np.float64)
    if tx.ndim != 2 or tx.shape[1] != 3:
        raise InvalidParameterError(f"tx_xyz must have shape (n, 3), got shape {tx.shape}")
    if tx.shape[0] < 2:
        raise InvalidParameterError(f"tx_xyz has {tx.shape[0]} transmitter(s); at least 2 needed")
    if not np.all(np.isfinite(tx)):
        raise InvalidParameterError("tx_xyz contains NaN or infinite values")
    d = np.asarray(distances, dtype=np.float64)
    if d.shape != (tx.shape[0], 3):
        raise InvalidParameterError(
            f"distances must have shape {(tx.shape[0], 3)} (one row per Tx, one column per "
            f"receiver), got shape {d.shape}"
        )
    if not np.all(np.isfinite(d)):
        raise InvalidParameterError("distances contains NaN or infinite values")
    if np.any(d < 0.0):
        raise InvalidParameterError(f"distances must be >= 0, got minimum {d.min()!r}")
    return tx, d


def solve_pose(
    tx_xyz,
    distances,
    *,
    r_R: float = R_R_M,
    method: str = "hybrid",
    d_th: float = DEFAULT_D_TH_M,
) -> UHLPose:
    """Robot pose from Tx-to-receiver distances (UHL algorithm, Kim & Kim 2013 §II-B).

    Parameters
    ----------
    tx_xyz : array_like, shape (n, 3)
        Transmitter positions (m), ``n >= 2``; the receivers are in the plane ``z = 0``.
    distances : array_like, shape (n, 3)
        ``distances[i, l]``: distance (m) from Tx ``i`` to receiver ``l``, the receivers
        at angles 0°, 120°, 240° from the heading (Kim & Kim 2013 eq (1)).
    r_R : float, keyword-only
        Receiver radius on the robot (m).
    method : {"hybrid", "direct", "indirect"}, keyword-only
        Position by the direct method, the indirect method using ranges, or the hybrid
        rule of Table I.
    d_th : float, keyword-only
        Hybrid threshold (m): with collinear Txs, the DM position is kept when it lies
        within ``d_th`` of the Tx line (Table I line 3).

    Returns
    -------
    UHLPose

    Raises
    ------
    InvalidParameterError
        Bad shapes, fewer than 2 Txs, NaN/inf, negative distances, a bad ``r_R``,
        ``method`` or ``d_th``, or all Txs at the same x-y point (the heading is then
        unobservable).

    Notes
    -----
    *Heading* (all methods): ``A Phi = b`` of Kim & Kim 2013 eq (4) over all Tx pairs;
    the constrained minimum ``|Phi| = 1`` is a root of the quartic eq (8) in
    ``sin(phi)``; each real root gives two candidates ``cos(phi) = ±sqrt(1 - sin^2)``
    (eq (9)), and the one closest to the pseudoinverse solution of eq (4) on the unit
    circle is taken. Choices where the paper is silent: roots of (8) are found with
    :func:`numpy.roots` and kept when ``|Im| <= 1e-6`` and ``|Re| <= 1 + 1e-6``; the
    chosen angle is then polished by Newton steps on eq (7) (which is ``dJ/dphi / 2``
    for the cost ``J`` of eq (5)), accepted only while ``J`` decreases, because a
    near-double root of (8) is only found to ~1e-8 by :func:`numpy.roots`; ties in the
    distance to the pseudoinverse are broken by ``J``; if (8) vanishes identically (``J``
    constant on the circle, e.g. all distances equal), the pseudoinverse direction, or
    ``phi = 0`` if that is zero, is returned.

    *DM position*: spherical interpolation, eq (10), ``G_DM [x, y, x^2 + y^2]^T = h_DM``
    solved by least squares (the constraint between the third unknown and ``x, y`` is
    not imposed, as in the paper).

    *IMR position*: the range to the array centre from the isotropic array, eq (11),
    ``rho_i^2 = (sum_l (d_l^i)^2 - 3 r_R^2) / 3``; horizontal ranges
    ``rho_i^2 - z_i^2`` (clipped at 0) are multilaterated by the same linearised least
    squares. With collinear Txs (always so for ``n = 2``) each pair of circles is
    intersected (eq (12)); when two circles do not meet (noise), their tangent point
    on the Tx line (``h = 0``) is used; the points are split by the side of the Tx
    line (eq (13)), each side averaged, and the sub-estimate closest to the DM
    position is returned. Coincident Tx pairs are skipped; if none is left, the DM
    position is returned.

    *Hybrid* (Table I): DM if the Txs are collinear and the DM position is within
    ``d_th`` of their line, IMR otherwise. The paper determines ``d_th`` by experiment
    from the Tx spacing and ``z_T``; the default 0.2 m was chosen by simulation (σ = 1 cm
    distance noise, 3 Txs 1.5 m apart, ``z_T = 2`` m): the RMS position error of the IMR
    circle intersection exceeds the DM's (about 7 cm) within about 0.15-0.2 m of the line.

    Txs may have different heights ``z_i`` (the paper has ``z_i = z_T``); every equation
    above holds with ``z_i`` in place of ``z_T``. Txs count as collinear when the smaller
    principal spread of their x-y positions is at most 1e-6 of the larger one.
    """
    tx, d = _check_inputs(tx_xyz, distances)
    r_R = V.positive("r_R", r_R)
    d_th = V.positive("d_th", d_th, allow_zero=True)
    if method not in _METHODS:
        raise InvalidParameterError(f"method={method!r} must be one of {tuple(_METHODS)}")
    x, y, phi, used_dm, residual, ok = K.uhl_core(tx, d, float(r_R), _METHODS[method], d_th)
    if not ok:
        raise InvalidParameterError(
            "tx_xyz: all transmitters are at the same x-y point; the heading is unobservable"
        )
    return UHLPose(
        x_m=float(x),
        y_m=float(y),
        phi_rad=float(phi),
        method_used="direct" if used_dm else "indirect",
        residual_m=float(residual),
    )
