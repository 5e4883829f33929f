"""``rangekit plot``: every figure type is written, draws the inputs' data, and errors are one line.

The data checks capture the figure the command saves (``rangekit.plot.figures.save_figure``
wrapped) and compare its artists with what ``rangekit detect`` / ``rangekit range`` print
for the same file, or with the input rows.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from clihelp import assert_error, ok, run

import rangekit.plot.figures as figures
from rangekit.io.audio import write_audio
from rangekit.sim import Device, pair_devices, render_beepbeep

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures_audio"
PLAN = FIXTURES / "corridor_plan.json"
MIN_BYTES = 8000


@pytest.fixture
def saved(monkeypatch):
    """The figures the command saved, in order."""
    figs = []
    real = figures.save_figure

    def keep(fig, path):
        figs.append(fig)
        return real(fig, path)

    monkeypatch.setattr(figures, "save_figure", keep)
    return figs


def _gid(fig, prefix: str) -> list:
    ax = fig.axes[0]
    arts = [*ax.lines, *ax.collections, *ax.patches, *ax.images]
    return [a for a in arts if (a.get_gid() or "").startswith(prefix)]


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    """A simulated three-device exchange: one WAV, three channels."""
    devs = [
        *pair_devices(2.0, rec_start_s=(0.0, 0.03), fs=44100.0),
        Device([1.0, 1.5, 1.2], [1.0, 1.6, 1.2], rec_start_s=0.02),
    ]
    sim = render_beepbeep(devs, snr_db=25.0, gap_s=0.1, rng=np.random.default_rng(11))
    n = min(len(x) for x in sim.recordings)
    path = tmp_path_factory.mktemp("rec") / "three.wav"
    write_audio(path, np.stack([x[:n] for x in sim.recordings], axis=1), fs=44100.0)
    return path


@pytest.mark.parametrize(("suffix", "channel"), [(".png", 0), (".pdf", 1), (".svg", 2)])
def test_spectrogram_marks_what_detect_prints(tmp_path, rec, saved, suffix, channel):
    out = tmp_path / f"spec{suffix}"
    r = ok(run(["plot", "spectrogram", rec, "--channel", channel, "-o", out]))
    assert out.stat().st_size > MIN_BYTES
    assert "3 onset(s) marked" in r.stderr
    det = json.loads(ok(run(["detect", rec, "--format", "json"])).stdout)["arrivals"]
    want = [a["onset_s"] for a in det if a["channel"] == channel]
    assert len(want) == 3
    got = [ln.get_xdata()[0] for ln in _gid(saved[0], "onset")]
    assert got == pytest.approx(want, rel=1e-12)


def test_spectrogram_xcorr_and_beep_options(tmp_path, rec, saved):
    out = tmp_path / "x.png"
    ok(run(["plot", "spectrogram", rec, "--detector", "xcorr", "-o", out]))
    det = json.loads(ok(run(["detect", rec, "--detector", "xcorr", "--format", "json"])).stdout)
    want = [a["onset_s"] for a in det["arrivals"] if a["channel"] == 0]
    assert [ln.get_xdata()[0] for ln in _gid(saved[0], "onset")] == pytest.approx(want)
    # A beep that was not played: nothing found, the spectrogram is still drawn.
    r = ok(run(["plot", "spectrogram", rec, "--freq", 9000, "-o", out]))
    assert "0 onset(s) marked" in r.stderr and not _gid(saved[1], "onset")


@pytest.fixture(scope="module")
def oneway(tmp_path_factory):
    out = tmp_path_factory.mktemp("ow") / "ow.wav"
    ok(run(["synth", "oneway", "--pose", "0.3,-0.2,40", "--period", 0.05, "--latency", 0.002,
            "--seed", 3, "-o", out]))  # fmt: skip
    return out


@pytest.mark.parametrize(("channel", "window"), [(0, 0), (2, 4)])
def test_matched_marks_the_range_commands_arrival(tmp_path, oneway, saved, channel, window):
    opts = ["--period", 0.05, "--latency", 0.002, "--tx-order", "0,1,2,3,4,5"]
    out = tmp_path / "mf.svg"
    r = ok(run(["plot", "matched", oneway, "--scheme", "oneway", *opts,
                "--channel", channel, "--window", window, "-o", out]))  # fmt: skip
    rows = json.loads(
        ok(run(["range", "--scheme", "oneway", oneway, *opts, "--format", "json"])).stdout
    )
    (row,) = [x for x in rows["ranges"] if (x["channel"], x["window"]) == (channel, window)]
    (line,) = _gid(saved[0], "first-path")
    assert line.get_xdata()[0] == pytest.approx(row["arrival_s"] * 1e3, rel=1e-12)
    assert f"{row['distance_m']:.4f} m" in r.stderr
    text = out.read_text()
    assert out.stat().st_size > MIN_BYTES and f"(tx {row['tx']})" in text


def test_matched_echo(tmp_path, saved):
    wav = tmp_path / "echo.wav"
    ok(run(["synth", "echo", "--map", PLAN, "--pose", "1,0.7,90", "--pose", "3.5,1,0",
            "--seed", 4, "-o", wav]))  # fmt: skip
    rows = json.loads(
        ok(run(["range", "--scheme", "echo", wav, "--period", 0.07, "--format", "json"])).stdout
    )["ranges"]
    for w in (0, 1):
        out = tmp_path / f"e{w}.png"
        r = ok(run(["plot", "matched", wav, "--scheme", "echo", "--period", 0.07, "--window", w,
                    "-o", out]))  # fmt: skip
        assert out.stat().st_size > MIN_BYTES
        marks = _gid(saved[w], "first-path")
        if rows[w]["distance_m"] is None:
            assert not marks and "nothing detected" in r.stderr
        else:
            assert marks[0].get_xdata()[0] == pytest.approx(rows[w]["arrival_s"] * 1e3)


def _series(path: Path) -> None:
    lines = ["t_s,a,b,distance_m,sigma_m,flags"]
    for k in range(12):
        lines.append(f"{0.5 * k},0,1,{2.5 + 0.01 * k},{0.01 + 0.001 * k},")
        lines.append(f"{0.5 * k},0,2,{'' if k == 5 else 3.0 - 0.02 * k},{'' if k == 5 else 0.02},")
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("suffix", [".png", ".pdf", ".svg"])
def test_ranges(tmp_path, saved, suffix):
    src = tmp_path / "series.csv"
    _series(src)
    out = tmp_path / f"r{suffix}"
    r = ok(run(["plot", "ranges", src, "-o", out]))
    assert out.stat().st_size > MIN_BYTES and "2 series, 23 ranges" in r.stderr
    (line,) = _gid(saved[0], "range:0-1")
    assert line.get_ydata() == pytest.approx([2.5 + 0.01 * k for k in range(12)])
    (band,) = _gid(saved[0], "band1:0-1")
    verts = np.concatenate([p.vertices for p in band.get_paths()])
    assert np.any(np.all(np.isclose(verts, [5.5, 2.61 - 0.021]), axis=1))


def _track(path: Path) -> np.ndarray:
    k = np.arange(30.0)
    rows = np.column_stack(
        [0.2 * k, 0.5 + 0.15 * k, 1.0 + 0.1 * np.sin(k / 3), np.full(30, 0.01),
         np.full(30, 0.004), np.zeros(30), np.zeros(30), np.zeros(30), np.full(30, 1.0)]
    )  # fmt: skip
    head = "t_s,x_m,y_m,var_x_m2,var_y_m2,var_heading_rad2,heading_rad,extra,status\n"
    path.write_text(head + "".join(",".join(repr(float(v)) for v in r) + "\n" for r in rows))
    return rows


@pytest.mark.parametrize("suffix", [".png", ".pdf", ".svg"])
def test_track_over_the_plan(tmp_path, saved, suffix):
    rows = _track(tmp_path / "pose.csv")
    truth = tmp_path / "truth.csv"
    truth.write_text("x_m,y_m\n0.5,1\n5,1\n")
    out = tmp_path / f"t{suffix}"
    r = ok(run(["plot", "track", tmp_path / "pose.csv", "--map", PLAN, "--truth", truth,
                "--ellipses", 7, "-o", out]))  # fmt: skip
    assert out.stat().st_size > MIN_BYTES
    assert "1 track(s), 30 points, 5 ellipses/circles" in r.stderr
    (line,) = _gid(saved[0], "track:")
    assert np.array_equal(line.get_xdata(), rows[:, 1])
    assert np.array_equal(line.get_ydata(), rows[:, 2])
    ells = _gid(saved[0], "ellipse:")
    assert [e.center for e in ells] == [tuple(rows[i, 1:3]) for i in (0, 7, 14, 21, 28)]
    assert (ells[0].width, ells[0].height) == pytest.approx((4 * 0.1, 4 * math.sqrt(0.004)))
    assert _gid(saved[0], "walls") and _gid(saved[0], "truth:")


def test_track_json_from_rangekit_track(tmp_path, saved):
    from rangekit.sim.jiang2018 import simulate

    log = tmp_path / "log.csv"
    log.write_text(simulate("lab", rng=np.random.default_rng(1)).log.to_csv())
    trk = tmp_path / "track.json"
    ok(run(["track", "--filter", "range-ekf", log, "--format", "json", "-o", trk]))
    doc = json.loads(trk.read_text())
    out = tmp_path / "t.png"
    ok(run(["plot", "track", trk, "--ellipses", 0, "-o", out]))
    cols = doc["columns"]
    rows = np.array(doc["rows"], dtype=float)
    for target in (1, 2):
        mine = rows[rows[:, cols.index("target")] == target]
        (line,) = _gid(saved[0], f"track:{target}")
        assert np.array_equal(line.get_xdata(), mine[:, cols.index("x_m")])
    assert not _gid(saved[0], "ellipse:")


@pytest.mark.parametrize("suffix", [".png", ".pdf", ".svg"])
def test_cdf(tmp_path, saved, suffix):
    src = tmp_path / "results.csv"
    rng = np.random.default_rng(0)
    lines = ["file,scheme,distance_m,true_distance_m,status"]
    errs = {"a": [], "b": []}
    for k in range(40):
        s = "ab"[k % 2]
        t = 1.0 + k * 0.1
        d = t + rng.normal(0, 0.01)
        if k % 10 == 3:
            lines.append(f"f{k},{s},,{t},ok")
        elif k % 10 == 7:
            lines.append(f"f{k},{s},{d},{t},failed")
        else:
            lines.append(f"f{k},{s},{d!r},{t!r},ok")
            errs[s].append(abs(d - t))
    src.write_text("\n".join(lines) + "\n")
    out = tmp_path / f"c{suffix}"
    r = ok(run(["plot", "cdf", src, "--by", "scheme", "-o", out]))
    assert out.stat().st_size > MIN_BYTES and "2 curve(s), 32 rows, 8 skipped" in r.stderr
    for s, e in errs.items():
        (line,) = _gid(saved[0], f"cdf:{s}")
        assert line.get_ydata()[-1] == 1.0
        assert np.allclose(line.get_xdata()[1:], np.sort(e) * 1e3)
        assert f"scheme={s}: n={len(e)}, median {np.median(e) * 1e3:.3g} mm" in line.get_label()


def test_errors(tmp_path, rec, oneway):
    src = tmp_path / "series.csv"
    _series(src)
    png = tmp_path / "x.png"
    assert_error(run(["plot", "ranges", src, "-o", tmp_path / "x.gif"]), 2, "x.gif", "'.gif'")
    assert_error(run(["plot", "ranges", src, "-o", tmp_path / "no" / "x.png"]), 3, "x.png")
    assert_error(run(["plot", "ranges", tmp_path / "none.csv", "-o", png]), 3, "none.csv")
    assert_error(run(["plot", "ranges", tmp_path / "s.txt", "-o", png]), 2, "s.txt", "'.txt'")
    plain = tmp_path / "plain.csv"
    plain.write_text("a,b,distance_m,sigma_m,flags\n0,1,2.5,0.01,\n")
    assert_error(run(["plot", "ranges", plain, "-o", png]), 4, "plain.csv", "'t_s'")
    assert_error(run(["plot", "spectrogram", rec, "--channel", 3, "-o", png]), 5, "three.wav", "3")
    assert_error(run(["plot", "spectrogram", tmp_path / "n.wav", "-o", png]), 3, "n.wav")
    assert_error(run(["plot", "spectrogram", rec, "--channel", -1, "-o", png]), 2, "--channel")
    assert_error(run(["plot", "spectrogram", rec]), 2, "--output")
    ow = ["plot", "matched", oneway, "--scheme", "oneway", "--period", 0.05]
    assert_error(run([*ow, "--window", 6, "-o", png]), 5, "ow.wav", "window 6", "--period")
    assert_error(run([*ow, "--channel", 3, "-o", png]), 5, "ow.wav", "--channel 3")
    assert_error(run([*ow, "--channels", 2, "-o", png]), 5, "ow.wav", "2 are expected")
    assert_error(run([*ow, "--freq", 1000, "-o", png]), 2, "--freq")
    assert_error(run(["plot", "matched", oneway, "-o", png]), 2, "--scheme")
    assert_error(
        run(["plot", "matched", oneway, "--scheme", "echo", "--latency", 0.1, "-o", png]),
        2,
        "--latency",
    )
    assert_error(run(["plot", "matched", rec, "--scheme", "echo", "-o", png]), 5, "three.wav")
    trk = tmp_path / "pose.csv"
    _track(trk)
    assert_error(run(["plot", "track", trk, "--map", tmp_path / "p.json", "-o", png]), 3, "p.json")
    assert_error(run(["plot", "track", src, "-o", png]), 4, "series.csv", "'x_m'")
    assert_error(run(["plot", "track", trk, "--ellipses", -2, "-o", png]), 2, "--ellipses")
    res = tmp_path / "res.jsonl"
    res.write_text('{"distance_m": null, "true_distance_m": 1.0, "status": "ok"}\n')
    assert_error(run(["plot", "cdf", res, "-o", png]), 4, "res.jsonl", "no row has both")
    assert_error(run(["plot", "cdf", res, "--by", "scheme", "-o", png]), 4, "'scheme'")
    assert not png.exists()


def test_failed_plot_keeps_existing_output(tmp_path, monkeypatch):
    src = tmp_path / "series.csv"
    _series(src)
    out = tmp_path / "r.png"
    out.write_bytes(b"keep me")

    def broken(self, path, **kw):
        path.write(b"half") if hasattr(path, "write") else Path(path).write_bytes(b"half")
        raise OSError(28, "No space left on device")

    from matplotlib.figure import Figure

    monkeypatch.setattr(Figure, "savefig", broken)
    assert_error(run(["plot", "ranges", src, "-o", out]), 3, "r.png", "No space left")
    assert out.read_bytes() == b"keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.png", "series.csv"]
