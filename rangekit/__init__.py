"""rangekit: acoustic and ultrasonic ranging.

The top-level namespace is curated, in sections that follow the layers of the library
(``docs/api.md`` is the reference page; ``docs/architecture.md`` the layout):

Signals (:mod:`rangekit.signals`)
    :class:`Beep`, :class:`CodedBurst`, :class:`Probe`, :func:`linear_sweep`,
    :func:`read_probe`, :func:`beep_waveform`
Detection (:mod:`rangekit.detect`)
    :func:`detect_arrivals` (the one front end, ``rangekit.detect.detect``),
    :func:`detect_changepoint`, :func:`detect_xcorr`, :func:`detect_template`
Ranging (:mod:`rangekit.ranging`)
    two-way: :func:`range_beepbeep`, :func:`range_channels`, :func:`range_files`,
    :func:`self_distances`; series: :func:`range_series_beepbeep`; clocks:
    :func:`estimate_clock_rates`, :func:`correct_clock`; calibration:
    :func:`fit_calibration`, :func:`read_calibration`, :class:`Calibration`; ultrasonic:
    :func:`range_oneway`, :func:`range_echo`; physics: :func:`speed_of_sound_m_s`
Localisation and tracking (:mod:`rangekit.localize`)
    :func:`solve_pose` (UHL), :func:`locate_pose` (``rangekit locate``),
    :func:`track_duhl`, :func:`track_ranges`,
    :func:`track_anchors`, :func:`dead_reckon`, :func:`lmax_offline`,
    :func:`lmax_online`, :func:`track_particles`, :func:`rts_smooth`; setups:
    :class:`Rig`, :func:`read_rig`, :class:`FloorPlan`, :func:`load_floorplan`
Input and output (:mod:`rangekit.io`)
    :func:`read_audio`, :func:`write_audio`, :func:`load_devices`
Simulation (:mod:`rangekit.sim`)
    :func:`render_beepbeep`, :func:`pair_devices`, :class:`Device`, :class:`ShoeboxRoom`;
    the scenes of ``rangekit synth``: :func:`synth_beepbeep`, :func:`synth_oneway`,
    :func:`synth_echo`, :class:`Synthesis`
Figures (:mod:`rangekit.plot.jobs`, drawn when called)
    :func:`spectrogram_figure`, :func:`matched_figure`, :func:`ranges_figure`,
    :func:`track_figure`, :func:`cdf_figure`
Results and errors
    :class:`Arrivals`, :class:`Range`, :class:`RangeResult`, :class:`RangekitError`

No top-level name is also the name of a subpackage (``rangekit.detect`` is the detection
package; its front end is :func:`detect_arrivals`). Units are spelled once, as a suffix:
``_m``, ``_s``, ``_hz``, ``_m_s`` (metres per second), ``_db``.

The names are imported lazily so that ``import rangekit`` stays cheap (no numba, no
scipy.signal until a name is used).

Examples
--------
>>> import rangekit
>>> rangekit.Beep().f_hz
16000.0
>>> round(rangekit.speed_of_sound_m_s(20.0), 1)
343.3
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

#: Section -> {public name: (module, attribute)}; the order is the reference page's.
SECTIONS: dict[str, dict[str, tuple[str, str]]] = {
    "Signals": {
        "Beep": ("rangekit.signals", "Beep"),
        "CodedBurst": ("rangekit.signals", "CodedBurst"),
        "Probe": ("rangekit.signals", "Probe"),
        "linear_sweep": ("rangekit.signals", "linear_sweep"),
        "read_probe": ("rangekit.signals", "read_probe"),
        "beep_waveform": ("rangekit.signals", "beep_waveform"),
    },
    "Detection": {
        "detect_arrivals": ("rangekit.detect", "detect"),
        "detect_changepoint": ("rangekit.detect", "detect_changepoint"),
        "detect_xcorr": ("rangekit.detect", "detect_xcorr"),
        "detect_template": ("rangekit.detect.template", "detect_template"),
        "detect_files": ("rangekit.detect.files", "detect_files"),
    },
    "Ranging": {
        "run_range": ("rangekit.ranging", "run_range"),
        "Medium": ("rangekit.ranging", "Medium"),
        "TwoWaySetup": ("rangekit.ranging", "TwoWaySetup"),
        "SeriesOptions": ("rangekit.ranging", "SeriesOptions"),
        "ClockRateCorrection": ("rangekit.ranging", "ClockRateCorrection"),
        "range_beepbeep": ("rangekit.ranging", "range_beepbeep"),
        "range_channels": ("rangekit.ranging", "range_channels"),
        "range_files": ("rangekit.ranging", "range_files"),
        "self_distances": ("rangekit.ranging", "self_distances"),
        "range_series_beepbeep": ("rangekit.ranging.series", "range_series_beepbeep"),
        "estimate_clock_rates": ("rangekit.ranging.clock", "estimate_clock_rates"),
        "correct_clock": ("rangekit.ranging.clock", "correct_clock"),
        "Calibration": ("rangekit.ranging.calibration", "Calibration"),
        "fit_calibration": ("rangekit.ranging.calibration", "fit_calibration"),
        "calibrate_recordings": ("rangekit.ranging.calibration", "calibrate_recordings"),
        "read_calibration": ("rangekit.ranging.calibration", "read_calibration"),
        "range_oneway": ("rangekit.ranging.ultrasonic", "range_oneway"),
        "range_echo": ("rangekit.ranging.ultrasonic", "range_echo"),
        "OneWaySetup": ("rangekit.ranging.config", "OneWaySetup"),
        "EchoSetup": ("rangekit.ranging.config", "EchoSetup"),
        "ultrasonic_setup": ("rangekit.ranging.ultrasonic_setup", "ultrasonic_setup"),
        "Detection": ("rangekit.ranging.config", "Detection"),
        "speed_of_sound_m_s": ("rangekit.physics", "speed_of_sound_m_s"),
    },
    "Localisation and tracking": {
        "solve_pose": ("rangekit.localize.uhl", "solve_pose"),
        "locate_pose": ("rangekit.localize.locate", "locate_pose"),
        "track_duhl": ("rangekit.localize.duhl", "track_duhl"),
        "track_ranges": ("rangekit.localize", "track_ranges"),
        "track_anchors": ("rangekit.localize", "track_anchors"),
        "dead_reckon": ("rangekit.localize", "dead_reckon"),
        "lmax_offline": ("rangekit.localize", "lmax_offline"),
        "lmax_online": ("rangekit.localize", "lmax_online"),
        "track_particles": ("rangekit.localize.particle", "track_particles"),
        "rts_smooth": ("rangekit.localize", "rts_smooth"),
        "Rig": ("rangekit.rig", "Rig"),
        "read_rig": ("rangekit.rig", "read_rig"),
        "FloorPlan": ("rangekit.floorplan", "FloorPlan"),
        "load_floorplan": ("rangekit.floorplan", "load_floorplan"),
    },
    "Input and output": {
        "read_audio": ("rangekit.io", "read_audio"),
        "write_audio": ("rangekit.io", "write_audio"),
        "load_devices": ("rangekit.io", "load_devices"),
        "RowWriter": ("rangekit.io.stream", "RowWriter"),
        "format_track": ("rangekit.io.tracks", "format_track"),
        "TrackReport": ("rangekit.io.tracks", "TrackReport"),
    },
    "Simulation": {
        "render_beepbeep": ("rangekit.sim", "render_beepbeep"),
        "pair_devices": ("rangekit.sim", "pair_devices"),
        "Device": ("rangekit.sim", "Device"),
        "ShoeboxRoom": ("rangekit.sim", "ShoeboxRoom"),
        "synth_beepbeep": ("rangekit.sim.scenarios", "synth_beepbeep"),
        "synth_oneway": ("rangekit.sim.scenarios", "synth_oneway"),
        "synth_echo": ("rangekit.sim.scenarios", "synth_echo"),
        "Synthesis": ("rangekit.sim.scenarios", "Synthesis"),
    },
    "Figures": {
        "spectrogram_figure": ("rangekit.plot.jobs", "spectrogram_figure"),
        "matched_figure": ("rangekit.plot.jobs", "matched_figure"),
        "ranges_figure": ("rangekit.plot.jobs", "ranges_figure"),
        "track_figure": ("rangekit.plot.jobs", "track_figure"),
        "cdf_figure": ("rangekit.plot.jobs", "cdf_figure"),
    },
    "Results and errors": {
        "Arrivals": ("rangekit.types", "Arrivals"),
        "Range": ("rangekit.types", "Range"),
        "RangeResult": ("rangekit.types", "RangeResult"),
        "RangekitError": ("rangekit.errors", "RangekitError"),
    },
}

_LAZY: dict[str, tuple[str, str]] = {
    name: where for section in SECTIONS.values() for name, where in section.items()
}

__all__ = ["__version__", *sorted(_LAZY)]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        module, attribute = _LAZY[name]
        value = getattr(importlib.import_module(module), attribute)
        globals()[name] = value  # resolved once
        return value
    raise AttributeError(f"module 'rangekit' has no attribute {name!r}")


def __dir__() -> list[str]:
    return __all__
