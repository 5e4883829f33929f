"""``rangekit range``: distances between devices from their recordings."""

from __future__ import annotations

import click
from rangekit_cli._options import (
    FiniteRange,
    beep_options,
    clock_ppm_option,
    debug_option,
    detail,
    detector_option,
    emit,
    float_list,
    format_option,
    is_verbose,
    make_beep,
    note,
    note_after,
    output_option,
    refuse_beep_options,
    self_distance_option,
    speed_of_sound_option,
    temperature_option,
    template_option,
    ultrasonic_kwargs,
    ultrasonic_options,
    verbosity_options,
    warn,
)

calibration_option = click.option(
    "--calibration",
    type=click.Path(dir_okay=False),
    default=None,
    metavar="CAL.json",
    help="Apply a calibration from `rangekit calibrate` (beepbeep, oneway): its offset "
    "replaces --self-distance (--latency for oneway), its fitted speed of sound, if any, "
    "replaces --temperature.",
)


@click.command("range")
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=True))
@click.option(
    "--scheme",
    type=click.Choice(["beepbeep", "oneway", "echo"]),
    default="beepbeep",
    show_default=True,
    help="beepbeep = two-way audible beeps, no clock sync; oneway = RF-synchronised "
    "ultrasonic beacons (sample 0 = trigger); echo = SRF02-style pulse-echo (sample 0 = ping).",
)
@self_distance_option(
    "Speaker-to-microphone distance in metres: one for all devices, or one per device."
)
@temperature_option
@speed_of_sound_option()
@clock_ppm_option("1-sigma sample-clock tolerance per device, ppm (widens sigma_m only).")
@detector_option
@template_option
@calibration_option
@beep_options
@ultrasonic_options
@click.option(
    "--series",
    is_flag=True,
    help="Long recordings: range block by block with bounded memory and print a time series "
    "(t_s first); CSV rows are written as they are produced.",
)
@click.option(
    "--block",
    "block_s",
    type=FiniteRange(0.001, 1e6),
    default=None,
    metavar="S",
    help="--series: block length in seconds [default: 2^21 samples over all channels].",
)
@click.option(
    "--exchange",
    "exchange_s",
    type=FiniteRange(0.001, 3600.0),
    default=None,
    metavar="S",
    help="--series beepbeep: longest time from device 0's beep to the last device's beep "
    "of one exchange [default: (N-1) x (beep duration + 0.5 s)].",
)
@click.option(
    "--skew",
    "skew_s",
    type=FiniteRange(0.0, 3600.0),
    default=None,
    metavar="S",
    help="--series beepbeep: allowance for the time of flight and for differing recording "
    "start times [default: 0.1].",
)
@click.option(
    "--clock-rate",
    "clock_rate",
    default=None,
    metavar="estimate|off|PPM[,PPM...]",
    help="--series beepbeep: correct the devices' sample-clock rates. estimate: from the "
    "spacing of the exchanges, relative to device 0 (reported on stderr; the rows then come "
    "at the end, after the whole recording); PPM,...: known rates, one per device (device 0 "
    "first) or one per device after device 0; off: no correction [default: off].",
)
@click.option(
    "--no-setup",
    "no_setup",
    is_flag=True,
    help="Do not read the setup (self-distances, temperature, period, latency, tx order) of "
    "a sidecar NAME.json beside the recordings that names exactly them, such as `rangekit "
    "synth` writes; options given always win over it.",
)
@click.option(
    "--jobs",
    type=click.IntRange(1, 256),
    default=None,
    metavar="N",
    help="With --series (beepbeep): N worker processes detect blocks in parallel; the "
    "rows are those of one job, in order (at most 256) [default: 1].",
)
@click.option(
    "--strict",
    is_flag=True,
    help="Never print a doubtful distance: a range flagged clipped, low_snr, "
    "ambiguous_first_path, inconsistent_bursts, poor_match, reverb_limited, negative or "
    "order is refused (exit 10). One beepbeep exchange: nothing is written. --series and "
    "oneway/echo rows: every row is written, doubtful ones with an empty distance and the "
    "flag 'withheld', then exit 10.",
)
@format_option
@output_option
@verbosity_options
@debug_option
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
    if not series:
        only = (("--block", block_s), ("--exchange", exchange_s), ("--skew", skew_s))
        for opt, v in (*only, ("--clock-rate", clock_rate), ("--jobs", jobs)):
            if v is not None:
                raise click.UsageError(f"{opt} applies to --series only")
    elif scheme != "beepbeep":
        only = (
            ("--exchange", exchange_s),
            ("--skew", skew_s),
            ("--clock-rate", clock_rate),
            ("--jobs", jobs),
        )
        for opt, v in only:
            if v is not None:
                raise click.UsageError(f"{opt} applies to --series with --scheme beepbeep only")
    if jobs is not None and jobs > 1 and any(f == "-" for f in files):
        raise click.UsageError(
            "--jobs N reads the recording in every worker: give a file, not - (standard input)"
        )
    series_opts = {"block_s": block_s} if series else None
    from rangekit_cli._options import load_template

    probe = load_template(template)
    cal = _read_calibration(calibration, scheme)
    if not no_setup:
        self_distance, temp_c = _apply_setup(files, scheme, self_distance, temp_c, speed, cal, kw)
    else:
        detail("rangekit: setup: not read (--no-setup)")
    _describe(scheme, detector, template, calibration, self_distance, temp_c, speed)
    if series and scheme != "beepbeep" and (probe is not None or cal is not None):
        raise click.UsageError(
            "--template and --calibration apply to --series with --scheme beepbeep only"
        )
    if (
        template is not None
        and click.get_current_context().get_parameter_source("detector")
        == click.core.ParameterSource.COMMANDLINE
    ):
        raise click.UsageError(
            "--detector applies to the built-in beep; --template uses the matched filter"
        )
    if scheme != "beepbeep":
        extra = {"probe": probe, "calibration": cal}
        _range_ultrasonic(
            files, scheme, temp_c, speed, fmt, output, kw, series_opts, extra, strict=strict
        )
        return
    from rangekit.io.results import format_ranges
    from rangekit.ranging import range_files

    _refuse_ultrasonic_options(kw)
    sd = float_list(self_distance, name="--self-distance", lo=0.0, hi=2.0)
    if cal is not None:
        _refuse_self_distance(sd)
    if probe is not None:
        refuse_beep_options(kw)
    beep = make_beep(kw)
    if series:
        from rangekit.physics import speed_of_sound_m_s
        from rangekit.ranging.series import DEFAULT_SKEW_S, range_series_beepbeep

        sink = SeriesSink("beepbeep", fmt, output, strict=strict)
        items = range_series_beepbeep(
            files,
            beep=beep,
            detector=detector,
            temp_c=temp_c,
            speed_m_s=speed,
            self_distance_m=sd[0] if len(sd) == 1 else sd,
            clock_ppm=clock_ppm,
            exchange_s=exchange_s,
            skew_s=DEFAULT_SKEW_S if skew_s is None else skew_s,
            block_s=block_s,
            progress=sink.progress,
            probe=probe,
            jobs=1 if jobs is None else jobs,
        )
        c = speed_of_sound_m_s(temp_c) if speed is None else speed
        meta = {
            "scheme": scheme,
            "series": True,
            "detector": detector,
            "files": [str(f) for f in files],
            "speed_of_sound_m_s": c,
        }
        if probe is not None:
            meta["detector"] = "template"
            meta["template"] = probe.name
        if clock_rate is not None:
            items = _clock_rate(sink, items, clock_rate, meta, c=c, sd=sd, clock_ppm=clock_ppm)
        if cal is not None:
            from dataclasses import replace

            meta["calibration"] = {"file": str(calibration), "model": cal.model}
            items = (replace(e, ranges=cal.apply_ranges(e.ranges, speed_m_s=c)) for e in items)
        sink.run(items, meta)
        return
    result = range_files(
        files,
        scheme=scheme,
        beep=beep,
        detector=detector,
        temp_c=temp_c,
        speed_m_s=speed,
        self_distance_m=sd[0] if len(sd) == 1 else sd,
        clock_ppm=clock_ppm,
        probe=probe,
        calibration=cal,
    )
    if strict:
        from rangekit.ranging.beepbeep import refuse_doubtful

        refuse_doubtful(result, what=", ".join(str(f) for f in files))
    meta = {
        "scheme": scheme,
        "detector": "template" if probe is not None else detector,
        "files": [str(f) for f in files],
    }
    if probe is not None:
        meta["template"] = probe.name
    if cal is not None:
        meta["calibration"] = {"file": str(calibration), "model": cal.model}
    emit(format_ranges(result, fmt, meta=meta), output)


