"""Benchmark the DUHL filter (Kim & Kim 2013 §III-IV) per step against peers run alongside.

Logs: the four simulated trajectories of :mod:`rangekit.sim.kim2013` (seed 2013), each
repeated ``--laps`` times end to end (``--quick``: 1 lap) so that one call runs several
thousand odometry steps.

Rows (µs):

* ``DUHL per cycle``: the whole log through :func:`rangekit.localize.duhl.track_duhl`
  (one compiled call), divided by the number of distance rows. One cycle = one Tx
  firing (200 ms): the ~20 odometry predictions of the pose and of every available Tx's
  distances (eqs (14), (16), (23), (24)), the distance correction or initialisation
  (eqs (25)-(30)), the discard step (eqs (31)-(32)), a UHL solve on all available Txs,
  ``R_k`` of eq (21) and the pose correction (eqs (17)-(20)). This is the paper's "step"
  of Table III (0.55-0.97 ms in C++ on a 2.66 GHz laptop): its EKF+UHL share (0.24 ms)
  only makes sense per UHL solve, which happens once per cycle.
* ``DUHL per odometry step``: the same time divided by the odometry rows (100 Hz).
* ``interpreted per cycle``: the same filter, the same kernels, run as plain Python and
  numpy (``NUMBA_DISABLE_JIT=1``, in a child process of this run) on the first 2000
  odometry rows of each trajectory: the straightforward implementation of the same
  update, and the peer of the DUHL row. Its poses must equal the compiled ones (1e-9 m).
* ``ranges variant per cycle``: the tightly coupled EKF (``variant="ranges"``).
* ``FilterPy per cycle``: FilterPy's ``ExtendedKalmanFilter(dim_x=3, dim_z=3)`` running
  the ``ranges`` model on the same log (odometry ``predict`` with ``F = J_f,x`` and
  ``Q = J_f,u U J_f,u^T`` per step, and ``update`` with the three distances per Tx row),
  first 2000 odometry rows; the peer measured in the same run (``pip install -e .[bench]``).

Ratios, all against peers timed in this run (issue 21): ``vs interpreted`` = the
interpreted filter's time per cycle / ours (acceptance: >= :data:`ACCEPT_X` on every
trajectory); ``vs FilterPy`` = FilterPy's per-cycle time / ours. Kim & Kim's Table III
(0.55-0.97 ms per step in C++ on a 2.66 GHz laptop, 2013) is printed beside as context
only, in a note: another machine, language and year are not a peer. Checks: the
interpreted and compiled DUHL agree to 1e-9 m, the ``ranges`` variant and FilterPy to 1e-6
m, on the first 2000 odometry rows (exit 1 otherwise).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import statistics
import subprocess
import sys
import time

import _one_core  # noqa: F401  (one BLAS thread, repository importable)
import numpy as np
from _report import row

from rangekit.experiments.kim2013 import PAPER_TABLE_III_MS
from rangekit.localize import _duhl_kernels as K
from rangekit.localize.duhl import DUHLConfig, track_duhl
from rangekit.sim.kim2013 import TRAJECTORIES, simulate

SEED = 2013
N_PEER = 2000
#: Acceptance: DUHL per cycle >= this many times faster than the interpreted filter.
ACCEPT_X = 30.0  # measured 59-213x (--quick, 2 shared cores)


def lapped(traj: int, laps: int) -> tuple:
    """The trajectory's log repeated ``laps`` times (times shifted, odometry of each lap
    restarting from the same pose is harmless for timing)."""
    sim = simulate(traj, rng=SEED)
    log = sim.to_log()
    o, d = log.odometry, log.distances
    span = o.t_s[-1] - o.t_s[0] + 0.01
    cat = lambda a, shift: np.concatenate([a + i * shift for i in range(laps)])  # noqa: E731
    odo = (cat(o.t_s, span), np.tile(o.v_right_mps, laps), np.tile(o.v_left_mps, laps))
    dist = (cat(d.t_s, span), np.tile(d.tx, laps), np.tile(d.d_m, (laps, 1)))
    return sim, odo, dist


def time_calls(fn, repeats: int) -> list[float]:
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def head(odo, dist, n: int) -> tuple:
    """The first ``n`` odometry rows and the distance rows up to the last of them."""
    m = int(np.searchsorted(dist[0], odo[0][n - 1], side="right"))
    return tuple(a[:n] for a in odo), tuple(a[:m] for a in dist)


def interpreted(traj: int, laps: int, n: int) -> dict:
    """Time DUHL with numba disabled, in a child process: {"us_cycle", "pose"}."""
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    cmd = [sys.executable, __file__, "--interpreted", str(traj), str(laps), str(n)]
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def _interpreted_child(traj: int, laps: int, n: int) -> None:
    sim, odo, dist = lapped(traj, laps)
    o, d = head(odo, dist, n)
    kw = {"tx_ids": sim.beacons.ids, "initial_pose": sim.true_pose[0]}
    call = functools.partial(track_duhl, *o, *d, sim.beacons.xyz_m, config=DUHLConfig(), **kw)
    tt = time_calls(call, 2)
    pose = call().pose
    print(json.dumps({"us_cycle": min(tt) / max(len(d[0]), 1) * 1e6, "pose": pose.tolist()}))


def filterpy_ranges(EKF, sim, odo, dist, n: int) -> np.ndarray:
    """The ``ranges`` variant with FilterPy on the first ``n`` odometry rows."""
    cfg = DUHLConfig()
    f = EKF(dim_x=3, dim_z=3)
    f.x = sim.true_pose[0].astype(float).copy()
    f.x[2] = math.remainder(f.x[2], 2 * math.pi)
    f.P = np.diag([0.05**2, 0.05**2, math.radians(2.0) ** 2])
    f.R = np.eye(3) * cfg.sigma_d_m**2
    ids = sim.beacons.ids.tolist()
    xyz = sim.beacons.xyz_m
    t, vr, vl = odo
    dt_, dtx, dd = dist
    out = np.empty((n, 3))
    j = 0

    def updates(t_now: float, j: int) -> int:
        while j < len(dt_) and dt_[j] <= t_now:
            tx = xyz[ids.index(int(dtx[j]))]

            def hj(s, tx=tx):
                return K.distance_jacobian(s, tx, cfg.r_R_m)[1]

            def hx(s, tx=tx):
                return K.distance_jacobian(s, tx, cfg.r_R_m)[0]

            f.update(dd[j], hj, hx)
            f.x[2] = math.remainder(f.x[2], 2 * math.pi)
            j += 1
        return j

    while j < len(dt_) and dt_[j] < t[0]:
        j += 1
    j = updates(t[0], j)
    out[0] = f.x
    for k in range(1, n):
        dt = t[k] - t[k - 1]
        x, q = f.x.copy(), np.zeros((3, 3))
        K.predict_pose(x, q, vr[k], vl[k], dt, cfg.wheel_base_m, cfg.k_v_m)  # eq (14), J U J^T
        jx = np.eye(3)  # J_f,x of eq (16)
        dd_ = dt * (vr[k] + vl[k]) / 2
        a = f.x[2] + 0.5 * dt * (vr[k] - vl[k]) / cfg.wheel_base_m
        jx[0, 2], jx[1, 2] = -dd_ * math.sin(a), dd_ * math.cos(a)
        f.F, f.Q = jx, q
        f.predict()  # P = F P F^T + Q (its linear x = F x is replaced below)
        f.x = x
        j = updates(t[k], j)
        out[k] = f.x
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one lap per trajectory")
    ap.add_argument("--laps", type=int, default=5, help="laps per trajectory (default 5)")
    ap.add_argument("--repeats", type=int, default=5, help="best and median of N (default 5)")
    ap.add_argument("--interpreted", nargs=3, type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.interpreted:  # the child process of interpreted()
        _interpreted_child(*args.interpreted)
        return 0
    laps = 1 if args.quick else args.laps
    try:
        from filterpy.kalman import ExtendedKalmanFilter as EKF
    except ImportError:
        EKF = None
        print("FilterPy not installed (pip install -e .[bench]): peer skipped")
    rows = []
    status = 0
    for traj in sorted(TRAJECTORIES):
        sim, odo, dist = lapped(traj, laps)
        kw = {"tx_ids": sim.beacons.ids, "initial_pose": sim.true_pose[0]}
        res = {}
        for variant in ("duhl", "ranges"):
            cfg = DUHLConfig(variant=variant)

            call = functools.partial(track_duhl, *odo, *dist, sim.beacons.xyz_m, config=cfg, **kw)

            call()  # compile or cache load
            tt = time_calls(call, args.repeats)
            res[variant] = (min(tt), statistics.median(tt))
        n_c, n_o = len(dist[0]), len(odo[0])
        paper_us = PAPER_TABLE_III_MS[traj][2] * 1e3
        best, med = res["duhl"]
        line = {
            "traj": traj,
            "cycles": n_c,
            "odo": n_o,
            "duhl_cycle": best / n_c * 1e6,
            "duhl_cycle_med": med / n_c * 1e6,
            "duhl_odo": best / n_o * 1e6,
            "ranges_cycle": res["ranges"][0] / n_c * 1e6,
            "paper": paper_us,
            "peer_cycle": float("nan"),
        }
        n = min(N_PEER, n_o)
        child = interpreted(traj, laps, n)
        line["interp_cycle"] = child["us_cycle"]
        o, d = head(odo, dist, n)
        ours = track_duhl(*o, *d, sim.beacons.xyz_m, config=DUHLConfig(), **kw).pose
        gap = float(np.nanmax(np.abs(ours - np.array(child["pose"], dtype=float))))
        if not gap < 1e-9:
            print(f"trajectory {traj}: interpreted and compiled DUHL differ by {gap:.3g} m")
            status = 1
        if EKF is not None:
            n = min(N_PEER, n_o)
            n_rows = int(np.searchsorted(dist[0], odo[0][n - 1], side="right"))
            tp = time_calls(functools.partial(filterpy_ranges, EKF, sim, odo, dist, n), 2)
            line["peer_cycle"] = min(tp) / max(n_rows, 1) * 1e6
            ref = filterpy_ranges(EKF, sim, odo, dist, n)
            cfg = DUHLConfig(variant="ranges")
            ours = track_duhl(*odo, *dist, sim.beacons.xyz_m, config=cfg, **kw)
            gap = float(np.max(np.abs(ours.pose[:n, :2] - ref[:, :2])))
            if not gap < 1e-6:
                print(f"trajectory {traj}: ranges variant and FilterPy differ by {gap:.3g} m")
                status = 1
        rows.append(line)

    print(f"\nDUHL per step, {laps} lap(s) per trajectory, best of {args.repeats} (median)")
    print(
        "| traj | cycles | DUHL µs/cycle | interpreted µs/cycle | vs interpreted "
        "| DUHL µs/odometry step | ranges µs/cycle | FilterPy µs/cycle | vs FilterPy (ranges) "
        "| note: Kim & Kim Table III (C++, 2013) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['traj']} | {r['cycles']} | {r['duhl_cycle']:.1f} ({r['duhl_cycle_med']:.1f}) "
            f"| {r['interp_cycle']:.0f} | {r['interp_cycle'] / r['duhl_cycle']:.0f}x "
            f"| {r['duhl_odo']:.2f} | {r['ranges_cycle']:.1f} | {r['peer_cycle']:.0f} "
            f"| {r['peer_cycle'] / r['ranges_cycle']:.0f}x | {r['paper']:.0f} µs |"
        )
    worst = min(r["interp_cycle"] / r["duhl_cycle"] for r in rows)
    print(f"\nworst DUHL ratio vs the interpreted filter: {worst:.1f}x "
          f"(acceptance: >= {ACCEPT_X:.0f}x)")  # fmt: skip

    # Headline rows for benchmarks/run.py (ratio = t_peer / t: > 1 = faster than the peer):
    # the trajectory with the smallest ratio of each comparison.
    size = f"{laps} lap(s), best of {args.repeats}"
    w = min(rows, key=lambda r: r["interp_cycle"] / r["duhl_cycle"])
    span = ", ".join(f"{r['duhl_cycle']:.1f}" for r in rows)
    row("duhl", f"track_duhl per cycle (one Tx firing), trajectory {w['traj']} (worst)",
        w["duhl_cycle"], "us/cycle",
        peer=f"the same kernels interpreted (NUMBA_DISABLE_JIT=1), first {N_PEER} odometry rows",
        peer_value=w["interp_cycle"],
        note=f"{size}; trajectories 1-4: {span} us; acceptance >= {ACCEPT_X:.0f}x: "
        f"{'met' if worst >= ACCEPT_X else 'NOT met'}; context: Kim & Kim 2013 Table III "
        f"reports {w['paper']:.0f} us per step (C++, their laptop)")  # fmt: skip
    w = min(rows, key=lambda r: r["peer_cycle"] / r["ranges_cycle"] if EKF is not None else 0.0)
    row("duhl", f"track_duhl ranges variant per cycle, trajectory {w['traj']} (worst)",
        w["ranges_cycle"], "us/cycle", peer="FilterPy ExtendedKalmanFilter, same model",
        peer_value=w["peer_cycle"] if EKF is not None else None,
        note=f"{size}; FilterPy on the first {N_PEER} odometry rows"
        + ("" if EKF is not None else "; FilterPy not installed"))  # fmt: skip
    return status


if __name__ == "__main__":
    raise SystemExit(main())
