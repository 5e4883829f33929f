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

import math
from dataclasses import dataclass

import numpy as np

from rangekit import _validate as V
from rangekit.errors import InvalidParameterError

__all__ = ["DEFAULT_D_TH_M", "R_R_M", "UHLPose", "solve_pose"]

#: Receiver radius on the robot (m), Kim & Kim 2013 §II-A (equal to
#: ``rangekit.sim.ultrasonic.R_RECEIVER_M``; processing does not import the simulator).
R_R_M = 0.19
#: Default hybrid threshold ``d_th`` (m) of Table I (see :func:`solve_pose`, Notes).
DEFAULT_D_TH_M = 0.2
#: Txs count as collinear when the smaller principal spread of their x-y positions is at
#: most this fraction of the larger one.
_COLLINEAR_RTOL = 1e-6
_METHODS = ("hybrid", "direct", "indirect")


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


def _receivers_local(r_R: float) -> np.ndarray:
    """Receiver positions in the robot frame, ``(3, 2)`` (Kim & Kim 2013 eq (1))."""
    g = 2.0 * np.pi * np.arange(3) / 3.0
    return r_R * np.stack([np.cos(g), np.sin(g)], axis=1)


def _orientation_system(txy: np.ndarray, d2: np.ndarray, r_R: float):
    """``A`` and ``b`` of Kim & Kim 2013 eq (4), over all pairs ``i < j``."""
    i, j = np.triu_indices(len(txy), k=1)
    dx = txy[j, 0] - txy[i, 0]
    dy = txy[j, 1] - txy[i, 1]
    s3 = math.sqrt(3.0)
    a = np.empty((2 * len(i), 2))
    a[0::2] = np.stack([s3 * dx, s3 * dy], axis=1)
    a[1::2] = np.stack([-dy, dx], axis=1)
    u = 2.0 * d2[:, 0] - d2[:, 1] - d2[:, 2]
    v = -d2[:, 1] + d2[:, 2]
    b = np.empty(2 * len(i))
    b[0::2] = u[i] - u[j]
    b[1::2] = v[i] - v[j]
    return a, b / (2.0 * s3 * r_R)


def _heading(txy: np.ndarray, d2: np.ndarray, r_R: float) -> float:
    """Heading by Kim & Kim 2013 eqs (4)-(9), polished by Newton steps on eq (7)."""
    a, b = _orientation_system(txy, d2, r_R)
    m = a.T @ a
    c = a.T @ b  # = -[b1, b2] of the paper
    a1, a2, a3 = m[0, 0], m[1, 1], m[0, 1]
    b1, b2 = -c[0], -c[1]
    phi_pinv = np.linalg.lstsq(a, b, rcond=None)[0]

    k4 = (a1 - a2) ** 2 + 4.0 * a3**2
    kappa = np.array(
        [
            k4,
            -2.0 * (a1 - a2) * b2 + 4.0 * a3 * b1,
            b1**2 + b2**2 - k4,
            2.0 * (a1 - a2) * b2 - 2.0 * a3 * b1,
            a3**2 - b2**2,
        ]
    )
    cands: list[float] = []
    scale = np.max(np.abs(kappa))
    if scale > 0.0:
        kappa = kappa / scale
        kappa[np.abs(kappa) < 1e-14] = 0.0
        if np.any(kappa[:-1] != 0.0):
            for root in np.roots(kappa):
                if abs(root.imag) <= 1e-6 and abs(root.real) <= 1.0 + 1e-6:
                    s = min(1.0, max(-1.0, root.real))
                    co = math.sqrt(max(0.0, 1.0 - s * s))
                    cands += [math.atan2(s, co), math.atan2(s, -co)]  # eq (9)

    def cost(phi: float) -> float:
        r = a @ np.array([math.cos(phi), math.sin(phi)]) - b
        return float(r @ r)

    if cands:
        pts = np.stack([np.cos(cands), np.sin(cands)], axis=1)
        gap = np.linalg.norm(pts - phi_pinv, axis=1)
        costs = np.array([cost(p) for p in cands])
        # closest to the pseudoinverse solution; ties broken by the eq (5) cost
        best = np.lexsort((costs, np.round(gap, 12)))[0]
        phi = float(cands[best])
    elif np.any(phi_pinv != 0.0):
        phi = math.atan2(phi_pinv[1], phi_pinv[0])
    else:
        phi = 0.0

    # Newton on eq (7), f(phi) = dJ/dphi / 2, accepted only while the cost J decreases.
    j0 = cost(phi)
    for _ in range(30):
        f = a3 * math.cos(2 * phi) + 0.5 * (a2 - a1) * math.sin(2 * phi)
        f += b2 * math.cos(phi) - b1 * math.sin(phi)
        fp = -2 * a3 * math.sin(2 * phi) + (a2 - a1) * math.cos(2 * phi)
        fp += -b2 * math.sin(phi) - b1 * math.cos(phi)
        if not fp > 0.0:
            break
        step = max(-0.1, min(0.1, -f / fp))
        for _ in range(20):
            j1 = cost(phi + step)
            if j1 <= j0:
                break
            step *= 0.5
        else:
            break
        phi, j0 = phi + step, j1
        if abs(step) < 1e-15:
            break
    return phi


