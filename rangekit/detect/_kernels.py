"""Compiled hot loops of the beep detectors.

The STFT change-point detector only needs the energy of a narrow frequency band in
every STFT frame.  Computing a full STFT (all ``n_win // 2 + 1`` bins, or more with
zero padding) and then summing three bins throws almost all of the work away, so
:func:`band_energy` evaluates the windowed DFT directly at the requested frequencies
only: per frame and frequency it is one real dot product for the real part and one
for the imaginary part, over contiguous memory, which the compiler vectorises.

On one core of a recent x86-64 machine this runs at several thousand times realtime
for 44.1 kHz audio with ``n_win=128``, ``hop=32`` and three frequencies (see
``benchmarks/bench_band_energy.py``: ~5000x), against a few tens of times realtime
for :class:`scipy.signal.ShortTimeFFT` followed by a band sum (100-160x slower).

Window
------
The analysis window is the *periodic* (DFT-even) Hann window,
``scipy.signal.windows.hann(n_win, sym=False)``, i.e.
``w[k] = 0.5 - 0.5 cos(2 pi k / n_win)``: the window that is normally passed to
:class:`scipy.signal.ShortTimeFFT`.  It is *not* the symmetric Hann window
(``sym=True``, ``np.hanning``).
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
from collections.abc import Iterator

import numpy as np

from rangekit import _validate
from rangekit.errors import InvalidParameterError

__all__ = ["band_energy", "long_recording", "recording_samples"]

# Only the flags that let LLVM reassociate the dot-product reductions (and fuse
# multiply-adds).  Unlike ``fastmath=True`` this keeps ``nnan``/``ninf`` off, so a NaN or
# an infinity in the signal propagates into the affected frames instead of being UB.
# Reassociation alone is worth ~2.4x here: without it the reductions stay scalar.
_FASTMATH = {"reassoc", "contract"}

_INT16_SCALE = 1.0 / 32768.0


def _band_energy_py(
    x: np.ndarray, kr: np.ndarray, ki: np.ndarray, hop: int, scale: float
) -> np.ndarray:
    """Band energy per frame from precomputed complex-kernel parts (compiled by numba).

    Parameters
    ----------
    x : numpy.ndarray
        Contiguous 1-D signal, float64, float32 or int16 (one compiled
        specialisation per dtype; samples are converted to float64 frame by frame).
    kr, ki : numpy.ndarray
        C-contiguous float64 arrays of shape ``(n_f, n_win)``: real and imaginary
        parts of ``w[k] * exp(-2j pi f k / fs)`` for each frequency ``f``.
    hop : int
        Frame advance in samples, ``>= 1``.
    scale : float
        Factor applied to the samples (``1/32768`` for int16).  It is applied to
        the energy as ``scale**2`` at the end, which is exact for powers of two.

    Returns
    -------
    numpy.ndarray
        float64 array of shape ``(n_frames,)`` with
        ``n_frames = (len(x) - n_win) // hop + 1`` (0 if ``len(x) < n_win``).
    """
    n_f, n_win = kr.shape
    n_x = x.shape[0]
    n_frames = (n_x - n_win) // hop + 1 if n_x >= n_win else 0
    out = np.empty(n_frames, dtype=np.float64)
    frame = np.empty(n_win, dtype=np.float64)
    scale2 = scale * scale
    for m in range(n_frames):
        start = m * hop
        # Convert the frame once to float64 in a small buffer that stays in L1; the
        # dot products below then read two contiguous float64 streams and vectorise.
        for k in range(n_win):
            frame[k] = x[start + k]
        energy = 0.0
        # Frequencies outside, samples inside: the k loop is a pair of plain
        # reductions that LLVM vectorises (putting the frequencies inside the k loop
        # instead was measured ~3x slower).
        for f in range(n_f):
            acc_re = 0.0
            acc_im = 0.0
            for k in range(n_win):
                acc_re += kr[f, k] * frame[k]
                acc_im += ki[f, k] * frame[k]
            energy += acc_re * acc_re + acc_im * acc_im
        out[m] = energy * scale2
    return out


#: Inputs with fewer samples than this use the numpy reference (same numbers, tested):
#: for a short file importing numba costs more (~0.25 s) than the whole computation.
NUMBA_MIN_SAMPLES = 1_000_000

#: Samples per channel of the recording that the detectors' input is a block of
#: (:func:`recording_samples`); 0: the input is the whole recording.
_RECORDING_SAMPLES: contextvars.ContextVar[int] = contextvars.ContextVar(
    "recording_samples", default=0
)


@contextlib.contextmanager
def recording_samples(n: int) -> Iterator[None]:
    """Within the block, detection runs on blocks of a recording of ``n`` samples per
    channel: the kernels are chosen by that length (:func:`long_recording`), not by the
    block's, so every block of a long recording (its short last one too) takes the
    compiled path, as the whole recording would.

    Examples
    --------
    >>> with recording_samples(5_000_000):
    ...     long_recording()
    True
    >>> long_recording()
    False
    """
    token = _RECORDING_SAMPLES.set(int(n))
    try:
        yield
    finally:
        _RECORDING_SAMPLES.reset(token)


def long_recording() -> bool:
    """Whether the detectors' input is a block of a recording of ``NUMBA_MIN_SAMPLES`` or
    more samples (:func:`recording_samples`): its kernels are the compiled ones whatever
    the block's own length."""
    return _RECORDING_SAMPLES.get() >= NUMBA_MIN_SAMPLES


