"""DUHL: robot pose tracking from ceiling ultrasonic Txs and wheel odometry (Kim & Kim 2013).

The robot pose ``[x, y, phi]`` is an EKF state (§III). Odometry of a differential drive
predicts it (eq (14), covariance eq (16)); a UHL pose (§II-B, :mod:`rangekit.localize.uhl`)
corrects it with an identity observation (eqs (15), (17)-(20)) whose covariance is
propagated from the distance estimates (eq (21)). The distances fed to UHL are not the
raw measurements, which come one Tx at a time at different poses, but *dynamic
distance estimates* (§IV): every Tx heard recently has three distances ``q^i`` and a
covariance ``Q^i`` that odometry predicts (eqs (22)-(24)), that a new measurement of
that Tx corrects (eqs (25)-(27)), that a newly heard Tx gets from the current pose
(eqs (28)-(30)), and that are discarded when ``max diag Q^i`` exceeds a threshold
(eqs (31)-(32)).

:func:`track_duhl` runs the whole filter over a log in one compiled call
(:func:`track_log` on a log file's contents); :func:`track_rows` is its table and
:func:`track_report` what ``rangekit track duhl`` prints; :func:`uhl_last_two` is the
paper's baseline, UHL on the raw distances of the last two Txs heard.

Examples
--------
A robot standing still under two Txs, heard in turn:

>>> import numpy as np
>>> from rangekit.sim.ultrasonic import receiver_positions
>>> tx = np.array([[0.0, 0.0, 2.0], [2.0, 0.0, 2.0]])
>>> rx = receiver_positions((1.0, 0.8, 0.3))
>>> d = np.linalg.norm(tx[:, None, :] - rx[None, :, :], axis=2)
>>> t = np.arange(0.0, 2.0, 0.01)
>>> dt_ = t[20::20]
>>> trk = track_duhl(t, np.zeros_like(t), np.zeros_like(t), dt_, np.arange(len(dt_)) % 2,
...                  d[np.arange(len(dt_)) % 2], tx, tx_ids=[0, 1])
>>> np.round(trk.pose[-1], 6).tolist()
[1.0, 0.8, 0.3]
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rangekit import _validate as V
from rangekit.errors import IncompatibleInputError, InvalidParameterError, LogFormatError
from rangekit.localize import _duhl_kernels as K
from rangekit.localize._uhl_kernels import uhl_core
from rangekit.localize.ekf import chi2_gate
from rangekit.localize.uhl import DEFAULT_D_TH_M, R_R_M

__all__ = [
    "DEFAULT_DISCARD_VAR_M2",
    "OBS_STATUS",
    "PIONEER_WHEEL_BASE_M",
    "TRACK_COLUMNS",
    "VARIANTS",
    "DUHLConfig",
    "DUHLTrack",
    "ObservationCounts",
    "UHLLastTwo",
    "rig_inputs",
    "track_duhl",
    "track_log",
    "track_report",
    "track_rows",
    "uhl_last_two",
]

#: Distance between the drive wheels ``B_w`` of a Pioneer P3-DX (m): the value used in
#: the P3-DX kinematic models (e.g. the ROS/Gazebo description); the paper gives none.
PIONEER_WHEEL_BASE_M = 0.33
#: Default discard threshold of eq (32) on ``max diag Q^i`` (m^2), chosen by simulation
#: (see ``docs/theory/kim2013.md``); the paper determines it experimentally.
DEFAULT_DISCARD_VAR_M2 = 0.012**2
#: Accepted ranges (m) of :class:`DUHLConfig`'s wheel base, receiver radius, odometry
#: noise and distance sigma: a robot from a toy to a truck, receivers within 100 m of
#: the centre, sigma from a micrometre to 10 m (outside them the arithmetic over- or
#: underflows into NaN poses, issue 17).
WHEEL_BASE_RANGE_M = (1e-3, 100.0)
R_R_RANGE_M = (1e-4, 100.0)
K_V_RANGE_M = (0.0, 1.0)
SIGMA_D_RANGE_M = (1e-6, 10.0)
#: Largest wheel speed (m/s) and coordinate or distance (m) :func:`track_duhl` accepts.
MAX_SPEED_MPS = 100.0
MAX_COORD_M = 1e6
#: Filters of :class:`DUHLConfig`.
VARIANTS = ("duhl", "ranges")
#: The ``rangekit track`` subcommand of each variant (the filter's name in reports).
FILTER_NAMES = {"duhl": "duhl", "ranges": "duhl-ranges"}
#: Columns of :func:`track_rows` (the ``rangekit track duhl`` and ``duhl-ranges`` output).
TRACK_COLUMNS = (
    "t_s", "x_m", "y_m", "heading_rad", "var_x_m2", "var_y_m2", "var_heading_rad2", "status",
)  # fmt: skip
#: Meaning of :attr:`DUHLTrack.obs_status` codes.
OBS_STATUS = {
    K.OBS_USED: "used",
    K.OBS_TOO_FEW: "fewer than 2 transmitters",
    K.OBS_DEGENERATE: "transmitters at one point",
    K.OBS_RESIDUAL: "UHL residual too large",
    K.OBS_GATED: "gated",
    K.OBS_EMPTY: "no finite distance",
    K.OBS_BEFORE_START: "before start",
}


@dataclass(frozen=True)
class DUHLConfig:
    """Parameters of :func:`track_duhl` (defaults: Kim & Kim 2013 §V).

    Attributes
    ----------
    wheel_base_m : float
        ``B_w`` of eq (14).
    r_R_m : float
        Receiver radius on the robot.
    k_v_m : float
        Odometry noise: ``sigma_v^2 = k_v |v| / Delta T_s`` per wheel (§V, 4e-4 m).
    sigma_d_m : float
        Distance measurement 1-sigma, eq (27) (§V: 0.01 m).
    discard_var_m2 : float
        Threshold of eq (32) on ``max diag Q^i``.
    d_th_m : float
        Hybrid threshold of UHL, Table I.
    variant : {"duhl", "ranges"}
        ``"duhl"``: the paper's filter. ``"ranges"``: a tightly coupled EKF for
        comparison, the same odometry prediction but each distance row corrects the pose
        directly through the distances of eq (28) (no dynamic distance estimation, no
        UHL); see Notes of :func:`track_duhl`.
    max_residual_m : float
        Reject a UHL observation whose RMS distance residual exceeds this (a guard the
        paper does not have; inconsistent distances give a meaningless pose).
    gate_prob : float or None
        Chi-square gate probability (3 dof) on the innovation of each distance
        correction (eq (25); for ``"ranges"`` the pose correction by the distances) and
        of the pose correction (eq (18)); a gated row is refused and flagged. ``None``:
        no gate (the paper).
    init_sigma : tuple of 3 floats
        1-sigma of the start pose ``(m, m, rad)`` when it comes from a UHL solve of the
        first two Txs heard (see :func:`track_duhl`).
    """

    wheel_base_m: float = PIONEER_WHEEL_BASE_M
    r_R_m: float = R_R_M
    k_v_m: float = 4e-4
    sigma_d_m: float = 0.01
    discard_var_m2: float = DEFAULT_DISCARD_VAR_M2
    d_th_m: float = DEFAULT_D_TH_M
    variant: str = "duhl"
    max_residual_m: float = 0.1
    gate_prob: float | None = None
    init_sigma: tuple[float, float, float] = (0.3, 0.3, math.radians(20.0))

    def __post_init__(self) -> None:
        # physical bounds (issue 17): beyond them the filter's arithmetic under- or
        # overflows and the poses come out NaN, so they are refused, not run
        V.in_range("wheel_base_m", self.wheel_base_m, *WHEEL_BASE_RANGE_M)
        V.in_range("r_R_m", self.r_R_m, *R_R_RANGE_M)
        V.in_range("k_v_m", self.k_v_m, *K_V_RANGE_M)
        V.in_range("sigma_d_m", self.sigma_d_m, *SIGMA_D_RANGE_M)
        V.positive("discard_var_m2", self.discard_var_m2)
        V.positive("d_th_m", self.d_th_m, allow_zero=True)
        V.positive("max_residual_m", self.max_residual_m)
        if self.variant not in VARIANTS:
            raise InvalidParameterError(f"variant={self.variant!r} must be one of {VARIANTS}")
        if self.gate_prob is not None and not 0.0 < self.gate_prob < 1.0:
            raise InvalidParameterError(f"gate_prob={self.gate_prob!r} must be in (0, 1)")
        s = np.asarray(self.init_sigma, dtype=np.float64)
        if s.shape != (3,) or not np.all(np.isfinite(s)) or np.any(s <= 0.0):
            raise InvalidParameterError(
                f"init_sigma={self.init_sigma!r} must be three positive numbers (m, m, rad)"
            )


@dataclass(frozen=True)
class ObservationCounts:
    """What became of a track's distance rows (:meth:`DUHLTrack.observation_counts`).

    Attributes
    ----------
    n_rows : int
        Distance rows in the log.
    used : int
        Rows whose observation corrected the pose.
    rejected : int
        Rows whose observation was rejected, as status bit 4 counts them: UHL undefined
        (transmitters at one point), residual too large, gated.
    without : int
        Rows that gave no observation (fewer than 2 transmitters, no finite distance).
    before_start : int
        Rows before the filter's start.
    """

    n_rows: int
    used: int
    rejected: int
    without: int
    before_start: int


@dataclass
class DUHLTrack:
    """Result of :func:`track_duhl`.

    Attributes
    ----------
    t_s : ndarray (n,)
        Odometry times; one pose per odometry row.
    pose : ndarray (n, 3)
        ``[x, y, phi]`` after the row's prediction and any correction (NaN before the
        start row).
    cov : ndarray (n, 3, 3)
        Pose covariance.
    status : ndarray (n,) of int
        Bit set: 1 observation applied, 2 a distance row came with fewer than 2 usable
        Txs (prediction only), 4 an observation was rejected, 8 the odometry sample was
        missing (no motion applied).
    obs_t_s, obs_tx : ndarray (m,)
        Time and Tx id of each distance row.
    obs_pose, obs_cov : ndarray (m, 3), (m, 3, 3)
        The UHL observation made at that row and its covariance ``R_k`` (NaN if none).
    obs_n_tx : ndarray (m,) of int
        Txs in the available set after the discard step.
    obs_status : ndarray (m,) of int
        See :data:`OBS_STATUS`.
    start_index : int
        Odometry row where the filter started.
    warnings : list of str
        Plain-language notes: long stretches without an observation, rejected rows.
    config : DUHLConfig or None
        The parameters used (set by :func:`track_duhl`).
    """

    t_s: np.ndarray
    pose: np.ndarray
    cov: np.ndarray
    status: np.ndarray
    obs_t_s: np.ndarray
    obs_tx: np.ndarray
    obs_pose: np.ndarray
    obs_cov: np.ndarray
    obs_n_tx: np.ndarray
    obs_status: np.ndarray
    start_index: int
    warnings: list[str] = field(default_factory=list)
    config: DUHLConfig | None = None

    @property
    def n_observations(self) -> int:
        """Number of UHL observations applied."""
        return int(np.count_nonzero(self.obs_status == K.OBS_USED))

    def observation_counts(self) -> ObservationCounts:
        """How many distance rows were used, rejected, gave no observation or came
        before the start (:data:`OBS_STATUS` grouped).

        Examples
        --------
        >>> st = np.array([K.OBS_BEFORE_START, K.OBS_USED, K.OBS_GATED, K.OBS_TOO_FEW])
        >>> trk = DUHLTrack(*[np.zeros(1)] * 9, st, 0)
        >>> trk.observation_counts()
        ObservationCounts(n_rows=4, used=1, rejected=1, without=1, before_start=1)
        """
        st = self.obs_status
        m = int(st.size)
        used = int(np.count_nonzero(st == K.OBS_USED))
        rejected = int(
            np.count_nonzero(np.isin(st, (K.OBS_DEGENERATE, K.OBS_RESIDUAL, K.OBS_GATED)))
        )
        before = int(np.count_nonzero(st == K.OBS_BEFORE_START))
        return ObservationCounts(m, used, rejected, m - used - rejected - before, before)


@dataclass
class UHLLastTwo:
    """Result of :func:`uhl_last_two`: one pose per distance row that completes a pair."""

    t_s: np.ndarray
    pose: np.ndarray
    row: np.ndarray


def _as_1d(name: str, v, n: int | None = None) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    if a.ndim != 1 or (n is not None and a.shape[0] != n):
        want = f"({n},)" if n is not None else "(n,)"
        raise InvalidParameterError(f"{name} must have shape {want}, got {a.shape}")
    return a


def _tx_index(tx_ids, dist_tx: np.ndarray, n_tx: int) -> np.ndarray:
    ids = np.arange(n_tx) if tx_ids is None else np.asarray(tx_ids)
    if ids.shape != (n_tx,):
        raise InvalidParameterError(f"tx_ids must have shape ({n_tx},), got {ids.shape}")
    if len(np.unique(ids)) != n_tx:
        raise InvalidParameterError("tx_ids contains duplicate ids")
    lookup = {int(v): i for i, v in enumerate(ids.tolist())}
    out = np.empty(len(dist_tx), dtype=np.int64)
    for r, v in enumerate(dist_tx.tolist()):
        if int(v) not in lookup:
            raise InvalidParameterError(
                f"distance row {r}: transmitter {int(v)} is not among the beacons {sorted(lookup)}"
            )
        out[r] = lookup[int(v)]
    return out


class _MeasurementError(InvalidParameterError):
    """A problem of the measurements (odometry and distances), not of a setting:
    :func:`track_log` reports it as the log's (:class:`~rangekit.errors.LogFormatError`,
    the log named); :func:`track_duhl`'s callers see an InvalidParameterError."""


