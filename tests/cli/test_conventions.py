"""CLI conventions shared by every verb: exit codes and docs link in ``rangekit --help``,
``[project.urls]``, defaults shown one way, ``--format table|json|csv`` with one set of
number rules, progress lines."""

from __future__ import annotations

import csv
import io
import json
import re
from pathlib import Path

import pytest
from clihelp import ok, run

from rangekit.errors import DOCS_URL, EXIT_CODES, RangekitError
from rangekit.io.results import format_pm, format_rows, sigma_decimals

ROOT = Path(__file__).resolve().parents[2]

#: The verbs of this area (track and batch have their own tests).
VERBS = [
    "range",
    "detect",
    "locate",
    "calibrate",
    "experiment",
    "design beep",
    "design sweep",
    "design barker",
    "synth beepbeep",
    "synth oneway",
    "synth echo",
    "plot spectrogram",
    "plot matched",
    "plot ranges",
    "plot track",
    "plot cdf",
]
#: Verbs that print results: each takes --format table|json|csv.
RESULT_VERBS = ["range", "detect", "locate", "calibrate", "experiment"]


def _help(verb: str) -> str:
    return ok(run([*verb.split(), "--help"])).stdout


def test_top_help_lists_every_exit_code_and_the_docs_url():
    out = _help("")
    for code, text in EXIT_CODES.items():
        assert re.search(rf"^\s+{code}\s+{re.escape(text)}$", out, re.M), (code, out)
    assert f"Documentation: {DOCS_URL}" in out
    assert "docs/" not in out.replace(DOCS_URL, "")


def test_every_error_class_has_a_documented_code():
    classes, todo = set(), [RangekitError]
    while todo:
        c = todo.pop()
        classes.add(c)
        todo += c.__subclasses__()
    assert {c.exit_code for c in classes} <= set(EXIT_CODES)


def test_docs_table_has_the_same_codes():
    text = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    section = text.split("## Exit codes", 1)[1].split("\n## ", 1)[0]
    codes = {int(m) for m in re.findall(r"^\| (\d+) \|", section, re.M)}
    assert codes == set(EXIT_CODES)


def test_project_urls_name_the_docs_url():
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    urls = text.split("[project.urls]\n", 1)[1].split("\n[", 1)[0]
    assert f'Documentation = "{DOCS_URL}"' in urls.splitlines()


#: What a bracket in a help text may be, besides "[default: X]".
_ALLOWED = re.compile(
    r"^\[(required|OPTIONS|ARGS|,.*|[-\d.]+, [-\w.]+|.*(<=|>=|<|>)x.*|x.*|.*\|.*)\]$"
)


@pytest.mark.parametrize("verb", VERBS)
def test_defaults_shown_one_way_and_no_docs_path(verb):
    out = " ".join(_help(verb).split())
    odd = [b for b in re.findall(r"\[[^\[\]]*\]", out) if not b.startswith("[default: ")]
    assert [b for b in odd if not _ALLOWED.match(b)] == []
    assert "docs/" not in out  # an installed package has no docs folder


@pytest.mark.parametrize("verb", RESULT_VERBS)
def test_result_verbs_offer_the_same_formats(verb):
    out = " ".join(_help(verb).split())
    assert "--format [table|json|csv]" in out and "[default: table]" in out


