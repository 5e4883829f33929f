"""The setup in a synth sidecar: ``range`` takes what a user would have given, never the
truth (issue 19: the "Typical use" of ``rangekit --help`` was 10 cm short)."""

from __future__ import annotations

import json

import pytest
from clihelp import assert_error, ok, run

from rangekit.errors import InputFileError
from rangekit.io.setup import find_setup, parse_setup


def _range(*args):
    res = ok(run(["range", *args, "--format", "json"]))
    return json.loads(res.stdout)["ranges"][0], res.stderr


def test_typical_use_gives_the_truth(tmp_path):
    """`rangekit synth beepbeep --distance 2 -o x.wav && rangekit range x.wav`."""
    wav = tmp_path / "x.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--seed", 1, "-o", wav]))
    setup = json.loads(wav.with_suffix(".json").read_text())["setup"]
    assert setup == {
        "scheme": "beepbeep", "self_distance_m": [0.1, 0.1], "temp_c": 20.0,
        "signal": {"beep": setup["signal"]["beep"]},
    }  # fmt: skip
    r, err = _range(wav)
    assert abs(r["distance_m"] - 2.0) < 2 * r["sigma_m"]  # was 1.898 m
    assert err.splitlines()[-1] == (
        f"rangekit: used the setup in '{wav.with_suffix('.json')}': --self-distance 0.1,0.1 "
        "--temperature 20 (--no-setup to ignore it)"
    )
    plain, err = _range(wav, "--no-setup")
    assert plain["distance_m"] == pytest.approx(r["distance_m"] - 0.1, abs=1e-9)
    assert "setup" not in err
    given, err = _range(wav, "--self-distance", 0.05)  # an option given wins
    assert given["distance_m"] == pytest.approx(r["distance_m"] - 0.05, abs=1e-9)
    assert "--self-distance" not in err and "--temperature 20" in err
    warm, _ = _range(wav, "--temperature", 30)
    assert warm["distance_m"] != r["distance_m"]


def test_mono_files_and_series_find_the_shared_sidecar(tmp_path):
    out = tmp_path / "s.wav"
    ok(run(["synth", "beepbeep", "--distance", 3, "--exchanges", 3, "--period", 1.5, "--mono",
            "--seed", 2, "-o", out]))  # fmt: skip
    devs = [tmp_path / "s_dev0.wav", tmp_path / "s_dev1.wav"]
    assert find_setup(devs).self_distance_m == (0.1, 0.1)
    assert find_setup(devs[::-1]) is None  # the sidecar names them in device order
    res = ok(run(["range", "--series", *devs, "--format", "csv"]))
    d = [float(line.split(",")[3]) for line in res.stdout.splitlines()[1:]]
    assert len(d) == 3 and all(abs(v - 3.0) < 0.02 for v in d)


def test_a_sidecar_for_other_files_is_not_used(tmp_path):
    wav = tmp_path / "x.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--seed", 1, "-o", wav]))
    other = tmp_path / "y.wav"
    other.write_bytes(wav.read_bytes())
    (tmp_path / "y.json").write_text(wav.with_suffix(".json").read_text())  # names x.wav
    r, err = _range(other)
    assert r["distance_m"] == pytest.approx(1.9, abs=0.02) and "setup" not in err


@pytest.mark.parametrize(
    ("setup", "field"),
    [
        ({"scheme": "beepbeep", "self_distance_m": True}, "self_distance_m"),
        ({"scheme": "beepbeep", "self_distance_m": [0.1, 5.0]}, "self_distance_m"),
        ({"scheme": "beepbeep", "temp_c": "20"}, "temp_c"),
        ({"scheme": "beepbeep", "temp_c": 1e300}, "temp_c"),
        ({"scheme": "oneway", "tx_order": [0, -1]}, "tx_order"),
        ({"scheme": "twoway"}, "scheme"),
        ([1, 2], "object"),
    ],
)
def test_a_malformed_setup_is_refused(tmp_path, setup, field):
    with pytest.raises(InputFileError, match=field):
        parse_setup(setup, name="s.json")
    wav = tmp_path / "x.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--seed", 1, "-o", wav]))
    side = wav.with_suffix(".json")
    obj = json.loads(side.read_text())
    obj["setup"] = setup
    side.write_text(json.dumps(obj))
    assert_error(run(["range", wav]), 3, "x.json", field)
    assert ok(run(["range", wav, "--no-setup"]))


def test_oneway_setup_gives_period_latency_and_ids(tmp_path):
    wav = tmp_path / "ow.wav"
    ok(run(["synth", "oneway", "--latency", 0.003, "--period", 0.1, "--seed", 3, "-o", wav]))
    truth = json.loads(wav.with_suffix(".json").read_text())
    res = ok(run(["range", "--scheme", "oneway", wav, "--format", "json"]))
    rows = json.loads(res.stdout)["ranges"]
    assert [r["tx"] for r in rows[:6:3]] == [0, 1]  # ids from the setup's tx_order
    err = abs(rows[0]["distance_m"] - truth["windows"][0]["distances_m"][0])
    assert err < 3 * rows[0]["sigma_m"]  # the 3 ms latency (1 m) came from the setup
    assert "--period 0.1 --latency 0.003 --tx-order 0,1,2,3,4,5" in res.stderr
