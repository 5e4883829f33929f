"""Whole commands as a user runs them: ``rangekit detect`` on 10 minutes, and start-up.

Issue 20's whole-command rows, each a subprocess timed by ``time.perf_counter`` around it
(wall) and by the child's user + system CPU (``RUSAGE_CHILDREN`` deltas), beside peers run
in the same round-robin loop so that load on a shared machine hits all of them alike:

* ``rangekit detect REC.wav --format json -o OUT`` on a 10-minute two-channel 16-bit
  44.1 kHz WAV (``bench_schemes.beepbeep_signal``: both devices' recordings of an
  exchange every 3 +- 0.5 s in white noise, 200 exchanges, 400 beeps per channel; the
  output is checked: 400 arrivals per channel). Peers: decoding alone (``python -c``
  ``soundfile.read(REC, dtype="float32")``) and decoding plus the ShortTimeFFT band
  energy of both channels (``_stft_peer.stft_band_energy``, ``mfft=128``, the bin nearest
  16 kHz: what a scipy user computes before any detection). Goal: >= 1500x realtime
  (600 s of recording per second of wall time) and >= 25x the ShortTimeFFT peer.
* ``rangekit range fixtures_audio/beepbeep_2p5m.wav --self-distance 0.1`` (goal: <= 0.3 s
  wall) and ``rangekit --help`` (goal: numba not imported; checked in one ``python
  -X importtime`` run of each, which also lists the slowest top-level imports), beside
  ``python -c pass`` and ``python -c "import numpy"``.

* What is left of the detect goal: the same recording through ``detect_files`` in this
  process (warm: decoding and both channels' detection, best CPU of the rounds) and a
  process that makes one cached compiled call (``NUMBA_FLOOR``: numba's start-up, less
  ``python -c "import numpy"``) split the command's CPU, and give its ceilings without
  numba's start-up and with no start-up at all.

BLAS/OpenMP pools are one thread in every child (``OMP_NUM_THREADS=1`` etc.).

Run: ``python benchmarks/bench_detect_cli.py [--quick] [--repeats N]`` (``--quick``: the
same 10-minute file, 2 rounds instead of 3, the ShortTimeFFT peer in the first only).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _one_core  # noqa: F401  (one thread, repo on sys.path; before numpy)
import soundfile as sf
from _report import goal_verdict, row
from bench_schemes import FS_AUDIO, beepbeep_signal

ROOT = Path(__file__).resolve().parents[1]
DURATION_S = 600.0
GOAL_DETECT_X = 1500.0
GOAL_DETECT_PEER = 25.0
GOAL_RANGE_S = 0.3
FIXTURE = ROOT / "fixtures_audio" / "beepbeep_2p5m.wav"
#: A process that makes one call of a cached compiled kernel: numba's start-up (its
#: import, its registries, the cache load) with the interpreter and numpy.
NUMBA_FLOOR = (
    "import numpy as np; from rangekit.detect import _edge_kernels as k; "
    "k.call('all_finite', np.zeros(8))"
)

STFT_PEER = (
    "import sys; sys.path.insert(0, {bench!r}); import soundfile as sf; "
    "from _stft_peer import stft_band_energy; "
    "x, fs = sf.read({wav!r}, dtype='float32', always_2d=True); "
    "q = round(16000.0 / (fs / 128)); "
    "[stft_band_energy(x[:, c].astype('float64'), fs=fs, n_win=128, hop=32, mfft=128, "
    "bins=slice(q, q + 1)) for c in range(x.shape[1])]"
)


def console_script() -> str:
    """The ``rangekit`` console script next to this interpreter (else the one on PATH)."""
    cand = Path(sys.prefix) / "bin" / "rangekit"
    return str(cand) if cand.exists() else "rangekit"


def _children_cpu() -> float:
    """User + system CPU seconds of every reaped child so far (sums, unlike ru_maxrss)."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def run_timed(cmd: list[str]) -> tuple[float, float, str]:
    """``(wall s, child CPU s, stdout)`` of one run; raises if the command fails."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    c0 = _children_cpu()
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, env=env, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {r.returncode}: {r.stderr.strip()[-400:]}")
    return wall, _children_cpu() - c0, r.stdout


def imported(cmd: list[str]) -> tuple[set[str], list[tuple[float, str]]]:
    """Modules a ``python -X importtime`` run of ``cmd`` imports, and the slowest
    top-level ones (cumulative ms)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    r = subprocess.run([sys.executable, "-X", "importtime", *cmd], cwd=ROOT, env=env,
                       capture_output=True, text=True, check=True)  # fmt: skip
    mods, top = set(), []
    for ln in r.stderr.splitlines():
        m = re.match(r"import time:\s+\d+ \|\s+(\d+) \|( *)(\S+)", ln)
        if m:
            mods.add(m.group(3))
            if len(m.group(2)) == 1:
                top.append((int(m.group(1)) / 1e3, m.group(3)))
    return mods, sorted(top, reverse=True)[:6]