def _check_inputs(odo_t, v_right, v_left, dist_t, dist_tx, dist_d, tx_xyz):
    E = _MeasurementError
    odo_t = _as_1d("odo_t", odo_t)
    n = len(odo_t)
    if n == 0:
        raise E("the log has no odometry rows")
    if not np.all(np.isfinite(odo_t)) or np.any(np.diff(odo_t) < 0.0):
        raise E("odo_t must be finite and non-decreasing")
    vr = _as_1d("v_right", v_right, n)
    vl = _as_1d("v_left", v_left, n)
    dist_t = _as_1d("dist_t", dist_t)
    m = len(dist_t)
    if not np.all(np.isfinite(dist_t)) or np.any(np.diff(dist_t) < 0.0):
        raise E("dist_t must be finite and non-decreasing")
    dist_tx = np.asarray(dist_tx)
    if dist_tx.shape != (m,) or (m and not np.issubdtype(dist_tx.dtype, np.integer)):
        raise E(f"dist_tx must be {m} integer Tx ids, got {dist_tx!r}")
    d = np.asarray(dist_d, dtype=np.float64).reshape(-1, 3) if m else np.empty((0, 3))
    if d.shape != (m, 3):
        raise E(f"dist_d must have shape ({m}, 3), got {np.shape(dist_d)}")
    if np.any(np.isinf(d)) or np.any(d < 0.0):
        raise E("dist_d must be >= 0 (NaN marks a missed receiver)")
    tx = np.asarray(tx_xyz, dtype=np.float64)
    if tx.ndim != 2 or tx.shape[1] != 3 or tx.shape[0] < 2:
        raise InvalidParameterError(f"tx_xyz must have shape (n >= 2, 3), got {tx.shape}")
    if not np.all(np.isfinite(tx)):
        raise InvalidParameterError("tx_xyz contains NaN or infinite values")
    for name, v, lim in (("v_right", vr, MAX_SPEED_MPS), ("v_left", vl, MAX_SPEED_MPS),
                         ("dist_d", d, MAX_COORD_M), ("tx_xyz", tx, MAX_COORD_M)):  # fmt: skip
        big = np.abs(np.nan_to_num(v)) > lim
        if np.any(big):
            raise (InvalidParameterError if name == "tx_xyz" else E)(
                f"{name} has a value of {v[big].flat[0]:.3g}, beyond +-{lim:g} (the filter's "
                "arithmetic would overflow)"
            )
    return odo_t, vr, vl, dist_t, dist_tx, d, tx


