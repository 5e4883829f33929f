"""Accuracy harness for two-way ranging: rendered exchanges against their truth.

Each trial draws a distance uniformly in ``distances_m``, places two (or more) devices
with that pair distance at a random place and heading (inside the room when there is
one, at hand height 0.9-1.5 m), random recording starts (0-0.1 s) and clock errors
(+-``ppm`` ppm), renders the exchange at ``snr_db`` and ranges it with ``detector``.
A trial fails when detection fails (any DetectionError) or the error exceeds 1 m.

Oracle rows: every device's speaker-to-microphone distance is ``self_distance_m``; by
default the ranging is told that same value, i.e. the simulator's true device geometry,
and every row says so (``row["oracle"] == "true self-distance"``). Pass
``assumed_self_distance_m`` (what a user would read from a phone's specification) to
range with another value: those rows have ``row["oracle"] is None``.

Examples
--------
>>> rows = run_trials(n_trials=2, snr_db=20.0, rng=0)
>>> len(rows), sorted(rows[0])[:3]
(2, ['a', 'b', 'detector'])
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from rangekit.errors import DetectionError
from rangekit.io.audio import Channel
from rangekit.ranging.pipeline import range_channels
from rangekit.signals.beep import Beep
from rangekit.sim.recording import Device, render_beepbeep
from rangekit.sim.room import ShoeboxRoom

__all__ = ["place_devices", "run_trials", "summarize"]


class _Sized(Protocol):
    """A room as :func:`place_devices` needs it: its size in metres."""

    size_m: tuple[float, float, float]


FAIL_M = 1.0


def place_devices(
    distance_m: float,
    *,
    n_devices: int = 2,
    room: ShoeboxRoom | _Sized | None,
    rng: np.random.Generator,
    margin_m: float = 0.2,
    heights_m: tuple[float, float] = (0.8, 1.6),
    near_wall: bool = False,
    max_tries: int = 100000,
) -> list[np.ndarray]:
    """Device centres: the first two ``distance_m`` apart, the others random.

    Centres are at hand height (``heights_m``) and, in a room (anything with a
    ``size_m``), at least ``margin_m`` from the walls (free field: within a 20 m square);
    with ``near_wall`` the first device is exactly ``margin_m`` from a random side wall.
    Raises ValueError when the distance does not fit.
    """
    size = np.array(room.size_m) if room is not None else np.array([20.0, 20.0, 3.0])
    lo = np.array([margin_m, margin_m, heights_m[0]])
    hi = np.array([size[0] - margin_m, size[1] - margin_m, min(heights_m[1], size[2] - margin_m)])
    for _ in range(max_tries):
        a = rng.uniform(lo, hi)
        if near_wall:
            axis = int(rng.integers(0, 2))
            a[axis] = margin_m if rng.random() < 0.5 else size[axis] - margin_m
        dz = rng.uniform(lo[2], hi[2]) - a[2]
        if abs(dz) >= distance_m:
            continue
        az = rng.uniform(0, 2 * math.pi)
        horiz = math.sqrt(distance_m**2 - dz**2)
        b = a + np.array([horiz * math.cos(az), horiz * math.sin(az), dz])
        if np.all(b >= lo) and np.all(b <= hi):
            pts = [a, b]
            while len(pts) < n_devices:
                pts.append(rng.uniform(lo, hi))
            return pts
    raise ValueError(f"distance {distance_m} m does not fit in the room")


def run_trials(
    *,
    n_trials: int,
    snr_db: float,
    distances_m: tuple[float, float] = (0.5, 7.0),
    room: ShoeboxRoom | None = None,
    detector: str = "changepoint",
    beep: Beep | None = None,
    n_devices: int = 2,
    self_distance_m: float = 0.1,
    noise: str = "white",
    ppm: float = 50.0,
    assumed_self_distance_m: float | None = None,
    rng=None,
) -> list[dict]:
    """Run seeded trials; one row per pair per trial with the error in metres.

    ``assumed_self_distance_m`` is the self-distance the ranging is told (default: the
    true ``self_distance_m``, which makes every row an oracle row; module docstring).
    """
    oracle = "true self-distance" if assumed_self_distance_m is None else None
    told = self_distance_m if assumed_self_distance_m is None else assumed_self_distance_m
    rng = np.random.default_rng(rng)
    beep = Beep() if beep is None else beep
    rows = []
    for trial in range(n_trials):
        d = rng.uniform(*distances_m)
        pts = place_devices(d, n_devices=n_devices, room=room, rng=rng)
        devices = []
        for p in pts:
            az = rng.uniform(0, 2 * math.pi)
            v = 0.5 * self_distance_m * np.array([math.cos(az), math.sin(az), 0.0])
            devices.append(
                Device(
                    p - v,
                    p + v,
                    rec_start_s=float(rng.uniform(0, 0.1)),
                    clock_ppm=float(rng.uniform(-ppm, ppm)),
                )
            )
        sim = render_beepbeep(devices, beep=beep, snr_db=snr_db, noise=noise, room=room, rng=rng)
        truth = sim.distances_m
        chans = [
            Channel(x, fs, f"dev{i}")
            for i, (x, fs) in enumerate(zip(sim.recordings, sim.fs, strict=True))
        ]
        try:
            res = range_channels(chans, beep=beep, detector=detector, self_distance_m=told)
            est = {(r.a, r.b): (r.distance_m, r.sigma_m) for r in res.ranges}
        except DetectionError:
            est = {}
        for a in range(n_devices):
            for b in range(a + 1, n_devices):
                dist, sig = est.get((a, b), (math.nan, math.nan))
                err = dist - truth[a, b]
                rows.append(
                    {
                        "trial": trial,
                        "a": a,
                        "b": b,
                        "detector": detector,
                        "snr_db": snr_db,
                        "room": room is not None,
                        "true_m": float(truth[a, b]),
                        "distance_m": dist,
                        "sigma_m": sig,
                        "error_m": err,
                        "failed": bool(not np.isfinite(err) or abs(err) > FAIL_M),
                        "oracle": oracle,
                    }
                )
    return rows


def summarize(rows: Sequence[dict]) -> dict:
    """Median, 90th percentile and max of |error| over the non-failed rows; failures; coverage.

    ``coverage_2sigma`` is the fraction of non-failed rows with |error| <= 2 sigma
    (0.954 for an honest Gaussian uncertainty); ``median_z`` the median of |error| / sigma
    (0.674 for an honest Gaussian uncertainty: smaller means sigma is too cautious, larger
    too confident).
    """
    ok = [r for r in rows if not r["failed"]]
    e = np.abs([r["error_m"] for r in ok]) if ok else np.array([np.nan])
    s = np.array([r["sigma_m"] for r in ok]) if ok else np.array([np.nan])
    return {
        "n": len(rows),
        "failures": len(rows) - len(ok),
        "median_m": float(np.median(e)),
        "p90_m": float(np.percentile(e, 90)),
        "max_m": float(np.max(e)),
        "coverage_2sigma": float(np.mean(e <= 2 * s)) if ok else math.nan,
        "median_z": float(np.median(e / s)) if ok else math.nan,
    }
