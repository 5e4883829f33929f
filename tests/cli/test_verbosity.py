"""``--quiet`` / ``--verbose`` on every verb (``rangekit_cli._options.verbosity_options``)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from clihelp import assert_error, ok, run

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures_audio"

#: Every verb (and group subcommand) that takes the two flags.
VERBS = [
    ["design", "beep"],
    ["design", "barker"],
    ["design", "sweep"],
    ["synth", "beepbeep"],
    ["synth", "oneway"],
    ["synth", "echo"],
    ["range"],
    ["detect"],
    ["locate"],
    ["calibrate"],
    ["experiment"],
    ["plot", "spectrogram"],
    ["plot", "matched"],
    ["plot", "ranges"],
    ["plot", "track"],
    ["plot", "cdf"],
]


@pytest.mark.parametrize("verb", VERBS, ids=" ".join)
def test_every_verb_has_quiet_and_verbose(verb):
    out = ok(run([*verb, "--help"])).stdout
    assert "-q, --quiet" in out and "-v, --verbose" in out


def test_quiet_and_verbose_together_is_a_usage_error(tmp_path):
    assert_error(run(["design", "beep", "-o", tmp_path / "b.wav", "-q", "-v"]), 2, "--quiet")
    assert not (tmp_path / "b.wav").exists()


def test_quiet_drops_the_note_verbose_keeps_it(tmp_path):
    r = ok(run(["design", "beep", "-o", tmp_path / "a.wav"]))
    assert r.stderr.startswith("wrote ")
    assert ok(run(["design", "beep", "-o", tmp_path / "b.wav", "--quiet"])).stderr == ""
    assert (tmp_path / "a.wav").read_bytes() == (tmp_path / "b.wav").read_bytes()


def test_range_quiet_drops_the_setup_note_not_the_results(tmp_path):
    wav = tmp_path / "x.wav"
    ok(run(["synth", "beepbeep", "--distance", "2", "--seed", "1", "-o", wav, "-q"]))
    normal = ok(run(["range", wav]))
    assert "used the setup" in normal.stderr
    quiet = ok(run(["range", wav, "-q"]))
    assert quiet.stderr == "" and quiet.stdout == normal.stdout
    verbose = ok(run(["range", wav, "--verbose"]))
    assert verbose.stdout == normal.stdout
    lines = verbose.stderr.splitlines()
    assert any("detector changepoint" in s and "temperature 20 C" in s for s in lines), lines
    assert lines[-1] == normal.stderr.splitlines()[-1]  # the setup note, after the results
    nosetup = ok(run(["range", wav, "-v", "--no-setup"])).stderr
    assert "setup: not read (--no-setup)" in nosetup


def test_verbose_says_when_no_setup_is_found(tmp_path):
    shutil.copy(FIXTURES / "beepbeep_2p5m.wav", tmp_path / "x.wav")
    err = ok(run(["range", tmp_path / "x.wav", "-v"])).stderr
    assert "no sidecar" in err
    assert ok(run(["detect", tmp_path / "x.wav", "-v"])).stderr.startswith(
        "rangekit: detect: the beep by changepoint"
    )


def test_quiet_keeps_errors(tmp_path):
    assert_error(run(["range", tmp_path / "missing.wav", "-q"]), 3, "missing.wav")


def test_progress_is_off_when_quiet_or_off_a_terminal(monkeypatch):
    import io
    import math

    import click
    from rangekit_cli._options import VERBOSITY_KEY, progress

    class Tty(io.StringIO):
        def isatty(self):
            return True

    for level, tty, on in ((0, False, False), (1, False, True), (0, True, True), (-1, True, False)):
        monkeypatch.setattr("sys.stderr", Tty() if tty else io.StringIO())
        with click.Context(click.Command("x")) as ctx:
            ctx.meta[VERBOSITY_KEY] = level
            bar = progress(10, "x", unit="files")
        assert math.isfinite(bar.interval_s) == on, (level, tty)


def test_verbose_names_the_seed_and_the_locate_inputs(tmp_path):
    import json

    err = ok(run(["synth", "beepbeep", "--distance", "1", "-o", tmp_path / "a.wav", "-v"])).stderr
    assert "rangekit: synth: no --seed: fresh randomness, not reproducible" in err
    err = ok(run(["synth", "beepbeep", "--distance", "1", "--seed", "4", "-o",
                  tmp_path / "b.wav", "-v"])).stderr  # fmt: skip
    assert "rangekit: synth: seed 4\n" in err
    tx = [{"id": i, "x_m": x, "y_m": -0.75, "z_m": 2.011} for i, x in enumerate((-1.5, 0, 1.5))]
    b = tmp_path / "b.json"
    b.write_text(json.dumps({"format": "rangekit-beacons", "version": 1, "units": "m",
                             "transmitters": tx}))  # fmt: skip
    args = ["locate", "--beacons", b, "--tx", "0:2.73,2.62,2.52", "--tx", "2:2.51,2.73,2.63"]
    r = ok(run([*args, "-v", "--sigma", "0.002"]))
    assert r.stderr == (
        "rangekit: locate: 2 transmitters (0, 2) from --tx, method hybrid, distance sigma 0.002 m\n"
    )
    assert ok(run([*args, "-q"])).stderr == ""
