"""``rangekit batch``: range a whole archive of recordings, in parallel and resumably."""

from __future__ import annotations

import os

import click
from rangekit_cli._options import (
    beep_options,
    calibration_option,
    clock_ppm_option,
    debug_option,
    detector_option,
    self_distance_option,
    speed_of_sound_option,
    temperature_option,
    template_option,
    verbosity_options,
)
from rangekit_cli.batch_setup import batch_options, details
from rangekit_cli.ultrasonic_options import ultrasonic_options

#: Exit codes of ``rangekit batch`` beyond the common ones (docs/cli.md).
EXIT_SOME_FAILED = 8
EXIT_ALL_FAILED = 9


#: Thread-count variables of the numeric libraries, set to 1 for a batch unless the user
#: set them: the parallelism is across sessions, and idle BLAS/OpenMP threads spinning
#: next to busy workers cost more than they give (measured: 2.4x slower with 2 busy cores).
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


def _one_thread_per_worker() -> None:
    """One compute thread per process, if numpy is not loaded yet (else it is too late)."""
    import sys

    if "numpy" in sys.modules:
        return
    for var in THREAD_VARS:
        os.environ.setdefault(var, "1")


# When the command is loaded, before its options are parsed: the check of -o loads numpy
# (rangekit.io), after which the setting came too late for the parent and the workers it
# forks (docs/batch.md: each process computes on one thread).
_one_thread_per_worker()


