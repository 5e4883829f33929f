"""Shoebox (rectangular) room acoustics with the image-source method.

The room spans ``[0, Lx] x [0, Ly] x [0, Lz]`` metres. Every wall reflects sound with
the same amplitude factor ``sqrt(1 - absorption)``; the image sources of the Allen &
Berkley (1979) model up to a given reflection order stand in for the reflections.

Examples
--------
>>> room = ShoeboxRoom((5.0, 4.0, 3.0), absorption=0.36, max_order=1)
>>> room.contains((1.0, 2.0, 1.5))
True
>>> positions_m, gains, orders = image_sources((1.0, 2.0, 1.5), room)
>>> positions_m.shape
(7, 3)
>>> positions_m[0].tolist(), float(gains[0]), int(orders[0])
([1.0, 2.0, 1.5], 1.0, 0)
>>> sorted(set(gains[1:].round(6).tolist()))
[0.8]
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from rangekit._validate import in_range, positive, positive_int
from rangekit.errors import InvalidParameterError

__all__ = ["MAX_ORDER", "ShoeboxRoom", "image_sources"]

#: Highest image-source order accepted (the image count grows as O(order^3)).
MAX_ORDER = 6


def _point_3d(name: str, p) -> np.ndarray:
    """Return ``p`` as a finite float64 array of shape (3,), or raise."""
    try:
        a = np.asarray(p, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidParameterError(f"{name}={p!r} must be a 3-D point (x, y, z) in m") from None
    if a.shape != (3,):
        raise InvalidParameterError(
            f"{name}={p!r} must be a 3-D point (x, y, z) in m, got shape {a.shape}"
        )
    if not np.all(np.isfinite(a)):
        raise InvalidParameterError(f"{name}={p!r} must have finite coordinates")
    return a


@dataclass(frozen=True)
class ShoeboxRoom:
    """A rectangular room with uniformly absorbing walls.

    Parameters
    ----------
    size_m : tuple of 3 float
        Room dimensions ``(Lx, Ly, Lz)`` in metres, each finite and > 0. The room
        occupies ``[0, Lx] x [0, Ly] x [0, Lz]``.
    absorption : float, optional
        Energy absorption coefficient of every wall, within [0, 1] (dimensionless).
        The wall amplitude reflection factor is ``sqrt(1 - absorption)``. Default 0.3.
    max_order : int, optional
        Highest image-source order (total number of wall reflections) to model,
        within [0, 6]; 0 keeps the direct path only. Default 1.

    Raises
    ------
    InvalidParameterError
        If any field is out of its domain.

    Examples
    --------
    >>> room = ShoeboxRoom((4.0, 3.0, 2.5))
    >>> room.size_m, room.absorption, room.max_order
    ((4.0, 3.0, 2.5), 0.3, 1)
    >>> round(room.reflection_factor, 4)
    0.8367
    """

    size_m: tuple[float, float, float]
    absorption: float = 0.3
    max_order: int = 1

    def __post_init__(self) -> None:
        try:
            dims = tuple(self.size_m)
        except TypeError:
            raise InvalidParameterError(
                f"size_m={self.size_m!r} must be three room dimensions in m"
            ) from None
        if len(dims) != 3:
            raise InvalidParameterError(
                f"size_m={self.size_m!r} must be three room dimensions in m"
            )
        dims = tuple(positive(f"size_m[{i}]", d) for i, d in enumerate(dims))
        absorption = in_range("absorption", self.absorption, 0.0, 1.0)
        max_order = positive_int("max_order", self.max_order, minimum=0)
        if max_order > MAX_ORDER:
            raise InvalidParameterError(f"max_order={self.max_order!r} must be <= {MAX_ORDER}")
        object.__setattr__(self, "size_m", dims)
        object.__setattr__(self, "absorption", absorption)
        object.__setattr__(self, "max_order", max_order)

    @property
    def reflection_factor(self) -> float:
        """Wall amplitude reflection factor ``sqrt(1 - absorption)`` (dimensionless)."""
        return math.sqrt(1.0 - self.absorption)

    def contains(self, p_m) -> bool:
        """Whether a point lies strictly inside the room.

        Parameters
        ----------
        p_m : array_like, shape (3,)
            Point ``(x, y, z)`` in metres.

        Returns
        -------
        bool
            True if ``0 < p_m[i] < size_m[i]`` for every axis; points on a wall are
            outside.

        Raises
        ------
        InvalidParameterError
            If ``p_m`` is not a finite 3-D point.

        Examples
        --------
        >>> room = ShoeboxRoom((4.0, 3.0, 2.5))
        >>> room.contains((1.0, 1.0, 1.0)), room.contains((0.0, 1.0, 1.0))
        (True, False)
        """
        p = _point_3d("p_m", p_m)
        size = np.asarray(self.size_m)
        return bool(np.all((p > 0.0) & (p < size)))


def _axis_images(coord_m: float, length_m: float, max_order: int) -> list[tuple[float, int]]:
    """Image coordinates along one axis and their reflection counts.

    The images of ``x`` between walls at 0 and ``L`` are ``x + 2 n L`` (``|2n|``
    reflections) and ``-x + 2 n L`` (``|2n - 1|`` reflections) for integer ``n``.
    """
    out = []
    for n in range(-max_order, max_order + 1):
        for q in (0, 1):
            count = abs(2 * n - q)
            if count <= max_order:
                out.append(((1 - 2 * q) * coord_m + 2 * n * length_m, count))
    out.sort(key=lambda item: item[1])
    return out


def image_sources(src_m, room: ShoeboxRoom) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Image sources of a point source in a shoebox room (Allen & Berkley model).

    Parameters
    ----------
    src_m : array_like, shape (3,)
        Source position ``(x, y, z)`` in metres, strictly inside ``room``.
    room : ShoeboxRoom
        The room; ``room.max_order`` bounds the total number of wall reflections.

    Returns
    -------
    positions_m : numpy.ndarray, shape (K, 3), float64
        Image-source positions in metres. Row 0 is the source itself (direct path).
    gains : numpy.ndarray, shape (K,), float64
        Amplitude gain of each image (dimensionless): the product of the wall
        reflection factors along its path, ``sqrt(1 - absorption) ** order``. Spherical
        spreading (1/r) is not included.
    orders : numpy.ndarray, shape (K,), int
        Number of wall reflections of each image, non-decreasing (0 first).

    Raises
    ------
    InvalidParameterError
        If ``src_m`` is not a finite 3-D point strictly inside the room, or ``room``
        is not a :class:`ShoeboxRoom`.

    Notes
    -----
    Along each axis the images are ``x + 2 n L`` and ``-x + 2 n L`` with ``|2n|`` and
    ``|2n - 1|`` reflections; a 3-D image combines one per axis and its order is the sum
    of the three counts. The count of images of order exactly ``N >= 1`` is
    ``4 N^2 + 2`` (6, 18, 38, ...), so up to order ``N`` there are
    ``1 + sum(4 k^2 + 2)`` (7, 25, 63, ...).

    References
    ----------
    J. B. Allen and D. A. Berkley, "Image method for efficiently simulating small-room
    acoustics", J. Acoust. Soc. Am. 65(4), 943-950, 1979.

    Examples
    --------
    >>> room = ShoeboxRoom((5.0, 4.0, 3.0), max_order=2)
    >>> positions_m, gains, orders = image_sources((1.0, 2.0, 1.5), room)
    >>> len(orders), int((orders == 1).sum()), int((orders == 2).sum())
    (25, 6, 18)
    """
    if not isinstance(room, ShoeboxRoom):
        raise InvalidParameterError(f"room={room!r} must be a ShoeboxRoom")
    src = _point_3d("src_m", src_m)
    if not room.contains(src):
        raise InvalidParameterError(
            f"src_m={src.tolist()!r} m must be strictly inside the room of size_m={room.size_m!r}"
        )
    n_max = room.max_order
    axes = [_axis_images(float(src[i]), room.size_m[i], n_max) for i in range(3)]
    positions = []
    orders = []
    for (x, cx), (y, cy), (z, cz) in itertools.product(*axes):
        order = cx + cy + cz
        if order <= n_max:
            positions.append((x, y, z))
            orders.append(order)
    positions_m = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    orders_arr = np.asarray(orders, dtype=np.int64)
    idx = np.argsort(orders_arr, kind="stable")
    positions_m = positions_m[idx]
    orders_arr = orders_arr[idx]
    gains = room.reflection_factor ** orders_arr.astype(np.float64)
    return positions_m, gains, orders_arr
