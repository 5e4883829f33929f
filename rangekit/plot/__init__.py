"""Figures (matplotlib, non-interactive Agg backend); the only package that imports matplotlib.

Every plotting function takes plain arrays or rangekit results and a path; the format
(PNG, PDF, SVG) follows the path's suffix. Import cost stays out of ``import rangekit``:
matplotlib is imported when a figure is first made.
"""

from __future__ import annotations

import os
from pathlib import Path

from rangekit.errors import InputFileError, InvalidParameterError

__all__ = ["FORMATS", "new_figure", "save_figure"]

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


def save_figure(fig, path: str | os.PathLike) -> Path:
    """Write ``fig`` to ``path`` (format from the suffix), close it, return the path.

    Raises
    ------
    InvalidParameterError
        The suffix is not one of :data:`FORMATS`.
    InputFileError
        The folder does not exist or is not writable.
    """
    path = Path(path)
    if path.suffix.lower() not in FORMATS:
        raise InvalidParameterError(
            f"plot file {str(path)!r}: unknown format {path.suffix!r} (use {', '.join(FORMATS)})"
        )
    if not path.parent.is_dir():
        raise InputFileError(f"cannot write {str(path)!r}: folder does not exist")
    try:
        fig.savefig(path, dpi=110, bbox_inches="tight")
    except PermissionError:
        raise InputFileError(f"cannot write {str(path)!r}: permission denied") from None
    finally:
        _pyplot().close(fig)
    return path