def _start_from_uhl(odo_t, dist_t, idx, d, tx, config) -> tuple[int, np.ndarray] | None:
    """First pose: UHL on the raw distances of the first two distinct Txs fully heard."""
    last: dict[int, int] = {}
    for r in range(len(dist_t)):
        if not np.all(np.isfinite(d[r])):
            continue
        last[int(idx[r])] = r
        if len(last) >= 2:
            rows = sorted(last.values())[-2:]
            ti = idx[rows]
            x, y, phi, _, _, ok = uhl_core(tx[ti], d[rows], config.r_R_m, 0, config.d_th_m)
            if ok:
                k = int(np.searchsorted(odo_t, dist_t[r], side="left"))
                return min(k, len(odo_t) - 1), np.array([x, y, phi])
    return None


def track_duhl(
    odo_t,
    v_right,
    v_left,
    dist_t,
    dist_tx,
    dist_d,
    tx_xyz,
    *,
    tx_ids=None,
    config: DUHLConfig | None = None,
    initial_pose=None,
    initial_cov=None,
) -> DUHLTrack:
    """Track a robot pose with DUHL (Kim & Kim 2013 §III-IV).

    Parameters
    ----------
    odo_t : array_like (n,)
        Odometry times (s), non-decreasing; the velocities of row ``k`` act over
        ``(odo_t[k-1], odo_t[k]]``.
    v_right, v_left : array_like (n,)
        Measured wheel velocities (m/s). NaN marks a missing sample (no motion applied,
        flagged in :attr:`DUHLTrack.status`).
    dist_t : array_like (m,)
        Times of the distance rows (s), non-decreasing.
    dist_tx : array_like of int (m,)
        Tx id of each distance row (an id of ``tx_ids``).
    dist_d : array_like (m, 3)
        Distances (m) from that Tx to receivers 0°, 120°, 240°; NaN = receiver missed.
    tx_xyz : array_like (n_tx, 3)
        Tx positions (m) on the ceiling.
    tx_ids : array_like of int (n_tx,), optional
        Ids of the rows of ``tx_xyz`` (default ``0 .. n_tx - 1``).
    config : DUHLConfig, optional
    initial_pose : (x, y, phi), optional
        The a-priori start pose of the paper, at the first odometry row. Without it the
        filter starts at the first distance row that completes a pair of distinct Txs,
        from UHL on those two raw distance rows, with covariance ``diag(init_sigma^2)``.
    initial_cov : array_like (3, 3), optional
        Covariance of ``initial_pose`` (default ``diag((0.05 m)^2, (0.05 m)^2,
        (2 deg)^2)``).

    Returns
    -------
    DUHLTrack

    Raises
    ------
    InvalidParameterError
        Bad shapes, times going backwards, unknown Tx ids, negative distances, fewer
        than 2 Txs, or no start pose (no ``initial_pose`` and never two Txs heard).

    Notes
    -----
    Choices where the paper is silent or ambiguous (see ``docs/theory/kim2013.md``):

    * ``J_f,u`` of eq (16) is printed with ``Delta T_s / R``; we use the chain rule through
      ``(Delta D, Delta phi)``, ``d Delta D / d v = Delta T_s / 2`` and
      ``d Delta phi / d v_{R,L} = +-Delta T_s / B_w``.
    * Eq (23) takes ``rho`` and ``theta`` from the EKF pose before the step, so
      ``J_g,q`` is the diagonal ``1 - (alpha - beta) / q^2``.
    * A distance row is processed after the odometry rows up to its time; the UHL
      observation is made after every distance row (5 Hz), after the discard step.
    * Missed receivers (NaN) are left out of the eq (25) correction; a row with no
      finite distance is ignored.
    * ``J_z,q^i`` of eq (21) is the least-squares sensitivity ``(H^T H)^-1 H_i^T`` of the
      pose to the distances (``H`` the stacked eq (22) partials at the UHL pose).
    * ``variant="ranges"`` is not in the paper: it skips §IV and UHL and corrects the
      pose with each Tx's three distances through eq (28) (an EKF with a nonlinear
      observation, the approach the paper argues against). It is the reference that
      shows what the dynamic distance estimates cost: their covariance ``Q^i`` (eq (24))
      holds only the odometry noise, not the pose error that enters eq (23) through
      ``rho`` and ``theta``, nor the correlation between ``q^i`` and the pose, so
      DUHL's ``R_k`` is too small (measured in ``docs/theory/kim2013.md``).
    * With fewer than two Txs in the available set the filter keeps predicting from
      odometry; each such row is flagged and stretches longer than 2 s are listed in
      :attr:`DUHLTrack.warnings`.
    """
    config = DUHLConfig() if config is None else config
    if not isinstance(config, DUHLConfig):
        raise InvalidParameterError(f"config must be a DUHLConfig, got {type(config).__name__}")
    odo_t, vr, vl, dist_t, dist_tx, d, tx = _check_inputs(
        odo_t, v_right, v_left, dist_t, dist_tx, dist_d, tx_xyz
    )
    idx = _tx_index(tx_ids, dist_tx, tx.shape[0])
    ids = np.arange(tx.shape[0]) if tx_ids is None else np.asarray(tx_ids)

    if initial_pose is not None:
        x0 = _as_1d("initial_pose", initial_pose, 3)
        if not np.all(np.isfinite(x0)):
            raise InvalidParameterError(f"initial_pose={initial_pose!r} must be finite")
        if initial_cov is None:
            p0 = np.diag([0.05**2, 0.05**2, math.radians(2.0) ** 2])
        else:
            p0 = np.asarray(initial_cov, dtype=np.float64)
            if p0.shape != (3, 3) or not np.all(np.isfinite(p0)):
                raise InvalidParameterError("initial_cov must be a finite (3, 3) matrix")
            if not np.allclose(p0, p0.T) or np.linalg.eigvalsh(p0).min() < 0.0:
                raise InvalidParameterError("initial_cov must be symmetric positive semidefinite")
        start = 0
    else:
        if initial_cov is not None:
            raise InvalidParameterError("initial_cov needs initial_pose")
        found = _start_from_uhl(odo_t, dist_t, idx, d, tx, config)
        if found is None:
            raise _MeasurementError(
                "no start pose: no two distinct transmitters were heard on all three "
                "receivers (give the initial pose)"
            )
        start, x0 = found
        p0 = np.diag(np.asarray(config.init_sigma, dtype=np.float64) ** 2)

    gate = chi2_gate(config.gate_prob, 3) if config.gate_prob is not None else 0.0
    poses, covs, status, obs_pose, obs_cov, obs_ntx, obs_status = K.run_duhl(
        odo_t,
        vr,
        vl,
        dist_t,
        idx,
        d,
        tx,
        start,
        x0,
        p0,
        float(config.wheel_base_m),
        float(config.k_v_m),
        float(config.r_R_m),
        float(config.sigma_d_m),
        float(config.discard_var_m2),
        float(config.d_th_m),
        config.variant == "ranges",
        float(config.max_residual_m),
        float(gate),
    )
    bad = ~np.all(np.isfinite(poses), axis=1) | ~np.all(np.isfinite(covs), axis=(1, 2))
    bad[:start] = False  # rows before the start pose are NaN by definition
    if np.any(bad):
        k = int(np.argmax(bad))
        raise IncompatibleInputError(
            f"the {config.variant} filter diverged at t_s={odo_t[k]:g} (non-finite pose); "
            "the noise settings do not fit this log"
        )
    track = DUHLTrack(
        t_s=odo_t,
        pose=poses,
        cov=covs,
        status=status,
        obs_t_s=dist_t,
        obs_tx=ids[idx] if len(idx) else np.empty(0, dtype=np.int64),
        obs_pose=obs_pose,
        obs_cov=obs_cov,
        obs_n_tx=obs_ntx,
        obs_status=obs_status,
        start_index=start,
        config=config,
    )
    track.warnings = _warnings(track)
    return track


