"""Time-of-flight ranging core shared by one-way and pulse-echo ultrasonic ranging.

The result type (:class:`ToF`), the layout of activation windows in a recording
(:func:`window_starts`), and the per-channel, per-window loop that turns first-path
arrivals (:func:`rangekit.detect.matched.detect_matched`, or the transducer fit of
:func:`rangekit.detect.fitted.fit_channel`) into distances ``scale * c * (t - offset)``.
The schemes are :mod:`rangekit.ranging.oneway` and :mod:`rangekit.ranging.echo`; files,
formatting and traces are in :mod:`rangekit.ranging.ultrasonic`.

Examples
--------
>>> window_starts(1000, fs=100.0, period_s=2.5).tolist()
[[0, 250], [250, 500], [500, 750], [750, 1000]]
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rangekit import _validate as V
from rangekit.detect.matched import detect_matched
from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.physics import Medium
from rangekit.signals.transducer import Transducer

__all__ = ["ToF", "window_starts"]

#: The transducer both schemes assume by default (Q 4 at 40 kHz, as the simulator).
_DEFAULT_TX = Transducer()


@dataclass(frozen=True)
class ToF:
    """One time-of-flight range.

    Attributes
    ----------
    window : int
        Activation window (one-way) or ranging cycle (echo), from 0.
    tx : int or None
        Transmitter id of the window (one-way with a firing order), else None.
    channel : int
        Receiver (channel of the recording), from 0.
    distance_m : float
        Distance in metres; NaN when nothing was detected (out of range).
    sigma_m : float
        1-sigma of the distance from the detection SNR (Cramér–Rao), metres; NaN if none.
    snr_db : float
        Matched-filter output SNR ``10 log10(2 E / N0)``; NaN if none.
    arrival_s : float
        Arrival time from the window's start (latency included), seconds; NaN if none.
    flags : tuple of str
        The arrival's flags (:data:`rangekit.types.ARRIVAL_FLAGS`: ``low_snr``,
        ``poor_match``, ``ambiguous_first_path``); empty when none or nothing detected.
    sigma_transducer_m : float
        The part of ``sigma_m`` (included in it) that is the transducers' own delay,
        the same for every range through the same Tx and receiver, so that a one-point
        calibration of the link absorbs it (``Arrivals.sigma_transducer``; the model-order
        term of :func:`rangekit.detect.fitted.order_terms`); 0 when none.
    """

    window: int
    tx: int | None
    channel: int
    distance_m: float
    sigma_m: float
    snr_db: float
    arrival_s: float
    flags: tuple[str, ...] = ()
    sigma_transducer_m: float = 0.0

    def as_dict(self) -> dict:
        """Plain-JSON form; NaN becomes None (null)."""

        def f(v: float) -> float | None:
            return None if not math.isfinite(v) else float(v)

        return {
            "window": self.window,
            "tx": self.tx,
            "channel": self.channel,
            "distance_m": f(self.distance_m),
            "sigma_m": f(self.sigma_m),
            "snr_db": f(self.snr_db),
            "arrival_s": f(self.arrival_s),
        }


def window_starts(n_samples: int, *, fs: float, period_s: float | None) -> np.ndarray:
    """``[start, stop)`` sample ranges of consecutive windows of ``period_s`` (one if None).

    A last window shorter than half a period is dropped (an activation cut off by the end
    of the recording).

    Examples
    --------
    >>> window_starts(1000, fs=100.0, period_s=2.5).tolist()
    [[0, 250], [250, 500], [500, 750], [750, 1000]]
    >>> window_starts(1000, fs=100.0, period_s=None).tolist()
    [[0, 1000]]
    """
    if period_s is None:
        return np.array([[0, n_samples]], dtype=np.int64)
    period_s = V.positive("period_s", period_s)
    per = period_s * fs
    if per < 2:
        raise InvalidParameterError(f"period_s={period_s!r} is shorter than two samples")
    k = np.arange(int(math.floor(n_samples / per + 0.5)) + 1)
    starts = np.round(k * per).astype(np.int64)
    starts = starts[starts < n_samples]
    stops = np.minimum(np.append(starts[1:], n_samples), n_samples)
    keep = (stops - starts) >= 0.5 * per
    if not keep.any():
        raise IncompatibleInputError(
            f"the recording ({n_samples / fs:g} s) is shorter than half a period "
            f"({period_s:g} s): no window to range"
        )
    return np.stack([starts[keep], stops[keep]], axis=1)


def _as_channels(x: np.ndarray) -> np.ndarray:
    """``(channels, samples)``; float32 recordings stay float32 (no float64 copy)."""
    a = np.asarray(x)
    if a.dtype != np.float32:
        a = np.asarray(x, dtype=np.float64)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] < 2:
        raise InvalidParameterError(f"x must be (channels, samples), got shape {a.shape}")
    return a


def _ranges(
    x: np.ndarray,
    *,
    fs: float,
    template: np.ndarray,
    windows: np.ndarray,
    lo_s: float,
    hi_s: float,
    offset_s: float,
    scale: float,
    c: float,
    tx_ids: Sequence[int] | None,
    thresholds: dict,
    block: int,
    first_window: int = 0,
    model=None,
    q0: float = 4.0,
    pool: bool = True,
    transducer_family: str = "resonator",
) -> list[ToF]:
    """Shared core: per channel, per window first paths -> distances ``scale*c*(t - off)``.

    Window ``w`` of ``windows`` is numbered ``first_window + w`` (its transmitter too).
    With ``model`` the arrivals are timed by the transducer fit, whose ``(Q, f0)``
    estimates are pooled per channel and transmitter (``tx_ids``; all windows of a channel
    when None), its model-choice variance by ``transducer_family``
    (:func:`rangekit.detect.fitted.fit_channel`).
    """
    lo = max(0, int(math.floor(lo_s * fs)) - 1)
    hi = int(math.ceil(hi_s * fs)) + 2
    rows: list[ToF] = []
    groups = None
    if tx_ids is not None:
        k = first_window + np.arange(len(windows))
        groups = np.asarray(tx_ids, dtype=np.int64)[k % len(tx_ids)]
    per_channel = []
    if model is None:
        for ch in range(x.shape[0]):
            per_channel.append(
                detect_matched(
                    x[ch],
                    fs=fs,
                    template=template,
                    windows=windows,
                    search=(lo, hi),
                    block=block,
                    **thresholds,
                )
            )
    else:
        from rangekit.detect.fitted import (
            check_shapes,
            fit_channel,
            order_terms,
            with_order_terms,
        )

        cf = [
            fit_channel(
                x[ch],
                fs=fs,
                template=template,
                models=model,
                windows=windows,
                search=(lo, hi),
                block=block,
                q0=q0,
                groups=groups,
                pool=pool,
                transducer_family=transducer_family,
                **thresholds,
            )
            for ch in range(x.shape[0])
        ]
        # A transducer's shape is the same through every receiver (multipath is not):
        # a receiver that disagrees with the others is refitted at their shape, and
        # without a consensus the resonator times that transmitter's arrivals.
        forces = check_shapes(cf) if pool else [{} for _ in cf]
        # A transducer of higher order than both models: its onset's model-order term,
        # from the first fits (a refit held at a consensus shape compares no models).
        terms = order_terms(cf)
        cf = [
            fit_channel(
                x[ch], fs=fs, template=template, models=model, windows=windows,
                search=(lo, hi), block=block, q0=q0, groups=groups, pool=pool,
                force=forces[ch], transducer_family=transducer_family, **thresholds,
            )
            if forces[ch]
            else f
            for ch, f in enumerate(cf)
        ]  # fmt: skip
        per_channel = [with_order_terms(f, t) for f, t in zip(cf, terms, strict=True)]
    for ch, arr in enumerate(per_channel):
        found = dict(zip(arr.window.tolist(), range(len(arr)), strict=True))
        for w, (s0, _) in enumerate(windows):
            k = first_window + w
            tx = None if tx_ids is None else int(tx_ids[k % len(tx_ids)])
            i = found.get(w)
            if i is None:
                rows.append(ToF(k, tx, ch, math.nan, math.nan, math.nan, math.nan))
                continue
            t = (arr.onset[i] - s0) / fs
            d = scale * c * (t - offset_s)
            sig = scale * c * arr.sigma[i] / fs
            fl = arr.flag_names(i)
            st = float(scale * c * arr.sigma_transducer[i] / fs)
            snr = float(arr.snr_db[i])
            rows.append(ToF(k, tx, ch, float(d), float(sig), snr, float(t), fl, st))
    rows.sort(key=lambda r: (r.window, r.channel))
    return rows


def _windows(
    n_samples: int,
    *,
    fs: float,
    period_s: float | None,
    windows: np.ndarray | None,
    first_window: int,
) -> np.ndarray:
    """The windows to range: ``window_starts`` of ``period_s``, or checked explicit ones."""
    V.positive_int("first_window", first_window, minimum=0)
    if windows is None:
        return window_starts(n_samples, fs=fs, period_s=period_s)
    if period_s is not None:
        raise InvalidParameterError("give period_s or windows, not both")
    w = np.asarray(windows)
    if (
        w.ndim != 2
        or w.shape[1] != 2
        or len(w) == 0
        or not np.issubdtype(w.dtype, np.integer)
        or np.any(w[:, 0] < 0)
        or np.any(w[:, 1] > n_samples)
        or np.any(w[:, 1] - w[:, 0] < 2)
    ):
        raise InvalidParameterError(
            f"windows must be integer [start, stop) rows of >= 2 samples within the "
            f"{n_samples} samples, got shape {w.shape}"
        )
    return w.astype(np.int64)


def _speed(temp_c: float, speed_m_s: float | None) -> float:
    return Medium(temp_c=temp_c, speed_m_s=speed_m_s).c
