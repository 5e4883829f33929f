"""Whole command as a user runs it: ``rangekit range --scheme oneway`` on 10 minutes.

Issue 20's one-way whole-command row: each command a subprocess timed by
``time.perf_counter`` around it (wall) and by the child's user + system CPU
(``RUSAGE_CHILDREN`` deltas), beside peers run in the same round-robin loop, so that load
on a shared machine hits all of them alike.

Recording: a 10-minute mono 16-bit 192 kHz WAV (115.2 M samples, 230 MB) of one-way
activations: ``render_oneway`` of ``bench_schemes``' four ceiling transmitters fired in
turn at 5 Hz, receiver 0 of the static robot, 20 dB SNR; 100 windows (20 s) rendered and
repeated 30 times (3000 windows). Commands:

* ``rangekit range --scheme oneway REC --period 0.2 --tx-order 0,1,2,3 --channels 1 --format csv -o
  OUT`` (the default: transducers unknown, every arrival timed by the transducer fit);
* the same with ``--transducer-q 4`` (the template of the true Q 4 transducers assumed:
  matched filter and first path only, no fit): what detection alone costs.

Peers: decoding alone (``soundfile.read(REC, dtype="float32")``) and decoding plus
``scipy.signal.correlate(x, h, mode="full", method="fft")`` with the same template
(real correlation only, no envelope or first-path search: what a scipy user computes
before any detection). Check (untimed, first run): every window within 1 cm of the
simulator's distance, in both commands. Goals (issue 20): >= 500x realtime and >= 15x the
correlate peer.

What is left of the goal: a process making one cached compiled call
(``bench_detect_cli.NUMBA_FLOOR``, less ``python -c "import numpy"``) measures numba's
start-up, and one ``python -X importtime`` run says whether ``--transducer-q 4`` imports
numba; the fits' cost over ``--transducer-q 4`` is split into that start-up and their own
work, with the ceilings left.

BLAS/OpenMP pools are one thread in every child.

Run: ``python benchmarks/bench_oneway_cli.py [--quick] [--repeats N]`` (``--quick``: 2
rounds instead of 3, the correlate peer in the first only).
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import tempfile
from pathlib import Path

import _one_core  # noqa: F401  (one thread, repo on sys.path; before numpy)
import numpy as np
import soundfile as sf
from _report import goal_verdict, row
from bench_detect_cli import NUMBA_FLOOR, console_script, imported
from bench_detect_cli import run_timed as _run_timed
from bench_schemes import FS_US, PERIOD_ONEWAY_S, TOL_US_M, oneway_signal

from rangekit.detect.matched import coded_template
from rangekit.signals.barker import CodedBurst
from rangekit.signals.transducer import Transducer

ROOT = Path(__file__).resolve().parents[1]
DURATION_S = 600.0
TILE_S = 20.0
GOAL_X = 500.0
GOAL_PEER = 15.0

CORR_PEER = (
    "import numpy as np, soundfile as sf, scipy.signal as ss; "
    "x, fs = sf.read({wav!r}, dtype='float32'); h = np.load({h!r}); "
    "ss.correlate(x, h, mode='full', method='fft')"
)


def run_timed(cmd: list[str]) -> tuple[float, float]:
    """``(wall s, child CPU s)`` of one run (``bench_detect_cli.run_timed``)."""
    return _run_timed(cmd)[:2]


def recording(path: str) -> list[float]:
    """Write the 10-minute mono WAV; return the true distance of each window."""
    sim = oneway_signal(TILE_S)
    tile = sim.x[0]
    n_tiles = int(round(DURATION_S / TILE_S))
    with sf.SoundFile(path, "w", samplerate=int(FS_US), channels=1, subtype="PCM_16") as f:
        for _ in range(n_tiles):
            f.write(tile)
    per = [w["distances_m"][0] for w in sim.truth["windows"]]
    return per * n_tiles


def check(out_csv: str, truth: list[float], label: str) -> bool:
    with open(out_csv, newline="") as f:
        rows = list(csv.DictReader(ln for ln in f if not ln.startswith("#")))
    got = {int(r["window"]): float(r["distance_m"] or "nan") for r in rows}
    err = np.array([abs(got.get(k, math.nan) - d) for k, d in enumerate(truth)])
    ok = len(rows) == len(truth) and bool(np.all(err <= TOL_US_M))
    print(f"check {label}: {int(np.sum(err <= TOL_US_M))} / {len(truth)} windows within "
          f"{TOL_US_M * 100:.0f} cm (max {np.nanmax(err) * 100:.2f} cm) -> "
          f"{'OK' if ok else 'FAIL'}")  # fmt: skip
    return ok


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 rounds, the correlate peer once")
    ap.add_argument("--repeats", type=int, default=3, help="rounds (default 3)")
    args = ap.parse_args()
    rounds = 2 if args.quick else max(1, args.repeats)
    rk = console_script()

    with tempfile.TemporaryDirectory(prefix="rangekit-bench-oneway-") as tmp:
        wav = str(Path(tmp) / "oneway10.wav")
        h_path = str(Path(tmp) / "h.npy")
        truth = recording(wav)
        np.save(h_path, coded_template(CodedBurst(), fs=FS_US, tx=Transducer(), rx=Transducer()))
        out = {k: str(Path(tmp) / f"{k}.csv") for k in ("fit", "fixed")}
        base = [rk, "range", "--scheme", "oneway", wav, "--period", str(PERIOD_ONEWAY_S),
                "--tx-order", "0,1,2,3", "--channels", "1", "--format", "csv"]  # fmt: skip
        cmds = {
            "fit": [*base, "-o", out["fit"]],
            "fixed": [*base, "--transducer-q", "4", "-o", out["fixed"]],
            "decode": [sys.executable, "-c",
                       f"import soundfile as sf; sf.read({wav!r}, dtype='float32')"],
            "corr": [sys.executable, "-c", CORR_PEER.format(wav=wav, h=h_path)],
            "numba": [sys.executable, "-c", NUMBA_FLOOR],
            "numpy": [sys.executable, "-c", "import numpy"],
        }  # fmt: skip
        for name in ("fit", "fixed", "decode"):  # warm-up (caches) and the output check
            run_timed(cmds[name])
        ok = check(out["fit"], truth, "oneway (fit)") & check(out["fixed"], truth, "oneway Q 4")
        times: dict[str, list[tuple[float, float]]] = {k: [] for k in cmds}
        for r in range(rounds):
            order = list(cmds)
            order = order[r % len(order) :] + order[: r % len(order)]
            for name in order:
                if name == "corr" and args.quick and r > 0:
                    continue
                times[name].append(run_timed(cmds[name]))
        rk_mod = [sys.executable, "-m", "rangekit_cli.main"]
        numba_fixed = any(
            m.split(".")[0] == "numba" for m in imported([*rk_mod[1:], *cmds["fixed"][1:]])[0]
        )

    def best(name: str) -> tuple[float, float]:
        return min(w for w, _ in times[name]), min(c for _, c in times[name])

    labels = {
        "fit": "rangekit range --scheme oneway (fit)",
        "fixed": "rangekit range --scheme oneway --transducer-q 4",
        "decode": "peer: decode only (soundfile, float32)",
        "corr": "peer: decode + scipy.signal.correlate fft",
        "numba": "numba start-up: one cached kernel call",
        "numpy": 'python -c "import numpy"',
    }
    print(f"\n  {'command':<50} {'best wall s':>11} {'x-realtime':>10} {'best CPU s':>10}")
    for name, label in labels.items():
        w, c = best(name)
        print(f"  {label:<50} {w:11.3f} {DURATION_S / w:9.0f}x {c:10.3f}")
    t_corr, c_corr = best("corr")
    for name, what in (("fit", "transducers fitted"), ("fixed", "--transducer-q 4, no fit")):
        t, c = best(name)
        x_rt, vs = DURATION_S / t, t_corr / t
        verdict = goal_verdict(
            f"goal >= {GOAL_X:.0f}x and >= {GOAL_PEER:.0f}x the peer",
            DURATION_S / c >= GOAL_X and c_corr / c >= GOAL_PEER,
            f"{DURATION_S / c:.0f}x, {c_corr / c:.2f}x the peer",
            f"{x_rt:.0f}x, {vs:.2f}x",
        )
        print(f"  {what}: {x_rt:.0f}x realtime ({DURATION_S / c:.0f}x on its CPU time), "
              f"{vs:.2f}x the correlate peer; {verdict}")  # fmt: skip
        row("oneway_cli", f"rangekit range --scheme oneway, 10 min mono 192 kHz ({what})",
            x_rt, "x-realtime", peer="decode + scipy.signal.correlate fft",
            peer_value=DURATION_S / t_corr,
            note=f"3000 windows, best of {rounds} (wall {t:.2f} s, CPU {c:.2f} s); decoding "
            f"alone {DURATION_S / best('decode')[0]:.0f}x; {verdict}")  # fmt: skip
    c_fit, c_fixed = best("fit")[1], best("fixed")[1]
    c_numba = best("numba")[1] - best("numpy")[1]
    fits = c_fit - c_fixed - (0.0 if numba_fixed else c_numba)
    print(f"  what is left: the fits cost {c_fit - c_fixed:.2f} s CPU over --transducer-q 4, "
          f"which {'imports numba too' if numba_fixed else 'imports no numba'}; numba's "
          f"start-up {c_numba:.2f} s (a process making one cached compiled call, less "
          f"'import numpy'){'' if numba_fixed else ' is part of that'}, the fits' own work "
          f"{fits:.2f} s. Ceilings: without numba's start-up "
          f"{DURATION_S / (c_fit - c_numba):.0f}x; with fits free as well, the detection "
          f"{DURATION_S / c_fixed:.0f}x")  # fmt: skip
    row("oneway_cli", "rangekit range --scheme oneway (fit) vs decoding alone",
        DURATION_S / best("fit")[0], "x-realtime", peer="decode only (soundfile float32)",
        peer_value=DURATION_S / best("decode")[0], note="the decode limit")  # fmt: skip
    if not ok:
        print("\nFAIL: a one-way range disagrees with the truth", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
