"""Issue 18's acceptance runs of the fixed-anchor range EKF, as printed in ``docs/rigs.md``.

``python -m rangekit.localize._rig_acceptance [--seeds N] [--first-seed S] [--duration S]
[--rate HZ] [--odometry-rate HZ] [--robust R] [--own-law]`` simulates the one-tag robot of
:func:`rangekit.sim.rigs.square_rig` (4 anchors on a 2.4 m square, one anchor per ranging
at 7.8 Hz, +10 cm bias, 10 cm skewed scatter, 5 % outliers up to +0.7 m, 20 Hz wheel
odometry with 0.5 % scale errors) and prints, per seed: the filter's RMSE with and
without an initial pose, the smoother's, least-squares multilateration's on the same
ranges, the largest bias error, the largest bias 1-sigma the filter reports and the
largest |error| / sigma, the convergence time without a pose and the share of ranges
down-weighted, the share of the seed's anchors whose bias error is within 2 sigma and the
position NEES (filter and smoother; 2 when the covariance is honest). Last, pooled over
every anchor of every seed: the share within 2 sigma (95.4 % for an honest sigma) and the
RMS of error / sigma (1). ``--own-law`` draws the ranges from the filter's own law instead
(Gaussian scatter, no outliers, no wheel scale errors): what the data allow, without the
model mismatch.
"""

from __future__ import annotations

import argparse

import numpy as np

from rangekit.localize.anchor_ekf import AnchorTrack, multilaterate_latest, track_anchors
from rangekit.sim.rigs import RigRun, simulate_rig_run, square_rig


def consistency(trk: AnchorTrack, run: RigRun) -> dict:
    """How honest a track's covariances are against the simulated truth.

    ``bias_z`` (A,): each anchor's final bias error over its reported 1-sigma; ``nees`` /
    ``nees_smooth``: the position NEES ``eᵀ P⁻¹ e`` averaged over the rows, filtered and
    (when smoothed) smoothed, 2 for an honest 2-D covariance (Bar-Shalom, Li &
    Kirubarajan 2001, §5.4.2).
    """
    out = {"bias_z": (trk.bias_m - run.true_bias_m) / trk.bias_sigma_m}
    txy = run.truth_xy(trk.t_s)
    for key, sm in (("nees", False), ("nees_smooth", True)):
        if sm and trk.x_smooth is None:
            continue
        e = trk.position(smoothed=sm) - txy
        P = trk.position_cov(smoothed=sm)
        out[key] = float(np.mean(np.einsum("ni,nij,nj->n", e, np.linalg.inv(P), e)))
    return out


def run_seed(
    seed: int,
    duration_s: float = 120.0,
    *,
    range_rate_hz: float = 7.8,
    odometry_rate_hz: float = 20.0,
    robust: str = "huber",
    own_law: bool = False,
) -> dict:
    """The acceptance numbers of one seeded run (m, s)."""
    law = {"skew_shape": 1e8, "outlier_prob": 0.0, "wheel_scale_sigma": 0.0} if own_law else {}
    run = simulate_rig_run(square_rig(), duration_s=duration_s, range_rate_hz=range_rate_hz,
                           odometry_rate_hz=odometry_rate_hz, rng=seed, **law)  # fmt: skip
    p0 = run.truth_pose([run.log.odometry.t_s[0]])[0]
    trk = track_anchors(run.log, run.rig, initial_pose=p0, smooth=True, robust=robust)
    rms = lambda e: float(np.sqrt(np.mean(e**2)))  # noqa: E731
    e = np.hypot(*(trk.position() - run.truth_xy(trk.t_s)).T)
    es = np.hypot(*(trk.position(smoothed=True) - run.truth_xy(trk.t_s)).T)
    tm, xm = multilaterate_latest(run.log, run.rig)
    ok = np.isfinite(xm[:, 0])
    em = np.hypot(*(xm[ok] - run.truth_xy(tm[ok])).T)
    t0 = track_anchors(run.log, run.rig, robust=robust)
    e0 = np.hypot(*(t0.position() - run.truth_xy(t0.t_s)).T)
    c = consistency(trk, run)
    bad = np.flatnonzero(e0 >= 0.3)
    conv = float(t0.t_s[bad[-1] + 1] if bad.size else t0.t_s[0])
    return {
        "rmse": rms(e),
        "rmse_smooth": rms(es),
        "rmse_ml": rms(em),
        "rmse_no_pose": rms(e0),
        "bias_err_max": float(np.max(np.abs(trk.bias_m - run.true_bias_m))),
        "bias_sigma_max": float(np.max(trk.bias_sigma_m)),
        "bias_z_max": float(np.max(np.abs(c["bias_z"]))),
        "bias_within_2s": float(np.mean(np.abs(c["bias_z"]) <= 2.0)),
        "nees": c["nees"],
        "nees_smooth": c["nees_smooth"],
        "converged_s": conv,
        "downweighted": len(trk.downweighted) / trk.t_s.size,
        "bias_z": c["bias_z"],
    }


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--first-seed", type=int, default=0, help="seeds S .. S+N-1")
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument("--rate", type=float, default=7.8, help="ranging rate, Hz")
    ap.add_argument("--odometry-rate", type=float, default=20.0, help="Hz")
    ap.add_argument("--robust", default="huber", choices=["huber", "student-t", "none"])
    ap.add_argument("--own-law", action="store_true", help="Gaussian ranges, no outliers")
    args = ap.parse_args(argv)
    cols = ("rmse", "rmse_ml", "rmse_smooth", "rmse_no_pose", "bias_err_max", "bias_sigma_max",
            "bias_z_max", "bias_within_2s", "nees", "nees_smooth", "converged_s",
            "downweighted")  # fmt: skip
    print("seed " + " ".join(f"{c:>14}" for c in cols))
    z = []
    for s in range(args.first_seed, args.first_seed + args.seeds):
        r = run_seed(s, args.duration, range_rate_hz=args.rate, odometry_rate_hz=args.odometry_rate,
                     robust=args.robust, own_law=args.own_law)  # fmt: skip
        print(f"{s:4d} " + " ".join(f"{r[c]:14.3f}" for c in cols))
        z.append(r["bias_z"])
    z = np.concatenate(z)
    print(f"pooled over {z.size} biases: within 2 sigma {np.mean(np.abs(z) <= 2.0):.3f} "
          f"(honest: 0.954), RMS error/sigma {np.sqrt(np.mean(z**2)):.2f} (honest: 1)")  # fmt: skip


if __name__ == "__main__":
    main()
