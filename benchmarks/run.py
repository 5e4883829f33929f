"""Run every ``benchmarks/bench_*.py`` in turn; print the machine facts and one summary table.

Each benchmark runs as its own subprocess (same interpreter, working directory = repo
root), one after the other so they do not compete for the cores; its output is streamed
under a header with its wall time and exit status.  ``--quick`` is passed to the
benchmarks that accept it (those whose source defines a ``--quick`` option); the others
run in full.  ``-k TEXT`` runs only the benchmarks whose file name contains TEXT.

Summary table.  Every benchmark states its headline numbers with
``_report.row(...)``, one line ``@row {json}`` each on its stdout; this script takes those
lines out of the streamed output and prints them at the end as ONE table: bench, metric,
value, unit, peer, the peer's value, ratio (> 1 = rangekit faster or smaller than the peer
measured in the same run; ``_report``) and the peak RSS of that benchmark's process. A
benchmark without ``@row`` lines, or one that failed, gets a line saying so.
``--markdown FILE`` also writes the machine facts and the table as a markdown section for
``docs/performance.md``; ``--json FILE`` writes the machine facts, one record per
benchmark and the raw rows.

Peak RSS.  The subprocess is reaped with ``os.wait4(pid)``, whose ``ru_maxrss`` is that
process's own peak resident set (Linux: kB, macOS: bytes).  ``getrusage(RUSAGE_CHILDREN)``
deltas would not do: its ``ru_maxrss`` is the maximum over all children reaped so far,
not a sum, so a benchmark after a bigger one would show the bigger one's peak.  Linux
folds the peaks of the benchmark's own reaped subprocesses into its ``ru_maxrss`` as a
maximum too, so for a benchmark that starts subprocesses (``bench_range_cli``,
``bench_batch``) the column is the largest single process, not the sum of processes that
ran at the same time.  A benchmark that resets its high-water mark to measure one call
(``bench_matched`` writes ``/proc/self/clear_refs``) also resets ``ru_maxrss``; so, on
Linux, the process's ``VmHWM`` is also sampled every 50 ms while it runs and the column is
the larger of the two (a peak that is reset less than 50 ms after it happened can still
be missed).  Where ``os.wait4`` is missing (Windows) only the sampling is left.  A
child's ``ru_maxrss`` may also include the parent's resident pages at fork time (before
exec): run this script from a small process (a shell), not from a large one.

Bytecode.  Where ``PYTHONDONTWRITEBYTECODE`` is set, the benchmarks run without it and with
``PYTHONPYCACHEPREFIX`` in a temporary folder (``_one_core``), so that the commands they
time do not compile rangekit's sources on every start (an installed package does not).

Exit status: 0 if every benchmark exited 0, else 1.

Run: ``python benchmarks/run.py [--quick] [-k TEXT] [--markdown FILE] [--json FILE]``
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

#: Start of a row line (``_report.PREFIX``; repeated so this script imports nothing local).
ROW_PREFIX = "@row "
#: Keys every row line must carry (``_report.FIELDS``).
ROW_FIELDS = ("bench", "metric", "value", "unit", "peer", "peer_value", "ratio", "note")
#: Period of the VmHWM sampling of a running benchmark, s (see the module docstring).
HWM_PERIOD_S = 0.05
#: Folder (in the temporary directory) of the benchmarks' bytecode where none was to be
#: written (``PYTHONDONTWRITEBYTECODE``; ``_one_core.PYCACHE``).
PYCACHE_DIR = "rangekit-bench-pycache"
#: Columns of the summary table.
COLUMNS = ("bench", "metric", "value", "unit", "peer", "peer value", "ratio", "peak RSS", "note")


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


def memory_total() -> str:
    """Total RAM from /proc/meminfo."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemTotal:"):
                    return f"{float(line.split()[1]) / 2**20:.1f} GiB"
    except OSError:
        pass
    return "unknown"


def machine_facts() -> list[tuple[str, str]]:
    """(name, value) pairs: date, CPU, cores and load, memory, platform, versions."""
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
        ("date", f"{datetime.datetime.now().astimezone():%Y-%m-%d %H:%M %Z}"),
        ("cpu", cpu_model()),
        ("cores", f"{n_cpu} logical, {n_usable} usable by this process; {load}"),
        ("memory", memory_total()),
        ("platform", platform.platform()),
        ("python", f"{platform.python_version()} ({sys.executable})"),
        (
            "packages",
            ", ".join(
                f"{d} {version(d)}" for d in ("numpy", "scipy", "numba", "filterpy", "rangekit")
            ),
        ),
    ]


