"""CLI tests of ``rangekit track duhl|duhl-ranges`` and ``rangekit locate``.

Inputs are Kim & Kim 2013 §V runs from :mod:`rangekit.sim.kim2013`, cut to 10 s.
"""

from __future__ import annotations

import csv
import io
import json
import math

import numpy as np
import pytest
from clihelp import assert_error, ok, run

from rangekit.localize.duhl import DUHLConfig
from rangekit.sim.kim2013 import simulate
from rangekit.sim.ultrasonic import receiver_positions

T_MAX_S = 10.0
COLUMNS = [
    "t_s",
    "x_m",
    "y_m",
    "heading_rad",
    "var_x_m2",
    "var_y_m2",
    "var_heading_rad2",
    "status",
]
SENTINEL = "SENTINEL, do not touch\n"


def _csv(text: str) -> tuple[list[str], np.ndarray]:
    rows = list(csv.reader(io.StringIO(text)))
    return rows[0], np.array(rows[1:], dtype=float)


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def _errors(run_, table: np.ndarray) -> tuple[float, float]:
    """RMS position error (m) and max |heading error| (rad) of a track against the truth."""
    k = np.searchsorted(run_.t_s, table[:, 0])
    np.testing.assert_allclose(run_.t_s[k], table[:, 0])
    truth = run_.true_pose[k]
    pos = np.sqrt(np.mean(np.sum((table[:, 1:3] - truth[:, :2]) ** 2, axis=1)))
    head = np.max(np.abs(_wrap(table[:, 3] - truth[:, 2])))
    return float(pos), float(head)


@pytest.fixture(scope="module")
def sims():
    return {tr: simulate(tr, t_max_s=T_MAX_S, rng=tr) for tr in (1, 3)}


@pytest.fixture(scope="module")
def files(tmp_path_factory, sims):
    """Per trajectory: (log path, beacon path) written to a module temp folder."""
    d = tmp_path_factory.mktemp("duhl")
    out = {}
    for tr, r in sims.items():
        log = d / f"run{tr}.csv"
        r.to_log().to_csv(log)
        bcn = d / f"beacons{tr}.json"
        bcn.write_text(json.dumps(r.beacons.to_json()))
        out[tr] = (log, bcn)
    return out


@pytest.fixture
def log1(files):
    return files[1]


def _track(log, bcn, *extra, filt="duhl"):
    return run(["track", filt, log, "--beacons", bcn, *extra])


# --- track duhl / duhl-ranges ----------------------------------------------------------------


@pytest.mark.parametrize("tr", [1, 3])
@pytest.mark.parametrize("filt", ["duhl", "duhl-ranges"])
def test_track_csv_follows_the_truth(sims, files, tr, filt):
    log, bcn = files[tr]
    r = ok(_track(log, bcn, filt=filt))
    header, table = _csv(r.stdout)
    assert header == COLUMNS
    run_ = sims[tr]
    # One row per odometry row from the start row (the filter starts from UHL of the first
    # two transmitters heard) to the end.
    assert table[-1, 0] == pytest.approx(run_.t_s[-1])
    k0 = int(np.searchsorted(run_.t_s, table[0, 0]))
    assert table.shape[0] == run_.t_s.size - k0
    assert 0 < k0 < 100
    pos, head = _errors(run_, table)
    assert pos < 0.1, pos
    assert head < math.radians(10.0), math.degrees(head)
    assert np.all(table[:, 4:7] > 0.0)
    assert np.all(table[:, 7] == np.round(table[:, 7]))
    assert set(np.unique(table[:, 7]).astype(int)) <= set(range(16))
    assert np.any(table[:, 7].astype(int) & 1)  # observations were applied
    assert all("." not in line.split(",")[-1] for line in r.stdout.splitlines()[1:])
    # stderr: the summary line, then one "warning: " line per warning.
    lines = r.stderr.splitlines()
    assert lines[0].startswith(f"{filt}: {table.shape[0]} poses"), lines
    for word in ("observations used", "rejected", "warnings"):
        assert word in lines[0], lines[0]
    assert all(ln.startswith("warning: ") for ln in lines[1:]), lines
    assert f"; {len(lines) - 1} warnings" in lines[0]
    # --quiet drops the summary, not the warnings nor the track; --verbose adds the config.
    quiet = ok(_track(log, bcn, "-q", filt=filt))
    assert quiet.stdout == r.stdout and quiet.stderr.splitlines() == lines[1:]
    verbose = ok(_track(log, bcn, "-v", filt=filt)).stderr.splitlines()
    assert verbose[1:] == lines and f"track {filt}: wheel_base_m 0.33" in verbose[0]


