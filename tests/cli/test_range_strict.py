"""``rangekit range --strict``: a flagged range is refused with exit 10 and nothing written."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import soundfile as sf
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
    r = json.loads(res.stdout)["ranges"][0]
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
    r = json.loads(res.stdout)["ranges"][0]
    assert r["flags"] == [] and abs(r["distance_m"] - 2.0) < 0.01


def _series(tmp_path) -> Path:
    """Two exchanges 3 s apart in one stereo file: a clean one, then a clipped one.

    Each is scaled to full scale per channel, as one device's converter would record both
    (its rails are the same all through the file)."""
    parts = []
    for name, extra in (("a", ()), ("b", ("--impair", "clip_db=15"))):
        x, fs = sf.read(_synth(tmp_path, name, *extra), always_2d=True)
        x = x / np.abs(x).max(axis=0)
        parts.append(np.pad(x, ((0, int(3 * fs) - len(x)), (0, 0))))
    out = tmp_path / "series.wav"
    sf.write(out, np.concatenate(parts), int(fs), subtype="FLOAT")
    return out


def _check_withheld(plain: list[dict], strict: list[dict]) -> int:
    """Strict rows = plain rows, except doubtful ones: empty distance, flag 'withheld'."""
    assert len(plain) == len(strict) > 0
    n = 0
    for p, s in zip(plain, strict, strict=True):
        doubtful = p["distance_m"] is not None and set(p["flags"]) - {"dc_or_lowband"}
        if doubtful:
            n += 1
            assert s["distance_m"] is None and s["sigma_m"] is None, s
            assert s["flags"] == [*p["flags"], "withheld"]
        else:
            assert s == p
    return n


def test_series_strict_withholds_the_doubtful_exchange(tmp_path):
    wav = _series(tmp_path)
    args = ["range", "--series", wav, "--self-distance", 0.1]
    plain = json.loads(ok(run([*args, "--format", "json"])).stdout)["ranges"]
    assert [round(r["distance_m"], 1) for r in plain] == [2.0, 2.0]
    assert plain[0]["flags"] == [] and "clipped" in plain[1]["flags"]
    out = tmp_path / "s.csv"
    msg = assert_error(run([*args, "--strict", "--format", "csv", "-o", out]), 10, "series.wav")
    assert "1 of 2 ranges withheld" in msg and "clipped" in msg
    rows = list(csv.DictReader(out.open()))  # every row written, the doubtful one emptied
    assert [r["distance_m"] != "" for r in rows] == [True, False]
    assert rows[1]["flags"].split(";")[-1] == "withheld"
    res = run([*args, "--strict", "--format", "json"])
    assert res.exit_code == 10
    assert _check_withheld(plain, json.loads(res.stdout)["ranges"]) == 1


def test_oneway_strict_withholds_flagged_rows(tmp_path):
    """A one-way recording at 8 dB: the low_snr rows are withheld, the others kept."""
    wav = tmp_path / "ow.wav"
    ok(run(["synth", "oneway", "--seed", 1, "--snr-db", 8, "-o", wav]))
    args = ["range", "--scheme", "oneway", wav, "--period", 0.2, "--format", "json"]
    plain = json.loads(ok(run(args)).stdout)["ranges"]
    res = run([*args, "--strict"])
    msg = assert_error(res, 10, "ow.wav", "withheld")
    n = _check_withheld(plain, json.loads(res.stdout)["ranges"])
    assert 0 < n < len(plain) and f"{n} of {len(plain)} ranges" in msg


ROOM = Path(__file__).resolve().parents[2] / "fixtures_audio" / "beepbeep_room_4p2m.wav"


def test_xcorr_on_a_reflection_is_flagged_not_confident(tmp_path):
    """The cross-correlation baseline takes a reflection 257 samples late in the room
    fixture (6.09 m for 4.08 m): it must carry a flag, and --strict refuses it."""
    res = ok(run(["range", ROOM, "--detector", "xcorr", "--format", "json"]))
    r = json.loads(res.stdout)["ranges"][0]
    assert abs(r["distance_m"] - 4.08) > 1.0  # still the baseline's wrong answer ...
    assert "ambiguous_first_path" in r["flags"]  # ... but no longer a confident one
    assert_error(run(["range", ROOM, "--detector", "xcorr", "--strict"]), 10, "pair 0-1")
    res = ok(run(["range", ROOM, "--strict", "--format", "json"]))  # changepoint: fine
    assert abs(json.loads(res.stdout)["ranges"][0]["distance_m"] - 4.08) < 0.01


def test_wrong_template_is_flagged_or_refused(tmp_path):
    """A beep recording ranged with a 17-20 kHz sweep as template (the issue's example of
    a confident wrong answer: 19.58 m, sigma 8.7 mm, exit 0)."""
    wav = _synth(tmp_path, "beep3m", "--distance", 3)
    sweep = tmp_path / "sweep.wav"
    ok(run(["design", "sweep", "--f0", 17000, "--f1", 20000, "--duration", 0.1, "-o", sweep]))
    res = run(["range", wav, "--template", sweep, "--self-distance", 0.1, "--format", "json"])
    if res.exit_code == 0:
        r = json.loads(res.stdout)["ranges"][0]
        assert abs(r["distance_m"] - 3.0) < 0.1 or r["flags"], r
        res = run(["range", wav, "--template", sweep, "--self-distance", 0.1, "--strict"])
        assert res.exit_code in (6, 10)
    else:
        assert res.exit_code == 6
