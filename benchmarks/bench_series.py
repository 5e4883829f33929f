"""Benchmark ``rangekit range --series`` (two-way BeepBeep): whole command and in process.

The recording: ``bench_schemes.beepbeep_signal`` (two devices 3 m apart, an exchange
every 3 +- 0.5 s in white noise, 20 dB SNR), one two-channel 44.1 kHz 16-bit WAV of
``--duration`` s (default 600; ``--quick`` 120). x-realtime = seconds of recording per
second (wall or CPU). Everything below runs in one script, the rows interleaved over
``--repeats`` rounds (best wall counts; the CPU time beside it), so the machine's load
falls on each row alike:

* whole command, a fresh process per run: ``rangekit range --series WAV --self-distance
  0.1 --format csv -o OUT`` with ``--jobs 1`` and ``--jobs 2`` (issue 20 item 4: every
  core for one long recording); their CSVs must be byte-identical. CPU = the command and
  its workers; the CPU critical path = the command's own CPU + its busiest worker's
  (reported by each process at exit, ``bench_batch.REPORT``): about the wall time on idle
  cores, which this shared machine does not have.
* peer: decoding alone, ``soundfile`` reading the WAV in the series' blocks into float32
  in a fresh ``python -c`` (the limit of the issue's table).
* numba's start-up: a process making one cached compiled call (``bench_detect_cli.
  NUMBA_FLOOR``) less ``python -c "import numpy"``; with the in-process rate it gives the
  ceilings the start-up leaves a 600 s recording.
* in process (no start-up): ``list(range_series_beepbeep([WAV], self_distance_m=0.1))``
  today, and with the previous block reader (``series._BLOCK_DTYPE = "float64"``: float64
  decode, finiteness and peak checks of every block, a strided column per channel) -- the
  two must give identical exchanges; and the detection alone, ``detect_changepoint`` on
  each block's channels (what the series adds over its detector).

Checks (exit 1 on failure): every exchange ranged within 2 cm of 3 m; the previous
reader's exchanges equal today's exactly; ``--jobs 2`` writes the bytes ``--jobs 1`` does.

Goal (issue 20): ``range --series`` beepbeep >= 1000x realtime, whole command.

Run: ``python benchmarks/bench_series.py [--quick] [--duration S] [--repeats N]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _one_core  # noqa: F401  (one thread, repo on sys.path; before numpy)
import soundfile as sf
from _report import goal_verdict, row
from bench_batch import COMMAND, REPORT
from bench_detect_cli import NUMBA_FLOOR, run_timed
from bench_schemes import DIST_M, FS_AUDIO, TOL_BEEPBEEP_M, beepbeep_signal

from rangekit.detect.changepoint import detect_changepoint
from rangekit.ranging import series
from rangekit.ranging.series import DEFAULT_BLOCK_SAMPLES, range_series_beepbeep

GOAL_X = 1000.0

DECODE_PEER = (
    "import soundfile as sf; f = sf.SoundFile({wav!r}); "
    "[f.read({step}, dtype='float32', always_2d=True) for _ in range(0, f.frames, {step})]"
)


def run_cpu(cmd: list[str]) -> tuple[float, float, float]:
    """Wall s, CPU s of the process and its workers, and the critical path: the
    process's own CPU + its busiest worker's (about the wall time on idle cores)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, env=env, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {r.returncode}: {r.stderr.strip()[-400:]}")
    lines = r.stderr.splitlines()
    own, workers = (float(v) for v in [ln for ln in lines if ln.startswith("@cpu")][-1].split()[1:])
    busiest = max((float(ln.split()[1]) for ln in lines if ln.startswith("@worker")), default=0.0)
    return wall, own + workers, own + busiest


def in_process(fn) -> tuple[float, float, object]:
    """Wall s, CPU s (this process) and the result of ``fn()``."""
    c0, t0 = time.process_time(), time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, time.process_time() - c0, out


def series_with(dtype: str, wav: str) -> list:
    series._BLOCK_DTYPE = dtype
    try:
        return list(range_series_beepbeep([wav], self_distance_m=0.1))
    finally:
        series._BLOCK_DTYPE = "auto"


