"""``rangekit range --series``: streamed CSV, atomic -o, formats, errors, progress."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from clihelp import assert_error, ok, run
from rangekit_cli._progress import Progress

from rangekit.io.stream import RowWriter
from rangekit.ranging.run import SeriesRows
from rangekit.ranging.series import SERIES_FIELDS, ExchangeRanges, WindowRanges
from rangekit.ranging.ultrasonic import ToF
from rangekit.sim.recording import pair_devices, render_beepbeep
from rangekit.types import Range

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures_audio"
FS = 44100
PERIOD = int(2.5 * FS)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A 6-exchange phone log (exchange 3 lacks device 1's beep on device 1) and an echo log."""
    d = tmp_path_factory.mktemp("series_cli")
    sim = render_beepbeep(pair_devices(2.0, self_distance_m=0.1), snr_db=None)
    one = np.stack(sim.recordings, axis=1)
    on = int(sim.onsets[1, 1])
    rng = np.random.default_rng(0)
    with sf.SoundFile(d / "log.wav", "w", FS, 2, "PCM_16") as f:
        for k in range(6):
            t = np.zeros((PERIOD, 2))
            t[: len(one)] = one
            if k == 3:
                t[on - 100 : on + 16000, 1] = 0.0
            f.write(t + 2e-3 * rng.standard_normal(t.shape))
    from rangekit.floorplan import FloorPlan
    from rangekit.sim.ultrasonic import render_echo

    plan = FloorPlan.from_walls([((1.5, -5), (1.5, 5)), ((-9, -5), (-9, 5))])
    x = render_echo(plan, [(0.0, 0.0, 0.0)] * 12, snr_db=20, rng=1).x[0]
    sf.write(d / "echo.wav", 0.5 * x / np.max(np.abs(x)), 192000, "PCM_16")
    return d


def _csv(text: str) -> list[dict]:
    return list(csv.DictReader(io.StringIO(text)))


def test_beepbeep_series_csv_on_stdout(files):
    r = ok(run(["range", "--series", files / "log.wav", "--self-distance", 0.1, "--format",
                "csv", "--block", 1.7]))  # fmt: skip
    lines = r.stdout.splitlines()
    assert lines[0] == "t_s,a,b,distance_m,sigma_m,flags" == ",".join(SERIES_FIELDS["beepbeep"])
    rows = _csv(r.stdout)
    assert len(rows) == 6
    t = [float(row["t_s"]) for row in rows]
    assert np.allclose(np.diff(t), 2.5, atol=1e-4)
    for k, row in enumerate(rows):
        if k == 3:
            assert (row["distance_m"], row["sigma_m"], row["flags"]) == ("", "", "detection")
        else:
            assert abs(float(row["distance_m"]) - 2.0) < 0.01 and row["flags"] == ""
    # One summary line on stderr counts the failure and says why.
    assert "1 of 6 exchanges failed detection" in r.stderr
    assert "log.wav#1' has 1 beep(s)" in r.stderr


def test_output_file_is_the_stdout_text_and_appears_whole(files, tmp_path):
    args = ["range", "--series", files / "log.wav", "--self-distance", 0.1, "--format", "csv"]
    text = ok(run(args)).stdout
    out = tmp_path / "ranges.csv"
    r = ok(run([*args, "-o", out]))
    assert r.stdout == ""
    assert out.read_text() == text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ranges.csv"]


def test_failure_leaves_no_file_and_keeps_the_old_one(tmp_path):
    noise = tmp_path / "noise.wav"
    sf.write(noise, 1e-3 * np.random.default_rng(1).standard_normal((3 * FS, 2)), FS)
    out = tmp_path / "ranges.csv"
    out.write_text("old\n")
    r = run(["range", "--series", noise, "--format", "csv", "-o", out, "--block", 1])
    assert_error(r, 6, "noise.wav#0", "no beep found")
    assert out.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["noise.wav", "ranges.csv"]


