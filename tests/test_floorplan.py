"""Tests for rangekit.floorplan (format, validation, ray casting, crossing) and _raycast."""

from __future__ import annotations

import copy
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rangekit import _raycast
from rangekit.errors import InputFileError, InvalidParameterError
from rangekit.floorplan import (
    Door,
    FloorPlan,
    Wall,
    cast_rays,
    load_floorplan,
    segment_crosses_wall,
)

ROOT = Path(__file__).resolve().parents[1]
CORRIDOR = ROOT / "fixtures_audio" / "corridor_plan.json"


def _doc(walls):
    return {"format": "rangekit-floorplan", "version": 1, "units": "m", "walls": walls}


# ------------------------------------------------------------------------ format


def test_corridor_fixture_loads():
    plan = load_floorplan(CORRIDOR)
    assert len(plan.walls) == 6
    assert plan.bounds == (0.0, 0.0, 10.0, 6.0)
    # The door (2.0 m from (0, 2), 0.9 m wide) splits wall 1 into two segments.
    np.testing.assert_array_equal(plan.segment_wall, [0, 1, 1, 2, 3, 4, 5])
    np.testing.assert_allclose(plan.segments[1:3], [[0, 2, 2, 2], [2.9, 2, 10, 2]])
    assert plan.walls[1].doors == (Door(2.0, 0.9),)


def test_json_round_trip(tmp_path):
    plan = load_floorplan(CORRIDOR)
    again = FloorPlan.from_json(json.loads(json.dumps(plan.to_json())))
    np.testing.assert_array_equal(again.segments, plan.segments)
    assert again.walls == plan.walls
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(plan.to_json()))
    assert load_floorplan(path).walls == plan.walls


def test_doors_cut_segments_along_any_direction():
    # A diagonal wall from (3, 4) to (0, 0) (length 5) with doors at its start and middle.
    wall = {
        "from": [3, 4],
        "to": [0, 0],
        "doors": [{"at_m": 2.0, "width_m": 1.0}, {"at_m": 0.0, "width_m": 0.5}],
    }
    plan = FloorPlan.from_walls([wall])
    assert [d.at_m for d in plan.walls[0].doors] == [0.0, 2.0]  # sorted
    np.testing.assert_allclose(
        plan.segments, [[2.7, 3.6, 1.8, 2.4], [1.2, 1.6, 0.0, 0.0]], atol=1e-12
    )


def test_door_covering_the_whole_wall_leaves_no_segment():
    plan = FloorPlan.from_walls(
        [{"from": [0, 0], "to": [1, 0], "doors": [{"at_m": 0, "width_m": 1}]}]
    )
    assert plan.segments.shape == (0, 4)
    hits = cast_rays(plan, [0.5, 1.0], -math.pi / 2, 5.0)
    assert np.isnan(hits.distance_m[0]) and hits.segment[0] == -1


def test_wall_inputs_accepted_in_several_forms():
    a = FloorPlan.from_walls([Wall((0.0, 0.0), (1.0, 0.0), (Door(0.2, 0.1),))])
    b = FloorPlan.from_walls(
        [{"from": [0, 0], "to": [1, 0], "doors": [{"at_m": 0.2, "width_m": 0.1}]}]
    )
    c = FloorPlan(np.array([[[0.0, 0.0], [1.0, 0.0]]]))
    assert a.walls == b.walls
    np.testing.assert_array_equal(a.segments, b.segments)
    assert c.segments.tolist() == [[0.0, 0.0, 1.0, 0.0]]
    assert FloorPlan.from_walls([]).segments.shape == (0, 4)
    assert all(math.isnan(v) for v in FloorPlan.from_walls([]).bounds)


def test_plan_is_frozen_and_segments_read_only():
    plan = load_floorplan(CORRIDOR)
    with pytest.raises(AttributeError):
        plan.walls = ()  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        plan.segments[0, 0] = 1.0


