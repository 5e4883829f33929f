"""``rangekit track`` as a click group: bare help, one subcommand per filter with only its
own options, library defaults in the help, and the deprecated ``--filter NAME`` form."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from clihelp import assert_error, ok, run

from rangekit.sim import ahn2007

CLI = Path(__file__).resolve().parents[2] / "cli"
FILTERS = ("range-ekf", "dead-reckoning", "lmax", "duhl", "duhl-ranges", "particle")


@pytest.fixture
def fixes(tmp_path):
    p = tmp_path / "fixes.csv"
    p.write_text(ahn2007.position_log_text(ahn2007.simulate_pedestrian(12, rng=3)))
    return p


def test_bare_track_prints_help_exit_0():
    r = run(["track"])
    assert r.exit_code == 0, r.stderr
    for name in FILTERS:
        assert name in r.stdout
    assert ok(run(["track", "--help"])).stdout == r.stdout


#: Options that must not show in a subcommand's help (they belong to other filters).
FOREIGN = {
    "range-ekf": ("--l-max", "--beacons", "--wheel-base", "--map", "--particles"),
    "dead-reckoning": ("--accel-psd", "--cross-sign", "--rig", "--l-max", "--beacons"),
    "lmax": ("--smooth", "--gate", "--accel-psd", "--beacons", "--map"),
    "duhl": ("--smooth", "--accel-psd", "--robust", "--map", "--l-max"),
    "duhl-ranges": ("--smooth", "--cross-sign", "--particles", "--steps"),
    "particle": ("--gate", "--smooth", "--beacons", "--initial-pose", "--steps", "--l-max"),
}


@pytest.mark.parametrize("name", FILTERS)
def test_each_subcommand_has_only_its_own_options(name):
    text = ok(run(["track", name, "--help"])).stdout
    assert f"rangekit track {name}" in text
    for opt in FOREIGN[name]:
        assert opt not in text, (name, opt)


def test_help_shows_the_library_defaults():
    from rangekit_cli.track_common import default

    from rangekit.localize.particle import ParticleConfig
    from rangekit.localize.range_ekf import track_ranges

    text = " ".join(ok(run(["track", "range-ekf", "--help"])).stdout.split())
    assert f"[default: {default(track_ranges, 'accel_psd')}]" in text
    assert f"[default: {default(track_ranges, 'gate'):g} per range]" in text
    text = " ".join(ok(run(["track", "particle", "--help"])).stdout.split())
    assert f"[default: {ParticleConfig().n_particles}]" in text
    assert f"[default: {ParticleConfig().method}]" in text


#: A bracket in a help text: "[default: X]", or click's own (choices, ranges, required).
_CLICK_BRACKET = re.compile(r"^\[(required|OPTIONS|ARGS|,.*|.*(<=|>=|<|>)x.*|x.*|.*\|.*)\]$")


@pytest.mark.parametrize("name", ["", *FILTERS])
def test_help_follows_the_conventions(name):
    """Defaults shown one way, no docs/ path (an installed package has none), the same
    --format choices as every verb (csv stays track's default: it is a data file)."""
    out = " ".join(ok(run(["track", *name.split(), "--help"])).stdout.split())
    odd = [b for b in re.findall(r"\[[^\[\]]*\]", out) if not b.startswith("[default: ")]
    assert [b for b in odd if not _CLICK_BRACKET.match(b)] == []
    assert "docs/" not in out
    if name:
        assert "--format [table|json|csv]" in out and "[default: csv]" in out


@pytest.mark.parametrize("name", FILTERS)
def test_every_subcommand_has_quiet_and_verbose(name):
    out = ok(run(["track", name, "--help"])).stdout
    assert "-q, --quiet" in out and "-v, --verbose" in out


def test_quiet_drops_the_summary_verbose_says_the_parameters(tmp_path):
    from rangekit.sim import jiang2018

    log = tmp_path / "walk.csv"
    log.write_text(jiang2018.simulate(rng=1).log.to_csv())
    normal = ok(run(["track", "range-ekf", log]))
    assert normal.stderr.startswith("range-ekf: ")
    quiet = ok(run(["track", "range-ekf", log, "--quiet"]))
    assert quiet.stderr == "" and quiet.stdout == normal.stdout
    verbose = ok(run(["track", "range-ekf", log, "-v", "--accel-psd", "0.1"]))
    lines = verbose.stderr.splitlines()
    assert lines[0] == (
        "rangekit: track range-ekf: accel_psd 0.1, gate 0.999, cross_sign physical, "
        "iterations 5, engine compiled"
    )
    assert lines[1:] == normal.stderr.splitlines()
    assert_error(run(["track", "range-ekf", log, "-q", "-v"]), 2, "--quiet")


def test_table_format_aligns_the_same_rows(fixes):
    import csv
    import io

    rows = list(csv.reader(io.StringIO(ok(run(["track", "lmax", fixes, "--l-max", "0.5"])).stdout)))
    table = ok(run(["track", "lmax", fixes, "--l-max", "0.5", "--format", "table"])).stdout
    lines = table.splitlines()
    assert lines[0].split() == rows[0] == ["t_s", "x_m", "y_m"]
    assert len(lines) == len(rows) and len({len(ln) for ln in lines}) == 1  # aligned
    for got, want in zip(lines[1:], rows[1:], strict=True):
        assert [float(v) for v in got.split()] == pytest.approx([float(v) for v in want], abs=1e-6)


def test_deprecated_filter_form_gives_the_same_track(fixes):
    new = ok(run(["track", "lmax", fixes, "--l-max", "0.5"]))
    assert new.stderr == ""
    for args in (
        ["track", "--filter", "lmax", fixes, "--l-max", "0.5"],
        ["track", "--filter=lmax", fixes, "--l-max", "0.5"],
        ["track", fixes, "--l-max", "0.5", "--filter", "lmax"],  # anywhere, as before
    ):
        old = ok(run(args))
        assert old.stdout == new.stdout
        lines = old.stderr.splitlines()
        assert len(lines) == 1 and "deprecated" in lines[0], old.stderr
        assert "'rangekit track lmax'" in lines[0]


def test_deprecated_form_errors_stay_one_line(tmp_path):
    r = run(["track", "--filter", "lmax", tmp_path / "no.csv", "--l-max", "1"])
    assert_error(r, 3, "no.csv")
    assert_error(run(["track", "--filter"]), 2, "--filter")
    assert_error(run(["track", "--filter", "kalman", "x.csv"]), 2, "kalman", "range-ekf")
    assert_error(run(["track", "--filter", "lmax", "x.csv", "--beacons", "b"]), 2, "--beacons")


def test_modules_stay_small():
    sizes = {p.name: len(p.read_text().splitlines()) for p in CLI.glob("track*.py")}
    assert len(sizes) >= 5 and max(sizes.values()) <= 250, sizes
