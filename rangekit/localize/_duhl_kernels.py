"""Compiled DUHL filter (Kim & Kim 2013 §III-IV): pose EKF and dynamic distance estimation.

The public interface is :mod:`rangekit.localize.duhl`; the equations and choices are
documented there. Everything here is a numba ``njit`` kernel on float64 arrays; a whole
log runs in one call of :func:`run_duhl`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rangekit.localize._uhl_kernels import uhl_core, wrap_angle

# Per-odometry-row status bits of run_duhl.
ST_OBSERVED = 1  # a UHL observation corrected the pose at this row
ST_TOO_FEW = 2  # a distance row arrived but fewer than 2 usable Txs: predict only
ST_REJECTED = 4  # a UHL observation was rejected (residual or gate)
ST_NO_ODOMETRY = 8  # the odometry sample was missing (NaN): no motion applied

# Per-distance-row status codes of run_duhl.
OBS_USED = 0  # observation applied
OBS_TOO_FEW = 1  # fewer than 2 usable Txs after the discard step
OBS_DEGENERATE = 2  # UHL undefined (all Txs at one x-y point)
OBS_RESIDUAL = 3  # UHL residual above max_residual_m
OBS_GATED = 4  # innovation outside the gate
OBS_EMPTY = 5  # the distance row had no finite distance
OBS_BEFORE_START = 6  # before the filter's start time: ignored

#: Variance given to a missed receiver in the eq (25) correction (effectively no update).
_MISSING_VAR = 1e12


@njit(cache=True)
def receiver_local(r_R: float, ell: int) -> tuple[float, float]:
    """Receiver ``ell`` in the robot frame, Kim & Kim 2013 eq (1)."""
    g = 2.0 * math.pi * ell / 3.0
    return r_R * math.cos(g), r_R * math.sin(g)


@njit(cache=True)
def inv3(a: np.ndarray) -> np.ndarray:
    """Inverse of a 3x3 matrix by cofactors."""
    out = np.empty((3, 3))
    out[0, 0] = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    out[0, 1] = a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]
    out[0, 2] = a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]
    out[1, 0] = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    out[1, 1] = a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]
    out[1, 2] = a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]
    out[2, 0] = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    out[2, 1] = a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]
    out[2, 2] = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    det = a[0, 0] * out[0, 0] + a[0, 1] * out[1, 0] + a[0, 2] * out[2, 0]
    return out / det


@njit(cache=True)
def _sym(p: np.ndarray) -> None:
    for i in range(3):
        for j in range(i + 1, 3):
            m = 0.5 * (p[i, j] + p[j, i])
            p[i, j] = m
            p[j, i] = m


@njit(cache=True)
def odometry_increment(v_r: float, v_l: float, dt: float, b_w: float) -> tuple[float, float]:
    """``(Delta D, Delta phi)`` of Kim & Kim 2013 eq (14)."""
    return dt * (v_r + v_l) / 2.0, dt * (v_r - v_l) / b_w


@njit(cache=True)
def predict_pose(
    x: np.ndarray, p: np.ndarray, v_r: float, v_l: float, dt: float, b_w: float, k_v: float
) -> None:
    """Pose prediction in place: eq (14) and the covariance of eq (16).

    ``U = diag(k_v |v_R| / dt, k_v |v_L| / dt)`` (§V); ``J_f,u`` is the chain
    ``d f / d(Delta D, Delta phi) . d(Delta D, Delta phi) / d(v_R, v_L)``. Written out
    in scalars (no temporaries): ``J_f,x = I + a e_0 e_2^T + b e_1 e_2^T``.
    """
    dd, dph = odometry_increment(v_r, v_l, dt, b_w)
    ang = x[2] + 0.5 * dph
    c, s = math.cos(ang), math.sin(ang)
    a = -dd * s
    b = dd * c
    # J_f,u = [[c, -dd/2 s], [s, dd/2 c], [0, 1]] @ [[dt/2, dt/2], [dt/b_w, -dt/b_w]]
    h, w = 0.5 * dt, dt / b_w
    j00, j01 = c * h + 0.5 * a * w, c * h - 0.5 * a * w
    j10, j11 = s * h + 0.5 * b * w, s * h - 0.5 * b * w
    j20, j21 = w, -w
    u0 = k_v * abs(v_r) / dt
    u1 = k_v * abs(v_l) / dt
    x[0] += dd * c
    x[1] += dd * s
    x[2] = wrap_angle(x[2] + dph)
    # J_f,x P J_f,x^T in place: rows 0, 1 then columns 0, 1 (row/column 2 unchanged)
    for j in range(3):
        p[0, j] += a * p[2, j]
        p[1, j] += b * p[2, j]
    for i in range(3):
        p[i, 0] += a * p[i, 2]
        p[i, 1] += b * p[i, 2]
    p[0, 0] += j00 * j00 * u0 + j01 * j01 * u1
    p[0, 1] += j00 * j10 * u0 + j01 * j11 * u1
    p[0, 2] += j00 * j20 * u0 + j01 * j21 * u1
    p[1, 1] += j10 * j10 * u0 + j11 * j11 * u1
    p[1, 2] += j10 * j20 * u0 + j11 * j21 * u1
    p[2, 2] += j20 * j20 * u0 + j21 * j21 * u1
    p[1, 0] = p[0, 1]
    p[2, 0] = p[0, 2]
    p[2, 1] = p[1, 2]


@njit(cache=True)
def predict_distances(
    pose: np.ndarray,
    q: np.ndarray,
    qc: np.ndarray,
    tx: np.ndarray,
    v_r: float,
    v_l: float,
    dt: float,
    b_w: float,
    k_v: float,
    r_R: float,
    ws: np.ndarray,
) -> None:
    """Distance prediction in place for one Tx: eq (23) and its covariance, eq (24).

    ``pose`` is the pose estimate before this odometry step (it gives ``rho`` and
    ``theta`` of eq (23)). ``J_g,q`` is diagonal, ``1 - (alpha - beta) / q^2``: the
    pose is the EKF estimate, not a function of ``q``, so the paper's
    ``d beta / d q`` term (through the UHL pose) is not included. ``ws`` is a
    workspace of 9 floats.
    """
    dd, dph = odometry_increment(v_r, v_l, dt, b_w)
    ch, sh = math.cos(0.5 * dph), math.sin(0.5 * dph)
    cp, sp = math.cos(pose[2]), math.sin(pose[2])
    u0 = k_v * abs(v_r) / dt
    u1 = k_v * abs(v_l) / dt
    predict_distances_fast(pose, q, qc, tx, dd, dph, ch, sh, cp, sp, u0, u1, dt, b_w, r_R, ws)


#: Receiver directions in the robot frame, (cos, sin) of 0, 120 and 240 degrees (eq (1)).
_RX_C = (1.0, -0.5, -0.5)
_RX_S = (0.0, 0.8660254037844386, -0.8660254037844386)


@njit(cache=True)
def predict_distances_fast(
    pose: np.ndarray,
    q: np.ndarray,
    qc: np.ndarray,
    tx: np.ndarray,
    dd: float,
    dph: float,
    ch: float,
    sh: float,
    cp: float,
    sp: float,
    u0: float,
    u1: float,
    dt: float,
    b_w: float,
    r_R: float,
    ws: np.ndarray,
) -> None:
    """:func:`predict_distances` with the per-step quantities precomputed (no
    trigonometry): ``(ch, sh)`` = cos, sin of ``Delta phi / 2``, ``(cp, sp)`` of the
    heading, ``u0, u1`` the diagonal of ``U``."""
    ex = tx[0] - pose[0]
    ey = tx[1] - pose[1]
    h = math.sqrt(ex * ex + ey * ey)  # sqrt(rho^2 - z_T^2)
    if h > 0.0:  # theta = atan2(ey, ex) - phi
        ct = (ex * cp + ey * sp) / h
        st = (ey * cp - ex * sp) / h
    else:
        ct, st = 1.0, 0.0
    ctd = ct * ch + st * sh  # cos(theta - dphi / 2)
    std = st * ch - ct * sh
    for ell in range(3):
        lx, ly = r_R * _RX_C[ell], r_R * _RX_S[ell]
        alpha = dd * (lx * ch + ly * sh)
        rot = lx * st - ly * ct
        beta = h * (dd * ctd + dph * rot)
        ql = q[ell]
        ws[ell] = 1.0 - (alpha - beta) / (ql * ql)  # J_g,q (diagonal)
        g_dd = (lx * ch + ly * sh - h * ctd) / ql
        g_dph = (0.5 * dd * (-lx * sh + ly * ch) - h * (0.5 * dd * std + rot)) / ql
        ws[3 + ell] = 0.5 * dt * g_dd + dt / b_w * g_dph  # J_g,u, v_R column
        ws[6 + ell] = 0.5 * dt * g_dd - dt / b_w * g_dph  # J_g,u, v_L column
        q[ell] = ql + (alpha - beta) / ql
    for i in range(3):
        for j in range(i, 3):
            v = ws[i] * qc[i, j] * ws[j] + ws[3 + i] * u0 * ws[3 + j] + ws[6 + i] * u1 * ws[6 + j]
            qc[i, j] = v
            qc[j, i] = v


@njit(cache=True)
def distance_jacobian(pose: np.ndarray, tx: np.ndarray, r_R: float) -> tuple:
    """Expected distances of eq (28) and their Jacobian w.r.t. the pose (eq (22) partials)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    q = np.empty(3)
    jac = np.empty((3, 3))
    for ell in range(3):
        lx, ly = receiver_local(r_R, ell)
        rx = pose[0] + lx * c - ly * s
        ry = pose[1] + lx * s + ly * c
        dx, dy = rx - tx[0], ry - tx[1]
        d = math.sqrt(dx * dx + dy * dy + tx[2] * tx[2])
        q[ell] = d
        jac[ell, 0] = dx / d
        jac[ell, 1] = dy / d
        jac[ell, 2] = (dx * (-lx * s - ly * c) + dy * (lx * c - ly * s)) / d
    return q, jac


