"""``rangekit range --strict``: a flagged range is refused with exit 10 and nothing written."""

from __future__ import annotations

import json
from pathlib import Path

from clihelp import assert_error, ok, run


def _synth(tmp_path, name, *extra):
    out = tmp_path / f"{name}.wav"
    if "--distance" not in extra:
        extra = ("--distance", 2, *extra)
    ok(run(["synth", "beepbeep", "--seed", 3, *extra, "-o", out]))
    return out


def test_clipped_exchange_is_flagged_and_refused_in_strict_mode(tmp_path):
    wav = _synth(tmp_path, "clipped", "--impair", "clip_db=15")
    res = ok(run(["range", wav, "--self-distance", 0.1, "--format", "json"]))
    r = json.loads(res.output)["ranges"][0]
    assert "clipped" in r["flags"]
    assert abs(r["distance_m"] - 2.0) < 0.03  # measured 15 mm long, sigma 9 mm (flagged)
    out = tmp_path / "ranges.txt"
    res = run(["range", wav, "--self-distance", 0.1, "--strict", "-o", out])
    msg = assert_error(res, 10, "strict", "pair 0-1", "clipped", "clipped.wav")
    assert "\n" not in msg.strip()
    assert not out.exists()


def test_clean_exchange_passes_strict_mode(tmp_path):
    wav = _synth(tmp_path, "clean")
    res = ok(run(["range", wav, "--self-distance", 0.1, "--strict", "--format", "json"]))
    r = json.loads(res.output)["ranges"][0]
    assert r["flags"] == [] and abs(r["distance_m"] - 2.0) < 0.01


def test_strict_is_beepbeep_only(tmp_path):
    wav = _synth(tmp_path, "x")
    assert_error(run(["range", wav, "--strict", "--series"]), 2, "--strict")
    assert_error(run(["range", wav, "--strict", "--scheme", "echo"]), 2, "--strict")


ROOM = Path(__file__).resolve().parents[2] / "fixtures_audio" / "beepbeep_room_4p2m.wav"


def test_xcorr_on_a_reflection_is_flagged_not_confident(tmp_path):
    """The cross-correlation baseline takes a reflection 257 samples late in the room
    fixture (6.09 m for 4.08 m): it must carry a flag, and --strict refuses it."""
    res = ok(run(["range", ROOM, "--detector", "xcorr", "--format", "json"]))
    r = json.loads(res.output)["ranges"][0]
    assert abs(r["distance_m"] - 4.08) > 1.0  # still the baseline's wrong answer ...
    assert "ambiguous_first_path" in r["flags"]  # ... but no longer a confident one
    assert_error(run(["range", ROOM, "--detector", "xcorr", "--strict"]), 10, "pair 0-1")
    res = ok(run(["range", ROOM, "--strict", "--format", "json"]))  # changepoint: fine
    assert abs(json.loads(res.output)["ranges"][0]["distance_m"] - 4.08) < 0.01


def test_wrong_template_is_flagged_or_refused(tmp_path):
    """A beep recording ranged with a 17-20 kHz sweep as template (the issue's example of
    a confident wrong answer: 19.58 m, sigma 8.7 mm, exit 0)."""
    wav = _synth(tmp_path, "beep3m", "--distance", 3)
    sweep = tmp_path / "sweep.wav"
    ok(run(["design", "sweep", "--f0", 17000, "--f1", 20000, "--duration", 0.1, "-o", sweep]))
    res = run(["range", wav, "--template", sweep, "--self-distance", 0.1, "--format", "json"])
    if res.exit_code == 0:
        r = json.loads(res.output)["ranges"][0]
        assert abs(r["distance_m"] - 3.0) < 0.1 or r["flags"], r
        res = run(["range", wav, "--template", sweep, "--self-distance", 0.1, "--strict"])
        assert res.exit_code in (6, 10)
    else:
        assert res.exit_code == 6
