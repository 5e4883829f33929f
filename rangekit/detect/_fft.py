"""scipy's pocketfft module, looked up once, on first use.

:mod:`rangekit.detect.matched` (the one-way windows' workspace) and
:mod:`rangekit.detect.pathfit` (the fit's small transforms) call pocketfft directly, as
``scipy.fft.rfft``/``irfft``/``ifft`` do, with their outputs given (the same numbers,
without the per-call argument handling). Importing it imports ``scipy.fft`` (~0.18 s), so
it is looked up only when a transform is needed.
"""

from __future__ import annotations

__all__ = ["pocketfft"]

_MODULE: object = False  # not looked up yet


def pocketfft():
    """``scipy.fft._pocketfft.pypocketfft``, or None if this scipy lays it out otherwise
    (then the callers use the public ``scipy.fft`` calls)."""
    global _MODULE
    if _MODULE is False:
        try:
            from scipy.fft._pocketfft import pypocketfft as mod
        except ImportError:  # pragma: no cover - another scipy layout: the public calls
            mod = None
        _MODULE = mod
    return _MODULE
