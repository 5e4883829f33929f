"""Tests for rangekit.sim.room (shoebox image-source model)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.sim.room import ShoeboxRoom, image_sources

SIZE_M = (5.0, 4.0, 3.0)
SRC_M = (1.2, 2.5, 0.8)


def _images(max_order: int, absorption: float = 0.3):
    room = ShoeboxRoom(SIZE_M, absorption=absorption, max_order=max_order)
    return image_sources(SRC_M, room)


def test_room_defaults_and_coercion():
    room = ShoeboxRoom([5, 4, 3])
    assert room.size_m == (5.0, 4.0, 3.0)
    assert all(isinstance(v, float) for v in room.size_m)
    assert room.absorption == 0.3
    assert room.max_order == 1
    assert room.reflection_factor == pytest.approx(math.sqrt(0.7))
    hash(room)  # frozen dataclass of immutable values


def test_room_is_frozen():
    room = ShoeboxRoom(SIZE_M)
    with pytest.raises(AttributeError):
        room.absorption = 0.5  # type: ignore[misc]


def test_contains_is_strict():
    room = ShoeboxRoom(SIZE_M)
    assert room.contains((2.5, 2.0, 1.5))
    assert room.contains(np.array([1e-9, 1e-9, 1e-9]))
    assert not room.contains((0.0, 2.0, 1.5))
    assert not room.contains((5.0, 2.0, 1.5))
    assert not room.contains((2.5, 4.1, 1.5))
    assert not room.contains((2.5, 2.0, -0.1))


def test_order_zero_gives_only_the_source():
    positions, gains, orders = _images(0)
    np.testing.assert_array_equal(positions, [SRC_M])
    np.testing.assert_array_equal(gains, [1.0])
    np.testing.assert_array_equal(orders, [0])
    assert positions.dtype == np.float64
    assert gains.dtype == np.float64
    assert np.issubdtype(orders.dtype, np.integer)


def test_order_one_has_direct_plus_six_mirror_images():
    absorption = 0.36
    positions, gains, orders = _images(1, absorption)
    assert positions.shape == (7, 3)
    np.testing.assert_array_equal(positions[0], SRC_M)
    assert gains[0] == 1.0
    assert orders[0] == 0
    np.testing.assert_array_equal(orders[1:], np.ones(6))
    np.testing.assert_allclose(gains[1:], math.sqrt(1.0 - absorption), rtol=1e-15)
    x, y, z = SRC_M
    lx, ly, lz = SIZE_M
    expected = {
        (-x, y, z),
        (2 * lx - x, y, z),
        (x, -y, z),
        (x, 2 * ly - y, z),
        (x, y, -z),  # floor image
        (x, y, 2 * lz - z),  # ceiling image
    }
    got = {tuple(np.round(p, 12)) for p in positions[1:]}
    assert got == {tuple(np.round(p, 12)) for p in expected}


def _brute_force_order1(src, size):
    """Mirror the source in each of the six wall planes."""
    images = []
    for axis in range(3):
        for wall in (0.0, size[axis]):
            p = list(src)
            p[axis] = 2.0 * wall - p[axis]
            images.append(p)
    return np.array(images)


def test_order_one_distances_match_brute_force_mirrors():
    rng = np.random.default_rng(7)
    room = ShoeboxRoom(SIZE_M, max_order=1)
    for _ in range(20):
        src = rng.uniform(0.05, 0.95, 3) * SIZE_M
        rcv = rng.uniform(0.05, 0.95, 3) * SIZE_M
        positions, _, orders = image_sources(src, room)
        d_model = np.sort(np.linalg.norm(positions[orders == 1] - rcv, axis=1))
        d_brute = np.sort(np.linalg.norm(_brute_force_order1(src, SIZE_M) - rcv, axis=1))
        np.testing.assert_allclose(d_model, d_brute, rtol=1e-13)
        assert np.linalg.norm(positions[0] - rcv) == pytest.approx(np.linalg.norm(src - rcv))


def test_order_two_count_is_25():
    positions, gains, orders = _images(2, 0.19)
    assert positions.shape == (25, 3)
    assert np.bincount(orders).tolist() == [1, 6, 18]
    np.testing.assert_allclose(gains, 0.9**orders, rtol=1e-14)
    # All images are distinct points.
    assert len({tuple(np.round(p, 9)) for p in positions}) == 25


@pytest.mark.parametrize("max_order", range(7))
def test_image_counts_and_sorting(max_order):
    positions, gains, orders = _images(max_order)
    expected = 1 + sum(4 * k * k + 2 for k in range(1, max_order + 1))
    assert positions.shape == (expected, 3)
    assert gains.shape == orders.shape == (expected,)
    assert np.all(np.diff(orders) >= 0)
    assert orders.max() == max_order
    # Images outside the room; only the source inside.
    room = ShoeboxRoom(SIZE_M)
    assert [room.contains(p) for p in positions].count(True) == 1


def test_order_two_images_are_mirrors_of_order_one_images():
    positions1, _, _ = _images(1)
    positions2, _, orders2 = _images(2)
    first = _brute_force_order1(SRC_M, SIZE_M)
    second = set()
    for img in first:
        for mirrored in _brute_force_order1(img, SIZE_M):
            if not np.allclose(mirrored, SRC_M):
                second.add(tuple(np.round(mirrored, 9)))
    # Mirroring each order-1 image in every wall (except straight back onto the source)
    # reaches exactly the order-2 images.
    got = {tuple(np.round(p, 9)) for p in positions2[orders2 == 2]}
    assert got == second
    assert len(positions1) == 7


def test_absorption_one_silences_reflections():
    _, gains, orders = _images(2, absorption=1.0)
    np.testing.assert_array_equal(gains, np.where(orders == 0, 1.0, 0.0))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"size_m": (5.0, 0.0, 3.0)}, "size_m"),
        ({"size_m": (5.0, -1.0, 3.0)}, "size_m"),
        ({"size_m": (5.0, float("inf"), 3.0)}, "size_m"),
        ({"size_m": (5.0, 4.0)}, "size_m"),
        ({"size_m": 5.0}, "size_m"),
        ({"absorption": -0.1}, "absorption"),
        ({"absorption": 1.5}, "absorption"),
        ({"max_order": -1}, "max_order"),
        ({"max_order": 7}, "max_order"),
        ({"max_order": 1.5}, "max_order"),
    ],
)
def test_invalid_room_raises(kwargs, match):
    args = {"size_m": SIZE_M, **kwargs}
    with pytest.raises(InvalidParameterError, match=match):
        ShoeboxRoom(**args)


@pytest.mark.parametrize(
    "src",
    [(0.0, 1.0, 1.0), (5.0, 1.0, 1.0), (1.0, -0.5, 1.0), (1.0, 1.0, 3.5)],
)
def test_source_outside_room_raises(src):
    with pytest.raises(InvalidParameterError, match="src_m"):
        image_sources(src, ShoeboxRoom(SIZE_M))


@pytest.mark.parametrize("src", [(1.0, 1.0), (1.0, np.nan, 1.0), "abc"])
def test_malformed_source_raises(src):
    with pytest.raises(InvalidParameterError, match="src_m"):
        image_sources(src, ShoeboxRoom(SIZE_M))


def test_contains_rejects_malformed_point():
    with pytest.raises(InvalidParameterError, match="p_m"):
        ShoeboxRoom(SIZE_M).contains((1.0, 2.0))


def test_room_argument_must_be_a_room():
    with pytest.raises(InvalidParameterError, match="room"):
        image_sources(SRC_M, SIZE_M)  # type: ignore[arg-type]
