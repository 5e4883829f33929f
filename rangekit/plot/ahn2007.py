"""Figures of Ahn & Yu §4 (Fig. 1-4): robot dead reckoning and the l_max pedestrian filter.

Each ``draw_*`` function draws on given axes and returns the artists; each ``figure_*``
function makes a figure with :func:`rangekit.plot.new_figure`, draws it and writes it with
:func:`rangekit.plot.save_figure`, returning the path.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from rangekit.plot import new_figure, save_figure

__all__ = [
    "draw_errors",
    "draw_paths",
    "figure_bias",
    "figure_pedestrian",
    "figure_pedestrian_errors",
    "figure_robot",
]


def draw_paths(ax, paths: dict[str, np.ndarray], *, styles: dict[str, str] | None = None):
    """Plot named (n, 2) paths on ``ax``; return the line artists."""
    styles = styles or {}
    lines = []
    for label, p in paths.items():
        p = np.asarray(p, dtype=float)
        lines += ax.plot(p[:, 0], p[:, 1], styles.get(label, "-"), label=label, lw=1.2, ms=3)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=8)
    return lines


def draw_errors(ax, t, errors: dict[str, np.ndarray], *, xlabel: str = "step"):
    """Plot named error curves against ``t`` on ``ax``; return the line artists."""
    lines = []
    for label, e in errors.items():
        lines += ax.plot(t, e, label=label, lw=1.0)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("error (m)")
    ax.legend(fontsize=8)
    return lines


def figure_robot(
    path: str | os.PathLike,
    *,
    t_s,
    truth_m,
    integrated_m,
    estimated_m,
    velocity_mps,
    estimated_velocity_mps,
) -> Path:
    """Fig. 1: paths (accelerometer integration, EKF), velocities and speed vs truth."""
    fig, ax = new_figure(2, 2, size=(10.0, 8.0))
    draw_paths(
        ax[0, 0],
        {"true": truth_m, "integrated accelerometer": integrated_m},
        styles={"integrated accelerometer": "--"},
    )
    ax[0, 0].set_title("true and propagated trajectory")
    draw_paths(
        ax[0, 1],
        {"true": truth_m, "EKF (bias states)": estimated_m},
        styles={"EKF (bias states)": "--"},
    )
    ax[0, 1].set_title("true and estimated trajectory")
    v, ve = np.asarray(velocity_mps), np.asarray(estimated_velocity_mps)
    for i, name in enumerate(("v_x", "v_y")):
        ax[1, 0].plot(t_s, v[:, i], label=f"true {name}")
        ax[1, 0].plot(t_s, ve[:, i], "--", label=f"estimated {name}")
    ax[1, 0].set_xlabel("time (s)")
    ax[1, 0].set_ylabel("velocity (m/s)")
    ax[1, 0].legend(fontsize=8)
    ax[1, 1].plot(t_s, np.hypot(v[:, 0], v[:, 1]), label="true speed")
    ax[1, 1].plot(t_s, np.hypot(ve[:, 0], ve[:, 1]), "--", label="estimated speed")
    ax[1, 1].set_xlabel("time (s)")
    ax[1, 1].set_ylabel("speed (m/s)")
    ax[1, 1].legend(fontsize=8)
    return save_figure(fig, path)


def figure_bias(path: str | os.PathLike, *, t_s, bias_mps2, estimated_bias_mps2) -> Path:
    """Fig. 2: simulated and estimated accelerometer bias δa_x, δa_y (eq (4)-(5))."""
    fig, ax = new_figure(2, 1, size=(7.0, 6.0))
    b, be = np.asarray(bias_mps2), np.asarray(estimated_bias_mps2)
    for i, name in enumerate(("δa_x", "δa_y")):
        a = ax[i, 0]
        a.plot(t_s, b[:, i], label=f"true {name}")
        a.plot(t_s, be[:, i], "--", label=f"estimated {name}")
        a.set_xlabel("time (s)")
        a.set_ylabel(f"{name} (m/s²)")
        a.legend(fontsize=8)
    return save_figure(fig, path)


def figure_pedestrian(path: str | os.PathLike, *, truth_m, measured_m, estimated_m) -> Path:
    """Fig. 3: true pedestrian path, wireless fixes and the l_max estimate."""
    fig, ax = new_figure(1, 1, size=(7.0, 6.0))
    draw_paths(
        ax[0, 0],
        {"true": truth_m, "measured (WSN)": measured_m, "l_max filter": estimated_m},
        styles={"measured (WSN)": ":.", "l_max filter": "--"},
    )
    return save_figure(fig, path)


def figure_pedestrian_errors(
    path: str | os.PathLike, *, measured_error_m, estimated_error_m
) -> Path:
    """Fig. 4: position error of the fixes and of the l_max estimate at each step."""
    fig, ax = new_figure(1, 1, size=(7.0, 4.0))
    n = len(measured_error_m)
    draw_errors(
        ax[0, 0],
        np.arange(n),
        {"measured (WSN)": measured_error_m, "l_max filter": estimated_error_m},
    )
    return save_figure(fig, path)
