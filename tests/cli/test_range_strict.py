"""``rangekit range --strict``: a flagged range is refused with exit 10 and nothing written."""

from __future__ import annotations

import json

from clihelp import assert_error, ok, run


def _synth(tmp_path, name, *extra):
    out = tmp_path / f"{name}.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--seed", 3, *extra, "-o", out]))
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
