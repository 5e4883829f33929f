"""CLI tests of ``rangekit batch``: output, exit codes, progress, resume, errors."""

from __future__ import annotations

import csv
import json
import shutil

import numpy as np
import pytest
from clihelp import assert_error, ok, run
from rangekit_cli.batch_cmd import EXIT_ALL_FAILED, EXIT_SOME_FAILED

from rangekit.io.audio import write_audio
from rangekit.io.sidecar import write_json
from rangekit.sim import pair_devices, render_beepbeep


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    """Three sidecar'd sessions at 1.5, 2.5 and 3.5 m."""
    root = tmp_path_factory.mktemp("good")
    for i, d in enumerate((1.5, 2.5, 3.5)):
        devices = pair_devices(d, self_distance_m=0.1, rec_start_s=(0.02, 0.05))
        sim = render_beepbeep(devices, snr_db=25.0, rng=np.random.default_rng(i))
        n = min(len(x) for x in sim.recordings)
        write_audio(root / f"s{i}.wav", np.stack([x[:n] for x in sim.recordings], 1), fs=44100.0)
        write_json(root / f"s{i}.json", {**sim.truth, "files": [f"s{i}.wav"]})
    return root


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_all_ranged_exit_0_and_accurate(good, tmp_path):
    out = tmp_path / "r.csv"
    r = ok(run(["batch", good, "-o", out, "--jobs", 1]))
    rows = _rows(out)
    assert [row["session"].rsplit("/", 1)[-1] for row in rows] == ["s0", "s1", "s2"]
    for row in rows:
        assert row["status"] == "ok"
        assert abs(float(row["distance_m"]) - float(row["true_distance_m"])) < 0.01
    err = r.stderr.splitlines()
    assert err[0] == f"batch: 3 sessions, 1 job -> {out}"
    assert err[-1] == f"batch: 3 of 3 sessions ranged, 0 failed -> {out}"


def test_jsonl_some_failed_exit_8(good, tmp_path):
    src = tmp_path / "src"
    shutil.copytree(good, src)
    (src / "broken.wav").write_text("not audio")
    out = tmp_path / "r.jsonl"
    r = run(["batch", src, "-o", out, "-q"])
    assert r.exit_code == EXIT_SOME_FAILED, r.stderr
    assert r.stderr == ""  # -q
    rows = [json.loads(ln) for ln in out.read_text().splitlines()]
    assert json.loads((tmp_path / "r.jsonl.meta.json").read_text())["results"] == "r.jsonl"
    bad = [x for x in rows if x["status"] == "error"]
    assert len(bad) == 1 and "broken.wav" in bad[0]["error"]
    assert bad[0]["distance_m"] is None


def test_none_ranged_exit_9_and_resume_skips(tmp_path):
    (tmp_path / "a.wav").write_text("x")
    (tmp_path / "b.wav").write_bytes(b"")
    out = tmp_path / "r.csv"
    r = run(["batch", tmp_path / "a.wav", tmp_path / "b.wav", "-o", out])
    assert r.exit_code == EXIT_ALL_FAILED, r.stderr
    assert len(_rows(out)) == 2
    before = out.read_bytes()
    r = run(["batch", tmp_path / "a.wav", tmp_path / "b.wav", "-o", out, "--resume"])
    assert r.exit_code == EXIT_ALL_FAILED
    assert "2 sessions already in" in r.stderr
    assert out.read_bytes() == before


def test_options_reach_the_sessions(good, tmp_path):
    # Without sidecars the self-distance comes from the option: copies of the files only.
    src = tmp_path / "nosidecar"
    src.mkdir()
    for f in good.glob("*.wav"):
        shutil.copy(f, src / f.name)
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    ok(run(["batch", src, "-o", a, "-q", "--self-distance", "0.1"]))
    ok(run(["batch", src, "-o", b, "-q"]))
    da = np.array([float(x["distance_m"]) for x in _rows(a)])
    db = np.array([float(x["distance_m"]) for x in _rows(b)])
    np.testing.assert_allclose(da, [1.5, 2.5, 3.5], atol=0.01)
    np.testing.assert_allclose(db, da - 0.1, atol=0.003)
    assert all(x["true_distance_m"] == "" for x in _rows(a))


def test_verbose_says_what_was_chosen_quiet_nothing_same_rows(good, tmp_path):
    """--verbose (the shared verbosity_options) adds what was chosen; -q drops every note;
    the results file is the same byte for byte."""
    src = tmp_path / "src"
    src.mkdir()
    for f in ("s0.wav", "s0.json"):
        shutil.copy(good / f, src / f)
    (src / "broken.wav").write_text("not audio")
    err = {}
    for flag in ("-q", "", "-v"):
        out = tmp_path / f"r{flag}.csv"
        r = run(["batch", src, "-o", out, "-j", 1, *([flag] if flag else [])])
        assert r.exit_code == EXIT_SOME_FAILED, r.stderr
        err[flag] = r.stderr.replace(out.name, "r.csv").splitlines()
    assert err["-q"] == []
    body = {(tmp_path / f"r{flag}.csv").read_bytes() for flag in err}
    assert len(body) == 1
    extra = [ln for ln in err["-v"] if ln not in err[""]]
    assert extra == [
        "batch: scheme beepbeep, detector changepoint; 1 of 2 sessions take their scheme or "
        "setup from a sidecar",
        f"batch: options recorded in {tmp_path / 'r.csv.meta.json'}",
        f"batch: first failed session: {src / 'broken.wav'}: '{src / 'broken.wav'}' is not a "
        "readable audio file (Format not recognised.)",
    ]
    assert [ln for ln in err["-v"] if ln in err[""]] == [ln for ln in err[""]]
    assert_error(run(["batch", src, "-o", tmp_path / "x.csv", "-q", "-v"]), 2, "--quiet")
    assert not (tmp_path / "x.csv").exists()


