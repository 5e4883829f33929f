"""CLI tests of ``rangekit batch --pair-by-name DIR0 DIR1 ...``: device folders of mono
recordings paired by file name (``docs/batch.md``, "Device folders paired by name")."""

from __future__ import annotations

import csv
import json
import shutil

import numpy as np
import pytest
from clihelp import assert_error, ok, run
from rangekit_cli.batch_cmd import EXIT_SOME_FAILED

from rangekit.io.audio import write_audio
from rangekit.sim import pair_devices, render_beepbeep

#: take key -> (true distance m, seed); device 1's take_02 is a FLAC, take_03 is nested.
TAKES = {"take_01": (0.8, 1), "take_02": (1.9, 2), "day2/take_03": (3.1, 3)}


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    """``dev0/`` and ``dev1/`` paired by name, the same recordings as ``flat/KEY_devN.wav``
    (the NAME_devN rule), and the true distance of every take."""
    root = tmp_path_factory.mktemp("pairs")
    truth = {}
    for key, (d, seed) in TAKES.items():
        sim = render_beepbeep(
            pair_devices(d, self_distance_m=0.1), snr_db=30.0, rng=np.random.default_rng(seed)
        )
        truth[key] = sim.truth["pairs"][0]["distance_m"]
        for i, x in enumerate(sim.recordings):
            suffix = ".flac" if (i, key) == (1, "take_02") else ".wav"
            path = root / f"dev{i}" / f"{key}{suffix}"
            path.parent.mkdir(parents=True, exist_ok=True)
            write_audio(path, x, fs=sim.fs[i])
            flat = root / "flat" / f"{key.replace('/', '_')}_dev{i}{suffix}"
            flat.parent.mkdir(exist_ok=True)
            write_audio(flat, x, fs=sim.fs[i])
    return root, truth


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _pair(root, out, *extra):
    devs = [root / "dev0", root / "dev1"]
    return run(
        ["batch", "--pair-by-name", *devs, "-o", out, "--self-distance", 0.1, "-j", 1, *extra]
    )


def test_pairs_by_name_ranges_every_take(archive, tmp_path):
    root, truth = archive
    out = tmp_path / "r.csv"
    r = ok(_pair(root, out))
    rows = _rows(out)
    assert [row["session"] for row in rows] == sorted(TAKES)  # session names = keys
    for row in rows:
        assert row["status"] == "ok" and (row["a"], row["b"]) == ("0", "1")
        err = float(row["distance_m"]) - truth[row["session"]]
        assert abs(err) < 0.02, (row["session"], err)
        assert row["true_distance_m"] == ""  # no sidecar
    take_02 = next(row for row in rows if row["session"] == "take_02")
    # device order = folder order; the device folders are kept
    assert take_02["files"] == f"{root}/dev0/take_02.wav;{root}/dev1/take_02.flac"
    assert r.stderr.splitlines()[0] == f"batch: 3 sessions, 1 job -> {out}"
    # The same recordings grouped by the NAME_devN rule give identical distances.
    out2 = tmp_path / "flat.csv"
    ok(run(["batch", root / "flat", "-o", out2, "--self-distance", 0.1, "--jobs", 1, "-q"]))
    flat = {row["session"].rsplit("/", 1)[-1]: row["distance_m"] for row in _rows(out2)}
    assert {row["session"].replace("/", "_"): row["distance_m"] for row in rows} == flat


def test_sidecar_beside_device_0_gives_the_truth(archive, tmp_path):
    root, _ = archive
    src = tmp_path / "src"
    shutil.copytree(root, src)
    sidecar = {"files": ["ignored.wav"], "pairs": [{"a": 0, "b": 1, "distance_m": 1.9}]}
    (src / "dev0" / "take_02.json").write_text(json.dumps(sidecar))
    out = tmp_path / "r.jsonl"
    ok(_pair(src, out, "-q"))
    rows = {x["session"]: x for x in map(json.loads, out.read_text().splitlines())}
    assert rows["take_02"]["true_distance_m"] == 1.9
    assert rows["take_01"]["true_distance_m"] is None


def test_missing_take_is_an_error_row_exit_8_and_resume(archive, tmp_path):
    root, _ = archive
    src = tmp_path / "src"
    shutil.copytree(root, src)
    (src / "dev1" / "take_01.wav").unlink()
    out = tmp_path / "r.csv"
    r = _pair(src, out, "-q")
    assert r.exit_code == EXIT_SOME_FAILED, r.stderr
    rows = {row["session"]: row for row in _rows(out)}
    assert sorted(rows) == sorted(TAKES)
    bad = rows["take_01"]
    assert bad["status"] == "error" and str(src / "dev1") in bad["error"]
    assert bad["distance_m"] == ""
    assert all(rows[k]["status"] == "ok" for k in ("take_02", "day2/take_03"))
    # --resume with the flag skips every session and leaves the file as it was ...
    before = out.read_bytes()
    r = _pair(src, out, "--resume")
    assert r.exit_code == EXIT_SOME_FAILED and "3 sessions already in" in r.stderr
    assert out.read_bytes() == before
    # ... and without it (other session names) is refused rather than mixed.
    r = run(["batch", src / "dev0", src / "dev1", "-o", out, "--self-distance", 0.1, "--resume"])
    assert_error(r, 2, "other options", "r.csv")
    assert out.read_bytes() == before


@pytest.mark.parametrize(
    ("args", "code", "named"),
    [
        (["--scheme", "echo"], 2, "--pair-by-name"),
        (["--scheme", "oneway"], 2, "--scheme beepbeep"),
    ],
)
def test_usage_errors(archive, tmp_path, args, code, named):
    root, _ = archive
    r = run(
        ["batch", "--pair-by-name", root / "dev0", root / "dev1", "-o", tmp_path / "r.csv", *args]
    )
    assert_error(r, code, named)
    assert list(tmp_path.iterdir()) == []


def test_input_errors(archive, tmp_path):
    root, _ = archive
    out = tmp_path / "r.csv"
    r = run(["batch", "--pair-by-name", root / "dev0", "-o", out])
    assert_error(r, 2, "--pair-by-name", "at least 2")
    r = run(["batch", "--pair-by-name", root / "dev0", root / "dev1" / "take_01.wav", "-o", out])
    assert_error(r, 3, "take_01.wav", "not a folder")
    r = run(["batch", "--pair-by-name", root / "dev0", tmp_path / "nope", "-o", out])
    assert_error(r, 3, "nope")
    (tmp_path / "e0").mkdir()
    (tmp_path / "e1").mkdir()
    r = run(["batch", "--pair-by-name", tmp_path / "e0", tmp_path / "e1", "-o", out])
    assert_error(r, 3, "no recordings", "e0", "e1")
    assert not out.exists()