def _clock_rate(sink, items, text: str, meta: dict, *, c, sd, clock_ppm):
    """``--clock-rate``: collect the series, estimate or take the rates, correct, report."""
    from rangekit.io.results import format_pm
    from rangekit.ranging.clock import correct_series_clock

    mode = text.strip().lower()
    if mode == "off":
        return items
    ppm = None if mode == "estimate" else float_list(text, name="--clock-rate", lo=-1e4, hi=1e4)
    explicit = click.get_current_context().get_parameter_source("clock_ppm")
    try:
        fixed, rates = correct_series_clock(
            items,
            speed_m_s=c,
            self_distance_m=sd[0] if len(sd) == 1 else sd,
            ppm=ppm,
            clock_ppm=clock_ppm if explicit == click.core.ParameterSource.COMMANDLINE else None,
        )
    finally:
        if sink._bar is not None:
            sink._bar.close()
    meta["clock_rate"] = {"mode": "estimate" if ppm is None else "given", **rates.as_dict()}
    if ppm is None:
        rej = f", {rates.n_rejected} rejected" if rates.n_rejected else ""
        for i in range(1, len(rates.ppm)):
            rate = format_pm(rates.ppm[i], rates.sigma_ppm[i], sign=True)
            note(
                f"rangekit: clock rate vs device 0: device {i} {rate} ppm "
                f"({rates.n_exchanges} exchanges over {rates.span_s:.1f} s{rej})"
            )
    return iter(fixed)


