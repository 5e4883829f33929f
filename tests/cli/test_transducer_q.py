"""``--transducer-q`` (range, synth) and its old spelling ``--q``, hidden, kept for a release."""

from __future__ import annotations

from pathlib import Path

import pytest
from clihelp import assert_error, ok, run

NOTE = "rangekit: --q is deprecated and goes in the next release: --transducer-q\n"


def test_old_spelling_gives_the_same_file_with_one_note(tmp_path):
    base = ["synth", "oneway", "--windows", "1", "--seed", "2", "-q"]
    new = ok(run([*base, "--transducer-q", "8", "-o", tmp_path / "a.wav"]))
    old = ok(run([*base, "--q", "8", "-o", tmp_path / "b.wav"]))
    assert new.stderr == "" and old.stderr == NOTE
    assert (tmp_path / "a.wav").read_bytes() == (tmp_path / "b.wav").read_bytes()
    other = ok(run([*base, "--transducer-q", "12", "-o", tmp_path / "c.wav"]))
    assert other.stderr == ""
    assert (tmp_path / "c.wav").read_bytes() != (tmp_path / "a.wav").read_bytes()


def test_both_spellings_is_a_usage_error(tmp_path):
    r = run(["range", "--scheme", "oneway", tmp_path / "x.wav", "--q", "4", "--transducer-q", "4"])
    assert_error(r, 2, "--transducer-q")


@pytest.mark.parametrize("verb", [["range"], ["synth", "oneway"], ["synth", "echo"]])
def test_help_shows_the_new_name_only(verb):
    out = ok(run([*verb, "--help"])).stdout
    assert "--transducer-q" in out and "--q " not in out and "--q," not in out


def test_no_suggestion_of_the_hidden_spelling():
    r = run(["range", "x.wav", "--quite"])
    line = assert_error(r, 2, "--quiet")
    assert "'--q'" not in line
    r = run(["range", "x.wav", "--quiet", "--detector", "nope"])
    assert_error(r, 2, "--detector")  # --quiet is an option now, not "did you mean --q"


BEEP = Path(__file__).resolve().parents[2] / "fixtures_audio" / "beepbeep_2p5m.wav"


@pytest.mark.parametrize("verb", ["range", "batch"])
@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("--transducer-q", "5"),
        ("--code", "13"),
        ("--carrier", "40000"),
        ("--cycles-per-bit", "3"),
        ("--latency", "0.1"),
        ("--min-range", "0.5"),
    ],
)
def test_an_ultrasonic_option_with_the_beep_is_refused_by_its_name(verb, option, value, tmp_path):
    """With --scheme beepbeep (the default) range refused --transducer-q naming the hidden
    '--q', and batch ignored --transducer-q, --code, --carrier and --cycles-per-bit (exit
    0): both refuse every one-way / echo option, by the name --help shows, and write
    nothing."""
    out = ["-o", tmp_path / "out.csv"]
    line = assert_error(run([verb, BEEP, option, value, *out]), 2, option)
    assert "'--q'" not in line and " --q " not in line
    assert list(tmp_path.iterdir()) == []
