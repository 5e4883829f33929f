"""Which fits run a compiled step: the caller's choice by the recording's length.

A light module (no scipy, no numba) so that :mod:`rangekit.detect.matched` can decorate
its detector without importing :mod:`rangekit.detect.pathfit` (whose FFTs import
``scipy.fft``, ~0.18 s) before a one-way fit needs it.
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
from collections.abc import Iterator

from rangekit.detect._kernels import NUMBA_MIN_SAMPLES, long_recording

__all__ = ["KERNEL_MIN_SAMPLES", "compiled_step", "kernel_by_length"]

#: Whether the fits in this context run the compiled step (:func:`compiled_step`).
_KERNEL: contextvars.ContextVar[bool] = contextvars.ContextVar("pathfit_kernel", default=False)
#: A recording this long or longer has its fits run the compiled step
#: (:func:`kernel_by_length`): the detectors' rule (``_kernels.NUMBA_MIN_SAMPLES``), so a
#: short file pays neither numba's import nor its cache load, and a recording gives the
#: same numbers whatever the process imported before (the step agrees with the numpy
#: reference to rounding only; before, it ran whenever numba happened to be imported).
KERNEL_MIN_SAMPLES = NUMBA_MIN_SAMPLES


@contextlib.contextmanager
def compiled_step(on: bool) -> Iterator[None]:
    """Within the block, the fits run the compiled step (``on``) or the numpy one.

    Examples
    --------
    >>> with compiled_step(True):
    ...     _KERNEL.get()
    True
    >>> _KERNEL.get()
    False
    """
    token = _KERNEL.set(bool(on))
    try:
        yield
    finally:
        _KERNEL.reset(token)


def kernel_by_length(fn):
    """Decorate a function of a recording ``x`` (its first argument): its fits run the
    compiled step when ``len(x) >= KERNEL_MIN_SAMPLES`` or ``x`` is a block of a recording
    that long (:func:`rangekit.detect._kernels.recording_samples`; :func:`compiled_step`)."""

    @functools.wraps(fn)
    def wrapper(x, *args, **kwargs):
        with compiled_step(len(x) >= KERNEL_MIN_SAMPLES or long_recording()):
            return fn(x, *args, **kwargs)

    return wrapper
