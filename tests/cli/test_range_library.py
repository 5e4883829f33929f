"""``rangekit.ranging.run_range``: the same options give the same rows through the library
call and through ``rangekit range`` (the output text compared exactly), and the
configuration objects (``rangekit.ranging.config``) keep the keyword APIs bit-identical."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
import soundfile as sf
from clihelp import assert_error, ok, run

from rangekit.errors import InvalidParameterError, UnreliableResultError
from rangekit.io.audio import load_devices, write_audio
from rangekit.io.results import format_rows
from rangekit.io.stream import RowWriter
from rangekit.physics import speed_of_sound_m_s
from rangekit.ranging import range_channels
from rangekit.ranging.calibration import Calibration
from rangekit.ranging.config import Medium, SeriesOptions, TwoWaySetup
from rangekit.ranging.run import ClockRateCorrection, clock_rate_lines, run_range
from rangekit.signals import Beep, beep_waveform
from rangekit.sim import pair_devices
from rangekit.sim.exchanges import render_exchanges

FS = 44100.0
CAL = Calibration(
    "beepbeep", "offset+speed", offset_m=-0.095, sigma_offset_m=0.002, latency_s=0.095 / 344.0,
    sigma_latency_s=0.002 / 344.0, speed_m_s=344.0, sigma_speed_m_s=0.4, cov_speed_offset=0.0,
    n_recordings=4, distances_m=(1.0, 2.0), rms_residual_m=0.001,
)  # fmt: skip


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """One exchange (stereo, 2 m), a 4-exchange series of two mono files (device 1 at
    +80 ppm), a one-way recording at 8 dB, a calibration file, and a clean then a clipped
    exchange in one file."""
    d = tmp_path_factory.mktemp("run_range")
    one = d / "one.wav"
    ok(run(["synth", "beepbeep", "--seed", 3, "--distance", 2, "-o", one]))
    ow = d / "ow.wav"
    ok(run(["synth", "oneway", "--seed", 1, "--snr-db", 8, "-o", ow]))
    devs = pair_devices(1.2, self_distance_m=0.1, clock_ppm=(0.0, 80.0), rec_start_s=(0, 0.02))
    sim = render_exchanges(
        devs, source=beep_waveform(Beep()), source_fs=FS, n_exchanges=4, period_s=1.5,
        jitter_s=0.1, snr_db=25.0, rng=7,
    )  # fmt: skip
    series = [d / f"dev{i}.wav" for i in range(2)]
    for p, x in zip(series, sim.recordings, strict=True):
        write_audio(p, x, fs=FS)
    cal = d / "cal.json"
    CAL.write(cal)
    clipped = d / "clipped.wav"
    ok(run(["synth", "beepbeep", "--seed", 3, "--distance", 2, "--impair", "clip_db=15", "-o",
            clipped]))  # fmt: skip
    parts = []  # each exchange at full scale per channel, as one converter records both
    for wav in (one, clipped):
        x, fs = sf.read(wav, always_2d=True)
        x = x / np.abs(x).max(axis=0)
        parts.append(np.pad(x, ((0, int(3 * fs) - len(x)), (0, 0))))
    clip = d / "series_clip.wav"
    sf.write(clip, np.concatenate(parts), int(fs), subtype="FLOAT")
    return {"one": one, "ow": ow, "series": series, "cal": cal, "clip": clip}


def _same(job, cli_args, fmt="json"):
    """The CLI's stdout equals the library run's rows in ``fmt``; returns the run."""
    r = run(["range", *cli_args, "--no-setup", "--format", fmt])
    lib = run_range(**job)
    rows = lib.rows()
    kw = {"meta": lib.meta, "key": "ranges"} if fmt == "json" else {}
    assert r.stdout == format_rows(rows, lib.fields, fmt, **kw)
    return lib, r


def test_single_exchange(data):
    job = {"files": [data["one"]], "setup": TwoWaySetup(self_distance_m=0.1)}
    lib, r = _same(job, [data["one"], "--self-distance", 0.1])
    assert r.exit_code == 0 and abs(lib.rows()[0]["distance_m"] - 2.0) < 0.01
    _same({**job, "medium": Medium(temp_c=30.0)}, [data["one"], "--self-distance", 0.1,
          "--temperature", 30], fmt="csv")  # fmt: skip


def test_single_exchange_calibrated(data):
    job = {"files": [data["one"]], "calibration": CAL, "calibration_file": str(data["cal"])}
    lib, _ = _same(job, [data["one"], "--calibration", data["cal"]])
    assert lib.meta["calibration"] == {"file": str(data["cal"]), "model": "offset+speed"}


def test_series_clock_rate_and_calibration(data):
    files = data["series"]
    base = {"files": files, "setup": TwoWaySetup(0.1), "series": SeriesOptions()}
    args = ["--series", *files, "--self-distance", 0.1]
    _same(base, args, fmt="csv")
    lib, r = _same({**base, "clock_rate": ClockRateCorrection()}, [*args, "--clock-rate",
                   "estimate"])  # fmt: skip
    assert abs(lib.clock_rates.ppm[1] - 80.0) < 2.0  # measured 79.20 +- 0.11 (4 exchanges)
    assert r.stderr.splitlines() == clock_rate_lines(lib.clock_rates)
    given = {**base, "clock_rate": ClockRateCorrection(ppm=(80.0,)), "calibration": CAL}
    given["calibration_file"] = str(data["cal"])
    given.pop("setup")
    lib, _ = _same(given, ["--series", *files, "--clock-rate", 80, "--calibration", data["cal"]])
    assert list(lib.meta)[-2:] == ["clock_rate", "calibration"]  # the CLI's key order


def test_oneway_and_strict(data):
    ow = data["ow"]
    job = {"files": [ow], "scheme": "oneway", "ultrasonic": {"period_s": 0.2, "channels": 3}}
    plain, _ = _same(job, ["--scheme", "oneway", ow, "--period", 0.2])
    lib = run_range(**job, strict=True)
    rows = lib.rows()
    kept = [(p, r) for p, r in zip(plain.rows(), rows, strict=True) if "withheld" not in r["flags"]]
    assert 0 < len(kept) < len(rows) and all(p == r for p, r in kept)
    with pytest.raises(UnreliableResultError) as e:
        lib.finish()
    res = run(["range", "--scheme", "oneway", ow, "--period", 0.2, "--no-setup", "--strict",
               "--format", "json"])  # fmt: skip
    assert_error(res, 10, str(e.value))
    assert res.stdout == format_rows(rows, lib.fields, "json", meta=lib.meta, key="ranges")


def test_series_strict_equals_the_cli(data):
    """A clean exchange, then a clipped one: the second is withheld, exit 10 after."""
    job = {"files": [data["clip"]], "setup": TwoWaySetup(0.1), "series": SeriesOptions()}
    lib = run_range(**job, strict=True)
    rows = lib.rows()
    assert [("withheld" in r["flags"]) for r in rows] == [False, True]
    with pytest.raises(UnreliableResultError) as e:
        lib.finish()
    res = run(["range", "--series", data["clip"], "--self-distance", 0.1, "--no-setup",
               "--strict", "--format", "csv"])  # fmt: skip
    assert_error(res, 10, str(e.value))
    assert res.stdout == format_rows(rows, lib.fields, "csv")


def test_keyword_api_builds_the_objects_bit_identical(data):
    chans = load_devices([data["one"]], min_devices=2)
    kw = range_channels(chans, temp_c=25.0, self_distance_m=[0.1, 0.11], clock_ppm=10.0)
    obj = range_channels(
        chans, medium=Medium(temp_c=25.0), setup=TwoWaySetup((0.1, 0.11), clock_ppm=10.0)
    )
    assert kw.ranges == obj.ranges and kw.speed_m_s == obj.speed_m_s
    arr = range_channels(chans, temp_c=25.0, self_distance_m=np.array([0.1, 0.11]), clock_ppm=10.0)
    assert arr.ranges == kw.ranges
    assert TwoWaySetup(np.array([0.1, 0.11])).self_distance_m == (0.1, 0.11)
    assert Medium(temp_c=25.0).c == speed_of_sound_m_s(25.0)
    assert Medium(temp_c=25.0, speed_m_s=350.0).c == 350.0


@pytest.mark.parametrize(
    "make, name",
    [
        (lambda: Medium(speed_m_s=50.0), "speed_m_s"),
        (lambda: Medium(temp_c=np.nan), "temp"),
        (lambda: TwoWaySetup(self_distance_m=3.0), "self_distance_m"),
        (lambda: TwoWaySetup(self_distance_m=(0.1, "x")), "self_distance_m"),
        (lambda: TwoWaySetup(clock_ppm=-1), "clock_ppm"),
        (lambda: SeriesOptions(block_s=0.0), "block_s"),
        (lambda: SeriesOptions(skew_s=-1.0), "skew_s"),
        (lambda: SeriesOptions(jobs=0), "jobs"),
        (lambda: RowWriter(("a",), "xml", None), "fmt"),
        (lambda: run_range(["x.wav"], scheme="radar"), "scheme"),
        (lambda: run_range(["x.wav"], scheme="echo", clock_rate=ClockRateCorrection()), "clock"),
    ],
)
def test_configuration_errors_name_the_value(make, name):
    with pytest.raises(InvalidParameterError, match=name):
        make()


def test_row_writer_streams_csv_and_keeps_a_failed_output(tmp_path):
    out = tmp_path / "o.csv"
    out.write_text("old\n")

    def blocks():
        yield [{"a": 0, "distance_m": 1.0}]
        raise RuntimeError("disk on fire")

    with pytest.raises(RuntimeError):
        RowWriter(("a", "distance_m"), "csv", str(out)).write(blocks(), {})
    assert out.read_text() == "old\n" and sorted(p.name for p in tmp_path.iterdir()) == ["o.csv"]
    buf = io.StringIO()
    RowWriter(("a",), "json", None, stdout=buf).write([[{"a": 1}]], {"scheme": "x"})
    assert json.loads(buf.getvalue()) == {"scheme": "x", "ranges": [{"a": 1}]}
