"""``rangekit synth beepbeep --template``: simulate the probe a lab plays, range it back."""

from __future__ import annotations

import json

import pytest
from clihelp import assert_error, ok, run


@pytest.fixture
def sweep(tmp_path):
    out = tmp_path / "sweep.wav"
    ok(run(["design", "sweep", "--f0", 2000, "--f1", 6000, "--duration", 0.1, "-o", out]))
    return out


def test_synth_with_a_probe_ranges_back_with_the_same_probe(tmp_path, sweep):
    wav = tmp_path / "sw.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--template", sweep, "--seed", 1, "-o", wav]))
    truth = json.loads(wav.with_suffix(".json").read_text())
    assert truth["beep"]["probe"].endswith("sweep.wav") and truth["beep"]["n_samples"] == 4410
    args = ["range", wav, "--template", sweep, "--self-distance", 0.1, "--format", "json"]
    r = json.loads(ok(run(args)).stdout)["ranges"][0]
    # measured 1.999860 m, sigma 2.55 mm
    assert abs(r["distance_m"] - 2.0) < 2 * r["sigma_m"] and r["sigma_m"] < 0.005
    assert r["flags"] == []
    # The beep does not find the sweep: the probe is what was played.
    assert run(["range", wav, "--self-distance", 0.1]).exit_code == 6


@pytest.mark.parametrize(
    "cmd",
    [
        ["synth", "beepbeep", "--distance", 2],
        ["range", "REC"],
        ["detect", "REC"],
        ["calibrate", "REC@1", "REC@1", "REC@2"],
    ],
    ids=lambda c: c[0],
)
def test_beep_options_with_a_template_are_a_usage_error(tmp_path, sweep, cmd):
    rec = tmp_path / "rec.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--seed", 1, "-o", rec]))
    cmd = [str(c).replace("REC", str(rec)) for c in cmd]
    out = tmp_path / "out.wav"
    res = run(
        [
            *cmd,
            "--template",
            sweep,
            "--spacing",
            4000,
            *(["-o", out] if cmd[0] in ("synth", "calibrate") else []),
        ]
    )
    assert_error(res, 2, "--spacing", "--template")
    assert not out.exists()
