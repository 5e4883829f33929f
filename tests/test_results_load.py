"""Every results file rangekit writes loads as it is, with the documented columns and types.

Issue 19 item 5: each file is read with ``csv.DictReader``, ``pandas.read_csv`` (CSV and
the aligned tables, whitespace-separated) and ``json``, and its columns or keys and their
types are checked against ``docs/formats.md`` (``docs/cli.md`` for ``locate``). The files
are made by the CLI, in process, on short inputs: the shipped 2.5 m fixture, a one-way
recording of 4 windows, a three-epoch tracking log, one trial of jiang2018.
"""

from __future__ import annotations

import csv
import json
import math
import shutil
import sys
from pathlib import Path

import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).parent / "cli"))
from clihelp import run

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = ROOT / "fixtures_audio" / "beepbeep_2p5m.wav"

#: Documented columns -> type ("str", "int", "float", "list"; "?" = may be null / empty).
RANGE = {"a": "int", "b": "int", "distance_m": "float", "sigma_m": "float", "flags": "list"}
ARRIVALS = {
    "file": "str",
    "channel": "int",
    "beep": "int",
    "onset_sample": "float",
    "onset_s": "float",
    "sigma_samples": "float",
    "snr_db": "float",
    "confidence": "float",
    "flags": "list",
}
ONEWAY = {
    "file": "str",
    "window": "int",
    "tx": "int?",
    "channel": "int",
    "distance_m": "float?",
    "sigma_m": "float?",
    "snr_db": "float?",
    "arrival_s": "float?",
    "flags": "list",
}
SERIES = {"t_s": "float", **{k: v + "?" for k, v in RANGE.items()}}
TRACK = {
    "t_s": "float",
    "target": "int",
    **dict.fromkeys(["x_m", "y_m", "vx_mps", "vy_mps", "var_x_m2", "var_y_m2"], "float"),
    "cov_xy_m2": "float",
}
BATCH = {
    "session": "str",
    "session_rows": "int",
    "status": "str",
    "error": "str?",
    "scheme": "str",
    "files": "list",
    **dict.fromkeys(["a", "b", "window", "tx", "channel"], "int?"),
    **dict.fromkeys(["distance_m", "sigma_m", "true_distance_m", "snr_db", "arrival_s"], "float?"),
    "flags": "list?",
}
LOCATE = {
    "x_m": "float",
    "y_m": "float",
    "heading_deg": "float",
    "method_used": "str",
    "residual_m": "float",
    "sigma_x_m": "float",
    "sigma_y_m": "float",
    "sigma_heading_deg": "float",
}
CALIBRATION_KEYS = {
    "format": "str",
    "scheme": "str",
    "model": "str",
    "offset_m": "float",
    "sigma_offset_m": "float",
    "latency_s": "float",
    "sigma_latency_s": "float",
    "speed_m_s": "float",
    "sigma_speed_m_s": "float",
    "cov_speed_offset": "float",
    "n_recordings": "int",
    "distances_m": "list",
    "rms_residual_m": "float",
    "residuals": "list",
}
EXPERIMENT_ROW = {
    "metric": "str",
    "condition": "str",
    "paper": "float?",
    "measured": "float?",
    "unit": "str",
    "note": "str",
    "oracle": "str?",
}


