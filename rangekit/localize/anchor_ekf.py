"""Range EKF against fixed anchors: a rig's tags ranged one anchor at a time, with odometry.

The tracked body carries one or more tags (receivers) at lever arms ``l_j`` in its frame;
fixed anchors ``a_i`` (a :class:`~rangekit.rig.Rig`) range them, one anchor at a time
(sequential single ranges) or one anchor to several tags at once (a simultaneous set, a
DUHL distance row). The state is the pose and one range bias per anchor,

    x = [x, y, φ, b_1 … b_A]              (differential drive)
    x = [x, y, v_x, v_y, b_1 … b_A]       (no odometry: constant velocity)

- **Prediction** (differential drive): Kim & Kim 2013 eq (14) with ΔD = Δt (v_R + v_L)/2,
  Δφ = Δt (v_R − v_L)/B_w, its Jacobians and wheel-velocity noise U = diag(k_v |v_R|/Δt,
  k_v |v_L|/Δt) of eq (16), plus a small slip noise (``slip_psd``). A range between two
  odometry rows splits the interval (same velocities, shorter Δt). Without odometry:
  Jiang 2018 eqs (2)–(3) (continuous white acceleration). Biases: a random walk
  (``bias_psd``), prior mean and 1-sigma from the rig.
- **Range** from anchor i to tag j: ``h = sqrt(|p + R(φ) l_j − a_i|² + (l_z − a_z)²) + b_i``
  (Kim & Kim 2013 eq (3) with a bias), one scalar EKF update per range (Joseph form).
- **Robust update**: the normalised innovation ``ν = y / sqrt(S)`` gives a weight ``w``
  and the range is applied with ``R / w``: Huber (``w = min(1, k/|ν|)``, k = 1.5; Huber
  1964, the Huber-Kalman filter of Karlgaard & Schaub 2007) or Student-t (``w = (n + 1) /
  (n + ν²)``, n = 4; Roth et al. 2013). No range is thrown away; every range with w < 1 is
  reported (:class:`DownWeighted`). The weighted updates report more information than
  the M-estimate has when the ranges have heavier tails: the final bias 1-sigmas are
  widened by the Huber sandwich factor ``E[w] E[ψ²] / E[ψ′]²`` (ψ = wν; Huber 1964) of the
  reported hypothesis's innovations (at least 1; :attr:`AnchorTrack.bias_scale`).
- **Start without a pose**: the first ranges up to ``init_window_s`` (at least three
  anchors, or two, then both circle intersections) are multilaterated by Gauss-Newton
  (the rig's bias means removed); the heading is unknown, so a bank of ``n_heading``
  hypotheses (spacing 2π/n, 1-sigma half a spacing) starts there. Each hypothesis is an
  EKF; hypotheses whose cumulative (robust) log-likelihood falls ``prune_nats`` below the
  best are dropped; the output at every range is the best hypothesis so far.
- **Smoother**: RTS (:func:`rangekit.localize.ekf.rts_smooth`, Joseph form) along the
  best final hypothesis, with the product of the odometry Jacobians between ranges as
  the transition.

Examples
--------
>>> import numpy as np
>>> from rangekit.sim.rigs import simulate_rig_run, square_rig
>>> run = simulate_rig_run(square_rig(), duration_s=20.0, rng=1)
>>> trk = track_anchors(run.log, run.rig)
>>> err = np.hypot(*(trk.xy_m - run.truth_xy(trk.t_s)).T)
>>> bool(np.sqrt(np.mean(err[-50:] ** 2)) < 0.15)
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rangekit._validate import positive, positive_int
from rangekit.errors import IncompatibleInputError, InvalidParameterError, LogFormatError
from rangekit.io.duhllog import DUHLLog
from rangekit.localize.ekf import rts_smooth
from rangekit.rig import Rig

__all__ = [
    "TRACK_COLUMNS",
    "AnchorTrack",
    "DownWeighted",
    "multilaterate",
    "multilaterate_latest",
    "odometry_step",
    "range_model",
    "track_anchors",
    "track_report",
    "track_rows",
]

ROBUST = ("huber", "student-t", "none")

#: Columns of the track written by :func:`track_rows`.
TRACK_COLUMNS = (
    "t_s", "x_m", "y_m", "heading_rad", "var_x_m2", "var_y_m2", "cov_xy_m2",
    "var_heading_rad2", "n_hypotheses",
)  # fmt: skip


# --------------------------------------------------------------------------- multilateration
def multilaterate(
    anchors_xyz: np.ndarray, ranges_m: np.ndarray, *, z_m: float = 0.0, x0=None, iters: int = 10
) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares 2-D position from ranges to known anchors (Gauss-Newton).

    Parameters
    ----------
    anchors_xyz : array_like, shape (m, 3)
    ranges_m : array_like, shape (m,)
    z_m : float
        Height of the ranged point.
    x0 : array_like, shape (2,), optional
        Start (default: the anchors' centroid, nudged off it).

    Returns
    -------
    xy : ndarray (2,)
    JtJ : ndarray (2, 2)
        Gauss-Newton information (unit range variance) at the solution.
    rms : float
        RMS range residual (m).

    Notes
    -----
    Minimises ``Σ (|p − a_i| − r_i)²`` with the 3-D distance (Kim & Kim 2013 §II-B's
    indirect method, solved iteratively instead of by differencing).

    Examples
    --------
    >>> a = np.array([[0.0, 0, 0], [2.4, 0, 0], [2.4, 2.4, 0], [0, 2.4, 0]])
    >>> r = np.hypot(*(a[:, :2] - [0.7, 1.5]).T)
    >>> multilaterate(a, r)[0].round(6).tolist()
    [0.7, 1.5]
    """
    A = np.asarray(anchors_xyz, dtype=np.float64)
    r = np.asarray(ranges_m, dtype=np.float64)
    p = A[:, :2].mean(axis=0) + 1e-3 if x0 is None else np.array(x0, dtype=np.float64)
    dz2 = (z_m - A[:, 2]) ** 2
    J = np.zeros((r.size, 2))
    for _ in range(iters):
        d = p - A[:, :2]
        rho = np.sqrt(np.sum(d * d, axis=1) + dz2)
        rho = np.maximum(rho, 1e-9)
        J = d / rho[:, None]
        res = r - rho
        JtJ = J.T @ J + 1e-9 * np.eye(2)
        step = np.linalg.solve(JtJ, J.T @ res)
        p = p + step
        if np.hypot(*step) < 1e-10:
            break
    d = p - A[:, :2]
    rho = np.sqrt(np.sum(d * d, axis=1) + dz2)
    return p, J.T @ J, float(np.sqrt(np.mean((r - rho) ** 2)))


