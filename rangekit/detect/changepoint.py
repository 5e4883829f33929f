"""STFT change-point detection of beep arrivals (Jiang et al. 2018, §4.3.2).

The seed's method: take the STFT of the recording, keep the beep's frequency band, and
find the first strong deviation from the background noise. rangekit does that per burst,
then times each burst below one STFT hop in the time domain
(:func:`rangekit.detect.refine.fit_edge`) and uses the known burst structure (number of
bursts, their spacing) to combine the bursts into one beep onset and to reject detections
whose spacing does not fit.

Notes
-----
1. Band energy ``E[m]`` of frame ``m`` (samples ``m*hop ... m*hop + n_win``, periodic Hann
   window) at the beep frequency, computed only at that bin (``_kernels.band_energy``).
2. Background level: the 20th percentile of ``E`` divided by -ln(0.8) (the mean of an
   exponential variable, the law of a noise-only bin, whose 20th percentile that is).
3. A burst starts where ``E`` first exceeds both ``threshold_db`` above the background and
   ``rise_db`` above its own level just before (the mean over ``pre`` frames ending one
   window earlier). The second condition finds bursts that start while earlier bursts'
   reverberation is still ringing; reflections, which add at most 6 dB, do not trigger it.
4. Each such change point brackets the onset to about one window; the edge fit times it.
5. Bursts are grouped into beeps: a beep needs its first burst and at least ``min_bursts``
   bursts within half a window plus a hop of their expected place (k * spacing). Each burst
   gives an estimate of the beep onset (its onset minus k * spacing); a clock-rate mismatch
   between player and recorder puts these on a line, so bursts more than a few samples off
   the best-supported drift line (slope within 200 ppm; the earliest on a tie: a burst
   timed on a reflection is late) are rejected, and the rest are averaged with inverse
   variance weights (:func:`_combine`). A beep that starts inside an earlier beep is that
   beep's echo and is dropped.
"""

from __future__ import annotations

import bisect
import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from rangekit import _validate as V
from rangekit.detect import _edge_kernels
from rangekit.detect._edge_kernels import _better_line
from rangekit.detect._edge_kernels import _drift_half_py as _drift_half
from rangekit.detect._kernels import band_energy, long_recording
from rangekit.detect.condition import (
    active_floor,
    bandlimit,
    bandpass_taps,
    clip_mask,
    live_frames,
    local_floor,
    out_of_band_ratio,
    percentile,
)
from rangekit.detect.refine import (
    N_COARSE,
    N_FINE,
    EdgeFit,
    _integer_basis,
    _window,
    edge_statistic,
    fit_edge,
    refine_onset,
)
from rangekit.signals.beep import Beep, check_beep_fits
from rangekit.types import Arrivals, flag_bit

__all__ = [
    "BurstCandidates",
    "beep_taps",
    "click_mask",
    "detect_changepoint",
    "drop_echoes",
    "find_bursts",
]

#: STFT window and hop in seconds (128 and 32 samples at 44.1 kHz).
WIN_S = 128 / 44100
HOP_S = 32 / 44100
#: Smallest edge statistic of a burst that counts as found (see ``refine.fit_edge``).
F_MIN = 15.0
#: How far before a change point the direct path of a burst is searched, s (a direct
#: path up to ~20 dB weaker than the reflections that make the energy cross its
#: threshold; 4 ms = 1.4 m of extra path).
LOOKBACK_S = 0.004
#: Model-error term of an onset's 1-sigma, samples at 44.1 kHz (scaled with fs): set on
#: the pyroomacoustics corpus (``rangekit.experiments.realistic``) so that 2-sigma covers
#: 90-97 % of the two-way errors (docs/accuracy.md).
MODEL_SIGMA = 1.0
#: Rise of the band energy at a burst place that counts as a burst there, dB: a beep's
#: start needs two such places before its bursts are fitted (a change point in noise has
#: one; a far beep in a reverberant room rises only 2-3 dB at some of its places).
MIN_RISE_DB = 1.5
#: Median burst SNR below which an arrival is flagged ``low_snr``, dB.
LOW_SNR_DB = 10.0
#: Length of the stretches with their own noise floor, s (automatic-gain steps, noise
#: that changes, the reverberation of a loud beep).
FLOOR_BLOCK_S = 0.25
#: A local floor this many times the recording's quiet level (the 10th percentile of the
#: stretches' floors) marks an arrival
#: ``reverb_limited`` (6 dB).
REVERB_FLOOR_RATIO = 4.0
#: Stretch before an onset searched for earlier sound of the beep's band, s, and the rise
#: over the level before it that flags the arrival ``ambiguous_first_path``, dB.
PRE_NEAR_S = 0.025
PRE_RISE_DB = 10.0
PRE_RUN = 8
#: The frames just before an onset, tested one by one: wholly within ``PRE_LAST_S`` (plus
#: a window) before the onset, ending ``PRE_GUARD_S`` before it; one of them
#: ``PRE_LAST_DB`` above the level before in every burst flags ``ambiguous_first_path`` (a
#: direct path too weak to time, 3-9 ms before a stronger reflection the onset was taken
#: on). 8 dB: on the pyroomacoustics corpus (80 exchanges, seeds 1 and 3 clean) correct
#: arrivals reach 5.5 dB; a direct path 20 dB under a reflection 150-300 samples later in
#: noise of 0.05 gives 9-13 dB (tests/detect/test_changepoint.py).
PRE_LAST_S = 256 / 44100
PRE_GUARD_S = 8 / 44100
PRE_LAST_DB = 8.0
#: The tone precursor test (:func:`_precursor_flags`): windows ending ``PRE_GUARD_S``
#: before each burst's onset, of these lengths (the guard included), s; the beep's tone
#: in every window, over its mean in the ``PRE_NEAR_S`` before, at least
#: ``PRE_TONE_RATIO`` flags ``ambiguous_first_path``. 4: in white noise the smallest of
#: four bursts' ratios is exponential with mean 1/4 (above 4 with probability e^-16 per
#: window); on 577 correct arrivals of the pyroomacoustics corpus (seeds 1 and 2
#: impaired, 3 clean, 60 exchanges each) the largest was 3.53 (32 samples), 3.05 (64 and
#: 128); a direct path 20 dB under a reflection 80 samples later gives 3.4-9 at noise
#: 0.05 and 36-240 at 0.01-0.02, one 40 samples later 13 (median, 32 samples) at 0.02.
PRE_TONE_S = (32 / 44100, 64 / 44100, 128 / 44100)
PRE_TONE_RATIO = 4.0
#: :func:`precursor_ratio` takes at most this many beeps at a time (memory, not numbers).
PRE_CHUNK = 64
#: A click (:func:`click_mask`): a run of clipped samples at most ``CLICK_MAX_S`` long
#: with no other clipped sample within ``CLICK_GAP_S`` (8 and 32 samples at 44.1 kHz).
CLICK_MAX_S = 8 / 44100
CLICK_GAP_S = 32 / 44100
#: Out-of-band over in-band energy above which an arrival is flagged ``dc_or_lowband``.
OOB_RATIO = 100.0
#: A burst edge one spacing before a beep's first burst (or after its last) whose edge
#: statistic is at least this fraction of the statistic of the burst at the other end
#: (the one a beep shifted by that spacing would leave out) makes the beep's start
#: ambiguous by a whole spacing: the arrival is flagged ``ambiguous_first_path``
#: (:func:`_shift_flags`; the statistic grows as the burst's energy, so 6 dB weaker).
SHIFT_RATIO = 0.25
#: A place one spacing beyond the beep where the band energy does not rise is tested all
#: the same when it holds this fraction of a burst's energy (12 dB under): a burst there
#: masked by a loud tone of the band (measured: a tone of 0.3 over a burst of 0.5 at
#: 16 kHz left 55/256 of the burst's plateau, and a rise of 0.2-0.8 dB).
MASK_RATIO = 1.0 / 16.0


@dataclass(frozen=True)
class BurstCandidates:
    """Individually timed burst onsets before grouping (samples of the recording)."""

    onset: np.ndarray
    sigma: np.ndarray
    snr_db: np.ndarray
    n_win: int
    hop: int


def _stft_params(fs: float, win_s: float, hop_s: float) -> tuple[int, int]:
    n_win = max(16, int(round(win_s * fs)))
    hop = max(1, min(n_win, int(round(hop_s * fs))))
    return n_win, hop


def _change_points(
    e: np.ndarray,
    *,
    n_win: int,
    hop: int,
    threshold_db: float,
    rise_db: float,
    floor: np.ndarray | None = None,
    lookback: int = 0,
) -> np.ndarray:
    """Frames where the band energy rises strongly above background and its recent level,
    and frames inside such a run where it rises ``rise_db`` again over the run's first
    window (a second step).

    ``floor`` is the per-frame noise level (default: :func:`condition.active_floor` of
    ``e``, one level for the whole series); ``lookback`` frames more separate the frame
    from the recent level it must rise over.
    """
    if len(e) == 0:
        return np.zeros(0, dtype=np.int64)
    if floor is None:
        floor = np.full(len(e), active_floor(e))
    # The recent level ends a window plus the lookback before the frame: a weak direct
    # path followed by stronger reflections rises in two steps within a few ms.
    gap = int(math.ceil(n_win / hop)) + lookback
    nb = 8
    if len(e) >= _edge_kernels.NUMBA_MIN_SAMPLES // hop or long_recording():
        return _edge_kernels.call(
            "change_points",
            np.ascontiguousarray(e, dtype=np.float64),
            np.ascontiguousarray(floor, dtype=np.float64),
            gap,
            nb,
            10 ** (threshold_db / 10),
            10 ** (rise_db / 10),
            int(math.ceil(n_win / hop)),
        )
    floor = np.maximum(floor, 1e-30)
    cs = np.concatenate(([0.0], np.cumsum(e)))
    m = np.arange(len(e))
    hi = np.clip(m - gap, 0, None)
    lo = np.clip(m - gap - nb, 0, None)
    cnt = hi - lo
    pre = np.where(cnt > 0, (cs[hi] - cs[lo]) / np.maximum(cnt, 1), floor)
    thr = np.maximum(floor * 10 ** (threshold_db / 10), pre * 10 ** (rise_db / 10))
    above = e > thr
    starts = np.flatnonzero(above & ~np.concatenate(([False], above[:-1])))
    ends = np.flatnonzero(above & ~np.concatenate((above[1:], [False]))) + 1
    # A second step inside a run above threshold: a frame a window or more into the run
    # rising ``rise_db`` over the run's first window (a weak direct path starts the run,
    # a reflection 20 dB stronger a few ms later would raise no change point of its own).
    w = int(math.ceil(n_win / hop))
    r_lin = 10 ** (rise_db / 10)
    steps = []
    for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
        while b - a > w:
            up = np.flatnonzero(e[a + w : b] > r_lin * float(np.max(e[a : a + w])))
            if len(up) == 0:
                break
            a = a + w + int(up[0])
            steps.append(a)
    if steps:
        starts = np.sort(np.concatenate((starts, np.array(steps))))
    return starts.astype(np.int64)


