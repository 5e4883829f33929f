"""Finding sessions: inputs (files, folders, globs) expanded safely and grouped by the
sidecar rule, the ``NAME_devN`` naming rule, or one session per file (rules 1-3 of
:mod:`rangekit.batch`, ``docs/batch.md``)."""

from __future__ import annotations

import glob
import os
import re
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rangekit.batch._options import SCHEMES
from rangekit.batch._sidecars import MAX_SIDECAR_FILES, _sidecar_values
from rangekit.errors import InputFileError, InvalidParameterError, RangekitError

#: File suffixes taken as recordings when a folder or glob is expanded.
AUDIO_SUFFIXES = (".wav", ".flac", ".ogg", ".aif", ".aiff")
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
