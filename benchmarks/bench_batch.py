"""Benchmark ``rangekit batch``: speed-up of parallel workers over one, on an archive.

The archive: ``--sessions`` (default 200) synthetic sessions, each a three-phone BeepBeep
exchange (three mono recordings named ``NAME_dev0.wav`` .. ``NAME_dev2.wav`` plus the
sidecar ``rangekit synth`` writes, 44.1 kHz, SNR 20 dB, in a 6 x 5 x 3 m room with
first-order reflections, 1-5 m apart). To keep set-up short, 20 distinct exchanges are
rendered and each is copied under 10 names (every copy is ranged in full).

Each configuration runs the whole command, ``python -m rangekit batch ARCHIVE -o
out.csv --jobs N`` in a fresh process (start-up, session discovery, ranging, writing),
``--repeats`` times; the best wall time counts. Rows: ``--jobs 1`` and ``--jobs K`` for K
= 2 .. cores, with the speed-up over ``--jobs 1`` and sessions per second. The results
files of every run must be identical (exit 1 otherwise).

Target (issue 7): ``--jobs 2`` at least 1.7x faster than ``--jobs 1`` on a 2-core machine.

Run: ``python benchmarks/bench_batch.py [--quick] [--sessions N] [--repeats R]``
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

TARGET = 1.7


def make_archive(folder: Path, n_sessions: int, *, distinct: int = 20, seed: int = 0) -> None:
    """``n_sessions`` three-device sessions (mono files + sidecar) in ``folder``."""
    from rangekit.io.audio import write_audio
    from rangekit.io.sidecar import write_json
    from rangekit.sim import Device, ShoeboxRoom, render_beepbeep

    rng = np.random.default_rng(seed)
    room = ShoeboxRoom((6.0, 5.0, 3.0), 0.3, 1)
    protos = []
    for k in range(min(distinct, n_sessions)):
        pts = [np.array([rng.uniform(0.5, 5.5), rng.uniform(0.5, 4.5), 1.2]) for _ in range(3)]
        up = np.array([0.0, 0.0, 0.05])
        devs = [
            Device(p - up, p + up, rec_start_s=float(rng.uniform(0, 0.1)), fs=44100.0) for p in pts
        ]
        sim = render_beepbeep(devs, snr_db=20.0, room=room, rng=rng)
        name = f"proto{k:03d}"
        files = [f"{name}_dev{i}.wav" for i in range(3)]
        for f, x in zip(files, sim.recordings, strict=True):
            write_audio(folder / f, x, fs=44100.0)
        protos.append((name, dict(sim.truth)))
    for i in range(n_sessions):
        name, truth = protos[i % len(protos)]
        new = f"s{i:04d}"
        files = []
        for d in range(3):
            shutil.copy(folder / f"{name}_dev{d}.wav", folder / f"{new}_dev{d}.wav")
            files.append(f"{new}_dev{d}.wav")
        write_json(folder / f"{new}.json", {**truth, "files": files})
    for name, _ in protos:
        for d in range(3):
            (folder / f"{name}_dev{d}.wav").unlink()


def run(archive: Path, out: Path, jobs: int) -> float:
    out.unlink(missing_ok=True)
    cmd = [sys.executable, "-m", "rangekit", "batch", str(archive), "-o", str(out), "-q"]
    cmd += ["--jobs", str(jobs)]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    t0 = time.perf_counter()
    r = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        sys.exit(f"batch --jobs {jobs} failed ({r.returncode}): {r.stderr.strip()}")
    return wall


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="60 sessions, 1 repeat")
    ap.add_argument("--sessions", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=2)
    a = ap.parse_args(argv)
    n = 60 if a.quick else a.sessions
    repeats = 1 if a.quick else a.repeats
    cores = os.cpu_count() or 1
    with tempfile.TemporaryDirectory(prefix="rangekit-bench-batch-") as tmp:
        tmp = Path(tmp)
        archive = tmp / "archive"
        archive.mkdir()
        t0 = time.perf_counter()
        make_archive(archive, n)
        print(f"archive: {n} sessions x 3 devices, built in {time.perf_counter() - t0:.1f} s")
        outputs = {}
        best = {}
        for jobs in [1, *range(2, cores + 1)]:
            times = []
            for r in range(repeats):
                out = tmp / f"out_{jobs}_{r}.csv"
                times.append(run(archive, out, jobs))
                outputs[(jobs, r)] = out.read_bytes()
            best[jobs] = min(times)
        ref = outputs[(1, 0)]
        same = all(v == ref for v in outputs.values())
        print(f"{'jobs':>5} {'wall s':>8} {'sessions/s':>11} {'speed-up':>9}")
        for jobs, t in best.items():
            print(f"{jobs:>5} {t:8.2f} {n / t:11.1f} {best[1] / t:9.2f}x")
        print(f"results identical across runs: {same}")
        from _report import row

        for jobs, t in best.items():
            row("batch", f"--jobs {jobs}, {n} sessions", n / t, "sessions/s")
        if 2 in best:
            s = best[1] / best[2]
            row("batch", "--jobs 2 speed-up over --jobs 1", s, "x", note=f"target >= {TARGET}x")
            verdict = "met" if s >= TARGET else "MISSED"
            print(f"target: --jobs 2 >= {TARGET}x --jobs 1: {s:.2f}x ({verdict})")
        return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
