"""Floor plans: wall segments with door openings, validation and ray casting.

A floor plan is a set of straight walls in a horizontal plane (metres). Doors are
openings cut out of a wall; what remains are the solid *segments* that rays and moves
are tested against. The JSON form (``docs/floorplan.md``)::

    {"format": "rangekit-floorplan", "version": 1, "units": "m",
     "walls": [{"from": [0, 0], "to": [10, 0]},
               {"from": [0, 2], "to": [10, 2], "doors": [{"at_m": 2.0, "width_m": 0.9}]}]}

``at_m`` is the distance along the wall from its ``from`` end to the door's first edge.

Ray casting is brute force over all segments (one compiled pass per ray; numba for large
problems). A spatial grid of tiles (Girard et al. 2011, §3: 2 m x 2 m tiles) is a later
optimisation.

Examples
--------
>>> plan = FloorPlan.from_walls([((0, 0), (4, 0)), ((0, 0), (0, 3))])
>>> plan.segments.tolist()
[[0.0, 0.0, 4.0, 0.0], [0.0, 0.0, 0.0, 3.0]]
>>> hits = cast_rays(plan, [[1.0, 2.0]], [-np.pi / 2], 6.0)
>>> float(hits.distance_m[0]), int(hits.segment[0]), round(float(hits.incidence_rad[0]), 6)
(2.0, 0, 1.570796)
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from rangekit import _raycast
from rangekit._jsondoc import check_header, json_number
from rangekit.errors import InputFileError, InvalidParameterError

__all__ = [
    "FORMAT",
    "VERSION",
    "Door",
    "FloorPlan",
    "RayHits",
    "Wall",
    "cast_rays",
    "load_floorplan",
    "segment_crosses_wall",
]

#: Value of the ``"format"`` key of a floor-plan JSON document.
FORMAT = "rangekit-floorplan"
#: Floor-plan format version this module reads and writes.
VERSION = 1
#: Door ends may overshoot the wall end by this much (m) to absorb rounding in the JSON.
_TOL_M = 1e-9

_TOP_KEYS = {"format", "version", "units", "walls", "name", "notes"}
_WALL_KEYS = {"from", "to", "doors"}
_DOOR_KEYS = {"at_m", "width_m"}


_number = json_number


def _point(where: str, p: Any) -> tuple[float, float]:
    """A finite 2-D point ``(x, y)`` from a JSON value, or raise naming ``where``."""
    if isinstance(p, np.ndarray):
        p = p.tolist()
    if isinstance(p, (str, bytes)) or not isinstance(p, Sequence) or len(p) != 2:
        raise InvalidParameterError(f"{where}={p!r} must be a point [x, y] in m")
    return (_number(f"{where}[0]", p[0]), _number(f"{where}[1]", p[1]))


@dataclass(frozen=True)
class Door:
    """An opening in a wall.

    Parameters
    ----------
    at_m : float
        Distance along the wall from its start point to the door's first edge, >= 0.
    width_m : float
        Width of the opening along the wall, > 0.
    """

    at_m: float
    width_m: float


@dataclass(frozen=True)
class Wall:
    """A straight wall from ``start_m`` to ``end_m`` with optional door openings.

    Parameters
    ----------
    start_m, end_m : tuple of 2 float
        End points ``(x, y)`` in metres (the JSON keys ``from`` and ``to``).
    doors : tuple of Door
        Openings, sorted by ``at_m``, not overlapping, inside the wall.
    """

    start_m: tuple[float, float]
    end_m: tuple[float, float]
    doors: tuple[Door, ...] = ()

    @property
    def length_m(self) -> float:
        """Wall length in metres."""
        return math.hypot(self.end_m[0] - self.start_m[0], self.end_m[1] - self.start_m[1])

    def solid_pieces(self) -> list[tuple[float, float]]:
        """Intervals ``(s0, s1)`` along the wall (m from the start) that are solid."""
        pieces, s = [], 0.0
        for d in self.doors:
            if d.at_m > s:
                pieces.append((s, d.at_m))
            s = max(s, d.at_m + d.width_m)
        if self.length_m > s:
            pieces.append((s, self.length_m))
        return pieces


def _check_wall(i: int, wall: Any) -> Wall:
    """Validate one wall given as a :class:`Wall`, a JSON mapping or a pair of points."""
    where = f"walls[{i}]"
    if isinstance(wall, Wall):
        raw = {
            "from": wall.start_m,
            "to": wall.end_m,
            "doors": [{"at_m": d.at_m, "width_m": d.width_m} for d in wall.doors],
        }
    elif isinstance(wall, Mapping):
        raw = wall
    elif isinstance(wall, (Sequence, np.ndarray)) and not isinstance(wall, (str, bytes)):
        if len(wall) != 2:
            raise InvalidParameterError(
                f"{where}={wall!r} must be a mapping with 'from' and 'to' or a pair of points"
            )
        raw = {"from": wall[0], "to": wall[1]}
    else:
        raise InvalidParameterError(
            f"{where}={wall!r} must be a mapping with 'from' and 'to' or a pair of points"
        )
    missing = [k for k in ("from", "to") if k not in raw]
    if missing:
        raise InvalidParameterError(f"{where}: missing key {missing[0]!r}")
    unknown = sorted(set(raw) - _WALL_KEYS)
    if unknown:
        raise InvalidParameterError(
            f"{where}: unknown key {unknown[0]!r} (expected 'from', 'to', 'doors')"
        )
    a = _point(f"{where}.from", raw["from"])
    b = _point(f"{where}.to", raw["to"])
    length = math.hypot(b[0] - a[0], b[1] - a[1])
    if not length > 0.0:
        raise InvalidParameterError(f"{where}: zero-length wall from {list(a)} to {list(b)}")
    raw_doors = raw.get("doors", [])
    if isinstance(raw_doors, (str, bytes, Mapping)) or not isinstance(raw_doors, Sequence):
        raise InvalidParameterError(f"{where}.doors={raw_doors!r} must be a list of doors")
    doors = []
    for j, d in enumerate(raw_doors):
        dw = f"{where}.doors[{j}]"
        if isinstance(d, Door):
            d = {"at_m": d.at_m, "width_m": d.width_m}
        if not isinstance(d, Mapping):
            raise InvalidParameterError(f"{dw}={d!r} must be a mapping with 'at_m' and 'width_m'")
        for k in ("at_m", "width_m"):
            if k not in d:
                raise InvalidParameterError(f"{dw}: missing key {k!r}")
        unknown = sorted(set(d) - _DOOR_KEYS)
        if unknown:
            raise InvalidParameterError(
                f"{dw}: unknown key {unknown[0]!r} (expected 'at_m', 'width_m')"
            )
        at = _number(f"{dw}.at_m", d["at_m"])
        width = _number(f"{dw}.width_m", d["width_m"])
        if at < 0.0:
            raise InvalidParameterError(f"{dw}.at_m={at!r} must be >= 0")
        if width <= 0.0:
            raise InvalidParameterError(f"{dw}.width_m={width!r} must be > 0")
        if at + width > length + _TOL_M:
            raise InvalidParameterError(
                f"{dw}: door [{at:g}, {at + width:g}] m lies outside its wall (length {length:g} m)"
            )
        doors.append((j, Door(at, min(width, length - at))))
    doors.sort(key=lambda jd: jd[1].at_m)
    for (j0, d0), (j1, d1) in itertools.pairwise(doors):
        if d1.at_m < d0.at_m + d0.width_m:
            raise InvalidParameterError(
                f"{where}: doors[{j0}] [{d0.at_m:g}, {d0.at_m + d0.width_m:g}] m and "
                f"doors[{j1}] [{d1.at_m:g}, {d1.at_m + d1.width_m:g}] m overlap"
            )
    return Wall(a, b, tuple(d for _, d in doors))


@dataclass(frozen=True, eq=False)
class FloorPlan:
    """Walls of a floor, and the solid segments left after cutting the doors out.

    Parameters
    ----------
    walls : sequence
        Walls as :class:`Wall` objects, JSON-style mappings
        (``{"from": [x, y], "to": [x, y], "doors": [...]}``) or pairs of points; all are
        validated (finite coordinates, non-zero length, doors inside their wall and not
        overlapping) and stored as a tuple of :class:`Wall`.

    Attributes
    ----------
    segments : numpy.ndarray
        Read-only float64 array ``(n, 4)`` of solid wall pieces ``x0, y0, x1, y1`` (m), in
        wall order and along each wall from its start.
    segment_wall : numpy.ndarray
        Read-only int64 array ``(n,)``: the index in ``walls`` of each segment.

    Raises
    ------
    InvalidParameterError
        If a wall is invalid; the message names the wall index (``walls[3]: ...``).

    Examples
    --------
    >>> wall = {"from": [0, 0], "to": [5, 0], "doors": [{"at_m": 1.0, "width_m": 0.8}]}
    >>> plan = FloorPlan.from_walls([wall])
    >>> plan.segments.tolist()
    [[0.0, 0.0, 1.0, 0.0], [1.8, 0.0, 5.0, 0.0]]
    >>> plan.segment_wall.tolist(), plan.bounds
    ([0, 0], (0.0, 0.0, 5.0, 0.0))
    """

    walls: tuple[Wall, ...]
    segments: np.ndarray = field(init=False, repr=False)
    segment_wall: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        raw = self.walls
        if isinstance(raw, (str, bytes, Mapping)) or not isinstance(raw, (Sequence, np.ndarray)):
            raise InvalidParameterError(f"walls={raw!r} must be a list of walls")
        walls = tuple(_check_wall(i, w) for i, w in enumerate(raw))
        rows, owner = [], []
        for i, w in enumerate(walls):
            (x0, y0), (x1, y1) = w.start_m, w.end_m
            ux, uy = (x1 - x0) / w.length_m, (y1 - y0) / w.length_m
            for s0, s1 in w.solid_pieces():
                a = (x0, y0) if s0 == 0.0 else (x0 + s0 * ux, y0 + s0 * uy)
                b = (x1, y1) if s1 == w.length_m else (x0 + s1 * ux, y0 + s1 * uy)
                rows.append((*a, *b))
                owner.append(i)
        seg = np.array(rows, dtype=np.float64).reshape(-1, 4)
        seg_wall = np.array(owner, dtype=np.int64)
        seg.flags.writeable = False
        seg_wall.flags.writeable = False
        object.__setattr__(self, "walls", walls)
        object.__setattr__(self, "segments", seg)
        object.__setattr__(self, "segment_wall", seg_wall)

    @classmethod
    def from_walls(cls, walls: Sequence[Any]) -> FloorPlan:
        """Build a plan from walls (see the class parameters); same as ``FloorPlan(walls)``."""
        return cls(walls)

    @classmethod
    def from_json(cls, obj: Any) -> FloorPlan:
        """Build a plan from a parsed floor-plan JSON document.

        Parameters
        ----------
        obj : dict
            ``{"format": "rangekit-floorplan", "version": 1, "units": "m",
            "walls": [...]}``; optional ``"name"`` and ``"notes"`` are ignored.

        Raises
        ------
        InvalidParameterError
            On a missing or unknown key, another format, version or unit, or an invalid
            wall (the message names the wall index).

        Examples
        --------
        >>> doc = {"format": "rangekit-floorplan", "version": 1, "units": "m",
        ...        "walls": [{"from": [0, 0], "to": [3, 0]}]}
        >>> FloorPlan.from_json(doc).segments.shape
        (1, 4)
        """
        check_header(
            obj, what="a floor plan", fmt=FORMAT, version=VERSION, body="walls", allowed=_TOP_KEYS
        )
        walls = obj["walls"]
        if not isinstance(walls, list):
            raise InvalidParameterError(f"walls={walls!r} must be a list of walls")
        return cls(walls)

    def to_json(self) -> dict[str, Any]:
        """The plan as a JSON-ready dict (round-trips through :meth:`from_json`).

        Examples
        --------
        >>> plan = FloorPlan.from_walls([((0, 0), (2, 0))])
        >>> plan.to_json()["walls"]
        [{'from': [0.0, 0.0], 'to': [2.0, 0.0], 'doors': []}]
        """
        return {
            "format": FORMAT,
            "version": VERSION,
            "units": "m",
            "walls": [
                {
                    "from": list(w.start_m),
                    "to": list(w.end_m),
                    "doors": [{"at_m": d.at_m, "width_m": d.width_m} for d in w.doors],
                }
                for w in self.walls
            ],
        }

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of all wall end points in m (NaN for no walls)."""
        if not self.walls:
            return (math.nan,) * 4
        pts = np.array([p for w in self.walls for p in (w.start_m, w.end_m)])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))


