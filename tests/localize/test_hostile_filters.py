"""Filters on hostile numbers (issue 17): values near 1e300 and extreme options either
give finite states or raise one RangekitError with a one-line message; no NaN pose, no
leaked warning. Hypothesis runs are seeded (derandomize) and small."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from rangekit.errors import IncompatibleInputError, InvalidParameterError, LogFormatError
from rangekit.io.tracklog import MeasurementLog, RangeRows
from rangekit.localize import duhl
from rangekit.localize.duhl import DUHLConfig, track_log
from rangekit.localize.ekf import predict, update
from rangekit.localize.range_ekf import track_ranges
from rangekit.sim.jiang2018 import simulate
from rangekit.sim.kim2013 import simulate as simulate_kim

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

HUGE = st.one_of(
    st.floats(min_value=-1e308, max_value=1e308, allow_nan=False),
    st.sampled_from([1e300, -1e300, 1e200, 1e160, 5e-324, 0.0]),
)


def _finite_or_refused(f, *a, **k):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            out = f(*a, **k)
        except InvalidParameterError as e:
            assert "\n" not in str(e)
            return None
    return out


@settings(derandomize=True, deadline=None, database=None, max_examples=300)
@given(x=HUGE, p=HUGE, z=HUGE, h=HUGE, r=HUGE)
def test_ekf_update_is_finite_or_refused(x, p, z, h, r):
    res = _finite_or_refused(
        update, [x, 1.0], np.diag([abs(p), 1.0]), [z], np.array([[h, 0.5]]), abs(r) + 1e-3
    )
    if res is not None:
        assert np.all(np.isfinite(res.x)) and np.all(np.isfinite(res.P))


@settings(derandomize=True, deadline=None, database=None, max_examples=150)
@given(x=HUGE, p=HUGE, f=HUGE)
def test_ekf_predict_is_finite_or_refused(x, p, f):
    F = np.array([[1.0, f], [0.0, 1.0]])
    res = _finite_or_refused(predict, [x, 1.0], np.diag([abs(p), 1.0]), F, np.eye(2))
    if res is not None:
        assert np.all(np.isfinite(res[0])) and np.all(np.isfinite(res[1]))


def test_range_tracker_refuses_absurd_logs_and_options():
    log = simulate(rng=1).log
    g = log.ranges
    for v in (1e300, 2e6):
        r = g.range_m.copy()
        r[3] = v
        bad = MeasurementLog(log.robot, log.fixes, RangeRows(g.t_s, g.a, g.b, r, g.sigma_m), 2)
        with pytest.raises(LogFormatError, match=r"^x\.csv: a range, fix or variance beyond"):
            track_ranges(bad, name="x.csv")
    for kw in ({"accel_psd": 1e300}, {"sigma_v0": 1e300}):
        with pytest.raises(InvalidParameterError, match="must be within"):
            track_ranges(log, **kw)
    # the largest accepted options still give finite states
    trk = track_ranges(log, accel_psd=1e6, sigma_v0=1e3)
    assert np.all(np.isfinite(trk.x)) and np.all(np.isfinite(trk.P))


@pytest.fixture(scope="module")
def kim_log():
    sim = simulate_kim(4, rng=11)
    log = sim.to_log()
    n = 400  # 4 s of odometry is enough to reach every code path
    from rangekit.io.duhllog import DistanceRows, DUHLLog, OdometryRows

    o, d = log.odometry, log.distances
    keep = d.t_s <= o.t_s[n - 1]
    short = DUHLLog(
        OdometryRows(o.t_s[:n], o.v_right_mps[:n], o.v_left_mps[:n]),
        DistanceRows(d.t_s[keep], d.tx[keep], d.d_m[keep]),
    )
    return sim, short


BOUNDS = {
    "wheel_base_m": duhl.WHEEL_BASE_RANGE_M,
    "r_R_m": duhl.R_R_RANGE_M,
    "k_v_m": duhl.K_V_RANGE_M,
    "sigma_d_m": duhl.SIGMA_D_RANGE_M,
}


@pytest.mark.parametrize("variant", ["ranges", "duhl"])
@pytest.mark.parametrize("field", sorted(BOUNDS))
def test_duhl_options_at_their_bounds_give_finite_poses(kim_log, field, variant):
    """Before: duhl-ranges with sigma_d 1e-12 / 1e300, k_v 1e300, wheel base 1e-12 wrote
    NaN poses (and duhl with r_R 1e-300). At the accepted bounds the poses are finite;
    beyond them the option is refused with one line."""
    sim, log = kim_log
    lo, hi = BOUNDS[field]
    for v in (lo, hi):
        for pose0 in (sim.true_pose[0], None):
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                trk = track_log(log, sim.beacons, config=DUHLConfig(**{field: v}, variant=variant),
                                initial_pose=pose0)  # fmt: skip
            assert np.all(np.isfinite(trk.pose[trk.start_index :])), (field, v)
    for v in (lo / 10 if lo > 0 else -1.0, hi * 10, 1e300, math.nan):
        with pytest.raises(InvalidParameterError, match=rf"^{field}=.* must be within"):
            DUHLConfig(**{field: v}, variant=variant)


def test_duhl_refuses_huge_inputs_and_reports_divergence(kim_log, monkeypatch):
    sim, log = kim_log
    o = log.odometry
    with pytest.raises(InvalidParameterError, match=r"^v_right has a value of 1e\+300"):
        duhl.track_duhl(o.t_s, np.full(o.t_s.size, 1e300), o.v_left_mps, log.distances.t_s,
                        log.distances.tx, log.distances.d_m, sim.beacons.xyz_m,
                        tx_ids=sim.beacons.ids)  # fmt: skip
    # a kernel that returns NaN (whatever the cause) is reported, not written
    real = duhl.K.run_duhl

    def nan_kernel(*a):
        out = list(real(*a))
        out[0] = out[0].copy()
        out[0][5:] = np.nan
        return tuple(out)

    monkeypatch.setattr(duhl.K, "run_duhl", nan_kernel)
    with pytest.raises(IncompatibleInputError, match=r"^the ranges filter diverged at t_s="):
        track_log(log, sim.beacons, config=DUHLConfig(variant="ranges"),
                  initial_pose=sim.true_pose[0])  # fmt: skip