BAD_WALLS = [
    ({"from": [0, 0]}, r"walls\[1\]: missing key 'to'"),
    ({"from": [0, 0], "to": [1, 0], "door": []}, r"walls\[1\]: unknown key 'door'"),
    ({"from": [0, "x"], "to": [1, 0]}, r"walls\[1\]\.from\[1\]='x' must be a number"),
    ({"from": [0, 0], "to": [1, float("nan")]}, r"walls\[1\]\.to\[1\]=nan must be finite"),
    ({"from": [0, 0], "to": [1, float("inf")]}, r"walls\[1\]\.to\[1\]=inf must be finite"),
    ({"from": [0, 0, 0], "to": [1, 0]}, r"walls\[1\]\.from=.* must be a point"),
    ({"from": [0, True], "to": [1, 0]}, r"walls\[1\]\.from\[1\]=True must be a number"),
    ({"from": [2, 3], "to": [2, 3]}, r"walls\[1\]: zero-length wall"),
    ({"from": [0, 0], "to": [1, 0], "doors": {}}, r"walls\[1\]\.doors=.* must be a list"),
    ({"from": [0, 0], "to": [1, 0], "doors": [3]}, r"walls\[1\]\.doors\[0\]=3 must be a mapping"),
    (
        {"from": [0, 0], "to": [1, 0], "doors": [{"at_m": 0.1}]},
        r"walls\[1\]\.doors\[0\]: missing key 'width_m'",
    ),
    (
        {"from": [0, 0], "to": [1, 0], "doors": [{"at_m": 0.1, "width_m": 0.2, "x": 1}]},
        r"walls\[1\]\.doors\[0\]: unknown key 'x'",
    ),
    (
        {"from": [0, 0], "to": [1, 0], "doors": [{"at_m": -0.1, "width_m": 0.2}]},
        r"walls\[1\]\.doors\[0\]\.at_m=-0\.1 must be >= 0",
    ),
    (
        {"from": [0, 0], "to": [1, 0], "doors": [{"at_m": 0.1, "width_m": 0}]},
        r"walls\[1\]\.doors\[0\]\.width_m=0\.0 must be > 0",
    ),
    (
        {"from": [0, 0], "to": [1, 0], "doors": [{"at_m": 0.5, "width_m": 0.6}]},
        r"walls\[1\]\.doors\[0\]: door \[0\.5, 1\.1\] m lies outside its wall \(length 1 m\)",
    ),
    (
        {
            "from": [0, 0],
            "to": [4, 0],
            "doors": [{"at_m": 2.0, "width_m": 1.0}, {"at_m": 0.5, "width_m": 1.8}],
        },
        r"walls\[1\]: doors\[1\] \[0\.5, 2\.3\] m and doors\[0\] \[2, 3\] m overlap",
    ),
    ("wall", r"walls\[1\]='wall' must be a mapping"),
    ([[0, 0]], r"walls\[1\]=.* must be a mapping"),
]


@pytest.mark.parametrize(("bad", "message"), BAD_WALLS)
def test_bad_wall_raises_naming_the_wall(bad, message, tmp_path):
    walls = [{"from": [0, 0], "to": [1, 0]}, bad]
    with pytest.raises(InvalidParameterError, match=message):
        FloorPlan.from_json(_doc(walls))
    path = tmp_path / "bad_plan.json"
    path.write_text(json.dumps(_doc(walls)))
    if "must be finite" in message:  # JSON has no NaN: the reader refuses the file first
        with pytest.raises(InputFileError, match=r"bad_plan\.json. as JSON: (NaN|Infinity)") as e:
            load_floorplan(path)
        assert e.value.exit_code == 3
        return
    with pytest.raises(
        InputFileError, match=r"'.*bad_plan\.json' is not a valid floor plan: "
    ) as e:
        load_floorplan(path)
    assert e.value.exit_code == 3
    assert "walls[1]" in str(e.value)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"format": "other"}, r"format='other' must be 'rangekit-floorplan'"),
        ({"version": 2}, r"version=2 is not supported \(this rangekit reads 1\)"),
        ({"version": True}, r"version=True is not supported"),
        ({"units": "cm"}, r"units='cm' must be 'm'"),
        ({"walls": {}}, r"walls=\{\} must be a list"),
        ({"extra": 1}, r"unknown key 'extra'"),
        ({"format": None}, r"format=None"),
    ],
)
def test_bad_document_raises(change, message):
    doc = {**_doc([]), **change}
    with pytest.raises(InvalidParameterError, match=message) as e:
        FloorPlan.from_json(doc)
    assert e.value.exit_code == 2


@pytest.mark.parametrize("key", ["format", "version", "units", "walls"])
def test_missing_top_level_key(key):
    doc = _doc([])
    del doc[key]
    with pytest.raises(InvalidParameterError, match=f"missing key '{key}'"):
        FloorPlan.from_json(doc)


def test_non_object_document_and_bad_walls_argument():
    with pytest.raises(InvalidParameterError, match="must be a JSON object, got list"):
        FloorPlan.from_json([])
    with pytest.raises(InvalidParameterError, match="must be a list of walls"):
        FloorPlan.from_walls("walls")