def supports_quick(path: Path) -> bool:
    return '"--quick"' in path.read_text()


# --------------------------------------------------------------------------- rows
def parse_row(line: str) -> dict[str, Any] | None:
    """The row of one output line ``@row {json}``; None if the line is not a row line.

    Raises
    ------
    ValueError
        The line starts with ``@row `` but is not a JSON object with the row's keys.
    """
    if not line.startswith(ROW_PREFIX):
        return None
    try:
        obj = json.loads(line[len(ROW_PREFIX) :])
    except json.JSONDecodeError as e:
        raise ValueError(f"row line is not JSON ({e}): {line.strip()!r}") from None
    if not isinstance(obj, dict):
        raise ValueError(f"row line is not a JSON object: {line.strip()!r}")
    missing = [k for k in ROW_FIELDS if k not in obj]
    if missing:
        raise ValueError(f"row line lacks {', '.join(missing)}: {line.strip()!r}")
    for k in ("value", "peer_value", "ratio"):
        v = obj[k]
        if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)):
            raise ValueError(f"row line has a non-numeric {k}={v!r}: {line.strip()!r}")
    return {k: obj[k] for k in ROW_FIELDS}


@dataclass
class BenchResult:
    """One benchmark's run: exit status, wall time, peak RSS and its rows."""

    file: str
    command: str
    returncode: int
    wall_s: float
    peak_rss_bytes: float | None
    rows: list[dict[str, Any]] = field(default_factory=list)
    bad_lines: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        """The file name without ``bench_`` and ``.py`` (what rows call ``bench``)."""
        stem = Path(self.file).stem
        return stem.removeprefix("bench_")


def collect(lines: Iterable[str], echo=None) -> tuple[list[dict[str, Any]], list[str]]:
    """Rows and malformed row lines of a benchmark's output; other lines go to ``echo``."""
    rows: list[dict[str, Any]] = []
    bad: list[str] = []
    for line in lines:
        try:
            r = parse_row(line)
        except ValueError as e:
            bad.append(str(e))
            continue
        if r is not None:
            rows.append(r)
        elif echo is not None:
            echo(line)
    return rows, bad


def maxrss_bytes(ru_maxrss: float) -> float:
    """``ru_maxrss`` in bytes (kilobytes on Linux and the BSDs, bytes on macOS)."""
    return float(ru_maxrss) * (1.0 if sys.platform == "darwin" else 1024.0)


def _hwm_bytes(pid: int) -> float | None:
    """VmHWM (peak RSS since start or the last reset) of a live process; None if unknown."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) * 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return None


def _sample_hwm(pid: int, stop: threading.Event, peak: list[float]) -> None:
    """Keep ``peak[0]`` at the largest VmHWM of ``pid`` seen until ``stop`` is set."""
    while True:
        v = _hwm_bytes(pid)
        if v is not None:
            peak[0] = max(peak[0], v)
        if stop.wait(HWM_PERIOD_S):
            return


def run_bench(cmd: Sequence[str], *, cwd: Path, display: str) -> BenchResult:
    """Run one benchmark: stream its stdout (without row lines), collect rows, peak RSS."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONIOENCODING": "utf-8"}
    if env.pop("PYTHONDONTWRITEBYTECODE", None) is not None:
        # as _one_core does: commands compile rangekit once, as an installed package has
        env.setdefault("PYTHONPYCACHEPREFIX", str(Path(tempfile.gettempdir()) / PYCACHE_DIR))
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        list(cmd), cwd=cwd, env=env, stdout=subprocess.PIPE, text=True, encoding="utf-8",
        errors="replace", bufsize=1,
    )  # fmt: skip
    # The child is reaped by os.wait4 below only: nothing here may poll() or wait() it.
    peak, stop = [0.0], threading.Event()
    sampler = threading.Thread(target=_sample_hwm, args=(proc.pid, stop, peak), daemon=True)
    sampler.start()
    out = proc.stdout  # a pipe (stdout=PIPE)
    with out:
        rows, bad = collect(iter(out.readline, ""), echo=lambda s: print(s, end="", flush=True))
    stop.set()
    sampler.join()
    if hasattr(os, "wait4"):
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        rss: float | None = max(maxrss_bytes(usage.ru_maxrss), peak[0])
    else:
        proc.wait()
        rss = peak[0] or None
    wall = time.perf_counter() - t0
    return BenchResult(Path(cmd[1]).name, display, proc.returncode, wall, rss, rows, bad)


