"""Render long recordings of repeated two-way exchanges of any probe signal.

:func:`render_exchanges` is :func:`rangekit.sim.recording.render_beepbeep` repeated:
exchange k starts at ``t0 + k * period_s`` (``t0``: the latest recording start plus
``lead_s``), and in every exchange each device plays ``source`` in turn (device 0 first,
Jiang et al. 2018, Algorithm 1), each after the previous device's signal ended plus a
gap and a random jitter. It is the simulator behind sample-clock-rate estimation
(:mod:`rangekit.ranging.clock`): 40 exchanges of 1 s sweeps by 2 devices in a shoebox
room render in about a second.

Time model
----------
That of :mod:`rangekit.sim.recording`. Absolute time t is shared by all devices. Device
i's sample n is taken at ``t = rec_start_s[i] + n / (fs_i (1 + ppm_i 1e-6))``; device
j's source sample k in exchange e is emitted at
``t = play_s[e, j] + k / (source_fs (1 + ppm_j 1e-6))``. A path of length r (direct, or
an image source of a shoebox room) adds delay r / c and gain g / r.

Schedule: ``play_s[e, 0] = t0 + e * period_s``;
``play_s[e, j] = play_s[e, j-1] + D (1 - ppm_{j-1} 1e-6) + gap_s[j-1] + U_ej`` with
``D = len(source) / source_fs`` (the previous device's signal ends after ``D / (1 +
ppm_{j-1} 1e-6)``, to first order in its clock error -- the expression
``render_beepbeep`` uses) and ``U_ej`` uniform in ``[0, jitter_s]``, drawn from ``rng``
per exchange and gap (before the noise; nothing is drawn when ``jitter_s`` is 0).

How it is fast
--------------
Evaluating every image source over the whole source for every exchange (what
``render_beepbeep`` does once) costs ``images x len(source)`` interpolations per
exchange. Here, per (source device j, microphone i):

1. The room impulse response is built once on device j's emission grid (unit: one
   source sample at ``source_fs (1 + ppm_j 1e-6)``): ``h[m] = sum_p (g_p / r_p)
   k(m + m0 - tau_p)``, ``tau_p = r_p / c * source_fs (1 + ppm_j 1e-6)`` fractional
   taps of the band-limited kernel k of :func:`rangekit.sim._fracdelay.interp_bandlimited`
   (``half_width=32``, ``cutoff=1``), ``m0`` the first tap.
2. The received waveform ``w = source * h`` (:func:`scipy.signal.fftconvolve`) is
   computed once: ``w[m]`` is what reaches microphone i at ``play + (m + m0) / (source_fs
   (1 + ppm_j 1e-6))`` when device j starts playing at ``play``. In free field there is
   one path and ``w = source / r`` with the delay kept exact (``m0 = tau``, no step 1).
3. For every exchange, ``w`` is evaluated at device i's sample times by band-limited
   interpolation at the exact fractional positions ``u_n = (t_n - play) source_fs (1 +
   ppm_j 1e-6) - m0`` (the kernel of ``interp_bandlimited``, ``half_width=32``,
   ``cutoff=0.95``, read from a table of 4096 phases with linear interpolation
   between phases: within 1e-7 of the direct evaluation).

Exactness against ``render_beepbeep`` (tested): in free field step 3 is the same
evaluation, so the recordings agree to ~1e-7 of their peak (the phase table). In a room
they agree to ~1e-4: ``render_beepbeep`` evaluates ``source`` at ``u - tau_p`` with the
80 dB stopband kernel, whose residual image of the tone above Nyquist (e.g. 28.1 kHz for
a 16 kHz beep at 44.1 kHz, 80 dB down) takes the phase of the fractional delay; the
two-stage path (delay by ``h``, then interpolate) gives that image a different phase.
Both are within the kernel's 80 dB design of the continuous-time signal.

Noise
-----
As ``render_beepbeep``: per channel at ``snr_db``, the power of the weakest direct
arrival on that channel over the full-band noise power. For a general source the
arrival's power is ``P / r^2`` with ``P`` the source's mean power over its non-zero
samples (its duration for a sweep or tone; for a burst train such as the beep the silent
gaps are not counted, so ``P`` is within 0.3 dB of the beep's plateau power ``A^2 / 2``).
Then each channel is scaled to a peak of ``peak``.

Ground truth
------------
``SimResult.truth`` has the layout of ``render_beepbeep``'s (``devices[i]["play_s"]``
and ``devices[i]["onsets"]`` are those of exchange 0), with ``"source"`` in place of
``"beep"``, plus ``"exchanges"``: per exchange ``{"play_s": [N absolute play times],
"onsets": N x N}``, ``onsets[i][j]`` the direct arrival of device j's signal (its first
sample) in device i's recording, in device i's samples.

Examples
--------
>>> from rangekit.signals import Beep, beep_waveform
>>> from rangekit.sim import pair_devices
>>> devs = pair_devices(2.0, clock_ppm=(0.0, 50.0))
>>> sim = render_exchanges(devs, source=beep_waveform(Beep()), source_fs=44100.0,
...                        n_exchanges=3, period_s=2.0, snr_db=None, rng=0)
>>> len(sim.truth["exchanges"]), round(sim.truth["exchanges"][2]["play_s"][0], 3)
(3, 4.15)
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence

import numpy as np
import scipy.signal
from numba import njit

from rangekit import _validate as V
from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.physics import speed_of_sound_m_s
from rangekit.sim._fracdelay import interp_bandlimited
from rangekit.sim.noise import make_noise
from rangekit.sim.recording import Device, SimResult, device_truth, pair_truth, room_truth
from rangekit.sim.room import ShoeboxRoom, image_sources

__all__ = ["render_exchanges"]

#: Half-width and cutoff of the recording interpolator (those of ``render_beepbeep``).
_HW = 32
_CUTOFF = 0.95
#: Half-width of the room-impulse-response taps; cutoff 1 (no extra lowpass).
_HW_RIR = 32
#: Phases of the interpolation table (linear interpolation between them).
_PHASES = 4096
#: Largest share of the source's energy allowed above 0.95 x a recording's Nyquist.
_ALIAS_SHARE = 1e-6


@functools.lru_cache(maxsize=2)
def _phase_table(half_width: int, cutoff: float, phases: int) -> np.ndarray:
    """``T[p, q] = k(p / phases + half_width - 1 - q)``: the kernel at every tap of a phase.

    Values come from :func:`interp_bandlimited` applied to a unit impulse, so they are
    its kernel exactly.
    """
    hw = half_width
    imp = np.zeros(2 * hw + 1)
    imp[hw] = 1.0
    t = (np.arange(phases + 1) / phases)[:, None] + (hw - 1 - np.arange(2 * hw))[None, :]
    vals = interp_bandlimited(imp, (t + hw).ravel(), half_width=hw, cutoff=cutoff)
    return vals.reshape(phases + 1, 2 * hw)


@njit(cache=True)
def _place_kernel(
    out: np.ndarray, n0: int, u: np.ndarray, w: np.ndarray, table: np.ndarray
) -> None:
    """``out[n0 + i] += sum_k w[k] k(u[i] - k)`` from the phase table (in place)."""
    n_w = w.shape[0]
    n_taps = table.shape[1]
    hw = n_taps // 2
    phases = table.shape[0] - 1
    for i in range(u.shape[0]):
        pos = u[i]
        if pos - hw >= n_w - 1 or pos + hw <= 0.0:
            continue
        k0 = math.floor(pos)
        ph = (pos - k0) * phases
        ip = min(int(ph), phases - 1)
        a = ph - ip
        k_start = k0 - hw + 1
        q_lo = max(0, -k_start)
        q_hi = min(n_taps, n_w - k_start)
        acc = 0.0
        for q in range(q_lo, q_hi):
            t0 = table[ip, q]
            acc += w[k_start + q] * (t0 + a * (table[ip + 1, q] - t0))
        out[n0 + i] += acc


def _received(
    src: np.ndarray, dj: Device, di: Device, *, rate_j: float, c: float, room: ShoeboxRoom | None
) -> tuple[np.ndarray, float]:
    """Waveform ``w`` at microphone i when device j plays ``src``, and its delay in j-samples.

    ``w[m]`` arrives at ``play + (m + m0) / rate_j``; returns ``(w, m0)``.
    """
    if room is None:
        r = max(float(np.linalg.norm(dj.speaker_m - di.mic_m)), 1e-3)
        return src / r, r / c * rate_j
    pos, gains, _ = image_sources(dj.speaker_m, room)
    r = np.maximum(np.linalg.norm(pos - di.mic_m[None, :], axis=1), 1e-3)
    tau = r / c * rate_j
    hw = _HW_RIR
    m0 = math.floor(float(tau.min())) - hw
    n_h = math.ceil(float(tau.max())) + hw + 1 - m0
    # Taps m with |m + m0 - tau_p| < hw of every path, as one interpolation of an impulse.
    base = np.floor(tau).astype(np.int64) - m0 - hw + 1
    m = base[:, None] + np.arange(2 * hw)[None, :]
    imp = np.zeros(2 * hw + 1)
    imp[hw] = 1.0
    taps = interp_bandlimited(
        imp, ((m + m0) - tau[:, None] + hw).ravel(), half_width=hw, cutoff=1.0
    ).reshape(m.shape)
    h = np.zeros(n_h)
    np.add.at(h, m.ravel(), (taps * (gains / r)[:, None]).ravel())
    return scipy.signal.fftconvolve(src, h), float(m0)


def _check_source_fits(src: np.ndarray, source_fs: float, devices: Sequence[Device]) -> None:
    """Refuse a source with energy where a recording's interpolator cannot carry it."""
    spec = np.abs(np.fft.rfft(src)) ** 2
    f = np.fft.rfftfreq(len(src), d=1.0 / source_fs)
    total = float(spec.sum())
    for i, d in enumerate(devices):
        f_max = _CUTOFF * 0.5 * min(d.fs, source_fs)
        share = float(spec[f > f_max].sum()) / total
        if share > _ALIAS_SHARE:
            raise IncompatibleInputError(
                f"device {i}: {share:.1e} of the source's energy lies above {f_max:g} Hz, "
                f"beyond what fs={d.fs:g} Hz (source_fs={source_fs:g} Hz) can carry; "
                "lower the source's band or raise the sample rate"
            )


