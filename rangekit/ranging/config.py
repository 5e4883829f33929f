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
- :class:`Detection`: the matched filter's first-path thresholds and FFT size
  (:func:`rangekit.detect.matched.first_path`), shared by the ultrasonic schemes.
- :class:`OneWaySetup`: a one-way (RF-synchronised beacon) job, Kim & Kim 2013 §II-A:
  the emitted code, the transducer model, the range window, the schedule (period,
  transmitter order, latency) and the receivers.
- :class:`EchoSetup`: a pulse-echo (SRF02) job, Girard 2011 §2.6: the ping, the
  transducer, the range window (ring-down to timeout) and the cycle period.

Every default of the ultrasonic objects is read from the library
(:func:`~rangekit.ranging.oneway.range_oneway`, :func:`~rangekit.ranging.echo.range_echo`,
:mod:`rangekit.detect.matched`); nothing is restated here or in the CLI.

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
>>> OneWaySetup().max_range_m, EchoSetup().min_range_m, OneWaySetup().channels
(15.0, 0.15, 3)
>>> EchoSetup(min_range_m=2.0, max_range_m=1.0)
Traceback (most recent call last):
...
rangekit.errors.InvalidParameterError: max_range_m=1.0 must exceed min_range_m=2.0
"""

from __future__ import annotations

import inspect
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from rangekit import _validate as V
from rangekit.physics import Medium
from rangekit.ranging.beepbeep import DEFAULT_CLOCK_PPM, self_distances
from rangekit.ranging.series import DEFAULT_SKEW_S
from rangekit.signals.barker import CodedBurst
from rangekit.signals.transducer import Transducer

__all__ = [
    "ONEWAY_RECEIVERS",
    "Detection",
    "EchoSetup",
    "Medium",
    "OneWaySetup",
    "SeriesOptions",
    "TwoWaySetup",
]


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


def _defaults(func) -> dict[str, Any]:
    """The keyword defaults of a library function: where each ultrasonic default lives."""
    return {k: p.default for k, p in inspect.signature(func).parameters.items()}


def _oneway_defaults() -> dict[str, Any]:
    from rangekit.ranging.oneway import range_oneway

    return _defaults(range_oneway)


def _echo_defaults() -> dict[str, Any]:
    from rangekit.ranging.echo import range_echo

    return _defaults(range_echo)


_ONEWAY = _oneway_defaults()
_ECHO = _echo_defaults()

#: Receivers a one-way recording has by default (channels; Kim & Kim 2013's robot carries 3).
ONEWAY_RECEIVERS = 3


@dataclass(frozen=True)
class Detection:
    """First-path detection of the matched filter (:func:`rangekit.detect.matched.first_path`).

    Parameters
    ----------
    k_noise : float
        Noise threshold, in units of the envelope's Rayleigh noise scale (> 0).
    k_detect : float
        Detection threshold of a peak, same unit (> 0).
    rel_threshold : float
        First-path threshold relative to the strongest peak, in (0, 1].
    block : int
        Overlap-save FFT size, >= 16 (raised to fit the template).
    """

    k_noise: float = _ONEWAY["k_noise"]
    k_detect: float = _ONEWAY["k_detect"]
    rel_threshold: float = _ONEWAY["rel_threshold"]
    block: int = _ONEWAY["block"]

    def __post_init__(self) -> None:
        V.positive("k_noise", self.k_noise)
        V.positive("k_detect", self.k_detect)
        V.in_range("rel_threshold", self.rel_threshold, 1e-6, 1.0)
        V.positive_int("block", self.block, minimum=16)

    def kwargs(self) -> dict[str, Any]:
        """As the keywords ``k_noise``, ``k_detect``, ``rel_threshold``, ``block``."""
        return {
            "k_noise": self.k_noise,
            "k_detect": self.k_detect,
            "rel_threshold": self.rel_threshold,
            "block": self.block,
        }


def _check_common(cfg) -> None:
    """The checks :class:`OneWaySetup` and :class:`EchoSetup` share (before any file)."""
    if not isinstance(cfg.burst, CodedBurst):
        raise V.InvalidParameterError(f"burst={cfg.burst!r} must be a CodedBurst")
    if cfg.transducer is not None and not isinstance(cfg.transducer, Transducer):
        raise V.InvalidParameterError(f"transducer={cfg.transducer!r} must be a Transducer or None")
    if cfg.period_s is not None:
        V.in_range("period_s", cfg.period_s, 1e-4, 3600.0)
    V.positive("min_range_m", cfg.min_range_m, allow_zero=True)
    V.positive("max_range_m", cfg.max_range_m)
    if cfg.max_range_m <= cfg.min_range_m:
        raise V.InvalidParameterError(
            f"max_range_m={cfg.max_range_m!r} must exceed min_range_m={cfg.min_range_m!r}"
        )
    if cfg.channels is not None:
        V.positive_int("channels", cfg.channels)
    if not isinstance(cfg.detection, Detection):
        raise V.InvalidParameterError(f"detection={cfg.detection!r} must be a Detection")
    if cfg.transducer_family != "resonator":  # the default imports no fit
        from rangekit.detect.fitted import check_transducer_family

        fit = getattr(cfg, "fit_transducers", getattr(cfg, "fit_transducer", True))
        check_transducer_family(
            cfg.transducer_family,
            fit=fit and cfg.transducer is not None,
            fit_name="a fitted transducer: Q auto",
        )


def _family_kwargs(cfg) -> dict[str, Any]:
    """``{"transducer_family": ...}`` when it is not the default, else ``{}``: a default
    job's keywords (and a batch's resume fingerprint of them) stay what they were."""
    fam = cfg.transducer_family
    return {} if fam == "resonator" else {"transducer_family": fam}


@dataclass(frozen=True)
class OneWaySetup:
    """A one-way (RF-synchronised beacon) ranging job (Kim & Kim 2013 §II-A).

    Sample 0 of a recording is the trigger; distances are ``c (arrival - latency_s)``
    (:func:`rangekit.ranging.oneway.range_oneway`, whose defaults these are).

    Parameters
    ----------
    burst : CodedBurst
        The emitted code [default: Barker-7, 40 kHz, 3 cycles per chip]; its rate is
        replaced by each file's.
    transducer : Transducer or None
        Model of the Tx and the Rx transducers [default: Q 4 at 40 kHz]; None = the bare
        drive (the transducers' delay stays in the ranges).
    fit_transducers : bool
        Fit each arrival through resonators of unknown Q and f0 (``transducer`` is then
        only the starting point); False folds ``transducer`` into the template as it is.
    transducer_family : {"resonator", "unknown"}
        With the fit: the resonant piezo of the papers (default), or a transducer of any
        shape, whose model error the sigma then covers
        (:func:`~rangekit.ranging.oneway.range_oneway`).
    latency_s : float
        System latency from the trigger to the drive, s, subtracted (>= 0).
    period_s : float, optional
        The file holds consecutive activation windows of this length, s [default: one].
    tx_ids : sequence of int, optional
        Transmitter id of each window, repeating (kept as a tuple).
    min_range_m, max_range_m : float
        Distances searched, m [default: 0-15].
    channels : int or None
        Channel (receiver) count every file must have; None accepts any [default: 3].
    detection : Detection
        First-path thresholds.
    """

    burst: CodedBurst = field(default_factory=CodedBurst)
    transducer: Transducer | None = _ONEWAY["tx"]
    fit_transducers: bool = _ONEWAY["fit_transducers"]
    transducer_family: str = _ONEWAY["transducer_family"]
    latency_s: float = _ONEWAY["latency_s"]
    period_s: float | None = _ONEWAY["period_s"]
    tx_ids: tuple[int, ...] | None = _ONEWAY["tx_ids"]
    min_range_m: float = _ONEWAY["min_range_m"]
    max_range_m: float = _ONEWAY["max_range_m"]
    channels: int | None = ONEWAY_RECEIVERS
    detection: Detection = field(default_factory=Detection)

    def __post_init__(self) -> None:
        _check_common(self)
        V.in_range("latency_s", self.latency_s, 0.0, 10.0)
        if self.tx_ids is not None:
            ids = tuple(self.tx_ids)
            if not ids or any(isinstance(i, bool) or int(i) != i or i < 0 for i in ids):
                raise V.InvalidParameterError(
                    f"tx_ids={self.tx_ids!r} must be a non-empty sequence of whole numbers >= 0"
                )
            object.__setattr__(self, "tx_ids", tuple(int(i) for i in ids))

    def kwargs(self) -> dict[str, Any]:
        """As the keywords of :func:`~rangekit.ranging.ultrasonic.range_ultrasonic_files`
        (``channels``, ``burst``, and :func:`~rangekit.ranging.oneway.range_oneway`'s)."""
        return {
            "channels": self.channels,
            "burst": self.burst,
            "period_s": self.period_s,
            "tx": self.transducer,
            "rx": self.transducer,
            "fit_transducers": self.fit_transducers,
            **_family_kwargs(self),
            "latency_s": self.latency_s,
            "tx_ids": None if self.tx_ids is None else list(self.tx_ids),
            "min_range_m": self.min_range_m,
            "max_range_m": self.max_range_m,
            **self.detection.kwargs(),
        }


def _srf02_ping() -> CodedBurst:
    from rangekit.signals.barker import srf02_ping

    return srf02_ping()


@dataclass(frozen=True)
class EchoSetup:
    """A pulse-echo (SRF02-style) ranging job (Girard 2011 §2.6).

    Sample 0 of a recording is the ping; the distance is ``c t / 2`` of the earliest echo
    (:func:`rangekit.ranging.echo.range_echo`, whose defaults these are).

    Parameters
    ----------
    burst : CodedBurst
        The ping [default: the SRF02's, 8 cycles of 40 kHz].
    transducer : Transducer or None
        The transducer (it sends and receives) [default: Q 4 at 40 kHz]; None = the bare
        drive.
    fit_transducer : bool
        Fit each echo through the transducer twice with Q and f0 unknown (``transducer``
        is then only the starting point); False folds ``transducer`` into the template
        as it is.
    transducer_family : {"resonator", "unknown"}
        With the fit: as :class:`OneWaySetup`.
    period_s : float, optional
        The file holds consecutive ranging cycles of this length, s (0.07 for the SRF02,
        :data:`~rangekit.ranging.echo.SRF02_CYCLE_S`) [default: one].
    min_range_m, max_range_m : float
        Distances searched, m [default: the SRF02's 0.15 ring-down to 6].
    channels : int or None
        Channel (sensor) count every file must have [default: any].
    detection : Detection
        First-path thresholds.
    """

    burst: CodedBurst = field(default_factory=_srf02_ping)
    transducer: Transducer | None = _ECHO["transducer"]
    fit_transducer: bool = _ECHO["fit_transducer"]
    transducer_family: str = _ECHO["transducer_family"]
    period_s: float | None = _ECHO["period_s"]
    min_range_m: float = _ECHO["min_range_m"]
    max_range_m: float = _ECHO["max_range_m"]
    channels: int | None = None
    detection: Detection = field(default_factory=Detection)

    def __post_init__(self) -> None:
        _check_common(self)

    def kwargs(self) -> dict[str, Any]:
        """As the keywords of :func:`~rangekit.ranging.ultrasonic.range_ultrasonic_files`
        (``channels``, ``burst``, and :func:`~rangekit.ranging.echo.range_echo`'s)."""
        return {
            "channels": self.channels,
            "burst": self.burst,
            "period_s": self.period_s,
            "transducer": self.transducer,
            "fit_transducer": self.fit_transducer,
            **_family_kwargs(self),
            "min_range_m": self.min_range_m,
            "max_range_m": self.max_range_m,
            **self.detection.kwargs(),
        }
