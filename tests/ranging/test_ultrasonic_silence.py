"""Ultrasonic windows of digital silence hold no arrival (one-way and pulse-echo).

A recording that starts with whole periods of exact zeros (a logger armed before the
transmitters fire): the matched filter's output there is the FFT's rounding of the loud
samples elsewhere in its block, and each window's noise level (the median of its own
envelope) is rounding too, so until 2026-12-04 the largest rounding blip of a silent
window was an "arrival" at 17-22 dB SNR (flagged ``low_snr`` and ``poor_match``): 9 of
30 silent one-way ranges and 2-4 of the echo cycles were finite. An arrival whose
samples are exactly zero over the filter's reach is now none (``matched._silent_input``);
the windows with sound range as without the silence.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from rangekit.detect.matched import _silent_input
from rangekit.floorplan import FloorPlan
from rangekit.ranging.echo import range_echo
from rangekit.ranging.oneway import range_oneway
from rangekit.sim.ultrasonic import render_echo, render_oneway

FS = 192000.0
PLAN = Path(__file__).resolve().parents[2] / "fixtures_audio" / "corridor_plan.json"


def _silence_first(x: np.ndarray, n_periods: int, period_s: float) -> np.ndarray:
    pad = np.zeros((x.shape[0], int(round(n_periods * period_s * FS))))
    return np.concatenate([pad, x], axis=1)


@pytest.mark.parametrize("n_silent", [2, 10])  # whole rounds of the two Txs
def test_oneway_silent_windows_have_no_arrival(n_silent):
    period = 0.05
    sim = render_oneway(
        [[1.0, 0.3, 2.5], [3.0, 0.5, 2.5]], (0.5, 0.5, 0.2), order=[0, 1], n_windows=6,
        period_s=period, rng=3,
    )  # fmt: skip
    kw = {"fs": FS, "period_s": period, "tx_ids": [0, 1]}
    ref = range_oneway(sim.x, **kw)
    got = range_oneway(_silence_first(sim.x, n_silent, period), **kw)
    n_ch = sim.x.shape[0]
    silent, sound = got[: n_silent * n_ch], got[n_silent * n_ch :]
    assert len(silent) == n_silent * n_ch and len(sound) == len(ref)
    assert all(math.isnan(r.distance_m) for r in silent)
    for a, b in zip(sound, ref, strict=True):
        assert (a.window - n_silent, a.tx, a.channel) == (b.window, b.tx, b.channel)
        assert a.flags == b.flags
        # measured (other FFT block boundaries): distances to 5.2e-14 m, sigmas to 1.5e-13
        assert a.distance_m == pytest.approx(b.distance_m, abs=1.1e-13)
        assert a.sigma_m == pytest.approx(b.sigma_m, rel=3e-13)


def test_echo_silent_cycles_have_no_arrival():
    period = 0.07
    plan = FloorPlan.from_json(json.loads(PLAN.read_text()))
    poses = np.column_stack([np.linspace(0.5, 2.5, 12), np.full(12, 1.0), np.full(12, np.pi / 2)])
    sim = render_echo(plan, poses, fs=FS, rng=2)
    ref = range_echo(sim.x, fs=FS, period_s=period)
    got = range_echo(_silence_first(sim.x, 20, period), fs=FS, period_s=period)
    assert all(math.isnan(r.distance_m) for r in got[:20])
    sound = got[20:]
    assert len(sound) == len(ref) and sum(math.isfinite(r.distance_m) for r in ref) == 12
    for a, b in zip(sound, ref, strict=True):
        assert a.flags == b.flags
        if math.isfinite(b.distance_m):  # measured: equal to 5.2e-14 m
            assert a.distance_m == pytest.approx(b.distance_m, abs=1.1e-13)


def test_silent_input_reads_the_filters_reach_either_side():
    x = np.zeros(1000)
    x[600] = 1e-30  # any sample not exactly zero is sound
    assert _silent_input(x, 200, 100)
    assert not _silent_input(x, 550, 100)  # 600 within [450, 650)
    assert not _silent_input(x, 690, 100)
    assert _silent_input(x, 701, 100)
    assert _silent_input(x, 2000, 100)  # beyond the recording: nothing read