def test_sigma_sets_the_digits():
    """A value is printed with as many decimals as its sigma needs (two significant digits
    of sigma): the clock-rate case of issue 19, 50 ppm +- 0.02 ppm, shows the sigma."""
    assert format_pm(50.0, 0.02, sign=True) == "+50.000 +- 0.020"
    assert [sigma_decimals(s) for s in (0.02, 0.0091, 0.5, 12.0, float("nan"))] == [
        3,
        4,
        2,
        0,
        None,
    ]
    rows = [{"x_m": 1.234567891, "sigma_x_m": 1.23e-7, "n": 3, "flags": ["a", "b"]}]
    fields = ["x_m", "sigma_x_m", "n", "flags"]
    table = format_rows(rows, fields, "table").splitlines()[1].split()
    assert table == ["1.23456789", "0.00000012", "3", "a,b"]  # CSV: 6 decimals, or more:
    cells = next(csv.DictReader(io.StringIO(format_rows(rows, fields, "csv"))))
    assert cells == {"x_m": "1.23456789", "sigma_x_m": "0.00000012", "n": "3", "flags": "a;b"}
    wide = format_rows([{**rows[0], "sigma_x_m": 0.5}], fields, "csv").splitlines()[1]
    assert wide.startswith("1.234568,0.500000,")
    js = json.loads(format_rows(rows, fields, "json"))["rows"][0]
    assert js["x_m"] == 1.234567891 and js["flags"] == ["a", "b"]
    missing = [{"x_m": None, "sigma_x_m": float("nan"), "n": 0, "flags": []}]
    assert format_rows(missing, fields, "table").splitlines()[1].split() == ["-", "-", "0", "-"]
    assert format_rows(missing, fields, "csv").splitlines()[1] == ",,0,"
    assert json.loads(format_rows(missing, fields, "json"))["rows"][0]["sigma_x_m"] is None


def test_locate_formats_share_the_rules(tmp_path):
    tx = [{"id": i, "x_m": x, "y_m": -0.75, "z_m": 2.011} for i, x in enumerate((-1.5, 0, 1.5))]
    beacons = tmp_path / "b.json"
    beacons.write_text(
        json.dumps({"format": "rangekit-beacons", "version": 1, "units": "m", "transmitters": tx})
    )
    args = ["locate", "--beacons", beacons, "--sigma", "0.001"]
    args += ["--tx", "0:2.73,2.62,2.52", "--tx", "1:2.16,2.21,2.10", "--tx", "2:2.51,2.73,2.63"]
    table = ok(run(args)).stdout.splitlines()
    row = dict(zip(table[0].split(), table[1].split(), strict=True))
    js = json.loads(ok(run([*args, "--format", "json"])).stdout)
    got = next(csv.DictReader(io.StringIO(ok(run([*args, "--format", "csv"])).stdout)))
    nd = sigma_decimals(js["sigma_x_m"])
    assert row["x_m"] == f"{js['x_m']:.{nd}f}" and len(row["sigma_x_m"].split(".")[1]) == nd
    assert float(got["x_m"]) == pytest.approx(js["x_m"], abs=1e-6)


def test_experiment_csv_loads_like_its_json():
    from rangekit.experiments.report import ExperimentReport
    from rangekit.io.results import format_report

    rep = ExperimentReport("demo", "A demo", {"trials": 2, "seed": 1})
    rep.add("median error", "target 2, 0.4 m/s", 0.85, 0.5312, unit="m")
    rep.add("NEES", "x", None, float("nan"))
    rows = list(csv.DictReader(io.StringIO(format_report(rep, "csv"))))
    assert [r["metric"] for r in rows] == ["median error", "NEES"]
    assert float(rows[0]["measured"]) == 0.5312 and rows[1]["measured"] == ""
    assert rows[1]["paper"] == "" and rows[0]["unit"] == "m"
    assert json.loads(format_report(rep, "json"))["rows"][1]["measured"] is None
    assert format_report(rep, "table").startswith("# A demo (trials=2, seed=1)\n")


def test_count_progress_counts_only_this_runs_work():
    from rangekit_cli._progress import CountProgress

    starts = []
    out = io.StringIO()
    p = CountProgress("batch", unit="sessions", on_start=starts.append, stream=out)
    for done in (4, 4, 6, 10):  # 4 found done in a resumed file, then 6 of this run
        p(done, 10)
    assert starts == [4] and p.last == 10
    assert p.bar.total == 6 and p.bar.done == 6
    p.close()
    quiet = CountProgress("batch", quiet=True, on_start=starts.append, stream=out)
    quiet(3, 10)
    assert quiet.bar is None and quiet.last == 3 and starts == [4]
