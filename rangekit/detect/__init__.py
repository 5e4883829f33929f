"""Arrival detection: float sample indices with per-arrival quality.

Detectors are pure functions ``(x, *, fs, beep, ...) -> Arrivals``. :func:`detect`
selects one by name.
"""

from __future__ import annotations

import numpy as np

from rangekit.detect.changepoint import detect_changepoint
from rangekit.detect.xcorr import detect_xcorr
from rangekit.errors import InvalidParameterError
from rangekit.signals.beep import Beep
from rangekit.types import Arrivals

__all__ = ["DETECTORS", "detect", "detect_changepoint", "detect_xcorr"]

#: Detector names accepted by :func:`detect` and ``--detector``.
DETECTORS = ("changepoint", "xcorr")


def detect(
    x: np.ndarray, *, fs: float, beep: Beep | None = None, detector: str = "changepoint", **kw
) -> Arrivals:
    """Detect beep arrivals in one channel with the named detector.

    Examples
    --------
    >>> import numpy as np
    >>> len(detect(np.zeros(44100), fs=44100.0))
    0
    """
    if detector == "changepoint":
        return detect_changepoint(x, fs=fs, beep=beep, **kw)
    if detector == "xcorr":
        return detect_xcorr(x, fs=fs, beep=beep, **kw)
    raise InvalidParameterError(f"detector={detector!r} must be one of {', '.join(DETECTORS)}")