def test_file_errors_name_the_file(tmp_path):
    with pytest.raises(InputFileError, match=r"cannot open '.*nope\.json': no such file"):
        load_floorplan(tmp_path / "nope.json")
    bad = tmp_path / "broken.json"
    bad.write_text("{not json")
    with pytest.raises(InputFileError, match=r"cannot read '.*broken\.json' as JSON"):
        load_floorplan(bad)
    other = tmp_path / "other.json"
    other.write_text(json.dumps({**_doc([]), "version": 7}))
    with pytest.raises(InputFileError, match=r"other\.json' is not a valid floor plan: version=7"):
        load_floorplan(other)


def test_optional_name_and_notes_are_ignored():
    doc = {**_doc([{"from": [0, 0], "to": [1, 0]}]), "name": "x", "notes": "y"}
    assert FloorPlan.from_json(doc).segments.shape == (1, 4)


# ----------------------------------------------------------------------- ray casting


@pytest.fixture(params=["numpy", "numba"])
def path_kind(request, monkeypatch):
    """Run a test through the numpy reference and through the numba kernels."""
    monkeypatch.setattr(_raycast, "NUMBA_MIN_PAIRS", 10**12 if request.param == "numpy" else 0)
    return request.param


def test_perpendicular_and_45_degree_rays(path_kind):
    plan = FloorPlan.from_walls([((3.0, -10.0), (3.0, 10.0))])
    hits = cast_rays(plan, [[0.0, 0.0], [1.0, 2.0]], [0.0, math.pi / 4], 10.0)
    np.testing.assert_allclose(hits.distance_m, [3.0, 2.0 * math.sqrt(2.0)], rtol=1e-14)
    np.testing.assert_array_equal(hits.segment, [0, 0])
    np.testing.assert_allclose(hits.incidence_rad, [math.pi / 2, math.pi / 4], rtol=1e-14)
    # The incidence is the same whatever the ray's side or the wall's orientation.
    flipped = FloorPlan.from_walls([((3.0, 10.0), (3.0, -10.0))])
    back = cast_rays(flipped, [[6.0, 0.0], [5.0, 2.0]], [math.pi, 3 * math.pi / 4], 10.0)
    np.testing.assert_allclose(back.incidence_rad, hits.incidence_rad, rtol=1e-14)
    np.testing.assert_allclose(back.distance_m, hits.distance_m, rtol=1e-14)


def test_misses_and_max_range(path_kind):
    plan = FloorPlan.from_walls([((3.0, -1.0), (3.0, 1.0))])
    origins = [[0.0, 0.0]] * 5
    angles = [math.pi, math.pi / 2, math.atan2(1.5, 3.0), 0.0, 0.0]
    hits = cast_rays(plan, origins, angles, [10.0, 10.0, 10.0, 2.99, 3.0])
    # Away from the wall, parallel to it, past its end, beyond max range, at max range.
    np.testing.assert_array_equal(np.isnan(hits.distance_m), [True, True, True, True, False])
    np.testing.assert_array_equal(hits.segment, [-1, -1, -1, -1, 0])
    assert np.isnan(hits.incidence_rad[:4]).all()
    assert hits.distance_m[4] == 3.0


def test_nearest_wall_wins_and_doors_let_rays_through(path_kind):
    plan = load_floorplan(CORRIDOR)
    # From the corridor centre line facing +y: the corridor wall at 1 m, except in front
    # of the door (x in [2, 2.9]) where the ray reaches room A's far wall at y = 6.
    xs = np.array([1.0, 2.1, 2.45, 2.8, 3.5])
    origins = np.c_[xs, np.ones_like(xs)]
    hits = cast_rays(plan, origins, np.full(xs.size, math.pi / 2), 20.0)
    np.testing.assert_allclose(hits.distance_m, [1.0, 5.0, 5.0, 5.0, 1.0])
    np.testing.assert_array_equal(plan.segment_wall[hits.segment], [1, 4, 4, 4, 1])
    # Door edges are solid (segments are closed).
    edge = cast_rays(plan, [2.0, 1.0], math.pi / 2, 20.0)
    assert edge.distance_m[0] == 1.0


