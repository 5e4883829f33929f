"""Device folders paired by file name (rule 4 of :mod:`rangekit.batch`, ``rangekit batch
--pair-by-name``): folder i holds device i's mono recordings, one session per name."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from rangekit.batch._sessions import AUDIO_SUFFIXES, Session, _printable, _refusal, _walk
from rangekit.batch._sidecars import _sidecar_values
from rangekit.errors import InputFileError, InvalidParameterError, RangekitError


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
