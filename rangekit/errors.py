"""The rangekit exception family.

Every error a user can cause derives from :class:`RangekitError` and carries the
exit code the command-line interface returns for it (documented in ``docs/cli.md``).
Library callers catch :class:`RangekitError`; they never need to look at exit codes.

Examples
--------
>>> from rangekit.errors import InputFileError
>>> err = InputFileError("cannot open 'x.wav': no such file")
>>> err.exit_code
3
"""

from __future__ import annotations

__all__ = [
    "AudioFormatError",
    "CalibrationError",
    "DetectionError",
    "IncompatibleInputError",
    "InputFileError",
    "InvalidParameterError",
    "LogFormatError",
    "RangekitError",
    "UnreliableResultError",
]


class RangekitError(Exception):
    """Base class of every error rangekit raises on purpose (exit code 1)."""

    exit_code: int = 1


class InvalidParameterError(RangekitError, ValueError):
    """A parameter value is out of its domain (exit code 2, like a usage error)."""

    exit_code = 2


class InputFileError(RangekitError, OSError):
    """An input file is missing or cannot be read (exit code 3)."""

    exit_code = 3


class AudioFormatError(RangekitError, ValueError):
    """A file is not audio, or is audio in a form rangekit cannot use (exit code 4)."""

    exit_code = 4


class LogFormatError(RangekitError, ValueError):
    """A data file (measurement log, step or range CSV) is malformed (exit code 4).

    The message names the file, the row (1-based, counting the header as row 1) and the
    column. Examples: a missing column, a NaN, time going backwards, a negative sigma.
    """

    exit_code = 4


class IncompatibleInputError(RangekitError, ValueError):
    """Inputs are valid on their own but do not fit together or with the signal (exit code 5).

    Examples: a sample rate too low to carry the beep, the wrong number of channels or
    files for the scheme.
    """

    exit_code = 5


class DetectionError(RangekitError):
    """The signal was not found as expected in the recording (exit code 6).

    Examples: fewer beeps found than devices, burst spacing that does not fit the beep.
    """

    exit_code = 6


class CalibrationError(RangekitError):
    """A calibration cannot be trusted and is refused (exit code 7).

    Examples: too few recordings, recordings at one distance that disagree beyond their
    uncertainty (the message names them).
    """

    exit_code = 7


class UnreliableResultError(RangekitError):
    """A result carries flags that make it doubtful and strict mode refuses it (exit 10).

    Raised only when asked (``--strict``): by default flagged results are returned with
    their flags. The message names each refused result and its flags.
    """

    exit_code = 10
