"""Batch takes a synth sidecar's setup, never its truth (issue 19 item 3)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from rangekit.batch import BatchOptions, find_sessions, run_session

sys.path.insert(0, str(Path(__file__).resolve().parent / "cli"))
from clihelp import ok, run


@pytest.fixture
def session(tmp_path):
    wav = tmp_path / "x.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--seed", 1, "-o", wav]))
    return wav


def _distance(folder):
    (s,) = find_sessions([folder])
    rows = run_session(s, BatchOptions())
    return rows[0]


def test_the_setup_not_the_truth_gives_the_self_distance(session):
    row = _distance(session.parent)
    assert abs(row["distance_m"] - 2.0) < 2 * row["sigma_m"]  # setup: 0.1 m each
    side = session.with_suffix(".json")
    obj = json.loads(side.read_text())
    obj["setup"]["self_distance_m"] = [0.05, 0.05]  # the user's belief, not the truth's 0.1
    side.write_text(json.dumps(obj))
    assert _distance(session.parent)["distance_m"] == pytest.approx(row["distance_m"] - 0.05)
    assert _distance(session.parent)["true_distance_m"] == pytest.approx(2.0, abs=1e-3)


def test_a_probe_session_is_an_error_row(session):
    side = session.with_suffix(".json")
    obj = json.loads(side.read_text())
    obj["setup"]["signal"] = {"probe": "sweep.wav"}
    side.write_text(json.dumps(obj))
    row = _distance(session.parent)
    assert row["status"] == "error" and "probe 'sweep.wav'" in row["error"]


def test_a_malformed_setup_is_an_error_row(session):
    side = session.with_suffix(".json")
    obj = json.loads(side.read_text())
    obj["setup"]["temp_c"] = True
    side.write_text(json.dumps(obj))
    row = _distance(session.parent)
    assert row["status"] == "error" and "temp_c" in row["error"]
