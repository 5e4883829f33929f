"""Long recordings ranged block by block with bounded memory (``rangekit range --series``).

A recording of any length -- a phone recording with a beep exchange every few seconds, a
192 kHz one-way beacon log or SRF02 echo log with a burst every cycle -- is read a block
at a time, each block is ranged with the whole-file code, and the ranges come out as a
time series: the generators below yield one item per exchange (two-way) or per window
(ultrasonic) as soon as its block is done. Memory is bounded by the block size plus the
overlap, not by the length of the recording.

Two-way (BeepBeep) series
-------------------------
Inputs as for :func:`rangekit.ranging.range_files`: one file with one channel per device,
or one mono file per device, read in lockstep. An *exchange* is every device's beep in
index order, device 0 first (Jiang et al. 2018, Algorithm 1); exchanges repeat.

1. Block ``k`` owns the samples ``[k B, (k + 1) B)`` of device 0's recording (its
   *core*). It is read with ``skew_s + D`` seconds before and ``exchange_s + skew_s + D +
   0.05`` s after the core (D: the beep's duration), so every beep of an exchange that
   starts in the core lies whole in the block.
2. The beeps of every channel are detected in the block (:func:`rangekit.detect.detect`).
3. Exchanges are anchored on device 0's recording: its earliest beep after the previous
   exchange, at ``t0``, is device 0's own beep. The exchange's beeps are, on device 0's
   recording, those starting in ``[t0, t0 + exchange_s + skew_s]``, and on device i's
   recording those in ``[t0 - skew_s, t0 + exchange_s + skew_s]`` (``skew_s`` covers the
   time of flight and a difference of the recordings' start times). The next anchor is
   device 0's first beep after ``t0 + exchange_s + skew_s``; consecutive exchanges must
   therefore start more than ``exchange_s + 2 skew_s`` apart.
4. An exchange belongs to the block whose core holds its anchor: one that straddles a
   block boundary is ranged exactly once (de-duplicated by its onset time).
5. With exactly N beeps on every channel, the exchange is ranged by
   :func:`rangekit.ranging.beepbeep.range_beepbeep` (Peng et al. 2007; two-way distance
   ``D_ab = c/2 ((t_a[b] - t_a[a]) - (t_b[b] - t_b[a])) + (s_a + s_b)/2``). Otherwise its
   rows carry a NaN distance and the flag ``"detection"``, ``error`` says what was found,
   and the series goes on.

Ultrasonic series
-----------------
The windows of ``period_s`` are those of :func:`rangekit.ranging.ultrasonic.window_starts`
(window k starts at ``round(k period fs)``). A block holds whole windows and is read with
the matched filter's reach (the analytic FIR's taps before and after lag 0) of context
on both sides, so each window's matched-filter output is the whole file's and its range is
the one :func:`~rangekit.ranging.ultrasonic.range_oneway` /
:func:`~rangekit.ranging.ultrasonic.range_echo` give for the whole file (to FFT rounding).

Time origin: ``t_s`` of an exchange is its anchor, the onset of device 0's beep in device
0's recording (seconds from its sample 0); ``t_s`` of a window is the window's start.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace

import numpy as np

from rangekit import _validate as V
from rangekit.detect import DETECTORS, detect
from rangekit.detect._kernels import recording_samples
from rangekit.errors import (
    AudioFormatError,
    DetectionError,
    IncompatibleInputError,
    InvalidParameterError,
)
from rangekit.physics import DEFAULT_TEMP_C, Medium
from rangekit.ranging.beepbeep import (
    DEFAULT_CLOCK_PPM,
    range_beepbeep,
    self_distances,
)
from rangekit.ranging.ultrasonic import ULTRASONIC_SCHEMES, ToF
from rangekit.signals.beep import Beep, check_beep_fits
from rangekit.signals.probe import Probe
from rangekit.types import Arrivals, Range

__all__ = [
    "DEFAULT_BLOCK_SAMPLES",
    "DEFAULT_SKEW_S",
    "SERIES_FIELDS",
    "ExchangeRanges",
    "WindowRanges",
    "default_exchange_s",
    "range_series_beepbeep",
    "range_series_ultrasonic",
]

#: Default block: this many samples of all channels together (2^21: 16 MB of float64;
#: 23.8 s of a stereo 44.1 kHz recording, 10.9 s of a mono 192 kHz one). The whole command
#: then peaks at about 200 MB (``docs/performance.md``).
DEFAULT_BLOCK_SAMPLES = 1 << 21
#: Default allowance for the time of flight and the recordings' start-time differences, s.
DEFAULT_SKEW_S = 0.1
#: Longest gap between one device's beep and the next one's that the default
#: ``exchange_s`` allows for, s.
_DEFAULT_GAP_S = 0.5
#: Extra context after the last beep of an exchange (the detector's last frames), s.
_TAIL_S = 0.05

#: Output columns of a series, per scheme (``docs/formats.md``).
SERIES_FIELDS: dict[str, tuple[str, ...]] = {
    "beepbeep": ("t_s", "a", "b", "distance_m", "sigma_m", "flags"),
    "oneway": ("t_s", "window", "tx", "channel", "distance_m", "sigma_m", "snr_db", "arrival_s"),
    "echo": ("t_s", "window", "channel", "distance_m", "sigma_m", "snr_db", "arrival_s"),
}

#: Called after each block as ``progress(done_s, total_s)``: seconds of (device 0's)
#: recording finished so far, and its whole length.
ProgressFn = Callable[[float, float], None]


def _finite_or_none(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


@dataclass(frozen=True)
class ExchangeRanges:
    """The ranges of one exchange of a two-way series.

    Attributes
    ----------
    exchange : int
        Index of the exchange in the recording, from 0.
    t_s : float
        Onset of device 0's beep in device 0's recording, s from its sample 0.
    ranges : tuple of Range
        One per pair (a < b), ordered (0, 1), (0, 2), ..., (1, 2), ... On a detection
        failure ``distance_m`` and ``sigma_m`` are NaN and ``flags`` is ``("detection",)``.
    error : str or None
        What went wrong on a detection failure (beeps found per recording), else None.
    arrivals : tuple of Arrivals or None
        The beeps given to :func:`~rangekit.ranging.beepbeep.range_beepbeep`, one
        Arrivals per recording (device order), onsets as sample indices of the whole
        file; None on a detection failure. Used by :mod:`rangekit.ranging.clock`.
    """

    exchange: int
    t_s: float
    ranges: tuple[Range, ...]
    error: str | None = None
    arrivals: tuple[Arrivals, ...] | None = None

    def rows(self) -> list[dict]:
        """One dict per pair with the keys of ``SERIES_FIELDS["beepbeep"]`` (NaN -> None)."""
        return [
            {
                "t_s": self.t_s,
                "a": r.a,
                "b": r.b,
                "distance_m": _finite_or_none(r.distance_m),
                "sigma_m": _finite_or_none(r.sigma_m),
                "flags": list(r.flags),
            }
            for r in self.ranges
        ]


@dataclass(frozen=True)
class WindowRanges:
    """The ranges of one window (activation or ranging cycle) of an ultrasonic series.

    Attributes
    ----------
    window : int
        Window index, from 0 (window k starts at ``round(k period_s fs)``).
    t_s : float
        The window's start, s from sample 0.
    tofs : tuple of ToF
        One per channel, in channel order; ``distance_m`` NaN where nothing was found.
    """

    window: int
    t_s: float
    tofs: tuple[ToF, ...]

    def rows(self, *, scheme: str) -> list[dict]:
        """One dict per channel with the keys of ``SERIES_FIELDS[scheme]`` (NaN -> None)."""
        out = []
        for r in self.tofs:
            d = {"t_s": self.t_s, **r.as_dict()}
            if scheme == "echo":
                d.pop("tx")
            out.append(d)
        return out


def default_exchange_s(beep: Beep | Probe, n_devices: int) -> float:
    """Default longest exchange: ``(n_devices - 1) * (beep duration + 0.5 s)``.

    The time from device 0's beep to the last device's beep when each device starts its
    beep at most half a second after the previous beep ended.

    Examples
    --------
    >>> round(default_exchange_s(Beep(), 2), 4)
    0.8501
    """
    return (n_devices - 1) * (beep.duration_s + _DEFAULT_GAP_S)


def _block_s(block_s: float | None, *, fs: float, n_channels: int) -> float:
    if block_s is None:
        return (DEFAULT_BLOCK_SAMPLES // n_channels) / fs
    return V.positive("block_s", block_s)


# --- two-way -----------------------------------------------------------------------------


@dataclass(frozen=True)
class _Source:
    """One opened input file and the devices (channels) it holds."""

    path: str
    f: object  # soundfile.SoundFile
    fs: float
    frames: int
    devices: tuple[int, ...]  # device index of each channel of the file


def _open_sources(
    paths: Sequence[str | os.PathLike], beep: Beep, probe: Probe | None = None
) -> list[_Source]:
    """Open the inputs like :func:`rangekit.io.audio.load_devices` (same checks)."""
    from rangekit.io.audio import open_audio

    paths = [str(p) for p in paths]
    if not paths:
        raise IncompatibleInputError("no input files given")
    if len(paths) == 1:
        f = open_audio(paths[0])
        if f.channels < 2:
            f.close()
            raise IncompatibleInputError(
                f"'{paths[0]}' has {f.channels} channel(s) but 2 devices are needed: "
                "give one WAV with a channel per device, or one mono WAV per device"
            )
        devices = [tuple(range(f.channels))]
        files = [f]
    else:
        files = []
        try:
            for p in paths:
                f = open_audio(p)
                files.append(f)
                if f.channels != 1:
                    raise IncompatibleInputError(
                        f"'{p}' has {f.channels} channels: with several files, each must be "
                        "mono (one file per device)"
                    )
        except Exception:
            for f in files:
                f.close()
            raise
        devices = [(i,) for i in range(len(paths))]
    out = [
        _Source(p, f, float(f.samplerate), int(f.frames), dev)
        for p, f, dev in zip(paths, files, devices, strict=True)
    ]
    try:
        for s in out:
            if probe is not None:
                probe.check_fits(s.fs, what=f"'{s.path}'")
            else:
                check_beep_fits(beep, fs=s.fs, what=f"'{s.path}'")
    except Exception:
        for s in out:
            s.f.close()
        raise
    return out


def _device_name(src: _Source, col: int) -> str:
    return f"{src.path}#{col}" if len(src.devices) > 1 else src.path


def _shift(arr: Arrivals, offset: int) -> Arrivals:
    """Arrivals found in a block that starts at sample ``offset``, as file sample indices."""
    return replace(arr, onset=arr.onset + offset, burst_onsets=arr.burst_onsets + offset)


def _group_exchanges(
    onsets_s: Sequence[np.ndarray],
    *,
    lo_s: float,
    hi_s: float,
    after_s: float,
    exchange_s: float,
    skew_s: float,
) -> tuple[list[tuple[int, list[np.ndarray]]], float]:
    """Exchanges anchored on device 0 in ``[lo_s, hi_s)`` after ``after_s`` (step 3 above).

    ``onsets_s[i]`` are device i's beep onsets in seconds, sorted. Returns ``(anchor index
    in onsets_s[0], member indices per device)`` per exchange, and the end of the last
    exchange's window on device 0 (``after_s`` for the next block).
    """
    t_dev0 = onsets_s[0]
    out = []
    for j, t0 in enumerate(t_dev0.tolist()):
        if t0 < lo_s or t0 >= hi_s or t0 <= after_s:
            continue
        end = t0 + exchange_s + skew_s
        members = [np.flatnonzero((t_dev0 >= t0) & (t_dev0 <= end))]
        for t in onsets_s[1:]:
            members.append(np.flatnonzero((t >= t0 - skew_s) & (t <= end)))
        out.append((j, members))
        after_s = end
    return out, after_s


def range_series_beepbeep(
    paths: Sequence[str | os.PathLike],
    *,
    beep: Beep | None = None,
    detector: str = "changepoint",
    temp_c: float = DEFAULT_TEMP_C,
    speed_m_s: float | None = None,
    self_distance_m: float | Sequence[float] = 0.0,
    clock_ppm: float = DEFAULT_CLOCK_PPM,
    exchange_s: float | None = None,
    skew_s: float = DEFAULT_SKEW_S,
    block_s: float | None = None,
    progress: ProgressFn | None = None,
    probe: Probe | None = None,
    jobs: int = 1,
) -> Iterator[ExchangeRanges]:
    """Two-way ranges of every exchange in long recordings, block by block.

    Parameters
    ----------
    paths : sequence of path-like
        One file with one channel per device (channel i = device i), or one mono file per
        device (file i = device i), read in lockstep (files may differ in sample rate).
    beep, detector, temp_c, speed_m_s, self_distance_m, clock_ppm
        As for :func:`rangekit.ranging.range_channels`.
    exchange_s : float, optional
        Longest time from device 0's beep to the last device's beep within one exchange,
        s. Default :func:`default_exchange_s` (beeps at most 0.5 s apart).
    skew_s : float
        Allowance for the time of flight plus the difference between the recordings'
        start times, s (default 0.1 s). Exchanges must start more than
        ``exchange_s + 2 skew_s`` apart.
    block_s : float, optional
        Core of a block in seconds of device 0's recording (default: 2^21 samples over
        all devices, e.g. 23.8 s of a stereo 44.1 kHz file). Memory grows with
        ``block_s + exchange_s + 2 skew_s + 2 D`` (D: beep duration), not with the length.
    progress : callable, optional
        Called after each block as ``progress(done_s, total_s)``: seconds of device 0's
        recording finished so far, and its length.
    probe : Probe, optional
        The signal the devices played if not the beep (a sweep, a lab's own file):
        arrivals by :func:`rangekit.detect.template.detect_template`; its duration takes
        the beep's in the defaults above.
    jobs : int
        Worker processes detecting blocks in parallel (default 1: in this process). The
        blocks' detections are grouped into exchanges in order in this process, so the
        result does not depend on ``jobs``; memory grows with ``2 jobs`` blocks.

    Yields
    ------
    ExchangeRanges
        One per exchange, in time order, each as soon as its block is done. A detection
        failure in one exchange gives NaN distances flagged ``"detection"``; the series
        goes on.

    Raises
    ------
    InvalidParameterError, IncompatibleInputError, InputFileError, AudioFormatError
        As :func:`rangekit.ranging.range_files`; parameters are checked at the call, the
        files when iteration starts.
    DetectionError
        Device 0's recording holds no beep at all (raised at the end of the iteration).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> from rangekit.io.audio import write_audio
    >>> from rangekit.sim.recording import pair_devices, render_beepbeep
    >>> sim = render_beepbeep(pair_devices(2.0, self_distance_m=0.1), snr_db=None)
    >>> one = np.stack(sim.recordings, axis=1)  # one exchange, repeated every 3 s:
    >>> x = np.concatenate([np.pad(one, ((0, 3 * 44100 - len(one)), (0, 0)))] * 3)
    >>> x += 1e-3 * np.random.default_rng(0).standard_normal(x.shape)
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "series.wav"
    >>> write_audio(path, x, fs=44100.0)
    >>> ex = list(range_series_beepbeep([path], self_distance_m=0.1, block_s=2.0))
    >>> [round(e.t_s, 2) for e in ex], [round(e.ranges[0].distance_m, 2) for e in ex]
    ([0.15, 3.15, 6.15], [2.0, 2.0, 2.0])
    """
    beep = Beep() if beep is None else beep
    c = Medium(temp_c=temp_c, speed_m_s=speed_m_s).c
    V.in_range("clock_ppm", clock_ppm, 0.0, 1e4)
    if detector not in DETECTORS:
        raise InvalidParameterError(f"detector={detector!r} must be one of {', '.join(DETECTORS)}")
    if exchange_s is not None:
        exchange_s = V.positive("exchange_s", exchange_s)
    skew_s = V.positive("skew_s", skew_s, allow_zero=True)
    if block_s is not None:
        block_s = V.positive("block_s", block_s)
    jobs = V.positive_int("jobs", jobs)
    return _beepbeep_series(
        list(paths),
        beep=beep,
        detector=detector,
        c=c,
        self_distance_m=self_distance_m,
        clock_ppm=clock_ppm,
        exchange_s=exchange_s,
        skew_s=skew_s,
        block_s=block_s,
        progress=progress,
        probe=probe,
        jobs=jobs,
    )


def _beepbeep_series(
    paths,
    *,
    beep,
    detector,
    c,
    self_distance_m,
    clock_ppm,
    exchange_s,
    skew_s,
    block_s,
    progress,
    probe=None,
    jobs=1,
) -> Iterator[ExchangeRanges]:
    sources = _open_sources(paths, beep, probe)
    signal = beep if probe is None else probe  # what was played
    method = detector if probe is None else "template"
    try:
        n = sum(len(s.devices) for s in sources)
        self_distances(self_distance_m, n)
        ex_s = default_exchange_s(signal, n) if exchange_s is None else exchange_s
        src0 = sources[0]
        fs0, n0 = src0.fs, src0.frames
        step = max(1, int(round(_block_s(block_s, fs=fs0, n_channels=n) * fs0)))
        plan = _BlockPlan(
            step=step,
            fs0=fs0,
            pre_s=skew_s + signal.duration_s,
            post_s=ex_s + skew_s + signal.duration_s + _TAIL_S,
            signal=signal,
            method=method,
        )
        pairs = [(a, b) for a in range(n) for b in range(a + 1, n)]
        after_s = -math.inf
        count = 0
        cores = range(0, n0, step)
        if jobs > 1 and len(cores) > 1:
            blocks = _parallel_blocks(sources, paths, beep, probe, plan, cores, jobs)
        else:
            blocks = (_detect_block(sources, plan, core0) for core0 in cores)
        for core0, (arrivals, names) in zip(cores, blocks, strict=True):
            core1 = min(core0 + step, n0)
            # Grouping is serial (it carries after_s from block to block); the detection
            # above is per block, so any number of jobs gives the same exchanges.
            groups, after_s = _group_exchanges(
                [a.onset_s for a in arrivals],
                lo_s=core0 / fs0,
                hi_s=core1 / fs0,
                after_s=after_s,
                exchange_s=ex_s,
                skew_s=skew_s,
            )
            for j, members in groups:
                t0 = float(arrivals[0].onset_s[j])
                bad = [
                    f"'{names[i]}' has {len(m)} beep(s)"
                    for i, m in enumerate(members)
                    if len(m) != n
                ]
                if bad:
                    err = (
                        f"exchange {count} at {t0:.3f} s: " + ", ".join(bad) + f" where {n} "
                        f"(one per device) were expected within {ex_s:g} s (+-{skew_s:g} s)"
                    )
                    ranges = tuple(
                        Range(a, b, math.nan, math.nan, ("detection",)) for a, b in pairs
                    )
                    yield ExchangeRanges(count, t0, ranges, err)
                else:
                    taken = tuple(arrivals[i].take(m) for i, m in enumerate(members))
                    res = range_beepbeep(
                        taken,
                        speed_m_s=c,
                        self_distance_m=self_distance_m,
                        clock_ppm=clock_ppm,
                    )
                    yield ExchangeRanges(count, t0, res.ranges, arrivals=taken)
                count += 1
            if progress is not None:
                progress(core1 / fs0, n0 / fs0)
        if count == 0:
            raise DetectionError(
                f"'{_device_name(src0, 0)}': no beep found in {n0 / fs0:.1f} s of device 0's "
                "recording (check the beep options; `rangekit detect` shows what is found)"
            )
    finally:
        for s in sources:
            s.f.close()


@dataclass(frozen=True)
class _BlockPlan:
    """How the blocks of a two-way series are cut and detected (picklable for workers)."""

    step: int  # core length, device 0 samples
    fs0: float
    pre_s: float  # read before the core (skew + one signal)
    post_s: float  # read after it (one exchange + skew + one signal + a tail)
    signal: object
    method: str


#: How blocks are decoded: "auto" as :func:`rangekit.io.audio.read_audio` (integer PCM of
#: up to 24 bits straight into float32, exactly, as the whole-file path reads it), or
#: "float64" (:func:`rangekit.io.audio.read_frames`; the reader before 2026-12-02, kept as
#: the benchmarks' previous-code-path peer).
_BLOCK_DTYPE = "auto"
#: Integer subtypes: every sample finite and within full scale, so no whole-block check.
_INTEGER_SUBTYPES = frozenset({"PCM_S8", "PCM_U8", "PCM_16", "PCM_24", "ALAW", "ULAW"})


def _read_block(f, start: int, stop: int) -> np.ndarray:
    """Samples ``[start, stop)`` of an opened file as (channels, n), each channel one
    contiguous row (what the detector takes without a copy).

    Integer PCM of up to 24 bits (and A-law, mu-law) is decoded straight into float32,
    which holds every such sample exactly (the values equal the float64 ones, as
    ``read_audio(dtype="auto")`` of the whole file), and needs no finiteness or peak check;
    anything else goes through :func:`rangekit.io.audio.read_frames` (float64, checked).
    """
    from rangekit.io.audio import _INT_AS_FLOAT32, _name, _read_int_float32, read_frames

    if _BLOCK_DTYPE != "auto" or f.subtype not in _INTEGER_SUBTYPES:
        return np.ascontiguousarray(read_frames(f, start, stop).T)
    start, stop = max(0, int(start)), min(int(f.frames), int(stop))
    if stop <= start:
        return np.zeros((f.channels, 0), dtype=np.float32)
    try:
        f.seek(start)
        if f.subtype in _INT_AS_FLOAT32:  # PCM 16/24: integers scaled by numpy (2.4x less CPU)
            x = _read_int_float32(f, f.subtype, stop - start)
        else:
            x = f.read(stop - start, dtype="float32", always_2d=True)
    except RuntimeError as e:  # soundfile.LibsndfileError is a RuntimeError
        raise AudioFormatError(f"'{_name(f)}': cannot read samples {start}-{stop} ({e})") from e
    return np.ascontiguousarray(x.T)  # mono: a view (a (1, n) array is contiguous)


def _detect_block(sources, plan: _BlockPlan, core0: int) -> tuple[list[Arrivals], list[str]]:
    """Every device's arrivals in the block whose core starts at device 0's ``core0``, as
    file sample indices sorted by onset, and the devices' names."""
    lo_s, hi_s = core0 / plan.fs0, (core0 + plan.step) / plan.fs0
    n = sum(len(s.devices) for s in sources)
    arrivals: list[Arrivals] = [None] * n  # type: ignore[list-item]
    names: list[str] = [""] * n
    n_bursts = 1 if plan.method == "template" else plan.signal.n_bursts
    for s in sources:
        r0 = max(0, int(math.floor((lo_s - plan.pre_s) * s.fs)))
        r1 = min(s.frames, int(math.ceil((hi_s + plan.post_s) * s.fs)))
        x = _read_block(s.f, r0, r1)
        for col, dev in enumerate(s.devices):
            names[dev] = _device_name(s, col)
            if x.shape[1] == 0:
                arrivals[dev] = Arrivals.empty(fs=s.fs, n_bursts=n_bursts)
                continue
            # the kernels the whole recording would take, the short last block's too
            with recording_samples(s.frames):
                a = detect(
                    x[col], fs=s.fs, signal=plan.signal, method=plan.method,
                    what=f"'{names[dev]}'",
                )  # fmt: skip
            a = a.take(np.argsort(a.onset, kind="stable"))
            arrivals[dev] = _shift(a, r0)
        del x
    return arrivals, names


#: The sources a series worker process opened (one set per process).
_WORKER_SOURCES: list[_Source] = []


def _worker_open(paths, beep, probe) -> None:
    _WORKER_SOURCES[:] = _open_sources(paths, beep, probe)


def _worker_block(plan: _BlockPlan, core0: int):
    return _detect_block(_WORKER_SOURCES, plan, core0)


def _parallel_blocks(sources, paths, beep, probe, plan: _BlockPlan, cores, jobs: int):
    """:func:`_detect_block` of every core in ``cores``, in order: the first one in this
    process, the others by ``jobs`` worker processes (each opens the files itself); at
    most ``2 jobs`` blocks in flight, so memory stays bounded by the block size.

    The first block is detected here before the workers are forked, so they start with
    the detector's imports, caches and compiled kernels loaded (~1 s CPU that each worker
    would otherwise spend again), and its result is not waited for.
    """
    import collections
    import concurrent.futures as cf
    import multiprocessing as mp

    first = _detect_block(sources, plan, cores[0])
    cores = cores[1:]
    ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
    ex = cf.ProcessPoolExecutor(
        max_workers=jobs,
        mp_context=ctx,
        initializer=_worker_open,
        initargs=([str(p) for p in paths], beep, probe),
    )
    pending: collections.deque = collections.deque()
    it = iter(cores)
    try:
        for core0 in it:
            pending.append(ex.submit(_worker_block, plan, core0))
            if len(pending) >= 2 * jobs:
                break
        yield first
        while pending:
            block = pending.popleft().result()
            nxt = next(it, None)
            if nxt is not None:
                pending.append(ex.submit(_worker_block, plan, nxt))
            yield block
    except BaseException:  # an error, Ctrl-C, or the consumer stopped (GeneratorExit)
        from rangekit._pool import stop_pool

        stop_pool(ex)
        raise
    ex.shutdown(wait=True)


# --- ultrasonic --------------------------------------------------------------------------


def _window_rows(k0: int, k1: int, n_samples: int, per: float) -> np.ndarray:
    """Windows ``k0 .. k1 - 1`` as ``[start, stop)`` rows, exactly as ``window_starts``.

    Stops at the end of the recording (a last window shorter than half a period is not a
    window).
    """
    s = np.round(np.arange(k0, k1 + 1) * per).astype(np.int64)
    starts, stops = s[:-1], np.minimum(s[1:], n_samples)
    ok = (starts < n_samples) & ((stops - starts) >= 0.5 * per)
    m = len(ok) if ok.all() else int(np.argmin(ok))
    return np.stack([starts[:m], stops[:m]], axis=1)


def _reach(scheme: str, burst, fs: float, kw: dict) -> tuple[int, int]:
    """Samples before and after a lag that the scheme's matched filter reads."""
    import inspect

    from rangekit.detect.matched import MatchedFilter, coded_template
    from rangekit.ranging.ultrasonic import range_echo, range_oneway

    func = range_oneway if scheme == "oneway" else range_echo
    p = {k: v.default for k, v in inspect.signature(func).parameters.items()} | kw
    tx, rx = (p["tx"], p["rx"]) if scheme == "oneway" else (p["transducer"],) * 2
    mf = MatchedFilter(coded_template(burst, fs=fs, tx=tx, rx=rx), block=p["block"])
    return mf.pre, mf.n_taps - mf.pre


def range_series_ultrasonic(
    path: str | os.PathLike,
    *,
    scheme: str,
    period_s: float,
    channels: int | None = None,
    burst=None,
    block_s: float | None = None,
    progress: ProgressFn | None = None,
    **kw,
) -> Iterator[WindowRanges]:
    """One-way or pulse-echo ranges of every window of a long recording, block by block.

    Parameters
    ----------
    path : path-like
        The recording (one-way: one channel per receiver, sample 0 = the first trigger;
        echo: one channel per sensor, sample 0 = the first ping).
    scheme : {"oneway", "echo"}
        :func:`~rangekit.ranging.ultrasonic.range_oneway` or
        :func:`~rangekit.ranging.ultrasonic.range_echo`.
    period_s : float
        Window (activation / ranging cycle) length, s.
    channels : int, optional
        Channel count the file must have; None accepts any.
    burst : CodedBurst, optional
        The emitted code (default per scheme, as ``range_ultrasonic_files``).
    block_s : float, optional
        Block length in seconds, rounded down to whole windows (at least one); default
        2^21 samples over all channels (10.9 s of a mono 192 kHz file).
    progress : callable, optional
        Called after each block as ``progress(done_s, total_s)``: seconds of the recording
        finished so far, and its length.
    **kw
        Passed to the scheme's function (``latency_s``, ``tx_ids``, ``min_range_m``, ...).

    Yields
    ------
    WindowRanges
        One per window, in order, as soon as its block is done.

    Raises
    ------
    InvalidParameterError, IncompatibleInputError, InputFileError, AudioFormatError
        As :func:`~rangekit.ranging.ultrasonic.range_ultrasonic_files`; the scheme, period
        and block are checked at the call, the file and the scheme's parameters when
        iteration starts.
    DetectionError
        One-way: no window of any channel holds a burst (raised at the end).
    """
    if scheme not in ULTRASONIC_SCHEMES:
        raise InvalidParameterError(
            f"scheme={scheme!r} must be one of {', '.join(ULTRASONIC_SCHEMES)}"
        )
    period_s = V.positive("period_s", period_s)
    if channels is not None:
        channels = V.positive_int("channels", channels)
    if block_s is not None:
        block_s = V.positive("block_s", block_s)
    for k in ("windows", "first_window", "fs"):
        if k in kw:
            raise InvalidParameterError(f"{k} is set by the series; do not pass it")
    return _ultrasonic_series(
        path,
        scheme=scheme,
        period_s=period_s,
        channels=channels,
        burst=burst,
        block_s=block_s,
        progress=progress,
        kw=kw,
    )


def _ultrasonic_series(
    path, *, scheme, period_s, channels, burst, block_s, progress, kw
) -> Iterator[WindowRanges]:
    from rangekit.io.audio import open_audio, read_frames
    from rangekit.ranging.ultrasonic import (
        _file_burst,
        _no_burst_message,
        range_echo,
        range_oneway,
    )

    func = range_oneway if scheme == "oneway" else range_echo
    with open_audio(path) as f:
        fs, n, n_ch = float(f.samplerate), int(f.frames), int(f.channels)
        b = _file_burst(path, n_ch, fs, scheme=scheme, channels=channels, burst=burst)
        per = period_s * fs
        if per < 2:
            raise InvalidParameterError(f"period_s={period_s!r} is shorter than two samples")
        pre, post = _reach(scheme, b, fs, kw)
        per_block = max(1, int(_block_s(block_s, fs=fs, n_channels=n_ch) * fs // per))
        found = False
        done = 0
        k0 = 0
        while True:
            win = _window_rows(k0, k0 + per_block, n, per)
            if len(win) == 0:
                break
            r0 = max(0, int(win[0, 0]) - pre)
            r1 = min(n, int(win[-1, 1]) + post)
            x = read_frames(f, r0, r1)
            with recording_samples(n):  # the whole recording's kernels, every block
                tofs = func(x.T, fs=fs, burst=b, windows=win - r0, first_window=k0, **kw)
            del x
            found = found or any(math.isfinite(r.distance_m) for r in tofs)
            # Sorted by (window, channel), one row per channel of every window.
            for i, (s0, _) in enumerate(win.tolist()):
                yield WindowRanges(k0 + i, s0 / fs, tuple(tofs[i * n_ch : (i + 1) * n_ch]))
            done = int(win[-1, 1])
            if progress is not None:
                progress(done / fs, n / fs)
            if len(win) < per_block:
                break
            k0 += per_block
        if progress is not None and done < n:
            progress(n / fs, n / fs)
        if scheme == "oneway" and not found:
            raise DetectionError(_no_burst_message(path, scheme))
