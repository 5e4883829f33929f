"""``rangekit synth ... --impair SPEC``: the file holds the impairments, the sidecar records
them and moves the truth by the silence padding, bad specs write nothing."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from clihelp import assert_error, ok, run

from rangekit.sim.impair import KEYS, estimate_floor_psd

FS = 44100
LSB = 1 / 32768
PLAN = Path(__file__).resolve().parents[2] / "fixtures_audio" / "corridor_plan.json"


def _beepbeep(tmp_path, name, *extra):
    out = tmp_path / f"{name}.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--seed", 1, *extra, "-o", out]))
    x, fs = sf.read(out)
    assert fs == FS
    return out, x, json.loads(out.with_suffix(".json").read_text())


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    return _beepbeep(tmp_path_factory.mktemp("clean"), "clean")


def test_silence_moves_the_truth_and_ranging_still_matches(tmp_path, clean):
    _, x0, truth0 = clean
    wav, x, truth = _beepbeep(tmp_path, "padded", "--impair", "silence_s=0.5")
    shift = round(0.5 * FS)
    rec = truth["impairments"]
    assert rec["silence_s"] == 0.5 and rec["spec"] == "silence_s=0.5"
    assert rec["shift_samples"] == shift and rec["shift_s"] == 0.5
    assert rec["clipped_fraction"] == [0.0, 0.0]
    # The file: exact zeros around the very recording --seed 1 renders without --impair.
    assert x.shape == (len(x0) + 2 * shift, 2)
    assert np.all(x[:shift] == 0.0) and np.all(x[-shift:] == 0.0)
    np.testing.assert_array_equal(x[shift:-shift], x0)
    # The truth: onsets moved by the shift, sample 0 moved back by it, distances kept.
    for d0, d in zip(truth0["devices"], truth["devices"], strict=True):
        assert d["onsets"] == pytest.approx([o + shift for o in d0["onsets"]], abs=1e-9)
        rate = d0["fs"] * (1 + d0["clock_ppm"] * 1e-6)
        assert d["rec_start_s"] == pytest.approx(d0["rec_start_s"] - shift / rate, abs=1e-12)
        assert d["play_s"] == d0["play_s"]
    assert truth["pairs"] == truth0["pairs"]
    # The detector finds the beeps where the moved truth says (measured within 0.13 samples).
    r = ok(run(["detect", wav, "--format", "json"]))
    found = json.loads(r.stdout)["arrivals"]
    assert len(found) == 4
    for a in found:
        true_onset = truth["devices"][a["channel"]]["onsets"][a["beep"]]
        assert abs(a["onset_sample"] - true_onset) < 0.5
    # Ranging the padded file matches the truth distance.
    r = ok(run(["range", wav, "--self-distance", 0.1, "--format", "json"]))
    (row,) = json.loads(r.stdout)["ranges"]
    assert abs(row["distance_m"] - truth["pairs"][0]["distance_m"]) < 0.005


def test_dc_and_clip_in_the_file(tmp_path, clean):
    _, x0, _ = clean
    _, x, truth = _beepbeep(tmp_path, "dc_clip", "--impair", "dc=0.02,clip_db=10")
    # What was asked: the offset added, then clipped at the channel's peak - 10 dB.
    level = np.max(np.abs(x0 + 0.02), axis=0) * 10 ** (-10 / 20)
    np.testing.assert_allclose(x.max(axis=0), level, atol=2 * LSB)
    np.testing.assert_allclose(x.min(axis=0), -level, atol=2 * LSB)
    expected = np.clip(x0 + 0.02, -level, level)
    np.testing.assert_allclose(x.mean(axis=0), expected.mean(axis=0), atol=1e-5)
    assert np.all(x.mean(axis=0) > 0.019)
    rec = truth["impairments"]
    np.testing.assert_allclose(
        rec["clipped_fraction"], np.mean(np.abs(x0 + 0.02) > level, axis=0), atol=1e-3
    )
    assert rec["full_scale_clipped_fraction"] == [0.0, 0.0]
    # The floor used is the render's noise (white, std noise_sigma).
    sig = [d["noise_sigma"] for d in truth["devices"]]
    np.testing.assert_allclose(rec["floor_psd"], 2 * np.square(sig) / FS, rtol=1e-12)

    _, x_dc, _ = _beepbeep(tmp_path, "dc", "--impair", "dc=-0.05")
    np.testing.assert_allclose(x_dc.mean(axis=0) - x0.mean(axis=0), -0.05, atol=LSB)


def test_levels_beyond_full_scale_clip_like_an_adc(tmp_path):
    _, x, truth = _beepbeep(tmp_path, "loud", "--impair", "agc_db=20,agc_steps=2")
    full = truth["impairments"]["full_scale_clipped_fraction"]
    # Seed 1: device 1's gain steps up by 20 dB (peak 0.5 -> 5) and the file clips at 1.0
    # (measured 2.65 % of its samples); device 0's steps down.
    assert full[0] == 0.0 and 0.01 < full[1] < 0.05
    np.testing.assert_allclose(np.mean(np.abs(x) >= 1.0 - LSB, axis=0), full, atol=1e-4)
    assert np.max(np.abs(x)) <= 1.0


def test_same_seed_same_file_and_mono_files(tmp_path):
    spec = "hum_db=30,interference=speech,interference_db=10,silence_s=0.1"
    _, a, _ = _beepbeep(tmp_path, "a", "--impair", spec)
    _, b, _ = _beepbeep(tmp_path, "b", "--impair", spec)
    np.testing.assert_array_equal(a, b)
    out = tmp_path / "m.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--seed", 1, "--mono", "--impair", spec,
            "-o", out]))  # fmt: skip
    truth = json.loads(out.with_suffix(".json").read_text())
    shift = round(0.1 * FS)
    assert truth["files"] == ["m_dev0.wav", "m_dev1.wav"]
    assert truth["impairments"]["shift_samples"] == shift
    assert len(truth["impairments"]["clipped_fraction"]) == 2
    for f in truth["files"]:
        x, _ = sf.read(tmp_path / f)
        assert x.ndim == 1 and np.all(x[:shift] == 0.0) and np.all(x[-shift:] == 0.0)


def test_ultrasonic_truth_windows_move(tmp_path):
    out = tmp_path / "ow.wav"
    args = ["synth", "oneway", "--tx", "1,0.5", "--tx", "-1,2", "--period", 0.05, "--seed", 3]
    ok(run([*args, "-o", tmp_path / "ow0.wav"]))
    ok(run([*args, "--impair", "silence_s=0.01,pink_db=10", "-o", out]))
    t0 = json.loads((tmp_path / "ow0.json").read_text())
    t = json.loads(out.with_suffix(".json").read_text())
    shift = round(0.01 * 192000)
    assert t["impairments"]["shift_samples"] == shift
    starts = [w["start_sample"] for w in t["windows"]]
    assert starts == [w["start_sample"] + shift for w in t0["windows"]]
    x0, _ = sf.read(tmp_path / "ow0.wav")
    x, _ = sf.read(out)
    assert x.shape == (len(x0) + 2 * shift, 3) and np.all(x[:shift] == 0.0)
    # The floor: the render's white noise at the WAV's scale, which the clean file shows.
    est = estimate_floor_psd(x0, fs=192000.0)
    got = np.asarray(t["impairments"]["floor_psd"])
    assert np.all(np.abs(10 * np.log10(est / got)) < 0.5)

    echo = tmp_path / "echo.wav"
    ok(run(["synth", "echo", "--map", PLAN, "--pose", "1,0.7,90", "--impair", "silence_s=0.002",
            "--seed", 1, "-o", echo]))  # fmt: skip
    te = json.loads(echo.with_suffix(".json").read_text())
    assert te["windows"][0]["start_sample"] == round(0.002 * 192000)
    assert te["impairments"]["spec"] == "silence_s=0.002"


@pytest.mark.parametrize(
    ("spec", "names"),
    [
        ("dc=0.02,clipdb=10", ["clipdb", "valid keys: dc, clip_db"]),
        ("dc", ["'dc' must be KEY=VALUE"]),
        ("hum_db=thirty", ["hum_db='thirty' must be a number"]),
        ("dc=0.1,dc=0.2", ["'dc' is given twice"]),
        ("dc=2", ["dc=2.0 must be within [-0.5, 0.5]"]),
    ],
)
def test_bad_spec_exits_2_and_writes_nothing(tmp_path, spec, names):
    out = tmp_path / "x.wav"
    r = run(["synth", "beepbeep", "--distance", 2, "--impair", spec, "-o", out])
    assert_error(r, 2, "--impair", *names)
    assert list(tmp_path.iterdir()) == []


def test_relative_level_of_a_noiseless_render_is_refused(tmp_path):
    out = tmp_path / "x.wav"
    r = run(
        ["synth", "beepbeep", "--distance", 2, "--no-noise", "--impair", "hum_db=30", "-o", out]
    )
    assert_error(r, 2, "hum_db", "floor is zero", "--snr-db")
    assert list(tmp_path.iterdir()) == []
    r = run(["synth", "oneway", "--no-noise", "--impair", "lf_db=30", "-o", out])
    assert_error(r, 2, "lf_db", "floor is zero")
    assert list(tmp_path.iterdir()) == []
    # DC and clipping need no floor.
    ok(run(["synth", "beepbeep", "--distance", 2, "--no-noise", "--impair", "dc=0.01", "-o", out]))


@pytest.mark.parametrize("cmd", ["beepbeep", "oneway", "echo"])
def test_help_lists_every_key(cmd):
    r = ok(run(["synth", cmd, "--help"]))
    text = " ".join(r.stdout.split())
    assert "--impair SPEC" in text and "impairments.md of the documentation" in text
    for key in KEYS:
        assert key in text, key
