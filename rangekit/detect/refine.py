"""Sub-sample timing of one tone-burst onset by a least-squares fit of its leading edge.

Notes
-----
Near a burst start the recording is modelled as

    x[n] = env((n - tau) / fs) * (alpha * sin(w n) + beta * cos(w n))        (+ noise)
           [+ gamma * sin(w n) + delta * cos(w n)]     (optional background tone)

with ``env`` the beep's known burst envelope (raised-cosine rise), ``w = 2 pi f / fs`` and
unknown complex amplitude (alpha, beta). The carrier phase is absorbed by (alpha, beta), so
the timing comes from the envelope only (no cycle slips). For each ``tau`` the amplitudes
are linear least squares; ``tau`` minimises the residual energy over a window that holds a
few samples of background before the onset and only the rising edge plus a short plateau
after it, so that reflections arriving later than that do not pull the estimate.

The estimate is invariant to the arrival's amplitude (the residual scales by A^2), which is
what two-way ranging needs: the loud own beep and the faint far beep are timed alike.

Two stages: (1) on an integer grid spanning the coarse interval, the F statistic of the
edge model in each window (explained energy per parameter over residual energy per degree
of freedom) finds the edges; the onset is the *earliest* local maximum reaching
``first_path`` (0.1) times the largest, so that later reflections adding up in phase into a
stronger edge do not win; (2) around that, the plain residual is minimised over
continuous ``tau`` in a fixed window (a coarse grid, a fine grid, then a parabola; each
grid one batched solve of the 2x2 (4x4) normal equations), which is unbiased at any
amplitude.

The optional background term models a tone already ringing at the beep frequency when the
burst starts (reverberation of earlier bursts); stage 1 then uses the partial F statistic
of the edge over the background-only model.

Both stages have numba kernels (:mod:`rangekit.detect._edge_kernels`, ``compiled=True``:
the same numbers to rounding, ~3x and ~11x faster per call); the numpy code here is their
reference and the path for short recordings (no numba import).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from rangekit.detect import _edge_kernels as K
from rangekit.signals.beep import Beep, burst_envelope

__all__ = ["EdgeFit", "edge_statistic", "first_peak", "fit_edge", "refine_onset"]

#: Onsets of the coarse grid (over +-(3 fs/44.1 kHz + 1) samples) and of the fine grid
#: (between the coarse minimum's neighbours) of stage 2. The residual is smooth at these
#: scales: 13 + 13 points give the onsets of 25 + 33 to within 0.002 samples (tests).
N_COARSE = 13
N_FINE = 13


@dataclass(frozen=True)
class EdgeFit:
    """Result of :func:`fit_edge` (all times in samples of the recording)."""

    onset: float
    sigma: float
    snr_db: float
    amplitude: float
    f_stat: float = math.inf
    n_masked: int = 0


def _basis_many(
    n: np.ndarray, taus, *, w: float, fs: float, beep: Beep, background: bool, dc: bool = False
):
    """Model columns for each onset in ``taus``: shape (T, L, p), p = 2, 4 or 6.

    Columns: the edge (``env * sin``, ``env * cos``), then the background tone (``sin``,
    ``cos``) when ``background``, then a constant and a slope when ``dc``.
    """
    taus = np.atleast_1d(np.asarray(taus, dtype=np.float64))
    env = burst_envelope((n[None, :] - taus[:, None]) / fs, beep=beep)  # (T, L)
    s, c = np.sin(w * n), np.cos(w * n)
    cols = [env * s, env * c]
    if background:
        cols += [np.broadcast_to(s, env.shape), np.broadcast_to(c, env.shape)]
    if dc:
        ramp = (n - n[0]) / max(float(n[-1] - n[0]), 1.0) - 0.5 if len(n) else n
        cols += [np.ones(env.shape), np.broadcast_to(ramp, env.shape)]
    return np.stack(cols, axis=2)


def _basis(n: np.ndarray, tau: float, **kw) -> np.ndarray:
    """Model columns for one onset: shape (L, p)."""
    return _basis_many(n, tau, **kw)[0]


def first_peak(f: np.ndarray, frac: float, f_min: float) -> int:
    """Index of the earliest local maximum of ``f`` reaching ``frac * max(f)`` and ``f_min``."""
    top = float(np.max(f))
    ok = f >= max(frac * top, min(f_min, top))
    left = np.concatenate(([True], f[1:] >= f[:-1]))
    right = np.concatenate((f[:-1] >= f[1:], [True]))
    idx = np.flatnonzero(ok & left & right)
    return int(idx[0]) if len(idx) else int(np.argmax(f))


def _fits(seg: np.ndarray, n: np.ndarray, taus, **kw) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares fit at each of ``taus`` (batched normal equations).

    Returns the residual energies (T,) and the amplitude coefficients (T, p).
    """
    b = _basis_many(n, taus, **kw)  # (T, L, p)
    gram = np.einsum("tlp,tlq->tpq", b, b)
    g = np.einsum("tlp,l->tp", b, seg)
    p = b.shape[2]
    gram += np.eye(p) * (1e-12 * np.trace(gram, axis1=1, axis2=2)[:, None, None] / p + 1e-300)
    coef = np.linalg.solve(gram, g[:, :, None])[:, :, 0]
    return float(seg @ seg) - np.einsum("tp,tp->t", g, coef), coef


