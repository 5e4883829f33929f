"""Batch ranging of recording archives: sessions, parallel workers, a resumable results file.

A *session* is one ranging run: the recordings of one two-way exchange (one multichannel
file, or one mono file per device), or one ultrasonic log. :func:`find_sessions` groups
the inputs into sessions, :func:`run_session` ranges one (a failure becomes an error row,
never an exception), and :func:`run_batch` runs many in parallel -- in local processes or
on a Dask cluster -- appending each finished session to a :class:`ResultsFile` so that a
batch killed at any moment loses no finished result and can be resumed.

Grouping rules (``docs/batch.md``)
---------------------------------
1. **Sidecar.** A ``.json`` file with a ``"files"`` list (names relative to its folder;
   what ``rangekit synth`` writes) makes those files one session, named after the
   sidecar (its path without ``.json``). Sidecars are those in the folders searched and
   those next to an input file that is one of their ``files``. From the sidecar rangekit
   also takes ``scheme``, ``beep`` (the beep's parameters), ``temp_c``, the
   self-distances (a top-level ``self_distance_m``, number or list, or
   ``devices[i].self_distance_m``) and the true distances
   ``pairs[k] = {"a", "b", "distance_m"}`` (the ``true_distance_m`` column).
   For ``oneway`` and ``echo`` sidecars (``rangekit synth oneway|echo``): ``period_s``,
   ``latency_s`` (oneway) and the true distances of ``windows[k]`` (``distances_m`` per
   receiver, or the echo's ``distance_m``). Sidecar values override the command's
   options for that session.
2. **Naming rule.** Among the files no sidecar claims, ``NAME_dev0.wav``,
   ``NAME_dev1.wav``, ... in one folder (indices 0..N-1, no gap, N >= 2) are the mono
   recordings of devices 0..N-1 of session ``NAME``.
3. Every other audio file is a session of its own.
4. **Device folders paired by name** (:func:`pair_sessions_by_name`, ``rangekit batch
   --pair-by-name DIR0 DIR1 ...``; replaces rules 1-3). Folder i holds device i's mono
   recordings. Each recording (any of :data:`AUDIO_SUFFIXES`, searched recursively, names
   starting with ``.`` skipped) is keyed by its path relative to its folder without the
   suffix, case-sensitively (``dev1/day1/take_01.wav`` and ``dev2/day1/take_01.flac``:
   key ``day1/take_01``). Each key is one BeepBeep session named by the key, with the
   folders' files in device order; a key missing from some folder gives a session that
   fails naming those folders (nothing is dropped silently). Two files of one folder with
   the same key are an error. A sidecar ``KEY.json`` beside device 0's file gives the
   values of rule 1 (its ``files`` are ignored: the names decide).

Examples
--------
>>> rows = run_session(Session("missing", ("no_such.wav",)), BatchOptions())
>>> rows[0]["status"], rows[0]["error"].startswith("cannot open")
('error', True)
"""

from __future__ import annotations

import glob
import json
import os
import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rangekit.errors import InputFileError, InvalidParameterError, RangekitError

__all__ = [
    "AUDIO_SUFFIXES",
    "BATCH_COLUMNS",
    "BatchOptions",
    "BatchSummary",
    "ResultsFile",
    "Session",
    "find_sessions",
    "iter_rows",
    "pair_sessions_by_name",
    "run_batch",
    "run_session",
]

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
#: File suffixes taken as recordings when a folder or glob is expanded.
AUDIO_SUFFIXES = (".wav", ".flac", ".ogg", ".aif", ".aiff")
SCHEMES = ("beepbeep", "oneway", "echo")
#: Seconds to wait for a Dask scheduler to answer before giving up.
DASK_CONNECT_TIMEOUT_S = 10.0

_DEV_RE = re.compile(r"^(?P<name>.+)_dev(?P<i>\d+)$")


@dataclass(frozen=True)
class Session:
    """One ranging run: its name (unique in a batch), files and what its sidecar says."""

    name: str
    files: tuple[str, ...]
    scheme: str | None = None
    params: dict[str, Any] = field(default_factory=dict)
    truth: tuple[tuple[int, int, float], ...] = ()
    problem: str | None = None

    # ``truth`` holds (a, b, distance) for BeepBeep pairs and (window, channel, distance)
    # for ultrasonic windows.