def test_duhl_and_ranges_differ(log1):
    a = _csv(ok(_track(*log1)).stdout)[1]
    b = _csv(ok(_track(*log1, filt="duhl-ranges")).stdout)[1]
    assert a.shape == b.shape
    assert not np.allclose(a[:, 1:4], b[:, 1:4])


def test_track_json(sims, log1):
    r = ok(_track(*log1, "--format", "json"))
    obj = json.loads(r.stdout)
    assert obj["filter"] == "duhl"
    assert obj["columns"] == COLUMNS
    assert obj["beacons"] == str(log1[1])
    rows = np.array(obj["rows"], dtype=float)
    assert rows.shape[1] == len(COLUMNS)
    assert all(isinstance(row[-1], int) for row in obj["rows"])
    assert _errors(sims[1], rows)[0] < 0.1
    csv_table = _csv(ok(_track(*log1)).stdout)[1]
    np.testing.assert_allclose(rows, csv_table)
    assert isinstance(obj["warnings"], list)
    assert all(isinstance(w, str) for w in obj["warnings"])
    lines = r.stderr.splitlines()
    assert lines[1:] == [f"warning: {w}" for w in obj["warnings"]]
    n = obj["n_distance_rows"]
    assert n == sims[1].distance_t_s.size
    assert (
        obj["n_observations"]
        + obj["n_rejected"]
        + obj["n_without_observation"]
        + obj["n_before_start"]
        == n
    )
    assert f"{obj['n_observations']} observations used" in lines[0]
    assert obj["start_t_s"] == rows[0, 0]
    assert obj["initial_pose"] is None
    cfg = DUHLConfig()
    assert obj["config"] == {
        "wheel_base_m": cfg.wheel_base_m,
        "sigma_d_m": cfg.sigma_d_m,
        "k_v_m": cfg.k_v_m,
        "gate": None,
    }


def test_initial_pose_starts_at_the_first_row(sims, log1):
    # The robot starts at the origin, heading 0 (x along the first leg).
    true0 = sims[1].true_pose[0]
    pose = f"{true0[0]},{true0[1]},{math.degrees(true0[2])}"
    r = ok(_track(*log1, "--initial-pose", pose, "--format", "json"))
    obj = json.loads(r.stdout)
    rows = np.array(obj["rows"], dtype=float)
    assert rows.shape[0] == sims[1].t_s.size
    assert rows[0, 0] == 0.0
    np.testing.assert_allclose(rows[0, 1:4], true0, atol=1e-12)
    assert obj["initial_pose"] == pytest.approx(list(true0))
    assert _errors(sims[1], rows)[0] < 0.1
    # A wrong start heading is corrected by the transmitters (values with a minus sign
    # are read as the option's value).
    r = ok(_track(*log1, "--initial-pose", "-0.1,0.05,-10"))
    table = _csv(r.stdout)[1]
    assert table[0, 3] == pytest.approx(math.radians(-10.0))
    assert _errors(sims[1], table[200:])[0] < 0.1


