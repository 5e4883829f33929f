"""Benchmark the three ranging schemes end to end on long recordings, in x-realtime.

x-realtime is seconds of recording (all channels together) per second of wall time. Each
scheme's signal is seeded, its ranges are checked against the simulator's truth (the
script exits 1 if a check fails, so it cannot time a broken pipeline), and a scipy peer
runs on the same data in the same process. Best of ``--repeats`` (default 3) after a
warm-up (numba compile or cache load, FFT plans). Durations: 10 min of recording for
BeepBeep and echo, 200 s for one-way (3 channels: the same 10 min of 192 kHz samples as
echo); ``--quick``: a tenth of that.

* **beepbeep** (two devices 3 m apart, Peng et al. 2007): ``render_beepbeep(
  pair_devices(3.0, self_distance_m=0.1), snr_db=20, rng=0)``; each device's 1.26 s
  recording is placed every 3 +- 0.5 s (seeded jitter) in white noise at its own noise
  level, both devices at the same places: one two-channel 44.1 kHz 16-bit WAV (in the
  system temp directory, 106 MB at 10 min). Timed:
  ``list(range_series_beepbeep([wav], self_distance_m=0.1))``, i.e. what
  ``rangekit range --series`` runs without the CLI: block-wise reading, change-point
  detection on both channels, exchange grouping, two-way ranging. Peer: scipy
  ``ShortTimeFFT`` band energy at the bin nearest 16 kHz (``mfft=128``, as in
  ``bench_detect.py``) of both channels, in memory. Check: every exchange ranged, within
  2 cm of 3 m.
* **oneway** (RF-synchronised beacons, Kim & Kim 2013): ``render_oneway`` of four ceiling
  transmitters (corners of a 3 x 3 m square, 2.5 m high) fired in turn at 5 Hz, a static
  robot at (1.2, 1.0) m heading 0.3 rad with 3 receivers, 192 kHz, 20 dB SNR: 1000
  windows (``--quick``: 100). Timed: ``range_oneway(x, fs=192000, period_s=0.2, tx_ids=[0, 1, 2,
  3])`` on the whole (3, n) array (matched filter, first-path search per window). Peer:
  ``scipy.signal.correlate(x[c], h, mode="full", method="fft")`` of each channel with the
  same template ``h`` (real correlation only: no envelope, no first-path search). Check:
  every window and receiver within 1 cm of the true distance.
* **echo** (SRF02-style pulse-echo): ``render_echo`` of one sensor walked along the
  corridor of ``fixtures_audio/corridor_plan.json`` (x from 0.5 to 9.5 m, y = 1 m, facing
  the wall at y = 2 m +- 0.3 rad), one 70 ms cycle per pose, 192 kHz, 20 dB SNR: 857
  cycles per minute. Timed: ``range_echo(x, fs=192000, period_s=0.07)``. Peer:
  ``scipy.signal.correlate`` with the ping through the transducer twice. Check: every
  cycle with a model range is ranged within 1 cm of it.

Memory: the peak RSS is ~1 GB with ``--quick``; the full run needs several GB (the
scipy peer's whole-channel FFT of 10 min of 192 kHz audio alone is ~5 GB,
``bench_matched.py``).
BLAS/OpenMP pools are limited to one thread (one core).

Run: ``python benchmarks/bench_schemes.py [--quick] [--repeats N]``
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import _one_core  # noqa: F401  (one thread, repo on sys.path; before numpy)
import numpy as np
import scipy.signal as ss
import soundfile as sf
from _report import best_of, goal_verdict, row
from _stft_peer import stft_band_energy

from rangekit.detect.matched import coded_template
from rangekit.floorplan import FloorPlan
from rangekit.ranging.series import range_series_beepbeep
from rangekit.ranging.ultrasonic import range_echo, range_oneway
from rangekit.signals.barker import CodedBurst, srf02_ping
from rangekit.signals.transducer import Transducer
from rangekit.sim import pair_devices, render_beepbeep
from rangekit.sim.ultrasonic import render_echo, render_oneway

ROOT = Path(__file__).resolve().parents[1]
FS_AUDIO = 44100.0
FS_US = 192000.0
TX_M = np.array([[0.0, 0.0, 2.5], [3.0, 0.0, 2.5], [0.0, 3.0, 2.5], [3.0, 3.0, 2.5]])
POSE = (1.2, 1.0, 0.3)
PERIOD_ONEWAY_S = 0.2
PERIOD_ECHO_S = 0.07
DIST_M = 3.0
#: Issue 20's goals (x realtime, judged on CPU time): range_oneway 3 receivers, range_echo.
GOALS_X = {"oneway": 400.0, "echo": 400.0}
#: Tolerances of the checks, m.
TOL_BEEPBEEP_M = 0.02
TOL_US_M = 0.01


class Seconds(float):
    """A best wall time (the float) with the best CPU time of the same calls (``.cpu``)."""

    cpu: float = math.nan


def best_time(fn, repeats: int) -> tuple[Seconds, object]:
    """Best wall time of ``repeats`` calls of ``fn()`` (its ``.cpu``: the best CPU time,
    ``_report.best_of``), and the last result."""
    wall, cpu, res = best_of(fn, repeats)
    t = Seconds(wall)
    t.cpu = cpu
    return t, res


# --------------------------------------------------------------------------- signals
def beepbeep_signal(duration_s: float) -> tuple[np.ndarray, int]:
    """(x of shape (2, n), number of exchanges): both devices' recordings every 3 +- 0.5 s."""
    sim = render_beepbeep(pair_devices(DIST_M, self_distance_m=0.1), snr_db=20, rng=0)
    tiles = sim.recordings
    rng = np.random.default_rng(2026)
    n = int(duration_s * FS_AUDIO)
    sigma = [
        float(np.std(t[: int(np.min(o)) - 200])) for t, o in zip(tiles, sim.onsets, strict=True)
    ]
    x = np.stack([s * rng.standard_normal(n) for s in sigma])
    size = len(tiles[0])
    period, jitter = int(3.0 * FS_AUDIO), int(0.5 * FS_AUDIO)
    starts = np.arange(jitter, n - size - jitter, period)
    starts = starts + rng.integers(-jitter, jitter + 1, size=len(starts))
    for s in starts:
        for c, tile in enumerate(tiles):
            x[c, s : s + size] = tile
    return x, len(starts)


