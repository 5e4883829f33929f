"""DUHL log and beacon file: round trips, and every malformed input names its row/column/key."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest

from rangekit.errors import InputFileError, InvalidParameterError, LogFormatError
from rangekit.io.duhllog import (
    LOG_COLUMNS,
    Beacons,
    DistanceRows,
    DUHLLog,
    OdometryRows,
    parse_beacons,
    read_beacons,
    read_duhl_log,
)

HEADER = ",".join(LOG_COLUMNS)
GOOD = [
    "0.00,odometry,,0.0,0.0,,,",  # row 2
    "0.01,odometry,,0.31,0.29,,,",  # row 3
    "0.01,distance,4,,,2.05,2.11,2.2",  # row 4
    "0.02,odometry,,0.32,0.30,,,",  # row 5
    "0.02,distance,0,,,,2.5,",  # row 6: receivers 1 and 3 missed
    "0.03,distance,5,,,,,",  # row 7: all missed
]


def read(lines, header=HEADER, name="log.csv"):
    return read_duhl_log(io.StringIO("\n".join([header, *lines]) + "\n"), name=name)


def _log(rng: np.random.Generator) -> DUHLLog:
    t = np.round(np.arange(12) * 0.01, 2)
    od = OdometryRows(t, rng.normal(0.3, 0.1, 12), rng.normal(0.3, 0.1, 12))
    td = np.array([0.0, 0.05, 0.05, 0.1, 0.115])
    d = rng.uniform(1.9, 3.0, (5, 3))
    d[1, 2] = d[3, 0] = np.nan
    return DUHLLog(od, DistanceRows(td, np.array([1, 2, 3, 1, 2]), d))


def test_good_log_parses():
    log = read(GOOD)
    assert log.odometry.t_s.tolist() == [0.0, 0.01, 0.02]
    assert log.odometry.v_right_mps.tolist() == [0.0, 0.31, 0.32]
    assert log.odometry.v_left_mps.tolist() == [0.0, 0.29, 0.30]
    assert log.distances.tx.dtype == np.int64
    assert log.distances.tx.tolist() == [4, 0, 5]
    assert log.distances.d_m.shape == (3, 3)
    assert log.distances.d_m[0].tolist() == [2.05, 2.11, 2.2]
    assert np.isnan(log.distances.d_m[1, [0, 2]]).all() and log.distances.d_m[1, 1] == 2.5
    assert np.isnan(log.distances.d_m[2]).all()


def test_round_trip_is_exact_with_nan_receivers(tmp_path):
    log = _log(np.random.default_rng(3))
    text = log.to_csv()
    again = read_duhl_log(io.StringIO(text), name="again")
    for a, b in [
        (again.odometry.t_s, log.odometry.t_s),
        (again.odometry.v_right_mps, log.odometry.v_right_mps),
        (again.odometry.v_left_mps, log.odometry.v_left_mps),
        (again.distances.t_s, log.distances.t_s),
        (again.distances.tx, log.distances.tx),
        (again.distances.d_m, log.distances.d_m),
    ]:
        assert np.array_equal(a, b, equal_nan=True)
    assert np.isnan(again.distances.d_m[1, 2]) and np.isnan(again.distances.d_m[3, 0])
    # To a path (atomic) and to a buffer: the same text.
    p = tmp_path / "run.csv"
    assert log.to_csv(p) is None
    assert p.read_text() == text
    buf = io.StringIO()
    assert log.to_csv(buf) is None
    assert buf.getvalue() == text
    from_file = read_duhl_log(p)
    assert np.array_equal(from_file.distances.d_m, log.distances.d_m, equal_nan=True)


def test_rows_merge_in_time_order_odometry_first_at_equal_times():
    log = _log(np.random.default_rng(4))
    lines = log.to_csv(comment="made by a test\nsecond line").splitlines()
    assert lines[:3] == ["# made by a test", "# second line", HEADER]
    body = [ln.split(",") for ln in lines[3:]]
    t = [float(r[0]) for r in body]
    assert t == sorted(t)
    assert len(body) == 12 + 5
    for i in range(1, len(body)):
        if t[i] == t[i - 1]:  # equal times: never a distance row before an odometry row
            assert not (body[i - 1][1] == "distance" and body[i][1] == "odometry")
    at_005 = [r[1] for r in body if float(r[0]) == 0.05]
    assert at_005 == ["odometry", "distance", "distance"]
    # Rows of one kind keep their order at equal times (tx 2 then tx 3 at t = 0.05).
    assert [r[2] for r in body if float(r[0]) == 0.05 and r[1] == "distance"] == ["2", "3"]
    # Unused cells are empty.
    assert body[0][2] == "" and body[0][5:] == ["", "", ""]


def test_empty_log_is_legal():
    log = read([])
    assert log.odometry.t_s.size == 0 and log.distances.d_m.shape == (0, 3)
    assert DUHLLog().to_csv() == HEADER + "\n"


@pytest.mark.parametrize(
    "row,edit,match",
    [
        (
            2,
            lambda s: s.replace("odometry", "lidar"),
            r"row 2, column 'kind': unknown kind 'lidar'",
        ),
        (
            3,
            lambda s: s.replace("0.31,", ","),
            r"row 3, column 'v_right_mps': a odometry row needs",
        ),
        (
            3,
            lambda s: s.replace(",0.29,", ",,"),
            r"row 3, column 'v_left_mps': a odometry row needs",
        ),
        (4, lambda s: s.replace(",4,", ",,"), r"row 4, column 'tx': a distance row needs a value"),
        (4, lambda s: s.replace(",4,", ",-2,"), r"row 4, column 'tx': -2 is negative"),
        (4, lambda s: s.replace(",4,", ",1.5,"), r"row 4, column 'tx': '1.5' is not an integer"),
        (4, lambda s: s.replace("2.11", "-0.1"), r"row 4, column 'd2_m': -0.1 is negative"),
        (4, lambda s: s.replace("2.05", "inf"), r"row 4, column 'd1_m': 'inf' is not finite"),
        (4, lambda s: s.replace("2.2", "nan"), r"row 4, column 'd3_m': 'nan' is not finite"),
        (4, lambda s: s.replace("2.2", "x"), r"row 4, column 'd3_m': 'x' is not a number"),
        (3, lambda s: s.replace("0.31", "nan"), r"row 3, column 'v_right_mps': 'nan' is not"),
        (5, lambda s: s.replace("0.02,", "0.005,"), r"row 5, column 't_s': time 0.005 goes back"),
        (2, lambda s: s.replace("0.00,", ","), r"row 2, column 't_s': empty cell"),
        (
            3,
            lambda s: s.replace("0.29,,", "0.29,1.0,"),
            r"row 3, column 'd1_m': a odometry row leaves this cell empty \(got 1\)$",
        ),
        (
            3,
            lambda s: s.replace("0.01,odometry,,", "0.01,odometry,3,"),
            r"row 3, column 'tx': a odometry row leaves this cell empty \(got 3\)$",
        ),
        (
            4,
            lambda s: s.replace("4,,,", "4,1e9,,"),
            r"row 4, column 'v_right_mps': a distance row leaves this cell empty \(got 1e\+09\)$",
        ),
        (4, lambda s: s + ",9", r"row 4: 9 cells, the header has 8"),
        (
            5,
            lambda s: s.replace("0.02,", "0.01,"),
            r"row 5, column 't_s': odometry time 0.01 repeats the previous odometry row",
        ),
    ],
)
def test_every_bad_row_names_row_and_column(row, edit, match):
    lines = list(GOOD)
    lines[row - 2] = edit(lines[row - 2])
    with pytest.raises(LogFormatError, match=r"^log\.csv " + match):
        read(lines)


def test_row_numbers_count_comment_lines():
    lines = ["# a comment", *GOOD]
    lines[3] = lines[3].replace("2.11", "-1")  # the first distance row, now file row 5
    with pytest.raises(LogFormatError, match=r"row 5, column 'd2_m'"):
        read(lines)
    text = "# leading\n" + HEADER + "\n# mid\n0.0,odometry,,0,0,,,\n0.1,radar,,,,,,\n"
    with pytest.raises(LogFormatError, match=r"row 5, column 'kind'"):
        read_duhl_log(io.StringIO(text), name="c.csv")


@pytest.mark.parametrize(
    "header,match",
    [
        (HEADER.replace(",d3_m", ""), r"row 1: missing column 'd3_m'"),
        (HEADER + ",note", r"row 1: unknown column 'note'"),
        (HEADER.replace("tx", "t_s"), r"row 1: duplicate column 't_s'"),
    ],
)
def test_bad_header(header, match):
    n = header.count(",") + 1
    with pytest.raises(LogFormatError, match=match):
        read([",".join(["0.0", "odometry", "", "0", "0"] + [""] * (n - 5))], header=header)


def test_header_order_is_free():
    cols = list(LOG_COLUMNS)[::-1]
    row = dict(zip(LOG_COLUMNS, ["0.5", "distance", "2", "", "", "2.0", "2.1", "2.2"], strict=True))
    log = read([",".join(row[c] for c in cols)], header=",".join(cols))
    assert log.distances.tx.tolist() == [2]
    assert log.distances.d_m.tolist() == [[2.0, 2.1, 2.2]]


def test_file_errors(tmp_path):
    with pytest.raises(InputFileError, match="no such file"):
        read_duhl_log(tmp_path / "missing.csv")
    p = tmp_path / "bad.csv"
    p.write_text(HEADER + "\n0.0,odometry,,0,0,,,\n0.1,odometry,,0,,,,\n")
    with pytest.raises(LogFormatError, match=r"bad\.csv row 3, column 'v_left_mps'"):
        read_duhl_log(p)


# --------------------------------------------------------------------------- beacons


def doc(**over):
    d = {
        "format": "rangekit-beacons",
        "version": 1,
        "units": "m",
        "transmitters": [
            {"id": 1, "x_m": 0.0, "y_m": 0.0, "z_m": 2.011},
            {"id": 2, "x_m": 3.0, "y_m": 0.0, "z_m": 2.011},
            {"id": 7, "x_m": 3.0, "y_m": 3.0, "z_m": 2.011},
        ],
    }
    d.update(over)
    return d


def test_beacons_round_trip_and_position(tmp_path):
    b = parse_beacons(doc(name="office", notes="three Txs"), name="b.json")
    assert b.ids.tolist() == [1, 2, 7] and b.ids.dtype == np.int64
    assert b.xyz_m.shape == (3, 3) and len(b) == 3
    assert b.position(7).tolist() == [3.0, 3.0, 2.011]
    assert b.position(np.array([[7, 1], [2, 2]])).shape == (2, 2, 3)
    assert b.position([2, 1])[:, 0].tolist() == [3.0, 0.0]
    with pytest.raises(InvalidParameterError, match="transmitter 5 is not in the beacons"):
        b.position([1, 5])
    with pytest.raises(InvalidParameterError, match="must be integers"):
        b.position(1.0)
    p = tmp_path / "b.json"
    p.write_text(json.dumps(b.to_json()))
    again = read_beacons(p)
    assert np.array_equal(again.ids, b.ids) and np.array_equal(again.xyz_m, b.xyz_m)
    assert not b.xyz_m.flags.writeable


def _tx(i, **kv):
    d = doc()
    d["transmitters"][i] = {**d["transmitters"][i], **kv}
    return d


def _drop(i, key):
    d = doc()
    del d["transmitters"][i][key]
    return d


@pytest.mark.parametrize(
    "obj,match",
    [
        ([1, 2], r"a beacon file must be a JSON object, got list"),
        ({k: v for k, v in doc().items() if k != "units"}, r"missing key 'units'"),
        ({k: v for k, v in doc().items() if k != "transmitters"}, r"missing key 'transmitters'"),
        (doc(color="red"), r"unknown key 'color'"),
        (doc(format="rangekit-floorplan"), r"format='rangekit-floorplan' must be 'rangekit-be"),
        (doc(version=2), r"version=2 is not supported"),
        (doc(version=True), r"version=True is not supported"),
        (doc(units="cm"), r"units='cm' must be 'm'"),
        (doc(transmitters={"id": 1}), r"transmitters=.* must be a list"),
        (doc(transmitters=doc()["transmitters"][:1]), r"transmitters has 1 entry: at least 2"),
        (doc(transmitters=[]), r"transmitters has 0 entries: at least 2"),
        (doc(transmitters=[doc()["transmitters"][0], 5]), r"transmitters\[1\]=5 must be an obj"),
        (_drop(2, "z_m"), r"transmitters\[2\]: missing key 'z_m'"),
        (_drop(0, "id"), r"transmitters\[0\]: missing key 'id'"),
        (_tx(1, height=2.0), r"transmitters\[1\]: unknown key 'height'"),
        (_tx(2, id=1), r"transmitters\[2\]\.id=1 repeats transmitters\[0\]\.id"),
        (_tx(1, id=-3), r"transmitters\[1\]\.id=-3 must be >= 0"),
        (_tx(1, id=2.0), r"transmitters\[1\]\.id=2\.0 must be an integer"),
        (_tx(1, id=True), r"transmitters\[1\]\.id=True must be an integer"),
        (_tx(0, x_m=float("nan")), r"transmitters\[0\]\.x_m=nan must be finite"),
        (_tx(2, z_m=float("inf")), r"transmitters\[2\]\.z_m=inf must be finite"),
        (_tx(2, y_m="1.0"), r"transmitters\[2\]\.y_m='1\.0' must be a number"),
    ],
)
def test_every_bad_beacon_document(obj, match, tmp_path):
    with pytest.raises(InvalidParameterError, match=r"^b\.json: " + match):
        parse_beacons(obj, name="b.json")
    p = tmp_path / "beacons.json"
    p.write_text(json.dumps(obj))  # json writes NaN/Infinity; rangekit's reader refuses them
    if "finite" in match:
        with pytest.raises(InputFileError, match=r"beacons\.json' as JSON: (NaN|Infinity) is"):
            read_beacons(p)
        return
    with pytest.raises(
        InputFileError, match=r"beacons\.json' is not a valid beacon file: " + match
    ):
        read_beacons(p)


def test_beacon_file_errors(tmp_path):
    with pytest.raises(InputFileError, match="no such file"):
        read_beacons(tmp_path / "none.json")
    p = tmp_path / "x.json"
    p.write_text("{not json")
    with pytest.raises(InputFileError, match="as JSON"):
        read_beacons(p)


@pytest.mark.parametrize(
    "ids,xyz,match",
    [
        ([1], [[0, 0, 2]], r"1 transmitter\(s\): at least 2"),
        ([1, 1], [[0, 0, 2], [1, 0, 2]], r"id 1 appears more than once"),
        ([1, -1], [[0, 0, 2], [1, 0, 2]], r"id -1 is negative"),
        ([1, 2], [[0, 0, 2], [1, np.nan, 2]], r"transmitter 2 has a non-finite position"),
        ([1, 2], [[0, 0, 2]], r"xyz_m must have shape \(2, 3\)"),
        ([1.0, 2.0], [[0, 0, 2], [1, 0, 2]], r"ids must be a 1-D array of integers"),
    ],
)
def test_beacons_constructor_checks(ids, xyz, match):
    with pytest.raises(InvalidParameterError, match=match):
        Beacons(ids, xyz)
