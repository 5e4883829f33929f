"""Simulated rigs: a differential-drive robot ranged from fixed anchors (issue 18 item 7).

The robot drives a smooth figure-eight inside the anchors; its log is what the robot
records (:class:`rangekit.io.duhllog.DUHLLog`): wheel-velocity odometry rows and one
distance row per ranging, one anchor at a time (round robin) to every tag of the rig.

The range errors are drawn from a law the filters do not assume (STYLE: validate beyond
your own model): per-anchor bias + a *skewed* scatter (a standardised gamma, mean 0,
skewness ``2 / sqrt(shape)``) + with probability ``outlier_prob`` a positive
non-line-of-sight excess uniform in (0, ``outlier_max_m``]. The odometry has a per-run
wheel scale error and white noise of variance ``k_v |v| / Δt`` per wheel.

Examples
--------
>>> run = simulate_rig_run(square_rig(), duration_s=5.0, rng=1)
>>> run.log.distances.d_m.shape[1], float(run.true_bias_m[0])
(3, 0.1)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rangekit._validate import positive
from rangekit.io.duhllog import DistanceRows, DUHLLog, OdometryRows
from rangekit.io.steplog import StepLog
from rangekit.rig import Odometry, Rig

__all__ = ["RigRun", "WalkerRun", "simulate_rig_run", "simulate_walker_run", "square_rig"]


def square_rig(
    side_m: float = 2.4,
    *,
    sigma_m: float = 0.10,
    bias_sigma_m: float = 0.05,
    common_bias_sigma_m: float = 0.20,
    n_tags: int = 1,
) -> Rig:
    """Issue 18's rig: four anchors at the corners of a square, a differential-drive robot
    (wheel base 0.33 m) with one tag at its centre (or ``n_tags`` on a 0.19 m circle)."""
    a = np.array([[0, 0, 0], [side_m, 0, 0], [side_m, side_m, 0], [0, side_m, 0]], dtype=float)
    if n_tags == 1:
        lever = np.zeros((1, 3))
    else:
        ang = 2 * np.pi * np.arange(n_tags) / n_tags
        lever = np.column_stack([0.19 * np.cos(ang), 0.19 * np.sin(ang), np.zeros(n_tags)])
    return Rig(
        np.arange(1, 5), a, np.zeros(4), np.full(4, sigma_m), np.full(4, bias_sigma_m),
        np.arange(1, n_tags + 1), lever, Odometry("differential-drive", 0.33, 4e-4),
        "square", common_bias_sigma_m,
    )  # fmt: skip


@dataclass(frozen=True)
class RigRun:
    """A simulated run: the log, the rig, the truth and the drawn errors."""

    log: DUHLLog
    rig: Rig
    t_truth_s: np.ndarray
    pose_truth: np.ndarray  # (n, 3) x, y, heading
    true_bias_m: np.ndarray  # (A,)
    range_error_m: np.ndarray  # (m, T) measured - true, NaN where not heard
    outlier: np.ndarray  # (m, T) bool

    def truth_xy(self, t_s: np.ndarray) -> np.ndarray:
        """True positions (n, 2) at times ``t_s`` (linear interpolation of the truth)."""
        t = np.asarray(t_s, dtype=np.float64)
        return np.column_stack(
            [np.interp(t, self.t_truth_s, self.pose_truth[:, c]) for c in (0, 1)]
        )

    def truth_pose(self, t_s: np.ndarray) -> np.ndarray:
        t = np.asarray(t_s, dtype=np.float64)
        h = np.unwrap(self.pose_truth[:, 2])
        return np.column_stack([self.truth_xy(t), np.interp(t, self.t_truth_s, h)])


def simulate_rig_run(
    rig: Rig,
    *,
    duration_s: float = 60.0,
    range_rate_hz: float = 7.8,
    odometry_rate_hz: float = 20.0,
    speed_mps: float = 0.3,
    bias_m=0.10,
    scatter_m: float = 0.10,
    skew_shape: float = 4.0,
    outlier_prob: float = 0.05,
    outlier_max_m: float = 0.7,
    wheel_scale_sigma: float = 0.005,
    k_v_m: float = 4e-4,
    rng=None,
) -> RigRun:
    """Simulate a differential-drive robot in the anchors' square and its range log.

    Parameters
    ----------
    rig : Rig
        Anchors and tags (the robot's wheel base from ``rig.odometry``).
    duration_s, range_rate_hz, odometry_rate_hz : float
        Run length; ranging rate (one anchor per ranging, round robin, ±10 % jitter);
        odometry rate.
    speed_mps : float
        Mean forward speed along the figure-eight (centred in the anchors' bounding box,
        half-widths 30 % and 25 % of its size).
    bias_m : float or array_like (A,)
        True range bias of each anchor (measured = true + bias + scatter + outlier).
    scatter_m : float
        1-sigma of the skewed scatter (standardised gamma of shape ``skew_shape``: mean 0,
        skewness 2/sqrt(shape); shape 4: skewness 1).
    outlier_prob, outlier_max_m : float
        Probability of a non-line-of-sight range and the largest excess (uniform).
    wheel_scale_sigma : float
        1-sigma of each wheel's scale error (fixed per run).
    k_v_m : float
        Odometry noise, variance ``k_v |v| / Δt`` per wheel velocity (Kim & Kim 2013 §V).
    rng : seed or Generator

    Returns
    -------
    RigRun
    """
    g = np.random.default_rng(rng)
    duration_s = positive("duration_s", duration_s)
    B = rig.odometry.wheel_base_m if rig.odometry.kind == "differential-drive" else 0.33
    lo, hi = rig.anchor_xyz_m[:, :2].min(axis=0), rig.anchor_xyz_m[:, :2].max(axis=0)
    c, half = (lo + hi) / 2, (hi - lo) * np.array([0.35, 0.35])
    # figure-eight p(s) = c + (hx sin s, hy sin 2s), traversed at speed_mps
    fine = 200.0
    t = np.arange(0.0, duration_s + 1e-9, 1.0 / fine)
    ss = np.linspace(0, 2 * np.pi, 4001)
    dp = np.column_stack([half[0] * np.cos(ss), 2 * half[1] * np.cos(2 * ss)])
    arc = np.concatenate([[0], np.cumsum(np.hypot(*dp.T)[:-1] * np.diff(ss))])
    per = arc[-1]
    phase0 = g.uniform(0, 2 * np.pi)
    s_of = lambda L: np.interp(np.mod(L, per), arc, ss) + 2 * np.pi * np.floor(L / per)  # noqa: E731
    s = s_of(phase0 / (2 * np.pi) * per + speed_mps * t)
    xy = c + np.column_stack([half[0] * np.sin(s), half[1] * np.sin(2 * s)])
    vel = np.gradient(xy, t, axis=0)
    head = np.unwrap(np.arctan2(vel[:, 1], vel[:, 0]))
    v = np.hypot(*vel.T)
    w = np.gradient(head, t)
    vr_true, vl_true = v + w * B / 2, v - w * B / 2
    # re-integrate the wheel velocities so the truth is exactly a unicycle path
    pose = np.empty((t.size, 3))
    pose[0] = [xy[0, 0], xy[0, 1], head[0]]
    dt = 1.0 / fine
    for k in range(1, t.size):
        vr, vl = vr_true[k - 1], vl_true[k - 1]
        dD, dphi = dt * (vr + vl) / 2, dt * (vr - vl) / B
        a = pose[k - 1, 2] + dphi / 2
        pose[k] = pose[k - 1] + [dD * math.cos(a), dD * math.sin(a), dphi]
    # odometry rows: interval means of the wheel velocities, scale error, white noise
    t_odo = np.arange(0.0, duration_s + 1e-9, 1.0 / odometry_rate_hz)
    idx = np.searchsorted(t, t_odo)
    scale = 1 + g.normal(0, wheel_scale_sigma, 2)
    vr_o, vl_o = np.zeros(t_odo.size), np.zeros(t_odo.size)
    for m in range(1, t_odo.size):
        sl = slice(idx[m - 1], idx[m])
        dto = t_odo[m] - t_odo[m - 1]
        for arr, vt, sc in ((vr_o, vr_true, scale[0]), (vl_o, vl_true, scale[1])):
            mean = float(np.mean(vt[sl]))
            arr[m] = sc * mean + g.normal(0, math.sqrt(k_v_m * abs(mean) / dto))
    odo = OdometryRows(t_odo, vr_o, vl_o)
    # ranges: round robin over the anchors, jittered times
    A, T = rig.n_anchors, rig.n_tags
    bias = np.broadcast_to(np.asarray(bias_m, dtype=np.float64), (A,)).copy()
    n_r = int(duration_s * range_rate_hz)
    t_r = (np.arange(n_r) + 0.5 + g.uniform(-0.1, 0.1, n_r)) / range_rate_hz
    t_r = t_r[t_r < duration_s]
    anchor = np.arange(t_r.size) % A
    pr = np.column_stack([np.interp(t_r, t, pose[:, c]) for c in range(3)])
    d_m = np.full((t_r.size, max(3, rig.n_tags)), np.nan)
    err = np.full((t_r.size, T), np.nan)
    out = np.zeros((t_r.size, T), dtype=bool)
    for tg in range(T):
        cth, sth = np.cos(pr[:, 2]), np.sin(pr[:, 2])
        lx, ly, lz = rig.tag_lever_m[tg]
        px = pr[:, 0] + cth * lx - sth * ly
        py = pr[:, 1] + sth * lx + cth * ly
        a = rig.anchor_xyz_m[anchor]
        true = np.sqrt((px - a[:, 0]) ** 2 + (py - a[:, 1]) ** 2 + (lz - a[:, 2]) ** 2)
        k = skew_shape
        scat = scatter_m * (g.gamma(k, 1.0, t_r.size) - k) / math.sqrt(k)
        o = g.random(t_r.size) < outlier_prob
        excess = np.where(o, g.uniform(0, outlier_max_m, t_r.size), 0.0)
        e = bias[anchor] + scat + excess
        d_m[:, tg] = np.maximum(true + e, 0.0)
        err[:, tg] = d_m[:, tg] - true
        out[:, tg] = o
    dist = DistanceRows(t_r, rig.anchor_ids[anchor].astype(np.int64), d_m)
    return RigRun(DUHLLog(odo, dist), rig, t, pose, bias, err, out)


@dataclass(frozen=True)
class WalkerRun:
    """A simulated walker: the range log (no odometry rows), the step log, the truth."""

    log: DUHLLog
    steps: StepLog
    rig: Rig
    t_truth_s: np.ndarray
    xy_truth: np.ndarray  # (n, 2)
    true_bias_m: np.ndarray

    def truth_xy(self, t_s: np.ndarray) -> np.ndarray:
        t = np.asarray(t_s, dtype=np.float64)
        return np.column_stack([np.interp(t, self.t_truth_s, self.xy_truth[:, c]) for c in (0, 1)])


def simulate_walker_run(
    rig: Rig,
    *,
    duration_s: float = 60.0,
    range_rate_hz: float = 4.0,
    speed_mps: float = 1.0,
    step_rate_hz: float = 1.8,
    length_sigma_m: float = 0.04,
    heading_sigma_rad: float = 0.05,
    heading_drift_rad_s: float = 0.003,
    bias_m=0.10,
    scatter_m: float = 0.10,
    skew_shape: float = 4.0,
    outlier_prob: float = 0.05,
    outlier_max_m: float = 0.7,
    rng=None,
) -> WalkerRun:
    """A walker on an ellipse inside the anchors, with step events and sequential ranges.

    Steps at ``step_rate_hz``: the measured length is the true chord ± ``length_sigma_m``,
    the heading the chord's direction + white noise ``heading_sigma_rad`` + a random-walk
    drift (``heading_drift_rad_s`` per sqrt(s): a foot IMU's yaw drift). Ranges as in
    :func:`simulate_rig_run` (bias + skewed scatter + positive outliers), one anchor per
    ranging, to the rig's tags rotated with the walking direction.

    Examples
    --------
    >>> from rangekit.io.steplog import StepLog
    >>> run = simulate_walker_run(square_rig(), duration_s=5.0, rng=1)
    >>> isinstance(run.steps, StepLog), run.log.odometry.t_s.size
    (True, 0)
    """
    g = np.random.default_rng(rng)
    duration_s = positive("duration_s", duration_s)
    lo, hi = rig.anchor_xyz_m[:, :2].min(axis=0), rig.anchor_xyz_m[:, :2].max(axis=0)
    c, half = (lo + hi) / 2, (hi - lo) * 0.3
    t = np.arange(0.0, duration_s + 1e-9, 0.01)
    per = 2 * np.pi * np.sqrt((half[0] ** 2 + half[1] ** 2) / 2)
    ang = g.uniform(0, 2 * np.pi) + 2 * np.pi * speed_mps * t / per
    xy = c + np.column_stack([half[0] * np.cos(ang), half[1] * np.sin(ang)])
    vel = np.gradient(xy, t, axis=0)
    head = np.arctan2(vel[:, 1], vel[:, 0])
    t_st = np.arange(1.0 / step_rate_hz, duration_s, 1.0 / step_rate_hz)
    p_st = np.column_stack([np.interp(t_st, t, xy[:, k]) for k in (0, 1)])
    prev = np.vstack([xy[:1], p_st[:-1]])
    chord = p_st - prev
    drift = np.cumsum(g.normal(0, heading_drift_rad_s * np.sqrt(1.0 / step_rate_hz), t_st.size))
    steps = StepLog(
        t_st,
        np.maximum(np.hypot(*chord.T) + g.normal(0, length_sigma_m, t_st.size), 0.0),
        np.arctan2(chord[:, 1], chord[:, 0]) + drift + g.normal(0, heading_sigma_rad, t_st.size),
        np.full(t_st.size, heading_sigma_rad),
    )
    A = rig.n_anchors
    bias = np.broadcast_to(np.asarray(bias_m, dtype=np.float64), (A,)).copy()
    n_r = int(duration_s * range_rate_hz)
    t_r = (np.arange(n_r) + 0.5 + g.uniform(-0.1, 0.1, n_r)) / range_rate_hz
    t_r = t_r[t_r < duration_s]
    anchor = np.arange(t_r.size) % A
    pr = np.column_stack([np.interp(t_r, t, xy[:, k]) for k in (0, 1)])
    hr = np.interp(t_r, t, np.unwrap(head))
    d_m = np.full((t_r.size, max(3, rig.n_tags)), np.nan)
    for tg in range(rig.n_tags):
        lx, ly, lz = rig.tag_lever_m[tg]
        px = pr[:, 0] + np.cos(hr) * lx - np.sin(hr) * ly
        py = pr[:, 1] + np.sin(hr) * lx + np.cos(hr) * ly
        a = rig.anchor_xyz_m[anchor]
        true = np.sqrt((px - a[:, 0]) ** 2 + (py - a[:, 1]) ** 2 + (lz - a[:, 2]) ** 2)
        k = skew_shape
        scat = scatter_m * (g.gamma(k, 1.0, t_r.size) - k) / math.sqrt(k)
        o = g.random(t_r.size) < outlier_prob
        excess = np.where(o, g.uniform(0, outlier_max_m, t_r.size), 0.0)
        d_m[:, tg] = np.maximum(true + bias[anchor] + scat + excess, 0.0)
    dist = DistanceRows(t_r, rig.anchor_ids[anchor].astype(np.int64), d_m)
    return WalkerRun(DUHLLog(distances=dist), steps, rig, t, xy, bias)
