"""rangekit experiment girard2011: Table 1 reproduced on walks held out from the tuning.

rangekit's own choices for Girard's filter (γ = ``eq1_power`` = 30, ``use_readings``,
``weighting``; docs/theory/girard2011.md) were made on the walks of
:data:`~rangekit.experiments.girard2011.TUNING_SEEDS` (seed 0, 10 walks). The acceptance
runs on seed :data:`TEST_SEED` = 1 (10 walks, ν = 150) and its first 2 walks (the ν =
1,000 sweep, JSON and figures); ``test_test_walks_are_held_out`` fails if they overlap.
Bounds sit within about 2x of what seed 1 measures today (written beside them).
"""

from __future__ import annotations

import inspect
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.experiments import girard2011
from rangekit.experiments.girard2011 import (
    MODE_LABELS,
    ORACLE_START,
    PAPER_TABLE_1,
    STATS,
    TUNING_SEEDS,
    TUNING_TRIALS,
    run,
    run_table,
    walks,
)
from rangekit.localize.particle import ParticleConfig

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perturb import worse  # tests/perturb.py: errors x $RANGEKIT_TEST_WORSE

TEST_SEED = 1
TEST_TRIALS = 10
SWEEP_TRIALS = 2
NUS = (150, 1000)

#: Seed 1, 10 walks, ν = 150 (measured 2026-12-01): (method, mode) -> μ, σ, Max, Ending (m).
MEASURED = {
    ("Girard", "imu"): (0.411, 0.266, 1.163, 1.060),
    ("Girard", "model"): (0.340, 0.195, 0.812, 0.677),
    ("Girard", "ranging"): (0.120, 0.073, 0.337, 0.321),
    ("SIR", "imu"): (0.387, 0.244, 1.046, 0.939),
    ("SIR", "model"): (0.262, 0.148, 0.646, 0.591),
    ("SIR", "ranging"): (0.135, 0.102, 0.445, 0.370),
}


@pytest.fixture(scope="module")
def plots(tmp_path_factory):
    return tmp_path_factory.mktemp("g11") / "figures"


@pytest.fixture(scope="module")
def report():
    """Table 1 at ν = 150 on the 10 held-out walks of seed 1 (mismatch rows: ``sweep``)."""
    return run_table(trials=TEST_TRIALS, seed=TEST_SEED, nus=(150,), mismatch=False)


@pytest.fixture(scope="module")
def sweep(plots):
    """The first 2 held-out walks with the ν = 1,000 sweep and the figures."""
    return run_table(trials=SWEEP_TRIALS, seed=TEST_SEED, nus=NUS, plots_dir=plots)


def _mu(report, mode, method="Girard", nu=150):
    return report.find("tracking error μ (oracle start)", f"{MODE_LABELS[mode]}, {method} ν={nu}"
                       ).measured  # fmt: skip


def test_test_walks_are_held_out():
    """The tuning walks and every walk an acceptance test here runs on are disjoint."""
    tuning = frozenset().union(*(walks(s, TUNING_TRIALS) for s in TUNING_SEEDS))
    assert len(tuning) == len(TUNING_SEEDS) * TUNING_TRIALS == 10
    for trials in (TEST_TRIALS, SWEEP_TRIALS):
        assert not walks(TEST_SEED, trials) & tuning


@pytest.mark.parametrize("method", ["Girard", "SIR"])
def test_every_table1_cell_within_2x_of_today(report, method):
    for mode, paper in PAPER_TABLE_1.items():
        measured = dict(zip(("μ", "σ", "Max", "Ending"), MEASURED[(method, mode)], strict=True))
        for (stat, _), p in zip(STATS, paper, strict=True):
            row = report.find(f"tracking error {stat} (oracle start)",
                              f"{MODE_LABELS[mode]}, {method} ν=150")  # fmt: skip
            assert row.paper == p and row.unit == "m" and row.oracle == ORACLE_START
            if stat == "Min":  # the best of 52 steps, 1-4 cm: not an accuracy claim
                assert 0.0 < row.measured <= row.paper * 10
            else:
                assert worse(row.measured) <= 2.0 * measured[stat], (mode, stat)


def test_acceptance_girard_ranging_mu_and_ordering(report):
    """Girard with ranging μ <= 0.13 m (paper 0.13); IMU only > with model > with ranging."""
    imu, model, ranging = (worse(_mu(report, m)) for m in ("imu", "model", "ranging"))
    assert ranging <= 0.13  # measured 0.120 (tuning seed 0: 0.111)
    assert imu > model > ranging
    cond = "Girard ν=150"
    # measured 0.828 and 0.354
    assert report.find("μ ratio, with model / IMU only (oracle start)", cond).measured < 1.0
    assert report.find("μ ratio, with ranging / with model (oracle start)", cond).measured < 0.6


def test_sir_ranging_mu_and_ordering(report):
    imu, model, ranging = (worse(_mu(report, m, "SIR")) for m in ("imu", "model", "ranging"))
    assert ranging <= 0.16  # measured 0.135 (tuning seed 0: 0.111)
    assert imu > model > ranging
    cond = "SIR ν=150"
    # measured 0.676 and 0.516
    assert report.find("μ ratio, with model / IMU only (oracle start)", cond).measured < 1.0
    assert report.find("μ ratio, with ranging / with model (oracle start)", cond).measured < 0.7


