"""Run every ``benchmarks/bench_*.py`` in turn and print the machine facts and their output.

Each benchmark runs as its own subprocess (same interpreter, working directory = repo
root), one after the other so they do not compete for the cores; its output is streamed
under a header with its wall time and exit status.  ``--quick`` is passed to the
benchmarks that accept it (those whose source defines a ``--quick`` option); the others
run in full.  ``-k TEXT`` runs only the benchmarks whose file name contains TEXT.

Exit status: 0 if every benchmark exited 0, else 1.

Run: ``python benchmarks/run.py [--quick] [-k TEXT]``
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def cpu_model() -> str:
    """CPU model name from /proc/cpuinfo with family/model/stepping, MHz and SIMD flags."""
    info: dict[str, str] = {}
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if not line.strip():
                    break  # first processor only
                key, _, val = line.partition(":")
                info[key.strip()] = val.strip()
    except OSError:
        return platform.processor() or "unknown"
    name = info.get("model name", platform.processor() or "unknown")
    flags = set(info.get("flags", "").split())
    simd = " ".join(f for f in ("avx2", "fma", "avx512f") if f in flags) or "no avx2"
    return (
        f"{name} (family {info.get('cpu family', '?')}, model {info.get('model', '?')}, "
        f"stepping {info.get('stepping', '?')}; {info.get('cpu MHz', '?')} MHz; {simd})"
    )


def version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


def machine_facts() -> list[str]:
    n_cpu = os.cpu_count()
    try:
        n_usable = len(os.sched_getaffinity(0))
    except AttributeError:
        n_usable = n_cpu
    try:
        load = "load average {:.2f} {:.2f} {:.2f} (1, 5, 15 min)".format(*os.getloadavg())
    except OSError:
        load = "load average unknown"
    return [
        f"date       : {datetime.datetime.now().astimezone():%Y-%m-%d %H:%M %Z}",
        f"cpu        : {cpu_model()}",
        f"cores      : {n_cpu} logical, {n_usable} usable by this process; {load}",
        f"platform   : {platform.platform()}",
        f"python     : {platform.python_version()} ({sys.executable})",
        "packages   : "
        + ", ".join(f"{d} {version(d)}" for d in ("numpy", "scipy", "numba", "rangekit")),
    ]


def supports_quick(path: Path) -> bool:
    return '"--quick"' in path.read_text()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="pass --quick where supported")
    ap.add_argument("-k", dest="only", default="", help="only files whose name contains this")
    args = ap.parse_args()

    benches = sorted(p for p in HERE.glob("bench_*.py") if args.only in p.name)
    print("=" * 78)
    print("rangekit benchmarks" + (" (--quick)" if args.quick else ""))
    for line in machine_facts():
        print("  " + line)
    print(f"  benchmarks : {', '.join(p.name for p in benches) or 'none'}")
    print("=" * 78, flush=True)

    failed = []
    t_all = time.perf_counter()
    for path in benches:
        cmd = [sys.executable, str(path.relative_to(ROOT))]
        if args.quick and supports_quick(path):
            cmd.append("--quick")
        print(f"\n{'-' * 78}\n## {path.name}\n$ python {' '.join(cmd[1:])}\n{'-' * 78}", flush=True)
        t0 = time.perf_counter()
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}  # stream in order, as it is printed
        rc = subprocess.run(cmd, cwd=ROOT, env=env, check=False).returncode
        dt = time.perf_counter() - t0
        status = "ok" if rc == 0 else f"FAILED (exit {rc})"
        print(f"-- {path.name}: {status}, {dt:.1f} s wall", flush=True)
        if rc != 0:
            failed.append(path.name)

    print(f"\n{'=' * 78}\nall benchmarks: {time.perf_counter() - t_all:.1f} s wall; ", end="")
    print(f"failed: {', '.join(failed)}" if failed else "all exited 0")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
