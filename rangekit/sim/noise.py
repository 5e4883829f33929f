"""Noise generators for simulated recordings.

Every generator draws from its own ``rng`` (anything :func:`numpy.random.default_rng`
accepts: None, an int seed, a SeedSequence, a BitGenerator or a Generator), never from
NumPy's global state.

Examples
--------
>>> x = make_noise(4096, kind="pink", rng=1)
>>> x.shape, x.dtype.name
((4096,), 'float64')
>>> bool(np.array_equal(x, pink_noise(4096, rng=1)))
True
"""

from __future__ import annotations

import numpy as np

from rangekit._validate import positive_int
from rangekit.errors import InvalidParameterError
from rangekit.types import RngLike

__all__ = ["NOISE_KINDS", "RngLike", "make_noise", "pink_noise", "white_noise"]


#: Noise kinds understood by :func:`make_noise`.
NOISE_KINDS = ("white", "pink")


def white_noise(n: int, *, rng: RngLike = None) -> np.ndarray:
    """Gaussian white noise with unit variance.

    Parameters
    ----------
    n : int
        Number of samples, >= 1.
    rng : RngLike, optional
        Random source, anything :func:`numpy.random.default_rng` accepts.

    Returns
    -------
    numpy.ndarray, shape (n,), float64
        Independent draws from N(0, 1) (dimensionless; population variance 1, the
        sample variance fluctuates around it).

    Raises
    ------
    InvalidParameterError
        If ``n`` is not an integer >= 1.

    Examples
    --------
    >>> x = white_noise(100_000, rng=0)
    >>> abs(float(x.var()) - 1.0) < 0.02
    True
    """
    n = positive_int("n", n)
    return np.random.default_rng(rng).standard_normal(n)


def pink_noise(n: int, *, rng: RngLike = None) -> np.ndarray:
    """Pink (1/f) Gaussian noise with zero mean and unit variance.

    Parameters
    ----------
    n : int
        Number of samples, >= 2.
    rng : RngLike, optional
        Random source, anything :func:`numpy.random.default_rng` accepts.

    Returns
    -------
    numpy.ndarray, shape (n,), float64
        Noise whose power spectral density falls as 1/f (-3 dB per octave), scaled
        to exactly zero sample mean and unit sample variance (dimensionless).

    Raises
    ------
    InvalidParameterError
        If ``n`` is not an integer >= 2.

    Notes
    -----
    Gaussian white noise is transformed with a real FFT, each bin ``k >= 1`` is scaled
    by ``1 / sqrt(k)`` (power ~ 1/f), the DC bin is set to zero, and the inverse FFT
    is normalised. The result is circular: its end joins smoothly onto its start.

    Examples
    --------
    >>> x = pink_noise(8192, rng=0)
    >>> round(float(x.var()), 9), abs(float(x.mean())) < 1e-12
    (1.0, True)
    """
    n = positive_int("n", n, minimum=2)
    spectrum = np.fft.rfft(np.random.default_rng(rng).standard_normal(n))
    spectrum[0] = 0.0
    spectrum[1:] /= np.sqrt(np.arange(1, spectrum.size, dtype=np.float64))
    x = np.fft.irfft(spectrum, n)
    x -= x.mean()
    return x / x.std()


def make_noise(n: int, *, kind: str = "white", rng: RngLike = None) -> np.ndarray:
    """Noise of a named kind.

    Parameters
    ----------
    n : int
        Number of samples (>= 1 for white, >= 2 for pink).
    kind : {"white", "pink"}, optional
        Spectral shape; see :func:`white_noise` and :func:`pink_noise`. Default "white".
    rng : RngLike, optional
        Random source, anything :func:`numpy.random.default_rng` accepts.

    Returns
    -------
    numpy.ndarray, shape (n,), float64
        Unit-variance noise (dimensionless).

    Raises
    ------
    InvalidParameterError
        If ``kind`` is not one of ``NOISE_KINDS`` or ``n`` is invalid.

    Examples
    --------
    >>> make_noise(3, kind="white", rng=0).shape
    (3,)
    >>> make_noise(3, kind="brown")
    Traceback (most recent call last):
    ...
    rangekit.errors.InvalidParameterError: kind='brown' must be one of 'white', 'pink'
    """
    if kind == "white":
        return white_noise(n, rng=rng)
    if kind == "pink":
        return pink_noise(n, rng=rng)
    choices = ", ".join(repr(k) for k in NOISE_KINDS)
    raise InvalidParameterError(f"kind={kind!r} must be one of {choices}")
