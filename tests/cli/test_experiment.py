"""CLI tests of ``rangekit experiment`` (ahn2007 only, with 1-2 trials, to stay fast)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from clihelp import assert_error, ok, run
from rangekit_cli.experiment_cmd import EXPERIMENTS


@pytest.fixture(scope="module")
def ahn_json() -> dict:
    r = ok(run(["experiment", "ahn2007", "--trials", 2, "--format", "json"]))
    assert "running ahn2007: 2 trials" in r.stderr
    assert "done in" in r.stderr
    return json.loads(r.stdout)


def test_json_report(ahn_json):
    assert ahn_json["experiment"] == "ahn2007"
    assert ahn_json["params"]["trials"] == 2
    assert ahn_json["params"]["seed"] == 0
    assert ahn_json["rows"]
    for row in ahn_json["rows"]:
        assert {"metric", "condition", "paper", "measured"} <= set(row), row
        assert row["paper"] is None or isinstance(row["paper"], float)


def test_same_seed_same_numbers_and_table(tmp_path, ahn_json):
    out = tmp_path / "ahn.json"
    r = ok(run(["experiment", "ahn2007", "--trials", 2, "--format", "json", "-o", out]))
    assert r.stdout == ""
    assert json.loads(out.read_text()) == ahn_json
    t = ok(run(["experiment", "ahn2007", "--trials", 1, "--seed", 3]))
    lines = t.stdout.splitlines()
    assert lines[0].startswith("# ") and "trials=1" in lines[0] and "seed=3" in lines[0]
    assert lines[1].split()[:4] == ["metric", "condition", "paper", "measured"]
    assert len(lines) == 2 + len(ahn_json["rows"])
    assert "running ahn2007: 1 trial," in t.stderr


def test_plots(tmp_path):
    plots = tmp_path / "figures"  # does not exist yet: created
    r = ok(run(["experiment", "ahn2007", "--trials", 1, "--plots", plots]))
    pngs = sorted(plots.glob("*.png"))
    assert pngs, list(plots.iterdir())
    for p in pngs:
        assert p.stat().st_size > 0
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert str(plots) in r.stderr


def test_plots_parent_missing(tmp_path):
    plots = tmp_path / "no_such_parent" / "figures"
    assert_error(run(["experiment", "ahn2007", "--trials", 1, "--plots", plots]), 3,
                  "no_such_parent")  # fmt: skip
    assert not plots.parent.exists()


def test_plots_is_a_file(tmp_path):
    f = tmp_path / "figures"
    f.write_text("a file")
    assert_error(run(["experiment", "ahn2007", "--trials", 1, "--plots", f]), 2, "--plots")
    assert f.read_text() == "a file"


def test_unknown_experiment():
    line = assert_error(run(["experiment", "nosuch2099"]), 2, "nosuch2099", "ahn2007")
    assert "rangekit experiment --help" in line


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        (["--trials", "0"], "--trials"),
        (["--trials", "-3"], "--trials"),
        (["--trials", "two"], "--trials"),
        (["--seed", "-1"], "--seed"),
        (["--format", "xml"], "--format"),
    ],
)
def test_bad_options(extra, named):
    assert_error(run(["experiment", "ahn2007", *extra]), 2, named)


def test_failed_run_leaves_existing_output_untouched(tmp_path):
    out = tmp_path / "report.json"
    out.write_text("SENTINEL\n")
    plots = tmp_path / "missing" / "figs"
    r = run(["experiment", "ahn2007", "--trials", 1, "--plots", plots, "-o", out])
    assert_error(r, 3, "missing")
    assert out.read_text() == "SENTINEL\n"


def test_help_lists_names_without_importing_them():
    """``--help`` must work even while an experiment module does not exist yet."""
    code = (
        "import sys\n"
        "from rangekit_cli.main import main\n"
        "try:\n"
        "    main(['experiment', '--help'])\n"
        "except SystemExit as e:\n"
        "    assert e.code in (0, None), e.code\n"
        "loaded = sorted(m for m in sys.modules if m.startswith('rangekit.experiments.'))\n"
        "print('LOADED', loaded)\n"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    for name in EXPERIMENTS:
        assert name in p.stdout
    assert "LOADED []" in p.stdout, p.stdout


def test_registry_maps_names_to_modules():
    assert {"ahn2007", "jiang2018"} <= set(EXPERIMENTS)
    for name, path in EXPERIMENTS.items():
        assert path == f"rangekit.experiments.{name}"