# --------------------------------------------------------------------------- the table
def fmt_num(v: float | None) -> str:
    """About three significant digits; ``n/a`` for a missing number."""
    if v is None:
        return "n/a"
    a = abs(v)
    if a >= 100:
        return f"{v:.0f}"
    if a >= 10:
        return f"{v:.1f}"
    if a >= 1:
        return f"{v:.2f}"
    return f"{v:.3g}"


def fmt_bytes(b: float | None) -> str:
    if b is None:
        return ""
    return f"{b / 1e9:.2f} GB" if b >= 1e9 else f"{b / 1e6:.0f} MB"


def table_rows(results: Sequence[BenchResult]) -> list[list[str]]:
    """The summary table's cells (:data:`COLUMNS`), benchmarks in run order.

    The peak RSS is given on the first line of each benchmark. A benchmark without rows
    gets one line saying so; a failed one gets a line with its exit status.
    """
    out: list[list[str]] = []
    for res in results:
        lines: list[list[str]] = []
        for r in res.rows:
            lines.append(
                [
                    str(r["bench"]),
                    str(r["metric"]),
                    fmt_num(r["value"]),
                    str(r["unit"]),
                    r["peer"] or "",
                    "" if r["peer_value"] is None else fmt_num(r["peer_value"]),
                    "" if r["ratio"] is None else fmt_num(r["ratio"]) + "x",
                    "",
                    str(r["note"] or ""),
                ]
            )
        if res.returncode != 0:
            lines.append([res.name, f"FAILED (exit {res.returncode})", *[""] * 7])
        elif not res.rows:
            lines.append([res.name, "(no @row lines)", *[""] * 7])
        if res.bad_lines:
            lines.append([res.name, f"({len(res.bad_lines)} malformed @row lines)", *[""] * 7])
        lines[0][7] = fmt_bytes(res.peak_rss_bytes)
        out += lines
    return out


def text_table(results: Sequence[BenchResult]) -> str:
    """The summary table as aligned text (numbers right-aligned, note unpadded)."""
    cells = [list(COLUMNS), *table_rows(results)]
    right = {2, 5, 6, 7}
    widths = [max(len(r[i]) for r in cells) for i in range(len(COLUMNS))]
    lines = []
    for k, r in enumerate(cells):
        parts = [
            (c.rjust(w) if i in right and k > 0 else c.ljust(w))
            for i, (c, w) in enumerate(zip(r[:-1], widths[:-1], strict=True))
        ]
        lines.append("  " + "  ".join(parts) + "  " + r[-1])
        if k == 0:
            lines.append("  " + "  ".join("-" * w for w in widths[:-1]) + "  ----")
    return "\n".join(line.rstrip() for line in lines)


#: A verdict in a row's note: "goal <= 0.3 s: met", "target >= 2000x: NOT MET (...)".
GOAL_RE = re.compile(r"((?:goal|target|acceptance|design)[^:;]*):\s*(NOT met|NOT MET|met|MET)")


def goal_rows(results: Sequence[BenchResult]) -> list[tuple[str, str, str, str]]:
    """``(bench, metric, goal, verdict)`` of every goal that a row's note judges (issue
    20: each goal reported as met / not met)."""
    out = []
    for res in results:
        for r in res.rows:
            for goal, verdict in GOAL_RE.findall(str(r["note"] or "")):
                v = "NOT met" if verdict.lower().startswith("not") else "met"
                out.append((str(r["bench"]), str(r["metric"]), goal.strip(), v))
    return out


def goals_text(results: Sequence[BenchResult]) -> str:
    """The goals, one line each, met ones first within a benchmark."""
    rows = goal_rows(results)
    if not rows:
        return "  no goals judged"
    w = max(len(f"{b}: {m}") for b, m, _, _ in rows)
    return "\n".join(f"  {f'{b}: {m}':<{w}}  {g}: {v}" for b, m, g, v in rows)


def _md(cell: str) -> str:
    return cell.replace("|", "\\|")


