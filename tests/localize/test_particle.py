"""Tests of the floor-plan particle filters (Girard et al. 2011 §3.2) and their kernels."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit import _raycast
from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.floorplan import FloorPlan
from rangekit.io.steplog import RangeLog, StepLog
from rangekit.localize import _particle_kernels as K
from rangekit.localize.particle import (
    ParticleConfig,
    eq1_weights,
    keep_best,
    sample_motion_vectors,
    track_particles,
    tracking_error,
    weighted_mean,
)
from rangekit.sensors.srf02 import SRF02, model_range
from rangekit.sim.girard2011 import simulate

BOX = FloorPlan.from_walls(
    [((0, 0), (10, 0)), ((10, 0), (10, 2)), ((10, 2), (0, 2)), ((0, 2), (0, 0))]
)


def _random_plan(seed: int = 1) -> FloorPlan:
    """Walls of every orientation, shared corners, a closed outline."""
    rng = np.random.default_rng(seed)
    walls = []
    for i in range(40):
        a = rng.uniform(0, 10, 2)
        d = rng.uniform(-3, 3, 2)
        if i % 3 == 1:
            d[1] = 0.0
        elif i % 3 == 2:
            d[0] = 0.0
        walls.append((tuple(a), tuple(a + d)))
    walls += [((0, 0), (10, 0)), ((10, 0), (10, 10)), ((10, 10), (0, 10)), ((0, 10), (0, 0))]
    walls += [((2, 2), (4, 2)), ((4, 2), (4, 4)), ((2, 2), (2, 4))]
    return FloorPlan.from_walls(walls)


def _rays(seg: np.ndarray, n: int, rng) -> tuple:
    ox, oy = rng.uniform(-2, 12, n), rng.uniform(-2, 12, n)
    ox[:100], oy[:100] = np.resize(seg[:, 0], 100), np.resize(seg[:, 1], 100)  # on corners
    ox[100:200], oy[100:200] = 2.0, np.linspace(0, 6, 100)  # through corners at 45 deg
    a = rng.uniform(-np.pi, np.pi, n)
    a[100:200], a[200:300], a[300:400] = np.pi / 4, 0.0, np.pi / 2  # axis-parallel
    rmax = rng.uniform(0.5, 8, n)
    rmax[:500] = np.inf
    return ox, oy, np.cos(a), np.sin(a), rmax


# ----------------------------------------------------------------------------- kernels


@pytest.mark.parametrize("cell_m", [0.3, 1.0, 2.0, 7.0])
def test_grid_cast_equals_numpy_reference(cell_m):
    seg = np.ascontiguousarray(_random_plan().segments)
    grid = K.build_grid(seg, cell_m)
    rng = np.random.default_rng(2)
    ox, oy, dx, dy, rmax = _rays(seg, 5000, rng)
    ref = _raycast._cast_rays_reference(ox, oy, dx, dy, rmax, seg, np.full(ox.size, -1, np.int64))
    got = K.cast_rays_grid(ox, oy, dx, dy, rmax, grid)
    assert np.array_equal(ref[0], got[0], equal_nan=True)
    assert np.array_equal(ref[1], got[1])
    # incidence: numpy's and libm's arctan2 may differ in the last bit
    np.testing.assert_allclose(got[2], ref[2], rtol=1e-12, atol=0)
    assert 0.3 < np.mean(got[1] >= 0) < 1.0  # the test exercises hits and misses


@pytest.mark.parametrize("cell_m", [0.3, 1.0, 2.0])
def test_grid_crossing_equals_numpy_reference(cell_m):
    seg = np.ascontiguousarray(_random_plan().segments)
    grid = K.build_grid(seg, cell_m)
    rng = np.random.default_rng(3)
    ax, ay, *_ = _rays(seg, 5000, rng)
    bx, by = ax + rng.uniform(-2, 2, ax.size), ay + rng.uniform(-2, 2, ax.size)
    bx[:50], by[:50] = ax[:50], ay[:50]  # zero-length moves
    bx[50:100], by[50:100] = np.resize(seg[:, 2], 50), np.resize(seg[:, 3], 50)  # to corners
    ref = _raycast._crosses_reference(ax, ay, bx, by, seg)
    got = K.crosses_grid(ax, ay, bx, by, grid)
    assert np.array_equal(ref, got)
    assert 0.2 < got.mean() < 0.8


@pytest.mark.parametrize("cell_m", [0.3, 1.0])
def test_grid_crossing_short_moves_on_hard_points(cell_m):
    """Moves within one cell (the fast path), along cell boundaries and along walls."""
    plan = _random_plan(3)
    seg = np.ascontiguousarray(plan.segments)
    grid = K.build_grid(seg, cell_m)
    rng = np.random.default_rng(13)
    a = _hard_points(plan, grid, rng, 4000)
    b = a + rng.normal(0.0, 0.1 * cell_m, a.shape)
    n = len(a) // 4
    b[:n, 0] = a[:n, 0]  # vertical moves (along cell boundaries for the boundary points)
    b[n : 2 * n, 1] = a[n : 2 * n, 1]  # horizontal moves
    w = rng.integers(0, seg.shape[0], n)  # moves along walls, from points on them
    e = seg[w, 2:] - seg[w, :2]
    a[2 * n : 3 * n] = seg[w, :2] + rng.uniform(0.0, 1.0, n)[:, None] * e
    b[2 * n : 3 * n] = a[2 * n : 3 * n] + rng.uniform(-0.3, 0.3, n)[:, None] * e
    ref = _raycast._crosses_reference(a[:, 0], a[:, 1], b[:, 0], b[:, 1], seg)
    got = K.crosses_grid(a[:, 0], a[:, 1], b[:, 0], b[:, 1], grid)
    np.testing.assert_array_equal(got, ref)
    assert 0.05 < got.mean() < 0.9
    sub = slice(0, len(a), 400)  # few moves for the grid: each one walks it
    assert K._SPARSE_PER_CELL * a[sub].shape[0] < grid.nx * grid.ny
    np.testing.assert_array_equal(
        K.crosses_grid(a[sub, 0], a[sub, 1], b[sub, 0], b[sub, 1], grid), ref[sub]
    )


def test_ray_model_equals_srf02_model_range():
    plan = _random_plan()
    grid = K.build_grid(np.ascontiguousarray(plan.segments), 1.0)
    s = SRF02()
    rng = np.random.default_rng(4)
    poses = np.column_stack([rng.uniform(0, 10, 2000), rng.uniform(0, 10, 2000)])
    poses = np.column_stack([poses, rng.uniform(-4, 4, 2000)])
    mounts = np.array([np.pi / 2, -np.pi / 2])
    thr = np.pi / 2 - s.incidence_window_rad - 1e-12
    psi = s.ray_offsets_rad
    got = K.ray_model_grid(
        poses[:, 0], poses[:, 1], poses[:, 2], mounts, psi, s.max_range_at(psi), thr,
        s.min_range_m, grid,
    )  # fmt: skip
    for j, m in enumerate(mounts):
        ref = model_range(plan, poses, s, mount_angle_rad=m, method="rays")
        np.testing.assert_array_equal(np.where(np.isinf(got[:, j]), np.nan, got[:, j]), ref)


def _axis_plan() -> FloorPlan:
    rows = [((0, y), (12, y)) for y in (0, 3, 6, 9, 12)]
    return FloorPlan.from_walls(rows + [((x, 0), (x, 12)) for x in (0, 3, 6, 9, 12)])


@pytest.mark.parametrize("heading", [0.0, 0.3, np.pi / 2, 0.0685, -2.5])
@pytest.mark.parametrize("plan_kind", ["axis", "random"])
def test_ray_model_shared_heading_equals_srf02(heading, plan_kind):
    """The fast path (one heading for all particles: ray tables) and plain casting."""
    plan = _axis_plan() if plan_kind == "axis" else _random_plan()
    grid = K.build_grid(np.ascontiguousarray(plan.segments), 1.0)
    s = SRF02()
    rng = np.random.default_rng(8)
    xy = rng.uniform(0, 10, (1500, 2))
    mounts = np.array([np.pi / 2, -np.pi / 2])
    thr = np.pi / 2 - s.incidence_window_rad - 1e-12
    psi = s.ray_offsets_rad
    args = (mounts, psi, s.max_range_at(psi), thr, s.min_range_m, grid)
    fast = K.ray_model_grid(xy[:, 0], xy[:, 1], heading, *args, tables=True)
    slow = K.ray_model_grid(xy[:, 0], xy[:, 1], heading, *args, tables=False)
    np.testing.assert_array_equal(fast, slow)
    np.testing.assert_array_equal(K.ray_model_grid(xy[:, 0], xy[:, 1], heading, *args), fast)
    pose = np.column_stack([xy, np.full(len(xy), heading)])
    for j, m in enumerate(mounts):
        ref = model_range(plan, pose, s, mount_angle_rad=m, method="rays")
        np.testing.assert_array_equal(np.where(np.isinf(fast[:, j]), np.nan, fast[:, j]), ref)


def _hard_points(plan: FloorPlan, grid: K.SegmentGrid, rng, n: int) -> np.ndarray:
    """Points on cell boundaries and corners, on walls, on wall lines past their ends, at
    and beyond the grid's edges, and random ones."""
    seg = plan.segments
    h = grid.cell_m
    x1, y1 = grid.x0 + grid.nx * h, grid.y0 + grid.ny * h
    k = n // 8
    pts = [rng.uniform([grid.x0, grid.y0], [x1, y1], (2 * k, 2))]
    ix = rng.integers(0, grid.nx + 1, k)
    pts.append(np.column_stack([grid.x0 + ix * h, rng.uniform(grid.y0, y1, k)]))
    iy = rng.integers(0, grid.ny + 1, k)
    pts.append(np.column_stack([rng.uniform(grid.x0, x1, k), grid.y0 + iy * h]))
    pts.append(np.column_stack([grid.x0 + ix * h, grid.y0 + iy * h]))  # cell corners
    w = rng.integers(0, seg.shape[0], 2 * k)
    u = rng.uniform(-0.5, 1.5, 2 * k)
    u[: k // 2] = rng.integers(0, 2, k // 2)  # wall ends
    pts.append(seg[w, :2] + u[:, None] * (seg[w, 2:] - seg[w, :2]))  # on wall lines
    pts.append(rng.uniform([x1 - 0.5 * h, grid.y0], [x1 + 2 * h, y1], (k, 2)))  # grid edge
    return np.concatenate(pts)


def _plan_and_headings(kind: str):
    """A plan, shared headings including ones whose rays run along walls, and those walls."""
    psi = SRF02().ray_offsets_rad
    if kind == "axis":
        plan = _axis_plan()
        # centre ray (mount +pi/2) along the x = const walls; ray 1 along them at -psi_1
        return plan, [0.3, -2.5, 0.0, np.pi / 2, np.pi, float(-psi[1])], np.arange(5, 10)
    plan = _random_plan(3)
    seg = plan.segments
    phi = np.arctan2(seg[:, 3] - seg[:, 1], seg[:, 2] - seg[:, 0])
    walls = np.flatnonzero(np.abs(np.sin(2 * phi)) > 0.2)[:3]  # slanted walls
    # heading + mount + psi_j == the wall's direction (mount +pi/2; rays j = 0, 5, 3)
    along = [float(phi[i] - np.pi / 2 - psi[j]) for i, j in zip(walls, (0, 5, 3), strict=True)]
    return plan, [0.3, -2.5, *along], walls


@pytest.mark.parametrize("kind", ["axis", "random"])
@pytest.mark.parametrize("cell_m", [0.3, 1.0, 2.0, 7.0])
@pytest.mark.parametrize("n_rays", [1, 7])
def test_ray_tables_equal_brute_force_on_hard_points(kind, cell_m, n_rays):
    """Ray tables vs the brute-force caster (:func:`model_range`, which casts every ray
    against every wall): one ray per sensor (its first hit exactly) and seven, particles
    on cell boundaries, on walls and their lines, at the grid's edges, rays along walls."""
    plan, headings, walls = _plan_and_headings(kind)
    seg = plan.segments
    grid = K.build_grid(np.ascontiguousarray(seg), cell_m)
    s = SRF02(n_rays=n_rays)
    rng = np.random.default_rng(11)
    u = rng.uniform(-0.5, 1.5, (walls.size, 60))
    u[:, :4] = [0.0, 1.0, 0.5, -0.2]
    on = seg[walls, None, :2] + u[..., None] * (seg[walls, None, 2:] - seg[walls, None, :2])
    xy = np.concatenate([_hard_points(plan, grid, rng, 1600), on.reshape(-1, 2)])
    mounts = np.array([np.pi / 2, -np.pi / 2])
    thr = np.pi / 2 - s.incidence_window_rad - 1e-12
    psi = s.ray_offsets_rad
    args = (mounts, psi, s.max_range_at(psi), thr, s.min_range_m, grid)
    n_read = 0
    for heading in headings:
        got = K.ray_model_grid(xy[:, 0], xy[:, 1], heading, *args, tables=True)
        pose = np.column_stack([xy, np.full(len(xy), heading)])
        for j, m in enumerate(mounts):
            ref = model_range(plan, pose, s, mount_angle_rad=m, method="rays")
            np.testing.assert_array_equal(np.where(np.isinf(got[:, j]), np.nan, got[:, j]), ref)
        n_read += np.isfinite(got).sum()
    assert n_read > 0.03 * got.size * len(headings)  # the test sees readings


def test_ray_tables_structure():
    """Every wall a ray from a particle meets within its range is listed (answer walls if
    eq. (3) accepts them, blockers if met before the nearest answer wall), under a lower
    bound of its hit distance; lists are sorted by that bound."""
    plan = _random_plan(4)
    seg = np.ascontiguousarray(plan.segments)
    grid = K.build_grid(seg, 1.0)
    s = SRF02()
    rng = np.random.default_rng(12)
    xy = _hard_points(plan, grid, rng, 800)
    xy = xy[(xy[:, 0] < grid.x0 + grid.nx) & (xy[:, 1] < grid.y0 + grid.ny)]  # in the grid
    mounts = np.array([np.pi / 2, -np.pi / 2])
    psi = s.ray_offsets_rad
    thr = np.pi / 2 - s.incidence_window_rad - 1e-12
    heading = 0.7
    tb = K.build_ray_tables(
        xy[:, 0], xy[:, 1], heading, mounts, psi, s.max_range_at(psi), thr, grid
    )
    lam = psi.size
    for start, dat in ((tb.a_start, tb.a_dat), (tb.b_start, tb.b_dat)):
        for key in range(start.size - 1):
            assert np.all(np.diff(dat[start[key] : start[key + 1], 0]) >= 0)
    # answer walls are the ones eq. (3) accepts for the key's direction; rows hold cseg
    key_dir = np.arange(tb.a_start.size - 1) % (mounts.size * psi.size)
    kd = np.repeat(key_dir, np.diff(tb.a_start))
    dx, dy = tb.dxs.ravel()[kd], tb.dys.ravel()[kd]
    e = tb.a_dat[:, 3:]
    theta = np.arctan2(np.abs(dx * e[:, 1] - dy * e[:, 0]), np.abs(dx * e[:, 0] + dy * e[:, 1]))
    assert np.all(theta >= thr)
    np.testing.assert_array_equal(tb.a_dat[:, 1:3], seg[tb.a_k, :2])
    np.testing.assert_array_equal(tb.a_dat[:, 3:], seg[tb.a_k, 2:] - seg[tb.a_k, :2])
    ex, ey = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
    checked = [0, 0]
    for i in range(len(xy)):
        for si in range(mounts.size):
            for jj in range(lam):
                key = (tb.slot[tb.cell[i]] * mounts.size + si) * lam + jj
                dx, dy = tb.dxs[si, jj], tb.dys[si, jj]
                denom = dx * ey - dy * ex
                wx, wy = seg[:, 0] - xy[i, 0], seg[:, 1] - xy[i, 1]
                with np.errstate(divide="ignore", invalid="ignore"):
                    t = (wx * ey - wy * ex) / denom
                    u = (wx * dy - wy * dx) / denom
                hit = (denom != 0) & (t >= 0) & (t <= tb.rmax[jj]) & (u >= 0) & (u <= 1)
                theta = np.arctan2(np.abs(denom), np.abs(dx * ex + dy * ey))
                acc = theta >= thr
                ta = t[hit & acc].min() if np.any(hit & acc) else -np.inf
                for ks, dat, need in (
                    (tb.a_k, tb.a_dat, hit & acc),
                    (tb.b_k, tb.b_dat, hit & ~acc & (t <= ta)),
                ):
                    lo, hi = (tb.a_start, tb.b_start)[ks is tb.b_k][key : key + 2]
                    listed = dict(zip(ks[lo:hi].tolist(), dat[lo:hi, 0], strict=True))
                    for k in np.flatnonzero(need):
                        assert k in listed and listed[k] <= t[k]
                        checked[ks is tb.b_k] += 1
    assert min(checked) > 50  # both lists were exercised


def test_useful_rays_in_an_axis_parallel_plan():
    plan = FloorPlan.from_walls([((0, 0), (5, 0)), ((0, 0), (0, 5))])
    grid = K.build_grid(np.ascontiguousarray(plan.segments), 1.0)
    s = SRF02()
    ang = 0.3 + np.pi / 2 + s.ray_offsets_rad
    use = K.useful_rays(ang, s.incidence_window_rad, grid)
    assert use.sum() == 1  # one sub-sector of seven holds a wall normal
    assert not K.useful_rays(ang, s.incidence_window_rad, K.build_grid(np.zeros((0, 4)))).any()


def test_empty_grid_has_no_hits():
    grid = K.build_grid(np.zeros((0, 4)), 1.0)
    d, k, _ = K.cast_rays_grid([0.0], [0.0], [1.0], [0.0], [10.0], grid)
    assert np.isnan(d[0]) and k[0] == -1
    assert not K.crosses_grid([0.0], [0.0], [1.0], [1.0], grid)[0]
    s = SRF02()
    psi = s.ray_offsets_rad
    args = ([np.pi / 2], psi, s.max_range_at(psi), 1.5, s.min_range_m, grid)
    for tables in (True, False):
        d = K.ray_model_grid([0.0, 0.5, 9.0], [0.0, -0.5, 0.0], 0.3, *args, tables=tables)
        assert d.shape == (3, 1) and np.all(np.isinf(d))


@pytest.mark.parametrize("spread", [1.0, 1e5])  # dense grid of tau cells; hashed cells
def test_merge_equals_reference_and_keeps_mass(spread):
    rng = np.random.default_rng(5)
    x, y = rng.uniform(0, 1, 2000), rng.uniform(0, 1, 2000)
    x[::2] += spread  # two clusters, far apart for the large spread
    w = rng.integers(1, 4, 2000).astype(float)  # many ties
    keep, wk = K.merge_close(x, y, w, 0.05)
    keep_r, wk_r = K.merge_close_reference(x, y, w, 0.05)
    np.testing.assert_array_equal(keep, keep_r)
    np.testing.assert_allclose(wk, wk_r, rtol=1e-12)
    assert math.isclose(wk.sum(), w.sum())
    d = np.hypot(x[keep, None] - x[None, keep], y[keep, None] - y[None, keep])
    assert np.all(d[~np.eye(keep.size, dtype=bool)] >= 0.05)


def test_merge_keeps_the_heavier_and_adds_the_weight():
    """Girard step 5: the lighter of two close particles is removed, its weight added."""
    keep, w = K.merge_close([0.0, 0.03, 1.0], [0.0, 0.0, 0.0], [1.0, 2.0, 5.0], 0.05)
    assert keep.tolist() == [1, 2] and w.tolist() == [3.0, 5.0]
    keep, w = K.merge_close([0.0, 0.06], [0.0, 0.0], [1.0, 2.0], 0.05)
    assert keep.tolist() == [0, 1] and w.tolist() == [1.0, 2.0]
    keep, w = K.merge_close([0.0, 0.0], [0.0, 0.0], [1.0, 2.0], 0.0)  # tau = 0: none closer
    assert keep.tolist() == [0, 1] and w.tolist() == [1.0, 2.0]


# ------------------------------------------------------------------ §3.2 step by step


def test_step3_motion_vectors_uniform_within_eps():
    rng = np.random.default_rng(6)
    v = sample_motion_vectors([0.0, 1.25], 0.25, 20_000, rng)
    r = np.hypot(v[:, 0], v[:, 1] - 1.25)
    assert r.max() <= 0.25
    assert abs(np.mean(r**2) - 0.25**2 / 2) < 2e-3  # uniform over the disc's area
    assert np.allclose(v.mean(axis=0), [0.0, 1.25], atol=5e-3)


def test_step4_wall_elimination():
    """Children whose move crosses a wall are removed; parents are removed."""
    plan = FloorPlan.from_walls(
        [((0, 0), (1.3, 0)), ((1.3, -1), (1.3, 1)), ((0, 1), (0, -1)), ((0, 1), (1.3, 1))]
    )
    plan_open = FloorPlan.from_walls([((0, 0), (3, 0)), ((0, 1), (0, -1))])
    steps = StepLog([1.0], [1.25], [0.0], [0.0])
    cfg = ParticleConfig(mode="model", tau_m=0.0, n_particles=1000)
    tr = track_particles(plan, steps, None, (0.1, 0.5), cfg, rng=0, save_clouds=[1])
    xy = tr.clouds[0].xy_m
    assert np.all(xy[:, 0] < 1.3) and np.all(xy[:, 1] > 0.0)
    assert 0 < xy.shape[0] < 20  # some of the 20 children were eliminated
    tr2 = track_particles(plan_open, steps, None, (0.1, 0.5), cfg, rng=0, save_clouds=[1])
    assert tr2.clouds[0].xy_m.shape[0] > xy.shape[0]


def test_step5_merging_reduces_the_cloud():
    steps = StepLog(np.arange(1.0, 6.0), [1.25] * 5, [0.0] * 5, [0.0] * 5)
    merged = track_particles(
        None, steps, None, (0, 0), ParticleConfig(mode="imu", n_particles=10**5), rng=1
    )
    unmerged = track_particles(
        None, steps, None, (0, 0), ParticleConfig(mode="imu", n_particles=10**5, tau_m=0.0), rng=1
    )
    assert unmerged.n_particles.tolist() == [20, 400, 8000, 10**5, 10**5]
    assert np.all(merged.n_particles[2:] < unmerged.n_particles[2:])


def test_step6_eq1_closed_form():
    # sensor 0 agrees, sensor 1 off by 20 %: mean of 1 and 0.8
    w = eq1_weights([[1.0, 2.0], [1.0, 2.5]], [1.0, 2.0], 6.0)
    np.testing.assert_allclose(w, [1.0, 0.9])
    # no echo counts as the maximum range; no wall in the model (inf) too
    np.testing.assert_allclose(eq1_weights([[np.inf], [3.0], [9.0]], [np.nan], 6.0), [1, 0.5, 1])
    np.testing.assert_allclose(eq1_weights([[np.inf]], [1.5], 6.0), [0.25])
    assert eq1_weights(np.zeros((3, 0)), [], 6.0).tolist() == [1.0, 1.0, 1.0]
    with pytest.raises(InvalidParameterError, match="model_m"):
        eq1_weights([[1.0]], [1.0, 2.0], 6.0)


def test_step6_ranging_picks_the_side_that_fits():
    """In a 2 m corridor, readings of 0.5 m left / 1.5 m right select y = 1.5."""
    steps = StepLog([1.0, 2.0], [1.0, 1.0], [0.0, 0.0], [0.0, 0.0])
    t = np.arange(0.05, 2.0, 0.1)
    sensor = np.arange(t.size) % 2
    ranges = RangeLog(t, sensor, np.where(sensor == 0, 0.5, 1.5))
    cfg = ParticleConfig(eps_m=0.6, n_particles=50)
    tr = track_particles(BOX, steps, ranges, (1.0, 1.0), cfg, rng=2)
    assert abs(tr.xy_m[-1, 1] - 1.5) < 0.1


def test_step7_keep_best():
    rng = np.random.default_rng(0)
    w = np.array([0.1, 0.9, 0.5, 0.7, 0.2])
    assert keep_best(w, 2, rng).tolist() == [1, 3]
    assert keep_best(w, 10, rng).tolist() == [0, 1, 2, 3, 4]
    ties = {tuple(keep_best(np.ones(10), 3, np.random.default_rng(s))) for s in range(5)}
    assert len(ties) > 1  # ties broken at random


def test_step8_eq2_weighted_mean():
    assert weighted_mean([[0, 0], [4, 2]], [1, 3]).tolist() == [3.0, 1.5]


def test_imu_mode_follows_dead_reckoning():
    rng = np.random.default_rng(3)
    h = rng.uniform(-np.pi, np.pi, 10)
    steps = StepLog(np.arange(1.0, 11.0), [1.25] * 10, h, [0.0] * 10)
    tr = track_particles(None, steps, None, (2, 3), ParticleConfig(mode="imu"), rng=4)
    dr = np.array([2.0, 3.0]) + np.cumsum(steps.vectors_m, axis=0)
    # the cloud's mean random-walks a little (truncation to the ν kept), no bias
    assert np.max(np.hypot(*(tr.xy_m - dr).T)) < 0.35
    assert np.all(np.diff(tr.spread_m[:4]) > 0)  # the cloud grows (Fig. 11)


# --------------------------------------------------------------------------- accuracy

SEEDS = (0, 1, 2, 3, 4, 5)


@pytest.fixture(scope="module")
def runs():
    return [simulate(rng=s) for s in SEEDS]


def _errors(runs, seeds=SEEDS, **cfg):
    out = {}
    for mode in ("imu", "model", "ranging"):
        c = ParticleConfig(mode=mode, **cfg)
        out[mode] = [
            tracking_error(
                track_particles(r.plan, r.steps, r.ranges, r.start_m, c, rng=s).xy_m, r.truth_m
            ).mean_m
            for s, r in zip(seeds, runs, strict=False)
        ]
    return {k: float(np.mean(v)) for k, v in out.items()}, out


@pytest.mark.parametrize(
    ("cfg", "bound"),
    [
        ({"method": "girard"}, 0.13),
        ({"method": "girard", "n_particles": 1000}, 0.13),
        ({"method": "sir", "n_particles": 1000}, 0.13),
        ({"method": "sir", "n_particles": 2000, "kld": True}, 0.13),
    ],
    ids=["girard-150", "girard-1000", "sir-1000", "sir-kld"],
)
def test_table1_accuracy_and_ordering(runs, cfg, bound):
    """Table 1 in simulation: with ranging mu <= 0.13 m (paper: 0.13), and on average over
    the seeds IMU only > with model > with ranging (paper: 0.59 > 0.47 > 0.13)."""
    mean, per_seed = _errors(runs, **cfg)
    assert mean["ranging"] <= bound, per_seed
    assert max(per_seed["ranging"]) <= 0.2, per_seed
    assert mean["imu"] > mean["model"] > mean["ranging"], mean


def test_literal_set_weighting_works_at_paper_size(runs):
    """weighting="set" (w = eq. (1), the paper's wording) at ν = 150: still far better
    than the model alone."""
    mean, _ = _errors(runs[:3], seeds=SEEDS[:3], weighting="set")
    assert mean["ranging"] < 0.2 and mean["ranging"] < 0.6 * mean["model"]


def test_latest_readings_only(runs):
    """use_readings="latest": one reading per sensor per step (the 2-sensor update)."""
    mean, _ = _errors(runs[:3], seeds=SEEDS[:3], use_readings="latest")
    assert mean["ranging"] <= 0.15


def test_kld_adapts_the_particle_count(runs):
    r = runs[0]
    cfg = ParticleConfig(method="sir", n_particles=5000, kld=True, kld_min_particles=200)
    tr = track_particles(r.plan, r.steps, r.ranges, r.start_m, cfg, rng=0)
    # KLD draws at least 200; a few may die in the next step's wall test
    assert tr.n_particles.max() <= 5000 and tr.n_particles[1:].min() >= 180
    assert tr.n_particles[1:].min() < 5000  # fewer when the cloud is compact


def test_clouds_are_saved_and_normalised(runs):
    r = runs[0]
    tr = track_particles(r.plan, r.steps, r.ranges, r.start_m, rng=0, save_clouds=(9, 21, 52))
    assert [c.after_steps for c in tr.clouds] == [9, 21, 52]
    for c in tr.clouds:
        assert math.isclose(c.weight.sum(), 1.0) and c.xy_m.shape == (c.weight.size, 2)
    assert tr.xy_m.shape == (52, 2) and tr.events == ()


def test_same_seed_same_track(runs):
    r = runs[0]
    a = track_particles(r.plan, r.steps, r.ranges, r.start_m, rng=7)
    b = track_particles(r.plan, r.steps, r.ranges, r.start_m, rng=7)
    np.testing.assert_array_equal(a.xy_m, b.xy_m)


# ------------------------------------------------------------------------- degenerate


@pytest.mark.parametrize("method", ["girard", "sir"])
def test_all_particles_die_reinitialises(method):
    """A step straight through a wall kills every particle: reported, re-initialised."""
    plan = FloorPlan.from_walls([((0, 0), (10, 0)), ((0, 2), (10, 2)), ((0, 4), (10, 4)),
                                 ((0, 0), (0, 4)), ((10, 0), (10, 4))])  # fmt: skip
    steps = StepLog([1.0, 2.0, 3.0], [2.0, 1.25, 1.25], [np.pi / 2, 0.0, 0.0], [0.0] * 3)
    cfg = ParticleConfig(method=method, mode="model", n_particles=200)
    tr = track_particles(plan, steps, None, (1.0, 1.0), cfg, rng=0)
    assert [e.kind for e in tr.events] == ["all_died"]
    assert tr.events[0].step == 1 and "re-initialised" in tr.events[0].message
    assert tr.xy_m.shape == (3, 2) and np.all(np.isfinite(tr.xy_m))
    assert np.all((tr.xy_m[:, 1] > 0) & (tr.xy_m[:, 1] < 4))


@pytest.mark.parametrize("method", ["girard", "sir"])
def test_walker_leaving_the_map_is_reported(method):
    """A corridor open at its east end: walking out of it leaves the map."""
    plan = FloorPlan.from_walls([((0, 0), (5, 0)), ((0, 2), (5, 2)), ((0, 0), (0, 2))])
    steps = StepLog(np.arange(1.0, 6.0), [1.25] * 5, [0.0] * 5, [0.0] * 5)
    cfg = ParticleConfig(method=method, mode="model")
    tr = track_particles(plan, steps, None, (2.0, 1.0), cfg, rng=0)
    kinds = [e.kind for e in tr.events]
    assert "left_map" in kinds
    assert np.all(tr.xy_m[:, 0] <= 5.0) and np.all(np.isfinite(tr.xy_m))


def test_bad_inputs_raise():
    steps = StepLog([1.0], [1.0], [0.0], [0.0])
    ranges = RangeLog([0.5], [0], [1.0])
    with pytest.raises(InvalidParameterError, match="needs a floor plan"):
        track_particles(None, steps, None, (0, 0), ParticleConfig(mode="model"))
    with pytest.raises(InvalidParameterError, match="needs a range log"):
        track_particles(BOX, steps, None, (1, 1))
    # inputs that do not fit each other (check_inputs): exit code 5, not 2
    with pytest.raises(IncompatibleInputError, match="outside the floor plan"):
        track_particles(BOX, steps, ranges, (20, 1))
    with pytest.raises(InvalidParameterError, match="start_xy"):
        track_particles(BOX, steps, ranges, (np.nan, 1))
    with pytest.raises(IncompatibleInputError, match="sensor 2"):
        track_particles(BOX, steps, RangeLog([0.5], [2], [1.0]), (1, 1))
    with pytest.raises(InvalidParameterError, match="steps must be a StepLog"):
        track_particles(BOX, [1.0], ranges, (1, 1))


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"method": "ukf"}, "method="),
        ({"mode": "gps"}, "mode="),
        ({"n_particles": 0}, "n_particles"),
        ({"eps_m": -0.1}, "eps_m"),
        ({"kappa": 1.5}, "kappa"),
        ({"weighting": "max"}, "weighting"),
        ({"use_readings": "some"}, "use_readings"),
        ({"n_rays": 5, "sensor": SRF02(n_rays=7)}, "n_rays"),
        ({"mount_angles_rad": ()}, "mount_angles_rad"),
        ({"p_outlier": 1.5}, "p_outlier"),
        ({"sensor": "srf02"}, "sensor must be an SRF02"),
    ],
)
def test_config_validation(kw, match):
    with pytest.raises(InvalidParameterError, match=match):
        ParticleConfig(**kw)


