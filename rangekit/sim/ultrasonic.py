"""Simulated ultrasonic recordings: one-way Barker beacons (Kim & Kim 2013) and SRF02 echoes.

A robot carries ``n`` receivers on a circle of radius ``r_R`` (0.19 m, at 0°, 120°, 240°
from its heading; Kim & Kim 2013 §II-B, §V); transmitters hang on the ceiling at height
``z_T``. The robot triggers one Tx per activation window (period ``period_s``; 0.2 s =
5 Hz in the paper); the Tx drives its transducer ``latency_s`` after the trigger. The
recording's sample 0 is the first trigger, so the ranging contract of
:func:`rangekit.ranging.ultrasonic.range_oneway` holds by construction.

Signal chain per path: drive -> Tx transducer -> propagation (true fractional delay by
band-limited interpolation, 1/r spreading, optional shoebox reflections and extra paths)
-> Rx transducer -> white noise. The noise level is set by the in-band SNR of the weakest
direct arrival: its energy ``E`` over the drive duration ``T`` against the white noise's
power in the burst's main lobe ``B`` (:attr:`CodedBurst.band_hz`, 26.7 kHz for Barker-7):
``SNR = (E / T) / (N0 B)``, so the matched filter's output SNR is ``2 E / N0 = 2 SNR T B``
(14.5 dB at 0 dB in-band SNR for the default burst).

Examples
--------
>>> sim = render_oneway([[1.0, 0.0, 2.0]], (0.0, 0.0, 0.0), snr_db=None, period_s=0.05)
>>> sim.x.shape, sim.fs
((3, 9600), 192000.0)
>>> [round(d, 4) for d in sim.truth["windows"][0]["distances_m"]]
[2.1578, 2.2861, 2.2861]
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from rangekit import _validate as V
from rangekit.errors import InvalidParameterError
from rangekit.physics import DEFAULT_TEMP_C, speed_of_sound_m_s
from rangekit.signals.barker import CodedBurst, burst_waveform
from rangekit.signals.transducer import Transducer
from rangekit.sim._fracdelay import interp_bandlimited
from rangekit.sim.noise import make_noise
from rangekit.sim.room import ShoeboxRoom, image_sources

__all__ = [
    "R_RECEIVER_M",
    "UltrasonicSim",
    "receiver_positions",
    "render_echo",
    "render_oneway",
    "specular_echoes",
]

#: Radius of Kim & Kim's receiver circle, m (§V).
R_RECEIVER_M = 0.19
_HW = 32  # half-width of the interpolation kernel, samples


@dataclass(frozen=True)
class UltrasonicSim:
    """A rendered ultrasonic recording and its truth.

    Attributes
    ----------
    x : ndarray, shape (channels, samples)
        The recording (float64).
    fs : float
        Sample rate in Hz.
    truth : dict
        Plain-JSON truth (written as the sidecar); see ``docs/formats.md``.
    """

    x: np.ndarray
    fs: float
    truth: dict = field(default_factory=dict)


def receiver_positions(
    pose, *, radius_m: float = R_RECEIVER_M, n: int = 3, height_m: float = 0.0
) -> np.ndarray:
    """Receiver positions ``(n, 3)`` for a robot pose ``(x, y, heading_rad)``.

    Receiver ``i`` sits at angle ``heading + 2 pi i / n`` on a circle of ``radius_m``
    around ``(x, y)``, at height ``height_m`` (Kim & Kim 2013 §II-B: 0°, 120°, 240°).

    Examples
    --------
    >>> receiver_positions((1.0, 2.0, 0.0)).round(3).tolist()[0]
    [1.19, 2.0, 0.0]
    """
    p = np.asarray(pose, dtype=np.float64)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise InvalidParameterError(f"pose={pose!r} must be (x, y, heading_rad), finite")
    radius_m = V.positive("radius_m", radius_m, allow_zero=True)
    n = V.positive_int("n", n)
    a = p[2] + 2.0 * math.pi * np.arange(n) / n
    return np.stack(
        [p[0] + radius_m * np.cos(a), p[1] + radius_m * np.sin(a), np.full(n, float(height_m))],
        axis=1,
    )


def _add_path(x: np.ndarray, src: np.ndarray, start: float, gain: float) -> None:
    """``x += gain * src`` delayed to the fractional sample ``start`` (band-limited)."""
    n0 = max(0, int(math.floor(start)) - _HW)
    n1 = min(len(x), int(math.ceil(start)) + len(src) + _HW)
    if n1 <= n0:
        return
    u = np.arange(n0, n1, dtype=np.float64) - start
    x[n0:n1] += gain * interp_bandlimited(src, u, half_width=_HW)


def render_oneway(
    tx_positions_m,
    pose,
    *,
    fs: float = 192000.0,
    burst: CodedBurst | None = None,
    tx: Transducer | None = None,
    rx: Transducer | None = None,
    order: Sequence[int] | None = None,
    n_windows: int | None = None,
    period_s: float = 0.2,
    latency_s: float = 0.0,
    temp_c: float = DEFAULT_TEMP_C,
    snr_db: float | None = 20.0,
    radius_m: float = R_RECEIVER_M,
    n_receivers: int = 3,
    receiver_height_m: float = 0.0,
    room: ShoeboxRoom | None = None,
    extra_paths: Sequence[tuple[float, float]] = (),
    rng=None,
) -> UltrasonicSim:
    """Render a one-way recording: Txs fired in turn, one per window, at a static robot.

    Parameters
    ----------
    tx_positions_m : array_like, shape (n_tx, 3)
        Transmitter positions in metres (on the ceiling: ``z = z_T``).
    pose : (x, y, heading_rad)
        Robot pose; receivers by :func:`receiver_positions`.
    fs : float
        Sample rate in Hz (default 192 kHz).
    burst : CodedBurst, optional
        The code (default Barker-7 on 40 kHz, 3 cycles per bit).
    tx, rx : Transducer, optional
        Transducer models (default Q = 4 each).
    order : sequence of int, optional
        Firing order (indices into ``tx_positions_m``); default all Txs in turn.
    n_windows : int, optional
        Number of activation windows (default ``len(order)``); the order repeats.
    period_s : float
        Activation period in seconds (default 0.2 s, 5 Hz).
    latency_s : float
        Delay from the trigger to the drive's start, >= 0.
    temp_c : float
        Air temperature (speed of sound by Kim & Kim 2013 §II-A).
    snr_db : float or None
        In-band SNR of the weakest direct arrival (see the module notes); None = no noise.
    radius_m, n_receivers, receiver_height_m
        Receiver array geometry.
    room : ShoeboxRoom, optional
        Adds wall/floor/ceiling reflections (image sources); all positions must be inside.
    extra_paths : sequence of (excess_delay_s, gain)
        Extra copies of every direct path, ``excess_delay_s`` later with amplitude ``gain``
        times the direct path's (e.g. ``[(1e-3, 2.0)]``: a reflection 6 dB stronger 1 ms later).
    rng : seed or Generator
        Randomness for the noise.

    Returns
    -------
    UltrasonicSim
    """
    fs = V.sample_rate(fs)
    burst = CodedBurst(fs=fs) if burst is None else burst.with_fs(fs)
    tx = Transducer() if tx is None else tx
    rx = Transducer() if rx is None else rx
    txp = np.asarray(tx_positions_m, dtype=np.float64)
    if txp.ndim != 2 or txp.shape[1] != 3 or len(txp) == 0 or not np.all(np.isfinite(txp)):
        raise InvalidParameterError("tx_positions_m must be a finite (n_tx, 3) array")
    order = list(range(len(txp))) if order is None else [int(i) for i in order]
    if not order or any(not 0 <= i < len(txp) for i in order):
        raise InvalidParameterError(f"order={order!r} must index tx_positions_m")
    n_windows = len(order) if n_windows is None else V.positive_int("n_windows", n_windows)
    period_s = V.positive("period_s", period_s)
    latency_s = V.positive("latency_s", latency_s, allow_zero=True)
    if snr_db is not None:
        snr_db = V.in_range("snr_db", snr_db, -60.0, 200.0)
    extra = [(V.positive("excess_delay_s", d), float(g)) for d, g in extra_paths]
    c = speed_of_sound_m_s(temp_c)
    rxp = receiver_positions(pose, radius_m=radius_m, n=n_receivers, height_m=receiver_height_m)
    if room is not None:
        for name, pts in (("transmitter", txp), ("receiver", rxp)):
            for i, p in enumerate(pts):
                if not room.contains(p):
                    raise InvalidParameterError(f"{name} {i} at {p.tolist()} is outside the room")

    emitted = tx.apply(np.concatenate([burst_waveform(burst), np.zeros(int(0.002 * fs))]), fs=fs)
    e_direct = float(np.sum(rx.apply(emitted, fs=fs) ** 2))  # energy at 1 m
    per = period_s * fs
    n_samp = int(math.ceil(n_windows * per))
    x = np.zeros((len(rxp), n_samp))
    windows, weakest = [], math.inf
    for w in range(n_windows):
        k = order[w % len(order)]
        start = round(w * per)
        if room is None:
            srcs, gains = txp[k][None, :], np.ones(1)
        else:
            srcs, gains, _ = image_sources(txp[k], room)
        dists = []
        for r, rp in enumerate(rxp):
            d_dir = float(np.linalg.norm(txp[k] - rp))
            dists.append(d_dir)
            weakest = min(weakest, 1.0 / max(d_dir, 1e-3))
            for s, g in zip(srcs, gains, strict=True):
                d = max(float(np.linalg.norm(s - rp)), 1e-3)
                _add_path(x[r], emitted, start + (latency_s + d / c) * fs, g / d)
            for dt, g in extra:
                _add_path(x[r], emitted, start + (latency_s + d_dir / c + dt) * fs, g / d_dir)
        windows.append({"window": w, "tx": k, "start_sample": int(start), "distances_m": dists})
    x = rx.apply(x, fs=fs)
    sigma = 0.0
    if snr_db is not None:
        t_drive = burst.duration_s
        b_hz = burst.band_hz[1] - burst.band_hz[0]
        p_sig = weakest**2 * e_direct / fs / t_drive  # E / T of the weakest, energy in s
        n0 = p_sig / (10.0 ** (snr_db / 10.0) * b_hz)  # one-sided PSD
        sigma = math.sqrt(n0 * fs / 2.0)
        rng = np.random.default_rng(rng)
        for r in range(len(x)):
            x[r] += sigma * make_noise(n_samp, rng=rng)
    truth = {
        "scheme": "oneway",
        "fs": fs,
        "temp_c": float(temp_c),
        "speed_of_sound_m_s": c,
        "latency_s": latency_s,
        "period_s": period_s,
        "snr_db": snr_db,
        "noise_sigma": sigma,
        "burst": {
            "code": list(burst.code),
            "carrier_hz": burst.carrier_hz,
            "cycles_per_bit": burst.cycles_per_bit,
            "amplitude": burst.amplitude,
        },
        "transducer_q": {"tx": tx.q, "rx": rx.q},
        "tx_positions_m": txp.tolist(),
        "pose": [float(v) for v in np.asarray(pose, dtype=float)],
        "receivers_m": rxp.tolist(),
        "room": None
        if room is None
        else {
            "size_m": list(room.size_m),
            "absorption": room.absorption,
            "max_order": room.max_order,
        },
        "extra_paths": [list(p) for p in extra],
        "windows": windows,
    }
    return UltrasonicSim(x, fs, truth)


def specular_echoes(
    plan, pose, *, mount_angle_rad: float = 0.0, beam_width_rad: float | None = None
):
    """First-order specular wall echoes heard by a pulse-echo sensor at ``pose``.

    A flat wall returns a ping to a co-located transmitter and receiver only from the foot
    of the perpendicular (the image-source method in 2-D). For every solid wall segment
    whose foot lies on the segment, in front of the sensor and not hidden by a nearer wall,
    returns its distance ``d`` (m), off-axis angle ``psi`` (rad) and relative amplitude
    ``D(psi)^2 / (2 d)`` (two-way beam pattern of
    :func:`rangekit.sensors.srf02.beam_pattern`, spherical spreading over the path ``2 d``),
    sorted by distance.

    Examples
    --------
    >>> from rangekit.floorplan import FloorPlan
    >>> plan = FloorPlan.from_walls([((2, -5), (2, 5)), ((-3, -5), (-3, 5))])
    >>> d, psi, amp = specular_echoes(plan, (0.0, 0.0, 0.0))
    >>> d.tolist(), psi.tolist(), amp.round(3).tolist()
    ([2.0], [0.0], [0.25])
    """
    from rangekit.floorplan import cast_rays
    from rangekit.sensors.srf02 import BEAM_WIDTH_RAD, beam_pattern

    bw = BEAM_WIDTH_RAD if beam_width_rad is None else V.positive("beam_width_rad", beam_width_rad)
    p = np.asarray(pose, dtype=np.float64)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise InvalidParameterError(f"pose={pose!r} must be (x, y, heading_rad), finite")
    seg = np.asarray(plan.segments, dtype=np.float64)
    if len(seg) == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    a, e = seg[:, :2], seg[:, 2:] - seg[:, :2]
    u = ((p[:2] - a) @ np.eye(2) * e).sum(axis=1) / (e * e).sum(axis=1)
    foot = a + u[:, None] * e
    v = foot - p[:2]
    d = np.hypot(v[:, 0], v[:, 1])
    psi = np.angle(np.exp(1j * (np.arctan2(v[:, 1], v[:, 0]) - p[2] - mount_angle_rad)))
    ok = (u >= 0.0) & (u <= 1.0) & (np.abs(psi) < 0.5 * math.pi) & (d > 1e-6)
    idx = np.flatnonzero(ok)
    if len(idx):
        hits = cast_rays(plan, p[:2], np.arctan2(v[idx, 1], v[idx, 0]), d[idx] * (1 + 1e-9))
        seen = ~(hits.distance_m < d[idx] - 1e-6)
        idx = idx[seen]
    order = idx[np.argsort(d[idx])]
    amp = beam_pattern(psi[order], beam_width_rad=bw) ** 2 / (2.0 * d[order])
    return d[order], psi[order], amp


def render_echo(
    plan,
    poses,
    *,
    sensor=None,
    mount_angle_rad: float = 0.0,
    fs: float = 192000.0,
    burst: CodedBurst | None = None,
    transducer: Transducer | None = None,
    temp_c: float = DEFAULT_TEMP_C,
    snr_db: float | None = 20.0,
    ring_gain: float = 30.0,
    rng=None,
) -> UltrasonicSim:
    """Render an SRF02 echo recording: one ranging cycle per pose, sample 0 = first ping.

    Each cycle lasts ``sensor.cycle_s`` (70 ms). It holds the ring-down (the drive through
    the transducer at ``ring_gain`` times the amplitude of an on-axis echo from 1 m, at
    lag 0) and every first-order specular wall echo (:func:`specular_echoes`) delayed by
    ``2 d / c`` with its amplitude; the ping passes the transducer on the way out and in.
    The noise is white; ``snr_db`` is the in-band SNR (as for :func:`render_oneway`) of an
    on-axis echo at the sensor's maximum range, so the detection limit of the rendered
    echoes follows the sensor's maximum range versus angle.

    The truth holds per cycle the model range of :func:`rangekit.sensors.srf02.model_range`
    with ``method="specular"`` (NaN = out of range) and the rendered echoes.

    Parameters
    ----------
    plan : FloorPlan
        The walls.
    poses : array_like, shape (3,) or (n_cycles, 3)
        Sensor carrier poses ``(x, y, heading_rad)``, one per ranging cycle.
    sensor : SRF02, optional
        Sensor parameters (beam, ranges, cycle).
    mount_angle_rad : float
        Sensor axis relative to the heading.
    fs : float
        Sample rate in Hz (default 192 kHz).
    burst : CodedBurst, optional
        The ping (default the SRF02's 8 cycles of 40 kHz).
    transducer : Transducer, optional
        The transducer (default Q = 4).
    temp_c : float
        Air temperature.
    snr_db : float or None
        See above; None = no noise.
    ring_gain : float
        Ring-down amplitude relative to a 1 m on-axis echo.
    rng : seed or Generator
        Randomness for the noise.
    """
    from rangekit.sensors.srf02 import SRF02, model_range
    from rangekit.signals.barker import srf02_ping

    sensor = SRF02() if sensor is None else sensor
    fs = V.sample_rate(fs)
    burst = srf02_ping(fs=fs) if burst is None else burst.with_fs(fs)
    transducer = Transducer() if transducer is None else transducer
    p = np.asarray(poses, dtype=np.float64)
    if p.ndim == 1:
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != 3 or len(p) == 0 or not np.all(np.isfinite(p)):
        raise InvalidParameterError("poses must be finite (x, y, heading_rad) rows")
    if snr_db is not None:
        snr_db = V.in_range("snr_db", snr_db, -60.0, 200.0)
    ring_gain = V.positive("ring_gain", ring_gain, allow_zero=True)
    c = speed_of_sound_m_s(temp_c)
    drive = np.concatenate([burst_waveform(burst), np.zeros(int(0.002 * fs))])
    emitted = transducer.apply(drive, fs=fs)
    per = sensor.cycle_s * fs
    n_samp = int(math.ceil(len(p) * per))
    x = np.zeros(n_samp)
    truth_model = model_range(plan, p, sensor, mount_angle_rad=mount_angle_rad, method="specular")
    cycles = []
    for k, pose in enumerate(p):
        start = round(k * per)
        _add_path(x, emitted, float(start), ring_gain)
        d, psi, amp = specular_echoes(
            plan, pose, mount_angle_rad=mount_angle_rad, beam_width_rad=sensor.aperture_rad
        )
        keep = 2.0 * d / c < sensor.cycle_s
        for dk, ak in zip(d[keep], amp[keep], strict=True):
            _add_path(x, emitted, start + 2.0 * dk / c * fs, 2.0 * ak)  # 2 a: 1 at 1 m on axis
        m = float(truth_model[k])
        cycles.append(
            {
                "window": k,
                "start_sample": int(start),
                "pose": pose.tolist(),
                "distance_m": m if math.isfinite(m) else None,
                "echoes": [
                    {"distance_m": float(a), "off_axis_rad": float(b), "amplitude": float(2 * g)}
                    for a, b, g in zip(d, psi, amp, strict=True)
                ],
            }
        )
    x = transducer.apply(x, fs=fs)
    sigma = 0.0
    if snr_db is not None:
        e_1m = float(np.sum(transducer.apply(emitted, fs=fs) ** 2)) / fs  # energy, 1 m on axis
        ref = 1.0 / sensor.max_range_m  # amplitude of an on-axis echo at max range
        b_hz = burst.band_hz[1] - burst.band_hz[0]
        n0 = ref**2 * e_1m / burst.duration_s / (10.0 ** (snr_db / 10.0) * b_hz)
        sigma = math.sqrt(n0 * fs / 2.0)
        x += sigma * make_noise(n_samp, rng=np.random.default_rng(rng))
    truth = {
        "scheme": "echo",
        "fs": fs,
        "temp_c": float(temp_c),
        "speed_of_sound_m_s": c,
        "period_s": sensor.cycle_s,
        "snr_db": snr_db,
        "noise_sigma": sigma,
        "mount_angle_rad": float(mount_angle_rad),
        "transducer_q": transducer.q,
        "sensor": {
            "aperture_rad": sensor.aperture_rad,
            "min_range_m": sensor.min_range_m,
            "max_range_m": sensor.max_range_m,
            "cycle_s": sensor.cycle_s,
        },
        "windows": cycles,
    }
    return UltrasonicSim(x[None, :], fs, truth)
