"""``rangekit experiment``: reproduce a paper's table (paper vs measured numbers)."""

from __future__ import annotations

import time
from pathlib import Path

import click
from rangekit_cli._options import (
    debug_option,
    emit,
    format_option,
    note,
    output_option,
    progress,
    verbosity_options,
)

#: Experiment name -> module (imported only when run). The module provides
#: ``run(*, trials, seed, plots_dir, progress) -> ExperimentReport`` (``progress(done,
#: total)`` after each trial: :data:`rangekit.experiments.report.ProgressCallback`) and
#: ``DEFAULT_TRIALS``.
EXPERIMENTS: dict[str, str] = {
    "ahn2007": "rangekit.experiments.ahn2007",
    "girard2011": "rangekit.experiments.girard2011",
    "jiang2018": "rangekit.experiments.jiang2018",
    "kim2013": "rangekit.experiments.kim2013",
}


@click.command("experiment")
@click.argument("name", type=click.Choice(sorted(EXPERIMENTS)), metavar="NAME")
@click.option(
    "--trials",
    type=click.IntRange(1, 10000),
    default=None,
    metavar="N",
    help="Monte Carlo trials, 1 to 10000 (the run time grows with it; 10000 is hours) "
    "[default: the experiment's default, e.g. 20 for ahn2007].",
)
@click.option(
    "--seed",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    metavar="S",
    help="Random seed (>= 0); the same seed and trials give the same numbers.",
)
@format_option
@click.option(
    "--plots",
    "plots",
    type=click.Path(file_okay=False),
    default=None,
    metavar="DIR",
    help="Also write the paper's figures as PNG files into DIR (created if missing; its "
    "parent folder must exist).",
)
@output_option
@verbosity_options
@debug_option
def experiment_cmd(name, trials, seed, fmt, plots, output):
    """Reproduce a paper's experiment by simulation: its numbers beside rangekit's.

    NAME is one of: ahn2007 (Ahn & Yu 2007: dead reckoning with bias states, l_max
    pedestrian filter), girard2011 (Girard 2011: floor-plan particle filter with body-worn
    range finders, Table 1), jiang2018 (Jiang 2018: tracking people from acoustic ranges),
    kim2013 (Kim & Kim 2013: DUHL robot localisation from ceiling ultrasonic beacons,
    Tables II and III).
    Prints a table of metric, condition, paper, measured, unit (or the JSON report,
    formats.md of the documentation). A progress note, a progress bar (runs done, rate,
    ETA; on a terminal, or every 30 s with --verbose) and the wall time go to stderr.

    \b
    Examples:
      rangekit experiment ahn2007
      rangekit experiment jiang2018 --trials 5 --seed 1 --format json -o jiang.json
      rangekit experiment ahn2007 --trials 2 --plots figures/
      rangekit experiment kim2013 --trials 3 --plots figures/
      rangekit experiment girard2011 --trials 5 --plots figures/
    """
    from rangekit.io.results import format_report

    mod = _load(name)
    n = mod.DEFAULT_TRIALS if trials is None else trials
    plots_dir = None if plots is None else _plots_dir(plots)
    note(f"running {name}: {n} trial{'s' if n != 1 else ''}, seed {seed} ...")
    t0 = time.perf_counter()
    with progress(0, name, unit="runs") as bar:
        report = mod.run(trials=n, seed=seed, plots_dir=plots_dir, progress=bar.report)
    wall = time.perf_counter() - t0
    text = format_report(report, fmt)
    if not text.endswith("\n"):
        text += "\n"
    emit(text, output)
    where = f"; figures in {plots_dir}" if plots_dir is not None else ""
    note(f"{name}: done in {wall:.1f} s{where}")


def _load(name: str):
    """Import the experiment's module; a module not installed is a rangekit error."""
    import importlib

    from rangekit.errors import RangekitError

    path = EXPERIMENTS[name]
    try:
        return importlib.import_module(path)
    except ModuleNotFoundError as e:
        if e.name != path:
            raise
        raise RangekitError(
            f"experiment {name!r} is not available in this installation ({path} not found)"
        ) from None


def _plots_dir(plots: str) -> Path:
    """DIR for the figures, created if missing; a missing parent is an output error."""
    from rangekit.errors import InputFileError

    p = Path(plots)
    if p.exists():
        if not p.is_dir():
            raise InputFileError(f"cannot write figures into '{p}': it is not a folder")
        return p
    if not p.parent.is_dir():
        raise InputFileError(f"cannot create '{p}': folder '{p.parent}' does not exist")
    try:
        p.mkdir()
    except OSError as e:
        raise InputFileError(f"cannot create '{p}': {e.strerror or e}") from e
    return p
