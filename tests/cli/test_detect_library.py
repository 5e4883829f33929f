"""``rangekit detect`` prints what ``rangekit.detect.files.detect_files`` returns: the same
options give the same text through the library call and the CLI (compared exactly), and
a channel without an arrival gives the library's DetectionError line and exit 6."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from clihelp import assert_error, ok, run

from rangekit.detect.files import detect_files
from rangekit.errors import DetectionError
from rangekit.io.audio import write_audio
from rangekit.signals import Beep
from rangekit.signals.probe import read_probe

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures_audio"
STEREO = str(FIXTURES / "beepbeep_2p5m.wav")
ROOM = str(FIXTURES / "beepbeep_room_4p2m.wav")


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """A probe file and a two-device recording of it."""
    d = tmp_path_factory.mktemp("detect_library")
    probe = d / "sweep.wav"
    ok(run(["design", "sweep", "--f0", 17000, "--f1", 20000, "--duration", 0.1, "-o", probe]))
    rec = d / "rec.wav"
    ok(run(["synth", "beepbeep", "--seed", 2, "--distance", 2, "--template", probe, "-o", rec]))
    return str(probe), str(rec)


@pytest.mark.parametrize("fmt", ["table", "csv", "json"])
def test_beep_output_is_the_library_runs(fmt):
    res = ok(run(["detect", "--format", fmt, STEREO, ROOM]))
    assert res.stdout == detect_files([STEREO, ROOM], signal=Beep()).format(fmt)
    assert res.stderr == ""


def test_options_reach_the_library_call_unchanged():
    res = ok(run(["detect", "--detector", "xcorr", "--expected", 1, "--format", "json", STEREO]))
    lib = detect_files([STEREO], signal=Beep(), method="xcorr", expected=1)
    assert res.stdout == lib.format("json")
    assert '"expected": 1' in res.stdout


def test_template_output_is_the_library_runs(sweep):
    probe, rec = sweep
    args = ["--expected", 2, "--min-separation", 0.1, "--weighting", "phat"]
    res = ok(run(["detect", "--template", probe, *args, "--format", "csv", rec]))
    lib = detect_files([rec], signal=read_probe(probe), expected=2, min_separation_s=0.1,
                       weighting="phat")  # fmt: skip
    assert res.stdout == lib.format("csv")
    assert len(lib.rows) == 4  # two arrivals in each of two channels


def test_empty_channel_is_the_library_error(tmp_path):
    silent = tmp_path / "silent.wav"
    write_audio(silent, 1e-4 * np.random.default_rng(0).standard_normal((44100, 2)), fs=44100.0)
    lib = detect_files([str(silent), STEREO])
    res = run(["detect", "--format", "json", str(silent), STEREO])
    line = assert_error(res, 6, f"{silent}#0", f"{silent}#1")
    assert res.stdout == lib.format("json")  # the other file's rows still printed
    with pytest.raises(DetectionError) as e:
        lib.finish()
    assert line == f"rangekit: error: {e.value}"
    # --debug keeps the one line and exit 6 (no traceback): the command's contract
    assert_error(run(["detect", "--debug", str(silent)]), 6, f"{silent}#0")
