"""One-way (RF-synchronised beacon) ultrasonic ranging (Kim & Kim 2013 §II-A).

The robot's RF message triggers a ceiling Tx, which fires its Barker-coded burst; each of
the robot's receivers times the burst's arrival from the trigger. In a recording, sample 0
is the trigger (the emission instant); each channel is a receiver; a known system latency
(trigger to drive start) is subtracted; distances are ``c * (arrival - latency)`` with
``c = 20.05 sqrt(T + 273.16)`` m/s. A file may hold many consecutive activation windows at
a known period (Kim & Kim fire the Txs in turn at 5 Hz): window ``k`` starts at sample
``round(k * period * fs)``, and its time origin is there. Each arrival is timed by the
transducer fit (:mod:`rangekit.detect.fitted`), so the ranges do not depend on knowing
the transducers (``docs/theory/ultrasonic.md``).

Examples
--------
>>> import numpy as np
>>> from rangekit.detect.matched import coded_template
>>> fs = 192000.0
>>> h = coded_template(fs=fs)
>>> x = np.zeros((1, 20000))
>>> x[0, 560 : 560 + len(h)] = h
>>> rows = range_oneway(x, fs=fs, tx=None, rx=None, speed_m_s=343.0)
>>> rows[0].channel, round(rows[0].distance_m, 4)
(0, 1.0004)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rangekit import _validate as V
from rangekit.detect.matched import (
    DEFAULT_BLOCK,
    DEFAULT_K_DETECT,
    DEFAULT_K_NOISE,
    DEFAULT_REL_THRESHOLD,
    coded_template,
)
from rangekit.errors import InvalidParameterError
from rangekit.physics import DEFAULT_TEMP_C
from rangekit.ranging.tof import _DEFAULT_TX, ToF, _as_channels, _ranges, _speed, _windows
from rangekit.signals.barker import CodedBurst, check_burst_fits
from rangekit.signals.probe import Probe
from rangekit.signals.transducer import Transducer

__all__ = ["range_oneway"]


def range_oneway(
    x: np.ndarray,
    *,
    fs: float,
    burst: CodedBurst | None = None,
    tx: Transducer | None = _DEFAULT_TX,
    rx: Transducer | None = _DEFAULT_TX,
    latency_s: float = 0.0,
    temp_c: float = DEFAULT_TEMP_C,
    speed_m_s: float | None = None,
    period_s: float | None = None,
    tx_ids: Sequence[int] | None = None,
    min_range_m: float = 0.0,
    max_range_m: float = 15.0,
    k_noise: float = DEFAULT_K_NOISE,
    k_detect: float = DEFAULT_K_DETECT,
    rel_threshold: float = DEFAULT_REL_THRESHOLD,
    block: int = DEFAULT_BLOCK,
    windows: np.ndarray | None = None,
    first_window: int = 0,
    probe: Probe | None = None,
    fit_transducers: bool = True,
    pool: bool = True,
    transducer_family: str = "resonator",
) -> list[ToF]:
    """One-way (RF-synchronised) ranges from a recording whose sample 0 is the trigger.

    Parameters
    ----------
    x : ndarray, shape (channels, samples) or (samples,)
        The recording; each channel is one receiver.
    fs : float
        Sample rate in Hz; must carry the burst's band (``CodedBurst.band_hz``).
    burst : CodedBurst, optional
        The emitted code (default Barker-7, 40 kHz, 3 cycles per bit; Kim & Kim 2013).
    tx, rx : Transducer or None
        The transducers in the path (default Q = 4 each, as the simulator uses). With
        ``fit_transducers`` they are only the starting point (their f0 centres the fit's
        f0 range, the coarse detection template folds them in); otherwise their responses
        are folded into the template as they are. None leaves one out; both None = the
        bare drive (nothing fitted, the transducers' delay stays in the ranges).
    latency_s : float
        Known system latency from the trigger to the drive's start, subtracted (>= 0).
    temp_c, speed_m_s : float
        Air temperature (sets ``c = 20.05 sqrt(T + 273.16)``), or the speed of sound.
    period_s : float, optional
        Activation period: the file holds consecutive windows of this length (e.g. 0.2 s
        for Kim & Kim's 5 Hz). Default: the whole file is one window.
    tx_ids : sequence of int, optional
        Firing order of the transmitters; window ``k`` is ``tx_ids[k % len(tx_ids)]``.
    min_range_m, max_range_m : float
        Distances the search considers (default 0-15 m).
    k_noise, k_detect, rel_threshold : float
        Detection thresholds (:func:`rangekit.detect.matched.first_path`).
    block : int
        Overlap-save FFT size.
    windows : ndarray of int, shape (n, 2), optional
        Explicit ``[start, stop)`` sample ranges of the windows, instead of ``period_s``
        (each window's time origin is its start). Used to range a long recording a block
        at a time (:mod:`rangekit.ranging.series`): ``x`` then holds the block with the
        matched filter's reach of context on both sides.
    first_window : int
        Number of the first window (window ``k`` of ``windows`` is ``first_window + k``,
        also for ``tx_ids``).
    probe : Probe, optional
        Any other emitted signal (a sweep, a lab's own file): the template is the probe at
        ``fs`` (:meth:`rangekit.signals.probe.Probe.at_rate`); ``burst``, ``tx`` and ``rx``
        are then unused (the recording's own responses stay in the arrival time, which a
        calibration's latency absorbs).
    fit_transducers : bool
        Time each arrival by fitting the drive through two resonators of unknown Q and f0,
        with overlapping reflections (:mod:`rangekit.detect.pathfit`), or through two
        elements of two stagger-tuned resonators each (:mod:`rangekit.detect.stagger`),
        whichever the recording favours per transmitter and receiver
        (:mod:`rangekit.detect.fitted`), so that the range does not depend on knowing the
        transducers (default True; ``docs/theory/ultrasonic.md``). False: the template of
        ``tx`` and ``rx`` is assumed right.
    pool : bool
        With ``fit_transducers``: pool the ``(Q, f0)`` estimates of every window of one
        receiver and transmitter (``tx_ids``; all windows of the receiver without them)
        when they agree, which brings each range's sigma down to the known-transducer
        bound (default True).
    transducer_family : {"resonator", "unknown"}
        With ``fit_transducers``: what is known of the transducers' family before
        measuring. ``"resonator"`` (default): the resonant piezo of Kim & Kim 2013,
        the model choice's sigma as Schwarz's criterion gives it; ``"unknown"``: a
        transducer of any shape, the model choice's sigma from Akaike weights, so that a
        non-resonator transducer's model error is covered (a resonator's sigma 1.7-4.5x
        wider; :mod:`rangekit.detect.fitted`, docs/accuracy.md). Only sigma differs.

    Returns
    -------
    list of ToF
        One entry per (window, channel), sorted; ``distance_m`` NaN where nothing was found.
    """
    from rangekit.detect.fitted import check_transducer_family

    fs = V.sample_rate(fs)
    transducer_family = check_transducer_family(transducer_family, fit=fit_transducers)
    burst = CodedBurst() if burst is None else burst
    if probe is None:
        check_burst_fits(burst, fs=fs)
    else:
        probe.check_fits(fs)
    x = _as_channels(x)
    latency_s = V.positive("latency_s", latency_s, allow_zero=True)
    c = _speed(temp_c, speed_m_s)
    min_range_m = V.positive("min_range_m", min_range_m, allow_zero=True)
    max_range_m = V.positive("max_range_m", max_range_m)
    if max_range_m <= min_range_m:
        raise InvalidParameterError(
            f"max_range_m={max_range_m!r} must exceed min_range_m={min_range_m!r}"
        )
    if tx_ids is not None and len(tx_ids) == 0:
        raise InvalidParameterError("tx_ids must not be empty")
    windows = _windows(
        x.shape[1], fs=fs, period_s=period_s, windows=windows, first_window=first_window
    )
    template = coded_template(burst, fs=fs, tx=tx, rx=rx) if probe is None else probe.at_rate(fs)
    model, q0 = (
        (None, 4.0) if probe is not None else _fit_model(burst, fs, (tx, rx), fit_transducers)
    )
    return _ranges(
        x,
        fs=fs,
        template=template,
        windows=windows,
        lo_s=latency_s + min_range_m / c,
        hi_s=latency_s + max_range_m / c,
        offset_s=latency_s,
        scale=1.0,
        c=c,
        tx_ids=tx_ids,
        thresholds={"k_noise": k_noise, "k_detect": k_detect, "rel_threshold": rel_threshold},
        block=block,
        first_window=first_window,
        model=model,
        q0=q0,
        pool=pool,
        transducer_family=transducer_family,
    )


def _fit_model(burst: CodedBurst, fs: float, transducers, fit: bool, stagger: bool = True):
    """The transducer fit's models and starting Q for ``transducers``, or ``(None, 4)``."""
    from rangekit.detect.fitted import transducer_models

    models, q0 = transducer_models(burst, fs=fs, transducers=transducers)
    if not fit or not models:
        return None, 4.0
    return (models if stagger else models[:1]), q0
