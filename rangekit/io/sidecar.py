"""JSON sidecars (ground truth written by the simulator) and atomic text output."""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np

__all__ = ["read_json", "write_json", "write_text_atomic"]


def _default(o: Any):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"cannot serialise {type(o).__name__} to JSON")


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` so that it appears complete or not at all.

    :func:`rangekit.io.guard.atomic_output`: an exclusive temporary file in the same
    folder, renamed at the end, removed on failure; a link, a directory or a device at
    ``path`` is refused (InvalidParameterError), an unwritable one is InputFileError.
    """
    from rangekit.io.guard import atomic_output, printable

    with atomic_output(path, text=True) as f:
        f.write(printable(text))


def write_json(path: str | os.PathLike, obj: Any) -> None:
    """Write ``obj`` as indented JSON (numpy arrays become lists), atomically."""
    write_text_atomic(path, json.dumps(obj, indent=2, default=_default) + "\n")


def read_json(path: str | os.PathLike) -> Any:
    """Read a JSON input file with rangekit's limits (:func:`rangekit.io.guard.read_json_file`).

    Raises InputFileError naming the path: missing, not a regular file, larger than
    :data:`~rangekit.io.guard.MAX_JSON_BYTES`, not UTF-8, not JSON, nested too deeply, a
    number too long or not finite.
    """
    from rangekit.io.guard import read_json_file

    return read_json_file(path)
