"""``-`` reads standard input where a recording or an input file is taken."""

from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path

import pytest
from clihelp import assert_error, ok, run

from rangekit.errors import InputFileError
from rangekit.io import guard

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures_audio"
WAV = FIXTURES / "beepbeep_2p5m.wav"


def test_range_from_real_stdin_equals_the_file():
    """A real pipe (a subprocess): the same rows as the file, no sidecar searched."""
    cmd = [sys.executable, "-m", "rangekit"]
    with open(WAV, "rb") as fh:
        piped = subprocess.run([*cmd, "range", "-"], stdin=fh, capture_output=True, check=False)
    assert piped.returncode == 0, piped.stderr
    direct = ok(run(["range", WAV, "--no-setup"]))
    assert piped.stdout.decode() == direct.stdout
    assert piped.stderr.decode().startswith("rangekit: standard input: no sidecar setup")


def test_detect_and_series_from_stdin():
    data = WAV.read_bytes()
    a = ok(run(["detect", "-", "--format", "json"], input=data))
    b = ok(run(["detect", WAV, "--format", "json"]))
    rows_a, rows_b = json.loads(a.stdout)["arrivals"], json.loads(b.stdout)["arrivals"]
    assert [r["file"] for r in rows_a] == ["-"] * len(rows_b)
    for r in (*rows_a, *rows_b):
        r.pop("file")
    assert rows_a == rows_b and len(rows_a) == 4
    s1 = ok(run(["range", "--series", "-", "--format", "csv"], input=data)).stdout
    s2 = ok(run(["range", "--series", WAV, "--format", "csv", "--no-setup"])).stdout
    assert s1 == s2


def test_verbose_says_no_setup_is_searched_for_stdin():
    r = ok(run(["range", "-", "-v"], input=WAV.read_bytes()))
    assert "setup: not searched for standard input" in r.stderr
    # Without --self-distance the default (0 m) is said, after the results.
    assert r.stderr.endswith("the self-distance is 0 m (give --self-distance)\n")
    r = ok(run(["range", "-", "--self-distance", "0.1"], input=WAV.read_bytes()))
    assert r.stderr == ""


def test_one_stdin_per_command():
    assert_error(run(["range", "-", "-"], input=WAV.read_bytes()), 2, "standard input")
    # Worker processes cannot share the one standard input.
    r = run(["range", "--series", "-", "--jobs", "2"], input=WAV.read_bytes())
    assert_error(r, 2, "--jobs", "standard input")


@pytest.mark.parametrize(
    ("data", "code", "words"),
    [
        (b"", 4, "holds no data"),
        (b"hello, not audio\n", 4, "standard input is not a readable audio file"),
    ],
)
def test_bad_stdin_is_one_line(data, code, words):
    assert_error(run(["range", "-"], input=data), code, words)


def test_stdin_over_the_memory_budget_is_refused(monkeypatch):
    # 64 KiB budget: at most 8 KiB of raw bytes; the fixture is ~80 KiB.
    monkeypatch.setenv("RANGEKIT_MEMORY_BUDGET", "64K")  # as --memory-budget 64K sets it
    r = run(["range", "-"], input=WAV.read_bytes())
    line = assert_error(r, 5, "standard input", "8192 bytes", "--series")
    assert "memory budget" in line


def test_read_stdin_refuses_a_terminal_and_keeps_what_it_read(monkeypatch):
    class Tty(io.BytesIO):
        def isatty(self):
            return True

    monkeypatch.setattr(sys, "stdin", Tty(b"x"))
    with pytest.raises(InputFileError, match="terminal"):
        guard.read_stdin(100)
    monkeypatch.setattr(sys, "stdin", io.BytesIO(b"0123456789"))
    with pytest.raises(InputFileError, match="more than the limit of 4 bytes"):
        guard.read_stdin(4)
    assert guard.read_stdin(10) == b"0123456789"  # read on from where it stopped
    assert guard.read_stdin(100) == b"0123456789"  # kept, not read again
    assert guard.is_stdin("-") and guard.is_stdin(Path("-")) and not guard.is_stdin("./-")


#: Rows of `rangekit synth oneway --seed 3` ranged by `range --scheme oneway --format csv`.
RANGES_CSV = """file,window,tx,channel,distance_m,sigma_m,snr_db,arrival_s,flags
ow.wav,0,0,0,2.732812,0.000688,34.561133,0.007961,
ow.wav,0,0,1,2.618124,0.000715,34.562501,0.007626,
ow.wav,0,0,2,2.522644,0.000649,35.165202,0.007348,
ow.wav,1,1,0,2.155125,0.000560,36.511925,0.006278,
ow.wav,1,1,1,2.210546,0.000936,36.107402,0.006439,
ow.wav,1,1,2,2.096145,0.000541,36.934340,0.006106,
ow.wav,2,2,0,2.513414,0.000796,35.238522,0.007321,
ow.wav,2,2,1,2.725772,0.000692,34.527721,0.007940,
ow.wav,2,2,2,2.633049,0.000700,34.479818,0.007670,
"""


def _beacons(tmp_path: Path) -> Path:
    tx = [{"id": i, "x_m": x, "y_m": -0.75, "z_m": 2.011} for i, x in enumerate((-1.5, 0, 1.5))]
    p = tmp_path / "b.json"
    p.write_text(
        json.dumps({"format": "rangekit-beacons", "version": 1, "units": "m", "transmitters": tx})
    )
    return p


def test_locate_reads_ranges_and_distances_from_stdin(tmp_path):
    beacons = _beacons(tmp_path)
    (tmp_path / "r.csv").write_text(RANGES_CSV)
    want = ok(run(["locate", "--beacons", beacons, "--ranges", tmp_path / "r.csv"])).stdout
    got = ok(run(["locate", "--beacons", beacons, "--ranges", "-"], input=RANGES_CSV)).stdout
    assert got == want
    keys = RANGES_CSV.splitlines()[0].split(",")
    rows = [dict(zip(keys, ln.split(","), strict=True)) for ln in RANGES_CSV.splitlines()[1:]]
    for r in rows:
        r.update(tx=int(r["tx"]), channel=int(r["channel"]))
        r.update(distance_m=float(r["distance_m"]), sigma_m=float(r["sigma_m"]))
    js = json.dumps({"ranges": rows})
    assert ok(run(["locate", "--beacons", beacons, "--ranges", "-"], input=js)).stdout == want
    d = "tx,d1_m,d2_m,d3_m\n0,2.7,2.6,2.5\n1,2.1,2.2,2.1\n2,2.5,2.7,2.6\n"
    (tmp_path / "d.csv").write_text(d)
    want = ok(run(["locate", "--beacons", beacons, "--distances", tmp_path / "d.csv"])).stdout
    assert ok(run(["locate", "--beacons", beacons, "--distances", "-"], input=d)).stdout == want
    assert_error(run(["locate", "--beacons", "-", "--ranges", "-"], input=js), 2, "standard")


def test_plot_spectrogram_from_stdin(tmp_path):
    png = tmp_path / "s.png"
    r = ok(run(["plot", "spectrogram", "-", "-o", png], input=WAV.read_bytes()))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and "onset" in r.stderr
