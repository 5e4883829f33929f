"""Guarded input and output: what a file is checked for before rangekit reads or replaces it.

Every file rangekit reads from a user (recordings, templates, JSON sidecars,
calibrations, floor plans, beacon files) passes :func:`regular_file` first: it must be
a regular file (after following symbolic links) -- directories, FIFOs, devices and
sockets are refused before they are opened, so ``/dev/zero`` or a named pipe can
neither fill the memory nor hang a run. JSON goes through :func:`read_json_file` /
:func:`parse_json`: a size cap checked before reading, a nesting limit, a limit on the
digits of a number, NaN and Infinity refused, a UTF-8 byte-order mark accepted.

Every file rangekit writes goes through :func:`atomic_output`: the data goes to a
temporary file created exclusively (``tempfile.mkstemp``: ``O_CREAT | O_EXCL``, a
random name, never following a link) in the target's folder, which is renamed over the
target only when it is complete and removed on any failure (a full disk included), so
an existing output is byte-identical after a failed run.

The path ``-`` is standard input (:func:`is_stdin`, :func:`read_stdin`): read once per
process and kept, within the same size caps as a file (a JSON input over
:data:`MAX_JSON_BYTES` is refused after that many bytes, without reading the rest); a
terminal is refused instead of waiting for typing. A sidecar is never searched for
``-``. :func:`check_output` refuses
an output that is a symbolic link, a directory, a device or a FIFO, or the same file
as one of the run's inputs. The rules are collected in ``docs/security.md``.

Examples
--------
>>> parse_json(b'\\xef\\xbb\\xbf{"a": [1, 2.5]}', name="x.json")
{'a': [1, 2.5]}
>>> parse_json('{"a": NaN}', name="x.json")
Traceback (most recent call last):
...
rangekit.errors.InputFileError: cannot read 'x.json' as JSON: NaN is not a number JSON allows
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import stat
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO, Any

from rangekit.errors import InputFileError, InvalidParameterError

__all__ = [
    "MAX_CSV_CELL",
    "MAX_JSON_BYTES",
    "MAX_JSON_DEPTH",
    "MAX_NUMBER_CHARS",
    "MAX_TABLE_BYTES",
    "atomic_output",
    "check_output",
    "default_mode",
    "is_stdin",
    "parse_json",
    "printable",
    "read_capped",
    "read_json_file",
    "read_stdin",
    "regular_file",
]

#: Largest JSON input file read, bytes (sidecars, calibrations, floor plans, beacons).
MAX_JSON_BYTES = 16 * 2**20
#: Deepest nesting of arrays and objects accepted in a JSON input.
MAX_JSON_DEPTH = 64
#: Largest CSV or JSON data table read (logs, series, batch results), bytes.
MAX_TABLE_BYTES = 512 * 2**20
#: Longest CSV cell accepted, characters.
MAX_CSV_CELL = 64 * 2**10
#: Most characters of one number in a JSON input (a 5,000-digit integer is refused).
MAX_NUMBER_CHARS = 40


def _kind(mode: int) -> str | None:
    """What a file of ``mode`` is, when it is not a regular file (None if it is)."""
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def regular_file(path: str | os.PathLike, *, what: str = "") -> os.stat_result:
    """The ``os.stat`` of ``path`` if it is a regular file (links followed), else an error.

    Nothing is opened: a FIFO or a device is refused without blocking or reading.

    Raises
    ------
    InputFileError
        Missing, a dangling link, a directory, a FIFO, a device, a socket, or not
        readable; the message names the file (``what`` is put before it, "template ").
    """
    p = os.fspath(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise InputFileError(f"cannot open {what}'{p}': no such file") from None
    except (OSError, ValueError) as e:  # ValueError: a NUL in the name
        raise InputFileError(
            f"cannot open {what}'{p}': {getattr(e, 'strerror', None) or e}"
        ) from None
    kind = _kind(st.st_mode)
    if kind is not None:
        raise InputFileError(f"cannot open {what}'{p}': it is {kind}, not a regular file")
    if not os.access(p, os.R_OK):
        raise InputFileError(f"cannot open {what}'{p}': permission denied")
    return st


#: Name of standard input as a path (``rangekit range - < x.wav``).
STDIN = "-"
#: The standard input last read: (stream, bytes so far, whether its end was reached).
_stdin_cache: tuple[object, bytes, bool] | None = None


def is_stdin(path: object) -> bool:
    """Whether ``path`` is ``-``, standard input (``./-`` is a file named ``-``)."""
    try:
        return os.fspath(path) == STDIN  # type: ignore[arg-type]
    except TypeError:
        return False


def read_stdin(
    limit: int, *, what: str = "", error: type[Exception] = InputFileError, hint: str = ""
) -> bytes:
    """All of standard input as bytes, refused once more than ``limit`` bytes arrive.

    Standard input is read once and kept: a second call in the same process (the same
    ``sys.stdin``) returns the same bytes, checked against its own ``limit``. A terminal
    is refused (nothing would arrive until the user typed a file). ``error`` is the
    class raised for input over the limit (``InputFileError``, exit 3, by default), with
    ``hint`` appended to its message.

    Raises
    ------
    InputFileError
        Standard input is closed, a terminal, or cannot be read.
    """
    import sys

    global _stdin_cache
    stream = sys.stdin
    label = f"{what}standard input"
    if _stdin_cache is not None and _stdin_cache[0] is stream:
        _, data, eof = _stdin_cache
    else:
        if stream is None:
            raise InputFileError(f"cannot read {label}: it is closed")
        try:
            tty = stream.isatty()
        except (OSError, ValueError):
            tty = False
        if tty:
            raise InputFileError(
                f"cannot read {label}: it is a terminal; redirect a file into it "
                "(`rangekit range - < x.wav`) or pipe one"
            )
        data, eof = b"", False
    if not eof and len(data) <= limit:
        raw = getattr(stream, "buffer", stream)
        chunks = [data]
        n = len(data)
        try:
            while n <= limit:
                b = raw.read(min(1 << 20, limit + 1 - n))
                if not b:
                    eof = True
                    break
                if isinstance(b, str):
                    b = b.encode("utf-8", "surrogateescape")
                chunks.append(b)
                n += len(b)
        except (OSError, ValueError) as e:
            msg = getattr(e, "strerror", None) or e
            raise InputFileError(f"cannot read {label}: {msg}") from None
        data = b"".join(chunks)
        _stdin_cache = (stream, data, eof)
    if len(data) > limit:
        raise error(
            f"cannot read {label}: more than the limit of {limit} bytes for this kind of "
            f"input{hint}"
        )
    return data


def read_capped(path: str | os.PathLike, limit: int, *, what: str = "") -> bytes:
    """The bytes of the regular file ``path``, refused before reading if over ``limit``.

    The file is opened non-blocking and checked again on the open descriptor, so a file
    swapped for a FIFO or a device between the check and the open is refused too.
    ``-`` is standard input (:func:`read_stdin`, the same limit).
    """
    if is_stdin(path):
        return read_stdin(limit, what=what)
    p = os.fspath(path)
    regular_file(p, what=what)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(p, flags)
    except OSError as e:
        raise InputFileError(f"cannot open {what}'{p}': {e.strerror or e}") from None
    try:
        st = os.fstat(fd)
        kind = _kind(st.st_mode)
        if kind is not None:
            raise InputFileError(f"cannot open {what}'{p}': it is {kind}, not a regular file")
        if st.st_size > limit:
            raise InputFileError(
                f"cannot read {what}'{p}': {st.st_size} bytes is more than the limit of "
                f"{limit} bytes for this kind of file"
            )
        chunks, n = [], 0
        while True:
            b = os.read(fd, min(1 << 20, limit + 1 - n))
            if not b:
                break
            chunks.append(b)
            n += len(b)
            if n > limit:
                raise InputFileError(
                    f"cannot read {what}'{p}': more than the limit of {limit} bytes"
                )
        return b"".join(chunks)
    except OSError as e:
        raise InputFileError(f"cannot read {what}'{p}': {e.strerror or e}") from None
    finally:
        os.close(fd)


_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.S)


def _depth(text: str) -> int:
    """Deepest nesting of ``[``/``{`` outside strings (a cheap scan before parsing)."""
    import numpy as np

    bare = _STRING.sub("", text).encode("utf-8", "surrogatepass")
    b = np.frombuffer(bare, dtype=np.uint8)
    step = np.isin(b, (0x5B, 0x7B)).astype(np.int64) - np.isin(b, (0x5D, 0x7D))
    return int(np.cumsum(step).max(initial=0))


def parse_json(data: bytes | str, *, name: str, error: type[Exception] = InputFileError) -> Any:
    """Parse JSON text with rangekit's limits; errors are InputFileError naming ``name``.

    Limits: nesting depth :data:`MAX_JSON_DEPTH`, numbers of at most
    :data:`MAX_NUMBER_CHARS` characters, finite numbers only (``NaN``, ``Infinity`` and
    overflowing literals such as ``1e400`` are refused). A UTF-8 byte-order mark is
    skipped; other encodings than UTF-8 are refused. ``error`` is the class raised
    (:class:`~rangekit.errors.LogFormatError` for data tables).
    """

    def bad(msg: str) -> Exception:
        return error(f"cannot read '{name}' as JSON: {msg}")

    if isinstance(data, bytes):
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError as e:
            raise bad(f"not UTF-8 text (byte {e.start})") from None
    else:
        text = data[1:] if data.startswith("\ufeff") else data
    if _depth(text) > MAX_JSON_DEPTH:
        raise bad(f"nested deeper than {MAX_JSON_DEPTH} levels")

    def number(s: str, conv):
        if len(s) > MAX_NUMBER_CHARS:
            raise bad(f"a number of {len(s)} characters (at most {MAX_NUMBER_CHARS})")
        v = conv(s)
        if isinstance(v, float) and v - v != 0.0:
            raise bad(f"the number {s} is out of range")
        return v

    def constant(s: str):
        raise bad(f"{s} is not a number JSON allows")

    try:
        return json.loads(
            text,
            parse_int=lambda s: number(s, int),
            parse_float=lambda s: number(s, float),
            parse_constant=constant,
        )
    except json.JSONDecodeError as e:
        raise bad(str(e)) from None
    except RecursionError:
        raise bad(f"nested deeper than {MAX_JSON_DEPTH} levels") from None


def read_json_file(path: str | os.PathLike, *, limit: int = MAX_JSON_BYTES, what: str = "") -> Any:
    """Read a JSON input file: :func:`read_capped` then :func:`parse_json`."""
    return parse_json(read_capped(path, limit, what=what), name=os.fspath(path))


# --- outputs -------------------------------------------------------------------------------


def printable(text: str) -> str:
    """``text`` with undecodable file-name bytes (surrogate escapes) as ``\\xNN``: valid
    UTF-8 for any output (a recording named with non-UTF-8 bytes, in a table or a
    message)."""
    try:
        text.encode("utf-8")
        return text
    except UnicodeEncodeError:
        pass
    try:
        raw = text.encode("utf-8", "surrogateescape")
    except UnicodeEncodeError:
        raw = text.encode("utf-8", "backslashreplace")
    return raw.decode("utf-8", "backslashreplace")


def _same(a: os.stat_result, b: os.stat_result) -> bool:
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


def check_output(path: str | os.PathLike, inputs: Iterable[str | os.PathLike] = ()) -> Path:
    """``path`` as a Path if an output may be written there; else the reason as an error.

    Raises
    ------
    InvalidParameterError
        ``path`` is a symbolic link, a directory, a device, a FIFO or a socket, or the
        same file (same inode, hard links included) as one of ``inputs`` (exit 2).
    InputFileError
        The folder of ``path`` does not exist (exit 3).
    """
    p = Path(path)
    try:
        st = os.lstat(p)
    except FileNotFoundError:
        st = None
    except (OSError, ValueError) as e:
        raise InputFileError(f"cannot write '{p}': {getattr(e, 'strerror', None) or e}") from None
    if st is not None:
        if stat.S_ISLNK(st.st_mode):
            raise InvalidParameterError(
                f"-o '{p}' is a symbolic link: refusing to write through it (give the real path)"
            )
        kind = _kind(st.st_mode)
        if kind is not None:
            raise InvalidParameterError(f"-o '{p}' is {kind}: the output must be a regular file")
        for i in inputs:
            try:
                si = os.stat(i)
            except (OSError, ValueError, TypeError):
                continue
            if _same(st, si):
                raise InvalidParameterError(
                    f"-o '{p}' is the input '{os.fspath(i)}': refusing to overwrite an input"
                )
    parent = p.parent
    if not parent.is_dir():
        raise InputFileError(f"cannot write '{p}': folder '{parent}' does not exist")
    return p


def default_mode() -> int:
    """The mode of a new file under the current umask (``0o666 & ~umask``)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike, *, text: bool = False) -> Iterator[IO]:
    """A file object whose content replaces ``path`` atomically when the block ends.

    The temporary file is created by ``tempfile.mkstemp`` in the target's folder
    (exclusive, random name, mode 0666 less the umask once complete), renamed over
    ``path`` at the end and removed if the block raises (the target is then unchanged).
    ``path`` is checked by :func:`check_output` first (no link, no device, no directory).
    A write error (a full disk) becomes :class:`InputFileError` naming ``path``.
    """
    p = check_output(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".part", dir=p.parent)
    done = False
    try:
        mode = "w" if text else "wb"
        kw = {"encoding": "utf-8", "newline": ""} if text else {}
        with os.fdopen(fd, mode, **kw) as f:
            yield f
            f.flush()
        os.chmod(tmp, default_mode())
        os.replace(tmp, p)
        done = True
    except OSError as e:
        if isinstance(e, InputFileError):
            raise
        raise InputFileError(f"cannot write '{p}': {e.strerror or e}") from e
    finally:
        if not done:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
