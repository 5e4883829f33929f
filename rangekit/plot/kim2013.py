"""Figures of Kim & Kim 2013 §V (Figs 8 and 10): pose errors over time and the paths.

The functions take the per-trial dicts of :mod:`rangekit.experiments.kim2013` (its
``_trial``): ``"sim"`` (a :class:`rangekit.sim.kim2013.KimRun`), ``"duhl"`` and
``"ranges"`` (each with a ``"track"``, a :class:`rangekit.localize.duhl.DUHLTrack`) and
``"uhl2"`` (with a ``"base"``, a :class:`rangekit.localize.duhl.UHLLastTwo`). They draw
with :func:`rangekit.plot.new_figure` and write with :func:`rangekit.plot.save_figure`,
so the format follows the path's suffix.
"""

from __future__ import annotations

import math
import os

import numpy as np

from rangekit.plot import new_figure, save_figure

__all__ = ["plot_errors", "plot_paths"]

#: ``obs_status`` of a distance row whose observation DUHL applied.
_OBS_USED = 0


def _errors(sim, t_s: np.ndarray, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times, ``E_p`` (m) and ``E_phi`` (deg, in [0, 180]) of the finite rows of ``pose``."""
    from rangekit.experiments.kim2013 import pose_errors

    t_s = np.asarray(t_s, dtype=float)
    pose = np.asarray(pose, dtype=float).reshape(-1, 3)
    ok = np.all(np.isfinite(pose), axis=1) & np.isfinite(t_s)
    t_s, pose = t_s[ok], pose[ok]
    k = np.clip(np.searchsorted(sim.t_s, t_s), 0, len(sim.t_s) - 1)
    ep, ephi, _ = pose_errors(pose, np.asarray(sim.true_pose)[k])
    return t_s, ep, np.degrees(ephi)


def plot_errors(trial: dict, path: str | os.PathLike, *, title: str = "") -> None:
    """Pose errors over time and the Tx ids heard, like Kim & Kim 2013 Figs 8 and 10.

    Three stacked panels sharing the time axis: the position error ``E_p(t)`` (eq (33)),
    the heading error ``E_phi(t)`` (eq (34), wrapped to [0°, 180°]) of DUHL and of the
    tightly coupled EKF (``"ranges"``, both at the odometry times) and of UHL using the
    last 2 Txs (at its own times); then the Tx id of each distance row, filled where
    DUHL applied an observation at that row and hollow where it did not.

    Parameters
    ----------
    trial : dict
        One trial of :mod:`rangekit.experiments.kim2013`: keys ``"sim"``, ``"duhl"``,
        ``"ranges"`` (optional) and ``"uhl2"``.
    path : str or os.PathLike
        Output file; ``.png``, ``.pdf`` or ``.svg``.
    title : str, optional
        Figure title.

    Raises
    ------
    rangekit.errors.InvalidParameterError
        Unknown file suffix.
    rangekit.errors.InputFileError
        The folder does not exist or is not writable.
    """
    sim = trial["sim"]
    fig, ax = new_figure(3, 1, size=(8.0, 7.5))
    a_p, a_phi, a_tx = ax[0, 0], ax[1, 0], ax[2, 0]
    for a in (a_phi, a_tx):
        a.sharex(a_p)

    curves = [("duhl", "DUHL", "b-"), ("ranges", "tightly coupled EKF", "g--")]
    for key, label, style in curves:
        if key not in trial:
            continue
        trk = trial[key]["track"]
        t, ep, ephi = _errors(sim, trk.t_s, trk.pose)
        a_p.plot(t, ep, style, lw=1.0, label=label)
        a_phi.plot(t, ephi, style, lw=1.0, label=label)
    base = trial["uhl2"]["base"]
    if len(base.t_s):
        t, ep, ephi = _errors(sim, base.t_s, base.pose)
        style = {"color": "r", "marker": ".", "ls": "none", "ms": 3, "alpha": 0.6}
        a_p.plot(t, ep, label="UHL using the last 2 Txs", **style)
        a_phi.plot(t, ephi, label="UHL using the last 2 Txs", **style)
    a_p.set_ylabel("E_p (m)")
    a_p.set_ylim(bottom=0.0)
    a_phi.set_ylabel("E_phi (deg)")
    a_phi.set_ylim(0.0, min(180.0, a_phi.get_ylim()[1]))

    t_row = np.asarray(sim.distance_t_s, dtype=float)
    tx = np.asarray(sim.distance_tx)
    used = np.zeros(len(t_row), dtype=bool)
    trk = trial["duhl"]["track"]
    if len(trk.obs_status) == len(t_row):
        used = np.asarray(trk.obs_status) == _OBS_USED
    a_tx.scatter(t_row[used], tx[used], s=10, c="b", label="DUHL observation used")
    a_tx.scatter(
        t_row[~used], tx[~used], s=10, facecolors="none", edgecolors="0.4", label="not used"
    )
    ids = np.asarray(sim.beacons.ids)
    a_tx.set_yticks(ids)
    if len(ids):
        a_tx.set_ylim(float(ids.min()) - 0.5, float(ids.max()) + 0.5)
    a_tx.set_ylabel("Tx id")
    a_tx.set_xlabel("time (s)")
    for a in (a_p, a_tx):
        a.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    for a in (a_p, a_phi):
        a.tick_params(labelbottom=False)
    if title:
        fig.suptitle(title)
        fig.subplots_adjust(top=0.93)
    save_figure(fig, path)


def plot_paths(trials: dict[int, dict], path: str | os.PathLike) -> None:
    """Beacon layout, true path, DUHL path and UHL-last-2 poses, one panel per trajectory.

    Parameters
    ----------
    trials : dict of int to dict
        Trajectory number -> one trial of :mod:`rangekit.experiments.kim2013` (keys
        ``"sim"``, ``"duhl"``, ``"uhl2"``); panels in ascending trajectory order, two per
        row.
    path : str or os.PathLike
        Output file; ``.png``, ``.pdf`` or ``.svg``.

    Raises
    ------
    rangekit.errors.InvalidParameterError
        Unknown file suffix.
    rangekit.errors.InputFileError
        The folder does not exist or is not writable.
    """
    keys = sorted(trials)
    ncols = 2 if len(keys) > 1 else 1
    nrows = max(1, math.ceil(len(keys) / ncols))
    fig, ax = new_figure(nrows, ncols, size=(5.5 * ncols, 5.0 * nrows))
    for i, traj in enumerate(keys):
        a = ax[i // ncols, i % ncols]
        trial = trials[traj]
        sim = trial["sim"]
        xyz = np.asarray(sim.beacons.xyz_m, dtype=float)
        a.plot(xyz[:, 0], xyz[:, 1], "k^", ms=7, label="Tx")
        for tx_id, (x, y) in zip(np.asarray(sim.beacons.ids), xyz[:, :2], strict=True):
            a.annotate(str(int(tx_id)), (x, y), textcoords="offset points", xytext=(4, 4))
        truth = np.asarray(sim.true_pose, dtype=float)
        a.plot(truth[:, 0], truth[:, 1], "k-", lw=1.2, label="true")
        pose = np.asarray(trial["duhl"]["track"].pose, dtype=float)
        a.plot(pose[:, 0], pose[:, 1], "b--", lw=1.0, label="DUHL")
        base = np.asarray(trial["uhl2"]["base"].pose, dtype=float).reshape(-1, 3)
        a.plot(base[:, 0], base[:, 1], "r.", ms=2, alpha=0.35, label="UHL using the last 2 Txs")
        a.set_title(f"trajectory {traj} ({sim.nominal_speed_mps:.2f} m/s)")
        a.set_xlabel("x (m)")
        a.set_ylabel("y (m)")
        a.set_aspect("equal", adjustable="datalim")
        a.legend(fontsize=7, loc="best")
    for j in range(len(keys), nrows * ncols):
        ax[j // ncols, j % ncols].set_visible(False)
    save_figure(fig, path)
