"""``changepoint._combine`` under a clock-rate mismatch, in both engines.

A beep played on one sample clock and recorded on another (rate mismatch ``r``) has its
burst ``k`` recorded ``k r spacing`` samples away from where the nominal spacing puts it:
the bursts' estimates of the beep onset lie on a line of slope ``r spacing`` a burst.
``_combine`` tests each burst against the drift line of the agreeing ones (slope within
200 ppm), so a drifting beep keeps all its bursts at any spacing and a burst off that line
is rejected whichever burst it is. The compiled loop (``_edge_kernels._combine_py``) must
give the same numbers.
"""

from __future__ import annotations

import numpy as np
import pytest

import rangekit.detect._edge_kernels as K
import rangekit.detect.changepoint as cp
from rangekit.detect.changepoint import detect_changepoint
from rangekit.detect.refine import EdgeFit
from rangekit.signals import Beep
from rangekit.sim.recording import pair_devices, render_beepbeep

FS = 44100.0


def _fits(onsets, sigmas):
    return [
        None if o is None else EdgeFit(onset=o, sigma=s, snr_db=20.0, amplitude=1.0, f_stat=100.0)
        for o, s in zip(onsets, sigmas, strict=True)
    ]


def _drifting(ppm: float, spacing: float, n: int = 4, t0: float = 0.0) -> list[float]:
    return [t0 + k * spacing * (1.0 + ppm * 1e-6) for k in range(n)]


@pytest.mark.parametrize("ppm", [150.0, -150.0, 195.0])
@pytest.mark.parametrize("spacing", [22050.0, 44100.0])
def test_a_drifting_beep_keeps_every_burst_at_long_spacings(ppm, spacing):
    """Four precise bursts (sigma 0.05) at 150-195 ppm over 0.5-1 s spacings: burst k is
    3.3-8.6 k samples off, yet all four lie on one drift line and are kept (before the
    drift line, 150 ppm over 0.5 s rejected burst 0: confidence 0.75,
    ``inconsistent_bursts``). The onset is the bursts' mean estimate, ``1.5 r spacing``
    after burst 0's, and sigma holds that spread (the reduced chi-square about it)."""
    on = _drifting(ppm, spacing)
    got = cp._combine(_fits(on, [0.05] * 4), [False] * 4, spacing=spacing, scale=1.0, min_bursts=3)
    assert got is not None
    t0, s0, _, conf, row, flags, _ = got
    assert conf == 1.0 and flags == 0
    np.testing.assert_array_equal(row, on)
    d = ppm * 1e-6 * spacing
    assert t0 == pytest.approx(1.5 * d, abs=1e-9)
    # chi-square about the mean: sum (d (k - 1.5))^2 / 0.05^2 / 3, times 0.05^2 / 4
    spread = np.sqrt(np.sum((d * (np.arange(4) - 1.5)) ** 2) / 3 / 4)
    assert s0 == pytest.approx(np.hypot(spread, cp.MODEL_SIGMA), rel=1e-9)


@pytest.mark.parametrize("spacing", [5000.0, 22050.0])
@pytest.mark.parametrize("ppm", [0.0, 150.0])
@pytest.mark.parametrize("bad", [0, 1, 2, 3])
def test_a_burst_off_the_drift_line_is_rejected_whichever_it_is(bad, ppm, spacing):
    """Bursts on a line of 0 or 150 ppm, one of them 8 samples off it (its timing noise
    allows 2 + 4 x 0.05 = 2.2, the slope up to 200 ppm: 1 or 4.4 samples a burst): that
    burst and no other is rejected, the beep flagged. (At 150 ppm over 5000 samples an
    end burst 6 off still lies on a line of slope -1 within 2.2 of all four.) Before the
    drift line, at 150 ppm over 0.5 s, burst 0 was rejected where burst 1, 2 or 3 was
    off (and kept where it was 8 samples late itself)."""
    on = _drifting(ppm, spacing)
    for off in (8.0, -8.0):
        x = list(on)
        x[bad] += off
        got = cp._combine(
            _fits(x, [0.05] * 4), [False] * 4, spacing=spacing, scale=1.0, min_bursts=3
        )
        assert got is not None
        _, _, _, conf, row, flags, _ = got
        assert conf == 0.75 and flags & cp.flag_bit("inconsistent_bursts")
        assert np.isnan(row[bad]) and np.isfinite(np.delete(row, bad)).all()


@pytest.mark.parametrize("bad", [0, 1, 2, 3])
def test_three_samples_off_an_inner_burst_is_rejected_an_outer_one_taken_for_drift(bad):
    """3 samples off at 0 ppm over the default spacing (5000 samples, 200 ppm = 1 sample
    a burst): an inner burst is off every admissible line and rejected; an outer one is
    within 2.2 of a line of slope 1 sample a burst (drift and an end burst's offset are
    not separable), so all four are kept and the onset moves by 3/4, which the
    chi-square-scaled sigma covers (measured |error| / sigma 0.60)."""
    on = _drifting(0.0, 5000.0)
    on[bad] += 3.0
    got = cp._combine(_fits(on, [0.05] * 4), [False] * 4, spacing=5000.0, scale=1.0, min_bursts=3)
    assert got is not None
    t0, s0, _, conf, row, flags, _ = got
    if bad in (1, 2):
        assert conf == 0.75 and np.isnan(row[bad]) and flags & cp.flag_bit("inconsistent_bursts")
        assert t0 == pytest.approx(0.0, abs=1e-9)
    else:
        assert conf == 1.0 and flags == 0
        assert t0 == pytest.approx(0.75, abs=1e-9)
        assert 0.5 < abs(t0) / s0 < 0.7  # covered within 1 sigma