def in_process(wav: str, rounds: int) -> float:
    """Best CPU s of ``detect_files([wav])`` in this process, warm (numba loaded, file
    cached): the command's library work, decoding and both channels' detection, without
    the interpreter, the imports, numba's start-up and the JSON."""
    from rangekit.detect.files import detect_files

    detect_files([wav])
    cpu = []
    for _ in range(rounds):
        c0 = time.process_time()
        detect_files([wav])
        cpu.append(time.process_time() - c0)
    return min(cpu)


def left_text(c_det: float, c_lib: float, c_numba: float) -> str:
    """What is left of the whole-command goal: the command's CPU split into the library
    in process, numba's start-up and the rest, and the ceilings they leave."""
    rest = c_det - c_lib - c_numba
    no_numba = DURATION_S / max(c_det - c_numba, c_lib)  # the two are measured apart
    no_start = DURATION_S / c_lib
    need = "the detector itself" if no_start < GOAL_DETECT_X else "the start-up"
    return (
        f"  what is left: of the command's {c_det:.2f} s CPU, decoding + detection in "
        f"process {c_lib:.2f} s ({DURATION_S / c_lib:.0f}x), numba's start-up "
        f"{c_numba:.2f} s (import, registries, first cache load; a process of its own "
        f"minus 'import numpy'), the rest {rest:.2f} s (interpreter, imports, JSON). "
        f"Ceilings: without numba's start-up {no_numba:.0f}x, with no start-up at all "
        f"{no_start:.0f}x; the {GOAL_DETECT_X:.0f}x goal needs {need} faster"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 rounds, the scipy peer once")
    ap.add_argument("--repeats", type=int, default=3, help="rounds (default 3)")
    args = ap.parse_args()
    rounds = 2 if args.quick else max(1, args.repeats)
    rk = console_script()

    with tempfile.TemporaryDirectory() as tmp:
        wav = str(Path(tmp) / "detect10.wav")
        out_json = str(Path(tmp) / "out.json")
        x, n_ex = beepbeep_signal(DURATION_S)
        sf.write(wav, x.T, int(FS_AUDIO), subtype="PCM_16")
        del x
        cmds = {
            "detect": [rk, "detect", wav, "--format", "json", "-o", out_json],
            "decode": [sys.executable, "-c",
                       f"import soundfile as sf; sf.read({wav!r}, dtype='float32')"],
            "stft": [sys.executable, "-c", STFT_PEER.format(bench=str(ROOT / "benchmarks"),
                                                            wav=wav)],
            "range": [rk, "range", str(FIXTURE), "--self-distance", "0.1"],
            "help": [rk, "--help"],
            "pass": [sys.executable, "-c", "pass"],
            "numpy": [sys.executable, "-c", "import numpy"],
            "numba": [sys.executable, "-c", NUMBA_FLOOR],
        }  # fmt: skip
        # warm-up (numba cache, file cache) and the output check
        for name in ("detect", "range", "help", "decode"):
            run_timed(cmds[name])
        doc = json.loads(Path(out_json).read_text())
        per_ch = [sum(a["channel"] == c for a in doc["arrivals"]) for c in (0, 1)]
        ok = per_ch == [2 * n_ex, 2 * n_ex]
        print(f"check: rangekit detect found {per_ch} arrivals per channel "
              f"(expected {2 * n_ex} each) -> {'OK' if ok else 'FAIL'}")  # fmt: skip
        times: dict[str, list[tuple[float, float]]] = {k: [] for k in cmds}
        for r in range(rounds):
            order = list(cmds)
            order = order[r % len(order) :] + order[: r % len(order)]
            for name in order:
                if name == "stft" and args.quick and r > 0:
                    continue
                wall, cpu, _ = run_timed(cmds[name])
                times[name].append((wall, cpu))
        c_lib = in_process(wav, rounds)
        rk_mod = [sys.executable, "-m", "rangekit_cli.main"]
        mods_help, _ = imported([*rk_mod[1:], "--help"])
        mods_range, top_range = imported([*rk_mod[1:], *cmds["range"][1:]])

    def best(name: str) -> tuple[float, float]:
        return min(w for w, _ in times[name]), min(c for _, c in times[name])

    def med(name: str) -> float:
        return statistics.median(w for w, _ in times[name])

    print(f"\n  {'command':<44} {'best wall s':>11} {'median s':>9} {'best CPU s':>10}")
    labels = {
        "detect": "rangekit detect (10 min stereo, JSON)",
        "decode": "peer: decode only (soundfile, float32)",
        "stft": "peer: decode + ShortTimeFFT band, 2 ch",
        "range": "rangekit range fixture (1.26 s)",
        "help": "rangekit --help",
        "pass": "python -c pass",
        "numpy": 'python -c "import numpy"',
        "numba": "numba start-up: one cached kernel call",
    }
    for name, label in labels.items():
        b, c = best(name)
        print(f"  {label:<44} {b:11.3f} {med(name):9.3f} {c:10.3f}")

    t_det, c_det = best("detect")
    x_rt = DURATION_S / t_det
    vs_peer = best("stft")[0] / t_det
    x_cpu, vs_cpu = DURATION_S / c_det, best("stft")[1] / c_det
    verdict = goal_verdict(
        f"goal >= {GOAL_DETECT_X:.0f}x and >= {GOAL_DETECT_PEER:.0f}x the peer",
        x_cpu >= GOAL_DETECT_X and vs_cpu >= GOAL_DETECT_PEER,
        f"{x_cpu:.0f}x, {vs_cpu:.1f}x the peer",
        f"{x_rt:.0f}x, {vs_peer:.1f}x",
    )
    print(f"\n  rangekit detect: {x_rt:.0f}x realtime (wall; {DURATION_S / c_det:.0f}x on its CPU "
          f"time), {vs_peer:.1f}x the ShortTimeFFT peer, decoding alone "
          f"{DURATION_S / best('decode')[0]:.0f}x; {verdict}")  # fmt: skip
    print(left_text(c_det, c_lib, best("numba")[1] - best("numpy")[1]))
    t_range, c_range = med("range"), best("range")[1]
    range_verdict = goal_verdict(
        f"goal <= {GOAL_RANGE_S} s", c_range <= GOAL_RANGE_S,
        f"{c_range:.3f} s; python -c 'import numpy' {best('numpy')[1]:.3f} s",
        f"median {t_range:.3f} s",
    )  # fmt: skip
    help_numba = any(m.split(".")[0] == "numba" for m in mods_help)
    range_numba = any(m.split(".")[0] == "numba" for m in mods_range)
    heavy = sorted(m for m in mods_range if m.startswith(("scipy.signal", "scipy.stats")))
    print(f"  rangekit range fixture: median {t_range:.3f} s, best {best('range')[0]:.3f} s "
          f"(python -c 'import numpy' {med('numpy'):.3f} s); {range_verdict}")  # fmt: skip
    print(f"  imports: --help numba {'YES' if help_numba else 'no'}; range numba "
          f"{'YES' if range_numba else 'no'}, scipy.signal/stats {heavy or 'none'}")  # fmt: skip
    print("  slowest top-level imports of `range` (cumulative ms): "
          + ", ".join(f"{n} {t:.0f}" for t, n in top_range))  # fmt: skip

    row("detect_cli", "rangekit detect, 10 min stereo 44.1 kHz, whole command", x_rt,
        "x-realtime", peer="decode + scipy ShortTimeFFT band (2 ch)",
        peer_value=DURATION_S / best("stft")[0],
        note=f"best of {rounds} (wall {t_det:.2f} s, CPU {c_det:.2f} s); decoding alone "
        f"{DURATION_S / best('decode')[0]:.0f}x; {verdict}")  # fmt: skip
    row("detect_cli", "rangekit detect vs decoding alone", x_rt, "x-realtime",
        peer="decode only (soundfile float32)", peer_value=DURATION_S / best("decode")[0],
        note="the decode limit")  # fmt: skip
    row("detect_cli", "rangekit range fixture, median wall", t_range, "s",
        peer='python -c "import numpy"', peer_value=med("numpy"),
        note=f"{range_verdict}; numba "
        f"{'imported' if range_numba else 'not imported'}")  # fmt: skip
    row("detect_cli", "rangekit --help, median wall", med("help"), "s",
        peer="python -c pass", peer_value=med("pass"),
        note=f"goal numba not imported: {'NOT met' if help_numba else 'met'}")  # fmt: skip
    if not ok:
        print("\nFAIL: rangekit detect did not find the expected beeps", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
