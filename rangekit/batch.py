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
from collections import Counter
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
    "json_value",
    "meta_path",
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
#: Seconds without a finished Dask task after which the batch checks that the cluster
#: still has workers (none: the batch stops with exit 3 instead of waiting forever).
DASK_WATCHDOG_S = 30.0

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
        """A stable JSON text of every option that changes results (checked on resume):
        option values as JSON (:func:`json_value`), not Python reprs."""
        parts: dict[str, Any] = {
            "scheme": self.scheme,
            "grouping": "pair-by-name" if self.pair_by_name else "rules",
            "beepbeep": json_value(self.beepbeep),
            "oneway": json_value(self.oneway),
            "echo": json_value(self.echo),
        }
        return json.dumps(parts, sort_keys=True, allow_nan=False)


def json_value(v: Any) -> Any:
    """An option value as plain JSON: a dataclass (``Beep``, ``Transducer``, ``Probe``,
    ``Calibration``, ...) as an object of its fields plus ``"type"``; a tuple as a list; an
    array by its length and SHA-1 (a probe's samples); a non-finite float as its text.

    >>> from rangekit.signals import Beep
    >>> json_value({"detector": "changepoint", "beep": Beep(f_hz=17000.0), "speed": None})
    ... # doctest: +NORMALIZE_WHITESPACE
    {'beep': {'type': 'Beep', 'f_hz': 17000.0, 'n_bursts': 4, 'spacing': 5000,
    'burst_len': 441, 'taper': 22, 'amplitude': 0.9, 'fs': 44100.0},
    'detector': 'changepoint', 'speed': None}
    """
    import dataclasses
    import math

    if v is None or isinstance(v, (bool, int, str)):
        return v
    if isinstance(v, float):
        return v if math.isfinite(v) else repr(v)
    if isinstance(v, dict):
        return {str(k): json_value(x) for k, x in sorted(v.items())}
    if isinstance(v, (list, tuple)):
        return [json_value(x) for x in v]
    if isinstance(v, os.PathLike):
        return os.fspath(v)
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        out = {"type": type(v).__name__}
        out.update({f.name: json_value(getattr(v, f.name)) for f in dataclasses.fields(v)})
        return out
    if hasattr(v, "tobytes") and hasattr(v, "shape"):  # a numpy array
        import hashlib

        if v.shape == ():
            return json_value(v.item())
        return {"shape": list(v.shape), "sha1": hashlib.sha1(v.tobytes()).hexdigest()}
    if hasattr(v, "item"):  # a numpy scalar
        return json_value(v.item())
    return repr(v)


# --- finding sessions ---------------------------------------------------------------------

#: Most entries of a sidecar's ``files`` list.
MAX_SIDECAR_FILES = 256


def _printable(text: str) -> str:
    """``text`` with the undecodable bytes of a file name (surrogate escapes) as ``\\xNN``,
    so that it can be written as UTF-8 (a session name, an error message)."""
    from rangekit.io.guard import printable

    return printable(text)


def _walk(root: Path) -> Iterable[Path]:
    """Files under ``root`` in sorted order; names starting with ``.`` skipped, links to
    folders not followed (a link loop cannot make the walk endless)."""
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        base = Path(dirpath)
        for f in sorted(filenames):
            if not f.startswith("."):
                yield base / f


def _refusal(p: Path, root: Path | None) -> str | None:
    """Why the file ``p`` found under ``root`` is not taken as an input (None: it is).

    It must be a regular file once links are followed (no FIFO, device, socket), and a
    link must lead inside ``root`` (``None``: a file named on the command line)."""
    try:
        st = os.stat(p)
    except OSError as e:
        return f"cannot open '{p}': {e.strerror or e}"
    from rangekit.io.guard import _kind

    kind = _kind(st.st_mode)
    if kind is not None:
        return f"cannot open '{p}': it is {kind}, not a regular file"
    if root is not None and p.is_symlink() and not _inside(p.resolve(), root):
        return f"'{p}' is a link to a file outside the folder '{root}' (not followed)"
    return None


def _inside(real: Path, root: Path) -> bool:
    r = root.resolve()
    return real == r or r in real.parents


def _match(parts: tuple[str, ...], pat: tuple[str, ...]) -> bool:
    """Whether path ``parts`` match glob ``pat`` (``**`` = any number of folders)."""
    import fnmatch

    if not pat:
        return not parts
    if pat[0] == "**":
        return any(_match(parts[k:], pat[1:]) for k in range(len(parts) + 1))
    return bool(parts) and fnmatch.fnmatchcase(parts[0], pat[0]) and _match(parts[1:], pat[1:])


