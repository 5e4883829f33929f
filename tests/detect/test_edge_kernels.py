"""The edge fit's numba kernels (``rangekit.detect._edge_kernels``) against the numpy path.

The numpy code of ``refine.py`` (and ``changepoint._anchor``) is the reference. The
kernels sum in another order and solve the normal equations by Cholesky instead of LU, so
they agree to rounding, not bit for bit. Tolerances (measured differences in brackets):
edge statistics 1e-9 of the largest value (~1e-13), onsets 1e-9 samples (~1e-12), sigma
and amplitude 1e-9 relative (~1e-13), SNR 1e-9 dB; anchors and whole detections: the same
anchors, flags, burst counts; onsets within 1e-6 samples (the acceptance bound; measured
< 1e-9), sigma 1e-9 relative.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from detections import assert_same_detections

import rangekit.detect._edge_kernels as K
import rangekit.detect.changepoint as cp
from rangekit.detect import refine
from rangekit.detect.condition import active_floor, local_floor
from rangekit.signals import Beep, beep_waveform
from rangekit.sim import pair_devices, render_beepbeep
from rangekit.sim.impair import Impairments, impair

FS = 44100.0
BEEP = Beep()


def _burst_recording(seed: int, *, n: int = 30000, at: int = 5000, amp: float = 0.3):
    rng = np.random.default_rng(seed)
    x = 0.01 * rng.standard_normal(n)
    x[at : at + BEEP.duration_samples] += amp * beep_waveform(BEEP)
    return x


def _mask(seed: int, n: int) -> np.ndarray:
    m = np.zeros(n, dtype=bool)
    m[np.random.default_rng(seed).integers(4980, 5040, size=6)] = True
    return m


MODELS = [(False, False), (True, False), (False, True), (True, True)]


@pytest.mark.parametrize(("background", "dc"), MODELS)
@pytest.mark.parametrize("masked", [False, True])
def test_edge_statistic_kernel_equals_numpy(background, dc, masked):
    for seed in range(3):
        x = _burst_recording(seed)
        kw = dict(fs=FS, beep=BEEP, lo=4800, hi=5200, background=background, dc=dc)
        if masked:
            kw["mask"] = _mask(seed, len(x))
        ref = refine.edge_statistic(x, **kw)
        fast = refine.edge_statistic(x, compiled=True, **kw)
        assert fast.shape == ref.shape
        np.testing.assert_allclose(fast, ref, rtol=0, atol=1e-9 * ref.max())
        assert ref.max() > 100.0  # an edge is in there


@pytest.mark.parametrize(("background", "dc"), MODELS)
@pytest.mark.parametrize("masked", [False, True])
def test_refine_onset_kernel_equals_numpy(background, dc, masked):
    for seed in range(3):
        x = _burst_recording(seed, amp=[0.3, 0.03, 0.003][seed])
        for a in (4998, 5001, 5003):
            kw = dict(fs=FS, beep=BEEP, a=a, f_stat=42.0, background=background, dc=dc)
            if masked:
                kw["mask"] = _mask(seed, len(x))
            ref = refine.refine_onset(x, **kw)
            fast = refine.refine_onset(x, compiled=True, **kw)
            assert abs(fast.onset - ref.onset) <= 1e-9
            assert math.isclose(fast.sigma, ref.sigma, rel_tol=1e-9)
            assert math.isclose(fast.amplitude, ref.amplitude, rel_tol=1e-9)
            assert abs(fast.snr_db - ref.snr_db) <= 1e-9
            assert (fast.f_stat, fast.n_masked) == (ref.f_stat, ref.n_masked)
            assert abs(ref.onset - 5000) < 3.0  # a fit near the edge, not a degenerate one


def test_refine_kernel_falls_back_when_the_system_is_singular():
    """All-zero input: the Cholesky of the unregularised Gram fails; numpy answers."""
    x = np.zeros(2000)
    ref = refine.refine_onset(x, fs=FS, beep=BEEP, a=1000)
    fast = refine.refine_onset(x, fs=FS, beep=BEEP, a=1000, compiled=True)
    assert fast == ref


def test_anchor_kernel_equals_python():
    rng = np.random.default_rng(5)
    e = rng.exponential(1.0, 20000)
    for k in range(4):  # a beep's four bursts, and a lone change point
        e[3000 + k * 156 : 3000 + k * 156 + 13] *= 100.0
    e[9000:9013] *= 100.0
    cs = np.concatenate(([0.0], np.cumsum(e)))
    c = np.arange(0, 20000 * 32, 977, dtype=np.int64)
    c = np.concatenate([c, [3000 * 32, 3156 * 32, 3312 * 32, 9000 * 32]])
    kw = dict(hop=32, n_win=128, beep=BEEP, fs=FS)
    fast = cp._anchors_compiled(c, cs, len(e), **kw)
    ref = [cp._anchor(int(v), e, spacing=BEEP.spacing_s * FS, cs=cs, **kw) for v in c]
    assert fast == ref
    assert max(r for _, r in ref) == 4


def test_local_floor_equals_block_by_block():
    """The batched percentile gives exactly the per-block numbers (silence, short tail)."""
    rng = np.random.default_rng(0)
    for _ in range(50):
        n, block = int(rng.integers(2, 20000)), int(rng.integers(1, 3000))
        e = rng.exponential(1.0, n) * rng.choice([1.0, 1e-20, 0.0], n, p=[0.8, 0.1, 0.1])
        if rng.uniform() < 0.3:
            e[: n // 2] = 0.0
        assert np.array_equal(local_floor(e, block=block), _local_floor_ref(e, block))


def _local_floor_ref(e: np.ndarray, block: int, q: float = 20.0, min_live: float = 0.25):
    """``local_floor`` as it was written before (one percentile per block)."""
    n = len(e)
    whole = active_floor(e, q=q)
    if n <= block:
        return np.full(n, whole)
    top = float(np.max(e))
    centres, levels = [], []
    for b in range(-(-n // block)):
        seg = e[b * block : min(n, (b + 1) * block)]
        live = seg[seg > 1e-12 * top]
        lvl = whole
        if len(live) >= max(8, min_live * len(seg)):
            lvl = float(np.percentile(live, q)) / -math.log(1.0 - q / 100.0)
        centres.append(b * block + 0.5 * (len(seg) - 1))
        levels.append(lvl)
    return np.interp(np.arange(n), centres, levels)


# ------------------------------------------------------------------ whole detections


def _detect_both(x, monkeypatch, **kw):
    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 10**12)
    ref = cp.detect_changepoint(x, fs=FS, **kw)
    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 0)
    fast = cp.detect_changepoint(x, fs=FS, **kw)
    return ref, fast


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_detections_equal_on_rendered_exchanges(seed, monkeypatch):
    sim = render_beepbeep(pair_devices(3.0, self_distance_m=0.1), snr_db=20, rng=seed)
    for x in sim.recordings:
        assert_same_detections(*_detect_both(x, monkeypatch))


def test_detections_equal_on_a_long_tiled_recording(monkeypatch):
    """Many beeps and noise change points (the benchmark's signal, 20 s)."""
    sim = render_beepbeep(pair_devices(3.0, self_distance_m=0.1), snr_db=20, rng=0)
    one = sim.recordings[0]
    rng = np.random.default_rng(0)
    x = float(np.std(one[:2000])) * rng.standard_normal(int(20 * FS))
    for k in range(6):
        s0 = int((3 * k + rng.uniform(-0.5, 0.5) + 0.5) * FS)
        if s0 + len(one) < len(x):
            x[s0 : s0 + len(one)] += one
    ref, fast = _detect_both(x, monkeypatch)
    assert len(ref) >= 10
    assert_same_detections(ref, fast)


def test_detections_equal_on_a_clipped_recording(monkeypatch):
    sim = render_beepbeep(
        pair_devices(2.0, self_distance_m=0.1, rec_start_s=0.0), snr_db=20.0, rng=4
    )
    x = impair(sim.recordings[0], fs=FS, impairments=Impairments(clip_db=15.0), rng=0).x
    ref, fast = _detect_both(x, monkeypatch)
    assert "clipped" in ref.flag_names(0)
    assert_same_detections(ref, fast)


def test_detections_equal_in_a_pyroomacoustics_room(monkeypatch):
    from rangekit.experiments.realistic import draw_room, render_exchange

    rng = np.random.default_rng(11)
    ex = render_exchange(rng, room=draw_room(rng), distance_m=4.0)
    for x in ex.recordings:
        assert_same_detections(*_detect_both(x, monkeypatch, expected=2))


def test_short_recordings_take_the_numpy_path(monkeypatch):
    called = []
    monkeypatch.setattr(K, "call", lambda *a: called.append(a[0]))
    sim = render_beepbeep(pair_devices(3.0, self_distance_m=0.1), snr_db=20, rng=0)
    assert len(sim.recordings[0]) < K.NUMBA_MIN_SAMPLES
    assert len(cp.detect_changepoint(sim.recordings[0], fs=FS)) == 2
    assert not called


def test_fir_kernel_equals_bandlimit():
    """The compiled band-limiting of a stretch equals ``bandlimit`` of it (ends included)."""
    from rangekit.detect.condition import bandlimit

    x = np.random.default_rng(3).standard_normal(3000)
    taps = cp.beep_taps(BEEP, FS)
    for compiled in (False, True):
        cond = cp._Conditioner(x, taps, None, compiled)
        for a, b in [(0, 700), (20, 400), (1000, 1525), (2600, 3000), (2990, 3100), (5, 5)]:
            y, off = cond.segment(a, b)
            h = (len(taps) - 1) // 2
            a1, b1 = max(0, a), min(len(x), b)
            a0, b0 = max(0, a1 - h), min(len(x), b1 + h)
            ref = bandlimit(x[a0:b0], taps)[a1 - a0 : a1 - a0 + max(b1 - a1, 0)]
            assert off == a1
            np.testing.assert_allclose(y, ref, rtol=0, atol=1e-12)


# ------------------------------------------- the compiled beep loop (issue 20, item 2)


def _tiled(seconds: float, seed: int = 0) -> np.ndarray:
    sim = render_beepbeep(pair_devices(3.0, self_distance_m=0.1), snr_db=20, rng=seed)
    one = sim.recordings[0]
    rng = np.random.default_rng(seed)
    x = float(np.std(one[:2000])) * rng.standard_normal(int(seconds * FS))
    for k in range(int(seconds // 3) - 1):
        s0 = int((3 * k + rng.uniform(-0.5, 0.5) + 0.5) * FS)
        x[s0 : s0 + len(one)] += one
    return x


def test_float32_input_on_the_compiled_path_equals_the_numpy_path(monkeypatch):
    """float32 samples are read as they are (no float64 copy): the same detections."""
    x = _tiled(12.0).astype(np.float32)
    ref, fast = _detect_both(x, monkeypatch)
    assert len(ref) >= 6
    assert_same_detections(ref, fast)
    assert_same_detections(ref, cp.detect_changepoint(x.astype(np.float64), fs=FS))


def test_unconditioned_detections_equal(monkeypatch):
    assert_same_detections(*_detect_both(_tiled(9.0, seed=1), monkeypatch, condition=False))


def test_an_anchor_left_to_the_reference_keeps_the_order(monkeypatch):
    """When the compiled loop hands an anchor back (a singular fit), the reference does it
    and the loop goes on: the same rows as without the hand-back."""
    x = _tiled(12.0, seed=2)
    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 0)
    plain = cp.detect_changepoint(x, fs=FS)
    real = K.call
    handed = []

    def call(name, *args):
        if name == "beeps" and args[4] in (0, 1) and args[4] not in handed:
            handed.append(args[4])
            return args[4]  # "do anchor i yourself"
        return real(name, *args)

    monkeypatch.setattr(K, "call", call)
    assert_same_detections(plain, cp.detect_changepoint(x, fs=FS))
    assert handed == [0, 1]


def test_change_point_kernel_and_float32_clip_mask_equal_numpy(monkeypatch):
    from rangekit.detect.condition import clip_mask

    rng = np.random.default_rng(5)
    e = rng.exponential(1.0, 50_000) * np.repeat(rng.uniform(0.5, 40.0, 50), 1000)
    floor = cp._floor(e, fs=FS, hop=32)
    kw = {"n_win": 128, "hop": 32, "threshold_db": 6.0, "rise_db": 10.0, "lookback": 6}
    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 10**12)
    ref = cp._change_points(e, floor=floor, **kw)
    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 0)
    np.testing.assert_array_equal(cp._change_points(e, floor=floor, **kw), ref)
    assert len(ref) > 10
    x = np.clip(rng.standard_normal(200_000), -3.0, 2.5).astype(np.float32)
    x[::7] = np.float32(2.5) - np.float32(2.0e-4)  # at the float32 threshold's edge
    m = clip_mask(x)  # float32 compared in float32 as the float64 values compare
    assert m.sum() > 0
    np.testing.assert_array_equal(clip_mask(x.astype(np.float64)), m)
