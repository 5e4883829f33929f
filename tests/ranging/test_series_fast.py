"""``rangekit.ranging.series`` on short recordings: the properties ``test_series.py`` checks
on 30 s files (one range per exchange, block boundaries that change nothing, a failed
exchange flagged and the series going on, the ultrasonic windows equal to the whole-file
code), plus the pieces one at a time (grouping, block reading, rows). Issue 21: the mutation
check of the module runs this file, ~10 s (``test_series.py`` takes ~100 s CPU).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import soundfile as sf

from rangekit.errors import DetectionError, IncompatibleInputError, InvalidParameterError
from rangekit.ranging import series as S
from rangekit.ranging.tof import ToF
from rangekit.ranging.ultrasonic import range_ultrasonic_files
from rangekit.signals.beep import Beep
from rangekit.sim.recording import pair_devices, render_beepbeep
from rangekit.types import Range

FS = 44100
PERIOD = int(2.5 * FS)
NOISE = 2e-3
US_FS = 192000
CYCLE = 13440


@pytest.fixture(scope="module")
def exchange():
    return render_beepbeep(pair_devices(2.0, self_distance_m=0.1), snr_db=None)


def _tiled(path, tile, *, count, rng, edit=None, period=PERIOD, subtype="PCM_16"):
    tile = np.asarray(tile, dtype=float)
    with sf.SoundFile(path, "w", FS, tile.shape[1], subtype) as f:
        for k in range(count):
            t = np.zeros((period, tile.shape[1]))
            t[: min(period, len(tile))] = tile[:period]
            if edit is not None:
                edit(k, t)
            f.write(t + NOISE * rng.standard_normal(t.shape))
    return path


@pytest.fixture(scope="module")
def three(exchange, tmp_path_factory):
    """3 exchanges 2.5 s apart (7.5 s, stereo)."""
    one = np.stack(exchange.recordings, axis=1)
    path = tmp_path_factory.mktemp("s") / "three.wav"
    return _tiled(path, one, count=3, rng=np.random.default_rng(1))


@pytest.fixture(scope="module")
def whole_blocks(three):
    return list(S.range_series_beepbeep([three], self_distance_m=0.1))


def test_every_exchange_once_with_its_time_distance_and_arrivals(exchange, whole_blocks):
    ex = whole_blocks
    assert [e.exchange for e in ex] == [0, 1, 2]
    t0 = exchange.onsets[0, 0] / FS
    assert [e.t_s for e in ex] == pytest.approx([t0 + 2.5 * k for k in range(3)], abs=2e-5)
    for e in ex:
        assert e.error is None and e.ranges[0].distance_m == pytest.approx(2.0, abs=0.01)
        # the arrivals are file sample indices: device 0's own beep is the anchor
        assert e.arrivals[0].onset[0] / FS == pytest.approx(e.t_s, abs=1e-9)
        assert len(e.arrivals) == 2 and all(len(a) == 2 for a in e.arrivals)


def _same_series(got, want):
    """Same exchanges, times and ranges (to rounding: a block's detection sums differ)."""
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        assert a.exchange == b.exchange and a.t_s == pytest.approx(b.t_s, abs=1e-9)
        (ra,), (rb,) = a.ranges, b.ranges
        assert ra.distance_m == pytest.approx(rb.distance_m, abs=1e-9)
        assert ra.sigma_m == pytest.approx(rb.sigma_m, rel=1e-9) and ra.flags == rb.flags


@pytest.mark.parametrize("block_s", [1.0, 2.6])
def test_block_boundaries_do_not_change_the_series(three, whole_blocks, block_s):
    """1.0 s blocks cut every exchange (first beep 0.15 s into its period, ~1 s long);
    2.6 s blocks put the boundary just after exchange 1's anchor."""
    seen = []
    got = list(S.range_series_beepbeep([three], self_distance_m=0.1, block_s=block_s,
                                       progress=lambda d, t: seen.append((d, t))))  # fmt: skip
    _same_series(got, whole_blocks)
    assert len(seen) == math.ceil(7.5 / block_s)
    assert all(t == pytest.approx(7.5) for _, t in seen)
    done = [d for d, _ in seen]
    assert done == sorted(done) and done[-1] == pytest.approx(7.5)
    assert done[0] == pytest.approx(block_s, abs=1 / FS)


def test_parallel_jobs_give_the_same_series(three, whole_blocks):
    got = list(S.range_series_beepbeep([three], self_distance_m=0.1, block_s=2.6, jobs=2))
    _same_series(got, whole_blocks)


def test_speed_self_distance_and_clock_reach_the_ranges(three, whole_blocks):
    got = list(S.range_series_beepbeep([three], self_distance_m=0.2, speed_m_s=350.0,
                                       clock_ppm=0.0))  # fmt: skip
    c0 = S.Medium().c
    for a, b in zip(got, whole_blocks, strict=True):
        assert a.ranges[0].distance_m - 0.2 == pytest.approx(
            (b.ranges[0].distance_m - 0.1) * 350.0 / c0, rel=1e-9
        )
        assert a.ranges[0].sigma_m < b.ranges[0].sigma_m  # no clock tolerance


def test_two_mono_files_equal_one_stereo_file(exchange, tmp_path, whole_blocks, three):
    x, _ = sf.read(three)
    mono = [tmp_path / f"d{i}.wav" for i in range(2)]
    for i, p in enumerate(mono):
        sf.write(p, x[:, i], FS, "PCM_16")
    got = list(S.range_series_beepbeep(mono, self_distance_m=0.1, block_s=2.6))
    _same_series(got, whole_blocks)


def test_a_failed_exchange_is_flagged_and_the_series_goes_on(exchange, tmp_path):
    one = np.stack(exchange.recordings, axis=1)
    on = int(exchange.onsets[1, 1])

    def edit(k, t):
        if k == 1:
            t[on - 100 : on + Beep().duration_samples + 100, 1] = 0.0

    path = _tiled(tmp_path / "gap.wav", one, count=3, rng=np.random.default_rng(3), edit=edit)
    ex = list(S.range_series_beepbeep([path], self_distance_m=0.1, block_s=1.5))
    assert [e.error is None for e in ex] == [True, False, True]
    bad = ex[1]
    (r,) = bad.ranges
    assert math.isnan(r.distance_m) and math.isnan(r.sigma_m) and r.flags == ("detection",)
    assert bad.arrivals is None and bad.exchange == 1
    exs = S.default_exchange_s(Beep(), 2)
    assert bad.error == (
        f"exchange 1 at {bad.t_s:.3f} s: '{path}#1' has 1 beep(s) where 2 (one per device) "
        f"were expected within {exs:g} s (+-0.1 s)"
    )
    assert ex[2].ranges[0].distance_m == pytest.approx(2.0, abs=0.01)


def test_no_beep_at_all_raises_at_the_end(tmp_path):
    path = tmp_path / "noise.wav"
    sf.write(path, NOISE * np.random.default_rng(4).standard_normal((2 * FS, 2)), FS)
    with pytest.raises(DetectionError, match=r"noise\.wav#0': no beep found in 2\.0 s"):
        list(S.range_series_beepbeep([path], block_s=1.0))


@pytest.mark.parametrize(
    "kw",
    [{"detector": "nope"}, {"block_s": 0.0}, {"skew_s": -1.0}, {"exchange_s": 0.0},
     {"clock_ppm": -1.0}, {"clock_ppm": 2e4}, {"speed_m_s": 5.0}, {"jobs": 0}],
)  # fmt: skip
def test_parameters_are_checked_at_the_call(kw):
    with pytest.raises(InvalidParameterError):
        S.range_series_beepbeep(["never-read.wav"], **kw)


def test_files_are_checked_when_iterating(three, tmp_path):
    assert S.range_series_beepbeep(["never-read.wav"], skew_s=0.0) is not None
    with pytest.raises(IncompatibleInputError, match="3 self-distances"):
        list(S.range_series_beepbeep([three], self_distance_m=[0.1, 0.1, 0.1]))
    mono = tmp_path / "mono.wav"
    sf.write(mono, np.zeros(FS), FS)
    with pytest.raises(IncompatibleInputError, match="has 1 channel"):
        list(S.range_series_beepbeep([mono]))
    with pytest.raises(IncompatibleInputError, match="each must be mono"):
        list(S.range_series_beepbeep([mono, three]))
    with pytest.raises(IncompatibleInputError, match="no input files"):
        list(S.range_series_beepbeep([]))
    low = tmp_path / "low.wav"
    sf.write(low, np.zeros((8000, 2)), 8000)
    with pytest.raises(IncompatibleInputError, match=r"low\.wav"):
        list(S.range_series_beepbeep([low]))


def test_grouping_anchors_on_device_0_within_the_core():
    d0 = np.array([0.5, 1.1, 3.0, 3.6, 6.0, 6.6])
    d1 = np.array([0.45, 1.15, 2.95, 3.65, 6.05, 6.65])
    kw = {"exchange_s": 0.85, "skew_s": 0.1}
    groups, after = S._group_exchanges([d0, d1], lo_s=0.0, hi_s=5.0, after_s=-math.inf, **kw)
    assert [j for j, _ in groups] == [0, 2]
    assert [m.tolist() for m in groups[0][1]] == [[0, 1], [0, 1]]
    assert after == pytest.approx(3.95)
    groups, _ = S._group_exchanges([d0, d1], lo_s=5.0, hi_s=10.0, after_s=after, **kw)
    assert [j for j, _ in groups] == [4]
    assert S._group_exchanges([d0, d1], lo_s=1.0, hi_s=2.0, after_s=1.35, **kw)[0] == []
    # the core is [lo, hi): an anchor at lo is this block's, one at hi the next one's
    assert [j for j, _ in S._group_exchanges([d0], lo_s=3.0, hi_s=6.0, after_s=0.0, **kw)[0]] == [2]
    assert S._group_exchanges([d0], lo_s=2.0, hi_s=3.0, after_s=0.0, **kw)[0] == []
    # an anchor at exactly the previous window's end belongs to that exchange
    assert S._group_exchanges([d0], lo_s=0.0, hi_s=9.0, after_s=3.0, **kw)[0][0][0] == 3
    # the windows are closed: device 0 in [t0, t0 + x + skew], device i from t0 - skew
    e0 = np.array([1.0, 1.95])
    e1 = np.array([0.9, 1.95, 1.96])
    ((_, (m0, m1)),), end = S._group_exchanges([e0, e1], lo_s=0, hi_s=2, after_s=-1, **kw)
    assert m0.tolist() == [0, 1] and m1.tolist() == [0, 1] and end == pytest.approx(1.95)


def test_default_exchange_and_block():
    b = Beep()
    assert S.default_exchange_s(b, 2) == pytest.approx(b.duration_s + 0.5)
    assert S.default_exchange_s(b, 4) == pytest.approx(3 * (b.duration_s + 0.5))
    assert S._block_s(None, fs=44100.0, n_channels=2) == (S.DEFAULT_BLOCK_SAMPLES // 2) / 44100.0
    assert S._block_s(3.0, fs=44100.0, n_channels=2) == 3.0
    # the documented memory bound: 2^21 samples, 16 MB of float64 (23.8 s of a stereo
    # 44.1 kHz recording, 10.9 s of a mono 192 kHz one)
    assert S._block_s(None, fs=44100.0, n_channels=2) == pytest.approx(23.78, abs=0.005)
    assert S._block_s(None, fs=192000.0, n_channels=1) == pytest.approx(10.92, abs=0.005)
    assert S.DEFAULT_BLOCK_SAMPLES * 8 == 16 * 2**20
    with pytest.raises(InvalidParameterError):
        S._block_s(0.0, fs=44100.0, n_channels=2)


def test_rows_turn_nan_into_none():
    e = S.ExchangeRanges(3, 1.25, (Range(0, 1, 2.0, 0.01, ("low_snr",)),
                                   Range(0, 2, math.nan, math.nan, ("detection",))))  # fmt: skip
    assert e.rows() == [
        {"t_s": 1.25, "a": 0, "b": 1, "distance_m": 2.0, "sigma_m": 0.01, "flags": ["low_snr"]},
        {"t_s": 1.25, "a": 0, "b": 2, "distance_m": None, "sigma_m": None, "flags": ["detection"]},
    ]
    assert S._finite_or_none(math.inf) is None and S._finite_or_none(np.float32(2.5)) == 2.5
    tof = ToF(window=4, tx=2, channel=1, distance_m=1.5, sigma_m=0.001, snr_db=20.0,
              arrival_s=0.004)  # fmt: skip
    w = S.WindowRanges(4, 0.28, (tof,))
    (one,) = w.rows(scheme="oneway")
    assert list(one) == list(S.SERIES_FIELDS["oneway"]) and one["tx"] == 2
    (ec,) = w.rows(scheme="echo")
    assert list(ec) == list(S.SERIES_FIELDS["echo"]) and ec["t_s"] == 0.28


def test_series_items_are_frozen():
    import dataclasses

    e = S.ExchangeRanges(0, 1.0, ())
    w = S.WindowRanges(0, 0.0, ())
    plan = S._BlockPlan(step=10, fs0=1.0, pre_s=0.0, post_s=0.0, signal=None, method="x")
    for obj, attr in ((e, "t_s"), (w, "window"), (plan, "step")):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(obj, attr, 5)


def test_read_block_integer_pcm_exact_in_float32(tmp_path):
    x = np.random.default_rng(9).uniform(-0.9, 0.9, (1000, 2))
    # PCM_16/24 are scaled by numpy, U8 and mu-law decoded by libsndfile into float32:
    # both integer routes, and the checked float64 route of a float file
    subtypes = ("PCM_16", "PCM_24", "PCM_U8", "ULAW")
    for sub, dtype in [(s, np.float32) for s in subtypes] + [("FLOAT", np.float64)]:
        p = tmp_path / f"{sub}.wav"
        sf.write(p, x, FS, sub)
        ref, _ = sf.read(p, dtype="float64")
        with sf.SoundFile(p) as f:
            got = S._read_block(f, 100, 400)
            assert got.shape == (2, 300) and got.dtype == dtype
            assert got.flags.c_contiguous and got[1].flags.c_contiguous
            np.testing.assert_array_equal(got.astype(np.float64), ref[100:400].T)
            clip = S._read_block(f, -50, 5000)  # clipped to the file
            assert clip.shape == (2, 1000)
            np.testing.assert_array_equal(clip.astype(np.float64), ref.T)
            assert S._read_block(f, 1200, 1300).shape == (2, 0)
            assert S._read_block(f, 500, 500).shape == (2, 0)


def test_window_rows_stop_at_the_end():
    from rangekit.ranging.ultrasonic import window_starts

    for n, per in ((1049, 100.0), (1051, 100.0), (999, 33.3333)):
        ref = window_starts(n, fs=1.0, period_s=per)
        for step in (1, 3, 1000):
            got = np.concatenate([S._window_rows(k, k + step, n, per)
                                  for k in range(0, len(ref) + step, step)])  # fmt: skip
            np.testing.assert_array_equal(got, ref)
    # a last window of exactly half a period is one, a shorter one is not
    assert S._window_rows(0, 5, 250, 100.0).tolist() == [[0, 100], [100, 200], [200, 250]]
    assert S._window_rows(0, 5, 249, 100.0).tolist() == [[0, 100], [100, 200]]


# --- ultrasonic ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def echo_log(tmp_path_factory):
    """8 SRF02 cycles at 1.5 m from a wall; cycle 3 without its echo."""
    from rangekit.floorplan import FloorPlan
    from rangekit.sim.ultrasonic import render_echo

    plan = FloorPlan.from_walls([((1.5, -5), (1.5, 5)), ((-9, -5), (-9, 5))])
    cyc = render_echo(plan, [(0.0, 0.0, 0.0)], snr_db=None).x[0][:CYCLE]
    cyc = 0.5 * cyc / np.max(np.abs(cyc))
    x = np.tile(cyc, 8) + 1e-3 * np.random.default_rng(5).standard_normal(8 * CYCLE)
    x[3 * CYCLE + 1000 : 3 * CYCLE + 9000] = 1e-3 * np.random.default_rng(6).standard_normal(8000)
    path = tmp_path_factory.mktemp("e") / "echo.wav"
    sf.write(path, x, US_FS, "PCM_16")
    return path


@pytest.mark.parametrize("block_s", [0.07, 0.2, None])
def test_echo_series_equals_the_whole_file_path(echo_log, block_s):
    """Each window fitted on its own (pool=False): the series is the whole-file code."""
    whole = range_ultrasonic_files([echo_log], scheme="echo", period_s=0.07, pool=False)
    seen = []
    got = list(S.range_series_ultrasonic(echo_log, scheme="echo", period_s=0.07, pool=False,
                                         block_s=block_s, progress=lambda d, t: seen.append(
                                             (d, t))))  # fmt: skip
    assert [w.window for w in got] == list(range(8))
    assert [w.t_s for w in got] == pytest.approx([k * 0.07 for k in range(8)], abs=1e-12)
    rows = [r for w in got for r in w.rows(scheme="echo")]
    assert len(rows) == len(whole) == 8
    for r, q in zip(rows, whole, strict=True):
        for k in ("distance_m", "sigma_m", "snr_db", "arrival_s"):
            assert (r[k] is None) == (q[k] is None)
            if q[k] is not None:
                assert r[k] == pytest.approx(q[k], rel=1e-9, abs=1e-12)
    assert rows[3]["distance_m"] is None
    assert rows[0]["distance_m"] == pytest.approx(1.5, abs=2e-3)
    per_block = 1 if block_s == 0.07 else (2 if block_s == 0.2 else 8)
    assert len(seen) == math.ceil(8 / per_block)
    assert seen[-1] == pytest.approx((0.56, 0.56)) and seen == sorted(seen)


def test_ultrasonic_blocks_read_the_filter_context_before_a_window(tmp_path):
    from rangekit.detect.matched import coded_template

    h = coded_template(fs=US_FS)
    per = 1920
    x = 1e-2 * np.random.default_rng(7).standard_normal(6 * per)
    for k in range(6):
        x[k * per + 3 : k * per + 3 + len(h)] += 0.5 * h / np.max(np.abs(h))
    path = tmp_path / "near.wav"
    sf.write(path, x, US_FS, "PCM_16")
    kw = {"period_s": per / US_FS, "tx": None, "rx": None, "speed_m_s": 343.0}
    whole = range_ultrasonic_files([path], scheme="oneway", **kw)
    got = [r for w in S.range_series_ultrasonic(path, scheme="oneway", block_s=0.02, **kw)
           for r in w.tofs]  # fmt: skip
    assert len(got) == len(whole) == 6
    for r, q in zip(got, whole, strict=True):
        assert r.distance_m == pytest.approx(q["distance_m"], rel=1e-12)


def test_ultrasonic_series_errors(tmp_path):
    path = tmp_path / "quiet.wav"
    sf.write(path, np.zeros((US_FS // 10, 3)), US_FS)
    with pytest.raises(DetectionError, match=r"quiet\.wav': no burst found"):
        list(S.range_series_ultrasonic(path, scheme="oneway", period_s=0.04, block_s=0.1))
    # 0.1 s in windows of 0.04 s: the last, half a period, is a window
    assert len(list(S.range_series_ultrasonic(path, scheme="echo", period_s=0.04))) == 3
    with pytest.raises(InvalidParameterError, match="shorter than two samples"):
        list(S.range_series_ultrasonic(path, scheme="echo", period_s=1.5 / US_FS))
    # exactly two samples pass the series' check (the echo's own blanking then refuses)
    with pytest.raises(IncompatibleInputError, match="ring-down blanking"):
        list(S.range_series_ultrasonic(path, scheme="echo", period_s=2.0 / US_FS))
    for kw in ({"scheme": "beepbeep", "period_s": 0.07}, {"scheme": "echo", "period_s": 0.0},
               {"scheme": "echo", "period_s": 0.07, "block_s": -1.0},
               {"scheme": "echo", "period_s": 0.07, "channels": 0},
               {"scheme": "echo", "period_s": 0.07, "fs": 1.0}):  # fmt: skip
        with pytest.raises(InvalidParameterError):
            S.range_series_ultrasonic(path, **kw)
