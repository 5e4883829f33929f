"""Long recordings ranged block by block (rangekit.ranging.series).

The recordings are one simulated exchange (or ranging cycle) tiled with fresh noise and
written block-wise with soundfile; every exchange has the same truth, so each must be
found once, at its own time, with the true distance, whatever the block size.
"""

from __future__ import annotations

import math
import tracemalloc

import numpy as np
import pytest
import soundfile as sf

from rangekit.errors import (
    DetectionError,
    IncompatibleInputError,
    InputFileError,
    InvalidParameterError,
)
from rangekit.ranging import range_files
from rangekit.ranging.series import (
    SERIES_FIELDS,
    _group_exchanges,
    _window_rows,
    default_exchange_s,
    range_series_beepbeep,
    range_series_ultrasonic,
)
from rangekit.ranging.ultrasonic import (
    range_oneway,
    range_ultrasonic_files,
    window_starts,
)
from rangekit.signals.beep import Beep
from rangekit.sim.recording import pair_devices, render_beepbeep
from rangekit.sim.ultrasonic import render_oneway

FS = 44100
PERIOD = int(2.5 * FS)  # an exchange every 2.5 s
NOISE = 2e-3
US_FS = 192000
CYCLE = 13440  # 70 ms at 192 kHz


@pytest.fixture(scope="module")
def exchange():
    """One noiseless exchange of two devices 2 m apart (self-distance 0.1 m), 1.26 s."""
    return render_beepbeep(pair_devices(2.0, self_distance_m=0.1), snr_db=None)


def _write_tiled(path, tile, *, period, count, fs, rng, edit=None, noise=NOISE):
    """``count`` periods of ``tile`` (samples, channels) plus fresh noise, block by block."""
    tile = np.asarray(tile, dtype=float)
    tile = tile[:, None] if tile.ndim == 1 else tile
    with sf.SoundFile(path, "w", fs, tile.shape[1], "PCM_16") as f:
        for k in range(count):
            t = np.zeros((period, tile.shape[1]))
            t[: min(period, len(tile))] = tile[:period]
            if edit is not None:
                edit(k, t)
            f.write(t + noise * rng.standard_normal(t.shape))
    return path


@pytest.fixture(scope="module")
def series_wav(exchange, tmp_path_factory):
    """12 exchanges, 2.5 s apart (30 s, stereo, 44.1 kHz)."""
    one = np.stack(exchange.recordings, axis=1)
    path = tmp_path_factory.mktemp("series") / "series.wav"
    return _write_tiled(path, one, period=PERIOD, count=12, fs=FS, rng=np.random.default_rng(1))


def _t0(exchange, k: int) -> float:
    return k * PERIOD / FS + exchange.onsets[0, 0] / FS


# --- two-way ------------------------------------------------------------------------------


def test_every_exchange_is_found_once_with_its_time_and_distance(exchange, series_wav):
    ex = list(range_series_beepbeep([series_wav], self_distance_m=0.1))
    assert [e.exchange for e in ex] == list(range(12))
    for k, e in enumerate(ex):
        assert e.error is None
        # Within 2x of today (issue 21): |t_s error| <= 0.51 us (was < 20 us), |distance
        # error| <= 3.18 mm (was < 1 cm), sigma 9.00-9.28 mm (was 0.1-10 mm), mostly the
        # 30 ppm clock term.
        assert e.t_s == pytest.approx(_t0(exchange, k), abs=1.1e-6)
        (r,) = e.ranges
        assert (r.a, r.b, r.flags) == (0, 1, ())
        assert r.distance_m == pytest.approx(2.0, abs=6.4e-3)
        assert 4.5e-3 < r.sigma_m < 18e-3