_ULTRASONIC_KEYS = (
    "latency",
    "period",
    "tx_order",
    "channels",
    "min_range",
    "max_range",
    "q",
    "code",
    "carrier",
    "cycles_per_bit",
)


def _describe(scheme, detector, template, calibration, self_distance, temp_c, speed) -> None:
    """--verbose: one stderr line with what the run uses."""
    if not is_verbose():
        return
    what = f"template '{template}'" if template is not None else f"detector {detector}"
    if scheme != "beepbeep" and template is None:
        what = "coded burst (--code)"
    air = f"speed of sound {speed:g} m/s" if speed is not None else f"temperature {temp_c:g} C"
    cal = f", calibration '{calibration}'" if calibration is not None else ""
    sd = f", self-distance {self_distance}" if scheme == "beepbeep" else ""
    detail(f"rangekit: range: scheme {scheme}, {what}, {air}{sd}{cal}")


def _refuse_ultrasonic_options(kw: dict) -> None:
    for k in _ULTRASONIC_KEYS:
        if kw.pop(k, None) is not None:
            opt = "--" + k.replace("_", "-")
            raise click.UsageError(f"{opt} applies to --scheme oneway and echo only")


def _apply_setup(files, scheme, self_distance, temp_c, speed, cal, kw):
    """Options not given, from the setup of a sidecar that names exactly ``files``
    (:func:`rangekit.io.setup.find_setup`); says on stderr what it took. Returns the
    self-distance and temperature to use; fills ``kw`` (period, latency, tx order)."""
    from rangekit.io.guard import is_stdin
    from rangekit.io.setup import find_setup

    if any(is_stdin(f) for f in files):
        detail("rangekit: setup: not searched for standard input (-)")
        ctx = click.get_current_context()
        default = ctx.get_parameter_source("self_distance") == click.core.ParameterSource.DEFAULT
        if scheme == "beepbeep" and cal is None and default:
            note_after(
                "rangekit: standard input: no sidecar setup is read for -, so the "
                "self-distance is 0 m (give --self-distance)"
            )
        return self_distance, temp_c
    setup = find_setup(files)
    if setup is None:
        detail("rangekit: setup: no sidecar beside the recordings names exactly them")
        return self_distance, temp_c
    if setup.scheme != scheme:
        detail(f"rangekit: setup: '{setup.path}' is for --scheme {setup.scheme}, not used")
        return self_distance, temp_c
    ctx = click.get_current_context()

    def unset(name: str) -> bool:
        return ctx.get_parameter_source(name) == click.core.ParameterSource.DEFAULT

    took = []
    if scheme == "beepbeep":
        if setup.self_distance_m is not None and unset("self_distance") and cal is None:
            self_distance = ",".join(repr(v) for v in setup.self_distance_m)
            took.append("--self-distance " + ",".join(f"{v:g}" for v in setup.self_distance_m))
    else:
        for key, value in (("period", setup.period_s), ("latency", setup.latency_s)):
            if (
                value is not None
                and kw.get(key) is None
                and (key == "period" or scheme == "oneway")
            ):
                kw[key] = value
                took.append(f"--{key} {value:g}")
        if setup.tx_order is not None and scheme == "oneway" and kw.get("tx_order") is None:
            kw["tx_order"] = ",".join(str(t) for t in setup.tx_order)
            took.append(f"--tx-order {kw['tx_order']}")
    if setup.temp_c is not None and unset("temp_c") and speed is None:
        temp_c = setup.temp_c
        took.append(f"--temperature {setup.temp_c:g}")
    if took:
        # Said after the results (an error stays one line): rangekit_cli.main prints notes.
        note_after(
            f"rangekit: used the setup in '{setup.path}': {' '.join(took)} (--no-setup to "
            "ignore it)"
        )
    return self_distance, temp_c


