"""Ranging schemes: distances from arrival times."""

from rangekit.ranging.beepbeep import range_beepbeep, self_distances
from rangekit.ranging.pipeline import range_channels, range_files

__all__ = ["range_beepbeep", "range_channels", "range_files", "self_distances"]
