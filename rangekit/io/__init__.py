"""Audio and result input/output."""

from rangekit.io.audio import Channel, load_devices, read_audio, write_audio
from rangekit.io.sidecar import read_json, write_json, write_text_atomic

__all__ = [
    "Channel",
    "load_devices",
    "read_audio",
    "read_json",
    "write_audio",
    "write_json",
    "write_text_atomic",
]
