"""``rangekit.detect.files.detect_files``: the detection job of ``rangekit detect`` as one
library call: every channel of every file through the front end, the empty channels
named, the metadata of the results file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rangekit.detect import detect
from rangekit.detect.files import DetectRun, detect_files
from rangekit.errors import DetectionError, InvalidParameterError
from rangekit.io.audio import read_audio, write_audio
from rangekit.io.results import ARRIVAL_FIELDS, arrivals_rows
from rangekit.signals import Beep, linear_sweep

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures_audio"
STEREO = FIXTURES / "beepbeep_2p5m.wav"
ROOM = FIXTURES / "beepbeep_room_4p2m.wav"


def _by_hand(files, **kw):
    rows = []
    for f in files:
        x, fs = read_audio(f)
        for ch in range(x.shape[1]):
            rows += arrivals_rows(detect(x[:, ch], fs=fs, **kw), file=str(f), channel=ch)
    return rows


def test_rows_are_the_front_ends_file_by_file_channel_by_channel():
    files = [STEREO, ROOM]
    run = detect_files(files)
    assert isinstance(run, DetectRun)
    assert list(run.rows) == _by_hand(files, signal=Beep())
    assert [(r["file"], r["channel"]) for r in run.rows][:1] == [(str(STEREO), 0)]
    assert {r["file"] for r in run.rows} == {str(STEREO), str(ROOM)}
    assert set(run.rows[0]) == set(ARRIVAL_FIELDS)
    assert run.empty == () and run.meta == {"detector": "changepoint"}
    run.finish()  # nothing empty: no error


def test_expected_and_method_reach_the_detector():
    run = detect_files([STEREO], method="xcorr", expected=1)
    assert list(run.rows) == _by_hand([STEREO], signal=Beep(), method="xcorr", expected=1)
    assert [r["channel"] for r in run.rows] == [0, 1]  # one per channel (the docs show 2)
    assert run.meta == {"detector": "xcorr", "expected": 1}


def test_probe_template_options_and_meta(tmp_path):
    probe = linear_sweep(17000.0, 20000.0, 0.1)
    fs = 44100.0
    x = 1e-3 * np.random.default_rng(2).standard_normal((int(fs), 1))
    s = probe.samples_at(fs)
    for start in (5000, 20000):
        x[start : start + len(s), 0] += 0.3 * s
    path = tmp_path / "two.wav"
    write_audio(path, x, fs=fs)
    run = detect_files([path], signal=probe, min_separation_s=0.1, weighting="phat")
    hand = _by_hand([path], signal=probe, min_separation_s=0.1, weighting="phat")
    assert list(run.rows) == hand
    assert [round(r["onset_sample"]) for r in run.rows] == [5000, 20000]
    assert run.meta == {"detector": "template", "template": probe.name}
    # the options are passed on, not dropped: another weighting, other sigmas
    other = detect_files([path], signal=probe, min_separation_s=0.1)
    assert [r["sigma_samples"] for r in other.rows] != [r["sigma_samples"] for r in run.rows]


def test_empty_channels_named_and_raised_only_by_finish(tmp_path):
    fs = 44100.0
    x = 1e-3 * np.random.default_rng(1).standard_normal((int(fs), 2))
    b = Beep().samples_at(fs)
    x[8000 : 8000 + len(b), 1] += 0.5 * b
    path = tmp_path / "half.wav"
    write_audio(path, x, fs=fs)
    run = detect_files([path, STEREO])
    assert run.empty == (f"{path}#0",)
    assert [r["channel"] for r in run.rows if r["file"] == str(path)] == [1]
    with pytest.raises(DetectionError, match=r"^no beep found in .*half\.wav#0$") as e:
        run.finish()
    assert e.value.exit_code == 6
    probe = linear_sweep(2000.0, 5000.0, 0.05)
    run = detect_files([path], signal=probe)
    with pytest.raises(DetectionError, match=f"no arrival of '{probe.name}' found in"):
        run.finish()


def test_format_is_format_arrivals_and_bad_method_refused():
    run = detect_files([STEREO])
    csv = run.format("csv").splitlines()
    assert csv[0] == ",".join(ARRIVAL_FIELDS) and len(csv) == 1 + len(run.rows)
    with pytest.raises(InvalidParameterError, match="does not apply"):
        detect_files([STEREO], method="template")
