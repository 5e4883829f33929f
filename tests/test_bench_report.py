"""benchmarks/_report.py (the ``@row`` lines) and benchmarks/run.py (collecting them into
one table), on canned output and tiny stand-in scripts: no real benchmark runs here."""

from __future__ import annotations

import importlib.util
import json
import math
import os
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


def _load(name: str):
    spec = importlib.util.spec_from_file_location(
        f"_bench_{name}", ROOT / "benchmarks" / f"{name}.py"
    )
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


report = _load("_report")
run = _load("run")


def _rows_printed(capsys) -> list[str]:
    return capsys.readouterr().out.splitlines()


# --------------------------------------------------------------------------- _report.row
def test_row_prints_one_json_line_with_every_field(capsys):
    out = report.row("detect", "detect_changepoint float64", 493.0, "x-realtime",
                     peer="scipy ShortTimeFFT", peer_value=41.0, note="10 min")  # fmt: skip
    lines = _rows_printed(capsys)
    assert len(lines) == 1 and lines[0].startswith("@row {")
    obj = json.loads(lines[0][len("@row ") :])
    assert list(obj) == list(report.FIELDS)
    assert obj == out
    assert obj["value"] == 493.0 and obj["peer_value"] == 41.0
    assert obj["ratio"] == pytest.approx(493.0 / 41.0)  # throughput: value / peer


def test_ratio_above_one_means_rangekit_faster_for_times_and_sizes(capsys):
    # us/step: rangekit 2 us, FilterPy 123 us -> 61.5x faster
    assert report.row("ekf", "step", 2.0, "us/step", peer_value=123.0)["ratio"] == 61.5
    assert report.row("cli", "median", 0.4, "s", peer_value=0.2)["ratio"] == 0.5
    assert report.row("m", "peak", 10.0, "MB", peer_value=30.0)["ratio"] == 3.0
    assert report.row("p", "ups", 12.0, "updates/s", peer_value=4.0)["ratio"] == 3.0
    assert report.row("b", "speed-up", 1.8, "x", peer_value=1.7)["ratio"] == pytest.approx(
        1.8 / 1.7
    )
    # an explicit ratio wins over the one from peer_value
    assert report.row("d", "x", 100.0, "x-realtime", peer_value=50.0, ratio=3.0)["ratio"] == 3.0
    assert len(_rows_printed(capsys)) == 6


def test_ratio_needs_a_known_direction(capsys):
    with pytest.raises(ValueError, match="unit='furlongs'"):
        report.row("x", "m", 1.0, "furlongs", peer_value=2.0)
    # without a peer value, or with an explicit ratio, any unit is fine
    assert report.row("x", "m", 1.0, "furlongs")["ratio"] is None
    assert report.row("x", "m", 1.0, "furlongs", peer_value=2.0, ratio=0.5)["ratio"] == 0.5
    assert len(_rows_printed(capsys)) == 2


def test_missing_numbers_are_null_and_numpy_scalars_accepted(capsys):
    r = report.row("ekf", "step", np.float64(2.5), "us/step", peer="FilterPy",
                   peer_value=None, note="FilterPy not installed")  # fmt: skip
    assert r["value"] == 2.5 and r["peer_value"] is None and r["ratio"] is None
    r = report.row("duhl", "cycle", 3.0, "us/cycle", peer_value=float("nan"))
    assert r["peer_value"] is None and r["ratio"] is None
    r = report.row("d", "m", math.inf, "x-realtime")
    assert r["value"] is None
    for line in _rows_printed(capsys):  # strict JSON: no NaN/Infinity tokens
        json.loads(line[5:], parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))


def test_row_rejects_bad_arguments(capsys):
    with pytest.raises(ValueError, match="metric"):
        report.row("detect", " ", 1.0, "s")
    with pytest.raises(ValueError, match="bench"):
        report.row("", "m", 1.0, "s")
    with pytest.raises(ValueError, match="one line"):
        report.row("detect", "m", 1.0, "s", note="two\nlines")
    with pytest.raises(TypeError, match="value"):
        report.row("detect", "m", "fast", "s")
    with pytest.raises(TypeError, match="peer_value"):
        report.row("detect", "m", 1.0, "s", peer_value=True)
    assert capsys.readouterr().out == ""  # nothing printed on an error


