"""Calibration of a device pair (two-way) or a link (one-way) from recordings at known distances.

Model
-----
Every scheme turns a measured time ``tau`` into a distance ``d = c tau + b``:

* two-way (BeepBeep, Peng et al. 2007; Jiang et al. 2018 §4.3): ``tau = ((t_a[b] - t_a[a])
  - (t_b[b] - t_b[a])) / 2`` and ``b = (s_a + s_b) / 2``, the mean speaker-to-microphone
  distance of the two devices (a length: it does not change with the temperature). Every
  latency cancels.
* one-way (Kim & Kim 2013 §II-A): ``tau`` is the arrival time from the trigger and ``b =
  -c L`` with ``L`` the system latency (trigger to emission: a time, so the offset is kept
  as ``latency_s``).

With recordings at **one** known distance ``D`` only the offset is fitted, with the speed
of sound ``c0`` from the air temperature (:func:`rangekit.physics.speed_of_sound_m_s`):
``b_i = D - c0 tau_i``, averaged. One distance is enough when the temperature is known to
a few degrees: an error ``dc`` in the speed of sound then gives ``dc / c * (d - D)`` at
distance ``d`` (0.18 % per degree: 1.8 mm per metre away from ``D`` per degree), and the
offset soaks up everything fixed (latency, speaker and microphone geometry, the
detector's and the probe's fixed delays).

With **two or more** distinct distances the effective speed is fitted too, by weighted
least squares of ``tau_i = (d_i - b) / c`` (the errors are in the measured times), which
absorbs a wrong temperature and any sample-clock scale common to the recordings.

Uncertainty: each recording's time carries its detection 1-sigma (Cramér–Rao) and a
placement tolerance ``tolerance_m / c0`` (how well the distance was measured, default
5 mm); the fit's covariance is scaled up by the reduced chi-square when the recordings
scatter more than that. Ranges after calibration carry the propagated variance
``c^2 s_tau^2 + tau^2 s_c^2 + s_b^2 + 2 tau cov(c, b)``.

Refusals (:class:`rangekit.errors.CalibrationError`, exit 7): fewer than
:data:`MIN_RECORDINGS` recordings for an offset, or fewer than
:data:`MIN_RECORDINGS_SPEED` for offset and speed; and recordings that disagree: each
recording is compared with the fit of all the others (leave-one-out); one more than
:data:`OUTLIER_SIGMA` of its predicted uncertainty away is named in the message.

Examples
--------
>>> m = [Measurement("r1.wav", 1.0, 0.0027, 1e-6), Measurement("r2.wav", 1.0, 0.0028, 1e-6),
...      Measurement("r3.wav", 1.0, 0.00275, 1e-6)]
>>> cal = fit_calibration(m, scheme="beepbeep", speed_m_s=343.0)
>>> cal.model, round(cal.offset_m, 5)
('offset', 0.05675)
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from rangekit import _validate as V
from rangekit.errors import CalibrationError, InputFileError, InvalidParameterError
from rangekit.types import Range, RangeResult

__all__ = [
    "CALIBRATION_SCHEMES",
    "MIN_RECORDINGS",
    "MIN_RECORDINGS_SPEED",
    "OUTLIER_SIGMA",
    "Calibration",
    "Measurement",
    "calibrate_recordings",
    "fit_calibration",
    "measure_recordings",
    "parse_recording",
    "read_calibration",
    "recording_paths",
]

#: Schemes a calibration applies to.
CALIBRATION_SCHEMES = ("beepbeep", "oneway")
#: Fewest recordings for an offset-only calibration (two cannot tell which one is wrong).
MIN_RECORDINGS = 3
#: Fewest recordings for an offset-and-speed calibration (two distinct distances).
MIN_RECORDINGS_SPEED = 4
#: A recording further than this many sigma from the fit of the others is refused.
OUTLIER_SIGMA = 4.0
#: Default placement tolerance of the known distances, m.
DEFAULT_TOLERANCE_M = 0.005
#: Format tag of calibration files.
FORMAT = "rangekit-calibration/1"


@dataclass(frozen=True)
class Measurement:
    """One calibration measurement: a recording's time at a known distance.

    Attributes
    ----------
    source : str
        Where it came from (file name, plus window/channel for one-way), for messages.
    distance_m : float
        The known distance, m.
    tau_s : float
        The measured time ``tau`` of the model ``d = c tau + b`` (see module docstring), s.
    sigma_s : float
        Its 1-sigma from the detection, s.
    """

    source: str
    distance_m: float
    tau_s: float
    sigma_s: float


@dataclass(frozen=True)
class Calibration:
    """A fitted calibration (``d = c tau + b``); see the module docstring.

    Attributes
    ----------
    scheme : str
        ``"beepbeep"`` or ``"oneway"``.
    model : str
        ``"offset"`` (speed of sound from the temperature when applied) or
        ``"offset+speed"`` (fitted speed).
    offset_m, sigma_offset_m : float
        ``b`` and its 1-sigma at the calibration's speed of sound, m.
    latency_s, sigma_latency_s : float
        ``-b / c`` and its 1-sigma, s (what a one-way offset-only calibration applies).
    speed_m_s, sigma_speed_m_s : float
        The speed of sound: fitted (``offset+speed``), or the one the offset was fitted
        with (``offset``; then ``sigma_speed_m_s`` is 0 and ranging uses its own).
    cov_speed_offset : float
        Covariance of the fitted speed and offset (0 for ``offset``).
    n_recordings : int
        Measurements used.
    distances_m : tuple of float
        The distinct known distances.
    rms_residual_m : float
        RMS of the measurements' residuals from the fit, m.
    residuals : tuple of dict
        Per measurement: ``source``, ``distance_m``, ``measured_m``, ``residual_m``.
    probe : str or None
        The probe the recordings were ranged with (None: the built-in beep or burst).
    """

    scheme: str
    model: str
    offset_m: float
    sigma_offset_m: float
    latency_s: float
    sigma_latency_s: float
    speed_m_s: float
    sigma_speed_m_s: float
    cov_speed_offset: float
    n_recordings: int
    distances_m: tuple[float, ...]
    rms_residual_m: float
    residuals: tuple[dict, ...] = field(default=(), repr=False)
    probe: str | None = None

    def check_scheme(self, scheme: str) -> None:
        """Raise unless this calibration was made for ``scheme``."""
        if scheme != self.scheme:
            raise InvalidParameterError(
                f"the calibration is for --scheme {self.scheme}, not {scheme}; calibrate with "
                f"recordings of the {scheme} scheme"
            )

    def distance(self, tau_s: float, sigma_s: float, *, speed_m_s: float) -> tuple[float, float]:
        """``(d, sigma_d)`` of a measured time; ``speed_m_s`` is used by offset-only models."""
        if self.model == "offset+speed":
            c, b = self.speed_m_s, self.offset_m
            d = c * tau_s + b
            var = (
                (c * sigma_s) ** 2
                + (tau_s * self.sigma_speed_m_s) ** 2
                + self.sigma_offset_m**2
                + 2.0 * tau_s * self.cov_speed_offset
            )
        elif self.scheme == "oneway":
            c = speed_m_s
            d = c * (tau_s - self.latency_s)
            var = c * c * (sigma_s**2 + self.sigma_latency_s**2)
        else:
            c = speed_m_s
            d = c * tau_s + self.offset_m
            var = (c * sigma_s) ** 2 + self.sigma_offset_m**2
        return float(d), float(math.sqrt(max(var, 0.0)))

    def apply(self, result: RangeResult) -> RangeResult:
        """The two-way ``result`` (ranged with zero self-distances) with this calibration."""
        ranges = self.apply_ranges(result.ranges, speed_m_s=result.speed_m_s)
        c = self.speed_m_s if self.model == "offset+speed" else result.speed_m_s
        return replace(result, ranges=ranges, speed_m_s=c)

    def apply_ranges(self, ranges: Sequence[Range], *, speed_m_s: float) -> tuple[Range, ...]:
        """Two-way ``ranges`` computed at ``speed_m_s`` with zero self-distances, calibrated.

        Ranges without a distance (NaN: a failed detection) pass unchanged.
        """
        self.check_scheme("beepbeep")
        c0 = speed_m_s
        out = []
        for r in ranges:
            if not math.isfinite(r.distance_m):
                out.append(r)
                continue
            d, s = self.distance(r.distance_m / c0, r.sigma_m / c0, speed_m_s=c0)
            flags = tuple(f for f in r.flags if f != "negative") + (("negative",) if d < 0 else ())
            out.append(Range(r.a, r.b, d, s, flags))
        return tuple(out)

    def to_dict(self) -> dict:
        """Plain-JSON form (what :meth:`write` stores)."""
        d = asdict(self)
        d["distances_m"] = list(self.distances_m)
        d["residuals"] = list(self.residuals)
        return {"format": FORMAT, **d}

    def write(self, path: str | os.PathLike) -> None:
        """Write the calibration as JSON, atomically (a temporary file renamed over it)."""
        from rangekit.io.sidecar import write_json

        write_json(path, self.to_dict())


def read_calibration(path: str | os.PathLike) -> Calibration:
    """Read a calibration written by :meth:`Calibration.write` (``rangekit calibrate``).

    Raises
    ------
    InputFileError
        The file is missing or not a rangekit calibration.
    """
    from pathlib import Path

    from rangekit.io.sidecar import read_json

    p = Path(path)
    obj = read_json(p)
    if not isinstance(obj, dict) or obj.get("format") != FORMAT:
        raise InputFileError(
            f'\'{p}\' is not a rangekit calibration (no "format": "{FORMAT}"; write one '
            "with `rangekit calibrate`)"
        )
    names = [f for f in Calibration.__dataclass_fields__]
    try:
        kw = {k: obj[k] for k in names if k in obj}
        kw["distances_m"] = tuple(float(v) for v in kw.get("distances_m", ()))
        kw["residuals"] = tuple(kw.get("residuals", ()))
        cal = Calibration(**kw)
        floats = (
            "offset_m",
            "sigma_offset_m",
            "latency_s",
            "sigma_latency_s",
            "speed_m_s",
            "sigma_speed_m_s",
            "cov_speed_offset",
        )
        for k in floats:
            v = getattr(cal, k)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise TypeError(f"{k}={v!r} must be a finite number")
        _check_ranges(cal)
        if cal.scheme not in CALIBRATION_SCHEMES or cal.model not in ("offset", "offset+speed"):
            raise TypeError(f"unknown scheme {cal.scheme!r} or model {cal.model!r}")
    except (TypeError, KeyError) as e:
        raise InputFileError(f"'{p}' is not a valid rangekit calibration: {e}") from None
    return cal


#: Bounds of a calibration's values checked by :func:`read_calibration` (the
#: physically plausible ones; a file outside them is refused, not applied).
CAL_LIMITS = {
    "speed_m_s": (200.0, 2000.0),
    "offset_m": (-100.0, 100.0),
    "sigma_offset_m": (0.0, 100.0),
    "latency_s": (-10.0, 10.0),
    "sigma_latency_s": (0.0, 10.0),
    "sigma_speed_m_s": (0.0, 1000.0),
}


def _check_ranges(cal: Calibration) -> None:
    """TypeError naming the first value of ``cal`` outside :data:`CAL_LIMITS`."""
    for k, (lo, hi) in CAL_LIMITS.items():
        v = getattr(cal, k)
        if not lo <= v <= hi:
            raise TypeError(f"{k}={v!r} must be within [{lo:g}, {hi:g}]")
    bound = cal.sigma_speed_m_s * cal.sigma_offset_m
    if abs(cal.cov_speed_offset) > bound * (1 + 1e-9) + 1e-300:
        raise TypeError(
            f"cov_speed_offset={cal.cov_speed_offset!r} exceeds sigma_speed_m_s x sigma_offset_m"
        )
    n = cal.n_recordings
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise TypeError(f"n_recordings={n!r} must be an integer >= 1")


def _offset_fit(d: np.ndarray, tau: np.ndarray, var: np.ndarray, c: float):
    """Weighted mean offset ``b = d - c tau``; returns (b, var_b, residuals, chi2_red)."""
    bi = d - c * tau
    w = 1.0 / (c * c * var)
    b = float(np.sum(w * bi) / np.sum(w))
    r = bi - b
    dof = len(d) - 1
    chi2 = float(np.sum(w * r * r) / dof) if dof > 0 else 1.0
    return b, max(1.0, chi2) / float(np.sum(w)), r, chi2


def _line_fit(d: np.ndarray, tau: np.ndarray, var: np.ndarray):
    """Weighted LS of ``tau = alpha d + beta``; returns (theta, cov, residuals_s, chi2_red)."""
    X = np.stack([d, np.ones_like(d)], axis=1)
    w = 1.0 / var
    A = X.T @ (X * w[:, None])
    theta = np.linalg.solve(A, X.T @ (w * tau))
    r = tau - X @ theta
    dof = len(d) - 2
    chi2 = float(np.sum(w * r * r) / dof) if dof > 0 else 1.0
    cov = np.linalg.inv(A) * max(1.0, chi2)
    return theta, cov, r, chi2


def fit_calibration(
    measurements: Sequence[Measurement],
    *,
    scheme: str,
    speed_m_s: float,
    fit_speed: bool | None = None,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    outlier_sigma: float = OUTLIER_SIGMA,
    probe: str | None = None,
) -> Calibration:
    """Fit the offset (one distance) or the offset and speed (several) of ``d = c tau + b``.

    Parameters
    ----------
    measurements : sequence of Measurement
        The recordings' times at their known distances.
    scheme : {"beepbeep", "oneway"}
        What the times are (module docstring).
    speed_m_s : float
        Speed of sound at the calibration (from the temperature), m/s.
    fit_speed : bool, optional
        Fit the speed too; default: when there are two or more distinct distances.
    tolerance_m : float
        How well the known distances are known (1-sigma placement), m (default 5 mm).
    outlier_sigma : float
        A measurement this many sigma from the leave-one-out fit is refused (default 4).
    probe : str, optional
        Name of the probe, stored for the record.

    Raises
    ------
    CalibrationError
        Too few measurements, or some disagree with the others (named in the message).
    """
    if scheme not in CALIBRATION_SCHEMES:
        raise InvalidParameterError(f"scheme={scheme!r} must be one of {CALIBRATION_SCHEMES}")
    c0 = V.in_range("speed_m_s", speed_m_s, 100.0, 2000.0)
    tol = V.positive("tolerance_m", tolerance_m, allow_zero=True)
    k = V.positive("outlier_sigma", outlier_sigma)
    ms = list(measurements)
    for m in ms:
        V.positive(f"distance_m of {m.source}", m.distance_m)
        if not (math.isfinite(m.tau_s) and math.isfinite(m.sigma_s)):
            raise CalibrationError(f"'{m.source}': no measurement (nothing was detected)")
    d = np.array([m.distance_m for m in ms], dtype=np.float64)
    distinct = sorted({round(float(v), 9) for v in d})
    speed = len(distinct) >= 2 if fit_speed is None else bool(fit_speed)
    need = MIN_RECORDINGS_SPEED if speed else MIN_RECORDINGS
    if speed and len(distinct) < 2:
        raise CalibrationError(
            "fitting the speed of sound needs recordings at two or more distinct distances; "
            f"all {len(ms)} are at {distinct[0] if distinct else '?'} m"
        )
    if len(ms) < need:
        what = "an offset and a speed" if speed else "an offset"
        names = ", ".join(f"'{m.source}'" for m in ms) or "none"
        raise CalibrationError(
            f"too few recordings to calibrate {what}: {len(ms)} given ({names}), at least "
            f"{need} needed (with fewer, a wrong one cannot be told from the others)"
        )
    tau = np.array([m.tau_s for m in ms], dtype=np.float64)
    var = np.array([m.sigma_s**2 for m in ms], dtype=np.float64) + (tol / c0) ** 2
    var = np.maximum(var, 1e-24)

    def loo_z(i: int) -> float:
        keep = np.arange(len(ms)) != i
        if speed:
            if len({round(float(v), 9) for v in d[keep]}) < 2:
                return 0.0  # the others cannot fit a line: no check from them
            th, cov, r, _ = _line_fit(d[keep], tau[keep], var[keep])
            x = np.array([d[i], 1.0])
            pred = float(x @ th)
            s2 = float(x @ cov @ x) + var[i] * max(1.0, _spread(r, var[keep], 2))
            return abs(tau[i] - pred) / math.sqrt(s2)
        b, vb, r, _ = _offset_fit(d[keep], tau[keep], var[keep], c0)
        s2 = vb + c0 * c0 * var[i] * max(1.0, _spread(r / c0, var[keep], 1))
        return abs(d[i] - c0 * tau[i] - b) / math.sqrt(s2)

    z = np.array([loo_z(i) for i in range(len(ms))])
    bad = np.flatnonzero(z > k)
    if len(bad):
        bad = bad[np.argsort(-z[bad])]
        listed = "; ".join(
            f"'{ms[i].source}' ({ms[i].distance_m:g} m: {z[i]:.1f} sigma off)" for i in bad
        )
        raise CalibrationError(
            f"recordings disagree beyond their uncertainty: {listed}, compared with the "
            f"others (limit {k:g} sigma, tolerance {tol * 100:g} cm); check their distances "
            "or leave them out"
        )
    if speed:
        th, cov, _, _ = _line_fit(d, tau, var)
        alpha, beta = float(th[0]), float(th[1])
        if alpha <= 0:
            raise CalibrationError("the fitted speed of sound is not positive; check the distances")
        c = 1.0 / alpha
        b = -beta / alpha
        J = np.array([[-1.0 / alpha**2, 0.0], [beta / alpha**2, -1.0 / alpha]])
        C = J @ cov @ J.T
        s_c, s_b, cov_cb = math.sqrt(C[0, 0]), math.sqrt(C[1, 1]), float(C[0, 1])
        lat, s_lat = beta, math.sqrt(cov[1, 1])  # -b / c = beta exactly
        model = "offset+speed"
        if not 100.0 <= c <= 2000.0:
            raise CalibrationError(
                f"the fitted speed of sound {c:.1f} m/s is implausible; check the distances"
            )
    else:
        b, vb, _, _ = _offset_fit(d, tau, var, c0)
        c, s_c, cov_cb = c0, 0.0, 0.0
        s_b = math.sqrt(vb)
        lat, s_lat = -b / c0, s_b / c0
        model = "offset"
    measured = c * tau + b
    residuals = tuple(
        {
            "source": m.source,
            "distance_m": float(m.distance_m),
            "measured_m": float(measured[i]),
            "residual_m": float(measured[i] - m.distance_m),
        }
        for i, m in enumerate(ms)
    )
    rms = float(np.sqrt(np.mean((measured - d) ** 2)))
    return Calibration(
        scheme=scheme,
        model=model,
        offset_m=float(b),
        sigma_offset_m=float(s_b),
        latency_s=float(lat),
        sigma_latency_s=float(s_lat),
        speed_m_s=float(c),
        sigma_speed_m_s=float(s_c),
        cov_speed_offset=cov_cb,
        n_recordings=len(ms),
        distances_m=tuple(float(v) for v in distinct),
        rms_residual_m=rms,
        residuals=residuals,
        probe=probe,
    )


def _spread(r: np.ndarray, var: np.ndarray, n_par: int) -> float:
    """Reduced chi-square of residuals ``r`` with variances ``var`` (1 if too few)."""
    dof = len(r) - n_par
    return float(np.sum(r * r / var) / dof) if dof > 0 else 1.0


def _split_recording(text: str) -> tuple[list[str], str | None]:
    """``PATH[+PATH][@M]`` -> (paths, the text after '@' or None); syntax only."""
    from pathlib import Path

    tail = None
    spec = text
    if not Path(text).exists() and "@" in text:
        spec, tail = text.rsplit("@", 1)
    return ([spec] if Path(spec).exists() else spec.split("+")), tail


def recording_paths(text: str) -> list[str]:
    """The files a recording spec (:func:`parse_recording`) names; its distance unchecked.

    Examples
    --------
    >>> recording_paths("dev0.wav+dev1.wav@2.5"), recording_paths("one.wav")
    (['dev0.wav', 'dev1.wav'], ['one.wav'])
    """
    return _split_recording(text)[0]


def parse_recording(text: str, default_m: float | None = None) -> tuple[list[str], float | None]:
    """A recording at a known distance, written ``PATH[+PATH][@M]`` (``rangekit calibrate``).

    ``PATH`` is one file, ``PATH+PATH`` the two devices' mono files (device 0 first); ``@M``
    gives its distance in metres (else ``default_m``, which may be None). A path that
    exists is never split, so files whose names hold ``+`` or ``@`` are read as they are.
    The result is one item of :func:`measure_recordings`' ``recordings``.

    Raises
    ------
    InvalidParameterError
        The text after ``@`` is not a number, or not a distance in (0, 10 km).

    Examples
    --------
    >>> parse_recording("dev0.wav+dev1.wav@2.5")
    (['dev0.wav', 'dev1.wav'], 2.5)
    >>> parse_recording("one.wav", 1.0), parse_recording("one.wav")
    ((['one.wav'], 1.0), (['one.wav'], None))
    >>> parse_recording("one.wav@-1")
    Traceback (most recent call last):
    ...
    rangekit.errors.InvalidParameterError: 'one.wav@-1': the distance must be positive, in metres
    """
    paths, tail = _split_recording(text)
    if tail is None:
        return paths, default_m
    try:
        dist = float(tail)
    except ValueError:
        raise InvalidParameterError(
            f"{text!r}: the distance after '@' must be a number of metres"
        ) from None
    if not (0.0 < dist < 1e4):
        raise InvalidParameterError(f"{text!r}: the distance must be positive, in metres")
    return paths, dist


def measure_recordings(
    recordings: Sequence[tuple[Sequence[str | os.PathLike], float]],
    *,
    scheme: str,
    probe=None,
    beep=None,
    detector: str = "changepoint",
    speed_m_s: float,
    **oneway_kw,
) -> list[Measurement]:
    """The calibration measurements of recordings at known distances.

    Parameters
    ----------
    recordings : sequence of (paths, distance_m)
        Each recording with its known distance (:func:`parse_recording` reads one from
        ``PATH[+PATH][@M]``). Two-way: one file with the two devices'
        channels, or the two devices' mono files (device 0 first). One-way: one file; every
        (window, channel) with an arrival is one measurement.
    scheme : {"beepbeep", "oneway"}
        The ranging scheme.
    probe : Probe, optional
        The signal played, if not the built-in beep (two-way) or burst (one-way).
    beep, detector
        Two-way without a probe: the beep and its detector.
    speed_m_s : float
        The speed of sound the times are converted with (only to undo the conversion).
    **oneway_kw
        One-way: keyword arguments of
        :func:`rangekit.ranging.ultrasonic.range_ultrasonic_files` (``burst``,
        ``period_s``, ``channels``, ...); ``latency_s`` must not be among them.

    Raises
    ------
    IncompatibleInputError
        A two-way recording does not hold exactly two devices.
    DetectionError
        Nothing was detected in a recording (its name is in the message).
    """
    from rangekit.errors import IncompatibleInputError
    from rangekit.io.audio import load_devices
    from rangekit.ranging.pipeline import range_channels
    from rangekit.ranging.ultrasonic import range_ultrasonic_files

    if scheme not in CALIBRATION_SCHEMES:
        raise InvalidParameterError(f"scheme={scheme!r} must be one of {CALIBRATION_SCHEMES}")
    c = V.in_range("speed_m_s", speed_m_s, 100.0, 2000.0)
    out: list[Measurement] = []
    for paths, dist in recordings:
        paths = [os.fspath(p) for p in paths]
        name = "+".join(paths)
        if scheme == "beepbeep":
            chans = load_devices(paths, min_devices=2)
            if len(chans) != 2:
                raise IncompatibleInputError(
                    f"'{name}' holds {len(chans)} devices; a calibration is for one pair of "
                    "devices (give a 2-channel file or two mono files)"
                )
            res = range_channels(
                chans, beep=beep, detector=detector, speed_m_s=c, clock_ppm=0.0, probe=probe
            )
            r = res.ranges[0]
            out.append(Measurement(name, float(dist), r.distance_m / c, r.sigma_m / c))
            continue
        if len(paths) != 1:
            raise IncompatibleInputError(f"'{name}': a one-way recording is one file")
        rows = range_ultrasonic_files(
            paths, scheme="oneway", probe=probe, speed_m_s=c, latency_s=0.0, **oneway_kw
        )
        for r in rows:
            if r["arrival_s"] is None:
                continue
            src = f"{name} (window {r['window']}, channel {r['channel']})"
            out.append(Measurement(src, float(dist), r["arrival_s"], r["sigma_m"] / c))
    return out


def calibrate_recordings(
    recordings: Sequence[tuple[Sequence[str | os.PathLike], float]],
    *,
    scheme: str = "beepbeep",
    speed_m_s: float,
    probe=None,
    beep=None,
    detector: str = "changepoint",
    setup=None,
    fit_speed: bool | None = None,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    progress=None,
) -> Calibration:
    """Measure recordings at known distances and fit their calibration: the whole job of
    ``rangekit calibrate`` (:func:`measure_recordings`, then :func:`fit_calibration`).

    Parameters
    ----------
    recordings : sequence of (paths, distance_m)
        As :func:`measure_recordings` (:func:`parse_recording` reads one item).
    scheme : {"beepbeep", "oneway", "echo"}
    speed_m_s : float
        The speed of sound the arrival times are converted with (and the fit's starting
        one when it fits the speed).
    probe : Probe, optional
        The played probe (a template), else the beep.
    beep, detector
        Two-way: the beep played and the detector (``probe`` None).
    setup : OneWaySetup or EchoSetup, optional
        One-way / echo: the job (default: the scheme's defaults,
        :func:`rangekit.ranging.ultrasonic_setup.ultrasonic_setup`). Its latency is left out:
        it is what a one-way calibration fits.
    fit_speed, tolerance_m
        As :func:`fit_calibration`.
    progress : callable, optional
        ``progress(done, total)`` after each recording is measured.

    Returns
    -------
    Calibration
        The fit; :class:`CalibrationError` (exit 7) when it is refused.
    """
    if scheme == "beepbeep":
        args: dict = {"beep": beep, "detector": detector}
    else:
        if setup is None:
            from rangekit.ranging.ultrasonic_setup import ultrasonic_setup

            setup = ultrasonic_setup(scheme)
        args = setup.kwargs()
        args.pop("latency_s", None)  # what the calibration fits
    meas: list[Measurement] = []
    for i, rec in enumerate(recordings):  # one at a time, for progress: the same result
        meas += measure_recordings([rec], scheme=scheme, probe=probe, speed_m_s=speed_m_s, **args)
        if progress is not None:
            progress(i + 1, len(recordings))
    return fit_calibration(
        meas,
        scheme=scheme,
        speed_m_s=speed_m_s,
        fit_speed=fit_speed,
        tolerance_m=tolerance_m,
        probe=None if probe is None else probe.name,
    )
