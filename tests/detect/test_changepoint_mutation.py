"""Change-point detector: documented thresholds and rules pinned one by one.

Written against the mutants of ``rangekit/detect/changepoint.py`` that its other tests let
through (``benchmarks/mutation.py``, docs/evidence.md). Each test states the rule of the
module it checks; short synthetic inputs only.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rangekit.detect import _edge_kernels as K
from rangekit.detect import changepoint as cp
from rangekit.detect.refine import EdgeFit
from rangekit.errors import InvalidParameterError
from rangekit.signals import Beep, beep_waveform
from rangekit.signals.beep import beep_continuous
from rangekit.types import Arrivals, flag_bit


@pytest.mark.parametrize(("noise", "low"), [(0.2, False), (0.3, False), (0.4, True)])
def test_low_snr_flag_is_a_median_burst_snr_below_10_db(noise, low):
    """Measured SNR 15.9, 12.0 and 9.0 dB (seed 0): flagged exactly below LOW_SNR_DB."""
    b = Beep()
    x = np.zeros(30000)
    x[1000 : 1000 + b.duration_samples] = beep_waveform(b)
    x += noise * np.random.default_rng(0).standard_normal(len(x))
    arr = cp.detect_changepoint(x, fs=b.fs, beep=b)
    assert len(arr) == 1
    assert ("low_snr" in arr.flag_names(0)) == low == (arr.snr_db[0] < cp.LOW_SNR_DB)
    assert cp.LOW_SNR_DB == 10.0


def test_change_points_rise_strictly_above_the_threshold():
    """A frame counts when its energy is *above* max(floor x threshold, recent x rise)."""
    kw = {"n_win": 128, "hop": 32, "threshold_db": 10.0, "rise_db": 10.0, "floor": None}
    e = np.ones(40)
    e[30:] = 10.0  # exactly 10 dB over the floor and over the level before
    assert cp._change_points(e, **{**kw, "floor": np.ones(40)}).tolist() == []
    e[30:] = 10.0 * (1 + 1e-9)
    assert cp._change_points(e, **{**kw, "floor": np.ones(40)}).tolist() == [30]
    assert cp._change_points(np.zeros(0), **kw).shape == (0,)
    # a series above its threshold from the first frame rises there (nothing before it)
    assert cp._change_points(np.full(40, 20.0), **{**kw, "floor": np.ones(40)}).tolist() == [0]


def test_anchor_of_a_one_burst_beep_is_its_change_point():
    e = np.ones(100)
    assert cp._anchor(1234, e, hop=32, n_win=128, spacing=5000.0, beep=Beep(n_bursts=1),
                      fs=44100.0) == (1234, 1)  # fmt: skip


def _frames_before(far, near, *, n=400):
    """Band energy per frame: ``far`` level, then ``near`` level just before frame ``n``."""
    e = np.full(n, float(far))
    e[n - 30 : n] = near
    return e


def test_precursor_rising_10_db_flags_an_ambiguous_first_path():
    """Within PRE_NEAR_S before the onset, 8 frames PRE_RISE_DB (10 dB) above the level
    before: ``ambiguous_first_path``; 8 dB is not enough, 12 dB is."""
    hop, n_win, fs = 32, 128, 44100.0
    t0 = 400 * hop + n_win  # the onset: frame 400 is the first not wholly before it
    bit = flag_bit("ambiguous_first_path")
    for far in (1.0, 1e-3):  # a rise over the level before, whatever that level
        for rise_db, flagged in ((8.0, False), (12.0, True)):
            e = _frames_before(far, far * 10 ** (rise_db / 10))
            got = cp._before_onset_flags(e, t0, hop=hop, n_win=n_win, fs=fs, quiet=far)
            assert bool(got & bit) == flagged, (far, rise_db)
    assert (
        cp._before_onset_flags(np.ones(10), 5 * hop + n_win, hop=hop, n_win=n_win, fs=fs, quiet=1.0)
        == 0
    )  # fmt: skip  (too close to the start)


def test_reverb_limited_is_a_level_4_times_the_quiet_one():
    hop, n_win, fs = 32, 128, 44100.0
    t0 = 400 * hop + n_win
    bit = flag_bit("reverb_limited")
    e = np.ones(400)
    for quiet, flagged in ((0.26, False), (0.24, True), (0.0, False)):
        got = cp._before_onset_flags(e, t0, hop=hop, n_win=n_win, fs=fs, quiet=quiet)
        assert bool(got & bit) == flagged, quiet


def _row(t0, onsets, strength):
    ons = np.asarray(onsets, dtype=float)
    return (t0, 1.0, 20.0, 1.0, ons, 0, strength)


def test_alias_groups_sharing_two_bursts_keep_the_stronger():
    """One beep indexed two ways (a noise change point one spacing early): groups that
    share two or more burst onsets within ``tol`` are one beep; the stronger stays."""
    real = _row(5000.0, [5000.0, 10000.0, 15000.0, 20000.0], 400.0)
    alias = _row(0.0, [0.0, 5000.5, 10000.5, np.nan], 300.0)
    assert cp._resolve_aliases([alias, real], tol=1.0) == [real]
    assert cp._resolve_aliases([alias, real], tol=0.4) == [alias, real]  # none shared
    one = _row(0.0, [0.0, 5000.5, 11000.0, np.nan], 300.0)  # shares one burst only
    assert cp._resolve_aliases([one, real], tol=1.0) == [one, real]
    stronger = _row(0.0, [0.0, 5000.5, 10000.5, np.nan], 500.0)
    assert cp._resolve_aliases([stronger, real], tol=1.0) == [stronger]
    same_start = _row(5000.5, [5000.5, 10000.5, 14000.0], 100.0)  # same beep start: kept
    assert len(cp._resolve_aliases([same_start, real], tol=1.0)) == 2


def _arrivals(onsets, confidence):
    n = len(onsets)
    z = np.zeros(n)
    conf = np.asarray(confidence, dtype=float)
    return Arrivals(np.asarray(onsets, dtype=float), 44100.0, z + 0.1, z + 20.0, conf,
                    np.zeros((n, 4)), "changepoint")  # fmt: skip


def test_drop_echoes_keeps_the_earlier_unless_the_later_agrees_more():
    arr = _arrivals([1000.0, 1500.0, 3000.0], [1.0, 1.0, 0.75])
    assert cp.drop_echoes(arr, duration=1000.0).onset.tolist() == [1000.0, 3000.0]
    # an arrival exactly one duration later starts a new one
    assert cp.drop_echoes(arr, duration=500.0).onset.tolist() == [1000.0, 1500.0, 3000.0]
    better = _arrivals([1000.0, 1500.0], [0.75, 1.0])
    assert cp.drop_echoes(better, duration=1000.0).onset.tolist() == [1500.0]
    # the arrival that replaced the earlier one has its own span: one inside it is dropped
    three = _arrivals([1000.0, 1500.0, 2200.0], [0.75, 1.0, 1.0])
    assert cp.drop_echoes(three, duration=1000.0).onset.tolist() == [1500.0]


def test_expected_drops_only_as_many_doubtful_arrivals_as_needed_weakest_first():
    """Three beeps, two of them doubtful (low_snr; the last also inconsistent_bursts):
    ``expected=2`` drops one, the one with fewer agreeing bursts; ``expected=1`` both."""
    b = Beep()
    w = beep_waveform(b)
    x = np.zeros(70000)
    for amp, t in ((1.0, 1000), (0.25, 22000), (0.2, 44000)):
        x[t : t + len(w)] += amp * w
    x += 0.1 * np.random.default_rng(1).standard_normal(len(x))
    found = {e: np.round(cp.detect_changepoint(x, fs=b.fs, beep=b, expected=e).onset, -3)
             for e in (None, 3, 2, 1)}  # fmt: skip
    assert found[None].tolist() == found[3].tolist() == [1000.0, 22000.0, 44000.0]
    assert found[2].tolist() == [1000.0, 22000.0]
    assert found[1].tolist() == [1000.0]


@pytest.mark.parametrize(
    ("dc", "hum", "flagged"),
    [(0.0, 0.0, False), (0.5, 0.0, False), (0.0, 5.0, True), (3.0, 0.0, True)],
)
def test_energy_outside_the_band_flags_dc_or_lowband(dc, hum, flagged):
    """Out-of-band over in-band energy above OOB_RATIO (100) flags the arrival; the onset
    is still found (the fit reads band-limited stretches)."""
    b = Beep()
    x = np.zeros(30000)
    x[1000 : 1000 + b.duration_samples] = beep_waveform(b)
    x += 0.01 * np.random.default_rng(0).standard_normal(len(x))
    x += dc + hum * np.sin(2 * np.pi * 50.0 * np.arange(len(x)) / b.fs)
    arr = cp.detect_changepoint(x, fs=b.fs, beep=b)
    assert len(arr) == 1 and abs(arr.onset[0] - 1000.0) < 0.1
    assert ("dc_or_lowband" in arr.flag_names(0)) == flagged
    if dc == hum == 0.0:  # unconditioned (raw samples): nothing measured, nothing flagged
        raw = cp.detect_changepoint(x, fs=b.fs, beep=b, condition=False)
        assert len(raw) == 1 and "dc_or_lowband" not in raw.flag_names(0)


def _fit(onset, sigma):
    return EdgeFit(onset=onset, sigma=sigma, snr_db=20.0, amplitude=1.0, f_stat=100.0)


def test_combine_centres_on_the_inverse_variance_mean_of_the_agreeing_bursts():
    """Three bursts agree (within their allowed scatter 2 + 4 sigma); the centre is their
    inverse-variance mean (~0, the two precise ones), so all three are kept. A centre
    weighted the other way (~3, the imprecise one) would reject the two precise bursts."""
    fits = [_fit(0.0, 0.01), _fit(100.0, 0.01), _fit(203.0, 0.5)]  # estimates 0, 0, 3
    got = cp._combine(fits, [False] * 3, spacing=100.0, scale=1.0, min_bursts=2)
    assert got is not None
    t0, s0, _, conf, row, flags, _ = got
    w = np.array([1e4, 1e4, 4.0])
    est = np.array([0.0, 0.0, 3.0])
    assert t0 == pytest.approx(float(w @ est) / w.sum(), abs=1e-9)
    # 1-sigma: inverse-variance, scaled by the reduced chi-square (2 dof), and the model
    # error MODEL_SIGMA (1 sample at 44.1 kHz) added in quadrature
    chi2 = float(w @ (est - t0) ** 2) / 2
    expect = np.hypot(np.sqrt(max(1.0, chi2) / w.sum()), cp.MODEL_SIGMA)
    assert s0 == pytest.approx(expect, rel=1e-9)
    assert conf == 1.0 and flags == 0
    np.testing.assert_array_equal(row, [0.0, 100.0, 203.0])


def test_clipped_samples_just_before_an_onset_make_the_fit_masked_and_flagged():
    """A saturated click 20 samples before each burst (inside the fit's pre-onset window,
    2 x 24 samples): the bursts are refined on the raw samples with the clipped ones left
    out, the arrival is flagged ``clipped`` and still timed (measured -0.034 samples)."""
    b = Beep()
    t = np.arange(30000) / b.fs
    onset = 3000.4
    x = 0.3 * beep_continuous(t - onset / b.fs, beep=b)
    x += 0.002 * np.random.default_rng(0).standard_normal(len(x))
    for k in range(b.n_bursts):
        i = int(onset + k * b.spacing) - 20
        x[i : i + 3] = 1.0  # three samples on the rail
    arr = cp.detect_changepoint(x, fs=b.fs, beep=b)
    assert len(arr) == 1 and arr.flag_names(0) == ("clipped",)
    assert abs(arr.onset[0] - onset) < 0.07


@pytest.mark.parametrize("fs", [96000.0])
@pytest.mark.parametrize("clip", [None, 0.5])
def test_compiled_detections_equal_the_numpy_path_at_another_rate(fs, clip, monkeypatch):
    """The compiled beep loop scales its constants with fs / 44100 as the numpy reference
    does (stage 2's search half-width, the clipped stretches' raw statistic): a loud and a
    faint beep at 96 kHz, clean and clipped, give the reference's numbers to rounding."""
    b = Beep()
    t = np.arange(int(0.9 * fs)) / fs
    onsets = [0.05 * fs + 0.3, 0.5 * fs + 0.7]
    x = beep_continuous(t - onsets[0] / fs, beep=b) + 0.05 * beep_continuous(
        t - onsets[1] / fs, beep=b
    )
    x += 0.002 * np.random.default_rng(0).standard_normal(len(x))
    if clip is not None:
        x = np.clip(x, -clip, clip)
    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 10**12)
    ref = cp.detect_changepoint(x, fs=fs, beep=b)
    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 0)
    fast = cp.detect_changepoint(x, fs=fs, beep=b)
    assert len(ref) == len(fast) == 2
    np.testing.assert_allclose(ref.onset, onsets, atol=0.25)  # measured 0.13 (the faint one)
    assert ("clipped" in ref.flag_names(0)) == (clip is not None)
    np.testing.assert_allclose(fast.onset, ref.onset, rtol=0, atol=1e-6)
    np.testing.assert_allclose(fast.sigma, ref.sigma, rtol=1e-9)
    np.testing.assert_allclose(fast.snr_db, ref.snr_db, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(fast.flags, ref.flags)
    np.testing.assert_allclose(fast.burst_onsets, ref.burst_onsets, rtol=0, atol=1e-6)


@pytest.mark.parametrize(("f_hz", "taper"), [(16000.0, 22), (2000.0, 22)])
def test_beep_taps_pass_the_beep_and_remove_dc_and_hum(f_hz, taper):
    """The band-limiting FIR is flat at the beep and its edge band (f +- 1 edge bandwidth)
    and removes DC and 50 Hz hum, also for a low beep whose band f - 2 bandwidths would
    reach below 0 Hz (its lower edge is then 0.1 f). Measured: DC/hum gain <= 8e-4."""
    b = Beep(f_hz=f_hz, taper=taper)
    h = cp.beep_taps(b, b.fs)
    n = np.arange(len(h))

    def gain(f):
        return abs(complex(np.sum(h * np.exp(-2j * np.pi * f / b.fs * n))))

    for f in (b.f_hz, b.f_hz + b.edge_bandwidth_hz, max(0.1 * f_hz, b.f_hz - b.edge_bandwidth_hz)):
        assert gain(f) == pytest.approx(1.0, abs=2e-3)
    assert gain(0.0) < 2e-3 and gain(50.0) < 2e-3
    if f_hz - 2 * b.edge_bandwidth_hz > 1500.0:
        # the stop band starts one transition (1500 Hz) below the pass band (measured
        # 6.6e-4 for the default beep; 0.12 with a 3000 Hz transition)
        assert gain(f_hz - 2 * b.edge_bandwidth_hz - 1500.0) < 1.5e-3


def test_find_bursts_times_every_burst_of_a_beep():
    """``find_bursts`` times each burst on its own (no grouping): four onsets one spacing
    apart, each within a sample of the truth at ~29 dB (measured errors <= 0.44 samples,
    sigma 0.15-0.18), and a frozen result."""
    b = Beep()
    t = np.arange(30000) / b.fs
    onset = 3000.4
    x = 0.3 * beep_continuous(t - onset / b.fs, beep=b)
    x += 0.01 * np.random.default_rng(0).standard_normal(len(x))
    bc = cp.find_bursts(x, fs=b.fs, beep=b)
    assert (bc.n_win, bc.hop) == (128, 32)
    truth = onset + np.arange(b.n_bursts) * b.spacing
    assert bc.onset.shape == (b.n_bursts,)
    assert np.all(np.abs(bc.onset - truth) < 1.0)
    assert np.all((bc.sigma > 0.08) & (bc.sigma < 0.36))
    assert np.all((bc.snr_db > 25.0) & (bc.snr_db < 33.0))
    with pytest.raises(dataclasses.FrozenInstanceError):
        bc.hop = 1  # type: ignore[misc]
    assert len(cp.find_bursts(0.01 * np.random.default_rng(1).standard_normal(20000),
                              fs=b.fs, beep=b).onset) == 0  # fmt: skip


@pytest.mark.parametrize(("amp", "found"), [(2.8, False), (3.2, True)])
def test_a_faint_beep_is_found_once_its_bursts_reach_the_per_burst_threshold(amp, found):
    """Unit white noise: each burst's edge statistic must reach 15 f_scale^(2/3) (26.9
    with the beep's filter, f_scale = 2.4) for the beep to count. Measured: amplitude 2.8
    gives nothing (a threshold of 15 f_scale^(1/3) = 20 would report it at 8.6 dB), 3.2 an
    arrival at 9.7 dB within half a sample."""
    b = Beep()
    t = np.arange(30000) / b.fs
    x = amp * beep_continuous(t - 3000.4 / b.fs, beep=b)
    x += np.random.default_rng(0).standard_normal(len(x))
    arr = cp.detect_changepoint(x, fs=b.fs, beep=b)
    assert len(arr) == int(found)
    if found:
        assert abs(arr.onset[0] - 3000.4) < 1.0 and "low_snr" in arr.flag_names(0)


def test_a_burst_is_timed_alike_wherever_its_change_point_falls_in_the_search_window():
    """``_fit_at`` searches ``[c - n_win/2 - lookback, c + n_win + hop]`` (here 240 samples
    before to 160 after ``c``): an onset anywhere inside, ends included, gets the same
    fit (the band-limited stretch reaches far enough past both ends for the fit's
    windows). Measured: -0.271 samples from the truth at every position."""
    b = Beep()
    t = np.arange(30000) / b.fs
    onset = 3000.4
    x = 0.3 * beep_continuous(t - onset / b.fs, beep=b)
    x += 0.01 * np.random.default_rng(0).standard_normal(len(x))
    cond = cp._conditioner(x, fs=b.fs, beep=b, condition=True)
    got = []
    for c in (3000 - 158, 3000 - 150, 3000, 3000 + 200, 3000 + 240):
        fit = cp._fit_at(cond, c, fs=b.fs, beep=b, n_win=128, hop=32, background=False)
        assert fit is not None, c
        got.append(fit.onset)
    np.testing.assert_allclose(got, got[2], rtol=0, atol=1e-9)
    assert abs(got[2] - onset) < 0.6


_BOUNDS = {
    "win_s": (1e-5, 1.0),
    "hop_s": (1e-7, 1.0),
    "threshold_db": (-100.0, 200.0),
    "rise_db": (-100.0, 200.0),
}


@pytest.mark.parametrize("name", sorted(_BOUNDS))
def test_parameters_are_accepted_at_their_documented_bounds_and_refused_beyond(name):
    """Each STFT/threshold parameter is accepted on its range's ends and refused just
    outside with an InvalidParameterError naming the range (silence: no arrivals)."""
    x = np.zeros(10000)
    lo, hi = _BOUNDS[name]
    for v in (lo, hi):
        assert len(cp.detect_changepoint(x, fs=44100.0, **{name: v})) == 0
    for v in (lo - abs(lo) * 0.1, hi * 1.1):
        with pytest.raises(InvalidParameterError, match=rf"{name}=.* must be within \["):
            cp.detect_changepoint(x, fs=44100.0, **{name: v})


def test_min_bursts_and_expected_domains():
    x = np.zeros(10000)
    b = Beep()
    assert len(cp.detect_changepoint(x, fs=b.fs, beep=b, min_bursts=b.n_bursts)) == 0
    with pytest.raises(InvalidParameterError, match="min_bursts=5 exceeds n_bursts=4"):
        cp.detect_changepoint(x, fs=b.fs, beep=b, min_bursts=5)
    with pytest.raises(InvalidParameterError, match="expected=0"):
        cp.detect_changepoint(x, fs=b.fs, beep=b, expected=0)


def test_samples_beyond_1e100_are_refused_and_integers_read_as_floats():
    """Squares of samples beyond MAX_SAMPLE_ABS (1e100) overflow: refused, one message;
    1e100 itself is accepted. Integer samples give the float samples' detections."""
    b = Beep()
    x = np.zeros(20000)
    x[100] = 1e100
    assert len(cp.detect_changepoint(x, fs=b.fs, beep=b)) == 0
    x[100] = 1.5e100
    with pytest.raises(InvalidParameterError, match=r"beyond \+-1e\+100"):
        cp.detect_changepoint(x, fs=b.fs, beep=b)
    w = np.zeros(20000)
    w[1000 : 1000 + b.duration_samples] = beep_waveform(b)
    w += 1e-3 * np.random.default_rng(0).standard_normal(len(w))
    pcm = np.round(w * 2**15).astype(np.int16)
    got = cp.detect_changepoint(pcm, fs=b.fs, beep=b)
    ref = cp.detect_changepoint(pcm.astype(np.float64), fs=b.fs, beep=b)
    assert len(got) == 1 and abs(got.onset[0] - 1000.0) < 0.1
    np.testing.assert_array_equal(got.onset, ref.onset)


def test_compiled_flags_equal_the_numpy_path_for_every_flag(monkeypatch):
    """One recording raising every arrival flag (a clipped loud beep, a faint one, one
    with a burst missing on a decaying in-band tail, one with an in-band precursor 16-7 ms
    before it): the compiled loop maps each of its flag bits as the reference does.
    The faint beep (amplitude 0.027 in noise 0.01) is timed one spacing early and
    flagged ``low_snr`` and ``inconsistent_bursts`` (doubtful, not confident)."""
    b = Beep()
    fs = b.fs
    t = np.arange(int(2.0 * fs)) / fs
    x = 0.01 * np.random.default_rng(0).standard_normal(len(t))
    x += beep_continuous(t - 2000.3 / fs, beep=b)
    tail = np.arange(40000, 52100)
    x[tail] += 0.05 * np.sin(2 * np.pi * b.f_hz * t[tail]) * np.exp(-(tail - 40000) / 20000)
    x += 0.03 * beep_continuous(t - 30000.6 / fs, beep=b)
    y = 0.3 * beep_continuous(t - 52000.2 / fs, beep=b)
    y[52000 + 2 * b.spacing - 50 : 52000 + 3 * b.spacing - 50] = 0.0  # burst 2 missing
    x += y + 0.4 * beep_continuous(t - 72000.5 / fs, beep=b)
    x[72000 - 700 : 72000 - 300] += 0.08 * np.sin(2 * np.pi * b.f_hz * t[:400])
    x = np.clip(x, -0.6, 0.6)
    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 10**12)
    ref = cp.detect_changepoint(x, fs=fs, beep=b)
    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 0)
    fast = cp.detect_changepoint(x, fs=fs, beep=b)
    names = [ref.flag_names(i) for i in range(len(ref))]
    assert len(ref) == 4, names
    np.testing.assert_allclose(ref.onset[[0, 2, 3]], [2000.3, 52000.2, 72000.5], atol=0.3)
    assert names[0] == ("clipped",) and "low_snr" in names[1]
    assert set(names[2]) == {"inconsistent_bursts", "reverb_limited"}
    assert names[3] == ("ambiguous_first_path",)
    np.testing.assert_array_equal(fast.flags, ref.flags)
    np.testing.assert_allclose(fast.onset, ref.onset, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(fast.confidence, ref.confidence)


def test_first_edge_is_the_earliest_peak_reaching_a_tenth_of_the_largest():
    """``_first_edge``: the earliest local maximum reaching ``max(frac * max, floor)``
    at least ``sep`` samples before the largest; otherwise the largest."""
    s = np.zeros(30)
    s[3], s[8], s[20] = 1.0, 2.0, 20.0  # 1 is below a tenth of 20; 2 is exactly a tenth
    assert cp._first_edge(s, 0.1, 0.0, sep=2) == 8
    assert cp._first_edge(s, 0.1, 2.5, sep=2) == 20  # the floor rules 2 out
    assert cp._first_edge(s, 0.04, 0.0, sep=2) == 3
    s[18] = 5.0  # a shoulder within sep of the largest is not an earlier path...
    assert cp._first_edge(s, 0.2, 0.0, sep=3) == 20
    assert cp._first_edge(s, 0.2, 0.0, sep=2) == 18  # ...one sep before it is


def test_f_scale_is_the_noise_gain_of_the_band_limiting_filter():
    """``f_scale = 1 / sum(h^2)``: white noise through the filter keeps ``sum(h^2)`` of its
    variance (measured 1 / f_scale within 1 % on 2^17 samples); 1 unconditioned."""
    b = Beep()
    taps = cp.beep_taps(b, b.fs)
    x = np.random.default_rng(0).standard_normal(1 << 17)
    cond = cp._Conditioner(x, taps, None)
    y, off = cond.segment(1000, len(x) - 1000)
    assert off == 1000
    assert float(np.var(y)) * cond.f_scale == pytest.approx(1.0, abs=0.02)  # measured 1.009
    assert cond.f_scale == pytest.approx(1.0 / float(taps @ taps), rel=1e-12)
    assert cp._Conditioner(x, None, None).f_scale == 1.0


def test_anchor_of_any_burst_is_the_beep_start_and_noise_has_fewer_than_two_rises():
    """``_anchor``: a change point at burst k of a beep gives the beep's start (k spacings
    earlier) with all four burst places rising; a change point in noise before the beep
    has fewer than two rising places (it is not an anchor)."""
    b = Beep()
    t = np.arange(40000) / b.fs
    x = 0.3 * beep_continuous(t - 8000.4 / b.fs, beep=b)
    x += 0.01 * np.random.default_rng(0).standard_normal(len(x))
    n_win, hop, e, _, _ = cp._candidates(
        x, fs=b.fs, beep=b, win_s=cp.WIN_S, hop_s=cp.HOP_S, threshold_db=6.0, rise_db=10.0
    )
    kw = {"hop": hop, "n_win": n_win, "spacing": float(b.spacing), "beep": b, "fs": b.fs}
    for k in range(b.n_bursts):
        assert cp._anchor(8000 + k * b.spacing, e, **kw) == (8000, b.n_bursts)
    assert cp._anchor(1000, e, **kw)[1] < 2


@pytest.mark.parametrize("amp", [0.03, 0.2])
def test_a_burst_like_blip_one_spacing_early_does_not_move_the_beep(amp):
    """A lone in-band burst one spacing before a beep makes a second group (the blip and
    the beep's bursts 0-2, all four agreeing); the two share three bursts within
    2 fs/44100 + 2 samples, so the stronger, the beep, is kept (without that rule the
    earlier group wins as the echo rule's first arrival: 5000.3, confidently wrong)."""
    b = Beep()
    t = np.arange(40000) / b.fs
    x = 0.3 * beep_continuous(t - 10000.4 / b.fs, beep=b)
    x += amp * beep_continuous(t - 5000.4 / b.fs, beep=Beep(n_bursts=1))
    x += 0.01 * np.random.default_rng(0).standard_normal(len(x))
    arr = cp.detect_changepoint(x, fs=b.fs, beep=b)
    assert len(arr) == 1 and abs(arr.onset[0] - 10000.4) < 0.3  # measured -0.12


def test_compiled_beep_loop_searches_the_reference_window_anchor_by_anchor():
    """One anchor at a time, at offsets spanning the documented search window (onset -
    anchor from -(n_win/2 + lookback) + taper to n_win + hop - taper: -217 ... 139 here):
    the compiled loop finds the beep exactly where the numpy reference does, with the
    same numbers, and neither finds it just before the early end. Past the late end
    (140 ... 173 measured) the edge's rise is still in the window: both re-anchor on it
    and find the beep (a click or noise peak just before a beep); from 174 its statistic
    no longer reaches the threshold inside the window."""
    b = Beep()
    t = np.arange(30000) / b.fs
    x = 0.3 * beep_continuous(t - 3000.4 / b.fs, beep=b)
    x += 0.01 * np.random.default_rng(0).standard_normal(len(x))
    n_win, hop, e, _, _ = cp._candidates(
        x, fs=b.fs, beep=b, win_s=cp.WIN_S, hop_s=cp.HOP_S, threshold_db=6.0, rise_db=10.0
    )
    kw = {"fs": b.fs, "beep": b, "n_win": n_win, "hop": hop, "background": True,
          "min_bursts": 3, "quiet": 0.0, "oob": False}  # fmt: skip
    ref_cond = cp._conditioner(x, fs=b.fs, beep=b, condition=True)
    fast_cond = cp._conditioner(x, fs=b.fs, beep=b, condition=True, compiled=True)
    offsets = ((-218, False), (-217, True), (0, True), (139, True), (140, True), (173, True))
    for off, found in (*offsets, (174, False)):
        ref = cp._beep_row(ref_cond, 3000 - off, e, cp._Found(), **kw)
        fast = cp._rows_compiled(fast_cond, np.array([3000 - off]), e, **kw)
        assert (ref is not None) == found == (len(fast) == 1), off
        if found:
            assert abs(ref[0] - 3000.4) < 0.3  # measured -0.14
            np.testing.assert_allclose(fast[0][:4], ref[:4], rtol=1e-9, atol=1e-6)
            np.testing.assert_allclose(fast[0][4], ref[4], rtol=0, atol=1e-6)
            assert fast[0][5] == ref[5]


def test_noise_floor_is_local_to_quarter_second_stretches_and_ignores_a_burst():
    """``_floor``: the band energy's noise level per FLOOR_BLOCK_S (0.25 s) stretch, from
    its 20th percentile: a 20-frame burst 40 dB up does not raise the floor under it
    (measured 1.20 for noise of mean 1), and a stretch whose noise is 20 dB up a second
    later has its own level (measured 91 for mean 100)."""
    rng = np.random.default_rng(0)
    fs, hop = 44100.0, 32
    n = int(fs / hop)  # one second of frames
    e = rng.exponential(1.0, 2 * n)
    e[n:] *= 100.0
    e[300:320] = 1e4
    f = cp._floor(e, fs=fs, hop=hop)
    assert np.all((f[300:320] > 0.6) & (f[300:320] < 2.0))
    assert 0.6 < f[100] < 2.0  # measured 1.33
    assert 50.0 < f[n + 400] < 200.0


@pytest.mark.parametrize("n_bursts", [1, 2])
def test_one_and_two_burst_beeps_on_both_paths(n_bursts, monkeypatch):
    """Default ``min_bursts`` is 1 for a one-burst beep and 2 (all but one, at least 2)
    for two bursts; both are found, the compiled path giving the reference's onset."""
    b = Beep(n_bursts=n_bursts)
    t = np.arange(20000) / b.fs
    x = 0.3 * beep_continuous(t - 3000.4 / b.fs, beep=b)
    x += 0.01 * np.random.default_rng(0).standard_normal(len(x))
    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 10**12)
    ref = cp.detect_changepoint(x, fs=b.fs, beep=b)
    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 0)
    fast = cp.detect_changepoint(x, fs=b.fs, beep=b)
    assert len(ref) == len(fast) == 1 and abs(ref.onset[0] - 3000.4) < 0.3  # measured 0.18
    assert ref.confidence[0] == 1.0
    np.testing.assert_allclose(fast.onset, ref.onset, rtol=0, atol=1e-6)