def markdown_section(
    results: Sequence[BenchResult], facts: Sequence[tuple[str, str]], command: str
) -> str:
    """Machine facts and the summary table as a markdown section for docs/performance.md."""
    lines = [
        f"### `{command}`",
        "",
        "| machine | |",
        "| --- | --- |",
        *(f"| {_md(k)} | {_md(v)} |" for k, v in facts),
        "",
        "| " + " | ".join(COLUMNS) + " |",
        "| "
        + " | ".join("---:" if i in (2, 5, 6, 7) else "---" for i in range(len(COLUMNS)))
        + " |",
        *("| " + " | ".join(_md(c) for c in r) + " |" for r in table_rows(results)),
        "",
        "Ratio: > 1 = rangekit faster (or smaller) than the peer measured in the same run. "
        "Peak RSS: the benchmark process's peak resident set (`ru_maxrss` from `os.wait4`, "
        "and `VmHWM` sampled every 50 ms; the largest single process, not a sum).",
        "",
        "Goals judged by the rows (met / not met):",
        "",
        "| bench | metric | goal | verdict |",
        "| --- | --- | --- | --- |",
        *(f"| {_md(b)} | {_md(m)} | {_md(g)} | {v} |" for b, m, g, v in goal_rows(results)),
        "",
        "Benchmarks: "
        + "; ".join(
            f"`{r.file}` {'ok' if r.returncode == 0 else f'FAILED (exit {r.returncode})'}, "
            f"{r.wall_s:.0f} s"
            for r in results
        )
        + ".",
        "",
    ]
    return "\n".join(lines)


def json_report(
    results: Sequence[BenchResult], facts: Sequence[tuple[str, str]], command: str
) -> dict[str, Any]:
    """Machine facts, one record per benchmark and the raw rows (with file and peak RSS)."""
    return {
        "command": command,
        "machine": dict(facts),
        "benchmarks": [
            {
                "file": r.file,
                "command": r.command,
                "returncode": r.returncode,
                "wall_s": r.wall_s,
                "peak_rss_bytes": r.peak_rss_bytes,
                "n_rows": len(r.rows),
                "malformed_row_lines": r.bad_lines,
            }
            for r in results
        ],
        "goals": [
            {"bench": b, "metric": m, "goal": g, "verdict": v} for b, m, g, v in goal_rows(results)
        ],
        "rows": [
            {**row, "file": r.file, "peak_rss_bytes": r.peak_rss_bytes}
            for r in results
            for row in r.rows
        ],
    }


# --------------------------------------------------------------------------- main
def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="pass --quick where supported")
    ap.add_argument("-k", dest="only", default="", help="only files whose name contains this")
    ap.add_argument("--markdown", metavar="FILE", help="also write the table as markdown")
    ap.add_argument("--json", metavar="FILE", help="also write the raw rows as JSON")
    args = ap.parse_args(argv)
    command = " ".join(["python benchmarks/run.py", *(sys.argv[1:] if argv is None else argv)])

    benches = sorted(p for p in HERE.glob("bench_*.py") if args.only in p.name)
    facts = machine_facts()
    print("=" * 78)
    print("rangekit benchmarks" + (" (--quick)" if args.quick else ""))
    for k, v in facts:
        print(f"  {k:<10} : {v}")
    print(f"  {'benchmarks':<10} : {', '.join(p.name for p in benches) or 'none'}")
    print("=" * 78, flush=True)

    results: list[BenchResult] = []
    t_all = time.perf_counter()
    for path in benches:
        cmd = [sys.executable, str(path.relative_to(ROOT))]
        if args.quick and supports_quick(path):
            cmd.append("--quick")
        display = f"python {' '.join(cmd[1:])}"
        print(f"\n{'-' * 78}\n## {path.name}\n$ {display}\n{'-' * 78}", flush=True)
        res = run_bench(cmd, cwd=ROOT, display=display)
        status = "ok" if res.returncode == 0 else f"FAILED (exit {res.returncode})"
        print(
            f"-- {path.name}: {status}, {res.wall_s:.1f} s wall, peak RSS "
            f"{fmt_bytes(res.peak_rss_bytes) or 'unknown'}, {len(res.rows)} @row lines",
            flush=True,
        )
        for b in res.bad_lines:
            print(f"-- {path.name}: malformed: {b}", flush=True)
        results.append(res)

    failed = [r.file for r in results if r.returncode != 0]
    print(f"\n{'=' * 78}\nsummary: {command}")
    for k, v in facts:
        print(f"  {k:<10} : {v}")
    print()
    print(text_table(results) if results else "  no benchmarks")
    print("  ratio: > 1 = rangekit faster (or smaller) than the peer measured in the same run")
    print("\ngoals (from the rows' notes):")
    print(goals_text(results))
    print(f"\nall benchmarks: {time.perf_counter() - t_all:.1f} s wall; ", end="")
    print(f"failed: {', '.join(failed)}" if failed else "all exited 0")
    if args.markdown:
        Path(args.markdown).write_text(markdown_section(results, facts, command))
        print(f"markdown: {args.markdown}")
    if args.json:
        Path(args.json).write_text(json.dumps(json_report(results, facts, command), indent=1))
        print(f"json: {args.json}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
