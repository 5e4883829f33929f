"""Accuracy harness for one-way ultrasonic ranging against the Cramér–Rao bound.

Each trial hangs one transmitter on a ceiling and puts the robot (three receivers on a
0.19 m circle, Kim & Kim 2013 §II-B) at a random pose below it, so that every
Tx-receiver distance lies in ``distances_m`` (default 0.5-6 m): the distance ``D`` of the
robot's centre is drawn uniformly in ``[lo + r, hi - r]`` (``r`` the receiver radius, so
the triangle inequality keeps every receiver in range), the Tx-receiver height difference
uniformly in ``vertical_m`` (capped at ``D``), the azimuth and heading uniformly. One
activation window is rendered with :func:`rangekit.sim.ultrasonic.render_oneway` at
``snr_db`` (the in-band SNR of the trial's weakest receiver) and ranged with
:func:`rangekit.ranging.ultrasonic.range_oneway`.

Per receiver the row holds the error, the reported 1-sigma and two Cramér–Rao bounds
(:func:`rangekit.detect.matched.crb_delay_s`, converted to metres with ``c``) for the
noiseless received direct path (the drive through the Tx and Rx transducers, scaled by
``1 / d``) in the truth's white noise ``noise_sigma``:

* ``crb_m``: amplitude and carrier phase unknown (non-coherent), the bound the envelope
  peak estimator of :func:`rangekit.detect.matched.first_path` faces;
* ``crb_coh_m``: only the delay unknown (coherent, Gabor's bandwidth), for reference.

The bound scales as ``d * noise_sigma``, so it is computed once for a unit waveform.

Examples
--------
>>> rows = run_trials(n_trials=2, snr_db=20.0, rng=0)
>>> len(rows), rows[0]["channel"], bool(rows[0]["crb_coh_m"] < rows[0]["crb_m"])
(6, 0, True)
>>> s = summarize(rows)
>>> s["n"], s["misses"], s["outliers"], bool(s["rms_m"] < 3 * s["crb_rms_m"])
(6, 0, 0, True)
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from rangekit import _validate as V
from rangekit.detect.matched import crb_delay_s
from rangekit.errors import InvalidParameterError
from rangekit.physics import DEFAULT_TEMP_C, speed_of_sound_m_s
from rangekit.ranging.ultrasonic import range_oneway
from rangekit.signals.barker import CodedBurst, burst_waveform
from rangekit.signals.transducer import Transducer, apply_chain
from rangekit.sim.ultrasonic import R_RECEIVER_M, render_oneway

__all__ = [
    "DIRECT_TOL_M",
    "OUTLIER_CRB",
    "place_robot",
    "received_waveform",
    "run_trials",
    "summarize",
]

#: An error beyond this many (non-coherent) Cramér–Rao bounds is an outlier.
OUTLIER_CRB = 5.0
#: An estimate within this distance of the truth took the direct path (a reflection
#: 1 ms later lies 34 cm behind it).
DIRECT_TOL_M = 0.05
#: Fast overlap-save block for the short windows of the trials.
_BLOCK = 4096


def place_robot(
    *,
    rng: np.random.Generator,
    distances_m: tuple[float, float] = (0.5, 6.0),
    vertical_m: tuple[float, float] = (0.3, 3.0),
    ceiling_m: float = 3.0,
    radius_m: float = R_RECEIVER_M,
    area_m: float = 10.0,
) -> tuple[np.ndarray, np.ndarray, float]:
    """A ceiling Tx, a robot pose and the receivers' height, all Tx-receiver distances in range.

    Returns ``(tx_m, pose, receiver_height_m)``: the Tx at ``(x, y, ceiling_m)`` with
    ``x, y`` uniform in ``[0, area_m]``, the pose ``(x, y, heading)``.
    """
    lo, hi = (float(v) for v in distances_m)
    if not 0.0 < lo + radius_m < hi - radius_m:
        raise InvalidParameterError(
            f"distances_m={distances_m!r} must leave room for the receiver radius {radius_m} m"
        )
    d = rng.uniform(lo + radius_m, hi - radius_m)
    dz = rng.uniform(min(vertical_m[0], d), min(vertical_m[1], d))
    horiz = math.sqrt(max(d * d - dz * dz, 0.0))
    az, heading = rng.uniform(0.0, 2.0 * math.pi, size=2)
    tx = np.array([*rng.uniform(0.0, area_m, size=2), ceiling_m])
    pose = np.array([tx[0] + horiz * math.cos(az), tx[1] + horiz * math.sin(az), heading])
    return tx, pose, ceiling_m - dz


def received_waveform(
    burst: CodedBurst | None = None,
    *,
    fs: float = 192000.0,
    tx: Transducer | None = None,
    rx: Transducer | None = None,
    tail_s: float = 0.002,
) -> np.ndarray:
    """The noiseless direct path at 1 m as :func:`render_oneway` makes it.

    The drive at ``fs`` followed by ``tail_s`` of silence, through ``tx`` then ``rx``
    (default Q = 4 each); a receiver at ``d`` metres gets this divided by ``d``.
    """
    burst = CodedBurst(fs=fs) if burst is None else burst.with_fs(fs)
    tx = Transducer() if tx is None else tx
    rx = Transducer() if rx is None else rx
    drive = np.concatenate([burst_waveform(burst), np.zeros(int(tail_s * fs))])
    return apply_chain(drive, (tx, rx), fs=fs)


def run_trials(
    n_trials: int,
    *,
    snr_db: float,
    rng=None,
    distances_m: tuple[float, float] = (0.5, 6.0),
    vertical_m: tuple[float, float] = (0.3, 3.0),
    extra_paths: Sequence[tuple[float, float]] = (),
    max_range_m: float = 7.0,
    window_s: float | None = None,
    latency_s: float = 0.0,
    temp_c: float = DEFAULT_TEMP_C,
    fs: float = 192000.0,
    burst: CodedBurst | None = None,
    block: int = _BLOCK,
) -> list[dict]:
    """Run seeded one-way trials; one row per receiver per trial.

    Parameters
    ----------
    n_trials : int
        Number of trials (renders of one activation window each).
    snr_db : float
        In-band SNR of each trial's weakest receiver (:func:`render_oneway`).
    rng : seed or Generator
        Randomness for the geometry and the noise.
    distances_m : (float, float)
        Range of the Tx-receiver distances (default 0.5-6 m).
    vertical_m : (float, float)
        Range of the Tx-receiver height difference (capped at the robot's distance).
    extra_paths : sequence of (excess_delay_s, gain)
        Extra copies of the direct path (:func:`render_oneway`), e.g. ``[(1e-3, 2.0)]``.
    max_range_m : float
        The search range of :func:`range_oneway` (default 7 m).
    window_s : float, optional
        Length of the rendered window; default the search range's flight time plus 3 ms.
    latency_s, temp_c, fs, burst
        As :func:`render_oneway` (the latency is subtracted by :func:`range_oneway`).
    block : int
        Overlap-save FFT size of the matched filter.

    Returns
    -------
    list of dict
        Keys ``trial, channel, snr_db, true_m, distance_m, error_m, sigma_m, snr_out_db``
        (the detector's output SNR), ``snr_true_db`` (``10 log10(E / sigma^2)`` of the
        noiseless path), ``crb_m``, ``crb_coh_m``, ``missed``.
    """
    n_trials = V.positive_int("n_trials", n_trials)
    rng = np.random.default_rng(rng)
    fs = V.sample_rate(fs)
    burst = CodedBurst(fs=fs) if burst is None else burst.with_fs(fs)
    c = speed_of_sound_m_s(temp_c)
    max_range_m = V.positive("max_range_m", max_range_m)
    if window_s is None:
        window_s = latency_s + max_range_m / c + 0.003
    window_s = V.positive("window_s", window_s)
    unit = received_waveform(burst, fs=fs)
    crb_unit = c * crb_delay_s(unit, fs=fs, noise_sigma=1.0)
    crb_coh_unit = c * crb_delay_s(unit, fs=fs, noise_sigma=1.0, coherent=True)
    e_unit = float(unit @ unit)
    rows: list[dict] = []
    for trial in range(n_trials):
        txp, pose, rx_h = place_robot(rng=rng, distances_m=distances_m, vertical_m=vertical_m)
        sim = render_oneway(
            [txp],
            pose,
            fs=fs,
            burst=burst,
            period_s=window_s,
            latency_s=latency_s,
            temp_c=temp_c,
            snr_db=snr_db,
            receiver_height_m=rx_h,
            extra_paths=extra_paths,
            rng=rng,
        )
        res = range_oneway(
            sim.x,
            fs=fs,
            burst=burst,
            latency_s=latency_s,
            temp_c=temp_c,
            max_range_m=max_range_m,
            block=block,
        )
        true = np.asarray(sim.truth["windows"][0]["distances_m"])
        sigma = float(sim.truth["noise_sigma"])
        for r in res:
            d = float(true[r.channel])
            err = r.distance_m - d
            snr_true = 10.0 * math.log10(e_unit / (d * sigma) ** 2) if sigma > 0 else math.inf
            rows.append(
                {
                    "trial": trial,
                    "channel": r.channel,
                    "snr_db": snr_db,
                    "true_m": d,
                    "distance_m": r.distance_m,
                    "error_m": err,
                    "sigma_m": r.sigma_m,
                    "snr_out_db": r.snr_db,
                    "snr_true_db": snr_true,
                    "crb_m": crb_unit * sigma * d,
                    "crb_coh_m": crb_coh_unit * sigma * d,
                    "missed": not math.isfinite(err),
                }
            )
    return rows


def summarize(rows: Sequence[dict], *, outlier_crb: float = OUTLIER_CRB) -> dict:
    """RMS error against the bound, misses, outliers, coverage and direct-path rate.

    ``rms_m`` and ``crb_rms_m`` (and ``crb_coh_rms_m``) are over the inliers (detected,
    ``|error| <= outlier_crb * crb_m``); ``ratio = rms_m / crb_rms_m`` (1 for an efficient
    estimator); ``rms_all_m`` is over every detection. ``coverage_2sigma`` is the
    fraction of detections with ``|error| <= 2 sigma_m`` (0.954 for an honest Gaussian
    sigma). ``direct_rate`` is the fraction of all rows within :data:`DIRECT_TOL_M` of the
    truth (the direct path chosen, not a reflection).
    """
    if not rows:
        raise InvalidParameterError("no rows to summarize")
    err = np.array([r["error_m"] for r in rows], dtype=np.float64)
    crb = np.array([r["crb_m"] for r in rows], dtype=np.float64)
    crb_coh = np.array([r["crb_coh_m"] for r in rows], dtype=np.float64)
    sig = np.array([r["sigma_m"] for r in rows], dtype=np.float64)
    found = np.isfinite(err)
    a = np.where(found, np.abs(err), np.inf)
    inl = found & (a <= outlier_crb * crb)
    n = len(rows)

    def rms(v: np.ndarray) -> float:
        return float(np.sqrt(np.mean(v**2))) if len(v) else math.nan

    out = {
        "n": n,
        "misses": int(n - found.sum()),
        "outliers": int((found & ~inl).sum()),
        "rms_m": rms(err[inl]),
        "rms_all_m": rms(err[found]),
        "bias_m": float(np.mean(err[inl])) if inl.any() else math.nan,
        "crb_rms_m": rms(crb[inl]),
        "crb_coh_rms_m": rms(crb_coh[inl]),
        "coverage_2sigma": float(np.mean(a[found] <= 2.0 * sig[found])) if found.any() else 0.0,
        "direct_rate": float(np.mean(a < DIRECT_TOL_M)),
    }
    out["miss_rate"] = out["misses"] / n
    out["outlier_rate"] = out["outliers"] / n
    out["ratio"] = out["rms_m"] / out["crb_rms_m"] if inl.any() else math.nan
    return out
