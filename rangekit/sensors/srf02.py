"""Devantech SRF02 ultrasonic range finder: beam, range model, errors, firing, crosstalk.

The model follows Girard et al. (2011) §2.6 (SRF02 behaviour) and §3.2 (the ray model of
eq. (3)) and the SRF02 technical pages (``../shared/REFERENCES.md``); every number and
every choice made where the sources are silent is listed in ``docs/theory/srf02.md``.

* :class:`SRF02`: parameters (aperture, rays, range limits, cycle, error model).
* :func:`beam_pattern`: circular-piston directivity with the datasheet's 55° -6 dB width.
* :func:`model_range`: the noise-free reading for poses in a :class:`~rangekit.floorplan.FloorPlan`
  (Girard's rays, or the exact specular echo), with optional secondary reflections.
* :func:`read_ranges`: Gaussian noise, wavefront slips and 1 cm quantisation.
* :func:`schedule_firings` and :func:`simulate_readings`: firing times over USB and the
  crosstalk of back-to-back sensors (Girard §2.6.5).

Out of range is NaN everywhere: no echo within the maximum range for the echo's off-axis
angle, or an echo inside the ring-down blanking (closer than ``min_range_m``).

Examples
--------
>>> from rangekit.floorplan import FloorPlan
>>> plan = FloorPlan.from_walls([((2.0, -3.0), (2.0, 3.0))])
>>> sensor = SRF02()
>>> float(model_range(plan, (0.0, 0.0, 0.0), sensor))
2.0
>>> float(model_range(plan, (0.0, 0.0, np.pi), sensor))
nan
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rangekit import _raycast
from rangekit._validate import in_range, positive, positive_int
from rangekit.errors import InvalidParameterError
from rangekit.floorplan import FloorPlan
from rangekit.physics import speed_of_sound_m_s
from rangekit.types import RngLike

__all__ = [
    "BEAM_WIDTH_RAD",
    "CYCLE_S",
    "DATASHEET_SPEED_M_S",
    "DATASHEET_TEMP_C",
    "FREQUENCY_HZ",
    "MAX_RANGE_M",
    "MIN_RANGE_M",
    "RESOLUTION_M",
    "SOURCE_CROSS_WALL",
    "SOURCE_LEAK",
    "SOURCE_NAMES",
    "SOURCE_NONE",
    "SOURCE_OWN",
    "SRF02",
    "USB_LATENCY_S",
    "WAVELENGTH_M",
    "SRF02Readings",
    "beam_pattern",
    "model_range",
    "piston_ka",
    "read_ranges",
    "schedule_firings",
    "simulate_readings",
]


#: Transducer frequency (datasheet): 40 kHz, one transducer sends and receives.
FREQUENCY_HZ = 40_000.0
#: Speed of sound the datasheet quotes ("approx. 346 m/s at 24 °C").
DATASHEET_SPEED_M_S = 346.0
#: Air temperature of the datasheet's speed of sound, °C.
DATASHEET_TEMP_C = 24.0
#: Wavelength at 40 kHz and 346 m/s: 8.65 mm, the datasheet's wavefront-slip step.
WAVELENGTH_M = DATASHEET_SPEED_M_S / FREQUENCY_HZ
#: Minimum range (ring-down), Girard 2011 §2.6; the datasheet gives 15-16 cm on a cool day.
MIN_RANGE_M = 0.15
#: Maximum range on axis (datasheet, Girard 2011 §2.6): 6 m.
MAX_RANGE_M = 6.0
#: Ranging cycle: no echo 70 ms after the ping means out of range (Girard 2011 §2.6.5).
CYCLE_S = 0.070
#: Full width of the beam at -6 dB (datasheet): 55°.
BEAM_WIDTH_RAD = math.radians(55.0)
#: Resolution of the reported range (datasheet: 16-bit result in cm): 1 cm.
RESOLUTION_M = 0.01
#: Latency of a command over the USB-I2C virtual COM port (Girard 2011 §2.6.5): 1-4 ms.
USB_LATENCY_S = (0.001, 0.004)

#: Reading sources reported by :func:`simulate_readings`.
SOURCE_NONE, SOURCE_OWN, SOURCE_LEAK, SOURCE_CROSS_WALL = 0, 1, 2, 3
#: Names of the reading sources, indexed by code.
SOURCE_NAMES = ("none", "own", "leak", "cross-wall")

# Default error model (docs/theory/srf02.md): sigma and slip probabilities chosen so that
# the mean absolute error is 3.5 cm, the middle of the datasheet's quoted 3-4 cm.
_NOISE_SIGMA_M = 0.043
_SLIP_PROBS = (0.25, 0.10, 0.05)
# Angular slack (rad) for window and beam tests, so exact perpendiculars stay inside.
_ANGLE_TOL = 1e-12


# ------------------------------------------------------------------------ beam pattern


def _piston_series(x: np.ndarray) -> np.ndarray:
    """``2 J1(x) / x`` by its power series (accurate to ~1e-13 for ``|x| <= 10``)."""
    h2 = (0.5 * x) ** 2
    term = np.ones_like(x)
    total = np.ones_like(x)
    for m in range(1, 40):
        term = term * (-h2 / (m * (m + 1)))
        total = total + term
    return total


def _piston(x: np.ndarray) -> np.ndarray:
    """Piston directivity ``2 J1(x) / x`` (1 at 0); scipy is imported only for ``|x| > 10``."""
    x = np.asarray(x, dtype=np.float64)
    if x.size == 0 or np.max(np.abs(x)) <= 10.0:
        return _piston_series(x)
    from scipy.special import j1

    out = _piston_series(np.minimum(np.abs(x), 10.0))
    big = np.abs(x) > 10.0
    out[big] = 2.0 * j1(x[big]) / x[big]
    return out


@functools.cache
def _half_amplitude_x() -> float:
    """The ``x`` where ``2 J1(x) / x = 1/2`` (-6.02 dB), by bisection on the main lobe."""
    lo, hi = 1.0, 3.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if _piston_series(np.array(mid)) > 0.5:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def piston_ka(beam_width_rad: float = BEAM_WIDTH_RAD) -> float:
    """The ``ka`` of a circular piston whose one-way -6 dB full beam width is given.

    Parameters
    ----------
    beam_width_rad : float
        Full width at half amplitude (-6 dB), within (0, pi) rad. Default 55° (datasheet).

    Returns
    -------
    float
        ``ka = x_half / sin(width / 2)`` with ``2 J1(x_half) / x_half = 1/2``
        (``x_half = 2.2151``).

    Examples
    --------
    >>> round(piston_ka(), 4)
    4.7972
    """
    w = in_range("beam_width_rad", beam_width_rad, 0.0, math.pi)
    if w <= 0.0 or w >= math.pi:
        raise InvalidParameterError(f"beam_width_rad={beam_width_rad!r} must be within (0, pi)")
    return _half_amplitude_x() / math.sin(0.5 * w)


def beam_pattern(off_axis_rad: Any, *, beam_width_rad: float = BEAM_WIDTH_RAD) -> np.ndarray:
    """One-way amplitude directivity ``D(psi)`` of the transducer (1 on axis).

    Parameters
    ----------
    off_axis_rad : array_like
        Angle ``psi`` between the sensor axis and the direction, rad.
    beam_width_rad : float, optional
        Full width at -6 dB (``D = 1/2``). Default 55° (datasheet).

    Returns
    -------
    numpy.ndarray
        ``D(psi) = 2 J1(ka sin psi) / (ka sin psi)`` with ``ka = piston_ka(beam_width_rad)``
        (circular piston in a baffle); 0 behind the transducer (``|psi| >= pi/2``).

    Notes
    -----
    The datasheet gives only the -6 dB width (55°) and a polar plot; Girard et al. 2011
    Fig. 2(b) shows the same main lobe. The piston is rangekit's choice of a shape with
    that width.

    Examples
    --------
    >>> beam_pattern(np.radians([0.0, 27.5])).round(6).tolist()
    [1.0, 0.5]
    """
    psi = np.asarray(off_axis_rad, dtype=np.float64)
    ka = piston_ka(beam_width_rad)
    d = _piston(ka * np.sin(psi))
    return np.where(np.abs(psi) < 0.5 * math.pi, d, 0.0)


# ---------------------------------------------------------------------------- sensor


@dataclass(frozen=True)
class SRF02:
    """Parameters of the SRF02 model (defaults from the datasheet and Girard et al. 2011).

    Parameters
    ----------
    aperture_rad : float
        Beam aperture alpha, within (0, pi): the -6 dB full width (datasheet 55°) and the
        cone split into rays (Girard 2011 §3.2). Default ``radians(55)``.
    n_rays : int
        Number of rays lambda across the aperture (Girard 2011 §3.1), >= 1. Default 7.
    min_range_m : float
        Shortest reading; echoes sooner than ``2 min_range_m / c`` fall in the ring-down
        blanking. Default 0.15 m (Girard 2011 §2.6).
    max_range_m : float
        Longest reading on axis, > ``min_range_m``. Default 6 m (datasheet).
    cycle_s : float
        Ranging cycle: the sensor listens this long after its ping. Default 0.070 s.
    noise_sigma_m : float
        Standard deviation of the Gaussian range noise, >= 0. Default 0.043 m.
    slip_probs : tuple of 3 float
        Probabilities that detection slips by one, two and three wavefronts (each >= 0,
        sum <= 1). Default (0.25, 0.10, 0.05).
    slip_step_m : float
        Range added per slipped wavefront, >= 0. Default 8.65 mm (datasheet).
    resolution_m : float
        Quantisation step of the reading, >= 0 (0 = none). Default 0.01 m (datasheet).

    Raises
    ------
    InvalidParameterError
        If a parameter is out of its domain.

    Notes
    -----
    The default error model gives a mean absolute error of 3.5 cm (datasheet: 3-4 cm);
    see :func:`read_ranges`.

    Examples
    --------
    >>> s = SRF02()
    >>> round(math.degrees(s.aperture_rad), 1), s.n_rays, s.min_range_m, s.max_range_m
    (55.0, 7, 0.15, 6.0)
    >>> round(math.degrees(s.incidence_window_rad), 4)
    3.9286
    >>> np.degrees(s.ray_offsets_rad).round(2).tolist()
    [-23.57, -15.71, -7.86, 0.0, 7.86, 15.71, 23.57]
    >>> s.max_range_at(np.radians([0.0, 27.5])).round(6).tolist()
    [6.0, 1.5]
    """

    aperture_rad: float = BEAM_WIDTH_RAD
    n_rays: int = 7
    min_range_m: float = MIN_RANGE_M
    max_range_m: float = MAX_RANGE_M
    cycle_s: float = CYCLE_S
    noise_sigma_m: float = _NOISE_SIGMA_M
    slip_probs: tuple[float, float, float] = _SLIP_PROBS
    slip_step_m: float = WAVELENGTH_M
    resolution_m: float = RESOLUTION_M

    def __post_init__(self) -> None:
        alpha = in_range("aperture_rad", self.aperture_rad, 0.0, math.pi)
        if alpha <= 0.0 or alpha >= math.pi:
            raise InvalidParameterError(f"aperture_rad={self.aperture_rad!r} must be in (0, pi)")
        n_rays = positive_int("n_rays", self.n_rays)
        rmin = positive("min_range_m", self.min_range_m)
        rmax = positive("max_range_m", self.max_range_m)
        if rmax <= rmin:
            raise InvalidParameterError(
                f"max_range_m={self.max_range_m!r} must be > min_range_m={self.min_range_m!r}"
            )
        try:
            probs = tuple(self.slip_probs)
        except TypeError:
            raise InvalidParameterError(
                f"slip_probs={self.slip_probs!r} must be 3 probabilities"
            ) from None
        if len(probs) != 3:
            raise InvalidParameterError(f"slip_probs={self.slip_probs!r} must be 3 probabilities")
        probs = tuple(in_range(f"slip_probs[{i}]", p, 0.0, 1.0) for i, p in enumerate(probs))
        if sum(probs) > 1.0 + 1e-12:
            raise InvalidParameterError(f"slip_probs={self.slip_probs!r} must sum to <= 1")
        values = {
            "aperture_rad": alpha,
            "n_rays": n_rays,
            "min_range_m": rmin,
            "max_range_m": rmax,
            "cycle_s": positive("cycle_s", self.cycle_s),
            "noise_sigma_m": positive("noise_sigma_m", self.noise_sigma_m, allow_zero=True),
            "slip_probs": probs,
            "slip_step_m": positive("slip_step_m", self.slip_step_m, allow_zero=True),
            "resolution_m": positive("resolution_m", self.resolution_m, allow_zero=True),
        }
        for k, v in values.items():
            object.__setattr__(self, k, v)

    @property
    def incidence_window_rad(self) -> float:
        """Half width ``alpha / (2 lambda)`` of the incidence window of Girard eq. (3), rad."""
        return self.aperture_rad / (2 * self.n_rays)

    @property
    def ray_offsets_rad(self) -> np.ndarray:
        """Off-axis angles of the lambda rays: centres of lambda equal sub-sectors of alpha.

        ``psi_j = -alpha/2 + (j + 1/2) alpha / lambda``; with the window of eq. (3) each ray
        accepts walls whose normal lies in its own sub-sector, so together the rays cover
        the beam without gaps or overlaps.
        """
        j = np.arange(self.n_rays, dtype=np.float64)
        return -0.5 * self.aperture_rad + (j + 0.5) * self.aperture_rad / self.n_rays

    def max_range_at(self, off_axis_rad: Any) -> np.ndarray:
        """Longest range of a flat-wall echo arriving from ``off_axis_rad``, in m.

        ``max_range_m * D(psi)**2``: the echo passes the two-way pattern ``D**2`` and a
        specular echo's amplitude falls as ``1 / (2 r)`` (image source), so the detection
        limit scales linearly with ``D**2``. It is ``max_range_m / 4`` at the beam edge.
        """
        d = beam_pattern(off_axis_rad, beam_width_rad=self.aperture_rad)
        return self.max_range_m * d * d


# ---------------------------------------------------------------------- range model


def _poses(pose: Any) -> np.ndarray:
    """``pose`` as finite float64 ``(n, 3)`` rows ``(x, y, heading)``."""
    p = np.asarray(pose, dtype=np.float64)
    if p.ndim == 0 or p.shape[-1] != 3:
        raise InvalidParameterError(
            f"pose must have shape (3,) or (n, 3) (x_m, y_m, heading_rad), got {p.shape}"
        )
    if not np.all(np.isfinite(p)):
        raise InvalidParameterError("pose contains NaN or infinite values")
    return p.reshape(-1, 3)


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles wrapped into [-pi, pi)."""
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def _rays_model(
    seg: np.ndarray,
    p: np.ndarray,
    sensor: SRF02,
    mount: float,
    secondary: bool,
    max_bounces: int,
) -> np.ndarray:
    """Girard 2011 §3.2 ray model, shortest accepted path per pose (inf for none)."""
    n, lam = p.shape[0], sensor.n_rays
    psi = sensor.ray_offsets_rad
    ang = ((p[:, 2] + mount)[:, None] + psi[None, :]).reshape(-1)
    ox = np.repeat(p[:, 0], lam)
    oy = np.repeat(p[:, 1], lam)
    dx, dy = np.cos(ang), np.sin(ang)
    rmax = np.tile(sensor.max_range_at(psi), n)
    dist, hit, theta = _raycast.cast(ox, oy, dx, dy, rmax, seg, np.full(n * lam, -1, np.int64))
    thr = 0.5 * np.pi - sensor.incidence_window_rad - _ANGLE_TOL
    found = hit >= 0
    in_window = found & (theta >= thr)
    cand = np.where(in_window & (dist >= sensor.min_range_m), dist, np.inf)
    if secondary and seg.shape[0]:
        live = np.flatnonzero(found & ~in_window)
        path = dist[live]
        px, py = ox[live] + path * dx[live], oy[live] + path * dy[live]
        vx, vy, last = dx[live], dy[live], hit[live]
        ex = seg[:, 2] - seg[:, 0]
        ey = seg[:, 3] - seg[:, 1]
        elen = np.hypot(ex, ey)
        ux, uy = ex / elen, ey / elen
        for _ in range(max_bounces):
            if live.size == 0:
                break
            # Specular reflection of the direction about the wall line: v' = 2 (v.u) u - v.
            wx, wy = ux[last], uy[last]
            dot = vx * wx + vy * wy
            vx, vy = 2.0 * dot * wx - vx, 2.0 * dot * wy - vy
            norm = np.hypot(vx, vy)
            vx, vy = vx / norm, vy / norm
            budget = np.maximum(rmax[live] - path, 0.0)
            d2, h2, th2 = _raycast.cast(
                np.ascontiguousarray(px), np.ascontiguousarray(py), vx, vy, budget, seg, last
            )
            hit2 = h2 >= 0
            back = hit2 & (th2 >= thr)
            total = path + d2
            ok = back & (total >= sensor.min_range_m)
            cand[live[ok]] = np.minimum(cand[live[ok]], total[ok])
            go = hit2 & ~back
            live, path, last = live[go], total[go], h2[go]
            px, py = px[go] + d2[go] * vx[go], py[go] + d2[go] * vy[go]
            vx, vy = vx[go], vy[go]
    return cand.reshape(n, lam).min(axis=1)