def test_filter_options_change_the_track(log1):
    base = ok(_track(*log1)).stdout
    for extra in (
        ["--wheel-base", "0.4"],
        ["--sigma-d", "0.05"],
        ["--k-v", "0.004"],
        ["--k-v", "0"],
    ):
        out = ok(_track(*log1, *extra)).stdout
        assert _csv(out)[0] == COLUMNS
        assert out != base, extra
    obj = json.loads(ok(_track(*log1, "--wheel-base", "0.4", "--format", "json")).stdout)
    assert obj["config"]["wheel_base_m"] == 0.4
    # The gate: a strict one rejects observations, --no-gate is the default (no gate).
    g = json.loads(ok(_track(*log1, "--gate", "0.01", "--format", "json")).stdout)
    assert g["config"]["gate"] == 0.01
    assert g["n_rejected"] > 0
    assert any(row[-1] & 4 for row in g["rows"])  # status bit 4: rejected
    assert ok(_track(*log1, "--no-gate")).stdout == base


def test_help_shows_the_library_defaults():
    cfg = DUHLConfig()
    text = " ".join(ok(run(["track", "duhl", "--help"])).stdout.split())
    for v in (cfg.wheel_base_m, cfg.sigma_d_m, cfg.k_v_m):
        assert f"[default: {v:g}]" in text, v


def test_output_file(tmp_path, log1):
    out = tmp_path / "pose.csv"
    r = ok(_track(*log1, "-o", out))
    assert r.stdout == ""
    assert r.stderr.startswith("duhl: ")
    assert _csv(out.read_text())[0] == COLUMNS


def test_help_lists_the_duhl_options():
    assert "duhl-ranges" in ok(run(["track", "--help"])).stdout
    for filt in ("duhl", "duhl-ranges"):
        r = ok(run(["track", filt, "--help"]))
        for opt in ("--beacons", "--rig", "--initial-pose", "--wheel-base", "--sigma-d", "--k-v"):
            assert opt in r.stdout, opt


# --- track: errors -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("filt", "extra", "named"),
    [
        ("duhl", [], "--beacons"),
        ("duhl-ranges", [], "--beacons"),
        ("range-ekf", ["--beacons", "b.json"], "--beacons"),
        ("lmax", ["--l-max", "1", "--beacons", "b.json"], "--beacons"),
        ("dead-reckoning", ["--initial-pose", "0,0,0"], "--initial-pose"),
        ("range-ekf", ["--wheel-base", "0.3"], "--wheel-base"),
        ("range-ekf", ["--sigma-d", "0.01"], "--sigma-d"),
        ("lmax", ["--l-max", "1", "--k-v", "0.001"], "--k-v"),
        ("duhl", ["--beacons", "b.json", "--smooth"], "--smooth"),
        ("duhl", ["--beacons", "b.json", "--l-max", "1"], "--l-max"),
        ("duhl", ["--beacons", "b.json", "--accel-psd", "0.1"], "--accel-psd"),
        ("duhl", ["--beacons", "b.json", "--gate", "0.9", "--no-gate"], "--no-gate"),
    ],
)
def test_option_not_for_this_filter(tmp_path, filt, extra, named):
    out = tmp_path / "out.csv"
    out.write_text(SENTINEL)
    r = run(["track", filt, tmp_path / "any.csv", *extra, "-o", out])
    assert_error(r, 2, named, f"rangekit track {filt} --help")
    assert out.read_text() == SENTINEL


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        (["--wheel-base", "0"], "--wheel-base"),
        (["--wheel-base", "nan"], "--wheel-base"),
        (["--sigma-d", "-0.01"], "--sigma-d"),
        (["--k-v", "-1"], "--k-v"),
        (["--k-v", "inf"], "--k-v"),
        (["--gate", "1"], "--gate"),
        (["--initial-pose", "1,2"], "--initial-pose"),
        (["--initial-pose", "1,2,3,4"], "--initial-pose"),
        (["--initial-pose", "a,b,c"], "--initial-pose"),
        (["--initial-pose", "1,nan,3"], "--initial-pose"),
        (["--format", "xml"], "--format"),
    ],
)
def test_bad_option_values(tmp_path, log1, extra, named):
    out = tmp_path / "out.csv"
    out.write_text(SENTINEL)
    assert_error(_track(*log1, *extra, "-o", out), 2, named)
    assert out.read_text() == SENTINEL