@pytest.mark.parametrize(
    ("args", "code", "named"),
    [
        (["-o", "OUT/r.txt"], 2, ".csv or .jsonl"),
        (["-o", "OUT/missing/r.csv"], 3, "missing"),
        (["-o", "OUT/r.csv", "--jobs", "0"], 2, "--jobs"),
        (["-o", "OUT/r.csv", "--jobs", "2", "--scheduler", "tcp://x:1"], 2, "--scheduler"),
        (["-o", "OUT/r.csv", "--period", "0.1"], 2, "--period"),
        (["-o", "OUT/r.csv", "--scheme", "echo", "--latency", "0.1"], 2, "--latency"),
        (["-o", "OUT/r.csv", "--scheme", "oneway", "--freq", "17000"], 2, "--freq"),
        (["-o", "OUT/r.csv", "--self-distance", "5"], 2, "--self-distance"),
        ([], 2, "--output"),
    ],
)
def test_usage_errors(good, tmp_path, args, code, named):
    args = [a.replace("OUT", str(tmp_path)) for a in args]
    assert_error(run(["batch", good, *args]), code, named)
    assert list(tmp_path.iterdir()) == []


def test_missing_inputs_and_existing_output(good, tmp_path):
    out = tmp_path / "r.csv"
    assert_error(run(["batch", tmp_path / "nothing_here", "-o", out]), 3, "nothing_here")
    assert_error(run(["batch", str(tmp_path / "*.flac"), "-o", out]), 3, "matches no file")
    out.write_text("precious\n")
    assert_error(run(["batch", good, "-o", out]), 2, "--resume", "r.csv")
    line = assert_error(run(["batch", good, "-o", out, "--resume"]), 2, "cannot resume")
    assert "r.csv" in line
    assert out.read_text() == "precious\n"


def test_resume_with_other_options_refused(good, tmp_path):
    out = tmp_path / "r.csv"
    ok(run(["batch", good, "-o", out, "-q", "--jobs", 1]))
    before = out.read_bytes()
    r = run(["batch", good, "-o", out, "--resume", "--temperature", "30"])
    assert_error(r, 2, "other options", "r.csv")
    assert out.read_bytes() == before


def test_scheduler_without_reachable_cluster(good, tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    import rangekit.batch

    monkeypatch.setattr(rangekit.batch, "DASK_CONNECT_TIMEOUT_S", 1.0)
    out = tmp_path / "r.csv"
    r = run(["batch", good, "-o", out, "-q", "--scheduler", "tcp://127.0.0.1:9"])
    assert_error(r, 3, "tcp://127.0.0.1:9")


def test_help_names_the_rules():
    r = ok(run(["batch", "--help"]))
    for s in ("--resume", "--jobs", "--scheduler", "_dev0", "sidecar", "docs/batch.md"):
        assert s in r.stdout
    assert "-q, --quiet" in r.stdout and "-v, --verbose" in r.stdout


def test_ultrasonic_sessions_from_their_sidecars(tmp_path):
    """Sidecars of `synth oneway` and `synth echo` give scheme, period and truth; the
    rows equal `rangekit range --scheme ...` on the same file."""
    ow, ec = tmp_path / "ow", tmp_path / "ec"
    ow.mkdir()
    ec.mkdir()
    ok(
        run(
            ["synth", "oneway", "--tx", "1,0.5", "--tx", "-1,2", "--seed", "1", "-o", ow / "ow.wav"]
        )
    )
    plan = tmp_path / "plan.json"
    walls = [[[0, 0], [4, 0]], [[4, 0], [4, 3]], [[4, 3], [0, 3]], [[0, 3], [0, 0]]]
    plan.write_text(
        json.dumps(
            {
                "format": "rangekit-floorplan",
                "version": 1,
                "units": "m",
                "walls": [{"from": a, "to": b} for a, b in walls],
            }
        )
    )
    args = ["synth", "echo", "--map", plan, "--pose", "1,1,90", "--pose", "1,1.5,90"]
    ok(run([*args, "--seed", "2", "-o", ec / "echo.wav"]))
    out = tmp_path / "u.csv"
    ok(run(["batch", ow, ec, "-o", out, "-q"]))  # default --scheme beepbeep: sidecars rule
    rows = _rows(out)
    assert {r["scheme"] for r in rows} == {"oneway", "echo"}
    assert len(rows) == 2 * 3 + 2
    for r in rows:
        assert abs(float(r["distance_m"]) - float(r["true_distance_m"])) < 0.005
    ref = ok(
        run(["range", "--scheme", "oneway", ow / "ow.wav", "--period", "0.2", "--format", "json"])
    )
    want = [x["distance_m"] for x in json.loads(ref.stdout)["ranges"]]
    got = [float(r["distance_m"]) for r in rows if r["scheme"] == "oneway"]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
