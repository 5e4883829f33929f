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
   gives an estimate of the beep onset (its onset minus k * spacing); the centre is the weighted
   mean of the estimates agreeing with the best-supported one (the earliest such mean on
   a tie: a burst timed on a reflection is late); bursts more than a few samples from it
   are rejected, and the rest are averaged with inverse variance weights. A beep that
   starts inside an earlier beep is that beep's echo and is dropped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rangekit import _validate as V
from rangekit.detect._kernels import band_energy
from rangekit.detect.refine import fit_edge
from rangekit.signals.beep import Beep, check_beep_fits
from rangekit.types import Arrivals

__all__ = ["BurstCandidates", "detect_changepoint", "find_bursts", "group_bursts"]

#: STFT window and hop in seconds (128 and 32 samples at 44.1 kHz).
WIN_S = 128 / 44100
HOP_S = 32 / 44100


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
    e: np.ndarray, *, n_win: int, hop: int, threshold_db: float, rise_db: float, refractory: int
) -> np.ndarray:
    """Frames where the band energy rises strongly above background and its recent level."""
    if len(e) == 0:
        return np.zeros(0, dtype=np.int64)
    floor = max(float(np.percentile(e, 20.0)) / -math.log(0.8), 1e-30)
    gap = int(math.ceil(n_win / hop))
    nb = 8
    cs = np.concatenate(([0.0], np.cumsum(e)))
    m = np.arange(len(e))
    hi = np.clip(m - gap, 0, None)
    lo = np.clip(m - gap - nb, 0, None)
    cnt = hi - lo
    pre = np.where(cnt > 0, (cs[hi] - cs[lo]) / np.maximum(cnt, 1), floor)
    thr = np.maximum(floor * 10 ** (threshold_db / 10), pre * 10 ** (rise_db / 10))
    above = e > thr
    starts = np.flatnonzero(above & ~np.concatenate(([False], above[:-1])))
    keep = []
    last = -(10**18)
    for s in starts:
        if s - last >= refractory:
            keep.append(s)
            last = s
    return np.asarray(keep, dtype=np.int64)


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
) -> BurstCandidates:
    """Find and time every burst onset in ``x`` (no grouping into beeps)."""
    n_win, hop = _stft_params(fs, win_s, hop_s)
    e = band_energy(x, fs=fs, f_hz=np.array([beep.f_hz]), n_win=n_win, hop=hop)
    refractory = max(1, int(beep.burst_s * fs / hop))
    frames = _change_points(
        e, n_win=n_win, hop=hop, threshold_db=threshold_db, rise_db=rise_db, refractory=refractory
    )
    on, sg, snr = [], [], []
    for m in frames:
        fit = fit_edge(
            x,
            fs=fs,
            beep=beep,
            lo=int(m) * hop - n_win // 2,
            hi=int(m) * hop + n_win + hop,
            background=background,
        )
        if fit is not None:
            on.append(fit.onset)
            sg.append(fit.sigma)
            snr.append(fit.snr_db)
    return BurstCandidates(np.array(on), np.array(sg), np.array(snr), n_win, hop)


