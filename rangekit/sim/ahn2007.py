"""Simulators of Ahn & Yu §4: a robot with a biased accelerometer, a pedestrian with noisy fixes.

Both return their ground truth with the measurements (plain arrays); the processing
modules (:mod:`rangekit.localize.deadreckoning`, :mod:`rangekit.localize.lmax`) never
import this module. :func:`imu_log_text` and :func:`position_log_text` write the
simulated measurements in the documented CSV log formats.

Readings of §4 where the text cannot be taken literally (``docs/theory/ahn2007.md``):

* Robot acceleration, "a_x = a_x + α(a_x + r_a)" with α = 3/4: read literally each step
  multiplies ``a`` by 1.75 and the acceleration diverges (1.75¹⁰⁰ ≈ 10²⁴ after 10 s).
  We read it as the one-sign correction ``a ← a + α(r − a)`` (a mean-reverting random
  acceleration), ``r`` uniform in [-1, 1] m/s².
* Pedestrian steps, "Δx = β(r_a − 0.55), Δy = β(r_b − 0.44)", β = 2, "−1 ≤ r ≤ 1": the
  offsets 0.55 and 0.44 only make sense as a slight drift around the mean 0.5 of a
  uniform [0, 1] draw (MATLAB's ``rand``), which satisfies the stated bound; with
  [-1, 1] the walker would drift 1.4 m per step. Default ``r_low=0``; ``r_low=-1`` gives
  the literal reading.
* Noise variances are per axis: process 0.001, measurement 0.001 (robot, Δt = 0.1 s) and
  4.0 m² (pedestrian).

Examples
--------
>>> sim = simulate_pedestrian(5, noise_var_m2=4.0, rng=1)
>>> sim.truth_m.shape, sim.measured_m.shape, sim.truth_m[0].tolist()
((5, 2), (5, 2), [0.0, 0.0])
>>> robot = simulate_robot(50, rng=1)
>>> robot.state.shape, bool(np.isnan(robot.speed_meas_mps).any())
((50, 6), False)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rangekit import _validate as V
from rangekit.errors import InvalidParameterError
from rangekit.io.csvlog import write_table
from rangekit.localize.deadreckoning import IMU_LOG_COLUMNS
from rangekit.localize.lmax import POSITION_LOG_COLUMNS

__all__ = [
    "PedestrianSim",
    "RobotSim",
    "imu_log_text",
    "position_log_text",
    "simulate_pedestrian",
    "simulate_robot",
    "step_length_stats",
]


def _dof(noise_dof) -> float | None:
    if noise_dof is None:
        return None
    dof = V.positive("noise_dof", noise_dof)
    if dof <= 2.0:
        raise InvalidParameterError(f"noise_dof={noise_dof!r} must be > 2 (finite variance)")
    return dof


def _noise(g: np.random.Generator, var: float, size, dof: float | None) -> np.ndarray:
    """Zero-mean noise of variance ``var``: Gaussian, or Student-t with ``dof`` (> 2)."""
    if dof is None:
        return g.normal(0.0, np.sqrt(var), size=size)
    return np.sqrt(var * (dof - 2.0) / dof) * g.standard_t(dof, size=size)


# --------------------------------------------------------------------------- robot
@dataclass(frozen=True)
class RobotSim:
    """A simulated robot run (Ahn & Yu §2, §4); n rows at times ``t_s``.

    Attributes
    ----------
    t_s : ndarray, shape (n,)
    position_m, velocity_mps : ndarray, shape (n, 2)
        True position and velocity.
    accel_mps2 : ndarray, shape (n, 2)
        True acceleration, constant over each step (row k drives step k -> k+1).
    bias_mps2 : ndarray, shape (n, 2)
        True ``δa`` in the paper's sign (eq (4)-(5)): ``ã = a − δa + n_a``.
    accel_meas_mps2 : ndarray, shape (n, 2)
        Measured world-frame acceleration ``ã`` (accelerometer combined with heading).
    heading_rad : ndarray, shape (n,)
        Heading (direction of travel), as an exact heading sensor reports it.
    accel_body_mps2 : ndarray, shape (n, 2)
        The accelerometer output in the body frame (forward, left): rotating it by
        ``heading_rad`` gives ``accel_meas_mps2``.
    speed2_meas : ndarray, shape (n,)
        Odometry ``z = v_x² + v_y² + w`` of eq (2) ((m/s)²), NaN at rows without odometry.
    speed_meas_mps : ndarray, shape (n,)
        ``sqrt(max(z, 0))`` (what the IMU log stores), NaN at rows without odometry.
    """

    t_s: np.ndarray
    position_m: np.ndarray
    velocity_mps: np.ndarray
    accel_mps2: np.ndarray
    bias_mps2: np.ndarray
    accel_meas_mps2: np.ndarray
    heading_rad: np.ndarray
    accel_body_mps2: np.ndarray
    speed2_meas: np.ndarray
    speed_meas_mps: np.ndarray

    @property
    def state(self) -> np.ndarray:
        """True states ``[x, y, v_x, v_y, δa_x, δa_y]``, shape (n, 6)."""
        return np.concatenate([self.position_m, self.velocity_mps, self.bias_mps2], axis=1)


def simulate_robot(
    n_steps: int = 600,
    *,
    dt_s: float = 0.1,
    alpha: float = 0.75,
    accel_var: float = 0.001,
    bias_rw_var: float = 0.001,
    meas_var: float = 0.001,
    bias0_mps2=None,
    bias0_std_mps2: float = 0.1,
    position_std_m: float = 0.0,
    velocity0_mps=(0.0, 0.0),
    velocity_std_mps: float = 0.0,
    odometry_every: int = 1,
    noise_dof: float | None = None,
    odometry_scale: float = 1.0,
    rng=None,
) -> RobotSim:
    """Simulate the mobile robot of Ahn & Yu §4.

    Parameters
    ----------
    n_steps : int
        Number of rows (>= 1).
    dt_s : float
        Sampling interval (s), > 0 (paper: 0.1).
    alpha : float
        Smoothing of the random acceleration, in (0, 1] (paper: 3/4):
        ``a_{k+1} = a_k + α (r_k − a_k)``, ``r_k`` uniform in [-1, 1]² m/s², ``a_0 = 0``.
    accel_var : float
        Variance of the white accelerometer noise ``n_a`` per axis (paper: 0.001).
    bias_rw_var : float
        Variance of ``f`` in eq (6), ``δa_{k+1} = δa_k + Δt f_k`` (paper: 0.001); 0 gives
        a constant bias.
    meas_var : float
        Variance of the odometry noise ``w`` of eq (2) (paper: 0.001).
    bias0_mps2 : array_like, shape (2,), optional
        Initial bias ``δa_0``; default drawn from N(0, ``bias0_std_mps2``²) per axis.
    bias0_std_mps2 : float
        Standard deviation of the drawn initial bias (m/s²).
    position_std_m, velocity_std_mps : float
        Standard deviations of the initial position (around the origin) and velocity
        (around ``velocity0_mps``), per axis; default 0 (known start).
    velocity0_mps : array_like, shape (2,)
        Mean initial velocity (default at rest).
    odometry_every : int
        Odometry at every ``odometry_every``-th row, starting with row 0 (default 1).
    noise_dof : float, optional
        Model mismatch (not in the paper): draw the accelerometer noise ``n_a`` from a
        Student-t law with this many degrees of freedom (> 2), scaled to the variance
        ``accel_var`` (heavy-tailed); None (default): Gaussian, as eq (7) assumes.
    odometry_scale : float
        Model mismatch (not in the paper): the odometer reads ``odometry_scale`` times
        the true speed (a wheel-radius error; 1.0, the default, is unbiased), > 0.
    rng : seed or Generator
        Anything :func:`numpy.random.default_rng` accepts.

    Returns
    -------
    RobotSim

    Notes
    -----
    Truth: ``v_{k+1} = v_k + Δt a_k``, ``p_{k+1} = p_k + Δt v_k + Δt²/2 a_k``;
    measurements ``ã_k = a_k − δa_k + n_k`` (eq (3)-(5)) and ``z_k = |v_k|² + w_k`` (eq (2)).
    This is eq (7) exactly except that the bias steps once per sample, so its noise does
    not reach position and velocity within the step (eq (7)'s Δt³/6 and Δt²/2 terms:
    below 0.5 % of the process-noise variance at the paper's settings).
    """
    n = V.positive_int("n_steps", n_steps)
    dt = V.positive("dt_s", dt_s)
    al = V.in_range("alpha", alpha, 0.0, 1.0)
    qa = V.positive("accel_var", accel_var, allow_zero=True)
    qf = V.positive("bias_rw_var", bias_rw_var, allow_zero=True)
    qw = V.positive("meas_var", meas_var, allow_zero=True)
    sb = V.positive("bias0_std_mps2", bias0_std_mps2, allow_zero=True)
    sp = V.positive("position_std_m", position_std_m, allow_zero=True)
    sv = V.positive("velocity_std_mps", velocity_std_mps, allow_zero=True)
    every = V.positive_int("odometry_every", odometry_every)
    dof = _dof(noise_dof)
    scale = V.positive("odometry_scale", odometry_scale)
    v0 = np.asarray(velocity0_mps, dtype=np.float64)
    if v0.shape != (2,) or not np.all(np.isfinite(v0)):
        raise InvalidParameterError(f"velocity0_mps={velocity0_mps!r} must be 2 finite numbers")
    g = np.random.default_rng(rng)

    r = g.uniform(-1.0, 1.0, size=(n, 2))
    a = np.zeros((n, 2))
    for k in range(n - 1):
        a[k + 1] = a[k] + al * (r[k] - a[k])
    if bias0_mps2 is None:
        b0 = g.normal(0.0, sb, size=2)
    else:
        b0 = np.asarray(bias0_mps2, dtype=np.float64)
        if b0.shape != (2,) or not np.all(np.isfinite(b0)):
            raise InvalidParameterError(f"bias0_mps2={bias0_mps2!r} must be 2 finite numbers")
    f = g.normal(0.0, np.sqrt(qf), size=(n - 1, 2))
    bias = b0 + np.vstack([np.zeros((1, 2)), np.cumsum(dt * f, axis=0)])
    p0 = g.normal(0.0, sp, size=2)
    v_init = v0 + g.normal(0.0, sv, size=2)
    vel = v_init + np.vstack([np.zeros((1, 2)), np.cumsum(dt * a[:-1], axis=0)])
    dpos = dt * vel[:-1] + 0.5 * dt * dt * a[:-1]
    pos = p0 + np.vstack([np.zeros((1, 2)), np.cumsum(dpos, axis=0)])
    noise = _noise(g, qa, (n, 2), dof)
    a_meas = a - bias + noise
    w = g.normal(0.0, np.sqrt(qw), size=n)
    z = np.full(n, np.nan)
    rows = np.arange(0, n, every)
    z[rows] = scale**2 * np.sum(vel[rows] ** 2, axis=1) + w[rows]
    speed = np.full(n, np.nan)
    speed[rows] = np.sqrt(np.maximum(z[rows], 0.0))
    heading = np.arctan2(vel[:, 1], vel[:, 0])
    c, s = np.cos(heading), np.sin(heading)
    body = np.stack([c * a_meas[:, 0] + s * a_meas[:, 1], -s * a_meas[:, 0] + c * a_meas[:, 1]], 1)
    t = np.arange(n) * dt
    return RobotSim(t, pos, vel, a, bias, a_meas, heading, body, z, speed)


# --------------------------------------------------------------------------- pedestrian
@dataclass(frozen=True)
class PedestrianSim:
    """A simulated pedestrian walk with wireless position fixes (Ahn & Yu §4).

    Attributes
    ----------
    t_s : ndarray, shape (n,)
    truth_m : ndarray, shape (n, 2)
        True positions ``P_i``.
    measured_m : ndarray, shape (n, 2)
        Fixes ``P̃_i = P_i + e_i``, ``e_i`` ~ N(0, ``noise_var_m2`` I₂) (Student-t of the
        same variance with ``noise_dof``).
    noise_var_m2 : float
        The per-axis fix variance (m²).
    """

    t_s: np.ndarray
    truth_m: np.ndarray
    measured_m: np.ndarray
    noise_var_m2: float


_OFFSETS = (0.55, 0.44)


def _walk_args(beta_m, offsets, r_low) -> tuple[float, np.ndarray, float]:
    beta = V.positive("beta_m", beta_m)
    off = np.asarray(offsets, dtype=np.float64)
    if off.shape != (2,) or not np.all(np.isfinite(off)):
        raise InvalidParameterError(f"offsets={offsets!r} must be 2 finite numbers")
    lo = V.in_range("r_low", r_low, -1.0, 0.999)
    return beta, off, lo


def simulate_pedestrian(
    n_steps: int = 100,
    *,
    noise_var_m2: float = 4.0,
    beta_m: float = 2.0,
    offsets=_OFFSETS,
    r_low: float = 0.0,
    dt_s: float = 1.0,
    start_m=(0.0, 0.0),
    noise_dof: float | None = None,
    rng=None,
) -> PedestrianSim:
    """Simulate the pedestrian walk of Ahn & Yu §4 and its noisy wireless fixes.

    Parameters
    ----------
    n_steps : int
        Number of positions (>= 1).
    noise_var_m2 : float
        Per-axis variance of the fixes (m², paper: 4.0), >= 0.
    beta_m : float
        Step scale β (m, paper: 2).
    offsets : (float, float)
        The offsets of ``Δx = β(r_a − 0.55)``, ``Δy = β(r_b − 0.44)``.
    r_low : float
        Lower end of the uniform draws ``r`` (upper end 1): 0 (default, MATLAB ``rand``)
        or -1 (the literal "−1 ≤ r ≤ 1").
    dt_s : float
        Interval between fixes (s; the paper gives none, default 1).
    start_m : (float, float)
        The first true position.
    noise_dof : float, optional
        Model mismatch (not in the paper): fix errors from a Student-t law with this many
        degrees of freedom (> 2) per axis, scaled to ``noise_var_m2`` (heavy-tailed);
        None (default): Gaussian.
    rng : seed or Generator

    Returns
    -------
    PedestrianSim
    """
    n = V.positive_int("n_steps", n_steps)
    var = V.positive("noise_var_m2", noise_var_m2, allow_zero=True)
    beta, off, lo = _walk_args(beta_m, offsets, r_low)
    dt = V.positive("dt_s", dt_s)
    dof = _dof(noise_dof)
    start = np.asarray(start_m, dtype=np.float64)
    if start.shape != (2,) or not np.all(np.isfinite(start)):
        raise InvalidParameterError(f"start_m={start_m!r} must be 2 finite numbers")
    g = np.random.default_rng(rng)
    steps = beta * (g.uniform(lo, 1.0, size=(n - 1, 2)) - off)
    truth = start + np.vstack([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
    meas = truth + _noise(g, var, (n, 2), dof)
    return PedestrianSim(np.arange(n) * dt, truth, meas, var)


def step_length_stats(
    beta_m: float = 2.0, offsets=_OFFSETS, r_low: float = 0.0
) -> tuple[float, float]:
    """Mean and maximum step length of the §4 walk (m), for choosing ``l_max``.

    Deterministic (midpoint rule on a 400 x 400 grid of the uniform draws); the paper
    recommends ``l_max`` = the maximum or the average distance moved per interval.

    Examples
    --------
    >>> mean, top = step_length_stats()
    >>> round(mean, 3), round(top, 3)
    (0.776, 1.57)
    """
    beta, off, lo = _walk_args(beta_m, offsets, r_low)
    m = 400
    u = lo + (1.0 - lo) * (np.arange(m) + 0.5) / m
    dx = beta * (u[:, None] - off[0])
    dy = beta * (u[None, :] - off[1])
    mean = float(np.mean(np.hypot(dx, dy)))
    ends = np.array([lo, 1.0])
    top = float(np.max(np.hypot(*np.meshgrid(beta * (ends - off[0]), beta * (ends - off[1])))))
    return mean, top


# --------------------------------------------------------------------------- logs
def imu_log_text(sim: RobotSim) -> str:
    """The robot's measurements as an IMU log (``t_s, ax_mps2, ay_mps2, speed_mps``).

    Examples
    --------
    >>> lines = imu_log_text(simulate_robot(3, odometry_every=2, rng=0)).splitlines()
    >>> lines[1], lines[3].endswith(",")  # row 1 has no odometry: empty speed cell
    ('t_s,ax_mps2,ay_mps2,speed_mps', True)
    """
    rows = np.column_stack([sim.t_s, sim.accel_meas_mps2, sim.speed_meas_mps])
    return write_table(
        list(IMU_LOG_COLUMNS), rows.tolist(), header_comment="simulated IMU log (Ahn & Yu §4)"
    )


def position_log_text(sim: PedestrianSim) -> str:
    """The pedestrian's fixes as a position log (``t_s, x_m, y_m``).

    Examples
    --------
    >>> sim = simulate_pedestrian(2, noise_var_m2=0.0, rng=0)
    >>> print(position_log_text(sim).splitlines()[1])
    t_s,x_m,y_m
    """
    rows = np.column_stack([sim.t_s, sim.measured_m])
    return write_table(
        list(POSITION_LOG_COLUMNS),
        rows.tolist(),
        header_comment=f"simulated wireless fixes (Ahn & Yu §4), variance {sim.noise_var_m2} m²",
    )