def _ok(args):
    r = run(args)
    assert r.exit_code == 0, (args, r.exit_code, r.stderr)
    return r


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    """Every results file, written once by the CLI into one folder."""
    d = tmp_path_factory.mktemp("results")
    x = d / FIXTURE.name
    shutil.copy(FIXTURE, x)
    shutil.copy(FIXTURE.with_suffix(".json"), d)  # its setup (self-distances) and truth
    sd = ["--self-distance", 0.1]
    for f, extra in (("range", sd), ("detect", [])):
        for fmt in ("table", "csv", "json"):
            _ok([f, x, *extra, "--format", fmt, "-o", d / f"{f}.{fmt}"])
    for fmt in ("csv", "json"):
        _ok(["range", x, *sd, "--series", "--format", fmt, "-o", d / f"series.{fmt}"])
    cal = [d / f"c{i}.wav" for i in range(3)]
    for c in cal:
        shutil.copy(FIXTURE, c)
    _ok(["calibrate", *cal, "--distance", 2.5, "-o", d / "cal.json"])
    ow = d / "ow" / "ow.wav"
    ow.parent.mkdir()
    _ok(["synth", "oneway", "--windows", 4, "--seed", 1, "-o", ow])
    tx = ["--period", 0.2, "--tx-order", "0,1,2,3,4,5"]
    for fmt in ("csv", "json"):
        _ok(["range", "--scheme", "oneway", ow, *tx, "--format", fmt, "-o", d / f"ow.{fmt}"])
    for fmt in ("table", "json"):
        beacons = ow.with_name("ow.beacons.json")
        _ok(["locate", "--beacons", beacons, "--ranges", d / "ow.csv", "--format", fmt, "-o",
             d / f"locate.{fmt}"])  # fmt: skip
    (d / "junk.wav").write_text("not audio")  # an error row: nulls
    _ok(["batch", x, "-o", d / "batch.csv", "-q", "-j", 1])
    r = run(["batch", x, d / "junk.wav", "-o", d / "batch.jsonl", "-q", "-j", 1])
    assert r.exit_code == 8, r.stderr
    r = run(["batch", d / "ow", "--scheme", "oneway", "-o", d / "batch_ow.csv", "-q", "-j", 1])
    assert r.exit_code == 0, r.stderr
    log = d / "walk.csv"
    log.write_text(
        "t_s,kind,a,b,x_m,y_m,heading_rad,var_x_m2,var_y_m2,cov_xy_m2,range_m,sigma_m\n"
        + "".join(
            f"{t},robot,,,{t},0.0,0.0,0.0036,0.0036,0,,\n"
            f"{t},fix,,1,2.0,{0.1 * t},,0.01,0.01,0,,\n"
            f"{t},range,0,1,,,,,,,{math.hypot(2.0, 0.1 * t):.4f},0.05\n"
            for t in (0.0, 0.5, 1.0)
        )
    )
    for fmt in ("csv", "json"):
        _ok(["track", "range-ekf", log, "--format", fmt, "-o", d / f"track.{fmt}"])
    _ok(["experiment", "jiang2018", "--trials", 1, "--format", "json", "-o", d / "exp.json"])
    return d


def _is(kind: str, v) -> bool:
    """Whether the JSON value ``v`` is of the documented ``kind``."""
    if kind.endswith("?"):
        return v is None or _is(kind[:-1], v)
    if kind == "float":
        return isinstance(v, (int, float)) and not isinstance(v, bool)
    if kind == "int":
        return isinstance(v, int) and not isinstance(v, bool)
    return isinstance(v, {"str": str, "list": list}[kind])


def _cell_is(kind: str, cell: str) -> bool:
    """Whether the CSV cell ``cell`` holds a value of ``kind`` (empty: a null)."""
    if cell == "":
        return kind.endswith("?") or kind.startswith("list")
    kind = kind.rstrip("?")
    try:
        {"int": int, "float": float, "str": str, "list": str}[kind](cell)
    except ValueError:
        return False
    return not (kind == "list" and "," in cell)  # one separator: ';'


def _check_frame(frame, schema: dict) -> None:
    """pandas typed every numeric column numerically (an all-empty one as float NaN)."""
    assert list(frame.columns) == list(schema)
    for col, kind in schema.items():
        base = kind.rstrip("?")
        if base in ("int", "float"):
            assert pd.api.types.is_numeric_dtype(frame[col]), (col, frame[col].dtype)
        if base == "int" and not kind.endswith("?"):
            assert pd.api.types.is_integer_dtype(frame[col]), (col, frame[col].dtype)


def _check_csv(path: Path, schema: dict, *, rows_min: int = 1) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        rows = list(reader)
    assert reader.fieldnames == list(schema), reader.fieldnames
    assert len(rows) >= rows_min
    for row in rows:
        for col, kind in schema.items():
            assert _cell_is(kind, row[col]), (path.name, col, row[col])
    _check_frame(pd.read_csv(path), schema)
    return rows


def _check_rows(rows: list, schema: dict) -> None:
    assert rows
    for row in rows:
        assert set(row) == set(schema), set(row) ^ set(schema)
        for col, kind in schema.items():
            assert _is(kind, row[col]), (col, row[col])


