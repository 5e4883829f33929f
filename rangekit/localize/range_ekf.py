"""Tracking people from acoustic ranges: the EKF of Jiang 2018 §4.4, for N targets.

The state holds position and velocity of every target, ``[x_1, y_1, vx_1, vy_1, x_2, ...]``
(Jiang 2018 §4.4.1: ``x = [ξ_t1, v_t1, ξ_t2, v_t2]``), each moving with constant velocity
driven by white acceleration (eqs (2)–(3)). Measurements come from a
:class:`~rangekit.io.tracklog.MeasurementLog`: ranges robot–target (``z1 = d_r2``, eq (4a)),
ranges target–target (``z2 = d_12``, eq (4b)) and world positions of followed targets
from the robot's pose plus a relative fix (``z3 = ξ_t1``, eq (4c)). All rows with the same
time form one measurement vector, and its covariance is Jiang's ``R(k)`` (eqs (7), (9),
(11)–(13)) generalised: every row that depends on the robot's pose shares its error.

Choices where the paper is silent or ambiguous (``docs/theory/jiang2018.md``):

- **Process noise.** Continuous white acceleration with spectral density ``accel_psd``
  (m²/s³) instead of the paper's per-step ``Q``, so irregular epoch spacing is handled
  exactly.
- **Sign of the cross-covariance (eq (12)).** With ``e_r`` the error of the robot's
  position estimate, the robot–target range error is ``-H_r2,2 e_r`` and the fix error
  is ``+e_r``, so ``R_r2,t1 = -H_r2,2 P_r``; the paper prints ``+H_r2,2 P_r``.
  ``cross_sign="physical"`` (default) uses the derived sign, ``"paper"`` the printed one;
  ``tests/localize/test_range_ekf.py`` checks the derived ``R`` against a Monte Carlo of
  the measurement errors.
- **Initialisation without prior knowledge** (the paper gives none): at the first epoch
  a target that has a fix starts there; a target with a range to a known point (the
  robot, or a target with a fix) starts at ``n_ring`` points on the circle of its most
  precise such range, each with the ring spacing as tangential sigma. Every combination
  is a hypothesis (an EKF) in a bank.
- **Mirror ambiguity.** Ranges from the robot and from the followed person, 1–1.5 m
  apart, fix a target only up to its reflection in the line through them (§4.4.3: the
  density is multi-modal). The bank is a Gaussian-sum filter: at every epoch each
  hypothesis is updated twice, once linearised at its prediction and once at the
  prediction's mirror image, and the iterated update (Gauss-Newton on the posterior,
  Bell & Cathey 1993) takes each to its own mode of the same posterior. Both children
  share their parent's past, so each is weighted by its measurement likelihood alone:
  the mirror branch is the alternative history of the target, not a jump of it, and
  needs no prior penalty. Candidates that reach the same mode (positions within
  :data:`MERGE_M`, velocities within :data:`MERGE_MPS`) pool their weights; the
  ``n_keep`` heaviest survive. Ranges are linearised where the epoch's fixes put the
  fixed targets (two persons 0.6 m apart whose predictions are off by as much at a
  turn otherwise give the pair range the wrong direction and the update the wrong
  side). The filtered output is the most probable hypothesis at each epoch (causal),
  the bank is also reported as a mixture with a branch probability, and the smoothed
  track is the RTS smoother over the lineage of the best final hypothesis.
- **Gating.** Each range is gated on its own innovation (``y_i² / S_ii`` against the
  ``gate`` quantile of chi-square with 1 dof), so one non-line-of-sight range (0.5–5 m
  too long, §5.4.3) is rejected and logged without discarding the rest of its epoch.

Examples
--------
Two targets, target 1 followed, target 2 ranged from the robot and from target 1:

>>> import io
>>> from rangekit.io.tracklog import read_measurement_log
>>> rows = ["t_s,kind,a,b,x_m,y_m,heading_rad,var_x_m2,var_y_m2,cov_xy_m2,range_m,sigma_m"]
>>> for k in range(8):
...     t = 3.0 * k
...     rows += [f"{t},robot,,,{0.4 * t},0,0,0.0036,0.0036,0,,",
...              f"{t},fix,,1,1.2,0,,0.01,0.01,0,,",
...              f"{t},range,0,2,,,,,,,{((0.4 * t - 0.4 * t) ** 2 + 9) ** 0.5},0.1",
...              f"{t},range,1,2,,,,,,,{(1.2 ** 2 + 9) ** 0.5},0.1"]
>>> log = read_measurement_log(io.StringIO("\\n".join(rows)), name="demo")
>>> trk = track_ranges(log, accel_psd=0.05)
>>> trk.n_targets, trk.t_s.size, trk.n_hypotheses
(2, 8, 8)
>>> bool(abs(trk.position(2)[-1, 1]) > 2.5)   # 3 m to the side of the path
True
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rangekit._validate import in_range, positive, positive_int
from rangekit.errors import IncompatibleInputError, InvalidParameterError, LogFormatError
from rangekit.io.tracklog import MeasurementLog
from rangekit.localize.ekf import chi2_gate, predict, rts_smooth, update

__all__ = [
    "RangeTrack",
    "Rejected",
    "cv_transition",
    "measurement_covariance",
    "track_ranges",
    "track_report",
    "track_rows",
]

KIND_ROBOT_RANGE, KIND_PAIR_RANGE, KIND_FIX_X, KIND_FIX_Y = 0, 1, 2, 3


#: Engines of :func:`track_ranges`.
ENGINES = ("compiled", "python", "numpy")

#: Largest coordinate or range (m) a log may hold; variances up to its square.
MAX_COORD_M = 1e6

#: The iterated update stops when a step moves the state by less than this (squared
#: norm, m² and (m/s)²: 1 mm; the compiled kernel reads it from here).
ITER_TOL_M2 = 1e-6


def cv_transition(dt: float, n_targets: int, accel_psd) -> tuple[np.ndarray, np.ndarray]:
    """Transition ``F`` and process noise ``Q`` of the constant-velocity model over ``dt``.

    ``accel_psd`` is one spectral density for all targets or one per target (m²/s³).

    Jiang 2018 eqs (2)–(3) with continuous white acceleration (Bar-Shalom et al. 2001,
    §6.2.2): per target and axis ``F = [[1, dt], [0, 1]]``,
    ``Q = q [[dt³/3, dt²/2], [dt²/2, dt]]``.

    Examples
    --------
    >>> F, Q = cv_transition(2.0, 1, 0.5)
    >>> F[0].tolist(), Q[0].round(4).tolist()
    ([1.0, 0.0, 2.0, 0.0], [1.3333, 0.0, 1.0, 0.0])
    """
    blk_F = np.array([[1.0, 0, dt, 0], [0, 1.0, 0, dt], [0, 0, 1.0, 0], [0, 0, 0, 1.0]])
    blk_Q = np.array([[dt**3 / 3, 0, dt**2 / 2, 0], [0, dt**3 / 3, 0, dt**2 / 2],
                      [dt**2 / 2, 0, dt, 0], [0, dt**2 / 2, 0, dt]])  # fmt: skip
    q = np.broadcast_to(np.asarray(accel_psd, dtype=np.float64), (n_targets,))
    return np.kron(np.eye(n_targets), blk_F), np.kron(np.diag(q), blk_Q)


# --------------------------------------------------------------------------- epochs
@dataclass(frozen=True)
class _Epochs:
    """The log flattened for the kernel: rows grouped by epoch (time)."""

    t_s: np.ndarray  # (n_ev,)
    start: np.ndarray  # (n_ev + 1,)
    kind: np.ndarray
    a: np.ndarray  # 0-based target index (-1 for the robot / unused)
    b: np.ndarray  # 0-based target index
    val: np.ndarray
    var: np.ndarray
    cov: np.ndarray
    robot_xy: np.ndarray  # (n_ev, 2)
    robot_P: np.ndarray  # (n_ev, 2, 2)
    row_t: np.ndarray  # time of each row, for the rejection log


def _epochs(log: MeasurementLog, name: str) -> _Epochs:
    R, F, G = log.robot, log.fixes, log.ranges
    usable = np.isfinite(G.range_m)
    times = np.unique(np.concatenate([F.t_s, G.t_s[usable]]))
    if times.size == 0:
        raise LogFormatError(f"{name}: no usable range (every range_m is empty)")
    ridx = np.searchsorted(R.t_s, times, side="right") - 1
    needs_robot = np.zeros(times.size, dtype=bool)
    needs_robot[np.searchsorted(times, F.t_s)] = True
    robot_rows = usable & (G.a == 0)
    needs_robot[np.searchsorted(times, G.t_s[robot_rows])] = True
    bad = needs_robot & (ridx < 0)
    if np.any(bad):
        raise LogFormatError(
            f"{name}: a fix or robot range at t_s={times[bad][0]:g} comes before the first "
            "robot pose (robot rows must come first)"
        )
    ridx = np.maximum(ridx, 0)
    robot_xy = R.xy_m[ridx] if R.t_s.size else np.zeros((times.size, 2))
    robot_P = R.cov_m2[ridx] if R.t_s.size else np.zeros((times.size, 2, 2))
    heading = R.heading_rad[ridx] if R.t_s.size else np.zeros(times.size)

    per: list[list[tuple]] = [[] for _ in range(times.size)]
    for i in range(F.t_s.size):
        e = int(np.searchsorted(times, F.t_s[i]))
        c, s = math.cos(heading[e]), math.sin(heading[e])
        rot = np.array([[c, -s], [s, c]])
        w = robot_xy[e] + rot @ F.rel_m[i]
        Rw = rot @ F.cov_m2[i] @ rot.T
        j = int(F.target[i]) - 1
        per[e].append((KIND_FIX_X, -1, j, w[0], Rw[0, 0], Rw[0, 1], F.t_s[i]))
        per[e].append((KIND_FIX_Y, -1, j, w[1], Rw[1, 1], 0.0, F.t_s[i]))
    for i in np.flatnonzero(usable):
        e = int(np.searchsorted(times, G.t_s[i]))
        kind = KIND_ROBOT_RANGE if G.a[i] == 0 else KIND_PAIR_RANGE
        var = float(G.sigma_m[i]) ** 2
        if var <= 0:
            raise LogFormatError(f"{name}: a range at t_s={G.t_s[i]:g} has sigma_m = 0")
        per[e].append((kind, int(G.a[i]) - 1, int(G.b[i]) - 1, G.range_m[i], var, 0.0, G.t_s[i]))
    for what, v, lim in (("a position or range", robot_xy, MAX_COORD_M),
                         ("a robot covariance", robot_P, MAX_COORD_M**2)):  # fmt: skip
        if np.any(np.abs(v) > lim):
            raise LogFormatError(f"{name}: {what} beyond {lim:g} (m or m²): not a tracking log")
    start = np.zeros(times.size + 1, dtype=np.int64)
    start[1:] = np.cumsum([len(p) for p in per])
    flat = [r for p in per for r in p]
    col = list(zip(*flat, strict=True))
    vals = np.array(col[3], dtype=np.float64)
    vars_ = np.array(col[4], dtype=np.float64)
    if np.any(np.abs(vals) > MAX_COORD_M) or np.any(vars_ > MAX_COORD_M**2):
        raise LogFormatError(
            f"{name}: a range, fix or variance beyond {MAX_COORD_M:g} m ({MAX_COORD_M**2:g} "
            "m²): not a tracking log (the filter's arithmetic would overflow)"
        )
    return _Epochs(
        times,
        start,
        np.array(col[0], dtype=np.int64),
        np.array(col[1], dtype=np.int64),
        np.array(col[2], dtype=np.int64),
        np.array(col[3], dtype=np.float64),
        np.array(col[4], dtype=np.float64),
        np.array(col[5], dtype=np.float64),
        np.ascontiguousarray(robot_xy, dtype=np.float64),
        np.ascontiguousarray(robot_P, dtype=np.float64),
        np.array(col[6], dtype=np.float64),
    )


# --------------------------------------------------------------------------- noise model
def measurement_covariance(
    kind, target_b, robot_xy, robot_P, x, var, cov, *, cross_sign: str = "physical"
) -> np.ndarray:
    """The covariance ``R(k)`` of one epoch's measurement vector (Jiang 2018 eqs (7)–(13)).

    Parameters
    ----------
    kind : array_like of int, shape (m,)
        Row kinds: 0 robot range to ``target_b``, 1 target-target range, 2 / 3 the x / y of
        a fix of ``target_b`` (adjacent rows).
    target_b : array_like of int, shape (m,)
        0-based index of the ranged or fixed target.
    robot_xy : array_like, shape (2,)
        Robot position estimate.
    robot_P : array_like, shape (2, 2)
        Its covariance ``P_r``.
    x : array_like, shape (4N,)
        The predicted state (the robot ranges are linearised there).
    var : array_like, shape (m,)
        Own noise variance of each row (``σ_d²`` for ranges, ``R_f + ...`` for fixes).
    cov : array_like, shape (m,)
        For a fix x-row, the covariance of its x and y noise; ignored otherwise.
    cross_sign : {"physical", "paper"}
        Sign of the robot-error term of robot ranges (see the module docstring).

    Returns
    -------
    ndarray, shape (m, m)
        ``G P_r G^T + N``: for two targets with rows (d_r2, d_12, ξ_t1) this is eq (13),
        with ``σ_r2² = H_r2,2 P_r H_r2,2^T + σ_d²`` (7), ``σ_12² = σ_d²`` (9),
        ``R_t1 = P_r + R_f`` (11) and ``R_r2,t1 = ∓H_r2,2 P_r`` (12).

    Examples
    --------
    Robot at the origin, target 2 at (3, 4), P_r = 0.01 I, σ_d = 0.1, R_f = 0.04 I:

    >>> import numpy as np
    >>> x = np.array([1.0, 0, 0, 0, 3.0, 4.0, 0, 0])
    >>> R = measurement_covariance([0, 1, 2, 3], [1, 1, 0, 0], [0, 0], 0.01 * np.eye(2), x,
    ...                            [0.01, 0.01, 0.04, 0.04], [0, 0, 0, 0])
    >>> R[0].round(4).tolist(), R[1].round(4).tolist()
    ([0.02, 0.0, 0.006, 0.008], [0.0, 0.01, 0.0, 0.0])
    >>> R[2:].round(4).tolist()
    [[0.006, 0.0, 0.05, 0.0], [0.008, 0.0, 0.0, 0.05]]
    """
    kind = np.asarray(kind, dtype=np.int64)
    tb = np.asarray(target_b, dtype=np.int64)
    rxy = np.asarray(robot_xy, dtype=np.float64)
    Pr = np.asarray(robot_P, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    var = np.asarray(var, dtype=np.float64)
    cov = np.asarray(cov, dtype=np.float64)
    sign = _sign(cross_sign)
    m = kind.size
    G = np.zeros((m, 2))
    N = np.diag(var)
    for r in range(m):
        if kind[r] == KIND_ROBOT_RANGE:
            u = x[4 * tb[r] : 4 * tb[r] + 2] - rxy
            G[r] = sign * u / np.linalg.norm(u)
        elif kind[r] in (KIND_FIX_X, KIND_FIX_Y):
            G[r, kind[r] - 2] = 1.0
            if kind[r] == KIND_FIX_X and r + 1 < m and kind[r + 1] == KIND_FIX_Y:
                N[r, r + 1] = N[r + 1, r] = cov[r]
    return G @ Pr @ G.T + N


def _sign(cross_sign: str) -> float:
    if cross_sign not in ("physical", "paper"):
        raise InvalidParameterError(f"cross_sign={cross_sign!r} must be 'physical' or 'paper'")
    return 1.0 if cross_sign == "physical" else -1.0


# --------------------------------------------------------------------------- initialisation
def _hypotheses(ep: _Epochs, e: int, n_targets: int, n_ring: int, sigma_v: float):
    """Initial (x0, P0) hypotheses at epoch e, or None if some target cannot start there."""
    lo, hi = ep.start[e], ep.start[e + 1]
    Pr = ep.robot_P[e]
    rxy = ep.robot_xy[e]
    fixed: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for r in range(lo, hi):
        if ep.kind[r] == KIND_FIX_X:
            j = int(ep.b[r])
            mean = np.array([ep.val[r], ep.val[r + 1]])
            Rw = np.array([[ep.var[r], ep.cov[r]], [ep.cov[r], ep.var[r + 1]]])
            fixed[j] = (mean, Rw + Pr)
    options: list[list[tuple[np.ndarray, np.ndarray]]] = []
    for j in range(n_targets):
        if j in fixed:
            options.append([fixed[j]])
            continue
        anchors = []  # (centre, radius, variance)
        for r in range(lo, hi):
            if ep.b[r] != j:
                continue
            if ep.kind[r] == KIND_ROBOT_RANGE:
                anchors.append((rxy, ep.val[r], ep.var[r] + np.trace(Pr) / 2))
            elif ep.kind[r] == KIND_PAIR_RANGE and int(ep.a[r]) in fixed:
                m_a, P_a = fixed[int(ep.a[r])]
                anchors.append((m_a, ep.val[r], ep.var[r] + np.trace(P_a) / 2))
        if not anchors:
            return None
        # n_ring points on the circle of the most precise range; the other ranges of
        # the epoch then weigh them in the first update (a two-circle intersection is
        # ill-conditioned when the anchors are 1-1.5 m apart and the target 3-6 m away).
        c, rad, var_r = min(anchors, key=lambda a: a[2])
        var_t = (rad * math.pi / n_ring) ** 2 + var_r
        opts = []
        for ang in 2 * np.pi * (np.arange(n_ring) + 0.5) / n_ring:
            u = np.array([math.cos(ang), math.sin(ang)])
            v = np.array([-u[1], u[0]])
            opts.append((c + rad * u, var_r * np.outer(u, u) + var_t * np.outer(v, v)))
        options.append(opts)
    hyps = []
    for combo in itertools.product(*options):
        x0 = np.zeros(4 * n_targets)
        P0 = np.zeros((4 * n_targets, 4 * n_targets))
        for j, (mean, cov) in enumerate(combo):
            x0[4 * j : 4 * j + 2] = mean
            P0[4 * j : 4 * j + 2, 4 * j : 4 * j + 2] = cov
            P0[4 * j + 2, 4 * j + 2] = P0[4 * j + 3, 4 * j + 3] = sigma_v**2
        hyps.append((x0, P0))
    return hyps


# --------------------------------------------------------------------------- engines
class _Ctx:
    """Everything an epoch step needs besides the state (one per track_ranges call)."""

    def __init__(self, ep, q, sign, thr, relock, sigma_v0, n_iter):
        self.ep, self.q, self.sign, self.thr = ep, q, sign, thr
        self.relock, self.sigma_v0, self.n_iter = relock, sigma_v0, n_iter
        self.a0 = np.maximum(ep.a, 0)
        n_rows = ep.kind.size
        self.acc = np.zeros(n_rows, dtype=np.bool_)
        self.nis = np.full(n_rows, np.nan)
        self.inno = np.full(n_rows, np.nan)


#: ``mirror`` argument of the steps: linearise at the prior mean itself.
NO_MIRROR = np.array([-1.0, 0.0, 0.0, 0.0, 0.0])


def _step_compiled(c: _Ctx, x, P, streak, dt, e, mirror=NO_MIRROR):
    """One epoch with the compiled kernel. Returns (x, P, xp, Pp, ll, n_reinit, acc, nis)
    with acc and nis for the epoch's rows; ``streak`` is updated in place. ``mirror``
    (:func:`_mirror_lines`) picks the branch the update is linearised on."""
    from rangekit.localize._kernels import epoch_step

    ep = c.ep
    x, P = x.copy(), P.copy()
    xp, Pp = np.empty_like(x), np.empty_like(P)
    ll, n_re = epoch_step(
        x, P, xp, Pp, dt, e, ep.start, ep.kind, c.a0, ep.b, ep.val, ep.var, ep.cov,
        ep.robot_xy, ep.robot_P, c.q, c.sign, c.thr, KIND_PAIR_RANGE, c.relock, c.sigma_v0,
        streak, c.acc, c.nis, c.inno, c.n_iter, mirror,
    )  # fmt: skip
    lo, hi = ep.start[e], ep.start[e + 1]
    return x, P, xp, Pp, ll, n_re, c.acc[lo:hi].copy(), c.nis[lo:hi].copy()


def _run_single(c: _Ctx, e0: int, x0: np.ndarray, P0: np.ndarray):
    """One hypothesis, no mirrors: the whole log in one compiled call (the fast path)."""
    from rangekit.localize._kernels import run_range_ekf

    ep = c.ep
    n, d = ep.t_s.size - e0, x0.size
    xs, Ps = np.empty((n, d)), np.empty((n, d, d))
    xps, Pps = np.empty((n, d)), np.empty((n, d, d))
    ll, reinit = np.empty(n), np.zeros(n, dtype=np.int64)
    run_range_ekf(
        x0, P0, ep.t_s[e0], ep.t_s[e0:], ep.start[e0:], ep.kind, c.a0, ep.b, ep.val, ep.var,
        ep.cov, ep.robot_xy[e0:], ep.robot_P[e0:], c.q, c.sign, c.thr, KIND_PAIR_RANGE,
        c.relock, c.sigma_v0, c.n_iter, xs, Ps, xps, Pps, c.acc, c.nis, c.inno, ll, reinit,
    )  # fmt: skip
    rows = [slice(ep.start[e], ep.start[e + 1]) for e in range(e0, ep.t_s.size)]
    acc_rows = [c.acc[r].copy() for r in rows]
    nis_rows = [c.nis[r].copy() for r in rows]
    mixed = (xs, Ps, np.ones((n, d // 4)))
    return xs, Ps, ll, acc_rows, nis_rows, (xs, Ps, xps, Pps, np.zeros(n, bool)), reinit, mixed


def _h_rows(ep: _Epochs, rows: np.ndarray, rxy: np.ndarray):
    """Measurement function over the given rows, for the numpy reference engine."""

    def h(x: np.ndarray):
        zh = np.empty(rows.size)
        H = np.zeros((rows.size, x.size))
        for p, r in enumerate(rows):
            ob = 4 * ep.b[r]
            if ep.kind[r] in (KIND_ROBOT_RANGE, KIND_PAIR_RANGE):
                anchor = rxy if ep.kind[r] == KIND_ROBOT_RANGE else x[4 * ep.a[r] : 4 * ep.a[r] + 2]
                diff = x[ob : ob + 2] - anchor
                dist = float(np.hypot(*diff))
                zh[p] = dist
                H[p, ob : ob + 2] = diff / dist
                if ep.kind[r] == KIND_PAIR_RANGE:
                    H[p, 4 * ep.a[r] : 4 * ep.a[r] + 2] = -diff / dist
            else:
                c = ep.kind[r] - KIND_FIX_X
                zh[p] = x[ob + c]
                H[p, ob + c] = 1.0
        return zh, H

    return h


def _update_numpy(c: _Ctx, e, x, P, thr, xlin, n_rows=None, n_iter=None):
    """Reference of :func:`rangekit.localize._kernels.epoch_update`: gate at ``xlin``,
    then iterate :func:`update` on the model linearised at the last estimate (the
    epoch's first ``n_rows`` rows only, if given)."""
    ep = c.ep
    n_iter = c.n_iter if n_iter is None else n_iter
    hi = ep.start[e + 1] if n_rows is None else ep.start[e] + n_rows
    rows = np.arange(ep.start[e], hi)
    h_all = _h_rows(ep, rows, ep.robot_xy[e])
    cross = "physical" if c.sign > 0 else "paper"

    def lin(h, xl):
        """``h`` made affine about ``xl`` (the iterated EKF's model)."""
        zl, Hl = h(xl)
        return lambda v: (zl + Hl @ (v - xl), Hl)

    def R_at(sel, xl):
        R = measurement_covariance(
            ep.kind[rows], ep.b[rows], ep.robot_xy[e], ep.robot_P[e], xl, ep.var[rows],
            ep.cov[rows], cross_sign=cross,
        )  # fmt: skip
        return R[np.ix_(sel, sel)]

    every = np.ones(rows.size, dtype=bool)
    zh, H = lin(h_all, xlin)(x)
    S = H @ P @ H.T + R_at(every, xlin)
    y = ep.val[rows] - zh
    marg = y**2 / np.diag(S)
    keep = ~((ep.kind[rows] <= KIND_PAIR_RANGE) & (marg > thr))
    lk0 = -0.5 * float(np.sum(thr + np.log(np.diag(S)[~keep]) + np.log(2 * np.pi)))
    lk = lk0
    if np.any(keep):
        kept = rows[keep]
        h_kept = _h_rows(ep, kept, ep.robot_xy[e])
        xl = xlin
        for it in range(n_iter):
            res = update(x, P, ep.val[kept], lin(h_kept, xl), R_at(keep, xl))
            if it + 1 == n_iter or np.sum((res.x - xl) ** 2) < ITER_TOL_M2:
                break
            xl = res.x
        _, logdet = np.linalg.slogdet(res.S)
        lk = lk0 - 0.5 * (res.nis + logdet + kept.size * np.log(2 * np.pi))
        x, P = res.x, res.P
    return x, P, lk, rows, keep, marg, y


def _mirror_point(xp: np.ndarray, mirror: np.ndarray) -> np.ndarray:
    """The prior mean with the position block ``mirror[0]`` reflected (or ``xp``)."""
    o = int(mirror[0])
    xl = xp.copy()
    if o >= 0:
        p0, u = mirror[1:3], mirror[3:5]
        dv = xp[o : o + 2] - p0
        xl[o : o + 2] = p0 + 2 * (dv @ u) * u - dv
    return xl


def _step_numpy(c: _Ctx, x, P, streak, dt, e, mirror=NO_MIRROR):
    """Reference for :func:`_step_compiled`: the validated core (:func:`predict`,
    :func:`update`) and the same lock-out breaker, in plain numpy."""
    ep = c.ep
    n_t = x.size // 4
    F, Q = cv_transition(dt, n_t, c.q)
    xp, Pp = predict(x, P, F, Q)
    # linearised where the epoch's fixes (its first rows) put the fixed targets
    kinds = ep.kind[ep.start[e] : ep.start[e + 1]]
    n_fix = int(np.argmin(kinds >= KIND_FIX_X)) if not np.all(kinds >= KIND_FIX_X) else kinds.size
    xlin = xp
    if c.n_iter > 1 and 0 < n_fix < kinds.size:
        xlin = _update_numpy(c, e, xp, Pp, np.inf, xp, n_rows=n_fix, n_iter=1)[0]
    xlin = _mirror_point(xlin, mirror)
    x, P, ll, rows, keep, marg, y = _update_numpy(c, e, xp, Pp, c.thr, xlin)
    Pp = Pp.copy()
    n_re = 0
    for j in range(n_t):
        kr = ep.kind[rows]
        ranges = (kr <= KIND_PAIR_RANGE) & (
            (ep.b[rows] == j) | ((kr == KIND_PAIR_RANGE) & (ep.a[rows] == j))
        )
        if not np.any(ranges):
            continue
        if np.any(keep[ranges]):
            streak[j] = 0
            continue
        streak[j] += 1
        if streak[j] >= c.relock:
            worst = float(np.max(y[ranges] ** 2))
            i = 4 * j + np.arange(2)
            Pp[i, i] += worst
            Pp[i + 2, i + 2] += c.sigma_v0**2
            streak[j] = 0
            n_re += 1
    if n_re:
        x, P, ll, rows, keep, marg, y = _update_numpy(c, e, xp, Pp, np.inf, xlin)
    return x, P, xp, Pp, ll, n_re, keep, marg


def _mirror_lines(ep: _Epochs, e: int, n_t: int) -> list[np.ndarray]:
    """The lines of mirror ambiguity at epoch e, one per target ranged from two known points.

    A target ranged from the robot and from a target with a fix is determined by the two
    ranges only up to its mirror image in the line through them (Jiang 2018 §4.4.3: the
    density is multi-modal). Returns ``[o, p_x, p_y, u_x, u_y]`` per such target: the
    offset of its block in the state, a point of the line (the robot) and its unit
    direction (towards the fixed target), the ``mirror`` argument of the steps.
    """
    lo, hi = ep.start[e], ep.start[e + 1]
    fixes = {int(ep.b[r]): (ep.val[r], ep.val[r + 1]) for r in range(lo, hi) if ep.kind[r] == 2}
    robot_ranged = {int(ep.b[r]) for r in range(lo, hi) if ep.kind[r] == KIND_ROBOT_RANGE}
    out = []
    for j in range(n_t):
        if j in fixes or j not in robot_ranged:
            continue
        partner = [
            int(ep.a[r]) for r in range(lo, hi)
            if ep.kind[r] == KIND_PAIR_RANGE and ep.b[r] == j and int(ep.a[r]) in fixes
        ]  # fmt: skip
        if not partner:
            continue
        p0 = ep.robot_xy[e]
        u = np.asarray(fixes[partner[0]]) - p0
        nu = float(np.hypot(*u))
        if nu < 1e-6:
            continue
        out.append(np.array([4.0 * j, p0[0], p0[1], u[0] / nu, u[1] / nu]))
    return out


def _mirror_d2(xp: np.ndarray, Pp: np.ndarray, line: np.ndarray) -> float:
    """Reference of :func:`rangekit.localize._kernels.mirror_d2`: the squared Mahalanobis
    distance (prediction's position covariance) from the predicted position of the
    line's target to its mirror image."""
    o = int(line[0])
    p0, u = line[1:3], line[3:5]
    dv = xp[o : o + 2] - p0
    v = p0 + 2 * (dv @ u) * u - dv - xp[o : o + 2]
    C = Pp[o : o + 2, o : o + 2]
    if not np.linalg.det(C) > 0:
        return 0.0
    return float(v @ np.linalg.solve(C, v))


@dataclass
class _Hyp:
    x: np.ndarray
    P: np.ndarray
    streak: np.ndarray
    cum: float
    slot: int  # row in the history arrays


#: A candidate whose target positions and velocities all lie within these of a better
#: one is the same mode (m, m/s): its weight joins the better one's. Two branches meet
#: where the target crosses the line of ambiguity, with reflected velocities; merging
#: on positions alone ended the other branch there.
MERGE_M = 0.25
MERGE_MPS = 0.25

#: A mirror branch whose image lies more than sqrt(this) prediction sigmas from the
#: predicted position is not updated: its weight would be below exp(-50) of the direct
#: branch's, nothing it could change is above rounding.
MIRROR_SKIP_D2 = 100.0


def _run_bank(c: _Ctx, e0: int, hyps, step, *, n_keep: int, mirror: bool):
    """Filter with a bank of Gaussian hypotheses (a Gaussian-sum filter with pruning).

    Start from ``hyps``. At every epoch each hypothesis is predicted and updated, and,
    for every target whose ranges leave a mirror ambiguity (``mirror=True``,
    :func:`_mirror_lines`), also updated a second time linearised on the other branch:
    the iterated update from the mirror image of the prior mean converges to the other
    mode of the same posterior. Both children condition on the same past (their
    parent's prediction), so each is weighted by its own measurement likelihood and
    nothing else: the mirror child is the alternative history, not a jump of the
    target. The ``n_keep`` candidates with the highest cumulative likelihood survive
    (candidates whose positions lie within :data:`MERGE_M` of a better one are dropped).

    Returns the reported hypothesis's per-epoch means, covariances, log-likelihoods,
    row flags and NIS (causal), the lineage of the final best (for smoothing), the
    re-opened target counts and the bank as a mixture.
    """
    ep = c.ep
    n = ep.t_s.size - e0
    n_t = hyps[0][0].size // 4
    bank = [_Hyp(x0, P0, np.zeros(n_t, dtype=np.int64), 0.0, -1) for x0, P0 in hyps]
    hist: list[list[tuple]] = []  # per epoch: list of (x, P, xp, Pp, parent, ll, acc, nis, m)
    t = ep.t_s[e0]
    best_idx = np.zeros(n, dtype=np.int64)
    n_reinit = np.zeros(n, dtype=np.int64)
    mix: list[tuple] = []
    for k in range(n):
        e = e0 + k
        dt = ep.t_s[e] - t
        t = ep.t_s[e]
        cands = []
        lines = [NO_MIRROR] + (_mirror_lines(ep, e, n_t) if mirror else [])
        for h in bank:
            direct = len(cands)  # where this hypothesis's direct child will be
            for i_line, line in enumerate(lines):
                if i_line > 0 and _mirror_d2(*cands[direct][3:5], line) > MIRROR_SKIP_D2:
                    continue  # that branch's weight would be about exp(-MIRROR_SKIP_D2 / 2)
                streak = h.streak.copy()
                x, P, xp, Pp, ll, n_re, acc, nis = step(c, h.x, h.P, streak, dt, e, line)
                cum = h.cum + ll
                cands.append((cum, x, P, xp, Pp, streak, h.slot, ll, acc, nis, n_re, i_line > 0))
        cands.sort(key=lambda r: -r[0])
        kept: list[tuple] = []
        for cd in cands:
            blk = cd[1].reshape(-1, 4)
            near = [
                i for i, kk in enumerate(kept)
                if np.max(np.hypot(*(blk[:, :2] - kk[1].reshape(-1, 4)[:, :2]).T)) < MERGE_M
                and np.max(np.hypot(*(blk[:, 2:] - kk[1].reshape(-1, 4)[:, 2:]).T)) < MERGE_MPS
            ]  # fmt: skip
            if near:
                # the same mode reached from another parent or branch: its weight joins
                # the better candidate's (the mixture's mass there), its state is dropped
                i = near[0]
                kept[i] = (float(np.logaddexp(kept[i][0], cd[0])), *kept[i][1:])
                continue
            if len(kept) < n_keep:
                kept.append(cd)
        kept.sort(key=lambda r: -r[0])
        hist.append(
            [(cd[1], cd[2], cd[3], cd[4], cd[6], cd[7], cd[8], cd[9], cd[11]) for cd in kept]
        )
        # report the most probable hypothesis (kept is sorted by weight); with honest
        # branch weights no hysteresis is needed (3 nats of it cost 0.3-2.3 m of median
        # target-2 error in the Jiang lab runs: the output stayed on a refuted branch)
        rep = 0
        best_idx[k] = rep
        mix.append(_mixture(kept, rep, n_t, lines[1:]))
        bank = [_Hyp(cd[1], cd[2], cd[5], cd[0], i) for i, cd in enumerate(kept)]
        n_reinit[k] = kept[rep][10]
    # causal output: the reported hypothesis of each epoch; lineage of the final best
    xs = np.stack([h[best_idx[k]][0] for k, h in enumerate(hist)])
    Ps = np.stack([h[best_idx[k]][1] for k, h in enumerate(hist)])
    ll = np.array([h[best_idx[k]][5] for k, h in enumerate(hist)])
    lineage = np.empty(n, dtype=np.int64)
    slot = 0
    for k in range(n - 1, -1, -1):
        lineage[k] = slot
        slot = hist[k][slot][4]
    line = [hist[k][lineage[k]] for k in range(n)]
    acc_rows = [h[best_idx[k]][6] for k, h in enumerate(hist)]
    nis_rows = [h[best_idx[k]][7] for k, h in enumerate(hist)]
    smooth_in = (
        np.stack([r[0] for r in line]),
        np.stack([r[1] for r in line]),
        np.stack([r[2] for r in line]),
        np.stack([r[3] for r in line]),
        np.array([r[8] for r in line]),  # updated on the mirror branch at epoch k
    )
    mixed = tuple(np.stack([m[i] for m in mix]) for i in range(3))
    return xs, Ps, ll, acc_rows, nis_rows, smooth_in, n_reinit, mixed


def _run_bank_compiled(c: _Ctx, e0: int, hyps, *, n_keep: int, mirror: bool):
    """:func:`_run_bank` in one compiled call (:func:`rangekit.localize._kernels.run_bank`);
    the same results to rounding (``tests/localize/test_range_ekf.py``)."""
    from rangekit.localize._kernels import run_bank

    ep = c.ep
    n = ep.t_s.size - e0
    n_t = hyps[0][0].size // 4
    d = 4 * n_t
    per = [[NO_MIRROR] + (_mirror_lines(ep, e0 + k, n_t) if mirror else []) for k in range(n)]
    n_lines = np.array([len(p) for p in per], dtype=np.int64)
    lines = np.zeros((n, int(n_lines.max()), 5))
    for k, p in enumerate(per):
        lines[k, : len(p)] = p
    K = n_keep
    m_max = int(np.max(np.diff(ep.start[e0:])))
    hx, hxp = np.empty((n, K, d)), np.empty((n, K, d))
    hP, hPp = np.empty((n, K, d, d)), np.empty((n, K, d, d))
    hparent = np.zeros((n, K), dtype=np.int64)
    hll, hcum = np.empty((n, K)), np.empty((n, K))
    hmirror = np.zeros((n, K), dtype=np.bool_)
    hnre = np.zeros((n, K), dtype=np.int64)
    hcount = np.zeros(n, dtype=np.int64)
    hacc = np.zeros((n, K, m_max), dtype=np.bool_)
    hnis = np.full((n, K, m_max), np.nan)
    mx, mP, mpb = np.empty((n, d)), np.empty((n, d, d)), np.empty((n, n_t))
    X0 = np.ascontiguousarray(np.stack([h[0] for h in hyps]))
    P0 = np.ascontiguousarray(np.stack([h[1] for h in hyps]))
    run_bank(
        X0, P0, e0, ep.t_s, ep.start, ep.kind, c.a0, ep.b, ep.val, ep.var, ep.cov,
        ep.robot_xy, ep.robot_P, c.q, c.sign, c.thr, KIND_PAIR_RANGE, c.relock, c.sigma_v0,
        c.n_iter, lines, n_lines, K, MERGE_M, MERGE_MPS, MIRROR_SKIP_D2, c.acc, c.nis, c.inno,
        hx, hP, hxp,
        hPp, hparent, hll, hcum, hmirror, hnre, hcount, hacc, hnis, mx, mP, mpb,
    )  # fmt: skip
    lineage = np.empty(n, dtype=np.int64)
    slot = 0
    for k in range(n - 1, -1, -1):
        lineage[k] = slot
        slot = hparent[k, slot]
    m = np.diff(ep.start[e0:])
    acc_rows = [hacc[k, 0, : m[k]].copy() for k in range(n)]
    nis_rows = [hnis[k, 0, : m[k]].copy() for k in range(n)]
    kk = np.arange(n)
    smooth_in = (hx[kk, lineage], hP[kk, lineage], hxp[kk, lineage], hPp[kk, lineage],
                 hmirror[kk, lineage])  # fmt: skip
    return (hx[:, 0].copy(), hP[:, 0].copy(), hll[:, 0].copy(), acc_rows, nis_rows, smooth_in,
            hnre[:, 0].copy(), (mx, mP, mpb))  # fmt: skip


def _mixture(kept, rep: int, n_t: int, lines=()):
    """Moments of the bank as a Gaussian mixture, and the branch probability.

    Weights ``w_i ∝ exp(L_i)`` from the cumulative log-likelihoods (merged modes
    pooled). Returns the mixture mean and covariance ``Σ w_i (P_i + (x_i − x̄)(x_i −
    x̄)ᵀ)`` and, per target, the probability that it is on the reported hypothesis's
    branch (:func:`_branch_probability`).
    """
    cum = np.array([cd[0] for cd in kept])
    w = np.exp(cum - cum.max())
    w /= w.sum()
    X = np.stack([cd[1] for cd in kept])
    P = np.stack([cd[2] for cd in kept])
    xbar = w @ X
    D = X - xbar
    Pbar = np.einsum("h,hij->ij", w, P) + np.einsum("h,hi,hj->ij", w, D, D)
    pb = np.array([_branch_probability(X, P, w, rep, j, lines) for j in range(n_t)])
    return xbar, 0.5 * (Pbar + Pbar.T), pb


def _branch_probability(X, P, w, rep: int, j: int, lines) -> float:
    """Probability that target ``j`` is on the reported hypothesis's branch.

    At an epoch where target ``j`` has a line of mirror ambiguity (:func:`_mirror_lines`:
    ranged from the robot and from a target with a fix), the branch is the side of that
    line, and the probability is the mixture's mass on the reported hypothesis's side,
    each Gaussian's own spread across the line included:
    ``Σ_i w_i Φ(s · nᵀ(p_i − p_0) / sqrt(nᵀ P_i n))`` with ``n`` the line's normal and
    ``s`` the sign of the reported position's side (the side probability of the particle
    reference, :func:`rangekit.experiments.jiang2018.reference_target2`). Counting each
    hypothesis's weight whole ignored a reported Gaussian that straddles the line: at
    p ≥ 0.95 the target was within 1.5 m at 26 of 40 steady epochs of two Jiang lab
    walks (65 %), now 17 of 20, every miss at the walks' last epoch
    (``docs/theory/jiang2018.md``). At other epochs: the weight of the hypotheses whose
    position of ``j`` lies within ``max(1 m, 3σ)`` of the reported one.
    """
    o = slice(4 * j, 4 * j + 2)
    for line in lines:
        if int(line[0]) != 4 * j:
            continue
        p0, nrm = line[1:3], np.array([-line[4], line[3]])
        dist = (X[:, o] - p0) @ nrm
        sig = np.sqrt(np.maximum(np.einsum("i,hij,j->h", nrm, P[:, o, o], nrm), 1e-24))
        s = 1.0 if dist[rep] >= 0 else -1.0
        return _unit(float(w @ (0.5 * _erfc(-s * dist / sig / math.sqrt(2.0)))))
    sig = math.sqrt(max(np.trace(P[rep][o, o]) / 2, 0.0))
    near = np.hypot(*(X[:, o] - X[rep, o]).T) <= max(1.0, 3 * sig)
    return _unit(float(w[near].sum()))


def _unit(p: float) -> float:
    """A probability summed from weights, clipped to [0, 1] (their sum's rounding gave
    1.0000000000000002)."""
    return min(1.0, max(0.0, p))


_erfc = np.vectorize(math.erfc, otypes=[np.float64])


def _smooth_lineage(smooth_in, t_s: np.ndarray, n_t: int, q: np.ndarray):
    """RTS over one lineage of the bank (Rauch et al. 1965 through
    :func:`rangekit.localize.ekf.rts_smooth`).

    Every hypothesis is the prediction of its parent (``F_k``) updated, on either branch,
    so the transition of the lineage is ``F_k`` throughout (the former mirror *jump*
    needed ``F_k T`` and, without it, gave negative smoothed variances: issue 18).
    """
    xf, Pf, xp, Pp, _ = smooth_in
    d = 4 * n_t
    Fs = np.empty((max(t_s.size - 1, 0), d, d))
    for k, dt in enumerate(np.diff(t_s)):
        Fs[k] = cv_transition(dt, n_t, q)[0]
    return rts_smooth(xf, Pf, xp, Pp, Fs)


# --------------------------------------------------------------------------- results
@dataclass(frozen=True)
class Rejected:
    """A range the innovation gate rejected (likely non-line-of-sight, Jiang 2018 §5.4.3)."""

    t_s: float
    a: int
    b: int
    range_m: float
    nis: float


@dataclass(frozen=True)
class RangeTrack:
    """The output of :func:`track_ranges`.

    Attributes
    ----------
    t_s : ndarray, shape (n,)
        Epoch times (every time with a range or fix, from the first epoch at which all
        targets could be initialised).
    x, P : ndarray, shapes (n, 4N), (n, 4N, 4N)
        Filtered means and covariances (state ``[x, y, vx, vy]`` per target).
    x_smooth, P_smooth : ndarray or None
        RTS-smoothed means and covariances (when ``smooth=True``).
    n_hypotheses : int
        Number of initial hypotheses.
    loglik : ndarray, shape (n,)
        Measurement log-likelihood of each epoch of the reported hypothesis.
    rejected : list of Rejected
        Ranges rejected by the gate (in the reported hypothesis at their epoch).
    n_reinit : ndarray of int, shape (n,)
        Targets re-opened by the lock-out breaker at each epoch (reported hypothesis).
    n_skipped : int
        Epochs before the first one at which every target could be initialised.
    n_targets : int
    x_line, P_line : ndarray or None
        With ``smooth=True``: the filtered means and covariances of the hypothesis the
        smoother follows (the lineage of the best final hypothesis). ``P_smooth <=
        P_line`` at every epoch; the causal output ``P`` is the same where ``same_line``.
    same_line : ndarray of bool or None
        With ``smooth=True``: epochs at which the causal filter reported that lineage.
        Elsewhere it reported another branch (e.g. the mirror image the later data
        ruled out), and ``P`` and ``P_smooth`` condition on different hypotheses.
    n_line_mirrors : int
        Epochs at which the smoothed lineage was updated on a mirror branch.
    x_mix, P_mix : ndarray
        The bank's hypotheses as a Gaussian mixture at each epoch (causal): weights from
        the cumulative likelihoods, mean and covariance with the spread of the means.
        While a target's mirror branch is alive the mixture covariance spans both.
    p_branch : ndarray, shape (n, N)
        Probability that each target is on the reported position's branch and not
        its mirror image (:func:`_branch_probability`: the bank's mass on that side of
        the epoch's mirror line; without one, the weight within max(1 m, 3σ)).
    """

    t_s: np.ndarray
    x: np.ndarray
    P: np.ndarray
    x_smooth: np.ndarray | None
    P_smooth: np.ndarray | None
    n_hypotheses: int
    loglik: np.ndarray
    rejected: list[Rejected]
    n_reinit: np.ndarray
    n_skipped: int
    n_targets: int
    x_line: np.ndarray | None = None
    P_line: np.ndarray | None = None
    same_line: np.ndarray | None = None
    n_line_mirrors: int = 0
    x_mix: np.ndarray | None = None
    P_mix: np.ndarray | None = None
    p_branch: np.ndarray | None = None

    def position_mixture(self, target: int) -> np.ndarray:
        """Positions (n, 2) of the bank's mixture mean (not one hypothesis)."""
        return self.x_mix[:, self._check(target)]

    def position_cov_mixture(self, target: int) -> np.ndarray:
        """Position covariances (n, 2, 2) of the bank as a mixture (spread included)."""
        s = self._check(target)
        return self.P_mix[:, s, s]

    def diagnostics(self, *, smoothed: bool = False) -> dict:
        """What the filter reports besides the track (the JSON keys of ``rangekit track
        range-ekf``): the ranges the gate rejected, the target count, the targets
        re-opened, the epochs skipped before the start, per row (epoch and target)
        ``p_branch``, and with ``smoothed`` the epochs where the causal filter reported
        another branch than the one smoothed along.

        Examples
        --------
        >>> trk = RangeTrack(np.array([0.0]), np.zeros((1, 4)), np.eye(4)[None], None,
        ...                  None, 1, np.zeros(1), [Rejected(0.0, 0, 1, 2.5, np.inf)],
        ...                  np.zeros(1, int), 0, 1, p_branch=np.ones((1, 1)))
        >>> trk.diagnostics()["rejected"]
        [{'t_s': 0.0, 'a': 0, 'b': 1, 'range_m': 2.5, 'nis': None}]
        """
        out = {
            "rejected": [
                {"t_s": r.t_s, "a": r.a, "b": r.b, "range_m": _num(r.range_m), "nis": _num(r.nis)}
                for r in self.rejected
            ],
            "n_targets": int(self.n_targets),
            "n_reinit": int(self.n_reinit.sum()),
            "n_skipped": int(self.n_skipped),
            # one per row: the probability that the target is near the filtered position
            # rather than on another branch of the bank (its mirror image)
            "p_branch": [float(p) for p in self.p_branch.reshape(-1)],
        }
        if smoothed:
            self._pick(True)  # refuses an unsmoothed track
            out["n_epochs_other_branch"] = int(self.same_line.size - self.same_line.sum())
        return out

    def _check(self, target: int) -> slice:
        if not 1 <= target <= self.n_targets:
            raise InvalidParameterError(f"target={target} must be in 1..{self.n_targets}")
        return slice(4 * (target - 1), 4 * (target - 1) + 2)

    def position(self, target: int, *, smoothed: bool = False) -> np.ndarray:
        """Positions (n, 2) of target ``target`` (1-based), filtered or smoothed."""
        s = self._check(target)
        return self._pick(smoothed)[0][:, s]

    def position_cov(self, target: int, *, smoothed: bool = False) -> np.ndarray:
        """Position covariances (n, 2, 2) of target ``target``."""
        s = self._check(target)
        return self._pick(smoothed)[1][:, s, s]

    def sqrt_det_p(self, target: int, *, smoothed: bool = False) -> np.ndarray:
        """``sqrt(det P_t)`` of the position covariance (m²), Jiang 2018 Figs 9c–11c."""
        return np.sqrt(np.linalg.det(self.position_cov(target, smoothed=smoothed)))

    def _pick(self, smoothed: bool):
        if smoothed:
            if self.x_smooth is None:
                raise InvalidParameterError("this track was not smoothed (use smooth=True)")
            return self.x_smooth, self.P_smooth
        return self.x, self.P


def track_ranges(
    log: MeasurementLog,
    *,
    accel_psd: float | Sequence[float] = 0.05,
    gate: float | None = 0.999,
    cross_sign: str = "physical",
    smooth: bool = False,
    sigma_v0: float = 1.0,
    n_ring: int = 8,
    max_hypotheses: int = 64,
    relock: int = 3,
    n_keep: int = 8,
    mirror: bool = True,
    iterations: int = 5,
    engine: str = "compiled",
    name: str = "log",
) -> RangeTrack:
    """Track N targets from a measurement log with the EKF of Jiang 2018 (Algorithm 2).

    Parameters
    ----------
    log : MeasurementLog
        From :func:`rangekit.io.tracklog.read_measurement_log` or a simulator.
    accel_psd : float or sequence of float
        Spectral density of the targets' white acceleration, m²/s³ per axis (> 0): one
        for all targets or one per target. Default 0.05 (walking people;
        ``docs/theory/jiang2018.md``).
    gate : float or None
        Gate probability for each range (chi-square, 1 dof), default 0.999; None: no gate.
    cross_sign : {"physical", "paper"}
        Sign of the robot-pose cross-covariance of eq (12) (module docstring).
    smooth : bool
        Also compute the RTS-smoothed track (offline logs).
    sigma_v0 : float
        Prior 1-sigma of every initial velocity component (m/s, > 0). Default 1.0.
    n_ring : int
        Initial hypotheses on the range circle of a target without a fix (>= 2).
    max_hypotheses : int
        Refuse logs whose start needs more initial hypotheses than this.
    relock : int
        After this many consecutive epochs in which the gate rejected every range of a
        target, its covariance is inflated and the epoch re-run without the gate (the
        filter had lost the target; see :mod:`rangekit.localize._kernels`). Default 3.
    n_keep : int
        Hypotheses kept after each epoch (>= 1; default 8).
    mirror : bool
        At every epoch also try the mirror image of each target ranged from the robot and
        a fixed target, in the line through them (default True). Two ranges from anchors
        1–1.5 m apart fix a target only up to this reflection, and a single EKF that
        follows the wrong branch when the target crosses the line never returns.
    iterations : int
        Gauss-Newton iterations of each update (the iterated EKF; >= 1, default 5),
        started where the epoch's fixes put the fixed targets. 1: the plain EKF,
        linearised at the prediction.
    engine : {"compiled", "python", "numpy"}
        ``"compiled"`` (default): the whole bank in one numba call
        (:func:`rangekit.localize._kernels.run_bank`); ``"python"``: the bank driven from
        Python, one compiled epoch step per hypothesis and branch; ``"numpy"``: the same
        in plain numpy on :func:`rangekit.localize.ekf.update` (slow; the reference).
        All three give the same track to rounding.
    name : str
        How the log is named in error messages.

    Returns
    -------
    RangeTrack

    Raises
    ------
    InvalidParameterError
        Bad parameter values.
    LogFormatError
        The log cannot be tracked: no usable range, fixes before the first robot pose,
        a target never initialisable, too many initial hypotheses.
    """
    q_in = np.atleast_1d(np.asarray(accel_psd, dtype=np.float64))
    q_list = [in_range("accel_psd", positive("accel_psd", float(v)), 0.0, 1e6) for v in q_in]
    thr = math.inf if gate is None else chi2_gate(in_range("gate", gate, 0.0, 1.0), 1)
    sign = _sign(cross_sign)
    sigma_v0 = in_range("sigma_v0", positive("sigma_v0", sigma_v0), 0.0, 1e3)
    n_ring = positive_int("n_ring", n_ring, minimum=2)
    max_hypotheses = positive_int("max_hypotheses", max_hypotheses)
    relock = positive_int("relock", relock)
    n_keep = positive_int("n_keep", n_keep)
    iterations = positive_int("iterations", iterations)
    if engine not in ENGINES:
        raise InvalidParameterError(f"engine={engine!r} must be one of {', '.join(ENGINES)}")
    ep = _epochs(log, name)
    n_t = log.n_targets
    if len(q_list) not in (1, n_t):
        raise InvalidParameterError(
            f"accel_psd has {len(q_list)} values; give one or one per target ({n_t})"
        )
    q = np.ascontiguousarray(np.broadcast_to(np.array(q_list), (n_t,)))
    e0 = 0
    hyps = None
    while e0 < ep.t_s.size:
        hyps = _hypotheses(ep, e0, n_t, n_ring, sigma_v0)
        if hyps is not None:
            break
        e0 += 1
    if hyps is None:
        raise LogFormatError(
            f"{name}: no epoch has a fix or a range to a known point for every target, so the "
            "tracker cannot start (each target needs a fix, or a range to the robot or to a "
            "fixed target, at one time)"
        )
    if len(hyps) > max_hypotheses:
        raise LogFormatError(
            f"{name}: starting needs {len(hyps)} initial hypotheses (> max_hypotheses="
            f"{max_hypotheses}); give fixes or more ranges at the first epoch"
        )
    ctx = _Ctx(ep, q, sign, thr, relock, sigma_v0, iterations)
    if engine == "compiled" and len(hyps) == 1 and not mirror:
        xs, Ps, ll, acc_rows, nis_rows, smooth_in, n_reinit, mixed = _run_single(ctx, e0, *hyps[0])
    elif engine == "compiled":
        xs, Ps, ll, acc_rows, nis_rows, smooth_in, n_reinit, mixed = _run_bank_compiled(
            ctx, e0, hyps, n_keep=n_keep, mirror=mirror
        )
    else:
        xs, Ps, ll, acc_rows, nis_rows, smooth_in, n_reinit, mixed = _run_bank(
            ctx, e0, hyps, _step_numpy if engine == "numpy" else _step_compiled,
            n_keep=n_keep, mirror=mirror,
        )  # fmt: skip
    if not (np.all(np.isfinite(xs)) and np.all(np.isfinite(Ps))):
        k_bad = int(np.argmax(~np.all(np.isfinite(xs), axis=1)))
        raise IncompatibleInputError(
            f"{name}: the filter diverged at t_s={ep.t_s[e0 + k_bad]:g} (non-finite state); "
            "the noise settings (accel_psd, sigma_v0) do not fit this log"
        )
    rejected = []
    for kk, e in enumerate(range(e0, ep.t_s.size)):
        for i, r in enumerate(range(ep.start[e], ep.start[e + 1])):
            if ep.kind[r] <= KIND_PAIR_RANGE and not acc_rows[kk][i]:
                rejected.append(
                    Rejected(float(ep.row_t[r]), int(ep.a[r]) + 1, int(ep.b[r]) + 1,
                             float(ep.val[r]), float(nis_rows[kk][i]))
                )  # fmt: skip
    xsm = Psm = same = None
    n_jumps = int(np.sum(smooth_in[4]))
    if smooth:
        xsm, Psm = _smooth_lineage(smooth_in, ep.t_s[e0:], n_t, q)
        same = np.all(smooth_in[1] == Ps, axis=(1, 2)) & np.all(smooth_in[0] == xs, axis=1)
    return RangeTrack(
        ep.t_s[e0:], xs, Ps, xsm, Psm, len(hyps), ll, rejected, n_reinit, e0, n_t,
        smooth_in[0] if smooth else None, smooth_in[1] if smooth else None, same, n_jumps,
        *mixed,
    )  # fmt: skip


#: Columns of a track file written by :func:`track_rows` (``docs/formats.md``).
TRACK_COLUMNS = (
    "t_s", "target", "x_m", "y_m", "vx_mps", "vy_mps", "var_x_m2", "var_y_m2", "cov_xy_m2",
)  # fmt: skip


def track_rows(track: RangeTrack, *, smoothed: bool = False) -> tuple[list[str], np.ndarray]:
    """The track as a table: one row per epoch and target (columns :data:`TRACK_COLUMNS`).

    Examples
    --------
    >>> import numpy as np
    >>> trk = RangeTrack(np.array([0.0]), np.arange(4.0)[None], np.eye(4)[None], None,
    ...                  None, 1, np.zeros(1), [], np.zeros(1, int), 0, 1)
    >>> cols, rows = track_rows(trk)
    >>> rows.tolist()
    [[0.0, 1.0, 0.0, 1.0, 2.0, 3.0, 1.0, 1.0, 0.0]]
    """
    xs, Ps = track._pick(smoothed)
    out = []
    for k in range(track.t_s.size):
        for j in range(track.n_targets):
            o = 4 * j
            out.append(
                [track.t_s[k], j + 1, *xs[k, o : o + 4], Ps[k, o, o], Ps[k, o + 1, o + 1],
                 Ps[k, o, o + 1]]
            )  # fmt: skip
    return list(TRACK_COLUMNS), np.array(out, dtype=np.float64).reshape(-1, len(TRACK_COLUMNS))


def _num(v) -> float | None:
    """A float for JSON (NaN and infinities as None)."""
    f = float(v)
    return f if math.isfinite(f) else None


#: Keywords of :func:`track_ranges` a report lists as the parameters used.
REPORT_PARAMETERS = ("accel_psd", "gate", "cross_sign", "iterations", "engine")


def track_report(track: RangeTrack, *, log: str, smoothed: bool = False, options=None):
    """The track as ``rangekit track range-ekf`` reports it: :func:`track_rows`, a summary
    (epochs, targets, rejected ranges, re-opened targets, skipped epochs), the
    :meth:`RangeTrack.diagnostics` in JSON, and the parameters used.

    Parameters
    ----------
    track : RangeTrack
    log : str
        The measurement log's name.
    smoothed : bool
        Report the smoothed track (``track_ranges(..., smooth=True)``).
    options : dict, optional
        The keywords given to :func:`track_ranges`; the parameters listed are
        :data:`REPORT_PARAMETERS`, its defaults where not given.

    Returns
    -------
    rangekit.io.tracks.TrackReport
    """
    import inspect

    from rangekit.io.tracks import TrackReport

    options = options or {}
    sig = inspect.signature(track_ranges).parameters
    parameters = {k: options.get(k, sig[k].default) for k in REPORT_PARAMETERS}
    columns, rows = track_rows(track, smoothed=smoothed)
    extra = track.diagnostics(smoothed=smoothed)
    summary = (
        f"range-ekf: {track.t_s.size} epochs, {track.n_targets} targets, "
        f"{len(track.rejected)} ranges rejected by the gate, {extra['n_reinit']} targets "
        f"re-opened, {track.n_skipped} epochs skipped before the start"
    )
    if smoothed:
        summary += (
            f"; smoothed along the final best branch ({extra['n_epochs_other_branch']} "
            "epochs where the causal filter reported another)"
        )
    return TrackReport("range-ekf", str(log), columns, rows, smoothed=smoothed, extra=extra,
                       summary=summary, parameters=parameters)  # fmt: skip