# --------------------------------------------------------------------------- run.py parsing
def test_parse_row_round_trips_report_output(capsys):
    out = report.row("matched", "correlate [folded | 147 taps]", 164.0, "x-realtime",
                     peer="scipy.signal.correlate", peer_value=51.0)  # fmt: skip
    line = capsys.readouterr().out
    assert run.parse_row(line) == out
    assert run.ROW_PREFIX == report.PREFIX and run.ROW_FIELDS == report.FIELDS
    assert run.parse_row("  signal: 600 s at 44100 Hz\n") is None
    assert run.parse_row("@rowing is not a row\n") is None


@pytest.mark.parametrize(
    ("line", "match"),
    [
        ("@row {not json\n", "not JSON"),
        ("@row [1, 2]\n", "not a JSON object"),
        ('@row {"bench": "b", "metric": "m"}\n', "lacks value"),
        (
            '@row {"bench": "b", "metric": "m", "value": "1", "unit": "s", "peer": null, '
            '"peer_value": null, "ratio": null, "note": ""}\n',
            "non-numeric value",
        ),
    ],
)
def test_parse_row_rejects_malformed_row_lines(line, match):
    with pytest.raises(ValueError, match=match):
        run.parse_row(line)


def test_collect_separates_rows_from_the_streamed_output():
    lines = [
        "signal: 60 s\n",
        '@row {"bench": "detect", "metric": "cp", "value": 500.0, "unit": "x-realtime", '
        '"peer": "stft", "peer_value": 40.0, "ratio": 12.5, "note": ""}\n',
        "@row {broken\n",
        "  check OK\n",
    ]
    echoed: list[str] = []
    rows, bad = run.collect(lines, echo=echoed.append)
    assert echoed == ["signal: 60 s\n", "  check OK\n"]
    assert [r["metric"] for r in rows] == ["cp"] and rows[0]["ratio"] == 12.5
    assert len(bad) == 1 and "not JSON" in bad[0]


# --------------------------------------------------------------------------- the table
def _canned() -> list:
    row = dict.fromkeys(run.ROW_FIELDS)
    detect = [
        {**row, "bench": "detect", "metric": "detect_changepoint float64", "value": 493.2,
         "unit": "x-realtime", "peer": "scipy ShortTimeFFT", "peer_value": 41.04,
         "ratio": 12.02, "note": "10 min"},
        {**row, "bench": "detect", "metric": "detect_xcorr", "value": 86.0,
         "unit": "x-realtime", "peer": None, "peer_value": None, "ratio": None, "note": ""},
    ]  # fmt: skip
    return [
        run.BenchResult("bench_detect.py", "python benchmarks/bench_detect.py --quick", 0,
                        61.0, 2.4e9, detect),
        run.BenchResult("bench_batch.py", "python benchmarks/bench_batch.py --quick", 0,
                        30.0, 150e6, []),
        run.BenchResult("bench_ekf.py", "python benchmarks/bench_ekf.py --quick", 1, 5.0,
                        None, [], ["row line is not JSON: '@row {'"]),
    ]  # fmt: skip


def test_table_rows_one_line_per_row_rss_once_per_bench_and_failures():
    cells = run.table_rows(_canned())
    assert all(len(c) == len(run.COLUMNS) for c in cells)
    by_col = [dict(zip(run.COLUMNS, c, strict=True)) for c in cells]
    assert [c["metric"] for c in by_col] == [
        "detect_changepoint float64",
        "detect_xcorr",
        "(no @row lines)",
        "FAILED (exit 1)",
        "(1 malformed @row lines)",
    ]
    first = by_col[0]
    assert (first["value"], first["peer value"], first["ratio"]) == ("493", "41.0", "12.0x")
    assert first["peak RSS"] == "2.40 GB" and by_col[1]["peak RSS"] == ""
    assert by_col[1]["ratio"] == "" and by_col[1]["peer"] == ""
    assert by_col[2]["bench"] == "batch" and by_col[2]["peak RSS"] == "150 MB"
    assert by_col[3]["bench"] == "ekf" and by_col[3]["peak RSS"] == ""


def test_fmt_num_keeps_about_three_digits():
    assert [run.fmt_num(v) for v in (4800.4, 493.2, 12.02, 2.024, 0.1234, None)] == [
        "4800", "493", "12.0", "2.02", "0.123", "n/a",
    ]  # fmt: skip


def test_text_table_aligns_columns():
    lines = run.text_table(_canned()).splitlines()
    assert lines[0].split()[:4] == ["bench", "metric", "value", "unit"]
    assert set(lines[1].replace(" ", "")) == {"-"}
    # the value column is right-aligned: its right edge is the same on every data line
    edge = lines[0].index("value") + len("value")
    assert lines[2][:edge].endswith("493") and lines[3][:edge].endswith("86.0")


