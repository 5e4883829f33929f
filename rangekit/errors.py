"""The rangekit exception family.

Every error a user can cause derives from :class:`RangekitError` and carries the
exit code the command-line interface returns for it. :data:`EXIT_CODES` is the one table
of those codes: ``rangekit --help`` prints it and ``docs/cli.md`` is tested against it.
Library callers catch :class:`RangekitError`; they never need to look at exit codes.

Examples
--------
>>> from rangekit.errors import InputFileError
>>> err = InputFileError("cannot open 'x.wav': no such file")
>>> err.exit_code
3
>>> EXIT_CODES[3]
'input file missing or unreadable, or output not writable'
"""

from __future__ import annotations

__all__ = [
    "DOCS_URL",
    "EXIT_CODES",
    "AudioFormatError",
    "CalibrationError",
    "DetectionError",
    "IncompatibleInputError",
    "InputFileError",
    "InvalidParameterError",
    "LogFormatError",
    "RangekitError",
    "UnreliableResultError",
    "exit_codes_text",
]


#: Where the documentation lives (``[project.urls] Documentation`` in pyproject.toml;
#: a test keeps the two equal). ``rangekit --help`` points there; help texts name its
#: pages (``formats.md of the documentation``).
DOCS_URL = "https://github.com/rangekit/rangekit/tree/main/docs"

#: Exit code -> what it means: the one table (``rangekit --help``, ``docs/cli.md``).
EXIT_CODES: dict[int, str] = {
    0: "success",
    1: "another rangekit error",
    2: "usage error or invalid parameter",
    3: "input file missing or unreadable, or output not writable",
    4: "not audio, no samples, or a malformed data file",
    5: "inputs incompatible (sample rate, channels, file count, memory budget)",
    6: "detection failure",
    7: "calibration refused (calibrate)",
    8: "some sessions failed (batch)",
    9: "every session failed (batch)",
    10: "a doubtful result refused (--strict)",
    70: "internal error (a bug: please report it)",
    130: "interrupted",
}


def exit_codes_text() -> str:
    """:data:`EXIT_CODES` as aligned lines ``  CODE  meaning`` (for ``--help``)."""
    return "\n".join(f"  {code:>3}  {text}" for code, text in EXIT_CODES.items())


class RangekitError(Exception):
    """Base class of every error rangekit raises on purpose (exit code 1)."""

    exit_code: int = 1


class InvalidParameterError(RangekitError, ValueError):
    """A parameter value is out of its domain (exit code 2, like a usage error).

    ``param``: the parameter's name where one parameter is at fault (the validators of
    :mod:`rangekit._validate` set it), so that a caller can name its own spelling of it
    (the CLI its option) without reading the message; None otherwise.

    Examples
    --------
    >>> InvalidParameterError("n_particles=0 must be >= 1", param="n_particles").param
    'n_particles'
    """

    exit_code = 2

    def __init__(self, *args: object, param: str | None = None) -> None:
        super().__init__(*args)
        self.param = param


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
