"""JSON sidecars (ground truth written by the simulator) and atomic text output."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from rangekit.errors import InputFileError

__all__ = ["read_json", "write_json", "write_text_atomic"]


def _default(o: Any):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"cannot serialise {type(o).__name__} to JSON")


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` so that it appears complete or not at all."""
    p = Path(path)
    if not p.parent.exists():
        raise InputFileError(f"cannot write '{p}': folder '{p.parent}' does not exist")
    tmp = p.with_name(f".{p.name}.part")
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, p)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise InputFileError(f"cannot write '{p}': {e.strerror or e}") from e


def write_json(path: str | os.PathLike, obj: Any) -> None:
    """Write ``obj`` as indented JSON (numpy arrays become lists), atomically."""
    write_text_atomic(path, json.dumps(obj, indent=2, default=_default) + "\n")


def read_json(path: str | os.PathLike) -> Any:
    """Read a JSON file, raising InputFileError with the path on failure."""
    p = Path(path)
    try:
        return json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputFileError(f"cannot open '{p}': no such file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise InputFileError(f"cannot read '{p}' as JSON: {e}") from e
