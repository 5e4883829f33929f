"""Benchmark the wall time of the whole ``rangekit range`` command, start-up included.

Command: ``rangekit range fixtures_audio/beepbeep_2p5m.wav --self-distance 0.1`` (a
1.26 s two-channel 44.1 kHz exchange, true distance 2.5 m), run as a subprocess, exactly
as a user runs it.  The console script is the one installed next to this interpreter
(``<sys.prefix>/bin/rangekit``); if the ``rangekit`` found on PATH is another file (a
pyenv shim, a wrapper), it is timed as a second row, since that is what typing
``rangekit`` runs.

Peers, run in the same loop with the same interpreter: ``python -c pass`` (interpreter
start-up), ``python -c "import numpy, scipy"`` and ``python -c "import numpy, scipy,
scipy.signal"``.  Every command runs once first (warm numba cache, warm file cache; the
output of ``rangekit range`` is checked against the fixture's true distance), then the
commands are timed round-robin ``--repeats`` times (default 10; ``--quick``: 3), so load
changes on a shared machine hit all of them alike.  Reported: best and median wall time
(``time.perf_counter`` around ``subprocess.run``), and the median relative to
``python -c pass`` and to ``rangekit range``.  One ``python -X importtime`` run of the
command then lists the slowest top-level imports.

Targets: under 1 s (acceptance) and <= 0.5 s (design target), judged on the median.

Run: ``python benchmarks/bench_range_cli.py [--quick] [--repeats N]``
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import _one_core  # noqa: F401  (one thread, bytecode cache; before numpy)
import soundfile as sf
from _report import row

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = ROOT / "fixtures_audio" / "beepbeep_2p5m.wav"
TRUTH = FIXTURE.with_suffix(".json")
ARGS = ["range", str(FIXTURE.relative_to(ROOT)), "--self-distance", "0.1"]
ACCEPT_S = 1.0
TARGET_S = 0.5


def rangekit_scripts() -> list[tuple[str, list[str]]]:
    """The console script(s) to time: next to the interpreter, and on PATH if different."""
    here = Path(sys.executable).parent / "rangekit"
    on_path = shutil.which("rangekit")
    out = []
    if here.exists():
        out.append(("rangekit range (console script)", [str(here)]))
    if on_path and (not here.exists() or Path(on_path).resolve() != here.resolve()):
        out.append((f"rangekit range (PATH: {on_path})", [on_path]))
    if not out:
        out.append(("python -m rangekit range", [sys.executable, "-m", "rangekit"]))
    return [(name, [*cmd, *ARGS]) for name, cmd in out]


def run(cmd: list[str]) -> tuple[float, subprocess.CompletedProcess]:
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    return time.perf_counter() - t0, proc


def check_range_output(name: str, proc: subprocess.CompletedProcess) -> bool:
    """Check that the command succeeded and printed the true distance (+- 5 cm)."""
    truth = json.loads(TRUTH.read_text())["pairs"][0]["distance_m"]
    m = re.search(r"^\s*0\s+1\s+([0-9.]+)", proc.stdout, flags=re.MULTILINE)
    ok = proc.returncode == 0 and m is not None and abs(float(m.group(1)) - truth) < 0.05
    got = m.group(1) if m else "nothing"
    print(
        f"  check {name}: exit {proc.returncode}, distance {got} m (truth {truth:.4f} m) "
        f"-> {'OK' if ok else 'FAIL'}"
    )
    if not ok:
        print(proc.stdout + proc.stderr, file=sys.stderr)
    return ok


def import_breakdown(cmd: list[str]) -> None:
    """Print the slowest top-level imports of one ``-X importtime`` run of ``cmd``."""
    script = cmd[0]
    if Path(script).resolve() == Path(sys.executable).resolve():
        full = [sys.executable, "-X", "importtime", *cmd[1:]]
    else:
        full = [sys.executable, "-X", "importtime", script, *cmd[1:]]
    proc = subprocess.run(full, cwd=ROOT, capture_output=True, text=True, check=False)
    rows = []
    names = set()
    for line in proc.stderr.splitlines():
        m = re.match(r"import time:\s+(\d+)\s+\|\s+(\d+)\s+\|( *)(\S+)", line)
        if not m:
            continue
        names.add(m.group(4))
        if len(m.group(3)) == 1:  # top level (imported by the script itself)
            rows.append((int(m.group(2)) / 1e6, m.group(4)))
    rows.sort(reverse=True)
    total = sum(t for t, _ in rows)
    print(f"\nslowest top-level imports of one run (python -X importtime), {total:.3f} s in all:")
    for t, name in rows[:8]:
        print(f"  {t:7.3f} s  {name}")
    heavy = [m for m in ("numba", "scipy.signal", "matplotlib", "scipy.fft") if m in names]
    print(f"  heavy modules imported: {', '.join(heavy) if heavy else 'none'} (of numba, ", end="")
    print("scipy.signal, matplotlib, scipy.fft)")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 repeats instead of 10")
    ap.add_argument("--repeats", type=int, default=10, help="timed runs per command (10)")
    args = ap.parse_args()
    repeats = 3 if args.quick else max(1, args.repeats)

    py = sys.executable
    commands = [
        *rangekit_scripts(),
        ("python -c pass", [py, "-c", "pass"]),
        ('python -c "import numpy, scipy"', [py, "-c", "import numpy, scipy"]),
        (
            'python -c "import numpy, scipy, scipy.signal"',
            [py, "-c", "import numpy, scipy, scipy.signal"],
        ),
    ]
    print(f"command: rangekit {' '.join(ARGS)}  (cwd {ROOT})")
    print(f"interpreter: {py}; {repeats} timed runs per command, round-robin, after one warm run")

    ok = True
    for name, cmd in commands:
        _, proc = run(cmd)
        if name.startswith(("rangekit", "python -m rangekit")):
            ok &= check_range_output(name, proc)
        elif proc.returncode != 0:
            print(f"  {name}: exit {proc.returncode}\n{proc.stderr}", file=sys.stderr)
            ok = False

    times: dict[str, list[float]] = {name: [] for name, _ in commands}
    for _ in range(repeats):
        for name, cmd in commands:
            t, _ = run(cmd)
            times[name].append(t)

    med = {name: statistics.median(ts) for name, ts in times.items()}
    ref_pass = med["python -c pass"]
    ref_range = med[commands[0][0]]
    print()
    print(f"  {'command':<52} {'best s':>7} {'median s':>9} {'/ pass':>7} {'/ range':>8}")
    for name, ts in times.items():
        print(
            f"  {name:<52} {min(ts):7.3f} {med[name]:9.3f} "
            f"{med[name] / ref_pass:6.1f}x {med[name] / ref_range:7.2f}x"
        )
    print("  (ratios: median over the median of `python -c pass` and of the first row)")

    for name, _ in commands:
        if not name.startswith(("rangekit", "python -m rangekit")):
            continue
        m = med[name]
        acc = "MET" if m < ACCEPT_S else "NOT MET"
        des = "MET" if m <= TARGET_S else "NOT MET"
        print(
            f"\n  {name}: median {m:.3f} s, best {min(times[name]):.3f} s\n"
            f"    acceptance < {ACCEPT_S:.1f} s: {acc};  design target <= {TARGET_S:.1f} s: {des}"
        )

    # Headline rows for benchmarks/run.py: the first rangekit row (the console script).
    name = commands[0][0]
    m, audio_s = med[name], sf.info(str(FIXTURE)).duration
    verdicts = (
        f"acceptance < {ACCEPT_S:.1f} s: {'met' if m < ACCEPT_S else 'NOT met'}; "
        f"design <= {TARGET_S:.1f} s: {'met' if m <= TARGET_S else 'NOT met'}"
    )
    peer = 'python -c "import numpy, scipy"'
    row("range_cli", f"{name}, median wall", m, "s", peer=peer, peer_value=med[peer],
        note=f"best {min(times[name]):.3f} s of {repeats} runs; {verdicts}")  # fmt: skip
    row("range_cli", f"{name}, whole command", audio_s / m, "x-realtime",
        note=f"{audio_s:.2f} s two-channel 44.1 kHz file (one exchange), median wall; "
        "start-up included")  # fmt: skip

    import_breakdown(commands[0][1])
    if not ok:
        print("\nFAIL: a command failed or printed a wrong distance", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
