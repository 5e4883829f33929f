"""A small progress reporter for long commands, on stderr.

On a terminal it keeps one line up to date in place (``\\r``), at most every 0.2 s, and
ends it with a newline on :meth:`Progress.close`. Elsewhere (a log file, a pipe, a test)
it writes a plain line every 30 s; a run shorter than that prints nothing at all, so
short commands keep a clean stderr.

A line reads ``range: 42.0% (1260/3000 s), 85.1 s/s, ETA 0:20``: label, share done,
done/total with the unit, rate (units per second of wall time) and the estimated time
left; the last line says ``done in M:SS`` instead of the ETA.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from typing import TextIO

__all__ = ["CountProgress", "Progress"]


def _num(v: float) -> str:
    return f"{v:.0f}" if v >= 100 or float(v).is_integer() else f"{v:.1f}"


def _hms(seconds: float) -> str:
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class Progress:
    """Done/total, rate and ETA of a long job, written to stderr now and then.

    Parameters
    ----------
    total : float
        Amount of work (e.g. seconds of audio, files).
    label : str
        Name of the job, first on the line.
    unit : str
        Unit of ``total`` (``"s"``, ``"files"``); empty for plain counts.
    stream : text file, optional
        Where to write (default ``sys.stderr`` at the time of writing).
    tty : bool, optional
        Rewrite one line in place (default: whether ``stream`` is a terminal).
    interval_s : float, optional
        Least wall time between two lines (default 0.2 s on a terminal, 30 s otherwise).
    clock : callable
        Wall clock in seconds (``time.monotonic``; tests pass a fake one).

    Examples
    --------
    >>> import io
    >>> t = iter([0.0, 40.0, 50.0, 80.0])  # wall clock at start, updates, close
    >>> out = io.StringIO()
    >>> p = Progress(100, "range", unit="s", stream=out, tty=False, clock=lambda: next(t))
    >>> p.update(50)
    >>> p.update(50)
    >>> p.close()
    >>> print(out.getvalue(), end="")
    range: 50.0% (50/100 s), 1.25 s/s, ETA 0:40
    range: 100.0% (100/100 s), 1.25 s/s, done in 1:20
    """

    def __init__(
        self,
        total: float,
        label: str,
        *,
        unit: str = "",
        stream: TextIO | None = None,
        tty: bool | None = None,
        interval_s: float | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.total = max(0.0, float(total))
        self.done = 0.0
        self.label = label
        self.unit = unit
        self._stream = stream
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)()) if tty is None else tty
        self.interval_s = (0.2 if self.tty else 30.0) if interval_s is None else interval_s
        self._clock = clock
        self._t0 = clock()
        self._last = self._t0
        self._width = 0
        self.printed = False
        self.closed = False

    @property
    def stream(self) -> TextIO:
        return sys.stderr if self._stream is None else self._stream

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def text(self, now: float, *, final: bool = False) -> str:
        """The progress line at wall time ``now``."""
        elapsed = max(0.0, now - self._t0)
        pct = 100.0 * self.done / self.total if self.total > 0 else 100.0
        unit = f" {self.unit}" if self.unit else ""
        rate = self.done / elapsed if elapsed > 0 else math.nan
        if not math.isfinite(rate):
            rate_txt = "-"
        else:
            rate_txt = (f"{rate:.0f}" if rate >= 100 else f"{rate:.3g}") + f"{unit}/s"
        if final:
            tail = f"done in {_hms(elapsed)}"
        elif math.isfinite(rate) and rate > 0:
            tail = f"ETA {_hms(max(0.0, self.total - self.done) / rate)}"
        else:
            tail = "ETA -"
        return (
            f"{self.label}: {pct:.1f}% ({_num(self.done)}/{_num(self.total)}{unit}), "
            f"{rate_txt}, {tail}"
        )

    def _write(self, line: str) -> None:
        s = self.stream
        if self.tty:
            pad = " " * max(0, self._width - len(line))
            s.write("\r" + line + pad)
            self._width = len(line)
        else:
            s.write(line + "\n")
        s.flush()
        self.printed = True

    def update(self, n: float = 1.0) -> None:
        """Add ``n`` to the work done; write a line if ``interval_s`` has passed."""
        if self.closed:
            return
        self.done = min(self.total, self.done + float(n)) if self.total > 0 else self.done + n
        now = self._clock()
        if now - self._last >= self.interval_s:
            self._last = now
            self._write(self.text(now))

    def report(self, done: float, total: float) -> None:
        """A library progress callback ``progress(done, total)`` (e.g.
        :data:`rangekit.experiments.report.ProgressCallback`): sets the total, moves to
        ``done``.

        >>> import io
        >>> t = iter([0.0, 10.0, 20.0])
        >>> out = io.StringIO()
        >>> p = Progress(0, "kim2013", unit="runs", stream=out, tty=False, interval_s=5,
        ...              clock=lambda: next(t))
        >>> p.report(1, 4)
        >>> print(out.getvalue(), end="")
        kim2013: 25.0% (1/4 runs), 0.1 runs/s, ETA 0:30
        """
        self.total = max(0.0, float(total))
        self.update(float(done) - self.done)

    def close(self) -> None:
        """Write the final line (only if a line was written before) and end it."""
        if self.closed:
            return
        self.closed = True
        if self.printed:
            self._write(self.text(self._clock(), final=True))
            if self.tty:
                self.stream.write("\n")
                self.stream.flush()


class CountProgress:
    """A library's ``progress(done, total)`` callback shown as a :class:`Progress`.

    The bar starts at the first call, after ``on_start(done)`` (which may print a
    header: ``done`` is the work found finished before this run, e.g. a resumed
    file), and counts only the work done after it. With ``quiet`` nothing is shown;
    ``last`` still counts, for an interrupt message.

    Examples
    --------
    >>> import io
    >>> out = io.StringIO()
    >>> p = CountProgress("batch", unit="sessions", stream=out)
    >>> for done in (2, 3, 5):
    ...     p(done, 5)
    >>> p.last, p.bar.total
    (5, 3.0)
    """

    def __init__(
        self,
        label: str,
        *,
        unit: str = "",
        quiet: bool = False,
        on_start: Callable[[int], None] | None = None,
        stream: TextIO | None = None,
    ) -> None:
        self.label, self.unit, self.quiet = label, unit, quiet
        self.on_start, self.stream = on_start, stream
        self.bar: Progress | None = None
        self.last = 0

    def __call__(self, done: int, total: int) -> None:
        if self.quiet:
            self.last = done
            return
        if self.bar is None:
            if self.on_start is not None:
                self.on_start(done)
            self.bar = Progress(total - done, self.label, unit=self.unit, stream=self.stream)
            self.last = done
        if done > self.last:
            self.bar.update(done - self.last)
            self.last = done

    def close(self) -> None:
        """End the bar's line, if one was started."""
        if self.bar is not None:
            self.bar.close()
