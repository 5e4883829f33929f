"""Range-sensor models.

Examples
--------
>>> from rangekit.sensors import SRF02
>>> SRF02().n_rays
7
"""

from rangekit.sensors.srf02 import (
    SRF02,
    SRF02Readings,
    beam_pattern,
    model_range,
    read_ranges,
    schedule_firings,
    simulate_readings,
)

__all__ = [
    "SRF02",
    "SRF02Readings",
    "beam_pattern",
    "model_range",
    "read_ranges",
    "schedule_firings",
    "simulate_readings",
]