@pytest.mark.xfail(
    strict=True,
    reason="SIR with ranging: μ 0.135 m on the held-out walks of seed 1 (0.111 on the "
    "tuning seed 0) against the paper's 0.13 m; see docs/theory/girard2011.md",
)
def test_acceptance_sir_ranging_mu_within_the_papers(report):
    assert _mu(report, "ranging", "SIR") <= 0.13


@pytest.mark.parametrize(("method", "measured"), [("Girard", 0.133), ("SIR", 0.129)])
def test_start_given_within_half_a_metre(report, method, measured):
    """The non-oracle rows: the user gives the start only within 0.5 m."""
    row = report.find("tracking error μ", f"with ranging, {method} ν=150, start within 0.5 m")
    assert row.oracle == "" and row.paper == 0.13
    assert worse(row.measured) <= 1.5 * measured  # measured: the parameter
    # not much better than from the true start (measured: +0.013 Girard, -0.006 SIR)
    assert worse(row.measured) >= worse(_mu(report, "ranging", method)) - 0.02


@pytest.mark.parametrize(("method", "measured"), [("Girard", 0.265), ("SIR", 0.306)])
def test_model_mismatch_rows(sweep, method, measured):
    """Compass 4° + 0.4°/step while the log says 2°, SRF02 noise and slips doubled, filter
    defaults, start within 0.5 m (seed 1, 2 walks: μ measured beside the parameter)."""
    mis = f"with ranging, {method} ν=150, start within 0.5 m, {girard2011._MISMATCH_LABEL}"
    row = sweep.find("tracking error μ", mis)
    assert row.oracle == "" and row.paper is None
    assert measured / 2 < worse(row.measured) < 2 * measured
    ok = sweep.find("tracking error μ", f"with ranging, {method} ν=150, start within 0.5 m")
    assert row.measured > 1.5 * ok.measured  # measured 2.3x (Girard), 2.8x (SIR)
    reinit = f"with ranging, ν=150, {girard2011._MISMATCH_LABEL}"
    assert sweep.find("re-initialisations (every particle eliminated), total", reinit).measured == 0


def test_mismatch_walks_state_the_compass_the_user_believes():
    sim = girard2011.simulate(**girard2011.MISMATCH, rng=0)
    assert np.allclose(sim.steps.heading_sigma_rad, np.radians(2.0))
    assert sim.params["heading_noise_rad"] == pytest.approx(np.radians(4.0))
    plain = girard2011.simulate(rng=0)
    assert np.allclose(plain.steps.heading_sigma_rad, np.radians(2.0))  # the drawn noise
    assert plain.params["logged_heading_sigma_rad"] is None


def test_sweep_nu_1000(sweep):
    for method in ("Girard", "SIR"):
        assert worse(_mu(sweep, "ranging", method, 1000)) <= 0.13  # measured 0.107, 0.086
        row = sweep.find("tracking error Max (oracle start)", f"with ranging, {method} ν=1000")
        assert row.paper == 0.40 and worse(row.measured) <= 0.66  # measured 0.328, 0.355


def test_statistics_are_consistent(report):
    """Min <= μ <= Max and Ending within [Min, Max] for every configuration."""
    conds = {r.condition for r in report.rows if r.metric.startswith("tracking error μ")}
    for c in conds - {"dead reckoning (step log alone, Fig. 10)"}:
        name = "" if "start within" in c else " (oracle start)"
        v = {s: report.find(f"tracking error {s}{name}", c).measured for s, _ in STATS}
        assert v["Min"] <= v["μ"] <= v["Max"], c
        assert v["Min"] <= v["Ending"] <= v["Max"], c
        assert v["σ"] <= v["Max"] - v["Min"] + 1e-12, c


@pytest.mark.parametrize(
    ("cond", "lo", "hi"),
    [
        ("with ranging, Girard ν=150", 0.38, 1.5),  # measured 0.753: the cloud is too wide
        ("with ranging, SIR ν=150", 0.62, 2.5),  # measured 1.244
        ("IMU only, Girard ν=150", 0.84, 3.4),  # measured 1.678: the cloud is too narrow
    ],
)
def test_cloud_spread_against_the_error_two_sided(report, cond, lo, hi):
    r = worse(report.find("RMS error / RMS cloud spread (oracle start)", cond).measured)
    assert lo <= r <= hi


def test_extras(report, sweep):
    # Girard's cloud is capped by ν; SIR keeps exactly ν
    assert report.find("largest cloud (particles after a step) (oracle start)",
                       "with ranging, Girard ν=150").measured == 150  # fmt: skip
    assert sweep.find("largest cloud (particles after a step) (oracle start)",
                      "with ranging, SIR ν=1000").measured == 1000  # fmt: skip
    dr = report.find("tracking error μ (oracle start)", "dead reckoning (step log alone, Fig. 10)")
    assert dr.paper == 0.59 and dr.measured > _mu(report, "ranging")
    # Every particle eliminated never happens on these walks (docs/theory/girard2011.md).
    row = report.find("re-initialisations (every particle eliminated), total",
                      "all filters and walks")  # fmt: skip
    assert row.measured == 0 and row.note.startswith("none")


