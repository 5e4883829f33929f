"""``rangekit range --series --jobs N``: the same rows as one job."""

from __future__ import annotations

from clihelp import assert_error, ok, run


def test_series_jobs_rows_equal_one_job(tmp_path):
    out = tmp_path / "s.wav"
    ok(run(["synth", "beepbeep", "--distance", 3, "--exchanges", 6, "--period", 1.2,
            "--mono", "--seed", 2, "-o", out]))  # fmt: skip
    devs = [tmp_path / "s_dev0.wav", tmp_path / "s_dev1.wav"]
    base = ["range", "--series", *devs, "--self-distance", 0.1, "--block", 1.5]
    one = ok(run([*base, "--format", "csv"])).stdout
    two = ok(run([*base, "--jobs", 2, "--format", "csv"])).stdout
    assert two == one and len(one.splitlines()) == 7


def test_jobs_needs_series_beepbeep(tmp_path):
    wav = tmp_path / "x.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--seed", 1, "-o", wav]))
    assert_error(run(["range", wav, "--jobs", 2]), 2, "--jobs", "--series")
    res = run(["range", "--series", "--scheme", "echo", wav, "--period", 0.07, "--jobs", 2])
    assert_error(res, 2, "--jobs")
    assert_error(run(["range", "--series", wav, "--jobs", 0]), 2, "--jobs")
