"""From recordings to ranges: the one entry point the CLI and batch processing call."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from rangekit.detect import DETECTORS, detect
from rangekit.detect.changepoint import find_bursts
from rangekit.errors import DetectionError, InvalidParameterError
from rangekit.io.audio import Channel, load_devices
from rangekit.physics import DEFAULT_TEMP_C
from rangekit.ranging.beepbeep import DEFAULT_CLOCK_PPM, range_beepbeep
from rangekit.ranging.calibration import Calibration
from rangekit.ranging.config import Medium, TwoWaySetup
from rangekit.signals.beep import Beep
from rangekit.signals.probe import Probe
from rangekit.types import Arrivals, RangeResult

__all__ = ["detect_channel", "range_channels", "range_files"]


def _spacing_hint(onsets: np.ndarray, *, beep: Beep, fs: float) -> str:
    """Explain why bursts were found but no beep: their spacing does not fit."""
    if len(onsets) < 2:
        return ""
    d = np.diff(np.sort(onsets))
    d = d[d > 0.3 * beep.spacing_s * fs]
    if len(d) == 0:
        return ""
    seen = float(np.median(d))
    want = beep.spacing_s * fs
    if abs(seen - want) <= 0.25 * beep.burst_s * fs:
        return ""
    return (
        f"; burst spacing does not fit: bursts are {seen:.0f} samples apart but the beep's "
        f"spacing is {want:.0f} samples ({beep.spacing_s * 1e3:.1f} ms); check --spacing"
    )


def detect_channel(
    ch: Channel,
    *,
    beep: Beep | None = None,
    detector: str = "changepoint",
    expected: int | None = None,
    probe: Probe | None = None,
    spectra=None,
) -> Arrivals:
    """Detect what was played in one device's recording; explain when too few are found.

    Detection is :func:`rangekit.detect.detect` of ``probe`` (method ``template``) when
    given, else of ``beep`` (default the rangekit beep) with ``detector``; ``spectra``
    (the template method's noise weighting, shared by an exchange's devices) is passed on.
    """
    beep = Beep() if beep is None else beep
    signal = beep if probe is None else probe
    method = "template" if probe is not None else detector
    kw = {"spectra": spectra} if method == "template" and spectra is not None else {}
    arr = detect(
        ch.x, fs=ch.fs, signal=signal, method=method, expected=expected, what=f"'{ch.source}'", **kw
    )
    if expected is not None and len(arr) < expected:
        if probe is not None:
            found = "no arrival" if len(arr) == 0 else f"{len(arr)} arrival(s)"
            raise DetectionError(
                f"'{ch.source}': found {found} of probe '{probe.name}' but expected "
                f"{expected} (one per device); check that this is the probe that was played"
            )
        # Only on failure: the individual bursts tell whether their spacing is the problem.
        cand = find_bursts(ch.x, fs=ch.fs, beep=beep)
        hint = _spacing_hint(cand.onset, beep=beep, fs=ch.fs)
        found = "no beep" if len(arr) == 0 else f"{len(arr)} beep(s)"
        raise DetectionError(
            f"'{ch.source}': found {found} but expected {expected} (one per device){hint}"
        )
    if expected is not None and len(arr) > expected:
        raise DetectionError(
            f"'{ch.source}': found {len(arr)} beeps but expected {expected} (one per device); "
            "is this one exchange? run `rangekit detect` on the file to see them"
        )
    return arr


def range_channels(
    channels: Sequence[Channel],
    *,
    beep: Beep | None = None,
    detector: str = "changepoint",
    temp_c: float = DEFAULT_TEMP_C,
    speed_m_s: float | None = None,
    self_distance_m: float | Sequence[float] = 0.0,
    clock_ppm: float = DEFAULT_CLOCK_PPM,
    probe: Probe | None = None,
    calibration: Calibration | None = None,
    medium: Medium | None = None,
    setup: TwoWaySetup | None = None,
) -> RangeResult:
    """Two-way ranges between devices from their recordings (device i = channel i).

    Parameters
    ----------
    channels : sequence of Channel
        One recording per device, in play order.
    beep : Beep, optional
        The beep that was played (default: the rangekit beep).
    detector : {"changepoint", "xcorr"}
        Arrival detection method for the beep (:data:`rangekit.detect.METHODS`).
    temp_c : float
        Air temperature in degrees Celsius (sets the speed of sound).
    speed_m_s : float, optional
        Speed of sound; overrides ``temp_c``.
    self_distance_m : float or sequence of float
        Speaker-to-microphone distance of the devices, metres.
    clock_ppm : float
        1-sigma sample-clock tolerance per device, ppm (uncertainty only).
    probe : Probe, optional
        The signal every device played, when it is not the beep (a sweep, a lab's own
        file): arrivals by matched filtering with first-path selection
        (:func:`rangekit.detect.template.detect_template`).
    calibration : Calibration, optional
        A two-way calibration (:func:`rangekit.ranging.calibration.fit_calibration`) to
        apply: its offset replaces ``self_distance_m`` (which must then be 0) and a fitted
        speed of sound replaces ``temp_c``/``speed_m_s``.
    medium : Medium, optional
        The air (:class:`rangekit.ranging.config.Medium`); replaces ``temp_c`` and
        ``speed_m_s`` (built from them when not given).
    setup : TwoWaySetup, optional
        Self-distances and clock tolerance (:class:`rangekit.ranging.config.TwoWaySetup`);
        replaces ``self_distance_m`` and ``clock_ppm`` (built from them when not given).
    """
    beep = Beep() if beep is None else beep
    n = len(channels)
    # Every parameter is checked (once, by the configuration objects) before detection.
    medium = Medium(temp_c=temp_c, speed_m_s=speed_m_s) if medium is None else medium
    if setup is None:
        setup = TwoWaySetup(self_distance_m=self_distance_m, clock_ppm=clock_ppm)
    c = medium.c
    self_distance_m, clock_ppm = setup.self_distance_m, setup.clock_ppm
    setup.self_distances(n)
    if detector not in DETECTORS:
        raise InvalidParameterError(f"detector={detector!r} must be one of {', '.join(DETECTORS)}")
    arrivals, errors = [], []
    if calibration is not None:
        calibration.check_scheme("beepbeep")
        if np.any(setup.self_distances(n) != 0):
            raise InvalidParameterError(
                "give self_distance_m or a calibration, not both: the calibration's offset "
                "already holds the speaker-to-microphone distances"
            )
    spectra = _common_spectra(channels, probe) if probe is not None else None
    for ch in channels:
        try:
            arrivals.append(
                detect_channel(
                    ch, beep=beep, detector=detector, expected=n, probe=probe, spectra=spectra
                )
            )
        except DetectionError as e:
            errors.append(str(e))
    if errors:
        raise DetectionError("; ".join(errors))
    result = range_beepbeep(
        arrivals, speed_m_s=c, self_distance_m=self_distance_m, clock_ppm=clock_ppm
    )
    return result if calibration is None else calibration.apply(result)


def _common_spectra(channels: Sequence[Channel], probe: Probe):
    """One noise spectrum for every device's probe filter (the bin-wise maximum), so the
    weighting's share of the transducers' dispersion is the same in every onset and
    cancels in two-way ranging (``docs/theory/probes.md``); None when the rates (or the
    spectra's grids) differ: each recording is then weighted by its own."""
    from rangekit.detect.matched import common_spectra
    from rangekit.detect.template import noise_spectra

    if len({ch.fs for ch in channels}) != 1:
        return None
    spectra = [noise_spectra(ch.x, fs=ch.fs, probe=probe) for ch in channels]
    if len({len(sp.f_hz) for sp in spectra}) != 1:
        return None  # a recording too short for the full segment length
    return common_spectra(spectra)


def range_files(
    paths: Sequence[str | os.PathLike],
    *,
    scheme: str = "beepbeep",
    **kw,
) -> RangeResult:
    """Two-way ranges from one multichannel WAV or one mono WAV per device.

    Keyword arguments are those of :func:`range_channels`.
    """
    if scheme != "beepbeep":
        raise InvalidParameterError(f"scheme={scheme!r} must be 'beepbeep'")
    return range_channels(load_devices(paths, min_devices=2), **kw)