def test_every_block_of_a_long_recording_takes_the_compiled_kernels(series_wav, monkeypatch):
    """The 30 s file (1.32 M frames) is long enough for the compiled kernels; its 1.7 s
    blocks (~0.2 M frames with their margins) are not, and took the numpy path until
    2026-12-04 (the last block of a 10-minute file too: ~10 % of the series' CPU). The
    detector now chooses by the recording's length (``recording_samples``): no block
    reaches the numpy band energy, and the exchanges are the one-block ones."""
    import rangekit.detect._kernels as K

    ref = list(range_series_beepbeep([series_wav], self_distance_m=0.1, block_s=60.0))

    def refused(*a, **k):
        raise AssertionError("a block of a long recording took the numpy band energy")

    monkeypatch.setattr(K, "_band_energy_reference", refused)
    got = list(range_series_beepbeep([series_wav], self_distance_m=0.1, block_s=1.7))
    assert len(got) == len(ref) == 12
    for a, b in zip(got, ref, strict=True):
        # measured (the blocks' own rounding, as with the numpy path before): t_s 3.6e-15
        # s, distance 1.22e-12 m, sigma 4.0e-15 m
        assert a.t_s == pytest.approx(b.t_s, abs=1e-14)
        assert a.ranges[0].distance_m == pytest.approx(b.ranges[0].distance_m, abs=2.5e-12)
        assert a.ranges[0].sigma_m == pytest.approx(b.ranges[0].sigma_m, abs=1e-14)
    assert not K.long_recording()  # the hint does not outlive the series


@pytest.mark.parametrize("block_s", [1.7, 2.65])
def test_block_boundaries_do_not_change_the_series(series_wav, block_s):
    """Exchanges (first beep at 0.15 + 2.5 k s, last beep ends ~1 s later) that straddle
    a boundary: at 1.7 s blocks, 3.4 s, 8.5 s and 10.2 s (50 ms after exchange 4's
    anchor); at 2.65 s blocks the second block starts 0.3 ms before exchange 1's anchor.
    Same numbers as one block for all."""
    ref = list(range_series_beepbeep([series_wav], self_distance_m=0.1, block_s=60.0))
    got = list(range_series_beepbeep([series_wav], self_distance_m=0.1, block_s=block_s))
    assert len(got) == len(ref) == 12
    for a, b in zip(got, ref, strict=True):
        assert a.t_s == pytest.approx(b.t_s, abs=1e-12)
        assert a.ranges[0].distance_m == pytest.approx(b.ranges[0].distance_m, abs=1e-9)
        assert a.ranges[0].sigma_m == pytest.approx(b.ranges[0].sigma_m, abs=1e-9)


@pytest.mark.parametrize("detector", ["changepoint", "xcorr"])
def test_series_equals_the_whole_file_path_on_one_exchange(exchange, tmp_path, detector):
    one = np.stack(exchange.recordings, axis=1)
    rng = np.random.default_rng(2)
    path = tmp_path / "one.wav"
    sf.write(path, one + NOISE * rng.standard_normal(one.shape), FS, "PCM_16")
    whole = range_files([path], self_distance_m=0.1, detector=detector, clock_ppm=10.0)
    for block_s in (None, 0.3):
        (e,) = range_series_beepbeep(
            [path], self_distance_m=0.1, detector=detector, clock_ppm=10.0, block_s=block_s
        )
        assert e.ranges == whole.ranges
        assert e.t_s == whole.arrivals[0].onset_s[0]


def test_three_mono_files_at_different_rates(tmp_path):
    """Devices 0, 1, 2 record at 44.1, 48 and 44.1 kHz; files read in lockstep by time."""
    from rangekit.sim.recording import Device

    rates = [44100.0, 48000.0, 44100.0]
    pos = [(0.0, 0.0), (2.0, 0.0), (0.0, 1.5)]
    devs = [
        Device([x, y - 0.05, 1.0], [x, y + 0.05, 1.0], fs=fs)
        for (x, y), fs in zip(pos, rates, strict=True)
    ]
    sim = render_beepbeep(devs, snr_db=None)
    paths = []
    for i, (x, fs) in enumerate(zip(sim.recordings, rates, strict=True)):
        paths.append(
            _write_tiled(
                tmp_path / f"dev{i}.wav",
                x,
                period=int(3.0 * fs),
                count=4,
                fs=int(fs),
                rng=np.random.default_rng(10 + i),
            )
        )
    ex = list(range_series_beepbeep(paths, self_distance_m=0.1, block_s=2.0))
    assert len(ex) == 4
    truth = sim.distances_m
    for k, e in enumerate(ex):
        assert e.error is None
        assert e.t_s == pytest.approx(3.0 * k + sim.onsets[0, 0] / 44100.0, abs=2e-5)
        assert [(r.a, r.b) for r in e.ranges] == [(0, 1), (0, 2), (1, 2)]
        for r in e.ranges:
            assert r.distance_m == pytest.approx(truth[r.a, r.b], abs=0.01)


