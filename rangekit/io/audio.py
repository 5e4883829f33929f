"""Reading and writing audio files, with validation and clear errors.

Conventions (``docs/formats.md``): a recording is read as floats in [-1, 1] (float32 where
that holds every sample exactly: integer PCM of up to 24 bits and 32-bit float files; else
float64; :func:`load_devices` and :func:`read_frames` give float64); one WAV
with N channels is N devices (channel i = device i); N mono WAVs are N devices (file i
= device i). Files may differ in sample rate.

The path ``-`` is standard input (``rangekit range - < x.wav``): read whole, at most
the memory budget's share for raw bytes (:func:`stdin_limit`), then decoded and checked
as a file is (:func:`rangekit.io.guard.read_stdin`).
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rangekit.errors import (
    AudioFormatError,
    IncompatibleInputError,
    InvalidParameterError,
    RangekitError,
)

__all__ = ["Channel", "load_devices", "open_audio", "read_audio", "read_frames", "write_audio"]


@dataclass(frozen=True)
class Channel:
    """One device's recording: samples, sample rate and where they came from."""

    x: np.ndarray
    fs: float
    source: str

    @property
    def duration_s(self) -> float:
        return len(self.x) / self.fs


#: Largest sample magnitude accepted in a recording. Integer formats are within [-1, 1];
#: a float file can hold anything, and a sample of 1e300 is not sound (its energy
#: overflows): such a file is refused (exit 4) instead of poisoning the detection.
MAX_SAMPLE_ABS = 1e3
#: Peak memory of a whole-file command per byte of float64 samples (measured: about 8x
#: the samples -- the STFT, the conditioned copy, the matched filter).
PEAK_FACTOR = 8
#: Environment variable with the memory budget of whole-file reads (``--memory-budget``).
BUDGET_ENV = "RANGEKIT_MEMORY_BUDGET"
#: Fraction of the available memory that is the default budget.
BUDGET_FRACTION = 0.5


def parse_size(text: str) -> int | None:
    """Bytes of ``"512M"``, ``"4G"``, ``"1.5G"``, ``"1000000"`` (K, M, G, T: powers of
    1024); None for ``"off"`` (no budget). InvalidParameterError otherwise."""
    import re

    from rangekit.errors import InvalidParameterError

    t = str(text).strip().lower()
    if t in ("off", "none", "0"):
        return None
    m = re.fullmatch(r"(\d+(?:\.\d+)?)\s*([kmgt]?)i?b?", t)
    if m is None:
        raise InvalidParameterError(
            f"memory budget {text!r} must be a size such as 512M, 4G or off"
        )
    v = float(m[1]) * 1024 ** " kmgt".index(m[2] or " ")
    if not 1 <= v <= 2**60:
        raise InvalidParameterError(f"memory budget {text!r} is out of range")
    return int(v)


