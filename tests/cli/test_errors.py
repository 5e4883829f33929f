"""User errors on the command line: exit code + one line ``rangekit: error: ...`` on stderr.

Exit codes (``docs/cli.md``): 2 usage or invalid parameter, 3 file missing/unreadable or
output not writable, 4 not audio, 5 incompatible inputs, 6 detection failure. With
``--debug`` the exception propagates (a traceback) instead.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from clihelp import assert_error, run

from rangekit.errors import (
    AudioFormatError,
    DetectionError,
    IncompatibleInputError,
    InputFileError,
    InvalidParameterError,
)

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures_audio"


def _fixture_files(name: str) -> list[str]:
    truth = json.loads((FIXTURES / f"{name}.json").read_text(encoding="utf-8"))
    return [str(FIXTURES / f) for f in truth["files"]]


def _noise(path: Path, *, fs: int = 44100, n: int = 88200, channels: int = 1, seed: int = 0):
    rng = np.random.default_rng(seed)
    shape = (n,) if channels == 1 else (n, channels)
    sf.write(path, 0.1 * rng.standard_normal(shape), fs, subtype="PCM_16")
    return path


def _synth(tmp_path: Path, name: str, *extra) -> Path:
    out = tmp_path / name
    r = run(["synth", "beepbeep", "--seed", 5, "-o", out, *extra])
    assert r.exit_code == 0, r.stderr
    return out


@pytest.fixture
def good_wav():
    return _fixture_files("beepbeep_2p5m")[0]


# --- files ---------------------------------------------------------------------------


def test_missing_file(tmp_path):
    missing = tmp_path / "no_such_recording.wav"
    assert_error(run(["range", missing]), 3, "no_such_recording.wav")


def test_directory_as_file(tmp_path):
    d = tmp_path / "a_folder.wav"
    d.mkdir()
    assert_error(run(["range", d]), 3, "a_folder.wav", "directory")


def test_text_file_is_not_audio(tmp_path):
    f = tmp_path / "notes.wav"
    f.write_text("these are not samples\n")
    assert_error(run(["range", f]), 4, "notes.wav")


def test_empty_wav(tmp_path):
    f = tmp_path / "empty.wav"
    sf.write(f, np.zeros((0, 2)), 44100, subtype="PCM_16")
    assert sf.info(str(f)).frames == 0
    assert_error(run(["range", f]), 4, "empty.wav")


# --- incompatible inputs ---------------------------------------------------------------


def test_sample_rate_too_low_for_beep(tmp_path):
    f = _noise(tmp_path / "rate16k.wav", fs=16000, n=16000, channels=2)
    line = assert_error(run(["range", f]), 5, "rate16k.wav", "16000")
    assert "too low" in line


def test_single_mono_file(tmp_path):
    f = _noise(tmp_path / "lonely.wav")
    assert_error(run(["range", f]), 5, "lonely.wav", "channel")


def test_two_files_one_stereo(tmp_path):
    a = _noise(tmp_path / "mono_a.wav")
    b = _noise(tmp_path / "stereo_b.wav", channels=2, seed=1)
    assert_error(run(["range", a, b]), 5, "stereo_b.wav", "mono")


def test_wrong_number_of_self_distances(good_wav):
    line = assert_error(
        run(["range", good_wav, "--self-distance", "0.1,0.1,0.1"]), 5, "3", "2 devices"
    )
    assert "self-distance" in line


# --- detection failures ----------------------------------------------------------------


def test_three_mono_files_one_pure_noise(tmp_path):
    """A 2-device exchange rendered as mono files, plus a third file that is pure noise."""
    _synth(tmp_path, "pair.wav", "--distance", 2, "--mono")
    noise = _noise(tmp_path / "just_noise.wav", seed=3)
    files = [tmp_path / "pair_dev0.wav", tmp_path / "pair_dev1.wav", noise]
    r = run(["range", *files])
    line = assert_error(r, 6, "expected 3")
    assert any(f.name in line for f in files), line


def test_noise_file_in_three_device_set_is_named(tmp_path):
    """The 3-device fixture with device 1's file replaced by noise: that file is blamed."""
    f0, _, f2 = _fixture_files("beepbeep_3dev")
    noise = _noise(tmp_path / "dev1_noise.wav", seed=4)
    assert_error(run(["range", f0, noise, f2]), 6, "dev1_noise.wav", "found no beep")