@dataclass(frozen=True)
class BatchOptions:
    """How sessions without a sidecar value are ranged.

    ``scheme`` is the default scheme; ``beepbeep`` holds the keyword arguments of
    :func:`rangekit.ranging.range_files` (``beep``, ``detector``, ``temp_c``,
    ``speed_m_s``, ``self_distance_m``, ``clock_ppm``); ``oneway`` and ``echo`` those of
    :func:`rangekit.ranging.ultrasonic.range_ultrasonic_files` except ``scheme``, for the
    sessions of each scheme. ``pair_by_name`` changes no ranging: set it when the sessions
    come from :func:`pair_sessions_by_name`, so that the results file records it and a
    resume with sessions grouped by rules 1-3 (other names, which would mix) is refused.
    """

    scheme: str = "beepbeep"
    beepbeep: dict[str, Any] = field(default_factory=dict)
    oneway: dict[str, Any] = field(default_factory=dict)
    echo: dict[str, Any] = field(default_factory=dict)
    pair_by_name: bool = False

    def __post_init__(self) -> None:
        if self.scheme not in SCHEMES:
            raise InvalidParameterError(f"scheme={self.scheme!r} must be one of {SCHEMES}")

    def fingerprint(self) -> str:
        """A stable text of every option that changes results (checked on resume)."""
        parts: dict[str, Any] = {
            "scheme": self.scheme,
            "beepbeep": {k: repr(v) for k, v in sorted(self.beepbeep.items())},
            "oneway": {k: repr(v) for k, v in sorted(self.oneway.items())},
            "echo": {k: repr(v) for k, v in sorted(self.echo.items())},
        }
        if self.pair_by_name:  # only then, so that other batches' files still resume
            parts["grouping"] = "pair-by-name"
        return json.dumps(parts, sort_keys=True)


# --- finding sessions ---------------------------------------------------------------------


def _expand(inputs: Sequence[str | os.PathLike]) -> tuple[list[Path], list[Path], set[Path]]:
    """Audio files and JSON files named by ``inputs`` (files, folders, globs), and the
    JSON files found only as neighbours of an input file (resolved paths)."""
    audio: list[Path] = []
    jsons: list[Path] = []

    def add(p: Path, explicit: bool) -> None:
        suf = p.suffix.lower()
        if suf == ".json":
            jsons.append(p)
        elif suf in AUDIO_SUFFIXES or explicit:
            audio.append(p)

    for raw in inputs:
        text = os.fspath(raw)
        p = Path(text)
        if p.is_dir():
            for q in sorted(p.rglob("*")):
                if q.is_file() and not q.name.startswith("."):
                    add(q, False)
        elif p.exists():
            add(p, True)
        elif glob.has_magic(text):
            hits = sorted(glob.glob(text, recursive=True))
            if not hits:
                raise InputFileError(f"'{text}' matches no file")
            for h in hits:
                q = Path(h)
                if q.is_dir():
                    for r in sorted(q.rglob("*")):
                        if r.is_file() and not r.name.startswith("."):
                            add(r, False)
                elif q.is_file():
                    add(q, False)
        else:
            raise InputFileError(f"cannot open '{text}': no such file or folder")
    # A folder next to an explicit file may hold its sidecar.
    seen = {q.resolve() for q in jsons}
    neighbours: set[Path] = set()
    for folder in sorted({q.parent for q in audio}):
        for j in sorted(folder.glob("*.json")):
            if j.resolve() not in seen:
                seen.add(j.resolve())
                neighbours.add(j.resolve())
                jsons.append(j)
    return _unique(audio), _unique(jsons), neighbours


def _unique(paths: list[Path]) -> list[Path]:
    out, seen = [], set()
    for p in paths:
        r = p.resolve()
        if r not in seen:
            seen.add(r)
            out.append(p)
    return out