def _edit_distance_row(text: str, col: str, value: str, which: int = 2) -> tuple[str, int]:
    """Set ``col`` of a distance row; returns the text and its row number (header = 1)."""
    lines = text.splitlines()
    header = lines[0].split(",")
    k = [i for i, ln in enumerate(lines) if ",distance," in ln][which]
    cells = lines[k].split(",")
    cells[header.index(col)] = value
    lines[k] = ",".join(cells)
    return "\n".join(lines) + "\n", k + 1


def _bad_log(tmp_path, text: str):
    p = tmp_path / "bad_log.csv"
    p.write_text(text)
    return p


def test_unknown_transmitter_in_the_log(tmp_path, log1):
    text, _ = _edit_distance_row(log1[0].read_text(), "tx", "42")
    log = _bad_log(tmp_path, text)
    out = tmp_path / "pose.csv"
    out.write_text(SENTINEL)
    r = _track(log, log1[1], "-o", out)
    line = assert_error(r, 5, "bad_log.csv", "transmitter 42", str(log1[1]))
    assert "[1, 2, 3, 4, 5, 6]" in line
    assert r.stdout == ""
    assert out.read_text() == SENTINEL
    assert_error(_track(log, log1[1], filt="duhl-ranges"), 5, "transmitter 42")


@pytest.mark.parametrize(
    ("col", "value", "named"),
    [
        ("d2_m", "-0.5", "d2_m"),
        ("d1_m", "abc", "d1_m"),
        ("kind", "sonar", "kind"),
        ("v_left_mps", "0.1", "v_left_mps"),  # a cell a distance row leaves empty
        ("t_s", "-1", "t_s"),  # time going backwards
    ],
)
def test_malformed_log(tmp_path, log1, col, value, named):
    text, row = _edit_distance_row(log1[0].read_text(), col, value)
    out = tmp_path / "pose.csv"
    out.write_text(SENTINEL)
    r = _track(_bad_log(tmp_path, text), log1[1], "-o", out)
    line = assert_error(r, 4, "bad_log.csv", named)
    assert f"row {row}" in line, line
    assert out.read_text() == SENTINEL


def test_log_missing_a_column(tmp_path, log1):
    lines = log1[0].read_text().splitlines()
    text = "\n".join(ln.rsplit(",", 1)[0] for ln in lines) + "\n"  # drop d3_m
    assert_error(_track(_bad_log(tmp_path, text), log1[1]), 4, "bad_log.csv", "d3_m")


def test_log_the_filter_cannot_start_from(tmp_path, log1):
    """The library's message, not rewritten by the command: one line, exit 4 (a data
    file the filter cannot use), the log named."""
    header = log1[0].read_text().splitlines()[0]
    # Header only: no odometry.
    log = _bad_log(tmp_path, header + "\n")
    line = assert_error(_track(log, log1[1]), 4, "bad_log.csv", "odometry")
    assert line == (
        f"rangekit: error: {log}: the filter cannot run on this log: the log has no odometry rows"
    )
    # One transmitter only: no UHL start pose (fine with --initial-pose).
    lines = log1[0].read_text().splitlines()
    keep = [ln for ln in lines[1:] if ",odometry," in ln or ln.split(",")[2] == "1"]
    log.write_text("\n".join([header, *keep]) + "\n")
    for filt in ("duhl", "duhl-ranges"):
        line = assert_error(_track(log, log1[1], filt=filt), 4)
        assert line == (
            f"rangekit: error: {log}: the filter cannot run on this log: no start pose: no two "
            "distinct transmitters were heard on all three receivers (give the initial pose)"
        )
    r = ok(_track(log, log1[1], "--initial-pose", "0,0,0"))
    assert "warning: " in r.stderr
    # A speed beyond the filter's arithmetic is the log's too (exit 4, not 2).
    rows = log1[0].read_text().splitlines()
    k = next(i for i, ln in enumerate(rows) if ",odometry," in ln)
    cells = rows[k].split(",")
    cells[header.split(",").index("v_right_mps")] = "1e9"
    rows[k] = ",".join(cells)
    log.write_text("\n".join(rows) + "\n")
    assert_error(_track(log, log1[1]), 4, "bad_log.csv", "v_right", "1e+09")


