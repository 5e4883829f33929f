"""Figures like Jiang 2018 Figs 9–13: trajectories, errors over time, sqrt(det P), CDFs."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from rangekit.plot import new_figure, save_figure

__all__ = ["figure_errors", "figure_summary", "figure_trajectories", "write_figures"]


def figure_trajectories(path: str | os.PathLike, run, track) -> Path:
    """True and estimated trajectories of both targets and the robot (like Fig. 9a)."""
    fig, ax = new_figure(size=(8.0, 4.8))
    ax = ax[0, 0]
    t1, t2 = run.targets_m[:, 0], run.targets_m[:, 1]
    ax.plot(t1[:, 0], t1[:, 1], "k-", lw=1, label="target 1 (truth)")
    ax.plot(t2[:, 0], t2[:, 1], "b-", lw=1, label="target 2 (truth)")
    ax.plot(run.robot_m[:, 0], run.robot_m[:, 1], color="0.6", lw=1, label="robot")
    p1, p2 = track.position(1), track.position(2)
    ax.plot(p1[:, 0], p1[:, 1], "ko", ms=3, label="target 1 (filter)")
    ax.plot(p2[:, 0], p2[:, 1], "bs", ms=3, label="target 2 (filter)")
    if track.x_smooth is not None:
        s2 = track.position(2, smoothed=True)
        ax.plot(s2[:, 0], s2[:, 1], "r^", ms=3, label="target 2 (smoother)")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7, loc="best")
    return save_figure(fig, path)


def figure_errors(path: str | os.PathLike, run, track) -> Path:
    """Errors of both targets over time and sqrt(det P_t2) (like Figs 9b–c)."""
    fig, ax = new_figure(2, 1, size=(7.0, 6.0))
    truth = run.update_targets_m[track.n_skipped :]
    for target, style in ((1, "k-"), (2, "b-")):
        e = np.hypot(*(track.position(target) - truth[:, target - 1]).T)
        ax[0, 0].plot(track.t_s, e, style, label=f"target {target} (filter)")
    if track.x_smooth is not None:
        e = np.hypot(*(track.position(2, smoothed=True) - truth[:, 1]).T)
        ax[0, 0].plot(track.t_s, e, "r--", label="target 2 (smoother)")
    ax[0, 0].set_ylabel("error (m)")
    ax[0, 0].legend(fontsize=8)
    ax[1, 0].plot(track.t_s, track.sqrt_det_p(2), "b-")
    ax[1, 0].set_ylabel("sqrt(det P_t2) (m²)")
    ax[1, 0].set_xlabel("time (s)")
    return save_figure(fig, path)


def figure_summary(path: str | os.PathLike, results: dict) -> Path:
    """CDFs of the per-trial steady-state errors of target 2 per condition (Figs 12–13)."""
    fig, ax = new_figure(1, 2, size=(10.0, 4.0))
    for label, rs in results.items():
        for col, kind in enumerate(("filter", "smoother")):
            e = np.sort([r.steady[(2, kind)] for r in rs])
            ax[0, col].step(e, np.arange(1, e.size + 1) / e.size, where="post", label=label)
    for col, kind in enumerate(("filter", "smoother")):
        ax[0, col].set_title(f"target 2, {kind}")
        ax[0, col].set_xlabel("steady-state error (m)")
        ax[0, col].set_ylabel("CDF over trials")
        ax[0, col].legend(fontsize=7)
    return save_figure(fig, path)


def write_figures(plots_dir: Path, results: dict) -> list[Path]:
    """Write the experiment's figures into ``plots_dir`` (created if missing)."""
    plots_dir.mkdir(exist_ok=True)
    first_label = next(iter(results))
    r0 = results[first_label][0]
    out = [
        figure_trajectories(plots_dir / "jiang2018_trajectories.png", r0.run, r0.track),
        figure_errors(plots_dir / "jiang2018_errors.png", r0.run, r0.track),
        figure_summary(plots_dir / "jiang2018_cdf.png", results),
    ]
    atrium = [k for k in results if k.startswith("atrium")]
    if atrium:
        ra = results[atrium[0]][0]
        out.append(figure_trajectories(plots_dir / "jiang2018_atrium.png", ra.run, ra.track))
    return out
