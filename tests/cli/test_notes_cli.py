"""``design``, ``synth`` and ``plot`` print the library's note (rangekit.io.notes) of what
they wrote: the same options through the library call give the same stderr line."""

from __future__ import annotations

import math
from pathlib import Path

from clihelp import ok, run

from rangekit.floorplan import load_floorplan
from rangekit.io import notes
from rangekit.plot import jobs
from rangekit.ranging.config import EchoSetup, Medium
from rangekit.signals import Beep
from rangekit.signals.barker import CodedBurst
from rangekit.signals.probe import linear_sweep
from rangekit.sim.scenarios import synth_beepbeep, synth_echo, synth_oneway

ROOT = Path(__file__).resolve().parents[2]
PLAN = ROOT / "fixtures_audio" / "corridor_plan.json"
WAV = ROOT / "fixtures_audio" / "beepbeep_2p5m.wav"


def _note(r) -> str:
    """The one stderr line of a command run without --verbose."""
    assert r.stderr.count("\n") == 1, r.stderr
    return r.stderr[:-1]


def test_design_notes(tmp_path):
    out = tmp_path / "b.wav"
    r = ok(run(["design", "beep", "--fs", "48000", "--freq", "17000", "-o", out]))
    assert _note(r) == notes.beep_note(out, Beep(f_hz=17000.0), fs=48000.0)
    r = ok(run(["design", "barker", "--code", "5", "--cycles-per-bit", "2", "-o", out]))
    burst = CodedBurst((1.0, 1.0, 1.0, -1.0, 1.0), 40000.0, 2, 0.9, 192000.0)
    assert _note(r) == notes.burst_note(out, burst)
    r = ok(run(["design", "sweep", "--f0", "2000", "--f1", "6000", "--duration", "0.03",
                "-o", out]))  # fmt: skip
    probe = linear_sweep(2000.0, 6000.0, 0.03)
    assert _note(r) == notes.sweep_note(out, probe, f0_hz=2000.0, f1_hz=6000.0, duration_s=0.03)


def test_synth_notes(tmp_path):
    out = tmp_path / "x.wav"
    r = ok(run(["synth", "beepbeep", "--distance", "2.5", "--seed", "3", "-o", out]))
    assert _note(r) == notes.synthesis_note(synth_beepbeep(distance_m=2.5, seed=3), out)
    assert _note(r) == "wrote x.wav and x.json (0-1: 2.5000 m)"
    r = ok(run(["synth", "oneway", "--tx", "1,0.5", "--tx", "-1,2", "--tx", "0,1",
                "--seed", "1", "-o", out]))  # fmt: skip
    syn = synth_oneway(txs_m=[(1, 0.5), (-1, 2), (0, 1)], seed=1)
    assert _note(r) == notes.synthesis_note(syn, out)
    assert _note(r).endswith("(Tx ids 0-2 in firing order: range with --tx-order 0,1,2)")
    r = ok(run(["synth", "echo", "--map", PLAN, "--pose", "1,1,90", "--pose", "1,1.5,0",
                "--seed", "2", "-o", out]))  # fmt: skip
    plan = load_floorplan(PLAN)
    syn = synth_echo(plan, [(1, 1, math.pi / 2), (1, 1.5, 0.0)], seed=2, map_name=str(PLAN))
    assert _note(r) == notes.synthesis_note(syn, out)


def test_plot_notes(tmp_path):
    png = tmp_path / "f.png"
    r = ok(run(["plot", "spectrogram", WAV, "--t0", "0", "--t1", "0.5", "-o", png]))
    fig = jobs.spectrogram_figure(WAV, png, t0_s=0.0, t1_s=0.5)
    assert _note(r) == notes.spectrogram_note(png, fig)
    echo = tmp_path / "echo.wav"
    ok(run(["synth", "echo", "--map", PLAN, "--pose", "1,1,90", "--seed", "4", "-o", echo]))
    r = ok(run(["plot", "matched", echo, "--scheme", "echo", "--period", "0.07", "-o", png]))
    trace = jobs.matched_figure(echo, png, setup=EchoSetup(period_s=0.07), medium=Medium())
    assert _note(r) == notes.matched_note(png, trace, channel=0, window=0)
    series = tmp_path / "s.csv"
    series.write_text("t_s,a,b,distance_m,sigma_m\n0,0,1,2.001,0.002\n1,0,1,2.010,0.002\n")
    r = ok(run(["plot", "ranges", series, "--truth", "2", "-o", png]))
    assert _note(r) == notes.ranges_note(png, jobs.ranges_figure(series, png, truth=2.0))
    track = tmp_path / "t.csv"
    track.write_text("t_s,x_m,y_m,var_x_m2,var_y_m2\n0,0,0,0.01,0.01\n1,1,0,0.01,0.01\n")
    r = ok(run(["plot", "track", track, "--map", PLAN, "--ellipses", "1", "-o", png]))
    fig = jobs.track_figure(track, png, map_path=PLAN, every=1)
    assert _note(r) == notes.track_figure_note(png, fig)
    results = tmp_path / "r.csv"
    results.write_text("distance_m,true_distance_m,scheme\n2.01,2.0,a\n3.02,3.0,b\n1.0,,b\n")
    r = ok(run(["plot", "cdf", results, "--by", "scheme", "-o", png]))
    assert _note(r) == notes.cdf_note(png, jobs.cdf_figure(results, png, by="scheme"))
    assert _note(r) == f"wrote {png} (2 curve(s), 2 rows, 1 skipped)"


