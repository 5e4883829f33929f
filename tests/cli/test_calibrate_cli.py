"""``rangekit calibrate`` and ``rangekit range --template --calibration`` end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest
from clihelp import assert_error, ok, run

from rangekit.io.audio import write_audio
from rangekit.physics import speed_of_sound_m_s
from rangekit.signals.probe import linear_sweep
from rangekit.sim.exchanges import render_exchanges
from rangekit.sim.recording import Device
from rangekit.sim.room import ShoeboxRoom

C = speed_of_sound_m_s(20.0)
ROOM = ShoeboxRoom((7.0, 5.0, 3.0), absorption=0.4, max_order=2)
SELF_M = (0.12, 0.18)


def _devices(d, rng, fs=44100.0):
    centre = np.array([3.5, 2.5, 1.3]) + rng.uniform(-0.2, 0.2, 3)
    u = np.array([1.0, 0.0, 0.0])
    spk = [centre - u * d / 2, centre + u * d / 2]
    # Mics above the speakers: the mean cross distance is sqrt(d^2 + dz^2)-ish, close to d.
    return [
        Device(speaker_m=s, mic_m=s + np.array([0.0, 0.0, m]), fs=fs)
        for s, m in zip(spk, SELF_M, strict=True)
    ]


def _record(path, probe, d, rng, *, mono=False):
    """Write a two-way recording at speaker distance d; return the true (mean cross) distance."""
    sim = render_exchanges(
        _devices(d, rng), source=probe.samples, source_fs=probe.fs, room=ROOM, rng=rng
    )
    n = min(len(x) for x in sim.recordings)
    x = np.stack([r[:n] for r in sim.recordings], axis=1)
    if mono:
        for i in range(2):
            write_audio(path.with_name(f"{path.stem}_dev{i}.wav"), x[:, i], fs=44100.0)
    else:
        write_audio(path, x, fs=44100.0)
    return sim.truth["pairs"][0]["distance_m"]


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """A sweep file, three recordings at one true distance, two at another, a test one."""
    tmp = tmp_path_factory.mktemp("cal")
    rng = np.random.default_rng(21)
    probe = linear_sweep(17000.0, 20000.0, 0.1)
    sweep = tmp / "sweep.wav"
    ok(run(["design", "sweep", "--f0", 17000, "--f1", 20000, "--duration", 0.1, "-o", sweep]))
    truth = {}
    for name, d in (("a1", 1.0), ("a2", 1.0), ("a3", 1.0), ("b1", 3.0), ("b2", 3.0), ("t", 2.4)):
        truth[name] = _record(tmp / f"{name}.wav", probe, d, rng)
    truth["m"] = _record(tmp / "m.wav", probe, 1.5, rng, mono=True)
    return tmp, sweep, truth


def _cal(tmp, sweep, names, truth, *extra, out="cal.json"):
    recs = [f"{tmp / (n + '.wav')}@{truth[n]:.6f}" for n in names]
    return run(["calibrate", "--template", sweep, *recs, "-o", tmp / out, *extra])


def test_one_distance_offset_then_range(scene):
    tmp, sweep, truth = scene
    r = ok(_cal(tmp, sweep, ["a1", "a2", "a3"], truth, "--no-fit-speed"))
    assert "model offset" in r.output
    cal = json.loads((tmp / "cal.json").read_text())
    assert cal["format"] == "rangekit-calibration/1" and cal["model"] == "offset"
    assert cal["n_recordings"] == 3
    # The offset is the speaker-to-microphone geometry: close to the mean self-distance.
    assert abs(cal["offset_m"] - np.mean(SELF_M)) < 0.02
    r = ok(
        run(
            [
                "range",
                "--template",
                sweep,
                "--calibration",
                tmp / "cal.json",
                tmp / "t.wav",
                "--format",
                "json",
            ]
        )
    )
    out = json.loads(r.output)
    assert abs(out["ranges"][0]["distance_m"] - truth["t"]) < 0.01
    assert out["calibration"]["model"] == "offset"
    # Without the calibration the range is off by about the offset.
    r = ok(run(["range", "--template", sweep, tmp / "t.wav", "--format", "json"]))
    raw = json.loads(r.output)["ranges"][0]["distance_m"]
    assert abs(truth["t"] - raw - cal["offset_m"]) < 0.01


def test_mono_device_files_with_plus(scene):
    """dev0.wav+dev1.wav is one two-way recording of two mono device files."""
    tmp, sweep, truth = scene
    m0, m1 = tmp / "m_dev0.wav", tmp / "m_dev1.wav"
    recs = [f"{tmp / (n + '.wav')}@{truth[n]:.6f}" for n in ("a1", "a2")]
    out = tmp / "mono.json"
    args = ["calibrate", "--template", sweep, *recs, f"{m0}+{m1}@{truth['m']:.6f}"]
    ok(run([*args, "--no-fit-speed", "-o", out]))
    cal = json.loads(out.read_text())
    assert cal["n_recordings"] == 3
    assert any(r["source"] == f"{m0}+{m1}" for r in cal["residuals"])
    assert max(abs(r["residual_m"]) for r in cal["residuals"]) < 0.01


def test_two_distances_fit_the_speed(scene):
    tmp, sweep, truth = scene
    ok(_cal(tmp, sweep, ["a1", "a2", "b1", "b2"], truth, out="cs.json"))
    cal = json.loads((tmp / "cs.json").read_text())
    assert cal["model"] == "offset+speed"
    assert abs(cal["speed_m_s"] - C) < 3 * cal["sigma_speed_m_s"] + 0.5
    assert cal["sigma_speed_m_s"] > 0


def test_formats_and_digits(scene):
    """--format json prints the file's object, csv one row that loads, table the fitted
    values to their sigma (two significant digits of it)."""
    import csv
    import io

    from rangekit.io.results import format_pm

    tmp, sweep, truth = scene
    names = ["a1", "a2", "b1", "b2"]
    js = ok(_cal(tmp, sweep, names, truth, "--format", "json", "-q", out="fj.json"))
    assert json.loads(js.stdout) == json.loads((tmp / "fj.json").read_text())
    assert js.stderr == ""
    cal = json.loads(js.stdout)
    row = next(csv.DictReader(io.StringIO(ok(_cal(tmp, sweep, names, truth, "--format",
                                                  "csv", out="fc.json")).stdout)))  # fmt: skip
    assert float(row["offset_m"]) == pytest.approx(cal["offset_m"], abs=1e-6)
    assert row["latency_s"] == "" and row["model"] == "offset+speed"
    table = ok(_cal(tmp, sweep, names, truth, out="ft.json")).stdout
    pm = format_pm(cal["speed_m_s"], cal["sigma_speed_m_s"])
    assert f"speed_m_s    {pm}" in table
    assert f"offset_m     {format_pm(cal['offset_m'], cal['sigma_offset_m'], sign=True)}" in table


def test_too_few_recordings_refused(scene):
    tmp, sweep, truth = scene
    r = _cal(tmp, sweep, ["a1", "a2"], truth)
    assert_error(r, 7, "too few recordings", "a1.wav", "a2.wav")
    assert not (tmp / "cal.json.never").exists()


def test_inconsistent_recording_named(scene):
    tmp, sweep, truth = scene
    bad = dict(truth, a3=truth["a3"] + 0.25)  # a wrong tape measurement
    names = ["a1", "a2", "a3"]
    recs = [f"{tmp / (n + '.wav')}@1.0" for n in names[:2]] + [f"{tmp / 'a3.wav'}@{bad['a3']}"]
    out = tmp / "bad.json"
    r = run(["calibrate", "--template", sweep, *recs, "-o", out, "--no-fit-speed"])
    line = assert_error(r, 7, "disagree", "a3.wav")
    assert "a1.wav" not in line
    assert not out.exists()


def test_calibration_errors(scene):
    tmp, sweep, truth = scene
    ok(_cal(tmp, sweep, ["a1", "a2", "a3"], truth, "--no-fit-speed", out="ok.json"))
    t = tmp / "t.wav"
    r = run(
        ["range", "--template", sweep, "--calibration", tmp / "ok.json", t, "--self-distance", 0.1]
    )
    assert_error(r, 2, "--self-distance", "calibration")
    (tmp / "junk.json").write_text("{")
    assert_error(run(["range", "--calibration", tmp / "junk.json", t]), 3, "junk.json")
    (tmp / "other.json").write_text('{"a": 1}')
    assert_error(run(["range", "--calibration", tmp / "other.json", t]), 3, "other.json")
    assert_error(run(["range", "--calibration", tmp / "none.json", t]), 3, "none.json")
    r = run(["range", "--scheme", "oneway", "--calibration", tmp / "ok.json", t])
    assert_error(r, 2, "ok.json", "beepbeep")
    r = run(["calibrate", "--template", sweep, t, "-o", tmp / "x.json"])
    assert_error(r, 2, "distance")
    r = run(["calibrate", "--template", sweep, f"{t}@abc", "-o", tmp / "x.json"])
    assert_error(r, 2, "abc")


def test_batch_with_template_and_calibration(scene):
    """batch --template --calibration gives the distances of range with the same options."""
    import csv

    tmp, sweep, truth = scene
    cal = tmp / "bcal.json"
    ok(_cal(tmp, sweep, ["a1", "a2", "a3"], truth, "--no-fit-speed", out=cal.name))
    out = tmp / "batch.csv"
    args = ["--template", sweep, "--calibration", cal]
    ok(run(["batch", tmp / "t.wav", tmp / "b1.wav", "-o", out, "--jobs", 1, "-q", *args]))
    rows = {r["session"]: r for r in csv.DictReader(line for line in open(out) if line[0] != "#")}
    for name in ("t", "b1"):
        r = ok(run(["range", *args, tmp / f"{name}.wav", "--format", "json"]))
        want = json.loads(r.output)["ranges"][0]["distance_m"]
        got = float(rows[str(tmp / f"{name}.wav")]["distance_m"])
        assert got == pytest.approx(want, abs=1e-9)
        assert abs(got - truth[name]) < 0.01
    r = run(["batch", tmp / "t.wav", "-o", tmp / "b2.csv", *args, "--self-distance", 0.1])
    assert_error(r, 2, "--self-distance", "calibration")


def test_oneway_calibrate_then_range(tmp_path):
    """One-way with an unknown latency: calibrate at 1 m, range at 3 m within 1 cm."""
    rng = np.random.default_rng(5)
    probe = linear_sweep(17000.0, 20000.0, 0.1)
    sweep = tmp_path / "sweep.wav"
    write_audio(sweep, probe.samples, fs=probe.fs)
    latency = 0.0123

    def rec(name, d):
        centre = np.array([3.5, 2.5, 1.3]) + rng.uniform(-0.2, 0.2, 3)
        half = np.array([d / 2, 0.0, 0.0])
        a, b = centre - half, centre + half
        devs = [
            Device(speaker_m=a, mic_m=a + np.array([0.0, 0.0, 0.05])),
            Device(speaker_m=b, mic_m=b),
        ]
        sim = render_exchanges(
            devs, source=probe.samples, source_fs=probe.fs, room=ROOM, lead_s=latency,
            gap_s=0.3, rng=rng,
        )  # fmt: skip
        write_audio(tmp_path / f"{name}.wav", sim.recordings[1], fs=44100.0)
        return float(np.linalg.norm(devs[0].speaker_m - devs[1].mic_m))

    truth = {n: rec(n, d) for n, d in (("c1", 1.0), ("c2", 1.0), ("c3", 1.0), ("t", 3.0))}
    recs = [f"{tmp_path / (n + '.wav')}@{truth[n]:.6f}" for n in ("c1", "c2", "c3")]
    cal = tmp_path / "ow.json"
    args = ["calibrate", "--scheme", "oneway", "--template", sweep, *recs, "--no-fit-speed"]
    r = ok(run([*args, "-o", cal]))
    assert "latency_s" in r.output
    got = json.loads(cal.read_text())
    assert got["scheme"] == "oneway" and abs(got["latency_s"] - latency) < 3e-5
    rng_args = ["range", "--scheme", "oneway", "--template", sweep, "--calibration", cal]
    r = ok(run([*rng_args, tmp_path / "t.wav", "--format", "json"]))
    d = json.loads(r.output)["ranges"][0]["distance_m"]
    assert abs(d - truth["t"]) < 0.01
    r = run([*args, "--latency", 0.01, "-o", tmp_path / "x.json"])
    assert_error(r, 2, "--latency")
    # the command is one library call: the same calibration from calibrate_recordings
    from dataclasses import replace

    from rangekit.ranging.calibration import calibrate_recordings, parse_recording
    from rangekit.ranging.config import Medium
    from rangekit.ranging.ultrasonic_setup import ultrasonic_setup
    from rangekit.signals import read_probe

    calls = []
    lib = calibrate_recordings(
        [parse_recording(x) for x in recs], scheme="oneway", speed_m_s=Medium().c,
        probe=read_probe(sweep), setup=replace(ultrasonic_setup("oneway"), channels=None),
        fit_speed=False, progress=lambda done, total: calls.append((done, total)),
    )  # fmt: skip
    assert json.loads(json.dumps(lib.to_dict())) == got
    assert calls == [(1, 3), (2, 3), (3, 3)]


def test_tolerance_default_is_the_librarys(monkeypatch):
    """--tolerance shows and uses rangekit.ranging.calibration.DEFAULT_TOLERANCE_M (not a
    copy of it)."""
    from rangekit.ranging import calibration

    monkeypatch.setattr(calibration, "DEFAULT_TOLERANCE_M", 0.0125)
    text = " ".join(ok(run(["calibrate", "--help"])).stdout.split())
    assert "placed), m. [default: 0.0125;" in text
