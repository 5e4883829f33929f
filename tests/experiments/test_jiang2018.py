"""rangekit experiment jiang2018: the rows of Table 1, smoothing vs filtering, figures."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.experiments.jiang2018 import CONDITIONS, PAPER_TABLE1, run

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perturb import worse  # tests/perturb.py: errors x $RANGEKIT_TEST_WORSE


@pytest.fixture(scope="module")
def report():
    return run(trials=4, seed=1)


def test_every_table1_cell_is_reported_with_the_papers_number(report):
    for (target, label), (med, p90) in PAPER_TABLE1.items():
        row = report.find("median error", f"target {target}, {label}, filter")
        assert row.paper == med and row.unit == "m" and np.isfinite(row.measured)
        assert report.find("p90 error", f"target {target}, {label}, filter").paper == p90
        assert report.find("median error", f"target {target}, {label}, smoother").paper is None
    js = report.to_json()
    assert js["experiment"] == "jiang2018" and js["params"]["trials"] == 4
    assert all({"metric", "condition", "paper", "measured"} <= set(r) for r in js["rows"])


def test_target_1_follows_the_fix_and_smoothing_beats_filtering(report):
    for cond in CONDITIONS:
        t1 = worse(report.find("median error", f"target 1, {cond.label}, filter").measured)
        assert t1 < 0.3  # followed target: fix sigma 0.1 m + robot 0.06-0.10 m
    f = [report.find("median error", f"target 2, {c.label}, filter").measured for c in CONDITIONS]
    s = [report.find("median error", f"target 2, {c.label}, smoother").measured for c in CONDITIONS]
    assert np.mean(s) < 0.7 * np.mean(f), (f, s)


def test_seeded_runs_repeat():
    a = run(trials=1, seed=7).to_json()["rows"]
    b = run(trials=1, seed=7).to_json()["rows"]
    assert a == b


def test_plots_are_written(tmp_path):
    run(trials=1, seed=2, plots_dir=tmp_path / "figs")
    files = sorted(p.name for p in (tmp_path / "figs").iterdir())
    assert files == [
        "jiang2018_atrium.png",
        "jiang2018_cdf.png",
        "jiang2018_errors.png",
        "jiang2018_trajectories.png",
    ]
    assert all((tmp_path / "figs" / f).stat().st_size > 10_000 for f in files)


def test_bad_trials():
    with pytest.raises(InvalidParameterError, match="trials"):
        run(trials=0)