def test_tracking_error_validation():
    with pytest.raises(InvalidParameterError, match="truth_m"):
        tracking_error([[0, 0]], [[0, 0], [1, 1]])


@pytest.mark.parametrize(
    ("doc", "message"),
    [
        ('{"format": "rangekit-floorplan", "version": 1, "units": "m", "walls": '
         '[{"from": [0, 0], "to": [0, 0]}]}', "walls[0]: zero-length wall"),
        ('{"format": "rangekit-floorplan", "version": 1, "units": "m", "walls": '
         '[{"from": [0, 0], "to": [3, 0], "doors": [{"at_m": 2.5, "width_m": 0.9}]}]}',
         "walls[0].doors[0]: door [2.5, 3.4] m lies outside its wall"),
        ('{"format": "rangekit-floorplan", "version": 1, "units": "ft", "walls": []}',
         "units='ft' must be 'm'"),
        ('{"format": "rangekit-floorplan", "version": 1, "units": "m", "walls": [', ""),
    ],
)  # fmt: skip
def test_malformed_floor_plan_gives_one_clear_line(tmp_path, doc, message):
    """The filter's plan input (rangekit.floorplan.load_floorplan): one line, names the file."""
    from rangekit.errors import RangekitError
    from rangekit.floorplan import load_floorplan

    p = tmp_path / "plan.json"
    p.write_text(doc)
    with pytest.raises(RangekitError) as e:
        load_floorplan(p)
    text = str(e.value)
    assert "plan.json" in text and message in text and "\n" not in text
