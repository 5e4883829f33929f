"""Scenario simulator of Jiang 2018 §5: two walking persons, a following robot, a measurement log.

Jiang 2018 §5.3 tracks two persons walking along waypoints marked on the floor: the robot
follows Target 1 (seen by its Kinect) while acoustic ranging measures the distances robot to
Target 2 (``d_r2``) and Target 1 to Target 2 (``d_12``) about every 3 s (§4.3.3, §5.3.1).
:func:`simulate` re-creates those runs with known truth and writes what the robot would log
(:class:`rangekit.io.tracklog.MeasurementLog`): its self-localised pose (§4.1, §5.2.2), the
relative fix of Target 1 (§4.2) and the two ranges (§4.4.2, Eq. 4).

Environments (coordinates are this module's design; the paper gives sizes, not coordinates):

* ``"lab"`` -- the lab/office floor of §5.1 (Fig. 5a), 69 x 33 ft = 21.0 x 10.1 m: a
  laboratory (x 0-8 m), a 1.8 m wide corridor (x 8-13 m, y 4.15-5.95 m) and an office
  (x 13-21 m), see :func:`environment`. Both persons walk from the laboratory through the
  corridor into the office on 19 waypoints each (§5.3.1), side by side in the corridor
  (lanes y = 4.7 m and 5.4 m). Robot to Target 2 stays within 1.4-4.6 m (§5.3.2: up to 4 m).
* ``"atrium"`` -- the Babbio atrium of §5.1 (Fig. 5b), about 400 m^2, modelled as an open
  20 x 20 m square, 12 waypoints each (§5.3.2). Both walk an S-shaped route (east, a
  U-turn left, west, a U-turn right, east) of about equal length, Target 2 drifting about
  2-5.6 m to the side of Target 1, so that robot to Target 2 spans 2.0-6.5 m (§5.3.2).

Examples
--------
>>> run = simulate("lab", rng=0)
>>> run.targets_m.shape[1:], run.log.n_targets, run.update_t_s[:3].tolist()
((2, 2), 2, [0.0, 3.0, 6.0])
>>> run.log.ranges.a[:2].tolist(), run.log.ranges.b[:2].tolist()
([0, 1], [2, 2])
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rangekit import _validate
from rangekit.errors import InvalidParameterError
from rangekit.io.tracklog import FixRows, MeasurementLog, RangeRows, RobotRows

__all__ = [
    "SCENARIOS",
    "Environment",
    "JiangRun",
    "Room",
    "atrium_paths",
    "environment",
    "lab_office_paths",
    "paper_settings",
    "simulate",
    "trail",
    "walk",
]

#: Scenario names :func:`simulate` knows.
SCENARIOS = ("lab", "atrium")

#: Excess path length of a non-line-of-sight range, metres (Jiang 2018 §5.4.3).
NLOS_EXCESS_M = (0.5, 5.0)

#: How far each extra target (id >= 3) trails the one before it on Target 2's path, metres.
EXTRA_TARGET_GAP_M = 0.8


@dataclass(frozen=True)
class Room:
    """An axis-aligned rectangle of floor: ``lo_m`` = (x_min, y_min), ``hi_m`` = (x_max, y_max)."""

    name: str
    lo_m: tuple[float, float]
    hi_m: tuple[float, float]


@dataclass(frozen=True)
class Environment:
    """Walkable floor of a scenario: the union of its rooms (metres, world frame).

    Attributes
    ----------
    name : str
    size_m : tuple of float
        Bounding box (width x, depth y) with its corner at the origin.
    rooms : tuple of Room
    """

    name: str
    size_m: tuple[float, float]
    rooms: tuple[Room, ...]

    def contains(self, xy_m: np.ndarray, *, margin_m: float = 0.0) -> np.ndarray:
        """Whether points (..., 2) are on the floor, at least ``margin_m`` from every wall.

        A point counts as clear of the walls when it and its eight neighbours at
        ``margin_m`` (axis and diagonal directions) all lie in some room, so a point in a
        doorway between two rooms is not penalised for the rooms' shared edge.
        """
        p = np.asarray(xy_m, dtype=np.float64)
        m = _validate.positive("margin_m", margin_m, allow_zero=True)
        c = m / math.sqrt(2.0)
        offs = [(0.0, 0.0), (m, 0.0), (-m, 0.0), (0.0, m), (0.0, -m)]
        offs += [(c, c), (c, -c), (-c, c), (-c, -c)]
        ok = np.ones(p.shape[:-1], dtype=bool)
        for dx, dy in offs:
            q = p + np.array([dx, dy])
            inside = np.zeros(p.shape[:-1], dtype=bool)
            for r in self.rooms:
                inside |= (
                    (q[..., 0] >= r.lo_m[0])
                    & (q[..., 0] <= r.hi_m[0])
                    & (q[..., 1] >= r.lo_m[1])
                    & (q[..., 1] <= r.hi_m[1])
                )
            ok &= inside
        return ok


def environment(scenario: str) -> Environment:
    """The floor of a Jiang 2018 §5.1 scenario (``"lab"`` or ``"atrium"``).

    ``"lab"``: 69 x 33 ft = 21.0 x 10.1 m; laboratory x 0-8 m, corridor x 8-13 m by
    y 4.15-5.95 m (1.8 m wide, centred), office x 13-21 m (Jiang 2018 §5.1, Fig. 5a).
    ``"atrium"``: an open 20 x 20 m square (about 400 m^2; Jiang 2018 §5.1, Fig. 5b).

    Examples
    --------
    >>> env = environment("lab")
    >>> [r.name for r in env.rooms], env.size_m
    (['laboratory', 'corridor', 'office'], (21.0, 10.1))
    >>> env.contains(np.array([[10.0, 5.0], [10.0, 8.0]])).tolist()
    [True, False]
    """
    _check_scenario(scenario)
    if scenario == "lab":
        w, h = 21.0, 10.1
        return Environment(
            "lab",
            (w, h),
            (
                Room("laboratory", (0.0, 0.0), (8.0, h)),
                Room("corridor", (8.0, 4.15), (13.0, 5.95)),
                Room("office", (13.0, 0.0), (w, h)),
            ),
        )
    return Environment("atrium", (20.0, 20.0), (Room("atrium", (0.0, 0.0), (20.0, 20.0)),))


def lab_office_paths() -> tuple[np.ndarray, np.ndarray]:
    """Waypoints (19, 2) in metres of Target 1 and Target 2 on the lab/office floor.

    Both persons start in the laboratory (Target 1 in the lower half, Target 2 about 2 m to
    its left), walk to the corridor door, through the corridor side by side (Target 1 on
    the lane y = 4.7 m, Target 2 on y = 5.4 m, 0.55 m from the walls) and into the office,
    where Target 1 bears right and Target 2 left between the cubicles, about 3 m apart,
    to the far wall (Jiang 2018 §5.3.1: 19 waypoints, laboratory to office through the
    corridor). Both paths are 21.0 m long and reach the corridor doors at the same arc
    length, so the persons walk side by side. Layout in :func:`environment`.

    Examples
    --------
    >>> p1, p2 = lab_office_paths()
    >>> p1.shape, p2.shape
    ((19, 2), (19, 2))
    """
    p1 = np.array(
        [
            [2.2, 2.5],
            [2.9, 2.3],
            [4.3, 2.3],
            [5.6, 2.7],
            [6.6, 3.4],
            [7.3, 4.2],
            [8.0, 4.7],  # corridor door (laboratory side)
            [9.7, 4.7],
            [11.3, 4.7],
            [13.0, 4.7],  # corridor door (office side)
            [14.0, 4.3],
            [15.1, 3.9],
            [16.2, 3.6],
            [17.3, 3.4],
            [18.4, 3.4],
            [19.4, 3.6],
            [19.9, 4.2],
            [20.0, 5.1],
            [19.8, 6.1],
        ]
    )
    p2 = np.array(
        [
            [1.65, 4.5],
            [2.3, 4.8],
            [3.6, 5.3],
            [4.9, 5.7],
            [6.2, 5.8],
            [7.2, 5.6],
            [8.0, 5.4],  # corridor door (laboratory side)
            [9.7, 5.4],
            [11.3, 5.4],
            [13.0, 5.4],  # corridor door (office side)
            [14.0, 5.8],
            [15.1, 6.1],
            [16.2, 6.3],
            [17.3, 6.4],
            [18.4, 6.5],
            [19.3, 6.9],
            [19.6, 7.8],
            [19.0, 8.5],
            [18.1, 8.8],
        ]
    )
    return p1, p2


def atrium_paths() -> tuple[np.ndarray, np.ndarray]:
    """Waypoints (12, 2) in metres of Target 1 and Target 2 in the 20 x 20 m atrium.

    Target 1 (followed by the robot) walks an S: east along the bottom, a left U-turn,
    west through the middle, a right U-turn, east along the top. Target 2 starts 2 m
    ahead of it and walks a route of about the same length (46.7 m vs 48.1 m) that drifts up
    to about 5.6 m to its side through the first U-turn and comes back, so that robot to
    Target 2 grows from 2 m to about 6.5 m and back (Jiang 2018 §5.3.2: 12 waypoints,
    robot to target up to 6.5 m).

    Examples
    --------
    >>> p1, p2 = atrium_paths()
    >>> p1.shape, p2.shape
    ((12, 2), (12, 2))
    """
    p1 = np.array(
        [
            [2.5, 3.0],
            [7.0, 2.5],
            [12.0, 2.5],
            [16.0, 3.5],
            [17.5, 7.0],
            [15.0, 9.5],
            [10.0, 10.0],
            [5.5, 10.5],
            [3.0, 12.5],
            [4.5, 15.5],
            [9.0, 16.3],
            [14.0, 16.3],
        ]
    )
    p2 = np.array(
        [
            [4.5, 3.2],
            [8.9, 4.3],
            [13.7, 5.5],
            [16.8, 8.1],
            [13.5, 9.9],
            [10.1, 9.2],
            [6.2, 6.1],
            [1.9, 6.6],
            [1.0, 10.0],
            [2.0, 13.6],
            [6.5, 18.0],
            [11.0, 18.4],
        ]
    )
    return p1, p2


def paper_settings(case: str) -> dict:
    """Keyword arguments of :func:`simulate` for a run of Jiang 2018 §5.2-5.3.

    ``"lab_moderate"`` (evening, sigma_d 0.10 m), ``"lab_heavy"`` (daytime, 0.15 m), both
    with robot sigma 0.06 m (§5.2.1-5.2.2); ``"atrium"`` (sigma_d 0.25 m, robot 0.10 m).
    ``"lab_mismatch"`` is not the paper's: the moderate lab with ranges drawn from
    another law than the filter's (+0.10 m bias, skewed scatter of 0.10 m, 5 % outliers
    up to +0.7 m, as real acoustic and UWB ranges; issue 18). A fresh dict on every call.

    Examples
    --------
    >>> paper_settings("atrium")
    {'scenario': 'atrium', 'sigma_d_m': 0.25, 'robot_sigma_m': 0.1}
    """
    table = {
        "lab_moderate": {"scenario": "lab", "sigma_d_m": 0.10, "robot_sigma_m": 0.06},
        "lab_heavy": {"scenario": "lab", "sigma_d_m": 0.15, "robot_sigma_m": 0.06},
        "atrium": {"scenario": "atrium", "sigma_d_m": 0.25, "robot_sigma_m": 0.10},
        "lab_mismatch": {"scenario": "lab", "sigma_d_m": 0.10, "robot_sigma_m": 0.06,
                         "range_bias_m": 0.10, "skew_shape": 4.0, "outlier_prob": 0.05,
                         "outlier_max_m": 0.7},
    }  # fmt: skip
    if case not in table:
        raise InvalidParameterError(f"case={case!r} must be one of {', '.join(table)}")
    return dict(table[case])


def _check_scenario(scenario: str) -> None:
    if scenario not in SCENARIOS:
        raise InvalidParameterError(
            f"scenario={scenario!r} must be one of {', '.join(repr(s) for s in SCENARIOS)}"
        )


def _polyline(waypoints) -> tuple[np.ndarray, np.ndarray]:
    """Waypoints without zero-length segments, and their cumulative arc length."""
    wp = np.asarray(waypoints, dtype=np.float64)
    if wp.ndim != 2 or wp.shape[1] != 2 or wp.shape[0] < 1:
        raise InvalidParameterError(f"waypoints must have shape (k >= 1, 2), got {wp.shape}")
    if not np.all(np.isfinite(wp)):
        raise InvalidParameterError("waypoints contain NaN or infinite values")
    seg = np.hypot(*np.diff(wp, axis=0).T)
    keep = np.concatenate([[True], seg > 0])
    wp = wp[keep]
    return wp, np.concatenate([[0.0], np.cumsum(seg[seg > 0])])


def _at_arc(wp: np.ndarray, cum: np.ndarray, s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, cum[-1])
    if wp.shape[0] == 1:
        return np.broadcast_to(wp[0], (*np.shape(s), 2)).copy()
    return np.stack([np.interp(s, cum, wp[:, 0]), np.interp(s, cum, wp[:, 1])], axis=-1)


def walk(waypoints, speed_mps: float, t_s) -> np.ndarray:
    """Positions (..., 2) in metres at times ``t_s`` walking a polyline at constant speed.

    The walker is at ``waypoints[0]`` for t <= 0, moves along the segments at
    ``speed_mps`` and stops at the last waypoint (Jiang 2018 §5.3.1: persons walk the
    marked waypoints at an average 0.4 m/s, §5.4.2: or 0.8 m/s).

    Parameters
    ----------
    waypoints : array_like, shape (k, 2)
    speed_mps : float
        Walking speed, > 0.
    t_s : float or array_like
        Times from the start of the walk.

    Examples
    --------
    >>> walk([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]], 1.0, [0.5, 3.0, 9.0]).tolist()
    [[0.5, 0.0], [2.0, 1.0], [2.0, 2.0]]
    """
    v = _validate.positive("speed_mps", speed_mps)
    wp, cum = _polyline(waypoints)
    t = np.asarray(t_s, dtype=np.float64)
    return _at_arc(wp, cum, v * t)


def _trail_one(wp: np.ndarray, cum: np.ndarray, s_lead: float, gap: float) -> np.ndarray:
    """Point on the path behind arc ``s_lead`` at straight-line distance ``gap`` from it."""
    p = _at_arc(wp, cum, np.float64(s_lead))
    k = int(np.clip(np.searchsorted(cum, s_lead, side="right") - 1, 0, wp.shape[0] - 2))
    for j in range(k, -1, -1):
        a, b = wp[j], (p if j == k else wp[j + 1])
        d0, e = b - p, a - b
        aa = float(e @ e)
        if aa == 0.0:
            continue
        bb, cc = float(d0 @ e), float(d0 @ d0) - gap * gap
        u = (-bb + math.sqrt(max(bb * bb - aa * cc, 0.0))) / aa
        if u <= 1.0:
            return b + u * e
    # Behind the start: on the first segment's line, extended backwards.
    back = wp[0] - wp[1]
    back = back / math.hypot(*back)
    d0 = wp[0] - p
    bb, cc = float(d0 @ back), float(d0 @ d0) - gap * gap
    return wp[0] + (-bb + math.sqrt(max(bb * bb - cc, 0.0))) * back


def trail(waypoints, speed_mps: float, t_s, gap_m: float) -> np.ndarray:
    """Positions (..., 2) of a follower on a walker's path, ``gap_m`` behind it in a straight line.

    The walker moves as in :func:`walk`; the follower is at the point of the walker's path
    behind the walker (the first one met walking the path backwards) whose straight-line
    distance to the walker is exactly ``gap_m``. Before the walker has covered ``gap_m``,
    that point lies on the first segment extended backwards. This is the robot of Jiang
    2018 §4.2 keeping a given distance to Target 1 while following it.

    Examples
    --------
    >>> trail([[0.0, 0.0], [4.0, 0.0]], 1.0, [0.0, 3.0], 1.2).round(6).tolist()
    [[-1.2, 0.0], [1.8, 0.0]]
    """
    v = _validate.positive("speed_mps", speed_mps)
    g = _validate.positive("gap_m", gap_m)
    wp, cum = _polyline(waypoints)
    if wp.shape[0] < 2:
        raise InvalidParameterError("waypoints must span at least one segment to trail along")
    t = np.asarray(t_s, dtype=np.float64)
    s = np.clip(v * t, 0.0, cum[-1]).reshape(-1)
    out = np.array([_trail_one(wp, cum, si, g) for si in s]).reshape(*t.shape, 2)
    return out


@dataclass(frozen=True, eq=False)
class JiangRun:
    """A simulated Jiang 2018 §5 run: ground truth and the robot's measurement log.

    Attributes
    ----------
    scenario : str
        ``"lab"`` or ``"atrium"``.
    t_s : ndarray, shape (n_t,)
        Truth times, from 0 at ``truth_rate_hz``, until the last walker stops.
    targets_m : ndarray, shape (n_t, N, 2)
        True target positions; index 0 is Target 1 (followed), 1 is Target 2, ...
    robot_m : ndarray, shape (n_t, 2)
        True robot position.
    robot_heading_rad : ndarray, shape (n_t,)
        True robot heading (world frame, counter-clockwise from +x), towards Target 1.
    update_t_s : ndarray, shape (n_u,)
        Ranging times: 0, ``update_interval_s``, ...
    update_targets_m, update_robot_m, update_heading_rad : ndarray
        The same truth at the ranging times, shapes (n_u, N, 2), (n_u, 2), (n_u,).
    log : MeasurementLog
        What the robot records (rows per ranging time: robot, fix of Target 1, ranges).
    range_truth_m : ndarray, shape (n_r,)
        True distance of each row of ``log.ranges``.
    nlos : ndarray of bool, shape (n_r,)
        Which range rows are non-line-of-sight (too long by U(0.5, 5) m).
    waypoints_m : tuple of ndarray
        The paths walked by Target 1 and Target 2.
    params : dict
        Every parameter of :func:`simulate` (except ``rng``).
    """

    scenario: str
    t_s: np.ndarray
    targets_m: np.ndarray
    robot_m: np.ndarray
    robot_heading_rad: np.ndarray
    update_t_s: np.ndarray
    update_targets_m: np.ndarray
    update_robot_m: np.ndarray
    update_heading_rad: np.ndarray
    log: MeasurementLog
    range_truth_m: np.ndarray
    nlos: np.ndarray
    waypoints_m: tuple[np.ndarray, ...]
    params: dict


def _truth(paths, speed: float, follow_m: float, n_targets: int, t: np.ndarray):
    """Targets (n, N, 2), robot (n, 2) and robot heading (n,) at times t."""
    p1, p2 = paths
    cols = [walk(p1, speed, t), walk(p2, speed, t)]
    for j in range(3, n_targets + 1):
        cols.append(trail(p2, speed, t, (j - 2) * EXTRA_TARGET_GAP_M))
    targets = np.stack(cols, axis=1)
    robot = trail(p1, speed, t, follow_m)
    d = targets[:, 0] - robot
    return targets, robot, np.arctan2(d[:, 1], d[:, 0])


def simulate(
    scenario: str = "lab",
    *,
    speed_mps: float = 0.4,
    sigma_d_m: float = 0.10,
    robot_sigma_m: float = 0.06,
    fix_sigma_m: float = 0.10,
    heading_sigma_rad: float = 0.0,
    update_interval_s: float = 3.0,
    truth_rate_hz: float = 10.0,
    follow_m: float = 1.2,
    nlos: float | None = None,
    fail_prob: float = 0.0,
    n_targets: int = 2,
    range_bias_m: float = 0.0,
    skew_shape: float | None = None,
    outlier_prob: float = 0.0,
    outlier_max_m: float = 0.7,
    rng=None,
) -> JiangRun:
    """Simulate a Jiang 2018 §5.3 tracking run and the robot's measurement log.

    Both persons start walking their waypoints (:func:`lab_office_paths`,
    :func:`atrium_paths`) at t = 0 at ``speed_mps``; the robot trails Target 1 along its
    path at a straight-line distance ``follow_m``, facing it (:func:`trail`). At every
    ranging time t_k = k ``update_interval_s`` (the first at t = 0, §5.3.1) the log gets

    * a robot row: true position + N(0, robot_sigma^2 I), drawn independently per update
      (§5.2.2, Fig. 8: uncorrelated in time), covariance P_r = robot_sigma^2 I; heading =
      true heading + N(0, heading_sigma^2);
    * a fix row for Target 1: its true position relative to the robot in the robot's true
      frame (x forward, y left) + N(0, fix_sigma^2 I), covariance R_t1 = fix_sigma^2 I
      (Eq. 4c);
    * for every target j >= 2, a range row 0 -> j (true robot to target distance,
      Eq. 1a/4a) and a range row 1 -> j (Target 1 to target j, Eq. 1b/4b), each + N(0,
      sigma_d^2) with ``sigma_m`` = sigma_d (with ``skew_shape``: a standardised gamma
      of that shape instead, mean 0, 1-sigma sigma_d, skewness 2/sqrt(shape), plus
      ``range_bias_m``, plus with probability ``outlier_prob`` a U(0, ``outlier_max_m``)
      excess: the filter's Gaussian law is then not the simulator's). A range is NLOS
      with probability ``nlos`` (independently per range) and then too long by U(0.5, 5)
      m (§5.4.3); it fails (NaN) with probability ``fail_prob``. Ranges are clipped at 0
      (they are distances).

    Parameters
    ----------
    scenario : {"lab", "atrium"}
    speed_mps : float
        Walking speed (§5.4.2: 0.4 or 0.8 m/s).
    sigma_d_m : float
        Ranging noise 1-sigma (§5.2.1: 0.10 m lab moderate, 0.15 m lab heavy, 0.25 m atrium).
    robot_sigma_m : float
        Robot self-localisation 1-sigma per axis (§5.2.2: 0.06 m lab, 0.10 m atrium).
    fix_sigma_m : float
        Kinect fix 1-sigma per axis.
    heading_sigma_rad : float
        Error of the logged robot heading, >= 0 (0: the heading is exact).
    update_interval_s : float
        Time between rangings (§5.3.1: about 3 s, 5-6 iterations in 15-18 s).
    truth_rate_hz : float
        Rate of the ground-truth samples ``t_s``.
    follow_m : float
        Robot to Target 1 distance kept while following.
    nlos : float or None
        Probability that a range is NLOS (None or 0: never).
    fail_prob : float
        Probability that a ranging fails (range logged as NaN).
    range_bias_m : float
        Added to every range (|bias| <= 1 m; the log's sigma_m does not include it).
    skew_shape : float or None
        Shape (> 0) of the standardised gamma the range noise is drawn from (None:
        Gaussian, the filter's own law).
    outlier_prob, outlier_max_m : float
        Probability of a positive outlier per range and its largest excess (m).
    n_targets : int
        Number of persons, >= 2 (2 is the paper's setup). Target j >= 3 walks Target 2's
        path, trailing Target 2 by (j - 2) ``EXTRA_TARGET_GAP_M`` in a straight line
        (:func:`trail`; before the start, on the first segment extended backwards, which
        keeps them on the floor for n_targets <= 3 in the lab, <= 5 in the atrium). The
        truth of Targets 1 and 2 and the robot does not depend on ``n_targets``.
    rng : seed or Generator
        Anything :func:`numpy.random.default_rng` accepts.

    Returns
    -------
    JiangRun

    Raises
    ------
    InvalidParameterError
        Unknown scenario, a non-positive sigma, speed, interval, rate or follow distance,
        a negative heading sigma, a probability outside [0, 1], ``n_targets`` < 2.

    Examples
    --------
    >>> run = simulate(**paper_settings("atrium"), rng=1)
    >>> run.params["sigma_d_m"], float(run.log.ranges.sigma_m[0])
    (0.25, 0.25)
    >>> float(np.hypot(*(run.targets_m[-1, 0] - run.robot_m[-1])).round(9))
    1.2
    """
    _check_scenario(scenario)
    params = {
        "scenario": scenario,
        "speed_mps": _validate.positive("speed_mps", speed_mps),
        "sigma_d_m": _validate.positive("sigma_d_m", sigma_d_m),
        "robot_sigma_m": _validate.positive("robot_sigma_m", robot_sigma_m),
        "fix_sigma_m": _validate.positive("fix_sigma_m", fix_sigma_m),
        "heading_sigma_rad": _validate.positive(
            "heading_sigma_rad", heading_sigma_rad, allow_zero=True
        ),
        "update_interval_s": _validate.positive("update_interval_s", update_interval_s),
        "truth_rate_hz": _validate.positive("truth_rate_hz", truth_rate_hz),
        "follow_m": _validate.positive("follow_m", follow_m),
        "nlos": None if nlos is None else _validate.in_range("nlos", nlos, 0.0, 1.0),
        "fail_prob": _validate.in_range("fail_prob", fail_prob, 0.0, 1.0),
        "n_targets": _validate.positive_int("n_targets", n_targets, minimum=2),
        "range_bias_m": _validate.in_range("range_bias_m", range_bias_m, -1.0, 1.0),
        "skew_shape": None if skew_shape is None else _validate.positive("skew_shape", skew_shape),
        "outlier_prob": _validate.in_range("outlier_prob", outlier_prob, 0.0, 1.0),
        "outlier_max_m": _validate.positive("outlier_max_m", outlier_max_m),
    }
    rng = np.random.default_rng(rng)
    speed, n_tg = params["speed_mps"], params["n_targets"]
    paths = lab_office_paths() if scenario == "lab" else atrium_paths()
    length = max(float(np.sum(np.hypot(*np.diff(p, axis=0).T))) for p in paths)
    t_end = length / speed
    t = np.arange(math.floor(t_end * params["truth_rate_hz"] + 1e-9) + 1)
    t = t / params["truth_rate_hz"]
    tu = np.arange(math.floor(t_end / params["update_interval_s"] + 1e-9) + 1)
    tu = tu * params["update_interval_s"]
    follow = params["follow_m"]
    targets, robot, heading = _truth(paths, speed, follow, n_tg, t)
    utargets, urobot, uheading = _truth(paths, speed, follow, n_tg, tu)
    n_u = tu.size

    # Robot rows: estimated pose (Jiang 2018 §5.2.2), independent per update.
    rs, hs = params["robot_sigma_m"], params["heading_sigma_rad"]
    robot_est = urobot + rs * rng.standard_normal((n_u, 2))
    heading_est = uheading + hs * rng.standard_normal(n_u)
    robot_rows = RobotRows(
        tu.copy(), robot_est, heading_est, np.broadcast_to(rs * rs * np.eye(2), (n_u, 2, 2)).copy()
    )

    # Fix rows: Target 1 in the robot's true frame (x forward, y left), Eq. 4c.
    d = utargets[:, 0] - urobot
    c, s = np.cos(uheading), np.sin(uheading)
    rel = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
    fs = params["fix_sigma_m"]
    rel = rel + fs * rng.standard_normal((n_u, 2))
    fix_rows = FixRows(
        tu.copy(),
        np.ones(n_u, dtype=np.int64),
        rel,
        np.broadcast_to(fs * fs * np.eye(2), (n_u, 2, 2)).copy(),
    )

    # Range rows, per update: (0, 2), (1, 2), (0, 3), (1, 3), ... (Eq. 1, 4a-b).
    pairs = [(a, b) for b in range(2, n_tg + 1) for a in (0, 1)]
    a_id = np.tile([a for a, _ in pairs], n_u)
    b_id = np.tile([b for _, b in pairs], n_u)
    rt = np.repeat(tu, len(pairs))
    ui = np.repeat(np.arange(n_u), len(pairs))
    pos_a = np.where((a_id == 0)[:, None], urobot[ui], utargets[ui, 0])
    truth_r = np.hypot(*(utargets[ui, b_id - 1] - pos_a).T)
    sd = params["sigma_d_m"]
    n_r = truth_r.size
    k = params["skew_shape"]
    if k is None:
        meas = truth_r + sd * rng.standard_normal(n_r)
    else:
        meas = truth_r + sd * (rng.gamma(k, 1.0, n_r) - k) / math.sqrt(k)
    meas = meas + params["range_bias_m"]
    if params["outlier_prob"] > 0:  # (no draw otherwise: the paper runs keep their stream)
        outlier = rng.random(n_r) < params["outlier_prob"]
        meas = meas + np.where(outlier, rng.uniform(0.0, params["outlier_max_m"], n_r), 0.0)
    p_nlos = params["nlos"] or 0.0
    is_nlos = rng.random(n_r) < p_nlos
    excess = rng.uniform(*NLOS_EXCESS_M, size=n_r)
    meas = np.where(is_nlos, meas + excess, meas)
    meas = np.maximum(meas, 0.0)
    failed = rng.random(n_r) < params["fail_prob"]
    meas = np.where(failed, np.nan, meas)
    range_rows = RangeRows(rt, a_id.astype(np.int64), b_id.astype(np.int64), meas, np.full(n_r, sd))

    log = MeasurementLog(robot_rows, fix_rows, range_rows, n_tg)
    return JiangRun(
        scenario=scenario,
        t_s=t,
        targets_m=targets,
        robot_m=robot,
        robot_heading_rad=heading,
        update_t_s=tu,
        update_targets_m=utargets,
        update_robot_m=urobot,
        update_heading_rad=uheading,
        log=log,
        range_truth_m=truth_r,
        nlos=is_nlos,
        waypoints_m=paths,
        params=params,
    )