def track_log(
    log,
    beacons,
    *,
    config: DUHLConfig | None = None,
    initial_pose=None,
    initial_cov=None,
    name: str | None = None,
    beacon_file: str | None = None,
) -> DUHLTrack:
    """:func:`track_duhl` on a :class:`~rangekit.io.duhllog.DUHLLog` and its
    :class:`~rangekit.io.duhllog.Beacons` (what :func:`~rangekit.io.duhllog.read_duhl_log`
    and :func:`~rangekit.io.duhllog.read_beacons` return).

    ``name`` and ``beacon_file`` are the log's and the beacon file's names in error
    messages.

    Raises
    ------
    IncompatibleInputError
        A distance row names a transmitter the beacons lack (its time and id named), or
        the log has distances of more than three receivers.
    LogFormatError
        The filter cannot run on the log (``name`` first): no odometry rows, a value
        beyond the filter's arithmetic, or no start pose (no ``initial_pose``, and no two
        distinct transmitters heard on all three receivers).
    InvalidParameterError
        As :func:`track_duhl`, for the settings (``config``, ``initial_pose``,
        ``initial_cov``) and the beacons.

    Examples
    --------
    >>> from rangekit.io.duhllog import Beacons, DUHLLog, DistanceRows, OdometryRows
    >>> log = DUHLLog(OdometryRows(np.array([0.0, 0.1]), np.zeros(2), np.zeros(2)),
    ...               DistanceRows(np.array([0.05]), np.array([0]), np.ones((1, 3))))
    >>> bcn = Beacons(np.array([0, 1]), np.array([[0.0, 0.0, 2.5], [1.0, 0.0, 2.5]]))
    >>> track_log(log, bcn, name="run.csv")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    rangekit.errors.LogFormatError: run.csv: the filter cannot run on this log: no start pose: ...
    """
    o, d = log.odometry, log.distances
    known = {int(i) for i in beacons.ids.tolist()}
    for t_s, tx in zip(d.t_s.tolist(), d.tx.tolist(), strict=True):
        if int(tx) not in known:
            where = f"the beacon file {beacon_file!r}" if beacon_file else "the beacons"
            raise IncompatibleInputError(
                f"{name or 'the log'}: the distance row at t_s={t_s:g} names transmitter "
                f"{int(tx)}, which is not in {where} (ids: {sorted(known)})"
            )
    d_m = d.d_m
    if d_m.ndim == 2 and d_m.shape[1] > 3:  # a log written for a rig with more tags
        if np.any(np.isfinite(d_m[:, 3:])):
            raise IncompatibleInputError(
                f"the log has distances in d4_m ... d{d_m.shape[1]}_m: DUHL's robot has three "
                "receivers (Kim & Kim 2013 eq (1)); use 'rangekit track range-ekf --rig'"
            )
        d_m = d_m[:, :3]
    try:
        return track_duhl(
            o.t_s,
            o.v_right_mps,
            o.v_left_mps,
            d.t_s,
            d.tx,
            d_m,
            beacons.xyz_m,
            tx_ids=beacons.ids,
            config=config,
            initial_pose=initial_pose,
            initial_cov=initial_cov,
        )
    except _MeasurementError as e:  # the measurements are the log's
        raise LogFormatError(f"{name or 'the log'}: the filter cannot run on this log: {e}") from e