def multilaterate_latest(log: DUHLLog, rig: Rig, *, tag: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The plain baseline: at every distance row, least squares on the latest range of each
    anchor to ``tag`` (raw ranges: no bias, no motion model, no outlier handling).

    Returns ``(t_s (n,), xy_m (n, 2))`` from the first row at which three anchors have
    been heard (NaN before).
    """
    d = log.distances
    latest = np.full(rig.n_anchors, np.nan)
    out = np.full((d.t_s.size, 2), np.nan)
    xy = None
    z = rig.tag_lever_m[tag, 2]
    for k in range(d.t_s.size):
        i = rig.anchor_index(int(d.tx[k]))
        if np.isfinite(d.d_m[k, tag]):
            latest[i] = d.d_m[k, tag]
        ok = np.isfinite(latest)
        if ok.sum() >= 3:
            xy, _, _ = multilaterate(rig.anchor_xyz_m[ok], latest[ok], z_m=z, x0=xy)
            out[k] = xy
    return d.t_s.copy(), out


# --------------------------------------------------------------------------- results
@dataclass(frozen=True)
class DownWeighted:
    """A range the robust update applied with weight < 1 (its noise variance ``σ² / w``)."""

    t_s: float
    anchor: int
    tag: int
    range_m: float
    residual_m: float
    nu: float
    weight: float


@dataclass(frozen=True)
class AnchorTrack:
    """The output of :func:`track_anchors` (one row per distance row used).

    Attributes
    ----------
    t_s : ndarray (n,)
    x, P : ndarray (n, d), (n, d, d)
        Filtered state and covariance of the best hypothesis at each row (causal).
    x_smooth, P_smooth : ndarray or None
        RTS-smoothed along the best final hypothesis (``smooth=True``).
    x_line, P_line : ndarray or None
        Filtered state of that final hypothesis (``P_smooth <= P_line``).
    n_hypotheses : ndarray of int (n,)
        Hypotheses alive at each row.
    anchor_ids : ndarray of int (A,)
    bias_m, bias_sigma_m : ndarray (A,)
        Final bias estimates and 1-sigmas (smoothed when smoothed). The 1-sigmas include
        ``sqrt(bias_scale)``.
    downweighted : list of DownWeighted
        Ranges applied with weight < 1 by the reported hypothesis.
    start : str
        ``"given"`` (initial pose) or ``"multilateration"``.
    start_t_s : float
    heading : bool
        True: state ``[x, y, φ, b…]``; False: ``[x, y, vx, vy, b…]``.
    bias_scale : float
        Variance factor (≥ 1) applied to ``bias_sigma_m``: the sandwich ``E[w] E[ψ²] /
        E[ψ′]²`` of the reported hypothesis's normalised innovations ν (ψ = wν), the
        M-estimator's asymptotic variance (Huber 1964) over the information the weighted
        updates report. About 1.04 under 5 % outliers, 1.55 under 15 % (docs/rigs.md);
        ``P`` and ``P_smooth`` do not include it.
    """

    t_s: np.ndarray
    x: np.ndarray
    P: np.ndarray
    x_smooth: np.ndarray | None
    P_smooth: np.ndarray | None
    x_line: np.ndarray | None
    P_line: np.ndarray | None
    n_hypotheses: np.ndarray
    anchor_ids: np.ndarray
    bias_m: np.ndarray
    bias_sigma_m: np.ndarray
    downweighted: list[DownWeighted]
    start: str
    start_t_s: float
    heading: bool
    bias_scale: float = 1.0

    def _pick(self, smoothed: bool):
        if smoothed:
            if self.x_smooth is None:
                raise InvalidParameterError("this track was not smoothed (use smooth=True)")
            return self.x_smooth, self.P_smooth
        return self.x, self.P

    @property
    def xy_m(self) -> np.ndarray:
        """Filtered positions (n, 2)."""
        return self.x[:, :2]

    def position(self, *, smoothed: bool = False) -> np.ndarray:
        return self._pick(smoothed)[0][:, :2]

    def position_cov(self, *, smoothed: bool = False) -> np.ndarray:
        return self._pick(smoothed)[1][:, :2, :2]

    def diagnostics(self) -> dict:
        """What the filter reports besides the track (JSON keys of ``rangekit track
        range-ekf --rig``): each anchor's range bias and 1-sigma, and every range
        applied with weight < 1.

        Examples
        --------
        >>> z = np.zeros((1, 2))
        >>> trk = AnchorTrack(np.zeros(1), z, z[:, :, None], None, None, None, None,
        ...                   np.ones(1, int), np.array([7]), np.array([0.1]),
        ...                   np.array([0.02]), [], "given", 0.0, False)
        >>> trk.diagnostics()
        {'biases': [{'anchor': 7, 'bias_m': 0.1, 'sigma_m': 0.02}], 'downweighted': []}
        """
        return {
            "biases": [
                {"anchor": int(a), "bias_m": float(b), "sigma_m": float(s)}
                for a, b, s in zip(self.anchor_ids, self.bias_m, self.bias_sigma_m, strict=True)
            ],
            "downweighted": [
                {
                    "t_s": d.t_s,
                    "anchor": d.anchor,
                    "tag": d.tag,
                    "range_m": d.range_m,
                    "residual_m": d.residual_m,
                    "nu": d.nu,
                    "weight": d.weight,
                }
                for d in self.downweighted
            ],
        }

    def bias_text(self) -> str:
        """The range biases as one line: ``ANCHOR: +BIAS±SIGMA`` (m, 3 decimals) per anchor."""
        return ", ".join(
            f"{int(a)}: {b:+.3f}±{s:.3f}"
            for a, b, s in zip(self.anchor_ids, self.bias_m, self.bias_sigma_m, strict=True)
        )


# --------------------------------------------------------------------------- the filter
def _robust_weight(nu: np.ndarray, robust: str, k: float, dof: float) -> np.ndarray:
    a = np.abs(nu)
    if robust == "huber":
        return np.where(a <= k, 1.0, k / np.maximum(a, 1e-300))
    if robust == "student-t":
        return (dof + 1.0) / (dof + a * a)
    return np.ones_like(a)


def _robust_slope(nu: np.ndarray, robust: str, k: float, dof: float) -> np.ndarray:
    """ψ′(ν) = d(w ν)/dν of :func:`_robust_weight`."""
    if robust == "huber":
        return (np.abs(nu) <= k).astype(np.float64)
    if robust == "student-t":
        return (dof + 1.0) * (dof - nu * nu) / (dof + nu * nu) ** 2
    return np.ones_like(nu)


def range_model(
    x: np.ndarray,
    a_xyz,
    lever,
    i_b: int | None,
    *,
    heading: bool,
    off: int | None = None,
    phi=None,
) -> tuple[np.ndarray, np.ndarray]:
    """Predicted range and its Jacobian for states ``x`` (H, d).

    ``h = sqrt(|p + R(φ) l_xy − a_xy|² + (l_z − a_z)²) + b_i`` (Kim & Kim 2013 eq (3) with
    the lever arm ``l`` of the tag and the anchor's bias); without a heading state
    (``heading=False``) the lever arm is rotated by a known heading ``phi`` (step events:
    the last step's heading), or not at all. ``off`` is the index of the first bias
    (default 3 with a heading state, else 4).

    Returns ``h`` (H,) and ``H = ∂h/∂x`` (H, d).
    """
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    Hn, d = x.shape
    if heading or phi is not None:
        ang = x[:, 2] if heading else np.broadcast_to(np.asarray(phi, dtype=np.float64), (Hn,))
        c, s = np.cos(ang), np.sin(ang)
        lx = c * lever[0] - s * lever[1]
        ly = s * lever[0] + c * lever[1]
    else:
        lx = ly = np.zeros(Hn)
    dx = x[:, 0] + lx - a_xyz[0]
    dy = x[:, 1] + ly - a_xyz[1]
    dz = lever[2] - a_xyz[2]
    rho = np.maximum(np.sqrt(dx * dx + dy * dy + dz * dz), 1e-9)
    Hm = np.zeros((Hn, d))
    Hm[:, 0] = dx / rho
    Hm[:, 1] = dy / rho
    if heading:
        # ∂(R(φ) l)/∂φ = (−l_y', l_x') with l' the rotated lever arm
        Hm[:, 2] = (dx * -ly + dy * lx) / rho
    if off is None:
        off = 3 if heading else 4
    h = rho
    if i_b is not None:
        Hm[:, off + i_b] = 1.0
        h = rho + x[:, off + i_b]
    return h, Hm


def odometry_step(x: np.ndarray, dt: float, v_right: float, v_left: float, wheel_base: float):
    """Kim & Kim 2013 eq (14) on states ``x`` (H, d) with pose in the first three entries.

    Returns ``(x_new, F, G)``: ``F = ∂x_new/∂x`` (H, d, d) and ``G = ∂x_new/∂(v_R, v_L)``
    (H, d, 2), the Jacobians of eq (16).
    """
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    Hn, d = x.shape
    dD = dt * (v_right + v_left) / 2.0
    dphi = dt * (v_right - v_left) / wheel_base
    ang = x[:, 2] + dphi / 2.0
    c, s = np.cos(ang), np.sin(ang)
    F = np.broadcast_to(np.eye(d), (Hn, d, d)).copy()
    F[:, 0, 2] = -dD * s
    F[:, 1, 2] = dD * c
    Gp = np.zeros((Hn, d, 2))  # ∂/∂(ΔD, Δφ)
    Gp[:, 0, 0], Gp[:, 0, 1] = c, -dD * s / 2.0
    Gp[:, 1, 0], Gp[:, 1, 1] = s, dD * c / 2.0
    Gp[:, 2, 1] = 1.0
    M = np.array([[dt / 2.0, dt / 2.0], [dt / wheel_base, -dt / wheel_base]])
    xn = x.copy()
    xn[:, 0] += dD * c
    xn[:, 1] += dD * s
    xn[:, 2] += dphi
    return xn, F, Gp @ M


class _Bank:
    """H hypotheses of one EKF, vectorised: x (H, d), P (H, d, d)."""

    def __init__(self, x: np.ndarray, P: np.ndarray, heading: bool, n_b: int):
        self.x, self.P = x, P
        self.heading = heading
        self.off = x.shape[1] - n_b
        self.phi = None  # known heading for the lever arms (step events)
        self.n_b = n_b
        self.d = x.shape[1]
        self.ll = np.zeros(x.shape[0])
        self.alive = np.ones(x.shape[0], dtype=bool)
        self.Phi = np.broadcast_to(np.eye(self.d), P.shape).copy()
        self.sand = np.zeros((x.shape[0], 4))  # Σ w, Σ ψ², Σ ψ′, count (sandwich factor)

    def bias_scale(self, h: int) -> float:
        """Sandwich variance factor ``E[w] E[ψ²] / E[ψ′]²`` of hypothesis ``h``, at least 1."""
        sw, spsi2, sdpsi, n = self.sand[h]
        if n < 10 or sdpsi <= 0:
            return 1.0
        return max(1.0, (sw / n) * (spsi2 / n) / (sdpsi / n) ** 2)

    def predict_odo(self, dt, vr, vl, B, k_v, slip_psd, bias_psd):
        x, P = self.x, self.P
        x, F, G = odometry_step(x, dt, vr, vl, B)
        U = np.diag([k_v * abs(vr) / dt, k_v * abs(vl) / dt])
        Q = G @ U @ np.swapaxes(G, 1, 2)
        Q[:, 0, 0] += slip_psd[0] * dt
        Q[:, 1, 1] += slip_psd[0] * dt
        Q[:, 2, 2] += slip_psd[1] * dt
        b = np.arange(3, self.d)
        Q[:, b, b] += bias_psd * dt
        self.x = x
        self.P = _sym(F @ P @ np.swapaxes(F, 1, 2) + Q)
        self.Phi = F @ self.Phi

    def predict_walk(self, dt, slip_psd, bias_psd):
        """Between step events: a random walk of the position (sway, slip)."""
        if dt <= 0:
            return
        Q = np.zeros((self.d, self.d))
        Q[0, 0] = Q[1, 1] = slip_psd * dt
        b = np.arange(self.off, self.d)
        Q[b, b] = bias_psd * dt
        self.P = _sym(self.P + Q)

    def predict_step(self, length, heading, sigma_l, sigma_h):
        """A step event: ``p += L (cos h, sin h)`` with noise from L and h (Girard 2011
        §3.2 step 2; the step's world heading from the foot IMU)."""
        c, s = math.cos(heading), math.sin(heading)
        J = np.array([[c, -length * s], [s, length * c]])
        Q = np.zeros((self.d, self.d))
        Q[:2, :2] = J @ np.diag([sigma_l**2, sigma_h**2]) @ J.T
        x = self.x.copy()
        x[:, 0] += length * c
        x[:, 1] += length * s
        self.x = x
        self.P = _sym(self.P + Q)
        self.phi = heading

    def predict_cv(self, dt, q, bias_psd):
        if dt <= 0:
            return
        F = np.eye(self.d)
        F[0, 2] = F[1, 3] = dt
        Q = np.zeros((self.d, self.d))
        for i in (0, 1):
            Q[i, i] = q * dt**3 / 3
            Q[i, i + 2] = Q[i + 2, i] = q * dt**2 / 2
            Q[i + 2, i + 2] = q * dt
        b = np.arange(4, self.d)
        Q[b, b] = bias_psd * dt
        self.x = self.x @ F.T
        self.P = _sym(F @ self.P @ F.T + Q)
        self.Phi = F @ self.Phi

    def update_range(self, a_xyz, lever, r, var, i_b, robust, k, dof):
        """Scalar robust update of every hypothesis; returns (y, nu, w) per hypothesis."""
        x, P = self.x, self.P
        h, Hm = range_model(x, a_xyz, lever, i_b, heading=self.heading, off=self.off, phi=self.phi)
        y = r - h
        PH = np.einsum("hij,hj->hi", P, Hm)
        S0 = np.einsum("hi,hi->h", Hm, PH) + var
        nu = y / np.sqrt(S0)
        w = _robust_weight(nu, robust, k, dof)
        self.sand += np.column_stack(
            [w, (w * nu) ** 2, _robust_slope(nu, robust, k, dof), np.ones_like(w)]
        )
        Rw = var / w
        S = S0 - var + Rw
        K = PH / S[:, None]
        self.x = x + K * y[:, None]
        A = np.broadcast_to(np.eye(self.d), P.shape) - K[:, :, None] * Hm[:, None, :]
        self.P = _sym(
            A @ P @ np.swapaxes(A, 1, 2) + Rw[:, None, None] * K[:, :, None] * K[:, None, :]
        )
        self.ll += -0.5 * (y * y / S + np.log(2 * np.pi * S))
        return y, nu, w

    def keep(self, idx: np.ndarray) -> None:
        self.x, self.P, self.ll, self.Phi = self.x[idx], self.P[idx], self.ll[idx], self.Phi[idx]
        self.sand = self.sand[idx]


def _survivors(bank: _Bank, prune_nats: float) -> np.ndarray:
    """Hypotheses to keep: within ``prune_nats`` of the best log-likelihood, and not a
    duplicate (within 5 cm and 3° of a better one: converged to the same pose)."""
    order = np.argsort(-bank.ll)
    best = bank.ll[order[0]]
    kept: list[int] = []
    for h in order:
        if bank.ll[h] < best - prune_nats:
            break
        dup = False
        for g in kept:
            dxy = np.hypot(*(bank.x[h, :2] - bank.x[g, :2]))
            dh = (
                abs((bank.x[h, 2] - bank.x[g, 2] + np.pi) % (2 * np.pi) - np.pi)
                if bank.heading
                else 0.0
            )
            if dxy < 0.05 and dh < math.radians(3.0):
                dup = True
                break
        if not dup:
            kept.append(int(h))
    return np.sort(np.array(kept, dtype=np.int64))


def _bias_prior(rig: Rig) -> np.ndarray:
    """Prior covariance of the bias deviations: a part common to every anchor (σ_c² 1 1ᵀ,
    the rig's ``common_bias_sigma_m``: speed of sound, antenna or processing delay) plus
    each anchor's own (σ_i², ``bias_sigma_m``)."""
    own = np.maximum(rig.anchor_bias_sigma_m, 1e-6) ** 2
    c = rig.common_bias_sigma_m**2 if np.any(rig.anchor_bias_sigma_m > 0) else 0.0
    return np.diag(own) + c * np.ones((own.size, own.size))


def _sym(P: np.ndarray) -> np.ndarray:
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def _initial_bank(rig, log, heading, t_start_idx, init_window_s, n_heading, sigma_v0, name):
    """Multilaterate the first ranges; returns (x0 (H, d), P0 (H, d, d), k_next, t0)."""
    d = log.distances
    A, n_b = rig.n_anchors, rig.n_anchors
    seen: dict[int, list[float]] = {}
    t_first = None
    k_end = None
    for k in range(t_start_idx, d.t_s.size):
        i = rig.anchor_index(int(d.tx[k]))
        for j in range(rig.n_tags):
            if np.isfinite(d.d_m[k, j]):
                rr = d.d_m[k, j] - rig.anchor_bias_m[i]
                seen.setdefault(i, []).append(rr)
                t_first = d.t_s[k] if t_first is None else t_first
        if t_first is not None and (len(seen) >= 3 and d.t_s[k] - t_first >= 0.0):
            k_end = k
            if len(seen) >= min(A, 4) or d.t_s[k] - t_first >= init_window_s:
                break
        if t_first is not None and d.t_s[k] - t_first > init_window_s and len(seen) >= 2:
            k_end = k
            break
    if k_end is None or len(seen) < 2:
        raise LogFormatError(
            f"{name}: no start pose: the first ranges never reach two distinct anchors "
            "(give the initial pose)"
        )
    ids = sorted(seen)
    anchors = rig.anchor_xyz_m[ids]
    r = np.array([np.median(seen[i]) for i in ids])
    lever = float(np.max(np.hypot(rig.tag_lever_m[:, 0], rig.tag_lever_m[:, 1])))
    z = float(np.mean(rig.tag_lever_m[:, 2]))
    starts = []
    if len(ids) >= 3:
        xy, JtJ, rms = multilaterate(anchors, r, z_m=z)
        sig = max(float(np.mean(rig.anchor_sigma_m[ids])), rms)
        var_r = sig**2 + lever**2 + float(np.mean(rig.anchor_bias_sigma_m[ids] ** 2))
        var_r += rig.common_bias_sigma_m**2
        Pxy = var_r * np.linalg.inv(JtJ + 1e-6 * np.eye(2))
        starts.append((xy, Pxy))
    else:  # two anchors: both intersections of the circles
        (a1, a2), (r1, r2) = anchors[:, :2], r
        dvec = a2 - a1
        L = float(np.hypot(*dvec))
        along = (L * L + r1 * r1 - r2 * r2) / (2 * L)
        h2 = max(r1 * r1 - along * along, 0.0)
        u = dvec / L
        v = np.array([-u[1], u[0]])
        var_r = float(np.mean(rig.anchor_sigma_m[ids] ** 2)) + lever**2 + 0.04
        for sgn in (1.0, -1.0):
            p = a1 + along * u + sgn * math.sqrt(h2) * v
            starts.append((p, np.diag([var_r + 0.25, var_r + 0.25])))
    motion_var = 0.05  # the body moved during the window (0.2 m 1-sigma)
    off = {"differential-drive": 3, "none": 4, "steps": 2}[rig.odometry.kind]
    dim = off + n_b
    xs, Ps = [], []
    nh = n_heading if heading else 1
    for xy, Pxy in starts:
        for h in range(nh):
            x0 = np.zeros(dim)
            P0 = np.zeros((dim, dim))
            x0[:2] = xy
            P0[:2, :2] = Pxy + motion_var * np.eye(2)
            if heading:
                x0[2] = -math.pi + 2 * math.pi * (h + 0.5) / nh
                P0[2, 2] = (math.pi / nh) ** 2
            elif off == 4:
                P0[2, 2] = P0[3, 3] = sigma_v0**2
            x0[off:] = 0.0
            P0[off:, off:] = _bias_prior(rig)
            xs.append(x0)
            Ps.append(P0)
    return np.array(xs), np.array(Ps), k_end + 1, float(d.t_s[k_end])


def track_anchors(
    log: DUHLLog,
    rig: Rig,
    *,
    initial_pose=None,
    initial_sigma=(0.05, 0.05, 0.035),
    robust: str = "huber",
    huber_k: float = 1.5,
    student_dof: float = 4.0,
    estimate_bias: bool = True,
    bias_psd: float = 1e-7,
    slip_psd=(1e-4, 1e-4),
    n_heading: int = 12,
    prune_nats: float = 12.0,
    init_window_s: float = 1.5,
    sigma_v0: float = 1.0,
    smooth: bool = False,
    steps=None,
    name: str = "log",
) -> AnchorTrack:
    """Track a rig's body from ranges to fixed anchors (and odometry) with a robust EKF.

    Parameters
    ----------
    log : DUHLLog
        Odometry rows (differential drive; none for ``odometry.type = "none"``) and
        distance rows: anchor id in ``tx``, the ranges to tags 1..3 in ``d1_m..d3_m``
        (empty: not heard), one anchor per row (``docs/rigs.md``).
    rig : Rig
    initial_pose : (x, y, heading_rad) or (x, y), optional
        The pose at the first row; default: start from the first ranges (module docstring).
    initial_sigma : (σ_x, σ_y, σ_φ)
        1-sigmas of a given initial pose (default 5 cm, 5 cm, 2°).
    robust : {"huber", "student-t", "none"}
    huber_k, student_dof : float
        The Huber threshold (in normalised innovations) and the Student-t degrees of freedom.
    estimate_bias : bool
        Estimate each anchor's range bias (prior: the rig's ``bias_m`` ± ``bias_sigma_m``).
        False: biases fixed at the rig's values.
    bias_psd : float
        Random-walk spectral density of the biases (m²/s).
    slip_psd : (float, float)
        Extra pose noise, (m²/s, rad²/s), for wheel slip and odometry scale errors.
    n_heading : int
        Heading hypotheses when starting without a pose.
    prune_nats : float
        Drop hypotheses this far below the best cumulative log-likelihood.
    init_window_s : float
        Longest stretch of first ranges multilaterated for the start.
    smooth : bool
        Also RTS-smooth along the best final hypothesis.
    steps : StepLog, optional
        Step events (:func:`rangekit.io.steplog.read_step_log`) for a rig with
        ``odometry.type = "steps"``: each moves the body by its length along its world
        heading (Girard 2011 §3.2), the lever arms turn with the last step's heading.
    name : str
        The log's name in error messages.

    Returns
    -------
    AnchorTrack

    Raises
    ------
    InvalidParameterError
        Bad parameters.
    IncompatibleInputError
        A distance row naming an anchor the rig lacks, a range in a tag column the rig
        has no tag for, a rig whose odometry this filter does not read (steps).
    LogFormatError
        No usable range, odometry rows for a rig without odometry or too few for a
        differential drive, no start pose.

    Notes
    -----
    Kim & Kim 2013 eqs (3), (14), (16) for the range and the odometry; Jiang 2018 eqs
    (2)–(3) without odometry; Huber (1964) / Karlgaard & Schaub (2007) or Student-t
    weights (Roth, Özkan & Gustafsson 2013) on the normalised innovation; Joseph-form
    updates; RTS smoothing (Rauch, Tung & Striebel 1965).
    """
    if robust not in ROBUST:
        raise InvalidParameterError(f"robust={robust!r} must be one of {ROBUST}")
    huber_k = positive("huber_k", huber_k)
    student_dof = positive("student_dof", student_dof)
    n_heading = positive_int("n_heading", n_heading)
    prune_nats = positive("prune_nats", prune_nats)
    kind = rig.odometry.kind
    if kind == "steps" and steps is None:
        raise IncompatibleInputError(
            f"{name}: the rig's odometry is step events (odometry.type 'steps'): give the step log"
        )
    if kind != "steps" and steps is not None:
        raise IncompatibleInputError(
            f"{name}: a step log was given but the rig's odometry is {kind!r}, not 'steps'"
        )
    rig.require_anchors("the anchor EKF (track range-ekf --rig)")
    heading = kind == "differential-drive"
    odo, dist = log.odometry, log.distances
    for k in range(dist.t_s.size):
        if int(dist.tx[k]) not in set(rig.anchor_ids.tolist()):
            raise IncompatibleInputError(
                f"{name}: the distance row at t_s={dist.t_s[k]:g} names anchor {int(dist.tx[k])}, "
                f"which is not in the rig (ids: {rig.anchor_ids.tolist()})"
            )
        heard = np.flatnonzero(np.isfinite(dist.d_m[k]))
        if heard.size and heard.max() >= rig.n_tags:
            raise IncompatibleInputError(
                f"{name}: the distance row at t_s={dist.t_s[k]:g} has a range in "
                f"d{heard.max() + 1}_m but the rig has {rig.n_tags} tag(s)"
            )
    if not np.any(np.isfinite(dist.d_m)):
        raise LogFormatError(f"{name}: no usable range (every distance cell is empty)")
    if heading and odo.t_s.size < 2:
        raise LogFormatError(
            f"{name}: the rig has differential-drive odometry but the log has "
            f"{odo.t_s.size} odometry row(s) (at least 2 needed)"
        )
    if not heading and odo.t_s.size:
        raise LogFormatError(f"{name}: odometry rows in the log but the rig's odometry is {kind!r}")
    n_b = rig.n_anchors
    bias_prior = rig.anchor_bias_m.copy()
    if not estimate_bias:
        rig = Rig(rig.anchor_ids, rig.anchor_xyz_m, rig.anchor_bias_m, rig.anchor_sigma_m,
                  np.zeros(n_b), rig.tag_ids, rig.tag_lever_m, rig.odometry, rig.name)  # fmt: skip
    # ---- start
    if heading:
        k0 = int(np.searchsorted(dist.t_s, odo.t_s[0], side="left"))
    else:
        k0 = 0
    off = {"differential-drive": 3, "none": 4, "steps": 2}[kind]
    dim = off + n_b
    if initial_pose is not None:
        p0 = np.asarray(initial_pose, dtype=np.float64)
        if p0.shape != ((3,) if heading else (2,)) or not np.all(np.isfinite(p0)):
            raise InvalidParameterError(
                f"initial_pose={initial_pose!r} must be "
                + ("(x, y, heading_rad)" if heading else "(x, y)")
            )
        x0 = np.zeros((1, dim))
        P0 = np.zeros((1, dim, dim))
        x0[0, :2] = p0[:2]
        sig = np.asarray(initial_sigma, dtype=np.float64)
        P0[0, 0, 0], P0[0, 1, 1] = sig[0] ** 2, sig[1] ** 2
        if heading:
            x0[0, 2] = p0[2]
            P0[0, 2, 2] = sig[2] ** 2
        elif off == 4:
            P0[0, 2, 2] = P0[0, 3, 3] = sigma_v0**2
        P0[0, off:, off:] = _bias_prior(rig)
        k_next = k0
        t0 = float(odo.t_s[0]) if heading else float(dist.t_s[0])
        if steps is not None and steps.t_s.size:
            t0 = min(t0, float(steps.t_s[0])) - 1e-6  # the pose before the first step
        start = "given"
    else:
        x0, P0, k_next, t0 = _initial_bank(
            rig, log, heading, k0, init_window_s, n_heading, sigma_v0, name
        )
        start = "multilateration"
    bank = _Bank(x0, P0, heading, n_b)
    bank.x[:, off:] = 0.0  # biases are carried as deviations from the rig's means
    H0 = x0.shape[0]
    hid = np.arange(H0)  # global ids of the live hypotheses
    B = rig.odometry.wheel_base_m
    k_v = rig.odometry.k_v_m
    slip = np.asarray(slip_psd, dtype=np.float64)
    q_cv = rig.odometry.accel_psd
    si = 0  # next step event
    if steps is not None:
        si = int(np.searchsorted(steps.t_s, t0, side="right"))
        h_sig = np.where(np.isnan(steps.heading_sigma_rad), rig.odometry.heading_sigma_rad,
                         steps.heading_sigma_rad)  # fmt: skip
        if si > 0:
            bank.phi = float(steps.heading_rad[si - 1])
        # when each step's displacement starts: the previous step (the first: one step
        # period before it)
        step_start = np.empty(steps.t_s.size)
        if steps.t_s.size:
            step_start[1:] = steps.t_s[:-1]
            first = float(np.median(np.diff(steps.t_s))) if steps.t_s.size > 1 else 0.5
            step_start[0] = steps.t_s[0] - first
        si = int(np.searchsorted(steps.t_s, t0, side="left"))
    # odometry cursor: interval j is (odo.t_s[j-1], odo.t_s[j]] with velocities of row j
    t_now = t0
    j = int(np.searchsorted(odo.t_s, t0, side="right")) if heading else 0

    def advance(t_target: float) -> None:
        nonlocal t_now, j, si
        if steps is not None:
            # step si is the displacement over (t_{si-1}, t_si]: a range inside that
            # interval sees the walker part of the way (like a split odometry interval)
            while t_now < t_target - 1e-12:
                if si >= steps.t_s.size:
                    bank.predict_walk(t_target - t_now, slip[0], bias_psd)
                    t_now = t_target
                    return
                t_a = step_start[si]
                t_b = float(steps.t_s[si])
                t_end = min(t_b, t_target)
                f = (t_end - max(t_now, t_a)) / max(t_b - t_a, 1e-9)
                bank.predict_walk(t_end - t_now, slip[0], bias_psd)
                if f > 0:
                    bank.predict_step(f * float(steps.length_m[si]), float(steps.heading_rad[si]),
                                      math.sqrt(f) * rig.odometry.length_sigma_m,
                                      float(h_sig[si]))  # fmt: skip
                t_now = t_end
                if t_end >= t_b:
                    si += 1
            return
        if not heading:
            bank.predict_cv(t_target - t_now, q_cv, bias_psd)
            t_now = t_target
            return
        while t_now < t_target - 1e-12:
            if j >= odo.t_s.size:  # past the last odometry row: hold still, slip noise only
                bank.predict_odo(t_target - t_now, 0.0, 0.0, B, k_v, slip, bias_psd)
                t_now = t_target
                return
            t_end = min(float(odo.t_s[j]), t_target)
            dt = t_end - t_now
            if dt > 0:
                bank.predict_odo(dt, float(odo.v_right_mps[j]), float(odo.v_left_mps[j]), B,
                                 k_v, slip, bias_psd)  # fmt: skip
            t_now = t_end
            if t_end >= float(odo.t_s[j]):
                j += 1

    n_rows = dist.t_s.size - k_next
    xs = np.empty((n_rows, dim))
    Ps = np.empty((n_rows, dim, dim))
    nh = np.empty(n_rows, dtype=np.int64)
    hist_x = np.full((n_rows, H0, dim), np.nan)
    hist_P = np.full((n_rows, H0, dim, dim), np.nan)
    hist_xp = np.full((n_rows, H0, dim), np.nan)
    hist_Pp = np.full((n_rows, H0, dim, dim), np.nan)
    hist_F = np.full((n_rows, H0, dim, dim), np.nan)
    weights: list[list] = []
    best_hist = np.empty(n_rows, dtype=np.int64)
    for n, k in enumerate(range(k_next, dist.t_s.size)):
        bank.Phi = np.broadcast_to(np.eye(dim), bank.P.shape).copy()
        advance(float(dist.t_s[k]))
        hist_xp[n, hid], hist_Pp[n, hid], hist_F[n, hid] = bank.x, bank.P, bank.Phi
        i = rig.anchor_index(int(dist.tx[k]))
        row_w = []
        for tg in range(rig.n_tags):
            r = dist.d_m[k, tg]
            if not np.isfinite(r):
                continue
            y, nu, w = bank.update_range(
                rig.anchor_xyz_m[i], rig.tag_lever_m[tg], r - bias_prior[i],
                rig.anchor_sigma_m[i] ** 2, i, robust, huber_k, student_dof,
            )  # fmt: skip
            row_w.append((tg, r, y, nu, w))
        hist_x[n, hid], hist_P[n, hid] = bank.x, bank.P
        b = int(np.argmax(bank.ll))
        best_hist[n] = hid[b]
        xs[n], Ps[n] = bank.x[b], bank.P[b]
        weights.append(
            [(dist.t_s[k], int(dist.tx[k]), tg, r, y[b], nu[b], w[b]) for tg, r, y, nu, w in row_w]
        )
        keep = _survivors(bank, prune_nats)
        if keep.size < bank.ll.size:
            bank.keep(keep)
            hid = hid[keep]
        nh[n] = hid.size
    xs[:, off:] += bias_prior
    down = [
        DownWeighted(float(t), int(a), int(rig.tag_ids[tg]), float(r), float(y), float(nu),
                     float(w))
        for row in weights for (t, a, tg, r, y, nu, w) in row if w < 1.0
    ]  # fmt: skip
    xsm = Psm = xl = Pl = None
    final = int(hid[int(np.argmax(bank.ll))])
    scale = bank.bias_scale(int(np.argmax(bank.ll)))
    if smooth and n_rows:
        xl = hist_x[:, final].copy()
        Pl = hist_P[:, final].copy()
        xsm, Psm = rts_smooth(xl, Pl, hist_xp[:, final], hist_Pp[:, final], hist_F[1:, final])
        xsm[:, off:] += bias_prior
        xl[:, off:] += bias_prior
    src_x, src_P = (xsm, Psm) if smooth else (xs, Ps)
    bias = src_x[-1, off:] if n_rows else bias_prior
    bsig = np.sqrt(scale * np.diagonal(src_P[-1])[off:]) if n_rows else rig.anchor_bias_sigma_m
    if heading:
        for arr in (xs, xsm):
            if arr is not None:
                arr[:, 2] = (arr[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return AnchorTrack(
        dist.t_s[k_next:].copy(), xs, Ps, xsm, Psm, xl, Pl, nh, rig.anchor_ids.copy(),
        bias, bsig, down, start, t0, heading, scale,
    )  # fmt: skip


def track_rows(track: AnchorTrack, *, smoothed: bool = False) -> tuple[list[str], np.ndarray]:
    """The track as a table (:data:`TRACK_COLUMNS`; heading NaN without odometry)."""
    xs, Ps = track._pick(smoothed)
    n = track.t_s.size
    if track.heading:
        hd, vh = xs[:, 2], Ps[:, 2, 2]
    else:
        hd = vh = np.full(n, np.nan)
    rows = np.column_stack(
        [track.t_s, xs[:, 0], xs[:, 1], hd, Ps[:, 0, 0], Ps[:, 1, 1], Ps[:, 0, 1], vh,
         track.n_hypotheses]
    )  # fmt: skip
    return list(TRACK_COLUMNS), rows.reshape(-1, len(TRACK_COLUMNS))


def track_report(
    track: AnchorTrack,
    *,
    log: str,
    rig: str,
    robust: str | None = None,
    initial_pose=None,
    smoothed: bool = False,
):
    """The track as ``rangekit track range-ekf --rig`` reports it: :func:`track_rows`, a
    summary (rows, start, ranges down-weighted, :meth:`AnchorTrack.bias_text`), and in
    JSON the rig, the weighting, the start and :meth:`AnchorTrack.diagnostics`.

    Parameters
    ----------
    track : AnchorTrack
    log, rig : str
        The log's and the rig file's names.
    robust : str, optional
        The ``robust`` given to :func:`track_anchors` (None: its default).
    initial_pose : sequence of float, optional
        The ``initial_pose`` given to :func:`track_anchors`: (x_m, y_m, heading_rad) or
        (x_m, y_m). The JSON keeps it so; the parameters for people
        (:meth:`~rangekit.io.tracks.TrackReport.parameters_text`) show the heading in
        degrees, as ``--initial-pose`` takes it.
    smoothed : bool
        Report the smoothed track.

    Returns
    -------
    rangekit.io.tracks.TrackReport
    """
    import inspect

    from rangekit.io.tracks import TrackReport

    if robust is None:
        robust = inspect.signature(track_anchors).parameters["robust"].default
    pose0 = None if initial_pose is None else [float(v) for v in initial_pose]
    columns, rows = track_rows(track, smoothed=smoothed)
    summary = (
        f"range-ekf (rig {rig}): {track.t_s.size} distance rows from t_s={track.t_s[0]:g} "
        f"(start: {track.start}), {len(track.downweighted)} ranges down-weighted ({robust}); "
        f"range bias m per anchor {track.bias_text()}"
    )
    extra = {
        "rig": str(rig),
        "robust": robust,
        "start": track.start,
        "start_t_s": float(track.start_t_s),
        "initial_pose": pose0,
        **track.diagnostics(),
    }
    # For people, as --initial-pose takes it: x, y in m and the heading in degrees.
    shown = None if pose0 is None else [*pose0[:2], *(math.degrees(h) for h in pose0[2:])]
    parameters = {"rig": rig, "robust": robust, "initial_pose": shown or "from the ranges"}
    return TrackReport("range-ekf", str(log), columns, rows, smoothed=smoothed, extra=extra,
                       summary=summary, parameters=parameters)  # fmt: skip
