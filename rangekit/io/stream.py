"""Writing rows as they are produced: the streaming results writer of a series.

:class:`RowWriter` takes rows block by block (one list per exchange or window, as
:class:`rangekit.ranging.run.RangeRun` yields them). CSV rows are written as they come and
flushed once per block, to standard output or to a temporary ``.FILE.<random>.part``
beside ``FILE`` that is renamed over it only when every block is written (a failure never
leaves a half file at FILE, and removes the part file). Table and JSON are collected and
written at the end (atomically to a file). The number rules are
:func:`rangekit.io.results.format_rows`'.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Protocol

from rangekit.errors import InputFileError, InvalidParameterError

__all__ = ["ProgressBar", "RowWriter"]


class ProgressBar(Protocol):
    """What :class:`RowWriter` needs of a progress display (the command line's progress bar)."""

    done: float

    def update(self, n: float) -> None: ...

    def close(self) -> None: ...


class RowWriter:
    """Write rows of ``fields`` in ``fmt`` (table, json or csv) to ``output`` or stdout.

    Parameters
    ----------
    fields : sequence of str
        Column order (CSV header, table columns).
    fmt : {"table", "json", "csv"}
    output : str, optional
        File to write (atomically); None or ``-`` is standard output.
    bar : callable, optional
        ``bar(total_s)`` makes the progress display, on the first :meth:`progress` call.

    Examples
    --------
    >>> import io
    >>> out = io.StringIO()
    >>> w = RowWriter(("a", "distance_m"), "csv", None, stdout=out)
    >>> w.write([[{"a": 0, "distance_m": 2.0}], [{"a": 1, "distance_m": None}]], {})
    >>> print(out.getvalue(), end="")
    a,distance_m
    0,2.000000
    1,
    """

    def __init__(
        self,
        fields: Sequence[str],
        fmt: str,
        output: str | None,
        *,
        bar: Callable[[float], ProgressBar] | None = None,
        stdout=None,
    ) -> None:
        if fmt not in ("table", "json", "csv"):
            raise InvalidParameterError(f"fmt={fmt!r} must be table, json or csv")
        self.fields = tuple(fields)
        self.fmt = fmt
        self.output = None if output == "-" else output
        self._make_bar = bar
        self._stdout = stdout
        self._buf: list[str] = []
        self._file = None
        self._tmp: Path | None = None
        self._bar: ProgressBar | None = None
        self._header = False

    def progress(self, done_s: float, total_s: float) -> None:
        """Progress callback of a series: flush the block's CSV rows, advance the display."""
        self.flush()
        if self._make_bar is None:
            return
        if self._bar is None:
            self._bar = self._make_bar(total_s)
        self._bar.update(done_s - self._bar.done)

    def close_progress(self) -> None:
        """End the progress display (before a report line on stderr)."""
        if self._bar is not None:
            self._bar.close()

    def _out(self):
        return sys.stdout if self._stdout is None else self._stdout

    def _open(self) -> None:
        if self.output is None or self._file is not None:
            return
        import tempfile

        from rangekit.io.guard import check_output

        p = check_output(self.output)
        try:  # exclusive, random name, in the target's folder (rangekit.io.guard)
            fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".part", dir=p.parent)
            self._tmp = Path(tmp)
            self._file = open(fd, "w", encoding="utf-8", newline="")
        except OSError as e:
            raise InputFileError(f"cannot write '{p}': {e.strerror or e}") from e

    def flush(self) -> None:
        """Write the buffered CSV text (one block's rows) and flush it.

        Standard output closed by its reader (``| head``) raises BrokenPipeError after
        pointing stdout at the null device (so that the interpreter's exit is quiet).
        """
        if not self._buf:
            return
        from rangekit.io.guard import printable

        text = printable("".join(self._buf))
        self._buf.clear()
        if self._file is None:
            out = self._out()
            try:
                out.write(text)
                out.flush()
            except BrokenPipeError:
                if self._stdout is None:
                    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
                raise
        else:
            try:
                self._file.write(text)
                self._file.flush()
            except OSError as e:  # a full disk: the .part file is removed by write()
                raise InputFileError(f"cannot write '{self.output}': {e.strerror or e}") from e

    def _csv(self, rows: list[dict]) -> None:
        from rangekit.io.results import format_rows

        text = format_rows(rows, self.fields, "csv")
        if self._header:
            text = text.split("\n", 1)[1]
        self._header = True
        self._buf.append(text)

    def write(self, blocks: Iterable[list[dict]], meta: dict) -> None:
        """Consume ``blocks`` (lists of rows) and write them; ``meta`` heads the JSON
        object (read at the end: it may be completed while the blocks are produced)."""
        from rangekit.io.results import format_rows

        collected: list[dict] = []
        ok = False
        try:
            if self.fmt == "csv":
                self._open()
            for rows in blocks:
                if self.fmt == "csv":
                    self._csv(rows)
                else:
                    collected.extend(rows)
            if self.fmt == "csv":
                if not self._header:
                    self._csv([])
                self.flush()
            ok = True
        finally:
            self.close_progress()
            if self._file is not None:
                self._finish_file(ok)
        if self.fmt != "csv":
            kw = {"meta": meta, "key": "ranges"} if self.fmt == "json" else {}
            self._emit(format_rows(collected, self.fields, self.fmt, **kw))

    def _finish_file(self, ok: bool) -> None:
        try:
            self._file.close()
            if ok:
                from rangekit.io.guard import default_mode

                os.chmod(self._tmp, default_mode())
                os.replace(self._tmp, self.output)
        except OSError as e:
            ok = False
            raise InputFileError(f"cannot write '{self.output}': {e.strerror or e}") from e
        finally:
            if not ok:
                self._tmp.unlink(missing_ok=True)

    def _emit(self, text: str) -> None:
        """The whole text, atomically to the file or to standard output."""
        from rangekit.io.guard import printable

        text = printable(text)
        if self.output is None:
            out = self._out()
            out.write(text if text.endswith("\n") else text + "\n")
            out.flush()
        else:
            from rangekit.io.sidecar import write_text_atomic

            write_text_atomic(self.output, text)