def track_rows(track: DUHLTrack) -> tuple[tuple[str, ...], np.ndarray]:
    """:data:`TRACK_COLUMNS` and one row per odometry row from the start: time, pose,
    the pose covariance's diagonal, status bits (:attr:`DUHLTrack.status`).

    Examples
    --------
    >>> trk = DUHLTrack(np.array([0.0, 1.0]), np.ones((2, 3)), np.tile(np.eye(3), (2, 1, 1)),
    ...                 np.array([0, 1]), *[np.zeros(0)] * 6, start_index=1)
    >>> track_rows(trk)[1].tolist()
    [[1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]]
    """
    k0 = track.start_index
    cov = track.cov[k0:]
    rows = np.column_stack(
        [track.t_s[k0:], track.pose[k0:], cov[:, 0, 0], cov[:, 1, 1], cov[:, 2, 2],
         track.status[k0:]]
    )  # fmt: skip
    return TRACK_COLUMNS, rows


def track_report(track: DUHLTrack, *, log: str, beacons: str, initial_pose=None):
    """The track as ``rangekit track duhl`` (or ``duhl-ranges``) reports it: its rows, a
    summary of the distance rows' fate, the warnings, and in JSON the beacon file, the
    start, the parameters and the counts (:meth:`DUHLTrack.observation_counts`).

    Parameters
    ----------
    track : DUHLTrack
        A result of :func:`track_duhl` (it carries its config).
    log, beacons : str
        The log's and the beacon (or rig) file's names.
    initial_pose : sequence of 3 floats, optional
        The given start pose ``(x_m, y_m, heading_rad)``, as passed to :func:`track_log`.

    Returns
    -------
    rangekit.io.tracks.TrackReport
    """
    from rangekit.io.tracks import TrackReport

    if track.config is None:
        raise InvalidParameterError("track has no config (a DUHLTrack from track_duhl has)")
    config = track.config
    name = FILTER_NAMES[config.variant]
    columns, rows = track_rows(track)
    c = track.observation_counts()
    warnings = list(track.warnings)
    t0 = track.t_s[track.start_index]
    summary = (
        f"{name}: {rows.shape[0]} poses from t_s={t0:g}, {c.n_rows} distance rows: "
        f"{c.used} observations used, {c.rejected} rejected, {c.without} without an "
        f"observation, {c.before_start} before the start; {len(warnings)} warnings"
    )
    parameters = {
        "wheel_base_m": config.wheel_base_m,
        "sigma_d_m": config.sigma_d_m,
        "k_v_m": config.k_v_m,
        "gate": config.gate_prob,
    }
    extra = {
        "beacons": str(beacons),
        "start_t_s": float(t0),
        "initial_pose": None if initial_pose is None else [float(v) for v in initial_pose],
        "config": parameters,
        "n_distance_rows": c.n_rows,
        "n_observations": c.used,
        "n_rejected": c.rejected,
        "n_without_observation": c.without,
        "n_before_start": c.before_start,
        "warnings": warnings,
    }
    return TrackReport(name, str(log), columns, rows, extra=extra, summary=summary,
                       warnings=tuple(warnings), parameters=parameters)  # fmt: skip


