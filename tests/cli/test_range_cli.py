"""CLI tests of ``rangekit range`` on the shipped fixtures (truth read from their sidecars).

The fixtures may be regenerated at any time: every expected number comes from the
sidecar JSON next to the WAV (``docs/formats.md``), never from this file.
"""

from __future__ import annotations

import csv
import io
import json
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner
from rangekit_cli.main import cli

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures_audio"
TOL_M = 0.01  # every pair within 1 cm of the truth


def _truth(name: str) -> dict:
    return json.loads((FIXTURES / f"{name}.json").read_text(encoding="utf-8"))


def _files(truth: dict) -> list[str]:
    return [str(FIXTURES / f) for f in truth["files"]]


def _truth_args(truth: dict) -> list[str]:
    """Temperature and beep options matching the sidecar (defaults today, robust tomorrow)."""
    b = truth["beep"]
    return [
        "--temperature", repr(truth["temp_c"]),
        "--freq", repr(b["f_hz"]),
        "--bursts", str(b["n_bursts"]),
        "--spacing", str(b["spacing"]),
        "--burst-len", str(b["burst_len"]),
        "--taper", str(b["taper"]),
        "--beep-fs", repr(b["fs"]),
    ]  # fmt: skip


def _true_self(truth: dict) -> list[float]:
    return [d["self_distance_m"] for d in truth["devices"]]


def _expected(truth: dict, self_m: list[float] | float) -> dict[tuple[int, int], float]:
    """True pair distances as `range` should report them with self-distances ``self_m``.

    D_ab = c/2 * (interval difference) + (s_a + s_b) / 2, so a self-distance that differs
    from the true one shifts the result by half the difference per device.
    """
    true_s = _true_self(truth)
    s = [self_m] * len(true_s) if isinstance(self_m, float) else list(self_m)
    return {
        (p["a"], p["b"]): p["distance_m"]
        + 0.5 * ((s[p["a"]] - true_s[p["a"]]) + (s[p["b"]] - true_s[p["b"]]))
        for p in truth["pairs"]
    }


def _sd_arg(self_m: list[float] | float) -> str:
    return repr(self_m) if isinstance(self_m, float) else ",".join(repr(v) for v in self_m)


def _run(args: list[str]):
    return CliRunner().invoke(cli, args, prog_name="rangekit", catch_exceptions=False)


def _run_json(args: list[str]) -> dict:
    r = _run([*args, "--format", "json"])
    assert r.exit_code == 0, r.stderr
    assert r.stderr == ""
    return json.loads(r.stdout)


def _check_ranges(ranges: list[dict], expected: dict[tuple[int, int], float]) -> None:
    assert {(r["a"], r["b"]) for r in ranges} == set(expected)
    assert len(ranges) == len(expected)
    for r in ranges:
        assert set(r) == {"a", "b", "distance_m", "sigma_m", "flags"}
        want = expected[(r["a"], r["b"])]
        assert abs(r["distance_m"] - want) < TOL_M, (r, want)
        assert r["sigma_m"] > 0
        assert r["flags"] == []


# Each case: fixture name, self-distance option (None: the sidecar's per-device values).
CASES = [
    pytest.param("beepbeep_2p5m", 0.1, id="free-field-2dev"),
    pytest.param("beepbeep_room_4p2m", None, id="room-2dev"),
    pytest.param("beepbeep_3dev", None, id="mono-3dev-48k"),
]


@pytest.mark.parametrize(("name", "self_m"), CASES)
def test_range_json_matches_truth(name, self_m):
    truth = _truth(name)
    s = _true_self(truth) if self_m is None else self_m
    out = _run_json(["range", *_files(truth), "--self-distance", _sd_arg(s), *_truth_args(truth)])
    _check_ranges(out["ranges"], _expected(truth, s))
    assert out["scheme"] == "beepbeep"
    assert out["detector"] == "changepoint"
    assert out["files"] == _files(truth)
    assert out["speed_of_sound_m_s"] == pytest.approx(truth["speed_of_sound_m_s"], rel=1e-9)


def test_three_device_fixture_mixes_sample_rates():
    truth = _truth("beepbeep_3dev")
    rates = {d["fs"] for d in truth["devices"]}
    assert len(truth["files"]) == 3
    assert 48000.0 in rates and len(rates) > 1


@pytest.mark.parametrize(("name", "self_m"), CASES)
def test_range_csv_same_numbers_as_json(name, self_m):
    truth = _truth(name)
    s = _true_self(truth) if self_m is None else self_m
    args = ["range", *_files(truth), "--self-distance", _sd_arg(s), *_truth_args(truth)]
    js = _run_json(args)["ranges"]
    r = _run([*args, "--format", "csv"])
    assert r.exit_code == 0, r.stderr
    rows = list(csv.DictReader(io.StringIO(r.stdout)))
    assert list(rows[0]) == ["a", "b", "distance_m", "sigma_m", "flags"]
    assert len(rows) == len(js)
    for row, j in zip(rows, js, strict=True):
        assert (int(row["a"]), int(row["b"])) == (j["a"], j["b"])
        assert float(row["distance_m"]) == pytest.approx(j["distance_m"], abs=1e-6)
        assert float(row["sigma_m"]) == pytest.approx(j["sigma_m"], abs=1e-6)
        assert row["flags"] == ";".join(j["flags"])
    _check_ranges(
        [{**j, "distance_m": float(row["distance_m"])} for row, j in zip(rows, js, strict=True)],
        _expected(truth, s),
    )


