"""The result of a paper experiment: rows of (metric, condition, paper, measured).

Every ``rangekit experiment NAME`` returns an :class:`ExperimentReport`. Its JSON form is
an object with ``experiment``, ``title``, ``params`` and ``rows``; each row has at least
``metric``, ``condition``, ``paper`` (the paper's number, or null where the paper gives
none) and ``measured`` (see ``docs/formats.md``).

Examples
--------
>>> rep = ExperimentReport("demo", "A demo", {"trials": 2, "seed": 1})
>>> rep.add("median error", "target 2, 0.4 m/s", 0.85, 0.5312, unit="m")
>>> rep.add("NEES", "target 2, 0.4 m/s", None, 3.9)
>>> rep.to_json()["rows"][0]["paper"]
0.85
>>> print(rep.to_table())
# A demo (trials=2, seed=1)
metric        condition          paper  measured  unit
median error  target 2, 0.4 m/s  0.85   0.5312    m
NEES          target 2, 0.4 m/s  -      3.9
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

__all__ = ["ExperimentReport", "ExperimentRow"]


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
    """

    metric: str
    condition: str
    paper: float | None
    measured: float
    unit: str = ""
    note: str = ""

    def to_json(self) -> dict:
        m = float(self.measured)
        return {
            "metric": self.metric,
            "condition": self.condition,
            "paper": None if self.paper is None else float(self.paper),
            "measured": None if math.isnan(m) else m,
            "unit": self.unit,
            "note": self.note,
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
    ) -> None:
        """Append one :class:`ExperimentRow`."""
        self.rows.append(ExperimentRow(metric, condition, paper, float(measured), unit, note))

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