def _first(r) -> str:
    """The first stderr line of a --verbose run: what the run uses."""
    return r.stderr.splitlines()[0]


def test_range_verbose_line_is_the_librarys(tmp_path):
    from rangekit.ranging.config import TwoWaySetup

    args = ["range", WAV, "-v", "--no-setup", "--self-distance", "0.1,0.12", "--temperature", 25]
    r = ok(run(args))
    line = notes.range_detail("beepbeep", medium=Medium(temp_c=25.0), detector="changepoint",
                              setup=TwoWaySetup(self_distance_m=(0.1, 0.12)))  # fmt: skip
    assert r.stderr.splitlines()[1] == "rangekit: range: " + line
    r = ok(run(["range", WAV, "-v", "--no-setup", "--speed-of-sound", 340]))
    line = notes.range_detail("beepbeep", medium=Medium(speed_m_s=340.0), detector="changepoint")
    assert r.stderr.splitlines()[1] == "rangekit: range: " + line
    # the self-distance a sidecar gave, as the library holds it
    x = tmp_path / "x.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--seed", 1, "-o", x]))
    r = ok(run(["range", x, "-v"]))
    sd = TwoWaySetup(self_distance_m=(0.1, 0.1))
    line = notes.range_detail("beepbeep", medium=Medium(), detector="changepoint", setup=sd)
    assert _first(r) == "rangekit: range: " + line


def test_range_refused_before_it_runs_says_no_verbose_line():
    """The line says what a run uses: a run refused before it starts has none."""
    r = run(["range", WAV, "-v", "--no-setup", "--self-distance", "abc"])
    assert r.exit_code == 2
    assert r.stderr == (
        "rangekit: setup: not read (--no-setup)\n"
        "rangekit: error: Invalid value for --self-distance: 'abc' is not a comma-separated "
        "list of numbers (see 'rangekit range --help')\n"
    )


def test_calibrate_verbose_line_is_the_librarys(tmp_path):
    r = ok(run(["calibrate", "-v", "--distance", 2.5, WAV, WAV, WAV, "--temperature", 30,
                "-o", tmp_path / "c.json"]))  # fmt: skip
    line = notes.calibrate_detail(
        "beepbeep", n_recordings=3, medium=Medium(temp_c=30.0), detector="changepoint"
    )
    assert _first(r) == "rangekit: calibrate: " + line
    assert line.endswith("c = 349.10 m/s")


def test_locate_verbose_line_is_the_librarys(tmp_path):
    ok(run(["synth", "oneway", "--seed", 1, "-o", tmp_path / "ow.wav"]))
    beacons = tmp_path / "ow.beacons.json"
    tx = ["--tx", "0:2.11,2.05,2.20", "--tx", "2:2.42,2.37,2.51"]
    r = ok(run(["locate", "--beacons", beacons, *tx, "--sigma", 0.002, "-v"]))
    line = notes.locate_detail([0, 2], source="--tx", method="hybrid", sigma_m=0.002)
    assert _first(r) == "rangekit: locate: " + line
    d = tmp_path / "d.csv"
    d.write_text("tx,d1_m,d2_m,d3_m\n0,2.11,2.05,2.20\n1,2.42,2.37,2.51\n")
    r = ok(run(["locate", "--beacons", beacons, "--distances", d, "--method", "direct", "-v"]))
    assert _first(r) == "rangekit: locate: " + notes.locate_detail(
        [0, 1], source=str(d), method="direct"
    )


def test_batch_verbose_lines_are_the_librarys(tmp_path):
    from rangekit.batch import BatchOptions, find_sessions

    x = tmp_path / "x.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--seed", 1, "-o", x]))
    out = tmp_path / "r.jsonl"
    r = ok(run(["batch", x, WAV, "--detector", "xcorr", "--jobs", 1, "-v", "-o", out]))
    want = notes.batch_details(
        BatchOptions(beepbeep={"detector": "xcorr"}), find_sessions([str(x), str(WAV)]), out
    )
    assert want[0].endswith("2 of 2 sessions take their scheme or setup from a sidecar")
    assert r.stderr.splitlines()[1:3] == [f"batch: {line}" for line in want]


def test_detect_verbose_line_is_the_librarys():
    r = ok(run(["detect", WAV, "-v", "--detector", "xcorr", "--expected", 2]))
    assert _first(r) == "rangekit: detect: " + notes.detect_detail("xcorr", expected=2)
    assert _first(r) == "rangekit: detect: the beep by xcorr, at most 2 per channel"
