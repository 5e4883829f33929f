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

**Unknown transducers** (:func:`run_q_trials`, :func:`q_table`; ``python -m
rangekit.experiments.oneway_accuracy``): the same set-up with Tx and Rx transducers of a
given Q (4-20) that the ranging is not told (it fits them,
:mod:`rangekit.detect.pathfit`), optionally of another model than rangekit's resonator
(:class:`rangekit.signals.transducer.BandpassTransducer` of 4th and 6th order,
:class:`~rangekit.signals.transducer.CoupledTransducer`), a reflection stronger than the
direct path arriving 0.2-2 ms after it (a ceiling or floor bounce), and several
activation windows per trial (a robot at rest hearing the same Tx in turn), so that the
per-receiver pooling of the transducer estimate is exercised. The bound reported there is
the known-transducer Cramér-Rao bound of the true received waveform.

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
from rangekit.detect.fitted import TRANSDUCER_FAMILIES
from rangekit.detect.matched import crb_delay_s
from rangekit.errors import InvalidParameterError
from rangekit.physics import DEFAULT_TEMP_C, speed_of_sound_m_s
from rangekit.ranging.ultrasonic import range_oneway
from rangekit.signals.barker import CodedBurst, burst_waveform
from rangekit.signals.transducer import (
    BandpassTransducer,
    CoupledTransducer,
    Transducer,
    apply_chain,
)
from rangekit.sim.ultrasonic import R_RECEIVER_M, render_oneway

