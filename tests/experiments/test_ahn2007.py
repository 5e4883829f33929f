"""The Ahn & Yu §4 experiment: expected rows, numbers in range, figures."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from rangekit.experiments.ahn2007 import run

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perturb import worse  # tests/perturb.py: errors x $RANGEKIT_TEST_WORSE


def _improvement(x: float) -> float:
    """An improvement (raw fixes' error / the filter's) with the filter's error x worse()."""
    return x / worse(1.0)


@pytest.fixture(scope="module")
def report():
    return run(trials=2, seed=3)


def test_report_has_the_expected_rows(report):
    keys = {(r.metric, r.condition) for r in report.rows}
    robot = "robot, Δt=0.1 s, 60 s, noise var 0.001"
    for metric in (
        "bias RMS error, 6-state EKF, last 30 s",
        "final position error, 6-state EKF (bias states)",
        "final position error, 4-state EKF (no bias states)",
        "final position error, accelerometer integration",
        "ANEES, 6-state EKF (d=6)",
    ):
        assert (metric, robot) in keys
    for var in (1.0, 4.0, 9.0):
        for metric in ("mean error, raw fixes", "improvement of mean error, online (oracle start)",
                       "improvement of peak error, online (oracle start)"):  # fmt: skip
            assert (metric, f"pedestrian, σ²={var} m²") in keys
    row = report.find("improvement of peak error, online (oracle start)", "pedestrian, σ²=4.0 m²")
    assert row.paper == 2.5 and "2~3" in row.note
    assert report.find("mean error, raw fixes", "pedestrian, σ²=4.0 m²").paper is None
    json.dumps(report.to_json())


def test_numbers_are_in_the_expected_ranges(report):
    robot = "robot, Δt=0.1 s, 60 s, noise var 0.001"
    bias = worse(report.find("bias RMS error, 6-state EKF, last 30 s", robot).measured)
    true_bias = report.find("true bias RMS, last 30 s", robot).measured
    assert bias < 0.05 < true_bias
    e6 = worse(report.find("final position error, 6-state EKF (bias states)", robot).measured)
    e4 = worse(report.find("final position error, 4-state EKF (no bias states)", robot).measured)
    ei = worse(report.find("final position error, accelerometer integration", robot).measured)
    assert e6 < 3.0 and e6 < e4 < ei
    ped = "pedestrian, σ²=4.0 m²"
    raw = report.find("mean error, raw fixes", ped).measured
    assert 2.3 < raw < 2.8  # Rayleigh mean 2 sqrt(pi / 2) = 2.51 m
    mean_gain = report.find("improvement of mean error, online (oracle start)", ped).measured
    peak_gain = report.find("improvement of peak error, online (oracle start)", ped).measured
    assert 0.8 < _improvement(mean_gain) < 1.4
    assert 2.0 < _improvement(peak_gain) < 4.0


def test_plots_dir_writes_nontrivial_pngs(tmp_path):
    run(trials=1, seed=1, plots_dir=tmp_path)
    files = sorted(p.name for p in tmp_path.glob("*.png"))
    assert files == [f"ahn2007_fig{i}.png" for i in range(1, 5)]
    for p in tmp_path.glob("*.png"):
        data = p.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000


# Oracle rows and their non-oracle peers (issue 21 item 5): the paper's online filter
# starts at the true start, its offline filter anchors at the fix nearest the truth.
_PEERS = {
    "online (oracle start)": "online from the first fix",
    "offline (oracle anchor)": "offline, i* from the fixes",
}


def test_every_oracle_row_is_named_marked_and_has_a_non_oracle_peer(report):
    doc = report.to_json()
    oracle = [r for r in doc["rows"] if r["oracle"]]
    assert oracle and all("(oracle " in r["metric"] for r in oracle)
    assert all(r["oracle"] is None for r in doc["rows"] if "(oracle" not in r["metric"])
    keys = {(r["metric"], r["condition"]) for r in doc["rows"] if not r["oracle"]}
    literal = "pedestrian, σ²=4.0 m², literal r ∈ [-1, 1]"  # the text's reading, context only
    for r in oracle:
        if r["condition"] == literal:
            continue
        ((o, peer),) = [(o, p) for o, p in _PEERS.items() if o in r["metric"]]
        assert (r["metric"].replace(o, peer), r["condition"]) in keys, r["metric"]
    # the paper's number sits on the rows run as the paper ran them (known start)
    assert {r["metric"] for r in doc["rows"] if r["paper"] is not None} <= {
        r["metric"] for r in oracle
    }


def test_non_oracle_rows_cost_a_little_accuracy(report):
    """Without the truth the l_max filters lose a little (seed 3, 20 walks, σ² = 4 m²)."""
    ped = "pedestrian, σ²=4.0 m²"
    on_o = worse(report.find("mean error, l_max online (oracle start)", ped).measured)  # 1.410
    on = worse(report.find("mean error, l_max online from the first fix", ped).measured)  # 1.484
    off = worse(report.find("mean error, l_max offline, i* from the fixes", ped).measured)  # 1.469
    raw = report.find("mean error, raw fixes", ped).measured  # 2.456
    assert on_o < on < 1.1 * on_o  # measured +5 %
    assert on_o < off < 1.1 * on_o  # measured +4 %
    assert 1.23 < on < 2.0 < raw


def test_model_mismatch_rows(report):
    """Heavy-tailed 4x accelerometer noise, odometer 2 % fast, EKF at the paper's values."""
    paper = "robot, Δt=0.1 s, 60 s, noise var 0.001"
    mis = "robot, model mismatch: accel noise Student-t ν=3 var 0.004, odometer +2 %"
    e6 = "final position error, 6-state EKF (bias states)"
    anees = "ANEES, 6-state EKF (d=6)"
    assert 1.0 < worse(report.find(e6, mis).measured) < 4.1  # measured 2.05 m (paper 0.52)
    assert report.find(e6, mis).measured > 2.0 * report.find(e6, paper).measured
    assert 69 < report.find(anees, mis).measured < 277  # 138.5: the filter is overconfident
    ped = "pedestrian, model mismatch: Student-t ν=3 fixes, σ²=4 m², l_max=1 m"
    raw = report.find("mean error, raw fixes", ped).measured  # 2.07 (Student-t: smaller mean)
    on = worse(report.find("mean error, l_max online from the first fix", ped).measured)  # 1.198
    assert 0.6 < on < 2.4 and on < 0.7 * raw
    rows = [r for r in report.rows if "model mismatch" in r.condition]
    assert all(r.paper is None and not r.oracle for r in rows if "(oracle" not in r.metric)