def _glob(pattern: str) -> tuple[Path, list[Path]]:
    """The folder a glob starts from (its part without wildcards) and the files it
    matches, a matched folder standing for every file under it. Links to folders are
    not followed (``glob.glob`` follows them: three self-links expand exponentially)."""
    parts = Path(pattern).parts
    i = next(k for k, part in enumerate(parts) if glob.has_magic(part))
    root = Path(*parts[:i]) if i else Path(".")
    rest = parts[i:]
    hits: list[Path] = []
    if not root.is_dir():
        return root, hits
    deep = "**" in rest
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        base = Path(dirpath)
        rel = base.relative_to(root).parts
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        for d in list(dirnames):
            if _match((*rel, d), rest) and not (base / d).is_symlink():
                hits.extend(_walk(base / d))
        for f in sorted(filenames):
            if not f.startswith(".") and _match((*rel, f), rest):
                hits.append(base / f)
        if not deep and len(rel) + 1 >= len(rest):
            dirnames[:] = []
    return root, sorted(set(hits))


@dataclass
class _Found:
    """What the inputs name: recordings and JSON files with the folder each was found in
    (the confinement root of its sidecar), neighbour JSONs, and refused files."""

    audio: list[Path] = field(default_factory=list)
    jsons: list[tuple[Path, Path]] = field(default_factory=list)
    neighbours: set[Path] = field(default_factory=set)
    refused: list[tuple[Path, str]] = field(default_factory=list)


def _expand(inputs: Sequence[str | os.PathLike]) -> _Found:
    """Audio files and JSON files named by ``inputs`` (files, folders, globs), the JSON
    files found only as neighbours of an input file (resolved paths), and the files
    refused (special files, links out of their folder)."""
    found = _Found()
    seen_json: set[Path] = set()

    def add(p: Path, root: Path | None, explicit: bool) -> None:
        suf = p.suffix.lower()
        if suf != ".json" and suf not in AUDIO_SUFFIXES and not explicit:
            return
        why = _refusal(p, root)
        if why is not None:
            if p.absolute() not in seen_json:
                seen_json.add(p.absolute())
                found.refused.append((p, why))
        elif suf == ".json":
            if p.resolve() not in seen_json:
                seen_json.add(p.resolve())
                found.jsons.append((p, root if root is not None else p.parent))
        else:
            found.audio.append(p)

    for raw in inputs:
        text = os.fspath(raw)
        p = Path(text)
        if p.is_dir():
            for q in _walk(p):
                add(q, p, False)
        elif os.path.lexists(p):
            add(p, None, True)
        elif glob.has_magic(text):
            root, hits = _glob(text)
            if not hits:
                raise InputFileError(f"'{_printable(text)}' matches no file")
            for q in hits:
                add(q, root, False)
        else:
            raise InputFileError(f"cannot open '{_printable(text)}': no such file or folder")
    # A folder next to an explicit file may hold its sidecar.
    for folder in sorted({q.parent for q in found.audio}):
        try:
            names = sorted(e.name for e in os.scandir(folder) if e.name.lower().endswith(".json"))
        except OSError:
            continue
        for n in names:
            j = folder / n
            if n.startswith(".") or j.resolve() in seen_json or j.absolute() in seen_json:
                continue
            why = _refusal(j, folder)
            if why is not None:
                seen_json.add(j.absolute())
                found.refused.append((j, why))
                continue
            seen_json.add(j.resolve())
            found.neighbours.add(j.resolve())
            found.jsons.append((j, folder))
    found.audio = _unique(found.audio)
    return found


def _unique(paths: list[Path]) -> list[Path]:
    out, seen = [], set()
    for p in paths:
        r = p.resolve()
        if r not in seen:
            seen.add(r)
            out.append(p)
    return out


def _confined(sidecar: Path, name: Any, root: Path) -> str | None:
    """Why the ``files`` entry ``name`` of ``sidecar`` is refused (None: it is inside the
    folder ``root`` the batch was given). Says nothing about files outside ``root``."""
    if not isinstance(name, str) or not name or "\x00" in name:
        return "'files' must be a list of file names"
    if os.path.isabs(name):
        return f"file {_printable(name)!r} is an absolute path (names are relative to the sidecar)"
    if not _inside((sidecar.parent / name).resolve(), root):
        return f"file {_printable(name)!r} is outside the folder '{_printable(str(root))}'"
    return None