def _specular_model(seg: np.ndarray, p: np.ndarray, sensor: SRF02, mount: float) -> np.ndarray:
    """Earliest specular echo (foot of the perpendicular) per pose (inf for none)."""
    n, m = p.shape[0], seg.shape[0]
    out = np.full(n, np.inf)
    if m == 0 or n == 0:
        return out
    ax, ay = seg[:, 0], seg[:, 1]
    ex, ey = seg[:, 2] - ax, seg[:, 3] - ay
    len2 = ex * ex + ey * ey
    half = 0.5 * sensor.aperture_rad + _ANGLE_TOL
    step = max(1, (1 << 18) // m)
    for s in range(0, n, step):
        sx, sy = p[s : s + step, 0:1], p[s : s + step, 1:2]
        axis = p[s : s + step, 2:3] + mount
        u = ((sx - ax) * ex + (sy - ay) * ey) / len2
        fx, fy = ax + u * ex, ay + u * ey
        vx, vy = fx - sx, fy - sy
        d = np.hypot(vx, vy)
        psi = _wrap(np.arctan2(vy, vx) - axis)
        ok = (u >= 0.0) & (u <= 1.0) & (np.abs(psi) <= half) & (d >= sensor.min_range_m)
        ok &= d <= sensor.max_range_at(np.where(ok, psi, 0.0))
        cand = np.where(ok, d, np.inf)
        # Drop candidates whose perpendicular is blocked by a nearer wall, and retry.
        rows = np.arange(cand.shape[0])
        while rows.size:
            k = np.argmin(cand[rows], axis=1)
            best = cand[rows, k]
            keep = np.isfinite(best)
            rows, k, best = rows[keep], k[keep], best[keep]
            if rows.size == 0:
                break
            ox, oy = sx[rows, 0], sy[rows, 0]
            dirx, diry = vx[rows, k] / best, vy[rows, k] / best
            dist, hit, _ = _raycast.cast(
                ox, oy, dirx, diry, best, seg, np.full(rows.size, -1, np.int64)
            )
            blocked = (hit >= 0) & (hit != k) & (dist < best - 1e-9)
            out[s + rows[~blocked]] = best[~blocked]
            cand[rows[blocked], k[blocked]] = np.inf
            rows = rows[blocked]
    return out


def model_range(
    plan: FloorPlan,
    pose: Any,
    sensor: SRF02 | None = None,
    *,
    mount_angle_rad: float = 0.0,
    method: str = "rays",
    secondary: bool = False,
    max_bounces: int = 2,
) -> np.ndarray:
    """Noise-free SRF02 reading for sensor poses in a floor plan.

    Parameters
    ----------
    plan : FloorPlan
        The walls.
    pose : array_like, shape (3,) or (..., 3)
        Device poses ``(x_m, y_m, heading_rad)``, heading counter-clockwise from +x.
    sensor : SRF02, optional
        Sensor parameters; default ``SRF02()``.
    mount_angle_rad : float, optional
        Sensor axis relative to the heading (e.g. ``+pi/2`` left, ``-pi/2`` right for
        Girard's back-to-back pair). Default 0.
    method : {"rays", "specular"}, optional
        ``"rays"``: Girard et al. 2011 §3.2 (see Notes). ``"specular"``: the earliest
        specular echo a real transducer hears. Default ``"rays"``.
    secondary : bool, optional
        With ``method="rays"``, follow rays that a wall does not send back (Girard 2011
        §2.6.4, Fig. 3b). Default False.
    max_bounces : int, optional
        Reflections followed per ray when ``secondary`` is set, >= 1. Default 2.

    Returns
    -------
    numpy.ndarray
        float64 of shape ``pose.shape[:-1]``: range in m, NaN when out of range.

    Raises
    ------
    InvalidParameterError
        On bad poses or options (``secondary=True`` needs ``method="rays"``).

    Notes
    -----
    **Rays** (Girard 2011 §3.2): lambda rays at off-axis angles
    ``psi_j = -alpha/2 + (j + 1/2) alpha / lambda`` (:attr:`SRF02.ray_offsets_rad`). Each
    ray stops at its first wall. A hit counts if its incidence angle satisfies eq. (3),
    ``pi/2 - alpha/(2 lambda) <= theta <= pi/2 + alpha/(2 lambda)`` (theta folded into
    ``[0, pi/2]`` as in :func:`rangekit.floorplan.cast_rays`, so ``theta >= pi/2 -
    alpha/(2 lambda)``), its distance is at most ``max_range_at(psi_j)`` and at least
    ``min_range_m``; the shortest counted hit is the reading ("the shortest one is kept").

    **Secondary** reflections: a ray whose hit fails eq. (3) is reflected specularly and
    followed for up to ``max_bounces`` reflections; if a later leg meets a wall within the
    window, the echo retraces the path and the reading is the total one-way path length
    (a false long reading), still at most ``max_range_at(psi_j)``.

    **Specular**: for each wall segment, the foot of the perpendicular from the sensor, if
    it lies on the segment, within ``alpha/2`` of the axis, within ``max_range_at(psi)``
    and not behind a nearer wall; the reading is the nearest such foot.

    Readings shorter than ``min_range_m`` (ring-down, Girard 2011 §2.6) are dropped as out
    of range; the shortest remaining candidate is kept.

    Examples
    --------
    >>> from rangekit.floorplan import FloorPlan
    >>> plan = FloorPlan.from_walls([((0, 1), (10, 1)), ((0, -1.5), (10, -1.5))])
    >>> poses = [(2.0, 0.0, 0.0), (5.0, 0.0, 0.0)]
    >>> model_range(plan, poses, mount_angle_rad=np.pi / 2).tolist()
    [1.0, 1.0]
    >>> model_range(plan, poses, mount_angle_rad=-np.pi / 2, method="specular").tolist()
    [1.5, 1.5]
    """
    if not isinstance(plan, FloorPlan):
        raise InvalidParameterError(f"plan must be a FloorPlan, got {type(plan).__name__}")
    sensor = SRF02() if sensor is None else sensor
    if not isinstance(sensor, SRF02):
        raise InvalidParameterError(f"sensor must be an SRF02, got {type(sensor).__name__}")
    batch = np.shape(pose)[:-1]
    p = _poses(pose)
    mount = float(mount_angle_rad)
    if not math.isfinite(mount):
        raise InvalidParameterError(f"mount_angle_rad={mount_angle_rad!r} must be finite")
    if method not in ("rays", "specular"):
        raise InvalidParameterError(f"method={method!r} must be 'rays' or 'specular'")
    max_bounces = positive_int("max_bounces", max_bounces)
    seg = np.ascontiguousarray(plan.segments)
    if method == "rays":
        r = _rays_model(seg, p, sensor, mount, bool(secondary), max_bounces)
    elif secondary:
        raise InvalidParameterError("secondary=True needs method='rays'")
    else:
        r = _specular_model(seg, p, sensor, mount)
    r[~np.isfinite(r)] = np.nan
    return r.reshape(batch)


# ---------------------------------------------------------------------- error model


def read_ranges(true_ranges_m: Any, sensor: SRF02 | None = None, *, rng: RngLike = None):
    """Readings with the SRF02 error model applied to noise-free ranges.

    Parameters
    ----------
    true_ranges_m : array_like
        Noise-free ranges in m (from :func:`model_range`); NaN (out of range) stays NaN.
    sensor : SRF02, optional
        Error-model parameters; default ``SRF02()``.
    rng : RngLike, optional
        Random source, anything :func:`numpy.random.default_rng` accepts.

    Returns
    -------
    numpy.ndarray
        float64 readings of the same shape.

    Notes
    -----
    ``reading = Q(r + sigma n + k s)``, floored at ``min_range_m``: ``n ~ N(0, 1)``;
    ``k`` in {0, 1, 2, 3} slipped wavefronts with probabilities
    ``(1 - p1 - p2 - p3, p1, p2, p3)`` (datasheet: detection may trigger on the first,
    second or third wavefront, 8.65 mm of jitter each); ``Q`` rounds to ``resolution_m``
    (1 cm). With the defaults (sigma 4.3 cm, slips 25/10/5 %) the mean absolute error is
    3.5 cm and the mean error +5 mm (slips only lengthen): the datasheet quotes 3-4 cm
    without a distribution, Girard 2011 §2.6 "an average range error of 3 to 4 cm".

    Examples
    --------
    >>> r = read_ranges(np.full(100_000, 2.0), rng=0)
    >>> bool(0.03 <= np.mean(np.abs(r - 2.0)) <= 0.04)
    True
    >>> read_ranges([np.nan, 1.0], SRF02(noise_sigma_m=0, slip_probs=(0, 0, 0)), rng=0).tolist()
    [nan, 1.0]
    """
    sensor = SRF02() if sensor is None else sensor
    if not isinstance(sensor, SRF02):
        raise InvalidParameterError(f"sensor must be an SRF02, got {type(sensor).__name__}")
    r = np.array(true_ranges_m, dtype=np.float64)
    if np.any(np.isinf(r)) or np.any(r < 0.0):
        raise InvalidParameterError("true_ranges_m must be >= 0 and finite (NaN = out of range)")
    g = np.random.default_rng(rng)
    p = np.array([1.0 - sum(sensor.slip_probs), *sensor.slip_probs])
    k = g.choice(4, size=r.shape, p=p / p.sum())
    out = r + sensor.noise_sigma_m * g.standard_normal(r.shape) + k * sensor.slip_step_m
    if sensor.resolution_m > 0.0:
        out = np.round(out / sensor.resolution_m) * sensor.resolution_m
    return np.where(np.isnan(r), np.nan, np.maximum(out, sensor.min_range_m))


# --------------------------------------------------------------- firing and crosstalk


def _latency(usb_latency_s: Any) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in usb_latency_s)
    except (TypeError, ValueError):
        raise InvalidParameterError(
            f"usb_latency_s={usb_latency_s!r} must be a pair (min_s, max_s)"
        ) from None
    lo = positive("usb_latency_s[0]", lo, allow_zero=True)
    hi = positive("usb_latency_s[1]", hi, allow_zero=True)
    if hi < lo:
        raise InvalidParameterError(f"usb_latency_s={usb_latency_s!r} must have min <= max")
    return lo, hi