def test_a_failed_exchange_is_flagged_and_the_series_goes_on(exchange, tmp_path):
    one = np.stack(exchange.recordings, axis=1)
    beep = Beep()
    # Device 1's own beep is cut out of device 1's recording in exchange 2.
    on = int(exchange.onsets[1, 1])

    def edit(k, t):
        if k == 2:
            t[on - 100 : on + beep.duration_samples + 100, 1] = 0.0

    path = _write_tiled(
        tmp_path / "gap.wav", one, period=PERIOD, count=5, fs=FS, rng=np.random.default_rng(3),
        edit=edit,
    )  # fmt: skip
    ex = list(range_series_beepbeep([path], self_distance_m=0.1, block_s=1.5))
    assert len(ex) == 5
    bad = [e for e in ex if e.error is not None]
    assert [e.exchange for e in bad] == [2]
    (r,) = bad[0].ranges
    assert math.isnan(r.distance_m) and math.isnan(r.sigma_m) and r.flags == ("detection",)
    assert "gap.wav#1' has 1 beep(s)" in bad[0].error and "exchange 2" in bad[0].error
    assert bad[0].t_s == pytest.approx(_t0(exchange, 2), abs=2e-5)
    assert bad[0].rows() == [
        {"t_s": bad[0].t_s, "a": 0, "b": 1, "distance_m": None, "sigma_m": None,
         "flags": ["detection"]}
    ]  # fmt: skip
    for e in ex:
        if e.error is None:
            assert e.ranges[0].distance_m == pytest.approx(2.0, abs=0.01)


def test_no_beep_at_all_raises_at_the_end(tmp_path):
    path = tmp_path / "noise.wav"
    sf.write(path, NOISE * np.random.default_rng(4).standard_normal((3 * FS, 2)), FS)
    it = range_series_beepbeep([path], block_s=1.0)
    with pytest.raises(DetectionError, match=r"noise\.wav#0': no beep found in 3\.0 s"):
        list(it)


def test_progress_reports_every_block_up_to_the_length(series_wav):
    seen = []
    list(
        range_series_beepbeep([series_wav], block_s=7.0, progress=lambda d, t: seen.append((d, t)))
    )
    assert len(seen) == 5  # 30 s in blocks of ~7 s
    assert all(t == pytest.approx(30.0) for _, t in seen)
    done = [d for d, _ in seen]
    assert done == sorted(done) and done[-1] == pytest.approx(30.0)


def test_parameters_are_checked_at_the_call_files_when_iterating(series_wav, tmp_path):
    for kw in (
        {"detector": "nope"},
        {"block_s": 0.0},
        {"skew_s": -1.0},
        {"exchange_s": math.nan},
        {"clock_ppm": -1.0},
        {"speed_m_s": 5.0},
    ):
        with pytest.raises(InvalidParameterError):
            range_series_beepbeep([series_wav], **kw)  # no iteration needed
    with pytest.raises(IncompatibleInputError, match="3 self-distances"):
        list(range_series_beepbeep([series_wav], self_distance_m=[0.1, 0.1, 0.1]))
    with pytest.raises(InputFileError, match=r"missing\.wav"):
        list(range_series_beepbeep([tmp_path / "missing.wav"]))
    mono = tmp_path / "mono.wav"
    sf.write(mono, np.zeros(FS), FS)
    with pytest.raises(IncompatibleInputError, match="1 channel"):
        list(range_series_beepbeep([mono]))
    with pytest.raises(IncompatibleInputError, match="each must be mono"):
        list(range_series_beepbeep([mono, series_wav]))
    low = tmp_path / "low.wav"
    sf.write(low, np.zeros((8000, 2)), 8000)
    with pytest.raises(IncompatibleInputError, match=r"low\.wav"):
        list(range_series_beepbeep([low]))