def _sidecar_session(path: Path, obj: dict) -> Session:
    """The session a sidecar describes (``problem`` set when it cannot be ranged)."""
    name = str(path.with_suffix(""))
    files = obj["files"]
    if not isinstance(files, list) or not files or not all(isinstance(f, str) for f in files):
        return Session(name, (str(path),), problem=f"'{path}': 'files' must be a list of names")
    paths = tuple(str(path.parent / f) for f in files)
    scheme = obj.get("scheme")
    if scheme is not None and scheme not in SCHEMES:
        return Session(
            name, paths, problem=f"'{path}': scheme {scheme!r} is not one of {', '.join(SCHEMES)}"
        )
    params, truth = _sidecar_values(obj, scheme)
    return Session(name, paths, scheme=scheme, params=params, truth=truth)


def _sidecar_values(
    obj: dict, scheme: str | None
) -> tuple[dict[str, Any], tuple[tuple[int, int, float], ...]]:
    """The ranging parameters and true distances a sidecar gives (rule 1 of the module
    docstring), for a session of ``scheme``; keys of the wrong type are ignored."""
    params: dict[str, Any] = {}
    if isinstance(obj.get("beep"), dict):
        params["beep"] = dict(obj["beep"])
    if isinstance(obj.get("temp_c"), (int, float)):
        params["temp_c"] = float(obj["temp_c"])
    sd = obj.get("self_distance_m")
    devices = obj.get("devices")
    if isinstance(sd, (int, float)) or (
        isinstance(sd, list) and all(isinstance(v, (int, float)) for v in sd)
    ):
        params["self_distance_m"] = sd
    elif isinstance(devices, list) and all(
        isinstance(d, dict) and isinstance(d.get("self_distance_m"), (int, float)) for d in devices
    ):
        params["self_distance_m"] = [float(d["self_distance_m"]) for d in devices]
    for key in ("period_s", "latency_s"):
        if scheme in ("oneway", "echo") and isinstance(obj.get(key), (int, float)):
            params[key] = float(obj[key])
    truth = []
    for w in obj.get("windows") or ():
        if not isinstance(w, dict) or not isinstance(w.get("window"), int):
            continue
        if scheme == "oneway" and isinstance(w.get("distances_m"), list):
            truth += [
                (w["window"], c, float(d))
                for c, d in enumerate(w["distances_m"])
                if isinstance(d, (int, float))
            ]
        elif scheme == "echo" and isinstance(w.get("distance_m"), (int, float)):
            truth.append((w["window"], 0, float(w["distance_m"])))
    for p in obj.get("pairs") or ():
        if isinstance(p, dict) and all(isinstance(p.get(k), (int, float)) for k in "ab"):
            d = p.get("distance_m")
            if isinstance(d, (int, float)):
                truth.append((int(p["a"]), int(p["b"]), float(d)))
    return params, tuple(truth)