def test_default_min_bursts_is_all_but_one():
    """Four bursts, two of them blanked: the default (3 agreeing) finds nothing,
    ``min_bursts=2`` finds the beep, flagged ``inconsistent_bursts``."""
    b = Beep()
    t = np.arange(30000) / b.fs
    x = 0.3 * beep_continuous(t - 3000.4 / b.fs, beep=b)
    for k in (2, 3):
        x[3000 + k * b.spacing - 50 : 3000 + k * b.spacing + 600] = 0.0
    x += 0.01 * np.random.default_rng(0).standard_normal(len(x))
    assert len(cp.detect_changepoint(x, fs=b.fs, beep=b)) == 0
    arr = cp.detect_changepoint(x, fs=b.fs, beep=b, min_bursts=2)
    assert len(arr) == 1 and arr.flag_names(0) == ("inconsistent_bursts",)
    assert arr.confidence[0] == 0.5


def test_precursor_level_before_is_the_stretch_just_before_the_near_one():
    """The level a precursor must rise over is the mean of the ``PRE_NEAR_S`` stretch just
    before the near one (not anything earlier: a loud stretch before that is ignored)."""
    hop, n_win, fs = 32, 128, 44100.0
    near = int(round(cp.PRE_NEAR_S * fs / hop))
    t0 = 400 * hop + n_win
    e = np.full(400, 100.0)  # loud long before
    e[400 - 2 * near :] = 1.0  # the level before
    e[400 - 30 :] = 10**1.2  # 12 dB up just before the onset
    got = cp._before_onset_flags(e, t0, hop=hop, n_win=n_win, fs=fs, quiet=1.0)
    assert got & flag_bit("ambiguous_first_path")


