"""Benchmark the peak memory of ``rangekit range --series`` on a 2 GB recording.

Acceptance (rangekit issue 7): a 2 GB WAV is ranged with ``--series`` under 400 MB peak
memory; memory is bounded by the block, not the file.

Signal: a 192 kHz 16-bit mono SRF02 echo log, 2 GiB (2^31 bytes of samples: 1.07e9
samples, 93 min, 79 891 ranging cycles of 70 ms; ``--quick``: 0.25 GiB, 11.7 min). One
noiseless cycle is rendered once (``render_echo``, a wall 1.5 m ahead and one 9 m behind,
the ring-down included) and tiled with fresh white noise (sigma 1e-3, seeded) written
block-wise with ``soundfile`` into a temporary directory (``--tmpdir``) by a subprocess of
its own; the file is deleted at the end. The measuring process itself imports neither
numpy nor rangekit: on Linux a child's ``ru_maxrss`` starts from its parent's resident
set at the fork (the parent's pages are folded in at ``exec``), so a big parent would
inflate the child's number.

Command, run as a subprocess with the interpreter running this script (one BLAS/OpenMP
thread, ``benchmarks/_one_core.py``)::

    python -m rangekit range --series --scheme echo LOG.wav --period 0.07 --format csv -o OUT.csv

Measured: the subprocess's own peak resident set (``ru_maxrss`` from ``os.wait4`` on
its pid: ``getrusage(RUSAGE_CHILDREN)`` of that one child), its wall time and the
throughput in x realtime (audio seconds per wall second). Checked: one CSV row per cycle,
and the median distance is the wall's 1.5 m (within 5 mm). Exits 1 if the peak exceeds
400 MB or a check fails.

Run: ``python benchmarks/bench_series_memory.py [--quick] [--size-gib G] [--block S]
[--tmpdir DIR]``
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _one_core  # noqa: F401  (one BLAS thread, inherited; repository on sys.path)
from _report import row

FS = 192000
CYCLE = 13440  # 70 ms at 192 kHz
LIMIT_MB = 400.0
WALL_M = 1.5


def one_cycle():
    """One noiseless SRF02 cycle (ring-down, echo from 1.5 m), peak 0.5."""
    import numpy as np

    from rangekit.floorplan import FloorPlan
    from rangekit.sim.ultrasonic import render_echo

    plan = FloorPlan.from_walls([((WALL_M, -5), (WALL_M, 5)), ((-9, -5), (-9, 5))])
    x = render_echo(plan, [(0.0, 0.0, 0.0)], snr_db=None).x[0][:CYCLE]
    return 0.5 * x / np.max(np.abs(x))


def write_log(path: Path, n_cycles: int, *, seed: int = 0) -> None:
    """Write ``n_cycles`` noisy cycles block-wise (500 cycles, 6.7 M samples, at a time)."""
    import numpy as np
    import soundfile as sf

    cycle = one_cycle()
    rng = np.random.default_rng(seed)
    with sf.SoundFile(path, "w", FS, 1, "PCM_16") as f:
        for k in range(0, n_cycles, 500):
            m = min(500, n_cycles - k)
            f.write(np.tile(cycle, m) + 1e-3 * rng.standard_normal(m * CYCLE))


def run_series(wav: Path, out: Path, block: float | None) -> tuple[int, float, float, str]:
    """Run the command; return (exit code, peak RSS in MB, wall s, stderr)."""
    cmd = [sys.executable, "-m", "rangekit", "range", "--series", "--scheme", "echo",
           str(wav), "--period", "0.07", "--format", "csv", "-o", str(out)]  # fmt: skip
    if block is not None:
        cmd += ["--block", str(block)]
    err_path = out.with_suffix(".err")
    with open(err_path, "w") as err:
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
    p.returncode = os.waitstatus_to_exitcode(status)
    rss_mb = usage.ru_maxrss * (1.0 if sys.platform == "darwin" else 1024.0) / 1e6
    return p.returncode, rss_mb, wall, err_path.read_text()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="0.25 GiB instead of 2 GiB")
    ap.add_argument("--size-gib", type=float, default=None, help="file size, GiB [2]")
    ap.add_argument("--block", type=float, default=None, help="--block S [default block]")
    ap.add_argument("--tmpdir", default=None, help="where to write the file [system temp]")
    ap.add_argument("--write", nargs=2, metavar=("PATH", "CYCLES"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.write:  # the writer subprocess
        write_log(Path(args.write[0]), int(args.write[1]))
        return 0
    gib = args.size_gib if args.size_gib is not None else (0.25 if args.quick else 2.0)
    n_cycles = int(math.ceil(gib * 2**30 / 2 / CYCLE))
    audio_s = n_cycles * CYCLE / FS
    ok = True
    with tempfile.TemporaryDirectory(dir=args.tmpdir, prefix="rk_series_") as d:
        wav, out = Path(d) / "echo_log.wav", Path(d) / "ranges.csv"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, __file__, "--write", str(wav), str(n_cycles)], check=True)
        t_write = time.perf_counter() - t0
        size = wav.stat().st_size
        print(
            f"file: {size / 2**30:.3f} GiB ({size} bytes), {n_cycles} cycles, "
            f"{audio_s / 60:.1f} min of 192 kHz mono 16-bit; written in {t_write:.1f} s"
        )
        code, rss_mb, wall, err = run_series(wav, out, args.block)
        print(f"command exit {code}; stderr: {err.strip() or '(empty)'}")
        if code != 0:
            return 1
        with open(out, newline="") as f:
            rows = list(csv.DictReader(f))
        dist = [float(r["distance_m"]) for r in rows if r["distance_m"]]
        med = statistics.median(dist) if dist else math.nan
        print(f"rows: {len(rows)} (expected {n_cycles}); with a distance: {len(dist)}; "
              f"median distance {med:.4f} m (wall at {WALL_M} m)")  # fmt: skip
        if len(rows) != n_cycles or not abs(med - WALL_M) < 5e-3:
            print("CHECK FAILED: rows or distances wrong")
            ok = False
    block = "default block" if args.block is None else f"--block {args.block:g}"
    print(f"peak RSS {rss_mb:.1f} MB (limit {LIMIT_MB:.0f} MB), wall {wall:.1f} s, "
          f"{audio_s / wall:.1f}x realtime ({block})")  # fmt: skip
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    own_mb = own * (1.0 if sys.platform == "darwin" else 1024.0) / 1e6
    if own_mb < rss_mb:
        print(f"(this measuring process: {own_mb:.1f} MB, below the child's: not folded in)")
    else:
        print(f"WARNING: this process peaked at {own_mb:.1f} MB; the child's number may be it")
    note = f"{size / 2**30:.2f} GiB 192 kHz echo log, {block}"
    limit = f"; limit {LIMIT_MB:.0f} MB"
    row("series_memory", "range --series, peak RSS", rss_mb, "MB", note=note + limit)
    row("series_memory", "range --series, throughput", audio_s / wall, "x-realtime", note=note)
    if rss_mb > LIMIT_MB:
        print(f"FAIL: peak RSS {rss_mb:.1f} MB > {LIMIT_MB:.0f} MB")
        ok = False
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