def test_csv_rows_are_written_per_block_before_the_series_ends(tmp_path):
    """Streaming: a block's rows are in the file when its progress call returns; a failure
    later removes the partial file."""
    out = tmp_path / "s.csv"
    sink = RowWriter(SERIES_FIELDS["echo"], "csv", str(out))
    seen = []

    def items():
        for k in range(3):
            tof = ToF(k, None, 0, 1.0 + k, 1e-3, 30.0, 0.01)
            yield WindowRanges(k, 0.07 * k, (tof,))
            sink.progress(0.07 * (k + 1), 0.21)
            (part,) = tmp_path.glob(".s.csv.*.part")  # exclusive, random name
            seen.append(part.read_text())
        raise RuntimeError("disk on fire")

    with pytest.raises(RuntimeError, match="disk on fire"):
        sink.write(SeriesRows(items(), scheme="echo"), {})
    assert seen[0].splitlines() == [
        "t_s,window,channel,distance_m,sigma_m,snr_db,arrival_s",
        "0.000000,0,0,1.000000,0.001000,30.000000,0.010000",
    ]
    assert len(seen[2].splitlines()) == 4
    assert not out.exists() and not list(tmp_path.iterdir())


def test_json_and_table_formats(files):
    base = ["range", "--series", files / "log.wav", "--self-distance", 0.1]
    obj = json.loads(ok(run([*base, "--format", "json"])).stdout)
    assert obj["scheme"] == "beepbeep" and obj["series"] is True
    assert obj["detector"] == "changepoint" and obj["files"] == [str(files / "log.wav")]
    assert obj["speed_of_sound_m_s"] == pytest.approx(343.29, abs=0.01)
    assert len(obj["ranges"]) == 6
    assert list(obj["ranges"][0]) == list(SERIES_FIELDS["beepbeep"])
    assert obj["ranges"][3]["distance_m"] is None and obj["ranges"][3]["flags"] == ["detection"]
    table = ok(run(base)).stdout.splitlines()
    assert table[0].split() == list(SERIES_FIELDS["beepbeep"])
    assert len(table) == 7
    assert table[4].split()[3:] == ["-", "-", "detection"]


def test_series_matches_the_whole_file_command_on_one_exchange():
    wav = FIXTURES / "beepbeep_2p5m.wav"
    whole = _csv(ok(run(["range", wav, "--self-distance", 0.1, "--format", "csv"])).stdout)
    series = _csv(
        ok(run(["range", "--series", wav, "--self-distance", 0.1, "--format", "csv"])).stdout
    )
    assert len(whole) == len(series) == 1
    for k in ("a", "b", "distance_m", "sigma_m", "flags"):
        assert series[0][k] == whole[0][k]


def test_echo_series_matches_the_whole_file_command(files):
    wav = files / "echo.wav"
    base = ["range", "--scheme", "echo", wav, "--period", 0.07, "--format", "csv"]
    whole = _csv(ok(run(base)).stdout)
    r = ok(run([*base, "--series", "--block", 0.2]))
    series = _csv(r.stdout)
    assert r.stdout.splitlines()[0] == ",".join(SERIES_FIELDS["echo"])
    assert len(series) == len(whole) == 12
    for k, (s, w) in enumerate(zip(series, whole, strict=True)):
        assert float(s["t_s"]) == pytest.approx(0.07 * k)
        assert (s["window"], s["channel"]) == (w["window"], w["channel"])
        # The transducer fit pools (Q, f0) over the cycles ranged together: a block's in
        # the series, the file's otherwise, so the ranges agree within their sigma.
        if w["distance_m"]:
            tol = 2.0 * max(float(s["sigma_m"]), float(w["sigma_m"]))
            assert float(s["distance_m"]) == pytest.approx(float(w["distance_m"]), abs=tol)
        else:
            assert not s["distance_m"]
    assert abs(float(series[0]["distance_m"]) - 1.5) < 0.01


