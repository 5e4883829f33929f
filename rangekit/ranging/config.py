"""Frozen configuration of a ranging job, each validated once when it is built.

In the spirit of :class:`scipy.signal.ShortTimeFFT`: the arguments that used to travel as
loose keywords through :func:`~rangekit.ranging.pipeline.range_channels`, the series code,
batch processing and the CLI are grouped by what they describe, checked in
``__post_init__`` (a bad value is an :class:`~rangekit.errors.InvalidParameterError`
naming it, before any recording is read), and derived values are computed in one place
(:attr:`Medium.c` is the only ``speed_of_sound_m_s(temp_c) if speed is None else speed``).

- :class:`Medium`: the air (temperature, or a speed of sound that overrides it).
- :class:`TwoWaySetup`: what a user knows of the devices of a two-way exchange before
  measuring (speaker-to-microphone self-distances, sample-clock tolerance); devices play
  in index order (device 0 first).
- :class:`SeriesOptions`: how a long recording is cut (block, exchange, skew) and how many
  worker processes detect its blocks.

Examples
--------
>>> Medium(temp_c=20.0).c  # doctest: +ELLIPSIS
343.2...
>>> Medium(speed_m_s=340.0).c
340.0
>>> TwoWaySetup(self_distance_m=[0.1, 0.12]).self_distance_m
(0.1, 0.12)
>>> TwoWaySetup(clock_ppm=-1.0)
Traceback (most recent call last):
...
rangekit.errors.InvalidParameterError: clock_ppm=-1.0 must be within [0.0, 10000.0]
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from rangekit import _validate as V
from rangekit.physics import DEFAULT_TEMP_C, speed_of_sound_m_s
from rangekit.ranging.beepbeep import DEFAULT_CLOCK_PPM, check_speed, self_distances
from rangekit.ranging.series import DEFAULT_SKEW_S

__all__ = ["Medium", "SeriesOptions", "TwoWaySetup"]


@dataclass(frozen=True)
class Medium:
    """The air sound travels through.

    Parameters
    ----------
    temp_c : float
        Air temperature, degrees Celsius (:func:`rangekit.physics.speed_of_sound_m_s`).
    speed_m_s : float, optional
        Speed of sound, m/s (within 100-2000); overrides ``temp_c``.

    Attributes
    ----------
    c : float
        The speed of sound used, m/s: ``speed_m_s`` when given, else that of ``temp_c``.
    """

    temp_c: float = DEFAULT_TEMP_C
    speed_m_s: float | None = None
    c: float = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # The one place the speed of sound is derived from the options.
        c = (
            speed_of_sound_m_s(self.temp_c)
            if self.speed_m_s is None
            else check_speed(self.speed_m_s)
        )
        object.__setattr__(self, "c", float(c))

    def kwargs(self) -> dict:
        """As the keywords ``temp_c``, ``speed_m_s`` of the keyword APIs."""
        return {"temp_c": self.temp_c, "speed_m_s": self.speed_m_s}


@dataclass(frozen=True)
class TwoWaySetup:
    """The devices of a two-way (BeepBeep) exchange, as known before measuring.

    Parameters
    ----------
    self_distance_m : float or sequence of float
        Speaker-to-microphone distance of every device, or one per device (play order),
        metres, within [0, 2]. A list or array is kept as a tuple.
    clock_ppm : float
        1-sigma sample-clock tolerance per device, ppm, within [0, 1e4] (widens sigma only).

    Devices play in index order: device i is channel (or file) i, device 0 first.
    """

    self_distance_m: float | tuple[float, ...] = 0.0
    clock_ppm: float = DEFAULT_CLOCK_PPM

    def __post_init__(self) -> None:
        sd = self.self_distance_m
        if hasattr(sd, "tolist") and getattr(sd, "ndim", 0) > 0:  # a numpy array
            sd = sd.tolist()
        if isinstance(sd, (list, tuple)):
            sd = tuple(sd)
            object.__setattr__(self, "self_distance_m", sd)
            self_distances(sd, len(sd))
        else:
            self_distances(sd, 1)
        V.in_range("clock_ppm", self.clock_ppm, 0.0, 1e4)

    def self_distances(self, n_devices: int):
        """The ``n_devices`` self-distances (one broadcast, or checked to count ``n_devices``)."""
        return self_distances(self.self_distance_m, n_devices)

    def kwargs(self) -> dict:
        """As the keywords ``self_distance_m``, ``clock_ppm`` of the keyword APIs."""
        sd = self.self_distance_m
        return {
            "self_distance_m": list(sd) if isinstance(sd, tuple) else sd,
            "clock_ppm": self.clock_ppm,
        }


@dataclass(frozen=True)
class SeriesOptions:
    """How a long recording is ranged block by block (``rangekit range --series``).

    Parameters
    ----------
    block_s : float, optional
        Block length, s [default: 2^21 samples over all channels].
    exchange_s : float, optional
        Two-way: longest time from device 0's beep to the last device's beep of one
        exchange [default: (N-1) x (beep duration + 0.5 s)].
    skew_s : float
        Two-way: allowance for the time of flight and differing start times, s.
    jobs : int
        Two-way: worker processes detecting blocks in parallel (1-256).
    """

    block_s: float | None = None
    exchange_s: float | None = None
    skew_s: float = DEFAULT_SKEW_S
    jobs: int = 1

    def __post_init__(self) -> None:
        if self.block_s is not None:
            V.in_range("block_s", self.block_s, 0.001, 1e6)
        if self.exchange_s is not None:
            V.in_range("exchange_s", self.exchange_s, 0.001, 3600.0)
        V.in_range("skew_s", self.skew_s, 0.0, 3600.0)
        if (
            isinstance(self.jobs, bool)
            or not isinstance(self.jobs, int)
            or not 1 <= self.jobs <= 256
        ):
            raise V.InvalidParameterError(f"jobs={self.jobs!r} must be a whole number in 1..256")


def as_self_distance(values: Sequence[float]) -> float | tuple[float, ...]:
    """One value as a float, several as a tuple (what :class:`TwoWaySetup` holds)."""
    vals = tuple(float(v) for v in values)
    return vals[0] if len(vals) == 1 else vals
