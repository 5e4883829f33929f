"""Simulation: rendered recordings with their ground truth."""

from rangekit.sim.exchanges import render_exchanges
from rangekit.sim.recording import Device, SimResult, pair_devices, render_beepbeep
from rangekit.sim.room import ShoeboxRoom, image_sources

__all__ = [
    "Device",
    "ShoeboxRoom",
    "SimResult",
    "image_sources",
    "pair_devices",
    "render_beepbeep",
    "render_exchanges",
]