def _sphere_ls(centres: np.ndarray, rhs_r2: np.ndarray) -> np.ndarray:
    """Least-squares ``[x, y]`` from ``|c_k - p|^2 = r2_k`` linearised in ``(x, y, x^2+y^2)``.

    This is the spherical-interpolation form of Kim & Kim 2013 eq (10) with rows
    ``[c_x, c_y, -0.5] . [x, y, x^2 + y^2] = (|c|^2 - r2) / 2``.
    """
    g = np.column_stack([centres, np.full(len(centres), -0.5)])
    h = 0.5 * (np.sum(centres**2, axis=1) - rhs_r2)
    return np.linalg.lstsq(g, h, rcond=None)[0][:2]


def _position_dm(txy, z2, d2, phi, r_R) -> np.ndarray:
    """Position by the direct method, Kim & Kim 2013 eq (10) (frame centred on the Txs)."""
    loc = _receivers_local(r_R)
    rot = np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]])
    g = loc @ rot.T  # (3, 2): g_l of eq (10)
    centres = (txy[:, None, :] - g[None, :, :]).reshape(-1, 2)
    r2 = (d2 - z2[:, None]).reshape(-1)
    return _sphere_ls(centres, r2)


def _ranges_horizontal2(d2, z2, r_R) -> np.ndarray:
    """Squared horizontal range to the array centre from eq (11): rho^2 - z^2, clipped >= 0."""
    rho2 = np.sum(d2, axis=1) / 3.0 - r_R**2
    return np.maximum(rho2 - z2, 0.0)


def _position_imr_collinear(txy, r2, centre_dir, p_dm) -> np.ndarray:
    """Collinear-Tx IMR: circle intersections, eqs (12)-(13), side chosen by the DM."""
    u, n = centre_dir
    t = txy @ u  # positions along the line (frame centred on the Tx centroid)
    off = float(np.mean(txy @ n))  # the line is n . p = off
    side = [[], []]
    for i in range(len(txy)):
        for j in range(i + 1, len(txy)):
            dist = t[j] - t[i]
            if abs(dist) <= 1e-12 * (1.0 + np.max(np.abs(t))):
                continue  # coincident Txs: no intersection information
            a = (r2[i] - r2[j] + dist * dist) / (2.0 * dist)
            h = math.sqrt(max(0.0, r2[i] - a * a))  # no intersection: tangent point
            foot = (t[i] + a) * u + off * n
            side[0].append(foot + h * n)  # Delta >= 0 (set I_1)
            side[1].append(foot - h * n)  # Delta <= 0 (set I_2)
    if not side[0]:
        return p_dm
    subs = [np.mean(s, axis=0) for s in side]
    return min(subs, key=lambda q: float(np.linalg.norm(q - p_dm)))


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
        raise InvalidParameterError(f"method={method!r} must be one of {_METHODS}")

    origin = tx[:, :2].mean(axis=0)
    txy = tx[:, :2] - origin  # work in a frame centred on the Txs (conditioning)
    z2 = tx[:, 2] ** 2
    d2 = d * d
    _, sv, vt = np.linalg.svd(txy, full_matrices=False)
    if not sv[0] > 1e-12 * (1.0 + float(np.max(np.abs(tx[:, :2])))):
        raise InvalidParameterError(
            "tx_xyz: all transmitters are at the same x-y point; the heading is unobservable"
        )
    collinear = bool(sv[1] <= _COLLINEAR_RTOL * sv[0])
    u = vt[0]
    n = np.array([-u[1], u[0]])

    phi = _heading(txy, d2, r_R)
    p_dm = _position_dm(txy, z2, d2, phi, r_R)
    if method == "direct":
        use_dm = True
    elif method == "indirect":
        use_dm = False
    else:
        use_dm = collinear and abs(float(n @ p_dm) - float(np.mean(txy @ n))) < d_th
    if use_dm:
        p, used = p_dm, "direct"
    else:
        r2 = _ranges_horizontal2(d2, z2, r_R)
        if collinear:
            p = _position_imr_collinear(txy, r2, (u, n), p_dm)
        else:
            p = _sphere_ls(txy, r2)
        used = "indirect"

    phi = math.remainder(phi, 2.0 * math.pi)
    if phi <= -math.pi:
        phi += 2.0 * math.pi
    loc = _receivers_local(r_R)
    rot = np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]])
    rx = p + loc @ rot.T
    pred = np.sqrt(np.sum((txy[:, None, :] - rx[None, :, :]) ** 2, axis=2) + z2[:, None])
    residual = float(np.sqrt(np.mean((pred - d) ** 2)))
    return UHLPose(
        x_m=float(p[0] + origin[0]),
        y_m=float(p[1] + origin[1]),
        phi_rad=float(phi),
        method_used=used,
        residual_m=residual,
    )
