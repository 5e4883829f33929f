"""``rangekit experiment`` shows progress from the library's callback (issue 19 item 4):
the experiments call ``progress(done, total)`` and never print; the CLI draws the bar."""

from __future__ import annotations

import io
import sys
import types

import rangekit_cli.experiment_cmd as experiment_cmd
from clihelp import ok, run
from rangekit_cli._progress import Progress

from rangekit.experiments import ahn2007
from rangekit.experiments.report import ExperimentReport


def _fake_experiment(monkeypatch, calls: list):
    """A fast experiment module registered as ``ahn2007``: three trials, each reported."""
    mod = types.ModuleType("rangekit_test_fake_experiment")
    mod.DEFAULT_TRIALS = 3

    def fake_run(*, trials, seed, plots_dir, progress=None):
        for i in range(trials):
            if progress is not None:
                progress(i + 1, trials)
            calls.append(i)
        rep = ExperimentReport("fake", "A fake experiment", {"trials": trials, "seed": seed})
        rep.add("metric", "condition", None, 1.0)
        return rep

    mod.run = fake_run
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    monkeypatch.setitem(experiment_cmd.EXPERIMENTS, "ahn2007", mod.__name__)


def test_cli_turns_the_callback_into_progress_lines(monkeypatch):
    calls: list = []
    _fake_experiment(monkeypatch, calls)
    out = io.StringIO()

    def bar(total, label, *, unit=""):  # a plain-line bar that writes every update
        return Progress(total, label, unit=unit, stream=out, tty=False, interval_s=0.0)

    monkeypatch.setattr(experiment_cmd, "progress", bar)
    r = ok(run(["experiment", "ahn2007", "--trials", "3"]))
    assert calls == [0, 1, 2] and "metric" in r.stdout
    lines = out.getvalue().splitlines()
    assert [ln.split(",")[0] for ln in lines[:3]] == [
        "ahn2007: 33.3% (1/3 runs)",
        "ahn2007: 66.7% (2/3 runs)",
        "ahn2007: 100.0% (3/3 runs)",
    ]
    assert "done in" in lines[-1]


def test_cli_quiet_and_off_a_terminal_show_no_bar(monkeypatch):
    _fake_experiment(monkeypatch, [])
    r = ok(run(["experiment", "ahn2007", "--trials", "2", "-q"]))
    assert r.stderr == ""
    r = ok(run(["experiment", "ahn2007", "--trials", "2"]))  # not a terminal: notes only
    assert "%" not in r.stderr and r.stderr.startswith("running ahn2007: 2 trials")


def test_library_reports_every_run_and_prints_nothing(capsys):
    seen: list = []
    ahn2007.run(trials=1, progress=lambda done, total: seen.append((done, total)))
    # 1 robot run + 1 mismatch run + 10 walks x (3 noise levels + mismatch + literal); 7 s CPU
    assert seen == [(i, 52) for i in range(1, 53)]
    assert capsys.readouterr() == ("", "")
