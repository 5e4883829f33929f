"""Physical constants and conversions between delays and distances.

Examples
--------
>>> round(speed_of_sound_m_s(20.0), 2)
343.29
>>> round(delay_to_distance_m(0.01, speed_m_s=343.0), 6)
3.43
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rangekit.errors import InvalidParameterError

__all__ = [
    "DEFAULT_TEMP_C",
    "Medium",
    "check_speed",
    "delay_to_distance_m",
    "distance_to_delay_s",
    "speed_of_sound_m_s",
]

#: Default air temperature in degrees Celsius.
DEFAULT_TEMP_C = 20.0


def speed_of_sound_m_s(temp_c: float = DEFAULT_TEMP_C) -> float:
    """Speed of sound in dry air.

    Parameters
    ----------
    temp_c : float
        Air temperature in degrees Celsius, within [-60, 60].

    Returns
    -------
    float
        Speed of sound in m/s.

    Notes
    -----
    c = 20.05 * sqrt(T + 273.16), with T in degrees Celsius (Kim & Kim 2013, §II-A).
    """
    if isinstance(temp_c, (bool, str)):
        raise InvalidParameterError(f"temperature {temp_c!r} must be a number")
    try:
        temp_c = float(temp_c)
    except (TypeError, ValueError, OverflowError):
        raise InvalidParameterError(f"temperature {temp_c!r} must be a number") from None
    if not math.isfinite(temp_c) or not -60.0 <= temp_c <= 60.0:
        raise InvalidParameterError(f"temperature {temp_c} C is outside [-60, 60] C")
    return 20.05 * math.sqrt(temp_c + 273.16)


def delay_to_distance_m(delay_s, *, speed_m_s: float):
    """Distance travelled by sound in ``delay_s`` seconds (scalar or array)."""
    return np.asarray(delay_s) * speed_m_s if np.ndim(delay_s) else delay_s * speed_m_s


def distance_to_delay_s(distance_m, *, speed_m_s: float):
    """Propagation delay in seconds over ``distance_m`` metres (scalar or array)."""
    return np.asarray(distance_m) / speed_m_s if np.ndim(distance_m) else distance_m / speed_m_s


def check_speed(speed_m_s: float) -> float:
    """Validate a speed of sound in m/s (finite, within [100, 2000])."""
    from rangekit import _validate as V

    return V.in_range("speed_m_s", speed_m_s, 100.0, 2000.0)


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
