"""The table "A direct path weaker than a reflection" of docs/accuracy.md.

``python tests/detect/measure_precursor.py``: one beep whose direct path (peak 0.05) is
followed ``lag`` samples later by a copy 10 times stronger, in white noise; 10 seeds per
row; where the first arrival's onset lies and whether it is flagged, with the tone
precursor test (``changepoint._precursor_flags``) and without it.
"""

from __future__ import annotations

import numpy as np

from rangekit.detect import changepoint as cp
from rangekit.signals import Beep
from rangekit.signals.beep import beep_continuous

FS = 44100.0
B = Beep()


def _x(lag: float, noise: float, seed: int) -> np.ndarray:
    t = np.arange(60000) / FS
    x = 0.05 / 0.9 * beep_continuous(t - 20000 / FS, beep=B)
    x = x + 0.5 / 0.9 * beep_continuous(t - (20000 + lag) / FS, beep=B)
    return x + noise * np.random.default_rng(seed).standard_normal(len(t))


def _row(lag: float, noise: float, seeds: int = 10) -> dict:
    out = {"direct": 0, "reflection flagged": 0, "reflection unflagged": 0, "other": 0}
    for seed in range(seeds):
        a = cp.detect_changepoint(_x(lag, noise, seed), fs=FS, beep=B)
        e = a.onset[0] - 20000.0
        if abs(e) < 3:
            out["direct"] += 1
        elif abs(e - lag) < 3:
            flagged = "ambiguous_first_path" in a.flag_names(0)
            out["reflection flagged" if flagged else "reflection unflagged"] += 1
        else:
            out["other"] += 1
    return out


def main() -> None:
    on = cp._precursor_flags
    for lag in (20, 40, 80, 150, 300):
        for noise in (0.01, 0.02, 0.05, 0.1):
            cp._precursor_flags = on
            now = _row(lag, noise)
            cp._precursor_flags = lambda arr, cond, **kw: arr
            off = _row(lag, noise)
            cp._precursor_flags = on
            print(f"lag {lag} noise {noise}: {now}; without the precursor test: {off}")


if __name__ == "__main__":
    main()
