"""Simulator of Girard et al. 2011's test (§3.4, Fig. 9): a walk on floor markers.

The paper's test area is a 2 m wide corridor connected with three rooms of about
3 m x 5 m (OTB building, TU Delft); the walker steps on floor markers from position 1
through 2, 3, ... back to the start (10), twice, 52 steps in all; the IMU reports a fixed
step length of 1.25 m (the true steps differ by up to 25 cm) and a compass heading that is
noisy and drifts (Fig. 10); two SRF02s back to back on the laptop held in front of the body
range to the left and right walls, fired one after the other (§2.6.5).

The paper gives sizes, not coordinates. This module's layout (:func:`test_area`):

* corridor ``0 <= x <= 9``, ``0 <= y <= 2`` (2 m wide, closed at both ends);
* rooms A, B, C north of it, ``y`` from 2 to 7 (5 m deep) and ``x`` 0-3, 3-6, 6-9 (3 m
  wide); a 0.9 m door from the corridor into each room, centred at x = 1.25, 5.0 and 7.5.

The path (:data:`WAYPOINTS_M`, 10 positions, the last the start again): start in the
corridor in front of room A, 3 steps into A and 3 back, 5 steps east to room C, 3 in and 3
back, 2 steps west to room B, 2 in and 2 back, 3 steps west to the start: 26 steps of
1.25 m per lap. Every step ends on a marker; markers are laid with an error (``marker_jitter_m``
along the path, a quarter of it across), so true steps differ from 1.25 m by up to
2 ``marker_jitter_m`` (default 0.12 m: up to 24 cm).

Examples
--------
>>> run = simulate(rng=0)
>>> len(run.steps), run.truth_m.shape, run.ranges.n_sensors
(52, (52, 2), 2)
>>> float(np.hypot(*(run.truth_m[-1] - run.start_m)))
0.0
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rangekit import _validate
from rangekit.errors import InvalidParameterError
from rangekit.floorplan import FloorPlan
from rangekit.io.steplog import RangeLog, StepLog
from rangekit.sensors import srf02
from rangekit.types import RngLike

__all__ = [
    "LEG_STEPS",
    "MOUNT_ANGLES_RAD",
    "STEP_LENGTH_M",
    "WAYPOINTS_M",
    "GirardRun",
    "markers",
    "simulate",
    "test_area",
]


#: The step length pre-set in the paper's system (§3.3), m.
STEP_LENGTH_M = 1.25
#: Numbered path positions 1..10 (Fig. 9), m; 10 is the start again.
WAYPOINTS_M = np.array(
    [
        [1.25, 1.0], [1.25, 4.75], [1.25, 1.0], [7.5, 1.0], [7.5, 4.75],
        [7.5, 1.0], [5.0, 1.0], [5.0, 3.5], [5.0, 1.0], [1.25, 1.0],
    ]
)  # fmt: skip
#: Steps on each leg between consecutive waypoints (26 per lap).
LEG_STEPS = (3, 3, 5, 3, 3, 2, 2, 2, 3)
#: Sensor axes relative to the walking direction: sensor 0 left, sensor 1 right (§2.6).
MOUNT_ANGLES_RAD = (0.5 * math.pi, -0.5 * math.pi)


def test_area() -> FloorPlan:
    """The corridor and three rooms (module docstring) as a :class:`FloorPlan`.

    Examples
    --------
    >>> plan = test_area()
    >>> len(plan.walls), plan.segments.shape[0], plan.bounds
    (7, 10, (0.0, 0.0, 9.0, 7.0))
    """
    doors = [{"at_m": c - 0.45, "width_m": 0.9} for c in (1.25, 5.0, 7.5)]
    return FloorPlan.from_walls(
        [
            {"from": [0, 0], "to": [9, 0]},
            {"from": [0, 2], "to": [9, 2], "doors": doors},
            {"from": [0, 0], "to": [0, 7]},
            {"from": [9, 0], "to": [9, 7]},
            {"from": [0, 7], "to": [9, 7]},
            {"from": [3, 2], "to": [3, 7]},
            {"from": [6, 2], "to": [6, 7]},
        ]
    )


test_area.__test__ = False  # not a pytest test despite its name


def markers(jitter_m: float = 0.12, *, rng: RngLike = None) -> np.ndarray:
    """Floor markers of one lap, ``(27, 2)`` m: the start and the end of each step.

    Each leg is split into :data:`LEG_STEPS` equal steps; every marker but the start
    (and its copy at the end) is displaced by ``U(-jitter, jitter)`` along the leg and
    ``U(-jitter/4, jitter/4)`` across it.

    Examples
    --------
    >>> m = markers(0.0)
    >>> m.shape, np.hypot(*np.diff(m, axis=0).T).round(6).min()
    ((27, 2), np.float64(1.25))
    """
    jit = _validate.positive("jitter_m", jitter_m, allow_zero=True)
    g = np.random.default_rng(rng)
    pts = [WAYPOINTS_M[0]]
    for i, n in enumerate(LEG_STEPS):
        a, b = WAYPOINTS_M[i], WAYPOINTS_M[i + 1]
        for j in range(1, n + 1):
            pts.append(a + (b - a) * j / n)
    out = np.array(pts)
    # along/across direction of the leg each marker ends
    legs = np.repeat(np.arange(len(LEG_STEPS)), LEG_STEPS)
    d = WAYPOINTS_M[legs + 1] - WAYPOINTS_M[legs]
    d = d / np.hypot(*d.T)[:, None]
    along = g.uniform(-jit, jit, legs.size)
    across = g.uniform(-0.25 * jit, 0.25 * jit, legs.size)
    along[-1] = across[-1] = 0.0  # the end is the start marker
    out[1:] += along[:, None] * d + across[:, None] * np.column_stack([-d[:, 1], d[:, 0]])
    return out


@dataclass(frozen=True)
class GirardRun:
    """A simulated walk of the paper's test with its truth.

    Attributes
    ----------
    plan : FloorPlan
        The test area (:func:`test_area`).
    start_m : numpy.ndarray
        ``(2,)`` start position (marker 1), what the user enters (§3.2 step 1).
    truth_m : numpy.ndarray
        ``(n_steps, 2)`` true position after each step (the markers stepped on).
    true_heading_rad : numpy.ndarray
        ``(n_steps,)`` true direction of each step.
    steps : StepLog
        What the foot-mounted IMU reports.
    ranges : RangeLog
        SRF02 readings (sensor 0 left, sensor 1 right of the walking direction).
    reading_pose : numpy.ndarray
        ``(n_readings, 3)`` true sensor-carrier pose ``(x, y, heading)`` at each reading.
    range_truth_m : numpy.ndarray
        ``(n_readings,)`` noise-free reading of the model (NaN: out of range).
    dead_reckoning_m : numpy.ndarray
        ``(n_steps, 2)`` positions integrated from the step log alone (Fig. 10).
    params : dict
        The simulation parameters.
    """

    plan: FloorPlan
    start_m: np.ndarray
    truth_m: np.ndarray
    true_heading_rad: np.ndarray
    steps: StepLog
    ranges: RangeLog
    reading_pose: np.ndarray
    range_truth_m: np.ndarray
    dead_reckoning_m: np.ndarray
    params: dict


def simulate(
    *,
    n_laps: int = 2,
    step_duration_s: float = 1.0,
    marker_jitter_m: float = 0.12,
    heading_noise_rad: float = math.radians(2.0),
    heading_drift_rad_per_step: float = math.radians(0.2),
    heading_walk_rad: float = math.radians(0.3),
    sensor_sway_rad: float = math.radians(1.0),
    range_method: str = "specular",
    sensor: srf02.SRF02 | None = None,
    logged_heading_sigma_rad: float | None = None,
    rng: RngLike = None,
) -> GirardRun:
    """Simulate the paper's test walk: steps, compass, SRF02 readings, and the truth.

    Parameters
    ----------
    n_laps : int
        Times the path is walked (paper: 2, 52 steps). Default 2.
    step_duration_s : float
        Time per step (the paper's system handled one step per second). Default 1 s.
    marker_jitter_m : float
        Marker placement error (see :func:`markers`), >= 0. Default 0.12 m.
    heading_noise_rad : float
        White compass noise per step, 1-sigma. Default 2°; also written to the step log
        as ``heading_sigma_rad``.
    heading_drift_rad_per_step : float
        Compass drift: the heading error grows by this much per step. Default 0.2°
        (10° after 52 steps: the per-step error stays mostly within the paper's ε =
        25 cm, which §3.3 chose above the largest drift between two steps).
    heading_walk_rad : float
        Random-walk part of the drift, 1-sigma per step. Default 0.3°.
    sensor_sway_rad : float
        1-sigma of the laptop's orientation about the walking direction at each reading
        (the user holds it aligned with the body, §3.3). Default 1°.
    range_method : {"specular", "rays"}
        Range model producing the readings (:func:`rangekit.sensors.srf02.model_range`);
        the default ``"specular"`` differs from the filter's ray model, so the filter is
        not tested on its own model. Default ``"specular"``.
    sensor : SRF02, optional
        Sensor parameters (error model, cycle); default ``SRF02()``.
    logged_heading_sigma_rad : float, optional
        Model mismatch (not in the paper): the heading 1-sigma the step log states (what
        the IMU's datasheet says), >= 0, when it differs from the noise drawn
        (``heading_noise_rad``). None (default): the log states the drawn noise.
    rng : RngLike, optional
        Random source, anything :func:`numpy.random.default_rng` accepts.

    Returns
    -------
    GirardRun

    Raises
    ------
    InvalidParameterError
        On a parameter out of its domain.

    Notes
    -----
    Timeline: t = 0 at the start marker; step k (1-based) moves the body linearly from
    marker k-1 to marker k during ``[(k-1) T, k T]`` and the step event is logged at
    ``k T`` (foot landing). The measured step is length 1.25 m (§3.3) and heading
    ``true + k drift + walk_k + noise_k``. The two sensors are fired sequentially
    (:func:`rangekit.sensors.srf02.schedule_firings`, USB latency 1-4 ms) from t = 0 to
    the last step; each reading is the model range at the pose of its firing (position
    interpolated, heading = the current step's direction plus sway), passed through the
    crosstalk model (:func:`~rangekit.sensors.srf02.simulate_readings`, none when fired
    sequentially) and the SRF02 error model (:func:`~rangekit.sensors.srf02.read_ranges`).
    """
    n_laps = _validate.positive_int("n_laps", n_laps)
    T = _validate.positive("step_duration_s", step_duration_s)
    pos = _validate.positive
    params: dict[str, Any] = {
        "n_laps": n_laps,
        "step_duration_s": T,
        "marker_jitter_m": pos("marker_jitter_m", marker_jitter_m, allow_zero=True),
        "heading_noise_rad": pos("heading_noise_rad", heading_noise_rad, allow_zero=True),
        "heading_drift_rad_per_step": float(heading_drift_rad_per_step),
        "heading_walk_rad": pos("heading_walk_rad", heading_walk_rad, allow_zero=True),
        "sensor_sway_rad": pos("sensor_sway_rad", sensor_sway_rad, allow_zero=True),
        "range_method": range_method,
        "logged_heading_sigma_rad": None
        if logged_heading_sigma_rad is None
        else pos("logged_heading_sigma_rad", logged_heading_sigma_rad, allow_zero=True),
    }
    if not math.isfinite(params["heading_drift_rad_per_step"]):
        raise InvalidParameterError(
            f"heading_drift_rad_per_step={heading_drift_rad_per_step!r} must be finite"
        )
    if range_method not in ("specular", "rays"):
        raise InvalidParameterError(f"range_method={range_method!r} must be 'specular' or 'rays'")
    sensor = srf02.SRF02() if sensor is None else sensor
    g = np.random.default_rng(rng)
    plan = test_area()

    lap = markers(params["marker_jitter_m"], rng=g)
    path = np.concatenate([lap[:1]] + [lap[1:]] * n_laps)
    n = path.shape[0] - 1
    delta = np.diff(path, axis=0)
    true_head = np.arctan2(delta[:, 1], delta[:, 0])
    k = np.arange(1, n + 1)
    walk = np.cumsum(params["heading_walk_rad"] * g.standard_normal(n))
    noise = params["heading_noise_rad"] * g.standard_normal(n)
    meas_head = true_head + params["heading_drift_rad_per_step"] * k + walk + noise
    meas_head = (meas_head + np.pi) % (2 * np.pi) - np.pi
    t_steps = k * T
    logged = params["logged_heading_sigma_rad"]
    logged = params["heading_noise_rad"] if logged is None else logged
    steps = StepLog(t_steps, np.full(n, STEP_LENGTH_M), meas_head, np.full(n, logged))
    dr = path[0] + np.cumsum(steps.vectors_m, axis=0)

    # Sequential firing of the two sensors from t = 0 to the last step.
    cycle = sensor.cycle_s + srf02.USB_LATENCY_S[1]
    n_cycles = int(math.ceil(n * T / (2 * cycle))) + 2
    fire = srf02.schedule_firings(2, n_cycles, mode="sequential", cycle_s=sensor.cycle_s, rng=g)
    ft = fire.reshape(-1)
    idx = np.clip(np.ceil(ft / T).astype(np.int64), 1, n)  # step in progress (1-based)
    frac = np.clip(ft / T - (idx - 1), 0.0, 1.0)
    xy = path[idx - 1] + frac[:, None] * delta[idx - 1]
    head = true_head[idx - 1] + params["sensor_sway_rad"] * g.standard_normal(ft.size)
    pose = np.column_stack([xy, head]).reshape(n_cycles, 2, 3)
    true_r = np.empty((n_cycles, 2))
    for s, mount in enumerate(MOUNT_ANGLES_RAD):
        true_r[:, s] = srf02.model_range(
            plan, pose[:, s], sensor, mount_angle_rad=mount, method=range_method
        )
    heard = srf02.simulate_readings(fire, true_r, sensor)
    reading = srf02.read_ranges(heard.range_m, sensor, rng=g)
    keep = ft <= n * T
    ranges = RangeLog(ft[keep], np.tile([0, 1], n_cycles)[keep], reading.reshape(-1)[keep])
    return GirardRun(
        plan=plan,
        start_m=path[0].copy(),
        truth_m=path[1:].copy(),
        true_heading_rad=true_head,
        steps=steps,
        ranges=ranges,
        reading_pose=pose.reshape(-1, 3)[keep],
        range_truth_m=true_r.reshape(-1)[keep],
        dead_reckoning_m=dr,
        params=params,
    )
