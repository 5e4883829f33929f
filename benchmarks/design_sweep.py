"""Choose the beep's burst length and taper by measurement (docs/accuracy.md).

For each (burst_len, taper) it runs the seeded accuracy harness in three conditions
(free field at SNR 20 dB; shoebox room 6x5x3 m, absorption 0.3, first order, at 10 and
at 5 dB) and prints p90 |error|, max |error| and failures, plus the beep's spectral
splatter: the energy below 14 kHz (audible to most adults) relative to the total, in dB.

    python benchmarks/design_sweep.py [--trials 30] [--seed 1]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rangekit.errors import InvalidParameterError
from rangekit.experiments.beepbeep_accuracy import run_trials, summarize
from rangekit.signals import Beep, beep_waveform
from rangekit.sim import ShoeboxRoom


def splatter_db(beep: Beep, f_max_hz: float = 14000.0) -> float:
    x = beep_waveform(beep)[: beep.burst_len]
    spec = np.abs(np.fft.rfft(x, 1 << 16)) ** 2
    f = np.fft.rfftfreq(1 << 16, 1 / beep.fs)
    return float(10 * np.log10(spec[f < f_max_hz].sum() / spec.sum() + 1e-300))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--trials", type=int, default=30)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    room = ShoeboxRoom((6.0, 5.0, 3.0), absorption=0.3, max_order=1)
    conds = [("free 20 dB", None, 20.0), ("room 10 dB", room, 10.0), ("room 5 dB", room, 5.0)]
    head = f"{'burst':>6} {'taper':>5} {'splatter':>8}"
    for name, *_ in conds:
        head += f" | {name + ' p90/max/fail':>26}"
    print(head)
    for burst_len in (220, 441, 882, 1764):
        for taper in (11, 22, 44):
            try:
                beep = Beep(burst_len=burst_len, taper=taper)
            except InvalidParameterError:
                continue
            line = f"{burst_len:>6} {taper:>5} {splatter_db(beep):>7.1f}dB"
            for _, rm, snr in conds:
                s = summarize(
                    run_trials(n_trials=args.trials, snr_db=snr, room=rm, beep=beep, rng=args.seed)
                )
                line += (
                    f" | {100 * s['p90_m']:7.2f} {100 * s['max_m']:7.2f} cm {s['failures']:4d}   "
                )
            print(line, flush=True)


if __name__ == "__main__":
    main()
