"""One library call per detection job: what ``rangekit detect`` does, without the CLI.

:func:`detect_files` reads every recording, detects ``signal`` in every channel through
the front end :func:`rangekit.detect.detect` and returns a :class:`DetectRun`: the
arrival rows (:func:`rangekit.io.results.arrivals_rows`), the channels that held no
arrival, and the metadata a results file records. :meth:`DetectRun.format` is the text
the command prints; :meth:`DetectRun.finish` raises the error it exits with (6) when a
channel held nothing.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

from rangekit.errors import DetectionError
from rangekit.signals import Signal, signal_kind

__all__ = ["DetectRun", "detect_files"]


@dataclass(frozen=True)
class DetectRun:
    """A detection job (:func:`detect_files`).

    Attributes
    ----------
    rows : tuple of dict
        One per arrival, file by file, channel by channel, in time order (the fields of
        :data:`rangekit.io.results.ARRIVAL_FIELDS`).
    empty : tuple of str
        The channels without an arrival, as ``FILE#CHANNEL``.
    meta : dict
        ``detector`` (the method used), ``template`` (a probe's name, i.e. its file) and
        ``expected`` when given: the JSON output's header keys.
    missing : str
        What was not found, for the error: ``no beep`` or ``no arrival of 'NAME'``.
    """

    rows: tuple[dict, ...]
    empty: tuple[str, ...]
    meta: dict
    missing: str

    def format(self, fmt: str) -> str:
        """The rows as ``rangekit detect --format fmt`` prints them (table, json or csv)."""
        from rangekit.io.results import format_arrivals

        return format_arrivals(list(self.rows), fmt, meta=self.meta)

    def finish(self) -> None:
        """Raise DetectionError (exit 6) naming every channel without an arrival, if any."""
        if self.empty:
            raise DetectionError(f"{self.missing} found in {', '.join(self.empty)}")


def detect_files(
    files: Sequence[str | os.PathLike],
    *,
    signal: Signal | None = None,
    method: str | None = None,
    expected: int | None = None,
    min_separation_s: float | None = None,
    weighting: str | None = None,
) -> DetectRun:
    """Arrivals of ``signal`` in every channel of every file (``rangekit detect``).

    Parameters
    ----------
    files : sequence of path
        Recordings, any number of channels each; ``-`` is standard input.
    signal : Beep, CodedBurst or Probe, optional
        What was played (default: the rangekit beep).
    method : str, optional
        One of ``rangekit.detect.METHODS[signal.kind]`` (default the first).
    expected : int, optional
        Emissions per channel: at most this many arrivals, the best supported.
    min_separation_s, weighting : optional
        Options of the ``template`` method (:func:`rangekit.detect.template.detect_template`);
        None keeps its defaults.

    Returns
    -------
    DetectRun
        The rows, the channels without an arrival and the metadata; nothing is raised
        for an empty channel until :meth:`DetectRun.finish`.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import numpy as np
    >>> from rangekit.io import write_audio
    >>> from rangekit.signals import Beep
    >>> fs = 44100.0
    >>> beep = Beep().samples_at(fs)
    >>> x = 1e-3 * np.random.default_rng(1).standard_normal((2 * int(fs), 2))
    >>> x[10000 : 10000 + len(beep), 0] = 0.5 * beep
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "one.wav"
    >>> write_audio(path, x, fs=fs)
    >>> run = detect_files([path])
    >>> [(r["channel"], round(r["onset_sample"])) for r in run.rows], run.empty[0][-2:]
    ([(0, 10000)], '#1')
    >>> run.finish()  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    rangekit.errors.DetectionError: no beep found in ...one.wav#1
    """
    from rangekit.detect import detect, method_for
    from rangekit.io.audio import read_audio
    from rangekit.io.results import arrivals_rows
    from rangekit.signals.beep import Beep

    signal = Beep() if signal is None else signal
    kind = signal_kind(signal)
    method = method_for(signal, method)
    kw: dict = {}
    if min_separation_s is not None:
        kw["min_separation_s"] = min_separation_s
    if weighting is not None:
        kw["weighting"] = weighting
    rows: list[dict] = []
    empty: list[str] = []
    for f in files:
        x, fs = read_audio(f)
        for ch in range(x.shape[1]):
            arr = detect(
                x[:, ch], fs=fs, signal=signal, method=method, expected=expected,
                what=f"'{f}'", **kw,
            )  # fmt: skip
            if len(arr) == 0:
                empty.append(f"{f}#{ch}")
            rows += arrivals_rows(arr, file=str(f), channel=ch)
    meta: dict = {"detector": method}
    if kind == "probe":
        meta["template"] = signal.name
    if expected is not None:
        meta["expected"] = expected
    missing = "no beep" if kind == "beep" else f"no arrival of '{getattr(signal, 'name', kind)}'"
    return DetectRun(tuple(rows), tuple(empty), meta, missing)