def _sidecar_session(path: Path, obj: dict, root: Path | None = None) -> Session:
    """The session a sidecar describes (``problem`` set when it cannot be ranged).

    Its ``files`` must resolve (links followed) inside ``root``, the folder the batch
    was given (default: the sidecar's own folder)."""
    root = path.parent if root is None else root
    name = _printable(str(path.with_suffix("")))
    shown = _printable(str(path))
    files = obj["files"]
    if not isinstance(files, list) or not files or len(files) > MAX_SIDECAR_FILES:
        return Session(
            name,
            (str(path),),
            problem=f"'{shown}': 'files' must be a list of 1 to {MAX_SIDECAR_FILES} names",
        )
    for f in files:
        why = _confined(path, f, root)
        if why is not None:
            return Session(name, (str(path),), problem=f"'{shown}': {why}")
    paths = tuple(str(path.parent / f) for f in files)
    scheme = obj.get("scheme")
    if scheme is not None and scheme not in SCHEMES:
        return Session(
            name,
            paths,
            problem=f"'{shown}': scheme {scheme!r} is not one of {', '.join(SCHEMES)}",
        )
    try:
        params, truth = _sidecar_values(obj, scheme)
    except InvalidParameterError as e:
        return Session(name, paths, problem=f"'{shown}': {e}")
    return Session(name, paths, scheme=scheme, params=params, truth=truth)


def _number(where: str, v: Any, lo: float, hi: float) -> float:
    """A JSON number within [lo, hi] (booleans are not numbers), else InvalidParameterError."""
    import math

    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InvalidParameterError(f"{where}={v!r} must be a number")
    f = float(v)
    if not (math.isfinite(f) and lo <= f <= hi):
        raise InvalidParameterError(f"{where}={v!r} must be within [{lo:g}, {hi:g}]")
    return f


def _index(where: str, v: Any) -> int:
    """A JSON integer >= 0 (``2.0`` accepted, ``true`` not), else InvalidParameterError."""
    if isinstance(v, float) and v.is_integer():
        v = int(v)
    if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= 10**6:
        raise InvalidParameterError(f"{where}={v!r} must be an integer in [0, 1000000]")
    return v


#: Sidecar ``beep`` keys and their type (int or float); others are refused.
_BEEP_KEYS = {
    "f_hz": float,
    "n_bursts": int,
    "spacing": int,
    "burst_len": int,
    "taper": int,
    "amplitude": float,
    "fs": float,
}
#: Largest true distance accepted in a sidecar, m.
_MAX_TRUE_M = 1e5