@functools.cache
def _compiled_kernel():
    """The numba-compiled kernel (numba is imported on first use only)."""
    import numba

    return numba.njit(cache=True, fastmath=_FASTMATH, nogil=True)(_band_energy_py)


def _band_energy_kernel(x, kr, ki, hop, scale):
    """Call the compiled kernel (see :func:`_band_energy_py`)."""
    return _compiled_kernel()(x, kr, ki, hop, scale)


def _complex_kernels(fs: float, f_hz: np.ndarray, n_win: int) -> np.ndarray:
    """Return ``c[f, k] = w[k] exp(-2j pi f k / fs)`` as complex128 ``(n_f, n_win)``.

    ``w`` is the periodic Hann window ``hann(n_win, sym=False)``.
    """
    # Periodic Hann, equal to scipy.signal.windows.hann(n_win, sym=False) (tested); written
    # out so that importing the detector does not import scipy.signal (0.7 s).
    w = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n_win) / n_win)
    k = np.arange(n_win, dtype=np.float64)
    # Reduce the cycle count f*k/fs modulo 1 before multiplying by 2 pi to keep the
    # phase argument small (exact for the integer part, rounding only the fraction).
    cycles = np.outer(f_hz, k) / fs
    cycles -= np.floor(cycles)
    return w * np.exp(-2j * np.pi * cycles)


def _band_energy_reference(
    x: np.ndarray, *, fs: float, f_hz: np.ndarray, n_win: int, hop: int
) -> np.ndarray:
    """Plain-numpy band energy, the test oracle for :func:`band_energy`.

    Same definition and window as :func:`band_energy`, computed as a complex matrix
    product of the strided frame view with the kernel matrix.  No input validation.

    Parameters
    ----------
    x : numpy.ndarray
        1-D signal; int16 is scaled by ``1/32768``.
    fs : float
        Sample rate in Hz.
    f_hz : numpy.ndarray
        Frequencies in Hz.
    n_win, hop : int
        Frame length and frame advance in samples.

    Returns
    -------
    numpy.ndarray
        float64 energies, shape ``(n_frames,)``.
    """
    x = np.asarray(x)
    xf = x.astype(np.float64) * _INT16_SCALE if x.dtype == np.int16 else x.astype(np.float64)
    if xf.shape[0] < n_win:
        return np.zeros(0, dtype=np.float64)
    frames = np.lib.stride_tricks.sliding_window_view(xf, n_win)[::hop]
    c = _complex_kernels(float(fs), np.atleast_1d(np.asarray(f_hz, dtype=np.float64)), n_win)
    spec = frames @ c.T  # (n_frames, n_f)
    return np.sum(spec.real**2 + spec.imag**2, axis=1)