def test_silence_only(tmp_path):
    f = tmp_path / "silence.wav"
    sf.write(f, np.zeros((44100, 2)), 44100, subtype="PCM_16")
    assert_error(run(["range", f]), 6, "silence.wav", "found no beep")


def test_burst_spacing_mismatch(tmp_path):
    f = _synth(tmp_path, "spaced.wav", "--distance", 2, "--spacing", 4000)
    line = assert_error(run(["range", f]), 6, "spaced.wav", "spacing", "4000", "5000")
    assert "--spacing" in line
    # With the right --spacing (and the true self-distance) the same file ranges fine.
    truth = json.loads(f.with_suffix(".json").read_text())
    sd = truth["devices"][0]["self_distance_m"]
    ok = run(["range", f, "--spacing", 4000, "--self-distance", sd, "--format", "json"])
    assert ok.exit_code == 0, ok.stderr
    assert json.loads(ok.stdout)["ranges"][0]["distance_m"] == pytest.approx(
        truth["pairs"][0]["distance_m"], abs=0.01
    )


# --- invalid parameters ------------------------------------------------------------------


@pytest.mark.parametrize("temp", ["-100", "nan", "200", "inf"])
def test_bad_temperature(good_wav, temp):
    assert_error(run(["range", good_wav, "--temperature", temp]), 2, temp, "temperature")


def test_absurd_speed_of_sound(good_wav):
    assert_error(run(["range", good_wav, "--speed-of-sound", "5"]), 2, "5")


def test_bad_format_choice_is_usage_error(good_wav):
    r = run(["range", good_wav, "--format", "xml"])
    line = assert_error(r, 2, "'xml'", "--format")
    assert "rangekit range --help" in line
    assert r.stdout == ""


# --- output ------------------------------------------------------------------------------


def test_output_into_missing_folder(good_wav, tmp_path):
    out = tmp_path / "no_such_dir" / "out.json"
    assert_error(run(["range", good_wav, "-o", out]), 3, "no_such_dir")
    assert not out.parent.exists()


@pytest.mark.parametrize("bad", ["missing", "silence"])
def test_failed_run_leaves_existing_output_untouched(tmp_path, bad):
    sentinel = tmp_path / "sentinel.json"
    sentinel.write_text("SENTINEL, do not touch\n")
    if bad == "missing":
        f, code = tmp_path / "missing.wav", 3
    else:
        f, code = tmp_path / "silence.wav", 6
        sf.write(f, np.zeros((44100, 2)), 44100, subtype="PCM_16")
    r = run(["range", f, "--format", "json", "-o", sentinel])
    assert_error(r, code, f.name)
    assert r.stdout == ""
    assert sentinel.read_text() == "SENTINEL, do not touch\n"
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []


# --- --debug -----------------------------------------------------------------------------


@pytest.mark.parametrize("where", ["before", "after"])
@pytest.mark.parametrize(
    ("case", "exc"),
    [
        ("missing", InputFileError),
        ("notaudio", AudioFormatError),
        ("mono", IncompatibleInputError),
        ("silence", DetectionError),
        ("beep", InvalidParameterError),
    ],
)
def test_debug_propagates_exception(tmp_path, where, case, exc):
    if case == "missing":
        args = ["range", tmp_path / "missing.wav"]
    elif case == "notaudio":
        (tmp_path / "t.wav").write_text("text")
        args = ["range", tmp_path / "t.wav"]
    elif case == "mono":
        args = ["range", _noise(tmp_path / "m.wav")]
    elif case == "silence":
        sf.write(tmp_path / "s.wav", np.zeros((44100, 2)), 44100, subtype="PCM_16")
        args = ["range", tmp_path / "s.wav"]
    else:
        args = ["range", *_fixture_files("beepbeep_2p5m"), "--freq", "21000"]
    args = ["--debug", *args] if where == "before" else [*args, "--debug"]
    r = run(args)
    assert isinstance(r.exception, exc), (r.exception, r.stderr)
    assert r.exit_code == 1
    assert "rangekit: error:" not in r.stderr