def find_sessions(inputs: Sequence[str | os.PathLike]) -> list[Session]:
    """Group files, folders and globs into sessions (rules in the module docstring).

    Folders are searched recursively; files and folders whose names start with ``.`` are
    skipped. Sessions are returned sorted by name.

    Raises
    ------
    InputFileError
        If an input does not exist (or a glob matches nothing), or no recording is found.
    """
    audio, jsons, neighbours = _expand(inputs)
    given = {p.resolve() for p in audio}
    sessions: list[Session] = []
    claimed: set[Path] = set()
    for j in jsons:
        try:
            obj = json.loads(j.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            continue  # not a sidecar (e.g. a floor plan that is not ours to judge)
        if not isinstance(obj, dict) or "files" not in obj:
            continue
        s = _sidecar_session(j, obj)
        if j.resolve() in neighbours and not given & {Path(f).resolve() for f in s.files}:
            continue  # a sidecar next to an input, of recordings that were not asked for
        sessions.append(s)
        claimed.update(Path(f).resolve() for f in s.files)
    rest = [p for p in audio if p.resolve() not in claimed]
    groups: dict[tuple[Path, str], dict[int, Path]] = {}
    singles: list[Path] = []
    for p in rest:
        m = _DEV_RE.match(p.stem)
        if m is None:
            singles.append(p)
        else:
            groups.setdefault((p.parent, m["name"]), {})[int(m["i"])] = p
    for (folder, name), devs in groups.items():
        idx = sorted(devs)
        if len(idx) >= 2 and idx == list(range(len(idx))):
            files = tuple(str(devs[i]) for i in idx)
            sessions.append(Session(str(folder / name), files))
        else:
            singles.extend(devs.values())
    sessions.extend(Session(str(p), (str(p),)) for p in singles)
    if not sessions:
        shown = ", ".join(os.fspath(i) for i in inputs[:3])
        raise InputFileError(f"no recordings found in {shown}{' ...' if len(inputs) > 3 else ''}")
    sessions.sort(key=lambda s: s.name)
    names = [s.name for s in sessions]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise InputFileError(f"two sessions share the name {sorted(dup)[0]!r}")
    return sessions


def pair_sessions_by_name(folders: Sequence[str | os.PathLike]) -> list[Session]:
    """Pair the mono recordings of one folder per device by their names (rule 4).

    Every recording in ``folders[i]`` (searched recursively; names starting with ``.``
    skipped) is device i's, keyed by its path relative to the folder without the suffix.
    Each key is one BeepBeep session named by the key (``day1/take_01``) whose files are
    the folders' recordings of that key in device order; the rule in full is in the module
    docstring and ``docs/batch.md``.

    Parameters
    ----------
    folders : sequence of str or os.PathLike
        Two or more device folders, in device order (``folders[0]`` holds device 0).

    Returns
    -------
    list of Session
        Sorted by name, every one with ``scheme="beepbeep"``. A key missing from some
        folder gives a session whose ``problem`` names those folders (an error row in a
        batch); a sidecar ``KEY.json`` beside device 0's recording gives its parameters
        and true distances (its ``files`` are ignored).

    Raises
    ------
    InvalidParameterError
        Fewer than 2 folders, or a folder given twice or inside another.
    InputFileError
        A folder that does not exist or is not a folder; two recordings of one folder
        with the same key (``take_01.wav`` and ``take_01.flac``); no recording at all.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     for f in ("alice/take_01.wav", "alice/day2/take_02.flac", "bob/take_01.wav",
    ...               "bob/day2/take_02.wav", "bob/take_03.wav"):
    ...         (Path(tmp) / f).parent.mkdir(parents=True, exist_ok=True)
    ...         (Path(tmp) / f).touch()
    ...     sessions = pair_sessions_by_name([Path(tmp) / "alice", Path(tmp) / "bob"])
    >>> for s in sessions:
    ...     print(s.name, [Path(f).name for f in s.files], s.problem is not None)
    day2/take_02 ['take_02.flac', 'take_02.wav'] False
    take_01 ['take_01.wav', 'take_01.wav'] False
    take_03 ['take_03.wav'] True
    >>> sessions[2].problem.endswith("alice' (device 0)")
    True
    """
    folders = list(folders)
    if len(folders) < 2:
        raise InvalidParameterError(
            f"pairing by name needs at least 2 device folders, got {len(folders)}"
        )
    roots = [Path(f) for f in folders]
    for root in roots:
        if not root.exists():
            raise InputFileError(f"cannot open '{root}': no such folder")
        if not root.is_dir():
            raise InputFileError(
                f"'{root}' is not a folder: pairing by name takes one folder per device"
            )
    resolved = [r.resolve() for r in roots]
    for i, a in enumerate(resolved):
        for j, b in enumerate(resolved):
            if i < j and a == b:
                raise InvalidParameterError(f"device folder '{roots[j]}' is given twice")
            if i != j and a in b.parents:
                raise InvalidParameterError(
                    f"device folder '{roots[j]}' is inside device folder '{roots[i]}'"
                )
    keyed: list[dict[str, Path]] = []
    for root in roots:
        found: dict[str, Path] = {}
        for q in sorted(root.rglob("*")):
            rel = q.relative_to(root)
            if any(part.startswith(".") for part in rel.parts):
                continue
            if q.suffix.lower() not in AUDIO_SUFFIXES or not q.is_file():
                continue
            key = rel.with_suffix("").as_posix()
            if key in found:
                raise InputFileError(
                    f"'{found[key]}' and '{q}' have the same name {key!r} (pairing by name "
                    "ignores the suffix): keep one of them"
                )
            found[key] = q
        keyed.append(found)
    keys = sorted(set().union(*keyed))
    if not keys:
        shown = ", ".join(f"'{r}'" for r in roots)
        raise InputFileError(f"no recordings found in the device folders {shown}")
    sessions = []
    for key in keys:
        files = tuple(str(found[key]) for found in keyed if key in found)
        missing = [f"'{r}' (device {i})" for i, r in enumerate(roots) if key not in keyed[i]]
        if missing:
            where = "folder " if len(missing) == 1 else "folders "
            problem = f"no recording {key!r} in device {where}{', '.join(missing)}"
            sessions.append(Session(key, files, scheme="beepbeep", problem=problem))
        else:
            sessions.append(_paired_session(key, files, roots[0] / f"{key}.json"))
    return sessions


def _paired_session(key: str, files: tuple[str, ...], sidecar: Path) -> Session:
    """Session ``key`` of paired ``files``, with the values of ``sidecar`` if it exists."""
    if not sidecar.is_file():
        return Session(key, files, scheme="beepbeep")
    try:
        obj = json.loads(sidecar.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        problem = f"cannot read the sidecar '{sidecar}': {e}"
        return Session(key, files, scheme="beepbeep", problem=problem)
    if not isinstance(obj, dict):
        problem = f"the sidecar '{sidecar}' is not a JSON object"
        return Session(key, files, scheme="beepbeep", problem=problem)
    scheme = obj.get("scheme")
    if scheme is not None and scheme != "beepbeep":
        problem = (
            f"the sidecar '{sidecar}' says scheme {scheme!r}, but device folders paired by "
            "name hold BeepBeep sessions"
        )
        return Session(key, files, scheme="beepbeep", problem=problem)
    params, truth = _sidecar_values(obj, "beepbeep")
    return Session(key, files, scheme="beepbeep", params=params, truth=truth)


# --- one session ----------------------------------------------------------------------------


def _row(session: Session, scheme: str, **values: Any) -> dict[str, Any]:
    row: dict[str, Any] = dict.fromkeys(BATCH_COLUMNS)
    row.update(session=session.name, status="ok", error="", scheme=scheme, flags="")
    row["files"] = ";".join(Path(f).name for f in session.files)
    row.update(values)
    return row


def _beepbeep_rows(session: Session, opts: BatchOptions) -> list[dict[str, Any]]:
    from rangekit.ranging import range_files
    from rangekit.signals import Beep

    kw = dict(opts.beepbeep)
    p = session.params
    if "beep" in p:
        keys = ("f_hz", "n_bursts", "spacing", "burst_len", "taper", "amplitude", "fs")
        kw["beep"] = Beep(**{k: p["beep"][k] for k in keys if k in p["beep"]})
    if "temp_c" in p and kw.get("speed_m_s") is None:
        kw["temp_c"] = p["temp_c"]
    if "self_distance_m" in p:
        kw["self_distance_m"] = p["self_distance_m"]
    result = range_files(list(session.files), scheme="beepbeep", **kw)
    truth = {(a, b): d for a, b, d in session.truth}
    truth.update({(b, a): d for a, b, d in session.truth})
    rows = []
    for r in result.ranges:
        rows.append(
            _row(
                session,
                "beepbeep",
                a=r.a,
                b=r.b,
                distance_m=r.distance_m,
                sigma_m=r.sigma_m,
                true_distance_m=truth.get((r.a, r.b)),
                flags=",".join(r.flags),
            )
        )
    return rows


def _ultrasonic_rows(session: Session, scheme: str, opts: BatchOptions) -> list[dict[str, Any]]:
    from rangekit.ranging.ultrasonic import range_ultrasonic_files

    kw = dict(opts.oneway if scheme == "oneway" else opts.echo)
    p = session.params
    if "temp_c" in p and kw.get("speed_m_s") is None:
        kw["temp_c"] = p["temp_c"]
    if "period_s" in p:
        kw["period_s"] = p["period_s"]
    if "latency_s" in p and scheme == "oneway":
        kw["latency_s"] = p["latency_s"]
    truth = {(w, c): d for w, c, d in session.truth}
    rows = []
    for r in range_ultrasonic_files(list(session.files), scheme=scheme, **kw):
        rows.append(
            _row(
                session,
                scheme,
                files=Path(r["file"]).name,
                window=r["window"],
                tx=r.get("tx"),
                channel=r["channel"],
                distance_m=r["distance_m"],
                sigma_m=r["sigma_m"],
                true_distance_m=truth.get((r["window"], r["channel"])),
                snr_db=r["snr_db"],
                arrival_s=r["arrival_s"],
            )
        )
    return rows


def run_session(session: Session, options: BatchOptions) -> list[dict[str, Any]]:
    """Range one session; rows with the keys of :data:`BATCH_COLUMNS`.

    Never raises for a bad recording: a rangekit error (or any other exception) becomes
    one row with ``status="error"`` and the message in ``error``. Every row carries
    ``session_rows``, the number of rows of its session (the resume check).
    """
    scheme = session.scheme or options.scheme
    try:
        if session.problem is not None:
            raise InputFileError(session.problem)
        if scheme == "beepbeep":
            rows = _beepbeep_rows(session, options)
        else:
            rows = _ultrasonic_rows(session, scheme, options)
        if not rows:
            raise RangekitError("no range came out of this session")
    except RangekitError as e:
        rows = [_row(session, scheme, status="error", error=str(e))]
    except Exception as e:  # a bug must not stop the batch; it is reported in the row
        rows = [
            _row(session, scheme, status="error", error=f"internal error: {type(e).__name__}: {e}")
        ]
    for r in rows:
        r["session_rows"] = len(rows)
    return rows


def _run_chunk(sessions: Sequence[Session], options: BatchOptions) -> list[list[dict]]:
    return [run_session(s, options) for s in sessions]


# --- the results file -----------------------------------------------------------------------


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v) if v == v else ""
    return str(v)


def _csv_line(row: dict[str, Any]) -> str:
    import csv
    import io

    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow([_cell(row[c]) for c in BATCH_COLUMNS])
    return buf.getvalue()


def _json_line(row: dict[str, Any]) -> str:
    clean = {
        c: (None if isinstance(row[c], float) and row[c] != row[c] else row[c])
        for c in BATCH_COLUMNS
    }
    return json.dumps(clean, allow_nan=False) + "\n"


class ResultsFile:
    """A batch's results file (CSV or JSON Lines), appended one session at a time.

    The first line identifies the batch and its options (CSV: a ``#`` comment; JSONL: an
    object with the key ``rangekit_batch``); CSV then has the header row. Each finished
    session is appended as its rows in one ``write`` on a file opened for appending, so a
    batch killed at any moment leaves whole sessions plus at most one torn tail, which
    :meth:`open` with ``resume=True`` cuts off (a tail is torn when its last line lacks
    its newline or its session has fewer rows than its ``session_rows``). When the batch
    completes, :meth:`finish` rewrites the file atomically in session order, so a
    resumed batch ends with the same file as an uninterrupted one.

    Parameters
    ----------
    path : str or os.PathLike
        ``.csv`` or ``.jsonl`` (the format follows the suffix).
    options : BatchOptions
        Written into the first line; a resumed file must have been written with the same.
    resume : bool
        Continue an existing file (skip its finished sessions). Without it an existing
        file is an error (nothing is overwritten).

    Raises
    ------
    InvalidParameterError
        Unknown suffix; an existing file without ``resume``; resuming a file written
        with other options or that is not a batch results file.
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
        self.head = self._head(options)
        self.done: dict[str, list[str]] = {}  # session -> its lines, in file order
        self.status: dict[str, str] = {}  # session -> "ok" or "error"
        if not self.path.parent.is_dir():
            raise InputFileError(
                f"cannot write '{self.path}': folder '{self.path.parent}' does not exist"
            )
        if self.path.exists():
            if not resume:
                raise InvalidParameterError(
                    f"'{self.path}' exists: pass --resume to continue that batch, or choose "
                    "another output file (nothing was overwritten)"
                )
            self._recover()
        else:
            self._write_new(self.head)
        try:
            self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        except OSError as e:
            raise InputFileError(f"cannot write '{self.path}': {e.strerror or e}") from e

    def _head(self, options: BatchOptions) -> str:
        meta = json.dumps({"version": 1, "options": json.loads(options.fingerprint())})
        if self.fmt == "csv":
            return f"# rangekit batch {meta}\n" + ",".join(BATCH_COLUMNS) + "\n"
        return json.dumps({"rangekit_batch": json.loads(meta)}) + "\n"

    def _write_new(self, text: str) -> None:
        try:
            with open(self.path, "x", encoding="utf-8") as f:
                f.write(text)
        except OSError as e:
            raise InputFileError(f"cannot write '{self.path}': {e.strerror or e}") from e

    def _parse(self, line: str) -> tuple[str, int, str]:
        """(session, session_rows, status) of one data line; ValueError if it is not one."""
        if self.fmt == "jsonl":
            obj = json.loads(line)
            return str(obj["session"]), int(obj["session_rows"]), str(obj["status"])
        import csv

        cells = next(csv.reader([line]))
        if len(cells) != len(BATCH_COLUMNS):
            raise ValueError("wrong number of cells")
        return cells[0], int(cells[1]), cells[2]

    def _recover(self) -> None:
        """Read a resumed file: keep whole sessions, cut a torn tail off the file."""
        try:
            data = self.path.read_bytes()
        except OSError as e:
            raise InputFileError(f"cannot read '{self.path}': {e.strerror or e}") from e
        text = data.decode("utf-8", errors="replace")
        if not text.startswith(self.head):
            first = text.splitlines()[0] if text else ""
            what = "other options" if "rangekit" in first and "batch" in first else "something else"
            raise InvalidParameterError(
                f"cannot resume '{self.path}': it was written by {what} (its first "
                f"line{'s' if self.fmt == 'csv' else ''} differ from this batch's); rerun with "
                "the same options, or write a new file"
            )
        pos = len(self.head.encode("utf-8"))
        keep = pos
        pending: list[str] = []
        pending_name, pending_n = None, 0
        for raw in data[pos:].splitlines(keepends=True):
            if not raw.endswith(b"\n"):
                break  # torn last line
            line = raw.decode("utf-8")
            try:
                name, n, status = self._parse(line)
            except (ValueError, KeyError, TypeError, StopIteration):
                break
            if name != pending_name:
                pending, pending_name, pending_n = [], name, n
            pending.append(line)
            pos += len(raw)
            if len(pending) == pending_n:
                self.done[name] = pending
                self.status[name] = status
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
            n = os.write(self._fd, view)
            view = view[n:]
        name = str(rows[0]["session"])
        self.done[name] = lines
        self.status[name] = str(rows[0]["status"])

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


# --- running a batch ------------------------------------------------------------------------


@dataclass(frozen=True)
class BatchSummary:
    """Counts of a finished batch over its sessions: ``total``; ``skipped`` (found done
    in a resumed file); ``ok`` and ``failed`` (status of every session in the file, the
    skipped ones included); and the output ``path``."""

    total: int
    skipped: int
    ok: int
    failed: int
    path: str


def _chunks(items: Sequence[Session], size: int) -> list[list[Session]]:
    return [list(items[i : i + size]) for i in range(0, len(items), size)]


def _pool_initializer() -> None:
    """Workers leave Ctrl-C to the parent (which stops them and keeps what is written),
    and on Linux die with it (a parent killed by SIGKILL leaves no orphan working on)."""
    import signal
    import sys

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass


def run_batch(
    sessions: Sequence[Session],
    output: str | os.PathLike,
    options: BatchOptions | None = None,
    *,
    jobs: int = 1,
    resume: bool = False,
    scheduler: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    chunk: int | None = None,
) -> BatchSummary:
    """Range ``sessions`` and write every result row to ``output``.

    Parameters
    ----------
    sessions : sequence of Session
        From :func:`find_sessions`.
    output : str or os.PathLike
        The results file, ``.csv`` or ``.jsonl`` (:class:`ResultsFile`).
    options : BatchOptions, optional
        Defaults for sessions without a sidecar value.
    jobs : int
        Worker processes (1: in this process). Ignored with ``scheduler``.
    resume : bool
        Continue ``output``: sessions already in it are skipped.
    scheduler : str, optional
        Address of a Dask distributed scheduler (``tcp://HOST:PORT``); needs the optional
        ``dask[distributed]`` (``pip install rangekit[dask]``).
    progress : callable, optional
        Called as ``progress(done, total)`` after each session (``done`` counts skipped
        sessions too).
    chunk : int, optional
        Sessions per task sent to a worker; default: about 4 tasks per worker, at most 16
        sessions.

    Returns
    -------
    BatchSummary

    Notes
    -----
    On an interrupt (Ctrl-C) the workers are stopped, every session finished so far is in
    the file, and ``KeyboardInterrupt`` propagates; rerun with ``resume=True``.
    """
    options = BatchOptions() if options is None else options
    jobs = int(jobs)
    if jobs < 1:
        raise InvalidParameterError(f"jobs={jobs} must be >= 1")
    results = ResultsFile(output, options, resume=resume)
    order = [s.name for s in sessions]
    todo = [s for s in sessions if s.name not in results.done]
    total = len(sessions)
    skipped = total - len(todo)
    done = skipped
    if progress is not None:
        progress(done, total)

    def record(rows: list[dict]) -> None:
        nonlocal done
        results.append(rows)
        done += 1
        if progress is not None:
            progress(done, total)

    workers = jobs if scheduler is None else 4
    size = chunk or max(1, min(16, len(todo) // (4 * workers) or 1))
    try:
        if scheduler is not None:
            _run_dask(scheduler, _chunks(todo, size), options, record)
        elif jobs == 1 or len(todo) <= 1:
            for s in todo:
                record(run_session(s, options))
        else:
            _run_pool(jobs, _chunks(todo, size), options, record)
    finally:
        results.close()
    ok = sum(results.status.get(n) == "ok" for n in order)
    failed = sum(results.status.get(n) == "error" for n in order)
    summary = BatchSummary(total, skipped, ok, failed, str(results.path))
    results.finish(order)
    return summary


def _run_pool(jobs: int, chunks: list[list[Session]], options, record) -> None:
    import concurrent.futures as cf
    import multiprocessing as mp

    # fork starts workers in milliseconds with rangekit (and numba's compiled kernels)
    # already loaded; elsewhere spawn.
    ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
    ex = cf.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=_pool_initializer)
    try:
        futs = [ex.submit(_run_chunk, c, options) for c in chunks]
        for f in cf.as_completed(futs):
            for rows in f.result():
                record(rows)
    except BaseException:
        ex.shutdown(wait=False, cancel_futures=True)
        for p in list(getattr(ex, "_processes", {}).values()):
            p.terminate()
        raise
    ex.shutdown(wait=True)


def _run_dask(address: str, chunks: list[list[Session]], options, record) -> None:
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise InvalidParameterError(
            "--scheduler needs Dask: pip install 'rangekit[dask]' (dask[distributed])"
        ) from None
    try:
        client = Client(address, timeout=f"{DASK_CONNECT_TIMEOUT_S}s")
    except (OSError, TimeoutError) as e:
        raise InputFileError(f"cannot connect to the Dask scheduler at {address}: {e}") from e
    try:
        futs = [client.submit(_run_chunk, c, options, pure=False) for c in chunks]
        for f in as_completed(futs):
            for rows in f.result():
                record(rows)
    finally:
        client.close()


def iter_rows(path: str | os.PathLike) -> Iterable[dict[str, Any]]:
    """The data rows of a batch results file as dicts (CSV cells as strings)."""
    p = Path(path)
    text = p.read_text(encoding="utf-8")
    if p.suffix.lower() == ".jsonl":
        for line in text.splitlines()[1:]:
            if line.strip():
                yield json.loads(line)
        return
    import csv

    lines = [ln for ln in text.splitlines() if not ln.startswith("#")]
    yield from csv.DictReader(lines)
