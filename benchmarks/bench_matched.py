"""Benchmark the ultrasonic matched filter (:class:`rangekit.detect.matched.MatchedFilter`).

Signal: 10 minutes of 192 kHz white noise (sigma 0.05) with a Barker-7 burst (the default
:class:`~rangekit.signals.barker.CodedBurst` through two Q=4 transducers) every 50 +- 10 ms
(seeded jitter), amplitudes 0.2-0.5: 12 000 bursts at known onsets.  ``--quick``: 1 minute.

Templates: ``coded_template(CodedBurst(), fs=192000, tx=Transducer(), rx=Transducer())``
("folded", 165 taps) and the bare 101-sample drive (``tx=None, rx=None``).  The analytic
FIR that ``MatchedFilter`` builds from them has 184 and 1954 taps (the bare drive's
spectrum reaches DC and Nyquist, so its Hilbert transform decays slowly).

1. **Whole array**, per template, rows timed round-robin (best of ``--repeats``, after a
   warm-up; each round starts one row later), each with the kernel CPU share of the best
   call (``sys``: page faults of fresh memory) and the growth of the process's peak RSS
   during the call:

   * ``MatchedFilter(h).correlate(x)``: complex analytic correlation (overlap-save with
     ``scipy.fft``, two real inverse FFTs per block); and ``np.abs`` of it (envelope);
   * peer ``scipy.signal.correlate(x, h, mode='full', method='fft')``: one FFT of the
     whole array, *real* correlation only (less work: no Hilbert part);
   * peer ``scipy.signal.oaconvolve(x, h[::-1], mode='full')``: overlap-add, real only;
   * peer ``scipy.signal.oaconvolve(x, conj(g[::-1]))`` with ``g`` the analytic FIR
     rangekit builds: the same complex output as rangekit (checked), a like-for-like peer;
   * ``block`` sweep: ``MatchedFilter(h, block=2**k).correlate(x)`` for k = 13..17 (the
     default 2^15 again as its own row), timed round-robin among themselves after the rows
     above: a call right after one of the big peers runs faster (its page faults are
     cheaper) than one after a rangekit call, so the sweep compares like with like.

   ``rk/peer`` is ``t_peer / t_rangekit`` (above 1: rangekit's complex correlation is
   faster than the peer).  If the whole-array ``scipy.signal.correlate`` would need more
   than half of the available memory it runs on 60 s and is scaled (the row says so).
2. **Streaming**: 16-bit mono WAVs of 1 and 10 minutes (``--quick``: 10 s and 1 min) in a
   temporary directory, read by ``soundfile.blocks(path, blocksize=2**16,
   dtype='float64')`` through ``MatchedFilter.stream`` keeping only the running maximum of
   the envelope.  Peak memory is ``tracemalloc``'s peak of traced allocations (numpy
   arrays; one extra untimed run each); the ratio 10 min / 1 min should be ~1.  Peer: the
   same ``soundfile.blocks`` loop decoding only.

Checks (untimed, first 60 s at most): rangekit's real part equals
``scipy.signal.correlate``, its complex output equals the analytic ``oaconvolve``, every
burst's envelope peak (folded template) is within 2 samples of its onset, and the streamed
maximum equals the whole-array one.  The script exits 1 if a check fails.

BLAS/OpenMP pools are limited to one thread (scipy.fft uses one worker by default): one
core, like the target (whole detection >= 500x realtime).

Run: ``python benchmarks/bench_matched.py [--quick] [--repeats N]``
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import resource
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import _one_core  # noqa: F401  (one thread, repo on sys.path; before numpy)
import numpy as np
import scipy.signal as ss
import soundfile as sf
from _report import goal_verdict, row

from rangekit.detect.matched import (
    DEFAULT_BLOCK,
    FLOAT32_RTOL,
    MatchedFilter,
    _analytic_fir,
    coded_template,
)
from rangekit.signals.barker import CodedBurst
from rangekit.signals.transducer import Transducer

FS = 192000.0
NOISE = 0.05
PERIOD_S = 0.050
JITTER_S = 0.010
AMP = (0.2, 0.5)
BLOCKS = (1 << 13, 1 << 14, 1 << 15, 1 << 16, 1 << 17)
WAV_BLOCKSIZE = 1 << 16
TARGET_X = 500.0
#: Issue 20's goals: MatchedFilter.correlate >= 800x, stream from a 16-bit WAV >= 500x.
GOAL_CORRELATE_X = 800.0
GOAL_STREAM_X = 500.0
#: A burst's envelope peak must be within this many samples of its onset.
PEAK_TOL = 2
#: A different block counts as "clearly faster" than the default above this speed-up.
CLEARLY = 1.15
CHECK_S = 60.0


def make_signal(duration_s: float, burst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (x, onsets): noise with ``burst`` every 50 +- 10 ms at known onsets."""
    rng = np.random.default_rng(2026)
    n = int(round(duration_s * FS))
    x = NOISE * rng.standard_normal(n)
    period, jitter = int(PERIOD_S * FS), int(JITTER_S * FS)
    starts = np.arange(jitter, n - len(burst) - jitter, period)
    starts = starts + rng.integers(-jitter, jitter + 1, size=len(starts))
    amps = rng.uniform(*AMP, size=len(starts))
    x[starts[:, None] + np.arange(len(burst))[None, :]] += amps[:, None] * burst[None, :]
    return x, starts


