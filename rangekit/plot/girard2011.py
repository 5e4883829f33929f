"""Figures of Girard et al. 2011 §4: particle clouds (Figs 11-13), paths (Fig. 10), errors.

Each ``draw_*`` function draws on given axes and returns the artists; each ``figure_*``
function makes a figure with :func:`rangekit.plot.new_figure`, draws it and writes it with
:func:`rangekit.plot.save_figure` (format from the path's suffix), returning the path.
Inputs are plain arrays and :class:`rangekit.localize.particle.Cloud`-like objects
(attributes ``after_steps``, ``xy_m``, ``weight``).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rangekit.errors import InvalidParameterError
from rangekit.plot import new_figure, save_figure

__all__ = [
    "draw_cloud",
    "draw_walls",
    "figure_clouds",
    "figure_errors",
    "figure_paths",
]


def _xy(name: str, a: Any) -> np.ndarray:
    p = np.asarray(a, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        raise InvalidParameterError(f"{name} must have shape (n, 2), got {p.shape}")
    return p


def draw_walls(ax, walls_m: Any):
    """Draw wall segments ``(n, 4)`` rows ``(x0, y0, x1, y1)`` (m); return the artists."""
    w = np.asarray(walls_m, dtype=float).reshape(-1, 4)
    lines = []
    for x0, y0, x1, y1 in w:
        lines += ax.plot([x0, x1], [y0, y1], "k-", lw=2.0, solid_capstyle="butt")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    return lines


def draw_cloud(ax, cloud, *, truth_m: Any, estimate_m: Any, start_m: Any = None):
    """One panel of Figs 11-13: the cloud after ``cloud.after_steps`` steps.

    Draws the true path up to that step (grey) with the current true position (the big
    square of the paper's figures), the estimated path (eq. (2), blue) and the current
    estimate, the particles coloured by weight, and a circle around the estimate through
    the farthest particle (Fig. 11's "area covered by the cloud").

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    cloud : Cloud
        ``after_steps`` (k >= 1), ``xy_m`` ``(n, 2)``, ``weight`` ``(n,)``.
    truth_m, estimate_m : array_like, shape (n_steps, 2)
        True and estimated position after each step, m (n_steps >= k).
    start_m : array_like, shape (2,), optional
        Start position, prepended to both paths.

    Returns
    -------
    list
        The artists drawn.
    """
    truth, est, k, xy = _check_cloud(cloud, truth_m, estimate_m)
    w = np.asarray(cloud.weight, dtype=float).reshape(-1)
    head = [] if start_m is None else [np.asarray(start_m, dtype=float).reshape(1, 2)]
    tp = np.concatenate([*head, truth[:k]])
    ep = np.concatenate([*head, est[:k]])
    art = []
    art += ax.plot(tp[:, 0], tp[:, 1], "-", color="0.6", lw=1.0, label="true path")
    art += ax.plot(ep[:, 0], ep[:, 1], "b-", lw=0.8, alpha=0.7, label="estimated path")
    order = np.argsort(w)
    art.append(
        ax.scatter(xy[order, 0], xy[order, 1], c=w[order], s=4, cmap="viridis",
                   label=f"particles ({xy.shape[0]})", zorder=3)
    )  # fmt: skip
    art += ax.plot(*truth[k - 1], "s", ms=10, mfc="none", mec="r", mew=1.5,
                   label="true position", zorder=4)  # fmt: skip
    art += ax.plot(*est[k - 1], "x", ms=8, color="b", mew=1.5, label="estimate", zorder=4)
    if xy.shape[0]:
        r = float(np.max(np.hypot(*(xy - est[k - 1]).T)))
        circle = _circle(est[k - 1], max(r, 1e-3))
        art += ax.plot(circle[:, 0], circle[:, 1], "m--", lw=0.8, label="cloud extent")
    err = float(np.hypot(*(est[k - 1] - truth[k - 1])))
    ax.set_title(f"after {k} steps: error {err:.2f} m", fontsize=9)
    return art


def _check_cloud(cloud, truth_m: Any, estimate_m: Any):
    truth = _xy("truth_m", truth_m)
    est = _xy("estimate_m", estimate_m)
    k = int(cloud.after_steps)
    if not 1 <= k <= min(len(truth), len(est)):
        raise InvalidParameterError(
            f"cloud.after_steps={k} must be in 1..{min(len(truth), len(est))} (the steps given)"
        )
    return truth, est, k, _xy("cloud.xy_m", cloud.xy_m)


def _circle(c: np.ndarray, r: float) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * np.pi, 97)
    return np.column_stack([c[0] + r * np.cos(a), c[1] + r * np.sin(a)])


def figure_clouds(
    path: str | os.PathLike,
    *,
    walls_m: Any,
    truth_m: Any,
    estimate_m: Any,
    clouds: Sequence[Any],
    start_m: Any = None,
    title: str = "",
) -> Path:
    """Clouds after given steps over the floor plan, one panel each, like Figs 11-13.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; ``.png``, ``.pdf`` or ``.svg``.
    walls_m : array_like, shape (n, 4)
        Wall segments ``(x0, y0, x1, y1)``, m.
    truth_m, estimate_m : array_like, shape (n_steps, 2)
        True and estimated positions after each step, m.
    clouds : sequence of Cloud
        The clouds to draw (at least one), in panel order.
    start_m : array_like, shape (2,), optional
        Start position.
    title : str, optional
        Figure title.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    rangekit.errors.InvalidParameterError
        No cloud, a cloud after a step beyond the paths, or an unknown file suffix.
    rangekit.errors.InputFileError
        The folder does not exist or is not writable.
    """
    clouds = list(clouds)
    if not clouds:
        raise InvalidParameterError("clouds is empty: nothing to draw")
    for cloud in clouds:  # before a figure exists
        _check_cloud(cloud, truth_m, estimate_m)
    fig, ax = new_figure(1, len(clouds), size=(4.6 * len(clouds), 4.4))
    for a, cloud in zip(ax[0], clouds, strict=True):
        draw_walls(a, walls_m)
        draw_cloud(a, cloud, truth_m=truth_m, estimate_m=estimate_m, start_m=start_m)
    ax[0, -1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)


def figure_paths(
    path: str | os.PathLike,
    *,
    walls_m: Any,
    paths: dict[str, Any],
    start_m: Any = None,
    title: str = "",
) -> Path:
    """Named ``(n, 2)`` paths over the floor plan (like Fig. 10 with the estimates added).

    A path named ``"true"`` is drawn in black with square markers (the floor markers);
    the others as lines with dots, in order. ``start_m`` is prepended to every path and
    marked. Returns the path written; raises as :func:`figure_clouds`.
    """
    head = [] if start_m is None else [np.asarray(start_m, dtype=float).reshape(1, 2)]
    xy = {label: np.concatenate([*head, _xy(f"paths[{label!r}]", p)]) for label, p in paths.items()}
    fig, ax = new_figure(1, 1, size=(7.5, 6.2))
    a = ax[0, 0]
    draw_walls(a, walls_m)
    for label, p in xy.items():
        if label == "true":
            a.plot(p[:, 0], p[:, 1], "ks-", ms=4, mfc="none", lw=0.8, label=label, zorder=3)
        else:
            a.plot(p[:, 0], p[:, 1], ".-", ms=3, lw=0.9, alpha=0.8, label=label)
    if head:
        a.plot(*head[0][0], "r*", ms=12, label="start", zorder=4)
    a.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    if title:
        a.set_title(title, fontsize=10)
    return save_figure(fig, path)


def figure_errors(
    path: str | os.PathLike,
    *,
    errors_m: dict[str, Any],
    styles: dict[str, str] | None = None,
    title: str = "",
) -> Path:
    """Distance from the true position after each step, one curve per name.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; ``.png``, ``.pdf`` or ``.svg``.
    errors_m : dict of str to array_like, shape (n_steps,)
        Error after steps 1..n_steps, m.
    styles : dict of str to str, optional
        matplotlib format strings by name (default ``"-"``).
    title : str, optional

    Returns
    -------
    pathlib.Path

    Raises
    ------
    rangekit.errors.InvalidParameterError
        No curve, or an unknown file suffix.
    rangekit.errors.InputFileError
        The folder does not exist or is not writable.
    """
    if not errors_m:
        raise InvalidParameterError("errors_m is empty: nothing to draw")
    fig, ax = new_figure(1, 1, size=(8.5, 4.5))
    a = ax[0, 0]
    for label, e in errors_m.items():
        e = np.asarray(e, dtype=float).reshape(-1)
        style = (styles or {}).get(label, "-")
        a.plot(np.arange(1, e.size + 1), e, style, lw=1.2, label=label)
    a.set_xlabel("step")
    a.set_ylabel("distance from the true position (m)")
    a.set_ylim(bottom=0.0)
    a.grid(alpha=0.3)
    a.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    if title:
        a.set_title(title, fontsize=10)
    return save_figure(fig, path)
