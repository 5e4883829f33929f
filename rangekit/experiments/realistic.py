"""A realistic two-way corpus: exchanges in rooms that rangekit's simulator did not make.

rangekit's own renderer draws the envelope its beep detector fits, white noise, a few
low-order reflections and peak-normalised channels. Accuracy claims must also hold where
none of that is true (``../shared/STYLE.md``, "the inverse crime"), so this module renders
two-device exchanges with **pyroomacoustics** (image sources of high order, frequency-
dependent air absorption, its own fractional-delay filters) and then applies the
impairments real recordings carry (:mod:`rangekit.sim.impair`): white noise at 10–30 dB
SNR, low-frequency noise and hum, speech or music interference above the far arrival but
outside the signal's band, DC offsets, clipping, digital silence, automatic-gain steps,
device band responses, independent recording starts and ±``ppm`` sample clocks.

Truth is geometric: the mean of the two cross speaker-to-microphone distances, which is
what two-way ranging measures (:mod:`rangekit.ranging.beepbeep`). pyroomacoustics'
impulse responses carry a fixed delay (its fractional-delay filter's half length, 40
samples at the default settings; ``../shared/REFERENCES.md``); it is the same in every
response, so two-way ranging cancels it, and one-way uses of this corpus must remove it.

pyroomacoustics is an optional dependency (the ``test`` and ``rooms`` extras); importing
this module does not import it.

Examples
--------
>>> room = RoomSpec(size_m=(6, 5, 3), absorption=0.3, max_order=3)
>>> ex = render_exchange(1, room=room, distance_m=2.0)
>>> len(ex.recordings), round(ex.distance_m, 2)  # phones 2 m apart, speaker-to-mic truth
(2, 2.0)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rangekit.errors import InvalidParameterError
from rangekit.physics import speed_of_sound_m_s
from rangekit.signals.beep import Beep, beep_waveform
from rangekit.signals.probe import Probe
from rangekit.types import RngLike

if TYPE_CHECKING:
    from rangekit.sim.impair import Impairments

__all__ = [
    "Exchange",
    "RoomSpec",
    "draw_impairments",
    "draw_room",
    "impair_exchange",
    "render_exchange",
    "run_corpus",
    "summarize",
]


@dataclass(frozen=True)
class RoomSpec:
    """A shoebox room for pyroomacoustics.

    Parameters
    ----------
    size_m : (float, float, float)
        Room size in metres.
    absorption : float
        Energy absorption of every surface (0..1, flat in frequency).
    max_order : int
        Image-source order.
    air_absorption : bool
        Frequency-dependent air absorption (pyroomacoustics' model).
    """

    size_m: tuple[float, float, float]
    absorption: float
    max_order: int
    air_absorption: bool = True

    def rt60_sabine_s(self) -> float:
        """Sabine reverberation time of the room, seconds (0.161 V / (S a))."""
        lx, ly, lz = self.size_m
        vol = lx * ly * lz
        surf = 2.0 * (lx * ly + lx * lz + ly * lz)
        return 0.161 * vol / (surf * self.absorption)


def draw_room(
    rng: np.random.Generator,
    *,
    size_lo_m: Sequence[float] = (4.0, 3.0, 2.5),
    size_hi_m: Sequence[float] = (20.0, 18.0, 6.0),
    absorption: tuple[float, float] = (0.15, 0.35),
    max_order: tuple[int, int] = (6, 12),
) -> RoomSpec:
    """A random room: size, absorption and image order uniform within the given ranges."""
    size = tuple(float(v) for v in rng.uniform(size_lo_m, size_hi_m))
    a = float(rng.uniform(*absorption))
    order = int(rng.integers(max_order[0], max_order[1] + 1))
    return RoomSpec(size, a, order)


@dataclass(frozen=True)
class Exchange:
    """One rendered two-way exchange.

    Attributes
    ----------
    recordings : list of ndarray
        Device i's recording (float64, full scale 1).
    fs : float
        Nominal sample rate of every recording, Hz.
    distance_m : float
        True two-way distance: the mean of the two cross speaker-to-microphone distances.
    self_distance_m : (float, float)
        Each device's speaker-to-microphone distance (what a user measures and gives).
    speed_m_s : float
        Speed of sound the room was rendered with.
    info : dict
        What was drawn (room, positions, clocks, levels, impairments).
    """

    recordings: list[np.ndarray]
    fs: float
    distance_m: float
    self_distance_m: tuple[float, float]
    speed_m_s: float
    info: dict = field(repr=False, default_factory=dict)


def _signal_samples(signal: Beep | Probe | None, fs: float) -> np.ndarray:
    if signal is None:
        signal = Beep(fs=fs)
    if isinstance(signal, Beep):
        if signal.fs != fs:
            signal = Beep(**{**signal.__dict__, "fs": fs})
        return beep_waveform(signal)
    if isinstance(signal, Probe):
        return signal.at_rate(fs)
    raise InvalidParameterError(f"signal must be a Beep or a Probe, got {type(signal).__name__}")


def _phone(rng: np.random.Generator, centre: np.ndarray, self_m: float) -> tuple[np.ndarray, ...]:
    """Speaker and microphone of a phone held at ``centre``, ``self_m`` apart, random pose."""
    az = rng.uniform(0.0, 2.0 * math.pi)
    el = rng.uniform(-0.5, 0.5)
    u = np.array([math.cos(az) * math.cos(el), math.sin(az) * math.cos(el), math.sin(el)])
    return centre + 0.5 * self_m * u, centre - 0.5 * self_m * u


def _clocked(x: np.ndarray, *, start: float, ppm: float, n_out: int) -> np.ndarray:
    """Device samples of the room-time signal ``x``: sample n is room sample start + n (1+e)."""
    from rangekit.sim._fracdelay import interp_bandlimited

    pos = start + np.arange(n_out, dtype=np.float64) * (1.0 + ppm * 1e-6)
    return interp_bandlimited(x, pos)


def render_exchange(
    rng: RngLike,
    *,
    room: RoomSpec,
    distance_m: float,
    signal: Beep | Probe | None = None,
    fs: float = 44100.0,
    temp_c: float = 20.0,
    self_distance_m: tuple[float, float] = (0.08, 0.16),
    heights_m: tuple[float, float] = (0.8, 1.6),
    margin_m: float = 0.3,
    near_wall: bool = False,
    snr_db: float = 20.0,
    ppm: float = 40.0,
    gap_s: tuple[float, float] = (0.1, 0.8),
    tail_s: float = 0.6,
) -> Exchange:
    """Render one two-device exchange in a pyroomacoustics room.

    Device 0 plays ``signal`` (default the rangekit beep), then device 1 a random
    ``gap_s`` after device 0's signal ended; each records from its own random start
    (0.05–0.2 s before device 0 plays) with its own sample clock (uniform in ±``ppm``).
    White noise is added per device at ``snr_db`` below the power of the far arrival's
    strongest burst (the direct path and the reflections within it). Impairments are
    applied by the caller (:func:`rangekit.sim.impair.impair`).

    Parameters
    ----------
    rng : int, Generator or None
        Random source.
    room : RoomSpec
        The room.
    distance_m : float
        Distance between the two phones' centres, m.
    signal : Beep or Probe, optional
        What both devices play.
    fs : float
        Sample rate, Hz.
    temp_c : float
        Air temperature; sets the speed of sound (rangekit's formula, so ranging and room
        agree).
    self_distance_m : (float, float)
        Range of each phone's speaker-to-microphone distance, m (drawn uniformly).
    heights_m, margin_m : float
        Hand height range and the distance kept from the walls, m.
    near_wall : bool
        Put device 0 against a wall (``margin_m`` from it).
    snr_db : float
        Far-arrival power over the white-noise power, dB.
    ppm : float
        Clock errors are uniform in ±``ppm``.
    gap_s : (float, float)
        Time from the end of device 0's play to the start of device 1's, s.
    tail_s : float
        Recording kept after device 1's play ends, s.
    """
    import pyroomacoustics as pra

    rng = np.random.default_rng(rng)
    c = speed_of_sound_m_s(temp_c)
    src = _signal_samples(signal, fs)
    size = np.asarray(room.size_m, dtype=np.float64)
    from rangekit.experiments.beepbeep_accuracy import place_devices

    ca, cb = place_devices(
        distance_m,
        room=room,
        rng=rng,
        margin_m=margin_m,
        heights_m=heights_m,
        near_wall=near_wall,
        max_tries=10000,
    )
    s = rng.uniform(*self_distance_m, size=2)
    spk0, mic0 = _phone(rng, ca, s[0])
    spk1, mic1 = _phone(rng, cb, s[1])
    truth = 0.5 * (np.linalg.norm(spk0 - mic1) + np.linalg.norm(spk1 - mic0))
    # The self distance a user gives is the phone's speaker-to-mic spacing.
    mat = pra.Material(energy_absorption=room.absorption)
    pr = pra.ShoeBox(
        size,
        fs=int(fs),
        materials=mat,
        max_order=room.max_order,
        air_absorption=room.air_absorption,
        temperature=temp_c,
    )
    pr.set_sound_speed(c)
    pr.add_source(spk0)
    pr.add_source(spk1)
    pr.add_microphone_array(np.stack([mic0, mic1], axis=1))
    pr.compute_rir()
    t0 = int(round(rng.uniform(0.2, 0.35) * fs))
    t1 = t0 + len(src) + int(round(rng.uniform(*gap_s) * fs))
    n_rir = max(len(pr.rir[m][k]) for m in range(2) for k in range(2))
    n_room = t1 + len(src) + n_rir + int(tail_s * fs)
    recs, levels = [], []
    from scipy.signal import oaconvolve

    for m in range(2):
        parts = []
        for k, t_play in ((0, t0), (1, t1)):
            y = np.zeros(n_room)
            r = oaconvolve(src, pr.rir[m][k])
            y[t_play : t_play + len(r)] = r[: n_room - t_play]
            parts.append(y)
        own, far = (parts[0], parts[1]) if m == 0 else (parts[1], parts[0])
        # Far-arrival power: the strongest burst-long stretch of the far part.
        n_b = max(16, min(len(src), int(0.01 * fs)))
        p = np.convolve(far**2, np.ones(n_b) / n_b, mode="valid")
        levels.append(float(p.max()))
        recs.append(own + far)
    out, starts, clocks, onsets = [], [], [], []
    pra_delay = pra.constants.get("frac_delay_length") // 2
    for m in range(2):
        start = t0 - rng.uniform(0.05, 0.2) * fs  # room sample of the device's sample 0
        e = rng.uniform(-ppm, ppm)
        n_out = int((n_room - start - 64) / (1.0 + e * 1e-6))
        y = _clocked(recs[m], start=start, ppm=e, n_out=n_out)
        mic = (mic0, mic1)[m]
        onsets.append(
            [
                (t_play + pra_delay + np.linalg.norm(spk - mic) / c * fs - start) / (1 + e * 1e-6)
                for spk, t_play in ((spk0, t0), (spk1, t1))
            ]
        )
        sigma = math.sqrt(levels[m] / 10.0 ** (snr_db / 10.0))
        y = y + sigma * rng.standard_normal(len(y))
        out.append(y)
        starts.append(float(start))
        clocks.append(float(e))
    info = {
        "room": {
            "size_m": list(room.size_m),
            "absorption": room.absorption,
            "max_order": room.max_order,
            "rt60_sabine_s": room.rt60_sabine_s(),
        },
        "speaker_m": [spk0.tolist(), spk1.tolist()],
        "mic_m": [mic0.tolist(), mic1.tolist()],
        "clock_ppm": clocks,
        "onsets": onsets,
        "far_power": levels,
        "noise_sigma": [math.sqrt(lv / 10.0 ** (snr_db / 10.0)) for lv in levels],
        "snr_db": snr_db,
        "near_wall": near_wall,
    }
    return Exchange(out, float(fs), float(truth), (float(s[0]), float(s[1])), c, info)


def draw_impairments(rng: np.random.Generator, *, snr_db: float, fs: float) -> Impairments:
    """A random mix of the impairments real recordings carry (each on with a probability).

    Levels are relative to the white-noise floor that :func:`render_exchange` adds at
    ``snr_db`` below the far arrival: interference (speech or music, p = 0.5) 10 dB
    above the far arrival's power, low-frequency noise 30 dB above the floor's PSD
    (p = 0.5), mains hum at 30 dB (p = 0.3), a DC offset of up to 5 % (p = 0.3), clipping
    6–20 dB below the peak (p = 0.2), 0.5–1 s of digital silence at both ends (p = 0.2),
    three automatic-gain steps of ±6 dB (p = 0.2) and a device band response (high-pass
    100–300 Hz, low-pass 18–20 kHz; p = 0.3).
    """
    from rangekit.sim.impair import Impairments, interference_band_hz

    kw: dict = {}
    if rng.random() < 0.5:
        kind = "speech" if rng.random() < 0.5 else "music"
        probe = Impairments(interference=kind)
        lo, hi = interference_band_hz(probe, fs=fs)
        # floor power in the band = (2 sigma^2 / fs) (hi - lo); far power = sigma^2 10^(snr/10)
        band = 2.0 * (hi - lo) / fs
        kw.update(interference=kind, interference_db=10.0 + snr_db - 10.0 * math.log10(band))
    if rng.random() < 0.5:
        kw["lf_db"] = 30.0
    if rng.random() < 0.3:
        kw["hum_db"] = 30.0
        kw["hum_hz"] = 50.0 if rng.random() < 0.5 else 60.0
    if rng.random() < 0.3:
        kw["dc"] = float(rng.uniform(0.001, 0.05))
    if rng.random() < 0.2:
        kw["clip_db"] = float(rng.uniform(6.0, 20.0))
    if rng.random() < 0.2:
        kw["silence_s"] = float(rng.uniform(0.5, 1.0))
    if rng.random() < 0.2:
        kw["agc_db"] = 6.0
    if rng.random() < 0.3:
        kw["hp_hz"] = float(rng.uniform(100.0, 300.0))
        kw["lp_hz"] = float(rng.uniform(18000.0, min(20000.0, 0.45 * fs)))
    return Impairments(**kw)


def impair_exchange(ex: Exchange, impairments: Impairments, rng: RngLike = None) -> Exchange:
    """``ex`` with ``impairments`` applied to each recording (independent draws).

    The floor is the white noise :func:`render_exchange` added (``2 sigma^2 / fs``).
    Silence padding shifts every sample of a recording alike, so the two-way truth does
    not change.
    """
    from rangekit.sim.impair import impair

    rng = np.random.default_rng(rng)
    out = []
    for x, sigma in zip(ex.recordings, ex.info["noise_sigma"], strict=True):
        res = impair(
            x, fs=ex.fs, impairments=impairments, rng=rng, floor_psd=2.0 * sigma**2 / ex.fs
        )
        out.append(res.x)
    info = {**ex.info, "impairments": impairments.as_dict()}
    return Exchange(out, ex.fs, ex.distance_m, ex.self_distance_m, ex.speed_m_s, info)


def run_corpus(
    n: int,
    *,
    rng: RngLike = 0,
    signal: Beep | Probe | None = None,
    impaired: bool = True,
    max_order: tuple[int, int] = (6, 10),
    distances_m: tuple[float, float] = (0.5, 7.0),
    snr_db: tuple[float, float] = (10.0, 30.0),
    detector: str = "changepoint",
) -> list[dict]:
    """Range ``n`` random exchanges of the corpus; one row per exchange.

    Rooms from :func:`draw_room` (image order in ``max_order``), one device against a
    wall in a quarter of them, distances and SNRs uniform, impairments from
    :func:`draw_impairments` when ``impaired``. Each row holds the truth, the estimate
    and its sigma and flags, or ``error`` (the detection error's message) when ranging
    failed. The self-distances are given to the ranging as a user would measure them.
    """
    from rangekit.errors import DetectionError
    from rangekit.io.audio import Channel
    from rangekit.ranging.pipeline import range_channels

    rng = np.random.default_rng(rng)
    rows = []
    for i in range(n):
        room = draw_room(rng, max_order=max_order)
        d = float(rng.uniform(*distances_m))
        d = min(d, 0.8 * min(room.size_m[:2]))
        snr = float(rng.uniform(*snr_db))
        ex = render_exchange(
            rng, room=room, distance_m=d, signal=signal, snr_db=snr, near_wall=rng.random() < 0.25
        )
        imp = draw_impairments(rng, snr_db=snr, fs=ex.fs) if impaired else None
        if imp is not None:
            ex = impair_exchange(ex, imp, rng)
        row = {
            "i": i,
            "distance_m": ex.distance_m,
            "rt60_s": room.rt60_sabine_s(),
            "snr_db": snr,
            "impairments": "" if imp is None else imp.spec(),
        }
        chans = [Channel(x, ex.fs, f"dev{k}") for k, x in enumerate(ex.recordings)]
        try:
            res = range_channels(
                chans,
                detector=detector,
                probe=signal if isinstance(signal, Probe) else None,
                speed_m_s=ex.speed_m_s,
                self_distance_m=list(ex.self_distance_m),
            )
            r = res.ranges[0]
            row.update(
                estimate_m=r.distance_m,
                sigma_m=r.sigma_m,
                error_m=r.distance_m - ex.distance_m,
                flags=list(r.flags),
                error="",
            )
        except DetectionError as e:
            row.update(estimate_m=math.nan, sigma_m=math.nan, error_m=math.nan, flags=[])
            row["error"] = str(e)
        rows.append(row)
    return rows


def summarize(rows: Sequence[dict], *, gross_m: float = 0.10) -> dict:
    """Failures, error percentiles, unflagged gross errors and 2-sigma coverage of rows.

    Percentiles are over every ranged exchange (flagged ones included, never trimmed);
    ``doubtful`` flags are those other than :data:`rangekit.types.INFO_FLAGS`.
    """
    from rangekit.types import INFO_FLAGS

    ok = [r for r in rows if not r["error"]]
    err = np.abs([r["error_m"] for r in ok])
    sig = np.array([r["sigma_m"] for r in ok])
    doubtful = [any(f not in INFO_FLAGS for f in r["flags"]) for r in ok]
    gross = err > gross_m
    return {
        "n": len(rows),
        "failures": len(rows) - len(ok),
        "failure_rate": (len(rows) - len(ok)) / max(len(rows), 1),
        "median_m": float(np.median(err)) if len(err) else math.nan,
        "p90_m": float(np.percentile(err, 90)) if len(err) else math.nan,
        "max_m": float(err.max()) if len(err) else math.nan,
        "gross": int(gross.sum()),
        "gross_unflagged": int(np.sum(gross & ~np.array(doubtful, dtype=bool))),
        "flagged": int(np.sum(doubtful)),
        "within_2sigma": float(np.mean(err <= 2.0 * sig)) if len(err) else math.nan,
    }


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m rangekit.experiments.realistic [--n N] [--seed S] [--clean]``."""
    import argparse
    import json

    p = argparse.ArgumentParser(prog="python -m rangekit.experiments.realistic")
    p.add_argument("--n", type=int, default=200, help="exchanges (default 200)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--clean", action="store_true", help="rooms without impairments")
    a = p.parse_args(argv)
    rows = run_corpus(a.n, rng=a.seed, impaired=not a.clean)
    print(json.dumps(summarize(rows), indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
