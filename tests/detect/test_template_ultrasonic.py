"""A 25 kHz tone fired every 0.5 s through ringing piezo transducers: one arrival each.

**A stand-in** for the real 64 kHz ultrasonic logs of ``shared/REFERENCES.md`` (a 4 ms
25 kHz tone fired every 0.5 s, about 10 "arrivals" listed per emission): those logs are
not in the repository, so this log is simulated. Each emission reaches the receiver by a
direct path (3-4 m) and six echoes 5-40 ms later at 0.2-0.9 of its amplitude, plus a
diffuse tail (exponentially decaying noise, 60 dB in 80 ms), all through a transmitter
and a receiver modelled as second-order resonators at 25 kHz of Q 15 or 20
(:class:`rangekit.signals.transducer.Transducer`; rangekit's default is Q 4), white
noise 20 dB below the direct path. The template is the bare 4 ms tone (the transducers
are unknown), so every onset carries the transducers' delay, the same for all
emissions.

Measured (seed 3, 6 emissions): with ``min_separation_s`` = 0.45 s (the firing period
less the spread of the distances) or ``expected=6`` (its default separation is then 0.1
s) exactly one arrival per emission, onsets 20.6-21.6
samples (Q 15) / 27.2-28.7 (Q 20) after the direct path's arrival; flagged
``poor_match`` (the bare tone does not look like what the ringing transducers deliver;
not at Q 4). With only the default separation (the tone's 4 ms) 29 (Q 15) / 26 (Q 20)
arrivals for the 6 emissions: an echo 5-40 ms after its direct path, standing alone out
of the noise, cannot be told from a new emission without the firing period (a limit,
``docs/theory/probes.md``).
"""

from __future__ import annotations

import numpy as np
import pytest
from probecorpus import place

from rangekit.detect.template import detect_template
from rangekit.signals.probe import Probe
from rangekit.signals.transducer import Transducer

FS = 64000.0
PERIOD_S = 0.5
N_EMIT = 6


def _tone() -> Probe:
    n = int(0.004 * FS)
    t = np.arange(n) / FS
    w = np.ones(n)
    k = int(0.0002 * FS)
    w[:k] = w[-k:][::-1] = 0.5 - 0.5 * np.cos(np.pi * np.arange(k) / k)
    return Probe(np.sin(2 * np.pi * 25000.0 * t) * w, FS, "tone25k")


def _log(q: float, seed: int = 3):
    rng = np.random.default_rng(seed)
    tone = _tone()
    n = int(PERIOD_S * N_EMIT * FS)
    starts, amps, truth = [], [], []
    for k in range(N_EMIT):
        t0 = k * PERIOD_S * FS + rng.uniform(0, 1)
        d = rng.uniform(3.0, 4.0) / 343.0 * FS
        truth.append(t0 + d)
        starts += [t0 + d, *list(t0 + d + np.sort(rng.uniform(0.005, 0.04, 6)) * FS)]
        amps += [1.0, *list(rng.uniform(0.2, 0.9, 6))]
    x = place(tone.samples, starts, amps, n)
    # Diffuse tail after each direct path: decaying noise through the same band.
    for tt in truth:
        m = int(0.08 * FS)
        tail = rng.standard_normal(m) * 0.05 * 10 ** (-3 * np.arange(m) / m)
        i = int(tt) + int(0.002 * FS)
        x[i : i + m] += np.convolve(tail, tone.samples[:64] / 8, mode="same")
    td = Transducer(25000.0, q=q)
    x = td.apply(td.apply(x, fs=FS), fs=FS)
    x += 0.1 / np.sqrt(2) * 10 ** (-20 / 20) * rng.standard_normal(n)
    return x, np.array(truth), tone


@pytest.mark.parametrize(("q", "lag_lo", "lag_hi"), [(15.0, 18.0, 24.0), (20.0, 24.0, 32.0)])
def test_one_arrival_per_emission(q, lag_lo, lag_hi):
    x, truth, tone = _log(q)
    sep = 0.9 * PERIOD_S
    for kw in (
        {"min_separation_s": sep},
        {"expected": N_EMIT},
        {"min_separation_s": sep, "expected": N_EMIT},
    ):
        a = detect_template(x, fs=FS, probe=tone, **kw)
        assert len(a) == N_EMIT
        lag = a.onset - truth
        # The transducers' delay (unknown to the template) is the same for every emission.
        assert np.all((lag > lag_lo) & (lag < lag_hi)), lag
        assert np.std(lag) < 0.8, lag  # measured 0.33 (Q 15), 0.44 (Q 20) samples
        assert all("poor_match" in a.flag_names(i) for i in range(len(a)))
