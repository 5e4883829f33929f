"""The recording spec ``PATH[+PATH][@M]`` has one parser,
``rangekit.ranging.calibration.parse_recording``: ``rangekit calibrate`` reads its
RECORDINGs with it and the output guard counts the files it names (``recording_paths``)."""

from __future__ import annotations

import pytest
from clihelp import assert_error, run

from rangekit.errors import InvalidParameterError
from rangekit.ranging.calibration import parse_recording, recording_paths


def test_syntax(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert parse_recording("a.wav") == (["a.wav"], None)
    assert parse_recording("a.wav", 2.0) == (["a.wav"], 2.0)
    assert parse_recording("a.wav@0.5", 2.0) == (["a.wav"], 0.5)  # @M wins over the default
    assert parse_recording("a.wav+b.wav@3") == (["a.wav", "b.wav"], 3.0)
    assert parse_recording("a+b+c@1e3") == (["a", "b", "c"], 1000.0)
    assert parse_recording("x@y.wav@1") == (["x@y.wav"], 1.0)  # the last '@' only
    assert recording_paths("a.wav+b.wav@nonsense") == ["a.wav", "b.wav"]


def test_existing_paths_are_never_split(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ("p+q.wav", "at@2.wav"):
        (tmp_path / name).write_bytes(b"")
    assert parse_recording("p+q.wav") == (["p+q.wav"], None)
    assert parse_recording("at@2.wav", 1.5) == (["at@2.wav"], 1.5)  # not a distance of 2
    assert parse_recording("at@2.wav@0.7") == (["at@2.wav"], 0.7)
    assert parse_recording("p+q.wav@4") == (["p+q.wav"], 4.0)
    assert recording_paths("p+q.wav+r.wav") == ["p", "q.wav", "r.wav"]  # that one is absent


@pytest.mark.parametrize("tail", ["", "x", "nan", "inf", "0", "-1", "1e4", "2m"])
def test_bad_distances_refused(tail):
    with pytest.raises(InvalidParameterError, match=r"^'a\.wav@.*': the distance") as e:
        parse_recording(f"a.wav@{tail}", 1.0)
    assert e.value.exit_code == 2


def test_calibrate_reports_the_parsers_error_and_guards_its_paths(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ("m0.wav", "m1.wav", "at@2.wav"):
        (tmp_path / name).write_bytes(b"")
    with pytest.raises(InvalidParameterError) as e:
        parse_recording("m0.wav@x")
    res = run(["calibrate", "m0.wav@x", "-o", "cal.json"])
    line = assert_error(res, 2)
    assert line.startswith(f"rangekit: error: Invalid value: {e.value} (see ")
    line = assert_error(run(["calibrate", "m0.wav", "-o", "cal.json"]), 2, "no distance")
    # -o may not be any file a spec names (recording_paths), before anything is read
    for spec, out in (("m0.wav+m1.wav@1", "m1.wav"), ("at@2.wav@1", "at@2.wav")):
        assert_error(run(["calibrate", spec, "-o", out]), 2, "refusing to overwrite an input")