def oneway_signal(duration_s: float):
    n_win = int(round(duration_s / PERIOD_ONEWAY_S))
    return render_oneway(TX_M, POSE, fs=FS_US, n_windows=n_win, period_s=PERIOD_ONEWAY_S, rng=1)


def echo_signal(duration_s: float):
    plan = FloorPlan.from_json(json.loads((ROOT / "fixtures_audio/corridor_plan.json").read_text()))
    n = int(round(duration_s / PERIOD_ECHO_S))
    rng = np.random.default_rng(7)
    poses = np.column_stack(
        [np.linspace(0.5, 9.5, n), np.full(n, 1.0), np.pi / 2 + rng.uniform(-0.3, 0.3, n)]
    )
    return render_echo(plan, poses, fs=FS_US, rng=2)


# --------------------------------------------------------------------------- checks
def check(name: str, ok: bool, text: str) -> bool:
    print(f"  check {name:<9}: {text} -> {'OK' if ok else 'FAIL'}")
    return ok


def check_beepbeep(exchanges, n_expected: int) -> bool:
    d = np.array([e.ranges[0].distance_m for e in exchanges])
    err = np.abs(d - DIST_M)
    ok = len(d) == n_expected and bool(np.all(err <= TOL_BEEPBEEP_M))
    worst = float(np.nanmax(err)) if len(d) else math.nan
    return check(
        "beepbeep",
        ok,
        f"{len(d)} / {n_expected} exchanges ranged, max |d - {DIST_M} m| = {worst * 100:.2f} cm",
    )


def check_oneway(tofs, truth: dict) -> bool:
    want = {
        (w["window"], c): dist for w in truth["windows"] for c, dist in enumerate(w["distances_m"])
    }
    got = {(r.window, r.channel): r.distance_m for r in tofs}
    err = np.array([abs(got.get(k, math.nan) - v) for k, v in want.items()])
    ok = bool(np.all(err <= TOL_US_M))  # NaN (missed) fails
    return check(
        "oneway",
        ok,
        f"{np.sum(err <= TOL_US_M)} / {len(want)} (window, receiver) within "
        f"{TOL_US_M * 100:.0f} cm, max error {np.nanmax(err) * 100:.2f} cm",
    )


