"""Benchmark the beep detectors on 10 minutes of realistic 44.1 kHz audio.

Signal: one simulated two-device exchange, ``render_beepbeep(pair_devices(3.0,
self_distance_m=0.1), snr_db=20, rng=0)``, channel 0 (1.26 s: the device's own beep from
0.1 m and the other device's beep from 3 m, ~29.5 dB weaker, full-band SNR of the weak
one 20 dB), placed every 3 s +- 0.5 s (seeded jitter) in 10 minutes of white noise at the
level of the rendered noise: 200 exchanges, 400 beeps at known onsets.  ``--quick``: 60 s
(40 beeps).

Rows, each the best of ``--repeats`` calls (default 3) after a warm-up (numba compile or
cache load, FFT planning):

* ``detect_changepoint`` float64: one call on the whole array (numba path: the signal is
  longer than ``NUMBA_MIN_SAMPLES``).
* ``detect_changepoint`` numpy path: the same call with the edge fit's numba kernels off
  (``rangekit.detect._edge_kernels.NUMBA_MIN_SAMPLES`` raised), the reference the kernels
  are tested against; the script checks that both give the same onsets (1e-6 samples).
* ``detect_changepoint`` float32: the same array as float32 (read as it is: the kernels
  take float32, no float64 copy of the recording; what ``rangekit detect`` passes for
  16-bit files since ``rangekit.io.audio.read_audio`` decodes them into float32).
* ``detect_xcorr``: the FFT matched-filter baseline on the whole array (~2.2-2.4 GB peak
  memory for 10 min).  If a 60 s trial projects to more than 60 s or more than half of
  the available memory, it is run on 60 s and scaled, and the row says so.
* stages of ``detect_changepoint`` (float64): input check, band energy, noise floor,
  change points, conditioning, out-of-band check, the compiled beep loop
  (``_rows_compiled``: every anchor's edge fits, grouping and flags in one kernel call; of
  which the anchors handed to the numpy reference, ``_beep_row``), aliases, echoes and
  the rest, timed inside one real call by wrapping those functions in
  ``rangekit.detect.changepoint``'s namespace (fastest of ``--repeats`` instrumented
  calls).
* peer: ``scipy.signal.ShortTimeFFT(hann(128, sym=False), hop=32, mfft=128,
  scale_to=None)`` + ``|X|**2`` of the bin nearest 16 kHz (bin 46, 15848 Hz), in chunks
  of 60 s of whole frames (a 10-min STFT with 65 bins would be ~0.9 GB of complex128);
  the script checks that it equals ``band_energy`` at that bin frequency.

The table gives seconds, x-realtime (seconds of audio per second of wall time) and the
time relative to the ShortTimeFFT peer (``t / t_peer``; < 1 is faster than the peer).
The detections are checked (count and timing against the known onsets) and printed; the
script exits with status 1 if ``detect_changepoint`` missed or invented beeps, so it
cannot silently time a broken detector.  When the whole detection is below half of the
design target (2000x realtime on one core) the script profiles it (cProfile of one call
plus per-call timings of the two edge-fit stages) and prints where the time goes; ``--profile``
forces that.

BLAS/OpenMP pools are limited to one thread before numpy is imported (one core, like the
target); the numba kernel is single-threaded and scipy.fft uses one worker by default.

Run: ``python benchmarks/bench_detect.py [--quick] [--repeats N] [--profile]``
"""

from __future__ import annotations

import argparse
import cProfile
import io
import math
import pstats
import sys
import time
from pathlib import Path

import _one_core  # noqa: F401  (one thread, repo on sys.path; before numpy)
import numpy as np
from _report import best_of, goal_verdict, row
from _stft_peer import stft_band_energy

import rangekit.detect._edge_kernels as edge_kernels
import rangekit.detect.changepoint as cp
import rangekit.detect.refine as refine
from rangekit.detect import detect_changepoint, detect_xcorr
from rangekit.detect._kernels import NUMBA_MIN_SAMPLES, band_energy
from rangekit.signals import Beep
from rangekit.sim import pair_devices, render_beepbeep

