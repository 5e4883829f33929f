"""Pictures of what happened (``rangekit plot``): spectrogram, matched filter, ranges, tracks, CDFs.

Each figure has a ``draw_*(ax, ...)`` function that draws on one matplotlib axes and
returns the data it drew (a frozen dataclass), and a ``plot_*(..., path)`` function that
makes the figure, draws it and writes it with :func:`rangekit.plot.save_figure` (format
from the suffix: PNG, PDF or SVG; written atomically). The artists carry a ``gid``
(``"onset"``, ``"track:TARGET"``, ...; listed in each ``draw_*``) so that tests, and SVG
readers, can find what was drawn.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from rangekit import _validate as V
from rangekit.errors import InvalidParameterError
from rangekit.plot import new_figure, save_figure

__all__ = [
    "CdfPlot",
    "MatchedPlot",
    "RangesPlot",
    "SpectrogramPlot",
    "TrackPlot",
    "TruthAgreement",
    "covariance_ellipse",
    "draw_cdf",
    "draw_matched",
    "draw_ranges",
    "draw_spectrogram",
    "draw_track",
    "error_cdf",
    "plot_cdf",
    "plot_matched",
    "plot_ranges",
    "plot_spectrogram",
    "plot_track",
    "spectrogram_db",
    "truth_agreement",
    "truth_for",
]

#: Most STFT frames a spectrogram shows (the hop grows for longer recordings).
MAX_FRAMES = 4000
#: Levels below the peak that the spectrogram and matched-filter figures show, dB.
DYNAMIC_RANGE_DB = 80.0


def _finish(fig, ax, path, title: str) -> None:
    if title:
        ax.set_title(title, fontsize=9)
    save_figure(fig, path)


# --- spectrogram ----------------------------------------------------------------------------


@dataclass(frozen=True)
class SpectrogramPlot:
    """What :func:`draw_spectrogram` drew.

    Attributes
    ----------
    t_s : ndarray, shape (n_frames,)
        Frame centres, s from sample 0.
    f_hz : ndarray, shape (n_bins,)
        Bin frequencies, Hz.
    power_db : ndarray, shape (n_bins, n_frames)
        Power spectral density, dB re 1/Hz (full scale 1).
    onsets_s : ndarray
        The marked onsets, s from sample 0.
    """

    t_s: np.ndarray
    f_hz: np.ndarray
    power_db: np.ndarray
    onsets_s: np.ndarray


def spectrogram_db(
    x: np.ndarray, *, fs: float, n_fft: int | None = None, hop: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """STFT power spectral density in dB (Hann window), for display.

    Parameters
    ----------
    x : ndarray
        One channel.
    fs : float
        Sample rate, Hz.
    n_fft : int, optional
        Window length (default: the power of two nearest 5 ms, at least 64; at most
        ``len(x)``).
    hop : int, optional
        Frame step (default ``n_fft // 4``, raised so that at most :data:`MAX_FRAMES`
        frames are computed).

    Returns
    -------
    t_s, f_hz, power_db : ndarray
        Frame centres (s), bin frequencies (Hz), PSD in dB (bins x frames); silence is
        floored at 300 dB below full scale.

    Examples
    --------
    >>> fs = 8000.0
    >>> x = np.sin(2 * np.pi * 1000.0 * np.arange(8000) / fs)
    >>> t, f, p = spectrogram_db(x, fs=fs)
    >>> float(f[np.argmax(p[:, 10])])
    1000.0
    """
    from scipy.signal import spectrogram

    fs = V.sample_rate(fs)
    x = V.signal_1d("x", x)
    if len(x) < 16:
        raise InvalidParameterError(f"x has {len(x)} samples; a spectrogram needs at least 16")
    if n_fft is None:
        n_fft = max(64, 1 << round(math.log2(0.005 * fs)))
    n_fft = min(V.positive_int("n_fft", n_fft, minimum=8), len(x))
    if hop is None:
        hop = max(n_fft // 4, math.ceil((len(x) - n_fft) / (MAX_FRAMES - 1)))
    hop = min(V.positive_int("hop", hop), n_fft)
    f, t, sxx = spectrogram(
        x, fs=fs, window="hann", nperseg=n_fft, noverlap=n_fft - hop, scaling="density"
    )
    return t, f, 10.0 * np.log10(np.maximum(sxx, 1e-30))


def _time_window(n: int, fs: float, t0_s: float | None, t1_s: float | None) -> tuple[int, int]:
    """Samples ``[i0, i1)`` of an ``n``-sample channel inside ``[t0_s, t1_s]`` seconds."""
    t0 = 0.0 if t0_s is None else V.in_range("t0_s", t0_s, 0.0, math.inf)
    t1 = n / fs if t1_s is None else V.in_range("t1_s", t1_s, 0.0, math.inf)
    if not t0 < t1:
        raise InvalidParameterError(f"time window {t0:g}-{t1:g} s must have t0 < t1")
    i0, i1 = int(math.floor(t0 * fs)), min(n, int(math.ceil(t1 * fs)))
    if i1 - i0 < 16:
        raise InvalidParameterError(
            f"time window {t0:g}-{t1:g} s holds {max(0, i1 - i0)} samples of the "
            f"{n / fs:g} s recording; a spectrogram needs at least 16"
        )
    return i0, i1


def draw_spectrogram(
    ax,
    x: np.ndarray,
    *,
    fs: float,
    onsets: np.ndarray = (),
    n_fft: int | None = None,
    label: str = "onset",
    t0_s: float | None = None,
    t1_s: float | None = None,
    fmin_hz: float | None = None,
    fmax_hz: float | None = None,
) -> SpectrogramPlot:
    """Spectrogram of one channel with vertical lines at ``onsets``.

    Parameters
    ----------
    ax : matplotlib Axes
    x : ndarray
        One channel.
    fs : float
        Sample rate, Hz.
    onsets : array_like
        Float sample indices from sample 0 (e.g. :attr:`rangekit.types.Arrivals.onset`).
    n_fft : int, optional
        STFT window (:func:`spectrogram_db`).
    label : str
        Legend label of the onset lines.
    t0_s, t1_s : float, optional
        Time window to show, s from sample 0 (default the whole channel); the STFT is
        computed on the window only (its frames are finer on a short window), times stay
        those of the recording.
    fmin_hz, fmax_hz : float, optional
        Frequency range to show, Hz (default 0 to ``fs / 2``).

    Returns
    -------
    SpectrogramPlot
        Artists: the image (gid ``"spectrogram"``) and one vertical line per onset inside
        the window (gid ``"onset"``, x = the onset in seconds).
    """
    i0, i1 = _time_window(len(x), fs, t0_s, t1_s)
    lo = 0.0 if fmin_hz is None else V.in_range("fmin_hz", fmin_hz, 0.0, fs / 2)
    hi = fs / 2 if fmax_hz is None else V.in_range("fmax_hz", fmax_hz, 0.0, fs / 2)
    if not lo < hi:
        raise InvalidParameterError(f"frequency range {lo:g}-{hi:g} Hz must have fmin < fmax")
    t, f, p = spectrogram_db(np.asarray(x)[i0:i1], fs=fs, n_fft=n_fft)
    t = t + i0 / fs
    onsets_s = np.asarray(onsets, dtype=float).reshape(-1) / fs
    onsets_s = onsets_s[(onsets_s >= i0 / fs) & (onsets_s <= i1 / fs)]
    dt = (t[1] - t[0]) if len(t) > 1 else (i1 - i0) / fs
    df = f[1] - f[0]
    top = float(p.max())
    im = ax.imshow(
        p,
        origin="lower",
        aspect="auto",
        extent=(t[0] - dt / 2, t[-1] + dt / 2, (f[0] - df / 2) / 1e3, (f[-1] + df / 2) / 1e3),
        vmin=top - DYNAMIC_RANGE_DB,
        vmax=top,
        cmap="magma",
        interpolation="nearest",
    )
    im.set_gid("spectrogram")
    ax.figure.colorbar(im, ax=ax, label="PSD (dB re 1/Hz)")
    for i, o in enumerate(onsets_s):
        ax.axvline(
            o, color="c", lw=0.9, ls="--", gid="onset", label=label if i == 0 else "_nolegend_"
        )
    if len(onsets_s):
        ax.legend(fontsize=8, loc="upper right")
    ax.set_xlim(i0 / fs, i1 / fs)
    ax.set_ylim(lo / 1e3, hi / 1e3)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("frequency (kHz)")
    return SpectrogramPlot(t, f, p, onsets_s)


def plot_spectrogram(
    x: np.ndarray,
    path: str | os.PathLike,
    *,
    fs: float,
    onsets: np.ndarray = (),
    n_fft: int | None = None,
    title: str = "",
    label: str = "onset",
    t0_s: float | None = None,
    t1_s: float | None = None,
    fmin_hz: float | None = None,
    fmax_hz: float | None = None,
) -> SpectrogramPlot:
    """Write :func:`draw_spectrogram` of ``x`` to ``path`` (``.png``, ``.pdf``, ``.svg``)."""
    window = {"t0_s": t0_s, "t1_s": t1_s, "fmin_hz": fmin_hz, "fmax_hz": fmax_hz}
    draw_args = {"fs": fs, "onsets": onsets, "n_fft": n_fft, "label": label, **window}
    if any(v is not None for v in window.values()):  # checked before the figure is made
        _time_window(len(x), fs, t0_s, t1_s)
    fig, ax = new_figure(size=(9.0, 4.5))
    out = draw_spectrogram(ax[0, 0], x, **draw_args)
    _finish(fig, ax[0, 0], path, title)
    return out


# --- matched filter -------------------------------------------------------------------------


@dataclass(frozen=True)
class MatchedPlot:
    """What :func:`draw_matched` drew.

    Attributes
    ----------
    t_s : ndarray
        Lags, s from the window start.
    level_db : ndarray
        Envelope in dB re its maximum in the window (floored at -``DYNAMIC_RANGE_DB`` - 20).
    peak_s : float
        The chosen first path, s from the window start (NaN if none).
    threshold_db : float
        ``k_detect`` times the noise level, dB re the maximum (NaN without noise).
    """

    t_s: np.ndarray
    level_db: np.ndarray
    peak_s: float
    threshold_db: float


def draw_matched(ax, trace, *, k_detect: float | None = None) -> MatchedPlot:
    """Matched-filter envelope of one window with the chosen first path marked.

    Parameters
    ----------
    ax : matplotlib Axes
    trace : rangekit.ranging.ultrasonic.MatchedTrace
        From :func:`rangekit.ranging.ultrasonic.matched_trace`.
    k_detect : float, optional
        Noise multiple the strongest peak must clear
        (default :data:`rangekit.detect.matched.DEFAULT_K_DETECT`), drawn as a level.

    Returns
    -------
    MatchedPlot
        Artists: the envelope (gid ``"envelope"``, x in ms), the first path (vertical line,
        gid ``"first-path"``, at ``arrival_s`` in ms), the detection level (gid
        ``"threshold"``) and the searched lags (gid ``"search"``).
    """
    from rangekit.detect.matched import DEFAULT_K_DETECT

    k_detect = DEFAULT_K_DETECT if k_detect is None else float(k_detect)
    env = np.asarray(trace.envelope, dtype=float)
    fs = trace.fs
    t = np.arange(len(env)) / fs
    top = float(env.max()) if len(env) else 0.0
    floor = -DYNAMIC_RANGE_DB - 20.0
    if top > 0:
        level = 20.0 * np.log10(np.maximum(env / top, 10.0 ** (floor / 20.0)))
    else:
        level = np.full(len(env), floor)
    ax.plot(t * 1e3, level, "k-", lw=0.7, gid="envelope", label="matched-filter envelope")
    lo, hi = trace.search_s
    ax.axvspan(
        lo * 1e3,
        min(hi, t[-1] if len(t) else hi) * 1e3,
        color="0.85",
        gid="search",
        label="searched",
        zorder=0,
    )
    thr = math.nan
    if trace.noise > 0 and top > 0:
        thr = 20.0 * math.log10(k_detect * trace.noise / top)
        ax.axhline(
            thr,
            color="b",
            ls=":",
            lw=0.9,
            gid="threshold",
            label=f"detection level ({k_detect:g} x noise)",
        )
    tof = trace.tof
    peak_s = tof.arrival_s
    if math.isfinite(peak_s):
        ax.axvline(
            peak_s * 1e3,
            color="r",
            lw=1.0,
            gid="first-path",
            label=f"first path: {tof.distance_m:.4f} m",
        )
        ax.plot([peak_s * 1e3], [np.interp(peak_s * fs, np.arange(len(env)), level)], "ro", ms=4)
    ax.set_ylim(floor, 3.0)
    ax.set_xlabel("time from the window start (ms)")
    ax.set_ylabel("envelope (dB re max)")
    ax.legend(fontsize=8, loc="upper right")
    return MatchedPlot(t, level, float(peak_s), thr)


def plot_matched(
    trace, path: str | os.PathLike, *, k_detect: float | None = None, title: str | None = None
) -> MatchedPlot:
    """Write :func:`draw_matched` of ``trace`` to ``path``; the default title gives the range."""
    fig, ax = new_figure(size=(9.0, 4.5))
    out = draw_matched(ax[0, 0], trace, k_detect=k_detect)
    if title is None:
        tof = trace.tof
        where = f"channel {tof.channel}, window {tof.window}"
        if tof.tx is not None:
            where += f" (tx {tof.tx})"
        if math.isfinite(tof.distance_m):
            title = (
                f"{where}: {tof.distance_m:.4f} m ± {tof.sigma_m * 1e3:.2f} mm, "
                f"SNR {tof.snr_db:.1f} dB"
            )
        else:
            title = f"{where}: nothing detected"
    _finish(fig, ax[0, 0], path, title)
    return out


# --- range series ---------------------------------------------------------------------------


@dataclass(frozen=True)
class RangesPlot:
    """What :func:`draw_ranges` drew: per series key, ``(t_s, distance_m, sigma_m)``."""

    series: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]


def truth_for(series: Sequence, truth: float | Mapping[str, float] | None) -> dict[str, float]:
    """The true distance of each series key: one value for all, or a mapping by key
    (keys without a value are left out).

    Examples
    --------
    >>> from types import SimpleNamespace as S
    >>> truth_for([S(key="0-1"), S(key="0-2")], {"0-1": 2.0})
    {'0-1': 2.0}
    >>> truth_for([S(key="0-1")], 1.5)
    {'0-1': 1.5}
    """
    if truth is None:
        return {}
    if isinstance(truth, Mapping):
        return {s.key: float(truth[s.key]) for s in series if s.key in truth}
    return {s.key: float(truth) for s in series}


@dataclass(frozen=True)
class TruthAgreement:
    """How range series agree with their true distances (:func:`truth_agreement`).

    Attributes
    ----------
    n : int
        Ranges compared (finite distance, series with a true distance).
    median_abs_error_m : float
        Median ``|distance_m - truth|`` (m); NaN when ``n == 0``.
    within_2sigma : float
        Share of those ranges with ``|error| <= 2 sigma_m`` (NaN ``sigma_m`` counts as
        outside); NaN when ``n == 0``.
    """

    n: int
    median_abs_error_m: float
    within_2sigma: float


def truth_agreement(series: Sequence, truth: float | Mapping[str, float]) -> TruthAgreement:
    """Median absolute error and share within 2 sigma of ``series`` against ``truth``.

    ``truth`` is as in :func:`truth_for`; series without a true distance are left out.

    Examples
    --------
    >>> from types import SimpleNamespace as S
    >>> s = S(key="0-1", distance_m=np.array([2.001, 2.0, np.nan]), sigma_m=np.full(3, 1e-3))
    >>> a = truth_agreement([s], 2.0)
    >>> a.n, round(a.median_abs_error_m, 4), a.within_2sigma
    (2, 0.0005, 1.0)
    """
    by_key = truth_for(series, truth)
    use = [s for s in series if s.key in by_key]
    if not use:
        return TruthAgreement(0, math.nan, math.nan)
    err = np.concatenate([np.abs(np.asarray(s.distance_m) - by_key[s.key]) for s in use])
    sig = np.concatenate([np.asarray(s.sigma_m, dtype=float) for s in use])
    ok = np.isfinite(err)
    if not ok.any():
        return TruthAgreement(0, math.nan, math.nan)
    return TruthAgreement(
        int(ok.sum()), float(np.median(err[ok])), float(np.mean(err[ok] <= 2 * sig[ok]))
    )


def draw_ranges(
    ax, series: Sequence, *, truth: float | Mapping[str, float] | None = None
) -> RangesPlot:
    """Range time series with ±1 sigma and ±2 sigma bands, one line per series.

    Parameters
    ----------
    ax : matplotlib Axes
    series : sequence of rangekit.plot.inputs.RangeSeries
        From :func:`rangekit.plot.inputs.read_range_series`. NaN distances are gaps.
    truth : float or mapping of str to float, optional
        The true distance (m), one for every series or one per series key
        (:func:`truth_for`): drawn as a dashed line in the series' colour.

    Returns
    -------
    RangesPlot
        Artists per series key ``K``: the line (gid ``"range:K"``), the ±1 sigma band (gid
        ``"band1:K"``, edges at ``distance_m ± sigma_m``), the ±2 sigma band (gid
        ``"band2:K"``) and the truth (gid ``"truth:K"``).
    """
    out = {}
    true = truth_for(series, truth)
    for i, s in enumerate(series):
        color = f"C{i % 10}"
        label = s.key or "range"
        t, d, sig = (np.asarray(v, dtype=float) for v in (s.t_s, s.distance_m, s.sigma_m))
        for k, alpha in ((2, 0.12), (1, 0.3)):
            ax.fill_between(
                t, d - k * sig, d + k * sig, color=color, alpha=alpha, lw=0, gid=f"band{k}:{s.key}"
            )
        ax.plot(t, d, "-", marker=".", ms=4, lw=1.0, color=color, gid=f"range:{s.key}", label=label)
        if s.key in true:
            first = s.key == next(iter(true))
            ax.axhline(
                true[s.key],
                color=color,
                ls="--",
                lw=0.9,
                gid=f"truth:{s.key}",
                label="truth" if first else "_nolegend_",
            )
        out[s.key] = (t, d, sig)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("distance (m)")
    if out:
        ax.legend(fontsize=8, loc="best", title="bands: ±1σ, ±2σ", title_fontsize=8)
    return RangesPlot(out)


def plot_ranges(
    series: Sequence,
    path: str | os.PathLike,
    *,
    title: str = "",
    truth: float | Mapping[str, float] | None = None,
) -> RangesPlot:
    """Write :func:`draw_ranges` of ``series`` to ``path``."""
    fig, ax = new_figure(size=(9.0, 4.5))
    out = draw_ranges(ax[0, 0], series, truth=truth)
    _finish(fig, ax[0, 0], path, title)
    return out


# --- tracks ---------------------------------------------------------------------------------


def covariance_ellipse(cov_m2: np.ndarray, *, n_sigma: float = 2.0) -> tuple[float, float, float]:
    """Width, height and angle (degrees) of the ``n_sigma`` ellipse of a 2x2 covariance.

    The ellipse ``v^T P^-1 v = n_sigma^2`` (Mahalanobis distance ``n_sigma``; at 2 it holds
    1 - exp(-2) = 86.5 % of a Gaussian): axes ``2 n_sigma sqrt(lambda)`` along the
    eigenvectors of ``P``; the width lies along the major axis, at ``angle`` from +x.
    Negative eigenvalues (rounding) count as 0.

    Examples
    --------
    >>> [round(v, 9) for v in covariance_ellipse(np.diag([0.04, 0.01]))]
    [0.8, 0.4, 0.0]
    """
    p = np.asarray(cov_m2, dtype=float).reshape(2, 2)
    lam, vec = np.linalg.eigh(0.5 * (p + p.T))
    lam = np.maximum(lam, 0.0)
    angle = math.degrees(math.atan2(vec[1, 1], vec[0, 1]))
    return 2 * n_sigma * math.sqrt(lam[1]), 2 * n_sigma * math.sqrt(lam[0]), angle


@dataclass(frozen=True)
class TrackPlot:
    """What :func:`draw_track` drew.

    Attributes
    ----------
    xy_m : dict of str to ndarray
        Per target, the track points, shape (n, 2).
    ellipse_rows : dict of str to ndarray
        Per target, the rows (indices into ``xy_m``) that got a covariance ellipse or a
        spread circle.
    n_walls : int
        Solid wall segments drawn.
    """

    xy_m: dict[str, np.ndarray]
    ellipse_rows: dict[str, np.ndarray]
    n_walls: int


def draw_track(
    ax,
    paths: Sequence,
    *,
    plan=None,
    truth: Sequence = (),
    every: int = 10,
    n_sigma: float = 2.0,
) -> TrackPlot:
    """Trajectories with covariance ellipses (or spread circles) over a floor plan.

    Parameters
    ----------
    ax : matplotlib Axes
    paths : sequence of rangekit.plot.inputs.TrackPath
        The tracks (:func:`rangekit.plot.inputs.read_track`).
    plan : rangekit.floorplan.FloorPlan, optional
        Walls to draw (their solid segments; doors are gaps).
    truth : sequence of TrackPath
        True paths, drawn dashed.
    every : int
        An ellipse at rows 0, ``every``, ``2 every``, ... of each target (0: none). Rows
        with a covariance get the ``n_sigma`` ellipse (:func:`covariance_ellipse`); rows
        with only ``spread_m`` a circle of that radius.
    n_sigma : float
        Mahalanobis radius of the ellipses (2: the 86.5 % region).

    Returns
    -------
    TrackPlot
        Artists: walls (gid ``"walls"``), each track (gid ``"track:T"``, points = the
        rows), each truth (gid ``"truth:T"``), ellipses (gid ``"ellipse:T"``) and circles
        (gid ``"spread:T"``), ``T`` the target.
    """
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Circle, Ellipse

    every = V.positive_int("every", every, minimum=0)
    n_sigma = V.positive("n_sigma", n_sigma)
    n_walls = 0
    if plan is not None:
        seg = np.asarray(plan.segments, dtype=float).reshape(-1, 4)
        n_walls = len(seg)
        if n_walls:
            ax.add_collection(
                LineCollection(
                    seg.reshape(-1, 2, 2), colors="0.2", linewidths=2.0, gid="walls", label="walls"
                )
            )
    colors = {p.target: f"C{i % 10}" for i, p in enumerate(paths)}
    for p in truth:
        lab = f"truth {p.target}".strip()
        ax.plot(
            p.xy_m[:, 0],
            p.xy_m[:, 1],
            "--",
            color=colors.get(p.target, "0.45"),
            alpha=0.7,
            lw=1.0,
            gid=f"truth:{p.target}",
            label=lab,
        )
    xy_out, rows_out = {}, {}
    legend = {"ellipse": f"{n_sigma:g}σ covariance ellipse", "spread": "spread_m circle"}
    for p in paths:
        color = colors[p.target]
        lab = f"target {p.target}" if p.target else "track"
        ax.plot(
            p.xy_m[:, 0],
            p.xy_m[:, 1],
            "-",
            marker=".",
            ms=3,
            lw=1.0,
            color=color,
            gid=f"track:{p.target}",
            label=lab,
        )
        drawn = []
        for k in range(0, len(p.xy_m), every) if every else ():
            c = p.xy_m[k]
            if not np.all(np.isfinite(c)):
                continue
            cov = p.cov_m2[k]
            if np.all(np.isfinite(cov)):
                w, h, ang = covariance_ellipse(cov, n_sigma=n_sigma)
                patch = Ellipse(
                    tuple(c),
                    w,
                    h,
                    angle=ang,
                    fill=False,
                    ec=color,
                    lw=0.8,
                    gid=f"ellipse:{p.target}",
                )
            elif math.isfinite(p.spread_m[k]):
                patch = Circle(
                    tuple(c),
                    float(p.spread_m[k]),
                    fill=False,
                    ec=color,
                    lw=0.8,
                    ls="--",
                    gid=f"spread:{p.target}",
                )
            else:
                continue
            patch.set_label(legend.pop(patch.get_gid().split(":")[0], "_nolegend_"))
            ax.add_patch(patch)
            drawn.append(k)
        xy_out[p.target] = p.xy_m
        rows_out[p.target] = np.array(drawn, dtype=np.int64)
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8, loc="best")
    return TrackPlot(xy_out, rows_out, n_walls)


def plot_track(
    paths: Sequence,
    path: str | os.PathLike,
    *,
    plan=None,
    truth: Sequence = (),
    every: int = 10,
    n_sigma: float = 2.0,
    title: str = "",
) -> TrackPlot:
    """Write :func:`draw_track` to ``path``."""
    fig, ax = new_figure(size=(7.5, 6.5))
    out = draw_track(ax[0, 0], paths, plan=plan, truth=truth, every=every, n_sigma=n_sigma)
    _finish(fig, ax[0, 0], path, title)
    return out


# --- error CDFs -----------------------------------------------------------------------------


def error_cdf(errors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Empirical CDF as a post-step curve: ``(x, y)`` from ``(e_min, 0)`` up to ``(e_max, 1)``.

    Examples
    --------
    >>> x, y = error_cdf(np.array([0.3, 0.1, 0.2]))
    >>> x.tolist(), np.round(y, 3).tolist()
    ([0.1, 0.1, 0.2, 0.3], [0.0, 0.333, 0.667, 1.0])
    """
    e = np.sort(np.asarray(errors, dtype=float).reshape(-1))
    if len(e) == 0:
        return np.zeros(0), np.zeros(0)
    return np.concatenate([e[:1], e]), np.arange(len(e) + 1) / len(e)