__all__ = [
    "DIRECT_TOL_M",
    "OUTLIER_CRB",
    "TRANSDUCER_MODELS",
    "calibrated_spread",
    "make_transducer",
    "place_robot",
    "q_table",
    "received_waveform",
    "render_room_oneway",
    "run_q_trials",
    "run_room_trials",
    "run_trials",
    "summarize",
    "summarize_q",
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
    fit_transducers: bool = False,
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
    fit_transducers : bool
        Range with the transducer fit (:func:`range_oneway`'s default) instead of the
        known Q = 4 template (default False: this harness measures the known-transducer
        estimator against its bound; :func:`run_q_trials` the unknown-transducer one).

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
            fit_transducers=fit_transducers,
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


#: Transducer models of :func:`make_transducer`.
TRANSDUCER_MODELS = ("resonator", "bandpass", "coupled", "bandpass6")


def make_transducer(model: str, q: float, *, f0_hz: float = 40000.0):
    """A transducer of ``model`` (:data:`TRANSDUCER_MODELS`) with quality factor ``q``.

    ``"resonator"``: rangekit's second-order resonator (the estimator's first model, Q
    unknown to it); ``"bandpass"``: a 4th-order Butterworth band-pass with the same -3 dB
    band; ``"coupled"``: two resonators of Q ``q`` stagger-tuned half a band either side
    (both inside the estimator's second model, :mod:`rangekit.detect.stagger`, with their
    parameters unknown to it); ``"bandpass6"``: a 6th-order Butterworth band-pass (three
    pole pairs per element: outside both models, the check beyond them).
    """
    if model == "resonator":
        return Transducer(f0_hz, q)
    if model == "bandpass":
        return BandpassTransducer(f0_hz, q)
    if model == "coupled":
        return CoupledTransducer(f0_hz, q)
    if model == "bandpass6":
        return BandpassTransducer(f0_hz, q, order=3)
    raise InvalidParameterError(f"model={model!r} must be one of {', '.join(TRANSDUCER_MODELS)}")


def run_q_trials(
    n_trials: int,
    *,
    snr_db: float,
    q: float,
    model: str = "resonator",
    rx_q: float | None = None,
    rng=None,
    n_windows: int = 10,
    reflection_s: tuple[float, float] | None = (0.2e-3, 2.0e-3),
    reflection_gain: float = 1.5,
    distances_m: tuple[float, float] = (0.5, 6.0),
    vertical_m: tuple[float, float] = (0.3, 3.0),
    max_range_m: float = 7.0,
    temp_c: float = DEFAULT_TEMP_C,
    fs: float = 192000.0,
    burst: CodedBurst | None = None,
    fit_transducers: bool = True,
    pool: bool = True,
    block: int = _BLOCK,
    transducer_family: str = "resonator",
) -> list[dict]:
    """Seeded one-way trials through transducers the ranging does not know.

    Each trial places the robot as :func:`run_trials` does, draws one reflection (delay
    uniform in ``reflection_s`` after the direct path, amplitude ``reflection_gain``
    times the direct path's, the same at every receiver), renders ``n_windows``
    activation windows of the one Tx (:func:`render_oneway`, Tx and Rx transducers
    ``make_transducer(model, q)``; ``rx_q`` gives the Rx another Q) and ranges them with
    :func:`range_oneway` as a user would (default Q = 4 starting point, the transducer
    fit, pooling over the windows of each receiver; ``transducer_family`` as there).

    Returns
    -------
    list of dict
        One row per (trial, window, receiver): keys ``trial, window, channel, q, model,
        snr_db, reflection_s, true_m, distance_m, error_m, sigma_m, snr_out_db, crb_m``
        (the known-transducer bound of the true received waveform), ``flags`` (tuple of
        str), ``missed``.
    """
    n_trials = V.positive_int("n_trials", n_trials)
    n_windows = V.positive_int("n_windows", n_windows)
    rng = np.random.default_rng(rng)
    fs = V.sample_rate(fs)
    burst = CodedBurst(fs=fs) if burst is None else burst.with_fs(fs)
    c = speed_of_sound_m_s(temp_c)
    tx = make_transducer(model, q)
    rx = tx if rx_q is None else make_transducer(model, rx_q)
    window_s = max_range_m / c + 0.003
    unit = received_waveform(burst, fs=fs, tx=tx, rx=rx, tail_s=0.004)
    crb_unit = c * crb_delay_s(unit, fs=fs, noise_sigma=1.0)
    rows: list[dict] = []
    for trial in range(n_trials):
        txp, pose, rx_h = place_robot(rng=rng, distances_m=distances_m, vertical_m=vertical_m)
        extra: list[tuple[float, float]] = []
        dt = math.nan
        if reflection_s is not None:
            dt = float(rng.uniform(*reflection_s))
            extra = [(dt, float(reflection_gain))]
        sim = render_oneway(
            [txp],
            pose,
            fs=fs,
            burst=burst,
            tx=tx,
            rx=rx,
            order=[0],
            n_windows=n_windows,
            period_s=window_s,
            temp_c=temp_c,
            snr_db=snr_db,
            receiver_height_m=rx_h,
            extra_paths=extra,
            rng=rng,
        )
        res = range_oneway(
            sim.x,
            fs=fs,
            burst=burst,
            temp_c=temp_c,
            period_s=window_s,
            tx_ids=[0],
            max_range_m=max_range_m,
            block=block,
            fit_transducers=fit_transducers,
            pool=pool,
            transducer_family=transducer_family,
        )
        sigma = float(sim.truth["noise_sigma"])
        for r in res:
            d = float(sim.truth["windows"][r.window]["distances_m"][r.channel])
            rows.append(_q_row(trial, r, q, model, snr_db, dt, d, crb_unit * sigma * d))
    return rows


def _q_row(trial, r, q, model, snr_db, reflection_s, true_m, crb_m) -> dict:
    """One row of :func:`run_q_trials` / :func:`run_room_trials` from a ``ToF``."""
    err = r.distance_m - true_m
    return {
        "trial": trial,
        "window": r.window,
        "channel": r.channel,
        "q": float(q),
        "model": model,
        "snr_db": snr_db,
        "reflection_s": reflection_s,
        "true_m": true_m,
        "distance_m": r.distance_m,
        "error_m": err,
        "sigma_m": r.sigma_m,
        "snr_out_db": r.snr_db,
        "crb_m": crb_m,
        "flags": r.flags,
        "sigma_transducer_m": r.sigma_transducer_m,
        "missed": not math.isfinite(err),
    }


def summarize_q(rows: Sequence[dict], *, gross_m: float = 0.02) -> dict:
    """Error statistics of :func:`run_q_trials` rows (one condition).

    ``rms_m``, ``bias_m``, ``sd_m`` are over the detections within ``gross_m`` (2 cm) of
    the truth; ``gross`` counts the others (a reflection or a side lobe taken, a fit
    gone astray), ``gross_unflagged`` those without any flag. ``crb_rms_m`` is the
    known-transducer bound over the same rows, ``coverage_2sigma`` the fraction of all
    detections with ``|error| <= 2 sigma_m``; ``flag_rates`` the fraction of detections
    carrying each flag. ``wrong_unflagged`` counts the gross errors that are unflagged and
    beyond 2 sigma (confidently wrong), ``order_rate`` the fraction of detections whose
    sigma holds the transducer model-order term (:func:`rangekit.detect.fitted.
    order_terms`), ``median_m`` the median error of all detections, ``median_z`` the
    median of ``|error| / sigma_m`` over them (0.67 for an honest Gaussian sigma; below:
    over-cautious).
    """
    if not rows:
        raise InvalidParameterError("no rows to summarize")
    err = np.array([r["error_m"] for r in rows], dtype=np.float64)
    sig = np.array([r["sigma_m"] for r in rows], dtype=np.float64)
    crb = np.array([r["crb_m"] for r in rows], dtype=np.float64)
    found = np.isfinite(err)
    a = np.where(found, np.abs(err), np.inf)
    inl = found & (a <= gross_m)
    flagged = np.array([bool(r["flags"]) for r in rows])
    order = np.array([r.get("sigma_transducer_m", 0.0) > 0 for r in rows])
    names = sorted({f for r in rows for f in r["flags"]})
    n_found = max(int(found.sum()), 1)
    return {
        "n": len(rows),
        "misses": int((~found).sum()),
        "gross": int((found & ~inl).sum()),
        "gross_unflagged": int((found & ~inl & ~flagged).sum()),
        "wrong_unflagged": int((found & ~inl & ~flagged & (a > 2.0 * sig)).sum()),
        "order_rate": float(np.mean(order[found])) if found.any() else 0.0,
        "median_m": float(np.median(err[found])) if found.any() else math.nan,
        "median_z": float(np.median(a[found] / sig[found])) if found.any() else math.nan,
        "rms_m": float(np.sqrt(np.mean(err[inl] ** 2))) if inl.any() else math.nan,
        "bias_m": float(np.mean(err[inl])) if inl.any() else math.nan,
        "bias_se_m": float(np.std(err[inl]) / math.sqrt(inl.sum())) if inl.sum() > 1 else math.nan,
        "sd_m": float(np.std(err[inl])) if inl.any() else math.nan,
        "crb_rms_m": float(np.sqrt(np.mean(crb[inl] ** 2))) if inl.any() else math.nan,
        "sigma_rms_m": float(np.sqrt(np.mean(sig[inl] ** 2))) if inl.any() else math.nan,
        "coverage_2sigma": float(np.mean(a[found] <= 2.0 * sig[found])) if found.any() else 0.0,
        "flag_rates": {
            k: sum(k in r["flags"] for r, f in zip(rows, found, strict=True) if f) / n_found
            for k in names
        },
    }


def calibrated_spread(summaries: dict, *, at_q: float) -> dict:
    """Residual bias per Q after a one-point calibration at ``at_q``.

    ``summaries`` maps Q to :func:`summarize_q` output (one SNR, one model). A one-point
    calibration at a known distance fixes the one-way offset ``b`` of ``d = c tau + b``
    (:mod:`rangekit.ranging.calibration`), i.e. it removes the bias at ``at_q``; ranges
    with transducers of another Q keep ``bias(Q) - bias(at_q)``. Returns those residuals
    (m) and their largest magnitude and spread (``max - min``) over Q.
    """
    b0 = summaries[at_q]["bias_m"]
    res = {q: s["bias_m"] - b0 for q, s in summaries.items()}
    vals = np.array(list(res.values()))
    return {
        "residual_m": res,
        "max_abs_m": float(np.max(np.abs(vals))),
        "spread_m": float(vals.max() - vals.min()),
    }


def q_table(
    *,
    qs: Sequence[float] = (4.0, 8.0, 12.0, 16.0, 20.0),
    snrs: Sequence[float] = (20.0, 10.0, 0.0),
    model: str = "resonator",
    n_trials: int = 60,
    n_windows: int = 10,
    seed: int = 2026,
    **kw,
) -> list[dict]:
    """One :func:`summarize_q` row per (SNR, Q), each with its own seed; keys added:
    ``snr_db, q, model``."""
    out = []
    for snr in snrs:
        for q in qs:
            rows = run_q_trials(
                n_trials,
                snr_db=snr,
                q=q,
                model=model,
                n_windows=n_windows,
                rng=[seed, int(round(10 * snr)) % 1000, int(round(10 * q))],
                **kw,
            )
            out.append({"snr_db": snr, "q": q, "model": model, **summarize_q(rows)})
    return out


def render_room_oneway(
    *,
    q: float,
    rng,
    room_m: tuple[float, float, float] = (5.0, 4.0, 3.0),
    absorption: float = 0.3,
    max_order: int = 3,
    n_windows: int = 6,
    snr_db: float | None = 20.0,
    fs: float = 192000.0,
    temp_c: float = DEFAULT_TEMP_C,
    max_range_m: float = 7.0,
    burst: CodedBurst | None = None,
    model: str = "resonator",
) -> tuple[np.ndarray, dict]:
    """One-way windows of a ceiling Tx heard by three receivers in a pyroomacoustics room.

    The room (image sources to ``max_order``, energy absorption ``absorption`` on every
    surface, no air absorption: pyroomacoustics tabulates it only up to 8 kHz) is
    simulated at ``fs`` by pyroomacoustics (an optional dependency), independently of
    rangekit's own simulator; the Tx hangs 0.1 m below the ceiling, the robot's receivers
    (0.19 m circle) stand 0.3-1.0 m high, all at least 0.3 m from the walls. The source
    signal is the drive through the Tx transducer, each receiver's signal passes the Rx
    transducer; white noise at ``snr_db`` in-band (rangekit's one-way definition,
    :func:`render_oneway`) for the weakest direct path (its gain measured on the anechoic
    response).
    The same room response is placed at the start of each of ``n_windows`` windows (a
    robot at rest), each with its own noise.

    pyroomacoustics delays every impulse response by ``frac_delay_length // 2`` samples
    (40 at its default 81-tap fractional-delay filter; the direct path of a source at
    distance ``d`` is at ``40 + d / c * fs``): that many samples are dropped from the
    start of the simulated signals, so that sample 0 is the drive's start, as
    :func:`range_oneway` expects (tested against the anechoic room).

    Returns
    -------
    (ndarray, dict)
        The recording ``(3, n_windows * window)`` and the truth: ``window_s``,
        ``distances_m`` (per receiver), ``direct_gain`` (per receiver), ``noise_sigma``,
        ``speed_of_sound_m_s``.
    """
    import pyroomacoustics as pra
    from scipy.signal import oaconvolve

    rng = np.random.default_rng(rng)
    fs = V.sample_rate(fs)
    burst = CodedBurst(fs=fs) if burst is None else burst.with_fs(fs)
    c = speed_of_sound_m_s(temp_c)
    size = np.asarray(room_m, dtype=np.float64)
    margin = 0.3 + R_RECEIVER_M
    txp = np.array([*rng.uniform(0.3, size[:2] - 0.3), size[2] - 0.1])
    centre = rng.uniform(margin, size[:2] - margin)
    h = float(rng.uniform(0.3, 1.0))
    a = float(rng.uniform(0.0, 2.0 * math.pi)) + 2.0 * math.pi * np.arange(3) / 3
    rxp = np.stack(
        [centre[0] + R_RECEIVER_M * np.cos(a), centre[1] + R_RECEIVER_M * np.sin(a), [h] * 3],
        axis=1,
    )
    tx = make_transducer(model, q)
    rirs = []
    for order in (max_order, 0):  # the room, and the direct paths alone (their gains)
        pr = pra.ShoeBox(
            size,
            fs=int(fs),
            materials=pra.Material(energy_absorption=absorption),
            max_order=order,
            air_absorption=False,
        )
        pr.set_sound_speed(c)
        pr.add_source(txp)
        pr.add_microphone_array(rxp.T)
        pr.compute_rir()
        rirs.append([pr.rir[m][0] for m in range(3)])
    # pyroomacoustics' direct-path gain (its own spreading convention) at the carrier:
    # the anechoic response's gain there (its DC gain differs by ~30 %).
    ph = np.exp(-2j * math.pi * burst.carrier_hz / fs * np.arange(max(len(r) for r in rirs[1])))
    g_direct = np.array([float(abs(r @ ph[: len(r)])) for r in rirs[1]])
    pra_delay = int(pra.constants.get("frac_delay_length") // 2)
    src = tx.apply(np.concatenate([burst_waveform(burst), np.zeros(int(0.004 * fs))]), fs=fs)
    win = int(round((max_range_m / c + 0.003) * fs))
    n = n_windows * win
    x = np.zeros((3, n))
    for m in range(3):
        y = tx.apply(oaconvolve(src, rirs[0][m])[pra_delay : pra_delay + win], fs=fs)
        for w in range(n_windows):
            x[m, w * win : w * win + len(y)] = y
    d = np.linalg.norm(rxp - txp, axis=1)
    unit = received_waveform(burst, fs=fs, tx=tx, rx=tx, tail_s=0.004)
    e_weak = float(unit @ unit) * float(g_direct.min()) ** 2
    sigma = 0.0
    if snr_db is not None:
        b_hz = burst.band_hz[1] - burst.band_hz[0]
        sigma = math.sqrt(e_weak / (2.0 * burst.duration_s * b_hz * 10.0 ** (snr_db / 10.0)))
        x = x + sigma * rng.standard_normal(x.shape)
    truth = {
        "window_s": win / fs,
        "distances_m": d.tolist(),
        "direct_gain": g_direct.tolist(),
        "noise_sigma": sigma,
        "speed_of_sound_m_s": c,
        "tx_m": txp.tolist(),
        "receivers_m": rxp.tolist(),
    }
    return x, truth


def run_room_trials(
    n_trials: int,
    *,
    snr_db: float,
    qs: tuple[float, float] = (4.0, 20.0),
    rng=None,
    n_windows: int = 6,
    transducer_family: str = "resonator",
    **kw,
) -> list[dict]:
    """Seeded pyroomacoustics one-way trials (:func:`render_room_oneway`), Q drawn
    log-uniformly in ``qs`` per trial (Tx and Rx alike), ranged by :func:`range_oneway`
    with its defaults (``transducer_family`` as there). Rows as :func:`run_q_trials`
    (``crb_m`` of the direct path)."""
    n_trials = V.positive_int("n_trials", n_trials)
    rng = np.random.default_rng(rng)
    rows: list[dict] = []
    for trial in range(n_trials):
        q = float(math.exp(rng.uniform(math.log(qs[0]), math.log(qs[1]))))
        x, truth = render_room_oneway(q=q, rng=rng, n_windows=n_windows, snr_db=snr_db, **kw)
        fs = float(kw.get("fs", 192000.0))
        c = truth["speed_of_sound_m_s"]
        res = range_oneway(
            x, fs=fs, speed_m_s=c, period_s=truth["window_s"], tx_ids=[0], max_range_m=7.0,
            transducer_family=transducer_family,
        )  # fmt: skip
        tx = make_transducer(kw.get("model", "resonator"), q)
        unit = received_waveform(fs=fs, tx=tx, rx=tx, tail_s=0.004)
        crb_unit = c * crb_delay_s(unit, fs=fs, noise_sigma=1.0)
        for r in res:
            d = truth["distances_m"][r.channel]
            crb = crb_unit * truth["noise_sigma"] / truth["direct_gain"][r.channel]
            rows.append(_q_row(trial, r, q, kw.get("model", "resonator"), snr_db, math.nan, d, crb))
    return rows


def _markdown(table: list[dict], *, at_q: float, median_z: bool = False) -> str:
    """The table; ``median_z`` adds the column ``median |err|/sigma`` after ``within 2
    sigma`` (given with ``--transducer-family``: the default table stays as it was)."""
    z_head, z_rule = (" | median abs err/sigma", "---|") if median_z else ("", "")
    lines = [
        "| SNR dB | Q | RMS mm | bias mm | median mm | known-Q CRB mm | sigma mm "
        f"| within 2 sigma{z_head} | gross (unflagged, of them beyond 2 sigma) | order term "
        "| flags |",
        f"|---|---|---|---|---|---|---|---|{z_rule}---|---|---|",
    ]
    for r in table:
        fl = ", ".join(f"{k} {100 * v:.0f} %" for k, v in r["flag_rates"].items() if v > 0)
        z = f" {r['median_z']:.2f} |" if median_z else ""
        lines.append(
            f"| {r['snr_db']:g} | {r['q']:g} | {1e3 * r['rms_m']:.2f} | "
            f"{1e3 * r['bias_m']:+.2f} | {1e3 * r['median_m']:+.2f} | "
            f"{1e3 * r['crb_rms_m']:.2f} | {1e3 * r['sigma_rms_m']:.2f} | "
            f"{100 * r['coverage_2sigma']:.1f} % |{z} {r['gross']}/{r['n']} "
            f"({r['gross_unflagged']}, {r['wrong_unflagged']}) | "
            f"{100 * r['order_rate']:.0f} % | {fl or '-'} |"
        )
    for snr in sorted({r["snr_db"] for r in table}, reverse=True):
        sub = {r["q"]: r for r in table if r["snr_db"] == snr}
        if at_q in sub:
            sp = calibrated_spread(sub, at_q=at_q)
            res = ", ".join(f"Q {q:g}: {1e3 * v:+.2f}" for q, v in sp["residual_m"].items())
            lines.append("")
            lines.append(
                f"{snr:g} dB, calibrated at Q {at_q:g}: residual bias mm {res} "
                f"(largest {1e3 * sp['max_abs_m']:.2f}, spread {1e3 * sp['spread_m']:.2f})"
            )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m rangekit.experiments.oneway_accuracy``: the unknown-transducer table."""
    import argparse

    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("--model", choices=TRANSDUCER_MODELS, default="resonator")
    ap.add_argument("--q", default="4,8,12,16,20", help="comma-separated Q values")
    ap.add_argument("--snr", default="20,10,0", help="comma-separated in-band SNRs, dB")
    ap.add_argument("--trials", type=int, default=60)
    ap.add_argument("--windows", type=int, default=10)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--calibrate-at", type=float, default=12.0, help="Q of the calibration")
    ap.add_argument("--no-reflection", action="store_true")
    ap.add_argument("--no-pool", action="store_true")
    ap.add_argument(
        "--transducer-family",
        choices=TRANSDUCER_FAMILIES,
        default=None,
        help="what the ranging is told of the transducers' family (range_oneway's "
        "transducer_family) [default: resonator]; given, the table gains the column "
        "median abs err/sigma",
    )
    a = ap.parse_args(argv)
    fam = {} if a.transducer_family is None else {"transducer_family": a.transducer_family}
    qs = [float(v) for v in a.q.split(",")]
    table = q_table(
        qs=qs,
        snrs=[float(v) for v in a.snr.split(",")],
        model=a.model,
        n_trials=a.trials,
        n_windows=a.windows,
        seed=a.seed,
        reflection_s=None if a.no_reflection else (0.2e-3, 2.0e-3),
        pool=not a.no_pool,
        **fam,
    )
    at_q = a.calibrate_at if a.calibrate_at in qs else qs[0]
    print(_markdown(table, at_q=at_q, median_z=a.transducer_family is not None))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