@njit(cache=True)
def init_distances(
    pose: np.ndarray, p: np.ndarray, tx: np.ndarray, r_R: float
) -> tuple[np.ndarray, np.ndarray]:
    """Initialisation of a newly heard Tx from the pose: eqs (28)-(29)."""
    q, jac = distance_jacobian(pose, tx, r_R)
    qc = jac @ p @ jac.T
    _sym(qc)
    return q, qc


@njit(cache=True)
def correct_distances(
    q: np.ndarray, qc: np.ndarray, d: np.ndarray, var_d: float, gate: float
) -> int:
    """Distance correction in place: eqs (25)-(27), Joseph form; NaN receivers skipped.

    Returns the number of receivers used, or -1 (and no change) when the squared
    Mahalanobis distance of the innovation exceeds ``gate`` (``gate <= 0``: no gate).
    """
    r = np.zeros((3, 3))
    innov = np.zeros(3)
    used = 0
    for ell in range(3):
        if math.isfinite(d[ell]):
            r[ell, ell] = var_d
            innov[ell] = d[ell] - q[ell]
            used += 1
        else:
            r[ell, ell] = _MISSING_VAR
    if used == 0:
        return 0
    si = inv3(qc + r)
    if gate > 0.0:
        m2 = innov @ si @ innov
        if not m2 <= gate:
            return -1
    k = qc @ si
    ik = np.eye(3) - k
    qn = ik @ qc @ ik.T + k @ r @ k.T
    for ell in range(3):
        if not math.isfinite(d[ell]):
            for j in range(3):  # no information: keep the prediction's row and column
                k[ell, j] = 0.0
    q += k @ innov
    _sym(qn)
    qc[:, :] = qn
    return used


