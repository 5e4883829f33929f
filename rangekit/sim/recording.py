"""Render what N devices record when each plays the beep in turn (Jiang 2018, Algorithm 1).

Every device has a speaker and a microphone a few centimetres apart, its own recording
start, its own sample-clock error and a position (in free field or in a shoebox room).
Device 0 plays first, then device 1, and so on (Algorithm 1 order), each after the
previous beep ended plus a gap (the request/acknowledge round trip).

Time model
----------
Absolute time t is shared by all devices. Device i's sample n is taken at
``t = rec_start_s[i] + n / (fs_i * (1 + ppm_i * 1e-6))`` and device j's beep sample k is
emitted at ``t = play_s[j] + k / (beep.fs * (1 + ppm_j * 1e-6))`` (one codec clock per
device for playing and recording). Each path of length r (direct, or an image source of a
shoebox room) adds delay r / c and gain g / r (g: product of wall reflection factors,
1/r spreading with 1 m reference). Recordings are evaluated with band-limited
interpolation at the exact fractional positions (:func:`interp_bandlimited`), never rounded.

Noise is added per channel at ``snr_db``: the power of the weakest direct beep arrival
on that channel (amplitude A/r at its plateau, power (A/r)^2 / 2) over the noise power
in the full band. Each channel is then scaled to a peak of ``peak`` (automatic gain);
the scale does not change any time.

Ground truth: each device's true onsets (direct path, first burst start) in its own
samples, and each pair's true distance, the mean of the two cross speaker-to-microphone
distances (what two-way ranging measures).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from rangekit import _validate as V
from rangekit.errors import InvalidParameterError
from rangekit.physics import speed_of_sound_m_s
from rangekit.signals.beep import Beep, beep_waveform, check_beep_fits
from rangekit.signals.probe import Probe
from rangekit.sim._fracdelay import interp_bandlimited
from rangekit.sim.noise import make_noise
from rangekit.sim.room import ShoeboxRoom, image_sources

__all__ = ["Device", "SimResult", "pair_devices", "render_beepbeep"]


@dataclass(frozen=True)
class Device:
    """A phone-like device: speaker and microphone positions, clock and recording start.

    Parameters
    ----------
    speaker_m, mic_m : array_like, shape (3,)
        Positions in metres.
    rec_start_s : float
        Absolute time at which the device starts recording.
    clock_ppm : float
        Sample-clock error in parts per million (positive: the clock runs fast).
    fs : float
        Nominal recording sample rate in Hz (what the WAV header says).
    """

    speaker_m: np.ndarray
    mic_m: np.ndarray
    rec_start_s: float = 0.0
    clock_ppm: float = 0.0
    fs: float = 44100.0

    def __post_init__(self) -> None:
        for name in ("speaker_m", "mic_m"):
            p = np.asarray(getattr(self, name), dtype=np.float64).reshape(-1)
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                raise InvalidParameterError(
                    f"{name}={getattr(self, name)!r} must be 3 finite numbers"
                )
            object.__setattr__(self, name, p)
        object.__setattr__(self, "fs", V.sample_rate(self.fs))
        object.__setattr__(self, "clock_ppm", V.in_range("clock_ppm", self.clock_ppm, -1e4, 1e4))
        object.__setattr__(
            self, "rec_start_s", V.in_range("rec_start_s", self.rec_start_s, -1e6, 1e6)
        )

    @property
    def self_distance_m(self) -> float:
        """Speaker-to-microphone distance."""
        return float(np.linalg.norm(self.speaker_m - self.mic_m))


@dataclass(frozen=True)
class SimResult:
    """Rendered recordings and their ground truth.

    Attributes
    ----------
    recordings : list of ndarray
        Device i's recording (float64, peak ``peak``).
    fs : list of float
        Nominal sample rate of each recording.
    truth : dict
        JSON-ready ground truth (see ``docs/formats.md``).
    """

    recordings: list[np.ndarray]
    fs: list[float]
    truth: dict = field(repr=False)

    @property
    def onsets(self) -> np.ndarray:
        """(N, N) true onsets: ``onsets[i, j]`` is beep j's arrival in device i's samples."""
        return np.array([d["onsets"] for d in self.truth["devices"]])

    @property
    def distances_m(self) -> np.ndarray:
        """(N, N) true pair distances (mean of the cross speaker-to-microphone distances)."""
        n = len(self.recordings)
        d = np.zeros((n, n))
        for p in self.truth["pairs"]:
            d[p["a"], p["b"]] = d[p["b"], p["a"]] = p["distance_m"]
        return d


def pair_devices(
    distance_m: float,
    *,
    self_distance_m: float = 0.1,
    center_m: Sequence[float] = (0.0, 0.0, 1.2),
    azimuth_rad: float = 0.0,
    **device_kw,
) -> list[Device]:
    """Two devices whose true pair distance is exactly ``distance_m``.

    The devices face each other with their speaker-microphone axes antiparallel and
    perpendicular to the line joining them, so both cross speaker-to-microphone distances
    equal ``distance_m``.
    """
    d = V.positive("distance_m", distance_m)
    s = V.positive("self_distance_m", self_distance_m, allow_zero=True)
    c = np.asarray(center_m, dtype=np.float64)
    u = np.array([math.cos(azimuth_rad), math.sin(azimuth_rad), 0.0])
    v = np.array([-u[1], u[0], 0.0])
    a, b = c - 0.5 * d * u, c + 0.5 * d * u
    kw0 = {k: (val[0] if isinstance(val, (list, tuple)) else val) for k, val in device_kw.items()}
    kw1 = {k: (val[1] if isinstance(val, (list, tuple)) else val) for k, val in device_kw.items()}
    return [
        Device(speaker_m=a - 0.5 * s * v, mic_m=a + 0.5 * s * v, **kw0),
        Device(speaker_m=b + 0.5 * s * v, mic_m=b - 0.5 * s * v, **kw1),
    ]


def render_beepbeep(
    devices: Sequence[Device],
    *,
    beep: Beep | Probe | None = None,
    temp_c: float = 20.0,
    snr_db: float | None = 20.0,
    noise: str = "white",
    room: ShoeboxRoom | None = None,
    lead_s: float = 0.15,
    gap_s: float | Sequence[float] = 0.25,
    tail_s: float = 0.15,
    peak: float = 0.5,
    rng=None,
) -> SimResult:
    """Render the recordings of one exchange in which every device plays ``beep`` in turn.

    Parameters
    ----------
    devices : sequence of Device
        Two or more devices; device i plays i-th.
    beep : Beep or Probe, optional
        The beep every device plays (default: the rangekit beep), or any probe signal
        (:class:`rangekit.signals.probe.Probe`, e.g. a sweep): its samples are played at
        its rate through each device's clock. A probe's "plateau power" in the SNR is its
        mean power over its duration; the truth's onsets are its sample 0.
    temp_c : float
        Air temperature; sets the speed of sound.
    snr_db : float or None
        Per-channel SNR of the weakest direct beep arrival, full band; None for no noise.
    noise : {"white", "pink"}
        Noise colour.
    room : ShoeboxRoom, optional
        Adds wall reflections (image sources up to ``room.max_order``); positions must be
        inside the room. None for free field.
    lead_s : float
        Time from the latest recording start to the first beep.
    gap_s : float or sequence of float
        Silence between the end of one beep and the start of the next (one per gap).
    tail_s : float
        Recording time after the last beep has reached every microphone.
    peak : float
        Peak level of each rendered channel.
    rng : seed or Generator
        Randomness for the noise.

    Returns
    -------
    SimResult
    """
    beep = Beep() if beep is None else beep
    devices = list(devices)
    n_dev = len(devices)
    if n_dev < 2:
        raise InvalidParameterError(f"need at least 2 devices, got {n_dev}")
    is_probe = isinstance(beep, Probe)
    for i, d in enumerate(devices):
        if is_probe:
            beep.check_fits(d.fs, what=f"device {i}")
        else:
            check_beep_fits(beep, fs=d.fs, what=f"device {i}")
    c = speed_of_sound_m_s(temp_c)
    if snr_db is not None:
        snr_db = V.in_range("snr_db", snr_db, -60.0, 200.0)
    rng = np.random.default_rng(rng)
    gaps = np.broadcast_to(np.asarray(gap_s, dtype=np.float64), (n_dev - 1,))
    if np.any(gaps < 0):
        raise InvalidParameterError(f"gap_s={gap_s!r} must be >= 0")
    if room is not None:
        for i, d in enumerate(devices):
            for name in ("speaker_m", "mic_m"):
                if not room.contains(getattr(d, name)):
                    raise InvalidParameterError(f"device {i} {name} is outside the room")

    # Play schedule (absolute times), Algorithm 1 order.
    play = np.zeros(n_dev)
    play[0] = max(d.rec_start_s for d in devices) + lead_s
    for j in range(1, n_dev):
        play[j] = (
            play[j - 1] + beep.duration_s * (1 - devices[j - 1].clock_ppm * 1e-6) + gaps[j - 1]
        )

    if is_probe:
        src, src_fs = beep.samples, beep.fs
        amp = math.sqrt(2.0 * float(np.mean(src**2)))  # power amp^2 / 2 = mean power
    else:
        src, src_fs, amp = beep_waveform(beep), beep.fs, beep.amplitude
    hw = 32
    max_r = max(float(np.linalg.norm(a.speaker_m - b.mic_m)) for a in devices for b in devices)
    if room is not None:
        max_r = max(max_r, 2.0 * float(np.linalg.norm(room.size_m)) * (room.max_order + 1))
    t_end = play[-1] + beep.duration_s * 1.001 + max_r / c + tail_s

    recordings, truth_dev = [], []
    for i, di in enumerate(devices):
        rate_i = di.fs * (1 + di.clock_ppm * 1e-6)
        n_samp = int(math.ceil((t_end - di.rec_start_s) * rate_i))
        t_n = di.rec_start_s + np.arange(n_samp) / rate_i
        x = np.zeros(n_samp)
        onsets, weakest = [], math.inf
        for j, dj in enumerate(devices):
            if room is None:
                pos, gains = dj.speaker_m[None, :], np.ones(1)
            else:
                pos, gains, _ = image_sources(dj.speaker_m, room)
            rate_j = src_fs * (1 + dj.clock_ppm * 1e-6)
            for p, g in zip(pos, gains, strict=True):
                r = float(np.linalg.norm(p - di.mic_m))
                r = max(r, 1e-3)
                t0 = play[j] + r / c
                # Only samples that can see the beep (plus the interpolator's half-width).
                n0 = max(0, int(math.floor((t0 - di.rec_start_s) * rate_i)) - 2 * hw)
                n1 = min(
                    n_samp,
                    int(math.ceil((t0 + len(src) / rate_j - di.rec_start_s) * rate_i)) + 2 * hw,
                )
                if n1 <= n0:
                    continue
                u = (t_n[n0:n1] - t0) * rate_j
                x[n0:n1] += (g / r) * interp_bandlimited(src, u, half_width=hw)
            r_dir = float(np.linalg.norm(dj.speaker_m - di.mic_m))
            onsets.append((play[j] + r_dir / c - di.rec_start_s) * rate_i)
            weakest = min(weakest, amp / max(r_dir, 1e-3))
        sigma = 0.0
        if snr_db is not None:
            sig_pow = 0.5 * weakest**2
            sigma = math.sqrt(sig_pow / 10 ** (float(snr_db) / 10))
            x += sigma * make_noise(n_samp, kind=noise, rng=rng)
        scale = peak / float(np.max(np.abs(x)))
        recordings.append(x * scale)
        truth_dev.append(
            device_truth(di, play_s=float(play[i]), onsets=onsets, noise_sigma=sigma * scale)
        )
    pairs = pair_truth(devices)
    truth = {
        "scheme": "beepbeep",
        "temp_c": float(temp_c),
        "speed_of_sound_m_s": c,
        "snr_db": None if snr_db is None else float(snr_db),
        "noise": noise,
        "beep": _signal_truth(beep),
        "room": room_truth(room),
        "devices": truth_dev,
        "pairs": pairs,
    }
    return SimResult(recordings, [d.fs for d in devices], truth)


def device_truth(
    d: Device, *, play_s: float, onsets: Sequence[float], noise_sigma: float = 0.0
) -> dict:
    """One device's entry of the truth sidecar: geometry, clock, play time, true onsets and
    the standard deviation of the noise in the (scaled) recording."""
    return {
        "speaker_m": d.speaker_m.tolist(),
        "mic_m": d.mic_m.tolist(),
        "self_distance_m": d.self_distance_m,
        "rec_start_s": d.rec_start_s,
        "play_s": play_s,
        "clock_ppm": d.clock_ppm,
        "fs": d.fs,
        "onsets": [float(o) for o in onsets],
        "noise_sigma": float(noise_sigma),
    }


def pair_truth(devices: Sequence[Device]) -> list[dict]:
    """Each pair's true two-way distance: the mean of the two cross speaker-to-mic distances."""
    pairs = []
    for a in range(len(devices)):
        for b in range(a + 1, len(devices)):
            dab = np.linalg.norm(devices[a].speaker_m - devices[b].mic_m)
            dba = np.linalg.norm(devices[b].speaker_m - devices[a].mic_m)
            pairs.append({"a": a, "b": b, "distance_m": float(0.5 * (dab + dba))})
    return pairs


def room_truth(room: ShoeboxRoom | None) -> dict | None:
    """The room's description in the truth sidecar (None for free field)."""
    if room is None:
        return None
    return {"size_m": list(room.size_m), "absorption": room.absorption, "max_order": room.max_order}


def _signal_truth(beep: Beep | Probe) -> dict:
    """The played signal's description in the truth sidecar."""
    if isinstance(beep, Probe):
        return {"probe": beep.name, "fs": beep.fs, "n_samples": len(beep.samples)}
    return {
        "f_hz": beep.f_hz,
        "n_bursts": beep.n_bursts,
        "spacing": beep.spacing,
        "burst_len": beep.burst_len,
        "taper": beep.taper,
        "amplitude": beep.amplitude,
        "fs": beep.fs,
    }