def fit_edge(
    x: np.ndarray,
    *,
    fs: float,
    beep: Beep,
    lo: int,
    hi: int,
    pre: int | None = None,
    post: int | None = None,
    background: bool = False,
    first_path: float = 0.1,
    f_min: float = 15.0,
    mask: np.ndarray | None = None,
    dc: bool = False,
    compiled: bool = False,
) -> EdgeFit | None:
    """Time a burst onset known to lie in samples [lo, hi] of ``x``.

    Parameters
    ----------
    x : ndarray
        The recording (1-D float).
    fs : float
        Sample rate of ``x`` in Hz.
    beep : Beep
        The beep whose burst edge is fitted (frequency and envelope, in seconds).
    lo, hi : int
        Interval (samples) that contains the onset, from the coarse detector.
    pre, post : int, optional
        Window samples before and after the onset. Defaults: 24 samples of background
        (at 44.1 kHz, scaled with ``fs``) and the taper plus 8 samples.
    background : bool
        Also fit a constant tone at the beep frequency (reverberation of earlier bursts).
    first_path : float
        The onset is the earliest local maximum of the edge statistic that reaches this
        fraction of the largest one in [lo, hi] and at least ``f_min``.
    f_min : float
        Smallest F statistic taken as an edge (noise alone exceeds 15 with probability
        about e^-15 per offset).
    mask : ndarray of bool, optional
        Samples of ``x`` to leave out of the fit (clipped samples), in both stages.
    dc : bool
        Also fit a constant and a slope (a recording that was not band-limited: DC offset
        and low-frequency drift).
    compiled : bool
        Use the numba kernels of :mod:`rangekit.detect._edge_kernels` (the same numbers to
        rounding; worth it when numba is imported anyway, i.e. for long recordings).

    Returns
    -------
    EdgeFit or None
        None when the window does not fit in ``x``. ``f_stat`` is the edge statistic at
        the chosen onset (below ``f_min``: no edge was found, the fit is the best guess);
        ``n_masked`` the samples of the stage-2 window left out.
    """
    pre, post = _window(fs, beep, pre, post)
    lo = max(int(lo), pre)
    hi = min(int(hi), len(x) - post - 4)
    if hi < lo:
        return None

    f_stat = edge_statistic(
        x,
        fs=fs,
        beep=beep,
        lo=lo,
        hi=hi,
        pre=pre,
        post=post,
        background=background,
        mask=mask,
        dc=dc,
        compiled=compiled,
    )
    i_a = first_peak(f_stat, first_path, f_min)
    return refine_onset(
        x,
        fs=fs,
        beep=beep,
        a=lo + i_a,
        f_stat=float(f_stat[i_a]),
        pre=pre,
        post=post,
        background=background,
        mask=mask,
        dc=dc,
        compiled=compiled,
    )


