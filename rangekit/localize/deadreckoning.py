"""Dead reckoning of a mobile robot with accelerometer-bias states (Ahn & Yu, §2).

A six-state extended Kalman filter, state ``[x, y, v_x, v_y, δa_x, δa_y]`` (m, m/s,
m/s²), driven by the measured world-frame acceleration (accelerometer output combined with
the heading, Ahn & Yu eq (3) and (7)) and corrected by the odometer's squared speed
(Ahn & Yu eq (2)). The steps are :func:`rangekit.localize.ekf.predict` and
:func:`rangekit.localize.ekf.update`; :func:`dead_reckon` runs a whole log, optionally
followed by :func:`rangekit.localize.ekf.rts_smooth`. :func:`read_imu_log` and
:func:`track_log` read the IMU log format below (``docs/theory/ahn2007.md``).

IMU log format (CSV, ``#`` lines are comments)::

    t_s      time of the row (s), required, non-decreasing
    ax_mps2  measured acceleration along the world x axis (m/s²), required
    ay_mps2  measured acceleration along the world y axis (m/s²), required
    speed_mps  odometer speed (m/s), >= 0; an empty cell means no odometry at that row

Choices where the paper is silent or ambiguous (all in ``docs/theory/ahn2007.md``):

* Bias sign: eq (4)-(5), ``ã = a − δa``; the state holds the paper's ``δa`` (the
  correction *added* to the measurement), i.e. minus the usual measured-minus-true bias.
* Process noise: eq (7) shows only the bias-driving noise ``f`` (eq (6)); the white
  accelerometer noise ``n_a`` of eq (3) is kept too. ``Q = accel_var B Bᵀ +
  bias_rw_var G Gᵀ`` with ``B = [Δt²/2; Δt; 0] ⊗ I₂`` and ``G = [Δt³/6; Δt²/2; Δt] ⊗ I₂``
  as printed in eq (7).
* Measurement: ``z = s̃²`` (the logged speed squared) with additive noise ``w`` of
  constant variance ``meas_var`` in (m/s)⁴, exactly eq (2).
* Observability: position is not observable at all (dead reckoning: its variance only
  grows). The speed-squared measurement has Jacobian ``[0, 0, 2v_x, 2v_y, 0, 0]``: at one
  instant it sees only the velocity component along the current velocity, and through the
  dynamics only the bias component along the velocity (``d|v|²/dt = 2 v·(ã + δa)``). The
  cross-track bias becomes observable only when the heading changes (turns); both
  components are observable on a path whose velocity direction varies. At standstill the
  Jacobian vanishes and the measurement carries no information.

Examples
--------
A robot driving a circle at 1 m/s (turning at 0.3 rad/s, so both bias components are
observable) with an accelerometer bias of δa = (0.1, -0.05) m/s² (eq (4)-(5)) and an
exact odometer: the filter finds the bias within a few seconds.

>>> import numpy as np
>>> t = np.arange(301) * 0.1
>>> heading = 0.3 * t
>>> a_true = 0.3 * np.stack([-np.sin(heading), np.cos(heading)], axis=1)
>>> a_meas = a_true - [0.1, -0.05]
>>> res = dead_reckon(t, a_meas[:, 0], a_meas[:, 1], np.ones(301), x0=[0, 0, 1, 0, 0, 0])
>>> res.x.shape, res.P.shape
((301, 6), (301, 6, 6))
>>> res.x[-1, 4:].round(2).tolist()
[0.1, -0.05]
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import IO

import numpy as np

from rangekit import _validate as V
from rangekit.errors import InvalidParameterError
from rangekit.io.csvlog import Column, read_table
from rangekit.localize.ekf import predict, rts_smooth, update

__all__ = [
    "DEFAULT_ACCEL_VAR",
    "DEFAULT_BIAS_RW_VAR",
    "DEFAULT_MEAS_VAR",
    "DEFAULT_P0_DIAG",
    "IMU_LOG_COLUMNS",
    "TRACK_COLUMNS",
    "DeadReckoningResult",
    "ImuLog",
    "dead_reckon",
    "process_noise",
    "read_imu_log",
    "speed2_measurement",
    "track_log",
    "transition",
    "world_acceleration",
]

#: Variance of the white accelerometer noise n_a ((m/s²)²); Ahn & Yu §4 "process noise 0.001".
DEFAULT_ACCEL_VAR = 0.001
#: Variance of the bias-driving noise f of eq (6) ((m/s³)²); Ahn & Yu §4 "process noise 0.001".
DEFAULT_BIAS_RW_VAR = 0.001
#: Variance of w in eq (2) ((m/s)⁴); Ahn & Yu §4 "measurement noise 0.001".
DEFAULT_MEAS_VAR = 0.001
#: Default prior variances of [x, y, v_x, v_y, δa_x, δa_y]: a robot starting at rest at a
#: known place (1 cm, 1 cm/s) with an unknown bias of about 0.1 m/s².
DEFAULT_P0_DIAG = (1e-4, 1e-4, 1e-4, 1e-4, 1e-2, 1e-2)

#: The IMU log's columns (see the module docstring).
IMU_LOG_COLUMNS = {
    "t_s": Column(kind="time"),
    "ax_mps2": Column(),
    "ay_mps2": Column(),
    "speed_mps": Column(nonneg=True, empty_ok=True),
}
#: The columns of the array :func:`track_log` returns.
TRACK_COLUMNS = (
    "t_s",
    "x_m",
    "y_m",
    "vx_mps",
    "vy_mps",
    "bias_x_mps2",
    "bias_y_mps2",
    "sigma_x_m",
    "sigma_y_m",
)

_I2 = np.eye(2)


# --------------------------------------------------------------------------- model
def transition(dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """State-transition and input matrices of Ahn & Yu eq (7).

    Parameters
    ----------
    dt_s : float
        Step length Δt (s), >= 0.

    Returns
    -------
    A : ndarray, shape (6, 6)
        ``[[I, Δt I, Δt²/2 I], [0, I, Δt I], [0, 0, I]]``.
    B : ndarray, shape (6, 2)
        ``[Δt²/2 I; Δt I; 0]``, multiplying the measured acceleration ``ã``.

    Notes
    -----
    With eq (4)-(5) the true acceleration is ``ã + δa`` (less the white noise), hence the
    bias enters the position and velocity rows with the same coefficients as ``ã``.

    Examples
    --------
    >>> A, B = transition(0.1)
    >>> A[0].round(4).tolist(), B[:, 0].round(4).tolist()
    ([1.0, 0.0, 0.1, 0.0, 0.005, 0.0], [0.005, 0.0, 0.1, 0.0, 0.0, 0.0])
    """
    dt = V.positive("dt_s", dt_s, allow_zero=True)
    c = np.array([[1.0, dt, dt * dt / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    A = np.kron(c, _I2)
    B = np.kron(np.array([[dt * dt / 2], [dt], [0.0]]), _I2)
    return A, B


def process_noise(
    dt_s: float, *, accel_var: float = DEFAULT_ACCEL_VAR, bias_rw_var: float = DEFAULT_BIAS_RW_VAR
) -> np.ndarray:
    """Process-noise covariance of one step (Ahn & Yu eq (3), (6), (7)).

    Parameters
    ----------
    dt_s : float
        Step length Δt (s), >= 0.
    accel_var : float
        Variance of the white accelerometer noise ``n_a`` per axis ((m/s²)²), >= 0.
    bias_rw_var : float
        Variance of the bias-driving noise ``f`` of eq (6) per axis ((m/s³)²), >= 0.

    Returns
    -------
    ndarray, shape (6, 6)
        ``accel_var B Bᵀ + bias_rw_var G Gᵀ`` with ``B = [Δt²/2; Δt; 0] ⊗ I₂`` (eq (3))
        and ``G = [Δt³/6; Δt²/2; Δt] ⊗ I₂`` (eq (7)).

    Examples
    --------
    >>> Q = process_noise(0.1, accel_var=1.0, bias_rw_var=0.0)
    >>> round(float(Q[2, 2]), 6), round(float(Q[4, 4]), 6)
    (0.01, 0.0)
    """
    dt = V.positive("dt_s", dt_s, allow_zero=True)
    qa = V.positive("accel_var", accel_var, allow_zero=True)
    qf = V.positive("bias_rw_var", bias_rw_var, allow_zero=True)
    b = np.array([dt * dt / 2, dt, 0.0])
    g = np.array([dt**3 / 6, dt * dt / 2, dt])
    return np.kron(qa * np.outer(b, b) + qf * np.outer(g, g), _I2)


def speed2_measurement(x) -> tuple[np.ndarray, np.ndarray]:
    """Predicted squared speed and its Jacobian (Ahn & Yu eq (2)).

    Parameters
    ----------
    x : array_like, shape (6,) or (4,)
        State ``[x, y, v_x, v_y, ...]``.

    Returns
    -------
    z : ndarray, shape (1,)
        ``v_x² + v_y²`` ((m/s)²).
    H : ndarray, shape (1, d)
        ``[0, 0, 2 v_x, 2 v_y, 0, 0]`` (truncated to d columns).

    Examples
    --------
    >>> z, H = speed2_measurement([0.0, 0.0, 3.0, 4.0, 0.1, 0.2])
    >>> z.tolist(), H.tolist()
    ([25.0], [[0.0, 0.0, 6.0, 8.0, 0.0, 0.0]])
    """
    x = np.asarray(x, dtype=np.float64)
    H = np.zeros((1, x.size))
    H[0, 2], H[0, 3] = 2.0 * x[2], 2.0 * x[3]
    return np.array([x[2] * x[2] + x[3] * x[3]]), H


def world_acceleration(accel_body_mps2, heading_rad) -> np.ndarray:
    """Combine body-frame accelerometer output with the heading (the input of eq (3), (7)).

    Parameters
    ----------
    accel_body_mps2 : array_like, shape (n, 2)
        Accelerometer output along the robot's forward and left axes (m/s²).
    heading_rad : array_like, shape (n,)
        Heading of the forward axis from the world x axis, counter-clockwise (rad).

    Returns
    -------
    ndarray, shape (n, 2)
        ``R(heading) a_body``: the measured acceleration ``(ã_x, ã_y)`` in the world frame.

    Examples
    --------
    >>> world_acceleration([[1.0, 0.0]], [np.pi / 2]).round(12).tolist()
    [[0.0, 1.0]]
    """
    a = np.asarray(accel_body_mps2, dtype=np.float64)
    h = np.asarray(heading_rad, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 2:
        raise InvalidParameterError(f"accel_body_mps2 must have shape (n, 2), got shape {a.shape}")
    if h.shape != (a.shape[0],):
        raise InvalidParameterError(
            f"heading_rad must have shape ({a.shape[0]},), got shape {h.shape}"
        )
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(h))):
        raise InvalidParameterError("accel_body_mps2 and heading_rad must be finite")
    c, s = np.cos(h), np.sin(h)
    return np.stack([c * a[:, 0] - s * a[:, 1], s * a[:, 0] + c * a[:, 1]], axis=1)


# --------------------------------------------------------------------------- filter
@dataclass(frozen=True)
class DeadReckoningResult:
    """Per-row estimates of :func:`dead_reckon`.

    Attributes
    ----------
    t_s : ndarray, shape (n,)
        Row times (s).
    x : ndarray, shape (n, 6)
        Means ``[x_m, y_m, vx_mps, vy_mps, δa_x, δa_y]`` at each row, after that row's
        odometry update (smoothed if ``smoothed``).
    P : ndarray, shape (n, 6, 6)
        Their covariances.
    nis : ndarray, shape (n,)
        Normalised innovation squared of each row's odometry update (NaN: no odometry).
    accepted : ndarray of bool, shape (n,)
        Whether the row's odometry passed the gate (False where there was none).
    smoothed : bool
        Whether ``x`` and ``P`` are RTS-smoothed.
    """

    t_s: np.ndarray
    x: np.ndarray
    P: np.ndarray
    nis: np.ndarray
    accepted: np.ndarray
    smoothed: bool


def _inputs(t_s, ax_mps2, ay_mps2, speed_mps) -> tuple[np.ndarray, ...]:
    t = V.signal_1d("t_s", t_s)
    ax = V.signal_1d("ax_mps2", ax_mps2)
    ay = V.signal_1d("ay_mps2", ay_mps2)
    s = np.asarray(speed_mps, dtype=np.float64)
    if s.ndim != 1:
        raise InvalidParameterError(f"speed_mps must be 1-D, got shape {s.shape}")
    for name, a in (("ax_mps2", ax), ("ay_mps2", ay), ("speed_mps", s)):
        if a.shape != t.shape:
            raise InvalidParameterError(
                f"{name} has {a.size} values but t_s has {t.size}; give one per row"
            )
    if np.any(np.diff(t) < 0):
        k = int(np.argmax(np.diff(t) < 0)) + 1
        raise InvalidParameterError(f"t_s must not decrease: t_s[{k}]={t[k]!r} < t_s[{k - 1}]")
    bad = np.isinf(s) | (s < 0)
    if np.any(bad):
        k = int(np.argmax(bad))
        raise InvalidParameterError(
            f"speed_mps[{k}]={s[k]!r} must be >= 0 and finite (NaN for no odometry)"
        )
    return t, ax, ay, s


def _prior(x0, P0) -> tuple[np.ndarray, np.ndarray]:
    x = np.zeros(6) if x0 is None else np.asarray(x0, dtype=np.float64)
    P = np.diag(DEFAULT_P0_DIAG) if P0 is None else np.asarray(P0, dtype=np.float64)
    if x.shape != (6,) or not np.all(np.isfinite(x)):
        raise InvalidParameterError(f"x0 must be 6 finite numbers, got {x0!r}")
    if P.shape != (6, 6):
        raise InvalidParameterError(f"P0 must have shape (6, 6), got shape {P.shape}")
    return x, P


def dead_reckon(
    t_s,
    ax_mps2,
    ay_mps2,
    speed_mps,
    *,
    x0=None,
    P0=None,
    accel_var: float = DEFAULT_ACCEL_VAR,
    bias_rw_var: float = DEFAULT_BIAS_RW_VAR,
    meas_var: float = DEFAULT_MEAS_VAR,
    bias_states: bool = True,
    gate: float | None = None,
    smooth: bool = False,
    second_order: bool = False,
) -> DeadReckoningResult:
    """Run the bias-estimating dead-reckoning EKF of Ahn & Yu §2 over a whole log.

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Row times (s), non-decreasing.
    ax_mps2, ay_mps2 : array_like, shape (n,)
        Measured world-frame acceleration ``ã`` (accelerometer combined with heading,
        see :func:`world_acceleration`); row k drives the step from ``t_s[k]`` to
        ``t_s[k+1]`` (the last row's value is unused).
    speed_mps : array_like, shape (n,)
        Odometer speed at each row (m/s, >= 0); NaN where there is no odometry.
    x0 : array_like, shape (6,), optional
        Prior mean at ``t_s[0]``, ``[x, y, v_x, v_y, δa_x, δa_y]``. Default zeros.
    P0 : array_like, shape (6, 6), optional
        Prior covariance. Default ``diag(DEFAULT_P0_DIAG)``.
    accel_var : float
        Variance of the white accelerometer noise per axis ((m/s²)², default 0.001).
    bias_rw_var : float
        Variance of the bias-driving noise ``f`` of eq (6) ((m/s³)², default 0.001).
    meas_var : float
        Variance of ``w`` in eq (2) ((m/s)⁴, > 0, default 0.001).
    bias_states : bool
        True (default): the six-state filter of eq (7). False: the four-state filter of
        eq (3) with (1)-(2), which ignores the bias; the bias columns of the result are
        then zero with zero variance.
    gate : float, optional
        Innovation gate probability passed to :func:`rangekit.localize.ekf.update`.
    smooth : bool
        Apply the RTS smoother (:func:`rangekit.localize.ekf.rts_smooth`) afterwards.
    second_order : bool
        False (default): the plain EKF update the paper calls for. True: the
        second-order update of the quadratic measurement, ``h = |v|² + tr P_vv`` and
        ``R + 2 tr(P_vv²)`` (the exact mean and variance of ``|v|²`` under a Gaussian
        prior); it is more consistent when the velocity direction is uncertain.

    Returns
    -------
    DeadReckoningResult

    Raises
    ------
    InvalidParameterError
        Arrays of different lengths, non-finite times or accelerations, decreasing
        times, a negative or infinite speed, or an invalid variance or prior.

    Notes
    -----
    Per row k >= 1: predict with ``x⁻ = A(Δt) x + B(Δt) ã_{k-1}``, ``P⁻ = A P Aᵀ + Q(Δt)``
    (:func:`transition`, :func:`process_noise`, Ahn & Yu eq (7)); then, if ``speed_mps[k]``
    is not NaN, update with ``z = speed_mps[k]²`` and ``h(x) = v_x² + v_y²``, ``R =
    meas_var`` (Ahn & Yu eq (2), :func:`speed2_measurement`). Row 0 is updated from the
    prior. An empty log gives empty arrays.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(3) * 0.1
    >>> r = dead_reckon(t, [1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [np.nan] * 3)
    >>> r.x[:, 0].round(4).tolist(), r.x[:, 2].round(4).tolist()
    ([0.0, 0.005, 0.02], [0.0, 0.1, 0.2])
    """
    t, ax, ay, s = _inputs(t_s, ax_mps2, ay_mps2, speed_mps)
    xp, Pp = _prior(x0, P0)
    qa = V.positive("accel_var", accel_var, allow_zero=True)
    qf = V.positive("bias_rw_var", bias_rw_var, allow_zero=True)
    r = np.array([[V.positive("meas_var", meas_var)]])
    d = 6 if bias_states else 4
    xp, Pp = xp[:d], Pp[:d, :d]
    n = t.size
    xs, Ps = np.zeros((n, d)), np.zeros((n, d, d))
    xs_pred, Ps_pred = np.zeros((n, d)), np.zeros((n, d, d))
    Fs = np.zeros((n, d, d))
    nis = np.full(n, np.nan)
    accepted = np.zeros(n, dtype=bool)
    x, P = xp, Pp
    for k in range(n):
        if k > 0:
            dt = t[k] - t[k - 1]
            A, B = transition(dt)
            Q = process_noise(dt, accel_var=qa, bias_rw_var=qf)
            A, B, Q = A[:d, :d], B[:d], Q[:d, :d]
            u = np.array([ax[k - 1], ay[k - 1]])
            x, P = predict(x, P, lambda v, A=A, B=B, u=u: (A @ v + B @ u, A), Q)
            Fs[k - 1] = A
            xs_pred[k], Ps_pred[k] = x, P
        if not np.isnan(s[k]):
            if second_order:
                Pvv = P[2:4, 2:4]
                z0, H0 = speed2_measurement(x)
                hx = (z0 + np.trace(Pvv), H0)
                rk = r + 2.0 * np.sum(Pvv * Pvv)
                res = update(x, P, [s[k] * s[k]], lambda _v, hx=hx: hx, rk, gate=gate)
            else:
                res = update(x, P, [s[k] * s[k]], speed2_measurement, r, gate=gate)
            nis[k], accepted[k] = res.nis, res.accepted
            x, P = res.x, res.P
        xs[k], Ps[k] = x, P
    if smooth and n > 1:
        xs, Ps = rts_smooth(xs, Ps, xs_pred, Ps_pred, Fs[: n - 1])
    if not bias_states:
        xs = np.concatenate([xs, np.zeros((n, 2))], axis=1)
        Ps = np.pad(Ps, ((0, 0), (0, 2), (0, 2)))
    return DeadReckoningResult(t, xs, Ps, nis, accepted, bool(smooth))


# --------------------------------------------------------------------------- logs
@dataclass(frozen=True)
class ImuLog:
    """An IMU log as arrays (see the module docstring for the format).

    Attributes
    ----------
    t_s, ax_mps2, ay_mps2, speed_mps : ndarray, shape (n,)
        The columns; ``speed_mps`` is NaN where the cell was empty.
    """

    t_s: np.ndarray
    ax_mps2: np.ndarray
    ay_mps2: np.ndarray
    speed_mps: np.ndarray


def read_imu_log(path: str | os.PathLike | IO[str], *, name: str | None = None) -> ImuLog:
    """Read an IMU log: ``t_s, ax_mps2, ay_mps2, speed_mps`` (speed may be empty).

    Parameters
    ----------
    path : path or text stream
        The CSV file (format in the module docstring and ``docs/theory/ahn2007.md``).
    name : str, optional
        How the file is named in error messages (default: the path).

    Returns
    -------
    ImuLog

    Raises
    ------
    InputFileError
        The file cannot be opened.
    LogFormatError
        A missing column, an empty or non-numeric acceleration or time, a NaN or
        infinite value, a negative speed, or time going backwards; the message names
        the row and the column.

    Examples
    --------
    >>> import io
    >>> log = read_imu_log(io.StringIO("t_s,ax_mps2,ay_mps2,speed_mps\\n0,0.1,0,\\n0.1,0,0,0.5\\n"))
    >>> log.speed_mps.tolist()
    [nan, 0.5]
    """
    tab = read_table(path, IMU_LOG_COLUMNS, name=name)
    return ImuLog(tab["t_s"], tab["ax_mps2"], tab["ay_mps2"], tab["speed_mps"])


def track_log(
    path: str | os.PathLike | IO[str], *, smooth: bool = False, **params
) -> tuple[list[str], np.ndarray]:
    """Run :func:`dead_reckon` on an IMU log file; one output row per log row.

    Parameters
    ----------
    path : path or text stream
        IMU log (:func:`read_imu_log`).
    smooth : bool
        RTS-smooth the estimates (default False: causal filter).
    **params
        Keyword arguments of :func:`dead_reckon` (``x0``, ``P0``, ``accel_var``,
        ``bias_rw_var``, ``meas_var``, ``bias_states``, ``gate``, ``second_order``).

    Returns
    -------
    columns : list of str
        :data:`TRACK_COLUMNS`: ``t_s, x_m, y_m, vx_mps, vy_mps, bias_x_mps2, bias_y_mps2,
        sigma_x_m, sigma_y_m``; the bias columns are the paper's ``δa`` (eq (4)-(5): true
        acceleration = measured + δa); the sigmas are the standard deviations of x and y.
    rows : ndarray, shape (n, 9)

    Examples
    --------
    >>> import io
    >>> text = "t_s,ax_mps2,ay_mps2,speed_mps\\n0,1,0,0\\n0.1,1,0,\\n0.2,0,0,\\n"
    >>> cols, rows = track_log(io.StringIO(text), accel_var=0.0, bias_rw_var=0.0)
    >>> cols[:3], rows[:, 1].round(4).tolist()
    (['t_s', 'x_m', 'y_m'], [0.0, 0.005, 0.02])
    """
    unknown = sorted(
        set(params)
        - {
            "x0",
            "P0",
            "accel_var",
            "bias_rw_var",
            "meas_var",
            "bias_states",
            "gate",
            "second_order",
        }
    )
    if unknown:
        raise InvalidParameterError(f"unknown dead-reckoning parameter {unknown[0]!r}")
    log = read_imu_log(path)
    res = dead_reckon(log.t_s, log.ax_mps2, log.ay_mps2, log.speed_mps, smooth=smooth, **params)
    sig = np.sqrt(np.maximum(np.stack([res.P[:, 0, 0], res.P[:, 1, 1]], axis=1), 0.0))
    rows = np.column_stack([res.t_s, res.x, sig]) if res.t_s.size else np.zeros((0, 9))
    return list(TRACK_COLUMNS), rows