def test_grouping_anchors_on_device_0_within_the_core():
    d0 = np.array([0.5, 1.1, 3.0, 3.6, 6.0, 6.6])
    d1 = np.array([0.45, 1.15, 2.95, 3.65, 6.05, 6.65])  # up to 0.05 s early/late
    groups, after = _group_exchanges(
        [d0, d1], lo_s=0.0, hi_s=5.0, after_s=-math.inf, exchange_s=0.85, skew_s=0.1
    )
    assert [j for j, _ in groups] == [0, 2]  # 1.1 and 3.6 belong to the exchanges
    assert [m.tolist() for m in groups[0][1]] == [[0, 1], [0, 1]]
    assert [m.tolist() for m in groups[1][1]] == [[2, 3], [2, 3]]
    assert after == pytest.approx(3.95)  # 3.0 + exchange_s + skew_s
    # The next block (core from 5 s) continues after the last exchange's window.
    groups, _ = _group_exchanges(
        [d0, d1], lo_s=5.0, hi_s=10.0, after_s=after, exchange_s=0.85, skew_s=0.1
    )
    assert [j for j, _ in groups] == [4]
    # An anchor inside the previous exchange's window is not a new exchange.
    groups, _ = _group_exchanges(
        [d0, d1], lo_s=1.0, hi_s=2.0, after_s=1.35, exchange_s=0.85, skew_s=0.1
    )
    assert groups == []


def test_default_exchange_grows_with_the_devices():
    b = Beep()
    assert default_exchange_s(b, 3) == pytest.approx(2 * (b.duration_s + 0.5))


# --- ultrasonic -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def echo_cycle():
    """One SRF02 cycle at 1.5 m from a wall (noiseless), 13440 samples at 192 kHz."""
    from rangekit.floorplan import FloorPlan
    from rangekit.sim.ultrasonic import render_echo

    plan = FloorPlan.from_walls([((1.5, -5), (1.5, 5)), ((-9, -5), (-9, 5))])
    x = render_echo(plan, [(0.0, 0.0, 0.0)], snr_db=None).x[0][:CYCLE]
    return 0.5 * x / np.max(np.abs(x))


def _write_echo_log(path, cycle, seconds, seed=0):
    n = int(round(seconds / 0.07))
    rng = np.random.default_rng(seed)
    with sf.SoundFile(path, "w", US_FS, 1, "PCM_16") as f:
        for k in range(0, n, 50):
            m = min(50, n - k)
            f.write(np.tile(cycle, m) + 1e-3 * rng.standard_normal(m * CYCLE))
    return path


@pytest.mark.parametrize("block_s", [0.07, 0.2, None])
def test_echo_series_equals_the_whole_file_path(echo_cycle, tmp_path, block_s):
    path = _write_echo_log(tmp_path / "echo.wav", echo_cycle, 1.4, seed=5)
    # A cycle without its echo: out of range there, in both paths.
    with sf.SoundFile(path, "r+") as f:
        f.seek(7 * CYCLE + 1000)
        f.write(1e-3 * np.random.default_rng(6).standard_normal(8000))
    # Each cycle on its own (pool=False): the series is the whole-file code, exactly. By
    # default the transducer's (Q, f0) estimate is pooled over the cycles ranged together
    # (a block's in the series, the file's otherwise): then within the ranges' sigma.
    for pool in (False, True):
        whole = range_ultrasonic_files([path], scheme="echo", period_s=0.07, pool=pool)
        seen = []
        got = list(
            range_series_ultrasonic(
                path, scheme="echo", period_s=0.07, block_s=block_s, pool=pool,
                progress=lambda d, t, seen=seen: seen.append(d),
            )
        )  # fmt: skip
        assert [w.window for w in got] == list(range(20))
        assert [w.t_s for w in got] == pytest.approx([k * 0.07 for k in range(20)], abs=1e-12)
        rows = [r for w in got for r in w.rows(scheme="echo")]
        assert len(rows) == len(whole) == 20
        for r, q in zip(rows, whole, strict=True):
            assert list(r) == list(SERIES_FIELDS["echo"])
            assert (r["window"], r["channel"]) == (q["window"], q["channel"])
            if q["distance_m"] is None:
                assert r["distance_m"] is None
            elif pool:
                tol = 2.0 * max(r["sigma_m"], q["sigma_m"])
                assert r["distance_m"] == pytest.approx(q["distance_m"], abs=tol)
            else:
                for k in ("distance_m", "sigma_m", "snr_db", "arrival_s"):
                    assert r[k] == pytest.approx(q[k], rel=1e-9, abs=1e-12)
        assert rows[7]["distance_m"] is None
        assert rows[0]["distance_m"] == pytest.approx(1.5, abs=2e-3)
        assert seen[-1] == pytest.approx(1.4) and seen == sorted(seen)


