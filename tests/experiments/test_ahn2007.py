"""The Ahn & Yu §4 experiment: expected rows, numbers in range, figures."""

from __future__ import annotations

import json

import pytest

from rangekit.experiments.ahn2007 import run


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
        for metric in ("mean error, raw fixes", "improvement of mean error, online",
                       "improvement of peak error, online"):  # fmt: skip
            assert (metric, f"pedestrian, σ²={var} m²") in keys
    row = report.find("improvement of peak error, online", "pedestrian, σ²=4.0 m²")
    assert row.paper == 2.5 and "2~3" in row.note
    assert report.find("mean error, raw fixes", "pedestrian, σ²=4.0 m²").paper is None
    json.dumps(report.to_json())


def test_numbers_are_in_the_expected_ranges(report):
    robot = "robot, Δt=0.1 s, 60 s, noise var 0.001"
    bias = report.find("bias RMS error, 6-state EKF, last 30 s", robot).measured
    true_bias = report.find("true bias RMS, last 30 s", robot).measured
    assert bias < 0.05 < true_bias
    e6 = report.find("final position error, 6-state EKF (bias states)", robot).measured
    e4 = report.find("final position error, 4-state EKF (no bias states)", robot).measured
    ei = report.find("final position error, accelerometer integration", robot).measured
    assert e6 < 3.0 and e6 < e4 < ei
    ped = "pedestrian, σ²=4.0 m²"
    raw = report.find("mean error, raw fixes", ped).measured
    assert 2.3 < raw < 2.8  # Rayleigh mean 2 sqrt(pi / 2) = 2.51 m
    assert 0.8 < report.find("improvement of mean error, online", ped).measured < 1.4
    assert 2.0 < report.find("improvement of peak error, online", ped).measured < 4.0


def test_plots_dir_writes_nontrivial_pngs(tmp_path):
    run(trials=1, seed=1, plots_dir=tmp_path)
    files = sorted(p.name for p in tmp_path.glob("*.png"))
    assert files == [f"ahn2007_fig{i}.png" for i in range(1, 5)]
    for p in tmp_path.glob("*.png"):
        data = p.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