def _window(fs: float, beep: Beep, pre: int | None, post: int | None) -> tuple[int, int]:
    """Default samples of background before and of edge after an onset."""
    scale = fs / 44100.0
    pre = int(round(24 * scale)) if pre is None else int(pre)
    post = int(math.ceil(beep.taper_s * fs + 8 * scale)) if post is None else int(post)
    return pre, post


def edge_statistic(
    x: np.ndarray,
    *,
    fs: float,
    beep: Beep,
    lo: int,
    hi: int,
    pre: int | None = None,
    post: int | None = None,
    background: bool = False,
    mask: np.ndarray | None = None,
    dc: bool = False,
    compiled: bool = False,
) -> np.ndarray:
    """Stage 1 of :func:`fit_edge`: the edge's F statistic at every integer onset in
    ``[lo, hi]`` (``lo``, ``hi`` already clipped to where the window fits ``x``).

    On an integer grid the basis is the same for every onset (the carrier phase is
    absorbed), so one QR serves all offsets. The F statistic of the edge model in each
    window is explained energy per edge parameter over residual energy per degree of
    freedom; with nuisance columns (background tone, constant and slope) it is the partial
    F test of the edge columns over the nuisance-only model (a plateau is then explained by
    the background alone).
    """
    pre, post = _window(fs, beep, pre, post)
    length = pre + post
    seg = x[lo - pre : hi + post]
    cols, q_full, q_base, qt = _integer_basis(fs, beep, pre, post, background, dc)
    n_par = cols.shape[1]
    masked = mask is not None and np.any(mask[lo - pre : hi + post])
    if compiled:
        seg_c = np.ascontiguousarray(seg, dtype=np.float64)
        if not masked:
            return K.call("edge_stat", seg_c, qt, q_base.shape[1], n_par)
        keep = 1.0 - np.asarray(mask[lo - pre : hi + post], dtype=np.float64)
        f, ok = K.call("masked_stat", seg_c, keep, cols)
        if ok:
            return f
    frames = np.lib.stride_tricks.sliding_window_view(seg, length)
    if masked:
        return _masked_statistic(frames, mask[lo - pre : hi + post], cols)
    total = np.einsum("ij,ij->i", frames, frames)

    def explained_by(q: np.ndarray) -> np.ndarray:
        proj = frames @ q
        return np.einsum("ij,ij->i", proj, proj)

    full = explained_by(q_full)
    base = explained_by(q_base) if cols.shape[1] > 2 else 0.0
    # Residual floored at 1e-12 of the window energy: noiseless input must not turn
    # rounding residue into a statistic.
    resid = np.maximum(total - full, 1e-12 * total + 1e-300) / (length - n_par)
    return np.maximum(full - base, 0.0) / 2.0 / resid