def schedule_firings(
    n_sensors: int,
    n_cycles: int,
    *,
    mode: str = "sequential",
    cycle_s: float = CYCLE_S,
    usb_latency_s: tuple[float, float] = USB_LATENCY_S,
    rng: RngLike = None,
) -> np.ndarray:
    """Ping times of sensors driven over USB (Girard et al. 2011 §2.6.5).

    Parameters
    ----------
    n_sensors, n_cycles : int
        Sensors and ranging cycles, each >= 1.
    mode : {"sequential", "simultaneous"}, optional
        ``"sequential"`` (Girard's fix): a sensor is fired only after the previous one's
        result came back. ``"simultaneous"``: each cycle, the commands to all sensors are
        sent at once. Default ``"sequential"``.
    cycle_s : float, optional
        Ranging cycle in s, > 0. Default 0.070.
    usb_latency_s : tuple of 2 float, optional
        Each latency is drawn uniformly from ``[min, max]`` s. Default (0.001, 0.004).
    rng : RngLike, optional
        Random source, anything :func:`numpy.random.default_rng` accepts.

    Returns
    -------
    numpy.ndarray
        float64 ``(n_cycles, n_sensors)``: ping times in s; t = 0 is when the host sends
        the first command.

    Notes
    -----
    Sequential: firing k (cycle-major: cycle c, sensor i is k = c n + i) happens at
    ``t_k = t_{k-1} + cycle_s + L_k``, ``t_0 = L_0``: one latency draw stands for the
    host's turnaround (result back, next command out). Simultaneous: cycle c's commands
    leave at ``T_c`` and sensor i fires at ``T_c + L_ci``; the next cycle starts when the
    last result is back, ``T_{c+1} = max_i(T_c + L_ci) + cycle_s + L'_c``.

    Examples
    --------
    >>> t = schedule_firings(2, 3, rng=0)
    >>> t.shape, bool(np.all(np.diff(t.reshape(-1)) >= 0.071))
    ((3, 2), True)
    >>> t = schedule_firings(2, 3, mode="simultaneous", rng=0)
    >>> bool(np.all(np.ptp(t, axis=1) <= 0.003))
    True
    """
    n_sensors = positive_int("n_sensors", n_sensors)
    n_cycles = positive_int("n_cycles", n_cycles)
    cycle_s = positive("cycle_s", cycle_s)
    lo, hi = _latency(usb_latency_s)
    g = np.random.default_rng(rng)
    if mode == "sequential":
        lat = g.uniform(lo, hi, n_cycles * n_sensors)
        steps = lat + np.r_[0.0, np.full(lat.size - 1, cycle_s)]
        return np.cumsum(steps).reshape(n_cycles, n_sensors)
    if mode == "simultaneous":
        lat = g.uniform(lo, hi, (n_cycles, n_sensors))
        turn = g.uniform(lo, hi, n_cycles)
        starts = np.r_[0.0, np.cumsum(lat.max(axis=1) + cycle_s + turn)[:-1]]
        return starts[:, None] + lat
    raise InvalidParameterError(f"mode={mode!r} must be 'sequential' or 'simultaneous'")


