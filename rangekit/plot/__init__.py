"""Figures (matplotlib, non-interactive Agg backend); the only package that imports matplotlib.

Every plotting function takes plain arrays or rangekit results and a path; the format
(PNG, PDF, SVG) follows the path's suffix. Import cost stays out of ``import rangekit``:
matplotlib is imported when a figure is first made.
"""

from __future__ import annotations

import os
from pathlib import Path

from rangekit.errors import InvalidParameterError

__all__ = ["FORMATS", "check_figure_path", "new_figure", "save_figure"]

#: Output formats chosen by the file suffix.
FORMATS = (".png", ".pdf", ".svg")


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def new_figure(nrows: int = 1, ncols: int = 1, *, size: tuple[float, float] = (6.4, 4.8)):
    """A new (figure, axes) pair on the Agg backend."""
    return _pyplot().subplots(nrows, ncols, figsize=size, squeeze=False)


def check_figure_path(path: str | os.PathLike) -> Path:
    """``path`` as a Path if a figure can be written there (checked before any work).

    Raises
    ------
    InvalidParameterError
        The suffix is not one of :data:`FORMATS`.
    InputFileError
        The folder does not exist.
    InvalidParameterError
        ``path`` is a link, a directory or a device (:func:`rangekit.io.guard.check_output`).
    """
    path = Path(path)
    if path.suffix.lower() not in FORMATS:
        suffix = repr(path.suffix) if path.suffix else "(no suffix)"
        raise InvalidParameterError(
            f"plot file {str(path)!r}: unknown format {suffix} (use {', '.join(FORMATS)})"
        )
    from rangekit.io.guard import check_output

    return check_output(path)


def save_figure(fig, path: str | os.PathLike) -> Path:
    """Write ``fig`` to ``path`` (format from the suffix), close it, return the path.

    The file appears complete or not at all: the figure goes to a temporary file in the
    same folder, renamed over ``path`` at the end (an existing file stays untouched if
    writing fails).

    Raises
    ------
    InvalidParameterError
        The suffix is not one of :data:`FORMATS`.
    InputFileError
        The folder does not exist or is not writable.
    """
    from rangekit.io.guard import atomic_output

    try:
        path = check_figure_path(path)
        with atomic_output(path) as f:
            fig.savefig(f, format=path.suffix[1:].lower(), dpi=110, bbox_inches="tight")
    finally:
        _pyplot().close(fig)
    return path
