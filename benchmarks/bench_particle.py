"""Benchmark the floor-plan particle filters (Girard et al. 2011) and their ray casting.

Floor plans (generated, seeded): an office of 10 x 10 rooms of 3 m x 3 m, every inner
wall with a 0.9 m door (220 walls, 400 solid segments, all axis-parallel); and the same
office with a 1.2 m wall at a random angle in each room ("slanted", 320 walls, 500
segments, 102 wall directions). 100,000 particles uniformly in the building, heading
0.3 rad, two SRF02s back to back (mounts +-90 deg), 7 rays each (the paper's λ), one core.

Rows:

* ``ray model``: :func:`ray_model_grid` for 100,000 particles x 2 sensors x 7 rays (the
  δ of eq. (1)); "updates/s" counts one such evaluation as an update of the ranging
  part. The fast path answers from ray tables (``build_ray_tables``: per occupied grid
  cell and ray direction, the walls eq. (3) accepts and the walls that can block them;
  the row label gives the mean number of the 14 rays per particle that have an accepted
  wall within reach, the only ones looked at); the row "all 7 rays cast" times the same
  numbers by casting every ray through the grid. Both must agree exactly (exits 1
  otherwise).
* ``SIR update``: one whole step of ``method="sir"`` with 100,000 particles and one reading
  per sensor: propagate, wall-crossing tests, the ray model, the likelihood, systematic
  resampling and roughening (the "100,000 particles x 2 sensors x 7 rays" update), with
  the compiled propagation, likelihood, resampling and roughening
  (``_particle_kernels.sir_move``, ``sir_likelihood``, ``sir_resample``) and, in the same
  run, with their numpy references (``particle._sir_step_reference``,
  ``_sir_resample_reference``: the code before issue 20); both must give the same
  particles bit for bit (exits 1 otherwise). ``SIR resampling + roughening`` times that
  part alone, compiled and numpy.
* ``Girard update``: one whole step of the paper's filter with ν = 100,000 on the
  axis-parallel office, from the ~12,400 particles within 6 m of its centre (κ = 20 ->
  ~250,000 candidate moves, crossing tests, merging at τ, eq. (1) on the merged set, keep
  ν).

Ray casting (first-hit distance, segment and incidence of arbitrary rays, 6 m range, same
rays for every caster, "slanted" plan): rangekit's numba uniform-grid caster
(``cast_rays_grid``), the brute-force numba loop behind ``rangekit.floorplan.cast_rays``
and a plain numpy vectorised baseline (``_raycast._cast_rays_reference``: all ray x
segment pairs in blocks), rays/s and the ratio to numpy printed. The grid caster must
agree with the numpy baseline (distance and segment exactly); exits 1 otherwise. The last
line rates the ray model's tables (slanted office) in model rays answered per second
against the same numpy baseline.

Target (issue 6, raised by issue 20): >= 20 SIR updates/s for 100,000 particles x 2
sensors x 7 rays on >= 200 walls, one core (was 8.8-9.4 with the numpy SIR steps).

Times are medians of ``--repeats`` runs after a warm-up (the best run is printed too):
the machine is shared and noisy.

Run: ``python benchmarks/bench_particle.py [--quick] [--repeats N]``
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import _one_core  # noqa: F401  (one thread, repo on sys.path; before numpy)
import numpy as np

from rangekit import _raycast
from rangekit.floorplan import FloorPlan
from rangekit.localize import _particle_kernels as K
from rangekit.localize import particle as P
from rangekit.sensors.srf02 import SRF02

N_PARTICLES = 100_000
HEADING = 0.3
TARGET_UPS = 20.0
ROOM_M = 3.0


def office(n: int = 10, slanted: bool = False, seed: int = 6) -> FloorPlan:
    """n x n rooms of 3 m; doors in every inner wall; optionally a slanted wall per room."""
    walls = []
    for j in range(n + 1):
        for i in range(n):
            doors = [] if j in (0, n) else [{"at_m": 1.0, "width_m": 0.9}]
            a, b = [i * ROOM_M, j * ROOM_M], [(i + 1) * ROOM_M, j * ROOM_M]
            walls.append({"from": a, "to": b, "doors": doors})
            a, b = [j * ROOM_M, i * ROOM_M], [j * ROOM_M, (i + 1) * ROOM_M]
            walls.append({"from": a, "to": b, "doors": doors})
    if slanted:
        rng = np.random.default_rng(seed)
        for i in range(n):
            for j in range(n):
                c = np.array([i + 0.5, j + 0.5]) * ROOM_M + rng.uniform(-0.4, 0.4, 2)
                a = rng.uniform(0, np.pi)
                d = 0.6 * np.array([math.cos(a), math.sin(a)])
                walls.append({"from": (c - d).tolist(), "to": (c + d).tolist()})
    return FloorPlan.from_walls(walls)


def rays_looked_at(grid, sensor: SRF02, mounts: np.ndarray, thr: float, xy: np.ndarray) -> float:
    """Mean number of rays per particle with an accepted wall within reach (ray tables)."""
    psi = sensor.ray_offsets_rad
    tb = K.build_ray_tables(
        xy[:, 0], xy[:, 1], HEADING, mounts, psi, sensor.max_range_at(psi), thr, grid
    )
    per_cell = (np.diff(tb.a_start) > 0).reshape(-1, mounts.size * psi.size).sum(axis=1)
    return float(per_cell[tb.slot[tb.cell]].mean())


def timed(fn, repeats: int) -> tuple[float, float, float]:
    """Median and best wall time, and median CPU time of this process, of ``repeats``
    calls after a warm-up call (the CPU time is the one less disturbed by other jobs on a
    shared machine)."""
    fn()  # warm-up (compile or cache load)
    out, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        out.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return float(np.median(out)), min(out), float(np.median(cpu))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer rays for the slow peers")
    ap.add_argument("--repeats", type=int, default=7, help="median of N (default 7)")
    args = ap.parse_args()
    rep = args.repeats
    rng = np.random.default_rng(2011)
    sensor = SRF02()
    psi = sensor.ray_offsets_rad
    rmax_ray = sensor.max_range_at(psi)
    thr = 0.5 * math.pi - sensor.incidence_window_rad - 1e-12
    mounts = np.array([0.5 * math.pi, -0.5 * math.pi])
    side = 10 * ROOM_M
    xy = rng.uniform(0.05, side - 0.05, (N_PARTICLES, 2))
    rays_per_update = N_PARTICLES * mounts.size * psi.size

    rows = []
    exact = True
    plans = {"axis-parallel": office(), "slanted": office(slanted=True)}
    for name, plan in plans.items():
        grid = K.build_grid(np.ascontiguousarray(plan.segments), 1.0)
        print(
            f"plan {name}: {len(plan.walls)} walls, {plan.segments.shape[0]} segments, "
            f"{grid.orient.size} wall directions, grid {grid.nx} x {grid.ny} cells of 1 m"
        )
        margs = (mounts, psi, rmax_ray, thr, sensor.min_range_m, grid)
        looked = rays_looked_at(grid, sensor, mounts, thr, xy)
        fast = K.ray_model_grid(xy[:, 0], xy[:, 1], HEADING, *margs, tables=True)
        slow = K.ray_model_grid(xy[:, 0], xy[:, 1], HEADING, *margs, tables=False)
        same = np.array_equal(fast, slow)
        exact &= same
        print(
            f"  ray tables vs casting every ray: {'identical' if same else 'DIFFERENT'} "
            f"({np.isfinite(fast).mean():.0%} of the sensors have a reading)"
        )
        t = timed(lambda m=margs: K.ray_model_grid(xy[:, 0], xy[:, 1], HEADING, *m), rep)
        rows.append((f"ray model, {name} (tables; {looked:.1f} of 14 rays looked at)", t))
        t = timed(
            lambda m=margs: K.ray_model_grid(xy[:, 0], xy[:, 1], HEADING, *m, tables=False), rep
        )
        rows.append((f"ray model, {name}, all 7 rays cast", t))

        # One whole SIR update (one reading per sensor, at the particles' end positions).
        cfg = P.ParticleConfig(method="sir", n_particles=N_PARTICLES, use_readings="latest")
        world = P._World(plan, cfg, use_plan=True)
        ctx = P._StepCtx(
            0, 1.0, np.array([0.0, 0.0]), HEADING, 0.0, 0.03, np.ones(2), np.array([0, 1]),
            np.array([1.2, 1.7]),
        )  # fmt: skip
        w0 = np.full(N_PARTICLES, 1.0 / N_PARTICLES)

        def sir_update(world=world, cfg=cfg, ctx=ctx, w0=w0, step=P._sir_step,
                       resample=P._sir_resample):  # fmt: skip
            g = np.random.default_rng(0)
            res = step(world, cfg, xy, w0, ctx, g)
            w = res[1] / res[1].sum()
            return resample(world, cfg, res[0], w, g)[0], res[0], w

        def sir_update_numpy(world=world, cfg=cfg, ctx=ctx, w0=w0):
            return sir_update(world, cfg, ctx, w0, P._sir_step_reference,
                              P._sir_resample_reference)  # fmt: skip

        fast, moved, w_moved = sir_update()
        same = np.array_equal(fast, sir_update_numpy()[0])
        exact &= same
        print(f"  SIR update compiled vs numpy reference: {'identical' if same else 'DIFFERENT'}")
        rows.append((f"SIR update, {name} (step + resample + roughening)", timed(sir_update, rep)))
        rows.append((f"SIR update, {name}, numpy steps (before)", timed(sir_update_numpy, rep)))
        for label, fn in (("compiled", P._sir_resample), ("numpy", P._sir_resample_reference)):

            def resample(fn=fn, world=world, cfg=cfg, moved=moved, w=w_moved):
                return fn(world, cfg, moved, w, np.random.default_rng(1))

            rows.append((f"SIR resampling + roughening, {name}, {label}", timed(resample, rep)))

    # The paper's filter at nu = 100,000 on the axis-parallel office (one step).
    plan = plans["axis-parallel"]
    cfg = P.ParticleConfig(n_particles=N_PARTICLES, use_readings="latest")
    world = P._World(plan, cfg, use_plan=True)
    vec = 1.25 * np.array([math.cos(HEADING), math.sin(HEADING)])
    ctx = P._StepCtx(
        0, 1.0, vec, HEADING, 1.25, 0.03, np.ones(2), np.array([0, 1]), np.array([1.2, 1.7])
    )
    cloud = xy[np.hypot(*(xy - side / 2).T) < 6.0][:N_PARTICLES]
    wg = np.full(cloud.shape[0], 1.0 / cloud.shape[0])
    stats = {}

    def girard_update():
        out = P._girard_step(world, cfg, cloud, wg, ctx, np.random.default_rng(0))
        stats["kept"] = out[0].shape[0]

    t_girard = timed(girard_update, rep)
    rows.append(
        (f"Girard update, nu = 100,000 ({cloud.shape[0]} parents x 20 -> kept {stats['kept']})",
         t_girard)
    )  # fmt: skip

    print()
    w = max(len(r[0]) for r in rows)
    head = "update (100,000 particles x 2 sensors x 7 rays)"
    print(f"{head:<{w}}  {'median ms':>9}  {'best ms':>7}  {'updates/s':>9}  {'CPU ms':>6}  "
          f"{'per CPU s':>9}")  # fmt: skip
    for label, (t, t_best, c) in rows:
        print(f"{label:<{w}}  {t * 1e3:9.1f}  {t_best * 1e3:7.1f}  {1.0 / t:9.1f}  "
              f"{c * 1e3:6.1f}  {1.0 / c:9.1f}")  # fmt: skip
    print(f"(one update = {rays_per_update:,} model rays; target >= {TARGET_UPS:g} updates/s)")

    # Ray casting: grid vs brute force vs numpy, on the slanted plan.
    plan = plans["slanted"]
    seg = np.ascontiguousarray(plan.segments)
    grid = K.build_grid(seg, 1.0)
    n_rays = 1_400_000
    n_np = 20_000 if args.quick else 100_000
    ox, oy = rng.uniform(0.05, side - 0.05, (2, n_rays))
    a = rng.uniform(-np.pi, np.pi, n_rays)
    dx, dy = np.cos(a), np.sin(a)
    rmax = np.full(n_rays, 6.0)
    excl = np.full(n_rays, -1, np.int64)
    t_grid = timed(lambda: K.cast_rays_grid(ox, oy, dx, dy, rmax, grid), rep)[0]
    brute = _raycast._compiled("cast")
    nb = 200_000
    t_brute = timed(
        lambda: brute(ox[:nb], oy[:nb], dx[:nb], dy[:nb], rmax[:nb], seg, excl[:nb]), 3
    )[0]
    sl = slice(0, n_np)
    np_args = (ox[sl], oy[sl], dx[sl], dy[sl], rmax[sl], seg, excl[sl])
    t_np = timed(lambda: _raycast._cast_rays_reference(*np_args), 3)[0]
    r_grid, r_brute, r_np = n_rays / t_grid, nb / t_brute, n_np / t_np
    t_model = next(t for label, (t, _, _) in rows if label.startswith("ray model, slanted (tables"))
    r_model = rays_per_update / t_model
    print()
    print(f"ray casting, slanted plan ({seg.shape[0]} segments), random rays of 6 m:")
    print(f"  numba uniform grid (rangekit)     {r_grid / 1e6:8.2f} M rays/s  ({n_rays:,} rays)")
    print(f"  numba brute force (floorplan)     {r_brute / 1e6:8.2f} M rays/s  ({nb:,} rays)")
    print(f"  numpy vectorised baseline         {r_np / 1e6:8.2f} M rays/s  ({n_np:,} rays)")
    print(
        f"  ratio grid / numpy: {r_grid / r_np:.0f}x; grid / brute force: {r_grid / r_brute:.1f}x"
    )
    print(
        f"  ray model from tables (slanted office, rays answered, not cast) "
        f"{r_model / 1e6:.1f} M rays/s: {r_model / r_np:.0f}x numpy"
    )

    ref = _raycast._cast_rays_reference(*np_args)
    got = K.cast_rays_grid(ox[sl], oy[sl], dx[sl], dy[sl], rmax[sl], grid)
    agree = np.array_equal(ref[0], got[0], equal_nan=True) and np.array_equal(ref[1], got[1])
    print(f"agree with the numpy baseline (distance and segment, {n_np:,} rays): "
          f"{'yes' if agree else 'NO'}")  # fmt: skip
    ups = {label: 1.0 / t for label, (t, _, _) in rows}
    cpu_ups = {label: 1.0 / c for label, (_, _, c) in rows}
    for plan_name in plans:
        new = ups[f"SIR update, {plan_name} (step + resample + roughening)"]
        old = ups[f"SIR update, {plan_name}, numpy steps (before)"]
        rs_new = ups[f"SIR resampling + roughening, {plan_name}, compiled"]
        rs_old = ups[f"SIR resampling + roughening, {plan_name}, numpy"]
        cpu = cpu_ups[f"SIR update, {plan_name} (step + resample + roughening)"]
        print(
            f"target >= {TARGET_UPS:g} SIR updates/s, {plan_name} office: "
            f"{'met' if new >= TARGET_UPS else 'NOT met'} ({new:.1f}/s wall, {cpu:.1f} per CPU "
            f"second; numpy steps in the same run {old:.1f}/s, {new / old:.2f}x; resampling + "
            f"roughening alone {rs_new / rs_old:.1f}x)"
        )
    if not agree:
        print("\nFAIL: the grid caster disagrees with the numpy baseline", file=sys.stderr)
    if not exact:
        print("\nFAIL: ray tables or compiled SIR steps disagree with their references",
              file=sys.stderr)  # fmt: skip
    return 0 if agree and exact else 1


if __name__ == "__main__":
    sys.exit(main())