def load_floorplan(path: str | os.PathLike) -> FloorPlan:
    """Read and validate a floor-plan JSON file.

    Parameters
    ----------
    path : str or os.PathLike
        File in the format of ``docs/floorplan.md``.

    Returns
    -------
    FloorPlan

    Raises
    ------
    InputFileError
        If the file is missing, is not JSON, or is not a valid floor plan; the message
        names the file and, for a bad wall, its index (``'plan.json' is not a valid floor
        plan: walls[2]: zero-length wall ...``).
    """
    from rangekit.io.sidecar import read_json

    obj = read_json(path)
    try:
        return FloorPlan.from_json(obj)
    except InvalidParameterError as e:
        raise InputFileError(f"'{os.fspath(path)}' is not a valid floor plan: {e}") from e


class RayHits(NamedTuple):
    """First wall hit of each ray (see :func:`cast_rays`)."""

    #: float64 (n,): distance from the ray origin to the hit in m; NaN if nothing was hit.
    distance_m: np.ndarray
    #: int64 (n,): row of ``plan.segments`` hit (-1 if none); ``plan.segment_wall`` maps it
    #: to the wall index of the JSON file.
    segment: np.ndarray
    #: float64 (n,): incidence angle theta in [0, pi/2] rad (pi/2 = perpendicular); NaN.
    incidence_rad: np.ndarray