def _schedule(
    n_exchanges: int,
    t0: float,
    period_s: float,
    gaps: np.ndarray,
    jitter: np.ndarray,
    duration_s: float,
    ppm: np.ndarray,
) -> np.ndarray:
    """Absolute play times, shape (n_exchanges, N)."""
    n_dev = len(ppm)
    play = np.zeros((n_exchanges, n_dev))
    play[:, 0] = t0 + np.arange(n_exchanges) * period_s
    for j in range(1, n_dev):
        play[:, j] = (
            play[:, j - 1] + duration_s * (1 - ppm[j - 1] * 1e-6) + gaps[j - 1] + jitter[:, j - 1]
        )
    return play


def render_exchanges(
    devices: Sequence[Device],
    *,
    source: np.ndarray,
    source_fs: float,
    n_exchanges: int = 1,
    period_s: float = 2.0,
    gap_s: float | Sequence[float] = 0.25,
    jitter_s: float = 0.0,
    temp_c: float = 20.0,
    snr_db: float | None = 20.0,
    noise: str = "white",
    room: ShoeboxRoom | None = None,
    lead_s: float = 0.15,
    tail_s: float = 0.15,
    peak: float = 0.5,
    rng=None,
    progress: Callable[[int, int], None] | None = None,
) -> SimResult:
    """Render the recordings of ``n_exchanges`` exchanges of ``source``, every device in turn.

    Parameters
    ----------
    devices : sequence of Device
        Two or more devices; device j plays j-th in every exchange.
    source : array_like, shape (L,)
        The signal every device plays (the beep, a sweep, ...), sampled at ``source_fs``;
        sample 0 is its start (the truth onsets are where it arrives).
    source_fs : float
        Sample rate of ``source`` in Hz (device j emits it through its own clock).
    n_exchanges : int
        Number of exchanges, >= 1.
    period_s : float
        Time between the starts of consecutive exchanges (device 0's plays), s; must
        exceed one exchange (every device's signal, gap and jitter).
    gap_s : float or sequence of float
        Silence between the end of one device's signal and the start of the next (one
        per gap, N - 1), s.
    jitter_s : float
        Each gap of each exchange is lengthened by a uniform random time in
        ``[0, jitter_s]``, s.
    temp_c : float
        Air temperature; sets the speed of sound.
    snr_db : float or None
        Per-channel SNR of the weakest direct arrival, full band (see Noise in the module
        docstring); None for no noise.
    noise : {"white", "pink"}
        Noise colour.
    room : ShoeboxRoom, optional
        Adds wall reflections (image sources up to ``room.max_order``); positions must be
        inside the room. None for free field.
    lead_s : float
        Time from the latest recording start to the first exchange.
    tail_s : float
        Recording time after the last signal has reached every microphone.
    peak : float
        Peak level of each rendered channel.
    rng : seed or Generator
        Randomness for the jitter, then the noise.
    progress : callable, optional
        ``progress(done, total)`` after each placed signal (``total = N^2 n_exchanges``
        for N devices: every device's signal in every recording); nothing is printed.

    Returns
    -------
    SimResult
        Recordings, nominal rates and truth (``truth["exchanges"]``: see the module
        docstring).

    Raises
    ------
    InvalidParameterError
        Fewer than 2 devices, a parameter out of its domain, a position outside the room,
        or a period shorter than one exchange.
    IncompatibleInputError
        The source has energy above 0.95 x the Nyquist frequency of a recording (or of
        ``source_fs``).

    Notes
    -----
    With ``n_exchanges=1`` and ``source=beep_waveform(beep)`` the recordings are
    ``render_beepbeep``'s (same devices, gaps, room and ``rng``): to ~1e-7 of the peak in
    free field and ~1e-4 in a room (module docstring, "How it is fast").
    """
    devices = list(devices)
    n_dev = len(devices)
    if n_dev < 2:
        raise InvalidParameterError(f"need at least 2 devices, got {n_dev}")
    src = V.signal_1d("source", source)
    if len(src) == 0 or not np.any(src):
        raise InvalidParameterError("source must hold at least one non-zero sample")
    source_fs = V.sample_rate(source_fs)
    n_exchanges = V.positive_int("n_exchanges", n_exchanges)
    period_s = V.positive("period_s", period_s)
    jitter_s = V.positive("jitter_s", jitter_s, allow_zero=True)
    lead_s = V.positive("lead_s", lead_s, allow_zero=True)
    tail_s = V.positive("tail_s", tail_s, allow_zero=True)
    peak = V.positive("peak", peak)
    if snr_db is not None:
        snr_db = V.in_range("snr_db", snr_db, -60.0, 200.0)
    gaps = np.broadcast_to(np.asarray(gap_s, dtype=np.float64), (n_dev - 1,)).copy()
    if not np.all(np.isfinite(gaps)) or np.any(gaps < 0):
        raise InvalidParameterError(f"gap_s={gap_s!r} must be finite and >= 0")
    if room is not None:
        for i, d in enumerate(devices):
            for name in ("speaker_m", "mic_m"):
                if not room.contains(getattr(d, name)):
                    raise InvalidParameterError(f"device {i} {name} is outside the room")
    _check_source_fits(src, source_fs, devices)
    c = speed_of_sound_m_s(temp_c)
    rng = np.random.default_rng(rng)
    ppm = np.array([d.clock_ppm for d in devices])
    duration_s = len(src) / source_fs
    span_s = n_dev * duration_s * (1 + float(np.max(np.abs(ppm))) * 1e-6)
    span_s += float(gaps.sum()) + (n_dev - 1) * jitter_s
    if n_exchanges > 1 and period_s <= span_s:
        raise InvalidParameterError(
            f"period_s={period_s!r} must exceed one exchange ({span_s:.3f} s: {n_dev} "
            f"signals of {duration_s:.3f} s, the gaps and the jitter)"
        )

    if jitter_s > 0:
        jitter = rng.uniform(0.0, jitter_s, size=(n_exchanges, n_dev - 1))
    else:
        jitter = np.zeros((n_exchanges, n_dev - 1))
    t0 = max(d.rec_start_s for d in devices) + lead_s
    play = _schedule(n_exchanges, t0, period_s, gaps, jitter, duration_s, ppm)

    max_r = max(float(np.linalg.norm(a.speaker_m - b.mic_m)) for a in devices for b in devices)
    if room is not None:
        max_r = max(max_r, 2.0 * float(np.linalg.norm(room.size_m)) * (room.max_order + 1))
    t_end = float(play[-1, -1]) + duration_s * 1.001 + max_r / c + tail_s
    nz = src[src != 0.0]
    src_power = float(np.mean(nz**2))
    table = _phase_table(_HW, _CUTOFF, _PHASES)

    recordings, truth_dev = [], []
    onsets = np.zeros((n_exchanges, n_dev, n_dev))
    done, total = 0, n_dev * n_dev * n_exchanges
    for i, di in enumerate(devices):
        rate_i = di.fs * (1 + di.clock_ppm * 1e-6)
        n_samp = int(math.ceil((t_end - di.rec_start_s) * rate_i))
        x = np.zeros(n_samp)
        weakest = math.inf
        for j, dj in enumerate(devices):
            rate_j = source_fs * (1 + dj.clock_ppm * 1e-6)
            w, m0 = _received(src, dj, di, rate_j=rate_j, c=c, room=room)
            shift_s = m0 / rate_j
            for e in range(n_exchanges):
                if progress is not None:
                    done += 1
                    progress(done, total)
                t_w = play[e, j] + shift_s  # absolute time of w[0]
                n0 = max(0, int(math.floor((t_w - di.rec_start_s) * rate_i)) - 2 * _HW)
                n1 = min(
                    n_samp,
                    int(math.ceil((t_w + len(w) / rate_j - di.rec_start_s) * rate_i)) + 2 * _HW,
                )
                if n1 <= n0:
                    continue
                t_n = di.rec_start_s + np.arange(n0, n1) / rate_i
                _place_kernel(x, n0, (t_n - t_w) * rate_j, w, table)
            r_dir = float(np.linalg.norm(dj.speaker_m - di.mic_m))
            onsets[:, i, j] = (play[:, j] + r_dir / c - di.rec_start_s) * rate_i
            weakest = min(weakest, src_power / max(r_dir, 1e-3) ** 2)
        sigma = 0.0
        if snr_db is not None:
            sigma = math.sqrt(weakest / 10 ** (float(snr_db) / 10))
            x += sigma * make_noise(n_samp, kind=noise, rng=rng)
        scale = peak / float(np.max(np.abs(x)))
        recordings.append(x * scale)
        truth_dev.append(
            device_truth(
                di, play_s=float(play[0, i]), onsets=onsets[0, i], noise_sigma=sigma * scale
            )
        )
    pairs = pair_truth(devices)
    truth = {
        "scheme": "beepbeep",
        "temp_c": float(temp_c),
        "speed_of_sound_m_s": c,
        "snr_db": None if snr_db is None else float(snr_db),
        "noise": noise,
        "source": {
            "fs": source_fs,
            "n_samples": len(src),
            "duration_s": duration_s,
            "power": src_power,
        },
        "room": room_truth(room),
        "n_exchanges": n_exchanges,
        "period_s": period_s,
        "gap_s": gaps.tolist(),
        "jitter_s": jitter_s,
        "devices": truth_dev,
        "pairs": pairs,
        "exchanges": [
            {"play_s": play[e].tolist(), "onsets": onsets[e].tolist()} for e in range(n_exchanges)
        ],
    }
    return SimResult(recordings, [d.fs for d in devices], truth)
