"""Measurements behind the probe detector's choices (``docs/theory/probes.md``).

Run ``python tests/detect/measure_template.py
{weighting,dechorate,match,rooms,speed,transducer}``
from the repository root (``rooms 17``: the rooms corpus on another seed); every number
is seeded. Not a test module (no ``test_``
prefix): the tests in this folder assert bounds on the same measurements.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))


def weighting(n: int = 20) -> None:
    """Far-play detection and timing per weighting, LF shelf and white noise."""
    from test_template_weighting import _far_errors

    from rangekit.detect.matched import WEIGHTINGS
    from rangekit.signals.probe import linear_sweep

    for f0, f1, d in [(20.0, 20000.0, 1.0), (20.0, 20000.0, 0.1), (17000.0, 20000.0, 0.1)]:
        p = linear_sweep(f0, f1, d)
        for lf in (True, False):
            cells = []
            for w in WEIGHTINGS:
                e = _far_errors(p, w, lf=lf, n=n)
                ok = e < 2
                rms = np.sqrt(np.mean(e[ok] ** 2)) if ok.any() else np.nan
                cells.append(f"{w} {100 * ok.mean():3.0f} % {rms:.3f}")
            tag = "LF shelf" if lf else "white"
            print(f"{f0:.0f}-{f1:.0f} Hz {d} s, {tag}: " + " | ".join(cells), flush=True)


def dechorate() -> None:
    """First path against the annotation per probe and noise (dEchorate)."""
    import test_template_realdata as R

    from rangekit.signals.probe import linear_sweep
    from rangekit.types import INFO_FLAGS

    rirs = R.dechorate()
    for f0, f1 in [(200.0, 13000.0), (8000.0, 12000.0), (2000.0, 6000.0)]:
        p = linear_sweep(f0, f1, 0.2, fs=rirs[1])
        for kw in ({}, {"lf": True}, {"snr_db": 120.0}):
            rows = R._errors(rirs, p, check=False, **kw)
            e = np.array([r[0] for r in rows])
            s = np.array([r[1] for r in rows])
            doubt = np.array([bool(set(r[2]) - INFO_FLAGS) for r in rows])
            td = np.array([r[3] for r in rows])
            out = (np.abs(e) > 2 * s) & ~doubt
            print(
                f"{f0:.0f}-{f1:.0f} Hz {kw or '30 dB'}: <=1 {np.sum(np.abs(e) <= 1)}/12, "
                f"<=3 {np.sum(np.abs(e) <= 3)}/12, |e|<=2sigma {np.sum(np.abs(e) <= 2 * s)}/12, "
                f"max {np.abs(e).max():.1f}, sigma {s.min():.2f}-{s.max():.2f} (transducer "
                f"{td.min():.2f}-{td.max():.2f}), flagged {doubt.sum()}; unflagged beyond "
                f"2 sigma {out.sum()} {np.flatnonzero(out).tolist()}"
            )
            print("   errors", np.round(e, 1).tolist())
            print("   |e|/sigma", np.round(np.abs(e) / s, 2).tolist())
            print("   flagged channels", np.flatnonzero(doubt).tolist())
            if f0 == 200.0 and not kw:
                pair = e[:6] - e[6:]
                print("   pairs (ch i - ch i+6, same array):", np.round(pair, 2).tolist())
    own = R.own_peaks(rirs)
    print(
        f"response's own peak |h| vs the annotation: <=1 {np.sum(np.abs(own) <= 1)}/12,",
        np.round(own, 2).tolist(),
    )
    # The annotation's within-array differences against the calibrated geometry (the two
    # microphones of an array are a rigid pair, whatever the array's position error).
    import csv

    from probecorpus import DATA

    with open(DATA / "geometry.csv") as fh:
        geo = np.array([float(r["distance_m"]) for r in csv.DictReader(fh)]) / 345.844
    geo = geo * rirs[1]
    ann = rirs[2]
    print(
        "   annotation - geometry per channel:",
        np.round(ann - geo, 2).tolist(),
        "\n   within-array (i - (i+6)) annotation vs geometry:",
        np.round((ann[:6] - ann[6:]) - (geo[:6] - geo[6:]), 2).tolist(),
        "\n   within-array own peak vs geometry:",
        np.round((ann[:6] + own[:6] - ann[6:] - own[6:]) - (geo[:6] - geo[6:]), 2).tolist(),
    )


def _room_rirs(rng, fs: float, n: int):
    import pyroomacoustics as pra

    out = []
    while len(out) < n:
        size = np.array([rng.uniform(4, 12), rng.uniform(3, 9), rng.uniform(2.5, 4)])
        room = pra.ShoeBox(size, fs=int(fs), materials=pra.Material(rng.uniform(0.15, 0.35)),
                           max_order=6, air_absorption=True)  # fmt: skip
        src = np.array([rng.uniform(0.3, size[0] - 0.3), rng.uniform(0.3, size[1] - 0.3), 1.2])
        d, az = rng.uniform(0.5, 7.0), rng.uniform(0, 2 * np.pi)
        mic = src + np.array([d * np.cos(az), d * np.sin(az), rng.uniform(-0.2, 0.2)])
        if not (np.all(mic[:2] > 0.2) and np.all(mic[:2] < size[:2] - 0.2)):
            continue
        room.add_source(src)
        room.add_microphone(mic)
        room.compute_rir()
        out.append(np.asarray(room.rir[0][0]))
    return out


def match(n: int = 40, snrs: tuple[float, ...] = (10.0, 20.0, 40.0)) -> None:
    """poor_match / low_snr / no arrival on right and wrong templates (``match 25,30,35``:
    other SNRs, dB)."""
    from probecorpus import dechorate as dech
    from scipy.signal import fftconvolve

    from rangekit.detect.template import detect_template
    from rangekit.signals.beep import Beep, beep_waveform
    from rangekit.signals.probe import linear_sweep

    rng = np.random.default_rng(7)
    fs = 44100.0
    rirs = _room_rirs(rng, fs, n)
    hd, fsd, _ = dech()
    drirs = [hd[:, i] for i in range(12)]
    s1720 = linear_sweep(17000, 20000, 0.1)
    sfull = linear_sweep(20, 20000, 0.1)
    s1720l = linear_sweep(17000, 20000, 0.5)
    wide48 = linear_sweep(200, 13000, 0.2, fs=fsd)
    narrow48 = linear_sweep(8000, 12000, 0.2, fs=fsd)
    cases = {
        "right 17-20k 0.1 s, rooms": (s1720.samples, s1720, rirs, fs),
        "right 20-20k 0.1 s, rooms": (sfull.samples, sfull, rirs, fs),
        "right 17-20k 0.5 s, rooms": (s1720l.samples, s1720l, rirs, fs),
        "right 200-13k, dechorate": (wide48.samples, wide48, drirs, fsd),
        "right 8-12k, dechorate": (narrow48.samples, narrow48, drirs, fsd),
        "wrong: beep vs 17-20k": (beep_waveform(Beep()), s1720, rirs, fs),
        "wrong: 15-18k vs 17-20k": (linear_sweep(15000, 18000, 0.1).samples, s1720, rirs, fs),
        "wrong: 17-20k 0.5 s vs 0.1 s": (s1720l.samples, s1720, rirs, fs),
        "wrong: 17-20k vs 20-20k": (s1720.samples, sfull, rirs, fs),
    }
    for snr_db in snrs:
        for name, (played, tmpl, rr, f) in cases.items():
            pm = ls = lsa = none = 0
            for h in rr:
                y = fftconvolve(played, h)
                y = np.concatenate([np.zeros(int(0.05 * f)), y, np.zeros(int(0.05 * f))])
                s = np.sqrt(np.mean(played**2) * np.max(np.abs(h)) ** 2 / 10 ** (snr_db / 10))
                x = y + s * rng.standard_normal(len(y))
                a = detect_template(x, fs=f, probe=tmpl, expected=1)
                if len(a) == 0:
                    none += 1
                    continue
                names = a.flag_names(0)
                pm += "poor_match" in names
                ls += "low_snr" in names and "poor_match" not in names
                lsa += "low_snr" in names
            k = len(rr)
            print(
                f"SNR {snr_db:.0f} dB {name:30s} poor_match {100 * pm / k:3.0f} %, "
                f"low_snr only {100 * ls / k:3.0f} %, no arrival {100 * none / k:3.0f} % "
                f"(low_snr at all {100 * lsa / k:3.0f} %)",
                flush=True,
            )


def rooms(n_per_sweep: int = 25, seed: int = 16) -> None:
    """The two-way room acceptance corpus, larger (``rooms 17``: the held-out seed)."""
    import test_template_rooms as T

    print(f"seed {seed}")
    for n in (T.N_PER_SWEEP, n_per_sweep):
        T.N_PER_SWEEP = n
        sig: list = []
        err, flagged, failed = T.corpus(seed, sigmas=sig)
        k = len(T.SWEEPS) * n
        print(
            f"{k} exchanges: far found {k - failed}/{k}; |err| median {1e3 * np.median(err):.2f}"
            f" mm, p90 {1e3 * np.percentile(err, 90):.2f} mm, max {1e3 * err.max():.1f} mm; "
            f"> 10 cm {np.sum(err > 0.1)} (unflagged {np.sum((err > 0.1) & ~flagged)}); "
            f"> 2 cm {np.sum(err > 0.02)} (unflagged {np.sum((err > 0.02) & ~flagged)})",
            flush=True,
        )
        z = err / np.array(sig)
        per = len(err) // len(T.SWEEPS) if failed == 0 else None
        print(
            f"   two-way sigma {1e3 * np.min(sig):.2f}-{1e3 * np.max(sig):.2f} mm; |err|/sigma "
            f"median {np.median(z):.2f}, p90 {np.percentile(z, 90):.2f}, within 2 sigma "
            f"{np.mean(z <= 2):.0%} (unflagged beyond {np.sum((z > 2) & ~flagged)})",
            flush=True,
        )
        if per:
            for i, (f0, f1, d) in enumerate(T.SWEEPS):
                zi = z[i * per : (i + 1) * per]
                print(f"   {f0:.0f}-{f1:.0f} Hz {d} s: |err|/sigma median {np.median(zi):.2f}, "
                      f"within 2 sigma {np.mean(zi <= 2):.0%}")  # fmt: skip
            # Pooled as test_two_way_sigma_is_neither_too_confident_nor_too_cautious does.
            for name, lo in (("17-20 kHz", 0), ("20 Hz-20 kHz", 1)):
                zi = np.concatenate([z[i * per : (i + 1) * per] for i in (lo, lo + 2)])
                print(f"   {name} pooled: |err|/sigma median {np.median(zi):.3f}, max "
                      f"{zi.max():.2f}")  # fmt: skip


def transducer(n: int = 20) -> None:
    """Narrow and wide sweeps through random minimum-phase chains of +-6 dB ripple (2-5
    cosines of random period 1-20 kHz, 2nd-order band edges at 80-300 Hz and 15-20 kHz):
    onset error against the chain's pulse peak over sigma, and the transducer term."""
    import math

    import test_template_transducer as T

    from rangekit.signals.probe import linear_sweep

    rng = np.random.default_rng(0)
    f = np.fft.rfftfreq(T.N_FFT, 1.0 / T.FS)
    for f0, f1 in [(8000.0, 12000.0), (2000.0, 6000.0), (17000.0, 20000.0), (200.0, 13000.0)]:
        p = linear_sweep(f0, f1, 0.2, fs=T.FS)
        rows = []
        for _ in range(n):
            L = np.zeros_like(f)
            for _ in range(int(rng.integers(2, 6))):
                per, ph = rng.uniform(1000, 20000), rng.uniform(0, 2 * math.pi)
                L += np.cos(2 * math.pi * f / per + ph)
            L *= 6.0 / 20.0 * math.log(10.0) / np.max(np.abs(L[(f > 100) & (f < 16000)]))
            w = f / rng.uniform(80, 300)
            L += np.log(w**2 / np.sqrt(1 + w**4) + 1e-12)
            L += -0.5 * np.log(1 + (f / rng.uniform(15000, 20000)) ** 4)
            rows.append(T._onset_error(T._minimum_phase_chain(L), p, 6.0, rng))
        e, sig, td = (np.array(v) for v in zip(*rows, strict=True))
        z = np.abs(e) / sig
        print(
            f"{f0:.0f}-{f1:.0f} Hz: |e| max {np.abs(e).max():.2f} samples, |e|/sigma median "
            f"{np.median(z):.2f} max {z.max():.2f}, term {td.min():.2f}-{td.max():.2f}"
        )


