"""The ultrasonic schemes on the command line: design, synth, range, and their errors.

Exit codes as in ``docs/cli.md``: 2 usage/parameter, 3 missing file, 5 incompatible input
(sample rate, channel count), 6 no burst found.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from click.testing import CliRunner
from rangekit_cli.main import cli

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures_audio"
PLAN = FIXTURES / "corridor_plan.json"


def _run(args):
    return CliRunner().invoke(cli, [str(a) for a in args], prog_name="rangekit")


def _assert_error(result, code: int, *names: str) -> None:
    assert result.exit_code == code, (result.exit_code, result.stderr, result.exception)
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("rangekit: error: "), result.stderr
    assert "Traceback" not in result.stderr
    for n in names:
        assert n in lines[0], (n, lines[0])


def test_design_barker_writes_the_drive(tmp_path):
    out = tmp_path / "barker.wav"
    r = _run(["design", "barker", "-o", out])
    assert r.exit_code == 0, r.stderr
    x, fs = sf.read(out)
    assert fs == 192000 and len(x) == 101
    # 7 chips of 3 cycles: the sign flips where the Barker code changes sign.
    assert abs(np.max(np.abs(x)) - 0.9) < 1e-3


def test_design_barker_refuses_low_rate_and_bad_code(tmp_path):
    _assert_error(_run(["design", "barker", "--fs", 96000, "-o", tmp_path / "b.wav"]), 2, "96000")
    _assert_error(_run(["design", "barker", "--code", 6, "-o", tmp_path / "b.wav"]), 2, "--code")
    _assert_error(_run(["design", "barker", "--code", "+x", "-o", tmp_path / "b.wav"]), 2, "+x")
    assert not (tmp_path / "b.wav").exists()


@pytest.fixture(scope="module")
def oneway(tmp_path_factory):
    d = tmp_path_factory.mktemp("ow")
    out = d / "ow.wav"
    r = _run(
        ["synth", "oneway", "--pose", "0.3,-0.2,40", "--period", 0.05, "--latency", 0.002,
         "--seed", 3, "-o", out]
    )  # fmt: skip
    assert r.exit_code == 0, r.stderr
    return out, json.loads(out.with_suffix(".json").read_text())


def test_oneway_end_to_end(oneway):
    wav, truth = oneway
    r = _run(
        ["range", "--scheme", "oneway", wav, "--period", 0.05, "--latency", 0.002,
         "--tx-order", "0,1,2,3,4,5", "--format", "json"]
    )  # fmt: skip
    assert r.exit_code == 0, r.stderr
    rows = json.loads(r.stdout)["ranges"]
    assert len(rows) == 6 * 3
    for row in rows:
        w = truth["windows"][row["window"]]
        assert row["tx"] == w["tx"]
        assert abs(row["distance_m"] - w["distances_m"][row["channel"]]) < 2e-3
        assert 0 < row["sigma_m"] < 2e-3
        assert set(row) >= {"channel", "distance_m", "sigma_m", "window", "tx"}


def test_oneway_without_latency_is_biased_by_it(oneway):
    wav, truth = oneway
    # --no-setup: the sidecar's setup would give the 2 ms latency (as below).
    args = ["range", "--scheme", "oneway", wav, "--period", 0.05, "--format", "json"]
    row = json.loads(_run([*args, "--no-setup"]).stdout)["ranges"][0]
    bias = row["distance_m"] - truth["windows"][0]["distances_m"][0]
    assert abs(bias - 0.002 * truth["speed_of_sound_m_s"]) < 2e-3
    r = _run(args)
    row = json.loads(r.stdout)["ranges"][0]
    assert abs(row["distance_m"] - truth["windows"][0]["distances_m"][0]) < 2e-3
    assert r.stderr.splitlines()[-1].startswith("rangekit: used the setup in")
    assert "--latency 0.002" in r.stderr


def test_echo_end_to_end_and_out_of_range(tmp_path):
    out = tmp_path / "echo.wav"
    # Facing the corridor's side walls (y = 0 and y = 2) from y = 0.7, and the far end wall
    # (x = 10) from 3.5 m and 6.5 m away (out of range), and a wall 0.1 m away (ring-down).
    poses = ["1,0.7,90", "1,0.7,-90", "6.5,1,0", "3.5,1,0", "9.9,1,0"]
    args = ["synth", "echo", "--map", PLAN, "--seed", 4, "-o", out]
    for p in poses:
        args += ["--pose", p]
    r = _run(args)
    assert r.exit_code == 0, r.stderr
    truth = json.loads(out.with_suffix(".json").read_text())
    r = _run(["range", "--scheme", "echo", out, "--period", 0.07, "--format", "json"])
    assert r.exit_code == 0, r.stderr
    rows = json.loads(r.stdout)["ranges"]
    assert [w["distance_m"] is None for w in truth["windows"]] == [
        False, False, False, True, True,
    ]  # fmt: skip
    for row, w in zip(rows, truth["windows"], strict=True):
        if w["distance_m"] is None:
            assert row["distance_m"] is None and row["sigma_m"] is None
        else:
            assert abs(row["distance_m"] - w["distance_m"]) < 0.01
            assert "tx" not in row


def test_range_errors(tmp_path, oneway):
    wav, _ = oneway
    low = tmp_path / "low_rate.wav"
    sf.write(low, np.zeros((4800, 3)), 48000)
    _assert_error(_run(["range", "--scheme", "oneway", low]), 5, "low_rate.wav", "48000")
    noise = tmp_path / "no_burst.wav"
    sf.write(noise, 0.01 * np.random.default_rng(0).standard_normal((9600, 3)), 192000)
    _assert_error(_run(["range", "--scheme", "oneway", noise]), 6, "no_burst.wav")
    two = tmp_path / "two_channels.wav"
    sf.write(two, np.zeros((9600, 2)), 192000)
    _assert_error(_run(["range", "--scheme", "oneway", two]), 5, "two_channels.wav", "3")
    _assert_error(_run(["range", "--scheme", "echo", wav, "--latency", 1]), 2, "--latency")
    _assert_error(_run(["range", "--scheme", "oneway", wav, "--freq", 1000]), 2, "--freq")
    _assert_error(_run(["range", wav, "--period", 0.2]), 2, "--period")
    _assert_error(_run(["range", "--scheme", "oneway", wav, "--tx-order", "1.5"]), 2, "--tx-order")
    _assert_error(_run(["range", "--scheme", "oneway", tmp_path / "nope.wav"]), 3, "nope.wav")


def test_failed_run_keeps_existing_output(tmp_path):
    out = tmp_path / "results.json"
    out.write_text("keep me")
    two = tmp_path / "two.wav"
    sf.write(two, np.zeros((9600, 2)), 192000)
    _assert_error(_run(["range", "--scheme", "oneway", two, "-o", out]), 5, "two.wav")
    assert out.read_text() == "keep me"


def test_synth_echo_map_errors(tmp_path):
    _assert_error(
        _run(["synth", "echo", "--map", tmp_path / "none.json", "--pose", "0,0,0", "-o",
              tmp_path / "e.wav"]),
        3,
        "none.json",
    )  # fmt: skip
    bad = tmp_path / "bad_plan.json"
    bad.write_text(json.dumps({"format": "rangekit-floorplan", "version": 1, "walls": "x"}))
    r = _run(["synth", "echo", "--map", bad, "--pose", "0,0,0", "-o", tmp_path / "e.wav"])
    assert r.exit_code in (2, 3), r.stderr
    assert "bad_plan.json" in r.stderr
    _assert_error(
        _run(["synth", "echo", "--map", PLAN, "--pose", "1,1", "-o", tmp_path / "e.wav"]),
        2,
        "--pose",
    )
    assert not (tmp_path / "e.wav").exists()


def test_oneway_unknown_q_is_fitted_and_flags_are_a_column(tmp_path):
    """A recording through Q 15 transducers (``synth --q 15``, 20 dB, one window per Tx):
    the default ``--transducer-q auto`` ranges it within 4 mm and 3.5 sigma (measured: within 2.8 mm
    and 2.8 sigma), ``--transducer-q 4`` (the template assumed known, the old default) is biased by
    +25 to +30 mm at a sigma of 0.4 mm. Every output format carries the arrival flags,
    last."""
    out = tmp_path / "q15.wav"
    r = _run(["synth", "oneway", "--pose", "0.3,-0.2,40", "--period", 0.05, "--transducer-q", 15,
              "--seed", 8, "-o", out])  # fmt: skip
    assert r.exit_code == 0, r.stderr
    truth = json.loads(out.with_suffix(".json").read_text())
    base = ["range", "--scheme", "oneway", out, "--period", 0.05, "--tx-order", "0,1,2,3,4,5"]
    for q in ([], ["--transducer-q", "auto"], ["--transducer-q", 4]):
        r = _run([*base, *q, "--format", "json"])
        assert r.exit_code == 0, r.stderr
        for row in json.loads(r.stdout)["ranges"]:
            w = truth["windows"][row["window"]]
            err = row["distance_m"] - w["distances_m"][row["channel"]]
            if q == ["--transducer-q", 4]:
                assert 0.02 < err < 0.035
            else:
                assert abs(err) < min(4e-3, 3.5 * row["sigma_m"])
            assert row["flags"] == []
            assert list(row)[-1] == "flags"
    r = _run([*base, "--format", "csv"])
    assert r.stdout.splitlines()[0].endswith(",arrival_s,flags")
    r = _run(base)
    header = r.stdout.splitlines()[0].split()
    assert header[-2:] == ["arrival_s", "flags"]
    assert r.stdout.splitlines()[1].split()[-1] == "-"
    _assert_error(_run([*base, "--transducer-q", "high"]), 2, "--transducer-q")
