"""Calibration fit against closed forms, its refusals at their limits, its file checks.

No audio: :class:`Measurement` values are built directly, so these run in milliseconds.
Written against the mutants of ``rangekit/ranging/calibration.py`` that the acceptance
and CLI tests let through (``benchmarks/mutation.py``, docs/evidence.md); each test
states the property of the module docstring it checks.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from rangekit.errors import CalibrationError, InputFileError, InvalidParameterError
from rangekit.ranging.calibration import (
    DEFAULT_TOLERANCE_M,
    MIN_RECORDINGS,
    MIN_RECORDINGS_SPEED,
    OUTLIER_SIGMA,
    Calibration,
    Measurement,
    fit_calibration,
    read_calibration,
)
from rangekit.types import Range, RangeResult

C0 = 343.0


def _m(d, tau, sigma=1e-6, name=None):
    return Measurement(name or f"r{d}-{tau}", float(d), float(tau), float(sigma))


def _line(ds, c=340.0, b=0.05, jitter=(), sigma=2e-6):
    """Exact times of d = c tau + b (plus optional jitter in s)."""
    j = list(jitter) + [0.0] * (len(ds) - len(jitter))
    return [
        _m(d, (d - b) / c + e, sigma, f"r{i}") for i, (d, e) in enumerate(zip(ds, j, strict=False))
    ]


# --------------------------------------------------------------------------- offset only
def test_offset_is_the_inverse_variance_weighted_mean():
    """b = sum(w_i (D - c tau_i)) / sum(w_i), w_i = 1 / (sigma_i^2 + (tol / c)^2)."""
    sig = np.array([1e-6, 3e-6, 2e-6, 5e-6])
    tau = np.array([2.70e-3, 2.73e-3, 2.715e-3, 2.685e-3])
    ms = [_m(1.5, t, s) for t, s in zip(tau, sig, strict=False)]
    cal = fit_calibration(ms, scheme="beepbeep", speed_m_s=C0)
    var = sig**2 + (DEFAULT_TOLERANCE_M / C0) ** 2
    w = 1.0 / (C0 * C0 * var)
    bi = 1.5 - C0 * tau
    b = np.sum(w * bi) / np.sum(w)
    chi2 = np.sum(w * (bi - b) ** 2) / (len(ms) - 1)
    assert cal.model == "offset" and cal.scheme == "beepbeep"
    assert cal.offset_m == pytest.approx(b, rel=1e-12)
    assert cal.sigma_offset_m == pytest.approx(math.sqrt(max(1.0, chi2) / np.sum(w)), rel=1e-12)
    assert chi2 > 1.0  # these times scatter more than their sigmas: the sigma grows
    assert cal.latency_s == pytest.approx(-b / C0, rel=1e-12)
    assert cal.sigma_latency_s == pytest.approx(cal.sigma_offset_m / C0, rel=1e-12)
    assert (cal.speed_m_s, cal.sigma_speed_m_s, cal.cov_speed_offset) == (C0, 0.0, 0.0)
    assert cal.n_recordings == 4 and cal.distances_m == (1.5,)
    res = np.array([r["residual_m"] for r in cal.residuals])
    np.testing.assert_allclose(res, C0 * tau + b - 1.5, rtol=1e-12, atol=1e-15)
    assert cal.rms_residual_m == pytest.approx(math.sqrt(np.mean(res**2)), rel=1e-12)
    assert [r["source"] for r in cal.residuals] == [m.source for m in ms]
    assert all(r["distance_m"] == 1.5 for r in cal.residuals)


def test_consistent_times_keep_the_predicted_sigma():
    """No scatter (chi2 < 1): sigma_b is the prediction, tolerance / sqrt(n) here."""
    ms = [_m(2.0, 5.8e-3, 0.0, f"r{i}") for i in range(4)]
    for tol in (0.005, 0.01):
        cal = fit_calibration(ms, scheme="oneway", speed_m_s=C0, tolerance_m=tol)
        assert cal.sigma_offset_m == pytest.approx(tol / 2.0, rel=1e-12)
        assert cal.offset_m == pytest.approx(2.0 - C0 * 5.8e-3, rel=1e-12)
        assert cal.latency_s == pytest.approx(-(2.0 - C0 * 5.8e-3) / C0, rel=1e-12)


def test_distance_of_each_model():
    """d = c tau + b and its propagated sigma, per model (module docstring)."""
    off = Calibration("beepbeep", "offset", 0.05, 0.002, -0.05 / C0, 0.002 / C0, C0, 0.0, 0.0,
                      3, (1.0,), 0.0)  # fmt: skip
    d, s = off.distance(0.01, 1e-5, speed_m_s=340.0)  # offset: the given speed
    assert d == pytest.approx(340.0 * 0.01 + 0.05)
    assert s == pytest.approx(math.hypot(340.0 * 1e-5, 0.002))
    one = dataclasses.replace(off, scheme="oneway", latency_s=1e-3, sigma_latency_s=2e-5)
    d, s = one.distance(0.01, 1e-5, speed_m_s=340.0)  # one-way: latency as a time
    assert d == pytest.approx(340.0 * (0.01 - 1e-3))
    assert s == pytest.approx(340.0 * math.hypot(1e-5, 2e-5))
    line = dataclasses.replace(off, model="offset+speed", speed_m_s=338.0, sigma_speed_m_s=0.5,
                               cov_speed_offset=-4e-4)  # fmt: skip
    d, s = line.distance(0.01, 1e-5, speed_m_s=999.0)  # fitted speed, not the given one
    assert d == pytest.approx(338.0 * 0.01 + 0.05)
    var = (338.0 * 1e-5) ** 2 + (0.01 * 0.5) ** 2 + 0.002**2 + 2 * 0.01 * -4e-4
    assert s == pytest.approx(math.sqrt(var))
    neg = dataclasses.replace(line, cov_speed_offset=-1.0)  # a negative variance floors at 0
    assert neg.distance(0.01, 1e-5, speed_m_s=C0)[1] == 0.0


def test_apply_ranges_flags_negative_and_passes_failures():
    cal = Calibration("beepbeep", "offset", -0.5, 0.001, 0.5 / C0, 0.001 / C0, C0, 0.0, 0.0,
                      3, (1.0,), 0.0)  # fmt: skip
    rs = (Range(0, 1, 2.0, 0.01, ("negative",)), Range(0, 2, 0.3, 0.01), Range(1, 2, math.nan,
          math.nan, ("failed",)))  # fmt: skip
    out = cal.apply_ranges(rs, speed_m_s=C0)
    assert out[0].distance_m == pytest.approx(1.5) and out[0].flags == ()
    assert out[1].distance_m == pytest.approx(-0.2) and out[1].flags == ("negative",)
    assert out[2] is rs[2]
    zero = cal.apply_ranges((Range(0, 1, 0.5, 0.01),), speed_m_s=C0)[0]
    assert zero.distance_m == pytest.approx(0.0, abs=1e-12) and "negative" not in zero.flags
    assert out[0].sigma_m == pytest.approx(math.hypot(0.01, 0.001))
    with pytest.raises(InvalidParameterError, match="for --scheme oneway, not beepbeep"):
        dataclasses.replace(cal, scheme="oneway").apply_ranges(rs, speed_m_s=C0)
    cal.check_scheme("beepbeep")


def test_apply_keeps_the_results_speed_unless_fitted():
    cal = Calibration("beepbeep", "offset", 0.1, 0.001, 0.0, 0.0, C0, 0.0, 0.0, 3, (1.0,), 0.0)
    res = RangeResult(ranges=(Range(0, 1, 1.0, 0.01),), speed_m_s=340.0)
    assert cal.apply(res).speed_m_s == 340.0
    fitted = dataclasses.replace(cal, model="offset+speed", speed_m_s=337.0)
    out = fitted.apply(res)
    assert out.speed_m_s == 337.0
    assert out.ranges[0].distance_m == pytest.approx(337.0 * 1.0 / 340.0 + 0.1)


# --------------------------------------------------------------------------- with speed
def test_two_distances_recover_speed_and_offset_exactly():
    ms = _line([0.5, 0.5, 2.0, 2.0], c=338.5, b=0.07)
    cal = fit_calibration(ms, scheme="beepbeep", speed_m_s=C0)
    assert cal.model == "offset+speed" and cal.distances_m == (0.5, 2.0)
    assert cal.speed_m_s == pytest.approx(338.5, rel=1e-9)
    assert cal.offset_m == pytest.approx(0.07, abs=1e-9)
    assert cal.latency_s == pytest.approx(-0.07 / 338.5, rel=1e-6)
    assert cal.rms_residual_m < 1e-9


def test_speed_covariance_is_the_weighted_fit_propagated():
    """cov of (c, b) = J cov(alpha, beta) J^T for tau = alpha d + beta, c = 1 / alpha,
    b = -beta / alpha; checked against finite differences of that map."""
    jit = [9e-6, -6e-6, 3e-6, -12e-6, 6e-6, 0.0]
    sig = [2e-6, 4e-6, 2e-6, 3e-6, 2e-6, 5e-6]
    ds = [0.5, 1.0, 1.5, 2.0, 2.5, 3.0]
    ms = [_m(d, (d - 0.05) / 340.0 + e, s, f"r{i}") for i, (d, e, s) in
          enumerate(zip(ds, jit, sig, strict=False))]  # fmt: skip
    cal = fit_calibration(ms, scheme="oneway", speed_m_s=C0, tolerance_m=0.0)
    d = np.array(ds)
    tau = np.array([m.tau_s for m in ms])
    var = np.array(sig) ** 2
    X = np.stack([d, np.ones_like(d)], axis=1)
    A = X.T @ (X / var[:, None])
    theta = np.linalg.solve(A, X.T @ (tau / var))
    r = tau - X @ theta
    chi2 = np.sum(r * r / var) / (len(d) - 2)
    assert chi2 > 1.5  # the times scatter more than their sigmas: the covariance grows
    cov = np.linalg.inv(A) * max(1.0, chi2)

    def cb(t):
        return np.array([1.0 / t[0], -t[1] / t[0]])

    J = np.empty((2, 2))
    for k in range(2):
        h = np.zeros(2)
        h[k] = 1e-6 * abs(theta[k])
        J[:, k] = (cb(theta + h) - cb(theta - h)) / (2 * h[k])
    C = J @ cov @ J.T
    assert cal.speed_m_s == pytest.approx(1.0 / theta[0], rel=1e-12)
    assert cal.offset_m == pytest.approx(-theta[1] / theta[0], rel=1e-9)
    assert cal.sigma_speed_m_s == pytest.approx(math.sqrt(C[0, 0]), rel=1e-6)
    assert cal.sigma_offset_m == pytest.approx(math.sqrt(C[1, 1]), rel=1e-6)
    assert cal.cov_speed_offset == pytest.approx(C[0, 1], rel=1e-6)
    assert cal.latency_s == pytest.approx(theta[1], rel=1e-12)
    assert cal.sigma_latency_s == pytest.approx(math.sqrt(cov[1, 1]), rel=1e-12)


def test_fit_speed_can_be_forced_off_and_needs_two_distances_when_on():
    ms = _line([0.5, 0.5, 2.0, 2.0], c=338.5, b=0.07)
    off = fit_calibration(ms, scheme="beepbeep", speed_m_s=C0, fit_speed=False)
    assert off.model == "offset" and off.speed_m_s == C0
    same = [_m(1.0, 2.9e-3, 1e-6, f"r{i}") for i in range(5)]
    with pytest.raises(CalibrationError, match="two or more distinct distances; all 5 are at 1"):
        fit_calibration(same, scheme="beepbeep", speed_m_s=C0, fit_speed=True)


def test_minimum_numbers_of_recordings():
    """3 recordings for an offset, 4 for offset and speed: one fewer is refused."""
    one = [_m(1.0, 2.9e-3 + i * 1e-7, 1e-6, f"r{i}") for i in range(MIN_RECORDINGS)]
    assert fit_calibration(one, scheme="beepbeep", speed_m_s=C0).n_recordings == MIN_RECORDINGS
    with pytest.raises(CalibrationError, match=r"2 given \('r0', 'r1'\), at least 3 needed"):
        fit_calibration(one[:-1], scheme="beepbeep", speed_m_s=C0)
    two = _line([0.5, 1.0, 2.0, 2.5])
    assert fit_calibration(two, scheme="beepbeep", speed_m_s=C0).n_recordings == 4
    with pytest.raises(CalibrationError, match=r"an offset and a speed: 3 given .* 4 needed"):
        fit_calibration(two[: MIN_RECORDINGS_SPEED - 1], scheme="beepbeep", speed_m_s=C0)
    with pytest.raises(CalibrationError, match=r"0 given \(none\)"):
        fit_calibration([], scheme="beepbeep", speed_m_s=C0)


def _offset_with_outlier(shift_m):
    base = [_m(1.0, 2.9e-3, 0.0, f"r{i}") for i in range(5)]
    return [*base, _m(1.0, 0.0029 + shift_m / C0, 0.0, "bad.wav")]


def test_outlier_limit_is_4_sigma_of_the_leave_one_out_prediction():
    """Tolerance 5 mm, five others in agreement: the prediction's sigma is
    sqrt(tol^2 / 5 + tol^2) = 5.48 mm, so 21 mm off (3.8 sigma) passes, 23 mm (4.2) not."""
    s = DEFAULT_TOLERANCE_M * math.sqrt(1 + 1 / 5)
    fit_calibration(_offset_with_outlier(3.8 * s), scheme="beepbeep", speed_m_s=C0)
    with pytest.raises(CalibrationError, match=r"'bad.wav' \(1 m: 4.2 sigma off\)"):
        fit_calibration(_offset_with_outlier(4.2 * s), scheme="beepbeep", speed_m_s=C0)
    assert OUTLIER_SIGMA == 4.0
    with pytest.raises(CalibrationError, match=r"limit 3 sigma, tolerance 0\.5 cm"):
        fit_calibration(_offset_with_outlier(3.5 * s), scheme="beepbeep", speed_m_s=C0,
                        outlier_sigma=3.0)  # fmt: skip


def test_only_the_disagreeing_recording_is_named():
    ms = [_m(1.0, 2.9e-3, 0.0, f"x{i}") for i in range(6)]
    ms.insert(3, _m(1.0, 2.9e-3 - 0.2 / C0, 0.0, "worst.wav"))
    with pytest.raises(CalibrationError) as e:
        fit_calibration(ms, scheme="beepbeep", speed_m_s=C0)
    msg = str(e.value)
    assert "'worst.wav' (1 m: " in msg and msg.count(" sigma off)") == 1 and "'x" not in msg


def test_outlier_with_speed_is_checked_against_the_others_line():
    ms = _line([0.5, 1.0, 1.5, 2.0, 2.5], c=340.0, b=0.05, sigma=0.0)
    fit_calibration(ms, scheme="oneway", speed_m_s=C0)
    bad = [*ms, _m(3.0, (3.0 - 0.05) / 340.0 + 0.1 / 340.0, 0.0, "far.wav")]
    with pytest.raises(CalibrationError, match=r"'far\.wav' \(3 m"):
        fit_calibration(bad, scheme="oneway", speed_m_s=C0)
    # one distance apart from the others: without it they cannot fit a line, no check
    lone = [_m(1.0, (1.0 - 0.05) / 340.0, 0.0, f"r{i}") for i in range(3)]
    lone.append(_m(2.0, (2.0 - 0.05) / 340.0 + 1e-3, 0.0, "lone.wav"))
    cal = fit_calibration(lone, scheme="oneway", speed_m_s=C0)
    assert cal.model == "offset+speed" and cal.rms_residual_m < 1e-9 + 1e-3 * 340.0


def test_implausible_fits_are_refused():
    backwards = [_m(d, (3.0 - d) / 340.0, 1e-6, f"r{i}") for i, d in enumerate([0.5, 1, 2, 2.5])]
    with pytest.raises(CalibrationError, match="not positive"):
        fit_calibration(backwards, scheme="beepbeep", speed_m_s=C0, outlier_sigma=1e9)
    slow = _line([0.5, 1.0, 2.0, 2.5], c=90.0, b=0.0)
    with pytest.raises(CalibrationError, match=r"90\.0 m/s is implausible"):
        fit_calibration(slow, scheme="beepbeep", speed_m_s=C0)
    ok = _line([0.5, 1.0, 2.0, 2.5], c=101.0, b=0.0)
    assert fit_calibration(ok, scheme="beepbeep", speed_m_s=C0).speed_m_s == pytest.approx(101.0)
    fast = _line([0.5, 1.0, 2.0, 2.5], c=2100.0, b=0.0)
    with pytest.raises(CalibrationError, match="implausible"):
        fit_calibration(fast, scheme="beepbeep", speed_m_s=C0)


def test_bad_inputs():
    ms = [_m(1.0, 2.9e-3, 1e-6, f"r{i}") for i in range(3)]
    with pytest.raises(InvalidParameterError, match="scheme='echo'"):
        fit_calibration(ms, scheme="echo", speed_m_s=C0)
    for c in (99.0, 2001.0):
        with pytest.raises(InvalidParameterError, match="speed_m_s"):
            fit_calibration(ms, scheme="beepbeep", speed_m_s=c)
    for c in (100.0, 2000.0):  # the domain's ends are legal
        fit_calibration(ms, scheme="beepbeep", speed_m_s=c)
    with pytest.raises(CalibrationError, match="'r1': no measurement"):
        fit_calibration([ms[0], _m(1.0, math.nan, 1e-6, "r1"), ms[2]], scheme="beepbeep",
                        speed_m_s=C0)  # fmt: skip
    with pytest.raises(InvalidParameterError, match="distance_m of r0"):
        fit_calibration([_m(0.0, 0.001, 1e-06, "r0"), *ms], scheme="beepbeep", speed_m_s=C0)


# --------------------------------------------------------------------------- files
def _cal(**kw):
    base = fit_calibration(_line([0.5, 1.0, 2.0, 2.5], jitter=[1e-6, -1e-6]), scheme="beepbeep",
                           speed_m_s=C0, probe="sweep.wav")  # fmt: skip
    return dataclasses.replace(base, **kw)


def test_file_round_trip(tmp_path):
    cal = _cal()
    p = tmp_path / "cal.json"
    cal.write(p)
    back = read_calibration(p)
    assert back == cal and back.residuals == cal.residuals and back.probe == "sweep.wav"
    assert json.loads(p.read_text())["format"] == "rangekit-calibration/1"


#: The accepted ranges of a calibration file's values, as docs/formats.md ("Calibration
#: file") states them: written here, not read from the module, so a changed bound fails.
FILE_LIMITS = {
    "speed_m_s": (200.0, 2000.0),
    "offset_m": (-100.0, 100.0),
    "sigma_offset_m": (0.0, 100.0),
    "latency_s": (-10.0, 10.0),
    "sigma_latency_s": (0.0, 10.0),
    "sigma_speed_m_s": (0.0, 1000.0),
}


def _limit_cases():
    """Every documented bound: the bound itself accepted, a step past it refused (1 % of
    the range's width, so a bound moved either way is caught)."""
    for field, (lo, hi) in FILE_LIMITS.items():
        step = 0.01 * (hi - lo)
        yield field, lo, True
        yield field, hi, True
        yield field, lo - step, False
        yield field, hi + step, False


@pytest.mark.parametrize(
    ("field", "value", "ok"),
    [
        ("speed_m_s", 200.0, True),
        ("speed_m_s", 199.0, False),
        ("speed_m_s", 2000.0, True),
        ("speed_m_s", 2001.0, False),
        ("offset_m", 100.0, True),
        ("offset_m", -100.5, False),
        ("sigma_offset_m", -1e-9, False),
        ("sigma_offset_m", 100.0, True),
        ("sigma_offset_m", 100.5, False),
        ("latency_s", 10.5, False),
        ("sigma_latency_s", 10.0, True),
        ("sigma_speed_m_s", 1000.5, False),
        ("n_recordings", 1, True),
        ("n_recordings", 0, False),
        ("n_recordings", True, False),
        ("n_recordings", 2.0, False),
        *_limit_cases(),
    ],
)
def test_file_values_are_checked_at_their_limits(tmp_path, field, value, ok):
    doc = _cal().to_dict()
    doc[field] = value
    if field.startswith("sigma") and ok:
        doc["cov_speed_offset"] = 0.0
    p = tmp_path / "cal.json"
    p.write_text(json.dumps(doc))
    if ok:
        assert getattr(read_calibration(p), field) == value
    else:
        with pytest.raises(InputFileError, match=f"not a valid rangekit calibration: {field}"):
            read_calibration(p)


def test_file_covariance_within_the_sigmas_product(tmp_path):
    doc = _cal().to_dict()
    bound = doc["sigma_speed_m_s"] * doc["sigma_offset_m"]
    p = tmp_path / "cal.json"
    for cov, ok in ((bound, True), (-bound, True), (1.001 * bound, False), (-1.001 * bound, False)):
        doc["cov_speed_offset"] = cov
        p.write_text(json.dumps(doc))
        if ok:
            assert read_calibration(p).cov_speed_offset == cov
        else:
            with pytest.raises(InputFileError, match="exceeds sigma_speed_m_s x sigma_offset_m"):
                read_calibration(p)


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        ({"format": "other/1"}, "is not a rangekit calibration"),
        ({"scheme": "echo"}, "unknown scheme 'echo'"),
        ({"model": "line"}, "or model 'line'"),
        ({"offset_m": True}, "offset_m=True must be a finite number"),
        ({"latency_s": "0"}, "latency_s='0' must be a finite number"),
    ],
)
def test_file_refusals(tmp_path, edit, match):
    doc = {**_cal().to_dict(), **edit}
    p = tmp_path / "cal.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(InputFileError, match=match):
        read_calibration(p)


def test_measurements_and_calibrations_are_frozen_and_short_to_print():
    m = _m(1.0, 2.9e-3)
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.tau_s = 0.0
    cal = _cal()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cal.offset_m = 0.0
    assert cal.residuals and "residuals" not in repr(cal)  # one entry per recording: not shown


def test_a_flat_time_line_has_no_positive_speed():
    # every recording at time 0 whatever its distance: the fitted slope 1/c is exactly 0
    # (a zero right-hand side), no speed at all; refused as "not positive", never divided
    # by (a time 0.01 s gives a slope of -1e-18, which the rule refuses either way)
    flat = [_m(d, 0.0, 1e-6, f"r{i}") for i, d in enumerate([0.5, 1.0, 2.0, 2.5])]
    with pytest.raises(CalibrationError, match="not positive"):
        fit_calibration(flat, scheme="beepbeep", speed_m_s=C0, outlier_sigma=1e9)