def test_a_beep_after_a_quiet_stretch_needs_only_threshold_db_over_the_floor():
    """``threshold_db`` (6 dB) decides where the level just before a burst is far below
    the stretch's floor (noise gated off for 35 ms around each burst, as a phone's noise
    suppressor does): the 10 dB rise over that quiet level is met at once, and a burst
    whose band energy is 6-12 dB over the 0.25 s floor starts a change point. At peak
    0.015 in noise of 0.05 the beep is found with the default (measured 0.24 samples
    early of 20000.3... within 0.3) and lost with 12 dB (lost up to 0.02, found from
    0.025 on: measured)."""
    b = Beep()
    t = np.arange(60000) / b.fs
    noise = 0.05 * np.random.default_rng(0).standard_normal(len(t))
    for k in range(b.n_bursts):
        p = 20000 + k * b.spacing
        noise[p - 1000 : p + 600] *= 0.01
    x = 0.015 * beep_continuous(t - 20000.3 / b.fs, beep=b) + noise
    arr = cp.detect_changepoint(x, fs=b.fs, beep=b)
    assert len(arr) == 1 and abs(arr.onset[0] - 20000.3) < 0.3  # measured 0.24 - 0.3
    assert len(cp.detect_changepoint(x, fs=b.fs, beep=b, threshold_db=12.0)) == 0


