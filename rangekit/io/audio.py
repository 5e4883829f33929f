"""Reading and writing audio files, with validation and clear errors.

Conventions (``docs/formats.md``): a recording is read as floats in [-1, 1] (float32 where
that holds every sample exactly: integer PCM of up to 24 bits and 32-bit float files; else
float64; :func:`load_devices` and :func:`read_frames` give float64); one WAV
with N channels is N devices (channel i = device i); N mono WAVs are N devices (file i
= device i). Files may differ in sample rate.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rangekit.errors import (
    AudioFormatError,
    IncompatibleInputError,
    InputFileError,
    InvalidParameterError,
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


def _sf():
    import soundfile  # deferred: keeps `import rangekit` cheap

    return soundfile


def _readable(path: str | os.PathLike) -> Path:
    """``path`` as a Path if it is a readable file, else InputFileError naming it."""
    p = Path(path)
    if not p.exists():
        raise InputFileError(f"cannot open '{p}': no such file")
    if p.is_dir():
        raise InputFileError(f"cannot open '{p}': it is a directory")
    if not os.access(p, os.R_OK):
        raise InputFileError(f"cannot open '{p}': permission denied")
    return p


#: Subtypes whose samples float32 holds exactly (integers of up to 24 bits, 32-bit floats).
_EXACT_IN_FLOAT32 = frozenset({"PCM_S8", "PCM_U8", "PCM_16", "PCM_24", "FLOAT", "ALAW", "ULAW"})


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
    """
    if dtype not in ("auto", "float32", "float64"):
        raise InvalidParameterError(f"dtype={dtype!r} must be 'auto', 'float32' or 'float64'")
    p = _readable(path)
    sf = _sf()
    try:
        subtype = sf.info(str(p)).subtype
        if dtype == "auto":
            dtype = "float32" if subtype in _EXACT_IN_FLOAT32 else "float64"
        x, fs = sf.read(str(p), dtype=dtype, always_2d=True)
    except sf.LibsndfileError as e:
        raise AudioFormatError(f"'{p}' is not a readable audio file ({e.error_string})") from e
    except (RuntimeError, TypeError, ValueError) as e:
        raise AudioFormatError(f"'{p}' is not a readable audio file ({e})") from e
    if x.shape[0] == 0:
        raise AudioFormatError(f"'{p}' holds no audio samples")
    # Integer samples are finite: only float files need the (whole-array) check.
    if subtype in ("FLOAT", "DOUBLE") or not subtype.startswith(("PCM", "ALAW", "ULAW")):
        if not np.all(np.isfinite(x)):
            raise AudioFormatError(f"'{p}' holds NaN or infinite samples")
    return x, float(fs)


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
    """
    p = _readable(path)
    sf = _sf()
    try:
        f = sf.SoundFile(str(p))
    except sf.LibsndfileError as e:
        raise AudioFormatError(f"'{p}' is not a readable audio file ({e.error_string})") from e
    except (RuntimeError, TypeError, ValueError) as e:
        raise AudioFormatError(f"'{p}' is not a readable audio file ({e})") from e
    if f.frames <= 0:
        f.close()
        raise AudioFormatError(f"'{p}' holds no audio samples")
    if not f.seekable():
        f.close()
        raise AudioFormatError(f"'{p}' cannot be read in blocks (the file is not seekable)")
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
        raise AudioFormatError(f"'{f.name}': cannot read samples {start}-{stop} ({e})") from e
    if not np.all(np.isfinite(x)):
        raise AudioFormatError(f"'{f.name}' holds NaN or infinite samples (from sample {start})")
    return x


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
    p = Path(path)
    if p.parent and not p.parent.exists():
        raise InputFileError(f"cannot write '{p}': folder '{p.parent}' does not exist")
    tmp = p.with_name(f".{p.name}.part")
    sf = _sf()
    fmt = p.suffix.lstrip(".").upper() or "WAV"
    try:
        sf.write(str(tmp), x, int(round(fs)), subtype=subtype, format=fmt)
        os.replace(tmp, p)
    except (sf.LibsndfileError, TypeError, ValueError) as e:
        tmp.unlink(missing_ok=True)
        raise AudioFormatError(f"cannot write '{p}': {e}") from e
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise InputFileError(f"cannot write '{p}': {e.strerror or e}") from e