@njit(cache=True)
def observation(txs: np.ndarray, qs: np.ndarray, qcs: np.ndarray, r_R: float, d_th: float) -> tuple:
    """UHL pose from the estimated distances, eq (15), and its covariance, eq (21).

    Returns ``(z, R, residual_m, ok)``. ``J_z,q^i`` of eq (21) is the least-squares
    sensitivity ``(H^T H)^-1 H_i^T`` of the pose to the distances at ``z``, ``H`` the
    stacked eq (22) partials of all the Txs used.
    """
    n = txs.shape[0]
    x, y, phi, _, residual, ok = uhl_core(txs, qs, r_R, 0, d_th)
    z = np.array([x, y, phi])
    rr = np.zeros((3, 3))
    if not ok:
        return z, rr, residual, False
    a = np.zeros((3, 3))
    jacs = np.empty((n, 3, 3))
    for i in range(n):
        _, jac = distance_jacobian(z, txs[i], r_R)
        jacs[i] = jac
        a += jac.T @ jac
    ainv = inv3(a)
    for i in range(n):
        jz = ainv @ jacs[i].T  # J_z,q^i of eq (21)
        rr += jz @ qcs[i] @ jz.T
    _sym(rr)
    return z, rr, residual, True


@njit(cache=True)
def _update(
    x: np.ndarray, p: np.ndarray, innov: np.ndarray, jac: np.ndarray, r: np.ndarray, gate: float
) -> bool:
    """Pose EKF update in place (Joseph form, heading wrapped); False, with nothing
    changed, when the squared Mahalanobis distance exceeds ``gate`` (> 0)."""
    s = jac @ p @ jac.T + r
    si = inv3(s)
    if gate > 0.0:
        m2 = innov @ si @ innov
        if not m2 <= gate:
            return False
    k = p @ jac.T @ si
    ik = np.eye(3) - k @ jac
    pn = ik @ p @ ik.T + k @ r @ k.T
    _sym(pn)
    x += k @ innov
    x[2] = wrap_angle(x[2])
    p[:, :] = pn
    return True


