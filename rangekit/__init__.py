"""rangekit: acoustic and ultrasonic ranging.

The public API is imported lazily so that ``import rangekit`` stays cheap.

Examples
--------
>>> import rangekit
>>> rangekit.Beep().f_hz
16000.0
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

_LAZY = {
    "Beep": "rangekit.signals",
    "CodedBurst": "rangekit.signals",
    "Probe": "rangekit.signals",
    "linear_sweep": "rangekit.signals",
    "read_probe": "rangekit.signals",
    "beep_waveform": "rangekit.signals",
    "detect": "rangekit.detect",
    "detect_changepoint": "rangekit.detect",
    "detect_xcorr": "rangekit.detect",
    "range_beepbeep": "rangekit.ranging",
    "range_channels": "rangekit.ranging",
    "range_files": "rangekit.ranging",
    "speed_of_sound_m_s": "rangekit.physics",
    "Arrivals": "rangekit.types",
    "Range": "rangekit.types",
    "RangeResult": "rangekit.types",
    "RangekitError": "rangekit.errors",
    "load_devices": "rangekit.io",
    "render_beepbeep": "rangekit.sim",
    "pair_devices": "rangekit.sim",
    "Device": "rangekit.sim",
    "ShoeboxRoom": "rangekit.sim",
}

__all__ = ["__version__", *sorted(_LAZY)]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'rangekit' has no attribute {name!r}")


def __dir__() -> list[str]:
    return __all__
