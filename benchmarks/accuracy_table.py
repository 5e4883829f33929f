"""The two-way ranging accuracy table of docs/accuracy.md, for both detectors.

Seeded trials of ``rangekit.experiments.beepbeep_accuracy``: distances uniform in
0.5-7 m, two devices (self-distance 0.1 m) at hand height at random places and headings,
recording starts 0-0.1 s, clocks uniform within +-50 ppm, white noise at the SNR of the
weakest direct beep (full band). "room" = shoebox 6 x 5 x 3 m, absorption 0.3, first-order
image sources. A failure is a detection error or |error| > 1 m.

    python benchmarks/accuracy_table.py [--trials 100] [--seed 2026] [--markdown]
        [--snr 30 20 10 5] [--detectors changepoint xcorr]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rangekit.experiments.beepbeep_accuracy import run_trials, summarize
from rangekit.sim import ShoeboxRoom


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--snr", type=float, nargs="+", default=[30.0, 20.0, 10.0, 5.0])
    ap.add_argument("--markdown", action="store_true", help="print a Markdown table")
    ap.add_argument("--detectors", nargs="+", default=["changepoint", "xcorr"])
    args = ap.parse_args()
    room = ShoeboxRoom((6.0, 5.0, 3.0), absorption=0.3, max_order=1)
    cols = "detector | condition | SNR dB | median cm | p90 cm | max cm | failures | within 2σ"
    if args.markdown:
        print("| " + cols + " |")
        print("|" + "---|" * (cols.count("|") + 1))
    else:
        print(cols)
    t0 = time.perf_counter()
    for detector in args.detectors:
        for cond, rm in (("free field", None), ("room 1st order", room)):
            for snr in args.snr:
                rows = run_trials(
                    n_trials=args.trials, snr_db=snr, room=rm, detector=detector, rng=args.seed
                )
                s = summarize(rows)
                cells = [
                    detector,
                    cond,
                    f"{snr:g}",
                    f"{100 * s['median_m']:.2f}",
                    f"{100 * s['p90_m']:.2f}",
                    f"{100 * s['max_m']:.2f}",
                    f"{s['failures']}/{s['n']}",
                    f"{100 * s['coverage_2sigma']:.0f} %",
                ]
                print(("| " + " | ".join(cells) + " |") if args.markdown else "  ".join(cells))
                sys.stdout.flush()
    print(f"\n{args.trials} trials per row, seed {args.seed}, {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
