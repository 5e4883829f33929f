"""``rangekit detect --template``: arrivals of a played probe file in every channel."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest
import soundfile as sf
from clihelp import assert_error, ok, run

from rangekit.io.audio import read_audio, write_audio
from rangekit.signals.probe import read_probe
from rangekit.sim.recording import pair_devices, render_beepbeep

SWEEP = ["--f0", 17000, "--f1", 20000, "--duration", 0.1]


@pytest.fixture(scope="module")
def sweep_file(tmp_path_factory):
    """A 17-20 kHz, 0.1 s sweep written by `rangekit design sweep` (44.1 kHz)."""
    out = tmp_path_factory.mktemp("probe") / "sweep.wav"
    ok(run(["design", "sweep", *SWEEP, "-o", out]))
    return out


def _render(probe, fs: float, distance_m: float = 1.7, seed: int = 4):
    """Two devices playing ``probe`` in turn at ``fs``; recordings and true onsets."""
    devices = pair_devices(distance_m, self_distance_m=0.05, fs=fs)
    sim = render_beepbeep(devices, beep=probe, snr_db=20.0, gap_s=0.1, rng=seed)
    return np.stack(sim.recordings, axis=1), sim.onsets


@pytest.mark.parametrize("fs", [44100.0, 48000.0])
def test_detect_template_finds_the_rendered_onsets(tmp_path, sweep_file, fs):
    x, onsets = _render(read_probe(sweep_file), fs)
    rec = tmp_path / "rec.wav"
    write_audio(rec, x, fs=fs, subtype="PCM_16")
    r = ok(run(["detect", "--template", sweep_file, rec, "--format", "json"]))
    doc = json.loads(r.stdout)
    assert doc["detector"] == "template" and doc["template"] == str(sweep_file)
    rows = doc["arrivals"]
    assert [(a["channel"], a["beep"]) for a in rows] == [(0, 0), (0, 1), (1, 0), (1, 1)]
    got = np.array([a["onset_sample"] for a in rows]).reshape(2, 2)
    np.testing.assert_allclose(got, onsets, atol=0.05)
    for a in rows:
        assert a["file"] == str(rec)
        assert a["onset_s"] == pytest.approx(a["onset_sample"] / fs)
        # sigma is the absolute onset's: the transducers' unknown group delay in the 3 kHz
        # band dominates it (transducer_sigma, measured 7.3 samples at 44.1 kHz, 7.9 at 48).
        assert 5.0 < a["sigma_samples"] < 12.0 and a["snr_db"] > 30


def test_detect_template_mono_files_and_csv(tmp_path, sweep_file):
    x, onsets = _render(read_probe(sweep_file), 44100.0, distance_m=3.2, seed=9)
    files = []
    for i in range(2):
        f = tmp_path / f"dev{i}.wav"
        write_audio(f, x[:, i], fs=44100.0, subtype="PCM_16")
        files.append(f)
    r = ok(run(["detect", *files, "--template", sweep_file, "--format", "csv"]))
    rows = list(csv.DictReader(io.StringIO(r.stdout)))
    assert list(rows[0]) == [
        "file", "channel", "beep", "onset_sample", "onset_s", "sigma_samples", "snr_db",
        "confidence", "flags",
    ]  # fmt: skip
    assert [(row["file"], row["beep"]) for row in rows] == [
        (str(files[0]), "0"), (str(files[0]), "1"), (str(files[1]), "0"), (str(files[1]), "1"),
    ]  # fmt: skip
    got = np.array([float(row["onset_sample"]) for row in rows]).reshape(2, 2)
    np.testing.assert_allclose(got, onsets, atol=0.05)


def test_detect_template_noise_only_exits_6(tmp_path, sweep_file):
    rec = tmp_path / "noise.wav"
    write_audio(rec, 0.1 * np.random.default_rng(1).standard_normal(44100), fs=44100.0)
    r = run(["detect", "--template", sweep_file, rec])
    assert_error(r, 6, "no arrival", str(sweep_file), f"{rec}#0")
    assert len(r.stdout.splitlines()) == 1  # the table header only


def test_detect_template_file_errors(tmp_path, sweep_file):
    rec = tmp_path / "rec.wav"
    write_audio(rec, np.zeros(1000), fs=44100.0)
    missing = tmp_path / "missing.wav"
    assert_error(run(["detect", "--template", missing, rec]), 3, str(missing))
    stereo = tmp_path / "stereo.wav"
    sf.write(stereo, 0.1 * np.ones((200, 2)), 44100, subtype="PCM_16")
    assert_error(run(["detect", "--template", stereo, rec]), 4, str(stereo), "2 channels")


def test_detect_template_band_above_nyquist_exits_5(tmp_path, sweep_file):
    rec = tmp_path / "rec32k.wav"
    write_audio(rec, 0.1 * np.random.default_rng(2).standard_normal(32000), fs=32000.0)
    r = run(["detect", "--template", sweep_file, rec])
    assert_error(r, 5, str(sweep_file), str(rec), "Nyquist")


@pytest.mark.parametrize(
    ("extra", "names"),
    [(["--detector", "xcorr"], ("--detector",)), (["--freq", "17000"], ("--freq",))],
)
def test_detect_template_usage_errors(tmp_path, sweep_file, extra, names):
    rec = tmp_path / "rec.wav"
    write_audio(rec, np.zeros(1000), fs=44100.0)
    assert_error(run(["detect", "--template", sweep_file, *extra, rec]), 2, *names)


def test_detect_help_documents_template():
    out = " ".join(ok(run(["detect", "--help"])).stdout.split())
    assert "--template FILE" in out and "first-path" in out


# --- one arrival per emission: --expected, --min-separation, flags (issue 16) ------------


def test_detect_template_expected_gives_the_arrivals_range_uses(tmp_path, sweep_file):
    """--expected N: exactly N rows per channel, the arrivals `range` times (one code path)."""
    from rangekit.detect.template import detect_template

    probe = read_probe(sweep_file)
    x, onsets = _render(probe, 44100.0, distance_m=2.4, seed=12)
    rec = tmp_path / "rec.wav"
    write_audio(rec, x, fs=44100.0, subtype="FLOAT")
    x = read_audio(rec)[0]  # what the CLI reads (float32)
    for n in (1, 2):
        r = ok(run(["detect", "--template", sweep_file, "--expected", n, rec, "--format", "json"]))
        doc = json.loads(r.stdout)
        assert doc["expected"] == n
        rows = doc["arrivals"]
        assert [a["channel"] for a in rows] == [0] * n + [1] * n
        for ch in range(2):
            lib = detect_template(x[:, ch], fs=44100.0, probe=probe, expected=n)
            got = [a["onset_sample"] for a in rows if a["channel"] == ch]
            np.testing.assert_allclose(got, lib.onset, rtol=0, atol=1e-9)
            assert all(isinstance(a["flags"], list) for a in rows)
    # n = 2 finds both plays (own first on device 0, the far one first on device 1).
    got = np.array([a["onset_sample"] for a in rows]).reshape(2, 2)
    np.testing.assert_allclose(got, onsets, atol=0.05)


def test_detect_template_min_separation_groups_echoes(tmp_path, sweep_file):
    """An echo 30 ms after each play: its own arrival with a short separation only."""
    probe = read_probe(sweep_file)
    fs = 44100.0
    n = len(probe.samples)
    rng = np.random.default_rng(3)
    x = np.zeros(30000)
    for s in (3000, 17000):
        x[s : s + n] += probe.samples
        e = s + int(0.03 * fs)
        x[e : e + n] += 0.7 * probe.samples
    x += 1e-3 * rng.standard_normal(len(x))
    rec = tmp_path / "echo.wav"
    write_audio(rec, x, fs=fs, subtype="FLOAT")

    def onsets(*extra):
        r = ok(run(["detect", "--template", sweep_file, *extra, rec, "--format", "json"]))
        return [round(a["onset_sample"]) for a in json.loads(r.stdout)["arrivals"]]

    # Default separation (the probe's 0.1 s): the echo is part of its play.
    assert onsets() == [3000, 17000]
    assert onsets("--min-separation", 0.02) == [3000, 3000 + 1323, 17000, 17000 + 1323]
    assert onsets("--min-separation", 0.3) == [3000, 17000]


@pytest.mark.parametrize(
    "extra", [["--min-separation", "0.5"], ["--weighting", "ml"], ["--detector", "xcorr"]]
)
def test_detect_template_options_need_template(tmp_path, extra):
    """Matched-filter options need the matched filter; --detector needs the beep."""
    rec = tmp_path / "rec.wav"
    write_audio(rec, np.zeros(1000), fs=44100.0)
    if extra[0] == "--detector":
        assert_error(run(["detect", *extra, "--template", rec, rec]), 2, "--detector", "--template")
    else:
        assert_error(run(["detect", *extra, rec]), 2, extra[0], "--template")
