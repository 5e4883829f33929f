"""Ranging schemes: distances from arrival times.

:func:`run_range` is the one call per job (what ``rangekit range`` does); its
configuration objects (:mod:`rangekit.ranging.config`) are validated once when built.
"""

from rangekit.ranging.beepbeep import range_beepbeep, self_distances
from rangekit.ranging.config import Medium, SeriesOptions, TwoWaySetup
from rangekit.ranging.pipeline import range_channels, range_files
from rangekit.ranging.run import ClockRateCorrection, RangeRun, run_range

__all__ = [
    "ClockRateCorrection",
    "Medium",
    "RangeRun",
    "SeriesOptions",
    "TwoWaySetup",
    "range_beepbeep",
    "range_channels",
    "range_files",
    "run_range",
    "self_distances",
]
