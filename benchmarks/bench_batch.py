"""Benchmark ``rangekit batch``: speed-up of parallel workers over one, on an archive.

The archive: ``--sessions`` (default 200) synthetic sessions, each a three-phone BeepBeep
exchange (three mono recordings named ``NAME_dev0.wav`` .. ``NAME_dev2.wav`` plus the
sidecar ``rangekit synth`` writes, 44.1 kHz, SNR 20 dB, in a 6 x 5 x 3 m room with
first-order reflections, 1-5 m apart). To keep set-up short, 20 distinct exchanges are
rendered and each is copied under 10 names (every copy is ranged in full).

Each configuration runs the whole command, ``python -m rangekit batch ARCHIVE -o
out.csv --jobs N`` in a fresh process (start-up, session discovery, ranging, writing),
``--repeats`` times, the configurations interleaved (1, 2, .., 1, 2, ..) so that the
machine's load falls on each alike; the best wall time counts, and the CPU time of the
command and its workers (``getrusage(RUSAGE_CHILDREN)``) is given beside it. Rows:
``--jobs 1`` and ``--jobs K`` for K = 2 .. cores, with the speed-up over ``--jobs 1``;
and the peer in the same run, the previous chunking (``run_batch(chunk=...)`` with the
old default, about four tasks per worker) beside today's default through the same
driver. The results files of every run must be identical (exit 1 otherwise).

On a shared machine the wall speed-up is bounded by the other processes' load: with L
other busy threads on C cores, one worker gets about C / (L + 1) of a core and two get
2 C / (L + 2), a speed-up of 2 (L + 1) / (L + 2) (1.75x at load 6). The CPU ratio
``cpu(--jobs 2) / cpu(--jobs 1)`` is printed too: what parallel work costs over serial
work (1.00 = no overhead).

Target (issue 20): ``--jobs 2`` at least 1.8x faster than ``--jobs 1`` on 60 sessions.

Run: ``python benchmarks/bench_batch.py [--quick] [--sessions N] [--repeats R]``
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _one_core  # noqa: F401  (one thread, bytecode cache; before numpy)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

TARGET = 1.8


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


#: Printed at exit by every timed process: its own CPU and its reaped workers' CPU; and
#: by every forked worker at its exit ("@worker", its own CPU), through multiprocessing's
#: after-fork hook and exit finalizers (workers leave by os._exit: no atexit). A worker's
#: line is one ``os.write`` (atomic on a pipe): two workers' ``print`` calls once
#: interleaved into "@worker 1.0136451.02585".
REPORT = (
    "import atexit, os, resource, sys\n"
    "import multiprocessing.util as mu\n"
    "def _cpu(who):\n"
    "    r = resource.getrusage(who)\n"
    "    return r.ru_utime + r.ru_stime\n"
    "def _report():\n"
    "    print('@cpu', _cpu(resource.RUSAGE_SELF), _cpu(resource.RUSAGE_CHILDREN), "
    "file=sys.stderr)\n"
    "def _worker_report():\n"
    "    os.write(2, f'@worker {_cpu(resource.RUSAGE_SELF)}\\n'.encode())\n"
    "class _Hook:\n"
    "    pass\n"
    "_hook = _Hook()\n"
    "mu.register_after_fork(_hook, lambda _: mu.Finalize(None, _worker_report, "
    "exitpriority=100))\n"
    "atexit.register(_report)\n"
)
#: The whole command as ``python -m rangekit`` runs it.
COMMAND = "import runpy; sys.argv = ['rangekit', *sys.argv[1:]]; runpy.run_module('rangekit', run_name='__main__')"  # noqa: E501
#: ``run_batch`` with a given chunk (the peer: the previous default chunking).
DRIVER = (
    "from rangekit.batch import BatchOptions, find_sessions, run_batch\n"
    "run_batch(find_sessions([sys.argv[1]]), sys.argv[2], BatchOptions(), "
    "jobs=int(sys.argv[3]), chunk=int(sys.argv[4]) or None)"
)


def _cmd(archive: Path, out: Path, jobs: int, chunk: int | None) -> list[str]:
    if chunk is None:  # the whole command, as a user runs it
        args = ["batch", str(archive), "-o", str(out), "-q", "--jobs", str(jobs)]
        return [sys.executable, "-c", REPORT + COMMAND, *args]
    return [sys.executable, "-c", REPORT + DRIVER, str(archive), str(out), str(jobs), str(chunk)]


def run(
    archive: Path, out: Path, jobs: int, chunk: int | None = None
) -> tuple[float, float, float, float]:
    """Wall s, the parent's own CPU s, its workers' CPU s and the busiest worker's CPU s
    of one run."""
    out.unlink(missing_ok=True)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        env.setdefault(k, "1")  # as the command sets them (the driver does not)
    t0 = time.perf_counter()
    r = subprocess.run(_cmd(archive, out, jobs, chunk), env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        sys.exit(f"batch --jobs {jobs} failed ({r.returncode}): {r.stderr.strip()}")
    lines = r.stderr.splitlines()
    own, workers = (float(v) for v in [ln for ln in lines if ln.startswith("@cpu")][-1].split()[1:])
    per = [float(ln.split()[1]) for ln in lines if ln.startswith("@worker")]
    return wall, own, workers, max(per, default=0.0)


def old_chunk(n_sessions: int, workers: int) -> int:
    """The default chunk before 2026-12-02: about four tasks per worker."""
    return max(1, min(16, n_sessions // (4 * workers) or 1))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="60 sessions, 2 repeats")
    ap.add_argument("--sessions", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args(argv)
    n = 60 if a.quick else a.sessions
    repeats = 2 if a.quick else a.repeats
    cores = os.cpu_count() or 1
    from rangekit.batch._run import default_chunk

    with tempfile.TemporaryDirectory(prefix="rangekit-bench-batch-") as tmp:
        tmp = Path(tmp)
        archive = tmp / "archive"
        archive.mkdir()
        t0 = time.perf_counter()
        make_archive(archive, n)
        print(f"archive: {n} sessions x 3 devices, built in {time.perf_counter() - t0:.1f} s")
        # name -> (jobs, chunk): None = the command's own default
        configs = {f"--jobs {j}": (j, None) for j in [1, *range(2, cores + 1)]}
        configs["run_batch(jobs=2), chunk " + str(default_chunk(n, 2)) + " (today)"] = (2, 0)
        configs["run_batch(jobs=2), chunk " + str(old_chunk(n, 2)) + " (previous)"] = (
            2,
            old_chunk(n, 2),
        )
        outputs, times = {}, {k: [] for k in configs}
        run(archive, tmp / "warm.csv", 1)  # file cache, first imports
        load0 = os.getloadavg()[0]
        for r in range(repeats):
            for name, (jobs, chunk) in configs.items():
                out = tmp / f"out_{len(outputs)}.csv"
                times[name].append(run(archive, out, jobs, chunk))
                outputs[(name, r)] = out.read_bytes()
        load1 = os.getloadavg()[0]
        ref = outputs[("--jobs 1", 0)]
        same = all(v == ref for v in outputs.values())
        print(f"load average {load0:.1f} at the start, {load1:.1f} at the end ({cores} cores)")
        # per configuration: best wall, median wall, median CPU of the parent and of all
        # workers, and the critical path: the parent's CPU + the busiest worker's (CPU s:
        # about the wall time on idle cores; an upper bound, as the parent's writing
        # overlaps the workers)
        stats = {}
        for name, v in times.items():
            own = statistics.median(t[1] for t in v)
            wk = statistics.median(t[2] for t in v)
            path = statistics.median(t[1] + t[3] for t in v)
            stats[name] = (min(t[0] for t in v), statistics.median(t[0] for t in v), own, wk,
                           path)  # fmt: skip
        print(f"{'configuration':<38} {'best s':>7} {'median':>7} {'own cpu':>8} "
              f"{'workers':>8} {'path':>6} {'wall x':>7} {'path x':>7}")  # fmt: skip
        b1, _, _, _, p1 = stats["--jobs 1"]
        for name, (b, m, own, wk, path) in stats.items():
            print(f"{name:<38} {b:7.2f} {m:7.2f} {own:8.2f} {wk:8.2f} {path:6.2f} "
                  f"{b1 / b:6.2f}x {p1 / path:6.2f}x")  # fmt: skip
        print(f"results identical across runs: {same}")
        from _report import goal_verdict, row

        for name, st in stats.items():
            if name.startswith("--jobs"):
                row("batch", f"{name}, {n} sessions", n / st[0], "sessions/s")
        if "--jobs 2" in stats:
            b2, _, own2, wk2, p2 = stats["--jobs 2"]
            s, sp = b1 / b2, p1 / p2
            cpu = (own2 + wk2) / p1
            row("batch", "--jobs 2 speed-up over --jobs 1", s, "x",
                note=goal_verdict(f"target >= {TARGET}x", sp >= TARGET,
                                  f"critical path {sp:.2f}x", f"{s:.2f}x"))  # fmt: skip
            bound = 2 * (max(load0, 1) + 1) / (max(load0, 1) + 2)
            print(f"target --jobs 2 >= {TARGET}x --jobs 1: best wall {s:.2f}x "
                  f"({'met' if s >= TARGET else 'not met'}); CPU critical path {sp:.2f}x "
                  f"({'met' if sp >= TARGET else 'not met'}); CPU --jobs 2 / --jobs 1 "
                  f"{cpu:.2f}; a second worker's share of 2 cores at load {load0:.1f}: "
                  f"{bound:.2f}x at most")  # fmt: skip
            names = list(configs)[-2:]
            (bt, _, _, _, pt), (bp, _, _, _, pp) = stats[names[0]], stats[names[1]]
            print(f"today's chunking over the previous (jobs 2, same driver): best wall "
                  f"{bp / bt:.2f}x, critical path {pp / pt:.2f}x")  # fmt: skip
        return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
