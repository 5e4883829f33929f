"""Simulator of Kim & Kim 2013 §V: a Pioneer P3-DX under ceiling ultrasonic Txs.

Kim & Kim 2013 track a differential-drive robot (Pioneer P3-DX) with three ultrasonic
receivers at r_R = 0.19 m, 0°/120°/240° from its heading (eq (1)), from wheel odometry at
100 Hz and one-way distances to ceiling transmitters activated in turn at 5 Hz (§V).
:func:`simulate` re-creates the four trajectories of §V with known truth and returns
what the robot logs (:class:`rangekit.io.duhllog.DUHLLog`) plus the beacon file
(:class:`rangekit.io.duhllog.Beacons`).

Choices (the paper's Fig. 7 and Fig. 9, which show the Tx positions and the paths, are
not available; everything below is this module's design, sized after the text):

* **Layouts** (:func:`layout`). ``"six"`` (trajectories 1, 2, 4): six Txs at
  z_T = 2.011 m on a 2 x 3 grid 3 m apart, x in {0, 3, 6} m, y in {0, 3} m, over a
  7.5 x 4.5 m office area (ids 1-3 on y = 0, 4-6 on y = 3, by increasing x). ``"ten"``
  (trajectory 3): ten Txs at z_T = 1.887 m on a 2 x 5 grid along a corridor, x in {0, 3,
  6, 9, 12} m, y in {0, 2.4} m (ids 1-5 on y = 0, 6-10 on y = 2.4). With the default
  hearing radius of 4 m (horizontal), at least 2 Txs are audible everywhere along the
  paths (the UHL algorithm needs two, §II-B); a 3 m grid, not 2 m, so that the robot
  does not hear every Tx all the time (3-6 are audible along the four paths, median 4).
* **Trajectories** (:data:`TRAJECTORIES`): waypoint paths of 18-22 m with 4 turns of
  45°-128°. 1, 2 in ``"six"`` and 3 in ``"ten"`` at the nominal 0.37 m/s of §V (the
  caption of Fig. 7 says 0.34 m/s; the text, used here, 0.37 m/s); 4 in ``"six"`` at
  1.02 m/s (Experiment II).
* **Robot**: wheel base (track width) B_w = 0.33 m for the P3-DX (``wheel_base_m``; the
  paper does not state it). A pure-pursuit controller follows the path (lookahead
  L = max(0.5 m, 0.8 s x speed)); it starts and ends at rest with linear acceleration
  limited to 0.5 m/s², turn rate to 1.5 rad/s and turn acceleration to 3 rad/s², and
  slows before each corner to the speed at which the turn stays within the rate limit,
  so the wheel speeds are continuous ramps.
* **Truth** is integrated with eq (14) from the *true* wheel speeds, held constant over
  each odometry interval (ΔT_s = 10 ms); headings are continuous (not wrapped).
* **Odometry** reports v_meas = v_true + N(0, k_v |v_true| / ΔT_s) per wheel, k_v = 4e-4 m
  (§V, [11]); a wheel at rest reads exactly 0.
* **Ultrasonics**: a firing every ``odo_rate_hz / fire_rate_hz``-th odometry instant (5 Hz),
  starting at t = 0. The robot activates the Txs in turn, round robin in id order over those
  within ``audible_radius_m`` (horizontally) of its true position; a slot with none audible
  is skipped. A firing gives one distance row: the true 3-D distances Tx -> each receiver at
  that instant + N(0, σ_dd²), σ_dd = 0.01 m (§V, eq (27)), or, with
  ``distance_source="audio"``, the distances measured by
  :func:`rangekit.ranging.ultrasonic.range_oneway` on a Barker-7 window rendered by
  :func:`rangekit.sim.ultrasonic.render_oneway` at the robot's pose (NaN where a receiver
  finds nothing). The robot's motion during the flight (<= 15 ms) is neglected.

Examples
--------
>>> run = simulate(1, rng=0)
>>> run.layout, run.nominal_speed_mps, float(run.t_s[1]), len(run.beacons)
('six', 0.37, 0.01, 6)
>>> run.distance_t_s[:3].tolist(), run.distance_tx[:3].tolist()
([0.0, 0.2, 0.4], [1, 2, 4])
>>> log = run.to_log()
>>> log.odometry.t_s.size == run.t_s.size, log.distances.d_m.shape[1]
(True, 3)
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from rangekit import _validate
from rangekit.errors import InvalidParameterError
from rangekit.io.duhllog import Beacons, DistanceRows, DUHLLog, OdometryRows
from rangekit.sim.ultrasonic import R_RECEIVER_M, receiver_positions

__all__ = [
    "ACCEL_MPS2",
    "LAYOUTS",
    "TRAJECTORIES",
    "TURN_ACCEL_RADPS2",
    "TURN_RATE_RADPS",
    "WHEEL_BASE_M",
    "KimRun",
    "Trajectory",
    "drive",
    "follow_path",
    "layout",
    "simulate",
]

#: Pioneer P3-DX track width assumed here, m (Kim & Kim 2013 do not state B_w).
WHEEL_BASE_M = 0.33
#: Linear acceleration (and deceleration) limit of the path follower, m/s².
ACCEL_MPS2 = 0.5
#: Turn-rate limit of the path follower, rad/s.
TURN_RATE_RADPS = 1.5
#: Turn-acceleration limit of the path follower, rad/s².
TURN_ACCEL_RADPS2 = 3.0
#: Lowest speed the follower plans for a corner, m/s.
_MIN_CORNER_MPS = 0.08
#: Spacing of the dense path samples used for projection, m.
_DS_M = 0.005
#: The run ends when the robot is this close to the last waypoint (along the path), m.
_ARRIVE_M = 0.002


def _grid(xs, ys, z):
    return np.array([[x, y, z] for y in ys for x in xs], dtype=np.float64)


#: Ceiling layouts: name -> Tx positions (n, 3) in m, ids 1..n in row order.
LAYOUTS: dict[str, np.ndarray] = {
    "six": _grid((0.0, 3.0, 6.0), (0.0, 3.0), 2.011),
    "ten": _grid((0.0, 3.0, 6.0, 9.0, 12.0), (0.0, 2.4), 1.887),
}
for _a in LAYOUTS.values():
    _a.flags.writeable = False


@dataclass(frozen=True, eq=False)
class Trajectory:
    """One of Kim & Kim's four runs: ceiling ``layout``, nominal ``speed_mps``, and the
    ``waypoints_m`` (k, 2) the robot drives through, from rest to rest."""

    layout: str
    speed_mps: float
    waypoints_m: np.ndarray


def _wp(*pts) -> np.ndarray:
    a = np.array(pts, dtype=np.float64)
    a.flags.writeable = False
    return a


#: Trajectory number -> :class:`Trajectory` (§V: 1-3 Experiment I, 4 Experiment II).
TRAJECTORIES: dict[int, Trajectory] = {
    # A loop around the office: 18.5 m, 90° turns.
    1: Trajectory(
        "six", 0.37, _wp((-0.5, 0.5), (6.5, 0.5), (6.5, 2.5), (0.5, 2.5), (0.5, 1.5), (3.0, 1.5))
    ),
    # A zig-zag across the grid and back along its middle: 17.9 m, 108°-128° turns.
    2: Trajectory(
        "six", 0.37, _wp((0.0, 3.0), (2.0, 0.0), (4.0, 3.0), (6.0, 0.0), (6.5, 1.5), (1.0, 1.5))
    ),
    # Down the corridor on one side, back on the other: 19.2 m, 45°-90° turns.
    3: Trajectory(
        "ten",
        0.37,
        _wp((-0.5, 0.6), (5.0, 0.6), (6.2, 1.8), (12.0, 1.8), (12.0, 0.6), (7.0, 0.6)),
    ),
    # Experiment II, three times faster: a larger loop, 21.3 m, 90° turns.
    4: Trajectory(
        "six", 1.02, _wp((0.0, 0.0), (6.0, 0.0), (6.0, 3.0), (0.0, 3.0), (0.0, 1.2), (4.5, 1.2))
    ),
}


def layout(name: str) -> Beacons:
    """The ceiling transmitters of a layout (``"six"`` or ``"ten"``), ids 1..n.

    Examples
    --------
    >>> b = layout("ten")
    >>> b.ids.tolist(), b.position(7).tolist()
    ([1, 2, 3, 4, 5, 6, 7, 8, 9, 10], [3.0, 2.4, 1.887])
    """
    if name not in LAYOUTS:
        raise InvalidParameterError(f"layout={name!r} must be one of {sorted(LAYOUTS)}")
    xyz = LAYOUTS[name]
    return Beacons(np.arange(1, len(xyz) + 1, dtype=np.int64), xyz)


# --------------------------------------------------------------------------- kinematics


def _step(pose, v_r: float, v_l: float, dt: float, b_w: float):
    """One step of Kim & Kim 2013 eq (14)."""
    d_d = dt * (v_r + v_l) / 2.0
    d_phi = dt * (v_r - v_l) / b_w
    a = pose[2] + d_phi / 2.0
    return (pose[0] + d_d * math.cos(a), pose[1] + d_d * math.sin(a), pose[2] + d_phi)


def drive(
    v_right_mps,
    v_left_mps,
    *,
    pose0=(0.0, 0.0, 0.0),
    dt_s: float = 0.01,
    wheel_base_m: float = WHEEL_BASE_M,
) -> np.ndarray:
    """Integrate wheel speeds into poses by Kim & Kim 2013 eq (14).

    Parameters
    ----------
    v_right_mps, v_left_mps : array_like, shape (n,)
        Wheel speeds; entry k (k >= 1) is held over the interval ``[t_{k-1}, t_k]``,
        entry 0 is ignored (the log convention of :mod:`rangekit.io.duhllog`).
    pose0 : (x_m, y_m, heading_rad)
        Pose at t_0.
    dt_s : float
        Odometry interval ΔT_s.
    wheel_base_m : float
        Distance between the wheels B_w.

    Returns
    -------
    ndarray, shape (n, 3)
        Poses at t_0..t_{n-1}; the heading is continuous (not wrapped).

    Notes
    -----
    ``ΔD_k = ΔT_s (v_k^R + v_k^L) / 2``, ``Δφ_k = ΔT_s (v_k^R - v_k^L) / B_w``,
    ``x_k = x_{k-1} + ΔD_k cos(φ_{k-1} + Δφ_k / 2)``, likewise y with sin, and
    ``φ_k = φ_{k-1} + Δφ_k`` (eq (14) with w_k = 0).

    Examples
    --------
    >>> drive([0.0, 0.5, 0.5], [0.0, 0.5, 0.5], dt_s=0.1).tolist()
    [[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.1, 0.0, 0.0]]
    """
    vr = _validate.signal_1d("v_right_mps", v_right_mps)
    vl = _validate.signal_1d("v_left_mps", v_left_mps)
    if vr.size != vl.size:
        raise InvalidParameterError(
            f"v_right_mps and v_left_mps differ in length ({vr.size} != {vl.size})"
        )
    dt = _validate.positive("dt_s", dt_s)
    b_w = _validate.positive("wheel_base_m", wheel_base_m)
    p0 = np.asarray(pose0, dtype=np.float64)
    if p0.shape != (3,) or not np.all(np.isfinite(p0)):
        raise InvalidParameterError(f"pose0={pose0!r} must be (x, y, heading_rad), finite")
    out = np.empty((max(vr.size, 1), 3))
    pose = tuple(float(v) for v in p0)
    out[0] = pose
    for k in range(1, vr.size):
        pose = _step(pose, float(vr[k]), float(vl[k]), dt, b_w)
        out[k] = pose
    return out


# --------------------------------------------------------------------------- path following


def _dense_path(wp: np.ndarray):
    """Dense samples (M, 2) of the polyline, their arc lengths (M,), segment directions."""
    seg = np.diff(wp, axis=0)
    lens = np.hypot(seg[:, 0], seg[:, 1])
    if np.any(lens <= 0):
        raise InvalidParameterError("waypoints_m must not repeat a point (zero-length segment)")
    cum = np.concatenate([[0.0], np.cumsum(lens)])
    s = np.linspace(0.0, cum[-1], int(math.ceil(cum[-1] / _DS_M)) + 1)
    j = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    pts = wp[j] + seg[j] * ((s - cum[j]) / lens[j])[:, None]
    return pts, s, cum, seg / lens[:, None]


def _corner_speeds(dirs: np.ndarray, speed: float, look: float, w_max: float) -> np.ndarray:
    """Speed at which pure pursuit takes each interior corner within the turn-rate limit.

    Cutting a corner of turn angle θ, pure pursuit's curvature peaks near
    ``2 tan(θ/2) / L``, so ``v_c = ω_max L / (2 tan(θ/2))``.
    """
    cosang = np.clip(np.sum(dirs[:-1] * dirs[1:], axis=1), -1.0, 1.0)
    theta = np.arccos(cosang)
    with np.errstate(divide="ignore"):
        v = w_max * look / (2.0 * np.tan(theta / 2.0))
    return np.clip(np.nan_to_num(v, nan=speed, posinf=speed), _MIN_CORNER_MPS, speed)


def follow_path(
    waypoints_m,
    speed_mps: float,
    *,
    dt_s: float = 0.01,
    wheel_base_m: float = WHEEL_BASE_M,
    accel_mps2: float = ACCEL_MPS2,
    turn_rate_radps: float = TURN_RATE_RADPS,
    turn_accel_radps2: float = TURN_ACCEL_RADPS2,
    max_time_s: float = 600.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Drive a differential-drive robot along waypoints, from rest to rest (pure pursuit).

    The robot starts at the first waypoint facing the first segment. Every ``dt_s`` the
    controller picks the speed v (the nominal speed, lowered ahead of each corner and
    before the end so that a ``accel_mps2`` ramp reaches the corner speed or 0 in time,
    and so that the turn stays within ``turn_rate_radps``) and the turn rate
    ω = v κ towards a lookahead point L = max(0.5, 0.8 s x speed) m ahead along the
    path (κ = 2 y_L / l², the pure-pursuit arc); v and ω change by at most
    ``accel_mps2 dt`` and ``turn_accel_radps2 dt`` per step. The wheels get
    v ± ω B_w / 2 for the next interval, and the pose follows eq (14) (:func:`drive`).
    It stops within 2 mm of the last waypoint, at rest.

    Returns
    -------
    v_right_mps, v_left_mps : ndarray, shape (n,)
        True wheel speeds (entry 0 = 0, the start; the log convention of :func:`drive`).
    poses : ndarray, shape (n, 3)
        Poses at t_k = k dt_s (``drive(v_right, v_left, pose0=poses[0], ...)``).

    Raises
    ------
    InvalidParameterError
        Fewer than 2 waypoints, a repeated waypoint, a non-positive parameter, or a path
        not finished within ``max_time_s``.
    """
    wp = np.asarray(waypoints_m, dtype=np.float64)
    if wp.ndim != 2 or wp.shape[1] != 2 or len(wp) < 2 or not np.all(np.isfinite(wp)):
        raise InvalidParameterError("waypoints_m must be a finite (k, 2) array with k >= 2")
    speed = _validate.positive("speed_mps", speed_mps)
    dt = _validate.positive("dt_s", dt_s)
    b_w = _validate.positive("wheel_base_m", wheel_base_m)
    acc = _validate.positive("accel_mps2", accel_mps2)
    w_max = _validate.positive("turn_rate_radps", turn_rate_radps)
    w_acc = _validate.positive("turn_accel_radps2", turn_accel_radps2)
    t_max = _validate.positive("max_time_s", max_time_s)
    pts, s_dense, cum, dirs = _dense_path(wp)
    total = float(cum[-1])
    look = max(0.5, 0.8 * speed)
    v_corner = _corner_speeds(dirs, speed, look, w_max)
    s_corner = cum[1:-1]
    window = int(math.ceil(1.5 * look / _DS_M)) + 2

    pose = (float(wp[0, 0]), float(wp[0, 1]), math.atan2(dirs[0, 1], dirs[0, 0]))
    idx, v, w = 0, 0.0, 0.0
    vr_out, vl_out, poses = [0.0], [0.0], [pose]
    n_max = int(math.ceil(t_max / dt))
    for _ in range(n_max):
        hi = min(idx + window, len(pts))
        d2 = (pts[idx:hi, 0] - pose[0]) ** 2 + (pts[idx:hi, 1] - pose[1]) ** 2
        idx += int(np.argmin(d2))
        s = float(s_dense[idx])
        remaining = total - s
        if remaining < _ARRIVE_M:
            v_goal, w_goal = 0.0, 0.0
            if v == 0.0 and w == 0.0:
                break
        else:
            # Lookahead point, on the last segment extended past the end if need be.
            s_l = s + look
            if s_l <= total:
                j = min(int(round(s_l / _DS_M)), len(pts) - 1)
                gx, gy = pts[j]
            else:
                gx, gy = wp[-1] + dirs[-1] * (s_l - total)
            dx, dy = gx - pose[0], gy - pose[1]
            c, sn = math.cos(pose[2]), math.sin(pose[2])
            y_l = -sn * dx + c * dy
            kappa = 2.0 * y_l / max(dx * dx + dy * dy, 1e-12)
            ahead = s_corner + 0.5 * look > s
            v_goal = min(speed, math.sqrt(2.0 * acc * remaining))
            if np.any(ahead):
                gap = np.maximum(s_corner[ahead] - look - s, 0.0)
                v_goal = min(v_goal, float(np.min(np.sqrt(v_corner[ahead] ** 2 + 2 * acc * gap))))
            if kappa != 0.0:
                v_goal = min(v_goal, w_max / abs(kappa))
        v = min(max(v_goal, v - acc * dt), v + acc * dt)
        v = max(v, 0.0)
        if remaining >= _ARRIVE_M:
            w_goal = v * kappa
        w = min(max(w_goal, w - w_acc * dt), w + w_acc * dt)
        w = min(max(w, -w_max), w_max)
        if abs(v) < 1e-12:
            v = 0.0
        if abs(w) < 1e-12:
            w = 0.0
        v_r, v_l = v + w * b_w / 2.0, v - w * b_w / 2.0
        pose = _step(pose, v_r, v_l, dt, b_w)
        vr_out.append(v_r)
        vl_out.append(v_l)
        poses.append(pose)
    else:
        raise InvalidParameterError(
            f"the path of {total:.1f} m was not finished within max_time_s={t_max!r}"
        )
    return np.array(vr_out), np.array(vl_out), np.array(poses)


