"""Pulse-echo ultrasonic ranging (SRF02 style, Girard 2011 §2.6).

Sample 0 is the ping; the earliest echo after the ring-down blanking (the minimum range,
15 cm) gives ``c * t / 2``; nothing within the maximum range (6 m) is "out of range"
(distance NaN). A recording may hold many ranging cycles at a known period (70 ms for the
SRF02). The ping passes the transducer twice (it sends and receives). Each echo is timed
by the transducer fit of one-way ranging (:mod:`rangekit.detect.fitted`: the ping
through two equal resonators of unknown Q and f0, with overlapping reflections, or the
stagger-tuned model, pooled over the cycles), so the range does not depend on knowing
the transducer's Q: with the Q 4 template assumed, echoes through Q 8-20 transducers
came out 8-25 mm long at a sigma of 0.3-0.5 mm (``docs/theory/ultrasonic.md``,
pulse-echo). ``fit_transducer=False`` keeps the fixed template's matched-filter first
path (:mod:`rangekit.detect.matched`).

Examples
--------
>>> import numpy as np
>>> from rangekit.detect.matched import coded_template
>>> from rangekit.signals.barker import srf02_ping
>>> fs = 192000.0
>>> h = coded_template(srf02_ping(), fs=fs, tx=None, rx=None)
>>> x = np.zeros((1, 13440))
>>> x[0, 2240 : 2240 + len(h)] = h
>>> rows = range_echo(x, fs=fs, transducer=None, speed_m_s=343.0)
>>> round(rows[0].distance_m, 4)
2.0008
"""

from __future__ import annotations

import math

import numpy as np

from rangekit import _validate as V
from rangekit.detect.matched import (
    DEFAULT_BLOCK,
    DEFAULT_K_DETECT,
    DEFAULT_K_NOISE,
    DEFAULT_REL_THRESHOLD,
    coded_template,
)
from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.physics import DEFAULT_TEMP_C
from rangekit.ranging.oneway import _fit_model
from rangekit.ranging.tof import _DEFAULT_TX, ToF, _as_channels, _ranges, _speed, _windows
from rangekit.signals.barker import CodedBurst, check_burst_fits, srf02_ping
from rangekit.signals.probe import Probe
from rangekit.signals.transducer import Transducer

__all__ = ["SRF02_CYCLE_S", "SRF02_MAX_RANGE_M", "SRF02_MIN_RANGE_M", "range_echo"]

#: SRF02 ranging cycle (datasheet; Girard 2011 §2.6.5), s.
SRF02_CYCLE_S = 0.070
#: SRF02 minimum range (ring-down), m (Girard 2011 §2.6).
SRF02_MIN_RANGE_M = 0.15
#: SRF02 maximum range, m (Girard 2011 §2.6).
SRF02_MAX_RANGE_M = 6.0


def range_echo(
    x: np.ndarray,
    *,
    fs: float,
    burst: CodedBurst | None = None,
    transducer: Transducer | None = _DEFAULT_TX,
    temp_c: float = DEFAULT_TEMP_C,
    speed_m_s: float | None = None,
    period_s: float | None = None,
    min_range_m: float = SRF02_MIN_RANGE_M,
    max_range_m: float = SRF02_MAX_RANGE_M,
    k_noise: float = DEFAULT_K_NOISE,
    k_detect: float = DEFAULT_K_DETECT,
    rel_threshold: float = DEFAULT_REL_THRESHOLD,
    block: int = DEFAULT_BLOCK,
    windows: np.ndarray | None = None,
    first_window: int = 0,
    probe: Probe | None = None,
    fit_transducer: bool = True,
    pool: bool = True,
    transducer_family: str = "resonator",
) -> list[ToF]:
    """Pulse-echo ranges (SRF02 style) from a recording whose sample 0 is the ping.

    The template is the ping through the transducer twice (it sends and receives). Echoes
    earlier than ``2 min_range_m / c`` fall in the ring-down and are not searched; nothing
    before ``2 max_range_m / c`` means out of range (distance NaN, ``None`` in JSON).
    ``period_s`` splits a log of many ranging cycles (0.07 s for the SRF02), or
    ``windows`` gives them explicitly. ``fit_transducer`` (default True) times each echo
    by fitting the ping through the transducer twice with Q and f0 unknown
    (``transducer`` is the starting point and sets the nominal f0), ``pool`` pools the
    estimates over the cycles of each channel (the sensor's transducer is one); False
    folds ``transducer`` into the template as it is; ``transducer_family`` (with the
    fit; ``"resonator"`` or ``"unknown"``) what is known of its family, as for
    :func:`range_oneway` (only sigma differs). Other parameters as
    :func:`range_oneway` (with ``probe`` the template is the probe and ``burst``,
    ``transducer`` are unused).
    """
    from rangekit.detect.fitted import check_transducer_family

    fs = V.sample_rate(fs)
    transducer_family = check_transducer_family(
        transducer_family, fit=fit_transducer, fit_name="fit_transducer=True"
    )
    burst = srf02_ping() if burst is None else burst
    if probe is None:
        check_burst_fits(burst, fs=fs)
    else:
        probe.check_fits(fs)
    x = _as_channels(x)
    c = _speed(temp_c, speed_m_s)
    min_range_m = V.positive("min_range_m", min_range_m, allow_zero=True)
    max_range_m = V.positive("max_range_m", max_range_m)
    if max_range_m <= min_range_m:
        raise InvalidParameterError(
            f"max_range_m={max_range_m!r} must exceed min_range_m={min_range_m!r}"
        )
    windows = _windows(
        x.shape[1], fs=fs, period_s=period_s, windows=windows, first_window=first_window
    )
    if (windows[0, 1] - windows[0, 0]) / fs < 2.0 * min_range_m / c:
        raise IncompatibleInputError(
            f"recording of {x.shape[1]} samples is shorter than the ring-down blanking"
        )
    template = (
        coded_template(burst, fs=fs, tx=transducer, rx=transducer)
        if probe is None
        else probe.at_rate(fs)
    )
    # The ping passes the one transducer twice: two equal resonators, the transducer
    # fit's own model (helper of range_oneway; ``transducer`` is its starting point).
    model, q0 = (
        (None, 4.0)
        if probe is not None
        else _fit_model(burst, fs, (transducer, transducer), fit_transducer)
    )
    rows = _ranges(
        x,
        fs=fs,
        template=template,
        windows=windows,
        lo_s=2.0 * min_range_m / c,
        hi_s=2.0 * max_range_m / c,
        offset_s=0.0,
        scale=0.5,
        c=c,
        tx_ids=None,
        thresholds={"k_noise": k_noise, "k_detect": k_detect, "rel_threshold": rel_threshold},
        block=block,
        first_window=first_window,
        model=model,
        q0=q0,
        pool=pool,
        transducer_family=transducer_family,
    )
    # Paths found at the very edges of the search are the blanking's or timeout's edge.
    out = []
    for r in rows:
        if math.isfinite(r.distance_m) and not (min_range_m <= r.distance_m <= max_range_m):
            r = ToF(r.window, r.tx, r.channel, math.nan, math.nan, math.nan, math.nan)
        out.append(r)
    return out