@pytest.mark.parametrize(
    ("content", "named"),
    [
        (None, "no_such_beacons.json"),
        ("not json {", "no_such_beacons.json"),
        ('{"format": "rangekit-beacons", "version": 1, "units": "m", "transmitters": '
         '[{"id": 1, "x_m": 0, "y_m": 0, "z_m": 2}, {"id": 2, "x_m": 3, "y_m": 0}]}', "z_m"),
        ('{"format": "rangekit-beacons", "version": 1, "units": "m", "transmitters": '
         '[{"id": 1, "x_m": 0, "y_m": 0, "z_m": 2}]}', "at least 2"),
        ("[1, 2]", "JSON object"),
    ],
)  # fmt: skip
def test_bad_beacon_file(tmp_path, log1, content, named):
    bcn = tmp_path / "no_such_beacons.json"
    if content is not None:
        bcn.write_text(content)
    out = tmp_path / "pose.csv"
    out.write_text(SENTINEL)
    assert_error(_track(log1[0], bcn, "-o", out), 3, "no_such_beacons.json", named)
    assert out.read_text() == SENTINEL
    assert_error(_track(log1[0], tmp_path), 3, str(tmp_path))  # a directory


def test_missing_log(tmp_path, log1):
    out = tmp_path / "pose.csv"
    out.write_text(SENTINEL)
    r = _track(tmp_path / "no_such_log.csv", log1[1], "-o", out)
    assert_error(r, 3, "no_such_log.csv")
    assert out.read_text() == SENTINEL
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pose.csv"]


def test_output_into_missing_folder(tmp_path, log1):
    assert_error(_track(*log1, "-o", tmp_path / "nope" / "pose.csv"), 3, "nope")


def test_debug_propagates(tmp_path, log1):
    from rangekit.errors import IncompatibleInputError

    text, _ = _edit_distance_row(log1[0].read_text(), "tx", "42")
    r = _track(_bad_log(tmp_path, text), log1[1], "--debug")
    assert isinstance(r.exception, IncompatibleInputError)
    assert "rangekit: error:" not in r.stderr


# --- locate --------------------------------------------------------------------------------

POSE = (1.2, 0.7, math.radians(34.0))


@pytest.fixture
def beacons6(tmp_path, sims):
    p = tmp_path / "b.json"
    p.write_text(json.dumps(sims[1].beacons.to_json()))
    return p, sims[1].beacons


def _distances(beacons, ids, pose=POSE) -> list[list[float]]:
    rx = receiver_positions(pose)
    xyz = beacons.position(list(ids))
    return np.linalg.norm(xyz[:, None, :] - rx[None, :, :], axis=2).tolist()


def _cell(v) -> str:
    return v if isinstance(v, str) else repr(float(v))