def _refuse_self_distance(sd) -> None:
    if any(v != 0 for v in sd):
        raise click.UsageError(
            "give --self-distance or --calibration, not both: the calibration's offset "
            "already holds the speaker-to-microphone distances"
        )


def _read_calibration(path, scheme: str):
    """The calibration of ``--calibration`` (None without it), checked against the scheme."""
    if path is None:
        return None
    from rangekit.ranging.calibration import read_calibration

    cal = read_calibration(path)
    if cal.scheme != scheme:
        raise click.UsageError(f"'{path}' is a calibration for --scheme {cal.scheme}, not {scheme}")
    return cal


def _range_ultrasonic(files, scheme, temp_c, speed, fmt, output, kw, series_opts, extra, *, strict):
    from rangekit.io.results import format_tof
    from rangekit.ranging.ultrasonic import range_ultrasonic_files

    any_channels = extra["probe"] is not None and kw.get("channels") is None
    args = ultrasonic_kwargs(kw, scheme=scheme, temp_c=temp_c, speed=speed)
    burst = args.pop("burst")
    channels = args.pop("channels")
    if any_channels:
        channels = None  # a lab's probe: any number of receivers unless --channels says
    if series_opts is not None:
        from rangekit.ranging.series import range_series_ultrasonic

        if len(files) != 1:
            raise click.UsageError(f"--series --scheme {scheme} takes one FILE, got {len(files)}")
        if args["period_s"] is None:
            raise click.UsageError(f"--series --scheme {scheme} needs --period")
        sink = SeriesSink(scheme, fmt, output, strict=strict)
        items = range_series_ultrasonic(
            files[0],
            scheme=scheme,
            channels=channels,
            burst=burst,
            progress=sink.progress,
            **series_opts,
            **args,
        )
        sink.run(items, {"scheme": scheme, "series": True, "files": [str(files[0])]})
        return
    from rangekit.io.audio import check_period

    check_period(files, args["period_s"])
    rows = range_ultrasonic_files(
        files, scheme=scheme, channels=channels, burst=burst, **extra, **args
    )
    meta = {"scheme": scheme, "files": [str(f) for f in files]}
    if extra["probe"] is not None:
        meta["template"] = extra["probe"].name
    withheld = _withhold(rows) if strict else []
    emit(format_tof(rows, fmt, scheme=scheme, meta=meta), output)
    _report_withheld(withheld, len(rows), files)


def _withhold(rows: list[dict]) -> list[dict]:
    """--strict on output rows: empty the doubtful ones' distances; return those rows."""
    from rangekit.ranging.beepbeep import withhold_doubtful

    return [r for r in rows if withhold_doubtful(r)]


def _report_withheld(withheld: list[dict], n_rows: int, files) -> None:
    """--strict: exit 10 naming the inputs, how many rows were withheld and the first one."""
    if not withheld:
        return
    from rangekit.errors import UnreliableResultError

    r = withheld[0]
    where = ", ".join(
        f"{k} {r[k]}" for k in ("t_s", "a", "b", "window", "tx", "channel") if r.get(k) is not None
    )
    flags = ",".join(f for f in r["flags"] if f != "withheld")
    raise UnreliableResultError(
        f"strict: {', '.join(str(f) for f in files)}: {len(withheld)} of {n_rows} ranges "
        f"withheld as doubtful (written with an empty distance, flag 'withheld'); first: "
        f"{where} flagged {flags}"
    )


#: Exit code of ``--series`` when stdout is closed early by its reader (128 + SIGPIPE).
EXIT_BROKEN_PIPE = 141