def speed(repeats: int = 5) -> None:
    """detect_template on a 60 s 44.1 kHz recording holding 20 plays (best of repeats)."""
    from rangekit.detect.template import detect_template
    from rangekit.signals.probe import linear_sweep

    fs = 44100.0
    rng = np.random.default_rng(0)
    for f0, f1, d in [(17000.0, 20000.0, 0.1), (20.0, 20000.0, 1.0)]:
        p = linear_sweep(f0, f1, d)
        x = 0.01 * rng.standard_normal(int(60 * fs))
        for k in range(20):
            s = int((1 + 2.9 * k) * fs)
            x[s : s + len(p.samples)] += 0.1 * p.samples
        detect_template(x[:100000], fs=fs, probe=p)
        for w in ("ml", "none"):
            ts = []
            for _ in range(repeats):
                t = time.perf_counter()
                a = detect_template(x, fs=fs, probe=p, weighting=w)
                ts.append(time.perf_counter() - t)
            print(f"{f0:.0f}-{f1:.0f} Hz {d} s, {w}: best {1e3 * min(ts):.0f} ms ({len(a)} found)")


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else "weighting"
    if what == "match" and len(sys.argv) > 2:
        match(snrs=tuple(float(v) for v in sys.argv[2].split(",")))
    elif what == "rooms" and len(sys.argv) > 2:
        rooms(seed=int(sys.argv[2]))
    else:
        {"weighting": weighting, "dechorate": dechorate, "match": match, "rooms": rooms,
         "speed": speed, "transducer": transducer}[what]()  # fmt: skip