def test_papers_numbers_sit_where_the_paper_puts_them(report):
    """Girard et al. 2011 Table 1 and §3.3, read off the paper, against the report's rows
    and the filter's defaults (not against the module's own constants)."""
    cells = {
        ("μ", "with ranging, Girard ν=150"): 0.13,
        ("Max", "with ranging, SIR ν=150"): 0.40,
        ("Ending", "IMU only, Girard ν=150"): 1.47,
        ("σ", "with model, SIR ν=150"): 0.30,
        ("Min", "IMU only, SIR ν=150"): 0.01,
    }
    for (stat, cond), paper in cells.items():
        assert report.find(f"tracking error {stat} (oracle start)", cond).paper == paper
    ratio = report.find("μ ratio, with model / IMU only (oracle start)", "Girard ν=150")
    assert ratio.paper == pytest.approx(0.47 / 0.59)
    cfg = ParticleConfig()  # §3.3: ν = 150, ε = 25 cm, κ = 20, τ = 5 cm, λ = 7
    assert (cfg.n_particles, cfg.eps_m, cfg.kappa, cfg.tau_m, cfg.n_rays) == (150, 0.25, 20,
                                                                              0.05, 7)  # fmt: skip


def test_json_rows_form(sweep):
    doc = json.loads(sweep.to_json_text())
    assert doc["experiment"] == "girard2011"
    assert doc["params"]["trials"] == SWEEP_TRIALS and doc["params"]["nus"] == list(NUS)
    # 2 filters x 3 modes x 5 stats, 2 ratios x 2, 6 spread ratios, 2 x 5 sweep stats,
    # 4 cloud sizes, 2 dead-reckoning rows, 1 re-initialisation row, 2 x 5 given-start stats,
    # 2 x 5 model-mismatch stats and their re-initialisation row
    assert len(doc["rows"]) == 30 + 4 + 6 + 10 + 4 + 2 + 1 + 10 + 11
    for row in doc["rows"]:
        assert {"metric", "condition", "paper", "measured", "unit", "note", "oracle"} <= set(row)
        assert row["paper"] is None or isinstance(row["paper"], float)
        assert isinstance(row["measured"], float)
        # oracle rows say so in the name and in the field; the others carry null
        assert (row["oracle"] == ORACLE_START) == row["metric"].endswith("(oracle start)")
        assert row["oracle"] in (ORACLE_START, None)
    plain = {r["metric"] for r in doc["rows"] if r["oracle"] is None}
    assert {f"tracking error {s}" for s, _ in STATS} <= plain


def test_plots_written(sweep, plots):
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


def test_sweep_reuses_the_same_streams(sweep, monkeypatch):
    """A configuration's numbers do not depend on the other configurations run, and
    ``walks(seed, trials)`` names exactly the walks that run_table simulates."""
    seen = []
    real = girard2011.simulate

    def spy(*, rng):
        seen.append(tuple(rng.bit_generator.seed_seq.entropy))
        return real(rng=rng)

    monkeypatch.setattr(girard2011, "simulate", spy)
    small = run_table(trials=SWEEP_TRIALS, seed=TEST_SEED, nus=(150,), mismatch=False)
    assert {(s, i) for s, i, _ in seen} == walks(TEST_SEED, SWEEP_TRIALS) and len(seen) == 2
    for mode in PAPER_TABLE_1:
        assert _mu(small, mode) == _mu(sweep, mode)


def test_eq1_power_sweep_is_the_tables_filter(sweep):
    """The tuning function runs the same walks and streams as Table 1 (γ = 30 default)."""
    got = girard2011.eq1_power_sweep([30.0], seed=TEST_SEED, trials=SWEEP_TRIALS)
    assert got[30.0].mean_m == _mu(sweep, "ranging")


def test_large_nu_sir_runs_on_fewer_walks(monkeypatch):
    monkeypatch.setattr(girard2011, "LARGE_NU", 200)
    rep = run_table(trials=3, seed=1, nus=(150, 200))
    row = rep.find("tracking error μ (oracle start)", "with ranging, SIR ν=200")
    assert f"first {girard2011.LARGE_NU_TRIALS} of 3 walks" in row.note
    assert "first" not in rep.find("tracking error μ (oracle start)",
                                   "with ranging, Girard ν=200").note  # fmt: skip
    assert rep.params["sir_trials_at_large_nu"] == girard2011.LARGE_NU_TRIALS


def test_run_has_the_standard_signature():
    sig = inspect.signature(run)
    assert list(sig.parameters) == ["trials", "seed", "plots_dir", "progress"]
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


def test_paper_table_keeps_the_papers_ordering():
    arr = np.array([PAPER_TABLE_1[m] for m in ("imu", "model", "ranging")])
    assert np.all(np.diff(arr[:, 0]) < 0)  # μ: IMU only > with model > with ranging