@dataclass(frozen=True)
class CdfPlot:
    """What :func:`draw_cdf` drew: per group the CDF curve (m, fraction), median and p90 (m)."""

    curves: dict[str, tuple[np.ndarray, np.ndarray]]
    median_m: dict[str, float]
    p90_m: dict[str, float]


def draw_cdf(ax, errors_m: Mapping[str, np.ndarray], *, by: str | None = None) -> CdfPlot:
    """Empirical CDFs of absolute errors (mm), one per group, median and p90 in the legend.

    Parameters
    ----------
    ax : matplotlib Axes
    errors_m : mapping of str to ndarray
        Group -> absolute errors (m) (:attr:`rangekit.plot.inputs.BatchErrors.errors_m`).
    by : str, optional
        Name of the grouping column, for the legend.

    Returns
    -------
    CdfPlot
        Artists: one step line per group ``G`` (gid ``"cdf:G"``, x in mm); the medians and
        90th percentiles are numpy's (``np.median``, ``np.percentile(e, 90)``).
    """
    curves, med, p90 = {}, {}, {}
    for i, (g, e) in enumerate(errors_m.items()):
        e = np.asarray(e, dtype=float)
        x, y = error_cdf(e)
        med[g], p90[g] = float(np.median(e)), float(np.percentile(e, 90))
        name = (f"{by}={g}" if by else g) if g else ("(empty)" if by else "all")
        lab = f"{name}: n={len(e)}, median {med[g] * 1e3:.3g} mm, p90 {p90[g] * 1e3:.3g} mm"
        ax.plot(
            x * 1e3,
            y,
            drawstyle="steps-post",
            color=f"C{i % 10}",
            lw=1.2,
            gid=f"cdf:{g}",
            label=lab,
        )
        curves[g] = (x, y)
    ax.set_ylim(0.0, 1.02)
    ax.set_xlim(left=0.0)
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("absolute range error (mm)")
    ax.set_ylabel("fraction of ranges")
    ax.legend(fontsize=8, loc="lower right")
    return CdfPlot(curves, med, p90)


def plot_cdf(batch, path: str | os.PathLike, *, title: str | None = None) -> CdfPlot:
    """Write :func:`draw_cdf` of a :class:`rangekit.plot.inputs.BatchErrors` to ``path``.

    The default title counts the rows used and skipped.
    """
    fig, ax = new_figure(size=(7.5, 5.0))
    out = draw_cdf(ax[0, 0], batch.errors_m, by=batch.by)
    if title is None:
        used = batch.n_rows - batch.n_skipped
        title = (
            f"absolute range error: {used} of {batch.n_rows} rows "
            f"({batch.n_skipped} skipped: no distance, no truth or status not ok)"
        )
    _finish(fig, ax[0, 0], path, title)
    return out
