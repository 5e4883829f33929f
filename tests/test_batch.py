"""Tests of rangekit.batch: grouping into sessions, error rows, the resumable results file,
parallel and Dask runs giving the same file, and SIGKILL + resume."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rangekit.batch import (
    BATCH_COLUMNS,
    BatchOptions,
    ResultsFile,
    Session,
    find_sessions,
    iter_rows,
    run_batch,
    run_session,
)
from rangekit.errors import InputFileError, InvalidParameterError
from rangekit.io.audio import write_audio
from rangekit.io.sidecar import write_json
from rangekit.sim import pair_devices, render_beepbeep

ROOT = Path(__file__).resolve().parents[1]


def _render(folder: Path, name: str, distance: float, seed: int, *, n_dev: int = 2, mono=False):
    """A simulated exchange written like ``rangekit synth beepbeep`` (WAV(s) + sidecar)."""
    rng = np.random.default_rng(seed)
    if n_dev == 2:
        devices = pair_devices(distance, self_distance_m=0.1, rec_start_s=(0.02, 0.06))
    else:
        from rangekit.sim import Device

        pts = [np.array([0.0, 0.0, 1.2]), np.array([distance, 0.0, 1.2])]
        pts.append(np.array([0.0, distance, 1.2]))
        up = np.array([0.0, 0.0, 0.05])
        devices = [Device(p - up, p + up, rec_start_s=0.01 * (i + 1)) for i, p in enumerate(pts)]
    sim = render_beepbeep(devices, snr_db=25.0, rng=rng)
    truth = dict(sim.truth)
    if mono:
        files = [f"{name}_dev{i}.wav" for i in range(len(devices))]
        for f, x in zip(files, sim.recordings, strict=True):
            write_audio(folder / f, x, fs=44100.0)
    else:
        n = min(len(x) for x in sim.recordings)
        write_audio(
            folder / f"{name}.wav", np.stack([x[:n] for x in sim.recordings], 1), fs=44100.0
        )
        files = [f"{name}.wav"]
    truth["files"] = files
    write_json(folder / f"{name}.json", truth)
    return truth


@pytest.fixture(scope="module")
def archive(tmp_path_factory) -> Path:
    """12 sessions: sidecar'd stereo and mono ones, a 3-device one, a naming-rule one
    without sidecar, a lone file without sidecar, and a bad file."""
    root = tmp_path_factory.mktemp("archive")
    a, b = root / "day1", root / "day2" / "deep"
    b.mkdir(parents=True)
    a.mkdir()
    for i in range(6):
        _render(a, f"ex{i:02d}", 1.0 + 0.7 * i, seed=i)
    _render(b, "mono", 2.2, seed=20, mono=True)
    _render(b, "trio", 1.5, seed=21, n_dev=3)
    # Naming rule: devices without a sidecar (self-distance unknown: option default).
    _render(b, "take", 3.0, seed=22, mono=True)
    (b / "take.json").unlink()
    # A lone stereo file without sidecar, a gap in dev indices (-> singles), junk.
    shutil.copy(a / "ex00.wav", b / "lone.wav")
    shutil.copy(b / "take_dev0.wav", b / "gap_dev0.wav")
    shutil.copy(b / "take_dev1.wav", b / "gap_dev2.wav")
    (b / "junk.wav").write_text("not audio")
    (b / "plan.json").write_text(json.dumps({"format": "rangekit-floorplan", "walls": []}))
    return root


def test_find_sessions_grouping(archive):
    sessions = {s.name: s for s in find_sessions([archive])}
    deep = archive / "day2" / "deep"
    assert sorted(Path(n).name for n in sessions) == sorted(
        [f"ex{i:02d}" for i in range(6)]
        + ["mono", "trio", "take", "lone.wav", "gap_dev0.wav", "gap_dev2.wav", "junk.wav"]
    )
    mono = sessions[str(deep / "mono")]
    assert [Path(f).name for f in mono.files] == ["mono_dev0.wav", "mono_dev1.wav"]
    assert mono.params["self_distance_m"] == [0.1, 0.1]
    assert mono.truth == ((0, 1, pytest.approx(2.2)),)
    take = sessions[str(deep / "take")]
    assert [Path(f).name for f in take.files] == ["take_dev0.wav", "take_dev1.wav"]
    assert take.params == {} and take.truth == ()
    assert len(sessions[str(deep / "trio")].truth) == 3


def test_find_sessions_globs_files_and_errors(archive, tmp_path):
    day1 = archive / "day1"
    got = find_sessions([str(day1 / "ex0[01].wav")])
    assert [Path(s.name).name for s in got] == ["ex00", "ex01"]  # sidecar found next to it
    got = find_sessions([str(archive / "**" / "mono_dev*.wav")])
    assert [Path(s.name).name for s in got] == ["mono"]
    with pytest.raises(InputFileError, match="no_such"):
        find_sessions([tmp_path / "no_such"])
    with pytest.raises(InputFileError, match="matches no file"):
        find_sessions([str(tmp_path / "*.wav")])
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputFileError, match="no recordings"):
        find_sessions([tmp_path / "empty"])


def test_run_session_rows_and_errors(archive):
    sessions = {Path(s.name).name: s for s in find_sessions([archive])}
    opts = BatchOptions()
    rows = run_session(sessions["ex03"], opts)
    assert len(rows) == 1 and set(rows[0]) == set(BATCH_COLUMNS)
    r = rows[0]
    assert r["status"] == "ok" and r["session_rows"] == 1
    assert r["true_distance_m"] == pytest.approx(3.1)
    # The sidecar's self-distances are used: 1 cm accuracy (without them: ~10 cm off).
    assert abs(r["distance_m"] - r["true_distance_m"]) < 0.01
    trio = run_session(sessions["trio"], opts)
    assert [(t["a"], t["b"]) for t in trio] == [(0, 1), (0, 2), (1, 2)]
    assert all(t["session_rows"] == 3 for t in trio)
    assert max(abs(t["distance_m"] - t["true_distance_m"]) for t in trio) < 0.01
    bad = run_session(sessions["junk.wav"], opts)
    assert bad[0]["status"] == "error" and "junk.wav" in bad[0]["error"]
    assert bad[0]["distance_m"] is None
    # A copy of ex00 without sidecar: the options give the self-distance, no truth.
    ex00 = run_session(sessions["ex00"], opts)[0]
    lone = run_session(sessions["lone.wav"], BatchOptions(beepbeep={"self_distance_m": 0.1}))
    assert lone[0]["status"] == "ok" and lone[0]["true_distance_m"] is None
    assert lone[0]["distance_m"] == ex00["distance_m"]
    lone0 = run_session(sessions["lone.wav"], opts)[0]  # self-distance 0: 10 cm short
    assert lone0["distance_m"] == pytest.approx(ex00["distance_m"] - 0.1, abs=0.002)
    problem = Session("x", ("x.wav",), problem="'x.json': 'files' must be a list of names")
    assert run_session(problem, opts)[0]["error"].endswith("list of names")


def _sessions(archive):
    return [s for s in find_sessions([archive]) if "lone" not in s.name]


def test_options_are_typed_checked_and_picklable():
    """BatchOptions' two-way part is a TwoWayOptions (a dict of its fields converts, an
    unknown key is an error naming it); the options travel to worker processes."""
    import pickle

    from rangekit.batch import TwoWayOptions
    from rangekit.signals import Beep

    o = BatchOptions(beepbeep={"self_distance_m": [0.1, 0.12], "beep": Beep(f_hz=17000.0)})
    assert isinstance(o.beepbeep, TwoWayOptions) and o.beepbeep.self_distance_m == (0.1, 0.12)
    assert o.beepbeep.kwargs() == {"beep": Beep(f_hz=17000.0), "self_distance_m": [0.1, 0.12]}
    assert pickle.loads(pickle.dumps(o)) == o
    assert o == BatchOptions(
        beepbeep=TwoWayOptions(beep=Beep(f_hz=17000.0), self_distance_m=(0.1, 0.12))
    )
    with pytest.raises(InvalidParameterError, match="'selfdistance'"):
        BatchOptions(beepbeep={"selfdistance": 0.1})
    with pytest.raises(InvalidParameterError, match="scheme='x'"):
        BatchOptions(scheme="x")
    opts = json.loads(o.fingerprint())["beepbeep"]
    assert opts["beep"]["f_hz"] == 17000.0 and opts["temp_c"] is None  # JSON, library default


@pytest.mark.parametrize("suffix", [".csv", ".jsonl"])
def test_parallel_equals_serial_and_summary(archive, tmp_path, suffix):
    sessions = _sessions(archive)
    seen = []
    one = run_batch(
        sessions, tmp_path / f"one{suffix}", jobs=1, progress=lambda d, t: seen.append(d)
    )
    two = run_batch(sessions, tmp_path / f"two{suffix}", jobs=2, chunk=2)
    a = (tmp_path / f"one{suffix}").read_bytes()
    assert a == (tmp_path / f"two{suffix}").read_bytes()
    assert seen == list(range(len(sessions) + 1))
    n_bad = 3  # junk.wav and the two gap_dev files (mono: one device each)
    assert (one.total, one.ok, one.failed, one.skipped) == (
        len(sessions),
        len(sessions) - n_bad,
        n_bad,
        0,
    )
    assert (two.ok, two.failed, two.first_error) == (one.ok, one.failed, one.first_error)
    assert one.first_error.split(": ", 1)[0] == min(s.name for s in sessions if "gap" in s.name)
    rows = list(iter_rows(tmp_path / f"one{suffix}"))
    assert [r["session"] for r in rows] == sorted(r["session"] for r in rows)
    assert len(rows) == len(sessions) + 2  # the trio has 3 rows
    ok = [r for r in rows if r["status"] == "ok" and r["true_distance_m"] not in ("", None)]
    err = [abs(float(r["distance_m"]) - float(r["true_distance_m"])) for r in ok]
    assert len(err) == 10 and max(err) < 0.01


def test_existing_file_needs_resume_and_same_options(archive, tmp_path):
    sessions = _sessions(archive)[:2]
    out = tmp_path / "r.csv"
    run_batch(sessions, out)
    before = out.read_bytes()
    with pytest.raises(InvalidParameterError, match="--resume"):
        run_batch(sessions, out)
    other = BatchOptions(beepbeep={"temp_c": 30.0})
    with pytest.raises(InvalidParameterError, match="other options"):
        run_batch(sessions, out, other, resume=True)
    assert out.read_bytes() == before
    s = run_batch(sessions, out, resume=True)
    assert (s.skipped, s.ok + s.failed) == (2, 2)
    assert out.read_bytes() == before
    with pytest.raises(InvalidParameterError, match=r"\.csv or \.jsonl"):
        ResultsFile(tmp_path / "r.txt", BatchOptions(), resume=False)
    with pytest.raises(InputFileError, match="does not exist"):
        ResultsFile(tmp_path / "nope" / "r.csv", BatchOptions(), resume=False)
    (tmp_path / "alien.csv").write_text("a,b\n1,2\n")
    with pytest.raises(InvalidParameterError, match=r"alien\.csv\.meta\.json' is missing"):
        run_batch(sessions, tmp_path / "alien.csv", resume=True)
    shutil.copy(tmp_path / "r.csv.meta.json", tmp_path / "alien.csv.meta.json")
    with pytest.raises(InvalidParameterError, match="another results file"):
        run_batch(sessions, tmp_path / "alien.csv", resume=True)
    # The metadata of r.csv with its name changed to alien.csv's: the header decides.
    meta = json.loads((tmp_path / "r.csv.meta.json").read_text())
    (tmp_path / "alien.csv.meta.json").write_text(json.dumps({**meta, "results": "alien.csv"}))
    with pytest.raises(InvalidParameterError, match="not the header"):
        run_batch(sessions, tmp_path / "alien.csv", resume=True)
    assert (tmp_path / "alien.csv").read_text() == "a,b\n1,2\n"
    # A new batch does not replace a file in its metadata file's place that is not one...
    (tmp_path / "new.csv.meta.json").write_text("[]")
    with pytest.raises(InvalidParameterError, match="not a rangekit batch metadata"):
        run_batch(sessions, tmp_path / "new.csv")
    assert not (tmp_path / "new.csv").exists()
    # ... but one left by a batch whose results file was deleted.
    out.unlink()
    run_batch(sessions, out)
    assert out.read_bytes() == before
    run_batch(sessions, tmp_path / "r.jsonl")  # r.csv's metadata file is not in the way


@pytest.mark.parametrize("suffix", [".csv", ".jsonl"])
def test_old_layout_is_read_but_not_resumed(archive, tmp_path, suffix):
    """Files of the layout before the metadata file (options in a first line): iter_rows
    skips that line; --resume refuses them in one line and leaves them untouched."""
    sessions = _sessions(archive)[:1]
    head = (
        '# rangekit batch {"version": 1, "options": {}}\n' + ",".join(BATCH_COLUMNS)
        if suffix == ".csv"
        else '{"rangekit_batch": {"version": 1, "options": {}}}'
    )
    row = dict.fromkeys(BATCH_COLUMNS, "")
    row.update(session="s", session_rows="1", status="ok", distance_m="2.0")
    body = ",".join(row.values()) if suffix == ".csv" else json.dumps(row)
    old = tmp_path / f"old{suffix}"
    old.write_text(head + "\n" + body + "\n")
    assert [r["distance_m"] for r in iter_rows(old)] == ["2.0"]
    with pytest.raises(InvalidParameterError, match="older rangekit") as e:
        run_batch(sessions, old, resume=True)
    assert "\n" not in str(e.value)
    assert old.read_text() == head + "\n" + body + "\n"


_RANGED: dict = {}  # session name -> rows, shared by the torn-tail tests


@pytest.mark.parametrize("suffix", [".csv", ".jsonl"])
def test_torn_tail_is_cut_and_redone(archive, tmp_path, suffix, monkeypatch):
    sessions = _sessions(archive)
    # Each session is ranged once for both formats: the resumes below redo sessions from
    # a cache (what is tested is the file, not the ranging).
    import copy

    import rangekit.batch._run as batch_run

    def ranged_once(session, options):
        if session.name not in _RANGED:
            _RANGED[session.name] = run_session(session, options)
        return copy.deepcopy(_RANGED[session.name])

    monkeypatch.setattr(batch_run, "run_session", ranged_once)
    full = tmp_path / f"full{suffix}"
    first_error = run_batch(sessions, full).first_error
    lines = full.read_text().splitlines(keepends=True)
    n_head = 1 if suffix == ".csv" else 0
    trio_at = next(i for i, ln in enumerate(lines) if "trio" in ln)
    for cut, whole in (
        ("".join(lines[: trio_at + 1]), trio_at),  # one of the trio's three rows
        ("".join(lines[: trio_at + 2]) + lines[trio_at + 2][:17], trio_at),  # + a torn line
        ("".join(lines[:n_head]) + lines[n_head][:5], n_head),  # only a torn first row
    ):
        part = tmp_path / f"part{suffix}"
        part.write_text(cut)
        meta = json.loads((tmp_path / f"full{suffix}.meta.json").read_text())
        write_json(tmp_path / f"part{suffix}.meta.json", {**meta, "results": part.name})
        ResultsFile(part, BatchOptions(), resume=True).close()  # opening cuts the torn tail
        assert part.read_text() == "".join(lines[:whole])
        s = run_batch(sessions, part, resume=True)
        assert part.read_bytes() == full.read_bytes()
        assert s.skipped < len(sessions)
        assert s.first_error == first_error  # read back from the file for skipped sessions
    s = run_batch(sessions, part, resume=True)  # every session from the file
    assert (s.skipped, s.first_error) == (len(sessions), first_error)
    assert "junk.wav" in s.first_error or "gap_dev" in s.first_error


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_sigkill_twice_then_resume_equals_uninterrupted(archive, tmp_path):
    """The acceptance test: kill -9 the batch twice at random moments, resume, compare."""
    rng = np.random.default_rng(7)
    out = tmp_path / "out.csv"
    ref = tmp_path / "ref.csv"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}

    def cmd(path, jobs):
        c = [sys.executable, "-m", "rangekit", "batch", str(archive), "-o", str(path), "-q"]
        return [*c, "--jobs", str(jobs)]

    r = subprocess.run(cmd(ref, 1), env=env, capture_output=True, text=True)
    assert r.returncode == 8, r.stderr  # some sessions are bad files
    kills = 0
    for attempt in range(2):
        args = cmd(out, 2) + (["--resume"] if attempt else [])
        target = int(rng.integers(1, 8))  # sessions in the file before the kill
        p = subprocess.Popen(args, env=env, stderr=subprocess.PIPE)
        deadline = time.monotonic() + 120
        while p.poll() is None and time.monotonic() < deadline:
            n = out.read_text().count("\n") - 1 if out.exists() else 0
            if n >= target:
                p.send_signal(signal.SIGKILL)
                kills += 1
                break
            time.sleep(0.002)
        p.wait()
    assert kills >= 1
    assert out.read_bytes() != ref.read_bytes()  # interrupted: not the final file yet
    r = subprocess.run([*cmd(out, 2), "--resume"], env=env, capture_output=True, text=True)
    assert r.returncode == 8, r.stderr
    assert out.read_bytes() == ref.read_bytes()
    names = ["out.csv", "out.csv.meta.json", "ref.csv", "ref.csv.meta.json"]
    assert sorted(os.listdir(tmp_path)) == names
    meta = json.loads((tmp_path / "out.csv.meta.json").read_text())
    assert {**meta, "results": "ref.csv"} == json.loads(Path(tmp_path / names[3]).read_text())


def test_dask_local_cluster_equals_local(archive, tmp_path):
    distributed = pytest.importorskip("distributed")
    sessions = _sessions(archive)
    run_batch(sessions, tmp_path / "local.jsonl", jobs=1)
    with distributed.LocalCluster(
        n_workers=1,
        threads_per_worker=2,
        processes=False,
        protocol="tcp",
        dashboard_address=None,
    ) as cluster:
        s = run_batch(sessions, tmp_path / "dask.jsonl", scheduler=cluster.scheduler_address)
    assert s.total == len(sessions)
    assert (tmp_path / "dask.jsonl").read_bytes() == (tmp_path / "local.jsonl").read_bytes()


def test_unreachable_scheduler_is_an_input_error(archive, tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    import rangekit.batch

    monkeypatch.setattr(rangekit.batch, "DASK_CONNECT_TIMEOUT_S", 1.0)
    with pytest.raises(InputFileError, match="Dask scheduler"):
        run_batch(_sessions(archive)[:1], tmp_path / "x.csv", scheduler="tcp://127.0.0.1:9")


def test_default_chunk_keeps_the_last_tasks_short():
    from rangekit.batch._run import default_chunk

    # 60 sessions on 2 workers: 1 a task (it was 7: one worker could end 7 sessions late)
    assert default_chunk(60, 2) == 1
    assert [default_chunk(n, 2) for n in (0, 31, 32, 100, 500, 511, 10_000)] == [
        1, 1, 1, 3, 15, 15, 16
    ]  # fmt: skip
    assert default_chunk(10_000, 0) == 16  # never divides by zero