def test_debug_prints_traceback_in_a_real_process(tmp_path):
    base = [sys.executable, "-m", "rangekit"]
    missing = str(tmp_path / "missing.wav")
    for args in (["--debug", "range", missing], ["range", missing, "--debug"]):
        p = subprocess.run(
            base + args, capture_output=True, text=True, timeout=60, check=False, cwd=tmp_path
        )
        assert p.returncode != 0
        assert "Traceback (most recent call last)" in p.stderr
        assert "InputFileError" in p.stderr and "missing.wav" in p.stderr
    p = subprocess.run(
        [*base, "range", missing], capture_output=True, text=True, timeout=60, check=False
    )
    assert p.returncode == 3
    assert p.stderr == f"rangekit: error: cannot open '{missing}': no such file\n"


# --- other commands ----------------------------------------------------------------------


def test_detect_silent_file_exits_6_with_header(tmp_path):
    f = tmp_path / "quiet.wav"
    sf.write(f, np.zeros((44100, 2)), 44100, subtype="PCM_16")
    for fmt in ("table", "csv"):
        r = run(["detect", f, "--format", fmt])
        assert_error(r, 6, "quiet.wav")
        header = r.stdout.splitlines()
        assert len(header) == 1
        assert header[0].replace(",", " ").split() == [
            "file", "channel", "beep", "onset_sample", "onset_s", "sigma_samples", "snr_db",
            "confidence", "flags",
        ]  # fmt: skip


def test_detect_fixture_finds_one_beep_per_device_per_channel():
    f = _fixture_files("beepbeep_2p5m")
    r = run(["detect", *f, "--format", "json"])
    assert r.exit_code == 0, r.stderr
    rows = json.loads(r.stdout)["arrivals"]
    assert sorted((a["channel"], a["beep"]) for a in rows) == [(0, 0), (0, 1), (1, 0), (1, 1)]


def test_design_beep_beyond_nyquist(tmp_path):
    out = tmp_path / "beep.wav"
    assert_error(run(["design", "beep", "--freq", "21000", "-o", out]), 2, "21000")
    assert not out.exists()


@pytest.mark.parametrize("fs", ["nan", "0", "-5", "1e9"])
def test_design_beep_bad_file_rate(tmp_path, fs):
    out = tmp_path / "beep.wav"
    assert_error(run(["design", "beep", "--fs", fs, "-o", out]), 2, "--fs")
    assert not out.exists()


@pytest.mark.parametrize(
    "opts",
    [{}, {"bursts": 3, "spacing": 3000, "burst_len": 300}],
    ids=["defaults", "custom"],
)
def test_design_beep_writes_pcm16(tmp_path, opts):
    from rangekit.signals import Beep

    out = tmp_path / "beep.wav"
    args = ["design", "beep", "-o", out]
    for k, v in opts.items():
        args += [f"--{k.replace('_', '-')}", v]
    r = run(args)
    assert r.exit_code == 0, r.stderr
    assert r.stdout == ""
    assert "wrote" in r.stderr
    info = sf.info(str(out))
    b = Beep(**{{"bursts": "n_bursts"}.get(k, k): v for k, v in opts.items()})
    assert info.subtype == "PCM_16"
    assert info.samplerate == 44100
    assert info.channels == 1
    assert info.frames == (b.n_bursts - 1) * b.spacing + b.burst_len
    x, _ = sf.read(str(out))
    assert 0.85 < np.max(np.abs(x)) <= 0.9 + 1e-4  # default --amplitude 0.9


def test_synth_without_distance_or_position(tmp_path):
    out = tmp_path / "x.wav"
    r = run(["synth", "beepbeep", "-o", out])
    assert_error(r, 2, "--distance", "--position", "rangekit synth beepbeep --help")
    assert not out.exists()
