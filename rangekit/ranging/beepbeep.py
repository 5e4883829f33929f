"""Two-way (BeepBeep) ranging without clock synchronisation, for N devices.

Notes
-----
Peng et al. 2007 (BeepBeep), as used by Jiang et al. 2018 §4.3 and Algorithm 1: devices
play the beep in turn (device 0 first) while all record. Let ``t_i[j]`` be the arrival of
device j's beep in device i's recording, in seconds of device i's own clock (onset sample
over its own sample rate). For a pair (a, b),

    D_ab = c / 2 * ((t_a[b] - t_a[a]) - (t_b[b] - t_b[a])) + (s_a + s_b) / 2

where ``s_i`` is device i's speaker-to-microphone distance (its self-distance) and c the
speed of sound. Play and record start times and every fixed latency cancel; D_ab is the
mean of the two cross speaker-to-microphone distances. A sample-clock error e (ppm) in a
recording scales the interval it measures by (1 + e): with intervals of a few tenths of
a second that is a few millimetres at 50 ppm.

Flags: a range carries ``negative`` (D < 0), ``order`` (a device heard the other before
itself) and every flag of the four arrivals it comes from (:data:`rangekit.types.ARRIVAL_FLAGS`).

Uncertainty: sigma_D^2 = (c/2)^2 * (sum of the four onset variances, s^2)
+ (c/2)^2 * ((Delta_a * e)^2 + (Delta_b * e)^2), where Delta_i = t_i[b] - t_i[a] is the
interval device i measured and ``e = clock_ppm * 1e-6`` the 1-sigma tolerance of a sample
clock. The second term is the unknown clock-rate error, which no detection quality can
reveal: one exchange cannot separate a clock-rate error from a distance. Set
``clock_ppm=0`` for clocks known to be exact (e.g. one sound card recording every channel).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from rangekit import _validate as V
from rangekit.errors import DetectionError, IncompatibleInputError, UnreliableResultError
from rangekit.physics import check_speed  # re-exported (it lived here)
from rangekit.types import INFO_FLAGS, Arrivals, Range, RangeResult, flag_names

__all__ = [
    "DEFAULT_CLOCK_PPM",
    "WITHHELD",
    "check_speed",
    "doubtful_flags",
    "range_beepbeep",
    "refuse_doubtful",
    "self_distances",
    "withhold_doubtful",
]

#: Default 1-sigma sample-clock tolerance of a device, ppm.
DEFAULT_CLOCK_PPM = 30.0
#: Largest arrival time (and sigma) accepted, s (about 115 days of recording).
MAX_ONSET_S = 1e7


def self_distances(self_distance_m, n_devices: int) -> np.ndarray:
    """Broadcast one self-distance, or check a list of ``n_devices`` of them (metres)."""
    vals = self_distance_m if isinstance(self_distance_m, (list, tuple)) else [self_distance_m]
    for v in vals if isinstance(vals, (list, tuple)) else ():
        if isinstance(v, (bool, str)) or v is None:
            raise V.InvalidParameterError(f"self_distance_m={v!r} must be a number")
    try:
        s = np.atleast_1d(np.asarray(self_distance_m, dtype=np.float64))
    except (TypeError, ValueError, OverflowError):
        raise V.InvalidParameterError(
            f"self_distance_m={self_distance_m!r} must be a number or a list of numbers"
        ) from None
    if s.ndim != 1 or len(s) not in (1, n_devices):
        raise IncompatibleInputError(
            f"{len(s)} self-distances given for {n_devices} devices: give one, or one per device"
        )
    for v in s.tolist():
        V.positive("self_distance_m", v, allow_zero=True)
        if v > 2.0:
            raise V.InvalidParameterError(f"self_distance_m={v} m is implausibly large (> 2 m)")
    return np.broadcast_to(s, (n_devices,)).copy()


def range_beepbeep(
    arrivals: Sequence[Arrivals],
    *,
    speed_m_s: float,
    self_distance_m: float | Sequence[float] = 0.0,
    clock_ppm: float = DEFAULT_CLOCK_PPM,
) -> RangeResult:
    """Distances between every pair of devices from their recordings' beep arrivals.

    Parameters
    ----------
    arrivals : sequence of Arrivals
        ``arrivals[i]`` are the beeps found in device i's recording; it must hold exactly
        one beep per device, in play order (device 0's beep first).
    speed_m_s : float
        Speed of sound in m/s.
    self_distance_m : float or sequence of float
        Speaker-to-microphone distance of every device, or of each device.
    clock_ppm : float
        1-sigma sample-clock tolerance of each device in ppm (default 30, typical of the
        crystal oscillators of phone audio codecs); enters ``sigma_m`` only.

    Returns
    -------
    RangeResult
        One Range per pair (a < b), ordered (0, 1), (0, 2), ..., (1, 2), ...

    Raises
    ------
    DetectionError
        A recording does not hold one beep per device.

    Examples
    --------
    >>> import numpy as np
    >>> from rangekit.types import Arrivals
    >>> def arr(onsets):
    ...     n = len(onsets)
    ...     z = np.zeros(n)
    ...     return Arrivals(np.array(onsets), 44100.0, z + 0.1, z + 30, z + 1, np.zeros((n, 4)))
    >>> # 343 samples of flight each way at 44.1 kHz: 343 / 44100 s * 343 m/s
    >>> res = range_beepbeep([arr([1000.0, 21343.0]), arr([5343.0, 25000.0])], speed_m_s=343.0)
    >>> round(res.ranges[0].distance_m, 4)
    2.6678
    """
    n = len(arrivals)
    if n < 2:
        raise IncompatibleInputError(f"two-way ranging needs at least 2 devices, got {n}")
    c = check_speed(speed_m_s)
    s = self_distances(self_distance_m, n)
    e = V.in_range("clock_ppm", clock_ppm, 0.0, 1e4) * 1e-6
    for i, a in enumerate(arrivals):
        if len(a) != n:
            found = "no beep" if len(a) == 0 else f"{len(a)} beep(s)"
            raise DetectionError(
                f"device {i}: found {found} but expected {n} (one per device); "
                "run `rangekit detect` on the file to see what was found"
            )
    for i, a in enumerate(arrivals):
        ok = np.all(np.isfinite(a.onset_s)) and np.all(np.abs(a.onset_s) <= MAX_ONSET_S)
        if not ok or not np.all(np.isfinite(a.sigma_s) & (a.sigma_s <= MAX_ONSET_S)):
            raise V.InvalidParameterError(
                f"device {i}: onsets and sigmas must be finite and within {MAX_ONSET_S:g} s"
            )
    t = [a.onset_s for a in arrivals]
    # Each device's speaker and microphone delays appear in both of a range's differences
    # and cancel: the arrivals' transducer term stays out (Arrivals.sigma_relative).
    v = [(a.sigma_relative / a.fs) ** 2 for a in arrivals]
    ranges = []
    for a in range(n):
        for b in range(a + 1, n):
            delta_a, delta_b = t[a][b] - t[a][a], t[b][b] - t[b][a]
            d = 0.5 * c * (delta_a - delta_b) + 0.5 * (s[a] + s[b])
            var = v[a][a] + v[a][b] + v[b][a] + v[b][b] + (delta_a * e) ** 2 + (delta_b * e) ** 2
            sig = 0.5 * c * math.sqrt(var)
            flags = []
            if d < 0:
                flags.append("negative")
            if t[a][b] <= t[a][a] or t[b][b] <= t[b][a]:
                flags.append("order")
            # The four arrivals' flags: whatever made one of them doubtful makes the range so.
            bits = 0
            for i, j in ((a, a), (a, b), (b, a), (b, b)):
                bits |= int(arrivals[i].flags[j])
            flags.extend(flag_names(bits))
            ranges.append(Range(a, b, float(d), float(sig), tuple(flags)))
    return RangeResult(tuple(ranges), c, tuple(arrivals))


#: The flag strict mode adds to an output row whose distance it withholds.
WITHHELD = "withheld"


def _doubtful(flags) -> tuple[str, ...]:
    return tuple(f for f in flags if f not in INFO_FLAGS and f != WITHHELD)


def doubtful_flags(r) -> tuple[str, ...]:
    """The flags of ``r`` (a Range, a ToF, anything with ``flags``) that make it doubtful:
    all but :data:`rangekit.types.INFO_FLAGS`."""
    return _doubtful(r.flags)


def withhold_doubtful(row: dict) -> bool:
    """Strict mode for one output row of a multi-row result (``--series``, one-way and
    echo rows, batch): a row with a distance and a doubtful flag keeps its flags, gains
    :data:`WITHHELD`, and its ``distance_m`` and ``sigma_m`` become None. Returns whether
    the row was withheld. (A one-exchange result is refused whole instead:
    :func:`refuse_doubtful`.)

    Examples
    --------
    >>> row = {"distance_m": 2.0, "sigma_m": 0.01, "flags": ["low_snr"]}
    >>> withhold_doubtful(row), row
    (True, {'distance_m': None, 'sigma_m': None, 'flags': ['low_snr', 'withheld']})
    >>> withhold_doubtful({"distance_m": 2.0, "sigma_m": 0.01, "flags": ["dc_or_lowband"]})
    False
    """
    d = row.get("distance_m")
    flags = list(row.get("flags") or ())
    if d is None or not math.isfinite(d) or WITHHELD in flags or not _doubtful(flags):
        return False
    row.update(distance_m=None, sigma_m=None, flags=[*flags, WITHHELD])
    return True


def refuse_doubtful(result: RangeResult, *, what: str = "the recording") -> RangeResult:
    """Return ``result``, or raise UnreliableResultError if any range has a doubtful flag.

    Examples
    --------
    >>> from rangekit.types import Range, RangeResult
    >>> refuse_doubtful(RangeResult((Range(0, 1, 2.0, 0.01, ("dc_or_lowband",)),), 343.0))
    ... # doctest: +ELLIPSIS
    RangeResult(...)
    >>> refuse_doubtful(RangeResult((Range(0, 1, 2.0, 0.01, ("clipped",)),), 343.0), what="x")
    Traceback (most recent call last):
    ...
    rangekit.errors.UnreliableResultError: strict: x: pair 0-1 (2.000 m) is flagged clipped
    """
    bad = [(r, doubtful_flags(r)) for r in result.ranges if doubtful_flags(r)]
    if bad:
        parts = [
            f"pair {r.a}-{r.b} ({r.distance_m:.3f} m) is flagged {','.join(f)}" for r, f in bad
        ]
        raise UnreliableResultError(f"strict: {what}: " + "; ".join(parts))
    return result