@functools.lru_cache(maxsize=16)
def _truth(trajectory: int, dt: float, b_w: float):
    tr = TRAJECTORIES[trajectory]
    out = follow_path(tr.waypoints_m, tr.speed_mps, dt_s=dt, wheel_base_m=b_w)
    for a in out:
        a.flags.writeable = False
    return out


# --------------------------------------------------------------------------- the run


@dataclass(frozen=True, eq=False)
class KimRun:
    """A simulated Kim & Kim 2013 §V run: truth, odometry, distances, beacons.

    Attributes
    ----------
    trajectory : int
        1-4 (:data:`TRAJECTORIES`).
    layout : str
        ``"six"`` or ``"ten"``.
    nominal_speed_mps : float
    t_s : ndarray, shape (n,)
        Odometry instants k ΔT_s from 0.
    true_pose : ndarray, shape (n, 3)
        True ``(x_m, y_m, heading_rad)`` at ``t_s`` (heading continuous, not wrapped).
    v_right, v_left : ndarray, shape (n,)
        Measured wheel speeds (m/s) over the interval ending at ``t_s[k]`` (entry 0 = 0).
    v_right_true, v_left_true : ndarray, shape (n,)
        The true wheel speeds (``true_pose`` is :func:`drive` of them).
    distance_t_s : ndarray, shape (m,)
        Firing instants (odometry instants).
    distance_k : ndarray of int64, shape (m,)
        Index into ``t_s`` of each firing.
    distance_tx : ndarray of int64, shape (m,)
        Transmitter fired.
    distance_m : ndarray, shape (m, 3)
        Measured distances to receivers 1-3 (NaN: missed, audio only).
    distance_true_m : ndarray, shape (m, 3)
        True 3-D distances at the firing instant.
    beacons : Beacons
        The layout's transmitters.
    waypoints_m : ndarray, shape (k, 2)
    params : dict
        Every parameter of :func:`simulate` (except ``rng``).
    """

    trajectory: int
    layout: str
    nominal_speed_mps: float
    t_s: np.ndarray
    true_pose: np.ndarray
    v_right: np.ndarray
    v_left: np.ndarray
    v_right_true: np.ndarray
    v_left_true: np.ndarray
    distance_t_s: np.ndarray
    distance_k: np.ndarray
    distance_tx: np.ndarray
    distance_m: np.ndarray
    distance_true_m: np.ndarray
    beacons: Beacons
    waypoints_m: np.ndarray
    params: dict

    def to_log(self) -> DUHLLog:
        """What the robot records: odometry rows and distance rows (a :class:`DUHLLog`)."""
        return DUHLLog(
            OdometryRows(self.t_s.copy(), self.v_right.copy(), self.v_left.copy()),
            DistanceRows(self.distance_t_s.copy(), self.distance_tx.copy(), self.distance_m.copy()),
        )