def group_bursts(
    cand: BurstCandidates, *, fs: float, beep: Beep, min_bursts: int | None = None
) -> Arrivals:
    """Group burst onsets into beeps using the known burst count and spacing."""
    k_b = beep.n_bursts
    min_bursts = k_b if min_bursts is None else V.positive_int("min_bursts", min_bursts)
    if min_bursts > k_b:
        raise V.InvalidParameterError(f"min_bursts={min_bursts} exceeds n_bursts={k_b}")
    spacing = beep.spacing_s * fs
    tol = 0.5 * cand.n_win + cand.hop
    scale = fs / 44100.0
    order = np.argsort(cand.onset)
    t = cand.onset[order]
    used = np.zeros(len(t), dtype=bool)
    rows = []
    for i in range(len(t)):
        if used[i]:
            continue
        members = [i]
        for k in range(1, k_b):
            target = t[i] + k * spacing
            j = int(np.searchsorted(t, target))
            best = None
            for jj in (j - 1, j):
                if 0 <= jj < len(t) and not used[jj] and jj not in members:
                    if abs(t[jj] - target) <= tol and (
                        best is None or abs(t[jj] - target) < abs(t[best] - target)
                    ):
                        best = jj
            members.append(best)
        if sum(mm is not None for mm in members) < min_bursts:
            continue
        for mm in members:
            if mm is not None:
                used[mm] = True
        rows.append(members)

    onset, sigma, snr, conf, bursts = [], [], [], [], []
    for members in rows:
        idx = [order[mm] if mm is not None else -1 for mm in members]
        ks = np.array([k for k, j in enumerate(idx) if j >= 0])
        js = np.array([j for j in idx if j >= 0])
        est = cand.onset[js] - ks * spacing
        # A failed fit reports an infinite sigma; it then weighs (almost) nothing.
        sg = np.clip(np.nan_to_num(cand.sigma[js], nan=1e6, posinf=1e6), 1e-3, 1e6)
        # Allowed scatter: timing noise, plus 200 ppm of clock-rate mismatch per spacing.
        allow = 2.0 * scale + 4.0 * sg + 2e-4 * ks * spacing
        # The centre is the weighted mean of the estimates that agree with the best-supported
        # one; on a tie, the earliest such mean (a burst timed on a reflection is late).
        close = np.abs(est[:, None] - est[None, :]) <= np.maximum(allow[:, None], allow[None, :])
        support = close.sum(axis=1)
        w_all = 1.0 / sg**2
        means = (close * w_all[None, :]) @ est / (close @ w_all)
        best = np.flatnonzero(support == support.max())
        centre = float(np.min(means[best]))
        ok = np.abs(est - centre) <= allow
        if ok.sum() < min(2, k_b):
            continue
        wts = 1.0 / sg[ok] ** 2
        t0 = float(np.sum(wts * est[ok]) / np.sum(wts))
        s0 = 1.0 / math.sqrt(float(np.sum(wts)))
        if ok.sum() > 1:
            chi2 = float(np.sum(wts * (est[ok] - t0) ** 2)) / (ok.sum() - 1)
            s0 *= math.sqrt(max(1.0, chi2))
        row = np.full(k_b, np.nan)
        row[ks[ok]] = cand.onset[js[ok]]
        onset.append(t0)
        sigma.append(s0)
        snr.append(float(np.median(cand.snr_db[js[ok]])))
        conf.append(ok.sum() / k_b)
        bursts.append(row)
    if not onset:
        return Arrivals.empty(fs=fs, n_bursts=k_b, detector="changepoint")
    arr = Arrivals(
        np.array(onset),
        float(fs),
        np.array(sigma),
        np.array(snr),
        np.array(conf),
        np.array(bursts),
        "changepoint",
    )
    return drop_echoes(arr, duration=beep.duration_s * fs)


def drop_echoes(arr: Arrivals, *, duration: float) -> Arrivals:
    """Drop arrivals that start inside an earlier arrival (echoes of it)."""
    order = np.argsort(arr.onset)
    keep = []
    end = -math.inf
    for i in order:
        if arr.onset[i] >= end:
            keep.append(i)
            end = arr.onset[i] + duration
    return arr.take(np.array(keep, dtype=np.int64))


def detect_changepoint(
    x: np.ndarray,
    *,
    fs: float,
    beep: Beep | None = None,
    win_s: float = WIN_S,
    hop_s: float = HOP_S,
    threshold_db: float = 12.0,
    rise_db: float = 10.0,
    min_bursts: int | None = None,
    background: bool = False,
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
        Minimum band energy above the background for a burst start, in dB.
    rise_db : float
        Minimum rise over the band energy just before, in dB.
    min_bursts : int, optional
        Bursts a beep needs (default: all of them). The first burst is always required.
    background : bool
        Fit a background tone during the edge fit (reverberant rooms).

    Returns
    -------
    Arrivals
        One entry per beep, in time order; empty for a silent recording.

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
    x = V.signal_1d("x", x)
    check_beep_fits(beep, fs=fs)
    cand = find_bursts(
        x,
        fs=fs,
        beep=beep,
        win_s=win_s,
        hop_s=hop_s,
        threshold_db=threshold_db,
        rise_db=rise_db,
        background=background,
    )
    return group_bursts(cand, fs=fs, beep=beep, min_bursts=min_bursts)