@dataclass(frozen=True)
class _Conditioner:
    """Local conditioning of the stretches the edge fits read (see :mod:`.condition`).

    Each fit reads a few hundred samples; band-limiting only those (plus the filter's
    reach) costs far less than filtering the whole recording. A stretch holding clipped
    samples is fitted on the raw samples instead, clipped ones left out and a constant and
    slope fitted (band-limiting would smear each clipped sample over the filter's length).
    """

    x: np.ndarray
    taps: np.ndarray | None
    clipped: np.ndarray | None
    #: Band-limit with the compiled FIR (``_edge_kernels._fir_py``: the same numbers to
    #: rounding) instead of ``condition.bandlimit``.
    compiled: bool = False

    @property
    def f_scale(self) -> float:
        """How much band-limiting inflates the edge statistic of noise: ``1 / sum(h^2)``.

        The statistic assumes white noise; band-limited noise has ``sum(h^2) = 2 B / fs``
        of the degrees of freedom in a window, so noise alone reaches that much higher
        values (measured on band-limited white noise: the 99.9 and 99.99 % points are 3.0
        and 3.3 times the raw ones, against ``1 / sum(h^2) = 4.0`` for the beep's filter).
        """
        return 1.0 if self.taps is None else 1.0 / float(self.taps @ self.taps)

    def segment(self, a: int, b: int) -> tuple[np.ndarray, int]:
        """``(samples, offset)``: the stretch ``[a, b)`` of the recording, band-limited
        (raw without conditioning); ``offset`` is its first sample's index."""
        a, b = max(0, a), min(len(self.x), b)
        if self.taps is None:
            return np.asarray(self.x[a:b], dtype=np.float64), a
        h = (len(self.taps) - 1) // 2
        if self.compiled:
            y = _edge_kernels.call("fir", self.x, self._taps_reversed, h, a, max(b - a, 0))
            return y, a
        a0, b0 = max(0, a - h), min(len(self.x), b + h)
        y = bandlimit(self.x[a0:b0], self.taps)
        return y[a - a0 : a - a0 + (b - a)], a

    @functools.cached_property
    def _taps_reversed(self) -> np.ndarray:
        return np.ascontiguousarray(self.taps[::-1], dtype=np.float64)

    def is_clipped(self, a: int, b: int) -> bool:
        """Whether clipped samples lie in ``[a, b)``."""
        return self.clipped is not None and bool(np.any(self.clipped[max(0, a) : b]))


def beep_taps(beep: Beep, fs: float) -> np.ndarray:
    """Band-limiting FIR for a beep: flat over ``f +- 2 edge bandwidths`` (within Nyquist)."""
    half = 2.0 * beep.edge_bandwidth_hz
    nyq = 0.5 * fs
    lo = max(beep.f_hz - half, 0.1 * beep.f_hz)
    hi = min(beep.f_hz + half, nyq - 0.02 * nyq)
    tw = min(1500.0, 0.5 * lo, max(nyq - hi, 0.01 * nyq))
    return bandpass_taps(fs, lo, hi, transition_hz=tw)


def _fit_at(
    cond: _Conditioner,
    c: int,
    *,
    fs: float,
    beep: Beep,
    n_win: int,
    hop: int,
    background: bool,
    compiled: bool = False,
) -> EdgeFit | None:
    """Edge fit of a burst whose change point is at sample ``c``.

    The onset is searched in ``[c - n_win/2 - lookback, c + n_win + hop]``: the band
    energy crosses its threshold where the burst is strong, which in a room can be after
    reflections have built up on a weak direct path (``LOOKBACK_S`` earlier at most); the
    edge fit's first-path rule then takes the earliest edge.
    """
    lo, hi = c - n_win // 2 - int(round(LOOKBACK_S * fs)), c + n_win + hop
    margin = int(math.ceil(48 * fs / 44100.0 + beep.taper_s * fs)) + 8
    seg, off = cond.segment(lo - margin, hi + margin)
    fit = fit_edge(
        seg, fs=fs, beep=beep, lo=lo - off, hi=hi - off, background=background, compiled=compiled
    )
    return None if fit is None else replace(fit, onset=fit.onset + off)