def _sidecar_values(
    obj: dict, scheme: str | None
) -> tuple[dict[str, Any], tuple[tuple[int, int, float], ...]]:
    """The ranging parameters and true distances a sidecar gives (rule 1 of the module
    docstring), for a session of ``scheme``. Every value is type- and range-checked
    (``InvalidParameterError`` naming the key): a wrong value is never replaced by a
    default silently.

    A sidecar with a ``"setup"`` object (what ``rangekit synth`` writes,
    :mod:`rangekit.io.setup`) gives its parameters from there only: the simulator's truth
    beside it (``devices``, true onsets) is never read as an input."""
    params: dict[str, Any] = {}
    if "setup" in obj:
        params = _setup_params(obj["setup"], scheme)
        obj = {k: v for k, v in obj.items() if k in ("windows", "pairs")}  # truth: scoring only
    beep = obj.get("beep")
    if beep is not None:
        if not isinstance(beep, dict):
            raise InvalidParameterError("'beep' must be an object")
        b: dict[str, Any] = {}
        for k, v in beep.items():
            if k not in _BEEP_KEYS:
                continue  # written by the simulator (e.g. durations), not a parameter
            if _BEEP_KEYS[k] is int:
                b[k] = _index(f"beep.{k}", v)
            else:
                b[k] = _number(f"beep.{k}", v, 0.0, 1e7)
        params["beep"] = b
    if obj.get("temp_c") is not None:
        params["temp_c"] = _number("temp_c", obj["temp_c"], -60.0, 60.0)
    sd = obj.get("self_distance_m")
    devices = obj.get("devices")
    if isinstance(sd, list):
        if not 1 <= len(sd) <= MAX_SIDECAR_FILES:
            raise InvalidParameterError("'self_distance_m' must hold 1 to 256 numbers")
        params["self_distance_m"] = [
            _number(f"self_distance_m[{i}]", v, 0.0, 2.0) for i, v in enumerate(sd)
        ]
    elif sd is not None:
        params["self_distance_m"] = _number("self_distance_m", sd, 0.0, 2.0)
    elif isinstance(devices, list) and devices:
        if all(isinstance(d, dict) and "self_distance_m" in d for d in devices):
            params["self_distance_m"] = [
                _number(f"devices[{i}].self_distance_m", d["self_distance_m"], 0.0, 2.0)
                for i, d in enumerate(devices)
            ]
    if scheme in ("oneway", "echo"):
        if obj.get("period_s") is not None:
            params["period_s"] = _number("period_s", obj["period_s"], 1e-4, 3600.0)
        if obj.get("latency_s") is not None:
            params["latency_s"] = _number("latency_s", obj["latency_s"], 0.0, 10.0)
    truth = []
    windows = obj.get("windows") or []
    pairs = obj.get("pairs") or []
    if not isinstance(windows, list) or not isinstance(pairs, list):
        raise InvalidParameterError("'windows' and 'pairs' must be lists")
    for k, w in enumerate(windows):
        if not isinstance(w, dict) or "window" not in w:
            raise InvalidParameterError(f"windows[{k}] must be an object with a 'window'")
        win = _index(f"windows[{k}].window", w["window"])
        if scheme == "oneway" and isinstance(w.get("distances_m"), list):
            for c, d in enumerate(w["distances_m"]):
                if d is not None:
                    where = f"windows[{k}].distances_m[{c}]"
                    truth.append((win, c, _number(where, d, 0.0, _MAX_TRUE_M)))
        elif scheme == "echo" and w.get("distance_m") is not None:
            d = _number(f"windows[{k}].distance_m", w["distance_m"], 0.0, _MAX_TRUE_M)
            truth.append((win, 0, d))
    for k, p in enumerate(pairs):
        if not isinstance(p, dict) or "a" not in p or "b" not in p:
            raise InvalidParameterError(f"pairs[{k}] must be an object with 'a' and 'b'")
        a, b_ = _index(f"pairs[{k}].a", p["a"]), _index(f"pairs[{k}].b", p["b"])
        if p.get("distance_m") is not None:
            d = _number(f"pairs[{k}].distance_m", p["distance_m"], 0.0, _MAX_TRUE_M)
            truth.append((a, b_, d))
    return params, tuple(truth)


def _setup_params(setup: Any, scheme: str | None) -> dict[str, Any]:
    """The parameters of a sidecar's ``setup`` (:func:`rangekit.io.setup.parse_setup`)."""
    from rangekit.io.setup import parse_setup

    try:
        s = parse_setup(setup, name="setup")
    except InputFileError as e:
        raise InvalidParameterError(str(e).replace("'setup': ", "")) from None
    signal = s.signal or {}
    if "probe" in signal:
        raise InvalidParameterError(
            f"the session played the probe {signal['probe']!r}; batch ranges the built-in "
            "beep only (range it with `rangekit range --template`)"
        )
    params: dict[str, Any] = {}
    beep = signal.get("beep")
    if isinstance(beep, dict):
        params["beep"] = {
            k: (_index(f"setup.signal.beep.{k}", v) if _BEEP_KEYS[k] is int
                else _number(f"setup.signal.beep.{k}", v, 0.0, 1e7))
            for k, v in beep.items()
            if k in _BEEP_KEYS
        }  # fmt: skip
    if s.temp_c is not None:
        params["temp_c"] = s.temp_c
    if s.self_distance_m is not None:
        params["self_distance_m"] = list(s.self_distance_m)
    if scheme in ("oneway", "echo") and s.period_s is not None:
        params["period_s"] = s.period_s
    if scheme == "oneway":
        if s.latency_s is not None:
            params["latency_s"] = s.latency_s
        if s.tx_order is not None:
            params["tx_order"] = list(s.tx_order)
    return params