def test_range_and_detect_csv_json_table(out):
    (r,) = _check_csv(out / "range.csv", RANGE)
    assert abs(float(r["distance_m"]) - 2.5) < 0.02
    _check_csv(out / "detect.csv", ARRIVALS, rows_min=2)
    obj = json.loads((out / "range.json").read_text())
    assert _is("str", obj["scheme"]) and _is("list", obj["files"])
    assert _is("float", obj["speed_of_sound_m_s"])
    _check_rows(obj["ranges"], RANGE)
    obj = json.loads((out / "detect.json").read_text())
    assert obj["detector"] == "changepoint"
    _check_rows(obj["arrivals"], ARRIVALS)
    # The tables are for people, but load whitespace-separated with the same columns.
    for name, schema in (("range", RANGE), ("detect", ARRIVALS)):
        frame = pd.read_csv(out / f"{name}.table", sep=r"\s+")
        _check_frame(frame, schema)


def test_series_csv_json(out):
    _check_csv(out / "series.csv", SERIES)
    obj = json.loads((out / "series.json").read_text())
    assert obj["series"] is True and obj["scheme"] == "beepbeep"
    _check_rows(obj["ranges"], SERIES)


def test_oneway_range_and_locate(out):
    rows = _check_csv(out / "ow.csv", ONEWAY, rows_min=12)
    assert {r["tx"] for r in rows} <= {str(i) for i in range(6)}
    _check_rows(json.loads((out / "ow.json").read_text())["ranges"], ONEWAY)
    obj = json.loads((out / "locate.json").read_text())
    for k, kind in {**LOCATE, "heading_rad": "float", "method": "str", "tx": "list"}.items():
        assert _is(kind, obj[k]), (k, obj[k])
    assert len(obj["covariance"]) == 3
    frame = pd.read_csv(out / "locate.table", sep=r"\s+")
    _check_frame(frame, LOCATE)
    assert len(frame) == 1


def test_batch_csv_jsonl_and_meta(out):
    """The batch files of item 5: a plain header row, JSON values, lists, null, meta."""
    (row,) = _check_csv(out / "batch.csv", BATCH)
    assert row["files"] == str(out / FIXTURE.name) and row["error"] == ""
    assert abs(float(row["distance_m"]) - float(row["true_distance_m"])) < 0.02
    rows = [json.loads(ln) for ln in (out / "batch.jsonl").read_text().splitlines()]
    _check_rows(rows, BATCH)
    ok, bad = sorted(rows, key=lambda r: r["status"] != "ok")
    assert ok["error"] is None and isinstance(ok["flags"], list)
    assert bad["status"] == "error" and bad["distance_m"] is None and bad["flags"] is None
    frame = pd.read_json(out / "batch.jsonl", lines=True)
    assert list(frame.columns) == list(BATCH)
    ow = _check_csv(out / "batch_ow.csv", BATCH, rows_min=12)
    assert {r["scheme"] for r in ow} == {"oneway"} and all(r["tx"] != "" for r in ow)
    assert all(r["true_distance_m"] != "" for r in ow)  # from the one-way sidecar
    for name in ("batch", "batch_ow"):
        meta = json.loads((out / f"{name}.csv.meta.json").read_text())
        assert meta["results"] == f"{name}.csv" and meta["list_separator"] == ";"
        assert list(meta["columns"]) == list(BATCH)
        assert {k: v.rstrip("?") for k, v in BATCH.items()} == meta["columns"]
        text = json.dumps(meta["options"])
        assert "Beep(" not in text and "'changepoint'" not in text  # JSON, not reprs
        assert meta["options"]["beepbeep"]["detector"] == "changepoint"
    assert meta["options"]["oneway"]["burst"]["type"] == "CodedBurst"
    assert meta["options"]["oneway"]["burst"]["code"] == [1, 1, 1, -1, -1, 1, -1]
    meta = json.loads((out / "batch.csv.meta.json").read_text())
    assert meta["options"]["beepbeep"]["beep"]["type"] == "Beep"


def test_track_calibration_experiment(out):
    _check_csv(out / "track.csv", TRACK, rows_min=3)
    obj = json.loads((out / "track.json").read_text())
    assert obj["columns"] == list(TRACK)
    _check_rows([dict(zip(obj["columns"], r, strict=True)) for r in obj["rows"]], TRACK)
    cal = json.loads((out / "cal.json").read_text())
    for k, kind in CALIBRATION_KEYS.items():
        assert _is(kind, cal[k]), (k, cal[k])
    assert cal["format"] == "rangekit-calibration/1" and cal["n_recordings"] == 3
    exp = json.loads((out / "exp.json").read_text())
    assert exp["experiment"] == "jiang2018" and isinstance(exp["params"], dict)
    _check_rows(exp["rows"], EXPERIMENT_ROW)