def _fit_beep(
    cond: _Conditioner,
    a: int,
    *,
    fs: float,
    beep: Beep,
    n_win: int,
    hop: int,
    background: bool,
    min_bursts: int,
    compiled: bool = False,
) -> tuple[list[EdgeFit | None], list[bool], int | None]:
    """Edge fits of every burst of the beep starting near sample ``a``, which bursts were
    clipped, and the sample to re-anchor on when the joint edge lies at the search
    window's late end (else None).

    The first path is chosen once for the whole beep: each burst's edge statistic over
    ``[-n_win/2 - lookback, n_win + hop]`` around its expected place ``a + k spacing`` is
    widened by +-2 samples (rounding of the spacing, timing) or, where more, by the drift
    of 200 ppm of clock rate from the middle burst to burst k (``_edge_kernels.
    _drift_half_py``: a beep with long spacings on a fast clock) and summed over the
    bursts; the onset is the earliest local maximum of the sum that reaches a tenth of its
    largest (:func:`rangekit.detect.refine.first_peak`). The direct path is at the same
    place in every burst, while a reverberant "edge" (the decaying tail of an earlier
    burst beating with a reflection) is at a random one, so the sum keeps the first and
    washes out the second. Only onsets where ``min_bursts`` bursts reach the per-burst
    threshold count. Each burst is then refined near that place (within its widening) on
    its own; a burst whose
    statistic there stays below the threshold counts as missing.
    """
    spacing = beep.spacing_s * fs
    look = int(round(LOOKBACK_S * fs))
    u0, u1 = -(n_win // 2) - look, n_win + hop
    width = u1 - u0 + 1
    pre, post = _window(fs, beep, None, None)
    segs, stats, widened = [], [], []
    for k in range(beep.n_bursts):
        p = int(round(a + k * spacing))
        seg, off, f = _burst_stat(
            cond, p, u0, width, fs=fs, beep=beep, background=background, compiled=compiled
        )
        segs.append((seg, off, p))
        stats.append(f)
        widened.append(_widen(f, _drift_half(k, beep.n_bursts, spacing)))
    joint = np.sum(widened, axis=0)
    fits: list[EdgeFit | None] = [None] * beep.n_bursts
    clipped = [False] * beep.n_bursts
    if not np.any(joint > 0):
        return fits, clipped, None
    # Band-limited noise reaches higher statistics than white noise (``f_scale``); the
    # thresholds grow as f_scale^(2/3): 38 per burst and 91 for three bursts summed with
    # the beep's filter, against 35 (99.99 % point of one burst's statistic on
    # band-limited white noise), 54 (its largest in 200k offsets) and 74 (the largest of
    # four bursts' widened statistics summed).
    # Only onsets where at least ``min_bursts`` bursts reach the per-burst threshold are
    # candidates (a sum of sub-threshold statistics is not a beep).
    f_min = F_MIN * cond.f_scale ** (2.0 / 3.0)
    f_joint = 0.8 * f_min * min_bursts
    count = np.sum(np.asarray(widened) >= f_min, axis=0)
    joint = np.where(count >= min_bursts, joint, 0.0)
    sep = max(2, int(round(beep.taper_s * fs)))
    u = _first_edge(joint, 0.1, f_joint, sep=sep)
    if joint[u] >= f_joint and u >= width - sep:
        # An edge cut by the window's late end: the change point came before the beep (a
        # noise peak or a click just before it, whose frames run into the beep's so the
        # beep raises no change point of its own). The caller re-anchors on the edge.
        return fits, clipped, int(a) + u0 + u
    if joint[u] < f_joint or not sep <= u < width - sep:
        # Nothing, or an edge cut by the window's early end (a change point on a later
        # part of a beep: the change point at its start holds the whole edge).
        return fits, clipped, None

    for k, ((seg, off, p), f) in enumerate(zip(segs, stats, strict=True)):
        hw = _drift_half(k, beep.n_bursts, spacing)
        j0, j1 = max(0, u - hw), min(width, u + hw + 1)
        j = j0 + int(np.argmax(f[j0:j1]))
        if f[j] < f_min:
            continue
        a_k = p + u0 + j  # integer onset in the recording
        if cond.is_clipped(a_k - 2 * pre, a_k + 2 * post):
            # Clipped: the band-limited edge is compressed (a clipped tone's fundamental
            # saturates), so the onset is refined on the raw samples with the clipped ones
            # left out and a constant and slope fitted (DC, low-frequency drift).
            r0 = max(0, a_k - 4 * pre - post)
            r1 = min(len(cond.x), a_k + 4 * post + pre)
            fit = refine_onset(
                np.asarray(cond.x[r0:r1], dtype=np.float64),
                fs=fs,
                beep=beep,
                a=a_k - r0,
                f_stat=float(f[j]),
                background=background,
                mask=cond.clipped[r0:r1],
                dc=True,
                compiled=compiled,
            )
            clipped[k] = True
            if fit is not None:
                fits[k] = replace(fit, onset=fit.onset + r0)
                continue
            # Too few unclipped samples: fall back to the band-limited edge (biased by a
            # few samples, and flagged).
        fit = refine_onset(
            seg,
            fs=fs,
            beep=beep,
            a=a_k - off,
            f_stat=float(f[j]),
            background=background,
            compiled=compiled,
        )
        if fit is not None:
            fits[k] = replace(fit, onset=fit.onset + off)
    return fits, clipped, None


def _burst_stat(
    cond: _Conditioner,
    p: int,
    u0: int,
    width: int,
    *,
    fs: float,
    beep: Beep,
    background: bool,
    compiled: bool = False,
) -> tuple[np.ndarray, int, np.ndarray]:
    """``(segment, its offset, statistic)``: the edge statistic of one burst at onsets
    ``p + u0 ... p + u0 + width - 1``, on the band-limited segment it was computed on.

    Clipped: a clipped tone's band-limited edge saturates (and its aliased harmonics
    reach the band), so the statistic is also computed on the raw samples with the
    clipped ones left out and a constant and slope fitted. The raw one (put on the
    band-limited scale) is used when it finds an edge at all; interference it cannot
    model can hide it, and then the band-limited one (biased by a few samples, but found)
    serves.
    """
    margin = int(math.ceil(48 * fs / 44100.0 + beep.taper_s * fs)) + 8
    u1 = u0 + width - 1
    seg, off = cond.segment(p + u0 - margin, p + u1 + margin)
    f = _stat_on(
        seg, None, False, off, p, u0, width, fs=fs, beep=beep, bg=background, compiled=compiled
    )
    if cond.is_clipped(p + u0 - margin, p + u1 + margin):
        a0, b0 = max(0, p + u0 - margin), min(len(cond.x), p + u1 + margin)
        f_raw = _stat_on(
            np.asarray(cond.x[a0:b0], dtype=np.float64),
            cond.clipped[a0:b0],
            True,
            a0,
            p,
            u0,
            width,
            fs=fs,
            beep=beep,
            bg=background,
            compiled=compiled,
        )
        if float(f_raw.max()) >= F_MIN:
            f = cond.f_scale ** (2.0 / 3.0) * f_raw
    return seg, off, f


def _widen(f: np.ndarray, half: int) -> np.ndarray:
    """Running maximum of ``f`` over ``+-half`` samples, zeros beyond the ends (what
    ``scipy.ndimage.maximum_filter1d(f, 2 * half + 1, mode="constant")`` gives for
    ``f >= 0``, without importing scipy.ndimage when rangekit starts).

    Examples
    --------
    >>> _widen(np.array([0.0, 0, 3, 0, 0, 0, 1]), 1).tolist()
    [0.0, 3.0, 3.0, 3.0, 0.0, 1.0, 1.0]
    """
    p = np.concatenate([np.zeros(half), f, np.zeros(half)])
    w = np.lib.stride_tricks.sliding_window_view(p, 2 * half + 1)
    return w.max(axis=1)


def _first_edge(stat: np.ndarray, frac: float, floor: float, *, sep: int) -> int:
    """Earliest local maximum of ``stat`` reaching ``max(frac * max, floor)`` that lies at
    least ``sep`` samples (the taper) before the largest one; else the largest.

    A strong edge's statistic has shoulders within a taper of its peak (the model's rise
    half overlapping the true one); they are not an earlier path.
    """
    top = int(np.argmax(stat))
    thr = max(frac * float(stat[top]), floor)
    mid = stat[1:-1]
    pk = np.flatnonzero((mid >= stat[:-2]) & (mid > stat[2:])) + 1
    pk = pk[(stat[pk] >= thr) & (pk <= top - sep)]
    return int(pk[0]) if len(pk) else top


def _stat_on(
    seg: np.ndarray,
    mask: np.ndarray | None,
    raw: bool,
    off: int,
    p: int,
    u0: int,
    width: int,
    *,
    fs: float,
    beep: Beep,
    bg: bool,
    compiled: bool = False,
) -> np.ndarray:
    """Edge statistic of ``seg`` (recording samples from ``off``) at onsets ``p + u0 ...
    p + u0 + width - 1``; 0 where the window does not fit."""
    pre, post = _window(fs, beep, None, None)
    lo = max(p + u0 - off, pre)
    hi = min(p + u0 + width - 1 - off, len(seg) - post - 4)
    f = np.zeros(width)
    if hi >= lo:
        fk = edge_statistic(
            seg,
            fs=fs,
            beep=beep,
            lo=lo,
            hi=hi,
            background=bg,
            mask=mask,
            dc=raw,
            compiled=compiled,
        )
        j0 = lo + off - p - u0
        f[j0 : j0 + len(fk)] = fk
    return f


def find_bursts(
    x: np.ndarray,
    *,
    fs: float,
    beep: Beep,
    win_s: float = WIN_S,
    hop_s: float = HOP_S,
    threshold_db: float = 12.0,
    rise_db: float = 10.0,
    background: bool = False,
    condition: bool = True,
) -> BurstCandidates:
    """Find and time every burst onset in ``x`` (no grouping into beeps)."""
    clipped = clip_mask(x) if condition else None
    n_win, hop, _, _, frames = _candidates(
        x, fs=fs, beep=beep, win_s=win_s, hop_s=hop_s, threshold_db=threshold_db,
        rise_db=rise_db, condition=condition, clipped=clipped,
    )  # fmt: skip
    compiled = len(x) >= _edge_kernels.NUMBA_MIN_SAMPLES or long_recording()
    cond = _conditioner(
        x, fs=fs, beep=beep, condition=condition, compiled=compiled, clipped=clipped
    )
    on, sg, snr = [], [], []
    last = -math.inf
    for m in frames:
        if m * hop - last < beep.burst_s * fs:
            continue
        fit = _fit_at(
            cond,
            int(m) * hop,
            fs=fs,
            beep=beep,
            n_win=n_win,
            hop=hop,
            background=background,
            compiled=compiled,
        )
        if fit is not None and fit.f_stat >= F_MIN * cond.f_scale:
            on.append(fit.onset)
            sg.append(fit.sigma)
            snr.append(fit.snr_db)
            last = m * hop
    return BurstCandidates(np.array(on), np.array(sg), np.array(snr), n_win, hop)


def _candidates(
    x: np.ndarray,
    *,
    fs: float,
    beep: Beep,
    win_s: float,
    hop_s: float,
    threshold_db: float,
    rise_db: float,
    condition: bool = True,
    clipped: np.ndarray | None = None,
) -> tuple[int, int, np.ndarray, np.ndarray, np.ndarray]:
    """``(n_win, hop, band energy, its local floor, change-point frames)`` of ``x``.

    With ``condition``, clicks (:func:`click_mask`) are bridged before the band energy is
    taken: a click's broadband energy would raise a change point of its own whose frames
    run into a beep starting within a window after it, which then raises none.
    ``clipped``: ``clip_mask(x)`` when the caller has it (computed here otherwise).
    """
    n_win, hop = _stft_params(fs, win_s, hop_s)
    if condition:
        clicks = click_mask(clip_mask(x) if clipped is None else clipped, fs=fs)
        if clicks.any():
            # bridged by a straight line between the samples around them: a click goes,
            # a slow waveform that touched the rail there stays as it was (zeroing it
            # would put a step, broadband energy, in its place)
            idx = np.flatnonzero(clicks)
            x = np.array(x, dtype=np.float64)
            x[idx] = bridge(x, idx)
    e = band_energy(x, fs=fs, f_hz=np.array([beep.f_hz]), n_win=n_win, hop=hop)
    floor = _floor(e, fs=fs, hop=hop)
    frames = _change_points(
        e,
        n_win=n_win,
        hop=hop,
        threshold_db=threshold_db,
        rise_db=rise_db,
        floor=floor,
        lookback=int(math.ceil(LOOKBACK_S * fs / hop)),
    )
    return n_win, hop, e, floor, frames


def bridge(x: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """The values a straight line between the samples around them gives the samples
    ``idx`` (sorted) of ``x``: ``np.interp(idx, keep, x[keep])`` with ``keep`` every other
    sample (a run at an end takes its one neighbour; 0 when ``idx`` is all of ``x``),
    computed from the runs' two neighbours only (``keep`` of a long recording is tens of
    millions of indices: 2 s of a 10-minute stereo command for a few clicks).

    Examples
    --------
    >>> x = np.array([0.0, 1.0, 9.0, 9.0, 4.0, 5.0, 9.0])
    >>> bridge(x, np.array([2, 3, 6])).tolist()
    [2.0, 3.0, 5.0]
    >>> idx = np.array([2, 3, 6])
    >>> keep = np.setdiff1d(np.arange(7), idx)
    >>> np.interp(idx, keep, x[keep]).tolist()
    [2.0, 3.0, 5.0]
    """
    idx = np.asarray(idx, dtype=np.int64)
    n = len(x)
    if len(idx) == 0:
        return np.zeros(0)
    if len(idx) >= n:
        return np.zeros(len(idx))
    brk = np.flatnonzero(np.diff(idx) > 1)
    starts = idx[np.concatenate(([0], brk + 1))]
    ends = idx[np.concatenate((brk, [len(idx) - 1]))] + 1  # exclusive
    anchors = np.concatenate((starts - 1, ends))
    anchors = np.unique(anchors[(anchors >= 0) & (anchors < n)])
    return np.interp(idx, anchors, np.asarray(x)[anchors])


def click_mask(clipped: np.ndarray, *, fs: float) -> np.ndarray:
    """Samples of clicks: short runs of clipped samples standing alone, widened by two.

    A run of at most ``CLICK_MAX_S`` with no other clipped sample within ``CLICK_GAP_S``
    on either side is a click (a saturated impulse: handling, a connector, a digital
    glitch). A clipped tone is clipped at every crest, a half period apart, so its
    clipped samples are never alone; a tone clipped only at its single highest crest
    loses one sample of its band energy.

    Examples
    --------
    >>> m = np.zeros(400, dtype=bool)
    >>> m[100:103] = True          # a click
    >>> m[250:350:3] = True        # a clipped tone's crests
    >>> np.flatnonzero(click_mask(m, fs=44100.0)).tolist()
    [98, 99, 100, 101, 102, 103, 104]
    """
    clipped = np.asarray(clipped, dtype=bool)
    out = np.zeros(len(clipped), dtype=bool)
    idx = np.flatnonzero(clipped)
    if len(idx) == 0:
        return out
    max_len = max(1, int(round(CLICK_MAX_S * fs)))
    gap = max(2, int(round(CLICK_GAP_S * fs)))
    # runs of consecutive clipped samples: [starts[i], ends[i]]
    brk = np.flatnonzero(np.diff(idx) > 1)
    starts = idx[np.concatenate(([0], brk + 1))]
    ends = idx[np.concatenate((brk, [len(idx) - 1]))]
    before = np.concatenate(([-np.inf], ends[:-1])).astype(np.float64)
    after = np.concatenate((starts[1:], [np.inf])).astype(np.float64)
    alone = (ends - starts < max_len) & (starts - before > gap) & (after - ends > gap)
    for a, b in zip(starts[alone].tolist(), ends[alone].tolist(), strict=True):
        out[max(0, a - 2) : b + 3] = True
    return out


def _floor_block(fs: float, hop: int) -> int:
    """Frames per stretch of ``FLOOR_BLOCK_S`` (at least 16)."""
    return max(16, int(round(FLOOR_BLOCK_S * fs / hop)))


def _floor(e: np.ndarray, *, fs: float, hop: int) -> np.ndarray:
    """Per-frame noise level of the band energy: :func:`condition.local_floor` over
    stretches of ``FLOOR_BLOCK_S``."""
    return local_floor(e, block=_floor_block(fs, hop))


def _quiet_level(e: np.ndarray, floor: np.ndarray, *, fs: float, hop: int) -> float:
    """The recording's quiet level: the 10th percentile of the per-frame floors of its
    live stretches (:func:`condition.live_frames`), those under 1e-12 of the largest left
    out, with stretches of digital silence left out of the floors' interpolation
    (``local_floor(silent="skip")``). ``floor`` (``silent="whole"``, what the thresholds
    use) gives silence the whole series' level, which raised the percentile twice, in the
    silence and in its neighbours' interpolated floors: 0.2-1 s of zeros before a
    recording dropped its arrivals' ``reverb_limited``. Without silence: ``floor``."""
    block = _floor_block(fs, hop)
    live = live_frames(e, block=block)
    if live.any() and not live.all():
        floor = local_floor(e, block=block, silent="skip")
    sel = floor[live] if live.any() else floor
    if len(sel) and sel.max() > 0:
        sel = sel[sel > 1e-12 * float(sel.max())]
    return float(percentile(sel, 10.0)) if len(sel) else 0.0


def _conditioner(
    x: np.ndarray,
    *,
    fs: float,
    beep: Beep,
    condition: bool,
    compiled: bool = False,
    clipped: np.ndarray | None = None,
) -> _Conditioner:
    """The conditioning of ``x`` (``clipped``: ``clip_mask(x)`` when the caller has it)."""
    if not condition:
        return _Conditioner(x, None, None)
    clipped = clip_mask(x) if clipped is None else clipped
    taps = beep_taps(beep, fs)
    return _Conditioner(x, taps, clipped if clipped.any() else None, compiled)


def _anchor(
    c: int,
    e: np.ndarray,
    *,
    hop: int,
    n_win: int,
    spacing: float,
    beep: Beep,
    fs: float,
    cs: np.ndarray | None = None,
) -> tuple[int, int]:
    """Start of the beep that a burst onset near sample ``c`` belongs to.

    A change point may be any burst of a beep (the first can be masked by noise or by the
    reverberation of another beep). For each hypothesis "``c`` is burst j" every burst
    place ``c + (k - j) spacing`` is scored by the rise of the band energy there: the
    mean over the frames inside the burst over the mean over the frames just before it,
    in dB, clipped to [0, 30]. The best total (the earliest hypothesis on a tie) gives the
    beep start ``c - j spacing``. A rise, not a level: a loud beep's reverberation has
    energy at the burst places of a faint beep that follows, but it does not rise there.
    Returns the beep start and how many of its burst places rise ``MIN_RISE_DB`` or more
    (a change point in noise has one such place, usually).
    """
    k_b = beep.n_bursts
    if k_b == 1:
        return c, 1
    if cs is None:  # cumulative sum of e with a leading 0 (pass it when calling often)
        cs = np.concatenate(([0.0], np.cumsum(e)))
    n_e = len(e)
    w = max(1, n_win // hop)
    n_plat = max(1, int((beep.burst_s * fs - 2 * n_win) / hop))
    scores = np.zeros(k_b)
    rising = np.zeros(k_b, dtype=np.int64)
    for j in range(k_b):
        tot = 0.0
        for k in range(k_b):
            rise = _rise_db(c + (k - j) * spacing, cs, n_e, hop=hop, w=w, n_plat=n_plat)
            if rise is not None:
                tot += rise
                rising[j] += rise >= MIN_RISE_DB
        scores[j] = tot
    best_j = int(np.flatnonzero(scores >= scores.max() - 1e-9)[0])
    return int(round(c - best_j * spacing)), int(rising[best_j])


def _rise_db(
    place: float, cs: np.ndarray, n_e: int, *, hop: int, w: int, n_plat: int
) -> float | None:
    """Rise of the band energy at a burst starting at sample ``place``, dB in [0, 30]: the
    mean over the ``n_plat`` frames from a window after it over the mean over the 8 frames
    ending a window before it (:func:`_levels`). None where those frames leave the series
    or the plateau holds no energy.
    """
    return _rise_of(_levels(place, cs, n_e, hop=hop, w=w, n_plat=n_plat))


def _rise_of(lv: tuple[float, float] | None) -> float | None:
    """:func:`_rise_db` of the levels ``(plateau, before)`` (:func:`_levels`)."""
    if lv is None or not lv[0] > 0:
        return None
    return min(30.0, max(0.0, 10.0 * math.log10(lv[0] / max(lv[1], 1e-300))))


def _levels(
    place: float, cs: np.ndarray, n_e: int, *, hop: int, w: int, n_plat: int
) -> tuple[float, float] | None:
    """``(plateau, before)``: the mean band energy over the ``n_plat`` frames from a
    window after sample ``place`` and over the 8 frames ending a window before it (``cs``:
    cumulative sum of the ``n_e`` frames' energy, with a leading 0); None where those
    frames leave the series."""
    f = int(round(place / hop))
    p0, p1 = f + w, f + w + n_plat
    q0, q1 = f - w - 8, f - w
    if q0 < 0 or p1 > n_e:
        return None
    return float((cs[p1] - cs[p0]) / (p1 - p0)), float((cs[q1] - cs[q0]) / (q1 - q0))


def _anchor_args(
    c: np.ndarray, cs: np.ndarray, n_e: int, *, hop: int, n_win: int, beep: Beep, fs: float
) -> tuple:
    """Arguments of the ``anchors`` kernel (``_edge_kernels._anchors_py``)."""
    return (
        np.ascontiguousarray(c, dtype=np.int64),
        np.ascontiguousarray(cs, dtype=np.float64),
        int(n_e),
        int(hop),
        max(1, n_win // hop),
        max(1, int((beep.burst_s * fs - 2 * n_win) / hop)),
        float(beep.spacing_s * fs),
        int(beep.n_bursts),
        float(MIN_RISE_DB),
    )


def _anchors_compiled(
    c: np.ndarray, cs: np.ndarray, n_e: int, *, hop: int, n_win: int, beep: Beep, fs: float
) -> list[tuple[int, int]]:
    """:func:`_anchor` of every change-point sample in ``c`` by one compiled loop
    (``_edge_kernels._anchors_py``: the same arithmetic, so the same numbers)."""
    if beep.n_bursts == 1:
        return [(int(v), 1) for v in c.tolist()]
    out = _edge_kernels.call(
        "anchors", *_anchor_args(c, cs, n_e, hop=hop, n_win=n_win, beep=beep, fs=fs)
    )
    return [(int(a), int(r)) for a, r in out.tolist()]


#: Largest clock-rate mismatch between the player's and the recorder's sample clocks that
#: :func:`_combine` takes for drift (not inconsistency) of a beep's bursts: 200 ppm (one
#: constant with the compiled loop's).
MAX_DRIFT = _edge_kernels.MAX_DRIFT


def _allowed_scatter(scale, sigma, k, spacing):
    """How far burst ``k``'s estimate of a beep onset may lie from burst 0's, samples:
    timing noise (2 samples at 44.1 kHz, ``scale`` = fs / 44100, and 4 sigma) plus
    :data:`MAX_DRIFT` of clock-rate mismatch per spacing (``k`` = 0: the timing noise
    alone, the tolerance about :func:`_drift_line`)."""
    return 2.0 * scale + 4.0 * sigma + MAX_DRIFT * k * spacing


def _drift_line(ks, est, w, members, spacing):
    """``(mean, slope, kbar)`` of the weighted straight lines through the onset estimates
    ``est`` of bursts ``ks`` (weights ``w``) selected by each row of ``members``: the
    estimates of a beep played on one clock and recorded on another drift by ``r
    spacing`` samples a burst (r the rate mismatch), so burst k estimates ``mean + slope
    (k - kbar)``. The least-squares slope is held within +-:data:`MAX_DRIFT` ``spacing``
    (a steeper drift is not a clock's); a row selecting no burst gives an infinite mean.
    ``_edge_kernels._combine_py`` computes the same in its loop."""
    wm = members * w[None, :]
    sw = wm.sum(axis=1)
    safe = np.where(sw > 0, sw, 1.0)
    kbar = (wm @ ks) / safe
    mean = np.where(sw > 0, (wm @ est) / safe, np.inf)
    dk = ks[None, :] - kbar[:, None]
    sxx = np.sum(wm * dk**2, axis=1)
    sxy = np.sum(wm * dk * (est[None, :] - np.where(sw > 0, mean, 0.0)[:, None]), axis=1)
    slope = np.divide(sxy, sxx, out=np.zeros(len(sxx)), where=sxx > 0)
    lim = MAX_DRIFT * spacing
    return mean, np.clip(slope, -lim, lim), kbar


def _combine(
    fits: list[EdgeFit | None],
    clipped: list[bool],
    *,
    spacing: float,
    scale: float,
    min_bursts: int,
) -> tuple[float, float, float, float, np.ndarray, int] | None:
    """One beep onset from its bursts' fits, or None when too few of them agree.

    Each found burst k gives an estimate of the beep onset, its onset minus k * spacing;
    under a clock-rate mismatch r between player and recorder they lie on a line of slope
    ``r spacing`` a burst. Each pair of bursts (slope held within :data:`MAX_DRIFT`) and
    each burst alone (slope 0) proposes such a line; the bursts within their timing noise
    (2 samples at 44.1 kHz and 4 sigma) of it give its least-squares drift line
    (:func:`_drift_line`), whose bursts within their timing noise are its members. The
    line with most members wins (:func:`_better_line`: on a tie the best fit, then the
    earliest mean, since a burst timed on a reflection is late); the other bursts are
    rejected, the members averaged with inverse-variance weights, the 1-sigma scaled up
    by their reduced chi-square about that mean. So a far beep recorded 150 ppm fast keeps
    all its bursts at any spacing, and a burst off the line is rejected whichever it is.
    The onset stays the members' mean estimate: under a rate mismatch r it lies ``r kbar
    spacing`` after burst 0's (``kbar`` the members' weighted mean index), which two-way
    ranging cancels when both far beeps keep the same bursts (they carry +-r) and the
    chi-square puts into sigma (``docs/theory/beepbeep.md`` step 8).

    Returns ``(onset, sigma, snr_db, confidence, burst_onsets, flags, strength)``;
    ``strength`` is the summed edge statistic of the kept bursts.
    """
    k_b = len(fits)
    ks = np.array([k for k, f in enumerate(fits) if f is not None])
    if len(ks) < min_bursts:
        return None
    on = np.array([fits[k].onset for k in ks])
    est = on - ks * spacing
    # A failed fit reports an infinite sigma; it then weighs (almost) nothing.
    raw_sg = np.array([fits[k].sigma for k in ks])
    sg = np.clip(np.nan_to_num(raw_sg, nan=1e6, posinf=1e6), 1e-3, 1e6)
    base = _allowed_scatter(scale, sg, 0, spacing)
    w_all = 1.0 / sg**2
    # Candidate drift lines: through each pair of bursts (slope held within MAX_DRIFT) and
    # each burst alone (slope 0). The bursts within their timing noise of a candidate give
    # its least-squares drift line (:func:`_drift_line`), and the bursts within their
    # timing noise of that line are the candidate's. The one with most bursts wins; on a
    # tie the one they fit best (``sum (residual / noise)^2``), then the earliest mean of
    # them (a burst timed on a reflection is late).
    i, j = np.triu_indices(len(ks), 1)
    lim = MAX_DRIFT * spacing
    slope = np.clip((est[j] - est[i]) / (ks[j] - ks[i]), -lim, lim)
    wp = w_all[i] + w_all[j]
    k_at = np.concatenate([(w_all[i] * ks[i] + w_all[j] * ks[j]) / wp, ks])
    e_at = np.concatenate([(w_all[i] * est[i] + w_all[j] * est[j]) / wp, est])
    slope = np.concatenate([slope, np.zeros(len(ks))])
    res = est[None, :] - (e_at[:, None] + slope[:, None] * (ks[None, :] - k_at[:, None]))
    mean, slope, kbar = _drift_line(ks, est, w_all, np.abs(res) <= base[None, :], spacing)
    res = est[None, :] - (mean[:, None] + slope[:, None] * (ks[None, :] - kbar[:, None]))
    inl = np.abs(res) <= base[None, :]
    support = inl.sum(axis=1)
    cost = np.sum(np.where(inl, (res / base[None, :]) ** 2, 0.0), axis=1)
    den = inl @ w_all
    means = np.divide(inl @ (w_all * est), den, out=np.full(len(den), np.inf), where=den > 0)
    pick = 0
    for c in range(1, len(support)):
        if _better_line(support[c], cost[c], means[c], support[pick], cost[pick], means[pick]):
            pick = c
    ok = inl[pick]
    if ok.sum() < min_bursts:
        return None
    wts = 1.0 / sg[ok] ** 2
    t0 = float(np.sum(wts * est[ok]) / np.sum(wts))
    s0 = 1.0 / math.sqrt(float(np.sum(wts)))
    if ok.sum() > 1:
        chi2 = float(np.sum(wts * (est[ok] - t0) ** 2)) / (ok.sum() - 1)
        s0 *= math.sqrt(max(1.0, chi2))
    # Model error: multipath inside the edge window that the fit cannot resolve, the same
    # in every burst (so the bursts' scatter does not show it).
    s0 = math.hypot(s0, MODEL_SIGMA * scale)
    row = np.full(k_b, np.nan)
    row[ks[ok]] = on[ok]
    snr = _median([fits[k].snr_db for k in ks[ok]])
    flags = 0
    if ok.sum() < k_b:
        flags |= flag_bit("inconsistent_bursts")
    if any(clipped[k] for k in ks[ok]):
        flags |= flag_bit("clipped")
    if snr < LOW_SNR_DB:
        flags |= flag_bit("low_snr")
    strength = float(sum(fits[k].f_stat for k in ks[ok]))
    return t0, s0, snr, ok.sum() / k_b, row, flags, strength


def _median(vals: list[float]) -> float:
    """``numpy.median`` of a few floats (the same arithmetic; ``numpy.median`` imports
    ``numpy.ma`` on first use)."""
    v = sorted(vals)
    m = len(v) // 2
    return float(v[m]) if len(v) % 2 else float((v[m - 1] + v[m]) / 2.0)


#: Largest set of groups linked by shared bursts whose best selection is searched whole
#: (:func:`_resolve_aliases`; 2^n subsets); a larger one is resolved pair by pair.
ALIAS_SET_MAX = 12


def _resolve_aliases(rows: list[tuple], *, tol: float) -> list[tuple]:
    """Keep one of two groups that share bursts: one beep indexed two ways.

    A change point in noise one spacing before a beep makes a group whose bursts 1..3 are
    the beep's bursts 0..2 and whose burst 0 is noise that happened to pass; it has as
    many agreeing bursts as the real group and starts earlier, so the echo rule would
    keep it. Groups sharing two or more burst onsets (within ``tol`` samples) are the same
    beep: the one with the larger summed edge statistic stays.

    Groups linked that way in a chain (two beeps on one spacing grid, the second starting
    one spacing after the first one's last burst: groups at every spacing between them,
    each mixing bursts of both) are resolved together: of the selections whose groups
    share no burst, the one with the largest summed edge statistic stays. That keeps the
    two beeps, which explain every burst once; dropping the weaker of each pair in turn
    kept one of the mixed groups and lost a beep. (Counting a burst two kept groups share
    once, from their mean statistics per burst, instead of forbidding it lost the faint
    beep after a loud one in 2 of 6 seeds: the loud bursts' statistics vary more between
    groups than a faint burst's whole statistic.) For two groups it is the rule above.
    """
    n = len(rows)
    ons = [r[4][np.isfinite(r[4])] for r in rows]
    span = [(float(a.min()), float(a.max())) if len(a) else (math.inf, -math.inf) for a in ons]
    # shared[(i, j)], i < j: bursts of group i within tol of one of group j's (pairs that
    # share none are absent). Groups whose burst onsets lie more than tol apart share
    # none, so only pairs overlapping in time are tested: a sweep over the groups in order
    # of their first burst (was every pair and n x n matrices: quadratic in time and
    # memory on an hour of beeps).
    by_start = sorted(range(n), key=lambda i: span[i][0])
    shared: dict[tuple[int, int], int] = {}
    for u, i in enumerate(by_start):
        for v in range(u + 1, n):
            j = by_start[v]
            if span[j][0] > span[i][1] + tol:
                break  # the later groups start later still
            if span[i][0] > span[j][1] + tol:
                continue
            lo, hi = min(i, j), max(i, j)
            a, b = ons[lo], ons[hi]
            k = int(np.sum(np.min(np.abs(a[:, None] - b[None, :]), axis=1) <= tol))
            if k:
                shared[lo, hi] = k
    onset = [float(r[0]) for r in rows]
    alias = {ij for ij, k in shared.items() if k >= 2 and abs(onset[ij[0]] - onset[ij[1]]) > tol}
    linked: list[list[int]] = [[] for _ in range(n)]
    for i, j in alias:
        linked[i].append(j)
        linked[j].append(i)
    strength = [float(r[6]) for r in rows]
    keep = [True] * n
    seen = [False] * n
    for start in range(n):
        if seen[start] or not linked[start]:
            continue
        comp, todo = [], [start]
        seen[start] = True
        while todo:
            i = todo.pop()
            comp.append(i)
            for j in sorted(linked[i]):
                if not seen[j]:
                    seen[j] = True
                    todo.append(j)
        comp.sort()
        if len(comp) <= ALIAS_SET_MAX:
            best, best_s = 0, -math.inf
            for m in range(1, 1 << len(comp)):
                sel = [comp[t] for t in range(len(comp)) if m >> t & 1]
                if any((i, j) in shared for i in sel for j in sel if i < j):
                    continue
                tot = sum(strength[i] for i in sel)
                if tot > best_s:
                    best, best_s = m, tot
            for t, i in enumerate(comp):
                keep[i] = bool(best >> t & 1)
            continue
        for i in comp:  # pair by pair, in order
            for j in comp:
                if i < j and keep[i] and keep[j] and (i, j) in alias:
                    keep[i if strength[i] < strength[j] else j] = False
    return [r for r, k in zip(rows, keep, strict=True) if k]


def drop_echoes(arr: Arrivals, *, duration: float) -> Arrivals:
    """Drop arrivals that start inside an earlier arrival (echoes of it).

    The earlier one stays, unless the later one has more agreeing bursts: a group of a
    few bursts lying on reflections of a real beep's bursts, one or more spacings before
    it, is not that beep's direct sound (a reflection of every burst of a beep lies
    within the same stretches as the direct sound, so an echo never has more).
    """
    order = np.argsort(arr.onset, kind="stable")
    keep: list[int] = []
    end = -math.inf
    for i in order.tolist():
        if arr.onset[i] >= end:
            keep.append(i)
            end = arr.onset[i] + duration
        elif arr.confidence[i] > arr.confidence[keep[-1]] + 1e-9:
            keep[-1] = i
            end = arr.onset[i] + duration
    return arr.take(np.array(keep, dtype=np.int64))


def detect_changepoint(
    x: np.ndarray,
    *,
    fs: float,
    beep: Beep | None = None,
    win_s: float = WIN_S,
    hop_s: float = HOP_S,
    threshold_db: float = 6.0,
    rise_db: float = 10.0,
    min_bursts: int | None = None,
    background: bool = True,
    condition: bool = True,
    expected: int | None = None,
) -> Arrivals:
    """Detect beep arrivals by STFT change points refined by an edge fit.

    Parameters
    ----------
    x : array_like, shape (n,)
        One channel of a recording.
    fs : float
        Sample rate in Hz.
    beep : Beep, optional
        The beep that was played (default: the rangekit beep).
    win_s, hop_s : float
        STFT window and hop in seconds.
    threshold_db : float
        Minimum band energy above the local background for a burst start, in dB.
    rise_db : float
        Minimum rise over the band energy just before, in dB.
    min_bursts : int, optional
        Bursts whose timing must agree for a beep (default: all but one, at least 2;
        1 for a one-burst beep). A beep with fewer agreeing than all is flagged
        ``inconsistent_bursts``.
    background : bool
        Fit a background tone during the edge fit (reverberant rooms).
    condition : bool
        Condition the recording (default): band-limit the stretches the edge fits read to
        the beep's band (DC, hum, speech and music removed), leave clipped samples out.
        ``False`` fits the raw samples, as rangekit did before (for comparisons).
    expected : int, optional
        How many beeps were played (e.g. one per device of an exchange). When more are
        found, doubtful ones (flagged ``inconsistent_bursts`` or ``low_snr``: spurious
        groups in dense reverberation) are dropped, weakest first, while more than
        ``expected`` remain; arrivals without those flags are never dropped, so a
        recording holding more beeps than expected still shows them all.

    Returns
    -------
    Arrivals
        One entry per beep, in time order; empty for a silent recording. ``flags`` per
        arrival: ``inconsistent_bursts``, ``clipped``, ``low_snr``,
        ``ambiguous_first_path`` (sound of the band before the onset, or a burst one
        spacing beyond the beep's first or last: :func:`_shift_flags`),
        ``reverb_limited``, ``dc_or_lowband`` (see :data:`rangekit.types.ARRIVAL_FLAGS`).

    Examples
    --------
    >>> import numpy as np
    >>> from rangekit.signals import Beep, beep_waveform
    >>> b = Beep()
    >>> x = np.zeros(30000)
    >>> x[1000:1000 + b.duration_samples] = beep_waveform(b)
    >>> x += 1e-3 * np.random.default_rng(0).standard_normal(len(x))
    >>> arr = detect_changepoint(x, fs=b.fs, beep=b)
    >>> bool(abs(arr.onset[0] - 1000) < 0.1)
    True
    """
    beep = Beep() if beep is None else beep
    fs = V.sample_rate(fs)
    x = _signal(x)
    check_beep_fits(beep, fs=fs)
    win_s = V.in_range("win_s", win_s, 1e-5, 1.0)
    hop_s = V.in_range("hop_s", hop_s, 1e-7, 1.0)
    threshold_db = V.in_range("threshold_db", threshold_db, -100.0, 200.0)
    rise_db = V.in_range("rise_db", rise_db, -100.0, 200.0)
    if expected is not None:
        expected = V.positive_int("expected", expected)
    k_b = beep.n_bursts
    if min_bursts is None:
        min_bursts = 1 if k_b == 1 else max(2, k_b - 1)
    min_bursts = V.positive_int("min_bursts", min_bursts)
    if min_bursts > k_b:
        raise V.InvalidParameterError(f"min_bursts={min_bursts} exceeds n_bursts={k_b}")
    # One clip mask for the clicks bridged before the band energy and the conditioning.
    clipped = clip_mask(x) if condition else None
    n_win, hop, e, floor, frames = _candidates(
        x, fs=fs, beep=beep, win_s=win_s, hop_s=hop_s, threshold_db=threshold_db,
        rise_db=rise_db, condition=condition, clipped=clipped,
    )  # fmt: skip
    spacing = beep.spacing_s * fs
    # Long recordings: numba is imported by band_energy already; the edge fits' kernels
    # (rangekit.detect._edge_kernels) give the numpy path's numbers to rounding.
    compiled = len(x) >= _edge_kernels.NUMBA_MIN_SAMPLES or long_recording()
    cs = np.concatenate(([0.0], np.cumsum(e)))
    if compiled:
        starts = (
            _edge_kernels.call(
                "anchors",
                *_anchor_args(frames * hop, cs, len(e), hop=hop, n_win=n_win, beep=beep, fs=fs),
            )
            if k_b > 1
            else np.stack([frames * hop, np.ones(len(frames), np.int64)], axis=1)
        )
        anchors = _edge_kernels.call(
            "dedupe",
            np.ascontiguousarray(starts[:, 0]),
            np.ascontiguousarray(starts[:, 1]),
            min(2, min_bursts),
            int(hop),
        ).tolist()
    else:
        starts = [
            _anchor(m * hop, e, hop=hop, n_win=n_win, spacing=spacing, beep=beep, fs=fs, cs=cs)
            for m in frames.tolist()
        ]
        anchors = []
        for a, n_rise in starts:
            if n_rise >= min(2, min_bursts) and all(abs(a - b) > hop for b in anchors[-8:]):
                anchors.append(a)
    cond = _conditioner(
        x, fs=fs, beep=beep, condition=condition, compiled=compiled, clipped=clipped
    )
    quiet = _quiet_level(e, floor, fs=fs, hop=hop)
    oob = _out_of_band(x, cond) if condition else False
    kw = {
        "fs": fs, "beep": beep, "n_win": n_win, "hop": hop, "background": background,
        "min_bursts": min_bursts, "quiet": quiet, "oob": oob,
    }  # fmt: skip
    if compiled:
        rows = _rows_compiled(cond, np.asarray(anchors, dtype=np.int64), e, **kw)
    else:
        found = _Found()
        rows = [r for a in anchors if (r := _beep_row(cond, a, e, found, **kw)) is not None]
    rows = _resolve_aliases(rows, tol=2.0 * fs / 44100.0 + 2.0)
    if not rows:
        return Arrivals.empty(fs=fs, n_bursts=k_b, detector="changepoint")
    arr = Arrivals(
        np.array([r[0] for r in rows]),
        float(fs),
        np.array([r[1] for r in rows]),
        np.array([r[2] for r in rows]),
        np.array([r[3] for r in rows]),
        np.array([r[4] for r in rows]),
        "changepoint",
        flags=np.array([r[5] for r in rows], dtype=np.int64),
    )
    arr = drop_echoes(arr, duration=beep.duration_s * fs)
    arr = _shift_flags(arr, cond, e, cs, fs=fs, beep=beep, n_win=n_win, hop=hop, bg=background)
    arr = _precursor_flags(arr, cond, fs=fs, beep=beep)
    if expected is not None and len(arr) > expected:
        weak = flag_bit("inconsistent_bursts") | flag_bit("low_snr")
        doubtful = np.flatnonzero(arr.flags & weak)
        # weakest first: fewest agreeing bursts, then lowest SNR
        order = doubtful[np.lexsort((arr.snr_db[doubtful], arr.confidence[doubtful]))]
        drop = order[: len(arr) - expected]
        arr = arr.take(np.setdiff1d(np.arange(len(arr)), drop))
    return arr


def _shift_flags(
    arr: Arrivals,
    cond: _Conditioner,
    e: np.ndarray,
    cs: np.ndarray,
    *,
    fs: float,
    beep: Beep,
    n_win: int,
    hop: int,
    bg: bool,
) -> Arrivals:
    """``arr`` with ``ambiguous_first_path`` added to each arrival whose start is
    ambiguous by a whole burst spacing.

    Bursts at ``t0, t0 + s, ..., t0 + (K-1) s`` plus a burst-like sound at ``t0 + K s``
    (a strong late reflection, another device's burst landing on the spacing grid) fit a
    beep at ``t0 + s`` nearly as well as one at ``t0``: the two share K-1 bursts, and
    which one the strengths favour is chance. Likewise a sound at ``t0 - s``. For each
    end, the place one spacing beyond the outermost burst found (from that burst's onset,
    at the nominal spacing) is tested: the band energy rising there (``_rise_db``,
    ``MIN_RISE_DB``), or holding ``MASK_RATIO`` of a burst's energy at or just before it
    (a burst masked by a loud tone of the band does not rise), and then the edge
    statistic (``_burst_stat``, clipped samples left out) over a taper plus the
    bursts' allowed scatter either side; the place is a burst when that statistic peaks
    within the scatter, reaches the per-burst threshold and ``SHIFT_RATIO`` of the
    statistic of the burst a shifted beep would drop (the one at the other end; 0 when
    that one is missing). A place where a burst of another arrival lies is not tested:
    that arrival explains the sound there, and the shifted beep would have to share its
    burst and leave a burst of this one unexplained (a far beep whose last burst lies one
    spacing before the own beep: the own beep's first burst is at the far beep's next
    place). Run on the finished arrivals (after :func:`drop_echoes`), the same for the
    numpy and the compiled path; the band-energy test keeps the edge statistic off
    almost every place.
    """
    k_b = beep.n_bursts
    if k_b < 2 or len(arr) == 0:
        return arr
    spacing = beep.spacing_s * fs
    scale = fs / 44100.0
    w = max(1, n_win // hop)
    n_plat = max(1, int((beep.burst_s * fs - 2 * n_win) / hop))
    sep = max(2, int(round(beep.taper_s * fs)))
    f_min = F_MIN * cond.f_scale ** (2.0 / 3.0)
    kw = {"fs": fs, "beep": beep, "background": bg, "compiled": cond.compiled}
    bit = flag_bit("ambiguous_first_path")
    flags = arr.flags.copy()
    # every arrival's bursts in one sorted array with their arrival's index: the bursts
    # of the others near a place are a slice (was one concatenation per arrival: O(n^2))
    bursts = [r[np.isfinite(r)] for r in arr.burst_onsets]
    all_b = np.concatenate(bursts)
    owner = np.repeat(np.arange(len(arr)), [len(b) for b in bursts])
    by_t = np.argsort(all_b, kind="stable")
    all_b, owner = all_b[by_t], owner[by_t]
    for i in range(len(arr)):
        if flags[i] & bit:
            continue
        row = arr.burst_onsets[i]
        ks = np.flatnonzero(np.isfinite(row))
        if len(ks) == 0:
            continue
        # The scatter _combine allows a burst one spacing on (sigma at most 2 samples)
        tol = int(
            math.ceil(_allowed_scatter(scale, min(float(arr.sigma[i]), 2.0 * scale), 1, spacing))
        )
        for k_n, k_x, k_r in ((int(ks[0]), -1, k_b - 1), (int(ks[-1]), k_b, 0)):
            place = float(row[k_n]) + (k_x - k_n) * spacing
            lv = _levels(place, cs, len(e), hop=hop, w=w, n_plat=n_plat)
            rise = _rise_of(lv)
            if rise is None or rise < MIN_RISE_DB:
                # No rise; but a burst masked by other sound of the band (a loud tone
                # there already, which may cancel much of it) does not rise either:
                # tested when the band holds, at the place or just before it,
                # ``MASK_RATIO`` of the energy of the burst a shifted beep would drop.
                k_ref = k_r if np.isfinite(row[k_r]) else k_n
                ref = _levels(float(row[k_ref]), cs, len(e), hop=hop, w=w, n_plat=n_plat)
                if lv is None or ref is None or not max(lv) >= MASK_RATIO * ref[0]:
                    continue
            p = int(round(place))
            if p - tol - sep < 0 or p + tol + sep >= len(cond.x):
                continue
            if _other_burst_near(all_b, owner, i, place, tol):
                continue  # a burst of another arrival: explained (see above)
            f_x = _burst_stat(cond, p, -tol - sep, 2 * (tol + sep) + 1, **kw)[2]
            j = int(np.argmax(f_x))
            if abs(j - tol - sep) > tol or f_x[j] < f_min:
                continue
            f_r = 0.0
            if np.isfinite(row[k_r]):
                f_r = float(_burst_stat(cond, int(round(row[k_r])), -2, 5, **kw)[2].max())
            if f_x[j] >= SHIFT_RATIO * f_r:
                flags[i] |= bit
                break
    return replace(arr, flags=flags)


def _other_burst_near(all_b: np.ndarray, owner: np.ndarray, i: int, place: float, tol: int) -> bool:
    """Whether a burst onset in ``all_b`` (sorted) of an arrival other than ``i``
    (``owner``) lies within ``tol`` samples of ``place``: ``|b - place| <= tol``, tested
    on the slice one sample wider either side (so rounding at the ends changes nothing)."""
    lo = int(np.searchsorted(all_b, place - tol - 1.0, side="left"))
    hi = int(np.searchsorted(all_b, place + tol + 1.0, side="right"))
    near = all_b[lo:hi][owner[lo:hi] != i]
    return bool(len(near)) and float(np.min(np.abs(near - place))) <= tol


def precursor_ratio(
    x: np.ndarray,
    onsets: np.ndarray,
    *,
    fs: float,
    f_hz: float,
    lengths: tuple[int, ...],
    guard: int,
    clipped: np.ndarray | None = None,
) -> np.ndarray:
    """The beep's tone just before each beep's bursts, over its level before.

    For each row of ``onsets`` (shape ``(n, K)``: the K burst onsets of n beeps, samples;
    one row may be given as a 1-d array) and each window length in ``lengths``
    (samples, the guard included), the smallest over its bursts of
    ``|sum_n w(n) x(n) e^(-i omega n)|^2`` over the ``length - guard`` samples ending
    ``guard`` before the onset (``w`` a Hann window, ``omega`` the tone's frequency),
    divided by the mean of the same over windows of that length (every half window)
    in the ``PRE_NEAR_S`` before; shape ``(n, len(lengths))``. NaN for a beep whose
    windows or level stretches leave the recording, whose level is 0, or with clipped
    samples (``clipped``, a mask) in those stretches (a click is not the beep's sound).

    The coherent projection on the tone is the matched statistic of a tone of unknown
    phase (Kay 1998, §7.6): a direct path 20 dB under a reflection 80 samples later, at
    peak 0.05 in white noise of 0.05, stands about 10 dB over noise in a 56-sample window
    where the band energy of a frame rises 2 dB. The Hann window is the band-limiting:
    its side lobes 8 kHz or more from the tone are about 45 dB down for 24 samples and 70
    dB for 56 (DC, hum and the speech band do not reach it; the impaired corpus, speech
    and music 10 dB over the far beep, did not raise it). The smallest over the bursts,
    because an echo of burst ``k - 1`` can precede burst ``k`` but nothing of the beep
    precedes its first burst (measured on the pyroomacoustics corpus: without the first
    burst the smallest of the other three reached 20 on correct arrivals).

    Examples
    --------
    >>> import numpy as np
    >>> from rangekit.signals import Beep, beep_waveform
    >>> b = Beep()
    >>> x = 1e-3 * np.random.default_rng(0).standard_normal(30000)
    >>> x[5000:5000 + b.duration_samples] += beep_waveform(b)
    >>> on = 5000.0 + b.spacing * np.arange(b.n_bursts)
    >>> r = precursor_ratio(x, on, fs=b.fs, f_hz=b.f_hz, lengths=(64, 128), guard=8)
    >>> r.shape, bool(np.all(r < 2.0))
    ((1, 2), True)
    >>> tone = 0.05 * np.sin(2 * np.pi * b.f_hz / b.fs * np.arange(40))
    >>> for k in range(b.n_bursts):
    ...     x[4960 + k * b.spacing : 5000 + k * b.spacing] += tone
    >>> bool(precursor_ratio(x, on, fs=b.fs, f_hz=b.f_hz, lengths=(64,), guard=8)[0, 0] > 100)
    True
    """
    on = np.atleast_2d(np.asarray(onsets, dtype=np.float64))
    if len(on) > PRE_CHUNK:
        # beeps in chunks: the level stretches of all beeps at once outgrow the caches
        # (per beep 20 us for 400 beeps, 38 us for 2400); each row's numbers are its own
        kw = {"fs": fs, "f_hz": f_hz, "lengths": lengths, "guard": guard, "clipped": clipped}
        return np.concatenate(
            [precursor_ratio(x, on[i : i + PRE_CHUNK], **kw) for i in range(0, len(on), PRE_CHUNK)]
        )
    n_k = on.shape[1]
    far = int(round(PRE_NEAR_S * fs))
    n_lens = [int(v) - guard for v in lengths]
    span = far + max(n_lens)
    end = np.floor(on).astype(np.int64) - guard  # (n, K) window ends, exclusive
    start = end - span
    ok = np.all((start >= 0) & (end <= len(x)), axis=1)
    out = np.full((len(on), len(n_lens)), np.nan)
    if not np.any(ok):
        return out
    rows = start[ok].ravel()[:, None] + np.arange(span)
    seg = np.asarray(x)[rows].astype(np.float64, copy=False)  # (m, span)
    bad = clipped[rows].any(axis=1) if clipped is not None else np.zeros(len(seg), bool)
    w0 = 2.0 * math.pi * f_hz / fs
    for c, n_len in enumerate(n_lens):
        # |sum_n w(n) x(p + n) e^(-i omega (p + n))| = |sum_n h(n) x(p + n)| with h(n) =
        # w(n) e^(-i omega n): real windows times the real and imaginary parts of h.
        ph = w0 * np.arange(n_len)
        win = np.hanning(n_len + 2)[1:-1]
        h = np.stack([win * np.cos(ph), win * np.sin(ph)], axis=1)  # (n_len, 2)
        o = span - n_len - far  # this length's level stretch starts here in seg
        pos = o + np.arange(0, far - n_len + 1, max(1, n_len // 2))
        windows = np.lib.stride_tricks.sliding_window_view(seg, n_len, axis=1)[:, pos]
        level = np.mean(np.sum((windows @ h) ** 2, axis=2), axis=1)
        last = np.sum((seg[:, span - n_len :] @ h) ** 2, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where((level > 0) & ~bad, last / level, np.nan).reshape(-1, n_k)
        out[ok, c] = np.where(np.isnan(r).any(axis=1), np.nan, np.min(r, axis=1))
    return out


def precursor_hits(
    x: np.ndarray,
    onsets: np.ndarray,
    *,
    fs: float,
    beep: Beep,
    clipped: np.ndarray | None = None,
) -> np.ndarray:
    """Which beeps of onsets ``onsets`` (samples, one per beep) have the beep's tone
    ``PRE_TONE_RATIO`` over its level before, just before every burst
    (:func:`precursor_ratio`, windows of ``PRE_TONE_S``): sound of the beep arrived
    before the chosen onset, within a few windows (a direct path too weak to time, 20
    dB under a reflection 0.7-3 ms later, or a pulse). Tested on beeps of three bursts or
    more whose every burst's window lies in the recording (one burst alone is
    exponential: e^-4 = 2 % of noise passes); ``clipped``: the recording's clip mask."""
    onsets = np.asarray(onsets, dtype=np.float64)
    hit = np.zeros(len(onsets), dtype=bool)
    if beep.n_bursts < 3 or len(onsets) == 0:
        return hit
    guard = int(round(PRE_GUARD_S * fs))
    on = onsets[:, None] + beep.spacing_s * fs * np.arange(beep.n_bursts)
    lengths = tuple(max(guard + 4, int(round(v * fs))) for v in PRE_TONE_S)
    kw = {"fs": fs, "f_hz": beep.f_hz, "lengths": lengths, "guard": guard, "clipped": clipped}
    # The smallest over the bursts reaches the ratio only if the first burst does (2 % of
    # noise): the other bursts are read for those beeps alone.
    hit = np.any(precursor_ratio(x, on[:, :1], **kw) >= PRE_TONE_RATIO, axis=1)  # NaN: no
    if np.any(hit):
        hit[hit] = np.any(precursor_ratio(x, on[hit], **kw) >= PRE_TONE_RATIO, axis=1)
    return hit


def _precursor_flags(arr: Arrivals, cond: _Conditioner, *, fs: float, beep: Beep) -> Arrivals:
    """``arr`` with ``ambiguous_first_path`` added where :func:`precursor_hits`."""
    hit = precursor_hits(cond.x, arr.onset, fs=fs, beep=beep, clipped=cond.clipped)
    bit = flag_bit("ambiguous_first_path")
    return replace(arr, flags=np.where(hit, arr.flags | bit, arr.flags))


class _Found:
    """Onsets found so far, sorted: is one within ``[lo, hi]``?"""

    def __init__(self) -> None:
        self.t: list[float] = []

    def within(self, lo: float, hi: float) -> bool:
        j = bisect.bisect_left(self.t, lo)
        return j < len(self.t) and self.t[j] <= hi

    def add(self, t: float) -> None:
        bisect.insort(self.t, t)


def _beep_row(
    cond: _Conditioner,
    a: int,
    e: np.ndarray,
    found: _Found,
    *,
    fs: float,
    beep: Beep,
    n_win: int,
    hop: int,
    background: bool,
    min_bursts: int,
    quiet: float,
    oob: bool,
    retry: bool = True,
) -> tuple | None:
    """The beep of anchor ``a`` (numpy reference): ``(onset, sigma, snr_db, confidence,
    burst_onsets, flags, strength)``, or None. ``found`` gains its onset. An edge at the
    search window's late end is searched again from an anchor on it (once: ``retry``)."""
    # An anchor whose search window holds a beep onset already found (away from the
    # window's ends) would find that beep again: the beep's other change points.
    look = int(round(LOOKBACK_S * fs))
    sep = max(2, int(round(beep.taper_s * fs)))
    if found.within(a - n_win // 2 - look + sep, a + n_win + hop - sep):
        return None
    fits, clipped, later = _fit_beep(
        cond,
        a,
        fs=fs,
        beep=beep,
        n_win=n_win,
        hop=hop,
        background=background,
        min_bursts=min_bursts,
        compiled=cond.compiled,
    )
    if later is not None:
        # Re-anchored once on an edge cut by the window's late end; the retry's window
        # puts that edge where a change point at the beep's start would. An edge where a
        # later burst of a beep already found lies is that burst, not a new beep (its
        # own retry would time that beep's bursts 1.. as bursts 0..: a beep one burst
        # spacing late, preferred over the true one when that one's first burst clipped).
        spacing = beep.spacing_s * fs
        lo, hi = later - n_win // 2 - look + sep, later + n_win + hop - sep
        if not retry or any(
            found.within(lo - k * spacing, hi - k * spacing) for k in range(1, beep.n_bursts)
        ):
            return None
        return _beep_row(
            cond, later, e, found, fs=fs, beep=beep, n_win=n_win, hop=hop,
            background=background, min_bursts=min_bursts, quiet=quiet, oob=oob, retry=False,
        )  # fmt: skip
    res = _combine(
        fits, clipped, spacing=beep.spacing_s * fs, scale=fs / 44100.0, min_bursts=min_bursts
    )
    if res is None:
        return None
    t0, s0, snr, conf, row, flags, strength = res
    found.add(t0)
    flags |= _before_onset_flags(
        e, t0, hop=hop, n_win=n_win, fs=fs, quiet=quiet, spacing=beep.spacing_s * fs,
        n_bursts=beep.n_bursts,
    )  # fmt: skip
    if oob:
        flags |= flag_bit("dc_or_lowband")
    return (t0, s0, snr, conf, row, flags, strength)


def _rows_compiled(
    cond: _Conditioner,
    anchors: np.ndarray,
    e: np.ndarray,
    *,
    fs: float,
    beep: Beep,
    n_win: int,
    hop: int,
    background: bool,
    min_bursts: int,
    quiet: float,
    oob: bool,
) -> list[tuple]:
    """:func:`_beep_row` of every anchor by one compiled loop (``_edge_kernels._beeps_py``:
    the same steps, clipped stretches included, equal to rounding); an anchor whose fit
    is singular, or whose edge lies at its window's late end (re-anchored), is done by
    :func:`_beep_row` in between, in order."""
    kw = {
        "fs": fs, "beep": beep, "n_win": n_win, "hop": hop, "background": background,
        "min_bursts": min_bursts, "quiet": quiet, "oob": oob,
    }  # fmt: skip
    scale = fs / 44100.0
    pre, post = _window(fs, beep, None, None)
    look = int(round(LOOKBACK_S * fs))
    u0, u1 = -(n_win // 2) - look, n_win + hop
    sep = max(2, int(round(beep.taper_s * fs)))
    margin = int(math.ceil(48 * fs / 44100.0 + beep.taper_s * fs)) + 8
    f_min = F_MIN * cond.f_scale ** (2.0 / 3.0)
    _, _, q_base, qt = _integer_basis(fs, beep, pre, post, background, False)
    cols_dc, _, q_base_dc, qt_dc = _integer_basis(fs, beep, pre, post, background, True)
    near = int(round(PRE_NEAR_S * fs / hop))
    ipar = np.array(
        [pre, post, u0, u1 - u0 + 1, margin, beep.n_bursts, sep, min_bursts, N_COARSE, N_FINE,
         int(background), hop, n_win, near, PRE_RUN, -(n_win // 2) - look + sep,
         n_win + hop - sep, _last_frames(0.0, hop=hop, n_win=n_win, fs=fs)[1]],
        dtype=np.int64,
    )  # fmt: skip
    fpar = np.array(
        [beep.spacing_s * fs, f_min, 0.8 * f_min * min_bursts, 3.0 * scale + 1.0, fs,
         2.0 * math.pi * beep.f_hz / fs, beep.taper_s, beep.burst_s, scale, MODEL_SIGMA,
         quiet, 10 ** (PRE_RISE_DB / 10), REVERB_FLOOR_RATIO, LOW_SNR_DB,
         cond.f_scale ** (2.0 / 3.0), F_MIN, 10 ** (PRE_LAST_DB / 10),
         float(round(PRE_GUARD_S * fs))],
        dtype=np.float64,
    )  # fmt: skip
    hr = cond._taps_reversed if cond.taps is not None else np.zeros(0)
    half = (len(cond.taps) - 1) // 2 if cond.taps is not None else 0
    if cond.clipped is not None:
        clip_idx, mask = np.flatnonzero(cond.clipped), cond.clipped
    else:
        clip_idx, mask = np.zeros(0, np.int64), np.zeros(0, dtype=bool)
    n_a = len(anchors)
    found_buf = np.zeros(n_a + 1)
    n_found = np.zeros(1, dtype=np.int64)
    out = np.zeros((n_a + 1, 7))
    burst_rows = np.zeros((n_a + 1, beep.n_bursts))
    n_rows = np.zeros(1, dtype=np.int64)
    bits = {
        1: flag_bit("ambiguous_first_path"), 2: flag_bit("reverb_limited"),
        4: flag_bit("inconsistent_bursts"), 8: flag_bit("low_snr"), 16: flag_bit("clipped"),
    }  # fmt: skip
    rows: list[tuple] = []
    i, done = 0, 0
    while i < n_a:
        i = _edge_kernels.call(
            "beeps", cond.x, hr, half, anchors, i, clip_idx, mask, qt, q_base.shape[1],
            qt.shape[0] - q_base.shape[1], qt_dc, q_base_dc.shape[1], cols_dc, ipar, fpar, e,
            found_buf, n_found, out, burst_rows, n_rows,
        )  # fmt: skip
        for r in range(done, int(n_rows[0])):
            fl = sum(b for k, b in bits.items() if int(out[r, 6]) & k)
            if oob:
                fl |= flag_bit("dc_or_lowband")
            rows.append(
                (float(out[r, 0]), float(out[r, 1]), float(out[r, 2]), float(out[r, 3]),
                 burst_rows[r].copy(), fl, float(out[r, 5]))
            )  # fmt: skip
        done = int(n_rows[0])
        if i >= n_a:
            break
        # The reference for this anchor (a singular fit, or an edge to re-anchor on).
        found = _Found()
        found.t = found_buf[: n_found[0]].tolist()
        r = _beep_row(cond, int(anchors[i]), e, found, **kw)
        if r is not None:
            rows.append(r)
            nf = int(n_found[0])
            found_buf[: nf + 1] = sorted([*found_buf[:nf].tolist(), r[0]])
            n_found[0] = nf + 1
        i += 1
    return rows


def _signal(x) -> np.ndarray:
    """``x`` as a contiguous 1-D array of finite values: float32 and float64 as they are
    (no float64 copy of a long float32 recording: the kernels read either, and every
    stretch a fit reads is converted), anything else as float64 (as
    ``rangekit._validate.signal_1d``)."""
    a = np.asarray(x)
    if a.dtype not in (np.float32, np.float64):
        return V.signal_1d("x", a, max_abs=V.MAX_SAMPLE_ABS)
    if a.ndim != 1:
        raise V.InvalidParameterError(f"x must be 1-D, got shape {a.shape}")
    a = np.ascontiguousarray(a)
    if len(a) >= _edge_kernels.NUMBA_MIN_SAMPLES or long_recording():
        finite = _edge_kernels.call("all_finite", a)
    else:
        finite = bool(np.all(np.isfinite(a)))
        a = a.astype(np.float64, copy=False)  # short: the numpy path, in float64
    if not finite:
        raise V.InvalidParameterError("x contains NaN or infinite values")
    if a.size and max(abs(float(a.max())), abs(float(a.min()))) > V.MAX_SAMPLE_ABS:
        raise V.InvalidParameterError(
            f"x holds values beyond +-{V.MAX_SAMPLE_ABS:g} (their energy overflows)"
        )
    return a


def _before_onset_flags(
    e: np.ndarray,
    t0: float,
    *,
    hop: int,
    n_win: int,
    fs: float,
    quiet: float,
    spacing: float = 0.0,
    n_bursts: int = 1,
) -> int:
    """Flags from the band energy just before an arrival's onset.

    ``ambiguous_first_path``: within ``PRE_NEAR_S`` before the onset some stretch of
    ``PRE_RUN`` frames (about three independent windows) rises ``PRE_RISE_DB`` above the
    level before that: sound of the beep's band arrived earlier than the chosen onset (a
    direct path too weak to be timed, or the onset taken on a reflection); or one of the
    frames just before the onset, in each of the ``n_bursts`` bursts ``spacing`` apart
    (:func:`_last_frames_ratio`), lies ``PRE_LAST_DB`` above its level before (the same,
    1-9 ms before: a direct path weaker than a reflection that follows within a few
    windows rises for too few frames to pass the run test).
    ``reverb_limited``: the level before is ``REVERB_FLOOR_RATIO`` times the recording's
    quiet level (the arrival rides on the reverberation of an earlier one).
    """
    flags = 0
    end = int(t0 - n_win) // hop  # last frame wholly before the onset
    near = int(round(PRE_NEAR_S * fs / hop))
    lo_near, lo_far = end - near, end - 2 * near
    if lo_far < 0 or end <= lo_near + PRE_RUN:
        return flags
    far = float(np.mean(e[lo_far:lo_near]))
    seg = e[lo_near:end]
    run = np.convolve(seg, np.ones(PRE_RUN) / PRE_RUN, mode="valid")
    if far > 0 and float(run.max()) > 10 ** (PRE_RISE_DB / 10) * far:
        flags |= flag_bit("ambiguous_first_path")
    ratio = _last_frames_ratio(e, t0, hop=hop, n_win=n_win, fs=fs, spacing=spacing, n=n_bursts)
    if len(ratio) and float(ratio.max()) > 10 ** (PRE_LAST_DB / 10):
        flags |= flag_bit("ambiguous_first_path")
    if quiet > 0 and far > REVERB_FLOOR_RATIO * quiet:
        flags |= flag_bit("reverb_limited")
    return flags


def _last_frames(t0: float, *, hop: int, n_win: int, fs: float) -> tuple[int, int]:
    """``(last, count)``: the last frame ending ``PRE_GUARD_S`` or more before onset ``t0``
    and how many frames up to it the one-by-one precursor test reads (``PRE_LAST_S``)."""
    guard = int(round(PRE_GUARD_S * fs))
    last = int(math.floor((t0 - guard - n_win) / hop))
    return last, max(1, int(round(PRE_LAST_S * fs / hop)))


def _last_frames_ratio(
    e: np.ndarray, t0: float, *, hop: int, n_win: int, fs: float, spacing: float, n: int
) -> np.ndarray:
    """The band energy of the frames just before each of ``n`` burst onsets ``t0 + k
    spacing`` (:func:`_last_frames`) over that burst's level before (the mean over the
    ``PRE_NEAR_S`` stretch ending ``PRE_NEAR_S`` before its last whole frame), the
    smallest over the bursts, frame by frame.

    The smallest: a direct path too weak to time precedes every burst, while an echo of
    the burst before (a late reflection arriving just before the next burst) precedes
    all but the first. In noise alone the smallest of four frames is exponential with a
    quarter of the mean (above 6 dB with probability e^-16 per frame). Bursts whose frames
    or level stretch leave ``e``, or whose level is 0, are left out; none: empty.
    """
    n_last = _last_frames(t0, hop=hop, n_win=n_win, fs=fs)[1]
    near = int(round(PRE_NEAR_S * fs / hop))
    out = np.full(n_last, np.inf)
    used = False
    for k in range(n):
        tk = t0 + k * spacing
        end = int(tk - n_win) // hop
        last = _last_frames(tk, hop=hop, n_win=n_win, fs=fs)[0]
        if end - 2 * near < 0 or last - n_last + 1 < 0 or last >= len(e):
            continue
        lvl = float(np.mean(e[end - 2 * near : end - near]))
        if lvl > 0:
            out = np.minimum(out, e[last - n_last + 1 : last + 1] / lvl)
            used = True
    return out if used else np.zeros(0)


def _out_of_band(x: np.ndarray, cond: _Conditioner) -> bool:
    """Whether energy outside the beep's band dominates the recording (a sample of it)."""
    if cond.taps is None or len(x) == 0:
        return False
    n = min(len(x), 1 << 16)
    i0 = (len(x) - n) // 2
    xs = np.asarray(x[i0 : i0 + n], dtype=np.float64)
    half = (len(cond.taps) - 1) // 2
    if cond.compiled:
        y = _edge_kernels.call("fir", xs, cond._taps_reversed, half, 0, n)
    else:
        # Direct convolution (what ``bandlimit`` does for short stretches; for this one it
        # would take scipy's FFT convolution and import scipy.signal, ~0.7-1 s).
        y = np.convolve(xs, cond.taps)[half : half + n]
    return out_of_band_ratio(xs, cond.taps, y) > OOB_RATIO