@njit(cache=True)
def correct_ranges(
    x: np.ndarray,
    p: np.ndarray,
    tx: np.ndarray,
    d: np.ndarray,
    var_d: float,
    r_R: float,
    gate: float,
) -> bool:
    """Tightly coupled correction: the three distances of one Tx as observations of the
    pose through eq (28), Joseph form; NaN receivers skipped. False if gated."""
    qp, jac = distance_jacobian(x, tx, r_R)
    r = np.zeros((3, 3))
    innov = np.zeros(3)
    for ell in range(3):
        if math.isfinite(d[ell]):
            r[ell, ell] = var_d
            innov[ell] = d[ell] - qp[ell]
        else:
            r[ell, ell] = _MISSING_VAR
            for c in range(3):
                jac[ell, c] = 0.0
    return _update(x, p, innov, jac, r, gate)


@njit(cache=True)
def correct_pose(x: np.ndarray, p: np.ndarray, z: np.ndarray, rr: np.ndarray, gate: float) -> bool:
    """EKF correction with ``h(x) = x``: eqs (17)-(20), Joseph form, heading innovation
    wrapped. Returns False (and leaves ``x``, ``p``) when the squared Mahalanobis
    distance exceeds ``gate`` (``gate <= 0``: no gate)."""
    innov = z - x
    innov[2] = wrap_angle(innov[2])
    return _update(x, p, innov, np.eye(3), rr, gate)


