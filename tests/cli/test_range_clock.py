"""``rangekit range --series --clock-rate``: equals the library, stderr report, errors."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest
from clihelp import assert_error, ok, run

from rangekit.io.audio import write_audio
from rangekit.io.results import format_pm
from rangekit.physics import speed_of_sound_m_s
from rangekit.ranging.clock import correct_series_clock
from rangekit.ranging.series import range_series_beepbeep
from rangekit.signals import Beep, beep_waveform
from rangekit.sim import pair_devices
from rangekit.sim.exchanges import render_exchanges

FS = 44100.0


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Two mono files: 10 exchanges 1.5 s apart, device 1 at +80 ppm; and 2 exchanges."""
    d = tmp_path_factory.mktemp("range_clock")
    devs = pair_devices(1.2, self_distance_m=0.1, clock_ppm=(0.0, 80.0), rec_start_s=(0, 0.02))
    out = {}
    for name, n in (("long", 10), ("short", 2)):
        sim = render_exchanges(
            devs, source=beep_waveform(Beep()), source_fs=FS, n_exchanges=n, period_s=1.5,
            jitter_s=0.1, snr_db=25.0, rng=7,
        )  # fmt: skip
        paths = [d / f"{name}_dev{i}.wav" for i in range(2)]
        for p, x in zip(paths, sim.recordings, strict=True):
            write_audio(p, x, fs=FS)
        out[name] = paths
    return out


def _library(paths, ppm=None):
    items = range_series_beepbeep(paths, self_distance_m=0.1)
    return correct_series_clock(
        items, speed_m_s=speed_of_sound_m_s(20.0), self_distance_m=0.1, ppm=ppm
    )


def test_estimate_json_equals_the_library_and_reports_on_stderr(files):
    args = ["range", "--series", *files["long"], "--self-distance", 0.1, "--format", "json"]
    r = ok(run([*args, "--clock-rate", "estimate"]))
    doc = json.loads(r.stdout)
    fixed, rates = _library(files["long"])
    rows = [row for e in fixed for row in e.rows()]
    assert doc["ranges"] == rows
    assert abs(rates.ppm[1] - 80.0) < 2.0
    meta = doc["clock_rate"]
    assert meta["mode"] == "estimate"
    assert meta["ppm"] == [0.0, rates.ppm[1]] and meta["n_exchanges"] == 10
    lines = r.stderr.splitlines()
    # The digits follow the sigma (two significant): "+80.0 +- 0.0" hid a 0.02 ppm sigma.
    want = (
        f"rangekit: clock rate vs device 0: device 1 "
        f"{format_pm(rates.ppm[1], rates.sigma_ppm[1], sign=True)} ppm "
        f"(10 exchanges over {rates.span_s:.1f} s)"
    )
    assert lines == [want]
    assert f"{rates.sigma_ppm[1]:.2g}".lstrip("0") in lines[0]
    # The correction changed the ranges (by about c/2 x 80 ppm x 0.6 s = 8 mm).
    off = json.loads(ok(run(args)).stdout)["ranges"]
    assert "clock_rate" not in json.loads(ok(run(args)).stdout)
    diff = [a["distance_m"] - b["distance_m"] for a, b in zip(doc["ranges"], off, strict=True)]
    assert np.all(np.array(diff) > 0.005)
    # --clock-rate off is the default.
    assert ok(run([*args, "--clock-rate", "off"])).stdout == ok(run(args)).stdout


def test_known_rates_csv(files):
    args = ["range", "--series", *files["long"], "--self-distance", 0.1, "--format", "csv"]
    r1 = ok(run([*args, "--clock-rate", "80"]))
    r2 = ok(run([*args, "--clock-rate", "0,80"]))
    assert r1.stdout == r2.stdout and r1.stderr == ""
    fixed, _ = _library(files["long"], ppm=[80.0])
    got = list(csv.DictReader(io.StringIO(r1.stdout)))
    want = [row for e in fixed for row in e.rows()]
    assert len(got) == len(want) == 10
    for g, w in zip(got, want, strict=True):
        assert float(g["distance_m"]) == pytest.approx(w["distance_m"], abs=1e-6)
        assert float(g["t_s"]) == pytest.approx(w["t_s"], abs=1e-6)


def test_errors(files):
    long, short = files["long"], files["short"]
    r = run(["range", *long, "--clock-rate", "estimate"])
    assert_error(r, 2, "--clock-rate", "--series")
    r = run(["range", "--series", "--scheme", "echo", long[0], "--period", 0.07,
             "--clock-rate", "estimate"])  # fmt: skip
    assert_error(r, 2, "--clock-rate", "--scheme beepbeep")
    r = run(["range", "--series", *long, "--clock-rate", "fast"])
    assert_error(r, 2, "--clock-rate", "'fast'")
    r = run(["range", "--series", *long, "--clock-rate", "1,2,3"])
    assert_error(r, 5, "3 clock rate(s)", "2 devices")
    r = run(["range", "--series", *short, "--self-distance", 0.1, "--clock-rate", "estimate"])
    assert_error(r, 5, "at least 3 exchanges, got 2")