def _warnings(track: DUHLTrack) -> list[str]:
    out: list[str] = []
    t = track.t_s[track.start_index :]
    if len(t) == 0:
        return out
    used = track.obs_t_s[track.obs_status == K.OBS_USED]
    marks = np.concatenate([[t[0]], used, [t[-1]]])
    gaps = np.diff(marks)
    for g in np.flatnonzero(gaps > 2.0):
        out.append(
            f"no observation for {gaps[g]:.1f} s from t={marks[g]:.2f} s: the pose was "
            "predicted from odometry only"
        )
    for code in (K.OBS_TOO_FEW, K.OBS_DEGENERATE, K.OBS_RESIDUAL, K.OBS_GATED, K.OBS_EMPTY):
        c = int(np.count_nonzero(track.obs_status == code))
        if c:
            out.append(f"{c} distance row(s) without an observation: {OBS_STATUS[code]}")
    return out


def uhl_last_two(
    dist_t,
    dist_tx,
    dist_d,
    tx_xyz,
    *,
    tx_ids=None,
    r_R: float = R_R_M,
    d_th: float = DEFAULT_D_TH_M,
) -> UHLLastTwo:
    """The paper's baseline: UHL on the raw distances of the last two distinct Txs heard.

    At every distance row with three finite distances, once another Tx has been heard
    before it, UHL (:func:`~rangekit.localize.uhl.solve_pose`, hybrid rule) is solved from
    this row and the latest full row of the most recent other Tx, with no motion
    compensation (Kim & Kim 2013 §V, Table II "UHL using the last 2 Txs").
    """
    dist_t = _as_1d("dist_t", dist_t)
    m = len(dist_t)
    d = np.asarray(dist_d, dtype=np.float64).reshape(-1, 3) if m else np.empty((0, 3))
    tx = np.asarray(tx_xyz, dtype=np.float64)
    if tx.ndim != 2 or tx.shape[1] != 3:
        raise InvalidParameterError(f"tx_xyz must have shape (n, 3), got {tx.shape}")
    idx = _tx_index(tx_ids, np.asarray(dist_tx), tx.shape[0])
    r_R = V.positive("r_R", r_R)
    last: dict[int, int] = {}
    ts, poses, rows = [], [], []
    for r in range(m):
        if not np.all(np.isfinite(d[r])):
            continue
        i = int(idx[r])
        others = [(row, a) for a, row in last.items() if a != i]
        last[i] = r
        if not others:
            continue
        prev = max(others)[0]
        sel = [prev, r]
        x, y, phi, _, _, ok = uhl_core(tx[idx[sel]], d[sel], float(r_R), 0, float(d_th))
        if ok:
            ts.append(dist_t[r])
            poses.append((x, y, phi))
            rows.append(r)
    return UHLLastTwo(
        t_s=np.asarray(ts, dtype=np.float64),
        pose=np.asarray(poses, dtype=np.float64).reshape(-1, 3),
        row=np.asarray(rows, dtype=np.int64),
    )