@dataclass(frozen=True)
class SRF02Readings:
    """Readings of several sensors over several cycles (see :func:`simulate_readings`).

    Attributes
    ----------
    range_m : numpy.ndarray
        float64 ``(n_cycles, n_sensors)``: reading in m, NaN when out of range.
    source : numpy.ndarray
        int8 ``(n_cycles, n_sensors)``: what produced the reading, :data:`SOURCE_NONE`,
        :data:`SOURCE_OWN`, :data:`SOURCE_LEAK` or :data:`SOURCE_CROSS_WALL`
        (names in :data:`SOURCE_NAMES`).
    """

    range_m: np.ndarray
    source: np.ndarray


def _earliest_at_or_after(sorted_times: np.ndarray, lo: np.ndarray) -> np.ndarray:
    """For each ``lo``, the first of ``sorted_times`` that is ``>= lo`` (inf if none)."""
    idx = np.searchsorted(sorted_times, lo, side="left")
    padded = np.r_[sorted_times, np.inf]
    return padded[idx]


def simulate_readings(
    fire_times_s: Any,
    ranges_m: Any,
    sensor: SRF02 | None = None,
    *,
    temp_c: float = DATASHEET_TEMP_C,
    leak_path_m: float = 0.05,
) -> SRF02Readings:
    """Readings of back-to-back sensors with crosstalk (Girard et al. 2011 §2.6.5).

    Parameters
    ----------
    fire_times_s : array_like, shape (n_cycles, n_sensors)
        Ping times in s (:func:`schedule_firings`).
    ranges_m : array_like, shape (n_cycles, n_sensors) or (n_sensors,)
        True range ``d_i`` of each sensor's own echo (:func:`model_range`), NaN if none.
    sensor : SRF02, optional
        Supplies ``min_range_m`` and ``cycle_s``; default ``SRF02()``.
    temp_c : float, optional
        Air temperature for the speed of sound; default 24 °C (datasheet: 346 m/s).
    leak_path_m : float, optional
        Direct path from one transducer to the other, > 0. Default 0.05 m.

    Returns
    -------
    SRF02Readings
        Noise-free readings and their sources; apply :func:`read_ranges` for noise.

    Notes
    -----
    Sensor i fired at ``t_i`` listens until ``t_i + cycle_s`` and is deaf before
    ``t_i + 2 min_range_m / c`` (ring-down). It hears, from every firing of itself and of
    every other sensor j:

    * its own echo at ``t_i + 2 d_i / c``;
    * j's ping directly, at ``t_j + leak_path_m / c`` (attenuated but detectable);
    * j's ping via the walls (j's wall, back past the device to i's wall and back to i)
      at ``t_j + 2 (d_i + d_j) / c``.

    The reading is ``c/2 (a - t_i)`` for the earliest heard arrival ``a`` (own echo on a
    tie), out of range if none. Fired within the 1-4 ms USB latency of each other, the
    first sensor hears the other's ping and reads tens of cm; fired sequentially, each
    ping is at least a cycle old when the next sensor listens and nothing leaks.

    Examples
    --------
    >>> fire = np.array([[0.0, 0.002], [0.1, 0.3]])
    >>> out = simulate_readings(fire, [1.0, 2.0])
    >>> out.range_m.round(3).tolist()
    [[0.371, 2.0], [1.0, 2.0]]
    >>> [[SOURCE_NAMES[s] for s in row] for row in out.source.tolist()]
    [['leak', 'own'], ['own', 'own']]
    """
    sensor = SRF02() if sensor is None else sensor
    if not isinstance(sensor, SRF02):
        raise InvalidParameterError(f"sensor must be an SRF02, got {type(sensor).__name__}")
    t = np.asarray(fire_times_s, dtype=np.float64)
    if t.ndim != 2 or t.size == 0:
        raise InvalidParameterError(
            f"fire_times_s must have shape (n_cycles, n_sensors), got {np.shape(fire_times_s)}"
        )
    if not np.all(np.isfinite(t)):
        raise InvalidParameterError("fire_times_s contains NaN or infinite values")
    try:
        d = np.broadcast_to(np.asarray(ranges_m, dtype=np.float64), t.shape)
    except ValueError:
        raise InvalidParameterError(
            f"ranges_m {np.shape(ranges_m)} does not fit fire_times_s {t.shape}"
        ) from None
    if np.any(np.isinf(d)) or np.any(d < 0.0):
        raise InvalidParameterError("ranges_m must be >= 0 and finite (NaN = no echo)")
    leak = positive("leak_path_m", leak_path_m)
    c = speed_of_sound_m_s(temp_c)
    n_sensors = t.shape[1]
    lo = t + 2.0 * sensor.min_range_m / c
    hi = t + sensor.cycle_s
    # Own echo first, so that a tie keeps SOURCE_OWN (later sources must be strictly sooner).
    own = t + 2.0 * d / c
    heard = (own >= lo) & (own <= hi)
    best = np.where(heard, own, np.inf)
    source = np.where(heard, SOURCE_OWN, SOURCE_NONE).astype(np.int8)
    echo_back = t + 2.0 * d / c  # when j's own echo is back at the device (NaN: none)
    for i in range(n_sensors):
        for j in range(n_sensors):
            if j == i:
                continue
            leak_t = np.sort(t[:, j]) + leak / c
            a = _earliest_at_or_after(leak_t, lo[:, i])
            k_i = 2.0 * d[:, i] / c
            back = np.sort(echo_back[np.isfinite(echo_back[:, j]), j])
            b = _earliest_at_or_after(back, np.where(np.isnan(k_i), np.inf, lo[:, i] - k_i))
            b = np.where(np.isnan(k_i), np.inf, b + k_i)
            for arrival, code in ((a, SOURCE_LEAK), (b, SOURCE_CROSS_WALL)):
                take = (arrival <= hi[:, i]) & (arrival < best[:, i])
                best[take, i] = arrival[take]
                source[take, i] = code
    reading = np.where(np.isfinite(best), 0.5 * c * (best - t), np.nan)
    return SRF02Readings(range_m=reading, source=source)