def check_echo(tofs, truth: dict) -> bool:
    got = {r.window: r.distance_m for r in tofs}
    want = {w["window"]: w["distance_m"] for w in truth["windows"] if w["distance_m"] is not None}
    err = np.array([abs(got.get(k, math.nan) - v) for k, v in want.items()])
    extra = sum(
        1 for w in truth["windows"] if w["distance_m"] is None and math.isfinite(got[w["window"]])
    )
    ok = len(want) > 0 and bool(np.all(err <= TOL_US_M))
    return check(
        "echo",
        ok,
        f"{np.sum(err <= TOL_US_M)} / {len(want)} cycles with a model range within "
        f"{TOL_US_M * 100:.0f} cm, max error {np.nanmax(err) * 100:.2f} cm; {extra} ranges "
        f"where the specular model has none (door edges)",
    )


# --------------------------------------------------------------------------- schemes
#: One line of the table: scheme, what rangekit ran, its seconds, peer, peer seconds, note.
Line = tuple[str, str, float, str, float, str]


def bench_beepbeep(duration_s: float, repeats: int) -> tuple[Line, bool]:
    """A two-channel WAV ranged block by block, against ShortTimeFFT of both channels."""
    t0 = time.perf_counter()
    x, n_ex = beepbeep_signal(duration_s)
    q = round(16000.0 / (FS_AUDIO / 128))

    def stft_peer(xs: np.ndarray) -> None:
        for ch in xs:
            stft_band_energy(ch, fs=FS_AUDIO, n_win=128, hop=32, mfft=128, bins=slice(q, q + 1))

    with tempfile.TemporaryDirectory(prefix="rangekit-bench-schemes-") as tmp:
        wav = str(Path(tmp) / "beepbeep.wav")
        sf.write(wav, x.T, int(FS_AUDIO), subtype="PCM_16")
        print(
            f"beepbeep: {duration_s:.0f} s, 2 channels, {n_ex} exchanges; made in "
            f"{time.perf_counter() - t0:.1f} s"
        )
        warm = str(Path(tmp) / "warm.wav")
        sf.write(warm, x[:, : int(30 * FS_AUDIO)].T, int(FS_AUDIO), subtype="PCM_16")
        list(range_series_beepbeep([warm], self_distance_m=0.1))  # numba, imports
        stft_peer(x[:, : int(5 * FS_AUDIO)])
        t_rk, ex = best_time(
            lambda: list(range_series_beepbeep([wav], self_distance_m=0.1)), repeats
        )
    t_peer, _ = best_time(lambda: stft_peer(x), repeats)
    ok = check_beepbeep(ex, n_ex)
    line = (
        "beepbeep",
        "range_series_beepbeep, 2-channel WAV",
        t_rk,
        "scipy ShortTimeFFT + bin 46 (mfft=128), 2 channels",
        t_peer,
        f"{n_ex} exchanges, 16-bit WAV read block-wise",
    )
    return line, ok


def corr_peer(x: np.ndarray, h: np.ndarray) -> None:
    """``scipy.signal.correlate`` (FFT) of every channel with ``h``, output discarded."""
    for ch in x:
        ss.correlate(ch, h, mode="full", method="fft")


def bench_oneway(duration_s: float, repeats: int) -> tuple[Line, bool]:
    """``range_oneway`` on 3 receivers in memory, against scipy correlation."""
    t0 = time.perf_counter()
    sim = oneway_signal(duration_s)
    n_win = len(sim.truth["windows"])
    print(
        f"oneway: {duration_s:.0f} s, {sim.x.shape[0]} receivers, {n_win} windows; "
        f"rendered in {time.perf_counter() - t0:.1f} s"
    )
    h = coded_template(CodedBurst(), fs=FS_US, tx=Transducer(), rx=Transducer())

    def run(x: np.ndarray):
        return range_oneway(x, fs=FS_US, period_s=PERIOD_ONEWAY_S, tx_ids=[0, 1, 2, 3])

    w = sim.x[:, : int(2 * FS_US)]
    run(w)
    corr_peer(w, h)
    t_rk, tofs = best_time(lambda: run(sim.x), repeats)
    t_peer, _ = best_time(lambda: corr_peer(sim.x, h), repeats)
    ok = check_oneway(tofs, sim.truth)
    line = (
        "oneway",
        "range_oneway, 3 receivers, 4 Txs at 5 Hz",
        t_rk,
        "scipy.signal.correlate fft, 3 channels",
        t_peer,
        f"{n_win} windows at 192 kHz; peer: real only, no first-path search",
    )
    return line, ok