def test_markdown_section_has_facts_and_a_well_formed_table():
    facts = [("date", "2026-11-23 03:00 UTC"), ("cpu", "AMD EPYC | Zen 4")]
    md = run.markdown_section(_canned(), facts, "python benchmarks/run.py --quick")
    assert md.startswith("### `python benchmarks/run.py --quick`")
    assert "| cpu | AMD EPYC \\| Zen 4 |" in md
    table = [ln for ln in md.splitlines() if ln.startswith("| bench") or ln.startswith("| detect")]
    assert table[0] == "| " + " | ".join(run.COLUMNS) + " |"
    # Every table (a run of "| " lines) is well formed: each row has its header's columns.
    # The results table has run.COLUMNS; run.py's goals table (met / not met) its own four.
    blocks, cur = [], []
    for ln in [*md.splitlines(), ""]:
        if ln.startswith("|"):
            cur.append(ln)
        elif cur:
            blocks.append(cur)
            cur = []

    def cells(ln):
        return ln.count("|") - ln.count("\\|") - 1

    for b in blocks:
        assert all(cells(ln) == cells(b[0]) for ln in b), b
    assert any(cells(b[0]) == len(run.COLUMNS) and b[0] == table[0] for b in blocks)
    assert "| 493 | x-realtime | scipy ShortTimeFFT | 41.0 | 12.0x | 2.40 GB |" in md
    assert "`bench_ekf.py` FAILED (exit 1), 5 s" in md


def test_json_report_keeps_raw_rows_with_file_and_rss():
    rep = run.json_report(_canned(), [("date", "d")], "python benchmarks/run.py")
    assert rep["machine"] == {"date": "d"}
    assert [b["returncode"] for b in rep["benchmarks"]] == [0, 0, 1]
    assert len(rep["rows"]) == 2
    assert rep["rows"][0]["value"] == 493.2 and rep["rows"][0]["file"] == "bench_detect.py"
    assert rep["rows"][0]["peak_rss_bytes"] == 2.4e9
    json.dumps(rep)  # serialisable


# --------------------------------------------------------------------------- subprocesses
_FAKE = """\
import sys
sys.path.insert(0, {bench_dir!r})
from _report import row
print("normal output", flush=True)
buf = bytearray({n_bytes})
for i in range(0, len(buf), 4096):
    buf[i] = 1
row("fake", "metric", 2.0, "us/step", peer="peer", peer_value=4.0)
print("after", flush=True)
sys.exit({code})
"""


def _fake_bench(path: Path, n_bytes: int, code: int) -> Path:
    path.write_text(_FAKE.format(bench_dir=str(ROOT / "benchmarks"), n_bytes=n_bytes, code=code))
    return path