def find_sessions(inputs: Sequence[str | os.PathLike]) -> list[Session]:
    """Group files, folders and globs into sessions (rules in the module docstring).

    Folders are searched recursively; files and folders whose names start with ``.`` are
    skipped. Sessions are returned sorted by name.

    Raises
    ------
    InputFileError
        If an input does not exist (or a glob matches nothing), or no recording is found.
    """
    from rangekit.io.guard import read_json_file

    found = _expand(inputs)
    audio = found.audio
    given = {p.resolve() for p in audio}
    sessions: list[Session] = []
    claimed: set[Path] = set()
    for j, root in found.jsons:
        try:
            obj = read_json_file(j)
        except RangekitError as e:
            # Not silently ignored: it may be the sidecar of recordings beside it, which
            # would then be ranged with the wrong values. Those named after it (j's stem,
            # or stem_devN) are claimed by its error row.
            mine = {
                q.resolve()
                for q in audio
                if q.parent == j.parent
                and (q.stem == j.stem or re.fullmatch(re.escape(j.stem) + r"_dev\d+", q.stem))
            }
            if j.resolve() in found.neighbours and not mine:
                continue  # beside an input file, and not about it
            name = _printable(str(j.with_suffix("")))
            sessions.append(Session(name, (str(j),), problem=f"sidecar: {_printable(str(e))}"))
            claimed |= mine
            continue
        if not isinstance(obj, dict) or "files" not in obj:
            continue  # not a sidecar (e.g. a floor plan)
        s = _sidecar_session(j, obj, root)
        if j.resolve() in found.neighbours and not given & {Path(f).resolve() for f in s.files}:
            continue  # a sidecar next to an input, of recordings that were not asked for
        sessions.append(s)
        claimed.update(Path(f).resolve() for f in s.files)
    for p, why in found.refused:
        sessions.append(Session(_printable(str(p)), (str(p),), problem=_printable(why)))
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
            sessions.append(Session(_printable(str(folder / name)), files))
        else:
            singles.extend(devs.values())
    sessions.extend(Session(_printable(str(p)), (str(p),)) for p in singles)
    if not sessions:
        shown = ", ".join(os.fspath(i) for i in inputs[:3])
        raise InputFileError(f"no recordings found in {shown}{' ...' if len(inputs) > 3 else ''}")
    sessions.sort(key=lambda s: s.name)
    names = [s.name for s in sessions]
    dup = {n for n, k in Counter(names).items() if k > 1}
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
        for q in _walk(root):
            rel = q.relative_to(root)
            if q.suffix.lower() not in AUDIO_SUFFIXES or _refusal(q, root) is not None:
                continue
            key = _printable(rel.with_suffix("").as_posix())
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
    from rangekit.io.guard import read_json_file

    if not os.path.lexists(sidecar):
        return Session(key, files, scheme="beepbeep")
    try:
        obj = read_json_file(sidecar, what="the sidecar ")
    except RangekitError as e:
        return Session(key, files, scheme="beepbeep", problem=_printable(str(e)))
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
    try:
        params, truth = _sidecar_values(obj, "beepbeep")
    except InvalidParameterError as e:
        problem = f"the sidecar '{_printable(str(sidecar))}': {e}"
        return Session(key, files, scheme="beepbeep", problem=problem)
    return Session(key, files, scheme="beepbeep", params=params, truth=truth)


# --- one session ----------------------------------------------------------------------------


