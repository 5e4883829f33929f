"""``rangekit range``: distances between devices from their recordings.

Parses the options into the library's configuration objects (:mod:`rangekit_cli.range_options`,
:mod:`rangekit.ranging.config`), calls :func:`rangekit.ranging.run.run_range` and writes
its rows with :class:`rangekit.io.stream.RowWriter`.
"""

from __future__ import annotations

import click
from rangekit_cli._options import (
    detail,
    float_list,
    load_template,
    make_beep,
    note,
    progress,
    read_calibration,
    refuse_beep_options,
    refuse_self_distance,
    warn,
)
from rangekit_cli.range_options import (
    check_series_options,
    check_template_options,
    range_options,
)
from rangekit_cli.range_setup import apply_setup
from rangekit_cli.ultrasonic_options import refuse_ultrasonic_options, ultrasonic_setup

from rangekit.io.stream import RowWriter

__all__ = ["EXIT_BROKEN_PIPE", "range_cmd"]

#: Exit code when stdout is closed early by its reader (128 + SIGPIPE).
EXIT_BROKEN_PIPE = 141


@click.command("range")
@range_options
def range_cmd(
    files,
    scheme,
    self_distance,
    temp_c,
    speed,
    clock_ppm,
    detector,
    template,
    calibration,
    series,
    block_s,
    exchange_s,
    skew_s,
    clock_rate,
    no_setup,
    jobs,
    strict,
    fmt,
    output,
    **kw,
):
    """Distances from recordings: two-way beeps, one-way beacons or pulse-echo.

    A FILE of - is standard input (one per command; no sidecar setup is read for it).

    beepbeep: FILE... is one WAV with one channel per device (channel i = device i), or
    one mono WAV per device (file i = device i). Devices played in index order (device 0
    first). Prints every pair's distance with its 1-sigma uncertainty.

    oneway / echo: each FILE is ranged on its own; each channel is a receiver (oneway) or
    a sensor (echo); sample 0 is the RF trigger (oneway) or the ping (echo). With
    --period the file holds consecutive activation windows (cycles). Prints one row per
    (file, window, channel); an empty distance means nothing in range.

    --series: a recording of any length is ranged block by block (memory bounded by
    --block): beepbeep exchanges repeating every few seconds give one row per exchange
    and pair (t_s, a, b, distance_m, sigma_m, flags); oneway/echo (one FILE, --period
    required) one row per window and channel, t_s first. An exchange whose beeps are not
    all found gives an empty distance flagged 'detection' and the series goes on. Use
    --format csv for huge files (table and json are collected in memory).

    \b
    Examples:
      rangekit range exchange.wav --self-distance 0.1
      rangekit range phone0.wav phone1.wav phone2.wav --format json
      rangekit range exchange.wav --self-distance 0.1 --strict
      rangekit range --scheme oneway beacons.wav --period 0.2 --tx-order 0,1,2,3,4,5
      rangekit range --scheme echo srf02.wav --period 0.07 --format json
      rangekit range --series phone_log.wav --self-distance 0.1 --format csv -o ranges.csv
      rangekit range --series phone_log.wav --self-distance 0.1 --jobs 2 --format csv
      rangekit range --series --scheme echo srf02_log.wav --period 0.07 --format csv
    """
    given = {"block_s": block_s, "exchange_s": exchange_s, "skew_s": skew_s, "jobs": jobs}
    check_series_options(
        files, scheme=scheme, series=series, kw={**given, "clock_rate": clock_rate}
    )
    probe = load_template(template)
    cal = read_calibration(calibration, scheme)
    if not no_setup:
        self_distance, temp_c = apply_setup(files, scheme, self_distance, temp_c, speed, cal, kw)
    else:
        detail("rangekit: setup: not read (--no-setup)")
    check_template_options(scheme=scheme, series=series, template=template, calibration=cal)
    from rangekit.ranging.config import Medium, SeriesOptions

    job = {"scheme": scheme, "medium": Medium(temp_c=temp_c, speed_m_s=speed), "strict": strict}
    job.update(probe=probe, calibration=cal, calibration_file=calibration)
    if series:
        job["series"] = SeriesOptions(**{k: v for k, v in given.items() if v is not None})
    if scheme == "beepbeep":
        job.update(_two_way(self_distance, clock_ppm, detector, clock_rate, cal, probe, kw))
    else:
        job["ultrasonic"] = _ultrasonic(files, scheme, series, probe, kw)
    _describe(job, template)
    _run(files, job, fmt, output)