@pytest.mark.skipif(not hasattr(os, "wait4"), reason="peak RSS needs os.wait4")
def test_run_bench_streams_collects_and_measures_each_child_alone(tmp_path, capsys):
    big = _fake_bench(tmp_path / "bench_big.py", 300_000_000, 3)
    small = _fake_bench(tmp_path / "bench_small.py", 0, 0)
    r_big = run.run_bench([sys.executable, str(big)], cwd=tmp_path, display="big")
    r_small = run.run_bench([sys.executable, str(small)], cwd=tmp_path, display="small")
    assert capsys.readouterr().out == "normal output\nafter\n" * 2  # row lines not echoed
    assert r_big.returncode == 3 and r_small.returncode == 0
    assert r_big.file == "bench_big.py" and r_big.name == "big"
    assert [r["ratio"] for r in r_big.rows] == [2.0]
    assert r_big.peak_rss_bytes >= 300e6
    # The second child's own peak, not the maximum over all children so far. On Linux a
    # child's ru_maxrss also counts the parent's pages at fork time (before exec), so
    # this is checkable only while this test process itself is small.
    import resource

    parent = run.maxrss_bytes(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
    if parent < 150e6:
        assert r_small.peak_rss_bytes < 200e6
    else:
        assert r_small.peak_rss_bytes < max(200e6, 1.1 * parent)


_RESETS_ITS_PEAK = """\
import time
buf = bytearray(300_000_000)
for i in range(0, len(buf), 4096):
    buf[i] = 1
time.sleep(0.4)
del buf
with open("/proc/self/clear_refs", "w") as f:
    f.write("5")  # VmHWM and ru_maxrss drop to the current RSS, as bench_matched.py does
"""


def _can_reset_peak() -> bool:
    try:
        with open("/proc/self/clear_refs", "w"):
            return True
    except OSError:
        return False


@pytest.mark.skipif(not _can_reset_peak(), reason="needs a writable /proc/self/clear_refs")
def test_run_bench_keeps_a_peak_the_benchmark_reset(tmp_path, capsys):
    script = tmp_path / "bench_reset.py"
    script.write_text(_RESETS_ITS_PEAK)
    res = run.run_bench([sys.executable, str(script)], cwd=tmp_path, display="reset")
    assert res.returncode == 0
    assert res.peak_rss_bytes >= 300e6  # seen by the VmHWM sampling, lost by ru_maxrss


def test_main_writes_markdown_and_json_and_keeps_the_exit_status(tmp_path, monkeypatch, capsys):
    bench_dir = tmp_path / "benchmarks"
    bench_dir.mkdir()
    _fake_bench(bench_dir / "bench_a.py", 0, 0)
    monkeypatch.setattr(run, "HERE", bench_dir)
    monkeypatch.setattr(run, "ROOT", tmp_path)
    md, js = tmp_path / "out.md", tmp_path / "out.json"
    assert run.main(["--quick", "--markdown", str(md), "--json", str(js)]) == 0
    out = capsys.readouterr().out
    assert "summary: python benchmarks/run.py --quick --markdown" in out
    assert "all exited 0" in out
    assert "| fake | metric | 2.00 | us/step | peer | 4.00 | 2.00x |" in md.read_text()
    assert json.loads(js.read_text())["rows"][0]["metric"] == "metric"

    _fake_bench(bench_dir / "bench_b.py", 0, 2)
    assert run.main(["-k", "bench_b"]) == 1
    out = capsys.readouterr().out
    assert "bench_a.py" not in out.split("benchmarks :")[1].splitlines()[0]
    assert "failed: bench_b.py" in out


def test_supports_quick_reads_the_source(tmp_path):
    p = tmp_path / "bench_q.py"
    p.write_text(textwrap.dedent('ap.add_argument("--quick", action="store_true")\n'))
    assert run.supports_quick(p)
    p.write_text("print('no options')\n")
    assert not run.supports_quick(p)


def test_run_bench_gives_its_children_a_bytecode_cache(tmp_path, monkeypatch, capsys):
    """Where PYTHONDONTWRITEBYTECODE is set, a benchmark (and what it starts) runs without
    it and keeps bytecode outside the checkout: no command recompiles rangekit."""
    script = tmp_path / "bench_env.py"
    script.write_text(
        "import os, sys\n"
        "print(os.environ.get('PYTHONDONTWRITEBYTECODE'), sys.dont_write_bytecode,\n"
        "      os.environ.get('PYTHONPYCACHEPREFIX'))\n"
    )
    monkeypatch.setenv("PYTHONDONTWRITEBYTECODE", "1")
    monkeypatch.delenv("PYTHONPYCACHEPREFIX", raising=False)
    res = run.run_bench([sys.executable, str(script)], cwd=tmp_path, display="env")
    assert res.returncode == 0
    none, dont, prefix = capsys.readouterr().out.split()
    assert (none, dont) == ("None", "False")
    assert prefix.endswith(run.PYCACHE_DIR) and not prefix.startswith(str(ROOT))


def test_best_of_gives_wall_and_cpu_and_the_result():
    import time

    def busy():
        t0 = time.process_time()
        while time.process_time() - t0 < 0.02:
            pass
        return 7

    wall, cpu, res = report.best_of(busy, 2)
    assert res == 7
    assert 0.02 <= cpu <= wall + 0.01  # measured 0.020 s CPU, wall about the same
    w_sleep, c_sleep, _ = report.best_of(lambda: time.sleep(0.05), 1)
    assert w_sleep >= 0.05 and c_sleep < 0.02  # sleeping costs wall, not CPU


def test_goal_verdicts_are_collected_by_run():
    note = "60 s; " + report.goal_verdict("goal >= 800x", False, "355x, 8.8x the peer", "178x")
    assert note.endswith("goal >= 800x: NOT met on CPU time (355x, 8.8x the peer; wall 178x)")
    ok = report.goal_verdict("goal <= 50 us/epoch for 8 hypotheses (issue 20)", True, "41 us")
    res = run.BenchResult("bench_x.py", "python benchmarks/bench_x.py", 0, 1.0, None, rows=[
        {"bench": "x", "metric": "a", "note": note}, {"bench": "x", "metric": "b", "note": ok},
    ])  # fmt: skip
    assert run.goal_rows([res]) == [
        ("x", "a", "goal >= 800x", "NOT met"),
        ("x", "b", "goal <= 50 us/epoch for 8 hypotheses (issue 20)", "met"),
    ]
