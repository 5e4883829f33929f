"""Pedestrian tracking on a floor plan with body-worn range finders (Girard et al. 2011).

Two particle filters over the same inputs -- step events from a foot-mounted IMU and
readings of two back-to-back SRF02 range finders (:mod:`rangekit.io.steplog`) -- and the
same output (:class:`ParticleTrack`):

* ``method="girard"``: the paper's filter, §3.2 steps 1-8 (κ motion vectors within ε,
  wall elimination, merging closer than τ, eq. (1) weights from λ-ray model distances
  under the incidence condition of eq. (3), keep the ν best, eq. (2) weighted mean);
* ``method="sir"``: sequential importance resampling with a likelihood from the SRF02
  error model, systematic resampling, roughening and optional KLD-sampling.

Each runs in one of Table 1's three modes: ``"imu"`` (steps only), ``"model"`` (steps and
the floor plan) and ``"ranging"`` (steps, floor plan and range readings).

Particles are arrays; ray casting, wall crossing and merging are compiled kernels over a
uniform grid (:mod:`rangekit.localize._particle_kernels`).

Examples
--------
>>> from rangekit.floorplan import FloorPlan
>>> from rangekit.io.steplog import StepLog
>>> plan = FloorPlan.from_walls([((0, 0), (20, 0)), ((0, 2), (20, 2)),
...                              ((0, 0), (0, 2)), ((20, 0), (20, 2))])
>>> steps = StepLog([1.0, 2.0, 3.0], [1.25] * 3, [0.0] * 3, [0.03] * 3)
>>> track = track_particles(plan, steps, None, (1.0, 1.0),
...                         ParticleConfig(mode="model"), rng=0)
>>> track.xy_m.shape, bool(abs(track.xy_m[-1, 0] - 4.75) < 0.2)
((3, 2), True)
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rangekit import _validate
from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.floorplan import FloorPlan
from rangekit.io.steplog import RangeLog, StepLog
from rangekit.sensors.srf02 import SRF02
from rangekit.types import RngLike

__all__ = [
    "MAX_CANDIDATES",
    "MAX_PARTICLES",
    "METHODS",
    "MODES",
    "TRACK_COLUMNS",
    "Cloud",
    "ParticleConfig",
    "ParticleEvent",
    "ParticleTrack",
    "TrackingError",
    "check_inputs",
    "default_mode",
    "eq1_weights",
    "keep_best",
    "rig_config",
    "sample_motion_vectors",
    "track_particles",
    "track_report",
    "track_rows",
    "tracking_error",
    "weighted_mean",
]


#: Filters :func:`track_particles` runs.
METHODS = ("girard", "sir")
#: Table 1's columns: steps only, steps + floor plan, steps + floor plan + ranging.
MODES = ("imu", "model", "ranging")

#: Largest ``n_particles`` accepted. Memory bounds it: an SIR update peaks at about 110
#: bytes per particle (numpy arrays, measured with tracemalloc: 0.11 GB at the bound).
MAX_PARTICLES = 1_000_000
#: Largest ``n_particles * kappa`` of the paper's filter: a step holds every candidate
#: move before merging, about 110 bytes each (measured: 2.2 GB for ν = 100,000 parents x
#: κ = 20), so at most 0.55 GB; ν <= 250,000 with the paper's κ = 20.
MAX_CANDIDATES = 5_000_000

#: Columns of :func:`track_rows` (the ``rangekit track particle`` output).
TRACK_COLUMNS = ("t_s", "x_m", "y_m", "n_particles", "spread_m")

# Angular slack of the eq. (3) window, as in rangekit.sensors.srf02 (exact perpendiculars).
_ANGLE_TOL = 1e-12


@dataclass(frozen=True)
class ParticleConfig:
    """Parameters of :func:`track_particles` (defaults: Girard et al. 2011 §3.3).

    Parameters
    ----------
    method : {"girard", "sir"}
        The paper's filter or sequential importance resampling. Default ``"girard"``.
    mode : {"imu", "model", "ranging"}
        Table 1's columns: steps only; steps and the floor plan (moves through walls
        eliminated); steps, plan and range readings. Default ``"ranging"``.
    n_particles : int
        ν, the maximum number of particles kept (§3.1), at most :data:`MAX_PARTICLES`
        (and ``n_particles * kappa`` at most :data:`MAX_CANDIDATES` with
        ``method="girard"``). Default 150.
    eps_m : float
        ε, radius of the motion-vector error (§3.1), m. Default 0.25.
    kappa : int
        κ, motion vectors drawn per step (§3.1). Default 20.
    tau_m : float
        τ, particles closer than this are merged (§3.1), m. Default 0.05.
    n_rays : int
        λ, rays across the aperture (§3.1). Default 7.
    sensor : SRF02 or None
        Range-finder model (aperture α, range limits, error model); ``None`` is
        ``SRF02(n_rays=n_rays)``. Its ``n_rays`` must equal ``n_rays``.
    mount_angles_rad : tuple of float
        Sensor axes relative to the walking direction, one per sensor index of the range
        log. Default ``(+pi/2, -pi/2)``: two sensors back to back, facing left (sensor 0)
        and right (sensor 1) of the walker (Girard §2.6, §3.3, Fig. 8b).
    lever_arms_m : tuple of (float, float), or None
        Each sensor's position in the body frame (x along the walking direction, y to
        its left), m, one per mount; the rays start there instead of at the particle
        (turned with the step's heading). None (default): every sensor at the particle.
        :func:`rig_config` takes them from a rig file's tags.
    max_reading_age_s : float
        With ``use_readings="latest"``, a step uses each sensor's latest reading no older
        than this. Default 0.3 s.
    use_readings : {"all", "latest"}
        Readings compared in step 6: ``"all"`` readings taken during the step, each at the
        particle's position at the reading time along its motion vector (Girard §3.3: one
        reading every 10 cm along the walls); ``"latest"`` only each sensor's latest
        reading, at the particle's position after the step. Default ``"all"``.
    weighting : {"product", "set"}
        Girard step 6: ``"product"`` multiplies the (merged) particle weight by eq. (1)
        raised to ``eq1_power``; ``"set"`` replaces the weight by eq. (1), the literal
        wording (memoryless: fine at ν = 150, worse for large ν). Default ``"product"``.
    eq1_power : float
        γ > 0, the power of eq. (1) in ``"product"`` weighting (see Notes of
        :func:`track_particles`). Default 30.
    reinit_radius_m : float
        When every particle dies, new ones are spread uniformly within this radius of
        the last estimate moved by the step. Default 1.0 m.
    grid_cell_m : float
        Cell side of the spatial grid over the walls. Default 1.0 m.
    step_sigma_m : float
        SIR: 1-sigma of the step length, m. Default 0.12.
    heading_sigma_rad : float
        SIR: heading 1-sigma added (in quadrature) to the log's per-step sigma (used
        alone where the log's sigma is NaN), rad. Default 0.06.
    range_sigma_m : float
        SIR: 1-sigma of the ray model's error, added in quadrature to the sensor's
        ``noise_sigma_m``. Default 0.10 m.
    p_outlier : float
        SIR: probability that a reading is unrelated to the model (uniform on
        ``[0, max_range_m]``). Default 0.05.
    p_miss : float
        SIR: probability of no echo where the model predicts one. Default 0.10.
    resample_ess : float
        SIR: resample when the effective sample size falls below this fraction of the
        particle count (1 = every step). Default 0.5.
    roughening : float
        SIR: roughening constant K (jitter ``K E N^(-1/2)`` per axis, E the cloud's
        extent); 0 disables. Default 0.2.
    kld : bool
        SIR: adapt the particle count by KLD-sampling (Fox 2003), at most
        ``n_particles``. Default False.
    kld_bin_m, kld_epsilon, kld_delta : float
        KLD-sampling bin size (m), error bound and confidence. Defaults 0.2, 0.05, 0.01.
    kld_min_particles : int
        KLD-sampling lower bound on the count. Default 100.

    Raises
    ------
    InvalidParameterError
        If a value is out of its domain.
    """

    method: str = "girard"
    mode: str = "ranging"
    n_particles: int = 150
    eps_m: float = 0.25
    kappa: int = 20
    tau_m: float = 0.05
    n_rays: int = 7
    sensor: SRF02 | None = None
    mount_angles_rad: tuple[float, ...] = (0.5 * math.pi, -0.5 * math.pi)
    lever_arms_m: tuple[tuple[float, float], ...] | None = None
    max_reading_age_s: float = 0.3
    use_readings: str = "all"
    weighting: str = "product"
    eq1_power: float = 30.0
    reinit_radius_m: float = 1.0
    grid_cell_m: float = 1.0
    step_sigma_m: float = 0.12
    heading_sigma_rad: float = 0.06
    range_sigma_m: float = 0.10
    p_outlier: float = 0.05
    p_miss: float = 0.10
    resample_ess: float = 0.5
    roughening: float = 0.2
    kld: bool = False
    kld_bin_m: float = 0.2
    kld_epsilon: float = 0.05
    kld_delta: float = 0.01
    kld_min_particles: int = 100

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise InvalidParameterError(f"method={self.method!r} must be one of {METHODS}")
        if self.mode not in MODES:
            raise InvalidParameterError(f"mode={self.mode!r} must be one of {MODES}")
        if self.use_readings not in ("all", "latest"):
            raise InvalidParameterError(
                f"use_readings={self.use_readings!r} must be 'all' or 'latest'"
            )
        if self.weighting not in ("product", "set"):
            raise InvalidParameterError(f"weighting={self.weighting!r} must be 'product' or 'set'")
        v = _validate
        vals: dict[str, Any] = {
            "n_particles": v.positive_int("n_particles", self.n_particles),
            "eps_m": v.positive("eps_m", self.eps_m, allow_zero=True),
            "kappa": v.positive_int("kappa", self.kappa),
            "tau_m": v.positive("tau_m", self.tau_m, allow_zero=True),
            "n_rays": v.positive_int("n_rays", self.n_rays),
            "max_reading_age_s": v.positive("max_reading_age_s", self.max_reading_age_s),
            "eq1_power": v.positive("eq1_power", self.eq1_power),
            "reinit_radius_m": v.positive("reinit_radius_m", self.reinit_radius_m),
            "grid_cell_m": v.positive("grid_cell_m", self.grid_cell_m),
            "step_sigma_m": v.positive("step_sigma_m", self.step_sigma_m, allow_zero=True),
            "heading_sigma_rad": v.positive(
                "heading_sigma_rad", self.heading_sigma_rad, allow_zero=True
            ),
            "range_sigma_m": v.positive("range_sigma_m", self.range_sigma_m, allow_zero=True),
            "p_outlier": v.in_range("p_outlier", self.p_outlier, 0.0, 1.0),
            "p_miss": v.in_range("p_miss", self.p_miss, 0.0, 1.0),
            "resample_ess": v.in_range("resample_ess", self.resample_ess, 0.0, 1.0),
            "roughening": v.positive("roughening", self.roughening, allow_zero=True),
            "kld": bool(self.kld),
            "kld_bin_m": v.positive("kld_bin_m", self.kld_bin_m),
            "kld_epsilon": v.positive("kld_epsilon", self.kld_epsilon),
            "kld_delta": v.in_range("kld_delta", self.kld_delta, 1e-12, 0.5),
            "kld_min_particles": v.positive_int("kld_min_particles", self.kld_min_particles),
        }
        sensor = SRF02(n_rays=vals["n_rays"]) if self.sensor is None else self.sensor
        if not isinstance(sensor, SRF02):
            raise InvalidParameterError(f"sensor must be an SRF02, got {type(sensor).__name__}")
        if sensor.n_rays != vals["n_rays"]:
            raise InvalidParameterError(
                f"sensor.n_rays={sensor.n_rays} differs from n_rays={vals['n_rays']}"
            )
        try:
            mounts = tuple(float(a) for a in self.mount_angles_rad)
        except (TypeError, ValueError):
            raise InvalidParameterError(
                f"mount_angles_rad={self.mount_angles_rad!r} must be a sequence of angles"
            ) from None
        if not mounts or not all(math.isfinite(a) for a in mounts):
            raise InvalidParameterError(
                f"mount_angles_rad={self.mount_angles_rad!r} must be finite angles (>= 1)"
            )
        if vals["n_particles"] > MAX_PARTICLES:
            raise InvalidParameterError(
                f"n_particles={vals['n_particles']} is above the bound {MAX_PARTICLES:,} "
                "(memory: about 110 bytes per particle)",
                param="n_particles",
            )
        if self.method == "girard" and vals["n_particles"] * vals["kappa"] > MAX_CANDIDATES:
            raise InvalidParameterError(
                f"n_particles * kappa = {vals['n_particles']} * {vals['kappa']} is above the "
                f"bound {MAX_CANDIDATES:,} of method='girard' (memory: every candidate move "
                "is held before merging, about 110 bytes each); use fewer particles or "
                "method='sir'",
                param="n_particles",
            )
        vals["sensor"] = sensor
        vals["mount_angles_rad"] = mounts
        vals["lever_arms_m"] = _lever_arms(self.lever_arms_m, len(mounts))
        for k, val in vals.items():
            object.__setattr__(self, k, val)


def _lever_arms(lever: Any, n_mounts: int) -> tuple[tuple[float, float], ...] | None:
    """Validated ``lever_arms_m``: None, or one finite (x, y) per mount."""
    if lever is None:
        return None
    try:
        arr = np.asarray(lever, dtype=np.float64)
    except (TypeError, ValueError):
        arr = np.zeros(0)
    if arr.shape != (n_mounts, 2) or not np.all(np.isfinite(arr)) or np.any(np.abs(arr) > 10):
        raise InvalidParameterError(
            f"lever_arms_m={lever!r} must be {n_mounts} finite (x, y) pairs within 10 m, "
            "one per mount angle"
        )
    return tuple((float(x), float(y)) for x, y in arr)


def rig_config(
    rig: Any, *, mount_angles_rad: Sequence[float] | None = None, name: str = "the rig", **kw: Any
) -> ParticleConfig:
    """A :class:`ParticleConfig` whose range sensors are the tags of a rig file.

    Sensor ``s`` of the range log is the rig's ``s``-th tag (``body.tags`` in file order);
    its lever arm (x forward, y left; z is ignored) places the sensor on the body, and its
    axis is the tag's ``axis_deg`` or else points away from the body centre along the lever
    arm (``atan2(y, x)``: a tag at ``(0, 0.15)`` faces left, +90°); ``mount_angles_rad``
    overrides both. The rig's
    anchors are not used (the filter ranges walls, not anchors). With ``method="sir"`` the
    rig's step-length sigma (``odometry.length_sigma_m``) is ``step_sigma_m`` unless given.

    Parameters
    ----------
    rig : rangekit.rig.Rig
        Its odometry must be ``steps`` (the filter moves on step events).
    mount_angles_rad : sequence of float, optional
        One axis per tag, rad, relative to the walking direction.
    name : str
        The rig's name in error messages (its file).
    **kw
        Other :class:`ParticleConfig` fields.

    Raises
    ------
    IncompatibleInputError
        The rig does not fit the filter: its odometry is not ``steps``, a tag sits at the
        body centre without a given axis, or ``mount_angles_rad`` does not give one angle
        per tag (exit code 5).
    InvalidParameterError
        ``rig`` is not a Rig, or a field of ``kw`` is out of its domain.
    """
    from rangekit.rig import Rig

    if not isinstance(rig, Rig):
        raise InvalidParameterError(f"rig must be a rangekit.rig.Rig, got {type(rig).__name__}")
    where = name
    if rig.odometry.kind != "steps":
        raise IncompatibleInputError(
            f"{where}: the particle filter moves on step events; the rig's odometry is "
            f"{rig.odometry.kind!r}, not 'steps'"
        )
    lever = rig.tag_lever_m[:, :2]
    if mount_angles_rad is None:
        given = np.isfinite(rig.tag_axis_rad)
        centre = np.flatnonzero(~given & (np.hypot(lever[:, 0], lever[:, 1]) == 0.0))
        if centre.size:
            raise IncompatibleInputError(
                f"{where}: tag {int(rig.tag_ids[centre[0]])} sits at the body centre and has "
                "no axis_deg, so its axis cannot be taken from its lever arm; give axis_deg "
                "in the rig or the sensor axes"
            )
        radial = np.arctan2(lever[:, 1], lever[:, 0])
        mounts = tuple(float(a) for a in np.where(given, rig.tag_axis_rad, radial))
    else:
        mounts = tuple(float(a) for a in mount_angles_rad)
        if len(mounts) != rig.n_tags:
            raise IncompatibleInputError(
                f"{where}: {len(mounts)} mount angle(s) for the rig's {rig.n_tags} tag(s)"
            )
    if kw.get("method") == "sir" and "step_sigma_m" not in kw:
        kw["step_sigma_m"] = rig.odometry.length_sigma_m
    levers = tuple((float(x), float(y)) for x, y in lever)
    return ParticleConfig(mount_angles_rad=mounts, lever_arms_m=levers, **kw)


@dataclass(frozen=True)
class ParticleEvent:
    """Something the filter reports: ``kind`` is ``"left_map"`` (every hypothesis of the
    step ended outside the floor plan) or ``"all_died"`` (every particle was eliminated);
    both are followed by a re-initialisation around the last estimate."""

    step: int
    t_s: float
    kind: str
    message: str


@dataclass(frozen=True)
class Cloud:
    """The particles after ``after_steps`` steps: positions ``xy_m`` (n, 2), weights (n,)
    summing to 1."""

    after_steps: int
    xy_m: np.ndarray
    weight: np.ndarray


@dataclass(frozen=True)
class ParticleTrack:
    """Result of :func:`track_particles`, one row per step event.

    Attributes
    ----------
    t_s : numpy.ndarray
        float64 ``(n,)`` step times, s.
    xy_m : numpy.ndarray
        float64 ``(n, 2)`` position estimates after each step (eq. (2)), m.
    n_particles : numpy.ndarray
        int64 ``(n,)`` particles in the cloud after each step.
    spread_m : numpy.ndarray
        float64 ``(n,)`` weighted RMS distance of the particles from the estimate, m.
    events : tuple of ParticleEvent
        Re-initialisations and their causes.
    clouds : tuple of Cloud
        The clouds saved at the requested steps.
    config : ParticleConfig
        The parameters used.
    """

    t_s: np.ndarray
    xy_m: np.ndarray
    n_particles: np.ndarray
    spread_m: np.ndarray
    events: tuple[ParticleEvent, ...]
    clouds: tuple[Cloud, ...]
    config: ParticleConfig = field(repr=False)


@dataclass(frozen=True)
class TrackingError:
    """Distances from the true positions (m), the statistics of Girard 2011 Table 1."""

    mean_m: float
    std_m: float
    max_m: float
    min_m: float
    ending_m: float


def track_rows(track: ParticleTrack) -> tuple[tuple[str, ...], np.ndarray]:
    """:data:`TRACK_COLUMNS` and one row per step: time, estimate, cloud size, spread."""
    rows = np.column_stack([track.t_s, track.xy_m, track.n_particles, track.spread_m])
    return TRACK_COLUMNS, rows


def default_mode(*, plan: bool, ranges: bool) -> str:
    """The mode the inputs given call for: ``"ranging"`` with range readings, else
    ``"model"`` with a floor plan, else ``"imu"`` (``rangekit track particle`` without
    ``--mode``).

    Examples
    --------
    >>> default_mode(plan=True, ranges=True), default_mode(plan=True, ranges=False)
    ('ranging', 'model')
    >>> default_mode(plan=False, ranges=False)
    'imu'
    """
    return "ranging" if ranges else ("model" if plan else "imu")


def check_inputs(
    plan: FloorPlan | None,
    ranges: RangeLog | None,
    start_xy: Any,
    config: ParticleConfig,
    *,
    plan_name: str = "",
    ranges_name: str = "the range log",
    rig_name: str | None = None,
    mounts_name: str = "mount_angles_rad",
    start_name: str = "start_xy",
) -> None:
    """Check that the inputs fit each other, as :func:`track_particles` does first (it
    calls this, the one place of these checks): in ``mode="ranging"`` every sensor
    index of the range log has a mount angle (a tag of the rig, ``rig_name``, when the
    config came from :func:`rig_config`), and where the mode uses the plan
    (``"model"``, ``"ranging"``) the start lies within its bounds.

    Each input is valid on its own; together they do not fit, hence
    :class:`~rangekit.errors.IncompatibleInputError` (exit code 5; the table in
    ``docs/cli.md``): a malformed log or a value out of its domain is caught before,
    by the readers and :class:`ParticleConfig`. The names are those of the inputs in
    the messages (``rangekit track particle`` passes its files and options through
    :func:`track_particles`' ``names``).

    Raises
    ------
    IncompatibleInputError
        The sensor index and the mount count, or the start and the plan's bounds, named.

    Examples
    --------
    >>> from rangekit.floorplan import FloorPlan
    >>> plan = FloorPlan.from_walls([((0, 0), (4, 0)), ((4, 0), (4, 3))])
    >>> check_inputs(plan, None, (5.0, 1.0), ParticleConfig(), plan_name="plan.json")
    ... # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    rangekit.errors.IncompatibleInputError: start_xy 5,1 is outside ... (x 0..4, y 0..3)
    """
    n = len(config.mount_angles_rad)
    if config.mode == "ranging" and ranges is not None and ranges.n_sensors > n:
        what = (
            f"the rig {rig_name} has {n} tag(s)"
            if rig_name is not None
            else f"{mounts_name} gives {n} sensor(s)"
        )
        raise IncompatibleInputError(
            f"{ranges_name}: has readings of sensor {ranges.n_sensors - 1} but {what} "
            f"(sensor indices 0..{n - 1})"
        )
    if config.mode != "imu" and plan is not None and plan.walls:
        xy0 = [float(v) for v in np.asarray(start_xy, dtype=np.float64).reshape(-1)]
        x0, y0, x1, y1 = plan.bounds
        if not (x0 <= xy0[0] <= x1 and y0 <= xy0[1] <= y1):
            raise IncompatibleInputError(
                f"{start_name} {xy0[0]:g},{xy0[1]:g} is outside the floor plan"
                f"{f' {plan_name}' if plan_name else ''} "
                f"(x {x0:g}..{x1:g}, y {y0:g}..{y1:g})"
            )


def track_report(
    track: ParticleTrack,
    *,
    log: str,
    start_xy: Any,
    plan: str | None = None,
    ranges: str | None = None,
    rig: str | None = None,
    seed: int | None = None,
):
    """The track as ``rangekit track particle`` reports it: :func:`track_rows`, a summary
    (filter, mode, steps, ν, re-initialisations), each re-initialisation as a warning,
    and in JSON the inputs, the parameters (:attr:`ParticleTrack.config`) and the events.

    Parameters
    ----------
    track : ParticleTrack
    log : str
        The step log's name.
    start_xy : sequence of 2 floats
        The start given to :func:`track_particles`.
    plan, ranges, rig : str, optional
        The floor plan's, range log's and rig file's names (None: not given).
    seed : int, optional
        The random seed given (None: fresh entropy).

    Returns
    -------
    rangekit.io.tracks.TrackReport
    """
    from rangekit.io.tracks import TrackReport

    config = track.config
    columns, rows = track_rows(track)
    summary = (
        f"particle ({config.method}, {config.mode}): {rows.shape[0]} steps, "
        f"nu={config.n_particles}, {len(track.events)} re-initialisations"
    )
    extra = {
        "method": config.method,
        "mode": config.mode,
        "map": None if plan is None else str(plan),
        "ranges": None if ranges is None else str(ranges),
        "rig": None if rig is None else str(rig),
        "start_m": [float(v) for v in start_xy],
        "n_particles": config.n_particles,
        "mounts_deg": [math.degrees(a) for a in config.mount_angles_rad],
        "lever_arms_m": None if config.lever_arms_m is None else list(config.lever_arms_m),
        "seed": seed,
        "events": [
            {"step": e.step, "t_s": e.t_s, "kind": e.kind, "message": e.message}
            for e in track.events
        ],
    }
    parameters = {k: extra[k] for k in ("method", "mode", "n_particles", "mounts_deg",
                                        "lever_arms_m")}  # fmt: skip
    notes = tuple(f"step {e.step} (t_s={e.t_s:g}): {e.message}" for e in track.events)
    return TrackReport("particle", str(log), columns, rows, extra=extra, summary=summary,
                       warnings=notes, parameters=parameters)  # fmt: skip


def tracking_error(xy_m: Any, truth_m: Any) -> TrackingError:
    """Table 1 statistics (μ, σ, Max, Min, Ending) of the distance to the truth.

    Parameters
    ----------
    xy_m, truth_m : array_like, shape (n, 2)
        Estimates and true positions, n >= 1.

    Examples
    --------
    >>> e = tracking_error([[0, 0], [1, 0]], [[0, 0.1], [1, 0.3]])
    >>> round(e.mean_m, 3), round(e.ending_m, 3)
    (0.2, 0.3)
    """
    a = np.asarray(xy_m, dtype=np.float64)
    b = np.asarray(truth_m, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 2 or a.shape[1] != 2 or a.shape[0] == 0:
        raise InvalidParameterError(
            f"xy_m {a.shape} and truth_m {b.shape} must both have shape (n >= 1, 2)"
        )
    d = np.hypot(*(a - b).T)
    return TrackingError(
        float(d.mean()), float(d.std()), float(d.max()), float(d.min()), float(d[-1])
    )


# --------------------------------------------------------------------- paper's steps


def sample_motion_vectors(
    step_m: Any, eps_m: float, kappa: int, rng: np.random.Generator
) -> np.ndarray:
    """κ motion vectors uniform in the disc of radius ε around the measured step vector.

    Girard et al. 2011 §3.2 step 3 (Fig. 6): "randomly generates, using a uniform
    distribution, a set of κ vectors around a radius of ε of the motion vector".

    Parameters
    ----------
    step_m : array_like, shape (2,)
        Measured step vector, m.
    eps_m : float
        ε, m.
    kappa : int
        κ.
    rng : numpy.random.Generator

    Returns
    -------
    numpy.ndarray
        float64 ``(kappa, 2)``.

    Notes
    -----
    Uniform over the disc's area: radius ``eps sqrt(U1)``, angle ``2 pi U2``.

    Examples
    --------
    >>> v = sample_motion_vectors([1.25, 0.0], 0.25, 20, np.random.default_rng(0))
    >>> v.shape, bool(np.all(np.hypot(v[:, 0] - 1.25, v[:, 1]) <= 0.25))
    ((20, 2), True)
    """
    r = eps_m * np.sqrt(rng.random(kappa))
    phi = 2.0 * np.pi * rng.random(kappa)
    s = np.asarray(step_m, dtype=np.float64)
    return np.column_stack([s[0] + r * np.cos(phi), s[1] + r * np.sin(phi)])


def eq1_weights(model_m: Any, measured_m: Any, max_range_m: float) -> np.ndarray:
    """Girard et al. 2011 eq. (1): similarity of model and measured ranges.

    Parameters
    ----------
    model_m : array_like, shape (n, k)
        δ_k: model distance of each particle to the wall seen by sensor k, m; ``inf``
        (or NaN) where the model finds no wall.
    measured_m : array_like, shape (k,)
        Δ_k: reading of sensor k, m; NaN (no echo) counts as ``max_range_m``.
    max_range_m : float
        Δ_k^max, the sensor's maximum range, m.

    Returns
    -------
    numpy.ndarray
        float64 ``(n,)``: ``w_i = 1/k sum_k min(δ, Δ, Δmax) / min(max(δ, Δ), Δmax)`` in
        ``[0, 1]``; 1 for ``k = 0``.

    Notes
    -----
    The paper sums over ``k = 0 .. n`` with ``1/n`` in front, n the number of sensors;
    rangekit averages over the sensors that have a reading (the sum has ``n`` terms). A
    model distance beyond the range (no wall found) is treated like a missing echo: as
    ``Δmax``.

    Examples
    --------
    >>> eq1_weights([[1.0, np.inf], [2.0, 6.0]], [1.0, np.nan], 6.0).tolist()
    [1.0, 0.75]
    """
    d = np.asarray(model_m, dtype=np.float64)
    m = np.asarray(measured_m, dtype=np.float64).reshape(-1)
    if d.ndim != 2 or d.shape[1] != m.size:
        raise InvalidParameterError(
            f"model_m {d.shape} must have shape (n, {m.size}) to match measured_m"
        )
    if m.size == 0:
        return np.ones(d.shape[0])
    dmax = float(max_range_m)
    d = np.where(np.isnan(d), np.inf, d)
    m = np.where(np.isnan(m), dmax, m)
    num = np.minimum(np.minimum(d, m[None, :]), dmax)
    den = np.minimum(np.maximum(d, m[None, :]), dmax)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(den > 0.0, num / den, 1.0)
    return r.mean(axis=1)


def weighted_mean(xy_m: Any, weight: Any) -> np.ndarray:
    """Girard et al. 2011 eq. (2): ``p_u = sum w_i p_i / sum w_i``.

    Examples
    --------
    >>> weighted_mean([[0.0, 0.0], [2.0, 4.0]], [3.0, 1.0]).tolist()
    [0.5, 1.0]
    """
    p = np.asarray(xy_m, dtype=np.float64)
    w = np.asarray(weight, dtype=np.float64)
    return (w[:, None] * p).sum(axis=0) / w.sum()


def keep_best(weight: np.ndarray, nu: int, rng: np.random.Generator) -> np.ndarray:
    """Indices of the ν heaviest particles (Girard step 7); ties broken at random."""
    n = weight.size
    if n <= nu:
        return np.arange(n)
    perm = rng.permutation(n)
    top = np.argpartition(-weight[perm], nu - 1)[:nu]
    return np.sort(perm[top])


# ---------------------------------------------------------------------------- engine


class _World:
    """Floor plan, grid and sensor geometry shared by both filters."""

    def __init__(self, plan: FloorPlan | None, cfg: ParticleConfig, use_plan: bool) -> None:
        from rangekit.localize import _particle_kernels as K

        self.K = K
        self.use_plan = use_plan and plan is not None
        self.plan = plan
        seg = np.zeros((0, 4)) if plan is None else np.ascontiguousarray(plan.segments)
        self.grid = K.build_grid(seg, cfg.grid_cell_m)
        if plan is not None and plan.walls:
            self.bounds = plan.bounds
        else:
            self.bounds = (-math.inf, -math.inf, math.inf, math.inf)
        s = cfg.sensor
        self.sensor = s
        self.mounts = np.array(cfg.mount_angles_rad, dtype=np.float64)
        lever = cfg.lever_arms_m
        self.lever = None if lever is None or not np.any(lever) else np.array(lever)
        self.psi = s.ray_offsets_rad
        self.rmax_ray = s.max_range_at(self.psi)
        self.thr = 0.5 * math.pi - s.incidence_window_rad - _ANGLE_TOL

    def inside(self, xy: np.ndarray) -> np.ndarray:
        x0, y0, x1, y1 = self.bounds
        return (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)

    def crosses(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return self.K.crosses_grid(a[:, 0], a[:, 1], b[:, 0], b[:, 1], self.grid)

    def model(self, start: np.ndarray, end: np.ndarray, ctx: _StepCtx) -> np.ndarray:
        """δ of eq. (1): ray-model distance (inf: none) per particle and reading.

        The particle is at ``start + frac (end - start)`` at a reading (its move is
        linear over the step); rays are cast along the step's measured heading.
        """
        n, r = end.shape[0], ctx.sensors.size
        out = np.empty((n, r))
        for f in np.unique(ctx.frac):
            xy = end if f == 1.0 else start + f * (end - start)
            cols = np.flatnonzero(ctx.frac == f)
            sens = ctx.sensors[cols]
            uniq, inv = np.unique(sens, return_inverse=True)
            if self.lever is None:
                d = self._rays(xy[:, 0], xy[:, 1], ctx.heading, self.mounts[uniq])
            else:  # each sensor's rays start at its lever arm, turned with the heading
                c, s = math.cos(ctx.heading), math.sin(ctx.heading)
                d = np.empty((n, uniq.size))
                for j, u in enumerate(uniq.tolist()):
                    lx, ly = self.lever[u]
                    ox, oy = xy[:, 0] + (c * lx - s * ly), xy[:, 1] + (s * lx + c * ly)
                    d[:, j] = self._rays(ox, oy, ctx.heading, self.mounts[u : u + 1])[:, 0]
            out[:, cols] = d[:, inv]
        return out

    def _rays(self, px: np.ndarray, py: np.ndarray, heading: float, mounts: np.ndarray):
        return self.K.ray_model_grid(
            px, py, heading, mounts, self.psi, self.rmax_ray, self.thr,
            self.sensor.min_range_m, self.grid,
        )  # fmt: skip


def _readings(steps: StepLog, ranges: RangeLog | None, n_mounts: int, cfg: ParticleConfig):
    """The readings each step uses: per step, arrays ``(frac, sensor, value)``.

    ``use_readings="latest"``: each sensor's latest reading at most ``max_reading_age_s``
    old at the step time, ``frac = 1`` (the particle's position after the step).
    ``"all"``: every reading since the previous step event, ``frac`` the fraction of the
    step done at the reading time (readings before the first step: those within one
    median step interval of it). Every sensor has a mount (:func:`check_inputs`).
    """
    n = len(steps)
    empty = (np.zeros(0), np.zeros(0, np.int64), np.zeros(0))
    if ranges is None or len(ranges) == 0:
        return [empty] * n
    t_step = steps.t_s
    out = []
    if cfg.use_readings == "latest":
        val = np.full((n, n_mounts), np.nan)
        have = np.zeros((n, n_mounts), dtype=bool)
        for s in range(n_mounts):
            sel = ranges.sensor == s
            t, r = ranges.t_s[sel], ranges.range_m[sel]
            i = np.searchsorted(t, t_step, side="right") - 1
            ok = i >= 0
            ok[ok] = t_step[ok] - t[i[ok]] <= cfg.max_reading_age_s
            have[:, s] = ok
            val[ok, s] = r[i[ok]]
        for k in range(n):
            ss = np.flatnonzero(have[k])
            out.append((np.ones(ss.size), ss.astype(np.int64), val[k, ss]))
        return out
    dt = float(np.median(np.diff(t_step))) if n > 1 else cfg.max_reading_age_s
    prev = np.r_[t_step[0] - dt, t_step[:-1]]
    lo = np.searchsorted(ranges.t_s, prev, side="right")
    hi = np.searchsorted(ranges.t_s, t_step, side="right")
    for k in range(n):
        sl = slice(lo[k], hi[k])
        span = t_step[k] - prev[k]
        fr = np.ones(hi[k] - lo[k]) if span <= 0 else (ranges.t_s[sl] - prev[k]) / span
        out.append((fr, ranges.sensor[sl].copy(), ranges.range_m[sl].copy()))
    return out


def _disc(center: np.ndarray, radius: float, n: int, rng: np.random.Generator) -> np.ndarray:
    r = radius * np.sqrt(rng.random(n))
    a = 2.0 * np.pi * rng.random(n)
    return np.column_stack([center[0] + r * np.cos(a), center[1] + r * np.sin(a)])


def _spread(xy: np.ndarray, w: np.ndarray, est: np.ndarray) -> float:
    d2 = np.sum((xy - est) ** 2, axis=1)
    return float(math.sqrt(max(float(np.sum(w * d2)), 0.0)))


def track_particles(
    plan: FloorPlan | None,
    steps: StepLog,
    ranges: RangeLog | None,
    start_xy: Any,
    config: ParticleConfig | None = None,
    *,
    rng: RngLike = None,
    save_clouds: Sequence[int] = (),
    names: Mapping[str, str | None] | None = None,
) -> ParticleTrack:
    """Track a walker on a floor plan from step events and range readings.

    Parameters
    ----------
    plan : FloorPlan or None
        The walls; may be None only in ``mode="imu"``.
    steps : StepLog
        Step events (time, length, heading, heading sigma).
    ranges : RangeLog or None
        Range readings, sensor index ``s`` mounted at ``config.mount_angles_rad[s]``;
        needed only in ``mode="ranging"``.
    start_xy : array_like, shape (2,)
        Starting position given by the user (Girard §3.2 step 1), m.
    config : ParticleConfig, optional
        Filter and parameters; default ``ParticleConfig()`` (the paper's filter with
        ranging, ν = 150, ε = 25 cm, κ = 20, τ = 5 cm, λ = 7).
    rng : RngLike, optional
        Random source, anything :func:`numpy.random.default_rng` accepts.
    save_clouds : sequence of int, optional
        Numbers of steps after which to keep a copy of the cloud (e.g. ``(9, 21, 52)``
        for Figs 11-13).
    names : mapping, optional
        What to call the inputs in the messages of :func:`check_inputs` (its keywords
        ``plan_name``, ``ranges_name``, ``rig_name``, ``mounts_name``, ``start_name``).

    Returns
    -------
    ParticleTrack

    Raises
    ------
    InvalidParameterError
        On a bad configuration, or a missing plan or range log for the mode.
    IncompatibleInputError
        A start point outside the plan, or a range log with more sensors than mounts
        (:func:`check_inputs`).

    Notes
    -----
    **Girard's filter** (``method="girard"``), per step event (§3.2):

    1. The cloud starts as one particle at ``start_xy`` (step 1).
    2. A step event brings the measured vector ``L (cos h, sin h)`` (step 2).
    3. κ vectors are drawn uniformly in the disc of radius ε around it
       (:func:`sample_motion_vectors`, step 3).
    4. Every vector is applied to every particle (n κ children inheriting their parent's
       weight); children whose move crosses or touches a wall, or that end outside the
       plan's bounding box, are eliminated; the parents are dropped (step 4). Walls are
       segments without thickness, so "ending inside a wall" is ending on it.
    5. Children closer than τ are merged, heaviest first, the lighter one's weight added to
       the heavier (:func:`~rangekit.localize._particle_kernels.merge_close`, step 5).
    6. Each particle is weighted by eq. (1) (:func:`eq1_weights`) with δ from λ rays
       across the aperture α accepted under eq. (3) (the model of
       :func:`rangekit.sensors.srf02.model_range`, ``method="rays"``), cast along the
       *measured* heading of the step (the walker's orientation, §3.2 step 6: "the distance
       calculated in the model according to the user orientation") plus the sensor mount;
       a missing echo counts as the maximum range Δmax (step 6). With
       ``use_readings="all"`` (default) every reading taken during the step is compared,
       at the particle's position at that time along its own motion vector; with
       ``"latest"`` each sensor's latest reading, at the position after the step.
    7. The ν heaviest particles are kept (:func:`keep_best`, step 7).
    8. The estimate is the weighted mean of eq. (2) (:func:`weighted_mean`, step 8).

    Where the paper is ambiguous rangekit chooses (each choice is tested):

    * step 6 "its weight is set proportionally to the similarity": with
      ``weighting="product"`` (default) the merged weight is multiplied by ``s^γ``, ``s``
      the eq. (1) similarity averaged over the step's readings and γ = ``eq1_power`` = 30.
      Multiplying keeps the weights added by merging (step 5) meaningful and gives the
      cloud a memory; the power is rangekit's: eq. (1) is a similarity in [0, 1] (a 10 cm
      error at 1 m still scores 0.9), too flat to outweigh the merged weights, and with
      γ = 1 ranging hardly improves on the model alone. ``weighting="set"`` takes the
      sentence literally (w = eq. (1)): memoryless, it works at the paper's ν = 150 but
      degrades as ν grows (the cloud spreads along every direction the readings do not
      constrain);
    * eq. (1)'s sum runs over ``k = 0..n`` with ``1/n``: it is taken as the mean over the
      readings used;
    * which readings: the paper compares "the ultrasonic distance measured" at each step
      and notes one reading every 10 cm along the walls (§3.3); ``"all"`` uses them all;
    * modes without ranging skip step 6 (weights stay the merged weights);
    * ties in step 7 (equal weights) are broken at random.

    **SIR** (``method="sir"``): each particle moves by its own step, length
    ``L + N(0, step_sigma_m)`` and heading ``h + N(0, sigma_h)``; moves through walls get
    zero weight; the weight is multiplied by the likelihood of each reading, a mixture of
    ``(1 - p_outlier) N(Δ; δ + slip bias, sqrt(noise_sigma^2 + range_sigma^2))`` and a
    uniform ``p_outlier / Δmax`` (``p_outlier / Δmax`` alone where the model sees no wall,
    ``p_miss`` / ``1 - p_miss`` for a missing echo where the model does / does not see a
    wall); the estimate is the weighted mean; then, when the effective sample size is
    below ``resample_ess`` n, systematic resampling, roughening (jitter that would cross a
    wall is undone) and, with ``kld``, KLD-sampling of the count (Fox 2003: the smallest
    prefix of the resampled, roughened and shuffled set whose occupied-bin count k meets
    ``n >= (k - 1) / (2 eps) (1 - 2/(9(k - 1)) + sqrt(2/(9(k - 1))) z_(1-delta))^3``).

    **Re-initialisation** (both): when every particle is eliminated, an event is
    recorded (``"left_map"`` when all candidate positions lay outside the plan,
    ``"all_died"`` otherwise) and the cloud restarts uniformly within
    ``reinit_radius_m`` of the last estimate moved by the measured step (clipped to
    positions inside the plan), then weighted as usual. This is step 1 "re-done"
    automatically around the last estimate instead of by the user.
    """
    cfg = ParticleConfig() if config is None else config
    if not isinstance(cfg, ParticleConfig):
        raise InvalidParameterError(f"config must be a ParticleConfig, got {type(cfg).__name__}")
    if not isinstance(steps, StepLog):
        raise InvalidParameterError(f"steps must be a StepLog, got {type(steps).__name__}")
    if ranges is not None and not isinstance(ranges, RangeLog):
        raise InvalidParameterError(f"ranges must be a RangeLog, got {type(ranges).__name__}")
    if plan is not None and not isinstance(plan, FloorPlan):
        raise InvalidParameterError(f"plan must be a FloorPlan, got {type(plan).__name__}")
    if plan is None and cfg.mode != "imu":
        raise InvalidParameterError(f"mode={cfg.mode!r} needs a floor plan (plan is None)")
    if ranges is None and cfg.mode == "ranging":
        raise InvalidParameterError("mode='ranging' needs a range log (ranges is None)")
    start = np.asarray(start_xy, dtype=np.float64).reshape(-1)
    if start.size != 2 or not np.all(np.isfinite(start)):
        raise InvalidParameterError(f"start_xy={start_xy!r} must be a finite point (x, y)")
    check_inputs(plan, ranges, start, cfg, **(names or {}))
    g = np.random.default_rng(rng)
    world = _World(plan, cfg, use_plan=cfg.mode != "imu")
    save = {_validate.positive_int("save_clouds[]", s) for s in save_clouds}
    n_m = len(cfg.mount_angles_rad)
    if cfg.mode == "ranging":
        per_step = _readings(steps, ranges, n_m, cfg)
    else:
        per_step = _readings(steps, None, n_m, cfg)
    step_fn = _girard_step if cfg.method == "girard" else _sir_step

    n = len(steps)
    out_xy = np.empty((n, 2))
    out_n = np.zeros(n, dtype=np.int64)
    out_spread = np.empty(n)
    events: list[ParticleEvent] = []
    clouds: list[Cloud] = []
    if cfg.method == "girard":
        xy = start[None, :].copy()
        w = np.ones(1)
    else:
        xy = np.repeat(start[None, :], cfg.n_particles, axis=0)
        w = np.full(cfg.n_particles, 1.0 / cfg.n_particles)
    est = start.copy()
    vecs = steps.vectors_m
    for k in range(n):
        frac, sensors, values = per_step[k]
        ctx = _StepCtx(
            k, float(steps.t_s[k]), vecs[k], float(steps.heading_rad[k]),
            float(steps.length_m[k]), float(steps.heading_sigma_rad[k]), frac, sensors,
            values,
        )  # fmt: skip
        res = step_fn(world, cfg, xy, w, ctx, g)
        if res is None or res[0].shape[0] == 0:
            xy, w, event = _reinit(world, cfg, est, ctx, g)
            events.append(event)
        else:
            xy, w = res
        w = w / w.sum()
        est = weighted_mean(xy, w)
        out_xy[k] = est
        out_n[k] = xy.shape[0]
        out_spread[k] = _spread(xy, w, est)
        if k + 1 in save:
            clouds.append(Cloud(k + 1, xy.copy(), w.copy()))
        if cfg.method == "sir":
            xy, w = _sir_resample(world, cfg, xy, w, g)
    return ParticleTrack(
        steps.t_s.copy(), out_xy, out_n, out_spread, tuple(events), tuple(clouds), cfg
    )


@dataclass(frozen=True)
class _StepCtx:
    k: int
    t_s: float
    vec: np.ndarray
    heading: float
    length: float
    heading_sigma: float
    frac: np.ndarray
    sensors: np.ndarray
    meas: np.ndarray


def _girard_weights(world: _World, cfg: ParticleConfig, start, xy, w, ctx: _StepCtx) -> np.ndarray:
    """Step 6: eq. (1) against the step's readings (weights unchanged without any)."""
    if cfg.mode != "ranging" or ctx.sensors.size == 0:
        return w
    delta = world.model(start, xy, ctx)
    s = eq1_weights(delta, ctx.meas, world.sensor.max_range_m)
    return s if cfg.weighting == "set" else w * s**cfg.eq1_power


def _girard_step(world: _World, cfg: ParticleConfig, xy, w, ctx: _StepCtx, g):
    """Steps 3-7 of Girard §3.2 for one step event; None when every particle died."""
    v = sample_motion_vectors(ctx.vec, cfg.eps_m, cfg.kappa, g)  # step 3
    n, kap = xy.shape[0], v.shape[0]
    parent = np.repeat(xy, kap, axis=0)  # step 4
    child = parent + np.tile(v, (n, 1))
    cw = np.repeat(w, kap)
    if world.use_plan:
        alive = world.inside(child)
        if not np.any(alive):
            return None
        alive[alive] = ~world.crosses(parent[alive], child[alive])
        child, cw, parent = child[alive], cw[alive], parent[alive]
        if child.shape[0] == 0:
            return None
    if cfg.tau_m > 0.0:  # step 5
        keep, cw = world.K.merge_close(child[:, 0], child[:, 1], cw, cfg.tau_m)
        child, parent = child[keep], parent[keep]
    cw = _girard_weights(world, cfg, parent, child, cw, ctx)  # step 6
    if not np.any(cw > 0.0):
        return None
    best = keep_best(cw, cfg.n_particles, g)  # step 7
    return child[best], cw[best]


def _reinit(world: _World, cfg: ParticleConfig, est: np.ndarray, ctx: _StepCtx, g):
    """Restart the cloud around the last estimate moved by the step; record the event."""
    center = est + ctx.vec
    n_try = max(cfg.n_particles, 1000)
    cand_all_out = world.use_plan and not np.any(
        world.inside(_disc(est + ctx.vec, cfg.eps_m, 64, g))
    )
    if cand_all_out:
        kind = "left_map"
        msg = (
            f"step {ctx.k + 1} (t = {ctx.t_s:g} s): every hypothesis left the floor plan "
            f"near ({center[0]:.2f}, {center[1]:.2f}) m; re-initialised around the last "
            "estimate"
        )
        center = est.copy()
    else:
        kind = "all_died"
        msg = (
            f"step {ctx.k + 1} (t = {ctx.t_s:g} s): every particle was eliminated; "
            f"re-initialised within {cfg.reinit_radius_m:g} m of "
            f"({center[0]:.2f}, {center[1]:.2f}) m"
        )
    xy = _disc(center, cfg.reinit_radius_m, n_try, g)
    if world.use_plan:
        xy = xy[world.inside(xy)]
        if xy.shape[0] == 0:
            xy = est[None, :].copy()
    w = np.ones(xy.shape[0])
    if cfg.method == "girard" and cfg.tau_m > 0.0:
        keep, w = world.K.merge_close(xy[:, 0], xy[:, 1], w, cfg.tau_m)
        xy = xy[keep]
    if cfg.method == "girard":
        w = _girard_weights(world, cfg, xy, xy, w, ctx)
        if not np.any(w > 0.0):
            w = np.ones(xy.shape[0])
        best = keep_best(w, cfg.n_particles, g)
        xy, w = xy[best], w[best]
    else:
        if xy.shape[0] > cfg.n_particles:
            xy = xy[: cfg.n_particles]
        w = _sir_likelihood(world, cfg, xy, xy, ctx)
        if not np.any(w > 0.0):
            w = np.ones(xy.shape[0])
    return xy, w, ParticleEvent(ctx.k + 1, ctx.t_s, kind, msg)


# ------------------------------------------------------------------------------- SIR


def _sir_likelihood(world: _World, cfg: ParticleConfig, start, xy, ctx: _StepCtx) -> np.ndarray:
    """Product over the step's readings of the SRF02 mixture likelihood (see Notes),
    compiled (``_particle_kernels.sir_likelihood``); :func:`_sir_likelihood_reference`'s
    numbers bit for bit."""
    n = xy.shape[0]
    if cfg.mode != "ranging" or ctx.sensors.size == 0:
        return np.ones(n)
    s = world.sensor
    delta = world.model(start, xy, ctx)
    return world.K.sir_likelihood(
        delta, ctx.meas, bias=_slip_bias(s), sig=math.hypot(s.noise_sigma_m, cfg.range_sigma_m),
        p_outlier=cfg.p_outlier, p_miss=cfg.p_miss, dmax=s.max_range_m,
    )  # fmt: skip


def _slip_bias(s: SRF02) -> float:
    """Mean range added by the SRF02 model's slips, m."""
    return s.slip_step_m * sum((i + 1) * p for i, p in enumerate(s.slip_probs))


def _sir_likelihood_reference(
    world: _World, cfg: ParticleConfig, start, xy, ctx: _StepCtx
) -> np.ndarray:
    """numpy reference of :func:`_sir_likelihood`."""
    n = xy.shape[0]
    if cfg.mode != "ranging" or ctx.sensors.size == 0:
        return np.ones(n)
    s = world.sensor
    delta = world.model(start, xy, ctx)
    sig = math.hypot(s.noise_sigma_m, cfg.range_sigma_m)
    bias = _slip_bias(s)
    dmax = s.max_range_m
    like = np.ones(n)
    for j in range(ctx.sensors.size):
        d = delta[:, j]
        seen = np.isfinite(d)
        z = ctx.meas[j]
        if math.isnan(z):
            lj = np.where(seen, cfg.p_miss, 1.0 - cfg.p_miss)
        else:
            r = np.where(seen, (z - d - bias) / sig, 0.0)
            gauss = np.exp(-0.5 * r * r) / (sig * math.sqrt(2.0 * math.pi))
            lj = np.where(seen, (1.0 - cfg.p_outlier) * gauss, 0.0) + cfg.p_outlier / dmax
        like *= lj
    return like


def _sir_draws(cfg: ParticleConfig, n: int, ctx: _StepCtx, g):
    """Each particle's step length and heading (the SIR motion model)."""
    hs = ctx.heading_sigma
    sig_h = cfg.heading_sigma_rad if math.isnan(hs) else math.hypot(hs, cfg.heading_sigma_rad)
    length = ctx.length + cfg.step_sigma_m * g.standard_normal(n)
    head = ctx.heading + sig_h * g.standard_normal(n)
    return length, head


def _sir_step(world: _World, cfg: ParticleConfig, xy, w, ctx: _StepCtx, g):
    """Propagate, eliminate wall crossings, weight; None when every particle died.
    Compiled (``_particle_kernels.sir_move``, :func:`_sir_likelihood`); the numbers of
    :func:`_sir_step_reference` bit for bit."""
    length, head = _sir_draws(cfg, xy.shape[0], ctx, g)
    bounds = world.bounds if world.use_plan else None
    new, w, any_inside = world.K.sir_move(xy, w, length, head, bounds=bounds, grid=world.grid)
    if not any_inside:
        return None
    w = w * _sir_likelihood(world, cfg, xy, new, ctx)
    live = w > 0.0
    if not np.any(live):
        return None
    return new[live], w[live]


def _sir_step_reference(world: _World, cfg: ParticleConfig, xy, w, ctx: _StepCtx, g):
    """numpy reference of :func:`_sir_step`."""
    length, head = _sir_draws(cfg, xy.shape[0], ctx, g)
    new = xy + np.column_stack([length * np.cos(head), length * np.sin(head)])
    w = w.copy()
    if world.use_plan:
        alive = world.inside(new)
        if not np.any(alive):
            return None
        alive[alive] = ~world.crosses(xy[alive], new[alive])
        w[~alive] = 0.0
    w = w * _sir_likelihood_reference(world, cfg, xy, new, ctx)
    live = w > 0.0
    if not np.any(live):
        return None
    return new[live], w[live]


def _kld_bound(k: np.ndarray, eps: float, delta: float) -> np.ndarray:
    """Fox 2003 sample-size bound for k occupied bins (Wilson-Hilferty chi-square)."""
    from scipy.special import ndtri  # the normal quantile (what scipy.stats.norm.ppf calls)

    z = ndtri(1.0 - delta)
    km1 = np.maximum(k - 1, 1).astype(np.float64)
    a = 2.0 / (9.0 * km1)
    return km1 / (2.0 * eps) * (1.0 - a + np.sqrt(a) * z) ** 3


def _sir_resample(world: _World, cfg: ParticleConfig, xy, w, g):
    """Systematic resampling, roughening (compiled: ``_particle_kernels.sir_resample``)
    and, optionally, KLD-sampling; the same numbers as :func:`_sir_resample_reference`."""
    n_target = cfg.n_particles
    ess = 1.0 / np.sum(w * w)
    if not cfg.kld and ess >= cfg.resample_ess * xy.shape[0] and xy.shape[0] == n_target:
        return xy, w
    new = world.K.sir_resample(
        xy, w, n_target, g, roughening=cfg.roughening,
        bounds=world.bounds if world.use_plan else None, grid=world.grid,
    )  # fmt: skip
    return _kld(cfg, new, g)


def _sir_resample_reference(world: _World, cfg: ParticleConfig, xy, w, g):
    """numpy reference of :func:`_sir_resample` (equal bit for bit, tested)."""
    n_target = cfg.n_particles
    ess = 1.0 / np.sum(w * w)
    if not cfg.kld and ess >= cfg.resample_ess * xy.shape[0] and xy.shape[0] == n_target:
        return xy, w
    u = (g.random() + np.arange(n_target)) / n_target
    idx = np.minimum(np.searchsorted(np.cumsum(w), u, side="right"), w.size - 1)
    new = xy[idx]
    if cfg.roughening > 0.0 and new.shape[0] > 1:
        extent = new.max(axis=0) - new.min(axis=0)
        sig = cfg.roughening * extent * new.shape[0] ** (-0.5)
        moved = new + sig[None, :] * g.standard_normal(new.shape)
        if world.use_plan:
            bad = ~world.inside(moved)
            ok = ~bad
            bad[ok] = world.crosses(new[ok], moved[ok])
            moved[bad] = new[bad]
        new = moved
    return _kld(cfg, new, g)


def _kld(cfg: ParticleConfig, new: np.ndarray, g):
    """KLD-sampling of the resampled cloud's size (Fox 2003), when ``cfg.kld``."""
    n_target = cfg.n_particles
    if cfg.kld:
        new = new[g.permutation(new.shape[0])]
        b = np.floor(new / cfg.kld_bin_m).astype(np.int64)
        _, first = np.unique(b, axis=0, return_index=True)
        is_first = np.zeros(new.shape[0], dtype=bool)
        is_first[first] = True
        k = np.cumsum(is_first)
        m = np.arange(1, new.shape[0] + 1)
        need = _kld_bound(k, cfg.kld_epsilon, cfg.kld_delta)
        ok = (m >= need) & (m >= min(cfg.kld_min_particles, n_target))
        cut = int(np.argmax(ok)) + 1 if np.any(ok) else new.shape[0]
        new = new[:cut]
    return new, np.full(new.shape[0], 1.0 / new.shape[0])
