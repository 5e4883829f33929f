"""Tests of rangekit.batch.pair_sessions_by_name: device folders paired by file name
(grouping rule 4, ``docs/batch.md``). Pairing never reads the audio, so empty files do."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rangekit.batch import (
    BatchOptions,
    ResultsFile,
    pair_sessions_by_name,
    run_session,
)
from rangekit.errors import InputFileError, InvalidParameterError


def _tree(root: Path, files: list[str]) -> None:
    for f in files:
        p = root / f
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(b"")


@pytest.fixture
def three(tmp_path):
    """Three device folders: nested takes, mixed suffixes, hidden and non-audio files."""
    _tree(
        tmp_path,
        [
            "a/take_01.wav",
            "a/day2/take_02.WAV",
            "a/day2/notes.txt",
            "a/.hidden.wav",
            "a/.cache/take_09.wav",
            "b/take_01.flac",
            "b/day2/take_02.wav",
            "b/take_01.json",  # a JSON in a device folder other than device 0's is no recording
            "c/take_01.aiff",
            "c/day2/take_02.ogg",
            "c/.cache/take_09.wav",
        ],
    )
    return tmp_path


def test_pairs_nested_tree_mixed_suffixes_in_folder_order(three):
    folders = [three / "a", three / "b", three / "c"]
    sessions = pair_sessions_by_name(folders)
    assert [s.name for s in sessions] == ["day2/take_02", "take_01"]
    s = {x.name: x for x in sessions}
    assert s["take_01"].files == tuple(
        str(p)
        for p in (three / "a/take_01.wav", three / "b/take_01.flac", three / "c/take_01.aiff")
    )
    assert s["day2/take_02"].files == tuple(
        str(p)
        for p in (
            three / "a/day2/take_02.WAV",
            three / "b/day2/take_02.wav",
            three / "c/day2/take_02.ogg",
        )
    )
    for x in sessions:
        assert x.problem is None and x.scheme == "beepbeep"
        assert x.params == {} and x.truth == ()
    # Device order is folder order: reversing the folders reverses every session's files.
    rev = pair_sessions_by_name(folders[::-1])
    assert [x.files for x in rev] == [x.files[::-1] for x in sessions]


def test_missing_take_is_a_session_with_a_problem_naming_the_folders(tmp_path):
    _tree(tmp_path, ["d0/t1.wav", "d0/t2.wav", "d1/t1.wav", "d2/t1.wav", "d2/t3.wav"])
    folders = [tmp_path / "d0", tmp_path / "d1", tmp_path / "d2"]
    sessions = pair_sessions_by_name(folders)
    assert [s.name for s in sessions] == ["t1", "t2", "t3"]
    t1, t2, t3 = sessions
    assert t1.problem is None and len(t1.files) == 3
    assert t2.files == (str(tmp_path / "d0/t2.wav"),)
    assert f"'{folders[1]}' (device 1)" in t2.problem and f"'{folders[2]}' (device 2)" in t2.problem
    assert str(folders[0]) not in t2.problem
    assert f"'{folders[0]}' (device 0), '{folders[1]}' (device 1)" in t3.problem
    # run_session turns the problem into one error row, naming the folder.
    rows = run_session(t2, BatchOptions())
    assert len(rows) == 1 and rows[0]["status"] == "error"
    assert str(folders[1]) in rows[0]["error"] and "'t2'" in rows[0]["error"]
    assert rows[0]["files"] == [str(tmp_path / "d0/t2.wav")] and rows[0]["session_rows"] == 1


def test_matching_is_case_sensitive(tmp_path):
    _tree(tmp_path, ["x/Take.wav", "y/take.wav"])
    sessions = pair_sessions_by_name([tmp_path / "x", tmp_path / "y"])
    assert [s.name for s in sessions] == ["Take", "take"]
    assert all(s.problem is not None for s in sessions)


def test_same_key_twice_in_one_folder_is_an_error(tmp_path):
    _tree(tmp_path, ["x/sub/take_01.wav", "x/sub/take_01.flac", "y/sub/take_01.wav"])
    with pytest.raises(InputFileError) as e:
        pair_sessions_by_name([tmp_path / "x", tmp_path / "y"])
    msg = str(e.value)
    assert "take_01.wav" in msg and "take_01.flac" in msg and "'sub/take_01'" in msg


def test_no_recordings_is_an_error(tmp_path):
    _tree(tmp_path, ["x/readme.txt", "x/.h.wav", "y/sub/notes.json"])
    with pytest.raises(InputFileError, match="no recordings found") as e:
        pair_sessions_by_name([tmp_path / "x", tmp_path / "y"])
    assert str(tmp_path / "x") in str(e.value) and str(tmp_path / "y") in str(e.value)


def test_folder_errors(tmp_path):
    _tree(tmp_path, ["x/t.wav", "y/t.wav", "x/inner/t.wav", "file.wav"])
    x, y = tmp_path / "x", tmp_path / "y"
    with pytest.raises(InvalidParameterError, match="at least 2 device folders, got 1"):
        pair_sessions_by_name([x])
    with pytest.raises(InputFileError, match="no such folder") as e:
        pair_sessions_by_name([x, tmp_path / "nowhere"])
    assert "nowhere" in str(e.value)
    with pytest.raises(InputFileError, match="is not a folder") as e:
        pair_sessions_by_name([x, tmp_path / "file.wav"])
    assert "file.wav" in str(e.value)
    with pytest.raises(InvalidParameterError, match="given twice"):
        pair_sessions_by_name([x, y, tmp_path / "y" / ".." / "y"])
    with pytest.raises(InvalidParameterError, match="inside device folder") as e:
        pair_sessions_by_name([x / "inner", y, x])
    assert "inner" in str(e.value)


def test_sidecar_beside_device_0_gives_values_not_files(tmp_path):
    _tree(tmp_path, ["d0/s/t1.wav", "d1/s/t1.wav", "d0/t2.wav", "d1/t2.wav"])
    _tree(tmp_path, ["d0/t3.wav", "d1/t3.wav", "d0/t4.wav", "d1/t4.wav"])
    sidecar = {
        "files": ["elsewhere.wav"],
        "scheme": "beepbeep",
        "temp_c": 25,
        "beep": {"f_hz": 3000.0},
        "devices": [{"self_distance_m": 0.12}, {"self_distance_m": 0.15}],
        "pairs": [{"a": 0, "b": 1, "distance_m": 2.5}],
    }
    (tmp_path / "d0/s/t1.json").write_text(json.dumps(sidecar))
    (tmp_path / "d1/t2.json").write_text(json.dumps(sidecar))  # not device 0's folder
    (tmp_path / "d0/t3.json").write_text("{not json")
    (tmp_path / "d0/t4.json").write_text(json.dumps({"scheme": "echo"}))
    s = {x.name: x for x in pair_sessions_by_name([tmp_path / "d0", tmp_path / "d1"])}
    t1 = s["s/t1"]
    assert t1.problem is None
    assert t1.files == (str(tmp_path / "d0/s/t1.wav"), str(tmp_path / "d1/s/t1.wav"))
    assert t1.params == {"beep": {"f_hz": 3000.0}, "temp_c": 25.0, "self_distance_m": [0.12, 0.15]}
    assert t1.truth == ((0, 1, 2.5),)
    assert s["t2"].problem is None and s["t2"].params == {} and s["t2"].truth == ()
    assert "t3.json" in s["t3"].problem and "cannot read" in s["t3"].problem
    assert "t4.json" in s["t4"].problem and "'echo'" in s["t4"].problem


def test_sessions_are_beepbeep_whatever_the_default_scheme(tmp_path):
    """A paired session is ranged as BeepBeep even with BatchOptions(scheme="echo")."""
    _tree(tmp_path, ["x/t.wav", "y/t.wav"])
    (s,) = pair_sessions_by_name([tmp_path / "x", tmp_path / "y"])
    rows = run_session(s, BatchOptions(scheme="echo"))
    assert rows[0]["scheme"] == "beepbeep" and rows[0]["status"] == "error"  # empty files


def test_pair_by_name_is_recorded_so_resume_does_not_mix_groupings(tmp_path):
    plain, paired = BatchOptions(), BatchOptions(pair_by_name=True)
    assert json.loads(plain.fingerprint())["grouping"] == "rules"
    assert json.loads(paired.fingerprint())["grouping"] == "pair-by-name"
    out = tmp_path / "r.csv"
    ResultsFile(out, paired, resume=False).close()
    ResultsFile(out, paired, resume=True).close()
    with pytest.raises(InvalidParameterError, match="other options"):
        ResultsFile(out, plain, resume=True)