def _write_distances(path, ids, d, header="tx,d1_m,d2_m,d3_m"):
    rows = [",".join([str(t), *(_cell(v) for v in r)]) for t, r in zip(ids, d, strict=True)]
    lines = [header, *rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def _tx_args(ids, d) -> list[str]:
    out = []
    for t, r in zip(ids, d, strict=True):
        out += ["--tx", f"{t}:{r[0]!r},{r[1]!r},{r[2]!r}"]
    return out


def _check_pose(obj, pose=POSE):
    assert obj["x_m"] == pytest.approx(pose[0], abs=1e-9)
    assert obj["y_m"] == pytest.approx(pose[1], abs=1e-9)
    assert obj["heading_deg"] == pytest.approx(math.degrees(pose[2]), abs=1e-7)
    assert obj["residual_m"] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("method", ["hybrid", "direct", "indirect"])
def test_locate_exact_from_a_file(tmp_path, beacons6, method):
    path, b = beacons6
    ids = [1, 2, 4, 5]
    d = _write_distances(tmp_path / "d.csv", ids, _distances(b, ids))
    r = ok(run(["locate", "--beacons", path, "--distances", d, "--method", method,
                "--format", "json"]))  # fmt: skip
    obj = json.loads(r.stdout)
    _check_pose(obj)
    assert obj["method"] == method
    assert obj["tx"] == ids
    assert obj["heading_rad"] == pytest.approx(POSE[2], abs=1e-9)
    if method != "hybrid":
        assert obj["method_used"] == method
    assert r.stderr == ""


def test_locate_inline_and_table(tmp_path, beacons6):
    path, b = beacons6
    ids = [2, 1]  # two Txs (collinear): the hybrid rule picks the method
    pose = (2.1, 0.3, math.radians(-120.0))
    d = _distances(b, ids, pose)
    r = ok(run(["locate", "--beacons", path, *_tx_args(ids, d), "--format", "json"]))
    obj = json.loads(r.stdout)
    _check_pose(obj, pose)
    assert obj["method_used"] in ("direct", "indirect")
    t = ok(run(["locate", "--beacons", path, *_tx_args(ids, d)])).stdout.splitlines()
    assert t[0].split() == ["x_m", "y_m", "heading_deg", "method_used", "residual_m"]
    cells = t[1].split()
    assert float(cells[0]) == pytest.approx(2.1, abs=1e-6)
    assert float(cells[2]) == pytest.approx(-120.0, abs=1e-5)
    assert cells[3] == obj["method_used"]
    out = tmp_path / "pose.json"
    r = ok(run(["locate", "--beacons", path, *_tx_args(ids, d), "--format", "json", "-o", out]))
    assert r.stdout == ""
    _check_pose(json.loads(out.read_text()), pose)


def test_locate_options(tmp_path, beacons6):
    path, b = beacons6
    ids = [1, 2]
    d = _distances(b, ids)
    base = json.loads(ok(run(["locate", "--beacons", path, *_tx_args(ids, d),
                              "--format", "json"])).stdout)  # fmt: skip
    assert base["r_R_m"] == 0.19 and base["d_th_m"] == 0.2
    other = json.loads(ok(run(["locate", "--beacons", path, *_tx_args(ids, d), "--r-r", "0.25",
                               "--d-th", "0", "--format", "json"])).stdout)  # fmt: skip
    assert other["r_R_m"] == 0.25 and other["d_th_m"] == 0.0
    assert other["residual_m"] > 1e-3  # the wrong radius does not fit the distances


def _locate_err(tmp_path, args, code, *names):
    out = tmp_path / "pose.txt"
    out.write_text(SENTINEL)
    r = run(["locate", *args, "-o", out])
    line = assert_error(r, code, *names)
    assert r.stdout == ""
    assert out.read_text() == SENTINEL
    return line


def test_locate_inline_errors(tmp_path, beacons6):
    path, _ = beacons6
    good = ["--tx", "1:2.5,2.4,2.4"]
    cases = [
        (["--tx", "1:2.5,2.4,nan", "--tx", "2:2.7,2.9,2.7"], 2, "--tx", "nan"),
        (["--tx", "1:2.5,-2.4,2.4", "--tx", "2:2.7,2.9,2.7"], 2, "--tx", "-2.4"),
        (["--tx", "1:2.5,2.4", "--tx", "2:2.7,2.9,2.7"], 2, "--tx", "three"),
        (["--tx", "x:2.5,2.4,2.4", "--tx", "2:2.7,2.9,2.7"], 2, "--tx", "ID:D1,D2,D3"),
        (["--tx", "1=2.5,2.4,2.4", "--tx", "2:2.7,2.9,2.7"], 2, "--tx", "ID:D1,D2,D3"),
        (["--tx", "-1:2.5,2.4,2.4", "--tx", "2:2.7,2.9,2.7"], 2, "--tx", "negative"),
        ([*good, *good], 2, "--tx", "transmitter 1", "more than once"),
        (good, 5, "1 transmitter(s)", "at least 2"),
        ([*good, "--tx", "9:2.7,2.9,2.7"], 5, "transmitter 9", "b.json"),
        ([], 2, "--distances", "--tx"),
        ([*good, "--distances", tmp_path / "d.csv"], 2, "--distances", "--tx"),
        ([*good, "--tx", "2:2.7,2.9,2.7", "--method", "best"], 2, "--method"),
        ([*good, "--tx", "2:2.7,2.9,2.7", "--r-r", "0"], 2, "--r-r"),
        ([*good, "--tx", "2:2.7,2.9,2.7", "--d-th", "-1"], 2, "--d-th"),
        ([*good, "--tx", "2:2.7,2.9,2.7", "--format", "xml"], 2, "--format"),
    ]
    for args, code, *names in cases:
        _locate_err(tmp_path, ["--beacons", path, *args], code, *names)
    # --beacons is required; a missing or bad beacon file is exit 3.
    _locate_err(tmp_path, [*good, "--tx", "2:2.7,2.9,2.7"], 2, "--beacons")
    args = ["--beacons", tmp_path / "nope.json", *good, "--tx", "2:2.7,2.9,2.7"]
    _locate_err(tmp_path, args, 3, "nope.json")


def test_locate_file_errors(tmp_path, beacons6):
    path, b = beacons6
    d = _distances(b, [1, 2])

    def check(ids, dist, code, *names, header="tx,d1_m,d2_m,d3_m"):
        f = _write_distances(tmp_path / "dist.csv", ids, dist, header)
        return _locate_err(tmp_path, ["--beacons", path, "--distances", f], code, *names)

    line = check([1, 2], [d[0], [d[1][0], "nan", d[1][2]]], 4, "dist.csv", "d2_m", "finite")
    assert "row 3" in line
    check([1, 2], [d[0], [d[1][0], d[1][1], -0.1]], 4, "dist.csv", "d3_m", "row 3")
    check([1, 2], [d[0], [d[1][0], d[1][1], ""]], 4, "dist.csv", "d3_m", "row 3", "empty")
    check([1, 2], d, 4, "dist.csv", "d3", header="tx,d1_m,d2_m,d3")
    check([1, 1], d, 4, "dist.csv", "transmitter 1", "more than once")
    check([1, 7], d, 5, "dist.csv", "transmitter 7", "b.json")
    check([1], d[:1], 5, "dist.csv", "1 transmitter(s)")
    check([], [], 5, "dist.csv", "0 transmitter(s)")
    args = ["--beacons", path, "--distances", tmp_path / "no_such.csv"]
    _locate_err(tmp_path, args, 3, "no_such.csv")


def test_locate_transmitters_at_one_point(tmp_path):
    bcn = tmp_path / "stack.json"
    bcn.write_text(json.dumps({
        "format": "rangekit-beacons", "version": 1, "units": "m",
        "transmitters": [{"id": 1, "x_m": 1.0, "y_m": 1.0, "z_m": 2.0},
                         {"id": 2, "x_m": 1.0, "y_m": 1.0, "z_m": 2.5}],
    }))  # fmt: skip
    args = ["--beacons", bcn, "--tx", "1:2.1,2.2,2.3", "--tx", "2:2.6,2.7,2.8"]
    _locate_err(tmp_path, args, 5, "transmitters 1, 2", "same x-y point")