def test_oneway_series_keeps_window_numbers_and_tx_ids(tmp_path):
    txs = [[0.5, 0.3, 2.6], [3.0, 0.5, 2.6], [1.5, 3.5, 2.6]]
    sim = render_oneway(
        txs, (1.4, 1.1, 0.4), order=[2, 0, 1], n_windows=7, period_s=0.04, latency_s=1.7e-3,
        rng=1,
    )  # fmt: skip
    path = tmp_path / "ow.wav"
    sf.write(path, 0.5 * sim.x.T / np.max(np.abs(sim.x)), US_FS, "PCM_16")
    kw = {"period_s": 0.04, "latency_s": 1.7e-3, "tx_ids": [2, 0, 1], "channels": 3}
    # Each window on its own (pool=False): the series is the whole-file code, exactly.
    # By default the transducers' (Q, f0) estimate is pooled over the windows ranged
    # together, which are a block's in the series and the file's otherwise: the two
    # then agree within the ranges' sigma (measured here: <= 0.5 mm at sigma ~0.7 mm).
    for pool in (False, True):
        whole = range_ultrasonic_files([path], scheme="oneway", pool=pool, **kw)
        got = list(range_series_ultrasonic(path, scheme="oneway", block_s=0.1, pool=pool, **kw))
        rows = [r for w in got for r in w.rows(scheme="oneway")]
        assert len(rows) == len(whole) == 21
        for r, q in zip(rows, whole, strict=True):
            assert list(r) == list(SERIES_FIELDS["oneway"])
            assert (r["window"], r["tx"], r["channel"]) == (q["window"], q["tx"], q["channel"])
            if pool:
                tol = 2.0 * max(r["sigma_m"], q["sigma_m"])
                assert r["distance_m"] == pytest.approx(q["distance_m"], abs=tol)
            else:
                assert r["distance_m"] == pytest.approx(q["distance_m"], rel=1e-9)
            truth = sim.truth["windows"][r["window"]]["distances_m"][r["channel"]]
            assert r["distance_m"] == pytest.approx(truth, abs=2e-3)
    with pytest.raises(IncompatibleInputError, match="2 are expected"):
        list(range_series_ultrasonic(path, scheme="oneway", period_s=0.04, channels=2))


def test_ultrasonic_blocks_read_the_matched_filter_context_before_a_window(tmp_path):
    """Bursts 3 samples after each window's start: the analytic filter's output there
    depends on samples of the previous window, which the block must include."""
    from rangekit.detect.matched import coded_template

    h = coded_template(fs=US_FS)
    per = 1920
    x = 1e-2 * np.random.default_rng(7).standard_normal(10 * per)
    for k in range(10):
        x[k * per + 3 : k * per + 3 + len(h)] += 0.5 * h / np.max(np.abs(h))
    path = tmp_path / "near.wav"
    sf.write(path, x, US_FS, "PCM_16")
    kw = {"period_s": per / US_FS, "tx": None, "rx": None, "speed_m_s": 343.0}
    whole = range_ultrasonic_files([path], scheme="oneway", **kw)
    got = [r for w in range_series_ultrasonic(path, scheme="oneway", block_s=0.02, **kw)
           for r in w.tofs]  # fmt: skip
    assert len(got) == len(whole) == 10
    for r, q in zip(got, whole, strict=True):
        assert r.arrival_s * US_FS == pytest.approx(3.0, abs=0.05)
        assert r.distance_m == pytest.approx(q["distance_m"], rel=1e-12)


