"""rangekit.plot.jobs: the library call of each ``rangekit plot`` command draws what the
command draws (issue 19: a thin CLI), and ``-`` reads a table from standard input."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from rangekit.plot import jobs
from rangekit.ranging.config import Medium, OneWaySetup
from rangekit.signals import Beep

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "cli"))
from clihelp import assert_error, ok, run

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures_audio"
WAV = FIXTURES / "beepbeep_2p5m.wav"
SERIES = "t_s,a,b,distance_m,sigma_m\n0,0,1,2.001,0.002\n1,0,1,2.010,0.002\n2,0,1,1.999,0.002\n"


def _png(path: Path) -> bytes:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return data


def test_spectrogram_library_equals_cli(tmp_path):
    lib = jobs.spectrogram_figure(WAV, tmp_path / "lib.png", beep=Beep(), t0_s=0.0, t1_s=0.5)
    r = ok(run(["plot", "spectrogram", WAV, "--t0", "0", "--t1", "0.5", "-o", tmp_path / "c.png"]))
    # 2 onsets on channel 0 (measured), 1 of them before 0.5 s
    assert "2 onset(s) marked, 1 in the window" in r.stderr
    assert lib.n_onsets == 2 and len(lib.plot.onsets_s) == 1
    assert _png(tmp_path / "lib.png") == _png(tmp_path / "c.png")  # same pixels and metadata


def test_ranges_library_equals_cli_and_reads_stdin(tmp_path):
    csv = tmp_path / "s.csv"
    csv.write_text(SERIES)
    lib = jobs.ranges_figure(csv, tmp_path / "lib.png", truth=2.0)
    assert lib.n_ranges == 3 and lib.agreement.n == 3
    assert abs(lib.agreement.median_abs_error_m - 1e-3) < 1e-9  # errors 1, 10, 1 mm
    assert abs(lib.agreement.within_2sigma - 2 / 3) < 1e-12
    ok(run(["plot", "ranges", csv, "--truth", "2.0", "-o", tmp_path / "cli.png"]))
    assert _png(tmp_path / "lib.png") == _png(tmp_path / "cli.png")
    # Standard input: CSV sniffed; the same series (title names standard input as '-').
    r = ok(run(["plot", "ranges", "-", "--truth", "2.0", "-o", tmp_path / "in.png"], input=SERIES))
    assert "1 series, 3 ranges; against the truth: median |error| 1.0 mm" in r.stderr
    rows = [dict(zip(("t_s", "distance_m", "sigma_m"), v, strict=True))
            for v in ((0, 2.001, 0.002), (1, 2.010, 0.002), (2, 1.999, 0.002))]  # fmt: skip
    doc = json.dumps({"ranges": [{"a": 0, "b": 1, **x} for x in rows]})
    r = ok(run(["plot", "ranges", "-", "-o", tmp_path / "j.png"], input=doc))
    assert "1 series, 3 ranges" in r.stderr
    assert_error(
        run(["plot", "ranges", "-", "-o", tmp_path / "x.png"], input="{"), 4, "standard input"
    )


def test_cdf_and_track_from_stdin_equal_the_file(tmp_path):
    rows = "distance_m,true_distance_m,scheme\n2.01,2.0,a\n3.02,3.0,a\n1.0,,b\n"
    (tmp_path / "r.csv").write_text(rows)
    lib = jobs.cdf_figure(tmp_path / "r.csv", tmp_path / "lib.png", by="scheme")
    assert (lib.n_rows, lib.n_skipped) == (3, 1)
    np.testing.assert_allclose(lib.errors_m["a"], [0.01, 0.02], atol=1e-12)
    r = ok(run(["plot", "cdf", "-", "--by", "scheme", "-o", tmp_path / "c.png"], input=rows))
    assert "1 curve(s), 2 rows, 1 skipped" in r.stderr
    jl = "\n".join(
        json.dumps({"distance_m": d, "true_distance_m": t}) for d, t in ((2.01, 2.0), (3.0, 3.1))
    )
    r = ok(run(["plot", "cdf", "-", "-o", tmp_path / "jl.png"], input=jl + "\n"))
    assert "1 curve(s), 2 rows, 0 skipped" in r.stderr  # JSON lines sniffed
    track = "t_s,x_m,y_m,var_x_m2,var_y_m2\n0,0,0,0.01,0.01\n1,1,0,0.01,0.01\n2,2,1,0.02,0.01\n"
    (tmp_path / "t.csv").write_text(track)
    out = jobs.track_figure(tmp_path / "t.csv", tmp_path / "tl.png", every=1)
    np.testing.assert_array_equal(out.xy_m[""], [[0, 0], [1, 0], [2, 1]])
    r = ok(run(["plot", "track", "-", "--ellipses", "1", "-o", tmp_path / "tc.png"], input=track))
    assert "1 track(s), 3 points, 3 ellipses/circles" in r.stderr


def test_matched_library_equals_cli(tmp_path):
    ow = tmp_path / "ow.wav"
    ok(run(["synth", "oneway", "--tx", "1,0.5", "--tx", "-1,2", "--seed", "1", "-o", ow]))
    setup = OneWaySetup(period_s=0.2)
    trace = jobs.matched_figure(ow, tmp_path / "lib.png", setup=setup, medium=Medium(), window=1)
    r = ok(run(["plot", "matched", ow, "--scheme", "oneway", "--period", "0.2", "--window", "1",
                "-o", tmp_path / "cli.png"]))  # fmt: skip
    assert f"window 1: {trace.tof.distance_m:.4f} m" in r.stderr
    truth = json.loads(ow.with_suffix(".json").read_text())["windows"][1]["distances_m"][0]
    assert abs(trace.tof.distance_m - truth) < 0.01  # measured 1.5 mm off
    assert _png(tmp_path / "lib.png") == _png(tmp_path / "cli.png")