def _points(name: str, p: Any) -> np.ndarray:
    """``p`` as finite float64 ``(n, 2)`` (a single point becomes ``(1, 2)``)."""
    a = np.asarray(p, dtype=np.float64)
    if a.ndim == 1:
        a = a.reshape(1, -1)
    if a.ndim != 2 or a.shape[1] != 2:
        raise InvalidParameterError(f"{name} must have shape (n, 2), got {np.shape(p)}")
    if not np.all(np.isfinite(a)):
        raise InvalidParameterError(f"{name} contains NaN or infinite coordinates")
    return a


def cast_rays(plan: FloorPlan, origins_m: Any, angles_rad: Any, max_range_m: Any) -> RayHits:
    """First wall segment hit by each ray, with distance and incidence angle.

    Parameters
    ----------
    plan : FloorPlan
        The walls (doors are openings: rays pass through them).
    origins_m : array_like, shape (n, 2) or (2,)
        Ray origins ``(x, y)`` in m; one origin is shared by all rays.
    angles_rad : array_like, shape (n,) or scalar
        Ray directions in rad, counter-clockwise from the +x axis.
    max_range_m : float or array_like, shape (n,)
        Longest distance looked at, > 0 (``inf`` allowed). A hit exactly at this
        distance counts.

    Returns
    -------
    RayHits
        ``(distance_m, segment, incidence_rad)``, each of shape ``(n,)``.

    Notes
    -----
    The incidence angle is the acute angle between the ray and the wall,
    ``theta = atan2(|d x e|, |d . e|)`` in ``[0, pi/2]`` (``d`` the ray direction, ``e``
    the wall direction): ``pi/2`` is a perpendicular hit, 0 grazing. This is Girard et al.
    (2011) eq. (3)'s theta folded into ``[0, pi/2]``, so their window
    ``pi/2 - alpha/(2 lambda) <= theta <= pi/2 + alpha/(2 lambda)`` becomes
    ``theta >= pi/2 - alpha/(2 lambda)``. A ray starting on a wall hits it at distance 0;
    a ray parallel to a wall never hits it. Brute force over all segments (numba for large
    problems, the numpy reference below ``_raycast.NUMBA_MIN_PAIRS`` pairs).

    Examples
    --------
    >>> plan = FloorPlan.from_walls([((2, -5), (2, 5))])
    >>> hits = cast_rays(plan, [0.0, 0.0], [0.0, np.pi / 4, np.pi], 10.0)
    >>> hits.distance_m.round(4).tolist()
    [2.0, 2.8284, nan]
    >>> np.degrees(hits.incidence_rad[:2]).round(6).tolist()
    [90.0, 45.0]
    """
    if not isinstance(plan, FloorPlan):
        raise InvalidParameterError(f"plan must be a FloorPlan, got {type(plan).__name__}")
    o = _points("origins_m", origins_m)
    a = np.asarray(angles_rad, dtype=np.float64).reshape(-1)
    if not np.all(np.isfinite(a)):
        raise InvalidParameterError("angles_rad contains NaN or infinite values")
    r = np.asarray(max_range_m, dtype=np.float64).reshape(-1)
    if np.any(np.isnan(r)) or np.any(r <= 0.0):
        raise InvalidParameterError(f"max_range_m={max_range_m!r} must be > 0")
    try:
        n = np.broadcast_shapes((o.shape[0],), a.shape, r.shape)[0]
    except ValueError:
        raise InvalidParameterError(
            f"origins_m {o.shape}, angles_rad {a.shape} and max_range_m {r.shape} "
            "do not have matching lengths"
        ) from None
    o = np.broadcast_to(o, (n, 2))
    a = np.broadcast_to(a, (n,))
    ox, oy = np.ascontiguousarray(o[:, 0]), np.ascontiguousarray(o[:, 1])
    dx, dy = np.cos(a), np.sin(a)
    rmax = np.ascontiguousarray(np.broadcast_to(r, (n,)))
    exclude = np.full(n, -1, dtype=np.int64)
    seg = np.ascontiguousarray(plan.segments)
    return RayHits(*_raycast.cast(ox, oy, dx, dy, rmax, seg, exclude))