def _flags_on_both_paths(e_edit):
    """Flags of one clean beep at 6000.4 on the numpy and the compiled path, with the band
    energy the flags read replaced by ones edited by ``e_edit(e, t0)``."""
    b = Beep()
    t = np.arange(40000) / b.fs
    x = 0.3 * beep_continuous(t - 6000.4 / b.fs, beep=b)
    x += 0.01 * np.random.default_rng(0).standard_normal(len(x))
    n_win, hop, e, _, _ = cp._candidates(
        x, fs=b.fs, beep=b, win_s=cp.WIN_S, hop_s=cp.HOP_S, threshold_db=6.0, rise_db=10.0
    )
    e = np.ones(len(e))
    e_edit(e, 6000.4 + np.arange(b.n_bursts) * b.spacing, n_win, hop)
    kw = {"fs": b.fs, "beep": b, "n_win": n_win, "hop": hop, "background": True,
          "min_bursts": 3, "quiet": 0.0, "oob": False}  # fmt: skip
    ref = cp._beep_row(
        cp._conditioner(x, fs=b.fs, beep=b, condition=True), 6000, e, cp._Found(), **kw
    )
    fast = cp._rows_compiled(
        cp._conditioner(x, fs=b.fs, beep=b, condition=True, compiled=True),
        np.array([6000]), e, **kw,
    )  # fmt: skip
    assert ref is not None and len(fast) == 1 and abs(ref[0] - 6000.4) < 0.3
    return ref[5], fast[0][5]