@njit(cache=True)
def run_duhl(
    odo_t: np.ndarray,
    odo_vr: np.ndarray,
    odo_vl: np.ndarray,
    dist_t: np.ndarray,
    dist_tx: np.ndarray,
    dist_d: np.ndarray,
    tx_xyz: np.ndarray,
    start: int,
    x0: np.ndarray,
    p0: np.ndarray,
    b_w: float,
    k_v: float,
    r_R: float,
    sigma_d: float,
    discard_var: float,
    d_th: float,
    tight: bool,
    max_residual: float,
    gate: float,
) -> tuple:
    """DUHL over a whole log (Kim & Kim 2013 Fig. 3).

    ``dist_tx`` are row indices into ``tx_xyz``. The filter starts at odometry row
    ``start`` with pose ``x0`` and covariance ``p0``; distance rows at times
    ``<= odo_t[start]`` before it are ignored, except those at exactly the start time.
    Distance rows are processed after the odometry rows with the same or an earlier
    time stamp.

    Returns ``(poses (n,3), covs (n,3,3), status (n,), obs_pose (m,3), obs_cov (m,3,3),
    obs_ntx (m,), obs_status (m,))``; rows before ``start`` are NaN.
    """
    n = odo_t.shape[0]
    m = dist_t.shape[0]
    ntx = tx_xyz.shape[0]
    poses = np.full((n, 3), np.nan)
    covs = np.full((n, 3, 3), np.nan)
    status = np.zeros(n, dtype=np.int64)
    obs_pose = np.full((m, 3), np.nan)
    obs_cov = np.full((m, 3, 3), np.nan)
    obs_ntx = np.zeros(m, dtype=np.int64)
    obs_status = np.full(m, OBS_BEFORE_START, dtype=np.int64)

    x = x0.copy()
    p = p0.copy()
    active = np.zeros(ntx, dtype=np.bool_)
    q = np.zeros((ntx, 3))
    qc = np.zeros((ntx, 3, 3))
    var_d = sigma_d * sigma_d
    t_start = odo_t[start]
    ws = np.empty(9)
    j = 0
    while j < m and dist_t[j] < t_start:
        j += 1
    for k in range(start, n):
        if k > start:
            dt = odo_t[k] - odo_t[k - 1]
            vr, vl = odo_vr[k], odo_vl[k]
            if not (math.isfinite(vr) and math.isfinite(vl)):
                status[k] |= ST_NO_ODOMETRY
            elif dt > 0.0:
                for i in range(ntx):
                    if active[i] and not tight:
                        predict_distances(x, q[i], qc[i], tx_xyz[i], vr, vl, dt, b_w, k_v, r_R, ws)
                predict_pose(x, p, vr, vl, dt, b_w, k_v)
        while j < m and dist_t[j] <= odo_t[k]:
            i = dist_tx[j]
            d = dist_d[j]
            has = False
            for ell in range(3):
                if math.isfinite(d[ell]):
                    has = True
            if not has:
                obs_status[j] = OBS_EMPTY
                j += 1
                continue
            if tight:
                obs_ntx[j] = 1
                used = correct_ranges(x, p, tx_xyz[i], d, var_d, r_R, gate)
                obs_status[j] = OBS_USED if used else OBS_GATED
                status[k] |= ST_OBSERVED if used else ST_REJECTED
                j += 1
                continue
            if not active[i]:  # eqs (28)-(30)
                qi, qci = init_distances(x, p, tx_xyz[i], r_R)
                q[i] = qi
                qc[i] = qci
                active[i] = True
            if correct_distances(q[i], qc[i], d, var_d, gate) < 0:  # eqs (25)-(27)
                obs_status[j] = OBS_GATED
                status[k] |= ST_REJECTED
                j += 1
                continue
            cnt = 0
            for a in range(ntx):  # discard, eqs (31)-(32)
                if active[a]:
                    eps = max(qc[a, 0, 0], qc[a, 1, 1], qc[a, 2, 2])
                    if not eps <= discard_var:
                        active[a] = False
                    else:
                        cnt += 1
            obs_ntx[j] = cnt
            if cnt < 2:
                obs_status[j] = OBS_TOO_FEW
                status[k] |= ST_TOO_FEW
                j += 1
                continue
            txs = np.empty((cnt, 3))
            qs = np.empty((cnt, 3))
            qcs = np.empty((cnt, 3, 3))
            c = 0
            for a in range(ntx):
                if active[a]:
                    txs[c] = tx_xyz[a]
                    qs[c] = q[a]
                    qcs[c] = qc[a]
                    c += 1
            z, rr, resid, ok = observation(txs, qs, qcs, r_R, d_th)
            if not ok:
                obs_status[j] = OBS_DEGENERATE
                status[k] |= ST_REJECTED
            elif not resid <= max_residual:
                obs_status[j] = OBS_RESIDUAL
                status[k] |= ST_REJECTED
            else:
                obs_pose[j] = z
                obs_cov[j] = rr
                used = correct_pose(x, p, z, rr, gate)
                obs_status[j] = OBS_USED if used else OBS_GATED
                status[k] |= ST_OBSERVED if used else ST_REJECTED
            j += 1
        poses[k] = x
        covs[k] = p
    return poses, covs, status, obs_pose, obs_cov, obs_ntx, obs_status