def rig_inputs(rig, log, *, name: str | None = None):
    """DUHL's inputs from a :class:`~rangekit.rig.Rig`: ``(beacons, log, config_kwargs)``.

    DUHL's robot is Kim & Kim 2013's (eq (1)): three receivers at 0°, 120°, 240° on one
    circle around the centre, at one height; the rig must describe that (a one-tag robot
    or another geometry goes to the range EKF, ``rangekit track range-ekf --rig``). The
    anchors become the beacons (their heights taken relative to the receivers'); a known
    ``bias_m`` is subtracted from that anchor's distances (DUHL estimates no bias);
    ``sigma_d_m`` is the largest anchor sigma, the wheel base and ``k_v`` those of the
    rig's differential drive.

    Raises
    ------
    IncompatibleInputError
        The rig is not a three-receiver circle, or has no differential drive.
    """
    from rangekit.errors import IncompatibleInputError
    from rangekit.io.duhllog import Beacons, DistanceRows, DUHLLog

    name = name or rig.name or "the rig"
    rig.require_anchors("DUHL (track duhl --rig)", source=name)
    if rig.odometry.kind != "differential-drive":
        raise IncompatibleInputError(
            f"{name}: DUHL needs differential-drive odometry (the rig has "
            f"{rig.odometry.kind!r}); use 'rangekit track range-ekf --rig'"
        )
    lv = rig.tag_lever_m
    rad = np.hypot(lv[:, 0], lv[:, 1]) if lv.size else np.zeros(0)
    ang = np.degrees(np.arctan2(lv[:, 1], lv[:, 0])) % 360 if lv.size else np.zeros(0)
    want = np.array([0.0, 120.0, 240.0])
    circle = (
        rig.n_tags == 3
        and rad.min() > 0
        and np.ptp(rad) < 1e-3
        and np.all(np.abs((ang - want + 180) % 360 - 180) < 0.5)
        and np.ptp(lv[:, 2]) < 1e-6
    )
    if not circle:
        raise IncompatibleInputError(
            f"{name}: DUHL needs three receivers at 0, 120, 240 degrees on one circle "
            f"(Kim & Kim 2013 eq (1)); the rig has {rig.n_tags} tag(s) "
            "elsewhere, use 'rangekit track range-ekf --rig'"
        )
    xyz = rig.anchor_xyz_m.copy()
    xyz[:, 2] -= lv[0, 2]
    beacons = Beacons(rig.anchor_ids, xyz)
    d = log.distances
    bias = {int(i): float(b) for i, b in zip(rig.anchor_ids, rig.anchor_bias_m, strict=True)}
    corr = np.array([bias.get(int(t), 0.0) for t in d.tx])[:, None]
    log = DUHLLog(log.odometry, DistanceRows(d.t_s, d.tx, d.d_m - corr))
    cfg = {
        "wheel_base_m": rig.odometry.wheel_base_m,
        "k_v_m": rig.odometry.k_v_m,
        "sigma_d_m": float(np.max(rig.anchor_sigma_m)),
        "r_R_m": float(rad.mean()),
    }
    return beacons, log, cfg