def test_oneway_series_has_the_tx_column(tmp_path):
    wav = tmp_path / "ow.wav"
    ok(run(["synth", "oneway", "--pose", "0.3,-0.2,40", "--period", 0.05, "--seed", 3,
            "-o", wav]))  # fmt: skip
    r = ok(run(["range", "--scheme", "oneway", "--series", wav, "--period", 0.05,
                "--tx-order", "4,5", "--format", "csv"]))  # fmt: skip
    assert r.stdout.splitlines()[0] == ",".join(SERIES_FIELDS["oneway"])
    rows = _csv(r.stdout)
    assert [row["tx"] for row in rows[:6]] == ["4", "4", "4", "5", "5", "5"]


@pytest.mark.parametrize(
    ("args", "names"),
    [
        (["--block", 5], ["--block", "--series"]),
        (["--skew", 0.2], ["--skew", "--series"]),
        (["--series", "--scheme", "echo", "--period", 0.07, "--exchange", 1], ["--exchange"]),
        (["--series", "--scheme", "echo"], ["--period"]),
        (["--series", "--block", 0], ["--block"]),
    ],
)
def test_usage_errors(files, args, names):
    assert_error(run(["range", files / "log.wav", *args]), 2, *names)


def test_ultrasonic_series_takes_one_file(files):
    wav = files / "echo.wav"
    r = run(["range", "--series", "--scheme", "echo", wav, wav, "--period", 0.07])
    assert_error(r, 2, "one FILE")


# --- Progress ----------------------------------------------------------------------------


def _clock(times):
    it = iter(times)
    return lambda: next(it)


def test_progress_plain_prints_nothing_for_a_short_run():
    out = io.StringIO()
    p = Progress(10, "range", unit="s", stream=out, tty=False, clock=_clock([0.0, 1.0, 2.0, 3.0]))
    p.update(5)
    p.update(5)
    p.close()
    assert out.getvalue() == ""


def test_progress_plain_lines_with_rate_and_eta():
    out = io.StringIO()
    p = Progress(
        3, "batch", unit="files", stream=out, tty=False, interval_s=10.0,
        clock=_clock([0.0, 12.0, 15.0, 30.0, 31.0]),
    )  # fmt: skip
    p.update()
    p.update()  # 3 s after the last line: no line
    p.update()
    p.close()
    p.close()  # idempotent
    assert out.getvalue().splitlines() == [
        "batch: 33.3% (1/3 files), 0.0833 files/s, ETA 0:24",
        "batch: 100.0% (3/3 files), 0.1 files/s, ETA 0:00",
        "batch: 100.0% (3/3 files), 0.0968 files/s, done in 0:31",
    ]


def test_progress_on_a_terminal_rewrites_one_line():
    out = io.StringIO()
    p = Progress(3600, "range", unit="s", stream=out, tty=True, clock=_clock([0.0, 1.0, 2.0, 3.0]))
    assert p.interval_s == 0.2
    p.update(1800.0)
    p.update(1800.0)
    p.close()
    text = out.getvalue()
    assert text.startswith("\rrange: 50.0% (1800/3600 s), 1800 s/s, ETA 0:01")
    assert text.count("\r") == 3 and text.endswith("done in 0:03\n")
    assert "\n" not in text[:-1]


def test_progress_counts_without_unit_and_zero_total():
    p = Progress(0, "x", stream=io.StringIO(), tty=False, clock=_clock([0.0, 5.0]))
    assert p.text(5.0) == "x: 100.0% (0/0), 0/s, ETA -"


def test_sink_writes_csv_without_progress_calls(tmp_path):
    sink = RowWriter(SERIES_FIELDS["beepbeep"], "csv", str(tmp_path / "o.csv"))
    rng = (Range(0, 1, 2.0, 0.01, ()),)
    items = (ExchangeRanges(k, 2.5 * k, rng) for k in range(2))
    sink.write(SeriesRows(items, scheme="beepbeep"), {})
    assert (tmp_path / "o.csv").read_text().splitlines()[1:] == [
        "0.000000,0,1,2.000000,0.010000,",
        "2.500000,0,1,2.000000,0.010000,",
    ]