def _fire_schedule(xy: np.ndarray, beacons: Beacons, radius: float, every: int):
    """Firing indices and Tx ids: round robin in id order over the audible Txs."""
    order = np.argsort(beacons.ids, kind="stable")
    ids = beacons.ids[order]
    txy = beacons.xyz_m[order, :2]
    ks, txs, last = [], [], None
    for k in range(0, len(xy), every):
        audible = ids[np.hypot(*(txy - xy[k]).T) <= radius]
        if audible.size == 0:
            continue
        nxt = audible[audible > last] if last is not None else audible
        last = int(nxt[0] if nxt.size else audible[0])
        ks.append(k)
        txs.append(last)
    return np.array(ks, dtype=np.int64), np.array(txs, dtype=np.int64)


def _audio_distances(txyz, pose, *, r_r, snr_db, max_range_m, rng) -> np.ndarray:
    """Render one firing and range it (NaN where a receiver found nothing)."""
    from rangekit.physics import speed_of_sound_m_s
    from rangekit.ranging.ultrasonic import range_oneway
    from rangekit.sim.ultrasonic import render_oneway

    period = max_range_m / speed_of_sound_m_s() + 0.01
    sim = render_oneway(
        txyz[None, :], pose, n_windows=1, period_s=period, snr_db=snr_db, radius_m=r_r, rng=rng
    )
    tofs = range_oneway(sim.x, fs=sim.fs, max_range_m=max_range_m)
    out = np.full(3, np.nan)
    for t in tofs:
        out[t.channel] = t.distance_m
    return out


