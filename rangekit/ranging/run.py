"""One library call per ranging job: what ``rangekit range`` does, without the CLI.

:func:`run_range` takes the recordings and the job's configuration objects
(:mod:`rangekit.ranging.config`) and returns a :class:`RangeRun`: its rows, block by block
(one exchange, or one window, at a time for a series), the metadata a results file records,
and, once iterated, the counts of failed detections and of rows withheld by ``strict``.
Clock-rate correction of a two-way series (:func:`~rangekit.ranging.clock.correct_series_clock`),
a calibration (:class:`~rangekit.ranging.calibration.Calibration`) and the strict
withholding (:func:`~rangekit.ranging.beepbeep.withhold_doubtful`) are options of the call.
Writing the rows is :class:`rangekit.io.stream.RowWriter`'s.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from rangekit.errors import InvalidParameterError, UnreliableResultError
from rangekit.ranging.beepbeep import refuse_doubtful, withhold_doubtful
from rangekit.ranging.calibration import Calibration
from rangekit.ranging.clock import ClockRates
from rangekit.ranging.config import EchoSetup, Medium, OneWaySetup, SeriesOptions, TwoWaySetup
from rangekit.signals.beep import Beep
from rangekit.signals.probe import Probe

__all__ = ["ClockRateCorrection", "RangeRun", "SeriesRows", "run_range"]

#: Progress callback of a series: (seconds done, seconds in total).
ProgressFn = Callable[[float, float], None]


@dataclass(frozen=True)
class ClockRateCorrection:
    """Sample-clock rate correction of a two-way series (``--clock-rate``).

    Parameters
    ----------
    ppm : sequence of float, optional
        Known rates (one per device, or one per device after device 0); None estimates
        them from the spacing of the exchanges, relative to device 0.
    tolerance_ppm : float, optional
        Remaining 1-sigma clock tolerance after the correction (None: the default of
        :func:`~rangekit.ranging.clock.correct_clock`).
    """

    ppm: tuple[float, ...] | None = None
    tolerance_ppm: float | None = None

    def __post_init__(self) -> None:
        if self.ppm is not None:
            object.__setattr__(self, "ppm", tuple(float(v) for v in self.ppm))


class SeriesRows:
    """The rows of a series' items (:class:`~rangekit.ranging.series.ExchangeRanges` or
    :class:`~rangekit.ranging.series.WindowRanges`), one list per item, counting as it
    goes the items (exchanges) and rows without a detection and, with ``strict``,
    withholding doubtful rows (:func:`~rangekit.ranging.beepbeep.withhold_doubtful`)."""

    def __init__(self, items: Iterable, *, scheme: str, strict: bool = False) -> None:
        self.items = items
        self.scheme = scheme
        self.strict = strict
        self.n_items = self.n_bad = self.n_rows = 0
        self.first_error: str | None = None
        self.withheld: list[dict] = []

    def __iter__(self) -> Iterator[list[dict]]:
        for item in self.items:
            if self.scheme == "beepbeep":
                rows = item.rows()
                self.n_items += 1
                if item.error is not None:
                    self.n_bad += 1
                    self.first_error = self.first_error or item.error
            else:
                rows = item.rows(scheme=self.scheme)
                self.n_bad += sum(r["distance_m"] is None for r in rows)
            self.n_rows += len(rows)
            if self.strict:
                self.withheld += [r for r in rows if withhold_doubtful(r)]
            yield rows

    def warnings(self) -> list[str]:
        """The caveats about the rows read so far (detections that failed), as lines."""
        if not self.n_bad:
            return []
        if self.scheme == "beepbeep":
            return [
                f"rangekit: {self.n_bad} of {self.n_items} exchanges failed detection (empty "
                f"distance, flag 'detection'); first: {self.first_error}"
            ]
        return [
            f"rangekit: {self.n_bad} of {self.n_rows} (window, channel) rows without a "
            "detection (empty distance: nothing in range)"
        ]


@dataclass
class RangeRun:
    """A ranging job (:func:`run_range`): iterate it for its rows, one list per block.

    Attributes
    ----------
    scheme : str
    series : bool
        Whether the rows come block by block from a series (iterate once; a two-way
        series with clock-rate correction is held in memory: its exchanges, not audio).
    fields : tuple of str
        The rows' keys, in column order.
    meta : dict
        What a results file records about the job (scheme, files, detector, speed of
        sound, template, calibration, clock rates once known).
    clock_rates : ClockRates or None
        The rates applied by the clock-rate correction, once the rows have been read.
    """

    scheme: str
    series: bool
    fields: tuple[str, ...]
    meta: dict
    files: tuple[str, ...]
    _blocks: Iterable[list[dict]] = field(repr=False)
    _rows: SeriesRows | None = field(default=None, repr=False)
    _withheld: list[dict] = field(default_factory=list, repr=False)
    _n_rows: int = 0
    clock_rates: ClockRates | None = None

    def __iter__(self) -> Iterator[list[dict]]:
        return iter(self._blocks)

    def rows(self) -> list[dict]:
        """Every row (reads the whole series)."""
        return [r for block in self for r in block]

    def warnings(self) -> list[str]:
        """Caveats about the rows read (a series' failed detections), as lines."""
        return [] if self._rows is None else self._rows.warnings()

    def finish(self) -> None:
        """After the rows are written: raise UnreliableResultError (exit 10) if ``strict``
        withheld any, naming the inputs, how many and the first one."""
        withheld, n_rows = self._withheld, self._n_rows
        if self._rows is not None:
            withheld, n_rows = self._rows.withheld, self._rows.n_rows
        if not withheld:
            return
        r = withheld[0]
        keys = ("t_s", "a", "b", "window", "tx", "channel")
        where = ", ".join(f"{k} {r[k]}" for k in keys if r.get(k) is not None)
        flags = ",".join(f for f in r["flags"] if f != "withheld")
        raise UnreliableResultError(
            f"strict: {', '.join(self.files)}: {len(withheld)} of {n_rows} ranges withheld "
            f"as doubtful (written with an empty distance, flag 'withheld'); first: {where} "
            f"flagged {flags}"
        )


def clock_rate_lines(rates: ClockRates) -> list[str]:
    """The estimated rates as report lines (device i vs device 0, value to its sigma)."""
    from rangekit.io.results import format_pm

    rej = f", {rates.n_rejected} rejected" if rates.n_rejected else ""
    return [
        f"rangekit: clock rate vs device 0: device {i} "
        f"{format_pm(rates.ppm[i], rates.sigma_ppm[i], sign=True)} ppm "
        f"({rates.n_exchanges} exchanges over {rates.span_s:.1f} s{rej})"
        for i in range(1, len(rates.ppm))
    ]


def run_range(
    files: Sequence[str | os.PathLike],
    *,
    scheme: str = "beepbeep",
    medium: Medium | None = None,
    setup: TwoWaySetup | None = None,
    series: SeriesOptions | None = None,
    beep: Beep | None = None,
    detector: str = "changepoint",
    probe: Probe | None = None,
    calibration: Calibration | None = None,
    calibration_file: str | os.PathLike | None = None,
    clock_rate: ClockRateCorrection | None = None,
    strict: bool = False,
    ultrasonic: OneWaySetup | EchoSetup | Mapping[str, Any] | None = None,
    progress: ProgressFn | None = None,
    report: Callable[[str], None] | None = None,
) -> RangeRun:
    """Range recordings: one call for every job of ``rangekit range``.

    Parameters
    ----------
    files : sequence of path
        Two-way: one multichannel WAV (channel i = device i) or one mono WAV per device;
        one-way / echo: each file on its own (one file with ``series``).
    scheme : {"beepbeep", "oneway", "echo"}
    medium : Medium, optional
        The air (default 20 C).
    setup : TwoWaySetup, optional
        Two-way self-distances and clock tolerance (default 0 m, 30 ppm).
    series : SeriesOptions, optional
        Range block by block with bounded memory (:mod:`rangekit.ranging.series`).
    beep, detector, probe
        What was played and how arrivals are found (:func:`rangekit.detect.detect`).
    calibration : Calibration, optional
        Applied to every range (two-way: its offset replaces the self-distances).
    calibration_file : path, optional
        Where the calibration was read from (recorded in ``meta``).
    clock_rate : ClockRateCorrection, optional
        Two-way series only: correct the devices' sample-clock rates.
    strict : bool
        Never a doubtful distance: one two-way exchange raises UnreliableResultError;
        series and one-way / echo rows are withheld (empty distance, flag ``withheld``)
        and :meth:`RangeRun.finish` raises after they are written.
    ultrasonic : OneWaySetup or EchoSetup, optional
        One-way / echo: the job's configuration (:mod:`rangekit.ranging.config`), of the
        scheme's type [default: ``OneWaySetup()`` or ``EchoSetup()``]; ``period_s``
        required with ``series``. A mapping of the keyword arguments of
        :func:`~rangekit.ranging.ultrasonic.range_ultrasonic_files` (other than
        ``scheme``, ``probe``, ``calibration``, ``temp_c``, ``speed_m_s``) is accepted too.
    progress : callable, optional
        ``progress(done_s, total_s)`` once per block of a series.
    report : callable, optional
        Called with each report line (the estimated clock rates) when known.

    Returns
    -------
    RangeRun
        Its rows are computed as it is iterated (a series) or already (one exchange or
        a set of one-way / echo files).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from rangekit.io import write_audio
    >>> from rangekit.sim import pair_devices, render_beepbeep
    >>> sim = render_beepbeep(pair_devices(2.0, self_distance_m=0.1), rng=1)
    >>> paths = [pathlib.Path(tempfile.mkdtemp()) / f"dev{i}.wav" for i in range(2)]
    >>> for p, x, fs in zip(paths, sim.recordings, sim.fs):
    ...     write_audio(p, x, fs=fs)
    >>> job = run_range(paths, setup=TwoWaySetup(self_distance_m=0.1))
    >>> [(r["a"], r["b"], round(r["distance_m"], 2)) for r in job.rows()]
    [(0, 1, 2.0)]
    """
    medium = Medium() if medium is None else medium
    setup = TwoWaySetup() if setup is None else setup
    names = tuple(str(f) for f in files)
    meta: dict = {"scheme": scheme}
    cal_meta = None
    if calibration is not None:
        cal_meta = {"file": None if calibration_file is None else str(calibration_file),
                    "model": calibration.model}  # fmt: skip
    if scheme == "beepbeep":
        return _two_way(
            files, names, meta, medium=medium, setup=setup, series=series, beep=beep,
            detector=detector, probe=probe, calibration=calibration, cal_meta=cal_meta,
            clock_rate=clock_rate, strict=strict, progress=progress, report=report,
        )  # fmt: skip
    if scheme not in ("oneway", "echo"):
        raise InvalidParameterError(f"scheme={scheme!r} must be beepbeep, oneway or echo")
    if clock_rate is not None:
        raise InvalidParameterError("clock_rate applies to a two-way (beepbeep) series only")
    from rangekit.io.results import tof_fields
    from rangekit.ranging.series import SERIES_FIELDS

    args = {**_ultrasonic_kwargs(scheme, ultrasonic), **medium.kwargs()}
    if series is not None:
        from rangekit.ranging.series import range_series_ultrasonic

        if probe is not None or calibration is not None:
            raise InvalidParameterError(
                "probe and calibration apply to a two-way (beepbeep) series only"
            )
        if len(files) != 1:
            raise InvalidParameterError(f"a {scheme} series takes one file, got {len(files)}")
        if args.get("period_s") is None:
            raise InvalidParameterError(f"a {scheme} series needs period_s")
        items = range_series_ultrasonic(
            files[0], scheme=scheme, block_s=series.block_s, progress=progress, **args
        )
        rows = SeriesRows(items, scheme=scheme, strict=strict)
        meta.update(series=True, files=[names[0]])
        return RangeRun(scheme, True, SERIES_FIELDS[scheme], meta, names[:1], rows, rows)
    from rangekit.io.audio import check_period
    from rangekit.ranging.ultrasonic import range_ultrasonic_files

    check_period(files, args.get("period_s"))
    out = range_ultrasonic_files(files, scheme=scheme, probe=probe, calibration=calibration, **args)
    meta["files"] = list(names)
    if probe is not None:
        meta["template"] = probe.name
    withheld = [r for r in out if withhold_doubtful(r)] if strict else []
    fields = tuple(tof_fields(scheme))
    return RangeRun(scheme, False, fields, meta, names, [out], None, withheld, len(out))


def _ultrasonic_kwargs(scheme: str, cfg) -> dict:
    """The keywords of ``range_ultrasonic_files`` from the scheme's configuration."""
    kind = OneWaySetup if scheme == "oneway" else EchoSetup
    if cfg is None:
        cfg = kind()
    if isinstance(cfg, (OneWaySetup, EchoSetup)):
        if not isinstance(cfg, kind):
            raise InvalidParameterError(
                f"ultrasonic={type(cfg).__name__}(...) does not describe scheme={scheme!r}: "
                f"give a {kind.__name__}"
            )
        return cfg.kwargs()
    return dict(cfg)


def _two_way(files, names, meta, *, medium, setup, series, beep, detector, probe, calibration,
             cal_meta, clock_rate, strict, progress, report) -> RangeRun:  # fmt: skip
    from rangekit.io.results import RANGE_FIELDS
    from rangekit.ranging.series import SERIES_FIELDS

    if series is None:
        from rangekit.ranging.pipeline import range_files

        if clock_rate is not None:
            raise InvalidParameterError("clock_rate applies to a two-way series only")
        result = range_files(
            files, beep=beep, detector=detector, probe=probe, calibration=calibration,
            medium=medium, setup=setup,
        )  # fmt: skip
        if strict:
            refuse_doubtful(result, what=", ".join(names))
        meta.update(detector="template" if probe is not None else detector, files=list(names))
        if probe is not None:
            meta["template"] = probe.name
        if calibration is not None:
            meta["calibration"] = cal_meta
        meta["speed_of_sound_m_s"] = result.speed_m_s
        rows = [r.as_dict() for r in result.ranges]
        return RangeRun("beepbeep", False, RANGE_FIELDS, meta, names, [rows])
    from rangekit.ranging.series import range_series_beepbeep

    items = range_series_beepbeep(
        files, beep=beep, detector=detector, **medium.kwargs(), **setup.kwargs(),
        exchange_s=series.exchange_s, skew_s=series.skew_s, block_s=series.block_s,
        progress=progress, probe=probe, jobs=series.jobs,
    )  # fmt: skip
    c = medium.c
    meta.update(series=True, detector=detector, files=list(names), speed_of_sound_m_s=c)
    if probe is not None:
        meta["detector"] = "template"
        meta["template"] = probe.name
    run = RangeRun("beepbeep", True, SERIES_FIELDS["beepbeep"], meta, names, ())
    if clock_rate is not None:
        meta["clock_rate"] = {"mode": "estimate" if clock_rate.ppm is None else "given"}
        items = _corrected(items, run, clock_rate, setup, c, report)
    if calibration is not None:
        meta["calibration"] = cal_meta
        items = (replace(e, ranges=calibration.apply_ranges(e.ranges, speed_m_s=c)) for e in items)
    run._rows = run._blocks = SeriesRows(items, scheme="beepbeep", strict=strict)
    return run


def _corrected(items, run: RangeRun, clock_rate, setup, c, report):
    """The clock-rate corrected exchanges (all read before the first is yielded)."""
    from rangekit.ranging.clock import correct_series_clock

    fixed, rates = correct_series_clock(
        items, speed_m_s=c, self_distance_m=setup.kwargs()["self_distance_m"],
        ppm=clock_rate.ppm, clock_ppm=clock_rate.tolerance_ppm,
    )  # fmt: skip
    run.clock_rates = rates
    run.meta["clock_rate"].update(rates.as_dict())
    if clock_rate.ppm is None and report is not None:
        for line in clock_rate_lines(rates):
            report(line)
    yield from fixed