def band_energy(x: np.ndarray, *, fs: float, f_hz: np.ndarray, n_win: int, hop: int) -> np.ndarray:
    """Energy of a set of STFT frequencies in every frame of a signal.

    For frame ``m``, covering ``x[m*hop : m*hop + n_win]``, returns::

        E[m] = sum_{f in f_hz} | sum_{k=0}^{n_win-1} w[k] x[m*hop + k] exp(-2j pi f k / fs) |^2

    with ``w = scipy.signal.windows.hann(n_win, sym=False)``, the *periodic*
    (DFT-even) Hann window.  When every ``f`` is a bin frequency ``q * fs / mfft`` this
    equals ``sum_q |X[q, p]|^2`` of :class:`scipy.signal.ShortTimeFFT` with the same
    window, ``hop``, ``mfft`` and ``scale_to=None``, at slice ``p = m + (n_win // 2) / hop``
    (ShortTimeFFT centres its slices on ``p * hop``).  Only the requested frequencies
    are evaluated, which is much cheaper than a full STFT for a narrow band.

    Parameters
    ----------
    x : numpy.ndarray
        1-D signal.  float64, float32 and int16 are used in place (no converted copy
        of the whole signal; int16 is scaled by ``1/32768``, i.e. full scale is 1.0).
        Other real dtypes (other integers, bool) are converted to float64 *unscaled*;
        complex and non-numeric dtypes are rejected.  Non-finite samples give non-finite
        energies in the frames that contain them.
    fs : float
        Sample rate in Hz, finite and > 0.
    f_hz : numpy.ndarray
        Frequencies in Hz (scalar or 1-D, at least one), each within the open
        interval ``(0, fs/2)``.  Frequencies need not be bin frequencies.
    n_win : int
        Frame (window) length in samples, ``>= 4``.
    hop : int
        Frame advance in samples, ``1 <= hop <= n_win``.

    Returns
    -------
    numpy.ndarray
        float64 array of shape ``(n_frames,)``, ``n_frames = (len(x) - n_win) // hop + 1``;
        frames that would run past the end are not produced, and the result is empty
        when ``len(x) < n_win``.

    Raises
    ------
    rangekit.errors.InvalidParameterError
        If ``x`` is not 1-D, ``fs`` is not finite and > 0, ``n_win < 4``, ``hop`` is
        not within ``[1, n_win]``, or ``f_hz`` is empty or has a value outside
        ``(0, fs/2)``.

    Examples
    --------
    >>> import numpy as np
    >>> fs = 44100.0
    >>> t = np.arange(4410) / fs
    >>> x = np.sin(2 * np.pi * 16000.0 * t) * (t > 0.05)
    >>> e = band_energy(x, fs=fs, f_hz=np.array([15900.0, 16000.0, 16100.0]), n_win=128, hop=32)
    >>> e.shape
    (134,)
    >>> bool(e[:60].max() < 1e-20 < e[-60:].min())
    True
    """
    fs_v = _validate.positive("fs", fs)
    n_win_v = _validate.positive_int("n_win", n_win, minimum=4)
    hop_v = _validate.positive_int("hop", hop, minimum=1)
    if hop_v > n_win_v:
        raise InvalidParameterError(f"hop={hop!r} must be <= n_win={n_win_v}")

    try:
        f_arr = np.atleast_1d(np.asarray(f_hz, dtype=np.float64))
    except (TypeError, ValueError):
        raise InvalidParameterError(f"f_hz={f_hz!r} must be an array of numbers") from None
    if f_arr.ndim != 1 or f_arr.size == 0:
        raise InvalidParameterError(f"f_hz must be 1-D and non-empty, got shape {f_arr.shape}")
    nyq = fs_v / 2.0
    bad = ~((f_arr > 0.0) & (f_arr < nyq))  # also catches NaN
    if np.any(bad):
        first = float(f_arr[np.argmax(bad)])
        raise InvalidParameterError(
            f"f_hz={first!r} Hz must be within the open interval (0, fs/2) = (0, {nyq!r})"
        )

    xa = np.asarray(x)
    if xa.ndim != 1:
        raise InvalidParameterError(f"x must be 1-D, got shape {xa.shape}")
    if xa.dtype == np.int16:
        scale = _INT16_SCALE
    else:
        scale = 1.0
        if xa.dtype not in (np.float64, np.float32):
            if not (
                np.issubdtype(xa.dtype, np.integer)
                or np.issubdtype(xa.dtype, np.floating)
                or xa.dtype == np.bool_
            ):
                raise InvalidParameterError(f"x must be real numeric, got dtype {xa.dtype}")
            xa = xa.astype(np.float64)
    xa = np.ascontiguousarray(xa)  # no copy when already contiguous

    if xa.shape[0] < n_win_v:
        return np.zeros(0, dtype=np.float64)

    if xa.shape[0] < NUMBA_MIN_SAMPLES and not long_recording():
        return _band_energy_reference(xa, fs=fs_v, f_hz=f_arr, n_win=n_win_v, hop=hop_v)
    c = _complex_kernels(fs_v, f_arr, n_win_v)
    kr = np.ascontiguousarray(c.real)
    ki = np.ascontiguousarray(c.imag)
    try:
        return _band_energy_kernel(xa, kr, ki, hop_v, scale)
    except ModuleNotFoundError:
        # numba's on-disk cache stores the defining module's *name* and re-imports it on
        # load; a cache entry written while this file was imported under another name
        # (e.g. ``_kernels`` by a prepend-mode doctest run) cannot be loaded.  Compile
        # an uncached copy instead of failing.
        return _uncached_kernel()(xa, kr, ki, hop_v, scale)


@functools.cache
def _uncached_kernel():
    """Return a copy of the kernel compiled without the disk cache."""
    import numba

    return numba.njit(cache=False, fastmath=_FASTMATH, nogil=True)(_band_energy_py)