def segment_crosses_wall(plan: FloorPlan, p0_m: Any, p1_m: Any) -> np.ndarray:
    """Whether each straight move ``p0 -> p1`` meets a solid wall segment.

    Parameters
    ----------
    plan : FloorPlan
        The walls; moves through door openings do not cross.
    p0_m, p1_m : array_like, shape (n, 2) or (2,)
        Start and end points in m (a single point broadcasts against the other).

    Returns
    -------
    numpy.ndarray
        bool ``(n,)``.

    Notes
    -----
    Segments are closed: touching a wall (an end point on it, or a move along a wall line
    overlapping it) counts as crossing; a zero-length move never crosses. Used by the
    particle filter to drop particles that walk through walls (Girard et al. 2011, §3.2
    step 4). Brute force over all segments, numba for large problems.

    Examples
    --------
    >>> plan = FloorPlan.from_walls([{"from": [1, -1], "to": [1, 3],
    ...                               "doors": [{"at_m": 2.0, "width_m": 1.0}]}])
    >>> segment_crosses_wall(plan, [[0, 0], [0, 1.5], [0, 0]], [[2, 0], [2, 1.5], [0.5, 0]])
    array([ True, False, False])
    """
    if not isinstance(plan, FloorPlan):
        raise InvalidParameterError(f"plan must be a FloorPlan, got {type(plan).__name__}")
    a = _points("p0_m", p0_m)
    b = _points("p1_m", p1_m)
    try:
        n = np.broadcast_shapes((a.shape[0],), (b.shape[0],))[0]
    except ValueError:
        raise InvalidParameterError(
            f"p0_m {a.shape} and p1_m {b.shape} do not have matching lengths"
        ) from None
    a = np.broadcast_to(a, (n, 2))
    b = np.broadcast_to(b, (n, 2))
    cols = [np.ascontiguousarray(c) for c in (a[:, 0], a[:, 1], b[:, 0], b[:, 1])]
    return _raycast.crosses(*cols, np.ascontiguousarray(plan.segments))