def simulate(
    trajectory: int,
    *,
    sigma_dd_m: float = 0.01,
    k_v_m: float = 4e-4,
    wheel_base_m: float = WHEEL_BASE_M,
    r_R_m: float = R_RECEIVER_M,
    odo_rate_hz: float = 100.0,
    fire_rate_hz: float = 5.0,
    audible_radius_m: float = 4.0,
    distance_source: str = "model",
    snr_db: float = 20.0,
    t_max_s: float | None = None,
    scale_error: float = 0.0,
    nlos_prob: float = 0.0,
    nlos_mean_m: float = 0.15,
    rng=None,
) -> KimRun:
    """Simulate one of Kim & Kim 2013's §V runs (see the module notes for every choice).

    Parameters
    ----------
    trajectory : {1, 2, 3, 4}
        :data:`TRAJECTORIES`; sets the layout and the nominal speed.
    sigma_dd_m : float
        Distance noise 1-sigma σ_dd (§V, eq (27): 0.01 m), >= 0; model distances only.
    k_v_m : float
        Odometry noise coefficient k_v: var = k_v |v| / ΔT_s per wheel (§V: 4e-4 m), >= 0.
    wheel_base_m : float
        B_w of eq (14) (P3-DX: 0.33 m assumed).
    r_R_m : float
        Receiver radius r_R of eq (1) (§V: 0.19 m).
    odo_rate_hz : float
        Odometry rate 1 / ΔT_s (§V: 100 Hz).
    fire_rate_hz : float
        Tx activation rate (§V: 5 Hz); ``odo_rate_hz / fire_rate_hz`` must be an integer.
    audible_radius_m : float
        Horizontal distance within which a Tx is heard (and so activated).
    distance_source : {"model", "audio"}
        ``"model"``: geometry + N(0, σ_dd²). ``"audio"``: render and range each firing
        (slow: about 0.1 s per firing).
    snr_db : float
        In-band SNR of the rendered firings (``"audio"`` only).
    t_max_s : float, optional
        Keep only the run up to this time (a slice of the trajectory); None: the whole run,
        until the robot is at rest at its last waypoint.
    scale_error : float
        Model mismatch (not in the paper; model distances only): every distance reads
        ``(1 + scale_error)`` times the true one (a speed of sound taken at the wrong
        temperature: 0.18 % per °C), within [-0.5, 0.5]. Default 0 (unbiased).
    nlos_prob : float
        Model mismatch (model distances only): the probability, in [0, 1], that a
        distance comes from a reflected path, longer by an exponential excess of mean
        ``nlos_mean_m`` (skewed, heavy-tailed errors). Default 0 (line of sight only).
    nlos_mean_m : float
        Mean excess of a reflected path (m), > 0. Default 0.15 m.
    rng : seed or Generator
        Anything :func:`numpy.random.default_rng` accepts.

    Returns
    -------
    KimRun

    Raises
    ------
    InvalidParameterError
        Unknown trajectory or distance source, a negative sigma or k_v, a non-positive
        wheel base, receiver radius, rate, hearing radius, ``t_max_s`` or ``nlos_mean_m``,
        ``scale_error`` or ``nlos_prob`` out of range, or rates whose ratio is not an
        integer.

    Examples
    --------
    >>> run = simulate(4, sigma_dd_m=0.0, k_v_m=0.0, rng=0)
    >>> bool(np.array_equal(run.v_right, run.v_right_true))
    True
    >>> round(float(np.max((run.v_right_true + run.v_left_true) / 2)), 6)
    1.02
    """
    if isinstance(trajectory, bool) or trajectory not in TRAJECTORIES:
        raise InvalidParameterError(
            f"trajectory={trajectory!r} must be one of {sorted(TRAJECTORIES)}"
        )
    if distance_source not in ("model", "audio"):
        raise InvalidParameterError(
            f"distance_source={distance_source!r} must be 'model' or 'audio'"
        )
    params = {
        "trajectory": int(trajectory),
        "sigma_dd_m": _validate.positive("sigma_dd_m", sigma_dd_m, allow_zero=True),
        "k_v_m": _validate.positive("k_v_m", k_v_m, allow_zero=True),
        "wheel_base_m": _validate.positive("wheel_base_m", wheel_base_m),
        "r_R_m": _validate.positive("r_R_m", r_R_m),
        "odo_rate_hz": _validate.positive("odo_rate_hz", odo_rate_hz),
        "fire_rate_hz": _validate.positive("fire_rate_hz", fire_rate_hz),
        "audible_radius_m": _validate.positive("audible_radius_m", audible_radius_m),
        "distance_source": distance_source,
        "snr_db": _validate.in_range("snr_db", snr_db, -60.0, 200.0),
        "t_max_s": None if t_max_s is None else _validate.positive("t_max_s", t_max_s),
        "scale_error": _validate.in_range("scale_error", scale_error, -0.5, 0.5),
        "nlos_prob": _validate.in_range("nlos_prob", nlos_prob, 0.0, 1.0),
        "nlos_mean_m": _validate.positive("nlos_mean_m", nlos_mean_m),
    }
    ratio = params["odo_rate_hz"] / params["fire_rate_hz"]
    every = round(ratio)
    if every < 1 or abs(ratio - every) > 1e-9 * ratio:
        raise InvalidParameterError(
            f"odo_rate_hz / fire_rate_hz = {ratio:g} must be an integer >= 1 "
            "(firings happen on odometry instants)"
        )
    rng = np.random.default_rng(rng)
    tr = TRAJECTORIES[trajectory]
    beacons = layout(tr.layout)
    dt = 1.0 / params["odo_rate_hz"]
    vr_t, vl_t, poses = (a.copy() for a in _truth(int(trajectory), dt, params["wheel_base_m"]))
    n = len(poses)
    if params["t_max_s"] is not None:
        n = min(n, int(math.floor(params["t_max_s"] / dt + 1e-9)) + 1)
        vr_t, vl_t, poses = vr_t[:n], vl_t[:n], poses[:n]
    t = np.arange(n) * dt

    # Odometry (§V): var = k_v |v| / ΔT_s per wheel, independent.
    e = rng.standard_normal((n, 2))
    k_v = params["k_v_m"]
    vr = vr_t + np.sqrt(k_v * np.abs(vr_t) / dt) * e[:, 0]
    vl = vl_t + np.sqrt(k_v * np.abs(vl_t) / dt) * e[:, 1]

    # Ultrasonic firings: round robin over the audible Txs, one row per firing.
    ks, txs = _fire_schedule(poses[:, :2], beacons, params["audible_radius_m"], every)
    r_r = params["r_R_m"]
    d_true = np.empty((ks.size, 3))
    for j, (k, tx) in enumerate(zip(ks, txs, strict=True)):
        rx = receiver_positions(poses[k], radius_m=r_r)
        d_true[j] = np.linalg.norm(rx - beacons.position(int(tx)), axis=1)
    if distance_source == "model":
        d_meas = d_true + params["sigma_dd_m"] * rng.standard_normal(d_true.shape)
        if params["scale_error"] != 0.0 or params["nlos_prob"] > 0.0:
            # drawn after the paper's noise, so the paper-settings runs are unchanged
            nlos = rng.random(d_true.shape) < params["nlos_prob"]
            excess = rng.exponential(params["nlos_mean_m"], d_true.shape)
            d_meas = d_meas + params["scale_error"] * d_true + np.where(nlos, excess, 0.0)
        d_meas = np.maximum(d_meas, 0.0)
    else:
        z_max = float(np.max(beacons.xyz_m[:, 2]))
        max_range = math.hypot(params["audible_radius_m"], z_max) + r_r + 0.5
        d_meas = np.array(
            [
                _audio_distances(
                    beacons.position(int(tx)),
                    poses[k],
                    r_r=r_r,
                    snr_db=params["snr_db"],
                    max_range_m=max_range,
                    rng=rng,
                )
                for k, tx in zip(ks, txs, strict=True)
            ]
        ).reshape(-1, 3)

    return KimRun(
        trajectory=int(trajectory),
        layout=tr.layout,
        nominal_speed_mps=tr.speed_mps,
        t_s=t,
        true_pose=poses,
        v_right=vr,
        v_left=vl,
        v_right_true=vr_t,
        v_left_true=vl_t,
        distance_t_s=t[ks],
        distance_k=ks,
        distance_tx=txs,
        distance_m=d_meas,
        distance_true_m=d_true,
        beacons=beacons,
        waypoints_m=tr.waypoints_m.copy(),
        params=params,
    )
