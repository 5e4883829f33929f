"""CLI tests of ``rangekit track`` on simulated logs (Jiang 2018 and Ahn & Yu 2007 sims)."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest
from clihelp import assert_error, ok, run

from rangekit.localize import deadreckoning, lmax
from rangekit.localize.range_ekf import TRACK_COLUMNS as EKF_COLUMNS
from rangekit.sim import ahn2007, jiang2018

N_IMU = 120
N_FIXES = 30


def _csv(text: str) -> tuple[list[str], list[list[str]]]:
    rows = list(csv.reader(io.StringIO(text)))
    return rows[0], rows[1:]


@pytest.fixture(scope="module")
def jiang_text() -> str:
    return jiang2018.simulate(rng=1).log.to_csv()


@pytest.fixture
def jiang_log(tmp_path, jiang_text):
    p = tmp_path / "measurements.csv"
    p.write_text(jiang_text)
    return p


@pytest.fixture
def imu_log(tmp_path):
    p = tmp_path / "imu.csv"
    p.write_text(ahn2007.imu_log_text(ahn2007.simulate_robot(N_IMU, rng=2)))
    return p


@pytest.fixture
def position_log(tmp_path):
    p = tmp_path / "fixes.csv"
    p.write_text(ahn2007.position_log_text(ahn2007.simulate_pedestrian(N_FIXES, rng=3)))
    return p


def _n_data_rows(path) -> int:
    lines = [ln for ln in path.read_text().splitlines() if ln.strip() and not ln.startswith("#")]
    return len(lines) - 1


# --- range-ekf ---------------------------------------------------------------------------


def test_range_ekf_csv(jiang_log):
    r = ok(run(["track", "range-ekf", jiang_log]))
    header, rows = _csv(r.stdout)
    assert header == list(EKF_COLUMNS)
    times = sorted({float(row[0]) for row in rows})
    targets = sorted({int(row[1]) for row in rows})
    assert targets == [1, 2]
    assert len(rows) == len(times) * 2
    assert all(len(row) == len(header) for row in rows)
    np.array(rows, dtype=float)  # every cell is a number
    summary = r.stderr.splitlines()
    assert len(summary) == 1
    s = summary[0]
    assert f"{len(times)} epochs" in s and "2 targets" in s
    for word in ("rejected", "re-opened", "skipped"):
        assert word in s, s


def test_range_ekf_smooth_differs(jiang_log):
    filt = ok(run(["track", "range-ekf", jiang_log])).stdout
    smooth = ok(run(["track", "range-ekf", jiang_log, "--smooth"])).stdout
    hf, rf = _csv(filt)
    hs, rs = _csv(smooth)
    assert hf == hs and len(rf) == len(rs)
    a, b = np.array(rf, dtype=float), np.array(rs, dtype=float)
    np.testing.assert_array_equal(a[:, :2], b[:, :2])  # same epochs and targets
    np.testing.assert_array_equal(a[-2:], b[-2:])  # smoother ends at the filter's last epoch
    assert not np.allclose(a[:, 2:4], b[:, 2:4])


def test_range_ekf_json_and_rejected(tmp_path, jiang_text):
    # A non-line-of-sight range (4 m too long) in the middle of the run is gated out.
    lines = jiang_text.splitlines()
    idx = [i for i, ln in enumerate(lines) if ",range,0,2," in ln]
    k = idx[len(idx) // 2]
    cells = lines[k].split(",")
    cells[10] = repr(float(cells[10]) + 4.0)
    lines[k] = ",".join(cells)
    log = tmp_path / "nlos.csv"
    log.write_text("\n".join(lines) + "\n")
    r = ok(run(["track", "range-ekf", log, "--format", "json"]))
    obj = json.loads(r.stdout)
    assert obj["columns"] == list(EKF_COLUMNS)
    assert obj["filter"] == "range-ekf"
    assert all(len(row) == len(EKF_COLUMNS) for row in obj["rows"])
    assert {row[1] for row in obj["rows"]} == {1, 2}
    rej = obj["rejected"]
    assert any(
        x["a"] == 0 and x["b"] == 2 and x["range_m"] == pytest.approx(float(cells[10])) for x in rej
    ), rej
    for x in rej:
        assert set(x) == {"t_s", "a", "b", "range_m", "nis"}
    assert f"{len(rej)} ranges rejected" in r.stderr
    # Without the gate nothing is rejected.
    r = ok(run(["track", "range-ekf", log, "--format", "json", "--no-gate"]))
    assert json.loads(r.stdout)["rejected"] == []


def test_range_ekf_filter_options(jiang_log):
    base = ok(run(["track", "range-ekf", jiang_log])).stdout
    for extra in (["--accel-psd", "0.5"], ["--cross-sign", "paper"], ["--gate", "0.9"]):
        out = ok(run(["track", "range-ekf", jiang_log, *extra])).stdout
        assert _csv(out)[0] == list(EKF_COLUMNS), extra
        assert len(_csv(out)[1]) == len(_csv(base)[1]), extra
    out = ok(run(["track", "range-ekf", jiang_log, "--accel-psd", "0.5"])).stdout
    assert out != base


def test_range_ekf_iterations_and_engine(jiang_log):
    """``--iterations`` and ``--engine`` pass through to ``track_ranges``: the CLI's rows
    equal the library's for each; one Gauss-Newton step (the plain EKF) gives another
    track, the numpy reference engine the same one to rounding (issue 18)."""
    from rangekit.io.tracklog import read_measurement_log
    from rangekit.localize.range_ekf import track_ranges, track_rows

    log = read_measurement_log(jiang_log)
    base = np.array(_csv(ok(run(["track", "range-ekf", jiang_log])).stdout)[1], dtype=float)
    one = ok(run(["track", "range-ekf", jiang_log, "--iterations", "1", "--format", "json"]))
    obj = json.loads(one.stdout)
    lib1 = track_rows(track_ranges(log, iterations=1))[1]
    assert np.allclose(np.array(obj["rows"], dtype=float), lib1, rtol=0, atol=1e-9)
    assert not np.allclose(lib1, base, rtol=0, atol=1e-6)
    ref = ok(run(["track", "range-ekf", jiang_log, "--engine", "numpy"])).stdout
    assert np.allclose(np.array(_csv(ref)[1], dtype=float), base, rtol=0, atol=1e-6)
    assert "--iterations" in ok(run(["track", "range-ekf", "--help"])).stdout


def test_output_file(tmp_path, jiang_log):
    out = tmp_path / "track.csv"
    r = ok(run(["track", "range-ekf", jiang_log, "-o", out]))
    assert r.stdout == ""
    assert _csv(out.read_text())[0] == list(EKF_COLUMNS)


# --- dead-reckoning and lmax ---------------------------------------------------------------


def test_dead_reckoning(imu_log):
    r = ok(run(["track", "dead-reckoning", imu_log]))
    header, rows = _csv(r.stdout)
    assert header == list(deadreckoning.TRACK_COLUMNS)
    assert len(rows) == _n_data_rows(imu_log) == N_IMU
    s = ok(run(["track", "dead-reckoning", imu_log, "--smooth"]))
    hs, rs = _csv(s.stdout)
    assert hs == header and len(rs) == len(rows)
    assert not np.allclose(np.array(rows, dtype=float), np.array(rs, dtype=float))
    j = ok(run(["track", "dead-reckoning", imu_log, "--format", "json"]))
    obj = json.loads(j.stdout)
    assert obj["columns"] == header and len(obj["rows"]) == N_IMU
    assert "rejected" not in obj
    g = ok(run(["track", "dead-reckoning", imu_log, "--gate", "0.99"]))
    assert _csv(g.stdout)[0] == header


def test_lmax_online_and_offline(position_log):
    r = ok(run(["track", "lmax", position_log, "--l-max", "0.8"]))
    header, rows = _csv(r.stdout)
    assert header == list(lmax.TRACK_COLUMNS)
    assert len(rows) == _n_data_rows(position_log) == N_FIXES
    online = np.array(rows, dtype=float)
    _, meas = lmax.read_position_log(position_log)
    np.testing.assert_allclose(online[0, 1:], meas[0])  # anchored at the first fix
    # --i-star is 1-based like the paper: the estimate at row i* is fix i*.
    i_star = 10
    r = ok(run(["track", "lmax", position_log, "--l-max", "0.8", "--i-star",
                  i_star]))  # fmt: skip
    off = np.array(_csv(r.stdout)[1], dtype=float)
    np.testing.assert_allclose(off[i_star - 1, 1:], meas[i_star - 1])
    expected = lmax.lmax_offline(meas, l_max_m=0.8, i_star=i_star - 1)
    np.testing.assert_allclose(off[:, 1:], expected)
    # --i-star 1 is the online filter.
    r = ok(run(["track", "lmax", position_log, "--l-max", "0.8", "--i-star", 1]))
    np.testing.assert_allclose(np.array(_csv(r.stdout)[1], dtype=float), online)


def test_lmax_i_star_beyond_the_fixes(position_log):
    args = ["track", "lmax", position_log, "--l-max", "1", "--i-star", N_FIXES + 1]
    assert_error(run(args), 2, "--i-star", str(N_FIXES + 1), str(N_FIXES))
    ok(run([*args[:-1], N_FIXES]))


# --- usage errors ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("filt", "extra", "named"),
    [
        ("lmax", ["--accel-psd", "0.1"], "--accel-psd"),
        ("lmax", ["--l-max", "1", "--smooth"], "--smooth"),
        ("lmax", ["--l-max", "1", "--gate", "0.9"], "--gate"),
        ("lmax", ["--l-max", "1", "--no-gate"], "--no-gate"),
        ("dead-reckoning", ["--cross-sign", "paper"], "--cross-sign"),
        ("dead-reckoning", ["--accel-psd", "0.1"], "--accel-psd"),
        ("dead-reckoning", ["--l-max", "1"], "--l-max"),
        ("range-ekf", ["--l-max", "1"], "--l-max"),
        ("range-ekf", ["--i-star", "2"], "--i-star"),
        ("range-ekf", ["--gate", "0.9", "--no-gate"], "--no-gate"),
        ("lmax", [], "--l-max"),
    ],
)
def test_option_not_for_this_filter(tmp_path, filt, extra, named):
    out = tmp_path / "out.csv"
    r = run(["track", filt, tmp_path / "any.csv", *extra, "-o", out])
    assert_error(r, 2, named, f"rangekit track {filt} --help")
    assert not out.exists()


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        (["--gate", "1.5"], "--gate"),
        (["--gate", "0"], "--gate"),
        (["--accel-psd", "0"], "--accel-psd"),
        (["--accel-psd", "nan"], "--accel-psd"),
        (["--cross-sign", "other"], "--cross-sign"),
        (["--iterations", "0"], "--iterations"),
        (["--engine", "fast"], "--engine"),
        (["--format", "xml"], "--format"),
    ],
)
def test_bad_option_values(jiang_log, extra, named):
    assert_error(run(["track", "range-ekf", jiang_log, *extra]), 2, named)


def test_missing_or_unknown_filter(jiang_log):
    assert_error(run(["track", jiang_log]), 2, "no tracking filter", jiang_log.name, "range-ekf")
    assert_error(run(["track", "kalman", jiang_log]), 2, "kalman", "range-ekf")
    assert_error(run(["track", "--filter", "kalman", jiang_log]), 2, "--filter", "kalman")


# --- bad logs --------------------------------------------------------------------------------


def _edit_range_row(text: str, col: str, value: str) -> tuple[str, int]:
    """Set ``col`` of the 3rd range row; returns the text and the row number (header = 1)."""
    lines = text.splitlines()
    header = lines[0].split(",")
    k = [i for i, ln in enumerate(lines) if ",range," in ln][2]
    cells = lines[k].split(",")
    cells[header.index(col)] = value
    lines[k] = ",".join(cells)
    return "\n".join(lines) + "\n", k + 1


def _drop_column(text: str, col: str) -> str:
    """The CSV without column ``col`` (comment lines kept)."""
    lines = text.splitlines()
    comments = [ln for ln in lines if ln.startswith("#")]
    rows = list(csv.reader(ln for ln in lines if not ln.startswith("#")))
    j = rows[0].index(col)
    buf = io.StringIO()
    buf.writelines(c + "\n" for c in comments)
    csv.writer(buf, lineterminator="\n").writerows([r[:j] + r[j + 1 :] for r in rows])
    return buf.getvalue()


@pytest.mark.parametrize("case", ["missing column", "nan", "backwards", "negative sigma"])
def test_bad_measurement_log(tmp_path, jiang_text, case):
    if case == "missing column":
        text, row, col = _drop_column(jiang_text, "sigma_m"), 1, "sigma_m"
    elif case == "nan":
        (text, row), col = _edit_range_row(jiang_text, "range_m", "nan"), "range_m"
    elif case == "backwards":
        (text, row), col = _edit_range_row(jiang_text, "t_s", "-1.0"), "t_s"
    else:
        (text, row), col = _edit_range_row(jiang_text, "sigma_m", "-0.1"), "sigma_m"
    log = tmp_path / "bad_log.csv"
    log.write_text(text)
    line = assert_error(run(["track", "range-ekf", log]), 4, "bad_log.csv", col)
    assert f"row {row}" in line, line


@pytest.mark.parametrize(
    ("filt", "extra", "fixture", "col"),
    [
        ("dead-reckoning", [], "imu_log", "ay_mps2"),
        ("lmax", ["--l-max", "1"], "position_log", "y_m"),
    ],
)
def test_bad_imu_and_position_logs(tmp_path, request, filt, extra, fixture, col):
    text = request.getfixturevalue(fixture).read_text()
    bad = tmp_path / "bad.csv"
    bad.write_text(_drop_column(text, col))
    assert_error(run(["track", filt, bad, *extra]), 4, "bad.csv", col, "row")
    lines = text.splitlines()
    k = next(i for i, ln in enumerate(lines) if ln and not ln.startswith("#")) + 3
    cells = lines[k].split(",")
    cells[1] = "nan"
    lines[k] = ",".join(cells)
    bad.write_text("\n".join(lines) + "\n")
    assert_error(run(["track", filt, bad, *extra]), 4, f"row {k + 1}")


@pytest.mark.parametrize("filt", ["range-ekf", "dead-reckoning", "lmax"])
def test_missing_log_file(tmp_path, filt):
    extra = ["--l-max", "1"] if filt == "lmax" else []
    missing = tmp_path / "no_such_log.csv"
    assert_error(run(["track", filt, missing, *extra]), 3, "no_such_log.csv")


def test_failed_run_leaves_existing_output_untouched(tmp_path, jiang_text):
    sentinel = tmp_path / "track.csv"
    sentinel.write_text("SENTINEL, do not touch\n")
    text, _ = _edit_range_row(jiang_text, "sigma_m", "-0.1")
    log = tmp_path / "bad.csv"
    log.write_text(text)
    r = run(["track", "range-ekf", log, "-o", sentinel])
    assert_error(r, 4, "bad.csv")
    assert r.stdout == ""
    assert sentinel.read_text() == "SENTINEL, do not touch\n"
    r = run(["track", "range-ekf", tmp_path / "missing.csv", "-o", sentinel])
    assert_error(r, 3, "missing.csv")
    assert sentinel.read_text() == "SENTINEL, do not touch\n"
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []


def test_output_into_missing_folder(tmp_path, jiang_log):
    out = tmp_path / "no_such_dir" / "track.csv"
    assert_error(run(["track", "range-ekf", jiang_log, "-o", out]), 3, "no_such_dir")


def test_debug_propagates(tmp_path):
    from rangekit.errors import InputFileError

    r = run(["track", "range-ekf", tmp_path / "missing.csv", "--debug"])
    assert isinstance(r.exception, InputFileError)
    assert "rangekit: error:" not in r.stderr