def test_oneway_series_without_any_burst_raises_at_the_end(tmp_path):
    path = tmp_path / "quiet.wav"
    sf.write(path, np.zeros((US_FS // 5, 3)), US_FS)
    with pytest.raises(DetectionError, match=r"quiet\.wav': no burst found"):
        list(range_series_ultrasonic(path, scheme="oneway", period_s=0.04, block_s=0.1))


def test_ultrasonic_series_checks_its_parameters(tmp_path):
    for kw in (
        {"scheme": "beepbeep", "period_s": 0.07},
        {"scheme": "echo", "period_s": 0.0},
        {"scheme": "echo", "period_s": 0.07, "block_s": -1.0},
        {"scheme": "echo", "period_s": 0.07, "windows": np.array([[0, 10]])},
    ):
        with pytest.raises(InvalidParameterError):
            range_series_ultrasonic(tmp_path / "any.wav", **kw)
    with pytest.raises(InputFileError, match=r"any\.wav"):
        list(range_series_ultrasonic(tmp_path / "any.wav", scheme="echo", period_s=0.07))


@pytest.mark.parametrize(
    ("n", "per"),
    [(1000, 100.0), (1049, 100.0), (1051, 100.0), (94085, 13440.0), (999, 33.3333), (10, 2.5)],
)
def test_window_rows_are_window_starts_in_pieces(n, per):
    ref = window_starts(n, fs=1.0, period_s=per)
    for step in (1, 3, 7, 1000):
        parts = [_window_rows(k, k + step, n, per) for k in range(0, len(ref) + step, step)]
        got = np.concatenate(parts)
        np.testing.assert_array_equal(got, ref)


def test_explicit_windows_and_first_window_of_range_oneway():
    from rangekit.detect.matched import coded_template

    h = coded_template(fs=US_FS)
    x = np.zeros((1, 30000))
    for s0 in (0, 10000, 20000):
        x[0, s0 + 560 : s0 + 560 + len(h)] += h
    whole = range_oneway(x, fs=US_FS, period_s=10000 / US_FS, tx_ids=[7, 8])
    part = range_oneway(
        x[:, 10000:], fs=US_FS, windows=np.array([[0, 10000], [10000, 20000]]), first_window=1,
        tx_ids=[7, 8],
    )  # fmt: skip
    assert [(r.window, r.tx) for r in part] == [(1, 8), (2, 7)]
    for r, q in zip(part, whole[1:], strict=True):
        assert r.distance_m == pytest.approx(q.distance_m, abs=1e-9)
    for kw in (
        {"windows": np.array([[0, 10]]), "period_s": 0.01},
        {"windows": np.array([[0, 40000]])},
        {"windows": np.array([[5, 6]])},
        {"windows": np.array([[0.0, 10.0]])},
        {"windows": np.array([0, 10])},
        {"first_window": -1},
    ):
        with pytest.raises(InvalidParameterError):
            range_oneway(x, fs=US_FS, **kw)


# --- memory ------------------------------------------------------------------------------


def _peak_bytes(run) -> int:
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        run()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _consume(items) -> int:
    n = 0
    for _ in items:  # rows are not kept: the test measures the ranging, not the caller
        n += 1
    return n


def test_beepbeep_memory_does_not_grow_with_the_length(exchange, tmp_path):
    one = np.stack(exchange.recordings, axis=1)
    paths = {}
    for n in (2, 8, 32):  # 5 s (warm-up), 20 s, 80 s
        paths[n] = _write_tiled(
            tmp_path / f"{n}.wav", one, period=PERIOD, count=n, fs=FS,
            rng=np.random.default_rng(n),
        )  # fmt: skip
    counts = {}

    def run(n):
        counts[n] = _consume(range_series_beepbeep([paths[n]], self_distance_m=0.1, block_s=5.0))

    _peak_bytes(lambda: run(2))  # imports, caches
    short = _peak_bytes(lambda: run(8))
    long = _peak_bytes(lambda: run(32))
    assert counts == {2: 2, 8: 8, 32: 32}
    assert long <= 1.2 * short, (short, long)
    # And far below the long file as float64 (80 s x 2 channels x 8 bytes = 56 MB).
    assert long < 0.75 * 32 * PERIOD * 2 * 8, long


def test_echo_memory_does_not_grow_with_the_length(echo_cycle, tmp_path):
    paths = {s: _write_echo_log(tmp_path / f"{s}.wav", echo_cycle, s, seed=s) for s in (1, 20, 80)}

    def run(s):
        _consume(range_series_ultrasonic(paths[s], scheme="echo", period_s=0.07, block_s=2.0))

    _peak_bytes(lambda: run(1))
    short = _peak_bytes(lambda: run(20))
    long = _peak_bytes(lambda: run(80))
    assert long <= 1.2 * short, (short, long)
    assert long < 0.5 * 80 * US_FS * 8, long  # 123 MB as float64