def bench_echo(duration_s: float, repeats: int) -> tuple[Line, bool]:
    """``range_echo`` on one sensor in memory, against scipy correlation."""
    t0 = time.perf_counter()
    sim = echo_signal(duration_s)
    n_cyc = len(sim.truth["windows"])
    print(
        f"echo: {duration_s:.0f} s, 1 sensor, {n_cyc} cycles; rendered in "
        f"{time.perf_counter() - t0:.1f} s"
    )
    h = coded_template(srf02_ping(), fs=FS_US, tx=Transducer(), rx=Transducer())

    def run(x: np.ndarray):
        return range_echo(x, fs=FS_US, period_s=PERIOD_ECHO_S)

    w = sim.x[:, : int(2 * FS_US)]
    run(w)
    corr_peer(w, h)
    t_rk, tofs = best_time(lambda: run(sim.x), repeats)
    t_peer, _ = best_time(lambda: corr_peer(sim.x, h), repeats)
    ok = check_echo(tofs, sim.truth)
    line = (
        "echo",
        "range_echo, 1 sensor, 70 ms cycles",
        t_rk,
        "scipy.signal.correlate fft, 1 channel",
        t_peer,
        f"{n_cyc} cycles at 192 kHz; peer: real only, no first-path search",
    )
    return line, ok


# --------------------------------------------------------------------------- main
def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a tenth of the recording lengths")
    ap.add_argument("--repeats", type=int, default=3, help="best of N (default 3)")
    args = ap.parse_args()
    duration_s = 60.0 if args.quick else 600.0
    repeats = max(1, args.repeats)

    table, ok = [], True
    for bench, dur in (
        (bench_beepbeep, duration_s),
        (bench_oneway, duration_s / 3),
        (bench_echo, duration_s),
    ):
        line, good = bench(dur, repeats)
        table.append((*line, dur))
        ok &= good

    print(
        f"\n  best of {repeats}; x-realtime = seconds of recording (all channels together) "
        "per second of wall time"
    )
    print(
        f"  {'scheme':<9} {'audio s':>7} {'rangekit s':>10} {'x-realtime':>11} {'CPU s':>7} "
        f"{'x CPU':>7} {'peer s':>8} {'peer x-rt':>10} {'t_peer / t':>11} {'CPU ratio':>9}  peer"
    )
    for scheme, _, t, peer, tp, _, dur in table:
        print(
            f"  {scheme:<9} {dur:7.0f} {t:10.3f} {dur / t:10.0f}x {t.cpu:7.3f} "
            f"{dur / t.cpu:6.0f}x {tp:8.3f} {dur / tp:9.0f}x {tp / t:10.2f}x "
            f"{tp.cpu / t.cpu:8.2f}x  {peer}"
        )
    # Headline rows for benchmarks/run.py (ratio = t_peer / t: > 1 = faster than the peer).
    for scheme, name, t, peer, tp, note, dur in table:
        x_cpu = dur / t.cpu
        goal = GOALS_X.get(scheme)
        judged = (
            goal_verdict(f"goal >= {goal:.0f}x", x_cpu >= goal,
                         f"{x_cpu:.0f}x, {tp.cpu / t.cpu:.2f}x the peer", f"{dur / t:.0f}x")
            if goal else f"{x_cpu:.0f}x CPU, {tp.cpu / t.cpu:.2f}x the peer's CPU"
        )  # fmt: skip
        row(
            "schemes",
            f"{scheme}: {name}",
            dur / t,
            "x-realtime",
            peer=peer,
            peer_value=dur / tp,
            note=f"{dur:.0f} s of recording, best of {repeats}; {note}; {judged}",
        )
    if not ok:
        print("\nFAIL: a scheme's ranges disagree with the truth", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
