"""Probe signals: tone-burst beeps (Jiang 2018 §4.3.1)."""

from rangekit.signals.beep import Beep, beep_waveform, burst_envelope, check_beep_fits

__all__ = ["Beep", "beep_waveform", "burst_envelope", "check_beep_fits"]