class SeriesSink:
    """Where ``--series`` output goes: CSV streamed, table and JSON collected.

    CSV rows are written as they are produced and flushed once per block, to stdout or
    to a temporary ``.FILE.part`` beside ``-o FILE`` that is renamed over FILE only when
    the series has finished (a failure never leaves a half file at FILE). Table and JSON
    are collected and written at the end (atomically with ``-o``). Progress goes to stderr
    (:class:`rangekit_cli._progress.Progress`), and at the end one line counts the
    exchanges (beepbeep) or rows (oneway/echo) without a detection.
    """

    def __init__(self, scheme: str, fmt: str, output: str | None, *, strict: bool = False) -> None:
        from rangekit.ranging.series import SERIES_FIELDS

        self.scheme = scheme
        self.strict = strict
        self.fmt = fmt
        self.output = output
        self.fields = SERIES_FIELDS[scheme]
        self._buf: list[str] = []
        self._file = None
        self._tmp = None
        self._bar = None
        self._header = False

    def progress(self, done_s: float, total_s: float) -> None:
        """Library progress callback: flush the block's CSV rows, advance the progress line."""
        from rangekit_cli._options import progress

        self.flush()
        if self._bar is None:
            self._bar = progress(total_s, "range --series", unit="s")
        self._bar.update(done_s - self._bar.done)

    def _open(self) -> None:
        if self.output is None or self._file is not None:
            return
        import tempfile
        from pathlib import Path

        from rangekit.errors import InputFileError
        from rangekit.io.guard import check_output

        p = check_output(self.output)
        try:  # exclusive, random name, in the target's folder (rangekit.io.guard)
            fd, self._tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".part", dir=p.parent)
            self._tmp = Path(self._tmp)
            self._file = open(fd, "w", encoding="utf-8", newline="")
        except OSError as e:
            raise InputFileError(f"cannot write '{p}': {e.strerror or e}") from e

    def flush(self) -> None:
        """Write the buffered CSV text (one block's rows) and flush it."""
        if not self._buf:
            return
        from rangekit.io.guard import printable

        text = printable("".join(self._buf))
        self._buf.clear()
        if self._file is None:
            try:
                click.echo(text, nl=False)  # click.echo flushes
            except BrokenPipeError:
                # The reader went away (`| head`): stop quietly, as SIGPIPE would (128 + 13).
                import os
                import sys

                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
                raise click.exceptions.Exit(EXIT_BROKEN_PIPE) from None
        else:
            try:
                self._file.write(text)
                self._file.flush()
            except OSError as e:  # a full disk: the .part file is removed by run()
                from rangekit.errors import InputFileError

                raise InputFileError(f"cannot write '{self.output}': {e.strerror or e}") from e

    def _csv(self, rows: list[dict]) -> None:
        from rangekit.io.results import format_rows

        text = format_rows(rows, self.fields, "csv")
        if self._header:
            text = text.split("\n", 1)[1]
        self._header = True
        self._buf.append(text)

    def run(self, items, meta: dict) -> None:
        """Consume the library's series; write the output; report on stderr."""
        import os

        from rangekit.io.results import format_rows

        collected: list[dict] = []
        withheld: list[dict] = []
        n_items = n_bad = n_rows = 0
        first_error = None
        ok = False
        try:
            if self.fmt == "csv":
                self._open()
            for item in items:
                if self.scheme == "beepbeep":
                    rows = item.rows()
                    n_items += 1
                    if item.error is not None:
                        n_bad += 1
                        first_error = first_error or item.error
                else:
                    rows = item.rows(scheme=self.scheme)
                    n_bad += sum(r["distance_m"] is None for r in rows)
                n_rows += len(rows)
                if self.strict:
                    withheld += _withhold(rows)
                if self.fmt == "csv":
                    self._csv(rows)
                else:
                    collected.extend(rows)
            if self.fmt == "csv":
                if not self._header:
                    self._csv([])
                self.flush()
            ok = True
        finally:
            if self._bar is not None:
                self._bar.close()
            if self._file is not None:
                try:
                    self._file.close()
                    if ok:
                        from rangekit.io.guard import default_mode

                        os.chmod(self._tmp, default_mode())
                        os.replace(self._tmp, self.output)
                except OSError as e:
                    ok = False
                    from rangekit.errors import InputFileError

                    raise InputFileError(f"cannot write '{self.output}': {e.strerror or e}") from e
                finally:
                    if not ok:
                        self._tmp.unlink(missing_ok=True)
        if self.fmt == "table":
            emit(format_rows(collected, self.fields, "table"), self.output)
        elif self.fmt == "json":
            emit(format_rows(collected, self.fields, "json", meta=meta, key="ranges"), self.output)
        if n_bad and self.scheme == "beepbeep":
            warn(
                f"rangekit: {n_bad} of {n_items} exchanges failed detection (empty distance, "
                f"flag 'detection'); first: {first_error}"
            )
        elif n_bad:
            warn(
                f"rangekit: {n_bad} of {n_rows} (window, channel) rows without a detection "
                "(empty distance: nothing in range)"
            )
        _report_withheld(withheld, n_rows, meta.get("files", ()))
