"""SIR resampling and roughening: the compiled kernel equals the numpy reference bit for
bit for a fixed seed, and systematic resampling draws what it should."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.floorplan import FloorPlan
from rangekit.localize import _particle_kernels as K
from rangekit.localize import particle as P


def _rooms() -> FloorPlan:
    """Two 3 m rooms side by side with a door: walls for the roughening to bump into."""
    walls = [
        {"from": [0, 0], "to": [6, 0]},
        {"from": [0, 3], "to": [6, 3]},
        {"from": [0, 0], "to": [0, 3]},
        {"from": [6, 0], "to": [6, 3]},
        {"from": [3, 0], "to": [3, 3], "doors": [{"at_m": 1.0, "width_m": 0.9}]},
    ]
    return FloorPlan.from_walls(walls)


def _cloud(n: int, seed: int):
    g = np.random.default_rng(seed)
    xy = np.column_stack([g.uniform(0.01, 5.99, n), g.uniform(0.01, 2.99, n)])
    w = g.gamma(0.3, size=n)  # skewed weights: many near zero, a few heavy
    return xy, w / w.sum()


@pytest.mark.parametrize(
    ("plan", "n_in", "n_out", "roughening", "seed"),
    [
        (True, 5000, 5000, 0.2, 1),
        (True, 5000, 3000, 2.0, 2),  # strong jitter: many moves undone at the walls
        (True, 7, 20, 0.2, 3),
        (False, 4000, 4000, 0.2, 4),
        (True, 3000, 3000, 0.0, 5),  # no roughening
        (True, 1, 1, 0.2, 6),
    ],
)
def test_compiled_equals_the_numpy_reference(plan, n_in, n_out, roughening, seed):
    cfg = P.ParticleConfig(method="sir", n_particles=n_out, roughening=roughening)
    world = P._World(_rooms() if plan else None, cfg, use_plan=plan)
    xy, w = _cloud(n_in, seed)
    g1, g2 = np.random.default_rng(seed), np.random.default_rng(seed)
    a, wa = P._sir_resample(world, cfg, xy, w, g1)
    b, wb = P._sir_resample_reference(world, cfg, xy, w, g2)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(wa, wb)
    assert g1.random() == g2.random()  # the same draws were taken


def test_kld_path_equals_the_reference():
    cfg = P.ParticleConfig(method="sir", n_particles=4000, kld=True, kld_min_particles=50)
    world = P._World(_rooms(), cfg, use_plan=True)
    xy, w = _cloud(4000, 7)
    xy = 1.5 + 0.1 * (xy - xy.mean(axis=0))  # a tight cloud: few KLD bins
    a = P._sir_resample(world, cfg, xy, w, np.random.default_rng(7))
    b = P._sir_resample_reference(world, cfg, xy, w, np.random.default_rng(7))
    np.testing.assert_array_equal(a[0], b[0])
    assert 50 <= a[0].shape[0] < 4000


def test_systematic_counts_are_floor_or_ceil_of_n_w():
    """Systematic resampling draws particle i floor(n w_i) or ceil(n w_i) times."""
    g = np.random.default_rng(8)
    n = 2000
    xy = np.column_stack([np.arange(n, dtype=float), np.zeros(n)])  # x = particle index
    w = g.gamma(0.5, size=n)
    w /= w.sum()
    grid = K.build_grid(np.zeros((0, 4)), 1.0)
    for _ in range(20):
        out = K.sir_resample(xy, w, n, g, roughening=0.0, bounds=None, grid=grid)
        counts = np.bincount(out[:, 0].astype(np.int64), minlength=n)
        assert counts.sum() == n
        lo, hi = np.floor(n * w - 1e-9), np.ceil(n * w + 1e-9)
        assert np.all((counts >= lo) & (counts <= hi))


def test_roughening_spread_and_walls():
    """Jitter per axis is K * extent / sqrt(n) (a point cloud on a 6 x 3 m box: sigma
    0.2 * (6, 3) / sqrt(10,000) = (12, 6) mm); no move crosses the middle wall."""
    n = 10_000
    g = np.random.default_rng(9)
    xy = np.column_stack([g.uniform(0.01, 5.99, n), g.uniform(0.01, 2.99, n)])
    w = np.full(n, 1.0 / n)
    cfg = P.ParticleConfig(method="sir", n_particles=n)
    world = P._World(_rooms(), cfg, use_plan=True)
    u = float(np.random.default_rng(10).random())
    idx = np.minimum(np.searchsorted(np.cumsum(w), (u + np.arange(n)) / n, side="right"), n - 1)
    out = K.sir_resample(xy, w, n, np.random.default_rng(10), roughening=0.2,
                         bounds=world.bounds, grid=world.grid)  # fmt: skip
    d = out - xy[idx]
    ext = xy[idx].max(axis=0) - xy[idx].min(axis=0)
    np.testing.assert_allclose(d.std(axis=0), 0.2 * ext / math.sqrt(n), rtol=0.05)
    src = xy[idx]
    near = (np.abs(src[:, 0] - 3.0) < 0.05) & ((src[:, 1] < 1.0) | (src[:, 1] > 1.9))  # no door
    assert near.sum() > 50
    assert np.all(np.sign(out[near, 0] - 3.0) == np.sign(src[near, 0] - 3.0))


@pytest.mark.parametrize("plan", [True, False])
def test_compiled_step_equals_the_numpy_reference(plan):
    """Propagation, wall elimination and the mixture likelihood (readings with and
    without an echo), compiled and in numpy: the same particles and weights."""
    cfg = P.ParticleConfig(method="sir", n_particles=3000, use_readings="latest")
    world = P._World(_rooms(), cfg, use_plan=plan)
    xy, w = _cloud(3000, 11)
    ctx = P._StepCtx(0, 1.0, np.zeros(2), 0.4, 0.7, math.nan, np.ones(2),
                     np.array([0, 1]), np.array([1.1, math.nan]))  # fmt: skip
    a = P._sir_step(world, cfg, xy, w, ctx, np.random.default_rng(12))
    b = P._sir_step_reference(world, cfg, xy, w, ctx, np.random.default_rng(12))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    if plan:
        assert a[0].shape[0] < 3000  # some moves went through walls


def test_whole_sir_track_equals_the_numpy_reference(monkeypatch):
    from rangekit.sim import girard2011

    walk = girard2011.simulate(n_laps=1, rng=13)
    cfg = P.ParticleConfig(method="sir", n_particles=500)
    fast = P.track_particles(walk.plan, walk.steps, walk.ranges, walk.start_m, cfg, rng=13)
    monkeypatch.setattr(P, "_sir_step", P._sir_step_reference)
    monkeypatch.setattr(P, "_sir_likelihood", P._sir_likelihood_reference)
    monkeypatch.setattr(P, "_sir_resample", P._sir_resample_reference)
    ref = P.track_particles(walk.plan, walk.steps, walk.ranges, walk.start_m, cfg, rng=13)
    np.testing.assert_array_equal(fast.xy_m, ref.xy_m)
    np.testing.assert_array_equal(fast.n_particles, ref.n_particles)
