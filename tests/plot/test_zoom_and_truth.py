"""Spectrogram time/frequency windows and range plots against the truth (issue 19 item 7)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from rangekit.detect import detect
from rangekit.errors import InvalidParameterError
from rangekit.plot import figures as F
from rangekit.plot import new_figure
from rangekit.plot.inputs import RangeSeries
from rangekit.sim import pair_devices, render_beepbeep

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "cli"))
from clihelp import assert_error, ok, run

FS = 44100.0


@pytest.fixture(scope="module")
def rec():
    sim = render_beepbeep(pair_devices(2.0), snr_db=20.0, rng=np.random.default_rng(5))
    return sim.recordings[0]


def _artists(ax, gid):
    return [a for a in (*ax.lines, *ax.images) if a.get_gid() == gid]


def test_spectrogram_window_shows_only_the_window(rec):
    arr = detect(rec, fs=FS, expected=2)
    t0, t1 = arr.onset_s[1] - 0.05, arr.onset_s[1] + 0.15  # around the second beep only
    _, ax = new_figure()
    out = F.draw_spectrogram(
        ax[0, 0], rec, fs=FS, onsets=arr.onset, t0_s=t0, t1_s=t1, fmin_hz=14e3, fmax_hz=18e3
    )
    assert np.all((out.t_s >= t0) & (out.t_s <= t1))  # times are the recording's
    np.testing.assert_allclose(out.onsets_s, [arr.onset_s[1]])
    lines = _artists(ax[0, 0], "onset")
    assert len(lines) == 1 and lines[0].get_xdata()[0] == pytest.approx(arr.onset_s[1])
    assert ax[0, 0].get_xlim() == pytest.approx((np.floor(t0 * FS) / FS, np.ceil(t1 * FS) / FS))
    assert ax[0, 0].get_ylim() == pytest.approx((14.0, 18.0))
    # The beep's 16 kHz bin is the brightest inside the window.
    assert abs(out.f_hz[np.argmax(out.power_db.max(axis=1))] - 16000) < 200


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"t0_s": 0.5, "t1_s": 0.4}, "t0 < t1"),
        ({"t0_s": 100.0}, "t0 < t1"),
        ({"t0_s": 0.1, "t1_s": 0.1 + 5 / FS}, "at least 16"),
        ({"fmin_hz": 9000.0, "fmax_hz": 8000.0}, "fmin < fmax"),
        ({"fmax_hz": 30000.0}, "fmax_hz"),
        ({"t0_s": float("nan")}, "t0_s"),
    ],
)
def test_spectrogram_window_errors(rec, tmp_path, kw, match):
    out = tmp_path / "x.png"
    with pytest.raises(InvalidParameterError, match=match):
        F.plot_spectrogram(rec, out, fs=FS, **kw)
    assert not out.exists()


def test_ranges_truth_lines():
    t = np.arange(5.0)
    series = [
        RangeSeries("0-1", t, 2.0 + 0.001 * t, np.full(5, 0.002)),
        RangeSeries("0-2", t, 3.0 + 0 * t, np.full(5, 0.002)),
    ]
    _, ax = new_figure()
    F.draw_ranges(ax[0, 0], series, truth={"0-1": 2.0})
    lines = _artists(ax[0, 0], "truth:0-1")
    assert len(lines) == 1 and np.all(np.asarray(lines[0].get_ydata()) == 2.0)
    assert not _artists(ax[0, 0], "truth:0-2")
    _, ax = new_figure()
    F.draw_ranges(ax[0, 0], series, truth=2.5)
    assert [_artists(ax[0, 0], f"truth:{k}")[0].get_ydata()[0] for k in ("0-1", "0-2")] == [
        2.5,
        2.5,
    ]


def test_cli_ranges_truth_summary_and_errors(tmp_path):
    csv = tmp_path / "s.csv"
    csv.write_text(
        "t_s,a,b,distance_m,sigma_m,flags\n"
        "0.0,0,1,2.001,0.002,\n1.0,0,1,2.010,0.002,\n2.0,0,1,1.999,0.002,\n3.0,0,1,,,detection\n"
    )
    side = tmp_path / "truth.json"
    side.write_text(json.dumps({"pairs": [{"a": 0, "b": 1, "distance_m": 2.0}]}))
    for truth in ("2.0", side):
        res = ok(run(["plot", "ranges", csv, "--truth", truth, "-o", tmp_path / "r.png"]))
        # errors 1, 10, 1 mm; 2 of 3 within 2 sigma = 4 mm
        assert "3 ranges; against the truth: median |error| 1.0 mm, 67 % within 2 sigma" in (
            res.stderr
        )
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"pairs": [{"a": 0, "b": 2, "distance_m": 2.0}]}))
    assert_error(run(["plot", "ranges", csv, "--truth", other, "-o", tmp_path / "x.png"]), 5,
                 "other.json", "0-1")  # fmt: skip
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    assert_error(run(["plot", "ranges", csv, "--truth", bad, "-o", tmp_path / "x.png"]), 2,
                 "bad.json", "not JSON")  # fmt: skip
    assert_error(run(["plot", "ranges", csv, "--truth", "-1", "-o", tmp_path / "x.png"]), 2,
                 "--truth")  # fmt: skip
    assert not (tmp_path / "x.png").exists()


def test_cli_spectrogram_template_and_window(tmp_path):
    sweep = tmp_path / "sweep.wav"
    ok(run(["design", "sweep", "--f0", 2000, "--f1", 6000, "--duration", 0.1, "-o", sweep]))
    wav = tmp_path / "sw.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--template", sweep, "--seed", 1, "-o", wav]))
    res = ok(run(["plot", "spectrogram", wav, "--template", sweep, "-o", tmp_path / "a.png"]))
    assert "2 onset(s) marked" in res.stderr
    res = ok(run(["plot", "spectrogram", wav, "--template", sweep, "--t1", 0.4,
                  "-o", tmp_path / "b.png"]))  # fmt: skip
    assert "2 onset(s) marked, 1 in the window" in res.stderr
    res = run(["plot", "spectrogram", wav, "--template", sweep, "--detector", "xcorr",
               "-o", tmp_path / "c.png"])  # fmt: skip
    assert_error(res, 2, "--detector", "--template")
    assert_error(run(["plot", "spectrogram", wav, "--t0", 5, "-o", tmp_path / "d.png"]), 2, "t0")
    assert not (tmp_path / "c.png").exists() and not (tmp_path / "d.png").exists()