@click.command("batch")
@click.argument("inputs", nargs=-1, required=True, metavar="INPUT...")
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(dir_okay=False),
    metavar="FILE.csv|FILE.jsonl",
    help="Results file (required), CSV or JSON Lines by its suffix, rows only (loads in "
    "pandas as it is); written as sessions finish, so an interrupted batch keeps every "
    "finished result. The options go to FILE.meta.json beside it.",
)
@click.option(
    "--jobs",
    "-j",
    type=click.IntRange(min=1, max=1024),
    default=None,
    metavar="N",
    help="Worker processes [all cores of this machine].",
)
@click.option(
    "--resume",
    is_flag=True,
    help="Continue an interrupted batch into the same -o file: finished sessions are "
    "skipped, a torn last session is redone; the final file equals an uninterrupted run's.",
)
@click.option(
    "--scheduler",
    default=None,
    metavar="tcp://HOST:PORT",
    help="Run on this Dask distributed scheduler instead of local processes (needs "
    "pip install 'rangekit[dask]').",
)
@click.option(
    "--scheme",
    type=click.Choice(["beepbeep", "oneway", "echo"]),
    default="beepbeep",
    show_default=True,
    help="Scheme of sessions whose sidecar does not name one (see rangekit range).",
)
@click.option(
    "--pair-by-name",
    is_flag=True,
    help="INPUT... are 2+ device folders in device order (the first is device 0), each "
    "holding one mono recording per take; recordings with the same path relative to their "
    "folder, suffix aside (dev0/day1/take_01.wav, dev1/day1/take_01.flac), are one "
    "BeepBeep session named by that path (day1/take_01). A take missing from a folder is "
    "an error row; a KEY.json beside device 0's file is its sidecar. beepbeep only.",
)
@self_distance_option(
    "beepbeep: speaker-to-microphone distance(s), m, where the sidecar gives none."
)
@temperature_option
@speed_of_sound_option("Speed of sound in m/s (overrides --temperature and sidecar temperatures).")
@clock_ppm_option("beepbeep: 1-sigma sample-clock tolerance per device, ppm (widens sigma_m only).")
@detector_option
@template_option
@calibration_option
@beep_options
@ultrasonic_options
@verbosity_options
@debug_option
def batch_cmd(
    inputs,
    output,
    jobs,
    resume,
    scheduler,
    scheme,
    pair_by_name,
    self_distance,
    temp_c,
    speed,
    clock_ppm,
    detector,
    template,
    calibration,
    **kw,
):
    """Range every session found in files, folders and globs; one results file.

    INPUT... are recordings, folders (searched recursively) and globs (quote them:
    'archive/**/*.wav'). Sessions: a sidecar JSON with a "files" list groups its files
    (and gives the scheme, beep, self-distances and true distances); else NAME_dev0.wav,
    NAME_dev1.wav, ... in one folder are devices 0, 1, ... of session NAME; else each
    file is a session (rules in docs/batch.md). With --pair-by-name, INPUT... are one
    folder per device and files of the same name are paired (see the option).

    Writes one row per range (or one error row per failed session) to -o as sessions
    finish, the options to -o's FILE.meta.json; progress (done/total, rate, ETA) on
    stderr (-q: none; -v: also the scheme, detector and first failure). A bad file
    becomes an error row and the batch goes on. Exit 0: every session ranged; 8: some
    failed; 9: none ranged; 130: interrupted (rerun with --resume).

    \b
    Examples:
      rangekit batch recordings/ -o results.csv
      rangekit batch 'archive/**/*.wav' -o archive.jsonl --jobs 8 --self-distance 0.1
      rangekit batch recordings/ -o results.csv --resume
      rangekit batch recordings/ -o results.csv --scheduler tcp://10.0.0.5:8786
      rangekit batch logs/ --scheme echo --period 0.07 -o echo.csv
      rangekit batch --pair-by-name phone_a/ phone_b/ -o pairs.csv --self-distance 0.1
    """
    from rangekit_cli._options import detail, is_quiet

    from rangekit.batch import find_sessions, pair_sessions_by_name, run_batch

    if scheduler is not None and jobs is not None:
        raise click.UsageError("--jobs and --scheduler exclude each other")
    if scheduler is not None and not scheduler.strip():
        raise click.BadParameter("empty address", param_hint="--scheduler")
    if scheduler is not None:
        from rangekit.batch import check_scheduler_address

        check_scheduler_address(scheduler)  # before any output (exit 2)
    if pair_by_name and scheme != "beepbeep":
        raise click.UsageError("--pair-by-name applies to --scheme beepbeep only")
    if pair_by_name and len(inputs) < 2:
        raise click.UsageError(f"--pair-by-name needs at least 2 device folders, got {len(inputs)}")
    options = batch_options(
        scheme,
        pair_by_name,
        self_distance,
        temp_c,
        speed,
        clock_ppm,
        detector,
        template,
        calibration,
        kw,
    )
    if pair_by_name:
        sessions = pair_sessions_by_name(list(inputs))
    else:
        sessions = find_sessions(list(inputs))
    n_jobs = jobs if jobs is not None else (os.cpu_count() or 1)
    where = f"on {scheduler}" if scheduler else f"{n_jobs} job{'s' if n_jobs != 1 else ''}"
    from rangekit_cli._progress import CountProgress

    def on_start(done: int) -> None:  # done: sessions found in a resumed file
        click.echo(f"batch: {len(sessions)} sessions, {where} -> {output}", err=True)
        details(options, sessions, output)
        if done:
            click.echo(f"batch: {done} sessions already in {output}, skipped", err=True)

    quiet = is_quiet()
    progress = CountProgress("batch", unit="sessions", quiet=quiet, on_start=on_start)

    try:
        summary = run_batch(
            sessions,
            output,
            options,
            jobs=n_jobs,
            resume=resume,
            scheduler=scheduler,
            progress=progress,
        )
    except KeyboardInterrupt:
        progress.close()
        click.echo(
            f"rangekit: interrupted: {progress.last} of {len(sessions)} sessions are in "
            f"{output}; rerun with --resume to finish",
            err=True,
        )
        click.get_current_context().exit(130)
    progress.close()
    if not quiet:
        click.echo(
            f"batch: {summary.ok} of {summary.total} sessions ranged, {summary.failed} failed"
            + (f" ({summary.skipped} done before this run)" if summary.skipped else "")
            + f" -> {output}",
            err=True,
        )
    if summary.failed:
        if not quiet:
            detail(f"batch: first failed session: {summary.first_error}")
        click.get_current_context().exit(EXIT_ALL_FAILED if summary.ok == 0 else EXIT_SOME_FAILED)