def test_range_table_has_header_and_one_row_per_pair():
    truth = _truth("beepbeep_3dev")
    s = _true_self(truth)
    r = _run(["range", *_files(truth), "--self-distance", _sd_arg(s), *_truth_args(truth)])
    assert r.exit_code == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].split() == ["a", "b", "distance_m", "sigma_m", "flags"]
    assert len(lines) == 1 + len(truth["pairs"])
    expected = _expected(truth, s)
    for line in lines[1:]:
        a, b, d, sig, flags = line.split()
        assert abs(float(d) - expected[(int(a), int(b))]) < TOL_M
        assert float(sig) > 0
        assert flags == "-"


def test_output_file_written_and_stdout_empty(tmp_path):
    truth = _truth("beepbeep_2p5m")
    out = tmp_path / "out.json"
    args = ["range", *_files(truth), "--self-distance", "0.1", *_truth_args(truth)]
    r = _run([*args, "--format", "json", "-o", str(out)])
    assert r.exit_code == 0, r.stderr
    assert r.stdout == ""
    assert r.stderr == ""
    _check_ranges(json.loads(out.read_text())["ranges"], _expected(truth, 0.1))
    assert not list(tmp_path.glob(".*.part"))  # no temporary file left behind


def test_speed_of_sound_scales_distances():
    truth = _truth("beepbeep_2p5m")
    c = truth["speed_of_sound_m_s"]
    base = ["range", *_files(truth), "--self-distance", "0.1", *_truth_args(truth)]
    r1 = _run_json([*base, "--speed-of-sound", repr(c)])
    r2 = _run_json([*base, "--speed-of-sound", repr(2 * c)])
    assert r1["speed_of_sound_m_s"] == pytest.approx(c)
    assert r2["speed_of_sound_m_s"] == pytest.approx(2 * c)
    _check_ranges(r1["ranges"], _expected(truth, 0.1))
    for a, b in zip(r1["ranges"], r2["ranges"], strict=True):
        # D = c/2 * interval + mean self-distance: only the acoustic part scales with c.
        assert b["distance_m"] - 0.1 == pytest.approx(2 * (a["distance_m"] - 0.1), rel=1e-6)
        assert b["sigma_m"] > a["sigma_m"]


def test_xcorr_detector_on_free_field_fixture():
    truth = _truth("beepbeep_2p5m")
    args = ["range", *_files(truth), "--self-distance", "0.1", *_truth_args(truth)]
    out = _run_json([*args, "--detector", "xcorr"])
    assert out["detector"] == "xcorr"
    _check_ranges(out["ranges"], _expected(truth, 0.1))


def test_per_device_self_distance_equals_single_value():
    truth = _truth("beepbeep_2p5m")
    base = ["range", *_files(truth), *_truth_args(truth)]
    one = _run_json([*base, "--self-distance", "0.1"])
    per = _run_json([*base, "--self-distance", "0.1,0.1"])
    assert per["ranges"] == one["ranges"]
    _check_ranges(per["ranges"], _expected(truth, [0.1, 0.1]))
    # Unequal per-device values shift the pair by their mean.
    mixed = _run_json([*base, "--self-distance", "0.0,0.2"])
    assert mixed["ranges"][0]["distance_m"] == pytest.approx(
        one["ranges"][0]["distance_m"], abs=1e-9
    )
    _check_ranges(mixed["ranges"], _expected(truth, [0.0, 0.2]))


def test_python_dash_m_rangekit(tmp_path):
    truth = _truth("beepbeep_2p5m")
    args = ["range", *_files(truth), "--self-distance", "0.1", *_truth_args(truth)]
    p = subprocess.run(
        [sys.executable, "-m", "rangekit", *args, "--format", "json"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=60,
        check=False,
    )
    assert p.returncode == 0, p.stderr
    _check_ranges(json.loads(p.stdout)["ranges"], _expected(truth, 0.1))


def test_version():
    from rangekit import __version__

    r = _run(["--version"])
    assert r.exit_code == 0
    assert r.stdout.strip() == f"rangekit, version {__version__}"


@pytest.mark.parametrize(
    "cmd",
    [[], ["range"], ["detect"], ["design"], ["design", "beep"], ["synth"], ["synth", "beepbeep"]],
    ids=lambda c: " ".join(c) or "rangekit",
)
@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_help_of_every_command(cmd, flag):
    r = _run([*cmd, flag])
    assert r.exit_code == 0, r.stderr
    assert r.stdout.startswith(f"Usage: rangekit {' '.join(cmd)}".rstrip())
    assert r.stderr == ""


@pytest.mark.parametrize(
    "cmd", [[], ["design"], ["synth"], ["plot"]], ids=lambda c: " ".join(c) or "rangekit"
)
def test_bare_group_prints_its_help(cmd):
    """A group without its subcommand prints the group's help on stdout, exit 0 (was one
    squashed error line, exit 2)."""
    r = _run(cmd)
    assert r.exit_code == 0, r.stderr
    assert r.stdout == _run([*cmd, "--help"]).stdout
    assert (
        r.stdout.startswith(f"Usage: rangekit {' '.join(cmd)}".rstrip()) and "Commands:" in r.stdout
    )
    assert r.stderr == ""


def test_range_help_lists_stable_options():
    r = _run(["range", "--help"])
    for opt in (
        "--scheme", "--self-distance", "--temperature", "--speed-of-sound", "--clock-ppm",
        "--detector", "--freq", "--bursts", "--spacing", "--burst-len", "--taper",
        "--beep-fs", "--format", "--output", "--debug",
    ):  # fmt: skip
        assert opt in r.stdout, opt
