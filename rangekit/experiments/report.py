"""The result of a paper experiment: rows of (metric, condition, paper, measured).

Every ``rangekit experiment NAME`` returns an :class:`ExperimentReport`. Its JSON form is
an object with ``experiment``, ``title``, ``params`` and ``rows``; each row has at least
``metric``, ``condition``, ``paper`` (the paper's number, or null where the paper gives
none) and ``measured`` (see ``docs/formats.md``), and ``unit``, ``note`` and ``oracle``.

Oracle rows
-----------
A row is an *oracle* row when the estimator behind it was given part of the simulator's
truth that a user would not have (a true start position, a true anchor, a true device
geometry). Its ``oracle`` is a short description of that truth (``"true start
position"``), and its metric name says so: it ends with ``(oracle ...)``
(:meth:`ExperimentReport.add` refuses an oracle row whose metric does not). Every other
row has ``"oracle": null``. Evaluating an estimate against the truth (an error, a
coverage) does not make a row an oracle row; feeding the truth to the estimator does.

Examples
--------
>>> rep = ExperimentReport("demo", "A demo", {"trials": 2, "seed": 1})
>>> rep.add("median error", "target 2, 0.4 m/s", 0.85, 0.5312, unit="m")
>>> rep.add("NEES", "target 2, 0.4 m/s", None, 3.9)
>>> rep.add("median error (oracle start)", "target 2, 0.4 m/s", None, 0.41, unit="m",
...         oracle="true start position")
>>> rep.to_json()["rows"][0]["paper"], rep.to_json()["rows"][0]["oracle"]
(0.85, None)
>>> [r.metric for r in rep.oracle_rows()]
['median error (oracle start)']
>>> print(rep.to_table())
# A demo (trials=2, seed=1)
metric                       condition          paper  measured  unit
median error                 target 2, 0.4 m/s  0.85   0.5312    m
NEES                         target 2, 0.4 m/s  -      3.9
median error (oracle start)  target 2, 0.4 m/s  -      0.41      m
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TypeVar

__all__ = ["ExperimentReport", "ExperimentRow", "ProgressCallback", "Ticker"]

#: ``progress(done, total)``: called by an experiment's ``run`` after each unit of its
#: work (a trial of one condition, a timing run); ``total`` is fixed for the run. The
#: library never prints: ``rangekit experiment`` turns the calls into a progress bar.
ProgressCallback = Callable[[int, int], None]

_T = TypeVar("_T")


@dataclass(frozen=True)
class ExperimentRow:
    """One number of a paper's table beside the number rangekit measured.

    Attributes
    ----------
    metric : str
        What is measured (``"median error"``, ``"E_p RMS"``...).
    condition : str
        The experimental condition (``"moderate noise, 0.4 m/s, target 2"``).
    paper : float or None
        The paper's number, None where the paper gives none.
    measured : float
        rangekit's number (NaN if it could not be measured).
    unit : str
        Unit of both numbers ("" for dimensionless).
    note : str
        Anything a reader needs to compare the two (how the paper's number was read).
    oracle : str
        The simulator truth the estimator was given ("" if none; module docstring). An
        oracle row's metric ends with ``(oracle ...)``.
    """

    metric: str
    condition: str
    paper: float | None
    measured: float
    unit: str = ""
    note: str = ""
    oracle: str = ""

    def to_json(self) -> dict:
        m = float(self.measured)
        return {
            "metric": self.metric,
            "condition": self.condition,
            "paper": None if self.paper is None else float(self.paper),
            "measured": None if math.isnan(m) else m,
            "unit": self.unit,
            "note": self.note,
            "oracle": self.oracle or None,
        }


def _num(v: float | None) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    return f"{v:.4g}"


@dataclass
class ExperimentReport:
    """The rows of one experiment run, with its parameters.

    Attributes
    ----------
    experiment : str
        The experiment's name (``"jiang2018"``).
    title : str
        One line saying what it reproduces.
    params : dict
        Trials, seed and other settings of the run (JSON-serialisable).
    rows : list of ExperimentRow
    """

    experiment: str
    title: str
    params: dict = field(default_factory=dict)
    rows: list[ExperimentRow] = field(default_factory=list)

    def add(
        self,
        metric: str,
        condition: str,
        paper: float | None,
        measured: float,
        *,
        unit: str = "",
        note: str = "",
        oracle: str = "",
    ) -> None:
        """Append one :class:`ExperimentRow`.

        Raises
        ------
        ValueError
            ``oracle`` is given but the metric does not end with ``(oracle ...)``, or the
            metric says oracle and ``oracle`` is empty.
        """
        named = metric.rstrip().endswith(")") and "(oracle" in metric
        if bool(oracle) != named:
            raise ValueError(
                f"metric={metric!r}, oracle={oracle!r}: an oracle row's metric ends with "
                "'(oracle ...)', and only an oracle row's does"
            )
        self.rows.append(
            ExperimentRow(metric, condition, paper, float(measured), unit, note, oracle)
        )

    def oracle_rows(self) -> list[ExperimentRow]:
        """The rows whose estimator was given simulator truth (module docstring)."""
        return [r for r in self.rows if r.oracle]

    def find(self, metric: str, condition: str) -> ExperimentRow:
        """The row with this metric and condition (KeyError if there is none)."""
        for r in self.rows:
            if r.metric == metric and r.condition == condition:
                return r
        raise KeyError((metric, condition))

    def to_json(self) -> dict:
        """The documented JSON object: experiment, title, params, rows."""
        return {
            "experiment": self.experiment,
            "title": self.title,
            "params": self.params,
            "rows": [r.to_json() for r in self.rows],
        }

    def to_json_text(self) -> str:
        return json.dumps(self.to_json(), indent=2) + "\n"

    def to_table(self) -> str:
        """A plain-text table: metric, condition, paper, measured, unit."""
        head = ["metric", "condition", "paper", "measured", "unit"]
        body = [[r.metric, r.condition, _num(r.paper), _num(r.measured), r.unit] for r in self.rows]
        widths = [max(len(x) for x in col) for col in zip(head, *body, strict=True)]
        params = ", ".join(f"{k}={v}" for k, v in self.params.items())
        lines = [f"# {self.title}" + (f" ({params})" if params else "")]
        for cells in [head, *body]:
            lines.append("  ".join(c.ljust(w) for c, w in zip(cells, widths, strict=True)).rstrip())
        return "\n".join(lines)


class Ticker:
    """Counts an experiment's units of work and reports each to a :data:`ProgressCallback`.

    Calling it with a value counts one unit and returns the value, so a trial loop
    reports progress without changing shape: ``[tick(_trial(s)) for s in seeds]``.

    Examples
    --------
    >>> seen = []
    >>> tick = Ticker(2, lambda done, total: seen.append((done, total)))
    >>> [tick(x) for x in "ab"], seen
    (['a', 'b'], [(1, 2), (2, 2)])
    >>> Ticker(3, None)("no callback: just counted")
    'no callback: just counted'
    """

    def __init__(self, total: int, progress: ProgressCallback | None) -> None:
        self.total = int(total)
        self.done = 0
        self.progress = progress

    def __call__(self, value: _T = None) -> _T:
        self.done += 1
        if self.progress is not None:
            self.progress(self.done, self.total)
        return value
