"""Shared input checks used at every public boundary.

Each check raises :class:`rangekit.errors.InvalidParameterError` with a message that
names the parameter and shows its value.
"""

from __future__ import annotations

import math

import numpy as np

from rangekit.errors import InvalidParameterError


def positive(name: str, value: float, *, allow_zero: bool = False) -> float:
    """Return ``value`` as float, or raise if it is not finite and > 0 (>= 0)."""
    if isinstance(value, (bool, str)):
        raise InvalidParameterError(f"{name}={value!r} must be a number", param=name)
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InvalidParameterError(f"{name}={value!r} must be a number", param=name) from None
    ok = math.isfinite(v) and (v >= 0.0 if allow_zero else v > 0.0)
    if not ok:
        bound = ">= 0" if allow_zero else "> 0"
        raise InvalidParameterError(f"{name}={value!r} must be finite and {bound}", param=name)
    return v


def in_range(name: str, value: float, lo: float, hi: float) -> float:
    """Return ``value`` as float, or raise if it is not within [lo, hi]."""
    if isinstance(value, (bool, str)):
        raise InvalidParameterError(f"{name}={value!r} must be a number", param=name)
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InvalidParameterError(f"{name}={value!r} must be a number", param=name) from None
    if not (math.isfinite(v) and lo <= v <= hi):
        raise InvalidParameterError(f"{name}={value!r} must be within [{lo}, {hi}]", param=name)
    return v


def positive_int(name: str, value: int, *, minimum: int = 1) -> int:
    """Return ``value`` as int, or raise if it is not an integer >= ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise InvalidParameterError(f"{name}={value!r} must be an integer", param=name)
    if value < minimum:
        raise InvalidParameterError(f"{name}={value!r} must be >= {minimum}", param=name)
    return int(value)


def sample_rate(fs: float) -> float:
    """Validate a sample rate in Hz (finite, >= 1 kHz, <= 10 MHz)."""
    v = positive("fs", fs)
    if not 1000.0 <= v <= 10e6:
        raise InvalidParameterError(f"fs={fs!r} Hz must be within [1000, 1e7] Hz")
    return v


#: Largest magnitude of a signal sample accepted by :func:`signal_1d`: beyond it the
#: energies (squares, sums of squares) overflow float64.
MAX_SAMPLE_ABS = 1e100


def signal_1d(name: str, x, *, max_abs: float | None = None) -> np.ndarray:
    """Return ``x`` as a contiguous 1-D float64 array of finite values (InvalidParameterError
    otherwise, never a bare ValueError/TypeError: strings, complex values and ragged lists
    are refused too). With ``max_abs`` (signals: :data:`MAX_SAMPLE_ABS`) values of larger
    magnitude are refused as well."""
    import warnings

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", np.exceptions.ComplexWarning)
            a = np.ascontiguousarray(x, dtype=np.float64)
    except (TypeError, ValueError, OverflowError, np.exceptions.ComplexWarning) as e:
        raise InvalidParameterError(f"{name} must be an array of real numbers ({e})") from None
    if a.ndim != 1:
        raise InvalidParameterError(f"{name} must be 1-D, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InvalidParameterError(f"{name} contains NaN or infinite values")
    if max_abs is not None and a.size and float(np.max(np.abs(a))) > max_abs:
        raise InvalidParameterError(
            f"{name} holds values beyond +-{max_abs:g} (their energy overflows)"
        )
    return a
