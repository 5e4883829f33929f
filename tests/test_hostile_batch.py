"""Hostile archives (issue 17): one bad file never stops a batch, sidecars are checked
and confined to the folder the batch was given, special files are never opened."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from rangekit.batch import BatchOptions, find_sessions, iter_rows, run_batch, run_session
from rangekit.errors import InputFileError
from rangekit.io.guard import MAX_JSON_DEPTH, parse_json, read_capped, read_json_file
from rangekit.ranging.calibration import Calibration, read_calibration

ROOT = Path(__file__).resolve().parents[1]
FIX = ROOT / "fixtures_audio"


def _sessions(*inputs) -> dict[str, object]:
    return {Path(s.name).name: s for s in find_sessions(list(inputs))}


def _archive(tmp_path: Path) -> Path:
    """A folder with one good session (recording + sidecar) to range beside the bad ones."""
    d = tmp_path / "arch"
    d.mkdir()
    shutil.copy(FIX / "beepbeep_2p5m.wav", d / "good.wav")
    shutil.copy(FIX / "beepbeep_2p5m.json", d / "good.json")
    obj = json.loads((d / "good.json").read_text())
    obj["files"] = ["good.wav"]
    (d / "good.json").write_text(json.dumps(obj))
    return d


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_special_files_are_error_rows_never_opened(tmp_path):
    d = _archive(tmp_path)
    os.symlink("/dev/zero", d / "evil.json")
    os.symlink("/dev/zero", d / "zero.wav")
    os.mkfifo(d / "pipe.json")
    os.mkfifo(d / "pipe.wav")
    s = _sessions(d)
    assert s["good"].problem is None
    for name, kind in [
        ("evil.json", "a device"),
        ("zero.wav", "a device"),
        ("pipe.json", "a FIFO"),
        ("pipe.wav", "a FIFO"),
    ]:
        assert kind in s[name].problem and name in s[name].problem
        row = run_session(s[name], BatchOptions())[0]
        assert row["status"] == "error" and name in row["error"]


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("[" * (MAX_JSON_DEPTH + 1) + "]" * (MAX_JSON_DEPTH + 1), "nested deeper"),
        ('{"files": ["x.wav"], "temp_c": ' + "1" * 5000 + "}", "a number of 5000 characters"),
        ('{"files": ["x.wav"], "pairs": [{"a": NaN, "b": 1, "distance_m": 1}]}', "NaN"),
        ('{"files": ["x.wav"], "temp_c": 1e400}', "out of range"),
        ('{"files": ["x.wav"], ', "Expecting"),
        (b"\xff\xfe{}", "not UTF-8"),
    ],
)
def test_a_sidecar_that_fails_to_parse_is_an_error_row_claiming_its_recordings(tmp_path, text, why):
    d = _archive(tmp_path)
    shutil.copy(FIX / "beepbeep_2p5m.wav", d / "x.wav")
    p = d / "x.json"
    p.write_bytes(text if isinstance(text, bytes) else text.encode())
    s = _sessions(d)
    assert why in s["x"].problem and "x.json" in s["x"].problem
    assert "x.wav" not in s  # not ranged with the defaults instead
    assert s["good"].problem is None


def test_sidecar_with_bom_is_read(tmp_path):
    d = _archive(tmp_path)
    raw = (d / "good.json").read_bytes()
    (d / "good.json").write_bytes(b"\xef\xbb\xbf" + raw)
    s = _sessions(d)["good"]
    assert s.problem is None and s.params["self_distance_m"]


@pytest.mark.parametrize(
    ("change", "why"),
    [
        ({"self_distance_m": True}, "self_distance_m=True must be a number"),
        ({"self_distance_m": [0.1, "x"]}, r"self_distance_m[1]='x' must be a number"),
        ({"self_distance_m": 5.0}, "must be within [0, 2]"),
        ({"temp_c": 1e300}, "temp_c=1e+300 must be within [-60, 60]"),
        ({"temp_c": False}, "temp_c=False must be a number"),
        ({"beep": "loud"}, "'beep' must be an object"),
        ({"beep": {"n_bursts": True}}, "beep.n_bursts=True must be an integer"),
        ({"pairs": [{"a": True, "b": 1, "distance_m": 2.0}]}, "pairs[0].a=True"),
        ({"pairs": [{"a": 0, "b": 1, "distance_m": -1}]}, "pairs[0].distance_m=-1"),
        ({"pairs": "x"}, "'windows' and 'pairs' must be lists"),
        ({"files": []}, "'files' must be a list of 1 to 256 names"),
        ({"files": [3]}, "'files' must be a list of file names"),
    ],
)
def test_sidecar_values_are_type_and_range_checked(tmp_path, change, why):
    d = _archive(tmp_path)
    obj = json.loads((d / "good.json").read_text())
    obj.update(change)
    (d / "good.json").write_text(json.dumps(obj))
    s = _sessions(d)["good"]
    assert s.problem is not None and why in s.problem, s.problem


@pytest.mark.parametrize(
    "files",
    [
        ["../outside.wav"],
        ["../no_such.wav"],
        ["/etc/hostname"],
        ["/no/such/file.wav"],
        ["sub/../../outside.wav"],
        ["link.wav"],  # a link inside the folder to a file outside it
    ],
)
def test_sidecar_files_are_confined_to_the_given_folder(tmp_path, files):
    d = _archive(tmp_path)
    shutil.copy(FIX / "beepbeep_2p5m.wav", tmp_path / "outside.wav")
    (d / "sub").mkdir()
    os.symlink(tmp_path / "outside.wav", d / "link.wav")
    (d / "x.json").write_text(json.dumps({"files": files}))
    s = _sessions(d)
    problem = s["x"].problem
    assert problem is not None and "x.json" in problem
    assert "outside the folder" in problem or "absolute path" in problem
    # the message is the same whether the file outside exists or not: no oracle
    assert "no such" not in problem and "audio" not in problem
    row = run_session(s["x"], BatchOptions())[0]
    assert row["status"] == "error" and row["distance_m"] is None
    # the link itself is refused as a recording too
    assert "outside the folder" in s["link.wav"].problem


def test_sidecar_file_inside_the_folder_through_dotdot_is_fine(tmp_path):
    d = _archive(tmp_path)
    (d / "sub").mkdir()
    shutil.copy(FIX / "beepbeep_2p5m.wav", d / "a.wav")
    (d / "sub" / "x.json").write_text(json.dumps({"files": ["../a.wav"]}))
    s = _sessions(d)
    assert s["x"].problem is None and Path(s["x"].files[0]).resolve() == (d / "a.wav").resolve()


def test_recursive_glob_does_not_follow_link_loops(tmp_path):
    d = _archive(tmp_path)
    for i in range(3):
        os.symlink(d, d / f"loop{i}")
    got = find_sessions([str(d / "**" / "*.wav")])
    assert [Path(s.name).name for s in got] == ["good"]
    got = find_sessions([d])
    assert [Path(s.name).name for s in got] == ["good"]


def test_non_utf8_recording_name_csv_and_resume(tmp_path):
    d = tmp_path / "a"
    d.mkdir()
    bad = os.fsdecode(b"r\xffec.wav")
    (d / bad).write_text("not audio")
    (d / "junk.wav").write_text("not audio")
    out = tmp_path / "r.csv"
    sessions = find_sessions([d])
    summary = run_batch(sessions, out, BatchOptions())
    assert summary.failed == 2
    rows = list(iter_rows(out))
    assert any("\\xff" in r["session"] for r in rows)
    out.write_text(out.read_text().rsplit("\n", 2)[0] + "\n")  # drop a session: torn
    summary = run_batch(sessions, out, BatchOptions(), resume=True)
    assert summary.total == 2 and summary.failed == 2


def test_guarded_reader_limits(tmp_path):
    assert parse_json(b'\xef\xbb\xbf{"a": 1}', name="x") == {"a": 1}
    with pytest.raises(InputFileError, match=r"'x' as JSON: -Infinity is not"):
        parse_json('{"a": -Infinity}', name="x")
    big = tmp_path / "big.json"
    big.write_bytes(b" " * 101)
    with pytest.raises(InputFileError, match=r"101 bytes is more than the limit of 100"):
        read_capped(big, 100)
    with pytest.raises(InputFileError, match=r"it is a directory"):
        read_json_file(tmp_path)
    fifo = tmp_path / "p.json"
    os.mkfifo(fifo)
    with pytest.raises(InputFileError, match=r"p\.json': it is a FIFO"):
        read_json_file(fifo)


#: A valid two-way calibration, built by the library (what ``rangekit calibrate`` writes).
VALID_CAL = Calibration(
    scheme="beepbeep", model="offset", offset_m=0.1, sigma_offset_m=0.001, latency_s=0.0,
    sigma_latency_s=0.0, speed_m_s=343.0, sigma_speed_m_s=0.0, cov_speed_offset=0.0,
    n_recordings=3, distances_m=(1.0,), rms_residual_m=0.001,
)  # fmt: skip


def _cal(tmp_path: Path, **change) -> Path:
    obj = VALID_CAL.to_dict()
    obj.update(change)
    for k in [k for k, v in change.items() if v is KeyError]:
        del obj[k]
    p = tmp_path / "cal.json"
    p.write_text(json.dumps(obj))
    return p


def test_calibration_values_are_checked(tmp_path):
    assert read_calibration(_cal(tmp_path)).speed_m_s == 343.0
    for change, why in [
        ({"speed_m_s": 0}, "speed_m_s=0 must be within [200, 2000]"),
        ({"speed_m_s": -343.0}, "speed_m_s=-343.0 must be within"),
        ({"speed_m_s": True}, "speed_m_s=True must be a finite number"),
        ({"offset_m": 1e300}, "offset_m=1e+300 must be within"),
        ({"sigma_offset_m": -1.0}, "sigma_offset_m=-1.0 must be within"),
        ({"cov_speed_offset": 5.0}, "cov_speed_offset=5.0 exceeds"),
        ({"n_recordings": True}, "n_recordings=True must be an integer"),
        ({"speed_m_s": KeyError}, "speed_m_s"),
    ]:
        with pytest.raises(InputFileError, match="not a valid rangekit calibration") as e:
            read_calibration(_cal(tmp_path, **change))
        assert why in str(e.value) and e.value.exit_code == 3


def test_broken_neighbour_sidecar_of_a_named_file(tmp_path):
    d = _archive(tmp_path)
    shutil.copy(FIX / "beepbeep_2p5m.wav", d / "x.wav")
    (d / "x.json").write_text("{broken")
    (d / "notes.json").write_text("{also broken")  # about nothing that was asked for
    s = _sessions(d / "x.wav")
    assert list(s) == ["x"] and "x.json" in s["x"].problem
    s = _sessions(d / "good.wav")
    assert list(s) == ["good"] and s["good"].problem is None