def test_single_origin_broadcasts_and_ray_starting_on_a_wall(path_kind):
    plan = FloorPlan.from_walls([((0.0, -1.0), (0.0, 1.0)), ((2.0, -1.0), (2.0, 1.0))])
    hits = cast_rays(plan, [1.0, 0.0], [0.0, math.pi], 5.0)
    np.testing.assert_allclose(hits.distance_m, [1.0, 1.0])
    np.testing.assert_array_equal(hits.segment, [1, 0])
    on_wall = cast_rays(plan, [0.0, 0.5], 0.0, 5.0)
    assert on_wall.distance_m[0] == 0.0 and on_wall.segment[0] == 0


def test_cast_rays_input_errors():
    plan = load_floorplan(CORRIDOR)
    with pytest.raises(InvalidParameterError, match="plan must be a FloorPlan"):
        cast_rays({"walls": []}, [0, 0], 0.0, 1.0)
    with pytest.raises(InvalidParameterError, match=r"origins_m must have shape \(n, 2\)"):
        cast_rays(plan, [[0, 0, 0]], 0.0, 1.0)
    with pytest.raises(InvalidParameterError, match="origins_m contains NaN"):
        cast_rays(plan, [np.nan, 0], 0.0, 1.0)
    with pytest.raises(InvalidParameterError, match="angles_rad contains NaN"):
        cast_rays(plan, [0, 0], [np.inf], 1.0)
    with pytest.raises(InvalidParameterError, match=r"max_range_m=0\.0 must be > 0"):
        cast_rays(plan, [0, 0], 0.0, 0.0)
    with pytest.raises(InvalidParameterError, match="do not have matching lengths"):
        cast_rays(plan, [[0, 0], [1, 1]], [0.0, 1.0, 2.0], 1.0)
    assert cast_rays(plan, [1, 1], 0.0, np.inf).distance_m[0] == 9.0


