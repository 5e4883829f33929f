"""rangekit.io.notes: each note of ``design``, ``synth`` and ``plot`` from the library's
results, exactly as the commands printed it before the notes moved out of ``cli/``
(strings taken from real runs of the old commands)."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.floorplan import load_floorplan
from rangekit.io import notes
from rangekit.plot.figures import TrackPlot
from rangekit.plot.inputs import BatchErrors
from rangekit.plot.jobs import RangesFigure, SpectrogramFigure, ranges_figure
from rangekit.signals import Beep
from rangekit.signals.barker import CodedBurst
from rangekit.signals.probe import linear_sweep
from rangekit.sim.scenarios import synth_beepbeep, synth_echo, synth_oneway

PLAN = Path(__file__).resolve().parents[2] / "fixtures_audio" / "corridor_plan.json"


def test_beep_note():
    assert notes.beep_note("beep.wav", Beep(), fs=44100.0) == (
        "wrote beep.wav: 4 x 16000 Hz bursts of 10.0 ms, 113.4 ms apart, 0.350 s at 44100 Hz"
    )
    # the file's rate, not the beep's, is the one named
    assert notes.beep_note("b48.wav", Beep(f_hz=17500.0), fs=48000.0).endswith(
        "4 x 17500 Hz bursts of 10.0 ms, 113.4 ms apart, 0.350 s at 48000 Hz"
    )


def test_burst_note():
    assert notes.burst_note("barker.wav", CodedBurst()) == (
        "wrote barker.wav: code +++--+- on 40000 Hz, 3 cycles per chip, 525.0 us at 192000 Hz"
    )
    ping = CodedBurst((1.0,), 40000.0, 8, 0.9, 192000.0)
    assert notes.burst_note("ping.wav", ping) == (
        "wrote ping.wav: code + on 40000 Hz, 8 cycles per chip, 200.0 us at 192000 Hz"
    )


def test_sweep_note_default_and_given_fade():
    p = linear_sweep(17000.0, 20000.0, 0.1)
    assert notes.sweep_note("sweep.wav", p, f0_hz=17000.0, f1_hz=20000.0, duration_s=0.1) == (
        "wrote sweep.wav: linear sweep 17000-20000 Hz, 0.1 s (4410 samples at 44100 Hz), "
        "fades 5.0 ms, 99.9 % of the energy in 16.98-20.02 kHz"
    )
    p = linear_sweep(2000.0, 6000.0, 0.1, fade_s=0.003)
    assert notes.sweep_note(
        "s2.wav", p, f0_hz=2000.0, f1_hz=6000.0, duration_s=0.1, fade_s=0.003
    ) == (
        "wrote s2.wav: linear sweep 2000-6000 Hz, 0.1 s (4410 samples at 44100 Hz), "
        "fades 3.0 ms, 99.9 % of the energy in 1.92-6.08 kHz"
    )
    # a short sweep's default fade is a tenth of it (linear_sweep's rule, not a copy)
    p = linear_sweep(2000.0, 6000.0, 0.02)
    assert "fades 2.0 ms" in notes.sweep_note(
        "s3.wav", p, f0_hz=2000.0, f1_hz=6000.0, duration_s=0.02
    )


def test_synthesis_note_beepbeep():
    syn = synth_beepbeep(distance_m=2.0, snr_db=None, seed=1)
    assert notes.synthesis_note(syn, "out/x.wav") == "wrote x.wav and x.json (0-1: 2.0000 m)"
    three = synth_beepbeep(positions_m=[(1, 1, 1.2), (4, 2, 1.2), (2, 4, 1.2)], snr_db=None, seed=2)
    assert notes.synthesis_note(three, "three.wav") == (
        "wrote three.wav and three.json (0-1: 3.1639 m, 0-2: 3.1639 m, 1-2: 2.8302 m)"
    )
    mono = synth_beepbeep(distance_m=3.3, snr_db=None, mono=True, seed=1)
    assert notes.synthesis_note(mono, "s.wav") == (
        "wrote s_dev0.wav, s_dev1.wav and s.json (0-1: 3.3000 m)"
    )


def test_synthesis_note_oneway_and_echo():
    ow = synth_oneway(txs_m=[(1, 0.5), (-1, 2)], pose=(0.2, 0.1, math.radians(30)), seed=1)
    assert notes.synthesis_note(ow, "ow.wav") == (
        "wrote ow.wav (2 windows x 3 receivers), ow.json and ow.beacons.json (Tx ids 0-1 in "
        "firing order: range with --tx-order 0,1)"
    )
    plan = load_floorplan(PLAN)
    echo = synth_echo(plan, [(1.0, 1.0, math.pi / 2), (1.0, 1.5, math.pi / 2)], seed=1)
    want = ", ".join(f"{w['distance_m']:.3f} m" for w in echo.truth["windows"])
    assert notes.synthesis_note(echo, "e.wav") == f"wrote e.wav and e.json (model: {want})"
    # a cycle out of the model's range is '-'
    gone = SimpleNamespace(truth={"scheme": "echo", "windows": [{"distance_m": None}]})
    gone.sidecar = lambda out: gone.truth
    assert notes.synthesis_note(gone, "g.wav") == "wrote g.wav and g.json (model: -)"
    bad = SimpleNamespace(sidecar=lambda out: {"scheme": "sonar"})
    with pytest.raises(InvalidParameterError, match="sonar"):
        notes.synthesis_note(bad, "b.wav")


def test_plot_notes():
    fig = SpectrogramFigure("x.wav#0", "changepoint", 2, SimpleNamespace(onsets_s=[0.2]))
    assert (
        notes.spectrogram_note("z.png", fig) == "wrote z.png (2 onset(s) marked, 1 in the window)"
    )
    fig = SpectrogramFigure("x.wav#0", "changepoint", 2, SimpleNamespace(onsets_s=[0.2, 0.3]))
    assert notes.spectrogram_note("x.png", fig) == "wrote x.png (2 onset(s) marked)"
    trace = SimpleNamespace(tof=SimpleNamespace(distance_m=3.02664))
    assert notes.matched_note("mf.svg", trace, channel=0, window=1) == (
        "wrote mf.svg (channel 0, window 1: 3.0266 m)"
    )
    trace = SimpleNamespace(tof=SimpleNamespace(distance_m=math.nan))
    assert notes.matched_note("mf.svg", trace, channel=2, window=0) == (
        "wrote mf.svg (channel 2, window 0: nothing detected)"
    )
    plot = TrackPlot({"0": np.zeros((52, 2))}, {"0": np.arange(6)}, 4)
    assert notes.track_figure_note("t.png", plot) == (
        "wrote t.png (1 track(s), 52 points, 6 ellipses/circles)"
    )
    batch = BatchErrors(None, {"": np.zeros(4)}, 5, 1)
    assert notes.cdf_note("cdf.png", batch) == "wrote cdf.png (1 curve(s), 4 rows, 1 skipped)"
    assert notes.ranges_note("r.png", RangesFigure([1], 5, None)) == (
        "wrote r.png (1 series, 5 ranges)"
    )


def test_ranges_note_against_the_truth(tmp_path):
    csv = tmp_path / "s.csv"
    csv.write_text("t_s,a,b,distance_m,sigma_m\n0,0,1,2.001,0.002\n1,0,1,2.010,0.002\n"
                   "2,0,1,1.999,0.002\n")  # fmt: skip
    fig = ranges_figure(csv, tmp_path / "r.png", truth=2.0)
    # errors 1, 10, 1 mm; two of three within 2 sigma = 4 mm
    assert notes.ranges_note("r.png", fig) == (
        "wrote r.png (1 series, 3 ranges; against the truth: median |error| 1.0 mm, "
        "67 % within 2 sigma)"
    )


# ------------------------------------------------- --verbose: what a run uses (range, ...)
# Strings from real runs of the commands before the lines moved out of cli/.


def test_range_detail():
    from rangekit.physics import Medium
    from rangekit.ranging.config import TwoWaySetup

    sd = TwoWaySetup(self_distance_m=(0.1, 0.1))
    assert notes.range_detail("beepbeep", medium=Medium(), detector="changepoint", setup=sd) == (
        "scheme beepbeep, detector changepoint, temperature 20 C, self-distance 0.1,0.1"
    )
    # no setup: the library's default self-distance (TwoWaySetup(): 0 m); a given speed
    assert notes.range_detail(
        "beepbeep", medium=Medium(speed_m_s=340.0), detector="changepoint"
    ) == ("scheme beepbeep, detector changepoint, speed of sound 340 m/s, self-distance 0")
    cal = notes.range_detail(
        "beepbeep", medium=Medium(temp_c=25.5), detector="changepoint", template="sweep.wav",
        calibration="cal.json", setup=TwoWaySetup(),
    )  # fmt: skip
    assert cal == (
        "scheme beepbeep, template 'sweep.wav', temperature 25.5 C, self-distance 0, "
        "calibration 'cal.json'"
    )
    # the ultrasonic schemes: the coded burst, no self-distance even if a setup is given
    for scheme in ("oneway", "echo"):
        assert notes.range_detail(scheme, medium=Medium(), setup=sd) == (
            f"scheme {scheme}, coded burst (--code), temperature 20 C"
        )
    assert notes.range_detail("oneway", medium=Medium(speed_m_s=343.5), template="c.wav") == (
        "scheme oneway, template 'c.wav', speed of sound 343.5 m/s"
    )
    # values by the text rule: no float repr
    sd = TwoWaySetup(self_distance_m=(0.1 + 0.2, 0.12))
    assert notes.range_detail("beepbeep", medium=Medium(), detector="x", setup=sd).endswith(
        "self-distance 0.3,0.12"
    )


def test_calibrate_detail():
    from rangekit.physics import Medium

    one = notes.calibrate_detail("beepbeep", n_recordings=4, medium=Medium(), template="s.wav")
    assert one == "beepbeep, template 's.wav', 4 recordings, c = 343.29 m/s"
    assert notes.calibrate_detail(
        "beepbeep", n_recordings=8, medium=Medium(speed_m_s=340.0), detector="changepoint"
    ) == ("beepbeep, detector changepoint, 8 recordings, c = 340.00 m/s")
    assert notes.calibrate_detail(
        "beepbeep", n_recordings=4, medium=Medium(temp_c=30.0), template="s.wav"
    ).endswith("c = 349.10 m/s")
    # one-way: the coded burst, not the beep's detector (it printed "detector changepoint")
    assert notes.calibrate_detail(
        "oneway", n_recordings=1, medium=Medium(), detector="changepoint"
    ) == ("oneway, coded burst (--code), 1 recording, c = 343.29 m/s")
    assert notes.calibrate_detail(
        "oneway", n_recordings=3, medium=Medium(), detector="changepoint", template="c.wav"
    ).startswith("oneway, template 'c.wav', 3 recordings")


def test_locate_detail():
    assert notes.locate_detail([0, 2], source="--tx", method="hybrid", sigma_m=0.002) == (
        "2 transmitters (0, 2) from --tx, method hybrid, distance sigma 0.002 m"
    )
    assert notes.locate_detail([0, 1, 2], source="d.csv", method="hybrid") == (
        "3 transmitters (0, 1, 2) from d.csv, method hybrid, distance sigma none"
    )
    per = notes.locate_detail(
        [0, 1], source="standard input", method="direct", sigma_m=np.full((2, 3), 0.01)
    )
    assert (
        per == "2 transmitters (0, 1) from standard input, method direct, distance sigma per range"
    )
    assert notes.locate_detail([3], source="x", method="hybrid", sigma_m=np.float64(0.01)).endswith(
        "distance sigma 0.01 m"
    )


def test_batch_details():
    from rangekit.batch import BatchOptions

    sessions = [SimpleNamespace(scheme=None, params={}), SimpleNamespace(scheme="x", params={})]
    sessions.append(SimpleNamespace(scheme=None, params={"temp_c": 20.0}))
    assert notes.batch_details(BatchOptions(), sessions, "res.jsonl") == [
        "scheme beepbeep, detector changepoint; 2 of 3 sessions take their scheme or setup "
        "from a sidecar",
        "options recorded in res.jsonl.meta.json",
    ]  # changepoint: range_channels' default, the options leave it None
    opts = BatchOptions(beepbeep={"detector": "xcorr"}, pair_by_name=True)
    assert notes.batch_details(opts, [], "r.csv") == [
        "scheme beepbeep, detector xcorr; 0 of 0 sessions take their scheme or setup from a "
        "sidecar",
        "sessions paired by name across the device folders",
        "options recorded in r.csv.meta.json",
    ]
    probe = linear_sweep(2000.0, 6000.0, 0.01)
    opts = BatchOptions(scheme="oneway", beepbeep={"probe": probe})
    assert notes.batch_details(opts, [], "r.csv")[0].startswith(
        "scheme oneway, probe (--template);"
    )


def test_detect_detail():
    assert notes.detect_detail("changepoint") == "the beep by changepoint"
    assert notes.detect_detail("xcorr", expected=2) == "the beep by xcorr, at most 2 per channel"
    assert notes.detect_detail("template", template="sweep.wav", expected=3) == (
        "template 'sweep.wav' by template, at most 3 per channel"
    )