FS = 44100.0
N_WIN = 128
HOP = 32
PERIOD_S = 3.0
JITTER_S = 0.5
CHUNK_S = 60.0
TARGET_X = 2000.0
#: Detected onsets must be within this many samples of the rendered truth.
ONSET_TOL = 2.0


def make_signal(duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Return (x, true onsets in samples): exchanges every ~3 s in white noise."""
    sim = render_beepbeep(pair_devices(3.0, self_distance_m=0.1), snr_db=20, rng=0)
    tile = sim.recordings[0]
    tile_onsets = sim.onsets[0]  # this device's recording: own beep, then the far one
    # Noise-only lead of the tile (the interpolator reaches 64 samples before an onset).
    sigma = float(np.std(tile[: int(tile_onsets.min()) - 200]))
    rng = np.random.default_rng(2026)
    n = int(duration_s * FS)
    x = sigma * rng.standard_normal(n)
    period, jitter = int(PERIOD_S * FS), int(JITTER_S * FS)
    starts = np.arange(jitter, n - len(tile) - jitter, period)
    starts = starts + rng.integers(-jitter, jitter + 1, size=len(starts))
    for s in starts:
        x[s : s + len(tile)] = tile
    truth = (starts[:, None] + tile_onsets[None, :]).ravel()
    return x, np.sort(truth)


def check(name: str, onsets: np.ndarray, truth: np.ndarray) -> bool:
    """Print whether the detections match the truth one to one; return True if they do."""
    onsets = np.sort(np.asarray(onsets, dtype=np.float64))
    if len(onsets) == len(truth):
        err = np.abs(onsets - truth)
        ok = bool(np.all(err <= ONSET_TOL))
        print(
            f"  check {name:<28}: found {len(onsets)} / {len(truth)} beeps, "
            f"max |onset - truth| = {err.max():.3f} samples -> {'OK' if ok else 'FAIL'}"
        )
        return ok
    print(f"  check {name:<28}: found {len(onsets)} / {len(truth)} beeps -> FAIL")
    return False


def best_time(fn, repeats: int):
    """Best wall time of ``repeats`` calls of ``fn()``, and the last result."""
    best = math.inf
    res = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = fn()
        best = min(best, time.perf_counter() - t0)
    return best, res


def stft_peer(x: np.ndarray) -> np.ndarray:
    """Band energy at the bin nearest 16 kHz by ShortTimeFFT (mfft=128), in ~60 s chunks."""
    q = round(16000.0 / (FS / N_WIN))
    return stft_band_energy(
        x, fs=FS, n_win=N_WIN, hop=HOP, mfft=N_WIN, bins=slice(q, q + 1), chunk_s=CHUNK_S
    )


def stages(x: np.ndarray, beep: Beep) -> tuple[dict[str, float], int, float, object]:
    """Time the steps of one real ``detect_changepoint`` call.

    The step functions are looked up by ``changepoint`` at call time, so wrapping them in
    that module's namespace times the real pipeline (wrapper cost ~1 us per call). The
    edge statistic and the onset refinement run inside the per-beep fits; their rows are
    parts of that row ("of which"), the others add up to the whole call.
    Returns (seconds per step, number of ``refine_onset`` calls, whole call, arrivals).
    """
    steps = {
        "_signal": "input check (no float64 copy)",
        "band_energy": "band_energy (numba)",
        "_floor": "local noise floor",
        "_change_points": "change points",
        "_conditioner": "conditioning (clip mask, taps)",
        "_out_of_band": "out-of-band check",
        "_rows_compiled": "beep loop (compiled: fits, grouping, flags)",
        "_beep_row": "  of which anchors done by the reference",
        "_resolve_aliases": "aliases",
        "drop_echoes": "echoes",
    }
    acc = dict.fromkeys(steps.values(), 0.0)
    calls = dict.fromkeys(steps.values(), 0)
    originals = {name: getattr(cp, name) for name in steps}

    def timed(name, fn):
        def wrapper(*a, **k):
            t0 = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                acc[steps[name]] += time.perf_counter() - t0
                calls[steps[name]] += 1

        return wrapper

    for name, fn in originals.items():
        setattr(cp, name, timed(name, fn))
    try:
        t0 = time.perf_counter()
        arr = cp.detect_changepoint(x, fs=FS, beep=beep)
        whole = time.perf_counter() - t0
    finally:
        for name, fn in originals.items():
            setattr(cp, name, fn)
    acc["rest (input check, conditioning, glue)"] = whole - sum(
        v for k, v in acc.items() if not k.startswith(" ")
    )
    return acc, calls["  of which anchors done by the reference"], whole, arr


def profile(x: np.ndarray, beep: Beep, t_whole: float, duration_s: float, n_fits: int) -> None:
    """Print where ``detect_changepoint`` spends its time."""
    print("\nprofile of detect_changepoint (float64, whole array)")
    prof = cProfile.Profile()
    prof.enable()
    detect_changepoint(x, fs=FS, beep=beep)
    prof.disable()
    s = io.StringIO()
    pstats.Stats(prof, stream=s).sort_stats("tottime").print_stats(12)
    lines = [ln for ln in s.getvalue().splitlines() if ln.strip()]
    start = next(i for i, ln in enumerate(lines) if ln.lstrip().startswith("ncalls"))
    print("  cProfile, top 12 by own time (cProfile inflates the total ~1.5-2x):")
    prefixes = (str(Path(__file__).resolve().parents[1]) + "/", str(Path(np.__file__).parent))
    for ln in lines[start:]:
        for prefix in prefixes:
            ln = ln.replace(prefix, "numpy" if prefix.endswith("numpy") else "")
        print("   ", ln)
    try:
        _per_call_costs(x, beep, t_whole, n_fits)
    except Exception as exc:  # private helpers may change; the profile above still stands
        print(f"  per-call timings unavailable ({type(exc).__name__}: {exc})")
    budget = duration_s / TARGET_X
    print(
        f"  budget for {TARGET_X:.0f}x realtime: {budget:.3f} s for {duration_s:.0f} s of audio, "
        f"i.e. {budget / max(n_fits, 1) * 1e6:.0f} us per candidate burst, everything included"
    )


def _per_call_costs(x: np.ndarray, beep: Beep, t_whole: float, n_fits: int) -> None:
    """Per-call cost of the two edge-fit stages, without profiler overhead."""
    # The arguments of real calls (the 2nd of the first 10 s; numpy path there if short).
    seen: dict[str, list] = {"edge_statistic": [], "refine_onset": []}
    orig = {name: getattr(cp, name) for name in seen}

    def recorder(name):
        def record(*a, **k):
            seen[name].append((a, k))
            return orig[name](*a, **k)

        return record

    for name in seen:
        setattr(cp, name, recorder(name))
    try:
        detect_changepoint(x, fs=FS, beep=beep)
    finally:
        for name, fn in orig.items():
            setattr(cp, name, fn)

    def per_call(fn, count: int) -> float:
        """Best of 5 batches of ``count`` calls, per call."""
        best = math.inf
        for _ in range(5):
            t0 = time.perf_counter()
            for _ in range(count):
                fn()
            best = min(best, (time.perf_counter() - t0) / count)
        return best

    if any(len(v) < 2 for v in seen.values()):
        print("  per call: the compiled beep loop (_edge_kernels._beeps_py) calls neither "
              "edge_statistic nor refine_onset on this signal; its cost is the cProfile row "
              "above")  # fmt: skip
        return
    print("  per call (no profiler; one real call of each, compiled and numpy path):")
    for name, fn in (
        ("edge_statistic", refine.edge_statistic),
        ("refine_onset", refine.refine_onset),
    ):
        a, k = seen[name][1]
        k_np = {**k, "compiled": False}
        k_nb = {**k, "compiled": True}
        t_np = per_call(lambda f=fn, a=a, k=k_np: f(*a, **k), 200)
        t_nb = per_call(lambda f=fn, a=a, k=k_nb: f(*a, **k), 200)
        print(
            f"    {name:<15} numpy {t_np * 1e6:7.1f} us, compiled {t_nb * 1e6:7.1f} us "
            f"({t_np / t_nb:.1f}x) x {len(seen[name])} calls"
        )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="60 s of audio, 3 repeats")
    ap.add_argument("--repeats", type=int, default=3, help="best of N (default 3)")
    ap.add_argument("--profile", action="store_true", help="always print the profile")
    args = ap.parse_args()
    duration_s = 60.0 if args.quick else 600.0
    repeats = 3 if args.quick else max(1, args.repeats)

    beep = Beep()
    x, truth = make_signal(duration_s)
    x32 = x.astype(np.float32)
    print(
        f"signal: {duration_s:.0f} s at {FS:.0f} Hz ({x.size} samples), {len(truth)} beeps "
        f"({len(truth) // 2} exchanges every {PERIOD_S:.0f} +- {JITTER_S} s, own beep 0.1 m "
        f"and far beep 3 m, far-beep SNR 20 dB), best of {repeats}"
    )

    # Warm-up: numba (compile or cache load) on a slice long enough for the numba path,
    # the detectors' first-call imports, scipy's FFT plans.
    t0 = time.perf_counter()
    w = x[: NUMBA_MIN_SAMPLES + 50_000]
    detect_changepoint(w, fs=FS, beep=beep)
    detect_changepoint(w.astype(np.float32), fs=FS, beep=beep)
    detect_xcorr(x[: int(5 * FS)], fs=FS, beep=beep)
    stft_peer(x[: int(5 * FS)])
    print(f"warm-up (numba compile/cache load, imports): {time.perf_counter() - t0:.2f} s")

    rows: list[tuple[str, float, str]] = []
    t_cp, c_cp, arr = best_of(lambda: detect_changepoint(x, fs=FS, beep=beep), repeats)
    rows.append(("detect_changepoint float64 (whole)", t_cp, f"CPU {c_cp:.3f} s"))
    t_cp32, c_cp32, arr32 = best_of(lambda: detect_changepoint(x32, fs=FS, beep=beep), repeats)
    rows.append(("detect_changepoint float32 (whole)", t_cp32,
                 f"CPU {c_cp32:.3f} s; no float64 copy"))  # fmt: skip
    min_samples = edge_kernels.NUMBA_MIN_SAMPLES
    edge_kernels.NUMBA_MIN_SAMPLES = 1 << 62  # the edge fit's numpy path (the reference)
    try:
        t_np, arr_np = best_time(lambda: detect_changepoint(x, fs=FS, beep=beep), repeats)
    finally:
        edge_kernels.NUMBA_MIN_SAMPLES = min_samples
    rows.append(("detect_changepoint, numpy edge fit", t_np, "the kernels' reference path"))

    # xcorr: full array unless a 60 s trial says it would be too slow or too big.
    n60 = int(60.0 * FS)
    t0 = time.perf_counter()
    detect_xcorr(x[:n60], fs=FS, beep=beep)
    t60 = time.perf_counter() - t0
    proj_s = t60 * x.size / n60 * math.log2(x.size) / math.log2(n60)
    proj_bytes = 90.0 * x.size  # measured peak ~84 B/sample (complex128 FFT buffers)
    avail = _mem_available()
    if x.size <= n60 or (proj_s <= 60.0 and proj_bytes <= 0.5 * avail):
        t_xc, arr_xc = best_time(lambda: detect_xcorr(x, fs=FS, beep=beep), repeats)
        rows.append(("detect_xcorr (whole)", t_xc, f"peak memory ~{proj_bytes / 1e9:.1f} GB"))
        xc_truth = truth
    else:
        t60b, arr_xc = best_time(lambda: detect_xcorr(x[:n60], fs=FS, beep=beep), repeats)
        t_xc = t60b * x.size / n60
        rows.append(("detect_xcorr (60 s, scaled x10)", t_xc, "run on 60 s, linear scaling"))
        xc_truth = truth[truth < n60 - beep.duration_samples]
    xc_name, _, xc_note = rows[-1]

    t_st, st_arr, n_cand = math.inf, None, 0
    st_times: dict[str, float] = {}
    for _ in range(repeats):
        t, n_c, whole, arr_s = stages(x, beep)
        if whole < t_st:
            t_st, st_times, n_cand, st_arr = whole, t, n_c, arr_s
    for k, v in st_times.items():
        note = f"{n_cand} anchors" if "reference" in k else ""
        rows.append((f"  stage: {k}", v, note))

    t_peer, c_peer, e_peer = best_of(lambda: stft_peer(x), repeats)
    rows.append(("peer: ShortTimeFFT + bin 46 (mfft=128)", t_peer,
                 f"CPU {c_peer:.3f} s; chunks of {CHUNK_S:.0f} s"))  # fmt: skip

    e_rk = band_energy(x, fs=FS, f_hz=np.array([46 * FS / N_WIN]), n_win=N_WIN, hop=HOP)
    rel = float(np.max(np.abs(e_rk - e_peer)) / np.max(e_peer))

    print()
    print(f"  {'name':<40} {'seconds':>9} {'x-realtime':>11} {'t / t_peer':>11}  note")
    for name, t, note in rows:
        rt = f"{duration_s / t:10.0f}x" if t > 0 else f"{'-':>11}"
        print(f"  {name:<40} {t:9.3f} {rt} {t / t_peer:10.2f}x  {note}")
    print(
        f"  peer check: band_energy at {46 * FS / N_WIN:.1f} Hz vs ShortTimeFFT bin 46: "
        f"max |diff| / max = {rel:.1e}"
    )

    x_rt, x_cpu = duration_s / t_cp, duration_s / c_cp
    verdict = goal_verdict(f"target >= {TARGET_X:.0f}x", x_cpu >= TARGET_X,
                           f"{x_cpu:.0f}x = {x_cpu / TARGET_X:.2f} of it, {c_peer / c_cp:.1f}x "
                           "the peer", f"{x_rt:.0f}x")  # fmt: skip
    print(f"\n  whole detection on one core: {verdict}")
    print(
        f"  stages: from the fastest of {repeats} instrumented calls ({t_st:.3f} s in all; "
        f"uninstrumented best {t_cp:.3f} s)\n"
    )

    same = len(arr_np) == len(arr) and bool(np.all(np.abs(arr_np.onset - arr.onset) <= 1e-6))
    same = same and np.array_equal(arr_np.flags, arr.flags)
    print(
        f"  check numba vs numpy edge fit     : {len(arr)} / {len(arr_np)} arrivals, max |onset "
        f"diff| = {np.max(np.abs(arr_np.onset - arr.onset)) if same else math.nan:.1e} "
        f"samples, flags equal -> {'OK' if same else 'FAIL'}"
    )
    ok = same
    ok &= check("detect_changepoint float64", arr.onset, truth)
    ok &= check("detect_changepoint float32", arr32.onset, truth)
    ok &= check("instrumented call", st_arr.onset, truth)
    check("detect_xcorr (baseline)", arr_xc.onset, xc_truth)

    # Headline rows for benchmarks/run.py (ratio = t_peer / t: > 1 = faster than the peer).
    size = f"{duration_s:.0f} s of 44.1 kHz audio, {len(truth)} beeps, best of {repeats}"
    headline = [
        ("detect_changepoint float64 (whole)", t_cp, verdict),
        ("detect_changepoint float32 (whole)", t_cp32,
         f"{duration_s / c_cp32:.0f}x CPU; float32 read as is, no float64 copy"),
        (xc_name, t_xc, xc_note),
    ]  # fmt: skip
    for name, t, note in headline:
        row("detect", name, duration_s / t, "x-realtime",
            peer="scipy ShortTimeFFT + bin 46 (mfft=128)", peer_value=duration_s / t_peer,
            note=f"{size}; {note}")  # fmt: skip

    if args.profile or x_cpu < TARGET_X:  # a goal missed: where the time goes
        profile(x, beep, t_cp, duration_s, n_cand)
    if not ok:
        print("\nFAIL: detect_changepoint did not find the expected beeps", file=sys.stderr)
        return 1
    return 0


def _mem_available() -> float:
    """Available memory in bytes from /proc/meminfo (inf if unknown)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return math.inf


if __name__ == "__main__":
    sys.exit(main())