# --- memory: peak RSS growth (Linux: /proc/self/status VmHWM, reset via clear_refs) -------


def _status_kb(key: str) -> float:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(key + ":"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return math.nan


def _reset_peak_rss() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")  # resets VmHWM to the current RSS (Linux >= 4.0)
        return True
    except OSError:
        return False


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


def measure(fn: Callable[[], object]) -> tuple[float, float, float, float]:
    """Wall time of one call of ``fn``, the growth of peak RSS during it (bytes), the
    kernel (system) CPU time of the process during it (page faults of fresh memory) and
    its whole CPU time (user + system, ``time.process_time``)."""
    gc.collect()
    rss0 = _status_kb("VmRSS")
    ok = _reset_peak_rss()
    sys0 = resource.getrusage(resource.RUSAGE_SELF).ru_stime
    c0 = time.process_time()
    t0 = time.perf_counter()
    res = fn()
    t = time.perf_counter() - t0
    cpu = time.process_time() - c0
    t_sys = resource.getrusage(resource.RUSAGE_SELF).ru_stime - sys0
    peak = _status_kb("VmHWM") - rss0 if ok else math.nan
    del res
    return t, peak, t_sys, cpu


@dataclass
class Row:
    name: str
    fn: Callable[[], object] | None
    note: str = ""
    peer: bool = False
    scale: float = 1.0  # the call covers 1 / scale of the signal
    t: float = math.inf
    cpu: float = math.inf  # best CPU time (user + system) of a call, scaled like t
    sys_share: float = math.nan  # kernel CPU time / wall time of the best call
    mem: float = math.nan
    mem_kind: str = "RSS"
    dur: float = 0.0  # seconds of audio the row covers (0: the whole signal)

    def run(self) -> None:
        t, m, t_sys, cpu = measure(self.fn)
        if t * self.scale < self.t:
            self.t, self.sys_share = t * self.scale, t_sys / t
        self.cpu = min(self.cpu, cpu * self.scale)
        self.mem = m if math.isnan(self.mem) else max(self.mem, m)


def round_robin(rows: list[Row], repeats: int) -> None:
    """Time ``rows`` one after the other, ``repeats`` rounds, each round starting one row
    later (load drifts and the state the previous call leaves hit all rows alike)."""
    for k in range(repeats):
        for i in range(len(rows)):
            rows[(i + k) % len(rows)].run()


def gb(b: float) -> str:
    if math.isnan(b):
        return "n/a"
    return f"{b / 1e9:.2f} GB" if b >= 1e8 else f"{b / 1e6:.1f} MB"


# --- streaming ------------------------------------------------------------------------------


def stream_max(path: str, h: np.ndarray) -> float:
    """Running maximum of the envelope of a WAV streamed through ``MatchedFilter.stream``."""
    mf = MatchedFilter(h)
    m = 0.0
    for y in mf.stream(sf.blocks(path, blocksize=WAV_BLOCKSIZE, dtype="float64")):
        m = max(m, float(np.max(np.abs(y))))
    return m


def stream_max32(path: str, h: np.ndarray) -> float:
    """:func:`stream_max` at float32: float32 blocks into a float32 filter."""
    mf = MatchedFilter(h, dtype="float32")
    m = 0.0
    for y in mf.stream(sf.blocks(path, blocksize=WAV_BLOCKSIZE, dtype="float32")):
        m = max(m, float(np.max(np.abs(y))))
    return m


def decode_max(path: str) -> float:
    """The same ``soundfile.blocks`` loop, decoding only (running max of |x|)."""
    m = 0.0
    for b in sf.blocks(path, blocksize=WAV_BLOCKSIZE, dtype="float64"):
        m = max(m, float(np.max(np.abs(b))))
    return m


def traced_peak(fn: Callable[[], object]) -> float:
    """Peak of ``tracemalloc``'s traced allocations during one call (bytes)."""
    gc.collect()
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        fn()
        return float(tracemalloc.get_traced_memory()[1])
    finally:
        tracemalloc.stop()


# --- checks ---------------------------------------------------------------------------------


def checks(x: np.ndarray, onsets: np.ndarray, templates: dict[str, np.ndarray]) -> bool:
    """Untimed checks on the first 60 s: peers compute the same, peaks at the onsets."""
    n = min(len(x), int(CHECK_S * FS))
    xs = x[:n]
    ok = True
    for label, h in templates.items():
        c = MatchedFilter(h).correlate(xs)
        ref = ss.correlate(xs, h, mode="full", method="fft")[len(h) - 1 : len(h) - 1 + n]
        d_re = float(np.max(np.abs(c.real - ref)) / np.max(np.abs(ref)))
        g, pre = _analytic_fir(h)
        oa = ss.oaconvolve(xs, np.conj(g[::-1]), mode="full")[len(g) - 1 - pre :][:n]
        d_oa = float(np.max(np.abs(c - oa)) / np.max(np.abs(oa)))
        m32 = MatchedFilter(h, dtype="float32")
        d32 = float(np.max(np.abs(m32.correlate(xs) - c)) / np.max(np.abs(c)))
        d_env = float(
            np.max(np.abs(m32.envelope(xs) - np.abs(c)[:: m32.decimation]))
            / np.sqrt(np.mean(np.abs(c) ** 2))
        )
        print(
            f"  check {label}: float32 correlate vs float64 {d32:.1e} of max (tol "
            f"{FLOAT32_RTOL:g}); decimated envelope (D={m32.decimation}) vs |float64|[::D] "
            f"{d_env:.1e} of RMS (tol 1.1e-2)"
        )
        good = d_re < 1e-9 and d_oa < 1e-9 and d32 < FLOAT32_RTOL and d_env < 1.1e-2
        ok &= good
        print(
            f"  check {label}: max|Re(rk) - scipy.correlate| / max = {d_re:.1e}, "
            f"max|rk - oaconvolve(analytic)| / max = {d_oa:.1e} -> {'OK' if good else 'FAIL'}"
        )
        if label.startswith("folded"):
            env = np.abs(c)
            on = onsets[onsets + 200 < n]
            on = on[on >= 200]
            w = np.arange(-200, 201)
            err = np.argmax(env[on[:, None] + w[None, :]], axis=1) - 200
            good = bool(np.all(np.abs(err) <= PEAK_TOL))
            ok &= good
            print(
                f"  check {label}: envelope peak of {len(on)} bursts within "
                f"{np.max(np.abs(err))} samples of the onset (tol {PEAK_TOL}) -> "
                f"{'OK' if good else 'FAIL'}"
            )
    return ok


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="1 min of audio; WAVs of 10 s and 1 min")
    ap.add_argument("--repeats", type=int, default=3, help="best of N (default 3)")
    args = ap.parse_args()
    duration_s = 60.0 if args.quick else 600.0
    wav_s = (10.0, 60.0) if args.quick else (60.0, 600.0)
    repeats = max(1, args.repeats)

    h_fold = coded_template(CodedBurst(), fs=FS, tx=Transducer(), rx=Transducer())
    h_bare = coded_template(CodedBurst(), fs=FS, tx=None, rx=None)
    templates = {
        f"folded tx+rx ({len(h_fold)} taps)": h_fold,
        f"bare drive ({len(h_bare)} taps)": h_bare,
    }
    t0 = time.perf_counter()
    x, onsets = make_signal(duration_s, h_fold)
    try:
        load = "load average {:.2f} {:.2f} {:.2f}".format(*os.getloadavg())
    except OSError:
        load = "load average unknown"
    print(
        f"signal: {duration_s:.0f} s at {FS:.0f} Hz ({x.size} samples, {x.nbytes / 1e9:.2f} GB), "
        f"{len(onsets)} Barker-7 bursts through tx+rx, noise sigma {NOISE}; best of {repeats}, "
        f"round-robin; {os.cpu_count()} cores, {load}; made in {time.perf_counter() - t0:.1f} s"
    )

    # Warm-up: imports, FFT plans of every block size, the scipy peers.
    t0 = time.perf_counter()
    w = x[: int(2 * FS)]
    for h in templates.values():
        for blk in BLOCKS:
            MatchedFilter(h, block=blk).correlate(w)
        ss.correlate(w, h, mode="full", method="fft")
        ss.oaconvolve(w, h[::-1], mode="full")
    print(f"warm-up: {time.perf_counter() - t0:.2f} s")

    ok = checks(x, onsets, templates)

    rows: list[Row] = []
    sweeps: dict[str, dict[int, Row]] = {}
    headline: dict[str, tuple[Row, list[Row]]] = {}
    n60 = int(60.0 * FS)
    for label, h in templates.items():
        g, _ = _analytic_fir(h)
        ga = np.ascontiguousarray(np.conj(g[::-1]))
        hr = np.ascontiguousarray(h[::-1])
        n_fft = MatchedFilter(h).n_fft
        rk = Row(
            f"rangekit MatchedFilter.correlate [{label}]",
            lambda h=h: MatchedFilter(h).correlate(x),
            f"complex analytic, {len(g)}-tap FIR, n_fft {n_fft}",
        )
        env = Row(
            "  rangekit np.abs(correlate) (envelope)",
            lambda h=h: np.abs(MatchedFilter(h).correlate(x)),
        )
        m32 = MatchedFilter(h, dtype="float32")
        f32 = Row(
            "  rangekit correlate, dtype float32",
            lambda m32=m32: m32.correlate(x),
            f"complex64 output; within {FLOAT32_RTOL:g} of float64",
        )
        envr = Row(
            f"  rangekit envelope (float32, decimated by {m32.decimation})",
            lambda m32=m32: m32.envelope(x),
            "complex baseband: one rfft and a 1/D-size ifft per block",
        )
        # scipy.signal.correlate of the whole array: project its memory from 60 s first.
        sc_note = "real only (no Hilbert part)"
        sc_fn, sc_scale = (lambda h=h: ss.correlate(x, h, mode="full", method="fft")), 1.0
        if x.size > n60:
            _, m60, _, _ = measure(lambda h=h: ss.correlate(x[:n60], h, mode="full", method="fft"))
            proj = m60 * x.size / n60
            if proj > 0.5 * _mem_available():
                sc_fn = lambda h=h: ss.correlate(x[:n60], h, mode="full", method="fft")  # noqa: E731
                sc_scale = x.size / n60
                sc_note += f"; run on 60 s, scaled x{sc_scale:.0f} (projected {gb(proj)})"
        peers = [
            Row("  peer scipy.signal.correlate fft", sc_fn, sc_note, True, sc_scale),
            Row(
                "  peer scipy.signal.oaconvolve (real)",
                lambda hr=hr: ss.oaconvolve(x, hr, mode="full"),
                "real only (no Hilbert part)",
                True,
            ),
            Row(
                "  peer scipy.signal.oaconvolve (analytic)",
                lambda ga=ga: ss.oaconvolve(x, ga, mode="full"),
                "same complex output as rangekit",
                True,
            ),
        ]
        sweep = {
            blk: Row(
                f"  block={blk} (2^{blk.bit_length() - 1})"
                + (" = default" if blk == DEFAULT_BLOCK else ""),
                lambda h=h, blk=blk: MatchedFilter(h, block=blk).correlate(x),
            )
            for blk in BLOCKS
        }
        sweeps[label] = sweep
        t0 = time.perf_counter()
        round_robin([rk, env, f32, envr, *peers], repeats)
        round_robin(list(sweep.values()), repeats)  # apart: no row right after a big peer
        for p in peers:
            p.note = f"{p.note}; rk/peer = {p.t / rk.t:.2f}"
        rows += [rk, env, f32, envr, *peers]
        headline[label] = (rk, peers, f32, envr)
        rows += sweep.values()
        print(f"timed [{label}]: {time.perf_counter() - t0:.0f} s wall")

    # Streaming from 16-bit WAVs.
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for s in wav_s:
            p = str(Path(tmp) / f"bursts_{s:.0f}s.wav")
            sf.write(p, x[: int(s * FS)], int(FS), subtype="PCM_16")
            paths.append(p)
        st = [
            Row(
                f"stream WAV {s:.0f} s (blocks 2^16, running max)",
                lambda p=p: stream_max(p, h_fold),
            )
            for s, p in zip(wav_s, paths, strict=True)
        ]
        dec = Row(
            f"  peer soundfile.blocks decode only ({wav_s[1]:.0f} s)",
            lambda: decode_max(paths[1]),
            peer=True,
        )
        st32 = Row(
            f"stream WAV {wav_s[1]:.0f} s, float32 (blocks 2^16, running max)",
            lambda: stream_max32(paths[1], h_fold),
        )
        round_robin([*st, st32, dec], repeats)
        traced = [traced_peak(lambda p=p: stream_max(p, h_fold)) for p in paths]
        y_whole = np.abs(MatchedFilter(h_fold).correlate(sf.read(paths[0])[0])).max()
        d_stream = abs(stream_max(paths[0], h_fold) - y_whole) / y_whole
    for s, r, tr in zip(wav_s, st, traced, strict=True):
        r.note = f"RSS growth {gb(r.mem)}; {s * FS / WAV_BLOCKSIZE:.0f} blocks"
        r.mem, r.mem_kind = tr, "traced"
    dec.note = f"decode share of the {wav_s[1]:.0f} s stream: {dec.t / st[1].t:.0%}"
    for r, s in zip(rows_stream := [*st, st32, dec], [*wav_s, *wav_s[1:], wav_s[1]], strict=True):
        r.dur = s

    print()
    print(f"  {'name':<58} {'seconds':>8} {'x-realtime':>11} {'CPU s':>7} {'x CPU':>7} "
          f"{'sys':>4} {'peak mem':>10}  note")  # fmt: skip
    for r in [*rows, *rows_stream]:
        dur = r.dur or duration_s
        mem = gb(r.mem) + ("*" if r.mem_kind == "traced" else "")
        print(
            f"  {r.name:<58} {r.t:8.3f} {dur / r.t:10.0f}x {r.cpu:7.3f} {dur / r.cpu:6.0f}x "
            f"{r.sys_share:4.0%} {mem:>10}  {r.note}"
        )
    print(
        "  CPU s: best user + system CPU time of a call (the load of a shared machine\n"
        "  inflates wall times far more); goals are judged on it.\n"
        "  sys: kernel CPU time / wall time of the best call (mostly page faults of fresh\n"
        "  memory); peak mem: growth of the process's peak RSS during the call (includes the\n"
        "  output: complex128 is 16 B/sample); * = tracemalloc peak of traced allocations."
    )

    print()
    for label, sweep in sweeps.items():
        best = min(sweep, key=lambda b: sweep[b].t)
        gain = sweep[DEFAULT_BLOCK].t / sweep[best].t
        verdict = (
            f"block={best} is {gain:.2f}x the default's speed: clearly faster (> {CLEARLY:.2f}x)"
            if best != DEFAULT_BLOCK and gain > CLEARLY
            else "the default is best or within 15 % of it"
        )
        print(
            f"  block sweep [{label}]: best block={best} "
            f"({duration_s / sweep[best].t:.0f}x); default {DEFAULT_BLOCK} "
            f"({duration_s / sweep[DEFAULT_BLOCK].t:.0f}x) -> {verdict}"
        )
    ratio = traced[1] / traced[0]
    print(
        f"  streaming memory (tracemalloc peak): {gb(traced[0])} for {wav_s[0]:.0f} s, "
        f"{gb(traced[1])} for {wav_s[1]:.0f} s: ratio {ratio:.2f} (~1 = bounded by the block)"
    )
    good = d_stream < 1e-9
    ok &= good
    print(
        f"  check stream: streamed max envelope vs whole-array ({wav_s[0]:.0f} s WAV): "
        f"rel. diff {d_stream:.1e} -> {'OK' if good else 'FAIL'}"
    )
    # Headline rows for benchmarks/run.py (ratio = t_peer / t: > 1 = faster than the peer).
    size = f"{duration_s:.0f} s at 192 kHz, best of {repeats}"
    for label, (rk, peers, f32, envr) in headline.items():
        corr, oa_real, oa_an = peers
        x32, c32 = duration_s / f32.t, duration_s / f32.cpu
        row(
            "matched",
            f"MatchedFilter(dtype=float32).correlate [{label}]",
            x32,
            "x-realtime",
            peer=corr.name.strip().removeprefix("peer "),
            peer_value=duration_s / corr.t,
            note=f"{size}; float64 {duration_s / rk.t:.0f}x; "
            + goal_verdict(f"goal >= {GOAL_CORRELATE_X:.0f}x", c32 >= GOAL_CORRELATE_X,
                      f"{c32:.0f}x, {corr.cpu / f32.cpu:.1f}x the peer", f"{x32:.0f}x"),
        )  # fmt: skip
        row(
            "matched",
            f"MatchedFilter.envelope, float32, decimated [{label}]",
            duration_s / envr.t,
            "x-realtime",
            peer=corr.name.strip().removeprefix("peer "),
            peer_value=duration_s / corr.t,
            note=f"{size}; {duration_s / envr.cpu:.0f}x CPU; the detection's noise statistics "
            "and coarse search",
        )
        for p, note in (
            (corr, "peer computes the real part only"),
            (oa_an, f"same complex output; vs real-only oaconvolve {oa_real.t / rk.t:.2f}x"),
        ):
            row(
                "matched",
                f"MatchedFilter.correlate [{label}]",
                duration_s / rk.t,
                "x-realtime",
                peer=p.name.strip().removeprefix("peer "),
                peer_value=duration_s / p.t,
                note=f"{size}; {note}; peak RSS growth {gb(rk.mem)} vs {gb(p.mem)}",
            )
    row(
        "matched",
        f"MatchedFilter.stream, {wav_s[1]:.0f} s 16-bit WAV",
        wav_s[1] / st[1].t,
        "x-realtime",
        note=f"soundfile.blocks of 2^16; decoding alone {wav_s[1] / dec.t:.0f}x",
    )
    x_st32, c_st32 = wav_s[1] / st32.t, wav_s[1] / st32.cpu
    row(
        "matched",
        f"MatchedFilter(dtype=float32).stream, {wav_s[1]:.0f} s 16-bit WAV",
        x_st32,
        "x-realtime",
        peer="soundfile.blocks decode only",
        peer_value=wav_s[1] / dec.t,
        note="float32 blocks; "
        + goal_verdict(f"goal >= {GOAL_STREAM_X:.0f}x", c_st32 >= GOAL_STREAM_X,
                  f"{c_st32:.0f}x; decode alone {wav_s[1] / dec.cpu:.0f}x", f"{x_st32:.0f}x"),
    )  # fmt: skip
    row(
        "matched",
        f"MatchedFilter.stream peak memory, {wav_s[1]:.0f} s WAV",
        traced[1] / 1e6,
        "MB",
        note=f"tracemalloc peak; {gb(traced[0])} for {wav_s[0]:.0f} s (ratio {ratio:.2f})",
    )

    x_rt = duration_s / rows[0].t
    print(
        f"\n  target: whole detection >= {TARGET_X:.0f}x realtime on one core; the matched "
        f"filter alone (folded, complex) runs at {x_rt:.0f}x ({x_rt / TARGET_X:.2f} of target)"
    )
    if not ok:
        print("\nFAIL: a check failed", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