def _random_plan(rng, n_walls: int) -> np.ndarray:
    """Random segments, including axis-aligned ones and shared end points."""
    seg = rng.uniform(-5, 5, (n_walls, 4))
    seg[: n_walls // 4, 2] = seg[: n_walls // 4, 0]  # vertical
    seg[n_walls // 4 : n_walls // 2, 3] = seg[n_walls // 4 : n_walls // 2, 1]  # horizontal
    seg[-3:, :2] = seg[-4:-1, 2:]  # chained corners
    return np.ascontiguousarray(seg)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cast_kernel_equals_numpy_reference(seed):
    rng = np.random.default_rng(seed)
    seg = _random_plan(rng, 40)
    n = 3000
    ox, oy = rng.uniform(-6, 6, n), rng.uniform(-6, 6, n)
    ang = rng.uniform(-np.pi, np.pi, n)
    ang[:50] = rng.choice([0.0, np.pi / 2, np.pi, -np.pi / 2], 50)  # axis-parallel rays
    dx, dy = np.cos(ang), np.sin(ang)
    rmax = rng.uniform(0.5, 12.0, n)
    exclude = rng.integers(-1, seg.shape[0], n)
    ref = _raycast._cast_rays_reference(ox, oy, dx, dy, rmax, seg, exclude)
    fast = _raycast._compiled("cast")(ox, oy, dx, dy, rmax, seg, exclude)
    assert 0.2 < np.mean(ref[1] >= 0) < 0.95  # a real mix of hits and misses
    np.testing.assert_array_equal(fast[1], ref[1])
    np.testing.assert_allclose(fast[0], ref[0], rtol=1e-12, equal_nan=True)
    np.testing.assert_allclose(fast[2], ref[2], rtol=1e-12, equal_nan=True)
    assert np.all((ref[1] != exclude) | (ref[1] == -1))
    # A brute-force per-ray oracle in plain Python confirms the reference.
    for i in range(0, n, 97):
        best, best_k = math.inf, -1
        for k, (x0, y0, x1, y1) in enumerate(seg):
            if k == exclude[i]:
                continue
            ex, ey = x1 - x0, y1 - y0
            den = dx[i] * ey - dy[i] * ex
            if den == 0.0:
                continue
            wx, wy = x0 - ox[i], y0 - oy[i]
            t = (wx * ey - wy * ex) / den
            u = (wx * dy[i] - wy * dx[i]) / den
            if 0.0 <= t <= rmax[i] and 0.0 <= u <= 1.0 and t < best:
                best, best_k = t, k
        assert ref[1][i] == best_k
        if best_k >= 0:
            assert ref[0][i] == pytest.approx(best, rel=1e-12)


def test_cast_rays_same_through_both_paths(monkeypatch):
    plan = load_floorplan(CORRIDOR)
    rng = np.random.default_rng(5)
    origins = np.c_[rng.uniform(0.1, 9.9, 2000), rng.uniform(0.1, 5.9, 2000)]
    angles = rng.uniform(-np.pi, np.pi, 2000)
    monkeypatch.setattr(_raycast, "NUMBA_MIN_PAIRS", 10**12)
    slow = cast_rays(plan, origins, angles, 6.0)
    monkeypatch.setattr(_raycast, "NUMBA_MIN_PAIRS", 0)
    fast = cast_rays(plan, origins, angles, 6.0)
    for a, b in zip(slow, fast, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, equal_nan=True)


# ------------------------------------------------------------------------- crossing


def test_segment_crossing_cases(path_kind):
    plan = FloorPlan.from_walls(
        [{"from": [0, 0], "to": [0, 4], "doors": [{"at_m": 1.0, "width_m": 1.0}]}]
    )
    p0 = [[-1, 0.5], [-1, 1.5], [-1, 3.0], [-1, 0.5], [0, 3.5], [0, -2], [0, -2], [1, 1], [1, 1]]
    p1 = [[1, 0.5], [1, 1.5], [-0.5, 3.0], [0, 0.5], [1, 3.5], [0, -0.5], [0, 0.5], [1, 1], [1, 3]]
    got = segment_crosses_wall(plan, p0, p1)
    expected = [
        True,  # through the wall
        False,  # through the door
        False,  # stops short
        True,  # ends on the wall (touching counts)
        True,  # starts on the wall
        False,  # collinear, before the wall
        True,  # collinear, overlapping it
        False,  # zero-length move
        False,  # parallel
    ]
    np.testing.assert_array_equal(got, expected)
    assert got.dtype == np.bool_


def test_segment_crossing_broadcast_and_errors():
    plan = load_floorplan(CORRIDOR)
    got = segment_crosses_wall(plan, [2.45, 1.0], [[2.45, 3.0], [4.0, 3.0], [8.0, 1.5]])
    np.testing.assert_array_equal(got, [False, True, False])
    with pytest.raises(InvalidParameterError, match="do not have matching lengths"):
        segment_crosses_wall(plan, [[0, 0], [1, 1]], [[0, 0], [1, 1], [2, 2]])
    with pytest.raises(InvalidParameterError, match="p1_m contains NaN"):
        segment_crosses_wall(plan, [0, 0], [np.nan, 1])
    with pytest.raises(InvalidParameterError, match="plan must be a FloorPlan"):
        segment_crosses_wall(None, [0, 0], [1, 1])


@pytest.mark.parametrize("seed", [0, 1])
def test_crossing_kernel_equals_numpy_reference(seed):
    rng = np.random.default_rng(seed)
    seg = _random_plan(rng, 30)
    n = 4000
    a = rng.uniform(-6, 6, (n, 2))
    b = a + rng.normal(0, 1.5, (n, 2))
    # Exact special cases: moves along a vertical wall line, zero-length moves.
    b[:40, 0] = a[:40, 0] = seg[0, 0]
    b[40:60] = a[40:60]
    args = [np.ascontiguousarray(c) for c in (a[:, 0], a[:, 1], b[:, 0], b[:, 1])]
    ref = _raycast._crosses_reference(*args, seg)
    fast = _raycast._compiled("crosses")(*args, seg)
    assert 0.1 < ref.mean() < 0.9
    assert ref[:40].any()
    assert not ref[40:60].any()
    np.testing.assert_array_equal(fast, ref)
    # Cross-check with the ray caster: a move crosses iff a ray along it hits within its length.
    length = np.hypot(b[60:, 0] - a[60:, 0], b[60:, 1] - a[60:, 1])
    ang = np.arctan2(b[60:, 1] - a[60:, 1], b[60:, 0] - a[60:, 0])
    dist, _, _ = _raycast._cast_rays_reference(
        np.ascontiguousarray(a[60:, 0]),
        np.ascontiguousarray(a[60:, 1]),
        np.cos(ang),
        np.sin(ang),
        length,
        seg,
        np.full(n - 60, -1, np.int64),
    )
    agree = np.isfinite(dist) == ref[60:]
    assert agree.mean() > 0.999  # only rounding at exact end points may differ


def test_importing_does_not_import_numba():
    code = (
        "import sys, rangekit.floorplan, rangekit.sensors.srf02; "
        "print(sorted(m for m in ('numba', 'scipy', 'soundfile') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr


def test_plan_copy_is_equal_by_walls():
    plan = load_floorplan(CORRIDOR)
    assert copy.deepcopy(plan).walls == plan.walls
