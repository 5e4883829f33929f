"""The results file of a batch: its columns and their types, rows written as CSV or JSON
Lines, the metadata file beside it, appending whole sessions, resuming after an
interruption (:class:`ResultsFile`) and reading it back (:func:`iter_rows`)."""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from rangekit.batch._options import BatchOptions
from rangekit.batch._sessions import _printable
from rangekit.errors import InputFileError, InvalidParameterError, RangekitError

#: Columns of a batch results file, in order (``docs/formats.md``, "Batch results").
BATCH_COLUMNS = (
    "session",
    "session_rows",
    "status",
    "error",
    "scheme",
    "files",
    "a",
    "b",
    "window",
    "tx",
    "channel",
    "distance_m",
    "sigma_m",
    "true_distance_m",
    "snr_db",
    "arrival_s",
    "flags",
)


#: Type of each column (``docs/formats.md``, "Batch results"): JSON values, and what a CSV
#: cell holds (``list`` cells are the items joined by :data:`LIST_SEPARATOR`). Every column
#: may be null (an empty CSV cell) except ``session``, ``session_rows``, ``status`` and
#: ``scheme``.
COLUMN_TYPES = {
    "session": "str",
    "session_rows": "int",
    "status": "str",
    "error": "str",
    "scheme": "str",
    "files": "list",
    "a": "int",
    "b": "int",
    "window": "int",
    "tx": "int",
    "channel": "int",
    "distance_m": "float",
    "sigma_m": "float",
    "true_distance_m": "float",
    "snr_db": "float",
    "arrival_s": "float",
    "flags": "list",
}
#: How a list (``files``, ``flags``) is joined in a CSV cell; the same as in every other
#: CSV rangekit writes (``rangekit range``, ``detect``).
LIST_SEPARATOR = ";"
#: ``format`` of the metadata file beside a results file.
META_FORMAT = "rangekit-batch-meta"
META_VERSION = 2


def meta_path(results: str | os.PathLike) -> Path:
    """The metadata file of a results file: ``RESULTS.meta.json`` beside it, ``RESULTS``
    the results file's whole name (``r.csv`` and ``r.jsonl`` in one folder do not share
    one).

    >>> meta_path("out/day1.csv").as_posix(), meta_path("r.jsonl").name
    ('out/day1.csv.meta.json', 'r.jsonl.meta.json')
    """
    p = Path(results)
    return p.with_name(p.name + ".meta.json")


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v) if v == v else ""
    if isinstance(v, (list, tuple)):
        return LIST_SEPARATOR.join(_printable(str(t)) for t in v)
    return _printable(str(v))


def _csv_line(row: dict[str, Any]) -> str:
    import csv
    import io

    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow([_cell(row[c]) for c in BATCH_COLUMNS])
    return buf.getvalue()


def _json_value(v: Any) -> Any:
    if isinstance(v, float) and v != v:
        return None
    if isinstance(v, str):
        return _printable(v)
    if isinstance(v, (list, tuple)):
        return [_json_value(t) for t in v]
    return v


def _json_line(row: dict[str, Any]) -> str:
    clean = {c: _json_value(row[c]) for c in BATCH_COLUMNS}
    return json.dumps(clean, allow_nan=False) + "\n"


#: First lines of results files written before the metadata file (version 1): a CSV
#: comment, a JSONL object of another schema. Such files are refused by ``--resume``.
_OLD_HEADS = ("# rangekit batch ", '{"rangekit_batch"')


