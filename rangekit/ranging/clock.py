"""Sample-clock rates of the devices from a series of two-way exchanges, and their correction.

A device's audio clock runs at ``1 + e_i`` times its nominal rate (``e_i``: tens of ppm for
the crystal of a phone codec). One exchange cannot tell a clock-rate error from a distance
(:mod:`rangekit.ranging.beepbeep`), but a series can: the spacing of successive exchanges
as measured by two recordings differs by the ratio of their clocks.

Notes
-----
Model (``docs/theory/clock.md`` gives the full derivation). Device i's sample n is taken
at absolute time ``R_i + n / (fs_i (1 + e_i))``, so a time read off its recording as
``n / fs_i`` is ``(1 + e_i) (t - R_i)``. In exchange k device 0 plays at ``P0_k`` and
device i at ``Pi_k``; their distance is ``d_k``, the self-distances ``s_0``, ``s_i``. With
A_k, B_k the onsets (s, device 0's clock) of device 0's and device i's signals in device
0's recording and C_k, D_k the same in device i's recording:

    A = (1 + e_0)(P0 + s_0/c - R_0)      B = (1 + e_0)(Pi + d/c - R_0)
    C = (1 + e_i)(P0 + d/c - R_i)        D = (1 + e_i)(Pi + s_i/c - R_i)

The midpoints ``M0 = (A + B)/2`` and ``Mi = (C + D)/2`` both contain ``tau_k = (P0_k +
Pi_k)/2 + d_k/(2c)``, the flight time entering both the same way:

    M0_k = (1 + e_0)(tau_k + s_0/(2c) - R_0),   Mi_k = (1 + e_i)(tau_k + s_i/(2c) - R_i)

hence ``Mi_k = rho_i M0_k + const`` with ``rho_i = (1 + e_i)/(1 + e_0)``, whatever the
schedule, the gaps or a changing distance (exact when the distance is the same for both
beeps of an exchange; a device moving at v changes it by ``v (Pi - P0)`` within the
exchange, a constant for steady motion). A weighted least-squares line of ``Mi`` on ``M0``
over the exchanges (weights ``1 / (var Mi + var M0)`` from the detector's onset sigmas)
gives ``rho_i``; ``ppm_i = (rho_i - 1) 1e6`` relative to device 0 (``ppm_0 = 0``), with the
1-sigma of the slope from the fit residuals, ``sigma_rho^2 = (sum w r^2 / (n - 2)) / sum
w (M0 - mean_w M0)^2``. Exchanges whose residual exceeds ``max(5 x 1.4826 MAD, 3)`` in
units of its sigma are dropped and the line refitted (a wrong detection, a beep taken for
another), as long as three remain.

Correction: every interval measured in device i's recording is divided by ``1 + ppm_i
1e-6`` (the onsets are read with a sample rate of ``fs_i (1 + ppm_i 1e-6)``), which
expresses it in device 0's time, and the exchange is ranged again with
:func:`~rangekit.ranging.beepbeep.range_beepbeep`. Uncorrected, the pair (a, b) is off by
(Peng et al. 2007 two-way formula with ``Delta_a = (1 + e_a) T_a``, ``Delta_b = (1 + e_b)
T_b``, ``T`` the true intervals):

    D_ab - d = c/2 (e_a T_a - e_b T_b) ~= -c/2 (e_b - e_a) G_ab + (e_a + e_b)/2 d

``G_ab = Pb - Pa`` the time from device a's signal to device b's (:func:`clock_error_m`).
After the correction the first term is gone and ``e_0 (d - (s_a + s_b)/2)`` remains: a
common clock error scales distances by ``1 + e_0`` (0.25 mm at 50 ppm and 5 m).

Examples
--------
>>> import numpy as np
>>> from rangekit.ranging.series import ExchangeRanges
>>> from rangekit.types import Arrivals
>>> def arr(t_s, fs=44100.0):
...     z = np.zeros(2)
...     return Arrivals(np.asarray(t_s) * fs, fs, z + 0.05, z + 30, z + 1, np.zeros((2, 4)))
>>> e1 = 50e-6  # device 1 runs 50 ppm fast; 1 m apart, beeps 0.6 s apart, every 2 s
>>> ex = []
>>> for k in range(5):
...     p0, p1, fl = 0.2 + 2.0 * k, 0.8 + 2.0 * k, 1.0 / 343.0
...     a = [arr([p0, p1 + fl]), arr(np.array([p0 + fl, p1]) * (1 + e1) + 0.01)]
...     ex.append(ExchangeRanges(k, p0, (), arrivals=tuple(a)))
>>> rates = estimate_clock_rates(ex)
>>> np.round(rates.ppm, 3).tolist(), rates.n_exchanges, round(rates.span_s, 6)
([0.0, 50.0], 5, 8.0)
>>> fixed = correct_clock(ex, rates, speed_m_s=343.0)
>>> round(fixed[0].ranges[0].distance_m, 9)
1.0
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from rangekit import _validate as V
from rangekit.errors import DetectionError, IncompatibleInputError, InvalidParameterError
from rangekit.ranging.beepbeep import check_speed, range_beepbeep
from rangekit.ranging.series import ExchangeRanges

__all__ = [
    "MIN_EXCHANGES",
    "MIN_SPAN_S",
    "ClockRates",
    "clock_error_m",
    "correct_clock",
    "correct_series_clock",
    "estimate_clock_rates",
]

#: Fewest exchanges with every beep detected that an estimate needs.
MIN_EXCHANGES = 3
#: Shortest time (device 0's clock) from the first to the last exchange used, s.
MIN_SPAN_S = 1.0
#: Rejection threshold in robust sigmas, and its floor in nominal (detector) sigmas.
_REJECT_MAD = 5.0
_REJECT_FLOOR = 3.0
#: Floor of an onset's 1-sigma in the weights, s (exact synthetic onsets carry sigma 0).
_SIGMA_FLOOR_S = 1e-9


@dataclass(frozen=True)
class ClockRates:
    """Sample-clock rate of every device.

    Attributes
    ----------
    ppm : ndarray, shape (N,)
        Clock-rate error of each device in ppm (positive: runs fast). Estimates are
        relative to device 0 (``ppm[0] = 0``); known values may be absolute.
    sigma_ppm : ndarray, shape (N,)
        1-sigma of each estimate from the fit residuals (0 for device 0 and for known
        values).
    n_exchanges : int
        Exchanges the estimate used (after skipping failed and rejected ones); 0 for
        known values.
    span_s : float
        Time from the first to the last exchange used, s of device 0's clock (0 for
        known values).
    n_rejected : int
        Exchanges with every beep detected that the robust fit dropped as outliers.
    """

    ppm: np.ndarray
    sigma_ppm: np.ndarray
    n_exchanges: int
    span_s: float
    n_rejected: int = 0

    @classmethod
    def known(cls, ppm: Sequence[float], n_devices: int) -> ClockRates:
        """Known clock errors: one per device (device 0 first), or one per device 1.. N-1.

        Examples
        --------
        >>> ClockRates.known([49.8], 2).ppm.tolist()
        [0.0, 49.8]
        """
        v = np.atleast_1d(np.asarray(ppm, dtype=np.float64))
        if v.ndim != 1 or len(v) not in (n_devices, n_devices - 1):
            raise IncompatibleInputError(
                f"{len(v)} clock rate(s) given for {n_devices} devices: give one per device "
                f"({n_devices}, device 0 first) or one per device after device 0 "
                f"({n_devices - 1})"
            )
        for x in v.tolist():
            V.in_range("clock rate (ppm)", x, -1e4, 1e4)
        if len(v) == n_devices - 1:
            v = np.concatenate([[0.0], v])
        return cls(v, np.zeros(n_devices), 0, 0.0)

    def as_dict(self) -> dict:
        """Plain-JSON form (the ``clock_rate`` entry of ``range --series`` JSON meta)."""
        return {
            "ppm": [float(x) for x in self.ppm],
            "sigma_ppm": [float(x) for x in self.sigma_ppm],
            "n_exchanges": int(self.n_exchanges),
            "span_s": float(self.span_s),
            "n_rejected": int(self.n_rejected),
        }


def clock_error_m(ppm: float, interval_s: float, *, speed_m_s: float) -> float:
    """Two-way range error of an uncorrected clock-rate difference.

    Parameters
    ----------
    ppm : float
        Clock-rate error of device b relative to device a, ppm (``(1 + e_b)/(1 + e_a) - 1``).
    interval_s : float
        Time from device a's signal to device b's within the exchange, s.
    speed_m_s : float
        Speed of sound, m/s.

    Returns
    -------
    float
        ``-c/2 * ppm 1e-6 * interval_s``, m (device b fast: the range comes out short).

    Examples
    --------
    >>> round(clock_error_m(50.0, 0.6, speed_m_s=343.0) * 1000, 3)  # mm
    -5.145
    """
    c = check_speed(speed_m_s)
    return -0.5 * c * float(ppm) * 1e-6 * float(interval_s)


def _usable(ex: ExchangeRanges, n: int | None) -> bool:
    """Whether an exchange has one finite onset per device on every recording."""
    if ex.error is not None:
        return False
    if ex.arrivals is None:
        raise IncompatibleInputError(
            f"exchange {ex.exchange} at {ex.t_s:.3f} s carries no arrivals (clock rates need "
            "the exchanges of range_series_beepbeep)"
        )
    if n is not None and len(ex.arrivals) != n:
        raise IncompatibleInputError(
            f"exchange {ex.exchange} has {len(ex.arrivals)} recordings where the others have {n}"
        )
    m = len(ex.arrivals)
    return all(len(a) == m and np.all(np.isfinite(a.onset)) for a in ex.arrivals)


def _fit_line(x: np.ndarray, d: np.ndarray, var: np.ndarray):
    """Robust WLS line ``x + d`` on ``x``: slope - 1, its sigma, kept mask."""
    w_all = 1.0 / var
    keep = np.ones(len(x), dtype=bool)
    for _ in range(10):
        w, xk, dk = w_all[keep], x[keep], d[keep]
        xm = np.sum(w * xk) / np.sum(w)
        dx = xk - xm
        sxx = float(np.sum(w * dx**2))
        b = float(np.sum(w * dx * (dk - np.sum(w * dk) / np.sum(w)))) / sxx
        a = float(np.sum(w * (dk - b * dx)) / np.sum(w))
        z = (d - a - b * (x - xm)) * np.sqrt(w_all)
        zk = z[keep]
        mad = 1.4826 * float(np.median(np.abs(zk - np.median(zk))))
        new = np.abs(z - np.median(zk)) <= max(_REJECT_MAD * mad, _REJECT_FLOOR)
        if new.sum() < MIN_EXCHANGES or np.array_equal(new, keep):
            break
        keep = new
    n = int(keep.sum())
    r = zk  # residuals of the kept points, in nominal sigmas (z = r sqrt(w))
    s2 = float(np.sum(r**2)) / (n - 2) if n > 2 else math.nan
    return b, math.sqrt(s2 / sxx), keep


def estimate_clock_rates(
    exchanges: Sequence[ExchangeRanges],
    *,
    min_exchanges: int = MIN_EXCHANGES,
    min_span_s: float = MIN_SPAN_S,
) -> ClockRates:
    """Each device's sample-clock rate relative to device 0 from a series of exchanges.

    Parameters
    ----------
    exchanges : sequence of ExchangeRanges
        The exchanges of :func:`rangekit.ranging.series.range_series_beepbeep` (they
        carry the arrivals they were ranged from). Exchanges that failed detection are
        skipped.
    min_exchanges : int
        Fewest usable exchanges, >= 3 (default 3).
    min_span_s : float
        Shortest time from the first to the last usable exchange, s (default 1).

    Returns
    -------
    ClockRates
        ``ppm[0] = 0``; ``ppm[i] = (rho_i - 1) 1e6`` with ``rho_i`` the slope of device
        i's exchange midpoints against device 0's (module Notes).

    Raises
    ------
    IncompatibleInputError
        Fewer than ``min_exchanges`` exchanges in all, usable ones spanning less than
        ``min_span_s``, exchanges without arrivals, or exchanges with differing device
        counts.
    DetectionError
        Enough exchanges, but fewer than ``min_exchanges`` of them with every beep
        detected.
    """
    min_exchanges = V.positive_int("min_exchanges", min_exchanges, minimum=MIN_EXCHANGES)
    min_span_s = V.positive("min_span_s", min_span_s, allow_zero=True)
    exchanges = list(exchanges)
    if len(exchanges) < min_exchanges:
        raise IncompatibleInputError(
            f"clock-rate estimation needs at least {min_exchanges} exchanges, got {len(exchanges)}"
        )
    n = next((len(e.arrivals) for e in exchanges if e.arrivals is not None), None)
    used = [e for e in exchanges if _usable(e, n)]
    if len(used) < min_exchanges:
        raise DetectionError(
            f"clock-rate estimation needs at least {min_exchanges} exchanges with every beep "
            f"detected, but only {len(used)} of {len(exchanges)} have them"
        )
    n = len(used[0].arrivals)
    t = [[a.onset_s for a in e.arrivals] for e in used]
    # Differences of arrivals through the same transducers: their delay cancels.
    v = [
        [np.maximum(a.sigma_relative / a.fs, _SIGMA_FLOOR_S) ** 2 for a in e.arrivals] for e in used
    ]
    t_own = np.array([tk[0][0] for tk in t])  # device 0's own beep, device 0's clock
    span = float(np.max(t_own) - np.min(t_own))
    if span < min_span_s:
        raise IncompatibleInputError(
            f"the {len(used)} usable exchanges span {span:.3f} s; clock-rate estimation "
            f"needs at least {min_span_s:g} s between the first and the last"
        )
    ppm, sigma = np.zeros(n), np.zeros(n)
    keep_all = np.ones(len(used), dtype=bool)
    for i in range(1, n):
        x = np.array([0.5 * (tk[0][0] + tk[0][i]) for tk in t])
        y = np.array([0.5 * (tk[i][0] + tk[i][i]) for tk in t])
        var = np.array([0.25 * (vk[0][0] + vk[0][i] + vk[i][0] + vk[i][i]) for vk in v])
        b, sb, keep = _fit_line(x, y - x, var)
        ppm[i], sigma[i] = 1e6 * b, 1e6 * sb
        keep_all &= keep
    span_used = float(np.ptp(t_own[keep_all])) if keep_all.any() else 0.0
    return ClockRates(ppm, sigma, int(keep_all.sum()), span_used, int((~keep_all).sum()))


def correct_clock(
    exchanges: Sequence[ExchangeRanges],
    rates: ClockRates,
    *,
    speed_m_s: float,
    self_distance_m: float | Sequence[float] = 0.0,
    clock_ppm: float | None = None,
) -> list[ExchangeRanges]:
    """Range every exchange again with each recording's intervals on device 0's clock.

    Parameters
    ----------
    exchanges : sequence of ExchangeRanges
        As for :func:`estimate_clock_rates`.
    rates : ClockRates
        One rate per device (:func:`estimate_clock_rates` or :meth:`ClockRates.known`).
    speed_m_s : float
        Speed of sound, m/s.
    self_distance_m : float or sequence of float
        Speaker-to-microphone distance of every device, or of each device.
    clock_ppm : float, optional
        Remaining 1-sigma clock tolerance for ``sigma_m`` (see ``range_beepbeep``);
        default the largest ``rates.sigma_ppm``.

    Returns
    -------
    list of ExchangeRanges
        Same exchanges, times and arrivals, with corrected ranges; exchanges that failed
        detection are returned unchanged.

    Raises
    ------
    IncompatibleInputError
        ``rates`` is for another number of devices, or an exchange carries no arrivals.
    """
    c = check_speed(speed_m_s)
    if clock_ppm is None:
        clock_ppm = float(np.max(rates.sigma_ppm)) if len(rates.sigma_ppm) else 0.0
    if not math.isfinite(clock_ppm):
        raise InvalidParameterError(f"clock_ppm={clock_ppm!r} must be finite")
    scale = 1.0 + np.asarray(rates.ppm, dtype=np.float64) * 1e-6
    out = []
    for ex in exchanges:
        if ex.error is not None:
            out.append(ex)
            continue
        if ex.arrivals is None:
            raise IncompatibleInputError(
                f"exchange {ex.exchange} at {ex.t_s:.3f} s carries no arrivals to correct"
            )
        if len(ex.arrivals) != len(scale):
            raise IncompatibleInputError(
                f"clock rates for {len(scale)} devices, but exchange {ex.exchange} has "
                f"{len(ex.arrivals)} recordings"
            )
        arr = [replace(a, fs=a.fs * s) for a, s in zip(ex.arrivals, scale, strict=True)]
        res = range_beepbeep(arr, speed_m_s=c, self_distance_m=self_distance_m, clock_ppm=clock_ppm)
        out.append(replace(ex, ranges=res.ranges))
    return out


def _n_devices(ex: ExchangeRanges) -> int:
    """Device count of an exchange: its recordings, or from its N (N - 1) / 2 pairs."""
    if ex.arrivals is not None:
        return len(ex.arrivals)
    return int(round(0.5 * (1.0 + math.sqrt(1.0 + 8.0 * len(ex.ranges)))))


def correct_series_clock(
    exchanges: Iterable[ExchangeRanges],
    *,
    speed_m_s: float,
    self_distance_m: float | Sequence[float] = 0.0,
    ppm: Sequence[float] | None = None,
    clock_ppm: float | None = None,
    min_exchanges: int = MIN_EXCHANGES,
    min_span_s: float = MIN_SPAN_S,
) -> tuple[list[ExchangeRanges], ClockRates]:
    """Collect a two-way series, estimate (or take) the clock rates, and correct it.

    What ``rangekit range --series --clock-rate`` does: every exchange must be read
    before the first corrected one is known, so the series is held in memory (its
    exchanges, not its audio).

    Parameters
    ----------
    exchanges : iterable of ExchangeRanges
        Typically :func:`~rangekit.ranging.series.range_series_beepbeep`'s iterator.
    speed_m_s : float
        Speed of sound, m/s.
    self_distance_m : float or sequence of float
        Speaker-to-microphone distance of every device, or of each device.
    ppm : sequence of float, optional
        Known clock rates (:meth:`ClockRates.known`: one per device, or one per device
        after device 0); None estimates them (:func:`estimate_clock_rates`).
    clock_ppm : float, optional
        Remaining 1-sigma clock tolerance (:func:`correct_clock`).
    min_exchanges, min_span_s
        As for :func:`estimate_clock_rates`.

    Returns
    -------
    exchanges : list of ExchangeRanges
        Corrected (:func:`correct_clock`).
    rates : ClockRates
        The rates applied.

    Raises
    ------
    IncompatibleInputError, DetectionError
        As :func:`estimate_clock_rates` and :meth:`ClockRates.known`.
    """
    exchanges = list(exchanges)
    if ppm is None:
        rates = estimate_clock_rates(exchanges, min_exchanges=min_exchanges, min_span_s=min_span_s)
    elif not exchanges:
        return [], ClockRates.known(ppm, len(np.atleast_1d(ppm)))
    else:
        rates = ClockRates.known(ppm, _n_devices(exchanges[0]))
    fixed = correct_clock(
        exchanges, rates, speed_m_s=speed_m_s, self_distance_m=self_distance_m, clock_ppm=clock_ppm
    )
    return fixed, rates
