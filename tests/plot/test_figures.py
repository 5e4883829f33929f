"""rangekit.plot.figures and rangekit.plot.inputs: every figure is written, and draws its data.

The data checks read the matplotlib artists back (found by their ``gid``): the marked
onsets are the detector's, the marked first path is the ranging result's arrival, the
track line goes through the input rows, the band edges are distance ± sigma, the CDF
ends at 1 and its median is numpy's.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from rangekit.detect import detect
from rangekit.detect.matched import MatchedFilter, coded_template
from rangekit.errors import InputFileError, InvalidParameterError, LogFormatError
from rangekit.floorplan import load_floorplan
from rangekit.plot import figures as F
from rangekit.plot import new_figure, save_figure
from rangekit.plot.inputs import (
    read_batch_errors,
    read_columns,
    read_range_series,
    read_track,
)
from rangekit.ranging.ultrasonic import matched_trace, range_echo, range_oneway
from rangekit.signals.transducer import Transducer
from rangekit.sim import pair_devices, render_beepbeep
from rangekit.sim.ultrasonic import render_echo, render_oneway

PLAN = Path(__file__).resolve().parents[2] / "fixtures_audio" / "corridor_plan.json"
SUFFIXES = (".png", ".pdf", ".svg")
#: Smallest plausible size of a written figure, bytes (an empty axes in PNG is ~5 kB).
MIN_BYTES = 8000


def _by_gid(ax, prefix: str) -> list:
    arts = [*ax.lines, *ax.collections, *ax.patches, *ax.images]
    return [a for a in arts if (a.get_gid() or "").startswith(prefix)]


def _ax():
    return new_figure()[1][0, 0]


# --- spectrogram ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def beepbeep():
    devs = pair_devices(2.0, rec_start_s=(0.01, 0.04), fs=44100.0)
    sim = render_beepbeep(devs, snr_db=25.0, gap_s=0.1, rng=np.random.default_rng(7))
    return sim


def test_spectrogram_marks_the_detected_onsets(beepbeep):
    x = beepbeep.recordings[0]
    arr = detect(x, fs=44100.0)
    assert len(arr) == 2
    # The detector finds the rendered beeps (so the marks are where the beeps are).
    assert np.allclose(arr.onset, beepbeep.onsets[0], atol=1.0)
    ax = _ax()
    out = F.draw_spectrogram(ax, x, fs=44100.0, onsets=arr.onset)
    lines = _by_gid(ax, "onset")
    assert [ln.get_xdata()[0] for ln in lines] == pytest.approx(arr.onset / 44100.0, abs=1e-12)
    assert out.onsets_s == pytest.approx(arr.onset / 44100.0)
    # The image is the spectrogram, and the beep's 16 kHz line is its loudest bin there.
    (im,) = _by_gid(ax, "spectrogram")
    assert np.array_equal(im.get_array(), out.power_db)
    k = int(np.argmin(np.abs(out.t_s - (arr.onset[0] / 44100.0 + 0.005))))
    assert abs(out.f_hz[np.argmax(out.power_db[:, k])] - 16000.0) <= out.f_hz[1]


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_spectrogram_written_in_every_format(tmp_path, beepbeep, suffix):
    x = beepbeep.recordings[1]
    out = tmp_path / f"spec{suffix}"
    res = F.plot_spectrogram(x, out, fs=44100.0, onsets=[1000.5], title="device 1")
    assert out.stat().st_size > MIN_BYTES
    assert res.onsets_s == pytest.approx([1000.5 / 44100.0])
    assert not list(tmp_path.glob(".*.part"))


def test_spectrogram_db_frames_are_capped_and_errors():
    x = np.random.default_rng(0).standard_normal(2_000_000)
    t, f, p = F.spectrogram_db(x, fs=192000.0)
    assert len(t) <= F.MAX_FRAMES and p.shape == (len(f), len(t))
    with pytest.raises(InvalidParameterError, match=r"16"):
        F.spectrogram_db(np.zeros(8), fs=8000.0)
    with pytest.raises(InvalidParameterError, match=r"fs"):
        F.spectrogram_db(np.zeros(100), fs=-1.0)


# --- matched filter -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def oneway():
    t = Transducer(q=4.0)
    txs = [[1.0, 0.5, 2.0], [-1.0, 1.5, 2.0]]
    return render_oneway(
        txs, (0.2, -0.1, 0.5), tx=t, rx=t, period_s=0.04, latency_s=0.001,
        rng=np.random.default_rng(3),
    )  # fmt: skip


@pytest.mark.parametrize(("channel", "window"), [(0, 0), (2, 1)])
def test_matched_peak_is_the_ranging_arrival(oneway, channel, window):
    kw = {"period_s": 0.04, "latency_s": 0.001}
    tr = matched_trace(
        oneway.x, fs=oneway.fs, scheme="oneway", channel=channel, window=window, **kw
    )
    rows = range_oneway(oneway.x, fs=oneway.fs, **kw)
    (row,) = [r for r in rows if (r.window, r.channel) == (window, channel)]
    assert tr.tof == row
    true_m = oneway.truth["windows"][window]["distances_m"][channel]
    assert abs(row.distance_m - true_m) < 2e-3
    # The envelope is the matched filter's, cut to the window; its peak is the arrival.
    s0 = tr.start
    assert s0 == round(window * 0.04 * oneway.fs)
    mf = MatchedFilter(coded_template(fs=oneway.fs, tx=Transducer(), rx=Transducer()))
    ref = np.abs(mf.correlate(oneway.x[channel]))[s0 : s0 + len(tr.envelope)]
    assert np.allclose(tr.envelope, ref, rtol=0, atol=1e-12 * ref.max())
    assert abs(int(np.argmax(tr.envelope)) - tr.peak_lag) <= 1.0
    lo, hi = tr.search_s
    assert lo == pytest.approx(0.001) and lo < row.arrival_s < hi
    ax = _ax()
    out = F.draw_matched(ax, tr)
    (line,) = _by_gid(ax, "first-path")
    assert line.get_xdata()[0] == pytest.approx(row.arrival_s * 1e3, abs=1e-12)
    assert out.peak_s == row.arrival_s
    (env,) = _by_gid(ax, "envelope")
    assert np.max(env.get_ydata()) == 0.0 and len(env.get_xdata()) == len(tr.envelope)
    assert math.isfinite(out.threshold_db) and out.threshold_db < 0


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_matched_written_in_every_format(tmp_path, oneway, suffix):
    tr = matched_trace(oneway.x, fs=oneway.fs, scheme="oneway", period_s=0.04, latency_s=0.001)
    out = tmp_path / f"mf{suffix}"
    F.plot_matched(tr, out)
    assert out.stat().st_size > MIN_BYTES
    if suffix == ".svg":
        assert f"{tr.tof.distance_m:.4f} m" in out.read_text()


def test_matched_echo_out_of_range_has_no_mark(tmp_path):
    plan = load_floorplan(PLAN)
    # Facing a side wall 0.7 m away, then the far end wall 6.5 m away (out of range).
    sim = render_echo(
        plan, [(1.0, 0.7, -math.pi / 2), (3.5, 1.0, 0.0)], transducer=Transducer(),
        rng=np.random.default_rng(4),
    )  # fmt: skip
    rows = range_echo(sim.x, fs=sim.fs, period_s=0.07)
    for w in (0, 1):
        tr = matched_trace(sim.x, fs=sim.fs, scheme="echo", window=w, period_s=0.07)
        assert tr.tof == rows[w]
        ax = _ax()
        out = F.draw_matched(ax, tr)
        marks = _by_gid(ax, "first-path")
        if w == 0:
            assert abs(rows[0].distance_m - 0.7) < 0.01
            assert marks[0].get_xdata()[0] == pytest.approx(rows[0].arrival_s * 1e3)
        else:
            assert math.isnan(rows[1].distance_m) and not marks and math.isnan(out.peak_s)
    out = tmp_path / "echo.svg"
    F.plot_matched(tr, out)
    assert "nothing detected" in out.read_text()


def test_matched_trace_errors(oneway):
    from rangekit.errors import IncompatibleInputError

    with pytest.raises(IncompatibleInputError, match=r"channel 3"):
        matched_trace(oneway.x, fs=oneway.fs, scheme="oneway", channel=3)
    with pytest.raises(IncompatibleInputError, match=r"window 2 .* 2 window"):
        matched_trace(oneway.x, fs=oneway.fs, scheme="oneway", window=2, period_s=0.04)
    with pytest.raises(InvalidParameterError, match=r"scheme"):
        matched_trace(oneway.x, fs=oneway.fs, scheme="beepbeep")
    with pytest.raises(InvalidParameterError, match=r"max_range_m"):
        matched_trace(oneway.x, fs=oneway.fs, scheme="oneway", max_range_m=-1.0)


# --- range series ---------------------------------------------------------------------------

SERIES_CSV = """# two pairs, rows interleaved; an empty distance is a failed range
t_s,a,b,distance_m,sigma_m,flags
0.0,0,1,2.50,0.010,
0.0,0,2,3.10,0.020,
0.5,0,1,2.52,0.012,
0.5,0,2,,,
1.0,0,1,2.55,0.011,negative
1.0,0,2,3.05,0.015,
1.5,0,2,3.00,0.020,
"""


def test_ranges_lines_and_bands_are_distance_pm_sigma(tmp_path):
    src = tmp_path / "series.csv"
    src.write_text(SERIES_CSV)
    series = read_range_series(src)
    assert [s.key for s in series] == ["0-1", "0-2"]
    ax = _ax()
    out = F.draw_ranges(ax, series)
    want = {
        "0-1": ([0.0, 0.5, 1.0], [2.50, 2.52, 2.55], [0.010, 0.012, 0.011]),
        "0-2": ([0.0, 0.5, 1.0, 1.5], [3.10, np.nan, 3.05, 3.00], [0.020, np.nan, 0.015, 0.020]),
    }
    for key, (t, d, s) in want.items():
        (line,) = _by_gid(ax, f"range:{key}")
        assert np.array_equal(line.get_xdata(), t)
        assert np.allclose(line.get_ydata(), d, equal_nan=True)
        assert np.allclose(out.series[key][2], s, equal_nan=True)
        for k in (1, 2):
            (band,) = _by_gid(ax, f"band{k}:{key}")
            verts = np.concatenate([p.vertices for p in band.get_paths()])
            for ti, di, si in zip(t, d, s, strict=True):
                if math.isnan(di):
                    assert not np.any(np.isclose(verts[:, 0], ti)), "a gap has no band"
                    continue
                for edge in (di - k * si, di + k * si):
                    assert np.any(np.all(np.isclose(verts, [ti, edge]), axis=1)), (key, ti, edge)


def test_ranges_json_reads_like_csv_and_keys(tmp_path):
    rows = [
        {"t_s": 1.0, "tx": 3, "channel": 0, "distance_m": 2.0, "sigma_m": 0.001, "file": "a"},
        {"t_s": 0.0, "tx": 3, "channel": 0, "distance_m": 2.1, "sigma_m": 0.002},
        {"t_s": 0.0, "tx": None, "channel": 1, "distance_m": None, "sigma_m": None},
    ]
    src = tmp_path / "s.json"
    src.write_text(json.dumps({"scheme": "oneway", "ranges": rows}))
    s = read_range_series(src)
    assert [x.key for x in s] == ["tx 3 ch 0", "tx - ch 1"]
    assert s[0].t_s.tolist() == [0.0, 1.0] and s[0].distance_m.tolist() == [2.1, 2.0]
    assert math.isnan(s[1].distance_m[0])
    echo = tmp_path / "e.csv"
    echo.write_text("t_s,channel,distance_m,sigma_m\n0,1,1.5,0.01\n0.07,1,,\n")
    assert [x.key for x in read_range_series(echo)] == ["ch 1"]


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_ranges_written_in_every_format(tmp_path, suffix):
    src = tmp_path / "series.csv"
    src.write_text(SERIES_CSV)
    out = tmp_path / f"ranges{suffix}"
    F.plot_ranges(read_range_series(src), out, title="two pairs")
    assert out.stat().st_size > MIN_BYTES


def test_ranges_and_track_without_rows_are_empty_figures(tmp_path):
    src = tmp_path / "empty.csv"
    src.write_text("t_s,a,b,distance_m,sigma_m\n")
    assert read_range_series(src) == []
    trk = tmp_path / "empty_track.csv"
    trk.write_text("t_s,x_m,y_m\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert F.plot_ranges([], tmp_path / "r.png").series == {}
        assert F.plot_track(read_track(trk), tmp_path / "t.png").xy_m == {}
    assert (tmp_path / "r.png").stat().st_size > 0 and (tmp_path / "t.png").is_file()


def test_ranges_input_errors(tmp_path):
    plain = tmp_path / "plain.csv"
    plain.write_text("a,b,distance_m,sigma_m,flags\n0,1,2.5,0.01,\n")
    with pytest.raises(LogFormatError, match=r"plain.csv: missing column 't_s'.*--series"):
        read_range_series(plain)
    bad = tmp_path / "bad.csv"
    bad.write_text("t_s,a,b,distance_m,sigma_m\n0,0,1,2.5,-0.01\n")
    with pytest.raises(LogFormatError, match=r"bad.csv row 2, column 'sigma_m'"):
        read_range_series(bad)
    badj = tmp_path / "bad.json"
    badj.write_text(json.dumps({"ranges": [{"t_s": 0, "distance_m": "x", "sigma_m": 1}]}))
    with pytest.raises(LogFormatError, match=r"bad.json ranges\[0\], column 'distance_m'"):
        read_range_series(badj)
    with pytest.raises(InvalidParameterError, match=r"'.txt'"):
        read_range_series(tmp_path / "s.txt")
    with pytest.raises(InputFileError, match=r"none.json"):
        read_range_series(tmp_path / "none.json")
    broken = tmp_path / "broken.json"
    broken.write_text("{")
    with pytest.raises(LogFormatError, match=r"broken.json: not JSON"):
        read_range_series(broken)
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"x": 1}))
    with pytest.raises(LogFormatError, match=r"without a list of rows"):
        read_range_series(other)


# --- tracks ---------------------------------------------------------------------------------


def _track_csv(path: Path) -> list[list[float]]:
    """A two-target range-ekf-style track; returns its rows."""
    rng = np.random.default_rng(2)
    rows = []
    for k in range(25):
        for target in (1, 2):
            x, y = 1.0 + 0.3 * k, 1.0 + 2.5 * (target - 1) + 0.2 * math.sin(k / 4)
            vx, vy = 0.01 + 0.02 * rng.random(), 0.01 + 0.02 * rng.random()
            c = 0.8 * math.sqrt(vx * vy) * (rng.random() * 2 - 1)
            rows.append([0.5 * k, target, x, y, 0.3, 0.0, vx, vy, c])
    head = "t_s,target,x_m,y_m,vx_mps,vy_mps,var_x_m2,var_y_m2,cov_xy_m2\n"
    path.write_text(head + "".join(",".join(repr(v) for v in r) + "\n" for r in rows))
    return rows


def test_track_points_and_ellipses_match_the_rows(tmp_path):
    rows = np.array(_track_csv(tmp_path / "track.csv"))
    paths = read_track(tmp_path / "track.csv")
    truth = tmp_path / "truth.csv"
    truth.write_text("target,x_m,y_m\n1,1,1\n1,8,1\n2,1,3.5\n2,8,3.5\n")
    plan = load_floorplan(PLAN)
    ax = _ax()
    out = F.draw_track(ax, paths, plan=plan, truth=read_track(truth), every=10)
    assert out.n_walls == len(plan.segments)
    (walls,) = _by_gid(ax, "walls")
    assert len(walls.get_segments()) == len(plan.segments)
    for target in (1, 2):
        mine = rows[rows[:, 1] == target]
        (line,) = _by_gid(ax, f"track:{target}")
        assert np.array_equal(line.get_xdata(), mine[:, 2])
        assert np.array_equal(line.get_ydata(), mine[:, 3])
        (tline,) = _by_gid(ax, f"truth:{target}")
        assert tline.get_ydata().tolist() == [1.0 + 2.5 * (target - 1)] * 2
        assert out.ellipse_rows[str(target)].tolist() == [0, 10, 20]
        ells = _by_gid(ax, f"ellipse:{target}")
        assert len(ells) == 3
        for e, k in zip(ells, (0, 10, 20), strict=True):
            r = mine[k]
            assert e.center == pytest.approx((r[2], r[3]))
            p = np.array([[r[6], r[8]], [r[8], r[7]]])
            # The drawn outline (the unit circle through the patch transform) is at
            # Mahalanobis distance 2 from the row everywhere.
            a = np.linspace(0.0, 2 * math.pi, 16)
            unit = np.column_stack([np.cos(a), np.sin(a)])
            v = e.get_patch_transform().transform(unit) - r[2:4]
            d2 = np.einsum("ni,ij,nj->n", v, np.linalg.inv(p), v)
            assert np.allclose(d2, 4.0, rtol=1e-9)


def test_track_dead_reckoning_sigmas_and_particle_spread(tmp_path):
    dr = tmp_path / "dr.csv"
    dr.write_text(
        "t_s,x_m,y_m,vx_mps,vy_mps,bias_x_mps2,bias_y_mps2,sigma_x_m,sigma_y_m\n"
        "0,0,0,0,0,0,0,0.1,0.2\n1,1,0,1,0,0,0,0.3,0.1\n"
    )
    (p,) = read_track(dr)
    assert p.target == "" and np.allclose(p.cov_m2[1], np.diag([0.09, 0.01]))
    ax = _ax()
    F.draw_track(ax, [p], every=1)
    e0, e1 = _by_gid(ax, "ellipse:")
    assert (e0.width, e0.height, e0.angle) == pytest.approx((0.8, 0.4, 90.0))
    assert (e1.width, e1.height) == pytest.approx((1.2, 0.4))
    assert abs(e1.angle) == pytest.approx(0.0, abs=1e-9) or abs(e1.angle) == pytest.approx(180.0)
    pf = tmp_path / "pf.json"
    pf.write_text(
        json.dumps(
            {"columns": ["t_s", "x_m", "y_m", "n_particles", "spread_m"],
             "rows": [[0, 1, 1, 500, 0.5], [1, 2, 1, 480, None], [2, 3, 1, 470, 0.25]]}
        )
    )  # fmt: skip
    (p,) = read_track(pf)
    ax = _ax()
    out = F.draw_track(ax, [p], every=1)
    circles = _by_gid(ax, "spread:")
    assert [c.get_radius() for c in circles] == [0.5, 0.25]
    assert out.ellipse_rows[""].tolist() == [0, 2]
    lmax = tmp_path / "lmax.csv"
    lmax.write_text("t_s,x_m,y_m\n0,0,0\n1,1,1\n")
    ax = _ax()
    assert F.draw_track(ax, read_track(lmax), every=1).ellipse_rows[""].size == 0


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_track_written_in_every_format(tmp_path, suffix):
    _track_csv(tmp_path / "track.csv")
    out = tmp_path / f"track{suffix}"
    res = F.plot_track(read_track(tmp_path / "track.csv"), out, plan=load_floorplan(PLAN))
    assert out.stat().st_size > MIN_BYTES
    assert sorted(res.xy_m) == ["1", "2"]


def test_covariance_ellipse_is_the_two_sigma_contour():
    p = np.array([[0.05, 0.03], [0.03, 0.04]])
    w, h, ang = F.covariance_ellipse(p)
    lam = np.linalg.eigvalsh(p)
    assert (w, h) == pytest.approx((4 * math.sqrt(lam[1]), 4 * math.sqrt(lam[0])))
    u = np.array([math.cos(math.radians(ang)), math.sin(math.radians(ang))])
    assert u @ p @ u == pytest.approx(lam[1])  # the width lies along the major axis
    # Rounding that makes P slightly indefinite gives a flat ellipse, not NaN.
    w, h, _ = F.covariance_ellipse(np.array([[1.0, 1.0 + 1e-12], [1.0 + 1e-12, 1.0]]))
    assert w > 0 and h == 0.0


# --- error CDFs -----------------------------------------------------------------------------


def _results(path: Path) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(5)
    errs: dict[str, list] = {"oneway": [], "echo": []}
    with open(path, "w") as f:
        for k in range(80):
            scheme = ("oneway", "echo")[k % 2]
            true = float(rng.uniform(0.5, 5))
            d = true + float(rng.normal(0, 0.002 if scheme == "oneway" else 0.02))
            row = {"scheme": scheme, "distance_m": d, "true_distance_m": true, "status": "ok"}
            if k % 13 == 0:
                row["status"] = "detection failed"
            elif k % 17 == 0:
                row["distance_m"] = None
            else:
                errs[scheme].append(abs(d - true))
            f.write(json.dumps(row) + "\n")
        f.write("\n")
    return {k: np.array(v) for k, v in errs.items()}


def test_cdf_ends_at_one_with_numpy_median(tmp_path):
    want = _results(tmp_path / "r.jsonl")
    batch = read_batch_errors(tmp_path / "r.jsonl", by="scheme")
    assert batch.n_rows == 80 and batch.n_skipped == 80 - sum(len(v) for v in want.values())
    ax = _ax()
    out = F.draw_cdf(ax, batch.errors_m, by="scheme")
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    for g, e in want.items():
        assert np.allclose(batch.errors_m[g], e)
        (line,) = _by_gid(ax, f"cdf:{g}")
        x_mm, y = line.get_xdata(), line.get_ydata()
        assert y[-1] == 1.0 and y[0] == 0.0 and np.all(np.diff(y) >= 0)
        assert np.allclose(x_mm[1:], np.sort(e) * 1e3)
        assert out.median_m[g] == np.median(e)
        assert out.p90_m[g] == np.percentile(e, 90)
        assert any(f"median {np.median(e) * 1e3:.3g} mm" in lab for lab in labels)
    assert any(lab.startswith("scheme=echo: n=") for lab in labels)


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_cdf_written_in_every_format_with_the_skipped_count(tmp_path, suffix):
    _results(tmp_path / "r.jsonl")
    batch = read_batch_errors(tmp_path / "r.jsonl")
    out = tmp_path / f"cdf{suffix}"
    F.plot_cdf(batch, out)
    assert out.stat().st_size > MIN_BYTES
    if suffix == ".svg":
        assert f"({batch.n_skipped} skipped" in out.read_text()


def test_cdf_input_errors(tmp_path):
    src = tmp_path / "r.csv"
    src.write_text("distance_m,true_distance_m,status\n,1.0,ok\n1.0,1.1,failed\n")
    with pytest.raises(LogFormatError, match=r"r.csv: no row has both.*2 rows"):
        read_batch_errors(src)
    with pytest.raises(LogFormatError, match=r"'scheme'"):
        read_batch_errors(src, by="scheme")
    ok = tmp_path / "ok.csv"
    ok.write_text("distance_m,true_distance_m\n1.0,1.002\n2.0,1.99\n")
    b = read_batch_errors(ok)
    assert np.allclose(b.errors_m[""], [0.002, 0.01]) and b.n_skipped == 0
    jl = tmp_path / "bad.jsonl"
    jl.write_text('{"distance_m": 1, "true_distance_m": 1}\n[1]\n')
    with pytest.raises(LogFormatError, match=r"bad.jsonl line 2: not a JSON object"):
        read_batch_errors(jl)
    jl.write_text('{"distance_m": 1, "true_distance_m": 1}\n{"distance_m": NaN}\n')
    with pytest.raises(LogFormatError, match=r"bad.jsonl line 2, column 'distance_m'.*finite"):
        read_batch_errors(jl)


def test_read_columns_time_and_absent_columns(tmp_path):
    from rangekit.io.csvlog import Column

    spec = {"t_s": Column(kind="time"), "k": Column(kind="int", required=False, empty_ok=True)}
    src = tmp_path / "t.jsonl"
    src.write_text('{"t_s": 1}\n{"t_s": 0.5}\n')
    with pytest.raises(LogFormatError, match=r"line 2, column 't_s': time 0.5 goes backwards"):
        read_columns(src, spec)
    src.write_text('{"t_s": 1}\n{"t_s": 2, "k": 3}\n')
    cols, present = read_columns(src, spec)
    assert cols["k"].tolist() == [-1, 3] and present == {"t_s", "k"}


# --- saving ---------------------------------------------------------------------------------


def test_save_figure_is_atomic_and_checks_the_suffix(tmp_path):
    out = tmp_path / "fig.png"
    out.write_bytes(b"keep me")
    fig, _ = new_figure()

    def broken(path, **kw):
        path.write(b"half") if hasattr(path, "write") else Path(path).write_bytes(b"half")
        raise OSError(28, "No space left on device")

    fig.savefig = broken
    with pytest.raises(InputFileError, match=r"No space left"):
        save_figure(fig, out)
    assert out.read_bytes() == b"keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig.png"]
    with pytest.raises(InvalidParameterError, match=r"unknown format '\.jpg'"):
        save_figure(new_figure()[0], tmp_path / "x.jpg")
    with pytest.raises(InputFileError, match=r"folder .*does not exist"):
        save_figure(new_figure()[0], tmp_path / "no" / "x.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig.png"]