def detect_only(wav: str, step: int) -> int:
    """``detect_changepoint`` on each channel of blocks of ``step`` frames (float32)."""
    n = 0
    with sf.SoundFile(wav) as f:
        for _ in range(0, f.frames, step):
            x = f.read(step, dtype="float32", always_2d=True).T.copy()
            n += sum(len(detect_changepoint(ch, fs=FS_AUDIO).onset) for ch in x)
    return n


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="120 s, 2 rounds")
    ap.add_argument("--duration", type=float, default=None, help="seconds (default 600)")
    ap.add_argument("--repeats", type=int, default=3, help="rounds (default 3)")
    a = ap.parse_args()
    dur = a.duration or (120.0 if a.quick else 600.0)
    rounds = 2 if a.quick else max(1, a.repeats)
    rk = [sys.executable, "-c", REPORT + COMMAND]  # python -m rangekit, CPU reported
    step = DEFAULT_BLOCK_SAMPLES // 2  # the series' default core, 2 channels
    with tempfile.TemporaryDirectory(prefix="rangekit-bench-series-") as tmp:
        wav = str(Path(tmp) / "series.wav")
        x, n_ex = beepbeep_signal(dur)
        sf.write(wav, x.T, int(FS_AUDIO), subtype="PCM_16")
        del x
        out = {j: str(Path(tmp) / f"out{j}.csv") for j in (1, 2)}
        cmds = {
            f"range --series --jobs {j}": [*rk, "range", "--series", wav, "--self-distance",
                                           "0.1", "--format", "csv", "-o", out[j],
                                           "--jobs", str(j)]
            for j in (1, 2)
        }  # fmt: skip
        cmds["decode alone (peer)"] = [
            sys.executable, "-c", DECODE_PEER.format(wav=wav, step=step)
        ]  # fmt: skip
        cmds["numba start-up: one cached kernel call"] = [sys.executable, "-c", NUMBA_FLOOR]
        cmds['python -c "import numpy"'] = [sys.executable, "-c", "import numpy"]
        inproc = {
            "range_series_beepbeep (today)": lambda: series_with("auto", wav),
            "same, previous block reader": lambda: series_with("float64", wav),
            "detect_changepoint alone on the blocks": lambda: detect_only(wav, step),
        }
        for c in cmds.values():  # warm-up: numba cache, file cache
            run_timed(c)
        paths: dict[str, list[float]] = {k: [] for k in cmds}
        series_with("auto", wav)
        load0 = os.getloadavg()[0]
        walls: dict[str, list[tuple[float, float]]] = {k: [] for k in [*cmds, *inproc]}
        results = {}
        for _ in range(rounds):
            for name, c in cmds.items():
                if name.startswith("range"):
                    w, cpu, path = run_cpu(c)
                else:
                    w, cpu, _ = run_timed(c)
                    path = cpu
                walls[name].append((w, cpu))
                paths[name].append(path)
            for name, fn in inproc.items():
                w, cpu, res = in_process(fn)
                walls[name].append((w, cpu))
                results[name] = res
        load1 = os.getloadavg()[0]
        today, prev = (
            results["range_series_beepbeep (today)"],
            results["same, previous block reader"],
        )
        ok_dist = len(today) == n_ex and all(
            abs(e.ranges[0].distance_m - DIST_M) <= TOL_BEEPBEEP_M for e in today
        )
        ok_same = [(e.t_s, e.ranges) for e in today] == [(e.t_s, e.ranges) for e in prev]
        ok_jobs = Path(out[1]).read_bytes() == Path(out[2]).read_bytes()
        print(f"{dur:.0f} s, 2 channels 44.1 kHz 16-bit, {n_ex} exchanges; load average "
              f"{load0:.1f} at the start, {load1:.1f} at the end ({os.cpu_count()} "
              "cores)")  # fmt: skip
        print(f"{'row':<42} {'wall s':>7} {'cpu s':>7} {'x wall':>8} {'x cpu':>8}")
        best = {k: min(v) for k, v in walls.items()}
        for name, (w, cpu) in best.items():
            print(f"{name:<42} {w:7.3f} {cpu:7.3f} {dur / w:8.0f} {dur / cpu:8.0f}")
        w1, c1 = best["range --series --jobs 1"]
        w2, c2 = best["range --series --jobs 2"]
        wt, ct = best["range_series_beepbeep (today)"]
        wp, cp = best["same, previous block reader"]
        wd, cd = best["detect_changepoint alone on the blocks"]
        print(f"today over the previous reader: {wp / wt:.2f}x wall, {cp / ct:.2f}x CPU")
        print(f"series over its detection alone: {wt / wd:.2f}x wall, {ct / cd:.2f}x CPU")
        p1, p2 = (statistics.median(paths[f"range --series --jobs {j}"]) for j in (1, 2))
        print(f"--jobs 2 over --jobs 1: {w1 / w2:.2f}x best wall, {p1 / p2:.2f}x CPU critical "
              f"path ({p1:.2f} s -> {p2:.2f} s: the command's own CPU + its busiest "
              f"worker's), CPU ratio {c2 / c1:.2f}")  # fmt: skip
        print(f"whole command start-up and decode: command CPU {c1:.2f} s - in-process "
              f"{ct:.2f} s = {c1 - ct:.2f} s")  # fmt: skip
        numba = best["numba start-up: one cached kernel call"][1]
        numba -= best['python -c "import numpy"'][1]
        start = c1 - ct
        print(f"of the start-up, numba's: {numba:.2f} s (a process making one cached "
              f"compiled call, less 'import numpy'); on 600 s the start-up caps the command "
              f"at {600 / (start + 600 * ct / dur):.0f}x, "
              f"{600 / (max(start - numba, 0.0) + 600 * ct / dur):.0f}x "
              f"without numba's start-up, {dur / ct:.0f}x with none")  # fmt: skip
        verdict = "met" if dur / c1 >= GOAL_X else "not met"  # on CPU time (load)
        print(f"goal: range --series >= {GOAL_X:.0f}x realtime (whole command): "
              f"{dur / w1:.0f}x wall, {dur / c1:.0f}x CPU ({verdict})")  # fmt: skip
        print(f"checks: distances {'OK' if ok_dist else 'FAIL'}, previous reader identical "
              f"{'OK' if ok_same else 'FAIL'}, --jobs 2 bytes == --jobs 1 "
              f"{'OK' if ok_jobs else 'FAIL'}")  # fmt: skip
        row("series", "range --series beepbeep, whole command", dur / w1, "x-realtime",
            note=goal_verdict(f"goal >= {GOAL_X:.0f}x", dur / c1 >= GOAL_X,
                              f"{dur / c1:.0f}x; in process {dur / ct:.0f}x, detection alone "
                              f"{dur / cd:.0f}x", f"{dur / w1:.0f}x"))  # fmt: skip
        row("series", "range --series --jobs 2 over --jobs 1", w1 / w2, "x",
            note=f"CPU critical path {p1 / p2:.2f}x; CPU ratio {c2 / c1:.2f}")  # fmt: skip
        return 0 if ok_dist and ok_same and ok_jobs else 1


if __name__ == "__main__":
    sys.exit(main())