def test_drift_beyond_200_ppm_is_not_taken_for_drift():
    """At 300 ppm over 0.5 s (6.6 samples a burst) every line's slope is held at 200 ppm
    (4.4 samples): no line holds more than two neighbouring bursts, and the earliest two
    are kept (confidence 0.5, flagged). At 195 ppm all four are kept (above)."""
    spacing = 22050.0
    on = _drifting(300.0, spacing)
    got = cp._combine(_fits(on, [0.05] * 4), [False] * 4, spacing=spacing, scale=1.0, min_bursts=2)
    assert got is not None and got[3] == 0.5 and got[5] & cp.flag_bit("inconsistent_bursts")
    np.testing.assert_array_equal(np.isfinite(got[4]), [True, True, False, False])
    assert (
        cp._combine(_fits(on, [0.05] * 4), [False] * 4, spacing=spacing, scale=1.0, min_bursts=3)
        is None
    )


def _compiled_combine(fits, spacing, scale, min_bursts):
    K._compiled("beeps")  # compiles the helpers (``_combine_py`` among them)
    k_b = len(fits)
    on = np.array([np.nan if f is None else f.onset for f in fits])
    sg = np.array([np.inf if f is None else f.sigma for f in fits])
    snr = np.array([0.0 if f is None else f.snr_db for f in fits])
    fst = np.array([0.0 if f is None else f.f_stat for f in fits])
    have = np.array([f is not None for f in fits])
    res, row = np.zeros(6), np.zeros(k_b)
    ok = K._combine_py(on, sg, snr, fst, have, spacing, scale, min_bursts, cp.MODEL_SIGMA, res, row)
    return (res, row) if ok else None


def test_compiled_combine_equals_the_reference():
    """200 seeded bursts sets (4-8 bursts, some missing, drift up to +-300 ppm, spacings
    5000-44100 samples, sigmas 0.01-2 samples, a few outliers of 1-20 samples): the
    compiled loop keeps the same bursts and gives the same onset and sigma (measured
    differences <= 1e-12 samples)."""
    rng = np.random.default_rng(7)
    n_none = n_partial = 0
    for _ in range(200):
        k_b = int(rng.integers(4, 9))
        spacing = float(rng.choice([5000.0, 22050.0, 44100.0]))
        on = _drifting(rng.uniform(-300, 300), spacing, k_b, t0=1000.0)
        sg = np.exp(rng.uniform(np.log(0.01), np.log(2.0), k_b))
        on = list(np.array(on) + sg * rng.standard_normal(k_b))
        for k in rng.choice(k_b, size=int(rng.integers(0, 3)), replace=False):
            on[k] += float(rng.choice([-1, 1]) * rng.uniform(1, 20))
        fits = _fits(on, sg)
        for k in rng.choice(k_b, size=int(rng.integers(0, 2)), replace=False):
            fits[k] = None
        mb = int(rng.integers(1, 4))
        ref = cp._combine(fits, [False] * k_b, spacing=spacing, scale=1.0, min_bursts=mb)
        got = _compiled_combine(fits, spacing, 1.0, mb)
        assert (ref is None) == (got is None)
        if ref is None:
            n_none += 1
            continue
        res, row = got
        np.testing.assert_array_equal(np.isnan(row), np.isnan(ref[4]))
        assert res[0] == pytest.approx(ref[0], abs=1e-9)
        assert res[1] == pytest.approx(ref[1], rel=1e-9)
        assert res[3] == ref[3]
        n_partial += ref[3] < 1.0
    # the draw exercises every branch: refusals, partial and full sets
    assert n_none > 0 and 0 < n_partial < 200 - n_none


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_an_exchange_with_150_ppm_between_the_clocks_keeps_every_burst(seed):
    """Two devices 150 ppm apart (+-75), beeps of four bursts 0.5 s apart: each far beep
    drifts by 3.3 samples a burst (+ in device 0's recording, - in device 1's). Every
    arrival keeps its four bursts, unflagged, each burst within 1.2 samples of its true
    place (measured <= 0.59; 0.73 without drift; the first-path search now widens by the
    drift: burst 3 was 2.4 samples off), the onset 1.5 bursts of drift after the true one
    within 2 sigma, and the two far arrivals' drift offsets cancel to within 2 samples
    (measured 0.16-1.0: the bursts' weights differ between the two). Before the drift
    line burst 0 of both far beeps was rejected (confidence 0.75,
    ``inconsistent_bursts``)."""
    rng = np.random.default_rng(seed)
    b = Beep(spacing=22050)
    devs = pair_devices(float(rng.uniform(1.0, 6.0)), self_distance_m=0.1, clock_ppm=(75.0, -75.0))
    sim = render_beepbeep(devs, beep=b, snr_db=float(rng.uniform(20, 30)), rng=rng)
    drift = []
    for i, x in enumerate(sim.recordings):
        arr = detect_changepoint(x, fs=FS, beep=b)
        assert len(arr) == 2
        for j in range(2):
            assert arr.confidence[j] == 1.0 and not arr.flag_names(j)
            r = (1 + devs[i].clock_ppm * 1e-6) / (1 + devs[j].clock_ppm * 1e-6) - 1
            true = sim.onsets[i][j] + np.arange(4) * b.spacing * (1 + r)
            np.testing.assert_allclose(arr.burst_onsets[j], true, rtol=0, atol=1.2)
            off = arr.onset[j] - sim.onsets[i][j]
            assert abs(off - 1.5 * r * b.spacing) < 2 * arr.sigma[j]
            if i != j:
                drift.append(off)
    assert abs(sum(drift)) < 2.0