@functools.lru_cache(maxsize=64)
def _integer_basis(
    fs: float, beep: Beep, pre: int, post: int, background: bool, dc: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Stage 1's basis on the integer grid, ``(cols, q_full, q_base, qt)``, computed once.

    ``cols`` (L, p) are the model columns for an onset ``pre`` samples into a window of
    ``L = pre + post``; ``q_full`` and ``q_base`` orthonormal bases (QR) of all of them and
    of the nuisance columns only (0 columns without nuisance terms); ``qt`` both bases'
    vectors as rows (the compiled kernel's layout). Read-only, C-contiguous float64.
    """
    k = np.arange(pre + post, dtype=np.float64)
    kw = {"w": 2.0 * math.pi * beep.f_hz / fs, "fs": fs, "beep": beep, "dc": dc}
    cols = _basis(k, float(pre), background=background, **kw)
    q_full = np.linalg.qr(cols)[0]
    q_base = np.linalg.qr(cols[:, 2:])[0] if cols.shape[1] > 2 else np.zeros((len(k), 0))
    qt = np.concatenate([q_full, q_base], axis=1).T
    out = tuple(np.ascontiguousarray(a, dtype=np.float64) for a in (cols, q_full, q_base, qt))
    for a in out:
        a.flags.writeable = False
    return out


def _masked_statistic(frames: np.ndarray, mask: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """The edge's partial F statistic per window with the masked samples left out.

    Each window has its own design (its unmasked rows), so the normal equations are
    formed per window: ``G_i = B^T W_i B``, ``g_i = B^T W_i d_i`` with ``W_i`` the
    window's 0/1 weights; a window with too few unmasked samples gets 0.
    """
    w = 1.0 - np.lib.stride_tricks.sliding_window_view(mask.astype(np.float64), frames.shape[1])
    wd = w * frames
    n_par = cols.shape[1]
    n_keep = w.sum(axis=1)
    total = np.einsum("ij,ij->i", wd, frames)

    def explained_by(b: np.ndarray) -> np.ndarray:
        gram = np.einsum("il,lp,lq->ipq", w, b, b)
        p = b.shape[1]
        gram += np.eye(p) * (1e-12 * np.trace(gram, axis1=1, axis2=2)[:, None, None] / p + 1e-300)
        g = wd @ b
        coef = np.linalg.solve(gram, g[:, :, None])[:, :, 0]
        return np.einsum("ip,ip->i", g, coef)

    full = explained_by(cols)
    base = explained_by(cols[:, 2:]) if n_par > 2 else 0.0
    dof = n_keep - n_par
    resid = np.maximum(total - full, 1e-12 * total + 1e-300) / np.maximum(dof, 1.0)
    f = np.maximum(full - base, 0.0) / 2.0 / resid
    return np.where(dof >= 8, f, 0.0)


def refine_onset(
    x: np.ndarray,
    *,
    fs: float,
    beep: Beep,
    a: int,
    f_stat: float = math.inf,
    pre: int | None = None,
    post: int | None = None,
    background: bool = False,
    mask: np.ndarray | None = None,
    dc: bool = False,
    compiled: bool = False,
) -> EdgeFit | None:
    """Stage 2 of :func:`fit_edge`: the continuous onset near integer onset ``a``, by the
    plain residual in a fixed window, with its Fisher-information 1-sigma.

    ``f_stat`` is passed through to the result. None when too few unmasked samples are
    left.
    """
    scale = fs / 44100.0
    pre, post = _window(fs, beep, pre, post)
    kw = {"w": 2.0 * math.pi * beep.f_hz / fs, "fs": fs, "beep": beep, "dc": dc}
    n_cols = 2 + 2 * int(background) + 2 * int(dc)
    # Stage 2: continuous tau in a fixed window around a, plain residual.
    h = 3.0 * scale + 1.0
    i0 = max(0, int(math.floor(a - h)) - pre)
    i1 = min(len(x), int(math.ceil(a + h)) + post)
    n = np.arange(i0, i1, dtype=np.float64)
    seg2 = x[i0:i1]
    n_masked = 0
    if mask is not None:
        keep = ~np.asarray(mask[i0:i1], dtype=bool)
        n_masked = int(len(keep) - keep.sum())
        if keep.sum() < 8 + 2 * n_cols:
            return None
        n, seg2 = n[keep], seg2[keep]
    kw2 = {**kw, "background": background}
    if compiled:
        fit = _refine_compiled(seg2, n, a, h, kw["w"], fs, beep, background, dc)
        if fit is not None:
            rss, tau, amp, perp2 = fit
            return _edge_fit(tau, rss, amp, perp2, len(seg2), n_cols, f_stat, n_masked)
    # Coarse grid, then a fine grid between the coarse minimum's neighbours, then a
    # parabola through the three lowest fine points; each grid is one batched solve.
    grid = np.linspace(a - h, a + h, N_COARSE)
    j = int(np.argmin(_fits(seg2, n, grid, **kw2)[0]))
    fine = np.linspace(grid[max(j - 1, 0)], grid[min(j + 1, len(grid) - 1)], N_FINE)
    rf = _fits(seg2, n, fine, **kw2)[0]
    m = int(np.clip(np.argmin(rf), 1, len(fine) - 2))
    y0, y1, y2 = rf[m - 1], rf[m], rf[m + 1]
    den = y0 - 2.0 * y1 + y2
    step = fine[1] - fine[0]
    vertex = float(np.clip(0.5 * (y0 - y2) / den, -1.0, 1.0)) if den > 0 else 0.0
    tau = float(fine[m] + vertex * step)

    # Uncertainty: Fisher information of tau with the linear amplitudes profiled out.
    rss_t, coef_t = _fits(seg2, n, tau, **kw2)
    rss, coef = max(float(rss_t[0]), 0.0), coef_t[0]
    b = _basis(n, tau, **kw2)
    eps = 1e-3
    dm = (_basis(n, tau + eps, **kw2) - _basis(n, tau - eps, **kw2)) @ coef / (2 * eps)
    qb, _ = np.linalg.qr(b)
    dm_perp = dm - qb @ (qb.T @ dm)
    amp = float(math.hypot(coef[0], coef[1]))
    perp2 = float(dm_perp @ dm_perp)
    return _edge_fit(tau, rss, amp, perp2, len(seg2), b.shape[1], f_stat, n_masked)


def _edge_fit(
    tau: float,
    rss: float,
    amp: float,
    perp2: float,
    n_samples: int,
    n_cols: int,
    f_stat: float,
    n_masked: int,
) -> EdgeFit:
    """The :class:`EdgeFit` of a stage-2 fit: ``perp2`` is the squared norm of the onset
    derivative of the model orthogonal to its columns (Fisher information x noise var)."""
    dof = max(n_samples - n_cols - 1, 1)
    noise_var = max(rss / dof, 1e-30)
    info = perp2 / noise_var
    sigma = 1.0 / math.sqrt(info) if info > 0 else math.inf
    snr_db = 10.0 * math.log10(max(0.5 * amp * amp / noise_var, 1e-30))
    return EdgeFit(
        onset=float(tau),
        sigma=float(sigma),
        snr_db=snr_db,
        amplitude=amp,
        f_stat=float(f_stat),
        n_masked=n_masked,
    )


def _refine_compiled(
    seg: np.ndarray,
    n: np.ndarray,
    a: int,
    h: float,
    w: float,
    fs: float,
    beep: Beep,
    background: bool,
    dc: bool,
) -> tuple[float, float, float, float] | None:
    """Stage 2 by :func:`rangekit.detect._edge_kernels._refine_py`: ``(rss, tau, amp,
    perp2)``, or None when a system was not positive definite (use the numpy path)."""
    seg = np.ascontiguousarray(seg, dtype=np.float64)
    s, c = np.sin(w * n), np.cos(w * n)
    nuis = []
    if background:
        nuis += [s, c]
    if dc:
        ramp = (n - n[0]) / max(float(n[-1] - n[0]), 1.0) - 0.5 if len(n) else n
        nuis += [np.ones(len(n)), ramp]
    nuis_a = np.stack(nuis, axis=1) if nuis else np.zeros((len(n), 0))
    res = K.call(
        "refine",
        seg,
        np.ascontiguousarray(n),
        nuis_a,
        s,
        c,
        float(seg @ seg),
        float(a),
        float(h),
        N_COARSE,
        N_FINE,
        float(fs),
        float(beep.taper_s),
        float(beep.burst_s),
    )
    if res[0] != 1.0:
        return None
    return float(res[2]), float(res[1]), float(math.hypot(res[3], res[4])), float(res[5])