@pytest.mark.parametrize(("rise_db", "flagged"), [(9.8, False), (10.2, True)])
def test_precursor_run_threshold_is_pre_rise_db_on_both_paths(rise_db, flagged):
    """The run test's 10 dB on the compiled path as on the numpy one (the kernel gets
    ``10 ** (PRE_RISE_DB / 10)``): a 30-frame precursor 9.8 dB up before the first burst
    is not flagged, 10.2 dB is."""

    def edit(e, onsets, n_win, hop):
        end = int(onsets[0] - n_win) // hop
        e[end - 30 : end] = 10 ** (rise_db / 10)

    ref, fast = _flags_on_both_paths(edit)
    bit = flag_bit("ambiguous_first_path")
    assert bool(ref & bit) == bool(fast & bit) == flagged


@pytest.mark.parametrize(("rise_db", "flagged"), [(7.8, False), (8.2, True)])
def test_last_frames_threshold_is_pre_last_db_in_every_burst_on_both_paths(rise_db, flagged):
    """The one-by-one test of the frames just before the onset: one frame ``PRE_LAST_DB``
    (8 dB) up before every burst flags ``ambiguous_first_path`` (7.8 dB does not), on both
    paths; the same frame before three of the four bursts only (an echo of the burst
    before) does not."""
    for n_up in (4, 3):

        def edit(e, onsets, n_win, hop, n_up=n_up):
            for k, t in enumerate(onsets):
                last = cp._last_frames(float(t), hop=hop, n_win=n_win, fs=44100.0)[0]
                if k >= len(onsets) - n_up:
                    e[last - 2] = 10 ** (rise_db / 10)

        ref, fast = _flags_on_both_paths(edit)
        bit = flag_bit("ambiguous_first_path")
        assert bool(ref & bit) == bool(fast & bit) == (flagged and n_up == 4), n_up


def test_quiet_level_is_the_tenth_percentile_of_the_stretch_floors():
    """``reverb_limited`` compares the level before an arrival with the recording's quiet
    level, the 10th percentile of its 0.25 s floors: a recording quiet (14 dB down) for
    its first eighth, the beep in the loud rest, is flagged; all loud, it is not."""
    b = Beep()
    t = np.arange(int(4.0 * b.fs)) / b.fs
    x = 0.3 * beep_continuous(t - 2.0, beep=b)
    for quiet_part, flagged in ((True, True), (False, False)):
        noise = 0.01 * np.random.default_rng(1).standard_normal(len(t))
        if quiet_part:
            noise[: len(t) // 8] *= 0.2
        arr = cp.detect_changepoint(x + noise, fs=b.fs, beep=b)
        assert len(arr) == 1
        assert ("reverb_limited" in arr.flag_names(0)) == flagged
