"""Extended Kalman filter core and Rauch–Tung–Striebel smoother (pure numpy).

A small functional core: :func:`predict` and :func:`update` take a state ``x`` of shape
(d,) and covariance ``P`` of shape (d, d) and return new arrays; they never modify their
inputs. :class:`ExtendedKalmanFilter` holds ``x`` and ``P`` for users who prefer an object
and logs the measurements that the innovation gate rejects. :func:`rts_smooth` smooths a
recorded run; :func:`numerical_jacobian` checks analytic Jacobians.

The covariance update is the Joseph form followed by symmetrisation, and every inverse is
a Cholesky solve, so ``P`` stays symmetric positive definite even with very precise
measurements (see ``docs/theory/ekf.md``).

Examples
--------
A scalar constant measured twice with unit noise, starting from a prior of variance 1:

>>> import numpy as np
>>> x, P = np.array([0.0]), np.array([[1.0]])
>>> H, R = np.array([[1.0]]), np.array([[1.0]])
>>> r = update(x, P, [2.0], H, R)
>>> round(float(r.x[0]), 12), round(float(r.P[0, 0]), 12)
(1.0, 0.5)
>>> x, P = predict(r.x, r.P, np.eye(1), np.zeros((1, 1)))
>>> r = update(x, P, [4.0], H, R)
>>> round(float(r.x[0]), 12), round(float(r.P[0, 0]), 12)
(2.0, 0.333333333333)
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from rangekit._validate import in_range, positive
from rangekit.errors import InvalidParameterError

__all__ = [
    "ExtendedKalmanFilter",
    "Rejection",
    "UpdateResult",
    "chi2_gate",
    "numerical_jacobian",
    "predict",
    "rts_smooth",
    "update",
]

#: Relative tolerance of the symmetry and positive-semidefiniteness checks of covariances.
COV_RTOL = 1e-9

MotionModel = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
MeasurementModel = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
Residual = Callable[[np.ndarray, np.ndarray], np.ndarray]


#: Largest magnitude of any entry of a state, covariance, measurement or model matrix.
MAX_ABS = 1e150


# --------------------------------------------------------------------------- validation
def _vector(name: str, v, n: int | None = None) -> np.ndarray:
    """Return ``v`` as a finite float64 vector (scalars become shape (1,))."""
    try:
        a = np.atleast_1d(np.asarray(v, dtype=np.float64))
    except (TypeError, ValueError):
        raise InvalidParameterError(f"{name}={v!r} must be a numeric vector") from None
    if a.ndim != 1:
        raise InvalidParameterError(f"{name} must be 1-D, got shape {a.shape}")
    if n is not None and a.shape != (n,):
        raise InvalidParameterError(f"{name} must have shape ({n},), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InvalidParameterError(f"{name} contains NaN or infinite values: {a!r}")
    return _bounded(name, a)


def _bounded(name: str, a: np.ndarray) -> np.ndarray:
    """Refuse entries beyond :data:`MAX_ABS` (their products overflow float64, issue 17)."""
    if a.size and float(np.max(np.abs(a))) > MAX_ABS:
        raise InvalidParameterError(
            f"{name} has an entry of magnitude {float(np.max(np.abs(a))):.3g}, beyond "
            f"{MAX_ABS:g} (the filter's products would overflow)"
        )
    return a


def _matrix(name: str, M, shape: tuple[int, int]) -> np.ndarray:
    """Return ``M`` as a finite float64 matrix of ``shape`` (a scalar is accepted for 1x1)."""
    try:
        a = np.asarray(M, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidParameterError(f"{name}={M!r} must be a numeric matrix") from None
    if a.ndim == 0 and shape == (1, 1):
        a = a.reshape(1, 1)
    if a.shape != shape:
        raise InvalidParameterError(f"{name} must have shape {shape}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InvalidParameterError(f"{name} contains NaN or infinite values")
    return _bounded(name, a)


def _covariance(name: str, M, n: int) -> np.ndarray:
    """Return ``M`` as a symmetric positive semidefinite (n, n) matrix, or raise."""
    a = _matrix(name, M, (n, n))
    scale = float(np.max(np.abs(a))) if a.size else 0.0
    asym = float(np.max(np.abs(a - a.T))) if a.size else 0.0
    if asym > COV_RTOL * scale:
        raise InvalidParameterError(
            f"{name} must be symmetric, max |{name} - {name}.T| = {asym:.3g} "
            f"(largest entry {scale:.3g})"
        )
    a = 0.5 * (a + a.T)
    if n:
        lam_min = float(np.linalg.eigvalsh(a)[0])
        if lam_min < -COV_RTOL * scale:
            raise InvalidParameterError(
                f"{name} must be positive semidefinite, smallest eigenvalue {lam_min:.3g}"
            )
    return a


def _finite_result(step: str, *arrays: np.ndarray) -> np.ndarray:
    """Return the first array; raise if any is not finite (the inputs' magnitudes, e.g.
    1e300, overflowed float64: issue 17). The filter refuses instead of returning NaN."""
    for a in arrays:
        if not np.all(np.isfinite(a)):
            raise InvalidParameterError(
                f"{step} overflowed: the magnitudes of the state, covariances or "
                "measurement are beyond what float64 arithmetic can filter"
            )
    return arrays[0]


def _symmetrise(P: np.ndarray) -> np.ndarray:
    return 0.5 * (P + P.T)


def _cholesky(name: str, S: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        raise InvalidParameterError(
            f"{name} is not positive definite (check R and the Jacobian): {S!r}"
        ) from None


@lru_cache(maxsize=64)
def chi2_gate(prob: float, dim: int) -> float:
    """Return the NIS threshold that a chi-square variable with ``dim`` dof stays below.

    Parameters
    ----------
    prob : float
        Gate probability within (0, 1), e.g. 0.999: a consistent measurement passes
        the gate with this probability.
    dim : int
        Measurement dimension (degrees of freedom), >= 1.

    Returns
    -------
    float
        The ``prob`` quantile of the chi-square distribution with ``dim`` dof.

    Examples
    --------
    >>> round(chi2_gate(0.95, 1), 4), round(chi2_gate(0.999, 2), 4)
    (3.8415, 13.8155)
    """
    p = in_range("gate", prob, 0.0, 1.0)
    if not 0.0 < p < 1.0:
        raise InvalidParameterError(f"gate={prob!r} must be a probability strictly in (0, 1)")
    if int(dim) < 1:
        raise InvalidParameterError(f"dim={dim!r} must be >= 1")
    from scipy.special import chdtri  # lazy: keep `import rangekit.localize.ekf` cheap

    return float(chdtri(int(dim), 1.0 - p))


# --------------------------------------------------------------------------- predict


def _linearise(model, x: np.ndarray, m: int, *, model_name: str, matrix_name: str, value: str):
    """``(value, jacobian)`` of a model given as a matrix or as ``model(x) -> (value, J)``."""
    d = x.size
    jac = f"{matrix_name}_jacobian"
    if callable(model):
        out = model(x)
        if not (isinstance(out, tuple) and len(out) == 2):
            raise InvalidParameterError(
                f"{model_name}, when callable, must return a tuple ({value}, {jac})"
            )
        return _vector(f"{model_name.lower()}(x)", out[0], m), _matrix(jac, out[1], (m, d))
    J = _matrix(matrix_name, model, (m, d))
    return J @ x, J


def predict(x, P, F: np.ndarray | MotionModel, Q) -> tuple[np.ndarray, np.ndarray]:
    """Propagate a Gaussian state estimate one step through a (linearised) motion model.

    Parameters
    ----------
    x : array_like, shape (d,)
        State mean.
    P : array_like, shape (d, d)
        State covariance, symmetric positive semidefinite.
    F : array_like, shape (d, d), or callable
        The transition matrix of a linear model (``x_new = F x``), or a callable
        ``f(x) -> (x_new, F_jacobian)`` of a nonlinear model returning the predicted
        mean, shape (d,), and the Jacobian of ``f`` at ``x``, shape (d, d).
    Q : array_like, shape (d, d)
        Process-noise covariance, symmetric positive semidefinite.

    Returns
    -------
    x : ndarray, shape (d,)
        Predicted mean ``f(x)`` (``F x`` in the linear case).
    P : ndarray, shape (d, d)
        Predicted covariance ``F P F^T + Q``, symmetrised.

    Raises
    ------
    InvalidParameterError
        On wrong shapes, non-finite values, or non-symmetric / indefinite covariances.

    Notes
    -----
    The EKF time update (Bar-Shalom et al. 2001):
    ``x⁻ = f(x)``, ``P⁻ = F P F^T + Q`` with ``F = ∂f/∂x``.

    Examples
    --------
    >>> import numpy as np
    >>> F = np.array([[1.0, 0.5], [0.0, 1.0]])   # constant velocity, dt = 0.5 s
    >>> x, P = predict([0.0, 2.0], np.eye(2), F, 0.01 * np.eye(2))
    >>> x.tolist()
    [1.0, 2.0]
    >>> P.round(3).tolist()
    [[1.26, 0.5], [0.5, 1.01]]
    """
    x = _vector("x", x)
    d = x.size
    P = _covariance("P", P, d)
    Q = _covariance("Q", Q, d)
    x_new, Fm = _linearise(F, x, d, model_name="F", matrix_name="F", value="x_new")
    with np.errstate(over="ignore", invalid="ignore"):
        P_new = _symmetrise(Fm @ P @ Fm.T + Q)
    return x_new, _finite_result("predict", P_new)


# --------------------------------------------------------------------------- update
@dataclass(frozen=True)
class UpdateResult:
    """Outcome of one measurement update.

    Attributes
    ----------
    x : ndarray, shape (d,)
        Posterior mean (the prior mean when the measurement was rejected).
    P : ndarray, shape (d, d)
        Posterior covariance (the prior covariance when rejected).
    innovation : ndarray, shape (m,)
        Innovation ``y = residual(z, h(x))``.
    S : ndarray, shape (m, m)
        Innovation covariance ``H P H^T + R``.
    nis : float
        Normalised innovation squared ``y^T S^-1 y`` (squared Mahalanobis distance).
    accepted : bool
        False if the innovation gate rejected the measurement.
    """

    x: np.ndarray
    P: np.ndarray
    innovation: np.ndarray
    S: np.ndarray
    nis: float
    accepted: bool


def _threshold(gate: float | None, gate_nis: float | None, m: int) -> float:
    if gate is not None and gate_nis is not None:
        raise InvalidParameterError("give at most one of gate (probability) and gate_nis")
    if gate is not None:
        return chi2_gate(float(gate), m)
    if gate_nis is not None:
        return positive("gate_nis", gate_nis)
    return math.inf


def update(
    x,
    P,
    z,
    h: np.ndarray | MeasurementModel,
    R,
    *,
    gate: float | None = None,
    gate_nis: float | None = None,
    residual: Residual | None = None,
) -> UpdateResult:
    """Correct a Gaussian state estimate with one measurement (EKF update, Joseph form).

    Parameters
    ----------
    x : array_like, shape (d,)
        Prior mean.
    P : array_like, shape (d, d)
        Prior covariance, symmetric positive semidefinite.
    z : array_like, shape (m,)
        Measurement (a scalar is taken as shape (1,)).
    h : array_like, shape (m, d), or callable
        The measurement matrix ``H`` of a linear model (``z = H x + v``), or a callable
        ``h(x) -> (z_pred, H_jacobian)`` returning the predicted measurement, shape (m,),
        and the Jacobian of ``h`` at ``x``, shape (m, d).
    R : array_like, shape (m, m)
        Measurement-noise covariance, symmetric positive semidefinite (a scalar for m = 1).
    gate : float, optional
        Gate probability within (0, 1), e.g. 0.999: the measurement is rejected when its
        NIS exceeds the ``gate`` quantile of the chi-square distribution with m degrees
        of freedom. Default None (no gating).
    gate_nis : float, optional
        A raw NIS threshold (> 0) instead of a probability. At most one of ``gate`` and
        ``gate_nis`` may be given.
    residual : callable, optional
        ``residual(z, z_pred) -> y``, shape (m,); use it to wrap angle components into
        [-pi, pi). Default ``z - z_pred``.

    Returns
    -------
    UpdateResult
        Posterior ``x``, ``P`` (unchanged if rejected), ``innovation``, ``S``, ``nis``
        and ``accepted``.

    Raises
    ------
    InvalidParameterError
        On wrong shapes, non-finite values, non-symmetric / indefinite covariances, or
        an innovation covariance ``S`` that is not positive definite.

    Notes
    -----
    With ``y = residual(z, h(x))``, ``S = H P H^T + R`` (Cholesky ``S = L L^T``) and
    ``K = P H^T S^-1`` (solves with the Cholesky factor of S, no inverse), the posterior is
    ``x⁺ = x + K y`` and the Joseph form (Bucy & Joseph 1968; Bar-Shalom et al. 2001)
    ``P⁺ = (I - K H) P (I - K H)^T + K R K^T``, then symmetrised. It is
    valid for any gain and keeps ``P⁺`` positive semidefinite under rounding, unlike
    ``(I - K H) P``. The gate tests ``NIS = y^T S^-1 y = |L^-1 y|^2`` against the
    threshold; NIS is chi-square with m dof for a consistent filter.

    Examples
    --------
    Range-only update of a 2-D position from a beacon at the origin, with a gate:

    >>> import numpy as np
    >>> def h_range(x):
    ...     r = np.hypot(x[0], x[1])
    ...     return np.array([r]), np.array([[x[0] / r, x[1] / r]])
    >>> res = update([3.0, 4.0], np.eye(2), [5.2], h_range, 0.01, gate=0.999)
    >>> res.accepted, round(res.nis, 4), res.x.round(4).tolist()
    (True, 0.0396, [3.1188, 4.1584])
    >>> update([3.0, 4.0], np.eye(2), [25.0], h_range, 0.01, gate=0.999).accepted
    False
    """
    x = _vector("x", x)
    d = x.size
    P = _covariance("P", P, d)
    z = _vector("z", z)
    m = z.size
    R = _covariance("R", R, m)
    z_pred, H = _linearise(h, x, m, model_name="h", matrix_name="H", value="z_pred")
    y = z - z_pred if residual is None else _vector("residual(z, z_pred)", residual(z, z_pred), m)
    threshold = _threshold(gate, gate_nis, m)

    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        PHt = P @ H.T
        S = _finite_result("update (S = H P H^T + R)", _symmetrise(H @ PHt + R))
        L = _cholesky("S = H P H^T + R", S)
        w = np.linalg.solve(L, y)
        nis = float(w @ w)
        if nis > threshold:
            return UpdateResult(x, P, y, S, nis, False)
        # K^T = S^-1 H P  (S = L L^T): two solves with L (np.linalg.solve), no inverse.
        Kt = np.linalg.solve(L.T, np.linalg.solve(L, PHt.T))
        K = Kt.T
        x_new = x + K @ y
        IKH = np.eye(d) - K @ H
        P_new = _symmetrise(IKH @ P @ IKH.T + K @ R @ K.T)
    _finite_result("update", x_new, P_new, np.asarray(nis))
    return UpdateResult(x_new, P_new, y, S, nis, True)


# --------------------------------------------------------------------------- class
@dataclass(frozen=True)
class Rejection:
    """A measurement rejected by the innovation gate.

    Attributes
    ----------
    index : int
        Zero-based count of ``update`` calls on the filter when it was rejected.
    t : float or None
        The time the caller passed with the measurement (s), if any.
    nis : float
        Its normalised innovation squared.
    threshold : float
        The NIS threshold it exceeded.
    """

    index: int
    t: float | None
    nis: float
    threshold: float


@dataclass
class ExtendedKalmanFilter:
    """An extended Kalman filter holding its state, with a log of gated-out measurements.

    Parameters
    ----------
    x : array_like, shape (d,)
        Initial state mean.
    P : array_like, shape (d, d)
        Initial state covariance, symmetric positive semidefinite.

    Attributes
    ----------
    x, P : ndarray
        The current mean and covariance (replaced, never modified in place).
    rejections : list of Rejection
        Every measurement the gate rejected, in order.
    n_updates : int
        Number of ``update`` calls so far (accepted or not).

    Examples
    --------
    >>> import numpy as np
    >>> kf = ExtendedKalmanFilter([0.0], [[1.0]])
    >>> kf.predict(np.eye(1), [[0.0]])
    >>> kf.update([1.0], np.eye(1), [[1.0]], gate=0.99).accepted
    True
    >>> kf.update([50.0], np.eye(1), [[1.0]], gate=0.99, t=2.0).accepted
    False
    >>> kf.x.round(12).tolist(), kf.P.round(12).tolist()
    ([0.5], [[0.5]])
    >>> r = kf.rejections[0]
    >>> r.index, r.t, round(r.nis, 1)
    (1, 2.0, 1633.5)
    """

    x: np.ndarray
    P: np.ndarray
    rejections: list[Rejection] = field(default_factory=list)
    n_updates: int = 0

    def __post_init__(self) -> None:
        self.x = _vector("x", self.x)
        self.P = _covariance("P", self.P, self.x.size)

    def predict(self, F: np.ndarray | MotionModel, Q) -> None:
        """Propagate the state with :func:`predict` (a predict-only step when no
        measurement arrives)."""
        self.x, self.P = predict(self.x, self.P, F, Q)

    def update(
        self,
        z,
        h: np.ndarray | MeasurementModel,
        R,
        *,
        gate: float | None = None,
        gate_nis: float | None = None,
        residual: Residual | None = None,
        t: float | None = None,
    ) -> UpdateResult:
        """Correct the state with :func:`update`; log the measurement if rejected.

        ``t`` (s) is only recorded in the rejection log. Returns the :class:`UpdateResult`.
        """
        res = update(self.x, self.P, z, h, R, gate=gate, gate_nis=gate_nis, residual=residual)
        if res.accepted:
            self.x, self.P = res.x, res.P
        else:
            thr = _threshold(gate, gate_nis, res.innovation.size)
            self.rejections.append(Rejection(self.n_updates, t, res.nis, thr))
        self.n_updates += 1
        return res


# --------------------------------------------------------------------------- smoother
def rts_smooth(xs_filt, Ps_filt, xs_pred, Ps_pred, Fs) -> tuple[np.ndarray, np.ndarray]:
    """Rauch–Tung–Striebel fixed-interval smoother for a recorded filter run.

    Parameters
    ----------
    xs_filt : array_like, shape (n, d)
        Filtered (posterior) means at steps 0 .. n-1.
    Ps_filt : array_like, shape (n, d, d)
        Filtered covariances.
    xs_pred : array_like, shape (n, d)
        ``xs_pred[k]`` is the prediction for step k made from step k-1; row 0 is unused.
    Ps_pred : array_like, shape (n, d, d)
        Predicted covariances, indexed like ``xs_pred``; ``Ps_pred[k]`` for k >= 1 must be
        positive definite.
    Fs : array_like, shape (n - 1, d, d) or (n, d, d)
        ``Fs[k]`` is the (Jacobian of the) transition from step k to k+1; a last row,
        if present, is unused.

    Returns
    -------
    xs_smooth : ndarray, shape (n, d)
    Ps_smooth : ndarray, shape (n, d, d)

    Raises
    ------
    InvalidParameterError
        On inconsistent shapes, non-finite values, or a singular predicted covariance.

    Notes
    -----
    Rauch, Tung & Striebel (1965); Bar-Shalom et al. (2001). Backwards from
    k = n-2: ``C_k = P_k F_k^T (P⁻_{k+1})^-1`` (a Cholesky solve),
    ``x^s_k = x_k + C_k (x^s_{k+1} - x⁻_{k+1})`` and
    ``P^s_k = P_k + C_k (P^s_{k+1} - P⁻_{k+1}) C_k^T``, evaluated in Joseph form,
    ``(I - C_k F_k) P_k (I - C_k F_k)^T + C_k (Q_k + P^s_{k+1}) C_k^T`` with
    ``Q_k = P⁻_{k+1} - F_k P_k F_k^T`` (clipped to PSD), and symmetrised: the sum of
    positive semidefinite terms cannot turn indefinite by rounding, and
    ``P_k - P^s_k = C_k (P⁻_{k+1} - P^s_{k+1}) C_k^T >= 0`` keeps it below the filter's.
    The inputs must be one consistent run: ``P⁻_{k+1} >= F_k P_k F_k^T`` (a transition
    that is not ``F_k``, such as a hypothesis jump, must be folded into ``Fs``).

    Examples
    --------
    A random walk measured twice: the first estimate borrows from the second.

    >>> import numpy as np
    >>> xs, Ps = rts_smooth([[0.0], [1.0]], [[[0.5]], [[0.6]]], [[0.0], [0.0]],
    ...                     [[[0.0]], [[1.5]]], [[[1.0]]])
    >>> round(float(xs[0, 0]), 4), round(float(Ps[0, 0, 0]), 4)
    (0.3333, 0.4)
    """
    try:
        xf = np.asarray(xs_filt, dtype=np.float64)
        Pf = np.asarray(Ps_filt, dtype=np.float64)
        xp = np.asarray(xs_pred, dtype=np.float64)
        Pp = np.asarray(Ps_pred, dtype=np.float64)
        F = np.asarray(Fs, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidParameterError("rts_smooth inputs must be numeric arrays") from None
    if xf.ndim != 2:
        raise InvalidParameterError(f"xs_filt must have shape (n, d), got shape {xf.shape}")
    n, d = xf.shape
    for name, a, shape in (
        ("Ps_filt", Pf, (n, d, d)),
        ("xs_pred", xp, (n, d)),
        ("Ps_pred", Pp, (n, d, d)),
    ):
        if a.shape != shape:
            raise InvalidParameterError(f"{name} must have shape {shape}, got shape {a.shape}")
    if F.shape not in ((max(n - 1, 0), d, d), (n, d, d)):
        raise InvalidParameterError(
            f"Fs must have shape ({n - 1}, {d}, {d}) or ({n}, {d}, {d}), got shape {F.shape}"
        )
    for name, a in (("xs_filt", xf), ("Ps_filt", Pf), ("xs_pred", xp[1:]), ("Ps_pred", Pp[1:]),
                    ("Fs", F[: n - 1])):  # fmt: skip
        if not np.all(np.isfinite(a)):
            raise InvalidParameterError(f"{name} contains NaN or infinite values")
    xs = xf.copy()
    Ps = np.array([_symmetrise(p) for p in Pf]) if n else Pf.copy()
    eye = np.eye(d)
    for k in range(n - 2, -1, -1):
        Pk = Ps[k]
        Pk1 = _symmetrise(Pp[k + 1])
        L = _cholesky(f"Ps_pred[{k + 1}]", Pk1)
        # C^T = (P⁻_{k+1})^-1 F_k P_k
        Ct = np.linalg.solve(L.T, np.linalg.solve(L, F[k] @ Pk))
        C = Ct.T
        xs[k] = xf[k] + C @ (xs[k + 1] - xp[k + 1])
        # Joseph form of P_k + C (P^s_{k+1} - P⁻_{k+1}) C^T: a sum of three positive
        # semidefinite terms, with Q_k = P⁻_{k+1} - F_k P_k F_k^T (the process noise the
        # filter added, projected onto the PSD cone against rounding)
        A = eye - C @ F[k]
        Qk = _psd_part(Pk1 - _symmetrise(F[k] @ Pk @ F[k].T))
        Ps[k] = _symmetrise(A @ Pk @ A.T + C @ (Qk + Ps[k + 1]) @ C.T)
    return xs, Ps


def _psd_part(M: np.ndarray) -> np.ndarray:
    """The nearest (Frobenius) positive semidefinite matrix to the symmetric ``M``."""
    w, V = np.linalg.eigh(M)
    if w.size == 0 or w[0] >= 0:
        return M
    return _symmetrise((V * np.maximum(w, 0.0)) @ V.T)


# --------------------------------------------------------------------------- jacobian
def numerical_jacobian(f: Callable[[np.ndarray], np.ndarray], x, eps: float = 1e-6) -> np.ndarray:
    """Central-difference Jacobian of ``f`` at ``x``, to check analytic Jacobians.

    Parameters
    ----------
    f : callable
        ``f(x) -> array_like`` of shape (m,) (a scalar is taken as shape (1,)).
    x : array_like, shape (d,)
        Point of evaluation.
    eps : float, optional
        Relative step (> 0): component i is perturbed by ``eps * max(1, |x_i|)``.
        Default 1e-6 (truncation and rounding errors about 1e-10 relative).

    Returns
    -------
    ndarray, shape (m, d)
        ``J[i, j] ≈ ∂f_i / ∂x_j``.

    Examples
    --------
    >>> import numpy as np
    >>> J = numerical_jacobian(lambda p: np.hypot(p[0], p[1]), [3.0, 4.0])
    >>> J.round(8).tolist()
    [[0.6, 0.8]]
    """
    x = _vector("x", x)
    eps = positive("eps", eps)
    cols = []
    for j in range(x.size):
        step = eps * max(1.0, abs(x[j]))
        xp, xm = x.copy(), x.copy()
        xp[j] += step
        xm[j] -= step
        fp = np.atleast_1d(np.asarray(f(xp), dtype=np.float64))
        fm = np.atleast_1d(np.asarray(f(xm), dtype=np.float64))
        cols.append((fp - fm) / (xp[j] - xm[j]))
    if not cols:
        m = np.atleast_1d(np.asarray(f(x), dtype=np.float64)).size
        return np.zeros((m, 0))
    return np.stack(cols, axis=1)