def _describe(job: dict, template: str | None) -> None:
    """--verbose: what the run uses, as the library says it (rangekit.io.notes.range_detail)."""
    from rangekit.io.notes import range_detail

    detail("rangekit: range: " + range_detail(
        job["scheme"], medium=job["medium"], detector=job.get("detector"), template=template,
        calibration=job["calibration_file"], setup=job.get("setup"),
    ))  # fmt: skip


def _two_way(self_distance, clock_ppm, detector, clock_rate, cal, probe, kw) -> dict:
    """run_range's two-way arguments from the options."""
    from rangekit.ranging.config import TwoWaySetup, as_self_distance
    from rangekit.ranging.run import ClockRateCorrection

    refuse_ultrasonic_options(kw)
    sd = float_list(self_distance, name="--self-distance", lo=0.0, hi=2.0)
    if cal is not None:
        refuse_self_distance(sd)
    if probe is not None:
        refuse_beep_options(kw)
    out = {"beep": make_beep(kw), "detector": detector}
    sd_kw = {} if sd is None else {"self_distance_m": as_self_distance(sd)}  # else the default
    out["setup"] = TwoWaySetup(**sd_kw, clock_ppm=clock_ppm)
    mode = None if clock_rate is None else clock_rate.strip().lower()
    if mode not in (None, "off"):
        ppm = (
            None
            if mode == "estimate"
            else float_list(clock_rate, name="--clock-rate", lo=-1e4, hi=1e4)
        )
        src = click.get_current_context().get_parameter_source("clock_ppm")
        tol = clock_ppm if src == click.core.ParameterSource.COMMANDLINE else None
        out["clock_rate"] = ClockRateCorrection(ppm=ppm, tolerance_ppm=tol)
    return out


def _ultrasonic(files, scheme, series, probe, kw):
    """run_range's one-way / echo configuration object from the options."""
    # a lab's probe: any number of receivers
    setup = ultrasonic_setup(kw, scheme=scheme, any_receivers=probe is not None)
    if series and len(files) != 1:
        raise click.UsageError(f"--series --scheme {scheme} takes one FILE, got {len(files)}")
    if series and setup.period_s is None:
        raise click.UsageError(f"--series --scheme {scheme} needs --period")
    return setup


def _bar(total_s: float):
    return progress(total_s, "range --series", unit="s")


def _run(files, job: dict, fmt: str, output: str | None) -> None:
    """Call the library, write its rows, report on stderr."""
    from rangekit.ranging.run import run_range

    writer: RowWriter | None = None  # made once the run knows its columns

    def on_progress(done_s: float, total_s: float) -> None:  # called while rows are written
        writer.progress(done_s, total_s)

    def on_report(line: str) -> None:
        writer.close_progress()
        note(line)

    if job.get("series") is not None:
        job.update(progress=on_progress, report=on_report)
    run = run_range(files, **job)
    writer = RowWriter(run.fields, fmt, output, bar=_bar)
    _write(run, writer)


def _write(run, writer: RowWriter) -> None:
    try:
        writer.write(run, run.meta)
    except BrokenPipeError:  # the reader went away (`| head`): stop quietly, as SIGPIPE would
        raise click.exceptions.Exit(EXIT_BROKEN_PIPE) from None
    for line in run.warnings():
        warn(line)
    run.finish()
