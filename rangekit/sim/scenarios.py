"""The scenarios of ``rangekit synth``: devices placed, rendered, impaired, ready to write.

One call per ``synth`` command (:func:`synth_beepbeep`, :func:`synth_oneway`,
:func:`synth_echo`) builds the scene from plain parameters, renders it with
:func:`rangekit.sim.render_beepbeep` / :func:`rangekit.sim.render_exchanges` /
:func:`rangekit.sim.ultrasonic.render_oneway` / :func:`~rangekit.sim.ultrasonic.render_echo`,
applies the real-recording impairments (:mod:`rangekit.sim.impair`) and returns a
:class:`Synthesis`: the WAV arrays and the JSON sidecar (the simulator's truth, with the
``setup`` part a user knows before measuring). :meth:`Synthesis.write` writes them.
``rangekit synth`` only parses its options into these calls, so a recording made from
Python equals the command's, sample for sample (tests/sim/test_scenarios.py).

Examples
--------
>>> import pathlib, tempfile
>>> syn = synth_beepbeep(distance_m=2.0, seed=1)
>>> [x.shape[1] for x in syn.recordings], syn.truth["pairs"][0]["distance_m"]
([2], 2.0)
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> [p.name for p in syn.write(d / "x.wav")]
['x.wav', 'x.json']
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rangekit.errors import InvalidParameterError
from rangekit.physics import DEFAULT_TEMP_C

__all__ = [
    "DEFAULT_TXS",
    "Synthesis",
    "impair_recordings",
    "synth_beepbeep",
    "synth_echo",
    "synth_oneway",
]

#: ``synth oneway`` without transmitters: six on a 1.5 m x 1.5 m grid around the origin.
DEFAULT_TXS = tuple((x, y) for y in (-0.75, 0.75) for x in (-1.5, 0.0, 1.5))


@dataclass
class Synthesis:
    """Rendered recordings and their sidecar, ready to write.

    Attributes
    ----------
    recordings : list of ndarray
        One array per WAV file (samples, or samples x channels), within [-1, 1].
    fs : float
        Sample rate of every file, Hz.
    truth : dict
        The sidecar: the simulator's truth and its ``setup``; ``files`` (and ``beacons``)
        are filled in from the output name by :meth:`sidecar`.
    mono : bool
        One WAV per device (``NAME_devI.wav``) instead of one multichannel file.
    extras : dict of str to object
        Further JSON files by suffix (``".beacons.json"``: the beacon file).
    """

    recordings: list[np.ndarray]
    fs: float
    truth: dict[str, Any]
    mono: bool = False
    extras: dict[str, Any] = field(default_factory=dict)

    def audio_paths(self, output: str | os.PathLike) -> list[Path]:
        """The WAV files :meth:`write` writes for ``output``."""
        out = Path(output)
        if self.mono:
            return [
                out.with_name(f"{out.stem}_dev{i}{out.suffix or '.wav'}")
                for i in range(len(self.recordings))
            ]
        return [out]

    def paths(self, output: str | os.PathLike) -> list[Path]:
        """Every file :meth:`write` writes: the WAVs, the sidecar, the extras."""
        out = Path(output)
        return [*self.audio_paths(out), out.with_suffix(".json")] + [
            out.with_suffix(s) for s in self.extras
        ]

    def sidecar(self, output: str | os.PathLike) -> dict[str, Any]:
        """:attr:`truth` with the names of the files written for ``output``."""
        out = Path(output)
        truth = dict(self.truth)
        truth["files"] = [f.name for f in self.audio_paths(out)]
        if ".beacons.json" in self.extras:
            truth["beacons"] = out.with_suffix(".beacons.json").name
        return truth

    def write(self, output: str | os.PathLike, *, inputs: Sequence[str] = ()) -> list[Path]:
        """Write the recordings (16-bit PCM), the sidecar and the extras; returns the paths.

        Every path is checked first (:func:`rangekit.io.guard.check_output`: not a link,
        a directory or a device, nor one of ``inputs``), so nothing is written when one
        is refused.
        """
        from rangekit.io.audio import write_audio
        from rangekit.io.guard import check_output
        from rangekit.io.sidecar import write_json

        out = Path(output)
        paths = self.paths(out)
        for p in paths:
            check_output(p, list(inputs))
        for f, x in zip(self.audio_paths(out), self.recordings, strict=True):
            write_audio(f, x, fs=self.fs)
        write_json(out.with_suffix(".json"), self.sidecar(out))
        for suffix, obj in self.extras.items():
            write_json(out.with_suffix(suffix), obj)
        return paths


def impair_recordings(
    impairments,
    recordings: Sequence[np.ndarray],
    *,
    fs: float,
    seed: int | None,
    floor_psd: Sequence,
    truth: dict,
) -> tuple[list[np.ndarray], dict]:
    """Apply ``impairments`` to each recording and clip at full scale as a 16-bit ADC would.

    Parameters
    ----------
    impairments : rangekit.sim.impair.Impairments or None
        What to add (None: the recordings and ``truth`` are returned as given).
    recordings : sequence of ndarray
        One WAV's samples each.
    fs : float
        Sample rate, Hz.
    seed : int or None
        The render's seed; the impairments draw from ``[seed, 1]``, a stream apart, so
        the same seed renders the same recording with or without them.
    floor_psd : sequence
        Per recording, the simulator's noise floor (one value or one per channel).
    truth : dict
        The sidecar; returned moved by the silence padding (``shift_truth``) with its
        ``impairments`` record.
    """
    from rangekit.sim.impair import impair, shift_truth

    if impairments is None:
        return list(recordings), truth
    rng = np.random.default_rng(None if seed is None else [seed, 1])
    out, clipped, full, floors, shift = [], [], [], [], 0
    for x, floor in zip(recordings, floor_psd, strict=True):
        r = impair(x, fs=fs, impairments=impairments, rng=rng, floor_psd=floor)
        over = np.abs(r.x) > 1.0
        full += np.atleast_1d(over.mean(axis=0)).tolist()
        out.append(np.clip(r.x, -1.0, 1.0))
        clipped += r.clipped_fraction.tolist()
        floors += r.floor_psd.tolist()
        shift = r.shift_samples
    truth = shift_truth(truth, shift)
    truth["impairments"] = {
        **impairments.as_dict(),
        "spec": impairments.spec(),
        "shift_samples": shift,
        "shift_s": shift / fs,
        "clipped_fraction": clipped,
        "full_scale_clipped_fraction": full,
        "floor_psd": floors,
    }
    return out, truth


def synth_beepbeep(
    *,
    distance_m: float | None = None,
    positions_m: Sequence[Sequence[float]] | None = None,
    self_distance_m: float = 0.1,
    snr_db: float | None = 20.0,
    noise: str = "white",
    room=None,
    temp_c: float = DEFAULT_TEMP_C,
    clock_ppm: float | Sequence[float] = 0.0,
    fs: float = 44100.0,
    mono: bool = False,
    exchanges: int = 1,
    period_s: float = 3.0,
    jitter_s: float = 0.0,
    seed: int | None = None,
    beep=None,
    probe=None,
    impairments=None,
    progress: Callable[[int, int], None] | None = None,
) -> Synthesis:
    """A BeepBeep exchange (or a series of them): every device plays in turn, device 0 first.

    Parameters
    ----------
    distance_m : float, optional
        Two devices this far apart (:func:`rangekit.sim.pair_devices`), centred at
        (0, 0, 1.2) m or in the middle of ``room``.
    positions_m : sequence of (x, y, z), optional
        One device per position instead (at least 2): speaker ``self_distance_m / 2``
        below, microphone above.
    self_distance_m : float
        Speaker-to-microphone distance of every device, m.
    snr_db : float or None
        SNR of the weakest direct beep, dB; None for no noise.
    noise : {"white", "pink"}
    room : rangekit.sim.ShoeboxRoom, optional
        Reflections; None for free field.
    temp_c : float
        Air temperature, °C.
    clock_ppm : float or sequence of float
        Sample-clock error per device (one for all, or one each), ppm.
    fs : float
        Recording sample rate, Hz.
    mono : bool
        One mono recording per device instead of one multichannel recording (the
        channels cut to the shortest device's length).
    exchanges : int
        Exchanges in the recording, ``period_s`` apart (:func:`rangekit.sim.render_exchanges`
        when > 1, with each gap lengthened by a uniform time in ``[0, jitter_s]``).
    seed : int, optional
        Seed of the recording starts (uniform in 0-0.1 s), the jitter and the noise.
    beep : rangekit.signals.Beep, optional
        The beep played (default ``Beep()``); ``probe`` replaces it.
    probe : rangekit.signals.probe.Probe, optional
        A probe signal played instead (e.g. from :func:`rangekit.signals.read_probe`);
        the setup names it by ``probe.name`` (its file for a probe read from one).
    impairments : rangekit.sim.impair.Impairments, optional
        Real recordings' impairments (:func:`impair_recordings`).
    progress : callable, optional
        ``progress(done, total)`` while a series renders (``exchanges > 1``).

    Returns
    -------
    Synthesis
        The recordings and the sidecar (positions, every device's true onsets, each
        pair's true distance, ``exchanges`` for a series, and ``setup``).

    Raises
    ------
    InvalidParameterError
        Neither or both of ``distance_m`` and ``positions_m``, fewer than 2 positions, a
        ``clock_ppm`` list of the wrong length, or a render parameter out of its domain.
    """
    from rangekit.signals import Beep
    from rangekit.sim import Device, pair_devices, render_beepbeep
    from rangekit.sim.impair import noise_floor_psd

    rng = np.random.default_rng(seed)
    if (positions_m is None) == (distance_m is None):
        raise InvalidParameterError("give distance_m or positions_m (one of them)")
    beep = Beep() if beep is None and probe is None else beep
    pts = None if positions_m is None else [np.asarray(p, dtype=float) for p in positions_m]
    if pts is not None and len(pts) < 2:
        raise InvalidParameterError("positions_m needs at least 2 positions (one per device)")
    n = len(pts) if pts is not None else 2
    clock = np.atleast_1d(np.asarray(clock_ppm, dtype=float))
    if len(clock) not in (1, n):
        raise InvalidParameterError(f"clock_ppm: {len(clock)} values for {n} devices")
    clock = np.broadcast_to(clock, (n,))
    starts = rng.uniform(0.0, 0.1, n)
    if pts is not None:
        up = np.array([0.0, 0.0, 0.5 * self_distance_m])
        devices = [
            Device(p - up, p + up, rec_start_s=float(starts[i]), clock_ppm=float(clock[i]), fs=fs)
            for i, p in enumerate(pts)
        ]
    else:
        center = (0.0, 0.0, 1.2) if room is None else tuple(0.5 * np.array(room.size_m))
        devices = pair_devices(
            distance_m,
            self_distance_m=self_distance_m,
            center_m=center,
            rec_start_s=tuple(float(s) for s in starts),
            clock_ppm=tuple(float(c) for c in clock),
            fs=fs,
        )
    common = {"temp_c": temp_c, "snr_db": snr_db, "noise": noise, "room": room, "rng": rng}
    signal = probe if probe is not None else beep
    if exchanges == 1:
        sim = render_beepbeep(devices, beep=signal, **common)
    else:
        from rangekit.sim.exchanges import render_exchanges

        source = signal.as_probe()
        sim = render_exchanges(
            devices,
            source=source.samples,
            source_fs=source.fs,
            n_exchanges=exchanges,
            period_s=period_s,
            jitter_s=jitter_s,
            progress=progress,
            **common,
        )
    floors = [
        noise_floor_psd(d["noise_sigma"], fs=fs, kind=noise, n_samples=len(x))
        for d, x in zip(sim.truth["devices"], sim.recordings, strict=True)
    ]
    if mono:
        recordings = sim.recordings
    else:
        length = min(len(x) for x in sim.recordings)
        recordings, floors = [np.stack([x[:length] for x in sim.recordings], axis=1)], [floors]
    recordings, truth = impair_recordings(
        impairments, recordings, fs=fs, seed=seed, floor_psd=floors, truth=dict(sim.truth)
    )
    truth["seed"] = seed
    truth["setup"] = {  # what a user knows before measuring (rangekit.io.setup)
        "scheme": "beepbeep",
        "self_distance_m": [float(d["self_distance_m"]) for d in truth["devices"]],
        "temp_c": temp_c,
        "signal": {"probe": probe.name} if probe is not None else {"beep": truth.get("beep")},
    }
    return Synthesis(recordings, fs, truth, mono=mono)


def _ultrasonic(x: np.ndarray, truth: dict, *, peak: float, fs: float, seed, impairments):
    """The WAV samples of an ultrasonic render (scaled to ``peak``, then impaired with the
    render's white-noise floor) and a copy of its truth."""
    from rangekit.sim.impair import noise_floor_psd

    scale = peak / float(np.max(np.abs(x)))
    floor = noise_floor_psd(truth["noise_sigma"] * scale, fs=fs)
    (x,), truth = impair_recordings(
        impairments, [x * scale], fs=fs, seed=seed, floor_psd=[floor], truth=truth
    )
    return x, dict(truth)


def synth_oneway(
    *,
    txs_m: Sequence[Sequence[float]] = DEFAULT_TXS,
    ceiling_m: float = 2.011,
    pose: Sequence[float] = (0.0, 0.0, 0.0),
    radius_m: float = 0.19,
    n_windows: int | None = None,
    period_s: float = 0.2,
    latency_s: float = 0.0,
    snr_db: float | None = 20.0,
    room=None,
    extra_paths: Sequence[tuple[float, float]] = (),
    temp_c: float = DEFAULT_TEMP_C,
    q: float = 4.0,
    fs: float = 192000.0,
    seed: int | None = None,
    impairments=None,
    name: str | os.PathLike = "synth oneway",
) -> Synthesis:
    """Ceiling beacons fired in turn, heard by a robot's three receivers (Kim & Kim 2013 §V).

    Parameters
    ----------
    txs_m : sequence of (x, y)
        Transmitter positions in the ceiling plane, m, fired in this order (ids 0, 1, ...).
    ceiling_m : float
        Transmitter height above the receivers' plane, m.
    pose : (x, y, heading)
        Robot pose: metres and heading in **radians**.
    radius_m : float
        Receiver circle radius, m (receivers at 0, 120, 240 degrees).
    n_windows : int, optional
        Activation windows (default: one per transmitter), ``period_s`` apart, each with
        its transmitter's Barker-7 burst on 40 kHz ``latency_s`` after the trigger.
    snr_db : float or None
        In-band SNR of the weakest direct arrival, dB; None for no noise.
    room : rangekit.sim.ShoeboxRoom, optional
    extra_paths : sequence of (delay_s, gain)
        Extra paths of every arrival.
    temp_c, q, fs, seed, impairments
        Air temperature (°C), transducer Q (Tx and Rx), sample rate (Hz), seed,
        impairments (:func:`impair_recordings`).
    name : path-like
        How the recording is named in a memory-budget error (the output file).

    Returns
    -------
    Synthesis
        One recording (one channel per receiver, peak 0.5, sample 0 = the first trigger),
        its sidecar (geometry, each window's Tx and true distances, ``setup``) and the
        beacon file of ``locate`` / ``track duhl`` (``extras[".beacons.json"]``).

    Raises
    ------
    IncompatibleInputError
        The recording would exceed the memory budget (checked before rendering).
    """
    from rangekit.io.audio import check_memory
    from rangekit.io.duhllog import Beacons
    from rangekit.signals.transducer import Transducer
    from rangekit.sim.ultrasonic import render_oneway

    pts = [[float(t[0]), float(t[1]), ceiling_m] for t in txs_m]
    frames = int((n_windows or len(pts)) * period_s * fs)
    check_memory(name, frames, 3, hint="render fewer --windows")  # before rendering
    t = Transducer(q=q)
    sim = render_oneway(
        pts,
        tuple(pose),
        fs=fs,
        tx=t,
        rx=t,
        n_windows=n_windows,
        period_s=period_s,
        latency_s=latency_s,
        temp_c=temp_c,
        snr_db=snr_db,
        radius_m=radius_m,
        room=room,
        extra_paths=list(extra_paths),
        rng=np.random.default_rng(seed),
    )
    x, truth = _ultrasonic(sim.x.T, sim.truth, peak=0.5, fs=fs, seed=seed, impairments=impairments)
    truth["seed"] = seed
    truth["files"] = []
    truth["beacons"] = ""
    truth["setup"] = {
        "scheme": "oneway",
        "temp_c": temp_c,
        "period_s": period_s,
        "latency_s": latency_s,
        "tx_order": list(range(len(pts))),
    }
    beacons = Beacons(np.arange(len(pts)), pts).to_json()
    return Synthesis([x], fs, truth, extras={".beacons.json": beacons})


def synth_echo(
    plan,
    poses: Sequence[Sequence[float]],
    *,
    mount_angle_rad: float = 0.0,
    snr_db: float | None = 20.0,
    temp_c: float = DEFAULT_TEMP_C,
    q: float = 4.0,
    fs: float = 192000.0,
    seed: int | None = None,
    impairments=None,
    map_name: str | None = None,
) -> Synthesis:
    """SRF02 echo recording in a floor plan: one 70 ms ranging cycle per pose (Girard 2011).

    Parameters
    ----------
    plan : rangekit.floorplan.FloorPlan
    poses : sequence of (x, y, heading)
        Carrier poses, metres and heading in **radians**.
    mount_angle_rad : float
        Sensor axis relative to the heading (+ = left).
    snr_db, temp_c, q, fs, seed, impairments
        As for :func:`synth_oneway`.
    map_name : str, optional
        The plan's file, recorded as the sidecar's ``map``.

    Returns
    -------
    Synthesis
        One mono recording (peak 0.9; sample 0 of each cycle = the ping) and its sidecar:
        per cycle the pose, the SRF02 model's range (null = out of range), the echoes.
    """
    from rangekit.signals.transducer import Transducer
    from rangekit.sim.ultrasonic import render_echo

    sim = render_echo(
        plan,
        [tuple(float(v) for v in p) for p in poses],
        mount_angle_rad=mount_angle_rad,
        fs=fs,
        transducer=Transducer(q=q),
        temp_c=temp_c,
        snr_db=snr_db,
        rng=np.random.default_rng(seed),
    )
    x, truth = _ultrasonic(sim.x[0], sim.truth, peak=0.9, fs=fs, seed=seed, impairments=impairments)
    truth["seed"] = seed
    truth["map"] = map_name
    truth["files"] = []
    truth["setup"] = {"scheme": "echo", "temp_c": temp_c, "period_s": truth.get("period_s")}
    return Synthesis([x], fs, truth)