def _row(session: Session, scheme: str, **values: Any) -> dict[str, Any]:
    """One results row: every column of :data:`BATCH_COLUMNS`, None where missing;
    ``files`` the session's files as found (their folders kept), ``flags`` a list."""
    row: dict[str, Any] = dict.fromkeys(BATCH_COLUMNS)
    row.update(session=session.name, status="ok", scheme=scheme)
    row["files"] = [_printable(f) for f in session.files]
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
                flags=list(r.flags),
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
    if "tx_order" in p and scheme == "oneway" and kw.get("tx_ids") is None:
        kw["tx_ids"] = p["tx_order"]
    from rangekit.io.audio import check_period

    check_period(session.files, kw.get("period_s"))
    truth = {(w, c): d for w, c, d in session.truth}
    rows = []
    for r in range_ultrasonic_files(list(session.files), scheme=scheme, **kw):
        rows.append(
            _row(
                session,
                scheme,
                files=[_printable(str(r["file"]))],
                window=r["window"],
                tx=r.get("tx"),
                channel=r["channel"],
                distance_m=r["distance_m"],
                sigma_m=r["sigma_m"],
                true_distance_m=truth.get((r["window"], r["channel"])),
                snr_db=r["snr_db"],
                arrival_s=r["arrival_s"],
                flags=list(r.get("flags") or ()),
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
                name, n, status = self._parse(line)
            except (ValueError, KeyError, TypeError, StopIteration, csv.Error):
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
            try:
                n = os.write(self._fd, view)
            except OSError as e:  # a full disk: what is written so far stays resumable
                raise InputFileError(f"cannot write '{self.path}': {e.strerror or e}") from e
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
    if scheduler is not None:
        check_scheduler_address(scheduler)
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
        procs = list((getattr(ex, "_processes", None) or {}).values())
        ex.shutdown(wait=False, cancel_futures=True)
        # shutdown() sets _processes to None: take the workers before it
        for p in procs:
            p.terminate()
        raise
    ex.shutdown(wait=True)


_ADDRESS_RE = re.compile(
    r"^(?:(?P<proto>tcp|tls)://)?(?P<host>\[[0-9a-fA-F:]+\]|[^\s:/\[\]]+):(?P<port>\d{1,5})$"
)


def check_scheduler_address(address: str) -> re.Match:
    """The parts of a ``[tcp://|tls://]HOST:PORT`` address, else InvalidParameterError."""
    m = _ADDRESS_RE.match(str(address).strip())
    if m is None or not 0 < int(m["port"]) < 65536:
        raise InvalidParameterError(
            f"--scheduler {address!r} is not an address of the form tcp://HOST:PORT"
        )
    return m


def _dask_client(Client, address: str):
    """A connected Dask client, or an error within about DASK_CONNECT_TIMEOUT_S.

    The address must be ``[tcp://|tls://]HOST:PORT`` (else InvalidParameterError). The
    TCP connection and then the Dask handshake each get the timeout: a server that
    accepts and never answers, or is not a Dask scheduler, is an InputFileError naming
    the address, not a hang."""
    import socket
    import threading

    m = check_scheduler_address(address)
    t = DASK_CONNECT_TIMEOUT_S
    where = f"the Dask scheduler at {address}"
    try:
        socket.create_connection((m["host"].strip("[]"), int(m["port"])), timeout=t).close()
    except OSError as e:
        raise InputFileError(f"cannot connect to {where}: {e.strerror or e}") from None
    box: dict[str, Any] = {}

    def connect() -> None:
        try:
            box["client"] = Client(address.strip(), timeout=f"{t}s")
        except BaseException as e:  # reported in the caller's thread
            box["error"] = e

    th = threading.Thread(target=connect, daemon=True, name="rangekit-dask-connect")
    th.start()
    th.join(t + 5.0)
    if th.is_alive():
        raise InputFileError(
            f"cannot connect to {where}: no Dask handshake within {t:g} s (is it a Dask scheduler?)"
        )
    if "error" in box:
        e = box["error"]
        raise InputFileError(f"cannot connect to {where}: {type(e).__name__}: {e}") from None
    return box["client"]


def _run_dask(address: str, chunks: list[list[Session]], options, record) -> None:
    try:
        from distributed import Client
    except ImportError:
        raise InvalidParameterError(
            "--scheduler needs Dask: pip install 'rangekit[dask]' (dask[distributed])"
        ) from None
    from distributed import wait

    client = _dask_client(Client, address)
    try:
        futs = [client.submit(_run_chunk, c, options, pure=False) for c in chunks]
        _dask_watch(client, futs, record, address=address, wait=wait)
    finally:
        client.close()


def _dask_watch(client, futs, record, *, address: str, wait) -> None:
    """Record the chunks' rows as their tasks finish, watching the cluster.

    Every :data:`DASK_WATCHDOG_S` without a finished task the scheduler is asked for its
    workers: none left (they died), or no answer, stops the batch with an InputFileError
    (exit 3) instead of waiting forever; so does a task that failed on the cluster (a
    worker killed while running it, ``KilledWorker``). Every session finished before is
    in the results file (rerun with ``--resume``)."""
    pending = set(futs)
    where = f"the Dask cluster at {address}"
    again = "every finished session is in the results file; rerun with --resume"
    while pending:
        try:
            done, pending = wait(pending, timeout=DASK_WATCHDOG_S, return_when="FIRST_COMPLETED")
        except TimeoutError:
            try:
                workers = client.scheduler_info().get("workers", {})
            except Exception as e:
                raise InputFileError(f"lost {where} ({type(e).__name__}: {e}); {again}") from None
            if not workers:
                raise InputFileError(
                    f"{where} has no worker left: {len(pending)} task(s) cannot run; {again}"
                ) from None
            continue
        for f in done:
            try:
                chunk = f.result()
            except Exception as e:  # KilledWorker, a worker's own failure
                raise InputFileError(
                    f"a task failed on {where} ({type(e).__name__}: {e}); {again}"
                ) from None
            for rows in chunk:
                record(rows)


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