class ResultsFile:
    """A batch's results file (CSV or JSON Lines), appended one session at a time.

    The file holds rows only (CSV: a plain header row first), so that ``csv.DictReader``,
    ``pandas.read_csv`` and a JSON Lines reader take it as it is; the batch's options are
    in its metadata file ``RESULTS.meta.json`` beside it (:func:`meta_path`), written
    atomically before the first row. Each finished session is appended as its rows in
    one ``write`` on a file opened for appending, so a batch killed at any moment leaves
    whole sessions plus at most one torn tail, which ``resume=True`` cuts off (a tail is
    torn when its last line lacks its newline or its session has fewer rows than its
    ``session_rows``). When the batch completes, :meth:`finish` rewrites the file
    atomically in session order, so a resumed batch ends with the same file as an
    uninterrupted one.

    Parameters
    ----------
    path : str or os.PathLike
        ``.csv`` or ``.jsonl`` (the format follows the suffix).
    options : BatchOptions
        Written into the metadata file; a resumed file must have been written with the
        same.
    resume : bool
        Continue an existing file (skip its finished sessions). Without it an existing
        file is an error (nothing is overwritten).

    Raises
    ------
    InvalidParameterError
        Unknown suffix; an existing file without ``resume``; resuming a file written
        with other options, without its metadata file, by a rangekit older than the
        metadata file, or that is not a batch results file; a file in the metadata
        file's place that is not one.
    InputFileError
        The folder does not exist or the file cannot be written.
    """

    def __init__(self, path: str | os.PathLike, options: BatchOptions, *, resume: bool) -> None:
        self.path = Path(path)
        suf = self.path.suffix.lower()
        if suf not in (".csv", ".jsonl"):
            raise InvalidParameterError(
                f"'{self.path}': the results file must end in .csv or .jsonl (got "
                f"{suf or 'no suffix'!r})"
            )
        self.fmt = suf[1:]
        self.head = ",".join(BATCH_COLUMNS) + "\n" if self.fmt == "csv" else ""
        self.meta_path = meta_path(self.path)
        self.meta = {
            "format": META_FORMAT,
            "version": META_VERSION,
            "results": self.path.name,
            "columns": {c: COLUMN_TYPES[c] for c in BATCH_COLUMNS},
            "list_separator": LIST_SEPARATOR,
            "options": json.loads(options.fingerprint()),
        }
        self.done: dict[str, list[str]] = {}  # session -> its lines, in file order
        self.status: dict[str, str] = {}  # session -> "ok" or "error"
        self.errors: dict[str, str] = {}  # failed session -> its message
        from rangekit.io.guard import check_output

        check_output(self.path)  # no link, device or directory; the folder exists
        check_output(self.meta_path)
        if self.path.exists():
            if not resume:
                raise InvalidParameterError(
                    f"'{self.path}' exists: pass --resume to continue that batch, or choose "
                    "another output file (nothing was overwritten)"
                )
            self._recover()
        else:
            self._claim_meta()
            self._write_meta()
            self._write_new(self.head)
        try:
            nofollow = getattr(os, "O_NOFOLLOW", 0)
            self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | nofollow)
        except OSError as e:
            raise InputFileError(f"cannot write '{self.path}': {e.strerror or e}") from e

    def _read_meta(self) -> Any:
        """The metadata file's object (None if there is none)."""
        if not os.path.lexists(self.meta_path):
            return None
        from rangekit.io.guard import read_json_file

        try:
            return read_json_file(self.meta_path)
        except RangekitError:
            return {}

    def _claim_meta(self) -> None:
        """Refuse a new batch whose metadata file would replace a file that is not a
        batch's metadata (one left by a batch whose results file was deleted is)."""
        old = self._read_meta()
        if old is None:
            return
        if isinstance(old, dict) and old.get("format") == META_FORMAT:
            return  # left by a batch whose results file is gone
        raise InvalidParameterError(
            f"'{self.meta_path}' exists and is not a rangekit batch metadata file: choose "
            "another output name (nothing was overwritten)"
        )

    def _write_meta(self) -> None:
        from rangekit.io.sidecar import write_text_atomic

        write_text_atomic(self.meta_path, json.dumps(self.meta, indent=2) + "\n")

    def _write_new(self, text: str) -> None:
        try:
            with open(self.path, "x", encoding="utf-8") as f:
                f.write(text)
        except OSError as e:
            raise InputFileError(f"cannot write '{self.path}': {e.strerror or e}") from e

    def _parse(self, line: str) -> tuple[str, int, str, str]:
        """(session, session_rows, status, error) of one data line; ValueError if it is not
        one."""
        if self.fmt == "jsonl":
            obj = json.loads(line)
            error = str(obj["error"] or "")
            return str(obj["session"]), int(obj["session_rows"]), str(obj["status"]), error
        import csv

        cells = next(csv.reader([line]))
        if len(cells) != len(BATCH_COLUMNS):
            raise ValueError("wrong number of cells")
        return cells[0], int(cells[1]), cells[2], cells[3]

    def _check_resumable(self, text: str) -> None:
        """Refuse to resume a file this batch did not write (one line, exit 2)."""
        first = text.split("\n", 1)[0]
        cannot = f"cannot resume '{self.path}'"
        if first.startswith(_OLD_HEADS):
            raise InvalidParameterError(
                f"{cannot}: it was written by an older rangekit (options in its first line, "
                "no metadata file); finish it with that version or start a new -o file"
            )
        meta = self._read_meta()
        if meta is None:
            raise InvalidParameterError(
                f"{cannot}: its metadata file '{self.meta_path}' is missing (a batch "
                "results file has one beside it); write a new file"
            )
        if not isinstance(meta, dict) or meta.get("format") != META_FORMAT:
            raise InvalidParameterError(
                f"{cannot}: '{self.meta_path}' is not a rangekit batch metadata file; "
                "write a new file"
            )
        if meta != self.meta:
            what = "another results file" if meta.get("results") != self.path.name else None
            raise InvalidParameterError(
                f"{cannot}: its metadata file '{self.meta_path}' describes "
                f"{what or 'a batch with other options'}; rerun with the same options, or "
                "write a new file"
            )
        if not text.startswith(self.head):
            raise InvalidParameterError(
                f"{cannot}: its first line is not the header of a batch results file; "
                "write a new file"
            )

    def _recover(self) -> None:
        """Read a resumed file: keep whole sessions, cut a torn tail off the file."""
        try:
            data = self.path.read_bytes()
        except OSError as e:
            raise InputFileError(f"cannot read '{self.path}': {e.strerror or e}") from e
        import csv

        self._check_resumable(data.decode("utf-8", errors="replace"))
        pos = len(self.head.encode("utf-8"))
        keep = pos
        pending: list[str] = []
        pending_name, pending_n = None, 0
        for raw in data[pos:].splitlines(keepends=True):
            if not raw.endswith(b"\n"):
                break  # torn last line
            try:
                line = raw.decode("utf-8")
                name, n, status, error = self._parse(line)
            except (ValueError, KeyError, TypeError, StopIteration, csv.Error):
                break
            if name != pending_name:
                pending, pending_name, pending_n = [], name, n
            pending.append(line)
            pos += len(raw)
            if len(pending) == pending_n:
                self.done[name] = pending
                self.status[name] = status
                if status == "error":
                    self.errors[name] = error
                keep = pos
                pending_name = None
        if keep < len(data):
            try:
                os.truncate(self.path, keep)
            except OSError as e:
                raise InputFileError(f"cannot write '{self.path}': {e.strerror or e}") from e

    def append(self, rows: Sequence[dict[str, Any]]) -> None:
        """Append one session's rows with a single write."""
        line = _csv_line if self.fmt == "csv" else _json_line
        lines = [line(r) for r in rows]
        blob = "".join(lines).encode("utf-8")
        view = memoryview(blob)
        while view:
            try:
                n = os.write(self._fd, view)
            except OSError as e:  # a full disk: what is written so far stays resumable
                raise InputFileError(f"cannot write '{self.path}': {e.strerror or e}") from e
            view = view[n:]
        name = str(rows[0]["session"])
        self.done[name] = lines
        self.status[name] = str(rows[0]["status"])
        if self.status[name] == "error":
            self.errors[name] = str(rows[0]["error"])

    def finish(self, order: Sequence[str]) -> None:
        """Rewrite the file atomically with the sessions in ``order`` (others after, by name)."""
        self.close()
        rank = {n: i for i, n in enumerate(order)}
        names = sorted(self.done, key=lambda n: (rank.get(n, len(rank)), n))
        text = self.head + "".join(line for n in names for line in self.done[n])
        from rangekit.io.sidecar import write_text_atomic

        write_text_atomic(self.path, text)

    def close(self) -> None:
        if getattr(self, "_fd", None) is not None:
            os.close(self._fd)
            self._fd = None


def iter_rows(path: str | os.PathLike) -> Iterable[dict[str, Any]]:
    """The data rows of a batch results file as dicts: JSON values from JSON Lines, the
    cells as strings from CSV. Reads files of the older layout too (their first line,
    the options, is skipped)."""
    p = Path(path)
    lines = p.read_text(encoding="utf-8").splitlines()
    if lines and lines[0].startswith(_OLD_HEADS):
        lines = lines[1:]
    if p.suffix.lower() == ".jsonl":
        for line in lines:
            if line.strip():
                yield json.loads(line)
        return
    import csv

    yield from csv.DictReader(lines)