def memory_budget() -> int | None:
    """Bytes a whole-file read may plan to use (None: no limit).

    ``$RANGEKIT_MEMORY_BUDGET`` (``rangekit --memory-budget``) if set, else
    :data:`BUDGET_FRACTION` of the available memory (``MemAvailable`` of /proc/meminfo;
    4 GiB where that is unknown)."""
    env = os.environ.get(BUDGET_ENV)
    if env:
        return parse_size(env)
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(BUDGET_FRACTION * int(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        pass
    return 4 * 2**30


def _size(n: int) -> str:
    return f"{n / 2**30:.2f} GiB" if n >= 2**30 else f"{n / 2**20:.1f} MiB"


def _what(path: str | os.PathLike) -> str:
    """How ``path`` is named in messages: ``'x.wav'``, or standard input for ``-``."""
    from rangekit.io.guard import is_stdin

    return "standard input" if is_stdin(path) else f"'{os.fspath(path)}'"


def stdin_limit() -> int:
    """Most bytes of a recording read from standard input: :func:`memory_budget` over
    :data:`PEAK_FACTOR` (a recording of that many bytes of float64 samples would need the
    whole budget; 1 TiB with no budget). The decoded samples are then checked by
    :func:`check_memory` as a file's are."""
    budget = memory_budget()
    return 2**40 if budget is None else max(1, budget // PEAK_FACTOR)


def _stdin_file():
    """Standard input's bytes as a seekable file object, within :func:`stdin_limit`."""
    import io

    from rangekit.io.guard import read_stdin

    data = read_stdin(
        stdin_limit(),
        error=IncompatibleInputError,
        hint=" (the memory budget over 8): write it to a file and use `rangekit range "
        f"--series`, or raise the budget (rangekit --memory-budget SIZE, or ${BUDGET_ENV})",
    )
    if not data:
        raise AudioFormatError("standard input holds no data (nothing was piped in)")
    return io.BytesIO(data)


def _open_sf(path: str | os.PathLike):
    """``(soundfile.SoundFile, name for messages)`` of ``path`` or of standard input."""
    from rangekit.io.guard import is_stdin

    sf = _sf()
    stdin = is_stdin(path)
    src = _stdin_file() if stdin else _sf_path(_readable(path))
    what = _what(path)
    try:
        return sf.SoundFile(src), what
    except sf.LibsndfileError as e:
        raise AudioFormatError(f"{what} is not a readable audio file ({e.error_string})") from e
    except (RuntimeError, TypeError, ValueError) as e:
        raise AudioFormatError(f"{what} is not a readable audio file ({e})") from e


def check_memory(
    path: str | os.PathLike, frames: int, channels: int, *, hint: str | None = None
) -> None:
    """Refuse a whole-file read whose estimated peak exceeds :func:`memory_budget`.

    Raises
    ------
    IncompatibleInputError
        Naming the file, the estimate, the budget, and ``--series`` (exit 5).
    """
    budget = memory_budget()
    need = int(frames) * int(channels) * 8 * PEAK_FACTOR
    if budget is not None and need > budget:
        raise IncompatibleInputError(
            f"{_what(path)}: {frames} frames x {channels} channel(s) need about "
            f"{_size(need)} to process whole, more than the memory budget of "
            f"{_size(budget)}: {hint or 'use `rangekit range --series` (bounded memory)'}, "
            f"or raise the budget (rangekit --memory-budget SIZE, or ${BUDGET_ENV})"
        )


def _sf_path(p: str | os.PathLike) -> str | bytes:
    """The path for libsndfile: bytes when the name is not valid UTF-8 (soundfile encodes
    str names strictly, so a recording named with other bytes could not be opened)."""
    text = os.fspath(p)
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return os.fsencode(text)
    return text


def _name(f) -> str:
    if isinstance(f.name, bytes):
        return os.fsdecode(f.name)
    return f.name if isinstance(f.name, str) else "standard input"


def _sf():
    import soundfile  # deferred: keeps `import rangekit` cheap

    return soundfile


def _readable(path: str | os.PathLike) -> Path:
    """``path`` as a Path if it is a readable regular file, else InputFileError naming it.

    Directories, FIFOs, devices (``/dev/zero``) and sockets are refused before they are
    opened (:func:`rangekit.io.guard.regular_file`): nothing blocks or reads forever.
    """
    from rangekit.io.guard import regular_file

    regular_file(path)
    return Path(path)


#: Subtypes whose samples float32 holds exactly (integers of up to 24 bits, 32-bit floats).
_EXACT_IN_FLOAT32 = frozenset({"PCM_S8", "PCM_U8", "PCM_16", "PCM_24", "FLOAT", "ALAW", "ULAW"})
#: Integer subtypes :func:`read_audio` decodes as integers and scales to float32 itself:
#: (integer dtype libsndfile reads them as, the scale to full scale 1). libsndfile's own
#: float conversion gives the same values (tested) at twice the CPU (10 min of 16-bit
#: stereo: 0.21-0.23 s against 0.10 s, measured 2026-12-02).
_INT_AS_FLOAT32 = {"PCM_16": ("int16", 2.0**-15), "PCM_24": ("int32", 2.0**-31)}
#: Frames per block of that conversion (the integer buffer stays small).
_INT_BLOCK_FRAMES = 1 << 18


def _read_int_float32(f, subtype: str, frames: int | None = None) -> np.ndarray:
    """The next ``frames`` frames (default: the rest) of open file ``f`` (16- or 24-bit
    PCM) as float32, (frames, channels): read block by block as integers into one buffer
    and scaled into the output channel by channel. The output is stored by channel (the
    transpose of a (channels, frames) array), so each channel ``x[:, c]`` is contiguous:
    the detectors take it without a copy (10 minutes of stereo: the two 0.06-0.4 s copies
    of the channels are gone, and the decode costs the same, measured 2026-12-03)."""
    idt, scale = _INT_AS_FLOAT32[subtype]
    n, c = f.frames - f.tell(), f.channels
    if frames is not None:
        n = max(0, min(n, int(frames)))
    rows = np.empty((c, n), dtype=np.float32)
    buf = np.empty((min(n, _INT_BLOCK_FRAMES), c), dtype=idt)
    s = np.float32(scale)
    i = 0
    while i < n:
        k = f.read(min(len(buf), n - i), dtype=idt, always_2d=True, out=buf[: n - i])
        if len(k) == 0:
            break
        for ch in range(c):
            np.multiply(k[:, ch], s, out=rows[ch, i : i + len(k)], dtype=np.float32)
        i += len(k)
    return rows[:, :i].T


def read_audio(path: str | os.PathLike, *, dtype: str = "auto") -> tuple[np.ndarray, float]:
    """Read an audio file as floats of shape (n_samples, n_channels) and its rate in Hz.

    ``dtype`` ``"auto"`` (default) decodes straight into float32 when that holds every
    sample exactly (integer PCM of up to 24 bits, 32-bit float; the values equal the
    float64 ones) and into float64 otherwise (32-bit PCM, 64-bit float, compressed
    formats); ``"float32"`` or ``"float64"`` force one.

    Raises
    ------
    InputFileError
        The file is missing, a directory, or cannot be read.
    AudioFormatError
        The file is not audio that libsndfile can decode, or holds no samples.
    IncompatibleInputError
        The recording needs more than the memory budget (:func:`check_memory`).

    ``path`` ``-`` reads standard input (at most :func:`stdin_limit` bytes).
    """
    if dtype not in ("auto", "float32", "float64"):
        raise InvalidParameterError(f"dtype={dtype!r} must be 'auto', 'float32' or 'float64'")
    sf = _sf()
    f, p = _open_sf(path)
    try:
        with f:
            check_memory(path, f.frames, f.channels)
            subtype = f.subtype
            if dtype == "auto":
                dtype = "float32" if subtype in _EXACT_IN_FLOAT32 else "float64"
            if dtype == "float32" and subtype in _INT_AS_FLOAT32 and f.seekable():
                x = _read_int_float32(f, subtype)
            else:
                x = f.read(dtype=dtype, always_2d=True)
            fs = f.samplerate
    except RangekitError:
        raise
    except sf.LibsndfileError as e:
        raise AudioFormatError(f"{p} is not a readable audio file ({e.error_string})") from e
    except (RuntimeError, TypeError, ValueError) as e:
        raise AudioFormatError(f"{p} is not a readable audio file ({e})") from e
    if x.shape[0] == 0:
        raise AudioFormatError(f"{p} holds no audio samples")
    # Integer samples are finite and within full scale: only float files need the
    # (whole-array) checks.
    if subtype in ("FLOAT", "DOUBLE") or not subtype.startswith(("PCM", "ALAW", "ULAW")):
        if not np.all(np.isfinite(x)):
            raise AudioFormatError(f"{p} holds NaN or infinite samples")
        _check_peak(x, p)
    return x, float(fs)


def _check_peak(x: np.ndarray, what: str) -> None:
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    if peak > MAX_SAMPLE_ABS:
        raise AudioFormatError(
            f"{what} holds a sample of magnitude {peak:.3g}, beyond {MAX_SAMPLE_ABS:g}: not "
            "a recording (float files are read as they are, full scale is 1)"
        )


def open_audio(path: str | os.PathLike):
    """Open an audio file for reading in blocks (:func:`read_frames`); close it when done.

    The checks and errors are those of :func:`read_audio`; the file must be seekable
    (WAV, FLAC, ... on disk). Returns a ``soundfile.SoundFile`` whose ``frames``,
    ``channels`` and ``samplerate`` give the recording's size and rate without reading it.

    Raises
    ------
    InputFileError
        The file is missing, a directory, or cannot be read.
    AudioFormatError
        The file is not audio that libsndfile can decode, holds no samples, or cannot seek.

    ``path`` ``-`` is standard input, held in memory (at most :func:`stdin_limit` bytes).
    """
    f, p = _open_sf(path)
    if f.frames <= 0:
        f.close()
        raise AudioFormatError(f"{p} holds no audio samples")
    if not f.seekable():
        f.close()
        raise AudioFormatError(f"{p} cannot be read in blocks (the file is not seekable)")
    return f


def read_frames(f, start: int, stop: int) -> np.ndarray:
    """Samples ``[start, stop)`` of a file opened by :func:`open_audio`, float64 (n, channels).

    The range is clipped to the file; values are those :func:`read_audio` returns for the
    same samples (both decode with libsndfile to float64 in [-1, 1]).

    Raises
    ------
    AudioFormatError
        The samples hold NaN or infinite values, or cannot be decoded.
    """
    start = max(0, int(start))
    stop = min(int(f.frames), int(stop))
    if stop <= start:
        return np.zeros((0, f.channels))
    sf = _sf()
    try:
        f.seek(start)
        x = f.read(stop - start, dtype="float64", always_2d=True)
    except (sf.LibsndfileError, RuntimeError) as e:
        raise AudioFormatError(f"'{_name(f)}': cannot read samples {start}-{stop} ({e})") from e
    if not np.all(np.isfinite(x)):
        raise AudioFormatError(f"'{_name(f)}' holds NaN or infinite samples (from sample {start})")
    _check_peak(x, f"'{_name(f)}' (from sample {start})")
    return x


def check_period(paths: Sequence[str | os.PathLike], period_s: float | None) -> None:
    """Refuse recordings shorter than one ``period_s`` window (ultrasonic ``--period``)
    before they are ranged: IncompatibleInputError naming the file (exit 5). Unreadable
    files are left to the reader's own error."""
    if period_s is None:
        return
    sf = _sf()
    for p in paths:
        try:
            _readable(p)  # never opens a FIFO or a device
            info = sf.info(_sf_path(p))
        except Exception:  # the reader reports it properly
            continue
        if info.frames < period_s * info.samplerate:
            raise IncompatibleInputError(
                f"'{os.fspath(p)}' lasts {info.frames / info.samplerate:.4g} s, shorter than "
                f"one window of --period {period_s:g} s"
            )


def load_devices(paths: Sequence[str | os.PathLike], *, min_devices: int = 2) -> list[Channel]:
    """Read the recordings of one exchange: one multichannel file or one mono file per device.

    Parameters
    ----------
    paths : sequence of path-like
        One file with N >= ``min_devices`` channels, or N mono files.
    min_devices : int
        Minimum number of devices the scheme needs.

    Returns
    -------
    list of Channel
        Device i's recording at index i.
    """
    paths = list(paths)
    if not paths:
        raise IncompatibleInputError("no input files given")
    if len(paths) == 1:
        x, fs = read_audio(paths[0], dtype="float64")
        if x.shape[1] < min_devices:
            raise IncompatibleInputError(
                f"'{paths[0]}' has {x.shape[1]} channel(s) but {min_devices} devices are needed: "
                "give one WAV with a channel per device, or one mono WAV per device"
            )
        return [
            Channel(np.ascontiguousarray(x[:, i]), fs, f"{paths[0]}#{i}") for i in range(x.shape[1])
        ]
    if len(paths) < min_devices:
        raise IncompatibleInputError(f"{len(paths)} files given but {min_devices} are needed")
    out = []
    for p in paths:
        x, fs = read_audio(p, dtype="float64")
        if x.shape[1] != 1:
            raise IncompatibleInputError(
                f"'{p}' has {x.shape[1]} channels: with several files, each must be mono "
                "(one file per device)"
            )
        out.append(Channel(np.ascontiguousarray(x[:, 0]), fs, str(p)))
    return out


def write_audio(
    path: str | os.PathLike, x: np.ndarray, *, fs: float, subtype: str = "PCM_16"
) -> None:
    """Write ``x`` (n_samples,) or (n_samples, n_channels) to ``path`` atomically.

    The file appears complete or not at all: data goes to a temporary file in the same
    folder that is renamed over ``path`` at the end. Samples beyond [-1, 1] raise rather
    than clip silently.
    """
    x = np.asarray(x, dtype=np.float64)
    if not np.all(np.isfinite(x)):
        raise AudioFormatError(f"cannot write '{path}': the signal holds NaN or infinite samples")
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    if subtype.startswith("PCM") and peak > 1.0:
        raise AudioFormatError(f"cannot write '{path}': peak {peak:.3f} exceeds full scale 1.0")
    from rangekit.io.guard import atomic_output

    p = Path(path)
    sf = _sf()
    fmt = p.suffix.lstrip(".").upper() or "WAV"
    try:
        # Encoded in memory first: libsndfile writing straight into the file reports a
        # full disk through cffi callbacks that print tracebacks on stderr; a memory
        # buffer cannot fail that way, and the one write below fails cleanly (exit 3).
        buf = io.BytesIO()
        sf.write(buf, x, int(round(fs)), subtype=subtype, format=fmt)
        with atomic_output(p) as f:
            f.write(buf.getbuffer())
    except (sf.LibsndfileError, TypeError, ValueError) as e:
        if isinstance(e, RangekitError):
            raise
        raise AudioFormatError(f"cannot write '{p}': {e}") from e
