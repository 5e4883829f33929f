"""rangekit experiment girard2011: Table 1 reproduced (2 seeded walks, ν = 150 and 1,000)."""

from __future__ import annotations

import inspect
import json

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.experiments import girard2011
from rangekit.experiments.girard2011 import MODE_LABELS, PAPER_TABLE_1, STATS, run, run_table

NUS = (150, 1000)


@pytest.fixture(scope="module")
def plots(tmp_path_factory):
    return tmp_path_factory.mktemp("g11") / "figures"


@pytest.fixture(scope="module")
def report(plots):
    return run_table(trials=2, seed=0, nus=NUS, plots_dir=plots)


def _mu(report, mode, method="Girard", nu=150):
    return report.find("tracking error μ", f"{MODE_LABELS[mode]}, {method} ν={nu}").measured


def test_every_table1_cell_has_the_papers_number(report):
    for method in ("Girard", "SIR"):
        for mode, paper in PAPER_TABLE_1.items():
            for (stat, _), p in zip(STATS, paper, strict=True):
                row = report.find(f"tracking error {stat}", f"{MODE_LABELS[mode]}, {method} ν=150")
                assert row.paper == p and row.unit == "m"
                assert 0.0 <= row.measured < 3.0
    for method in ("Girard", "SIR"):  # the sweep: the paper's ranging row beside
        row = report.find("tracking error Max", f"with ranging, {method} ν=1000")
        assert row.paper == 0.40


@pytest.mark.parametrize("method", ["Girard", "SIR"])
def test_acceptance_ranging_mu_and_ordering(report, method):
    """With ranging μ <= 0.13 m (paper 0.13); IMU only > with model > with ranging."""
    imu, model, ranging = (_mu(report, m, method) for m in ("imu", "model", "ranging"))
    assert ranging <= 0.13
    assert imu > model > ranging
    assert _mu(report, "ranging", method, 1000) <= 0.13
    cond = f"{method} ν=150"
    assert report.find("μ ratio, with model / IMU only", cond).measured < 1.0
    assert report.find("μ ratio, with ranging / with model", cond).measured < 0.6


def test_statistics_are_consistent(report):
    """Min <= μ <= Max and Ending within [Min, Max] for every configuration."""
    conds = {r.condition for r in report.rows if r.metric == "tracking error μ"}
    for c in conds - {"dead reckoning (step log alone, Fig. 10)"}:
        v = {s: report.find(f"tracking error {s}", c).measured for s, _ in STATS}
        assert v["Min"] <= v["μ"] <= v["Max"], c
        assert v["σ"] <= v["Max"] - v["Min"] + 1e-12, c


def test_extras(report):
    # Girard's cloud is capped by ν; SIR keeps exactly ν
    assert report.find("largest cloud (particles after a step)", "with ranging, Girard ν=150"
                       ).measured == 150  # fmt: skip
    assert report.find("largest cloud (particles after a step)", "with ranging, SIR ν=1000"
                       ).measured == 1000  # fmt: skip
    r = report.find("RMS error / RMS cloud spread", "with ranging, Girard ν=150").measured
    assert 0.1 < r < 10.0
    dr = report.find("tracking error μ", "dead reckoning (step log alone, Fig. 10)")
    assert dr.paper == 0.59 and dr.measured > _mu(report, "ranging")
    assert report.find("re-initialisations (every particle eliminated), total",
                       "all filters and walks").measured >= 0  # fmt: skip


def test_json_rows_form(report):
    doc = json.loads(report.to_json_text())
    assert doc["experiment"] == "girard2011"
    assert doc["params"]["trials"] == 2 and doc["params"]["nus"] == list(NUS)
    # 2 filters x 3 modes x 5 stats, 2 ratios x 2, 6 spread ratios, 2 x 5 sweep stats,
    # 4 cloud sizes, 2 dead-reckoning rows, 1 re-initialisation row
    assert len(doc["rows"]) == 30 + 4 + 6 + 10 + 4 + 2 + 1
    for row in doc["rows"]:
        assert {"metric", "condition", "paper", "measured", "unit", "note"} <= set(row)
        assert row["paper"] is None or isinstance(row["paper"], float)
        assert isinstance(row["measured"], float)


def test_plots_written(report, plots):
    names = {"girard2011_fig11.png", "girard2011_fig12.png", "girard2011_fig13.png",
             "girard2011_paths.png", "girard2011_errors.png"}  # fmt: skip
    assert {p.name for p in plots.iterdir()} == names
    for p in plots.iterdir():
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert p.stat().st_size > 20_000  # drawn content, not an empty canvas


def test_seeded_and_independent_of_the_sweep():
    a = run_table(trials=1, seed=3, nus=(150,))
    b = run_table(trials=1, seed=3, nus=(150,))
    assert a.to_json() == b.to_json()
    c = run_table(trials=1, seed=4, nus=(150,))
    assert _mu(a, "ranging") != _mu(c, "ranging")


def test_sweep_reuses_the_same_streams(report):
    """A configuration's numbers do not depend on the other configurations run."""
    small = run_table(trials=2, seed=0, nus=(150,))
    for mode in PAPER_TABLE_1:
        assert _mu(small, mode) == _mu(report, mode)


def test_large_nu_sir_runs_on_fewer_walks(monkeypatch):
    monkeypatch.setattr(girard2011, "LARGE_NU", 200)
    rep = run_table(trials=3, seed=1, nus=(150, 200))
    row = rep.find("tracking error μ", "with ranging, SIR ν=200")
    assert f"first {girard2011.LARGE_NU_TRIALS} of 3 walks" in row.note
    assert "first" not in rep.find("tracking error μ", "with ranging, Girard ν=200").note
    assert rep.params["sir_trials_at_large_nu"] == girard2011.LARGE_NU_TRIALS


def test_run_has_the_standard_signature():
    sig = inspect.signature(run)
    assert list(sig.parameters) == ["trials", "seed", "plots_dir"]
    assert all(p.kind is p.KEYWORD_ONLY for p in sig.parameters.values())
    assert sig.parameters["trials"].default == girard2011.DEFAULT_TRIALS
    assert girard2011.NUS == (150, 1_000, 10_000, 100_000)


@pytest.mark.parametrize(
    ("kw", "name"),
    [
        ({"trials": 0}, "trials"),
        ({"seed": -1}, "seed"),
        ({"nus": (150, 0)}, "nus"),
        ({"nus": (150, 2.5)}, "nus"),
        ({"nus": 5}, "nus"),
    ],
)
def test_bad_parameters(kw, name):
    with pytest.raises(InvalidParameterError, match=name):
        run_table(**{"trials": 1, **kw})


def test_paper_table_is_table_1():
    assert PAPER_TABLE_1["ranging"] == (0.13, 0.07, 0.40, 0.03, 0.18)
    arr = np.array([PAPER_TABLE_1[m] for m in ("imu", "model", "ranging")])
    assert np.all(np.diff(arr[:, 0]) < 0)  # the paper's own ordering
